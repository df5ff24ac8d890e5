#include "vh/haptics/haptic_renderer.h"

#include <chrono>
#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace vh::haptics {

HapticRenderer::HapticRenderer(std::shared_ptr<const ScalarVolume> volume, std::shared_ptr<const ToolModel> tool,
                               const RendererOptions& options, const Pose& X_WP_initial, double isovalue)
    : volume_(std::move(volume)),
      tool_(std::move(tool)),
      options_(options),
      collision_((volume_ && !volume_->empty()) ? *volume_ : throw std::invalid_argument("HapticRenderer: no volume"),
                 tool_ ? *tool_ : throw std::invalid_argument("HapticRenderer: no tool"), options.epsilon_m,
                 256, options.detection_mode, options.segment_fraction, options.segment_test),
      solver_(),
      coupling_(options.gains),
      X_WP_(X_WP_initial),
      last_isovalue_(isovalue) {
  if (!X_WP_initial.allFinite()) throw std::invalid_argument("HapticRenderer: the initial proxy pose is not finite");
  if (!std::isfinite(isovalue)) throw std::invalid_argument("HapticRenderer: the isovalue is not finite");
  if (options.max_contacts < 1 || options.max_contacts > 256)
    throw std::invalid_argument("HapticRenderer: max_contacts " + std::to_string(options.max_contacts) +
                                " must be in [1, 256]");
  X_WP_.R_AB.normalize();
  solver_.setGains(options.gains);
  collision_.setContactCap(static_cast<std::size_t>(options.max_contacts));
  collision_.setWorkBudget(options.work_budget);
  collision_.updateEmbedded(X_WP_, isovalue);
}

void HapticRenderer::resetProxy(const Pose& X_WP) noexcept {
  if (!X_WP.allFinite()) return;
  X_WP_ = X_WP;
  X_WP_.R_AB.normalize();
  collision_.clearContacts();
  embedded_scan_needed_ = true;
}

TickOutput HapticRenderer::tick(const Pose& X_WD_in, double isovalue) noexcept {
  using Clock = std::chrono::steady_clock;
  const auto start = Clock::now();
  TickOutput out;
  collision_.resetSampleCount();

  // Validate the device sample: zero force, proxy in place, counted (bad input never throws).
  Pose X_WD = X_WD_in;
  const double qn = X_WD.R_AB.norm();
  const bool finite = X_WD.allFinite() && std::isfinite(isovalue);
  if (!finite || std::abs(qn - 1.0) > 1e-3 ||
      (X_WD.p_AB_m - X_WP_.p_AB_m).norm() > options_.max_device_distance_m) {
    ++bad_inputs_;
    last_motion_ = RigidMotion::FromVelocity(X_WP_, tool_->mass.p_TCm_m, Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero());
    last_t_ = 0.0;
    out.X_WP = X_WP_;
    out.stats.bad_input = true;
    out.stats.contacts = static_cast<int>(collision_.contacts().size());
    out.stats.exec_time_us = std::chrono::duration<double, std::micro>(Clock::now() - start).count();
    return out;
  }
  X_WD.R_AB.coeffs() /= qn;

  const auto us_since = [](Clock::time_point a, Clock::time_point b) {
    return std::chrono::duration<double, std::micro>(b - a).count();
  };
  // A new isovalue moves the surface under the proxy: points it swallowed are embedded and
  // released once outside again (see haptics/README.md, "Isovalue changes").
  if (embedded_scan_needed_ || isovalue != last_isovalue_) {
    collision_.updateEmbedded(X_WP_, isovalue);
    last_isovalue_ = isovalue;
    embedded_scan_needed_ = false;
  } else {
    collision_.releaseEmbedded(X_WP_, isovalue);
  }

  const MassProperties& mass = tool_->mass;
  // Step 2: verify and prune the contact set.
  collision_.pruneContacts(X_WP_, X_WD, isovalue);
  auto phase = Clock::now();
  out.stats.prune_us = us_since(start, phase);
  // Steps 1 and 3: unconstrained, then constrained motion (Gauss' principle); step 4:
  // collision detection along the constrained path. When a contact blocks its own tangent step
  // (its eq. 1 normal disagrees with the trilinear surface), its normal is refined and steps
  // 3-4 are solved again, at most twice per tick.
  // The stand-off lift (an option, off by default) is a recovery: only after a tick that was
  // blocked almost at once (a lift on every tick drove a hook hanging from one contact into a
  // 2-cycle), and never while the surface has swallowed part of the tool (a moving surface must
  // not push the proxy against the user).
  const bool lift = blocked_last_tick_ && collision_.embeddedCount() == 0;
  const double standoff_m = lift ? options_.standoff_fraction * collision_.epsilon_m() : 0.0;
  RigidMotion motion;
  SweepResult hit;
  for (int attempt = 0; attempt < 3; ++attempt) {
    motion = solver_.constrainedMotion(X_WP_, X_WD, mass, collision_.contacts(), standoff_m);
    {
      const auto now = Clock::now();
      out.stats.solve_us += us_since(phase, now);
      phase = now;
    }
    // After a tick the work budget cut, a shorter step along the same constrained motion (the
    // velocity limit of section 2.3): fewer segments, smaller balls, so the sweep can finish
    // and the proxy make progress; the step doubles back after each tick that finishes.
    if (motion_scale_ < 1.0)
      motion = RigidMotion::FromVelocity(X_WP_, mass.p_TCm_m, motion.v_W_m() * motion_scale_,
                                         motion.omega_W_rad() * motion_scale_);
    hit = collision_.sweep(motion, isovalue);
    {
      const auto now = Clock::now();
      out.stats.sweep_us += us_since(phase, now);
      phase = now;
    }
    if (attempt == 2 || !collision_.refineStuckContact(motion, hit)) break;
  }
  blocked_last_tick_ = hit.hit_point >= 0 && hit.t < 0.01;
  if (hit.budget_cut) {
    motion_scale_ = std::max(1.0 / 4096.0, 0.5 * motion_scale_);
  } else if (motion_scale_ < 1.0) {
    motion_scale_ = std::min(1.0, 2.0 * motion_scale_);
  }
  // Step 5: move the proxy to the first contact (or the target).
  X_WP_ = motion.poseAt(hit.t);
  last_motion_ = motion;
  last_t_ = hit.t;
  collision_.refreshPositions(X_WP_);
  if (hit.hit_point >= 0) collision_.addContactsAt(motion, hit, isovalue);
  out.stats.contacts_us = us_since(phase, Clock::now());
  // Step 6: virtual coupling.
  const Wrench w = coupling_.compute(X_WP_, X_WD, mass);

  out.X_WP = X_WP_;
  out.force_W_N = w.force_W_N;
  out.torque_W_Nm = w.torque_W_Nm;
  out.stats.contacts = static_cast<int>(collision_.contacts().size());
  out.stats.volume_samples = collision_.sampleCount();
  out.stats.box_queries = collision_.boxQueryCount();
  out.stats.cells = collision_.cellCount();
  out.stats.work = collision_.work();
  out.stats.budget_cut = hit.budget_cut;
  out.stats.time_of_contact = hit.t;
  out.stats.exec_time_us = std::chrono::duration<double, std::micro>(Clock::now() - start).count();
  return out;
}

}  // namespace vh::haptics
