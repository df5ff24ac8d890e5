// The coupling and solver threads of vh/runtime/haptic_thread.h.
#include "vh/runtime/haptic_thread.h"

#include "vh/runtime/snapshot_channel.h"

#include "vh/runtime/jam_detector.h"
#include "vh/runtime/placement.h"

#include "vh/haptics/configuration_solver.h"
#include "vh/haptics/passivity_controller.h"
#include "vh/runtime/passivity_port.h"
#include "vh/runtime/realtime.h"
#include "vh/runtime/sample_filter.h"
#include "vh/runtime/sample_ring.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <span>
#include <stdexcept>
#include <thread>

#include <nlohmann/json.hpp>

namespace vh::runtime {

namespace {

constexpr int kCouplingPriority = 80;  // above the solver: on a shared core the coupling preempts it
constexpr int kSolverPriority = 79;

/// Energy the coupling's linear spring holds [J]: 0.5 k_lin |c_D - c_P|^2 = |F|^2 / (2 k_lin)
/// (virtual_coupling.h: F = -k_lin (c_D - c_P)); 0 without a spring.
double linearStoredEnergy_J(const Eigen::Vector3d& force_W_N, double k_lin_N_per_m) noexcept {
  return k_lin_N_per_m > 0.0 ? force_W_N.squaredNorm() / (2.0 * k_lin_N_per_m) : 0.0;
}

/// Energy the coupling's torsional spring holds [J]. Eq. 5 gives tau = -(k_ang / i) I_W dtheta
/// (i = trace(I_Cm) / 3, I_W = R_WP I_Cm_T R_WP^T: virtual_coupling.h), the gradient of
/// 0.5 (k_ang / i) dtheta^T I_W dtheta, which is (i / (2 k_ang)) tau^T I_W^-1 tau. Exact for the
/// quadratic form in the rotation vector; the rotation manifold's curvature is neglected (small
/// angles). Infinity (no cap) when it cannot be computed (e.g. a singular inertia); 0 without a
/// spring.
double angularStoredEnergy_J(const Eigen::Vector3d& torque_W_Nm, const Eigen::Quaterniond& R_WP,
                             const Eigen::Matrix3d& I_Cm_inv_T, double mean_moment_kgm2,
                             double k_ang_Nm_per_rad) noexcept {
  if (!(k_ang_Nm_per_rad > 0.0)) return 0.0;
  const Eigen::Vector3d tau_T = R_WP.conjugate() * torque_W_Nm;
  const double e = mean_moment_kgm2 / (2.0 * k_ang_Nm_per_rad) * tau_T.dot(I_Cm_inv_T * tau_T);
  return std::isfinite(e) && e >= 0.0 ? e : std::numeric_limits<double>::infinity();
}

bool sameGains(const haptics::CouplingGains& a, const haptics::CouplingGains& b) noexcept {
  return a.linear_N_per_m == b.linear_N_per_m && a.angular_Nm_per_rad == b.angular_Nm_per_rad &&
         a.passivity_control == b.passivity_control;
}

/// Solver -> coupling: the proxy pose to couple to.
struct ProxyState {
  haptics::Pose X_WP;
  bool bad_input = false;  ///< The renderer rejected the device pose of the tick that produced it.
  std::uint64_t placements = 0;  ///< Placements the solver had applied (PlacedSample::count).
};

/// A placement asked for by HapticThread::place() (GUI -> coupling thread).
struct Placement {
  haptics::Pose X_WP;
  haptics::Pose X_WD;
};

/// A placement the coupling thread passed on (coupling -> solver): the solver resets its proxy
/// to X_WP before it solves sample number `sample` (or the first one after it that it uses).
struct PlacedSample {
  std::uint64_t count = 0;   ///< Placements passed on so far (this one included).
  std::uint64_t sample = 0;  ///< The number (SampleRing) of the first sample at the placed device pose.
  haptics::Pose X_WP;
};

bool samePoseBits(const haptics::Pose& a, const haptics::Pose& b) noexcept {
  return std::memcmp(a.p_AB_m.data(), b.p_AB_m.data(), 3 * sizeof(double)) == 0 &&
         std::memcmp(a.R_AB.coeffs().data(), b.R_AB.coeffs().data(), 4 * sizeof(double)) == 0;
}

}  // namespace

struct HapticThread::Exchange {
  explicit Exchange(std::size_t ring_capacity) : samples(ring_capacity) {}
  SampleRing samples;
  TripleBuffer<ProxyState> proxy;
  TripleBuffer<Placement> placement;  ///< GUI -> coupling: the latest place() (HapticThread::placement_requests_).
  TripleBuffer<PlacedSample> placed;  ///< Coupling -> solver: the latest placement passed on.
  std::uint64_t placement_requests_at_start = 0;  ///< placement_requests_ when start() was called.
  SnapshotChannel gui;  ///< Both threads -> latestSnapshot().
  /// kRecordFlagForceLimited / ForceZeroed / NonFinite / Stopping of the latest command.
  std::atomic<std::uint32_t> command_flags{0};
  /// kRecordFlagDeadlineMiss when the coupling thread missed since the solver last looked.
  std::atomic<std::uint32_t> sticky_flags{0};
  std::atomic<bool> solver_fifo{false};
  /// The samples a kEverySample solver may fall behind before it skips to the newest.
  std::uint64_t backlog_limit = 1;
  /// The newest sample when start() was called: the solver begins with the one after it. Set by
  /// start() before either thread exists, so the coupling thread's first sample is never taken
  /// for an old one, however late the solver thread gets going.
  std::uint64_t first_sample_after = 0;
};

HapticThread::HapticThread(std::unique_ptr<haptics::HapticRenderer> renderer, std::shared_ptr<Device> device,
                           double isovalue, double servo_rate_Hz, const HapticThreadOptions& options)
    : renderer_(std::move(renderer)),
      device_(std::move(device)),
      period_s_(servo_rate_Hz > 0.0 ? 1.0 / servo_rate_Hz : 0.0),
      solver_period_s_(period_s_),
      every_sample_(true),
      options_(options),
      isovalue_(isovalue),
      gain_linear_(0.0),
      gain_angular_(0.0) {
  if (!renderer_) throw std::invalid_argument("HapticThread: no renderer");
  if (!device_) throw std::invalid_argument("HapticThread: no device");
  if (!(servo_rate_Hz > 0.0) || !std::isfinite(servo_rate_Hz)) {
    throw std::invalid_argument("HapticThread: servo rate must be a positive number of Hz");
  }
  const double solver_rate_Hz = options.solver_rate_Hz == 0.0 ? servo_rate_Hz : options.solver_rate_Hz;
  if (!(solver_rate_Hz > 0.0) || !std::isfinite(solver_rate_Hz)) {
    throw std::invalid_argument("HapticThread: solver rate must be a positive number of Hz (or 0)");
  }
  if (!(options.max_solver_backlog_s > 0.0) || !(options.max_solver_backlog_s <= 10.0)) {
    throw std::invalid_argument("HapticThread: max_solver_backlog_s must be in (0, 10] s");
  }
  solver_period_s_ = 1.0 / solver_rate_Hz;
  const bool equal_rates = solver_rate_Hz == servo_rate_Hz;
  switch (options.solver_input) {
    case SolverInput::kAuto: every_sample_ = equal_rates; break;
    case SolverInput::kLatest: every_sample_ = false; break;
    case SolverInput::kEverySample:
      if (!equal_rates) {
        throw std::invalid_argument("HapticThread: SolverInput::kEverySample needs the solver at the device's rate");
      }
      every_sample_ = true;
      break;
  }
  const auto backlog = static_cast<std::uint64_t>(std::max(1.0, std::round(options.max_solver_backlog_s * servo_rate_Hz)));
  x_ = std::make_unique<Exchange>(static_cast<std::size_t>(backlog) + 16);
  x_->backlog_limit = backlog;

  const haptics::CouplingGains gains = renderer_->coupling().gains();
  gain_linear_.store(gains.linear_N_per_m);
  gain_angular_.store(gains.angular_Nm_per_rad);
  gain_passivity_.store(gains.passivity_control);
  // Readers see the initial proxy/device pose before the first tick.
  ProxyState& proxy = x_->proxy.writeSlot();
  proxy.X_WP = renderer_->proxyPose();
  x_->proxy.publish();
  CouplingSnapshot c;
  c.X_WP = renderer_->proxyPose();
  c.X_WD = renderer_->proxyPose();
  c.timing.nominal_rate_Hz = servo_rate_Hz;
  SolverSnapshot s;
  s.isovalue = isovalue;
  s.timing.nominal_rate_Hz = solver_rate_Hz;
  for (SnapshotChannel* channel : {&x_->gui, options_.monitor.get()}) {
    if (channel == nullptr) continue;
    channel->couplingSlot() = c;
    channel->publishCoupling();
    channel->solverSlot() = s;
    channel->publishSolver();
  }
}

HapticThread::~HapticThread() { stop(); }

void HapticThread::setGains(const haptics::CouplingGains& gains) noexcept {
  // The event's tick is read before the change is published: the solver applies it on a later
  // tick (kRecordFlagGainsApplied), never on this one.
  const std::uint64_t before_tick = latest_recorded_tick_.load(std::memory_order_acquire);
  gain_linear_.store(gains.linear_N_per_m, std::memory_order_relaxed);
  gain_angular_.store(gains.angular_Nm_per_rad, std::memory_order_relaxed);
  gain_passivity_.store(gains.passivity_control, std::memory_order_relaxed);
  gains_dirty_.store(true, std::memory_order_release);
  if (recorder_.load(std::memory_order_acquire) == nullptr) return;
  try {
    const haptics::CouplingGains applied = clampGains(gains, device_->limits());
    nlohmann::json d;
    d["linear_N_per_m"] = applied.linear_N_per_m;
    d["angular_Nm_per_rad"] = applied.angular_Nm_per_rad;
    d["passivity_control"] = applied.passivity_control;
    d["requested"] = {{"linear_N_per_m", gains.linear_N_per_m},
                      {"angular_Nm_per_rad", gains.angular_Nm_per_rad},
                      {"passivity_control", gains.passivity_control}};
    recordEventAt("gains", d.dump(), before_tick);
  } catch (...) {  // NOLINT(bugprone-empty-catch): the event is best effort, the gains are set
  }
}

bool HapticThread::place(const haptics::Pose& X_WP, const haptics::Pose& X_WD) {
  SimulatedDevice* device = device_->simulatedDevice();
  if (device == nullptr || !X_WP.allFinite() || !X_WD.allFinite()) return false;
  // The event first (stamped before the tick that applies it), then the request, then the
  // device: the coupling thread applies the placement on its first sample at X_WD.
  if (recorder_.load(std::memory_order_acquire) != nullptr) {
    try {
      const auto pose = [](const haptics::Pose& X) {
        return nlohmann::json::array({X.p_AB_m.x(), X.p_AB_m.y(), X.p_AB_m.z(), X.R_AB.w(), X.R_AB.x(), X.R_AB.y(), X.R_AB.z()});
      };
      recordEvent("placement", nlohmann::json{{"X_WP", pose(X_WP)}, {"X_WD", pose(X_WD)}}.dump());
    } catch (...) {  // NOLINT(bugprone-empty-catch): the event is best effort, the placement is made
    }
  }
  if (!coupling_thread_.joinable()) {  // no threads to hand it on: the renderer starts there
    renderer_->resetProxy(X_WP);
    ProxyState& proxy = x_->proxy.writeSlot();
    proxy.X_WP = X_WP;
    x_->proxy.publish();
    device->setPose(X_WD);
    return true;
  }
  Placement& slot = x_->placement.writeSlot();
  slot.X_WP = X_WP;
  slot.X_WD = X_WD;
  x_->placement.publish();
  placement_requests_.fetch_add(1, std::memory_order_acq_rel);
  device->setPose(X_WD);
  return true;
}

void HapticThread::recordEvent(const std::string& type, const std::string& detail_json) {
  recordEventAt(type, detail_json, latest_recorded_tick_.load(std::memory_order_acquire));
}

void HapticThread::recordEventAt(const std::string& type, const std::string& detail_json, std::uint64_t latest) {
  RecordingWriter* recorder = recorder_.load(std::memory_order_acquire);
  if (recorder == nullptr) return;
  RecordingEvent event;
  event.type = type;
  event.detail_json = detail_json;
  const std::uint64_t first = first_recorded_tick_.load(std::memory_order_acquire);
  event.tick = latest;
  event.time_s = first != 0 && latest >= first ? static_cast<double>(latest - first) * solver_period_s_ : 0.0;
  recorder->addEvent(event);
}

bool HapticThread::realtimeScheduling() const noexcept {
  return fifo_.load(std::memory_order_acquire) && x_->solver_fifo.load(std::memory_order_acquire);
}

bool HapticThread::latestSnapshot(HapticSnapshot& out) noexcept { return x_->gui.read(out); }

bool HapticThread::placeProxy(const haptics::Pose& X_WP) noexcept {
  if (running() || coupling_thread_.joinable() || recorder_.load(std::memory_order_acquire) != nullptr ||
      !X_WP.allFinite())
    return false;
  renderer_->resetProxy(X_WP);
  ProxyState& proxy = x_->proxy.writeSlot();
  proxy.X_WP = renderer_->proxyPose();
  proxy.bad_input = false;
  x_->proxy.publish();
  return true;
}

void HapticThread::start() {
  if (coupling_thread_.joinable()) return;
  stop_requested_.store(false, std::memory_order_release);
  coupling_done_.store(false, std::memory_order_release);
  running_.store(true, std::memory_order_release);
  x_->first_sample_after = x_->samples.latest();
  // Counted here, not when the coupling thread starts: a place() made just after start() (Touch
  // the Surface at once) is then still new to it.
  x_->placement_requests_at_start = placement_requests_.load(std::memory_order_acquire);
  try {
    solver_thread_ = std::thread([this] { solverLoop(); });
  } catch (...) {
    running_.store(false, std::memory_order_release);
    throw;
  }
  try {
    coupling_thread_ = std::thread([this] { couplingLoop(); });
  } catch (...) {
    coupling_done_.store(true, std::memory_order_release);
    solver_thread_.join();
    running_.store(false, std::memory_order_release);
    throw;
  }
}

bool HapticThread::holdCutting(double timeout_ms) {
  if (options_.drill == nullptr) return false;
  // In the single order of these seq_cst operations: the hold, then this read of the count, then
  // the solver's next increment, then every later tick's read of the hold. So once the count
  // passes `before`, the tick that may have missed the hold has finished (its writes to the
  // field visible here), and every later one sees it.
  cutting_held_.store(true, std::memory_order_seq_cst);
  const std::uint64_t before = solver_ticks_.load(std::memory_order_seq_cst);
  if (!solver_thread_.joinable()) return true;  // no solver thread: nothing cuts
  const auto until = std::chrono::steady_clock::now() + std::chrono::duration<double, std::milli>(timeout_ms);
  while (solver_ticks_.load(std::memory_order_seq_cst) <= before) {
    if (std::chrono::steady_clock::now() > until) {
      releaseCutting();
      return false;
    }
    std::this_thread::sleep_for(std::chrono::microseconds(100));
  }
  return true;
}

void HapticThread::stop() {
  if (!coupling_thread_.joinable()) return;
  stop_requested_.store(true, std::memory_order_release);
  coupling_thread_.join();  // ramps the force down, commands zero, then tells the solver
  coupling_done_.store(true, std::memory_order_release);
  if (solver_thread_.joinable()) solver_thread_.join();
}

namespace {

// ---- Helpers of the servo loops: no allocation, no throw, no lock; inlined into the loops. ----

/// The coupling thread's passivity control (CouplingGains::passivity_control, passivity_port.h):
/// one controller per port, the force with the centre of mass's displacement and the torque with
/// the rotation vector since the previous coupled sample. Their state is kept across gain changes
/// (the rendered stiffness stays continuous) and short faults; they start afresh when the switch
/// turns on and after an outage (ForceSafety re-armed).
struct CouplingPassivity {
  explicit CouplingPassivity(const haptics::MassProperties& mass) noexcept
      : I_Cm_inv_T(mass.I_Cm_T_kgm2.inverse()), mean_moment_kgm2(mass.I_Cm_T_kgm2.trace() / 3.0) {}

