#include "vh/runtime/device.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>

namespace vh::runtime {

namespace {

double steadySeconds() noexcept {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

/// `v` scaled down to norm `max_norm` when longer (direction kept). @return true when clamped.
bool clampNorm(Eigen::Vector3d& v, double max_norm) noexcept {
  if (!(max_norm >= 0.0)) max_norm = 0.0;  // NaN limit: nothing passes
  const double n = v.norm();
  if (n <= max_norm) return false;
  if (max_norm == 0.0 || !std::isfinite(n)) {
    v.setZero();
  } else {
    v *= max_norm / n;
  }
  return true;
}

/// How long the device's samples have not changed: `stale_s` grows by the tick's `dt_s` while
/// the sample time repeats; a new sample time resets it and ends a silence.
inline void trackStaleness(double sample_time_s, double last_sample_time_s, double dt_s, double& stale_s,
                           bool& silent) noexcept {
  if (sample_time_s == last_sample_time_s) {
    stale_s += dt_s;
  } else {
    stale_s = 0.0;
    silent = false;
  }
}

/// Zeroes the parts of the command the device does not actuate. @return true when a non-zero
/// part was dropped.
inline bool dropUnactuated(DofMask actuated, Eigen::Vector3d& f, Eigen::Vector3d& tau) noexcept {
  bool dropped = false;
  if ((actuated & kDofTranslation) != kDofTranslation) {
    dropped = dropped || !f.isZero(0.0);
    f.setZero();
  }
  if ((actuated & kDofRotation) != kDofRotation) {
    dropped = dropped || !tau.isZero(0.0);
    tau.setZero();
  }
  return dropped;
}

/// The fault hold's output scale after `hold_age_s` of faults: 1 falling linearly to 0 over
/// `fault_hold_s`; 0 at once on a stall or without a (finite, positive) hold.
inline double faultHoldScale(double hold_age_s, double fault_hold_s, bool stall) noexcept {
  const double hold_s = std::isfinite(fault_hold_s) ? std::max(fault_hold_s, 0.0) : 0.0;
  return stall || !(hold_s > 0.0) ? 0.0 : std::max(0.0, 1.0 - hold_age_s / hold_s);
}

/// Gain g limited to [0, max]; non-finite or negative gains become 0.
double clampGain(double g, double max) noexcept {
  if (!std::isfinite(g) || g < 0.0) return 0.0;
  if (max >= 0.0 && g > max) return max;  // also false for a NaN max: keep g
  return g;
}

}  // namespace

haptics::CouplingGains clampGains(const haptics::CouplingGains& gains, const DeviceLimits& limits) noexcept {
  // With the passivity controller on, up to kPassivityStiffnessHeadroom times the device's rating:
  // its stiffness schedule renders no more than the device takes, never less than its rating.
  const double headroom = gains.passivity_control ? kPassivityStiffnessHeadroom : 1.0;
  return {clampGain(gains.linear_N_per_m, headroom * limits.max_linear_stiffness_N_per_m),
          clampGain(gains.angular_Nm_per_rad, headroom * limits.max_angular_stiffness_Nm_per_rad),
          gains.passivity_control};
}

// ---- ForceSafety --------------------------------------------------------------------------------

void ForceSafety::configure(const DeviceLimits& limits, const SafetyPolicy& policy, DofMask actuated) noexcept {
  limits_ = limits;
  policy_ = policy;
  actuated_ = actuated;
}

void ForceSafety::enable() noexcept {
  if (state_ == State::kOff) rearm();
}

void ForceSafety::rearm() noexcept {
  state_ = State::kWaitingForSmallForce;
  ramp_elapsed_s_ = 0.0;
  outage_ = false;
  hold_age_s_ = 0.0;
  held_force_W_N_.setZero();
  held_torque_W_Nm_.setZero();
  ramp_from_force_W_N_.setZero();
  ramp_from_torque_W_Nm_.setZero();
}

double ForceSafety::rampFactor() const noexcept {
  switch (state_) {
    case State::kEngaged:
      return 1.0;
    case State::kRamping:
      return policy_.ramp_time_s > 0.0 ? std::clamp(ramp_elapsed_s_ / policy_.ramp_time_s, 0.0, 1.0) : 1.0;
    default:
      return 0.0;
  }
}

ForceSafety::TickKind ForceSafety::classifyTick(const SafetyInput& in, double dt) noexcept {
  TickKind kind;
  if (!in.sample_ok) {
    ++stats_.missing_samples;
    kind.fault = true;
  } else {
    if (in.reseeded) kind.gate = true;
    if (!have_connection_ || in.connection != connection_) {
      if (have_connection_) kind.gate = true;  // a new connection: the hand may be anywhere
      connection_ = in.connection;
      have_connection_ = true;
      stale_s_ = 0.0;
      silent_ = false;
    }
    trackStaleness(in.sample_time_s, last_sample_time_s_, dt, stale_s_, silent_);
    last_sample_time_s_ = in.sample_time_s;
    if (stale_s_ > policy_.silent_s) {
      if (!silent_) ++stats_.silent_trips;
      silent_ = true;
      kind.fault = true;
    }
  }
  if (in.tick_interval_s > policy_.watchdog_s) {
    ++stats_.watchdog_trips;
    kind.fault = true;
    kind.stall = in.tick_interval_s > policy_.silent_s;
  }
  if (!in.force_W_N.allFinite() || !in.torque_W_Nm.allFinite()) {
    ++stats_.nonfinite_commands;
    kind.gate = true;
  }
  return kind;
}

void ForceSafety::holdLastCommand(double period_s, bool stall, Eigen::Vector3d& force_W_N,
                                  Eigen::Vector3d& torque_W_Nm) noexcept {
  hold_age_s_ += period_s;
  const double scale = faultHoldScale(hold_age_s_, policy_.fault_hold_s, stall);
  if (scale > 0.0 && state_ != State::kWaitingForSmallForce) {
    force_W_N = scale * held_force_W_N_;
    torque_W_Nm = scale * held_torque_W_Nm_;
    ++stats_.held_ticks;
  } else {
    ++stats_.zeroed_ticks;
  }
  if (scale == 0.0 && !outage_ && state_ != State::kWaitingForSmallForce) {
    // Re-armed for an outage: good ticks ramp up from where the output is now (zero).
    outage_ = true;
    ++stats_.outages;
    state_ = State::kRamping;
    ramp_elapsed_s_ = 0.0;
    ramp_from_force_W_N_.setZero();
    ramp_from_torque_W_Nm_.setZero();
  }
}

bool ForceSafety::passEngageGate(const Eigen::Vector3d& f, const Eigen::Vector3d& tau) noexcept {
  if (state_ != State::kWaitingForSmallForce) return true;
  if (f.norm() > policy_.engage_force_N || tau.norm() > policy_.engage_torque_Nm) return false;
  state_ = policy_.ramp_time_s > 0.0 ? State::kRamping : State::kEngaged;
  ramp_elapsed_s_ = 0.0;
  ramp_from_force_W_N_.setZero();
  ramp_from_torque_W_Nm_.setZero();
  return true;
}

void ForceSafety::step(const SafetyInput& in, Eigen::Vector3d& force_W_N, Eigen::Vector3d& torque_W_Nm) noexcept {
  ++stats_.ticks;
  force_W_N.setZero();
  torque_W_Nm.setZero();
  const bool enabled = state_ != State::kOff;
  const double dt = std::isfinite(in.tick_interval_s) && in.tick_interval_s > 0.0 ? in.tick_interval_s : 0.0;
  const double period = std::isfinite(in.period_s) && in.period_s > 0.0 ? in.period_s : dt;

  // 1 and 2: what kind of tick this is.
  const TickKind kind = classifyTick(in, dt);
  if (!enabled) {
    ++stats_.zeroed_ticks;
    return;
  }
  if (kind.gate) {
    rearm();
    ++stats_.zeroed_ticks;
    return;
  }
  if (kind.fault) {
    holdLastCommand(period, kind.stall, force_W_N, torque_W_Nm);
    return;
  }
  hold_age_s_ = 0.0;
  outage_ = false;

  // 3. Degrees of freedom the device renders.
  Eigen::Vector3d f = in.force_W_N;
  Eigen::Vector3d tau = in.torque_W_Nm;
  if (dropUnactuated(actuated_, f, tau)) ++stats_.dropped_dof_ticks;

  // 4. Engage gate (on what the device would render, before clamping).
  if (!passEngageGate(f, tau)) {
    ++stats_.zeroed_ticks;
    return;
  }

  // 5. Clamp to the limits.
  const bool clamped_f = clampNorm(f, limits_.max_force_N);
  const bool clamped_t = clampNorm(tau, limits_.max_torque_Nm);
  if (clamped_f || clamped_t) ++stats_.clamped_ticks;

  // 6. Ramp from where it started to the computed command.
  if (state_ == State::kRamping) {
    ramp_elapsed_s_ += dt;
    const double a =
        policy_.ramp_time_s > 0.0 ? std::clamp(ramp_elapsed_s_ / policy_.ramp_time_s, 0.0, 1.0) : 1.0;
    if (a >= 1.0) state_ = State::kEngaged;
    f = ramp_from_force_W_N_ + a * (f - ramp_from_force_W_N_);
    tau = ramp_from_torque_W_Nm_ + a * (tau - ramp_from_torque_W_Nm_);
  }
  force_W_N = f;
  torque_W_Nm = tau;
  held_force_W_N_ = f;
  held_torque_W_Nm_ = tau;
  if (f.isZero(0.0) && tau.isZero(0.0) && !(in.force_W_N.isZero(0.0) && in.torque_W_Nm.isZero(0.0)))
    ++stats_.zeroed_ticks;
}

// ---- WorkspaceMapping ---------------------------------------------------------------------------

haptics::Pose WorkspaceMapping::toWorld(const haptics::Pose& X_BH) const noexcept {
  haptics::Pose X_WD;
  X_WD.p_AB_m = X_WB.p_AB_m + scale * (X_WB.R_AB * X_BH.p_AB_m);
  X_WD.R_AB = (X_WB.R_AB * X_BH.R_AB * R_HD).normalized();
  return X_WD;
}

DeviceLimits WorkspaceMapping::limitsInWorld(const DeviceLimits& d) const noexcept {
  DeviceLimits w = d;
  w.max_linear_stiffness_N_per_m = d.max_linear_stiffness_N_per_m / scale;
  w.max_linear_damping_N_s_per_m = d.max_linear_damping_N_s_per_m / scale;
  w.workspace_radius_m = d.workspace_radius_m * scale;
  w.workspace_centre_m = X_WB.p_AB_m + scale * (X_WB.R_AB * d.workspace_centre_m);
  w.max_speed_m_per_s = d.max_speed_m_per_s * scale;
  return w;
}

bool WorkspaceMapping::valid() const noexcept {
  const auto unitOk = [](const Eigen::Quaterniond& q) {
    return q.coeffs().allFinite() && q.norm() > 1e-9;
  };
  return std::isfinite(scale) && scale > 0.0 && X_WB.p_AB_m.allFinite() && unitOk(X_WB.R_AB) && unitOk(R_HD);
}

void WorkspaceMapping::validate() const {
  if (!std::isfinite(scale) || !(scale > 0.0)) {
    throw std::invalid_argument("workspace mapping: scale must be a finite number > 0");
  }
  if (!X_WB.p_AB_m.allFinite()) throw std::invalid_argument("workspace mapping: offset must be finite");
  if (!X_WB.R_AB.coeffs().allFinite() || !(X_WB.R_AB.norm() > 1e-9)) {
    throw std::invalid_argument("workspace mapping: rotation must be a finite, non-zero quaternion");
  }
  if (!R_HD.coeffs().allFinite() || !(R_HD.norm() > 1e-9)) {
    throw std::invalid_argument("workspace mapping: tool rotation must be a finite, non-zero quaternion");
  }
}

// ---- MappedDevice -------------------------------------------------------------------------------

namespace {
WorkspaceMapping normalised(WorkspaceMapping m) {
  m.validate();
  m.X_WB.R_AB.normalize();
  m.R_HD.normalize();
  return m;
}
}  // namespace

MappedDevice::MappedDevice(std::shared_ptr<Device> raw, const WorkspaceMapping& mapping)
    : raw_(std::move(raw)), gui_mapping_(normalised(mapping)), scale_(gui_mapping_.scale), servo_mapping_(gui_mapping_) {
  if (!raw_) throw std::invalid_argument("MappedDevice: no device");
  mappings_.writeSlot() = gui_mapping_;
  mappings_.publish();
}

void MappedDevice::setMapping(const WorkspaceMapping& mapping) {
  gui_mapping_ = normalised(mapping);
  scale_.store(gui_mapping_.scale, std::memory_order_relaxed);
  mappings_.writeSlot() = gui_mapping_;
  mappings_.publish();
}

WorkspaceMapping MappedDevice::mapping() const { return gui_mapping_; }

DeviceLimits MappedDevice::limits() const noexcept {
  WorkspaceMapping m;
  m.scale = scale_.load(std::memory_order_relaxed);
  return m.limitsInWorld(raw_->limits());
}

bool MappedDevice::read(DeviceSample& sample) noexcept {
  if (mappings_.read(servo_mapping_)) ++mapping_epoch_;
  if (!raw_->read(sample)) return false;
  const haptics::Pose X_BH = sample.X_WD;
  sample.X_WD = servo_mapping_.toWorld(X_BH);
  sample.v_WD_m_per_s = servo_mapping_.linearVelocityToWorld(sample.v_WD_m_per_s);
  sample.w_WD_rad_per_s = servo_mapping_.angularVelocityToWorld(sample.w_WD_rad_per_s);
  sample.connection += mapping_epoch_;  // both only grow: a change of either changes the sum
  return true;
}

void MappedDevice::command(const Eigen::Vector3d& force_W_N, const Eigen::Vector3d& torque_W_Nm) noexcept {
  raw_->command(servo_mapping_.vectorToDevice(force_W_N), servo_mapping_.vectorToDevice(torque_W_Nm));
}

// ---- SimulatedDevice --------------------------------------------------------------------------

SimulatedDevice::SimulatedDevice(const haptics::Pose& X_WD_initial)
    : gui_pose_(X_WD_initial), last_(X_WD_initial), t0_s_(steadySeconds()) {
  poses_.writeSlot() = X_WD_initial;
  poses_.publish();
}

void SimulatedDevice::setPose(const haptics::Pose& X_WD) noexcept {
  gui_pose_ = X_WD;
  poses_.writeSlot() = X_WD;
  poses_.publish();
}

haptics::Pose SimulatedDevice::pose() const noexcept { return gui_pose_; }

bool SimulatedDevice::read(DeviceSample& sample) noexcept {
  const haptics::Pose previous = last_;
  const double previous_time_s = time_s_;
  poses_.read(last_);
  time_s_ = steadySeconds() - t0_s_;
  const double dt = time_s_ - previous_time_s;
  sample.time_s = time_s_;
  sample.X_WD = last_;
  if (have_read_ && dt > 0.0) {
    sample.v_WD_m_per_s = (last_.p_AB_m - previous.p_AB_m) / dt;
    sample.w_WD_rad_per_s = haptics::rotationVector(last_.R_AB * previous.R_AB.conjugate()) / dt;
  } else {
    sample.v_WD_m_per_s.setZero();
    sample.w_WD_rad_per_s.setZero();
  }
  have_read_ = true;
  sample.buttons = 0;
  sample.connection = 0;
  sample.valid = true;
  return true;
}

void SimulatedDevice::command(const Eigen::Vector3d& force_W_N, const Eigen::Vector3d& torque_W_Nm) noexcept {
  commands_.record(force_W_N, torque_W_Nm);
}

// ---- ScriptedDevice ---------------------------------------------------------------------------

ScriptedDevice::ScriptedDevice(Trajectory trajectory, double step_s, std::string source)
    : trajectory_(std::move(trajectory)), step_s_(step_s), source_(std::move(source)) {
  if (trajectory_.empty()) throw std::invalid_argument("ScriptedDevice: empty trajectory");
  if (!(step_s_ > 0.0)) throw std::invalid_argument("ScriptedDevice: step_s must be > 0");
}

std::string ScriptedDevice::name() const {
  return source_.empty() ? std::string("Scripted device") : "Scripted device (" + source_ + ")";
}

bool ScriptedDevice::read(DeviceSample& sample) noexcept {
  const std::uint64_t n = reads_.load(std::memory_order_relaxed);
  const double t = trajectory_.startTime_s() + static_cast<double>(n) * step_s_;
  sample.time_s = t;
  sample.X_WD = trajectory_.poseAt(t, cursor_);
  // Velocities: finite difference over the last step (zero at the start and past the end).
  const double t_prev = t - step_s_;
  if (t_prev >= trajectory_.startTime_s() && t <= trajectory_.endTime_s()) {
    const haptics::Pose X_prev = trajectory_.poseAt(t_prev);
    sample.v_WD_m_per_s = (sample.X_WD.p_AB_m - X_prev.p_AB_m) / step_s_;
    sample.w_WD_rad_per_s = haptics::rotationVector(sample.X_WD.R_AB * X_prev.R_AB.conjugate()) / step_s_;
  } else {
    sample.v_WD_m_per_s.setZero();
    sample.w_WD_rad_per_s.setZero();
  }
  sample.buttons = 0;
  sample.connection = 0;
  sample.valid = true;
  reads_.store(n + 1, std::memory_order_relaxed);
  if (t >= trajectory_.endTime_s()) finished_.store(true, std::memory_order_release);
  return true;
}

void ScriptedDevice::command(const Eigen::Vector3d& force_W_N, const Eigen::Vector3d& torque_W_Nm) noexcept {
  commands_.record(force_W_N, torque_W_Nm);
}

}  // namespace vh::runtime
