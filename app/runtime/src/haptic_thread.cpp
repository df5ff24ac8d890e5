#include "vh/runtime/haptic_thread.h"

#include <pthread.h>
#include <sched.h>
#include <sys/mman.h>
#include <sys/prctl.h>
#include <sys/resource.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <stdexcept>

#include <nlohmann/json.hpp>

namespace vh::runtime {

namespace {

constexpr std::int64_t kNsPerS = 1'000'000'000;

std::int64_t toNs(const timespec& t) noexcept { return static_cast<std::int64_t>(t.tv_sec) * kNsPerS + t.tv_nsec; }

timespec fromNs(std::int64_t ns) noexcept {
  timespec t{};
  t.tv_sec = static_cast<time_t>(ns / kNsPerS);
  t.tv_nsec = static_cast<long>(ns % kNsPerS);
  return t;
}

std::int64_t monotonicNs() noexcept {
  timespec t{};
  clock_gettime(CLOCK_MONOTONIC, &t);
  return toNs(t);
}

/// Best effort real-time set-up of the calling thread (devices.md, "Servo loop timing"): 1 ns
/// timer slack, SCHED_FIFO 80 and, when that worked, mlockall. Every failure (EPERM in a
/// container or for a normal user) silently leaves the default.
void configureRealtime(bool& fifo, bool& locked) noexcept {
  prctl(PR_SET_TIMERSLACK, 1UL, 0UL, 0UL, 0UL);
  sched_param param{};
  param.sched_priority = 80;
  fifo = pthread_setschedparam(pthread_self(), SCHED_FIFO, &param) == 0;
  locked = false;
  if (!fifo) return;
  // Lock only when the limit cannot make later allocations fail (root or unlimited).
  rlimit limit{};
  if (geteuid() != 0 && (getrlimit(RLIMIT_MEMLOCK, &limit) != 0 || limit.rlim_cur != RLIM_INFINITY)) return;
#ifdef MCL_ONFAULT
  // ONFAULT: resident pages are locked now, later ones when first touched (no pre-faulting of
  // large reservations such as thread stacks).
  locked = mlockall(MCL_CURRENT | MCL_FUTURE | MCL_ONFAULT) == 0;
  if (!locked && errno == EINVAL) locked = mlockall(MCL_CURRENT | MCL_FUTURE) == 0;
#else
  locked = mlockall(MCL_CURRENT | MCL_FUTURE) == 0;
#endif
}

}  // namespace

HapticThread::HapticThread(std::unique_ptr<haptics::HapticRenderer> renderer, std::shared_ptr<Device> device,
                           double isovalue, double servo_rate_Hz)
    : renderer_(std::move(renderer)),
      device_(std::move(device)),
      period_s_(servo_rate_Hz > 0.0 ? 1.0 / servo_rate_Hz : 0.0),
      isovalue_(isovalue),
      gain_linear_(0.0),
      gain_angular_(0.0) {
  if (!renderer_) throw std::invalid_argument("HapticThread: no renderer");
  if (!device_) throw std::invalid_argument("HapticThread: no device");
  if (!(servo_rate_Hz > 0.0) || !std::isfinite(servo_rate_Hz)) {
    throw std::invalid_argument("HapticThread: servo rate must be a positive number of Hz");
  }
  const haptics::CouplingGains gains = renderer_->coupling().gains();
  gain_linear_.store(gains.linear_N_per_m);
  gain_angular_.store(gains.angular_Nm_per_rad);
  // Readers see the initial proxy/device pose before the first tick.
  HapticSnapshot& first = snapshots_.writeSlot();
  first.X_WP = renderer_->proxyPose();
  first.X_WD = renderer_->proxyPose();
  first.isovalue = isovalue;
  snapshots_.publish();
}

HapticThread::~HapticThread() { stop(); }

void HapticThread::setGains(const haptics::CouplingGains& gains) noexcept {
  gain_linear_.store(gains.linear_N_per_m, std::memory_order_relaxed);
  gain_angular_.store(gains.angular_Nm_per_rad, std::memory_order_relaxed);
  gains_dirty_.store(true, std::memory_order_release);
  if (recorder_.load(std::memory_order_acquire) == nullptr) return;
  try {
    const haptics::CouplingGains applied = clampGains(gains, device_->limits());
    nlohmann::json d;
    d["linear_N_per_m"] = applied.linear_N_per_m;
    d["angular_Nm_per_rad"] = applied.angular_Nm_per_rad;
    d["requested"] = {{"linear_N_per_m", gains.linear_N_per_m}, {"angular_Nm_per_rad", gains.angular_Nm_per_rad}};
    recordEvent("gains", d.dump());
  } catch (...) {  // NOLINT(bugprone-empty-catch): the event is best effort, the gains are set
  }
}

void HapticThread::recordEvent(const std::string& type, const std::string& detail_json) {
  RecordingWriter* recorder = recorder_.load(std::memory_order_acquire);
  if (recorder == nullptr) return;
  RecordingEvent event;
  event.type = type;
  event.detail_json = detail_json;
  const std::uint64_t first = first_recorded_tick_.load(std::memory_order_acquire);
  const std::uint64_t latest = latest_recorded_tick_.load(std::memory_order_acquire);
  event.tick = latest;
  event.time_s = first != 0 && latest >= first ? static_cast<double>(latest - first) * period_s_ : 0.0;
  recorder->addEvent(event);
}

void HapticThread::start() {
  if (thread_.joinable()) return;
  stop_requested_.store(false, std::memory_order_release);
  running_.store(true, std::memory_order_release);
  try {
    thread_ = std::thread([this] { loop(); });
  } catch (...) {
    running_.store(false, std::memory_order_release);
    throw;
  }
}

void HapticThread::stop() {
  if (!thread_.joinable()) return;
  stop_requested_.store(true, std::memory_order_release);
  thread_.join();
}

void HapticThread::loop() noexcept {
  bool fifo = false, locked = false;
  configureRealtime(fifo, locked);
  fifo_.store(fifo, std::memory_order_release);
  memory_locked_.store(locked, std::memory_order_release);

  const std::int64_t period_ns = std::max<std::int64_t>(1, std::llround(period_s_ * 1e9));
  const int ramp_ticks = std::max(1, static_cast<int>(std::lround(0.050 / period_s_)));  // ~50 ms
  int ramp_left = -1;  // -1: not stopping

  std::uint64_t tick = 0;
  std::uint64_t deadline_misses = 0;
  std::uint64_t bad_samples = 0;
  std::uint64_t record_first_tick = 0;  // tick of the current recording's first record
  RecordingWriter* active_recorder = nullptr;  // the recorder of the current recording
  // Rolling statistics over windows of one second; until the first window closes, the running
  // window's values are published.
  std::int64_t window_start_ns = monotonicNs();
  std::uint64_t window_ticks = 0;
  double window_sum_us = 0.0, window_max_us = 0.0;
  double rate_Hz = 0.0, mean_us = 0.0, max_us = 0.0;
  bool have_window = false;

  DeviceSample sample;
  haptics::Pose X_WD_last = renderer_->proxyPose();
  std::int64_t next_ns = monotonicNs();
  std::int64_t previous_begin_ns = next_ns;

  // Every command goes through the one safety layer: the device's limits, engage gate, ramp,
  // watchdog, actuated DOF (device.h, ForceSafety). Coupling gains are kept within the device's
  // stable stiffness.
  ForceSafety safety(device_->limits(), device_->safetyPolicy(), device_->actuatedDof());
  safety.enable();
  haptics::CouplingGains requested_gains = renderer_->coupling().gains();
  haptics::CouplingGains applied_gains = clampGains(requested_gains, safety.limits());
  renderer_->setGains(applied_gains);

  while (true) {
    if (ramp_left < 0 && stop_requested_.load(std::memory_order_acquire)) ramp_left = ramp_ticks;
    if (ramp_left == 0) break;

    // Absolute-deadline sleep; on an overrun of more than one period count a miss and resync
    // (no catch-up ticks).
    next_ns += period_ns;
    const timespec deadline = fromNs(next_ns);
    while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &deadline, nullptr) == EINTR) {
    }
    const std::int64_t begin_ns = monotonicNs();
    const double tick_interval_s = 1e-9 * static_cast<double>(begin_ns - previous_begin_ns);
    previous_begin_ns = begin_ns;
    const bool missed = begin_ns - next_ns > period_ns;
    if (missed) {
      ++deadline_misses;
      next_ns = begin_ns;
    }

