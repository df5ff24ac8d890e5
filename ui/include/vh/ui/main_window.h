#pragma once
/// @file
/// The main window: it assembles the parts and lays them out (menus File / View / Haptics /
/// Connections / Help; docks Display, Segments, Haptics, the strip chart, Replay). Each part
/// observes the Session or sends it commands; the window itself keeps no live value:
///
///   runtime::Session   the one owner of the scene as loaded (loaded()) and of the live values
///                      (live(): isovalue, gains, tool, segments), the device and the haptic
///                      threads (no Qt);
///   SceneOpener        a path, a drop or a menu choice -> SceneLoader -> setScene();
///   ViewController     Session -> SceneView (the VTK picture) at the screen's rate; Display panel choices;
///   ToolPicker         the tool choice, rebuilt off the GUI thread -> Session::setTool();
///   IsovalueBar, HapticsPanel, SegmentsController, DevicePicker, DeviceInput, StatusLine,
///   SessionRecorder, ReplayController, IgtlPanel   the panels and controllers.
///
/// Threads: everything here runs on the GUI thread. Files are read on SceneLoader's worker
/// thread. The haptic thread is read only through Session::latestSnapshot() (never blocks) and
/// written only through the session's commands.

#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <QMainWindow>
#include <QString>

#include "vh/runtime/scene.h"
#include "vh/runtime/session.h"
#include "vh/ui/preferences.h"
#include "vh/ui/scene_opener.h"
#include "vh/ui/view/scene_view.h"

class QAction;
class QCloseEvent;
class QDockWidget;
class QDragEnterEvent;
class QDropEvent;
class QMenu;

namespace vh::ui {

class DeviceInput;
class DevicePicker;
class DisplayPanel;
class HapticsController;
class HapticsPanel;
class IgtlPanel;
class IsovalueBar;
class LoadNoticePanel;
class ReplayController;
class SceneLoader;
class SceneOpener;
class SegmentsController;
class TechniqueAlerts;
class ProximityAlerts;
class DrillController;
class TissueController;
class SessionRecorder;
class StatusLine;
class SoundOutput;
class StripChart;
class ToolPicker;
class ViewController;

class MainWindow : public QMainWindow {
  Q_OBJECT

 public:
  /// An empty window (drop or open a file); preferences from QSettings.
  explicit MainWindow(QWidget* parent = nullptr);
  /// A window showing `scene` (haptics not started: call startHaptics()).
  /// @throws std::invalid_argument when the scene's volume has no image or field.
  explicit MainWindow(ViewerScene scene, QWidget* parent = nullptr);
  ~MainWindow() override;  ///< Cancels loads, stops the haptic thread before any VTK object goes.

  // ---- Scenes ----------------------------------------------------------------------------------
  /// Replaces the shown scene (the old haptic thread stopped, force ramped to zero). Does not
  /// start the new one. A plain volume (no scene file) takes the remembered gains.
  /// @throws std::invalid_argument for a volume without image or field.
  void setScene(ViewerScene scene);
  bool hasScene() const noexcept;
  /// SceneOpener::openPath(): what is shown stays until the new scene is ready; sceneLoaded()
  /// or loadFailed() follows.
  void openPath(const QString& path);
  /// Dialogs (errors, series chooser) when true; otherwise errors go to stderr only and the
  /// largest DICOM series is taken (scripted runs, tests).
  void setInteractive(bool interactive);
  /// Starts the haptic thread automatically after a load finished (default true).
  void setAutoStartHaptics(bool on) { auto_start_haptics_ = on; }

  // ---- The session (runtime::Session) ----------------------------------------------------------
  runtime::Session& session() noexcept { return session_; }
  const runtime::Session& session() const noexcept { return session_; }
  /// The window title's detail of the scene shown.
  const std::string& sceneTitle() const noexcept { return title_; }
  void startHaptics();  ///< Refused (a notice) while a replay is shown.

  // ---- Preferences and the window ------------------------------------------------------------
  const Preferences& preferences() const noexcept { return prefs_; }
  Preferences& preferences() noexcept { return prefs_; }
  void saveSettings() const;
  void restoreLayout();
  /// A PNG of the whole window (the view composited in). @return false when it cannot be written.
  bool saveScreenshot(const QString& path);
  QString statusText() const;
  /// File > Data Folder's choice: where the shared datasets (scans named by their shared path,
  /// the real tool meshes) are looked for. A folder holding none of ct/, nrrd/, classic/ and
  /// meshes/ is refused (a message box naming it, nothing changes); else it is kept in the
  /// preferences, the Haptics panel's tools list what it holds, and the status bar says so
  /// (and that VH_SHARED_DATASETS_DIR, when set, wins). @return whether it was taken.
  bool setDataFolder(const QString& dir);

