// One passivity-controlled coupling port (vh/runtime/passivity_port.h).
#include "vh/runtime/passivity_port.h"

#include <algorithm>
#include <cmath>

namespace vh::runtime {

namespace {

/// The controller's options for a port of stiffness `k` on a device rated `limit`: told the
/// stiffness (its damper cap) and, when the device states one, a schedule floored at the rating.
/// The default delay (one tick) is the device models' (app/simulation device_catalog.h).
haptics::PassivityOptions portOptions(double k, double limit) noexcept {
  haptics::PassivityOptions o;
  o.port_stiffness = k > 0.0 && std::isfinite(k) ? k : 0.0;
  if (o.port_stiffness > 0.0 && limit > 0.0 && std::isfinite(limit)) o.min_gain = std::min(1.0, limit / o.port_stiffness);
  return o;
}

}  // namespace

void PassivityPort::configure(double stiffness, double device_limit) noexcept {
  stiffness_ = stiffness;
  device_limit_ = device_limit;
  h_ = 1.0;
  free_ticks_ = 0;
  rebuild();
}

void PassivityPort::rebuild() noexcept {
  controller_ = haptics::PassivityController(portOptions(h_ * stiffness_, device_limit_));
  stale_ = false;
}

void PassivityPort::restart() noexcept {
  free_ticks_ = 0;
  rebuild();
}

void PassivityPort::setStiffness(double stiffness, double device_limit) noexcept {
  if (stiffness == stiffness_ && device_limit == device_limit_) return;
  const double k_eff = h_ * stiffness_;
  if (stiffness > 0.0 && std::isfinite(stiffness) && k_eff > 0.0 && k_eff <= stiffness) {
    h_ = k_eff / stiffness;  // K_eff unchanged: the controller's options still hold
  } else {
    h_ = 1.0;  // softer (or no spring): applies at once, the controller is rebuilt in free space
    stale_ = true;
  }
  if (device_limit != device_limit_) stale_ = true;
  stiffness_ = stiffness;
  device_limit_ = device_limit;
}

haptics::PassivityController::Step PassivityPort::step(const Eigen::Vector3d& effort_W, const Eigen::Vector3d& step_W,
                                                       double dt_s, double stored_J) noexcept {
  const haptics::PassivityController::Step out = controller_.step(h_ * effort_W, step_W, dt_s, h_ * stored_J);
  free_ticks_ = effort_W.squaredNorm() == 0.0 ? free_ticks_ + 1 : 0;
  const double g = controller_.gain();
  // Free space for longer than the commands in flight: the spring holds nothing (the observed
  // reserve is capped at zero), so the controller can be rebuilt for the effective stiffness
  // with its gain folded into h. A deficit still pending (the hand left the wall faster than
  // the delayed command let go) is dropped with it: a reconfiguration that kept it needs
  // PassivityController to take new options without a reset.
  if (free_ticks_ > controller_.options().delay_ticks && (h_ < 1.0 || g < 1.0 || stale_) && std::isfinite(dt_s) &&
      dt_s > 0.0) {
    double h = h_ * g;
    if (g >= 1.0) h += dt_s / controller_.options().gain_recovery_s;  // the controller did not recover this tick
    h_ = std::clamp(h, 0.0, 1.0);
    if (!(h_ > 0.0)) h_ = 1e-3;
    rebuild();
  }
  return out;
}

}  // namespace vh::runtime
