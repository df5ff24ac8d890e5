#include "vh/ui/devices/device_input.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <optional>
#include <limits>
#include <memory>
#include <utility>
#include <vector>

#include <QEvent>
#include <QKeyEvent>
#include <QMouseEvent>
#include <QTimer>
#include <QWheelEvent>

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
    "        Shift+left drag rotate | keys (click the view): arrows, PgUp/PgDn, Shift+arrows, Home";

const char* const kControlsHtml =
    "<h3>Mouse in the view</h3><table cellpadding='2'>"
    "<tr><td>left drag</td><td>rotate the camera</td></tr>"
    "<tr><td>middle drag / right drag or wheel</td><td>pan / zoom the camera</td></tr>"
    "<tr><td>Ctrl + left drag</td><td>move the simulated device in the view plane</td></tr>"
    "<tr><td>Ctrl + wheel, Ctrl + right drag</td><td>move the device along the view direction</td></tr>"
    "<tr><td>Shift + left drag</td><td>rotate the device about the tool's centre</td></tr></table>"
    "<h3>Keys (click the view first)</h3><table cellpadding='2'>"
    "<tr><td>arrows</td><td>move the device in the view plane</td></tr>"
    "<tr><td>Page Up / Page Down</td><td>move the device away / towards you</td></tr>"
    "<tr><td>Shift + arrows</td><td>rotate the device by 5&deg;</td></tr>"
    "<tr><td>Home</td><td>device back to its starting pose</td></tr>"
    "<tr><td>[ and ]</td><td>isovalue down / up one step</td></tr></table>"
    "<p>The solid tool is the proxy, which stays on the surface; the wire tool is the device. "
    "The yellow arrow is the force on your hand, red dots are the contacts.</p>";


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

namespace {

/// Unit direction that turns `from` towards `to` on the unit sphere by `t` (0..1) of the angle
/// between them (an antipodal pair turns through `via`, a direction perpendicular to both).
Eigen::Vector3d turnTowards(const Eigen::Vector3d& from, const Eigen::Vector3d& to, const Eigen::Vector3d& via,
                            double t) {
  if (from.dot(to) < -0.999) {
    return t < 0.5 ? turnTowards(from, via, via, 2.0 * t) : turnTowards(via, to, via, 2.0 * t - 1.0);
  }
  const Eigen::Quaterniond q = Eigen::Quaterniond::FromTwoVectors(from, to);
  return Eigen::Quaterniond::Identity().slerp(t, q) * from;
}

}  // namespace