  // ---- Parts, for the application, tests and scripting ---------------------------------------
  SceneOpener* opener() const noexcept { return opener_; }
  SceneLoader* loader() const noexcept { return loader_; }
  SceneView* sceneView() const noexcept { return view_; }
  ViewController* viewController() const noexcept { return view_controller_; }
  ToolPicker* toolPicker() const noexcept { return tool_picker_; }
  DrillController* drillController() const noexcept { return drill_; }
  TissueController* tissueController() const noexcept { return tissue_; }
  IsovalueBar* isovalueBar() const noexcept { return iso_bar_; }
  HapticsPanel* hapticsPanel() const noexcept { return haptics_panel_; }
  HapticsController* haptics() const noexcept { return haptics_; }
  DisplayPanel* displayPanel() const noexcept { return display_panel_; }
  StripChart* stripChart() const noexcept { return chart_; }
  LoadNoticePanel* loadNotices() const noexcept { return notices_; }
  /// The OpenIGTLink switch (Connections menu): off until switched on here, by a scene file's
  /// "openigtlink" section or by the command line (AppOptions::igtl_port).
  IgtlPanel* igtlPanel() const noexcept { return igtl_; }
  DevicePicker* devicePicker() const noexcept { return device_picker_; }
  DeviceInput* deviceInput() const noexcept { return device_input_; }
  SessionRecorder* recorder() const noexcept { return recorder_; }
  ReplayController* replay() const noexcept { return replay_; }
  SegmentsController* segments() const noexcept { return segments_; }

 signals:
  /// A load finished and its scene is shown.
  void sceneLoaded();
  /// A load failed: `message` names the file and the problem; the previous scene is kept.
  void loadFailed(const QString& message);

 protected:
  void closeEvent(QCloseEvent* event) override;
  void dragEnterEvent(QDragEnterEvent* event) override;
  void dropEvent(QDropEvent* event) override;

 private:
  void buildUi();
  void buildDocks();
  void buildMenus();
  void connectParts();
  void connectSound();  // the burr's sound and the alert tone (critical segments, technique)
  void connectGuidance();  // the expert's ghost: live guidance and replay
  void onSessionChanged(runtime::SessionChange what);
  void onSceneLoaded(const std::shared_ptr<ViewerScene>& loaded);
  void onLoadEnded();
  void updateWindowTitle();
  void updateStatus();
  /// The sound follows the view's snapshot `snap` (the scene's burr, while the sound plays).
  void followSound(const runtime::HapticSnapshot& snap);

  runtime::Session session_;  // before every part that observes it
  Preferences prefs_;
  std::string title_;
  std::filesystem::path opened_;  // what the user opened for the scene shown (load notices)
  SceneView* view_ = nullptr;
  ViewController* view_controller_ = nullptr;
  SceneLoader* loader_ = nullptr;
  SceneOpener* opener_ = nullptr;
  ToolPicker* tool_picker_ = nullptr;
  IgtlPanel* igtl_ = nullptr;
  LoadNoticePanel* notices_ = nullptr;
  IsovalueBar* iso_bar_ = nullptr;
  DisplayPanel* display_panel_ = nullptr;
  HapticsPanel* haptics_panel_ = nullptr;
  HapticsController* haptics_ = nullptr;
  DevicePicker* device_picker_ = nullptr;
  DeviceInput* device_input_ = nullptr;
  StatusLine* status_ = nullptr;
  SegmentsController* segments_ = nullptr;
  DrillController* drill_ = nullptr;
  TissueController* tissue_ = nullptr;
  StripChart* chart_ = nullptr;
  SoundOutput* sound_ = nullptr;  // the burr and the alerts; opened at its first use
  TechniqueAlerts* technique_ = nullptr;  // technique feedback: status and alert tone
  ProximityAlerts* proximity_ = nullptr;  // warnings before harm: tool colour, status, cue
  SessionRecorder* recorder_ = nullptr;
  ReplayController* replay_ = nullptr;
  QDockWidget* display_dock_ = nullptr;
  QDockWidget* haptics_dock_ = nullptr;
  QDockWidget* chart_dock_ = nullptr;
  int observer_ = 0;
  int status_countdown_ = 0;
  bool auto_start_haptics_ = true;
};

}  // namespace vh::ui
