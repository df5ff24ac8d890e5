#pragma once
/// @file
/// Time-domain passivity observer and controller on the coupling port (Hannaford and Ryu 2002,
/// "Time-domain passivity control of haptic interfaces", IEEE T-RA 18(1), section III, the
/// impedance-causality form: velocity in, force out). Issue 19. Off by default
/// (CouplingGains::passivity_control).
///
/// Port and sign convention: the renderer reads the device velocity v [m/s] (W) and returns the
/// force F on the hand [N] (W). The power flowing from the hand INTO the coupling (the virtual
/// environment) is -F . v, so the observer is
///     E(n) = -T sum_{k<=n} F'(k) . v(k)      [J],  >= 0: the coupling has absorbed energy,
/// with F' the force actually sent (after the controller). When the observed energy with the
/// unmodified force, E_obs = E(n-1) - T F(n) . v(n), is negative, the controller adds a
/// variable damper on the hand:
///     alpha(n) = -E_obs / (T |v(n)|^2)      [N*s/m],   F'(n) = F(n) - alpha(n) v(n),
/// which dissipates exactly the deficit, so E(n) = 0 (H&R's f' = f + alpha v, with their f the
/// force applied to the environment, i.e. -F here).
/// Guards (always on, not debug-only): no damping when |v| < min_speed_mps (alpha would blow up
/// as v -> 0; the deficit is kept and dissipated once the hand moves again), alpha clamped to
/// max_damping_Ns_per_m, and non-finite inputs pass through without touching the state.
/// The servo step allocates nothing.
#include <Eigen/Core>

namespace vh::haptics {

struct PassivityOptions {
  double min_speed_mps = 1e-4;          ///< Below this speed the damper is not applied [m/s].
  double max_damping_Ns_per_m = 1e4;    ///< Largest alpha [N*s/m].
};

class PassivityController {
 public:
  struct Step {
    Eigen::Vector3d force_W_N = Eigen::Vector3d::Zero();  ///< F' = F - alpha v [N].
    double alpha_Ns_per_m = 0.0;                          ///< Damping applied this tick.
    double dissipated_J = 0.0;                            ///< alpha |v|^2 T this tick [J].
  };

  explicit PassivityController(const PassivityOptions& options = {}) : options_(options) {}
  /// Observe one tick and return the modified force. dt_s: the servo period T [s] (> 0).
  Step step(const Eigen::Vector3d& force_W_N, const Eigen::Vector3d& v_W_mps, double dt_s) noexcept;
  void reset() noexcept;

  /// E(n) [J]: energy the coupling has absorbed through the modified force (>= 0: passive so far).
  double observedEnergy_J() const noexcept { return energy_J_; }
  /// Total energy the damper has dissipated [J].
  double dissipated_J() const noexcept { return dissipated_J_; }
  const PassivityOptions& options() const noexcept { return options_; }

 private:
  PassivityOptions options_;
  double energy_J_ = 0.0;
  double dissipated_J_ = 0.0;
};

}  // namespace vh::haptics