  /// Both controllers afresh for `gains` on a device rated `limits`.
  void configure(const haptics::CouplingGains& gains, const DeviceLimits& limits) noexcept {
    force.configure(gains.linear_N_per_m, limits.max_linear_stiffness_N_per_m);
    torque.configure(gains.angular_Nm_per_rad, limits.max_angular_stiffness_Nm_per_rad);
  }

  /// A gain change: the controllers keep their state; the rendered stiffness moves on without a step.
  void setStiffness(const haptics::CouplingGains& gains, const DeviceLimits& limits) noexcept {
    force.setStiffness(gains.linear_N_per_m, limits.max_linear_stiffness_N_per_m);
    torque.setStiffness(gains.angular_Nm_per_rad, limits.max_angular_stiffness_Nm_per_rad);
  }

  /// A coupled tick at the device pose X_WD: with passivity control on, the wrench goes through
  /// both controllers (the hand's motion since the last coupled sample, over the ticks since: a
  /// short fault keeps the controllers' state; the spring's stored energy as the cap). Then
  /// X_WD is the last coupled pose.
  inline void coupled(Eigen::Vector3d& force_W_N, Eigen::Vector3d& torque_W_Nm, const haptics::Pose& X_WD,
                      const haptics::Pose& X_WP, const haptics::MassProperties& mass,
                      const haptics::CouplingGains& gains, double period_s) noexcept {
    if (gains.passivity_control) {
      haptics::Vector6d step_W = haptics::Vector6d::Zero();
      if (have_coupled_last) step_W = haptics::displacement_W(X_WD_coupled_last, X_WD, mass.p_TCm_m);
      const double dt_s = period_s * static_cast<double>(have_coupled_last ? ticks_since_coupled : 1);
      const auto f =
          force.step(force_W_N, step_W.head<3>(), dt_s, linearStoredEnergy_J(force_W_N, gains.linear_N_per_m));
      const auto t = torque.step(
          torque_W_Nm, step_W.tail<3>(), dt_s,
          angularStoredEnergy_J(torque_W_Nm, X_WP.R_AB, I_Cm_inv_T, mean_moment_kgm2, gains.angular_Nm_per_rad));
      force_W_N = f.effort_W;
      torque_W_Nm = t.effort_W;
      if (f.alpha > 0.0) ++active_ticks;
      if (t.alpha > 0.0) ++active_ticks;
      dissipated_J += f.predicted_dissipation_J + t.predicted_dissipation_J;
    }
    X_WD_coupled_last = X_WD;
    have_coupled_last = true;
    ticks_since_coupled = 0;
  }

