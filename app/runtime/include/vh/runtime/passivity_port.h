#pragma once
/// @file
/// One port (force or torque) of the coupling thread's passivity control: a
/// haptics::PassivityController (Hannaford and Ryu 2002; haptics/passivity_controller.h) whose
/// state - the observed energy, the stiffness schedule's gain g and the commands in flight - is
/// kept across gain changes and short faults instead of starting afresh at g = 1 (which let a
/// 20x stiffness step reach the hand at once).
///
/// The controller cannot be told a new port stiffness without a reset, so the port puts a
/// transition factor h in (0, 1] in front of it: the controller is configured for the effective
/// stiffness K_eff = h K and sees the effort h e(k) (and the stored energy h stored_J, the same
/// spring at stiffness h K). On a stiffness change K -> K' with h K <= K' the port sets
/// h' = h K / K': K_eff, hence the controller's options and state, stay as they were, and the
/// hand feels g h' K' = g h K, no step. h recovers to 1 only in free space (a zero effort for
/// longer than the command delay), where the spring holds nothing: there the controller is
/// rebuilt for the new K_eff with its g folded into h (h <- h g), and h climbs back at the
/// controller's own rate (1 / PassivityOptions::gain_recovery_s). A stiffness decrease below
/// K_eff (softer, never unsafe) applies at once (h = 1) and rebuilds the controller at the next
/// free-space tick. What a rebuild loses: an energy deficit still pending in free space (the
/// controller keeps it for the next contact), and its counters (the caller sums those).
///
/// The floor: the controller's schedule never goes below min_gain = device_limit / K_eff, so the
/// port never renders softer than the device's rating (g h K >= device_limit).
///
/// step() never allocates, blocks or throws.

#include <limits>

#include <Eigen/Core>

#include "vh/haptics/passivity_controller.h"

namespace vh::runtime {

class PassivityPort {
 public:
  PassivityPort() = default;

  /// Starts afresh (h = 1, a new controller) for a port spring of `stiffness` [N/m or
  /// N*m/rad] on a device rated `device_limit` (the same unit; infinity or <= 0: no floor).
  void configure(double stiffness, double device_limit) noexcept;
  /// A gain change while running: state kept, rendered stiffness continuous (see the file
  /// comment). Same units as configure().
  void setStiffness(double stiffness, double device_limit) noexcept;
  /// After an outage (the motion history is broken): a fresh controller for the current K_eff;
  /// h is kept.
  void restart() noexcept;

  /// One coupled tick: haptics::PassivityController::step() on h * effort (units as there).
  haptics::PassivityController::Step step(const Eigen::Vector3d& effort_W, const Eigen::Vector3d& step_W,
                                          double dt_s,
                                          double stored_J = std::numeric_limits<double>::infinity()) noexcept;

  /// The transition factor h in (0, 1].
  double transition() const noexcept { return h_; }
  /// The port's stiffness K (the applied gain) and the effective one K_eff = h K.
  double stiffness() const noexcept { return stiffness_; }
  double effectiveStiffness() const noexcept { return h_ * stiffness_; }
  /// The rendered stiffness g h K.
  double renderedStiffness() const noexcept { return controller_.gain() * h_ * stiffness_; }
  const haptics::PassivityController& controller() const noexcept { return controller_; }

 private:
  void rebuild() noexcept;

  haptics::PassivityController controller_;
  double stiffness_ = 0.0;
  double device_limit_ = std::numeric_limits<double>::infinity();
  double h_ = 1.0;
  bool stale_ = false;  // the controller's options are not those of the current K_eff
  int free_ticks_ = 0;  // consecutive ticks with a zero effort
};

}  // namespace vh::runtime
