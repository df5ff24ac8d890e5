#include "vh/haptics/passivity_controller.h"

#include <algorithm>
#include <cmath>

namespace vh::haptics {

PassivityController::Step PassivityController::step(const Eigen::Vector3d& F, const Eigen::Vector3d& v,
                                                    double T) noexcept {
  Step out;
  out.force_W_N = F;
  if (!F.allFinite() || !v.allFinite() || !(T > 0.0) || !std::isfinite(T)) return out;
  // Observer with the unmodified force (H&R eq. 9, impedance form).
  const double e_obs = energy_J_ - T * F.dot(v);
  const double v2 = v.squaredNorm();
  if (e_obs < 0.0 && v2 >= options_.min_speed_mps * options_.min_speed_mps) {
    // Controller (H&R eq. 10): the damper that dissipates the deficit in this tick.
    out.alpha_Ns_per_m = std::min(-e_obs / (T * v2), options_.max_damping_Ns_per_m);
    out.force_W_N = F - out.alpha_Ns_per_m * v;
    out.dissipated_J = out.alpha_Ns_per_m * v2 * T;
  }
  energy_J_ = e_obs + out.dissipated_J;  // = -T sum F' . v
  dissipated_J_ += out.dissipated_J;
  return out;
}

void PassivityController::reset() noexcept {
  energy_J_ = 0.0;
  dissipated_J_ = 0.0;
}

}  // namespace vh::haptics
