#include "vh/ui/devices/device_input.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <string>
#include <numbers>
#include <optional>
#include <limits>
#include <memory>
#include <utility>
#include <vector>

#include <QEvent>
#include <QKeyEvent>
#include <QMouseEvent>
#include <QWheelEvent>

#include "vh/runtime/drilling.h"
#include "vh/runtime/placement.h"
#include "vh/ui/view/device_manipulation.h"
#include "vh/ui/view/scene_view.h"
#include "vh/ui/view/vtk_view.h"

namespace vh::ui {
namespace {

constexpr double kKeyRotation_rad = 5.0 * std::numbers::pi / 180.0;

const char* const kHintCamera = "Camera: left drag rotate | middle drag pan | right drag / wheel zoom";
const char* const kHintDevice =
    "Device: Ctrl+left drag move in view plane | Ctrl+wheel or Ctrl+right drag move in depth\n"
    "        Shift+left drag rotate | Ctrl+Shift+click touch the surface there\n"
    "        keys (click the view): arrows, PgUp/PgDn, Shift+arrows, Home";

const char* const kControlsHtml =
    "<h3>Mouse in the view</h3><table cellpadding='2'>"
    "<tr><td>left drag</td><td>rotate the camera</td></tr>"
    "<tr><td>middle drag / right drag or wheel</td><td>pan / zoom the camera</td></tr>"
    "<tr><td>Ctrl + left drag</td><td>move the simulated device in the view plane</td></tr>"
    "<tr><td>Ctrl + wheel, Ctrl + right drag</td><td>move the device along the view direction</td></tr>"
    "<tr><td>Shift + left drag</td><td>rotate the device about the tool's centre</td></tr>"
    "<tr><td>Ctrl + Shift + click</td><td>touch the surface under the cursor (the tool comes to rest on it; a "
    "drill turns its burr onto it first)</td></tr></table>"
    "<h3>Keys (click the view first)</h3><table cellpadding='2'>"
    "<tr><td>arrows</td><td>move the device in the view plane</td></tr>"
    "<tr><td>Page Up / Page Down</td><td>move the device away / towards you</td></tr>"
    "<tr><td>Shift + arrows</td><td>rotate the device by 5&deg;</td></tr>"
    "<tr><td>Home</td><td>device back to its starting pose</td></tr>"
    "<tr><td>[ and ]</td><td>isovalue down / up one step</td></tr></table>"
    "<p>The solid tool is the proxy, which stays on the surface; the wire tool is the device. "
    "The yellow arrow is the force on your hand, red dots are the contacts.</p>";


/// The drill's burr centre in T [m] when the tool is a drill (the scene's drill settings, or a
/// mesh named as a drill before its burr was first switched on): Touch the Surface then turns
/// the burr onto the surface, since only the burr cuts. nullopt for another tool.
std::optional<Eigen::Vector3d> burrCentre_T(const runtime::LiveValues& scene) {
  if (scene.tool == nullptr) return std::nullopt;
  std::string name = std::filesystem::path(scene.tool_spec.mesh).filename().string();
  std::transform(name.begin(), name.end(), name.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  if (!scene.drill && name.find("drill") == std::string::npos) return std::nullopt;
  try {
    return runtime::burrOf(*scene.tool, scene.drill.value_or(runtime::DrillSpec{})).center_T_m;
  } catch (const std::invalid_argument&) {  // no burr to point: the tool is placed as it is held
    return std::nullopt;
  }
}

}  // namespace

DeviceInput::DeviceInput(runtime::Session& session, SceneView& view)
    : QObject(&view), session_(session), view_(view) {
  view_.widget()->installEventFilter(this);
}

std::string DeviceInput::hint(const runtime::Session& session) {
  std::string hint = kHintCamera;
  if (session.simulatedDevice() != nullptr && session.hapticThread() != nullptr) {
    hint += std::string("\n") + kHintDevice;
  } else if (session.device() != nullptr) {
    hint += "\nDevice: " + session.device()->name();
  } else {
    hint += "\nNo device in this scene: haptics off";
  }
  return hint;
}

QString DeviceInput::controlsHtml() { return QString::fromUtf8(kControlsHtml); }

void DeviceInput::setDevicePose(const haptics::Pose& X_WD) {
  runtime::SimulatedDevice* device = session_.simulatedDevice();
  if (device == nullptr || !X_WD.allFinite() || !session_.hasScene()) return;
  device->setPose(X_WD);
  view_.showDevicePose(X_WD);  // the proxy follows with the next snapshot
}

void DeviceInput::place(const haptics::Pose& X_WP, const haptics::Pose& X_WD) {
  runtime::SimulatedDevice* device = session_.simulatedDevice();
  if (device == nullptr || !X_WP.allFinite() || !X_WD.allFinite() || !session_.hasScene()) return;
  runtime::HapticThread* thread = session_.hapticThread();
  if (thread != nullptr) {
    const std::uint64_t applied = thread->placementsApplied();
    if (thread->place(X_WP, X_WD) && thread->running()) {
      awaited_thread_ = thread;
      awaited_placements_ = applied + 1;
    }
  } else {
    device->setPose(X_WD);
  }
  view_.showDevicePose(X_WD);  // the proxy shows with the next snapshot
}

bool DeviceInput::touchSurface(double depth_m) {
  runtime::SimulatedDevice* device = session_.simulatedDevice();
  const runtime::LiveValues& scene = session_.live();
  if (device == nullptr || scene.tool == nullptr || scene.hapticField() == nullptr) return false;
  // The surface the hand feels: the felt segments' when some are felt (aimed at, wherever they
  // lie in the volume), else the scan's (aimed at the volume's centre: the surface the user sees
  // in front of it).
  const haptics::ScalarVolume& field = *scene.hapticField();
  const double isovalue = scene.hapticIsovalue();
  Eigen::Vector3d aim_W = 0.5 * (field.boundsMin_W_m() + field.boundsMax_W_m());
  if (scene.feltSegments()) {
    if (const std::optional<Eigen::Vector3d> c_W = runtime::insideBoxCentre_W(field, isovalue)) aim_W = *c_W;
  }
  Eigen::Vector3d dir_W = view_.camera().forward_W();
  if (!dir_W.allFinite() || dir_W.norm() < 0.5) dir_W = Eigen::Vector3d::UnitY();  // from anterior (LPS)
  std::optional<runtime::SurfaceTouch> touch;
  if (const std::optional<Eigen::Vector3d> burr_T = burrCentre_T(scene))  // a drill: burr first
    touch = runtime::touchSurfaceTipFirst(field, scene.tool->point_shell, scene.tool->mass.p_TCm_m, *burr_T,
                                          device->pose().R_AB, dir_W, aim_W, isovalue, depth_m);
  if (!touch)
    touch = runtime::touchSurfacePose(field, scene.tool->point_shell, scene.tool->mass.p_TCm_m, device->pose().R_AB,
                                      dir_W, aim_W, isovalue, depth_m);
  if (!touch) return false;
  place(touch->X_WP, touch->X_WD);
  return true;
}

bool DeviceInput::touchSurfaceAt(const QPointF& pos_px, double depth_m) {
  runtime::SimulatedDevice* device = session_.simulatedDevice();
  const runtime::LiveValues& scene = session_.live();
  if (device == nullptr || scene.tool == nullptr || scene.hapticField() == nullptr) return false;
  const double ratio = view_.widget() != nullptr ? view_.widget()->devicePixelRatioF() : 1.0;
  const ViewRay ray = rayThroughPixel(view_.camera(), pos_px.x() * ratio, pos_px.y() * ratio);
  std::optional<runtime::SurfaceTouch> touch;
  if (const std::optional<Eigen::Vector3d> burr_T = burrCentre_T(scene))  // a drill: burr first
    touch = runtime::touchSurfaceTipFirst(*scene.hapticField(), scene.tool->point_shell, scene.tool->mass.p_TCm_m,
                                          *burr_T, device->pose().R_AB, ray.dir_W, ray.origin_W_m,
                                          scene.hapticIsovalue(), depth_m);
  if (!touch)
    touch = runtime::touchSurfacePoseOnLine(*scene.hapticField(), scene.tool->point_shell, scene.tool->mass.p_TCm_m,
                                            device->pose().R_AB, ray.dir_W, ray.origin_W_m, scene.hapticIsovalue(),
                                            depth_m);
  if (!touch) return false;
  place(touch->X_WP, touch->X_WD);
  return true;
}

bool DeviceInput::touchInProgress() const {
  const runtime::HapticThread* thread = session_.hapticThread();
  return thread != nullptr && thread == awaited_thread_ && thread->running() &&
         thread->placementsApplied() < awaited_placements_;
}

double DeviceInput::wheelStep_m() const {
  const auto& field = session_.live().scan_field;
  if (field == nullptr) return 1e-3;
  const double diagonal = (field->boundsMax_W_m() - field->boundsMin_W_m()).norm();
  return std::clamp(diagonal / 200.0, 0.5e-3, 5e-3);
}

bool DeviceInput::handleKey(QKeyEvent* e) {
  // Isovalue steps work with or without a device.
  if (e->key() == Qt::Key_BracketLeft || e->key() == Qt::Key_BracketRight) {
    emit isovalueStepRequested(e->key() == Qt::Key_BracketRight ? 1 : -1);
    return true;
  }
  runtime::SimulatedDevice* device = session_.simulatedDevice();
  if (device == nullptr) return false;
  const auto& tool = session_.live().tool;
  const Eigen::Vector3d p_DCm = tool != nullptr ? tool->mass.p_TCm_m : Eigen::Vector3d::Zero();
  const ViewCamera camera = view_.camera();
  const haptics::Pose X_WD = device->pose();
  const bool shift = e->modifiers() & Qt::ShiftModifier;
  const double step_m = wheelStep_m();
  const double px = step_m / std::max(1e-12, camera.metresPerPixelAt(X_WD * p_DCm));
  double dx = 0.0, dy = 0.0;
  switch (e->key()) {
    case Qt::Key_Left: dx = -1.0; break;
    case Qt::Key_Right: dx = 1.0; break;
    case Qt::Key_Up: dy = -1.0; break;
    case Qt::Key_Down: dy = 1.0; break;
    case Qt::Key_PageUp:
      setDevicePose(moveAlongView(X_WD, camera, step_m));
      return true;
    case Qt::Key_PageDown:
      setDevicePose(moveAlongView(X_WD, camera, -step_m));
      return true;
    case Qt::Key_Home:  // a placement: the proxy and the device together
      place(session_.live().X_WT_initial, session_.live().X_WT_initial);
      return true;
    default:
      return false;
  }
  if (shift) {
    setDevicePose(rotateTrackball(X_WD, camera, p_DCm, dx, dy, kKeyRotation_rad));
  } else {
    setDevicePose(dragInViewPlane(X_WD, camera, X_WD * p_DCm, dx * px, dy * px));
  }
  return true;
}

bool DeviceInput::eventFilter(QObject* watched, QEvent* event) {
  VtkView* widget = view_.widget();
  if (watched != widget || !session_.hasScene()) return false;
  if (event->type() == QEvent::KeyPress) return handleKey(static_cast<QKeyEvent*>(event));
  runtime::SimulatedDevice* device = session_.simulatedDevice();
  if (device == nullptr) return false;
  const auto& tool = session_.live().tool;
  const Eigen::Vector3d p_DCm = tool != nullptr ? tool->mass.p_TCm_m : Eigen::Vector3d::Zero();
  switch (event->type()) {
    case QEvent::MouseButtonPress: {
      auto* e = static_cast<QMouseEvent*>(event);
      const bool ctrl = e->modifiers() & Qt::ControlModifier;
      const bool shift = e->modifiers() & Qt::ShiftModifier;
      if (ctrl && shift && e->button() == Qt::LeftButton) {
        if (!touchSurfaceAt(e->position(), kTouchDepth_m)) emit message(tr("No surface under the cursor to touch"), 4000);
        return true;
      }
      if (ctrl && e->button() == Qt::LeftButton) {
        drag_ = DragMode::kTranslate;
      } else if (ctrl && e->button() == Qt::RightButton) {
        drag_ = DragMode::kDepth;
      } else if (shift && !ctrl && e->button() == Qt::LeftButton) {
        drag_ = DragMode::kRotate;
      } else {
        return false;  // the camera's
      }
      drag_last_ = e->position();
      widget->setCursor(drag_ == DragMode::kRotate ? Qt::ClosedHandCursor : Qt::SizeAllCursor);
      return true;
    }
    case QEvent::MouseMove: {
      if (drag_ == DragMode::kNone) return false;
      auto* e = static_cast<QMouseEvent*>(event);
      const QPointF delta = (e->position() - drag_last_) * widget->devicePixelRatioF();
      drag_last_ = e->position();
      const ViewCamera camera = view_.camera();
      const haptics::Pose X_WD = device->pose();
      switch (drag_) {
        case DragMode::kTranslate:
          setDevicePose(dragInViewPlane(X_WD, camera, X_WD * p_DCm, delta.x(), delta.y()));
          break;
        case DragMode::kDepth:
          setDevicePose(moveAlongView(X_WD, camera, -delta.y() * camera.metresPerPixelAt(X_WD * p_DCm)));
          break;
        case DragMode::kRotate:
          setDevicePose(rotateTrackball(X_WD, camera, p_DCm, delta.x(), delta.y(),
                                        std::numbers::pi / camera.viewport_height_px));
          break;
        case DragMode::kNone:
          break;
      }
      return true;
    }
    case QEvent::MouseButtonRelease: {
      if (drag_ == DragMode::kNone) return false;
      drag_ = DragMode::kNone;
      widget->unsetCursor();
      return true;
    }
    case QEvent::MouseButtonDblClick:
      return drag_ != DragMode::kNone;
    case QEvent::Wheel: {
      auto* e = static_cast<QWheelEvent*>(event);
      if (!(e->modifiers() & Qt::ControlModifier)) return false;
      const double notches = e->angleDelta().y() / 120.0;
      setDevicePose(moveAlongView(device->pose(), view_.camera(), notches * wheelStep_m()));
      return true;
    }
    default:
      return false;
  }
}

}  // namespace vh::ui
