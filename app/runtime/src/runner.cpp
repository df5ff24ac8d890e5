#include "vh/runtime/runner.h"

#include "vh/tissue/deformable_scene.h"

#include "vh/runtime/burr_load.h"
#include "vh/runtime/jam_detector.h"
#include "vh/runtime/placement.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iomanip>
#include <limits>
#include <memory>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>

#include "vh/haptics/crossing_verifier.h"
#include "vh/io/available_memory.h"
#include "vh/io/private_files.h"
#include "vh/runtime/default_isovalue.h"
#include "vh/runtime/device.h"
#include "vh/runtime/servo_factory.h"
#include "vh/runtime/sha256.h"
#include "vh/runtime/placement.h"
#include "vh/runtime/recording.h"
#include "vh/runtime/sample_filter.h"
#include "vh/runtime/session_metadata.h"
#include "vh/runtime/snapshot_channel.h"

namespace vh::runtime {

namespace {

/// The trace's `sample` column: what the plausibility test made of the tick's device sample.
const char* sampleVerdictName(SampleFilter::Verdict v) noexcept {
  switch (v) {
    case SampleFilter::Verdict::kGood: return "good";
    case SampleFilter::Verdict::kMissing: return "missing";
    case SampleFilter::Verdict::kImplausible: return "implausible";
    case SampleFilter::Verdict::kReseeded: return "reseeded";
  }
  return "?";
}

}  // namespace

double nearestRankPercentile(std::span<const double> sorted, double q) noexcept {
  if (sorted.empty()) return 0.0;
  const auto k = static_cast<std::size_t>(std::clamp(std::ceil(q * static_cast<double>(sorted.size())) - 1.0, 0.0,
                                                     static_cast<double>(sorted.size() - 1)));
  return sorted[k];
}

namespace {

/// The report's inputs: the scene, volume, tool and run settings.
void describeRun(RunReport& r, const LoadedScene& scene, const haptics::ScalarVolume& volume,
                 const haptics::ToolModel& tool, double isovalue, const Trajectory& trajectory,
                 const RunOptions& options) {
  r.scene = scene.spec.source.empty() ? std::string("builtin") : scene.spec.source.string();
  r.volume = scene.spec.volume.path;
  r.volume_notices = scene.volume.info.notices;
  r.volume_dims = volume.geometry().dims;
  r.volume_spacing_m = volume.geometry().spacing_m;
  r.isovalue = isovalue;
  r.tool = scene.spec.tool.mesh;
  r.point_count = tool.point_shell.size();
  r.point_spacing_m = tool.point_shell.meanNearestNeighbourSpacing_m();
  r.feature_size_m = volume.featureSize_m();
  r.servo_rate_Hz = options.servo_rate_Hz;
  r.trajectory_duration_s = trajectory.duration_s();
}

/// The per-tick trace CSV with its header written (RunOptions::trace_csv), or null when none is
/// asked for. Written beside its target and renamed into place by commit() at the run's end
/// (io::PrivateOutput: 0600, the session's poses and forces), so a failed write (a full disk)
/// is an error and leaves no partial trace that looks whole.
std::unique_ptr<io::PrivateOutput> openTrace(const std::filesystem::path& trace_csv) {
  if (trace_csv.empty()) return nullptr;
  std::unique_ptr<io::PrivateOutput> trace;
  try {
    trace = std::make_unique<io::PrivateOutput>(trace_csv);
  } catch (const std::runtime_error& e) {
    throw std::runtime_error(trace_csv.string() + ": cannot write the trace (" + e.what() + ")");
  }
  std::ostream& out = trace->stream();
  if (!out) throw std::runtime_error(trace_csv.string() + ": cannot write the trace");
  out << "tick,t_s,xd_m,yd_m,zd_m,xp_m,yp_m,zp_m,fx_N,fy_N,fz_N,tx_Nm,ty_Nm,tz_Nm,contacts,exec_us,penetration_m,"
         "qw_p,qx_p,qy_p,qz_p,time_of_contact,crossing_points,cmd_fx_N,cmd_fy_N,cmd_fz_N,cmd_tx_Nm,cmd_ty_Nm,"
         "cmd_tz_Nm,sample,isovalue,felt_isovalue\n"
      << std::setprecision(9);
  return trace;
}

/// The session recording's writer (RunOptions::record), or null when none is asked for.
std::unique_ptr<RecordingWriter> openRecorder(const LoadedScene& scene, const haptics::Pose& X_WD_first,
                                              const Device& device, const RunOptions& options) {
  if (options.record.empty()) return nullptr;
  LiveValues recorded = LiveValues::initial(scene);
  recorded.X_WT_initial = X_WD_first;  // the renderer starts there
  SessionInfo info;
  info.device_name = device.name();
  info.device_kind = "scripted";
  info.note = options.record_note;
  RecordingWriterOptions writer_options;
  writer_options.servo_rate_Hz = options.servo_rate_Hz;
  writer_options.ring_capacity = std::size_t{1} << 16;
  writer_options.chunk_records =
      std::clamp<std::size_t>(static_cast<std::size_t>(std::ceil(options.servo_rate_Hz / 2.0)), 1, 65535);
  return std::make_unique<RecordingWriter>(options.record, makeSessionMetadata(scene, recorded, info), writer_options);
}

/// The contact tally per segment when the scene has segments.
std::optional<SegmentContactTally> segmentTally(const LoadedScene& scene) {
  std::optional<SegmentContactTally> tally;
  if (scene.segments) {
    std::vector<std::string> names;
    std::vector<bool> critical;
    for (int k = 0; k < static_cast<int>(scene.segments->size()); ++k) {
      names.push_back(scene.segments->name(k));
      critical.push_back(scene.segments->isCritical(k));
    }
    tally.emplace(names, critical);
  }
  return tally;
}

/// The safety layer's input for a run tick (one servo period after the previous).
SafetyInput runSafetyInput(bool sample_ok, SampleFilter::Verdict verdict, const DeviceSample& sample, double period_s,
                           const haptics::TickOutput& out) {
  SafetyInput safety_in;
  safety_in.sample_ok = sample_ok;
  safety_in.reseeded = verdict == SampleFilter::Verdict::kReseeded;
  safety_in.sample_time_s = sample.time_s;
  safety_in.connection = sample.connection;
  safety_in.tick_interval_s = period_s;
  safety_in.period_s = period_s;
  safety_in.force_W_N = out.force_W_N;
  safety_in.torque_W_Nm = out.torque_W_Nm;
  return safety_in;
}

/// Work, command, contact and sample counts of tick `i` into the report and the sums for its means.
void addTickCounts(RunReport& r, const haptics::TickOutput& out, const Eigen::Vector3d& command_W_N, std::uint64_t i,
                   bool sample_ok, double& contact_sum, double& samples_sum) {
  r.budget_cuts += out.stats.budget_cut;
  r.max_work = std::max(r.max_work, out.stats.work);
  r.max_command_force_N = std::max(r.max_command_force_N, command_W_N.norm());
  if (out.stats.exec_time_us > 1000.0) ++r.ticks_over_1ms;
  r.max_contacts = std::max(r.max_contacts, out.stats.contacts);
  contact_sum += out.stats.contacts;
  samples_sum += static_cast<double>(out.stats.volume_samples);
  if (out.stats.contacts > 0) {
    ++r.ticks_in_contact;
    if (r.first_contact_tick < 0) r.first_contact_tick = static_cast<std::int64_t>(i);
  }
  if (out.stats.bad_input || !sample_ok) ++r.bad_device_samples;
}

/// The crossing check of tick `i`, outside the timed section: the path the proxy moved along
/// this tick, sampled densely; a point outside at its start and inside later was carried into
/// (or through) the isosurface. @return the points that crossed.
int checkCrossings(RunReport& r, const haptics::CrossingVerifier& verifier, const haptics::ShellEdges& edges,
                   const haptics::HapticRenderer& renderer, double felt_isovalue, std::uint64_t i) {
  const auto v0 = std::chrono::steady_clock::now();
  const haptics::CrossingVerifier::Result check =
      verifier.check(renderer.lastMotion(), renderer.lastTimeOfContact(), felt_isovalue);
  // The tool's surface between its points, at the end of the move.
  const haptics::CrossingVerifier::EdgeResult edge_check =
      verifier.checkEdges(renderer.lastMotion(), renderer.lastTimeOfContact(), felt_isovalue, edges, r.epsilon_m);
  if (edge_check.crossing_edges > 0) {
    ++r.edge_crossings;
    if (r.first_edge_crossing_tick < 0) r.first_edge_crossing_tick = static_cast<std::int64_t>(i);
  }
  r.verify_s += std::chrono::duration<double>(std::chrono::steady_clock::now() - v0).count();
  if (check.crossing_points > 0) {
    ++r.crossings;
    r.crossing_points += check.crossing_points;
    if (r.first_crossing_tick < 0) r.first_crossing_tick = static_cast<std::int64_t>(i);
  }
  return check.crossing_points;
}

/// Force, torque, proxy-device distance and (with RunOptions::check_penetration) penetration of a
/// finite tick `i` into the report. @return the penetration depth [m] (0 when not checked).
double addForceAndDepth(RunReport& r, const haptics::TickOutput& out, const haptics::Pose& X_WD_used,
                        const haptics::ScalarVolume& volume, const haptics::ToolModel& tool, double felt_isovalue,
                        bool check_penetration, std::uint64_t i) {
  r.max_force_N = std::max(r.max_force_N, out.force_W_N.norm());
  r.max_torque_Nm = std::max(r.max_torque_Nm, out.torque_W_Nm.norm());
  r.final_force_N = out.force_W_N.norm();
  r.final_proxy_device_distance_m = (out.X_WP.p_AB_m - X_WD_used.p_AB_m).norm();
  r.max_proxy_device_distance_m = std::max(r.max_proxy_device_distance_m, r.final_proxy_device_distance_m);
  double depth = 0.0;
  if (check_penetration) {
    depth = haptics::maxPenetration_m(volume, tool.point_shell, out.X_WP, felt_isovalue);
    if (depth > r.epsilon_m) ++r.ticks_penetrating;
    if (depth > r.max_penetration_m) {
      r.max_penetration_m = depth;
      r.max_penetration_tick = static_cast<std::int64_t>(i);
    }
  }
  return depth;
}

/// The recording's record of tick `i`: the device pose rendered (X_WD_used), the proxy pose after
/// the tick (X_WP_now) and the renderer's wrench.
TickRecord runRecord(std::uint64_t i, double servo_rate_Hz, const haptics::Pose& X_WD_used,
                     const haptics::Pose& X_WP_now, const haptics::TickOutput& out, double isovalue,
                     std::size_t contacts, bool finite, bool sample_ok, int segment) {
  TickRecord rec;
  rec.time_s = static_cast<double>(i) / servo_rate_Hz;
  rec.tick = i + 1;
  for (int k = 0; k < 3; ++k) {
    rec.p_WD_m[k] = X_WD_used.p_AB_m[k];
    rec.force_W_N[k] = out.force_W_N[k];
    rec.torque_W_Nm[k] = out.torque_W_Nm[k];
  }
  rec.q_WD[0] = X_WD_used.R_AB.w(); rec.q_WD[1] = X_WD_used.R_AB.x();
  rec.q_WD[2] = X_WD_used.R_AB.y(); rec.q_WD[3] = X_WD_used.R_AB.z();
  for (int k = 0; k < 3; ++k) rec.p_WP_m[k] = X_WP_now.p_AB_m[k];
  rec.q_WP[0] = X_WP_now.R_AB.w(); rec.q_WP[1] = X_WP_now.R_AB.x();
  rec.q_WP[2] = X_WP_now.R_AB.y(); rec.q_WP[3] = X_WP_now.R_AB.z();
  rec.isovalue = isovalue;
  rec.tick_time_s = 1e-6 * out.stats.exec_time_us;
  rec.contacts = static_cast<std::uint32_t>(contacts);
  rec.flags = (rec.contacts > 0 ? kRecordFlagContact : 0u) | (finite ? 0u : kRecordFlagNonFinite) |
              (sample_ok ? 0u : kRecordFlagBadSample) | recordSegmentBits(segment) |
              (sample_ok && out.stats.deadline_cut ? kRecordFlagDeadlineCut : 0u);
  rec.deadline_work = sample_ok ? out.stats.deadline_work : 0;
  return rec;
}

/// What a tick wrote besides the renderer's output: the command sent, the checks' results and
/// the isovalues (the trace's columns).
struct TraceExtras {
  double depth_m = 0.0;
  int crossing_points = -1;
  const Eigen::Vector3d& command_W_N;
  const Eigen::Vector3d& command_W_Nm;
  SampleFilter::Verdict verdict;
  double isovalue = 0.0;
  double felt_isovalue = 0.0;
};

/// What a rendered tick with tissue gave the report.
struct TissueTick {
  double indentation_m = 0.0;  // DeformableStep::indentation_m
  double force_N = 0.0;        // |the force on the hand|
  double push_N = 0.0;         // |the tissue's net push|
  double step_us = 0.0;        // the tissue's step
};

/// One row of the trace CSV (openTrace()'s columns).
void writeTraceRow(std::ostream& trace, std::uint64_t i, const DeviceSample& sample, const haptics::TickOutput& out,
                   const TraceExtras& x) {
  const Eigen::Vector3d& pd = sample.X_WD.p_AB_m;
  const Eigen::Vector3d& pp = out.X_WP.p_AB_m;
  trace << i << ',' << sample.time_s << ',' << pd.x() << ',' << pd.y() << ',' << pd.z() << ',' << pp.x() << ','
        << pp.y() << ',' << pp.z() << ',' << out.force_W_N.x() << ',' << out.force_W_N.y() << ','
        << out.force_W_N.z() << ',' << out.torque_W_Nm.x() << ',' << out.torque_W_Nm.y() << ','
        << out.torque_W_Nm.z() << ',' << out.stats.contacts << ',' << out.stats.exec_time_us << ',' << x.depth_m << ','
        << out.X_WP.R_AB.w() << ',' << out.X_WP.R_AB.x() << ',' << out.X_WP.R_AB.y() << ',' << out.X_WP.R_AB.z()
        << ',' << out.stats.time_of_contact << ',' << x.crossing_points << ',' << x.command_W_N.x() << ','
        << x.command_W_N.y() << ',' << x.command_W_N.z() << ',' << x.command_W_Nm.x() << ',' << x.command_W_Nm.y()
        << ',' << x.command_W_Nm.z() << ',' << sampleVerdictName(x.verdict) << ',' << x.isovalue << ','
        << x.felt_isovalue << '\n';
}

/// Tick `i` to the monitor (RunOptions::monitor) as the coupling and solver threads publish it.
void publishRunTick(SnapshotChannel& monitor, std::uint64_t i, const RunReport& r, const haptics::TickOutput& out,
                    const haptics::Pose& X_WD_used, const Eigen::Vector3d& command_W_N,
                    const Eigen::Vector3d& command_W_Nm, std::uint64_t held_ticks, double isovalue,
                    std::size_t contacts, int segment, const CriticalDistance& nearest) {
  CouplingSnapshot& c = monitor.couplingSlot();
  c.tick = i + 1;
  c.time_ns = std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now().time_since_epoch()).count();
  c.X_WP = out.X_WP;
  c.X_WD = X_WD_used;
  c.force_W_N = command_W_N;
  c.torque_W_Nm = command_W_Nm;
  c.implausible_samples = r.implausible_samples;
  c.held_ticks = held_ticks;
  monitor.publishCoupling();
  SolverSnapshot& solver = monitor.solverSlot();
  solver.tick = i + 1;
  solver.isovalue = isovalue;
  solver.contacts = static_cast<int>(contacts);
  solver.segment = segment;
  solver.critical_segment = nearest.segment;
  solver.critical_distance_m = nearest.distance_m;
  monitor.publishSolver();
}

/// The work budget's lag behind the unbudgeted reference run.
void reportLag(RunReport& r, const ProxyLag& lag) {
  r.lag_ticks = lag.ticks;
  r.max_lag_m = lag.max_m;
  r.max_lag_rad = lag.max_rad;
  r.max_behind_m = lag.max_behind_m;
  r.max_behind_rad = lag.max_behind_rad;
}

/// The tick-time statistics and the means over the run's `n` ticks (sorts `times_us`).
void summariseTicks(RunReport& r, std::vector<double>& times_us, std::uint64_t n, double contact_sum,
                    double samples_sum) {
  double sum = 0.0;
  for (double t : times_us) {
    sum += t;
    r.max_us = std::max(r.max_us, t);
  }
  r.mean_us = n ? sum / static_cast<double>(n) : 0.0;
  std::sort(times_us.begin(), times_us.end());
  r.p50_us = nearestRankPercentile(times_us, 0.50);
  r.p99_us = nearestRankPercentile(times_us, 0.99);
  r.mean_contacts = n ? contact_sum / static_cast<double>(n) : 0.0;
  r.mean_volume_samples = n ? samples_sum / static_cast<double>(n) : 0.0;
}

}  // namespace