    // 1. Device sample (a non-finite pose is no sample).
    const bool ok = device_->read(sample) && sample.valid && sample.X_WD.allFinite();
    // 2. Pending GUI commands; gains within the device's current limits (a workspace scale
    //    change alters them).
    safety.setLimits(device_->limits());
    if (gains_dirty_.exchange(false, std::memory_order_acq_rel)) {
      requested_gains = {gain_linear_.load(std::memory_order_relaxed), gain_angular_.load(std::memory_order_relaxed)};
    }
    const haptics::CouplingGains gains = clampGains(requested_gains, safety.limits());
    if (gains.linear_N_per_m != applied_gains.linear_N_per_m ||
        gains.angular_Nm_per_rad != applied_gains.angular_Nm_per_rad) {
      applied_gains = gains;
      renderer_->setGains(applied_gains);
    }
    const double isovalue = isovalue_.load(std::memory_order_relaxed);
    // 3. Render.
    Eigen::Vector3d force_W_N = Eigen::Vector3d::Zero();
    Eigen::Vector3d torque_W_Nm = Eigen::Vector3d::Zero();
    if (ok) {
      X_WD_last = sample.X_WD;
      const haptics::TickOutput out = renderer_->tick(sample.X_WD, isovalue);
      if (out.stats.bad_input) ++bad_samples;
      force_W_N = out.force_W_N;
      torque_W_Nm = out.torque_W_Nm;
    } else {
      ++bad_samples;  // watchdog: nothing usable from the device, no force
    }
    if (ramp_left > 0) {
      --ramp_left;
      const double scale = static_cast<double>(ramp_left) / ramp_ticks;  // reaches 0 on the last tick
      force_W_N *= scale;
      torque_W_Nm *= scale;
    }
    // 4. Safety layer, then command (never NaN, never beyond the device's limits).
    SafetyInput safety_in;
    safety_in.sample_ok = ok;
    safety_in.sample_time_s = sample.time_s;
    safety_in.connection = sample.connection;
    safety_in.tick_interval_s = tick_interval_s;
    safety_in.force_W_N = force_W_N;
    safety_in.torque_W_Nm = torque_W_Nm;
    const bool nonfinite = !force_W_N.allFinite() || !torque_W_Nm.allFinite();
    const std::uint64_t zeroed_before = safety.stats().zeroed_ticks;
    const Eigen::Vector3d force_rendered_W_N = force_W_N;
    const Eigen::Vector3d torque_rendered_W_Nm = torque_W_Nm;
    safety.step(safety_in, force_W_N, torque_W_Nm);
    // Bit comparison (a NaN that was zeroed counts as changed).
    const bool limited = std::memcmp(force_rendered_W_N.data(), force_W_N.data(), 3 * sizeof(double)) != 0 ||
                         std::memcmp(torque_rendered_W_Nm.data(), torque_W_Nm.data(), 3 * sizeof(double)) != 0;
    device_->command(force_W_N, torque_W_Nm);
    const bool zeroed = safety.stats().zeroed_ticks != zeroed_before;
    ++tick;

