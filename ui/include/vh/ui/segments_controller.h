#pragma once
/// @file
/// Segments in the main window: File > Open Segmentation (and a dropped or opened
/// .seg.nrrd while a scan is shown) reads a 3D Slicer segmentation or a label map for the scan
/// shown; the Segments dock (SegmentsPanel) chooses what is felt, shown and critical, which the
/// session applies (runtime::Session::setSegments()); the scene view draws the shown segments;
/// each haptic snapshot names the segment touched, and touching a critical one shows a red
/// alert in the view (and beeps when asked). The recording gets its "segment" and
/// "critical_contact" events from the records (runtime::RecordingWriter). "Show segments through
/// the scan" is kept in the preferences and drawn by the view (SceneView::setSegmentsThroughScan());
/// "go to segment" frames a segment in the view and, with the simulated device and the haptics
/// running, puts the tool on the first felt surface along the line of sight through its centre
/// (DeviceInput::touchSurfaceAt(), a placement).
///
/// Data flows one way: SegmentsPanel -> this -> Preferences, SceneView and DeviceInput.
/// Threads: GUI thread only. It observes runtime::Session; it holds no copy of the segments.
#include <filesystem>

#include <QObject>
#include <QString>

#include "vh/runtime/session.h"

class QDockWidget;
class QMainWindow;
class QStatusBar;

namespace vh::ui {

class DeviceInput;
struct Preferences;
class SceneView;
class SegmentsPanel;
struct SegmentChoices;

class SegmentsController : public QObject {
  Q_OBJECT

 public:
  /// Adds the Segments dock to `window` (right side) and observes `session`. `prefs` holds the
  /// display choice (segments through the scan); `device_input` (may be null: go to segment
  /// then only frames) places the tool. All outlive this.
  SegmentsController(runtime::Session& session, SceneView& view, QMainWindow* window, QStatusBar* status_bar,
                     Preferences& prefs, DeviceInput* device_input = nullptr);
  ~SegmentsController() override;

  /// Loads `path` (.seg.nrrd or label map) as the segments of the scan shown: every segment
  /// shown, none felt (the scan's isosurface stays felt). Errors are reported through
  /// errorReported() and the current segments stay.
  /// @return true when loaded.
  bool open(const std::filesystem::path& path);
  /// Asks for a file (File > Open Segmentation...).
  void openDialog(const QString& folder);
  /// Applies `choices` to the session's segments (felt, shown, critical, smoothing).
  /// @return false (and errorReported()) when the felt field cannot be built.
  bool apply(const SegmentChoices& choices);
  /// Shows what `snapshot` touches: the panel's row, the view's emphasis and, for a critical
  /// segment, the alert (a beep on entering it when the panel asks for sound).
  void showSnapshot(const runtime::HapticSnapshot& snapshot);
  /// The shown segments drawn through the scan or not: the preference, the panel's box, the view.
  void setThroughScan(bool on);

  /// What goToSegment() did.
  enum class GoTo {
    kNotShown,    ///< The segment is not shown: nothing moved.
    kFramedOnly,  ///< Framed; no simulated device, or the haptics not running: the tool stays.
    kNoSurface,   ///< Framed; the line of sight through its centre meets no felt surface.
    kPlaced,      ///< Framed, and the tool placed on the first felt surface along that line.
  };
  /// Go to segment (a double-click on its name): frames segment `segment` in the view
  /// (SceneView::frameSegment()) and then, with a simulated device and the haptic threads
  /// running, touches the surface at the centre of the view as Ctrl+Shift+click does there
  /// (DeviceInput::touchSurfaceAt(), a placement: the tool's centre of mass on the line of sight
  /// through the segment's centre, its shell on the first felt surface along it, the device
  /// DeviceInput::kTouchDepth_m further in). The status bar says what happened.
  GoTo goToSegment(int segment);

  SegmentsPanel* panel() const noexcept { return panel_; }
  /// The session's segment names for other threads (the OpenIGTLink link), updated with them.
  const std::shared_ptr<runtime::SegmentNameTable>& names() const noexcept { return names_; }
  QDockWidget* dock() const noexcept { return dock_; }
  /// Critical touches shown since the segments were set (entries into a critical segment).
  int criticalAlerts() const noexcept { return critical_alerts_; }

 signals:
  void errorReported(const QString& what, const QString& message);
  /// A critical segment was touched with the panel's sound on: the window beeps
  /// (SoundOutput::beep(): the alert tone on the burr's mixer).
  void alertSoundRequested();

 private:
  void onSessionChanged(runtime::SessionChange what);

  runtime::Session& session_;
  SceneView& view_;
  Preferences& prefs_;
  DeviceInput* device_input_;
  QMainWindow* window_;
  QStatusBar* status_bar_;
  SegmentsPanel* panel_ = nullptr;
  QDockWidget* dock_ = nullptr;
  int observer_ = -1;
  std::shared_ptr<runtime::SegmentNameTable> names_ = std::make_shared<runtime::SegmentNameTable>();
  int touched_ = -1;
  int critical_alerts_ = 0;
};

}  // namespace vh::ui