namespace {
/// The run's arguments checked before anything is set up: a trajectory, a positive servo rate, a
/// crossing-check step >= 0 and at most a day of ticks whose times fit in memory.
/// @throws std::runtime_error for an empty trajectory, std::invalid_argument for the rest.
void checkRunArguments(const Trajectory& trajectory, const RunOptions& options) {
  if (trajectory.empty()) throw std::runtime_error("runHeadless: empty trajectory");
  if (!(options.servo_rate_Hz > 0.0)) throw std::invalid_argument("runHeadless: servo rate must be > 0");
  if (!(options.verify_step_voxels >= 0.0) || !std::isfinite(options.verify_step_voxels))
    throw std::invalid_argument("runHeadless: the crossing-check step must be >= 0 voxels (0: off)");
  // Each shell point's path is sampled 1 / step times a voxel: below a thousandth of a voxel
  // (ten times finer than the default) the check would run for hours and resolve nothing more.
  if (options.verify_step_voxels > 0.0 && options.verify_step_voxels < kMinVerifyStep_voxels) {
    char text[200];
    std::snprintf(text, sizeof text,
                  "runHeadless: a crossing-check step of %g voxel is too fine: it must be at least %g voxel (0: off; "
                  "default 0.01)",
                  options.verify_step_voxels, kMinVerifyStep_voxels);
    throw std::invalid_argument(text);
  }
  // The tick count in double first: a trajectory ending at 1e19 s would overflow the integer.
  const double duration_s = trajectory.duration_s();
  if (!(duration_s >= 0.0 && duration_s <= kMaxRunDuration_s)) {
    char text[200];
    std::snprintf(text, sizeof text, "the trajectory lasts %g s (%.3g h); a run replays at most %g s (24 h)", duration_s,
                  duration_s / 3600.0, kMaxRunDuration_s);
    throw std::invalid_argument(text);
  }
  const double ticks = std::floor(duration_s * options.servo_rate_Hz + 1e-9) + 1.0;
  io::requireFitsInMemory(static_cast<std::uint64_t>(ticks) * sizeof(double), "the run's per-tick times");
}

/// The work budget's reference: the servo's renderer again without the budget (the lag), or none
/// when the lag is not asked for, there is no budget, or the scene drills: a reference without
/// the burr feels the uncut field, and the two proxies part by the cavity's depth, not by the
/// budget (17.5 mm "lag" for a drill slid through the head phantom's skull).
std::unique_ptr<haptics::HapticRenderer> makeLagReference(const LoadedScene& scene,
                                                          const haptics::RendererOptions& renderer_options,
                                                          const haptics::Pose& X_WD_first, const RunOptions& options,
                                                          std::int64_t work_budget) {
  if (!options.lag_reference || work_budget <= 0) return nullptr;
  if (scene.spec.drill && scene.spec.drill->on) return nullptr;
  haptics::RendererOptions unbudgeted = renderer_options;
  unbudgeted.work_budget = 0;
  // Made as the servo's renderer is (the scene's gains and edge test), so that only the budget
  // differs.
  return makeRenderer(LiveValues::initial(scene), unbudgeted, X_WD_first);
}

/// The crossing check of every tick's move (RunOptions::verify_step_voxels > 0) on the field the
/// tool feels, with the report's crossing counts started at 0 (checked); off, nothing changes.
void startCrossingCheck(RunReport& r, const haptics::ScalarVolume& felt, const haptics::ToolModel& tool,
                        const RunOptions& options, std::optional<haptics::CrossingVerifier>& verifier,
                        haptics::ShellEdges& shell_edges) {
  if (!(options.verify_step_voxels > 0.0)) return;
  verifier.emplace(felt, tool.point_shell, options.verify_step_voxels);
  r.verify_step_voxels = options.verify_step_voxels;
  r.crossings = 0;
  r.crossing_points = 0;
  r.edge_crossings = 0;
  shell_edges = haptics::makeShellEdges(tool.point_shell);
}

/// The guidance of a run with RunOptions::guide (its gains within the device's limits), and its
/// "guidance" event at the recording's start; nothing without.
std::optional<GuidanceTrack> startGuidance(const RunOptions& options, const DeviceLimits& limits,
                                           RecordingWriter* recorder) {
  std::optional<GuidanceTrack> track;
  if (!options.guide) return track;
  track.emplace(options.guide, clampGuidance(options.guide_gains, limits));
  if (recorder != nullptr)
    recorder->addEvent({0.0, 0, "guidance", guidanceEventJson(*options.guide, track->gains(), options.guide_gains)});
  return track;
}

/// What a headless run ticks with, set up once by runHeadless(): the servo's renderer and its
/// checks, the scripted device behind the coupling thread's plausibility test and safety layer,
/// the outputs, and the sums over the ticks.
struct HeadlessRun {
  const LoadedScene& scene;
  const Trajectory& trajectory;
  const RunOptions& options;
  const haptics::ToolModel& tool;
  const haptics::ScalarVolume& felt;  // the field the renderer feels (carved while drilling)
  double s;                           // the scene's isovalue
  double period_s;
  haptics::HapticRenderer& renderer;
  Drill* drill;
  bool drilling;
  haptics::HapticRenderer* reference;  // without the work budget, or null
  ProxyLag& lag;
  const haptics::CrossingVerifier* verifier;  // null: no crossing check
  const haptics::ShellEdges& shell_edges;
  Device& device;  // the scripted device, or the compliant hand around it
  GuidanceTrack* guidance;  // null: no guidance
  SampleFilter& filter;
  ForceSafety& safety;
  std::ostream* trace;  // null: no trace
  RecordingWriter* recorder;
  SegmentContactTally* segment_tally;
  CriticalProximity* proximity;         // null: no critical segment
  ProximityTally* proximity_tally;
  JamDetector& jam;
  std::vector<double>& times_us;
  RunReport& r;
  haptics::Pose X_WD_used;  // the last sample the renderer ticked with
  double contact_sum = 0.0;
  double samples_sum = 0.0;
  double eroded_mm3 = 0.0;  // the drill's eroded volume after the last tick
  ServoTechnique* technique = nullptr;  // the technique rules, or null
  tissue::DeformableScene* tissue = nullptr;  // soft tissue stepped before each tick, or null
  std::vector<TissueTick> tissue_ticks{};  // per rendered tick with tissue
};

/// One tick's device sample, what the renderer made of it and the command the device got.
struct RunTick {
  DeviceSample sample;
  SampleFilter::Verdict verdict = SampleFilter::Verdict::kGood;
  bool sample_ok = false;
  double isovalue = 0.0;  // asked for this tick
  haptics::TickOutput out;
  haptics::Pose X_WP_before;  // the proxy before the tick
  Eigen::Vector3d command_W_N, command_W_Nm;
};

/// Tick `i`'s servo work: read and test the device sample, render it (a rejected sample is not
/// rendered: the proxy stays, no force) and command the safety layer's force to the device.
void renderRunTick(HeadlessRun& run, std::uint64_t i, RunTick& t) {
  const bool read_ok = run.device.read(t.sample);
  t.verdict = run.filter.check(t.sample, read_ok, i == 0 ? 0.0 : run.period_s);
  t.sample_ok = t.verdict == SampleFilter::Verdict::kGood || t.verdict == SampleFilter::Verdict::kReseeded;
  // The isovalue asked for this tick: the trajectory's ninth column, else the scene's.
  t.isovalue = run.trajectory.isovalueAt(t.sample.time_s, run.s);
  t.X_WP_before = run.renderer.proxyPose();
  if (t.sample_ok) {
    tissue::DeformableStep step;
    if (run.tissue != nullptr) step = run.tissue->step(t.sample.X_WD, run.renderer);
    t.out = run.renderer.tick(t.sample.X_WD, t.isovalue);
    if (run.tissue != nullptr)
      run.tissue_ticks.push_back({step.indentation_m, t.out.force_W_N.norm(), step.contact.force_on_device_N.norm(),
                                  step.step_us});
    run.X_WD_used = t.sample.X_WD;
  } else {
    t.out.X_WP = run.renderer.proxyPose();  // not rendered: the proxy stays, no force
    t.out.stats.contacts = static_cast<int>(run.renderer.contacts().size());
    if (t.verdict == SampleFilter::Verdict::kImplausible) ++run.r.implausible_samples;
  }
  SafetyInput safety_in =
      runSafetyInput(t.sample_ok && !t.out.stats.bad_input, t.verdict, t.sample, run.period_s, t.out);
  if (run.guidance != nullptr)  // the guidance spring goes through the same safety layer
    safety_in.force_W_N += run.guidance->step(i, run.options.servo_rate_Hz, t.sample.X_WD.p_AB_m,
                                              safety_in.sample_ok, run.recorder);
  run.safety.step(safety_in, t.command_W_N, t.command_W_Nm);
  run.device.command(t.command_W_N, t.command_W_Nm);
}

/// The burr's cut after tick `i`'s checks, and a "critical_removed" event in the recording (as the
/// GUI writes it) when it removed part of a critical segment. @return the cut.
haptics::CutResult drillRunTick(HeadlessRun& run, std::uint64_t i, const haptics::TickOutput& out) {
  const haptics::CutResult cut = run.drill->step(run.renderer, out);
  if (cut.critical_removed <= 0 || !run.recorder) return cut;
  // As the GUI does: every removal of a critical segment is an event with its count.
  RecordingEvent event;
  event.time_s = static_cast<double>(i) / run.options.servo_rate_Hz;
  event.tick = i + 1;
  event.type = "critical_removed";
  event.detail_json =
      nlohmann::json{{"segment", run.drill->removal().materials()[static_cast<std::size_t>(cut.critical_material)].name},
                     {"voxels", cut.critical_removed},
                     {"mm3", cut.critical_removed * run.drill->removal().voxelVolume_mm3()}}
          .dump();
  run.recorder->addEvent(event);
  return cut;
}

/// Tick `i`'s burr to RunOptions::on_drill_tick (scenes with a drill): on or off, the force it
/// cut with, the hardness of what it cut, the removal rate, and whether a critical segment was
/// touched (`segment`, the contacts' segment) or cut.
void reportDrillTick(HeadlessRun& run, std::uint64_t i, bool drill_on, const haptics::CutResult& cut,
                     const haptics::TickOutput& out, int segment) {
  if (run.drill == nullptr || !run.options.on_drill_tick) return;
  const double eroded_mm3 = run.drill->removal().erodedVolume_mm3();
  const bool critical_contact =
      segment >= 0 && run.scene.segments && run.scene.segments->isCritical(segment) && out.stats.contacts > 0;
  const DrillTick d = drillTickOf(i + 1, static_cast<double>(i) / run.options.servo_rate_Hz, drill_on, cut, out,
                                  eroded_mm3 - run.eroded_mm3, run.period_s, critical_contact);
  run.eroded_mm3 = eroded_mm3;
  run.options.on_drill_tick(d);
}

/// The jam detector (jam_detector.h) after tick `i`: held in contact, far from a device in free
/// space. @return whether the proxy is jammed now.
bool updateRunJam(HeadlessRun& run, std::uint64_t i, const RunTick& t) {
  const bool stuck =
      t.sample_ok && !t.out.stats.bad_input &&
      JamDetector::candidate(t.X_WP_before, run.renderer.proxyPose(), t.sample.X_WD, run.tool.mass.p_TCm_m,
                             static_cast<int>(run.renderer.contacts().size())) &&
      countPointsInside(run.renderer.volume(), run.tool.point_shell, t.sample.X_WD, run.renderer.feltIsovalue()) == 0;
  const bool jammed = run.jam.update(stuck);
  if (jammed && run.r.first_jam_tick < 0) run.r.first_jam_tick = static_cast<std::int64_t>(i);
  return jammed;
}

/// The nearest critical segment after tick `i` (the proxy's shell against each one's distance
/// field), each one's distance into the tally.
CriticalDistance measureProximity(HeadlessRun& run, std::uint64_t i) {
  if (run.proximity == nullptr) return {};
  const CriticalDistance nearest = run.proximity->evaluate(run.renderer.proxyPose());
  const auto& critical = run.scene.segments->critical();
  const auto per_segment = run.proximity->perSegment();
  const double dt_s = 1.0 / run.options.servo_rate_Hz;
  for (std::size_t k = 0; k < per_segment.size(); ++k)
    run.proximity_tally->add(critical[k], per_segment[k].distance_m, static_cast<double>(i) * dt_s, dt_s);
  run.proximity_tally->endTick();
  return nearest;
}

/// Tick `i`'s bookkeeping, outside the timed section (exec_time_us is measured by tick()): the
/// reference's lag, the counts, the crossing and depth checks, the burr, the jam detector, and
/// the recording, trace and monitor.
void checkRunTick(HeadlessRun& run, std::uint64_t i, const RunTick& t) {
  const haptics::TickOutput& out = t.out;
  RunReport& r = run.r;
  run.times_us.push_back(out.stats.exec_time_us);
  if (run.reference && t.sample_ok) {
    const haptics::TickOutput ref = run.reference->tick(t.sample.X_WD, t.isovalue);
    if (ref.X_WP.allFinite() && out.X_WP.allFinite()) run.lag.add(out.X_WP, ref.X_WP, t.sample.X_WD);
  }
  addTickCounts(r, out, t.command_W_N, i, t.sample_ok, run.contact_sum, run.samples_sum);
  // |F| itself must be finite: components near 1e300 (a stiffness of 1e300 N/m) square to inf.
  const bool finite = out.force_W_N.allFinite() && out.torque_W_Nm.allFinite() && out.X_WP.allFinite() &&
                      std::isfinite(out.force_W_N.norm()) && std::isfinite(out.torque_W_Nm.norm());
  const int segment = run.scene.segments ? run.scene.segments->segmentOf(run.renderer.contacts()) : -1;
  if (run.segment_tally) run.segment_tally->add(segment, out.force_W_N.norm(), 1.0 / run.options.servo_rate_Hz);
  // The checks below use the isovalue the renderer rendered this tick (it may lag the
  // requested one while the tool presses on the surface: a lowered isovalue is deferred for
  // the hand), and the trace writes both.
  const double felt_isovalue = std::isfinite(out.stats.felt_isovalue) ? out.stats.felt_isovalue : t.isovalue;
  const int crossing_points = run.verifier && finite && t.sample_ok
                                  ? checkCrossings(r, *run.verifier, run.shell_edges, run.renderer, felt_isovalue, i)
                                  : -1;
  double depth = 0.0;
  if (!finite) ++r.nan_ticks;
  else depth = addForceAndDepth(r, out, run.X_WD_used, run.felt, run.tool, felt_isovalue, run.options.check_penetration, i);
  // The burr cuts after the checks (they test this tick's motion against the field it moved in).
  const bool drill_on = run.drilling && t.sample_ok && !out.stats.bad_input;
  const haptics::CutResult cut = drill_on ? drillRunTick(run, i, out) : haptics::CutResult{};
  reportDrillTick(run, i, drill_on, cut, out, segment);
  const bool jammed = updateRunJam(run, i, t);
  const CriticalDistance nearest = measureProximity(run, i);
  std::uint32_t technique = run.technique != nullptr ? run.technique->monitor().active() : 0u;
  if (run.technique != nullptr && t.sample_ok && !out.stats.bad_input && finite) {
    technique = run.technique->tick(static_cast<double>(i) * run.period_s, run.X_WD_used, out.force_W_N.norm(),
                                    run.renderer.contacts(), drill_on, cut.material, segment, nearest.distance_m);
  }
  if (run.recorder) {
    TickRecord rec = runRecord(i, run.options.servo_rate_Hz, run.X_WD_used, run.renderer.proxyPose(), out, t.isovalue,
                               run.renderer.contacts().size(), finite, t.sample_ok, segment);
    if (drill_on) rec.flags |= kRecordFlagDrillOn;
    rec.removed_voxels = static_cast<std::uint32_t>(std::max(0, cut.voxels_removed));
    if (jammed) rec.flags |= kRecordFlagJam;
    rec.flags |= recordTechniqueBits(technique);
    rec.critical_distance_m = nearest.distance_m;
    rec.critical_segment = nearest.segment;
    run.recorder->pushWaiting(rec);
  }
  if (run.trace != nullptr) {
    writeTraceRow(*run.trace, i, t.sample, out,
                  {depth, crossing_points, t.command_W_N, t.command_W_Nm, t.verdict, t.isovalue, felt_isovalue});
  }
  if (SnapshotChannel* monitor = run.options.monitor.get()) {
    publishRunTick(*monitor, i, r, out, run.X_WD_used, t.command_W_N, t.command_W_Nm, run.safety.stats().held_ticks,
                   t.isovalue, run.renderer.contacts().size(), segment, nearest);
  }
}

/// Force against indentation from the rendered ticks.
TissueReport tissueReport(const std::vector<TissueTick>& ticks) {
  TissueReport t;
  for (const TissueTick& k : ticks) {
    t.max_indentation_m = std::max(t.max_indentation_m, k.indentation_m);
    t.max_push_N = std::max(t.max_push_N, k.push_N);
    t.mean_step_us += k.step_us / static_cast<double>(ticks.size());
    t.max_step_us = std::max(t.max_step_us, k.step_us);
  }
  if (t.max_indentation_m > 0.0) {
    for (int b = 1; b <= 10; ++b) t.force_by_indentation.emplace_back(t.max_indentation_m * b / 10.0, 0.0);
    for (const TissueTick& k : ticks) {
      if (!(k.indentation_m > 0.0)) continue;
      const auto b = static_cast<std::size_t>(
          std::clamp(static_cast<int>(std::ceil(10.0 * k.indentation_m / t.max_indentation_m)) - 1, 0, 9));
      t.force_by_indentation[b].second = std::max(t.force_by_indentation[b].second, k.force_N);
    }
  }
  return t;
}

/// After the last of the `n` ticks: the recording closed (what the burr removed is in its
/// records, TickRecord::removed_voxels, as in the window's), and the report's totals.
/// @throws std::runtime_error naming the recording when one of its writes failed.
void finishRun(HeadlessRun& run, std::uint64_t n, std::chrono::steady_clock::time_point wall_begin) {
  RunReport& r = run.r;
  if (run.recorder) run.recorder->close();  // throws naming the file when a write failed
  if (run.segment_tally) r.segment_contacts = run.segment_tally->segments();
  if (run.proximity_tally) r.proximity = run.proximity_tally->segments();
  if (run.drill != nullptr) r.drill = drillReportOf(*run.drill, run.scene);
  if (run.tissue != nullptr) r.tissue = tissueReport(run.tissue_ticks);
  if (run.reference) reportLag(r, run.lag);
  if (run.guidance != nullptr) r.guidance = run.guidance->report(run.options.hand.has_value());
  r.total_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall_begin).count();
  r.ticks = n;
  r.held_ticks = run.safety.stats().held_ticks;
  r.jam_ticks = run.jam.jamTicks();
  r.jams = run.jam.jams();
  for (int k = 0; k < kTechniqueRuleCount && run.technique != nullptr; ++k)
    r.technique_episodes[static_cast<std::size_t>(k)] = run.technique->monitor().episodes(k);
  summariseTicks(r, run.times_us, n, run.contact_sum, run.samples_sum);
}
}  // namespace

