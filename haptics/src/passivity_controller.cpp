#include "vh/haptics/passivity_controller.h"

#include <algorithm>
#include <cmath>

namespace vh::haptics {

PassivityController::PassivityController(const PassivityOptions& options) noexcept : options_(options) {
  options_.delay_ticks = std::clamp(options_.delay_ticks, 0, kMaxDelayTicks);
  if (!(options_.min_gain > 0.0)) options_.min_gain = 1e-3;  // NaN or <= 0: a floor all the same
  options_.min_gain = std::min(options_.min_gain, 1.0);
  if (!(options_.stiffness_cut > 0.0 && options_.stiffness_cut < 1.0)) options_.stiffness_cut = 0.7;
  if (!(options_.gain_recovery_s > 0.0)) options_.gain_recovery_s = 0.5;
  reset();
}

PassivityController::Step PassivityController::step(const Eigen::Vector3d& effort_W, const Eigen::Vector3d& dq,
                                                    double T, double stored_J) noexcept {
  Step out;
  out.effort_W = effort_W;
  if (!effort_W.allFinite() || !dq.allFinite() || !(T > 0.0) || !std::isfinite(T) || std::isnan(stored_J)) return out;
  const int d = options_.delay_ticks;
  const bool schedule = options_.min_gain < 1.0;
  if (cut_wait_ticks_ > 0) --cut_wait_ticks_;
  // The schedule recovers only in free space, where the spring holds nothing to create.
  if (schedule && effort_W.squaredNorm() == 0.0) gain_ = std::min(1.0, gain_ + T / options_.gain_recovery_s);
  // Observer: the work the hand received over the last tick came from the command held then,
  // e'(k-1-d) = sent_[d]. The reserve is capped at what the (scheduled) spring holds.
  energy_J_ -= sent_[static_cast<std::size_t>(d)].dot(dq);
  energy_J_ = std::min(energy_J_, std::max(gain_ * stored_J, 0.0));
  // Predictor: the commands in flight, e'(k-d) .. e'(k-1) = sent_[d-1] .. sent_[0], with the hand
  // moving as over the last tick.
  double e_pred = energy_J_;
  for (int j = 0; j < d; ++j) e_pred -= sent_[static_cast<std::size_t>(j)].dot(dq);
  const double dq2 = dq.squaredNorm();
  const double along_in = effort_W.dot(dq);  // > 0: the command would give energy to the hand
  const bool may_act = along_in > 0.0 && dq2 >= options_.min_step * options_.min_step && dq2 > 0.0;
  // Stiffness schedule: a deficit means the coupling is stiffer than the device renders.
  if (schedule && may_act && e_pred - gain_ * along_in < 0.0 && cut_wait_ticks_ == 0) {
    gain_ = std::max(options_.min_gain, gain_ * (1.0 - options_.stiffness_cut));
    lowest_gain_ = std::min(lowest_gain_, gain_);
    cut_wait_ticks_ = std::max(1, static_cast<int>(std::lround(options_.cut_interval_s / T)));
  }
  const Eigen::Vector3d e = gain_ * effort_W;
  out.effort_W = e;
  const double along = gain_ * along_in;
  const double e_next = e_pred - along;
  if (e_next < 0.0 && may_act) {
    // Controller (H&R eq. 10 for the tick ahead): alpha dq^2 / T = -e_next, at most the damping
    // that cancels the effort along the motion (alpha dq^2 / T <= e . dq), and at most
    // damping_cap g K T when the port's stiffness K is known.
    double alpha = std::min({-e_next * T / dq2, options_.max_damping, along * T / dq2});
    if (options_.port_stiffness > 0.0)
      alpha = std::min(alpha, options_.damping_cap * gain_ * options_.port_stiffness * T);
    if (alpha > 0.0) {
      out.alpha = alpha;
      out.effort_W = e - (alpha / T) * dq;
      out.predicted_dissipation_J = alpha * dq2 / T;
      dissipated_J_ += out.predicted_dissipation_J;
      ++active_ticks_;
    }
  }
  for (int j = d; j > 0; --j) sent_[static_cast<std::size_t>(j)] = sent_[static_cast<std::size_t>(j - 1)];
  sent_[0] = out.effort_W;
  return out;
}

void PassivityController::reset() noexcept {
  energy_J_ = 0.0;
  dissipated_J_ = 0.0;
  active_ticks_ = 0;
  gain_ = 1.0;
  lowest_gain_ = 1.0;
  cut_wait_ticks_ = 0;
  for (auto& s : sent_) s.setZero();
}

}  // namespace vh::haptics
