#pragma once
/// @file
/// The main window: the VTK view (volume as isosurface / composite / MIP, the proxy and device
/// tools, contacts, force, orientation marker, optional clipping plane), the isovalue slider with
/// the volume's histogram behind it and a spin box in the data's units, the Display and Haptics
/// docks, a live strip chart, the status bar with the servo statistics and load progress, and
/// the File / View / Haptics / Help menus (open DICOM folder, NRRD / MetaImage, scene, recent
/// files, drag and drop, screenshots, standard views, About).
///
/// Threads: everything here runs on the GUI thread. Files are read on SceneLoader's worker
/// thread. The haptic thread is read only through HapticThread::latestSnapshot() (never blocks)
/// on a display timer (~30 Hz), and written only through its command setters (setIsovalue(),
/// setGains()) and SimulatedDevice::setPose(); nothing here renders from, or waits on, the
/// haptic thread except stopHaptics() (which joins it after the force ramp).
///
/// Devices: the window drives any runtime::Device through the HapticThread; mouse / keyboard
/// manipulation applies when the device is a runtime::SimulatedDevice. setDevice() swaps the
/// device (e.g. from a device picker) keeping the volume and the tool.

#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <QElapsedTimer>
#include <QMainWindow>
#include <QPoint>
#include <QString>
#include <QStringList>

#include "vh/haptics/pose.h"
#include "vh/haptics/tool_model.h"
#include "vh/haptics/virtual_coupling.h"
#include "vh/io/dicom_series.h"
#include "vh/io/volume_loader.h"
#include "vh/runtime/haptic_thread.h"
#include "vh/runtime/scene.h"
#include "vh/ui/histogram.h"
#include "vh/ui/preferences.h"
#include "vh/ui/render_presets.h"
#include "vh/ui/tool_catalog.h"

class QAction;
class QActionGroup;
class QCheckBox;
class QCloseEvent;
class QComboBox;
class QDockWidget;
class QDoubleSpinBox;
class QDragEnterEvent;
class QDropEvent;
class QGroupBox;
class QKeyEvent;
class QLabel;
class QMenu;
class QProgressBar;
class QPushButton;
class QSlider;
class QTimer;
class QToolButton;
class vtkActor;
class vtkTextActor;
class vtkVolume;

namespace vh::runtime {
class Device;
class SimulatedDevice;
}  // namespace vh::runtime

namespace vh::devices {
class DeviceCatalog;
class HotplugMonitor;
struct FoundDevice;
}  // namespace vh::devices

namespace vh::ui {

class HapticsPanel;
class LoadNoticePanel;
class HistogramSlider;
class OrientationMarker;
class ReplayController;
class SceneActors;
class SceneLoader;
class SessionRecorder;
class StripChart;
class VtkView;
struct LoadedViewerScene;
struct RebuiltTool;
struct ViewCamera;

/// What the main window shows and drives; built by makeViewerScene() (or by hand in a test).
struct ViewerScene {
  io::LoadedVolume volume;                          ///< Field + image (metres, data units); image required.
  std::shared_ptr<const haptics::ToolModel> tool;   ///< Tool (display mesh, point shell, mass).
  double isovalue = 0.0;                            ///< Initial isovalue (data units).
  haptics::Pose X_WT_initial;                       ///< Initial proxy/device pose in W [m].
  std::shared_ptr<runtime::Device> device;          ///< Null: no device (haptics off).
  std::unique_ptr<runtime::HapticThread> haptics;   ///< Null: no haptic thread. Not started yet.
  std::string title;                                ///< Window title detail (e.g. file name).
  runtime::ToolSpec tool_spec;                      ///< How the tool was made (mesh, scale, pose).
  haptics::CouplingGains gains;                     ///< Gains the haptic thread starts with.
  double point_spacing_m = 0.0;                     ///< Point shell spacing [m]; 0: estimated.
  std::optional<Histogram> histogram;               ///< Absent: computed when shown.
  std::filesystem::path opened;                     ///< What the user opened (recent files).
  bool scene_file = false;                          ///< Opened from a scene .json (its gains win).
  runtime::SceneSpec spec;                          ///< The scene as loaded (session metadata).
};

/// A ViewerScene from a loaded scene and (optionally) its device and haptic thread.
ViewerScene makeViewerScene(const runtime::LoadedScene& loaded, std::shared_ptr<runtime::Device> device,
                            std::unique_ptr<runtime::HapticThread> haptics);

/// Standard camera directions for a patient frame W = LPS (+x left, +y posterior, +z superior).
enum class StandardView { kAnterior, kPosterior, kLeft, kRight, kSuperior, kInferior };

/// Axis of the clipping plane in W.
enum class ClipAxis { kX, kY, kZ };

class MainWindow : public QMainWindow {
  Q_OBJECT