RunReport runHeadless(const LoadedScene& scene, const Trajectory& trajectory, const RunOptions& options) {
  checkRunArguments(trajectory, options);
  const haptics::ScalarVolume& volume = *scene.hapticField();
  const haptics::ToolModel& tool = *scene.tool;
  const double s = scene.hapticIsovalue();

  RunReport r;
  describeRun(r, scene, volume, tool, s, trajectory, options);

  const haptics::Pose X_WD_first = trajectory.samples().front().X_WD;
  r.initial_points_inside = countPointsInside(volume, tool.point_shell, X_WD_first, s);
  haptics::RendererOptions renderer_options;
  renderer_options.gains = scene.spec.gains;
  // With a "drill" section the renderer feels its own copy of the field, which the burr carves
  // after each tick's checks; the checks read that carved field.
  DrillingRenderer servo = makeServoRenderer(LiveValues::initial(scene), renderer_options, X_WD_first, options.servo_rate_Hz);
  Drill* const drill = servo.drill.get();
  // With tissue, its deformed field (rewritten in place before each tick): the checks read it.
  const haptics::ScalarVolume& felt = drill != nullptr        ? drill->removal().volume()
                                      : servo.tissue != nullptr ? *servo.tissue->feltVolume()
                                                                : volume;
  r.epsilon_m = servo.renderer->epsilon_m();
  r.work_budget = servo.renderer->workBudget();
  // The same without the budget: the lag.
  // (Not with tissue: the reference would feel the rigid scan, not the tissue's field.)
  std::unique_ptr<haptics::HapticRenderer> reference =
      servo.tissue != nullptr ? nullptr : makeLagReference(scene, renderer_options, X_WD_first, options, r.work_budget);
  ProxyLag lag;
  std::optional<haptics::CrossingVerifier> verifier;
  haptics::ShellEdges shell_edges;
  startCrossingCheck(r, felt, tool, options, verifier, shell_edges);
  ScriptedDevice scripted(trajectory, 1.0 / options.servo_rate_Hz);
  scripted.setLimits(options.device_limits);
  scripted.setSafetyPolicy(options.safety_policy);
  scripted.setActuatedDof(options.actuated_dof);
  std::optional<CompliantHand> hand;
  if (options.hand) hand.emplace(scripted, *options.hand, 1.0 / options.servo_rate_Hz);
  Device& device = hand ? static_cast<Device&>(*hand) : scripted;
  // The same plausibility test and safety layer as the coupling thread (HapticThread): a sample
  // faster than the device moves, outside its workspace or not finite is never rendered; the
  // command the device gets is the safety layer's (fault hold, ramp, clamp).
  SampleFilter filter(device.limits());
  ForceSafety safety(device.limits(), device.safetyPolicy(), device.actuatedDof());
  safety.enable();

  const auto n = static_cast<std::uint64_t>(std::floor(trajectory.duration_s() * options.servo_rate_Hz + 1e-9)) + 1;
  std::vector<double> times_us;
  times_us.reserve(n);
  const std::unique_ptr<io::PrivateOutput> trace = openTrace(options.trace_csv);
  std::unique_ptr<RecordingWriter> recorder = openRecorder(scene, X_WD_first, device, options);
  std::optional<SegmentContactTally> segment_tally = segmentTally(scene);
  std::optional<CriticalProximity> proximity;
  std::optional<ProximityTally> proximity_tally;
  if (scene.segments && !scene.segments->critical().empty()) {
    proximity.emplace(*scene.segments, tool.point_shell);
    proximity_tally.emplace(proximityTally(*scene.segments));
  }
  JamDetector jam;
  std::optional<GuidanceTrack> guidance = startGuidance(options, device.limits(), recorder.get());
  HeadlessRun run{scene,  trajectory, options, tool, felt, s, 1.0 / options.servo_rate_Hz, *servo.renderer, drill,
                  drill != nullptr && scene.spec.drill && scene.spec.drill->on, reference.get(), lag,
                  verifier ? &*verifier : nullptr, shell_edges, device, guidance ? &*guidance : nullptr, filter, safety,
                  trace != nullptr ? &trace->stream() : nullptr, recorder.get(), segment_tally ? &*segment_tally : nullptr, proximity ? &*proximity : nullptr,
                  proximity_tally ? &*proximity_tally : nullptr, jam, times_us, r, X_WD_first};
  const std::unique_ptr<ServoTechnique> technique = makeServoTechnique(LiveValues::initial(scene), drill);
  run.technique = technique.get();
  run.tissue = servo.tissue.get();
  if (run.tissue != nullptr) run.tissue_ticks.reserve(n);  // as times_us: no growth in the loop
  const auto wall_begin = std::chrono::steady_clock::now();
  for (std::uint64_t i = 0; i < n; ++i) {
    RunTick t;
    renderRunTick(run, i, t);
    checkRunTick(run, i, t);
    if (options.realtime) std::this_thread::sleep_until(wall_begin + std::chrono::nanoseconds(static_cast<std::int64_t>(1e9 * static_cast<double>(i + 1) / options.servo_rate_Hz)));
  }
  finishRun(run, n, wall_begin);
  if (trace != nullptr) trace->commit();  // @throws "cannot write TRACE: write failed (disk full?)"
  return r;
}

RunReport runHeadless(const SceneSpec& scene, const std::filesystem::path& trajectory_csv, const RunOptions& options) {
  const Trajectory trajectory = loadTrajectoryCsv(trajectory_csv);
  const LoadedScene loaded = loadScene(scene);
  if (options.on_notice) {
    for (const std::string& notice : loaded.volume.info.notices) options.on_notice(notice);
  }
  RunReport report = runHeadless(loaded, trajectory, options);
  report.trajectory = trajectory_csv.string();
  return report;
}

}  // namespace vh::runtime
