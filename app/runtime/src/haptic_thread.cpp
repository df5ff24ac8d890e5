// The coupling and solver threads of vh/runtime/haptic_thread.h.
#include "vh/runtime/haptic_thread.h"

#include "vh/runtime/burr_load.h"
#include "vh/runtime/snapshot_channel.h"

#include "coupling_passivity.h"
#include "solver_tick.h"
#include "vh/runtime/jam_detector.h"
#include "vh/runtime/placement.h"

#include "vh/haptics/configuration_solver.h"
#include "vh/haptics/passivity_controller.h"
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

using detail::CouplingPassivity;
using detail::PlacedSample;
using detail::SolverState;
using detail::SolverTickResult;
using detail::applyPlacement;
using detail::publishSolverTick;
using detail::recordSolverTick;
using detail::renderSolverSample;
using detail::solvePendingSamples;
using detail::solverTechnique;
using detail::writeRecordPoses;

constexpr int kCouplingPriority = 80;  // above the solver: on a shared core the coupling preempts it
constexpr int kSolverPriority = 79;

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

/// Guidance as setGuidance() asked (GUI -> coupling thread); path null: off.
struct GuidanceCommand {
  const haptics::GuidancePath* path = nullptr;
  haptics::GuidanceGains gains;
};

/// A placement asked for by HapticThread::place() (GUI -> coupling thread).
struct Placement {
  haptics::Pose X_WP;
  haptics::Pose X_WD;
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
  TripleBuffer<GuidanceCommand> guidance;  ///< GUI -> coupling: the latest setGuidance().
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
  if (options_.segments != nullptr && !options_.segments->critical().empty())
    proximity_ = std::make_unique<CriticalProximity>(*options_.segments, renderer_->tool().point_shell);

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

void HapticThread::setGuidance(std::shared_ptr<const ExpertPath> expert, const haptics::GuidanceGains& gains) {
  const haptics::GuidanceGains applied = clampGuidance(gains, device_->limits());
  if (expert) guides_kept_.push_back(expert);
  guide_ = std::move(expert);
  GuidanceCommand& slot = x_->guidance.writeSlot();
  slot.path = guide_ ? &guide_->path() : nullptr;
  slot.gains = applied;
  x_->guidance.publish();
  guidance_dirty_.store(true, std::memory_order_release);
  if (recorder_.load(std::memory_order_acquire) == nullptr) return;
  try {
    recordEvent("guidance", guide_ ? guidanceEventJson(*guide_, applied, gains) : std::string("{\"off\":true}"));
  } catch (...) {  // NOLINT(bugprone-empty-catch): the event is best effort, the guidance is set
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

void HapticThread::swapSegmentParts(SegmentParts& parts) noexcept {
  options_.segments.swap(parts.segments);
  proximity_.swap(parts.proximity);
  options_.technique.swap(parts.technique);
}

bool HapticThread::replaceSegments(std::shared_ptr<const SegmentSet> segments, std::shared_ptr<ServoTechnique> technique,
                                   double timeout_ms) {
  if (options_.drill != nullptr || recorder_.load(std::memory_order_acquire) != nullptr) return false;
  auto parts = std::make_unique<SegmentParts>();
  parts->segments = std::move(segments);
  if (parts->segments != nullptr && !parts->segments->critical().empty())
    parts->proximity = std::make_unique<CriticalProximity>(*parts->segments, renderer_->tool().point_shell);
  parts->technique = std::move(technique);
  if (!solver_thread_.joinable()) {  // no solver thread: this thread's own
    swapSegmentParts(*parts);
    return true;  // the old parts go with `parts`
  }
  segments_retired_.store(nullptr, std::memory_order_release);
  segments_pending_.store(parts.get(), std::memory_order_release);
  const auto until = std::chrono::steady_clock::now() + std::chrono::duration<double, std::milli>(timeout_ms);
  while (segments_retired_.load(std::memory_order_acquire) != parts.get()) {
    if (std::chrono::steady_clock::now() > until) {
      // Taken back unless the solver has just taken it (it then hands it back within its tick).
      if (segments_pending_.exchange(nullptr, std::memory_order_acq_rel) == parts.get()) return false;
    }
    std::this_thread::sleep_for(std::chrono::microseconds(100));
  }
  segments_retired_.store(nullptr, std::memory_order_release);
  return true;  // the old parts are freed here, on this thread
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

/// Gives the renderer the gains the coupling thread applied to this sample when they changed
/// (true then).
inline bool followGains(const haptics::CouplingGains& sample_gains, haptics::CouplingGains& gains,
                        haptics::HapticRenderer& renderer) noexcept {
  if (sameGains(sample_gains, gains)) return false;
  gains = sample_gains;
  renderer.setGains(gains);
  return true;
}

/// The coupling gains the GUI asks for (HapticThread::setGains()).
inline haptics::CouplingGains loadRequestedGains(const std::atomic<double>& linear, const std::atomic<double>& angular,
                                                 const std::atomic<bool>& passivity) noexcept {
  return {linear.load(std::memory_order_relaxed), angular.load(std::memory_order_relaxed),
          passivity.load(std::memory_order_relaxed)};
}

/// The coupling thread's state from tick to tick (couplingLoop()): the device sample and the
/// solver's proxy, the safety layer and plausibility test, the gains and the coupling, and the
/// placements (place()).
struct CouplingState {
  CouplingState(const Device& device, const haptics::MassProperties& mass, const haptics::CouplingGains& requested,
                std::uint64_t placement_requests_at_start) noexcept
      : safety(device.limits(), device.safetyPolicy(), device.actuatedDof()),
        filter(safety.limits()),
        requested_gains(requested),
        applied_gains(clampGains(requested, safety.limits())),
        coupling(applied_gains),
        passivity(mass),
        placement_requests_seen(placement_requests_at_start) {
    safety.enable();
    passivity.configure(applied_gains, safety.limits());
  }

  CouplingCounts counts;
  DeviceSample sample;
  CouplingSample input;
  ProxyState proxy;
  haptics::Pose X_WD_last;  // the last coupled device pose (until the first valid sample: the proxy's)
  // Every command goes through the one safety layer: the device's limits, engage gate, fault
  // hold, ramp, watchdog, actuated DOF (device.h, ForceSafety). Every sample goes through the
  // plausibility test first (sample_filter.h): a glitch is never coupled to. Coupling gains are
  // kept within the device's stable stiffness.
  ForceSafety safety;
  SampleFilter filter;
  haptics::CouplingGains requested_gains;
  haptics::CouplingGains applied_gains;
  haptics::VirtualCoupling coupling;
  CouplingPassivity passivity;
  // Placements (place()): the latest one asked for, whether it waits for its device sample, and
  // the ones handed to the solver.
  Placement placement;
  std::uint64_t placement_requests_seen;
  bool placement_waiting = false;
  std::uint64_t placements_sent = 0;
  haptics::Pose X_WP_placed;
  GuidanceCommand guidance;         // setGuidance()'s latest
  haptics::GuidanceForce guide;     // this tick's guidance force and nearest point
};

/// A new place() request (`requests` so far) is taken; when this tick's sample (`read_ok`) is
/// the placed one, the jump to it is no glitch and no motion of the hand: the placement is handed
/// to the solver as the sample that `samples` gets next, and the sample test and coupling start
/// afresh.
inline void passOnPlacement(CouplingState& c, std::uint64_t requests, bool read_ok, TripleBuffer<Placement>& asked,
                            const SampleRing& samples, TripleBuffer<PlacedSample>& placed_out) noexcept {
  if (requests != c.placement_requests_seen) {
    c.placement_requests_seen = requests;
    asked.read(c.placement);
    c.placement_waiting = true;
  }
  if (!c.placement_waiting || !read_ok || !samePoseBits(c.sample.X_WD, c.placement.X_WD)) return;
  // The placed sample: the jump to it is no glitch, and no motion of the hand.
  c.placement_waiting = false;
  ++c.placements_sent;
  c.X_WP_placed = c.placement.X_WP;
  PlacedSample& placed = placed_out.writeSlot();  // before the sample is pushed: the solver sees both
  placed.count = c.placements_sent;
  placed.sample = samples.latest() + 1;  // this tick's sample (this thread is the ring's one producer)
  placed.X_WP = c.placement.X_WP;
  placed_out.publish();
  c.filter = SampleFilter(c.safety.limits());
  c.passivity.have_coupled_last = false;
  c.coupling.resetTracking();
}

/// The sample handed to the solver, with this tick's isovalue and gains (a rejected sample: the
/// last good pose, marked not ok).
inline void fillSolverInput(CouplingState& c, bool ok, bool connected, double isovalue) noexcept {
  c.input.X_WD = ok ? c.sample.X_WD : c.X_WD_last;
  c.input.isovalue = isovalue;
  c.input.gains = c.applied_gains;
  c.input.ok = ok;
  c.input.connected = connected;
  c.input.drill_button = ok && (c.sample.buttons & HapticThread::kDrillButton) != 0;
}

/// Virtual coupling (eq. 5) of the good sample (`ok`) to the solver's latest proxy pose (c.proxy;
/// the placed pose while the solver has not applied a placement), with the device pose
/// normalised as the renderer does (so that the same pair gives the same bits), then passivity
/// control. A pose the renderer rejected on its latest tick gives no force.
/// @return whether the tick coupled; the wrench into `force_W_N`, `torque_W_Nm` (zero otherwise).
inline bool coupleToProxy(CouplingState& c, bool ok, const haptics::MassProperties& mass, double period_s,
                          Eigen::Vector3d& force_W_N, Eigen::Vector3d& torque_W_Nm) noexcept {
  if (c.proxy.placements < c.placements_sent) {  // the solver has not applied the placement yet
    c.proxy.X_WP = c.X_WP_placed;
    c.proxy.bad_input = false;
  }
  force_W_N = Eigen::Vector3d::Zero();
  torque_W_Nm = Eigen::Vector3d::Zero();
  ++c.passivity.ticks_since_coupled;
  if (!ok || c.proxy.bad_input) return false;
  haptics::Pose X_WD = c.sample.X_WD;
  X_WD.R_AB.coeffs() /= c.sample.X_WD.R_AB.norm();
  c.X_WD_last = X_WD;
  const haptics::Wrench w = c.coupling.track(c.proxy.X_WP, X_WD, mass);
  force_W_N = w.force_W_N;
  torque_W_Nm = w.torque_W_Nm;
  c.passivity.coupled(force_W_N, torque_W_Nm, X_WD, c.proxy.X_WP, mass, c.applied_gains, period_s);
  return true;
}

/// A coupling tick's snapshot to the GUI and the optional monitor.
inline void publishCouplingTick(SnapshotChannel& gui, SnapshotChannel* monitor, const CouplingState& c,
                                std::int64_t begin_ns, const Eigen::Vector3d& force_W_N,
                                const Eigen::Vector3d& torque_W_Nm, const ThreadTiming& timing) noexcept {
  CouplingSnapshot& snap = gui.couplingSlot();
  fillCouplingSnapshot(snap, c.counts, begin_ns, c.proxy.X_WP, c.X_WD_last, force_W_N, torque_W_Nm,
                       c.safety.stats().held_ticks, c.passivity);
  snap.timing = timing;
  snap.guidance_on = c.guidance.path != nullptr;
  snap.guidance_force_W_N = c.guide.force_W_N;
  snap.guidance_segment = c.guide.nearest.segment;
  snap.guidance_s = c.guide.nearest.s;
  snap.guidance_nearest_W_m = c.guide.nearest.p_W_m;
  if (monitor != nullptr) {
    monitor->couplingSlot() = snap;
    monitor->publishCoupling();
  }
  gui.publishCoupling();
}

}  // namespace

void HapticThread::couplingLoop() noexcept {
  bool fifo = false, locked = false;
  configureRealtime(kCouplingPriority, true, fifo, locked);
  memory_locked_.store(locked, std::memory_order_release);
  fifo_.store(fifo, std::memory_order_release);

  const int ramp_ticks = std::max(1, static_cast<int>(std::lround(0.050 / period_s_)));  // ~50 ms
  int ramp_left = -1;  // -1: not stopping
  PeriodicClock clock(period_s_, 0);
  const haptics::MassProperties& mass = renderer_->tool().mass;  // immutable: shared with the solver
  SnapshotChannel* const monitor = options_.monitor.get();  // optional second consumer
  CouplingState c(*device_, mass, loadRequestedGains(gain_linear_, gain_angular_, gain_passivity_),
                  x_->placement_requests_at_start);
  x_->proxy.read(c.proxy);
  c.X_WD_last = c.proxy.X_WP;  // until the first valid sample

  while (true) {
    if (ramp_left < 0 && stop_requested_.load(std::memory_order_acquire)) ramp_left = ramp_ticks;
    if (ramp_left == 0) break;
    const bool missed = clock.wait();
    const std::int64_t begin_ns = monotonicNs();
    if (missed) x_->sticky_flags.fetch_or(kRecordFlagDeadlineMiss, std::memory_order_relaxed);

    // 1. Device sample, tested before anything is computed from it: missing, non-finite,
    //    outside the workspace or faster than the device moves is no sample (never rendered,
    //    never handed to the solver, which keeps the last good one).
    c.safety.setLimits(device_->limits());
    c.filter.setLimits(c.safety.limits());
    const bool read_ok = device_->read(c.sample);
    passOnPlacement(c, placement_requests_.load(std::memory_order_acquire), read_ok, x_->placement, x_->samples,
                    x_->placed);
    const SampleFilter::Verdict verdict = c.filter.check(c.sample, read_ok, clock.interval_s());
    const bool ok = verdict == SampleFilter::Verdict::kGood || verdict == SampleFilter::Verdict::kReseeded;
    const bool connected = device_->connected();
    if (!ok) ++c.counts.bad_samples;
    if (verdict == SampleFilter::Verdict::kImplausible) ++c.counts.implausible;
    // 2. Pending GUI commands; gains within the device's current limits (a workspace scale
    //    change alters them).
    if (gains_dirty_.exchange(false, std::memory_order_acq_rel))
      c.requested_gains = loadRequestedGains(gain_linear_, gain_angular_, gain_passivity_);
    applyGains(clampGains(c.requested_gains, c.safety.limits()), c.safety.limits(), c.applied_gains, c.passivity,
               c.coupling);
    // 3. Hand the sample to the solver, with this tick's isovalue and gains.
    fillSolverInput(c, ok, connected, isovalue_.load(std::memory_order_relaxed));
    x_->samples.push(c.input);
    // 4. Virtual coupling to the solver's latest proxy pose; 4b: passivity control.
    x_->proxy.read(c.proxy);
    Eigen::Vector3d force_W_N, torque_W_Nm;
    const bool coupled = coupleToProxy(c, ok, mass, period_s_, force_W_N, torque_W_Nm);
    // 4c. Guidance toward the expert's path (guidance.h), inside the same ramp and safety layer.
    if (guidance_dirty_.exchange(false, std::memory_order_acq_rel)) x_->guidance.read(c.guidance);
    c.guide = coupled && c.guidance.path != nullptr
                  ? haptics::guidanceForce(*c.guidance.path, c.guidance.gains, c.X_WD_last.p_AB_m)
                  : haptics::GuidanceForce{};
    force_W_N += c.guide.force_W_N;
    rampDown(ramp_left, ramp_ticks, force_W_N, torque_W_Nm);
    // 5. Safety layer, then command (never NaN, never beyond the device's limits).
    const SafetyInput safety_in =
        couplingSafetyInput(coupled, verdict, period_s_, c.sample, clock.interval_s(), force_W_N, torque_W_Nm);
    const SafetyOutcome outcome = commandThroughSafety(c.safety, safety_in, *device_, force_W_N, torque_W_Nm);
    c.passivity.afterSafety(c.safety.stats().outages);
    x_->command_flags.store(commandFlags(outcome, ramp_left >= 0), std::memory_order_relaxed);
    ++c.counts.tick;

    // 6. Statistics and snapshot.
    clock.tick(begin_ns, monotonicNs());
    publishCouplingTick(x_->gui, monitor, c, begin_ns, force_W_N, torque_W_Nm, clock.timing());
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

  PeriodicClock clock(solver_period_s_, 0);
  SnapshotChannel* const monitor = options_.monitor.get();  // optional second consumer
  SolverState st;
  // Samples from before this start() are not used (a restart begins with the next one).
  st.consumed = x_->first_sample_after;
  // The renderer's gains (and the solver's metric) are set before the first tick, as
  // replayRecording() does; then each sample brings the gains the coupling thread applied.
  st.gains = renderer_->coupling().gains();
  renderer_->setGains(st.gains);
  st.X_WD_used = renderer_->proxyPose();

  // One solver tick on `in`: render, publish the proxy, record, publish the snapshot.
  const auto solve = [&](const CouplingSample& in) noexcept {
    const std::int64_t begin_ns = monotonicNs();
    const std::uint32_t gains_flags = followGains(in.gains, st.gains, *renderer_) ? kRecordFlagGainsApplied : 0u;
    const std::uint32_t placement_flags = applyPlacement(st, x_->placed, *renderer_, placements_applied_);
    SolverTickResult t;
    if (in.ok) renderSolverSample(st, in, *renderer_, options_.drill.get(), cutting_held_, drilling_, t, options_.tissue.get());
    const std::uint32_t jam_flags = st.jam.update(t.stuck) ? kRecordFlagJam : 0u;
    ProxyState& proxy = x_->proxy.writeSlot();
    proxy.X_WP = renderer_->proxyPose();
    proxy.bad_input = t.bad_input;
    proxy.placements = st.placements;
    x_->proxy.publish();
    ++st.tick;
    if (options_.solver_tick_hook != nullptr) options_.solver_tick_hook(options_.solver_tick_hook_context);
    const std::int64_t end_ns = monotonicNs();

    // Recording (lock-free push; a full ring drops the record and counts it).
    const std::uint32_t coupling_flags = x_->command_flags.load(std::memory_order_relaxed) |
                                         x_->sticky_flags.exchange(0, std::memory_order_relaxed);
    RecordingWriter* const recorder = recorder_.load(std::memory_order_acquire);
    if (recorder != st.active_recorder) {  // a new recording starts its clock at its first tick
      st.active_recorder = recorder;
      st.record_first_tick = st.tick;
      first_recorded_tick_.store(st.tick, std::memory_order_release);
    }
    const auto contacts = renderer_->contacts();
    const int segment = options_.segments != nullptr ? options_.segments->segmentOf(contacts) : -1;
    const CriticalDistance nearest = proximity_ ? proximity_->evaluate(renderer_->proxyPose()) : CriticalDistance{};
    const std::uint32_t technique_flags =
        solverTechnique(options_.technique.get(), st, in, t, contacts, segment, nearest.distance_m, solver_period_s_,
                        placement_flags != 0);
    if (recorder != nullptr) {
      recordSolverTick(*recorder, st, in, t, renderer_->proxyPose(), contacts.size(), segment, nearest,
                       solver_period_s_, end_ns - begin_ns,
                       st.wake_flags | coupling_flags | t.drill_flags | gains_flags | jam_flags | placement_flags |
                           technique_flags);
      latest_recorded_tick_.store(st.tick, std::memory_order_release);
    }
    st.wake_flags = 0;

    clock.tick(begin_ns, end_ns);
    publishSolverTick(x_->gui, monitor, st, in.isovalue, contacts, segment, nearest, clock.timing(), t,
                      options_.drill.get(), technique_flags);
    solver_ticks_.fetch_add(1, std::memory_order_seq_cst);
  };

  while (!coupling_done_.load(std::memory_order_acquire)) {
    if (clock.wait()) st.wake_flags = kRecordFlagDeadlineMiss;
    // New segment choices (replaceSegments()): swapped between two ticks, the old ones handed back.
    if (SegmentParts* parts = segments_pending_.exchange(nullptr, std::memory_order_acq_rel)) {
      swapSegmentParts(*parts);
      segments_retired_.store(parts, std::memory_order_release);
    }
    solvePendingSamples(st, x_->samples, every_sample_, x_->backlog_limit, solve);
  }
  // The samples of the coupling thread's last ticks.
  if (every_sample_) solvePendingSamples(st, x_->samples, every_sample_, x_->backlog_limit, solve);
}

}  // namespace vh::runtime
