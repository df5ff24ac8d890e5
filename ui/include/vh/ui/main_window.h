#pragma once
/// @file
/// The main window: menus (File / View / Haptics / Help), docks (Display, Haptics, the strip
/// chart, Replay), opening files (dialogs, recent files, drag and drop, the series chooser),
/// settings, and the wiring of its parts:
///
///   runtime::Session   the one owner of the scene as loaded (loaded()) and of the live values
///                      (live(): isovalue, gains, tool, segments), the device and the haptic
///                      threads (no Qt); every part below observes it or sends it commands;
///   SceneView          the VTK props, camera and clipping: turns a live snapshot and a
///                      recorded tick into the same picture;
///   IsovalueBar, DisplayPanel, HapticsPanel, DevicePicker, DeviceInput, StatusLine,
///   SessionRecorder, ReplayController   the panels and controllers.
///
/// Threads: everything here runs on the GUI thread. Files are read on SceneLoader's worker
/// thread. The haptic thread is read only through Session::latestSnapshot() (never blocks) on
/// a display timer (~30 Hz) and written only through the session's commands.

#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <QElapsedTimer>
#include <QMainWindow>
#include <QString>
#include <QStringList>

#include "vh/haptics/pose.h"
#include "vh/haptics/virtual_coupling.h"
#include "vh/io/dicom_series.h"
#include "vh/runtime/haptic_thread.h"
#include "vh/runtime/scene.h"
#include "vh/runtime/session.h"
#include "vh/ui/panels/histogram.h"
#include "vh/ui/preferences.h"
#include "vh/ui/view/render_presets.h"
#include "vh/ui/view/scene_view.h"
#include "vh/ui/tool_catalog.h"

class QAction;
class QActionGroup;
class QCloseEvent;
class QDockWidget;
class QDoubleSpinBox;
class QDragEnterEvent;
class QDropEvent;
class QMenu;
class QSlider;
class QTimer;
class vtkActor;
class vtkVolume;

namespace vh::ui {

class IgtlPanel;  // igtl_panel.h

class DeviceInput;
class DevicePicker;
class DisplayPanel;
class HapticsPanel;
class HistogramSlider;
class IsovalueBar;
class LoadNoticePanel;
class OrientationMarker;
class ReplayController;
class SceneActors;
class SceneLoader;
class SegmentsController;
class SessionRecorder;
class StatusLine;
class StripChart;
class VtkView;
struct LoadedViewerScene;
struct RebuiltTool;

/// What the main window opens: a loaded scene with its device (null: haptics off) and what the
/// window shows about it. The session builds the haptic threads.
struct ViewerScene {
  runtime::LoadedScene scene;               ///< As loaded: volume (field + image), tool, isovalue, pose, spec.
  std::shared_ptr<runtime::Device> device;  ///< Null: no device (haptics off).
  std::optional<Histogram> histogram;       ///< Absent: computed when shown.
  std::string title;                        ///< Window title detail (e.g. file name).
  std::filesystem::path opened;             ///< What the user opened (recent files).
};

/// A ViewerScene for `loaded` driving `device` (null: haptics off), titled by its file name.
ViewerScene makeViewerScene(const runtime::LoadedScene& loaded, std::shared_ptr<runtime::Device> device);

class MainWindow : public QMainWindow {
  Q_OBJECT

 public:
  /// An empty window (drop or open a file); preferences from QSettings.
  explicit MainWindow(QWidget* parent = nullptr);
  /// A window showing `scene` (haptics not started: call startHaptics()).
  /// @throws std::invalid_argument when the scene's volume has no image or field.
  explicit MainWindow(ViewerScene scene, QWidget* parent = nullptr);
  ~MainWindow() override;  ///< Cancels loads, stops the haptic thread before any VTK object goes.

