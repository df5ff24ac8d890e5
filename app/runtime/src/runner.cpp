#include "vh/runtime/runner.h"

#include "vh/runtime/jam_detector.h"
#include "vh/runtime/placement.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iomanip>
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

/// The per-tick trace CSV with its header written (RunOptions::trace_csv), or a closed stream
/// when none is asked for.
std::ofstream openTrace(const std::filesystem::path& trace_csv) {
  std::ofstream trace;
  if (!trace_csv.empty()) {
    try {
      io::createPrivateFile(trace_csv);  // 0600: the session's poses and forces
    } catch (const std::runtime_error&) {
      throw std::runtime_error(trace_csv.string() + ": cannot write the trace");
    }
    trace.open(trace_csv);
    if (!trace) throw std::runtime_error(trace_csv.string() + ": cannot write the trace");
    trace << "tick,t_s,xd_m,yd_m,zd_m,xp_m,yp_m,zp_m,fx_N,fy_N,fz_N,tx_Nm,ty_Nm,tz_Nm,contacts,exec_us,penetration_m,"
             "qw_p,qx_p,qy_p,qz_p,time_of_contact,crossing_points,cmd_fx_N,cmd_fy_N,cmd_fz_N,cmd_tx_Nm,cmd_ty_Nm,"
             "cmd_tz_Nm,sample,isovalue,felt_isovalue\n"
          << std::setprecision(9);
  }
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
              (sample_ok ? 0u : kRecordFlagBadSample) | recordSegmentBits(segment);
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

/// One row of the trace CSV (openTrace()'s columns).
void writeTraceRow(std::ofstream& trace, std::uint64_t i, const DeviceSample& sample, const haptics::TickOutput& out,
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
                    std::size_t contacts, int segment) {
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
/// Removed volume per material (the HU classes and the segments).
DrillReport drillReport(const Drill& drill, const LoadedScene& scene) {
  DrillReport d;
  const haptics::MaterialRemoval& removal = drill.removal();
  d.burr_radius_m = drill.burr().radius_m;
  d.removed_mm3 = drill.removed_mm3();
  d.eroded_mm3 = removal.erodedVolume_mm3();
  Sha256 sha;
  sha.update(removal.volume().bytes().data(), removal.volume().bytes().size());
  d.drilled_field_sha256 = sha.hexDigest();
  for (std::size_t m = 0; m < removal.materials().size(); ++m) {
    const auto& material = removal.materials()[m];
    DrillReport::Material row;
    row.name = material.name;
    row.segment = drill.segmentOfMaterial(static_cast<int>(m)) >= 0 && scene.segments ? material.name : "";
    row.critical = material.critical;
    row.voxels = removal.removedVoxels(static_cast<int>(m));
    row.removed_mm3 = static_cast<double>(row.voxels) * removal.voxelVolume_mm3();
    row.specific_energy_J_per_mm3 = material.specific_energy_J_per_mm3;
    d.materials.push_back(row);
  }
  return d;
}
}  // namespace

RunReport runHeadless(const LoadedScene& scene, const Trajectory& trajectory, const RunOptions& options) {
  if (trajectory.empty()) throw std::runtime_error("runHeadless: empty trajectory");
  if (!(options.servo_rate_Hz > 0.0)) throw std::invalid_argument("runHeadless: servo rate must be > 0");
  if (!(options.verify_step_voxels >= 0.0) || !std::isfinite(options.verify_step_voxels))
    throw std::invalid_argument("runHeadless: the crossing-check step must be >= 0 voxels (0: off)");
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
  haptics::HapticRenderer& renderer = *servo.renderer;
  Drill* const drill = servo.drill.get();
  const bool drilling = drill != nullptr && scene.spec.drill && scene.spec.drill->on;
  const haptics::ScalarVolume& felt = drill != nullptr ? drill->removal().volume() : volume;
  r.epsilon_m = renderer.epsilon_m();
  r.work_budget = renderer.workBudget();
  std::unique_ptr<haptics::HapticRenderer> reference;  // the same without the budget: the lag
  ProxyLag lag;
  if (options.lag_reference && r.work_budget > 0) {
    haptics::RendererOptions unbudgeted = renderer_options;
    unbudgeted.work_budget = 0;
    // Made as the servo's renderer is (the scene's gains and edge test), so that only the budget
    // differs (a drilling scene's reference feels the uncut field).
    reference = makeRenderer(LiveValues::initial(scene), unbudgeted, X_WD_first);
  }
  std::optional<haptics::CrossingVerifier> verifier;
  haptics::ShellEdges shell_edges;
  if (options.verify_step_voxels > 0.0) {
    verifier.emplace(felt, tool.point_shell, options.verify_step_voxels);
    r.verify_step_voxels = options.verify_step_voxels;
    r.crossings = 0;
    r.crossing_points = 0;
    r.edge_crossings = 0;
    shell_edges = haptics::makeShellEdges(tool.point_shell);
  }
  ScriptedDevice device(trajectory, 1.0 / options.servo_rate_Hz);
  device.setLimits(options.device_limits);
  device.setSafetyPolicy(options.safety_policy);
  device.setActuatedDof(options.actuated_dof);
  // The same plausibility test and safety layer as the coupling thread (HapticThread): a sample
  // faster than the device moves, outside its workspace or not finite is never rendered; the
  // command the device gets is the safety layer's (fault hold, ramp, clamp).
  const double period_s = 1.0 / options.servo_rate_Hz;
  SampleFilter filter(device.limits());
  ForceSafety safety(device.limits(), device.safetyPolicy(), device.actuatedDof());
  safety.enable();
  haptics::Pose X_WD_used = X_WD_first;  // the last sample the renderer ticked with

  const auto n = static_cast<std::uint64_t>(std::floor(trajectory.duration_s() * options.servo_rate_Hz + 1e-9)) + 1;
  std::vector<double> times_us;
  times_us.reserve(n);
  std::ofstream trace = openTrace(options.trace_csv);
  std::unique_ptr<RecordingWriter> recorder = openRecorder(scene, X_WD_first, device, options);
  std::optional<SegmentContactTally> segment_tally = segmentTally(scene);
  double contact_sum = 0.0, samples_sum = 0.0;
  JamDetector jam;
  const auto wall_begin = std::chrono::steady_clock::now();
  for (std::uint64_t i = 0; i < n; ++i) {
    DeviceSample sample;
    const bool read_ok = device.read(sample);
    const SampleFilter::Verdict verdict = filter.check(sample, read_ok, i == 0 ? 0.0 : period_s);
    const bool sample_ok = verdict == SampleFilter::Verdict::kGood || verdict == SampleFilter::Verdict::kReseeded;
    // The isovalue asked for this tick: the trajectory's ninth column, else the scene's.
    const double isovalue = trajectory.isovalueAt(sample.time_s, s);
    haptics::TickOutput out;
    const haptics::Pose X_WP_before = renderer.proxyPose();
    if (sample_ok) {
      out = renderer.tick(sample.X_WD, isovalue);
      X_WD_used = sample.X_WD;
    } else {
      out.X_WP = renderer.proxyPose();  // not rendered: the proxy stays, no force
      out.stats.contacts = static_cast<int>(renderer.contacts().size());
      if (verdict == SampleFilter::Verdict::kImplausible) ++r.implausible_samples;
    }
    const SafetyInput safety_in = runSafetyInput(sample_ok && !out.stats.bad_input, verdict, sample, period_s, out);
    Eigen::Vector3d command_W_N, command_W_Nm;
    safety.step(safety_in, command_W_N, command_W_Nm);
    device.command(command_W_N, command_W_Nm);

    // Everything below is outside the timed section (exec_time_us is measured by tick()).
    times_us.push_back(out.stats.exec_time_us);
    if (reference && sample_ok) {
      const haptics::TickOutput ref = reference->tick(sample.X_WD, isovalue);
      if (ref.X_WP.allFinite() && out.X_WP.allFinite()) lag.add(out.X_WP, ref.X_WP, sample.X_WD);
    }
    addTickCounts(r, out, command_W_N, i, sample_ok, contact_sum, samples_sum);
    // |F| itself must be finite: components near 1e300 (a stiffness of 1e300 N/m) square to inf.
    const bool finite = out.force_W_N.allFinite() && out.torque_W_Nm.allFinite() && out.X_WP.allFinite() &&
                        std::isfinite(out.force_W_N.norm()) && std::isfinite(out.torque_W_Nm.norm());
    const int segment = scene.segments ? scene.segments->segmentOf(renderer.contacts()) : -1;
    if (segment_tally) segment_tally->add(segment, out.force_W_N.norm(), 1.0 / options.servo_rate_Hz);
    // The checks below use the isovalue the renderer rendered this tick (it may lag the
    // requested one while the tool presses on the surface: a lowered isovalue is deferred for
    // the hand), and the trace writes both.
    const double felt_isovalue = std::isfinite(out.stats.felt_isovalue) ? out.stats.felt_isovalue : isovalue;
    const int crossing_points =
        verifier && finite && sample_ok ? checkCrossings(r, *verifier, shell_edges, renderer, felt_isovalue, i) : -1;
    double depth = 0.0;
    if (!finite) ++r.nan_ticks;
    else depth = addForceAndDepth(r, out, X_WD_used, felt, tool, felt_isovalue, options.check_penetration, i);
    // The burr cuts after the checks (they test this tick's motion against the field it moved in).
    if (drilling && sample_ok && !out.stats.bad_input) {
      const haptics::CutResult cut = drill->step(renderer, out);
      if (cut.critical_removed > 0 && recorder) {
        // As the GUI does: every removal of a critical segment is an event with its count.
        RecordingEvent event;
        event.time_s = static_cast<double>(i) / options.servo_rate_Hz;
        event.tick = i + 1;
        event.type = "critical_removed";
        event.detail_json = nlohmann::json{{"segment", drill->removal().materials()[static_cast<std::size_t>(cut.critical_material)].name},
                                           {"voxels", cut.critical_removed},
                                           {"mm3", cut.critical_removed * drill->removal().voxelVolume_mm3()}}
                                .dump();
        recorder->addEvent(event);
      }
    }
    // The jam detector (jam_detector.h): held in contact, far from a device in free space.
    const bool stuck = sample_ok && !out.stats.bad_input &&
                       JamDetector::candidate(X_WP_before, renderer.proxyPose(), sample.X_WD, tool.mass.p_TCm_m,
                                              static_cast<int>(renderer.contacts().size())) &&
                       countPointsInside(renderer.volume(), tool.point_shell, sample.X_WD, renderer.feltIsovalue()) == 0;
    const bool jammed = jam.update(stuck);
    if (jammed && r.first_jam_tick < 0) r.first_jam_tick = static_cast<std::int64_t>(i);
    if (recorder) {
      TickRecord rec = runRecord(i, options.servo_rate_Hz, X_WD_used, renderer.proxyPose(), out, isovalue,
                                 renderer.contacts().size(), finite, sample_ok, segment);
      if (drilling && sample_ok && !out.stats.bad_input) rec.flags |= kRecordFlagDrillOn;
      if (jammed) rec.flags |= kRecordFlagJam;
      recorder->pushWaiting(rec);
    }
    if (trace.is_open()) {
      writeTraceRow(trace, i, sample, out,
                    {depth, crossing_points, command_W_N, command_W_Nm, verdict, isovalue, felt_isovalue});
    }
    if (SnapshotChannel* monitor = options.monitor.get()) {
      publishRunTick(*monitor, i, r, out, X_WD_used, command_W_N, command_W_Nm, safety.stats().held_ticks, isovalue,
                     renderer.contacts().size(), segment);
    }
    if (options.realtime) std::this_thread::sleep_until(wall_begin + std::chrono::nanoseconds(static_cast<std::int64_t>(1e9 * static_cast<double>(i + 1) / options.servo_rate_Hz)));
  }
  if (recorder && drill != nullptr && n > 0) {
    // What the burr removed in all, for the cohort table (session_metrics.h: removed_mm3).
    RecordingEvent event;
    event.time_s = static_cast<double>(n - 1) / options.servo_rate_Hz;
    event.tick = n;
    event.type = "drilled";
    event.detail_json =
        nlohmann::json{{"voxels", drill->removal().removedVoxels()}, {"mm3", drill->removed_mm3()}}.dump();
    recorder->addEvent(event);
  }
  if (recorder) recorder->close();  // throws naming the file when a write failed
  if (segment_tally) r.segment_contacts = segment_tally->segments();
  if (drill != nullptr) r.drill = drillReport(*drill, scene);
  if (reference) reportLag(r, lag);
  r.total_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall_begin).count();
  r.ticks = n;
  r.held_ticks = safety.stats().held_ticks;
  r.jam_ticks = jam.jamTicks();
  r.jams = jam.jams();
  summariseTicks(r, times_us, n, contact_sum, samples_sum);
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

std::string RunReport::toJson() const {
  nlohmann::ordered_json j;
  j["scene"] = scene;
  j["trajectory"] = trajectory;
  j["volume"] = volume;
  j["volume_notices"] = volume_notices;
  j["volume_dims"] = volume_dims;
  j["volume_spacing_m"] = {volume_spacing_m.x(), volume_spacing_m.y(), volume_spacing_m.z()};
  j["isovalue"] = isovalue;
  j["tool"] = tool;
  j["point_count"] = point_count;
  j["point_spacing_m"] = point_spacing_m;
  j["epsilon_m"] = epsilon_m;
  j["feature_size_m"] = feature_size_m;
  j["servo_rate_Hz"] = servo_rate_Hz;
  j["trajectory_duration_s"] = trajectory_duration_s;
  j["ticks"] = ticks;
  j["mean_us"] = mean_us;
  j["p50_us"] = p50_us;
  j["p99_us"] = p99_us;
  j["max_us"] = max_us;
  j["ticks_over_1ms"] = ticks_over_1ms;
  j["total_s"] = total_s;
  j["max_contacts"] = max_contacts;
  j["mean_contacts"] = mean_contacts;
  j["ticks_in_contact"] = ticks_in_contact;
  j["first_contact_tick"] = first_contact_tick;
  j["max_force_N"] = max_force_N;
  j["max_torque_Nm"] = max_torque_Nm;
  j["mean_volume_samples"] = mean_volume_samples;
  j["max_penetration_m"] = max_penetration_m;
  j["max_penetration_tick"] = max_penetration_tick;
  j["ticks_penetrating"] = ticks_penetrating;
  j["nan_ticks"] = nan_ticks;
  // Not checked: null (never a 0 that reads as "no crossing").
  const auto checked = [this](std::int64_t v) { return crossingsChecked() ? nlohmann::ordered_json(v) : nlohmann::ordered_json(nullptr); };
  j["verify_step_voxels"] = verify_step_voxels;
  j["crossings"] = checked(crossings);
  j["crossing_points"] = checked(crossing_points);
  j["first_crossing_tick"] = checked(first_crossing_tick);
  j["edge_crossings"] = checked(edge_crossings);
  j["first_edge_crossing_tick"] = checked(first_edge_crossing_tick);
  j["verify_s"] = verify_s;
  j["bad_device_samples"] = bad_device_samples;
  j["implausible_samples"] = implausible_samples;
  j["held_ticks"] = held_ticks;
  j["max_command_force_N"] = max_command_force_N;
  j["initial_points_inside"] = initial_points_inside;
  j["final_force_N"] = final_force_N;
  j["final_proxy_device_distance_m"] = final_proxy_device_distance_m;
  j["max_proxy_device_distance_m"] = max_proxy_device_distance_m;
  j["jams"] = jams;
  j["jam_ticks"] = jam_ticks;
  j["first_jam_tick"] = first_jam_tick;
  j["work_budget"] = work_budget;
  j["budget_cuts"] = budget_cuts;
  j["max_work"] = max_work;
  // Not measured: null.
  j["lag_ticks"] = lag_ticks >= 0 ? nlohmann::ordered_json(lag_ticks) : nlohmann::ordered_json(nullptr);
  j["max_lag_m"] = max_lag_m >= 0.0 ? nlohmann::ordered_json(max_lag_m) : nlohmann::ordered_json(nullptr);
  j["max_lag_rad"] = max_lag_rad >= 0.0 ? nlohmann::ordered_json(max_lag_rad) : nlohmann::ordered_json(nullptr);
  j["max_behind_m"] = lag_ticks >= 0 ? nlohmann::ordered_json(max_behind_m) : nlohmann::ordered_json(nullptr);
  j["max_behind_rad"] = lag_ticks >= 0 ? nlohmann::ordered_json(max_behind_rad) : nlohmann::ordered_json(nullptr);
  j["segments"] = nlohmann::ordered_json::array();
  for (const SegmentContact& c : segment_contacts) {
    j["segments"].push_back({{"name", c.name},
                             {"critical", c.critical},
                             {"time_in_contact_s", c.time_in_contact_s},
                             {"peak_force_N", c.peak_force_N},
                             {"touches", c.touches}});
  }
  if (drill) {
    j["removed_mm3"] = drill->removed_mm3;
    j["eroded_mm3"] = drill->eroded_mm3;
    j["burr_radius_m"] = drill->burr_radius_m;
    j["drilled_field_sha256"] = drill->drilled_field_sha256;
    j["removed"] = nlohmann::ordered_json::array();
    for (const auto& m : drill->materials)
      j["removed"].push_back({{"material", m.name},
                              {"segment", m.segment.empty() ? nlohmann::ordered_json(nullptr) : nlohmann::ordered_json(m.segment)},
                              {"critical", m.critical},
                              {"voxels", m.voxels},
                              {"removed_mm3", m.removed_mm3},
                              {"specific_energy_J_per_mm3", m.specific_energy_J_per_mm3}});
  }
  return j.dump(2) + "\n";
}

std::string RunReport::summary() const {
  char line[640];
  std::snprintf(line, sizeof line,
                "ticks %llu, exec mean %.0f us, p50 %.0f us, p99 %.0f us, max %.0f us; %zu points; contacts <= %d "
                "(mean %.1f); max force %.2f N; penetration %.4f mm (epsilon %.4f mm); nan ticks %llu; bad samples %llu; ",
                static_cast<unsigned long long>(ticks), mean_us, p50_us, p99_us, max_us, point_count, max_contacts,
                mean_contacts, max_force_N, max_penetration_m * 1e3, epsilon_m * 1e3,
                static_cast<unsigned long long>(nan_ticks), static_cast<unsigned long long>(bad_device_samples));
  std::string out = line;
  if (!crossingsChecked()) {
    out += "crossings not checked (verify step 0)";
  } else if (crossings == 0) {
    std::snprintf(line, sizeof line, "crossings 0 (checked at %g voxel)", verify_step_voxels);
    out += line;
  } else {
    std::snprintf(line, sizeof line, "crossings %lld (%lld point%s, first at tick %lld; checked at %g voxel)",
                  static_cast<long long>(crossings), static_cast<long long>(crossing_points),
                  crossing_points == 1 ? "" : "s", static_cast<long long>(first_crossing_tick), verify_step_voxels);
    out += line;
  }
  if (crossingsChecked()) {
    if (edge_crossings == 0) {
      out += ", edges 0";
    } else {
      std::snprintf(line, sizeof line, ", edges %lld (first at tick %lld)", static_cast<long long>(edge_crossings),
                    static_cast<long long>(first_edge_crossing_tick));
      out += line;
    }
  }
  if (work_budget > 0) {
    std::snprintf(line, sizeof line, "; work budget %lld: %llu ticks cut, max work %lld",
                  static_cast<long long>(work_budget), static_cast<unsigned long long>(budget_cuts),
                  static_cast<long long>(max_work));
    out += line;
    if (lag_ticks >= 0) {
      std::snprintf(line, sizeof line,
                    ", lag behind the unbudgeted proxy %.3f mm, %.4f rad (%lld ticks), behind %.3f mm, %.4f rad",
                    max_lag_m * 1e3, max_lag_rad, static_cast<long long>(lag_ticks), max_behind_m * 1e3,
                    max_behind_rad);
      out += line;
    }
  }
  if (jams == 0) {
    out += "; jams 0";
  } else {
    std::snprintf(line, sizeof line, "; jams %llu (%llu ticks, first at tick %lld)", static_cast<unsigned long long>(jams),
                  static_cast<unsigned long long>(jam_ticks), static_cast<long long>(first_jam_tick));
    out += line;
  }
  if (drill) {
    std::snprintf(line, sizeof line, "; drilled %.2f mm^3", drill->removed_mm3);
    out += line;
    for (const auto& m : drill->materials) {
      if (m.voxels == 0) continue;
      std::snprintf(line, sizeof line, "%s %s %.2f mm^3%s", m.name == drill->materials.front().name ? " (" : ", ",
                    m.name.c_str(), m.removed_mm3, m.critical ? " CRITICAL" : "");
      out += line;
    }
    if (drill->removed_mm3 > 0.0) out += ")";
  }
  for (const SegmentContact& c : segment_contacts) {
    if (c.ticks == 0) continue;
    std::snprintf(line, sizeof line, "; touched %s%s: %.3f s, peak %.2f N, %llu touch%s", c.name.c_str(),
                  c.critical ? " (CRITICAL)" : "", c.time_in_contact_s, c.peak_force_N,
                  static_cast<unsigned long long>(c.touches), c.touches == 1 ? "" : "es");
    out += line;
  }
  return out;
}

void writeRunReport(const RunReport& report, const std::filesystem::path& path) {
  io::PrivateOutput file(path);  // 0600, renamed into place only when whole
  file.stream() << report.toJson();
  file.commit();
}

}  // namespace vh::runtime