    // 5. Statistics.
    const std::int64_t end_ns = monotonicNs();
    const double tick_us = 1e-3 * static_cast<double>(end_ns - begin_ns);

    // 6. Recording (lock-free push; a full ring drops the record and counts it).
    RecordingWriter* const recorder = recorder_.load(std::memory_order_acquire);
    if (recorder != active_recorder) {  // a new recording starts its clock at its first tick
      active_recorder = recorder;
      record_first_tick = tick;
      first_recorded_tick_.store(tick, std::memory_order_release);
    }
    if (recorder != nullptr) {
      TickRecord rec;
      rec.time_s = static_cast<double>(tick - record_first_tick) * period_s_;
      rec.tick = tick;
      const haptics::Pose X_WP_now = renderer_->proxyPose();
      const haptics::Pose& X_WD_rec = ok ? sample.X_WD : X_WD_last;
      for (int k = 0; k < 3; ++k) {
        rec.p_WD_m[k] = X_WD_rec.p_AB_m[k];
        rec.p_WP_m[k] = X_WP_now.p_AB_m[k];
        rec.force_W_N[k] = force_W_N[k];
        rec.torque_W_Nm[k] = torque_W_Nm[k];
      }
      rec.q_WD[0] = X_WD_rec.R_AB.w(); rec.q_WD[1] = X_WD_rec.R_AB.x();
      rec.q_WD[2] = X_WD_rec.R_AB.y(); rec.q_WD[3] = X_WD_rec.R_AB.z();
      rec.q_WP[0] = X_WP_now.R_AB.w(); rec.q_WP[1] = X_WP_now.R_AB.x();
      rec.q_WP[2] = X_WP_now.R_AB.y(); rec.q_WP[3] = X_WP_now.R_AB.z();
      rec.isovalue = isovalue;
      rec.tick_time_s = 1e-9 * static_cast<double>(end_ns - begin_ns);
      rec.contacts = static_cast<std::uint32_t>(renderer_->contacts().size());
      rec.flags = (rec.contacts > 0 ? kRecordFlagContact : 0u) | (ok ? 0u : kRecordFlagBadSample) |
                  (missed ? kRecordFlagDeadlineMiss : 0u) | (zeroed ? kRecordFlagForceZeroed : 0u) |
                  (nonfinite ? kRecordFlagNonFinite : 0u) | (ramp_left >= 0 ? kRecordFlagStopping : 0u) |
                  (limited || zeroed ? kRecordFlagForceLimited : 0u) |
                  (device_->connected() ? 0u : kRecordFlagDeviceDisconnected);
      (void)recorder->push(rec);
      latest_recorded_tick_.store(tick, std::memory_order_release);
    }
    ++window_ticks;
    window_sum_us += tick_us;
    window_max_us = std::max(window_max_us, tick_us);
    const std::int64_t window_ns = end_ns - window_start_ns;
    if (window_ns >= kNsPerS || !have_window) {
      rate_Hz = window_ns > 0 ? static_cast<double>(window_ticks) * 1e9 / static_cast<double>(window_ns) : 0.0;
      mean_us = window_sum_us / static_cast<double>(window_ticks);
      max_us = window_max_us;
    }
    if (window_ns >= kNsPerS) {
      have_window = true;
      window_start_ns = end_ns;
      window_ticks = 0;
      window_sum_us = 0.0;
      window_max_us = 0.0;
    }