  // ---- Scenes and loading ------------------------------------------------------------------
  /// Replaces the shown scene (the old haptic thread stopped, force ramped to zero). Does not
  /// start the new one. A plain volume (no scene file) takes the remembered gains.
  /// @throws std::invalid_argument for a volume without image or field.
  void setScene(ViewerScene scene);
  bool hasScene() const noexcept { return session_.hasScene() && view_->hasScene(); }
  /// Opens a path the way the user would: a scene .json, a recording .vhrec, a DICOM folder (a
  /// chooser when it holds several series), or a NRRD / MetaImage / DICOM file. Asynchronous:
  /// sceneLoaded() or loadFailed() follows; what is shown stays until the new scene is ready.
  void openPath(const QString& path);
  /// Loads a parsed scene asynchronously; `opened` goes to the recent files.
  void openScene(const runtime::SceneSpec& spec, const std::filesystem::path& opened = {});
  /// Opens a volume already in memory (one received over OpenIGTLink) as the new scene with the
  /// default tool and a simulated device, like a dropped file (not added to the recent files).
  void openLoadedVolume(io::LoadedVolume volume);
  /// The OpenIGTLink switch (Connections menu): off until switched on here, by a scene file's
  /// "openigtlink" section or by the command line (AppOptions::igtl_port).
  IgtlPanel* igtlPanel() const noexcept { return igtl_; }
  /// Loads series `series` of a listed DICOM folder, time point `phase` (0-based).
  void openDicomSeries(const io::DicomSeriesInfo& series, int phase = 0);
  /// True from a load's start until its scene is shown and rendered once (or it failed).
  bool loading() const noexcept;
  /// Abandons the running load; the current scene stays.
  void cancelLoading();
  /// Dialogs (errors, series chooser) when true; otherwise errors go to stderr only and the
  /// largest DICOM series is taken (scripted runs, tests).
  void setInteractive(bool interactive);
  /// The last load error ("FILE: problem"), empty when none.
  QString lastError() const { return last_error_; }
  /// Starts the haptic thread automatically after a load finished (default true).
  void setAutoStartHaptics(bool on) { auto_start_haptics_ = on; }

  // ---- The session (runtime::Session) and its commands -------------------------------------
  runtime::Session& session() noexcept { return session_; }
  const runtime::Session& session() const noexcept { return session_; }
  /// The window title's detail of the scene shown.
  const std::string& sceneTitle() const noexcept { return title_; }
  void startHaptics();  ///< Refused while a replay is shown.
  void stopHaptics() { session_.stopHaptics(); }
  bool hapticsRunning() const noexcept { return session_.hapticsRunning(); }
  void setGains(const haptics::CouplingGains& gains) { session_.setGains(gains); }
  haptics::CouplingGains gains() const noexcept { return session_.gains(); }
  void setIsovalue(double isovalue) { session_.setIsovalue(isovalue); }
  double isovalue() const noexcept { return session_.isovalue(); }
  runtime::Device* device() const noexcept { return session_.device(); }
  runtime::SimulatedDevice* simulatedDevice() const noexcept { return session_.simulatedDevice(); }
  runtime::HapticThread* hapticThread() const noexcept { return session_.hapticThread(); }
  /// Drives `device` instead (a device picker plugs in here): the haptic thread is rebuilt with
  /// the current tool at the proxy's current pose. Null: no haptics.
  void setDevice(std::shared_ptr<runtime::Device> device) { session_.setDevice(std::move(device)); }
  /// Rebuilds tool `choice_index` of toolChoices() at `point_spacing_m` [m] (0: automatic) on
  /// the loader thread, then hands it to the session. toolChanged() follows.
  void selectTool(int choice_index, double point_spacing_m = 0.0);
  const std::vector<ToolChoice>& toolChoices() const noexcept { return tools_; }
  int currentToolIndex() const noexcept { return tool_index_; }

  // ---- Devices (device_picker.h, device_input.h) --------------------------------------------
  void rescanDevices();
  QStringList deviceChoices() const;
  int currentDeviceChoice() const noexcept;
  bool chooseDevice(int index);
  QString lastDeviceError() const;
  QMenu* deviceMenu() const noexcept { return device_menu_; }
  /// Moves the simulated device (no effect without one).
  void setDevicePose(const haptics::Pose& X_WD);
  /// Scripted touch (DeviceInput::touchSurface()).
  bool touchSurface(double depth_m);

  /// Reads the session's latest snapshot now and shows it (scene view, strip chart, status
  /// line; the status text changes at most every ~200 ms unless `update_status_now`).
  /// @return true when something visible changed.
  bool refreshFromHaptics(bool update_status_now = false);

  // ---- Viewing -------------------------------------------------------------------------------
  void setRenderMode(RenderMode mode);
  RenderMode renderMode() const noexcept { return prefs_.mode; }
  void setPreset(VolumePreset preset);
  VolumePreset preset() const noexcept { return prefs_.preset; }
  void resetCamera();
  void focusOnTool();
  void setStandardView(StandardView view);
  void setClipping(bool enabled, ClipAxis axis = ClipAxis::kX, double fraction = 0.5, bool flip = false);
  void setOrientationMarkerVisible(bool visible);
  void setDeviceToolVisible(bool visible);
  void applyColours();
  /// Ends interactive (reduced) rendering now and asks for a full-quality frame.
  void renderStill(bool best_quality = false);
  /// A PNG of the whole window (the view composited in). @return false when it cannot be written.
  bool saveScreenshot(const QString& path);

