#pragma once
/// @file
/// The coupling thread's passivity control (haptic_thread.cpp): the energy the coupling's springs
/// hold, the cap of each passivity port. Private to vh::runtime.

#include <cmath>
#include <cstdint>
#include <limits>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "vh/haptics/configuration_solver.h"
#include "vh/haptics/passivity_controller.h"
#include "vh/runtime/device.h"
#include "vh/runtime/passivity_port.h"

namespace vh::runtime::detail {

/// Energy the coupling's linear spring holds [J]: 0.5 k_lin |c_D - c_P|^2 = |F|^2 / (2 k_lin)
/// (virtual_coupling.h: F = -k_lin (c_D - c_P)); 0 without a spring.
inline double linearStoredEnergy_J(const Eigen::Vector3d& force_W_N, double k_lin_N_per_m) noexcept {
  return k_lin_N_per_m > 0.0 ? force_W_N.squaredNorm() / (2.0 * k_lin_N_per_m) : 0.0;
}

/// Energy the coupling's torsional spring holds [J]. Eq. 5 gives tau = -(k_ang / i) I_W dtheta
/// (i = trace(I_Cm) / 3, I_W = R_WP I_Cm_T R_WP^T: virtual_coupling.h), the gradient of
/// 0.5 (k_ang / i) dtheta^T I_W dtheta, which is (i / (2 k_ang)) tau^T I_W^-1 tau. Exact for the
/// quadratic form in the rotation vector; the rotation manifold's curvature is neglected (small
/// angles). Infinity (no cap) when it cannot be computed (e.g. a singular inertia); 0 without a
/// spring.
inline double angularStoredEnergy_J(const Eigen::Vector3d& torque_W_Nm, const Eigen::Quaterniond& R_WP,
                                    const Eigen::Matrix3d& I_Cm_inv_T, double mean_moment_kgm2,
                                    double k_ang_Nm_per_rad) noexcept {
  if (!(k_ang_Nm_per_rad > 0.0)) return 0.0;
  const Eigen::Vector3d tau_T = R_WP.conjugate() * torque_W_Nm;
  const double e = mean_moment_kgm2 / (2.0 * k_ang_Nm_per_rad) * tau_T.dot(I_Cm_inv_T * tau_T);
  return std::isfinite(e) && e >= 0.0 ? e : std::numeric_limits<double>::infinity();
}

/// The coupling thread's passivity control (CouplingGains::passivity_control, passivity_port.h):
/// one controller per port, the force with the centre of mass's displacement and the torque with
/// the rotation vector since the previous coupled sample. Their state is kept across gain changes
/// (the rendered stiffness stays continuous) and short faults; they start afresh when the switch
/// turns on and after an outage (ForceSafety re-armed).
struct CouplingPassivity {
  explicit CouplingPassivity(const haptics::MassProperties& mass) noexcept
      : I_Cm_inv_T(mass.I_Cm_T_kgm2.inverse()), mean_moment_kgm2(mass.I_Cm_T_kgm2.trace() / 3.0) {}

  /// Both controllers afresh for `gains` on a device rated `limits`.
  void configure(const haptics::CouplingGains& gains, const DeviceLimits& limits) noexcept {
    force.configure(gains.linear_N_per_m, limits.max_linear_stiffness_N_per_m);
    torque.configure(gains.angular_Nm_per_rad, limits.max_angular_stiffness_Nm_per_rad);
  }

  /// A gain change: the controllers keep their state; the rendered stiffness moves on without a step.
  void setStiffness(const haptics::CouplingGains& gains, const DeviceLimits& limits) noexcept {
    force.setStiffness(gains.linear_N_per_m, limits.max_linear_stiffness_N_per_m);
    torque.setStiffness(gains.angular_Nm_per_rad, limits.max_angular_stiffness_Nm_per_rad);
  }

  /// A coupled tick at the device pose X_WD: with passivity control on, the wrench goes through
  /// both controllers (the hand's motion since the last coupled sample, over the ticks since: a
  /// short fault keeps the controllers' state; the spring's stored energy as the cap). Then
  /// X_WD is the last coupled pose.
  inline void coupled(Eigen::Vector3d& force_W_N, Eigen::Vector3d& torque_W_Nm, const haptics::Pose& X_WD,
                      const haptics::Pose& X_WP, const haptics::MassProperties& mass,
                      const haptics::CouplingGains& gains, double period_s) noexcept {
    if (gains.passivity_control) {
      haptics::Vector6d step_W = haptics::Vector6d::Zero();
      if (have_coupled_last) step_W = haptics::displacement_W(X_WD_coupled_last, X_WD, mass.p_TCm_m);
      const double dt_s = period_s * static_cast<double>(have_coupled_last ? ticks_since_coupled : 1);
      const auto f =
          force.step(force_W_N, step_W.head<3>(), dt_s, linearStoredEnergy_J(force_W_N, gains.linear_N_per_m));
      const auto t = torque.step(
          torque_W_Nm, step_W.tail<3>(), dt_s,
          angularStoredEnergy_J(torque_W_Nm, X_WP.R_AB, I_Cm_inv_T, mean_moment_kgm2, gains.angular_Nm_per_rad));
      force_W_N = f.effort_W;
      torque_W_Nm = t.effort_W;
      if (f.alpha > 0.0) ++active_ticks;
      if (t.alpha > 0.0) ++active_ticks;
      dissipated_J += f.predicted_dissipation_J + t.predicted_dissipation_J;
    }
    X_WD_coupled_last = X_WD;
    have_coupled_last = true;
    ticks_since_coupled = 0;
  }

  /// After the safety layer's step: an outage (a new count in `outages`) breaks the motion history.
  inline void afterSafety(std::uint64_t outages) noexcept {
    if (outages == outages_seen) return;
    outages_seen = outages;
    force.restart();
    torque.restart();
    have_coupled_last = false;
  }

  PassivityPort force;
  PassivityPort torque;
  haptics::Pose X_WD_coupled_last;         ///< The device pose of the last coupled tick.
  bool have_coupled_last = false;          ///< X_WD_coupled_last is valid (no outage since).
  std::uint64_t ticks_since_coupled = 0;
  std::uint64_t outages_seen = 0;
  const Eigen::Matrix3d I_Cm_inv_T;        ///< I_Cm^-1 in T, for the torsional spring's stored energy.
  const double mean_moment_kgm2;
  std::uint64_t active_ticks = 0;          ///< Summed over controller restarts.
  double dissipated_J = 0.0;
};

}  // namespace vh::runtime::detail
