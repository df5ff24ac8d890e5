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
  /// Time-domain passivity observer and controller on the coupling's force (issue 19,
  /// passivity_controller.h). Off by default: it changes the force the user feels.
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

  /// Step 6: eq. 5 for the proxy at X_WP and the device at X_WD.
  Wrench compute(const Pose& X_WP, const Pose& X_WD, const MassProperties& mass) const noexcept;

 private:
  CouplingGains gains_;
};

}  // namespace vh::haptics