 public:
  /// An empty window (drop or open a file); preferences from QSettings.
  explicit MainWindow(QWidget* parent = nullptr);
  /// A window showing `scene` (haptics not started: call startHaptics()).
  /// @throws std::invalid_argument when the scene's volume has no image.
  explicit MainWindow(ViewerScene scene, QWidget* parent = nullptr);
  ~MainWindow() override;  ///< Cancels loads, stops the haptic thread before any VTK object goes.

  // ---- Scenes and loading ------------------------------------------------------------------
  /// Replaces the shown scene (stopping the old haptic thread, force ramped to zero). Does not
  /// start the new haptic thread. @throws std::invalid_argument for a volume without image.
  void setScene(ViewerScene scene);
  bool hasScene() const noexcept { return actors_ != nullptr; }
  /// Opens a path the way the user would: a scene .json, a DICOM folder (a chooser when it holds
  /// several series), or a NRRD / MetaImage / DICOM file. Asynchronous: sceneLoaded() or
  /// loadFailed() follows; what is shown stays until the new scene is ready.
  void openPath(const QString& path);
  /// Loads a parsed scene asynchronously; `opened` goes to the recent files.
  void openScene(const runtime::SceneSpec& spec, const std::filesystem::path& opened = {});
  /// Loads series `series` of a listed DICOM folder asynchronously, time point `phase` (0-based)
  /// of a 4-D series: the scene's volume is the folder with VolumeSpec::series = the series UID.
  void openDicomSeries(const io::DicomSeriesInfo& series, int phase = 0);
  /// True from a load's start until its scene is shown and rendered once (or it failed).
  bool loading() const noexcept;
  /// Abandons the running load; the current scene stays.
  void cancelLoading();
  /// Dialogs (errors, series chooser) when true; otherwise errors go to stderr only and the
  /// largest DICOM series is taken (scripted runs, tests).
  void setInteractive(bool interactive) { interactive_ = interactive; }
  /// The last load error ("FILE: problem"), empty when none.
  QString lastError() const { return last_error_; }
  /// Starts the haptic thread automatically after a load finished (default true).
  void setAutoStartHaptics(bool on) { auto_start_haptics_ = on; }

  // ---- Haptics -------------------------------------------------------------------------------
  /// Starts the haptic thread (when the scene has one) and the display timer.
  void startHaptics();
  /// Stops the haptic thread: the force is ramped to zero, then the thread joins. Idempotent.
  void stopHaptics();
  bool hapticsRunning() const noexcept;
  /// Sets the coupling gains: linear [N/m] and torsional [N*m/rad]; applied at the haptic
  /// thread's next tick (HapticThread::setGains); remembered in the preferences.
  void setGains(const haptics::CouplingGains& gains);
  haptics::CouplingGains gains() const noexcept { return gains_; }
  /// Rebuilds the tool `choice_index` of toolCatalog() at `point_spacing_m` [m] (0: automatic)
  /// on the loader thread, then swaps it in (haptic thread restarted with a new renderer, the
  /// device moved to the new tool's free starting pose). toolChanged() follows.
  void selectTool(int choice_index, double point_spacing_m = 0.0);
  const std::vector<ToolChoice>& toolChoices() const noexcept { return tools_; }
  int currentToolIndex() const noexcept { return tool_index_; }
  /// Drives `device` instead of the current one (a device picker plugs in here): the haptic
  /// thread is rebuilt with the current tool at the proxy's current pose. Null: no haptics.
  /// `limits_text` describes the device's limits for the haptics panel (empty: from the device).
  void setDevice(std::shared_ptr<runtime::Device> device, const QString& limits_text = {});
  runtime::Device* device() const noexcept { return scene_.device.get(); }

