#pragma once
/// @file
/// The mouse and keyboard as a 6-DOF device: when the session's device is a simulated one
/// (runtime::Session::simulatedDevice()), drags and keys in the view move it (Ctrl+left drag in
/// the view plane, Ctrl+wheel / Ctrl+right drag in depth, Shift+left drag rotates about the
/// tool's centre; arrows, Page Up / Down, Shift+arrows, Home), touchSurface() brings the tool
/// onto the surface, and Ctrl+Shift+click (touchSurfaceAt()) onto the surface under the cursor. Plain drags stay the camera's. The [ and ] keys step the isovalue with
/// or without a device. GUI thread only.

#include <cstdint>
#include <string>

#include <QObject>
#include <QPointF>
#include <QString>

#include "vh/haptics/pose.h"
#include "vh/runtime/session.h"

class QKeyEvent;

namespace vh::ui {

class SceneView;

class DeviceInput : public QObject {
  Q_OBJECT

 public:
  /// How far past the first contact Touch the Surface puts the device [m]: a resting force of
  /// a few newtons at the usual stiffness, nothing more.
  static constexpr double kTouchDepth_m = 0.003;

  /// Filters the events of `view`'s widget; `session` and `view` must outlive it.
  DeviceInput(runtime::Session& session, SceneView& view);

  /// The view's overlay: the camera's mouse controls, then the device's (with a simulated
  /// device), the device's name (another device) or "haptics off" (none).
  static std::string hint(const runtime::Session& session);
  /// Help > Controls: every mouse and key binding of the view (rich text).
  static QString controlsHtml();

  /// Moves the simulated device to `X_WD` [m] and shows it at once (no effect without one, or
  /// for a non-finite pose).
  void setDevicePose(const haptics::Pose& X_WD);
  /// A placement: the proxy to `X_WP` and the simulated device to `X_WD` [m, W] together
  /// (runtime::HapticThread::place(): no spring stretched over the jump, recorded as a
  /// "placement", not as the hand's motion); without haptic threads only the device moves. No
  /// effect without a simulated device or for a non-finite pose.
  void place(const haptics::Pose& X_WP, const haptics::Pose& X_WD);
  /// Touch the Surface, as a placement: the tool approaches along the view direction
  /// (runtime::touchSurfacePose()) aimed at the felt segments when some are felt (the centre of
  /// their box), else at the volume's centre, from outside the volume; the proxy is put where
  /// its point shell first meets the felt isosurface and the device `depth_m` [m] further in,
  /// so the hand feels the resting force at once and nothing more. A drill (the scene's drill
  /// settings, or a drill's mesh) is turned first so that its burr points into the surface
  /// where the line of sight meets it, and approaches along that axis
  /// (runtime::touchSurfaceTipFirst()): the burr, the only part that cuts, is what touches.
  /// @return false without a simulated device or when no approach meets the surface.
  bool touchSurface(double depth_m);
  /// Touch the Surface at the point the user picks, as a placement: the tool's centre of mass
  /// moves along the line of sight through the view's pixel `pos_px` (widget pixels, y down;
  /// rayThroughPixel()) until its point shell meets the felt isosurface
  /// (runtime::touchSurfacePoseOnLine()), and the device `depth_m` [m] further along it; a drill
  /// is turned burr first onto that point, as in touchSurface().
  /// @return false without a simulated device or when the line of sight meets no surface (the
  /// tool stays where it was).
  bool touchSurfaceAt(const QPointF& pos_px, double depth_m);
  /// Whether the last placement has not yet reached the running haptic threads' solver.
  bool touchInProgress() const;
  /// One step of the device's keyboard motion and of the mouse wheel [m]: 1/200 of the volume's
  /// diagonal, 0.5 to 5 mm.
  double wheelStep_m() const;

 signals:
  /// [ (-1) or ] (+1) was pressed in the view.
  void isovalueStepRequested(int direction);
  /// A line for the status bar (e.g. a pick that met no surface).
  void message(const QString& text, int timeout_ms);

 protected:
  bool eventFilter(QObject* watched, QEvent* event) override;

 private:
  enum class DragMode { kNone, kTranslate, kDepth, kRotate };
  bool handleKey(QKeyEvent* event);

  runtime::Session& session_;
  SceneView& view_;
  DragMode drag_ = DragMode::kNone;
  QPointF drag_last_;
  const runtime::HapticThread* awaited_thread_ = nullptr;  // the threads of the last placement
  std::uint64_t awaited_placements_ = 0;                    // placementsApplied() once it is in
};

}  // namespace vh::ui
