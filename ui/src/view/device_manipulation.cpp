#include "vh/ui/view/device_manipulation.h"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace vh::ui {

Eigen::Vector3d ViewCamera::forward_W() const {
  const Eigen::Vector3d d = focal_point_W_m - position_W_m;
  const double n = d.norm();
  return n > 0.0 ? Eigen::Vector3d(d / n) : Eigen::Vector3d(0, 0, -1);
}

Eigen::Vector3d ViewCamera::right_W() const {
  Eigen::Vector3d r = forward_W().cross(view_up_W);
  if (r.norm() < 1e-12) {  // degenerate up: any perpendicular
    r = forward_W().unitOrthogonal();
  }
  return r.normalized();
}

Eigen::Vector3d ViewCamera::up_W() const { return right_W().cross(forward_W()).normalized(); }

double ViewCamera::metresPerPixelAt(const Eigen::Vector3d& p_W_m) const {
  const double h_px = std::max(1, viewport_height_px);
  if (parallel) {
    return 2.0 * parallel_scale_m / h_px;
  }
  // Depth of p along the view direction; never less than a small fraction of the eye-focal
  // distance, so a point behind the eye still moves sensibly.
  const double focal_distance = (focal_point_W_m - position_W_m).norm();
  const double depth = std::max((p_W_m - position_W_m).dot(forward_W()), 1e-3 * focal_distance);
  const double half_angle = 0.5 * view_angle_deg * std::numbers::pi / 180.0;
  return 2.0 * depth * std::tan(half_angle) / h_px;
}

ViewRay rayThroughPixel(const ViewCamera& camera, double x_px, double y_px) {
  const double w_px = std::max(1, camera.viewport_width_px);
  const double h_px = std::max(1, camera.viewport_height_px);
  // The pixel's offset from the view's centre, in units of half the view's height.
  const double u = (2.0 * x_px - w_px) / h_px;
  const double v = (h_px - 2.0 * y_px) / h_px;
  const Eigen::Vector3d forward = camera.forward_W(), right = camera.right_W(), up = camera.up_W();
  if (camera.parallel) {
    const double half_h_m = camera.parallel_scale_m;
    return {camera.position_W_m + half_h_m * (u * right + v * up), forward};
  }
  const double t = std::tan(0.5 * camera.view_angle_deg * std::numbers::pi / 180.0);
  return {camera.position_W_m, (forward + t * (u * right + v * up)).normalized()};
}

haptics::Pose dragInViewPlane(const haptics::Pose& X_WD, const ViewCamera& camera,
                              const Eigen::Vector3d& p_W_anchor_m, double dx_px, double dy_px) {
  const double m_per_px = camera.metresPerPixelAt(p_W_anchor_m);
  haptics::Pose out = X_WD;
  out.p_AB_m += m_per_px * (dx_px * camera.right_W() - dy_px * camera.up_W());
  return out;
}

haptics::Pose moveAlongView(const haptics::Pose& X_WD, const ViewCamera& camera, double distance_m) {
  haptics::Pose out = X_WD;
  out.p_AB_m += distance_m * camera.forward_W();
  return out;
}

haptics::Pose rotateTrackball(const haptics::Pose& X_WD, const ViewCamera& camera,
                              const Eigen::Vector3d& p_D_centre_m, double dx_px, double dy_px,
                              double rad_per_px) {
  // Right drag: about screen-up (the front turns right). Up drag (dy < 0): about screen-right,
  // with the front turning up.
  const Eigen::Vector3d omega_W = rad_per_px * (dx_px * camera.up_W() + dy_px * camera.right_W());
  const double angle = omega_W.norm();
  if (angle < 1e-12) {
    return X_WD;
  }
  const Eigen::Quaterniond R(Eigen::AngleAxisd(angle, omega_W / angle));
  const Eigen::Vector3d c_W = X_WD * p_D_centre_m;  // stays fixed
  haptics::Pose out;
  out.R_AB = (R * X_WD.R_AB).normalized();
  out.p_AB_m = R * (X_WD.p_AB_m - c_W) + c_W;
  return out;
}

}  // namespace vh::ui