  // ---- Device picker (Haptics > Device and the Haptics dock's Device group) -------------------
  /// Lists the devices again (DeviceCatalog::enumerate(); never throws): entry 0 is the
  /// simulated device, then one entry per device found. Problems go to the picker's tooltip
  /// and the status bar.
  void rescanDevices();
  /// The picker's entries: "Simulated device (mouse/keyboard)", then FoundDevice::label()s.
  QStringList deviceChoices() const;
  /// The entry in use; -1 when the device is none of them (e.g. named by the scene file).
  int currentDeviceChoice() const noexcept { return device_choice_; }
  /// Switches to entry `index`: 0 a SimulatedDevice at the proxy's pose; a hardware entry is
  /// opened mapped around the scene's initial tool pose and wrapped in a FallbackDevice (a
  /// Falcon asks for its firmware file once, remembered in QSettings). On failure the current
  /// device stays and the message is shown (dialog when interactive, else stderr).
  /// @return true when the device was switched.
  bool chooseDevice(int index);
  /// The last device error, empty when none.
  QString lastDeviceError() const { return last_device_error_; }
  QMenu* deviceMenu() const noexcept { return device_menu_; }

  /// Sets the isovalue (data units, clamped to the data range) of the rendered isosurface, the
  /// haptic thread and the widgets.
  void setIsovalue(double isovalue);
  double isovalue() const noexcept { return isovalue_; }

  /// Moves the simulated device (no effect without one).
  void setDevicePose(const haptics::Pose& X_WD);
  /// Scripted touch (see AppOptions::touch): moves the simulated device from its current pose
  /// towards the volume's centre until the tool's point shell meets the isosurface, then
  /// `depth_m` [m] further, so the proxy rests on the surface and a contact force shows. Where
  /// the central ray meets nothing, parallel rays on rings around it are tried (the device then
  /// goes sideways first and in 0.3 s later).
  /// @return false when there is no simulated device or no ray meets the surface.
  bool touchSurface(double depth_m);

  /// Reads the haptic thread's latest snapshot now and updates the props, the strip chart and
  /// the status bar (the display timer calls this; the status text changes at most every
  /// ~200 ms unless `update_status_now`). @return true when something visible changed.
  bool refreshFromHaptics(bool update_status_now = false);

  // ---- Viewing -------------------------------------------------------------------------------
  void setRenderMode(RenderMode mode);
  RenderMode renderMode() const noexcept { return prefs_.mode; }
  void setPreset(VolumePreset preset);
  VolumePreset preset() const noexcept { return prefs_.preset; }
  /// Resets the camera to the default view of the volume and tools (from anterior-left-above).
  void resetCamera();
  /// Keeps the viewing direction and moves the camera close to the tool (its proxy), so the
  /// contacts and the force arrow are seen in detail.
  void focusOnTool();
  /// Looks at the volume from a standard direction (patient LPS), fitted to the props.
  void setStandardView(StandardView view);
  /// Clips the volume (visual only) with a plane normal to `axis` at `fraction` (0..1) of the
  /// volume's extent along it; `flip` keeps the lower side instead of the upper.
  void setClipping(bool enabled, ClipAxis axis = ClipAxis::kX, double fraction = 0.5, bool flip = false);
  void setOrientationMarkerVisible(bool visible);
  void setDeviceToolVisible(bool visible);
  /// Colours from the preferences (background gradient, surface, tool, device) applied now.
  void applyColours();
  /// Ends interactive (reduced) rendering now and asks for a full-quality frame; used before
  /// screenshots. Interactive frames are used while the camera is dragged, the tools move or
  /// the isovalue slider is dragged, and end by themselves 300 ms after the last motion.
  /// @param best_quality also resets the still quality to the best level (screenshots).
  void renderStill(bool best_quality = false);
  /// A PNG of the whole window (the view composited in). @return false when it cannot be written.
  bool saveScreenshot(const QString& path);

  // ---- Preferences ---------------------------------------------------------------------------
  const Preferences& preferences() const noexcept { return prefs_; }
  Preferences& preferences() noexcept { return prefs_; }
  /// Writes the preferences, window geometry and dock layout to QSettings.
  void saveSettings() const;
  /// Restores the window geometry and dock layout saved by saveSettings() (if any).
  void restoreLayout();