  // ---- Preferences ---------------------------------------------------------------------------
  const Preferences& preferences() const noexcept { return prefs_; }
  Preferences& preferences() noexcept { return prefs_; }
  void saveSettings() const;
  void restoreLayout();

  // ---- Parts, for tests and scripting --------------------------------------------------------
  SceneView* sceneView() const noexcept { return view_; }
  VtkView* view() const noexcept;
  QSlider* isovalueSlider() const noexcept;
  HistogramSlider* histogramSlider() const noexcept;
  QDoubleSpinBox* isovalueSpinBox() const noexcept;
  HapticsPanel* hapticsPanel() const noexcept { return haptics_panel_; }
  DisplayPanel* displayPanel() const noexcept { return display_panel_; }
  StripChart* stripChart() const noexcept { return chart_; }
  SceneLoader* loader() const noexcept { return loader_; }
  LoadNoticePanel* loadNotices() const noexcept { return notices_; }
  SceneActors& actors() const noexcept;
  OrientationMarker* orientationMarker() const noexcept;
  vtkVolume* volumeProp() const noexcept;
  vtkActor* proxyActor() const noexcept;
  vtkActor* deviceActor() const noexcept;
  QString statusText() const;
  /// The last snapshot read from the haptic thread (default-constructed before the first).
  const runtime::HapticSnapshot& lastSnapshot() const noexcept { return snapshot_; }
  QMenu* recentFilesMenu() const noexcept { return recent_menu_; }
  SessionRecorder* recorder() const noexcept { return recorder_; }
  ReplayController* replay() const noexcept { return replay_; }
  SegmentsController* segments() const noexcept { return segments_; }

 signals:
  /// A load finished and its scene is shown.
  void sceneLoaded();
  /// A load failed: `message` names the file and the problem; the previous scene is kept.
  void loadFailed(const QString& message);
  /// A new tool is in use (selectTool()).
  void toolChanged();

 protected:
  void closeEvent(QCloseEvent* event) override;
  void dragEnterEvent(QDragEnterEvent* event) override;
  void dropEvent(QDropEvent* event) override;

 private:
  void buildUi();
  void buildDocks();
  void buildMenus();
  void connectParts();
  void onSessionChanged(runtime::SessionChange what);
  void onSceneLoaded(std::shared_ptr<LoadedViewerScene> loaded);
  void onToolBuilt(std::shared_ptr<RebuiltTool> tool);
  void onSeriesListed(const QString& folder, const std::vector<io::DicomSeriesInfo>& series);
  void showLoadNotices(const io::VolumeInfo& info, const runtime::SceneSpec& spec);
  void reportError(const QString& what, const QString& message);
  void rebuildRecentMenu();
  void openFileDialog(int kind);
  void chooseColour(QColor Preferences::*field, const QString& title);
  void applyClippingFromPanel();
  void updateHint();
  void updateHapticsPanel();
  void updateWindowTitle();
  void updateStatus();

  runtime::Session session_;  // before every part that observes it
  Preferences prefs_;
  std::string title_;
  std::filesystem::path opened_;  // what the user opened for the scene shown (load notices)
  std::vector<ToolChoice> tools_;
  int tool_index_ = -1;
  SceneView* view_ = nullptr;
  SceneLoader* loader_ = nullptr;
  IgtlPanel* igtl_ = nullptr;
  LoadNoticePanel* notices_ = nullptr;
  IsovalueBar* iso_bar_ = nullptr;
  DisplayPanel* display_panel_ = nullptr;
  HapticsPanel* haptics_panel_ = nullptr;
  DevicePicker* device_picker_ = nullptr;
  DeviceInput* device_input_ = nullptr;
  StatusLine* status_ = nullptr;
  SegmentsController* segments_ = nullptr;
  StripChart* chart_ = nullptr;
  SessionRecorder* recorder_ = nullptr;
  ReplayController* replay_ = nullptr;
  QDockWidget* display_dock_ = nullptr;
  QDockWidget* haptics_dock_ = nullptr;
  QDockWidget* chart_dock_ = nullptr;
  QMenu* recent_menu_ = nullptr;
  QMenu* device_menu_ = nullptr;
  QAction* haptics_action_ = nullptr;
  QTimer* display_timer_ = nullptr;
  QElapsedTimer clock_;  // strip chart time base
  int observer_ = 0;
  int status_countdown_ = 0;
  bool interactive_ = true;
  bool auto_start_haptics_ = true;
  bool upload_pending_ = false;  // a new scene waits for its first frame (GPU upload)
  std::uint64_t upload_frame_ = 0;
  QString last_error_;
  runtime::HapticSnapshot snapshot_;
  bool have_snapshot_ = false;
};

}  // namespace vh::ui