bool DeviceInput::touchSurface(double depth_m) {
  runtime::SimulatedDevice* device = session_.simulatedDevice();
  const runtime::LiveValues& scene = session_.live();
  if (device == nullptr || scene.tool == nullptr || scene.hapticField() == nullptr) return false;
  // A touch in progress gives way to this one.
  for (QTimer* t : findChildren<QTimer*>("touchPath", Qt::FindDirectChildrenOnly)) {
    t->stop();
    t->deleteLater();
  }
  // The surface the hand feels: the felt segments' when some are felt, else the scan's.
  const haptics::ScalarVolume& field = *scene.hapticField();
  const haptics::PointShell& shell = scene.tool->point_shell;
  const double isovalue = scene.hapticIsovalue();
  const haptics::Pose X_WD = device->pose();
  const Eigen::Vector3d p_TCm = scene.tool->mass.p_TCm_m;
  const Eigen::Vector3d lo = field.boundsMin_W_m();
  const Eigen::Vector3d hi = field.boundsMax_W_m();
  const Eigen::Vector3d centre_W = 0.5 * (lo + hi);
  const double extent_m = (hi - lo).norm();
  // The tool's reach about its centre of mass [m]: with the centre farther than the volume's
  // half diagonal plus this from the volume's centre, no shell point is in the volume's box.
  double reach_m = 0.0;
  for (const Eigen::Vector3d& p_T : shell.points_T_m()) reach_m = std::max(reach_m, (p_T - p_TCm).norm());
  const double margin_m = std::max(0.005, 0.05 * extent_m);
  const double outside_m = 0.5 * extent_m + reach_m + margin_m;  // a sphere about the centre, clear of the box
  // The approach: from outside the volume's box along the view direction through its centre, so
  // the tool meets the surface the user sees (the skin or the outer bone from the front of the
  // default view), never from inside the body.
  Eigen::Vector3d dir_W = view_.camera().forward_W();
  if (!dir_W.allFinite() || dir_W.norm() < 0.5) dir_W = Eigen::Vector3d::UnitY();  // from anterior (LPS)
  dir_W.normalize();
  const auto poseWithCentreAt = [&](const Eigen::Vector3d& c_W) {
    haptics::Pose X = X_WD;
    X.p_AB_m = c_W - X.R_AB * p_TCm;
    return X;
  };
  const double max_travel_m = outside_m + 0.5 * extent_m + reach_m;
  // Straight in first; where that ray slips through a hole in the surface, parallel rays on rings
  // around it (up to 30% of the volume's size).
  const Eigen::Vector3d e1 = dir_W.unitOrthogonal();
  const Eigen::Vector3d e2 = dir_W.cross(e1);
  std::optional<haptics::Pose> start, target;
  for (const double ring : {0.0, 0.05, 0.1, 0.2, 0.3}) {
    const int n = ring == 0.0 ? 1 : 8;
    for (int k = 0; k < n && !target; ++k) {
      const double a = 2.0 * std::numbers::pi * k / n;
      const haptics::Pose from =
          poseWithCentreAt(centre_W - outside_m * dir_W + ring * extent_m * (std::cos(a) * e1 + std::sin(a) * e2));
      const std::optional<double> free_m =
          runtime::firstContactDistance(field, shell, from, dir_W, max_travel_m, isovalue, 0.05 * field.featureSize_m());
      if (!free_m) continue;
      start = from;
      target = from;
      target->p_AB_m += (*free_m + std::max(0.0, depth_m)) * dir_W;
    }
    if (target) break;
  }
  if (!target) return false;
  if (!session_.hapticsRunning()) {  // no proxy to lead: the device goes straight there
    setDevicePose(*target);
    return true;
  }
  // The proxy follows the device only through free space: lead it out of the volume's box the
  // shortest free way, round it on the sphere of radius outside_m (clear of the box), to the
  // start, then in.
  std::vector<haptics::Pose> path;
  const Eigen::Vector3d c_W = X_WD * p_TCm;
  Eigen::Vector3d out_W = c_W - centre_W;
  if (out_W.norm() < outside_m) {
    std::optional<std::pair<double, Eigen::Vector3d>> exit;  // distance, unit direction
    const Eigen::Vector3d radial = out_W.norm() > 1e-9 ? Eigen::Vector3d(out_W.normalized()) : Eigen::Vector3d::UnitZ();
    for (const Eigen::Vector3d& u : {radial, Eigen::Vector3d(Eigen::Vector3d::UnitZ()), Eigen::Vector3d(-Eigen::Vector3d::UnitZ()),
                                     Eigen::Vector3d(Eigen::Vector3d::UnitX()), Eigen::Vector3d(-Eigen::Vector3d::UnitX()),
                                     Eigen::Vector3d(Eigen::Vector3d::UnitY()), Eigen::Vector3d(-Eigen::Vector3d::UnitY())}) {
      // |out + t u| = outside_m, t > 0.
      const double b = out_W.dot(u);
      const double t = -b + std::sqrt(std::max(0.0, b * b - out_W.squaredNorm() + outside_m * outside_m));
      if (runtime::countPointsInside(field, shell, X_WD, isovalue) > 0 ||
          runtime::firstContactDistance(field, shell, X_WD, u, t, isovalue).has_value()) {
        continue;
      }
      if (!exit || t < exit->first) exit = std::make_pair(t, u);
    }
    if (exit) {
      out_W += exit->first * exit->second;
      path.push_back(poseWithCentreAt(centre_W + out_W));
    }
  } else {
    out_W = out_W.normalized() * outside_m;
    path.push_back(poseWithCentreAt(centre_W + out_W));
  }
  const Eigen::Vector3d start_dir = ((start->R_AB * p_TCm + start->p_AB_m) - centre_W).normalized();
  const Eigen::Vector3d out_dir = out_W.normalized();
  const double angle = std::acos(std::clamp(out_dir.dot(start_dir), -1.0, 1.0));
  const int steps = std::max(1, static_cast<int>(std::ceil(angle / (10.0 * std::numbers::pi / 180.0))));
  for (int i = 1; i < steps; ++i) {
    path.push_back(poseWithCentreAt(centre_W + outside_m * turnTowards(out_dir, start_dir, e1, static_cast<double>(i) / steps)));
  }
  path.push_back(*start);
  path.push_back(*target);
  // One waypoint at a time: the next once the proxy has caught up with the device (within 1 mm),
  // or has stood still for 100 ms (held by the surface: the last step ends so, resting on it),
  // or after 1.5 s.
  struct Progress {
    std::size_t next = 0;
    int elapsed_ms = 0, still_ms = 0;
    Eigen::Vector3d last_p_W = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
  };
  auto* timer = new QTimer(this);
  timer->setObjectName("touchPath");
  timer->setInterval(10);
  auto progress = std::make_shared<Progress>();
  setDevicePose(path[0]);
  connect(timer, &QTimer::timeout, this, [this, timer, path, progress] {
    Progress& p = *progress;
    const Eigen::Vector3d p_W = session_.proxyPose().p_AB_m;
    p.elapsed_ms += 10;
    p.still_ms = (p_W - p.last_p_W).norm() < 0.02e-3 ? p.still_ms + 10 : 0;
    p.last_p_W = p_W;
    const bool caught_up = (p_W - path[p.next].p_AB_m).norm() < 1e-3;
    if (!caught_up && p.still_ms < 100 && p.elapsed_ms < 1500) return;
    if (++p.next >= path.size() || session_.simulatedDevice() == nullptr) {
      timer->stop();
      timer->deleteLater();
      return;
    }
    p.elapsed_ms = p.still_ms = 0;
    setDevicePose(path[p.next]);
  });
  timer->start();
  return true;
}

bool DeviceInput::touchInProgress() const {
  for (const QTimer* t : findChildren<QTimer*>("touchPath", Qt::FindDirectChildrenOnly)) {
    if (t->isActive()) return true;
  }
  return false;
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
    case Qt::Key_Home:
      setDevicePose(session_.live().X_WT_initial);
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