  // ---- Access for tests and scripting --------------------------------------------------------
  VtkView* view() const noexcept { return view_; }
  QSlider* isovalueSlider() const noexcept;
  HistogramSlider* histogramSlider() const noexcept { return slider_; }
  QDoubleSpinBox* isovalueSpinBox() const noexcept { return spin_; }
  HapticsPanel* hapticsPanel() const noexcept { return haptics_panel_; }
  StripChart* stripChart() const noexcept { return chart_; }
  SceneLoader* loader() const noexcept { return loader_; }
  /// The banner listing what the loader corrected or chose (Help > Load Notes).
  LoadNoticePanel* loadNotices() const noexcept { return notices_; }
  runtime::HapticThread* hapticThread() const noexcept { return scene_.haptics.get(); }
  const ViewerScene& scene() const noexcept { return scene_; }
  /// The simulated device, or null (no device, or a scripted/hardware one).
  runtime::SimulatedDevice* simulatedDevice() const noexcept;
  /// The scene's props; only while hasScene().
  SceneActors& actors() const noexcept { return *actors_; }
  OrientationMarker* orientationMarker() const noexcept { return marker_.get(); }
  vtkVolume* volumeProp() const noexcept;
  vtkActor* proxyActor() const noexcept;
  vtkActor* deviceActor() const noexcept;
  /// Text of the status bar's statistics.
  QString statusText() const;
  /// The last snapshot read from the haptic thread (default-constructed before the first).
  const runtime::HapticSnapshot& lastSnapshot() const noexcept { return snapshot_; }
  QMenu* recentFilesMenu() const noexcept { return recent_menu_; }

  // ---- Recordings (session_recorder.h, replay_panel.h) ---------------------------------------
  /// Haptics > Record Session, Add Marker and the recording's status.
  SessionRecorder* recorder() const noexcept { return recorder_; }
  /// File > Open Recording, the Replay dock, File > Export Recording.
  ReplayController* replay() const noexcept { return replay_; }
  /// The scene shown, as a runtime::LoadedScene (spec with the current tool, gains and
  /// isovalue; volume, tool and initial pose): what a recording's metadata describes.
  runtime::LoadedScene currentLoadedScene() const;

 signals:
  /// A load finished and its scene is shown.
  void sceneLoaded();
  /// A load failed: `message` names the file and the problem; the previous scene is kept.
  void loadFailed(const QString& message);
  /// A new tool is in use (selectTool()).
  void toolChanged();

 protected:
  void closeEvent(QCloseEvent* event) override;
  bool eventFilter(QObject* watched, QEvent* event) override;
  void dragEnterEvent(QDragEnterEvent* event) override;
  void dropEvent(QDropEvent* event) override;

 private:
  friend class SessionRecorder;
  friend class ReplayController;

  enum class DragMode { kNone, kTranslate, kDepth, kRotate };

  void buildUi();
  void buildMenus();
  void buildDocks();
  void connectLoader();
  void installScene();  // (re)creates the props and refreshes the widgets for scene_
  void teardownScene(); // stops haptics and removes the props
  void onSceneLoaded(std::shared_ptr<LoadedViewerScene> loaded);
  void onToolBuilt(std::shared_ptr<RebuiltTool> tool);
  void onSeriesListed(const QString& folder, const std::vector<io::DicomSeriesInfo>& series);
  void showLoadNotices();  // scene_'s io::VolumeInfo::notices: banner, status bar, console
  void reportError(const QString& what, const QString& message);
  void showProgress(const QString& stage, int percent, bool cancellable);
  void hideProgress();
  void rebuildRecentMenu();
  void openDicomFolderDialog();
  void openVolumeFileDialog();
  void openSceneFileDialog();
  void chooseColour(QColor Preferences::*field, const QString& title);
  void updateClipFromWidgets();
  void updateHint();
  void updateHapticsPanel();
  void updateWindowTitle();
  void onSliderMoved(int position);
  void onSpinChanged(double value);
  void updateStatus();
  void noteMotion();  // switches to interactive frames until the motion settles
  bool handleDeviceKey(QKeyEvent* event);
  ViewCamera currentCamera() const;
  double sliderToValue(int position) const;
  int valueToSlider(double value) const;
  double wheelStep_m() const;
  void fitCamera(const double direction_W[3], const double up_W[3], double zoom);
  void setUpDevicePicker();
  void showDeviceChoices();  // the found devices into the menu and the panel
  void syncDeviceChoice();   // the entry of the device in use
  void pollHotplug();

