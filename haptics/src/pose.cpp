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

}  // namespace vh::haptics
