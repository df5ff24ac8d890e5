#include "vh/haptics/virtual_coupling.h"

#include "vh/haptics/pose.h"

namespace vh::haptics {

Wrench VirtualCoupling::wrenchFor(const Vector6d& a_u, const Pose& X_WP, const MassProperties& mass) const noexcept {
  const Matrix6d M = mass.massMatrix_W(X_WP.R_AB.toRotationMatrix());
  const double mean_moment = mass.I_Cm_T_kgm2.trace() / 3.0;
  Vector6d K;
  K.head<3>().setConstant(gains_.linear_N_per_m / (2.0 * mass.mass_kg));
  K.tail<3>().setConstant(gains_.angular_Nm_per_rad / (2.0 * mean_moment));
  const Vector6d F = -(K.asDiagonal() * (M * a_u));
  Wrench w;
  w.force_W_N = F.head<3>();
  w.torque_W_Nm = F.tail<3>();
  return w;
}

Wrench VirtualCoupling::compute(const Pose& X_WP, const Pose& X_WD, const MassProperties& mass) const noexcept {
  // Eq. 5: F_r = -K M a'_u, a'_u = 2 dx' from the (moved) proxy to the device.
  return wrenchFor(2.0 * displacement_W(X_WP, X_WD, mass.p_TCm_m, &tracked_theta_W_rad_), X_WP, mass);
}

Wrench VirtualCoupling::track(const Pose& X_WP, const Pose& X_WD, const MassProperties& mass) noexcept {
  const Vector6d dx = displacement_W(X_WP, X_WD, mass.p_TCm_m, &tracked_theta_W_rad_);
  if (dx.tail<3>().allFinite()) tracked_theta_W_rad_ = dx.tail<3>();
  return wrenchFor(2.0 * dx, X_WP, mass);
}

}  // namespace vh::haptics