  ViewerScene scene_;
  Preferences prefs_;
  double value_min_ = 0.0;
  double value_max_ = 1.0;
  double isovalue_ = 0.0;
  haptics::CouplingGains gains_;
  std::vector<ToolChoice> tools_;
  int tool_index_ = -1;
  std::unique_ptr<SceneActors> actors_;
  std::unique_ptr<OrientationMarker> marker_;
  vtkTextActor* welcome_ = nullptr;  // owned by the renderer while shown
  VtkView* view_ = nullptr;
  SceneLoader* loader_ = nullptr;
  LoadNoticePanel* notices_ = nullptr;
  HistogramSlider* slider_ = nullptr;
  QDoubleSpinBox* spin_ = nullptr;
  QLabel* iso_label_ = nullptr;
  QComboBox* mode_box_ = nullptr;
  QComboBox* preset_box_ = nullptr;
  QCheckBox* marker_box_ = nullptr;
  QCheckBox* device_box_ = nullptr;
  QGroupBox* clip_group_ = nullptr;
  QComboBox* clip_axis_ = nullptr;
  QSlider* clip_position_ = nullptr;
  QCheckBox* clip_flip_ = nullptr;
  HapticsPanel* haptics_panel_ = nullptr;
  StripChart* chart_ = nullptr;
  QDockWidget* display_dock_ = nullptr;
  QDockWidget* haptics_dock_ = nullptr;
  QDockWidget* chart_dock_ = nullptr;
  QLabel* status_label_ = nullptr;
  QWidget* progress_box_ = nullptr;
  QLabel* progress_label_ = nullptr;
  QProgressBar* progress_bar_ = nullptr;
  QToolButton* progress_cancel_ = nullptr;
  QMenu* recent_menu_ = nullptr;
  QAction* haptics_action_ = nullptr;
  QActionGroup* mode_actions_ = nullptr;
  QActionGroup* preset_actions_ = nullptr;
  QAction* marker_action_ = nullptr;
  QAction* clip_action_ = nullptr;
  QAction* device_action_ = nullptr;
  QTimer* display_timer_ = nullptr;
  QTimer* settle_timer_ = nullptr;
  QElapsedTimer clock_;  // strip chart time base
  bool camera_interacting_ = false;
  bool slider_dragging_ = false;
  bool interactive_ = true;
  bool auto_start_haptics_ = true;
  bool upload_pending_ = false;  // a new scene waits for its first frame (GPU upload)
  std::uint64_t upload_frame_ = 0;
  QString last_error_;
  QString device_limits_text_;
  std::shared_ptr<devices::DeviceCatalog> catalog_;
  std::unique_ptr<devices::HotplugMonitor> hotplug_;
  std::vector<devices::FoundDevice> found_;
  std::vector<std::string> device_problems_;
  std::shared_ptr<runtime::Device> picked_device_;  // the hardware device the picker opened
  int picked_index_ = -1;                           // its entry
  int device_choice_ = -1;
  QString last_device_error_;
  QMenu* device_menu_ = nullptr;
  QActionGroup* device_actions_ = nullptr;
  QTimer* hotplug_timer_ = nullptr;
  runtime::HapticSnapshot snapshot_;
  bool have_snapshot_ = false;
  haptics::Pose shown_X_WP_;
  haptics::Pose shown_X_WD_;
  int shown_contacts_ = -1;
  Eigen::Vector3d shown_force_W_N_ = Eigen::Vector3d::Zero();
  int status_countdown_ = 0;
  DragMode drag_ = DragMode::kNone;
  QPointF drag_last_;
  SessionRecorder* recorder_ = nullptr;  // child QObjects
  ReplayController* replay_ = nullptr;
};

}  // namespace vh::ui