  /// After the safety layer's step: an outage (a new count in `outages`) breaks the motion history.
  inline void afterSafety(std::uint64_t outages) noexcept {
    if (outages == outages_seen) return;
    outages_seen = outages;
    force.restart();
    torque.restart();
    have_coupled_last = false;
  }

  PassivityPort force;
  PassivityPort torque;
  haptics::Pose X_WD_coupled_last;         ///< The device pose of the last coupled tick.
  bool have_coupled_last = false;          ///< X_WD_coupled_last is valid (no outage since).
  std::uint64_t ticks_since_coupled = 0;
  std::uint64_t outages_seen = 0;
  const Eigen::Matrix3d I_Cm_inv_T;        ///< I_Cm^-1 in T, for the torsional spring's stored energy.
  const double mean_moment_kgm2;
  std::uint64_t active_ticks = 0;          ///< Summed over controller restarts.
  double dissipated_J = 0.0;
};

/// The coupling thread's counters since start() (CouplingSnapshot).
struct CouplingCounts {
  std::uint64_t tick = 0;
  std::uint64_t bad_samples = 0;
  std::uint64_t implausible = 0;
};

/// Applies `gains` (the requested ones within the device's current `limits`) when they differ
/// from `applied`; switching passivity control on starts its controllers afresh at the stiffness
/// rendered so far.
inline void applyGains(const haptics::CouplingGains& gains, const DeviceLimits& limits,
                       haptics::CouplingGains& applied, CouplingPassivity& passivity,
                       haptics::VirtualCoupling& coupling) noexcept {
  if (sameGains(gains, applied)) return;
  if (gains.passivity_control && !applied.passivity_control) {
    // Switched on: afresh, at the stiffness rendered so far (then the step below).
    passivity.configure(applied, limits);
  }
  passivity.setStiffness(gains, limits);
  applied = gains;
  coupling.setGains(applied);
}

/// While stopping, scales the command down linearly over `ramp_ticks` (`ramp_left` > 0: ticks
/// left; it reaches 0 on the last tick).
inline void rampDown(int& ramp_left, int ramp_ticks, Eigen::Vector3d& force_W_N,
                     Eigen::Vector3d& torque_W_Nm) noexcept {
  if (ramp_left <= 0) return;
  --ramp_left;
  const double scale = static_cast<double>(ramp_left) / ramp_ticks;  // reaches 0 on the last tick
  force_W_N *= scale;
  torque_W_Nm *= scale;
}

/// The safety layer's input for a coupling tick.
inline SafetyInput couplingSafetyInput(bool coupled, SampleFilter::Verdict verdict, double period_s,
                                       const DeviceSample& sample, double tick_interval_s,
                                       const Eigen::Vector3d& force_W_N, const Eigen::Vector3d& torque_W_Nm) noexcept {
  SafetyInput in;
  in.sample_ok = coupled;
  in.reseeded = verdict == SampleFilter::Verdict::kReseeded;
  in.period_s = period_s;
  in.sample_time_s = sample.time_s;
  in.connection = sample.connection;
  in.tick_interval_s = tick_interval_s;
  in.force_W_N = force_W_N;
  in.torque_W_Nm = torque_W_Nm;
  return in;
}

/// What the safety layer did to a tick's command.
struct SafetyOutcome {
  bool nonfinite = false;  ///< The command asked for was not finite.
  bool limited = false;    ///< The command sent differs from the one asked for (bit comparison).
  bool zeroed = false;     ///< The safety layer counted the tick as zeroed.
};

/// The command through the safety layer, then to the device (never NaN, never beyond the
/// device's limits); `force_W_N` and `torque_W_Nm` become what was sent.
inline SafetyOutcome commandThroughSafety(ForceSafety& safety, const SafetyInput& safety_in, Device& device,
                                          Eigen::Vector3d& force_W_N, Eigen::Vector3d& torque_W_Nm) noexcept {
  SafetyOutcome o;
  o.nonfinite = !force_W_N.allFinite() || !torque_W_Nm.allFinite();
  const std::uint64_t zeroed_before = safety.stats().zeroed_ticks;
  const Eigen::Vector3d force_rendered_W_N = force_W_N;
  const Eigen::Vector3d torque_rendered_W_Nm = torque_W_Nm;
  safety.step(safety_in, force_W_N, torque_W_Nm);
  // Bit comparison (a NaN that was zeroed counts as changed).
  o.limited = std::memcmp(force_rendered_W_N.data(), force_W_N.data(), 3 * sizeof(double)) != 0 ||
              std::memcmp(torque_rendered_W_Nm.data(), torque_W_Nm.data(), 3 * sizeof(double)) != 0;
  device.command(force_W_N, torque_W_Nm);
  o.zeroed = safety.stats().zeroed_ticks != zeroed_before;
  return o;
}

/// The recording's flags for the latest command (HapticThread::Exchange::command_flags).
inline std::uint32_t commandFlags(const SafetyOutcome& o, bool stopping) noexcept {
  return (o.zeroed ? kRecordFlagForceZeroed : 0u) | (o.nonfinite ? kRecordFlagNonFinite : 0u) |
         (stopping ? kRecordFlagStopping : 0u) | (o.limited || o.zeroed ? kRecordFlagForceLimited : 0u);
}

/// A coupling tick's snapshot (the timing is set by the caller).
inline void fillCouplingSnapshot(CouplingSnapshot& snap, const CouplingCounts& counts, std::int64_t begin_ns,
                                 const haptics::Pose& X_WP, const haptics::Pose& X_WD,
                                 const Eigen::Vector3d& force_W_N, const Eigen::Vector3d& torque_W_Nm,
                                 std::uint64_t held_ticks, const CouplingPassivity& passivity) noexcept {
  snap.tick = counts.tick;
  snap.time_ns = begin_ns;
  snap.X_WP = X_WP;
  snap.X_WD = X_WD;
  snap.force_W_N = force_W_N;
  snap.torque_W_Nm = torque_W_Nm;
  snap.bad_samples = counts.bad_samples;
  snap.implausible_samples = counts.implausible;
  snap.held_ticks = held_ticks;
  snap.passivity_active_ticks = passivity.active_ticks;
  snap.passivity_dissipated_J = passivity.dissipated_J;
}

/// The poses and wrench of a solver tick into its record: the device pose it ticked with
/// (X_WD), the proxy pose after it (X_WP) and the renderer's wrench.
inline void writeRecordPoses(TickRecord& rec, const haptics::Pose& X_WD, const haptics::Pose& X_WP,
                             const haptics::TickOutput& out) noexcept {
  for (int k = 0; k < 3; ++k) {
    rec.p_WD_m[k] = X_WD.p_AB_m[k];
    rec.p_WP_m[k] = X_WP.p_AB_m[k];
    rec.force_W_N[k] = out.force_W_N[k];
    rec.torque_W_Nm[k] = out.torque_W_Nm[k];
  }
  rec.q_WD[0] = X_WD.R_AB.w(); rec.q_WD[1] = X_WD.R_AB.x();
  rec.q_WD[2] = X_WD.R_AB.y(); rec.q_WD[3] = X_WD.R_AB.z();
  rec.q_WP[0] = X_WP.R_AB.w(); rec.q_WP[1] = X_WP.R_AB.x();
  rec.q_WP[2] = X_WP.R_AB.y(); rec.q_WP[3] = X_WP.R_AB.z();
}

/// A solver tick's own recording flags: contact, bad sample, non-finite wrench, device
/// disconnected, the segment touched.
inline std::uint32_t solverRecordFlags(std::uint32_t contacts, const CouplingSample& in, const haptics::TickOutput& out,
                                       int segment) noexcept {
  const bool nonfinite = !out.force_W_N.allFinite() || !out.torque_W_Nm.allFinite();
  return (contacts > 0 ? kRecordFlagContact : 0u) | (in.ok ? 0u : kRecordFlagBadSample) |
         (nonfinite ? kRecordFlagNonFinite : 0u) | (in.connected ? 0u : kRecordFlagDeviceDisconnected) |
         (in.ok && out.stats.deadline_cut ? kRecordFlagDeadlineCut : 0u) | recordSegmentBits(segment);
}

/// Gives the renderer the gains the coupling thread applied to this sample when they changed
/// (true then).
inline bool followGains(const haptics::CouplingGains& sample_gains, haptics::CouplingGains& gains,
                        haptics::HapticRenderer& renderer) noexcept {
  if (sameGains(sample_gains, gains)) return false;
  gains = sample_gains;
  renderer.setGains(gains);
  return true;
}

/// A solver tick's contacts into its snapshot: their number, the segment touched and the first
/// ones (at most HapticSnapshot::kMaxContactsShown).
inline void showContacts(SolverSnapshot& snap, std::span<const haptics::Contact> contacts, int segment) noexcept {
  snap.contacts = static_cast<int>(contacts.size());
  snap.segment = segment;
  const int shown = std::min<int>(snap.contacts, HapticSnapshot::kMaxContactsShown);
  snap.contacts_shown = shown;
  for (int i = 0; i < shown; ++i) {
    snap.contact_p_W_m[static_cast<std::size_t>(i)] = contacts[static_cast<std::size_t>(i)].p_W_m;
    snap.contact_n_W[static_cast<std::size_t>(i)] = contacts[static_cast<std::size_t>(i)].n_W;
  }
}

}  // namespace

void HapticThread::couplingLoop() noexcept {
  bool fifo = false, locked = false;
  configureRealtime(kCouplingPriority, true, fifo, locked);
  memory_locked_.store(locked, std::memory_order_release);
  fifo_.store(fifo, std::memory_order_release);

  const int ramp_ticks = std::max(1, static_cast<int>(std::lround(0.050 / period_s_)));  // ~50 ms
  int ramp_left = -1;  // -1: not stopping
  CouplingCounts counts;
  PeriodicClock clock(period_s_, 0);

  DeviceSample sample;
  CouplingSample input;
  ProxyState proxy;
  x_->proxy.read(proxy);
  haptics::Pose X_WD_last = proxy.X_WP;  // until the first valid sample
  const haptics::MassProperties& mass = renderer_->tool().mass;  // immutable: shared with the solver
  SnapshotChannel* const monitor = options_.monitor.get();  // optional second consumer

  // Every command goes through the one safety layer: the device's limits, engage gate, fault
  // hold, ramp, watchdog, actuated DOF (device.h, ForceSafety). Every sample goes through the
  // plausibility test first (sample_filter.h): a glitch is never coupled to. Coupling gains are
  // kept within the device's stable stiffness.
  ForceSafety safety(device_->limits(), device_->safetyPolicy(), device_->actuatedDof());
  safety.enable();
  SampleFilter filter(safety.limits());
  haptics::CouplingGains requested_gains{gain_linear_.load(std::memory_order_relaxed),
                                         gain_angular_.load(std::memory_order_relaxed),
                                         gain_passivity_.load(std::memory_order_relaxed)};
  haptics::CouplingGains applied_gains = clampGains(requested_gains, safety.limits());
  haptics::VirtualCoupling coupling(applied_gains);
  CouplingPassivity passivity(mass);
  passivity.configure(applied_gains, safety.limits());
  // Placements (place()): the latest one asked for, whether it waits for its device sample, and
  // the ones handed to the solver.
  Placement placement;
  std::uint64_t placement_requests_seen = x_->placement_requests_at_start;
  bool placement_waiting = false;
  std::uint64_t placements_sent = 0;
  haptics::Pose X_WP_placed;

  while (true) {
    if (ramp_left < 0 && stop_requested_.load(std::memory_order_acquire)) ramp_left = ramp_ticks;
    if (ramp_left == 0) break;
    const bool missed = clock.wait();
    const std::int64_t begin_ns = monotonicNs();
    if (missed) x_->sticky_flags.fetch_or(kRecordFlagDeadlineMiss, std::memory_order_relaxed);

    // 1. Device sample, tested before anything is computed from it: missing, non-finite,
    //    outside the workspace or faster than the device moves is no sample (never rendered,
    //    never handed to the solver, which keeps the last good one).
    safety.setLimits(device_->limits());
    filter.setLimits(safety.limits());
    const bool read_ok = device_->read(sample);
    const std::uint64_t placement_requests = placement_requests_.load(std::memory_order_acquire);
    if (placement_requests != placement_requests_seen) {
      placement_requests_seen = placement_requests;
      x_->placement.read(placement);
      placement_waiting = true;
    }
    if (placement_waiting && read_ok && samePoseBits(sample.X_WD, placement.X_WD)) {
      // The placed sample: the jump to it is no glitch, and no motion of the hand.
      placement_waiting = false;
      ++placements_sent;
      X_WP_placed = placement.X_WP;
      PlacedSample& placed = x_->placed.writeSlot();  // before the sample is pushed: the solver sees both
      placed.count = placements_sent;
      placed.sample = x_->samples.latest() + 1;  // this tick's sample (this thread is the ring's one producer)
      placed.X_WP = placement.X_WP;
      x_->placed.publish();
      filter = SampleFilter(safety.limits());
      passivity.have_coupled_last = false;
      coupling.resetTracking();
    }
    const SampleFilter::Verdict verdict = filter.check(sample, read_ok, clock.interval_s());
    const bool ok = verdict == SampleFilter::Verdict::kGood || verdict == SampleFilter::Verdict::kReseeded;
    const bool connected = device_->connected();
    if (!ok) ++counts.bad_samples;
    if (verdict == SampleFilter::Verdict::kImplausible) ++counts.implausible;
    // 2. Pending GUI commands; gains within the device's current limits (a workspace scale
    //    change alters them).
    if (gains_dirty_.exchange(false, std::memory_order_acq_rel)) {
      requested_gains = {gain_linear_.load(std::memory_order_relaxed), gain_angular_.load(std::memory_order_relaxed),
                         gain_passivity_.load(std::memory_order_relaxed)};
    }
    applyGains(clampGains(requested_gains, safety.limits()), safety.limits(), applied_gains, passivity, coupling);
    // 3. Hand the sample to the solver, with this tick's isovalue and gains.
    input.X_WD = ok ? sample.X_WD : X_WD_last;
    input.isovalue = isovalue_.load(std::memory_order_relaxed);
    input.gains = applied_gains;
    input.ok = ok;
    input.connected = connected;
    input.drill_button = ok && (sample.buttons & kDrillButton) != 0;
    x_->samples.push(input);
    // 4. Virtual coupling (eq. 5) to the solver's latest proxy pose, with the device pose
    //    normalised as the renderer does (so that the same pair gives the same bits). A pose
    //    the renderer rejected on its latest tick gives no force. 4b: passivity control.
    x_->proxy.read(proxy);
    if (proxy.placements < placements_sent) {  // the solver has not applied the placement yet
      proxy.X_WP = X_WP_placed;
      proxy.bad_input = false;
    }
    Eigen::Vector3d force_W_N = Eigen::Vector3d::Zero();
    Eigen::Vector3d torque_W_Nm = Eigen::Vector3d::Zero();
    bool coupled = false;
    ++passivity.ticks_since_coupled;
    if (ok && !proxy.bad_input) {
      haptics::Pose X_WD = sample.X_WD;
      X_WD.R_AB.coeffs() /= sample.X_WD.R_AB.norm();
      X_WD_last = X_WD;
      const haptics::Wrench w = coupling.track(proxy.X_WP, X_WD, mass);
      force_W_N = w.force_W_N;
      torque_W_Nm = w.torque_W_Nm;
      coupled = true;
      passivity.coupled(force_W_N, torque_W_Nm, X_WD, proxy.X_WP, mass, applied_gains, period_s_);
    }
    rampDown(ramp_left, ramp_ticks, force_W_N, torque_W_Nm);
    // 5. Safety layer, then command (never NaN, never beyond the device's limits).
    const SafetyInput safety_in =
        couplingSafetyInput(coupled, verdict, period_s_, sample, clock.interval_s(), force_W_N, torque_W_Nm);
    const SafetyOutcome outcome = commandThroughSafety(safety, safety_in, *device_, force_W_N, torque_W_Nm);
    passivity.afterSafety(safety.stats().outages);
    x_->command_flags.store(commandFlags(outcome, ramp_left >= 0), std::memory_order_relaxed);
    ++counts.tick;

    // 6. Statistics and snapshot.
    clock.tick(begin_ns, monotonicNs());
    CouplingSnapshot& snap = x_->gui.couplingSlot();
    fillCouplingSnapshot(snap, counts, begin_ns, proxy.X_WP, X_WD_last, force_W_N, torque_W_Nm,
                         safety.stats().held_ticks, passivity);
    snap.timing = clock.timing();
    if (monitor != nullptr) {
      monitor->couplingSlot() = snap;
      monitor->publishCoupling();
    }
    x_->gui.publishCoupling();
  }

  device_->command(Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero());
  coupling_done_.store(true, std::memory_order_release);
  if (locked) releaseMemoryLock();
  running_.store(false, std::memory_order_release);
}

void HapticThread::solverLoop() noexcept {
  bool fifo = false, locked = false;
  configureRealtime(kSolverPriority, false, fifo, locked);
  x_->solver_fifo.store(fifo, std::memory_order_release);

  std::uint64_t tick = 0;
  std::uint64_t rejected = 0;
  std::uint64_t skipped = 0;
  std::uint64_t record_first_tick = 0;         // tick of the current recording's first record
  RecordingWriter* active_recorder = nullptr;  // the recorder of the current recording
  PeriodicClock clock(solver_period_s_, 0);
  SnapshotChannel* const monitor = options_.monitor.get();  // optional second consumer
  // Samples from before this start() are not used (a restart begins with the next one).
  std::uint64_t consumed = x_->first_sample_after;
  CouplingSample input, last_input;
  bool have_last = false;
  // The renderer's gains (and the solver's metric) are set before the first tick, as
  // replayRecording() does; then each sample brings the gains the coupling thread applied.
  haptics::CouplingGains gains = renderer_->coupling().gains();
  renderer_->setGains(gains);
  haptics::Pose X_WD_used = renderer_->proxyPose();  // the latest pose the renderer ticked with
  std::uint64_t placements = 0;                      // applied (PlacedSample::count)
  PlacedSample placed;                               // the latest placement passed on
  std::uint32_t wake_flags = 0;                      // deadline miss of this wake-up (first tick only)
  JamDetector jam;                                   // kRecordFlagJam

  // One solver tick on `in`: render, publish the proxy, record, publish the snapshot.
  const auto solve = [&](const CouplingSample& in) noexcept {
    const std::int64_t begin_ns = monotonicNs();
    const std::uint32_t gains_flags = followGains(in.gains, gains, *renderer_) ? kRecordFlagGainsApplied : 0u;
    std::uint32_t placement_flags = 0;
    x_->placed.read(placed);
    if (placed.count > placements && consumed >= placed.sample) {  // a placement: the proxy jumps with the device
      placements = placed.count;
      renderer_->resetProxy(placed.X_WP);
      placement_flags = kRecordFlagPlacement;
      placements_applied_.fetch_add(1, std::memory_order_acq_rel);
    }
    haptics::TickOutput out;
    bool bad_input = false;
    std::uint32_t drill_flags = 0;
    bool stuck = false;
    if (in.ok) {
      X_WD_used = in.X_WD;
      const haptics::Pose X_WP_before = renderer_->proxyPose();
      out = renderer_->tick(in.X_WD, in.isovalue);
      bad_input = out.stats.bad_input;
      if (bad_input) ++rejected;
      // The jam detector (jam_detector.h); the device's own freedom is tested only on candidates.
      const haptics::ToolModel& tool = renderer_->tool();
      stuck = !bad_input &&
              JamDetector::candidate(X_WP_before, renderer_->proxyPose(), in.X_WD, tool.mass.p_TCm_m,
                                     static_cast<int>(renderer_->contacts().size())) &&
              countPointsInside(renderer_->volume(), tool.point_shell, in.X_WD, renderer_->feltIsovalue()) == 0;
      // seq_cst with solver_ticks_ below: holdCutting()'s handshake (a tick that starts after the
      // one it waited for sees the hold).
      if (options_.drill != nullptr && !cutting_held_.load(std::memory_order_seq_cst) &&
          (drilling_.load(std::memory_order_relaxed) || in.drill_button)) {
        (void)options_.drill->step(*renderer_, out);
        drill_flags = kRecordFlagDrillOn;
      }
    }
    const std::uint32_t jam_flags = jam.update(stuck) ? kRecordFlagJam : 0u;
    ProxyState& proxy = x_->proxy.writeSlot();
    proxy.X_WP = renderer_->proxyPose();
    proxy.bad_input = bad_input;
    proxy.placements = placements;
    x_->proxy.publish();
    ++tick;
    if (options_.solver_tick_hook != nullptr) options_.solver_tick_hook(options_.solver_tick_hook_context);
    const std::int64_t end_ns = monotonicNs();

    // Recording (lock-free push; a full ring drops the record and counts it).
    const std::uint32_t coupling_flags = x_->command_flags.load(std::memory_order_relaxed) |
                                         x_->sticky_flags.exchange(0, std::memory_order_relaxed);
    RecordingWriter* const recorder = recorder_.load(std::memory_order_acquire);
    if (recorder != active_recorder) {  // a new recording starts its clock at its first tick
      active_recorder = recorder;
      record_first_tick = tick;
      first_recorded_tick_.store(tick, std::memory_order_release);
    }
    const auto contacts = renderer_->contacts();
    const int segment = options_.segments != nullptr ? options_.segments->segmentOf(contacts) : -1;
    if (recorder != nullptr) {
      TickRecord rec;
      rec.time_s = static_cast<double>(tick - record_first_tick) * solver_period_s_;
      rec.tick = tick;
      writeRecordPoses(rec, in.ok ? in.X_WD : X_WD_used, renderer_->proxyPose(), out);
      rec.isovalue = in.isovalue;
      rec.tick_time_s = 1e-9 * static_cast<double>(end_ns - begin_ns);
      rec.contacts = static_cast<std::uint32_t>(contacts.size());
      rec.flags =
          solverRecordFlags(rec.contacts, in, out, segment) | wake_flags | coupling_flags | drill_flags | gains_flags |
          jam_flags | placement_flags;
      (void)recorder->push(rec);
      latest_recorded_tick_.store(tick, std::memory_order_release);
    }
    wake_flags = 0;

    clock.tick(begin_ns, end_ns);
    SolverSnapshot& snap = x_->gui.solverSlot();
    snap.tick = tick;
    snap.isovalue = in.isovalue;
    showContacts(snap, contacts, segment);
    snap.rejected = rejected;
    snap.skipped = skipped;
    snap.timing = clock.timing();
    if (monitor != nullptr) {
      monitor->solverSlot() = snap;
      monitor->publishSolver();
    }
    x_->gui.publishSolver();
    solver_ticks_.fetch_add(1, std::memory_order_seq_cst);
  };

  // The samples waiting at this wake-up.
  const auto solvePending = [&]() noexcept {
    const std::uint64_t latest = x_->samples.latest();
    if (every_sample_) {
      // Every sample once, in order; skip to the newest only when too far behind (or when the
      // coupling thread overwrote the next one, which the backlog limit prevents).
      while (consumed < latest) {
        std::uint64_t next = consumed + 1;
        if (latest - next >= x_->backlog_limit) next = latest;
        if (!x_->samples.read(next, input)) {
          next = x_->samples.latest();
          if (!x_->samples.read(next, input)) break;
        }
        skipped += next - consumed - 1;
        consumed = next;
        solve(input);
      }
      return;
    }
    // The newest sample; the last one again when nothing new arrived.
    if (latest > consumed && x_->samples.read(latest, input)) {
      if (have_last) skipped += latest - consumed - 1;
      consumed = latest;
      last_input = input;
      have_last = true;
    }
    if (have_last) solve(last_input);
  };

  while (!coupling_done_.load(std::memory_order_acquire)) {
    if (clock.wait()) wake_flags = kRecordFlagDeadlineMiss;
    solvePending();
  }
  if (every_sample_) solvePending();  // the samples of the coupling thread's last ticks
}

}  // namespace vh::runtime
