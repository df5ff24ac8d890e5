#include "vh/haptics/rigid_motion.h"

namespace vh::haptics {

RigidMotion RigidMotion::FromVelocity(const Pose& X_WT0, const Eigen::Vector3d& p_TCm_m, const Eigen::Vector3d& v_W_m,
                                      const Eigen::Vector3d& omega_W_rad) noexcept {
  RigidMotion m;
  m.R0_ = X_WT0.R_AB;
  m.p_TCm_ = p_TCm_m;
  m.c0_ = X_WT0 * p_TCm_m;
  m.v_ = v_W_m;
  m.omega_ = omega_W_rad;
  m.speed_ = v_W_m.norm();
  m.angle_ = omega_W_rad.norm();
  m.axis_ = m.angle_ > 0.0 ? Eigen::Vector3d(omega_W_rad / m.angle_) : Eigen::Vector3d::UnitX();
  m.cos_start_ = std::cos(m.angle_ * 0.0);
  m.sin_start_ = std::sin(m.angle_ * 0.0);
  m.cos_end_ = std::cos(m.angle_ * 1.0);
  m.sin_end_ = std::sin(m.angle_ * 1.0);
  return m;
}

RigidMotion RigidMotion::Between(const Pose& X_WT0, const Pose& X_WT1, const Eigen::Vector3d& p_TCm_m) noexcept {
  const Eigen::Vector3d c0 = X_WT0 * p_TCm_m;
  const Eigen::Vector3d c1 = X_WT1 * p_TCm_m;
  const Eigen::Vector3d omega = rotationVector(X_WT1.R_AB * X_WT0.R_AB.conjugate());
  return FromVelocity(X_WT0, p_TCm_m, c1 - c0, omega);
}

Pose RigidMotion::poseAt(double t) const noexcept {
  Pose X;
  X.R_AB = (quaternionFromRotationVector(omega_ * t) * R0_).normalized();
  const Eigen::Vector3d c = c0_ + v_ * t;
  X.p_AB_m = c - X.R_AB * p_TCm_;
  return X;
}

}  // namespace vh::haptics
