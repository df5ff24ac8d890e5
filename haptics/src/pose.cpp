#include "vh/haptics/pose.h"

#include <cmath>

namespace vh::haptics {

Eigen::Vector3d rotationVector(const Eigen::Quaterniond& q_in) noexcept {
  // Take the representative with w >= 0 so that the angle lies in [0, pi].
  Eigen::Quaterniond q = q_in;
  if (q.w() < 0.0) q.coeffs() = -q.coeffs();
  const Eigen::Vector3d v = q.vec();
  const double s = v.norm();
  if (s < 1e-12) return 2.0 * v;  // first-order: angle ~ 2 |v|
  const double angle = 2.0 * std::atan2(s, q.w());
  return v * (angle / s);
}

Eigen::Vector3d unwrapRotationVector(const Eigen::Vector3d& theta, const Eigen::Vector3d& reference,
                                     double max_step_rad) noexcept {
  constexpr double kTwoPi = 2.0 * 3.14159265358979323846;
  const double ref_norm = reference.norm();
  if (!(ref_norm > 0.0) || !reference.allFinite() || !theta.allFinite()) return theta;
  const double angle = theta.norm();
  const Eigen::Vector3d axis = angle >= 1e-6 ? Eigen::Vector3d(theta / angle) : Eigen::Vector3d(reference / ref_norm);
  // theta = angle * axis, and the same rotation is (angle + 2 pi k) * axis: the k whose value
  // along the axis is nearest the reference's component along it.
  const double along = axis.dot(reference);
  const double k = std::round((along - angle) / kTwoPi);
  if (k == 0.0) return theta;
  const Eigen::Vector3d unwrapped = (angle + kTwoPi * k) * axis;
  return (unwrapped - reference).norm() <= max_step_rad ? unwrapped : theta;
}

Eigen::Quaterniond quaternionFromRotationVector(const Eigen::Vector3d& theta) noexcept {
  const double angle = theta.norm();
  if (angle < 1e-12) {
    Eigen::Quaterniond q(1.0, 0.5 * theta.x(), 0.5 * theta.y(), 0.5 * theta.z());
    return q.normalized();
  }
  const double half = 0.5 * angle;
  const Eigen::Vector3d axis = theta / angle;
  const double s = std::sin(half);
  return Eigen::Quaterniond(std::cos(half), axis.x() * s, axis.y() * s, axis.z() * s);
}

Vector6d displacement_W(const Pose& X_WA, const Pose& X_WB, const Eigen::Vector3d& p_TCm_m,
                        const Eigen::Vector3d* rotation_reference_rad) noexcept {
  Vector6d dx;
  dx.head<3>() = X_WB * p_TCm_m - X_WA * p_TCm_m;
  dx.tail<3>() = rotationVector(X_WB.R_AB * X_WA.R_AB.conjugate());
  if (rotation_reference_rad != nullptr) dx.tail<3>() = unwrapRotationVector(dx.tail<3>(), *rotation_reference_rad);
  return dx;
}

}  // namespace vh::haptics
