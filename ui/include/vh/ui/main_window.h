#pragma once
/// @file
/// The main window: the VTK view (isosurface, proxy and device tools, contacts, force), an
/// isovalue slider + spin box in the data's units, and a status bar with the servo statistics.
///
/// Threads: everything here runs on the GUI thread. The haptic thread is read only through
/// HapticThread::latestSnapshot() (never blocks) on a display timer (~30 Hz), and written only
/// through its command setters (setIsovalue()) and SimulatedDevice::setPose().

#include <memory>
#include <optional>
#include <string>

#include <QMainWindow>
#include <QPoint>
#include <QString>

#include "vh/haptics/pose.h"
#include "vh/haptics/tool_model.h"
#include "vh/io/volume_loader.h"
#include "vh/runtime/haptic_thread.h"

class QCloseEvent;
class QDoubleSpinBox;
class QLabel;
class QSlider;
class QTimer;
class vtkActor;
class vtkVolume;

namespace vh::runtime {
class Device;
class SimulatedDevice;
}  // namespace vh::runtime

namespace vh::ui {

class SceneActors;
class VtkView;
struct ViewCamera;

/// What the main window shows and drives; built by runApplication() (or a test).
struct ViewerScene {
  io::LoadedVolume volume;                          ///< Field + image (metres, data units); image required.
  std::shared_ptr<const haptics::ToolModel> tool;   ///< Tool (display mesh, point shell, mass).
  double isovalue = 0.0;                            ///< Initial isovalue (data units).
  haptics::Pose X_WT_initial;                       ///< Initial proxy/device pose in W [m].
  std::shared_ptr<runtime::Device> device;          ///< Null: no device (haptics off).
  std::unique_ptr<runtime::HapticThread> haptics;   ///< Null: no haptic thread. Not started yet.
  std::string title;                                ///< Window title detail (e.g. file name).
};

class MainWindow : public QMainWindow {
  Q_OBJECT

 public:
  /// @throws std::invalid_argument when the scene's volume has no image.
  explicit MainWindow(ViewerScene scene, QWidget* parent = nullptr);
  ~MainWindow() override;  ///< Stops the haptic thread before any VTK object goes away.

  /// Starts the haptic thread (when the scene has one) and the display timer.
  void startHaptics();
  /// Stops the haptic thread: the force is ramped to zero, then the thread joins. Idempotent.
  void stopHaptics();

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

  /// Reads the haptic thread's latest snapshot now and updates the props and the status bar
  /// (the display timer calls this; the status text changes at most every ~200 ms unless
  /// `update_status_now`). @return true when something visible changed.
  bool refreshFromHaptics(bool update_status_now = false);
  /// Resets the camera to the default view of the volume and tools.
  void resetCamera();
  /// Ends interactive (reduced) rendering now and asks for a full-quality frame; used before
  /// screenshots. Interactive frames are used while the camera is dragged, the tools move or
  /// the isovalue slider is dragged, and end by themselves 300 ms after the last motion.
  /// @param best_quality also resets the still quality to the best level (screenshots).
  void renderStill(bool best_quality = false);

  VtkView* view() const noexcept { return view_; }
  QSlider* isovalueSlider() const noexcept { return slider_; }
  QDoubleSpinBox* isovalueSpinBox() const noexcept { return spin_; }
  runtime::HapticThread* hapticThread() const noexcept { return scene_.haptics.get(); }
  /// The simulated device, or null (no device, or a scripted/hardware one).
  runtime::SimulatedDevice* simulatedDevice() const noexcept;
  SceneActors& actors() const noexcept { return *actors_; }
  vtkVolume* volumeProp() const noexcept;
  vtkActor* proxyActor() const noexcept;
  vtkActor* deviceActor() const noexcept;
  /// Text of the status bar's statistics.
  QString statusText() const;
  /// The last snapshot read from the haptic thread (default-constructed before the first).
  const runtime::HapticSnapshot& lastSnapshot() const noexcept { return snapshot_; }

 protected:
  void closeEvent(QCloseEvent* event) override;
  bool eventFilter(QObject* watched, QEvent* event) override;

 private:
  enum class DragMode { kNone, kTranslate, kDepth, kRotate };

  void buildUi();
  void onSliderMoved(int position);
  void onSpinChanged(double value);
  void updateStatus();
  void noteMotion();  // switches to interactive frames until the motion settles
  ViewCamera currentCamera() const;
  double sliderToValue(int position) const;
  int valueToSlider(double value) const;
  double wheelStep_m() const;

  ViewerScene scene_;
  double value_min_ = 0.0;
  double value_max_ = 1.0;
  double isovalue_ = 0.0;
  std::unique_ptr<SceneActors> actors_;
  VtkView* view_ = nullptr;
  QSlider* slider_ = nullptr;
  QDoubleSpinBox* spin_ = nullptr;
  QLabel* status_label_ = nullptr;
  QTimer* display_timer_ = nullptr;
  QTimer* settle_timer_ = nullptr;
  bool camera_interacting_ = false;
  bool slider_dragging_ = false;
  runtime::HapticSnapshot snapshot_;
  bool have_snapshot_ = false;
  haptics::Pose shown_X_WP_;
  haptics::Pose shown_X_WD_;
  int shown_contacts_ = -1;
  Eigen::Vector3d shown_force_W_N_ = Eigen::Vector3d::Zero();
  int status_countdown_ = 0;
  DragMode drag_ = DragMode::kNone;
  QPointF drag_last_;
};

}  // namespace vh::ui