    // 6. Snapshot.
    HapticSnapshot& snap = snapshots_.writeSlot();
    snap.tick = tick;
    snap.X_WP = renderer_->proxyPose();
    snap.X_WD = X_WD_last;
    snap.force_W_N = force_W_N;
    snap.torque_W_Nm = torque_W_Nm;
    snap.isovalue = isovalue;
    const auto contacts = renderer_->contacts();
    snap.contacts = static_cast<int>(contacts.size());
    const int shown = std::min<int>(snap.contacts, HapticSnapshot::kMaxContactsShown);
    snap.contacts_shown = shown;
    for (int i = 0; i < shown; ++i) {
      snap.contact_p_W_m[static_cast<std::size_t>(i)] = contacts[static_cast<std::size_t>(i)].p_W_m;
      snap.contact_n_W[static_cast<std::size_t>(i)] = contacts[static_cast<std::size_t>(i)].n_W;
    }
    snap.servo_rate_Hz = rate_Hz;
    snap.mean_tick_us = mean_us;
    snap.max_tick_us = max_us;
    snap.deadline_misses = deadline_misses;
    snap.bad_device_samples = bad_samples;
    snapshots_.publish();
  }

  device_->command(Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero());
  if (locked) munlockall();
  running_.store(false, std::memory_order_release);
}

}  // namespace vh::runtime
