#pragma once
/// @file
/// Time-domain passivity observer and controller on one port of the virtual coupling
/// (Hannaford and Ryu 2002, "Time-domain passivity control of haptic interfaces", IEEE T-RA
/// 18(1), section III: the impedance-causality form, motion in, effort out). Off by
/// default (CouplingGains::passivity_control). One controller per port: the force with the
/// translation of the tool's centre of mass, the torque with its rotation.
///
/// Port and sign convention (W frame): each servo tick k the caller gives the effort e(k) the
/// coupling asks to put on the hand (force [N] or torque [N*m]) and the hand's displacement over
/// the last tick dq(k) = q(k) - q(k-1) (the sensed position's difference [m], or the rotation
/// vector rotvec(R_k R_k-1^T) [rad]). Power from the hand INTO the coupling is -e . v.
///
/// Why not H&R's plain form: a real device holds a command for one tick (zero-order hold) and
/// starts it `delay_ticks` ticks after it was computed. The command e'(k) therefore acts over
/// [t_k+d, t_k+d+1], and pairing e(k) with the backward-difference velocity over [t_k-1, t_k], as
/// the plain form does, books energy the device never delivered; on a delayed 50,000 N/m wall the
/// plain form lets the handle gain energy at every contact (passivity_controller_test). So:
///
///   observer   E(k) = E(k-1) - e'(k-1-d) . dq(k): the work the hand really received over the
///              last tick, from the command that was then being held (zero before the first);
///              then E(k) <- min(E(k), stored_J(k)) (see stored_J below).
///   predictor  the commands e'(k-d) .. e'(k-1) are already on their way; with the hand moving
///              as it did over the last tick, they will take E_pred = E(k) - sum e'(j) . dq(k).
///   controller when E_pred - e(k) . dq(k) < 0, a damper on the hand, H&R's eq. 10 sized for the
///              tick the command will act over:
///                 alpha = -(E_pred - e(k) . dq(k)) T / |dq(k)|^2,   e'(k) = e(k) - alpha dq(k) / T,
///              which makes the predicted energy exactly 0.
///
/// Guards (always on): the damper acts only when this tick's command would give the hand energy
/// (e(k) . dq(k) > 0) and at most cancels the effort along the motion (alpha |dq|^2 / T <=
/// e . dq): it only takes force away, never reverses it, and adds nothing in free space (e = 0);
/// with the port's stiffness K known, alpha is at most damping_cap g K T, the order of the
/// damping a sampled, delayed spring needs to be passive (Colgate and Schenkel's b > K T / 2 for
/// the hold, more with the delay): a larger one-tick damper, itself delayed, turns every encoder
/// count into a force spike;
/// no damping when |dq| < min_step (alpha would blow up as dq -> 0; the deficit is kept and
/// dissipated once the hand moves again); alpha at most max_damping; non-finite inputs pass e(k)
/// through without touching the state. The servo step allocates nothing and never throws.
///
/// Stiffness schedule (on when min_gain < 1): a predicted deficit (this tick's command would give
/// the hand more than the port holds) means the coupling is stiffer than the device renders with
/// its delay. The port then
/// sends g e(k) instead of e(k): g is cut by stiffness_cut (at most once every cut_interval_s),
/// never below min_gain (the caller's floor, e.g. the device's rated stiffness over the requested
/// one), and recovers to 1 over gain_recovery_s only in free space (e = 0), where the spring holds
/// no energy that a higher gain could create. Lowering g lowers the energy the spring holds: it
/// only ever dissipates.
///
/// stored_J (optional): the energy the coupling spring holds after this tick [J], e.g.
/// |F|^2 / (2 k_lin). A spring can give back only what it holds, so the observed reserve is
/// capped at it: energy absorbed long ago (a slide, a press) cannot pay for a limit cycle now.
/// Without it (infinity) the observer is H&R's, which lets an old reserve run down first.
#include <array>
#include <limits>

#include <Eigen/Core>

namespace vh::haptics {

struct PassivityOptions {
  /// Whole ticks between a command and the start of its hold on the device (0: the next tick's
  /// hold starts at once). [0, PassivityController::kMaxDelayTicks].
  int delay_ticks = 1;
  /// Smallest displacement per tick for which the damper is applied [m or rad].
  double min_step = 1e-9;
  /// Largest alpha [N*s/m or N*m*s/rad].
  double max_damping = 1e4;
  /// Stiffness of the port's spring, k_lin [N/m] or the torsional equivalent [N*m/rad]; 0: not
  /// known (no damping cap).
  double port_stiffness = 0.0;
  /// alpha <= damping_cap g port_stiffness T [ticks of the spring's stiffness].
  double damping_cap = 1.0;
  /// The stiffness schedule's floor g_min in (0, 1]; 1: no schedule (H&R's controller alone).
  double min_gain = 1.0;
  double stiffness_cut = 0.7;     ///< Fraction of g removed by one cut.
  double cut_interval_s = 0.02;   ///< Shortest time between two cuts [s].
  double gain_recovery_s = 0.5;   ///< Time for g to climb back from 0 to 1 in free space [s].
};

class PassivityController {
 public:
  static constexpr int kMaxDelayTicks = 8;

  struct Step {
    Eigen::Vector3d effort_W = Eigen::Vector3d::Zero();  ///< e'(k) = e(k) - alpha dq / T.
    double alpha = 0.0;                                  ///< Damping applied this tick.
    double predicted_dissipation_J = 0.0;                ///< alpha |dq|^2 / T.
  };

  /// delay_ticks outside [0, kMaxDelayTicks] is clamped into it.
  explicit PassivityController(const PassivityOptions& options = {}) noexcept;

  /// Observe tick k and return the command to send.
  /// @param effort_W   e(k): force [N] or torque [N*m] on the hand, W.
  /// @param step_W     dq(k): the hand's displacement since the previous call [m or rad], W.
  /// @param dt_s       servo period T [s] (> 0).
  /// @param stored_J   energy held by the coupling after this tick [J]; infinity: not capped.
  Step step(const Eigen::Vector3d& effort_W, const Eigen::Vector3d& step_W, double dt_s,
            double stored_J = std::numeric_limits<double>::infinity()) noexcept;
  void reset() noexcept;

  /// E(k) [J]: energy the coupling has absorbed and may still return (>= 0: passive so far).
  double observedEnergy_J() const noexcept { return energy_J_; }
  /// Total damping the controller applied, as predicted when applied [J].
  double dissipated_J() const noexcept { return dissipated_J_; }
  /// Ticks on which the damper acted.
  long activeTicks() const noexcept { return active_ticks_; }
  /// The stiffness schedule's gain g in [min_gain, 1] (1 without a schedule).
  double gain() const noexcept { return gain_; }
  /// Lowest g since the last reset.
  double lowestGain() const noexcept { return lowest_gain_; }
  const PassivityOptions& options() const noexcept { return options_; }

 private:
  PassivityOptions options_;
  double energy_J_ = 0.0;
  double dissipated_J_ = 0.0;
  long active_ticks_ = 0;
  double gain_ = 1.0;
  double lowest_gain_ = 1.0;
  int cut_wait_ticks_ = 0;
  // Commands e'(k-1) .. e'(k-1-d), newest first (sent_[0] = e'(k-1)).
  std::array<Eigen::Vector3d, kMaxDelayTicks + 1> sent_{};
};

}  // namespace vh::haptics
