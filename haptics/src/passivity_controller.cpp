#include "vh/haptics/passivity_controller.h"

#include <algorithm>
#include <cmath>

namespace vh::haptics {

PassivityController::PassivityController(const PassivityOptions& options) noexcept : options_(options) {
  options_.delay_ticks = std::clamp(options_.delay_ticks, 0, kMaxDelayTicks);
  reset();
}

PassivityController::Step PassivityController::step(const Eigen::Vector3d& e, const Eigen::Vector3d& dq, double T,
                                                    double stored_J) noexcept {
  Step out;
  out.effort_W = e;
  if (!e.allFinite() || !dq.allFinite() || !(T > 0.0) || !std::isfinite(T) || std::isnan(stored_J)) return out;
  const int d = options_.delay_ticks;
  // Observer: the work the hand received over the last tick came from the command held then,
  // e'(k-1-d) = sent_[d].
  energy_J_ -= sent_[static_cast<std::size_t>(d)].dot(dq);
  energy_J_ = std::min(energy_J_, std::max(stored_J, 0.0));
  // Predictor: the commands in flight, e'(k-d) .. e'(k-1) = sent_[d-1] .. sent_[0], with the hand
  // moving as over the last tick; then this tick's own command.
  double e_pred = energy_J_;
  for (int j = 0; j < d; ++j) e_pred -= sent_[static_cast<std::size_t>(j)].dot(dq);
  const double e_next = e_pred - e.dot(dq);
  const double dq2 = dq.squaredNorm();
  const double min_step = options_.min_step;
  const double along = e.dot(dq);  // > 0: this tick's command would give energy to the hand
  if (e_next < 0.0 && along > 0.0 && dq2 >= min_step * min_step) {
    // Controller (H&R eq. 10 for the tick ahead): alpha dq^2 / T = -e_next, at most the damping
    // that cancels the effort along the motion (alpha dq^2 / T <= e . dq): it only ever takes
    // force away, never reverses it or adds one the coupling did not ask for.
    const double alpha = std::min({-e_next * T / dq2, options_.max_damping, along * T / dq2});
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
  for (auto& s : sent_) s.setZero();
}

}  // namespace vh::haptics
