#pragma once
/// @file
/// The virtual coupling (paper section 2.5, eq. 5): F_r = -K M a'_u, where a'_u = 2 dx' is the
/// acceleration that would take the proxy to the device after the proxy moved.
///
/// K = diag(k_lin / (2 m) I3, k_ang / (2 i) I3), with m the tool's mass and i the mean principal
/// moment of inertia (trace / 3), so that the force is exactly -k_lin (c_D - c_P) [N] and the
/// torque is -k_ang (I_W / i) dtheta [N*m]: the torque keeps the direction the mass metric gives
/// it (the paper's "mismatch between applied and reflected force directions"). The configuration
/// solver projects in the same metric (ConfigurationSolver::setGains()), so the proxy never moves
/// against this coupling.

#include <Eigen/Core>

#include "vh/haptics/cone_projection.h"
#include "vh/haptics/pose.h"
#include "vh/haptics/triangle_mesh.h"

namespace vh::haptics {

/// Coupling gains.
struct CouplingGains {
  double linear_N_per_m = 1000.0;      ///< Linear stiffness k_lin [N/m].
  double angular_Nm_per_rad = 1.0;     ///< Torsional stiffness k_ang [N*m/rad].
  /// Time-domain passivity observer and controller on the coupling's force
  /// (passivity_controller.h). Off by default: it changes the force the user feels.
  bool passivity_control = false;
};

/// Force and torque on the user's hand, in W, about the tool's centre of mass.
struct Wrench {
  Eigen::Vector3d force_W_N = Eigen::Vector3d::Zero();
  Eigen::Vector3d torque_W_Nm = Eigen::Vector3d::Zero();
};

class VirtualCoupling {
 public:
  explicit VirtualCoupling(const CouplingGains& gains = {}) : gains_(gains) {}
  void setGains(const CouplingGains& gains) noexcept { gains_ = gains; }
  const CouplingGains& gains() const noexcept { return gains_; }

  /// Step 6: eq. 5 for the proxy at X_WP and the device at X_WD, with the relative rotation
  /// taken nearest the tracked one (trackedRotation_W(); nothing is updated).
  Wrench compute(const Pose& X_WP, const Pose& X_WD, const MassProperties& mass) const noexcept;
  /// As compute(), and the relative rotation becomes the tracked one: call once per servo tick
  /// with the tick's poses. The rotation from proxy to device is then followed continuously
  /// (unwrapRotationVector(), phase unwrapping): a twist that keeps growing past pi keeps its
  /// torque's direction and grows it, where the shortest rotation would reverse it at pi and
  /// snap the proxy the other way. The device's torque limit bounds what the hand feels.
  Wrench track(const Pose& X_WP, const Pose& X_WD, const MassProperties& mass) noexcept;
  /// The relative rotation proxy -> device [rad, W] at the last track() (zero at first).
  const Eigen::Vector3d& trackedRotation_W() const noexcept { return tracked_theta_W_rad_; }
  /// Forgets the tracked rotation (the proxy was reset).
  void resetTracking() noexcept { tracked_theta_W_rad_.setZero(); }

 private:
  Wrench wrenchFor(const Vector6d& a_u, const Pose& X_WP, const MassProperties& mass) const noexcept;
  CouplingGains gains_;
  Eigen::Vector3d tracked_theta_W_rad_ = Eigen::Vector3d::Zero();
};

}  // namespace vh::haptics
