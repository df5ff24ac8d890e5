#pragma once
/// @file
/// The mouse and keyboard as a 6-DOF device: when the session's device is a simulated one
/// (runtime::Session::simulatedDevice()), drags and keys in the view move it (Ctrl+left drag in
/// the view plane, Ctrl+wheel / Ctrl+right drag in depth, Shift+left drag rotates about the
/// tool's centre; arrows, Page Up / Down, Shift+arrows, Home), and touchSurface() brings the
/// tool onto the surface. Plain drags stay the camera's. The [ and ] keys step the isovalue with
/// or without a device. GUI thread only.

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
  /// Brings the simulated device onto the surface from outside the volume: along the view
  /// direction through the volume's centre, from a start outside the volume's bounding box, until
  /// the tool's point shell meets the isosurface, then `depth_m` [m] further; where that ray
  /// meets nothing, parallel rays on rings around it are tried. With the haptic threads running
  /// the device goes there in steps the proxy can follow through free space (out of the box the
  /// shortest free way, round it, to the start, in), each once the proxy caught up, stood still
  /// for 100 ms (held by the surface) or after 1.5 s; without them it goes to the end at once.
  /// @return false without a simulated device or when no ray meets the surface.
  bool touchSurface(double depth_m);
  /// Whether a touchSurface() is still leading the device in steps.
  bool touchInProgress() const;
  /// One step of the device's keyboard motion and of the mouse wheel [m]: 1/200 of the volume's
  /// diagonal, 0.5 to 5 mm.
  double wheelStep_m() const;

 signals:
  /// [ (-1) or ] (+1) was pressed in the view.
  void isovalueStepRequested(int direction);

 protected:
  bool eventFilter(QObject* watched, QEvent* event) override;

 private:
  enum class DragMode { kNone, kTranslate, kDepth, kRotate };
  bool handleKey(QKeyEvent* event);

  runtime::Session& session_;
  SceneView& view_;
  DragMode drag_ = DragMode::kNone;
  QPointF drag_last_;
};

}  // namespace vh::ui
