#pragma once
/// @file
/// The headless runner (`volume-haptics run`): replays a device trajectory through the renderer
/// as fast as possible at simulated servo ticks and reports timing and correctness: tick i runs
/// at t = t_first + i / rate for t up to the trajectory's last time. After every tick, outside
/// the timed section, it measures how deep the proxy's point shell is inside the isosurface
/// (first order: (F(p) - s) / |grad F(p)| over the points with F(p) > s), counts ticks with a
/// non-finite force, torque or proxy pose, and checks with haptics::CrossingVerifier that the
/// tick's proxy motion (HapticRenderer::lastMotion() over [0, lastTimeOfContact()]) carried no
/// shell point from outside the isosurface into it (a crossing: the proxy went into or through
/// the surface).

#include <algorithm>
#include <array>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <span>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "vh/haptics/pose.h"
#include "vh/runtime/burr_load.h"
#include "vh/runtime/device.h"
#include "vh/runtime/drill_report.h"
#include "vh/runtime/guidance.h"
#include "vh/runtime/scene.h"
#include "vh/runtime/tool_fit.h"
#include "vh/runtime/trajectory.h"

namespace vh::runtime {

class SnapshotChannel;  // snapshot_channel.h

/// The finest crossing-check step accepted [voxels] (RunOptions::verify_step_voxels): a
/// thousandth of a voxel, ten times finer than the default; finer steps only cost time.
inline constexpr double kMinVerifyStep_voxels = 1e-3;

struct RunOptions {
  double servo_rate_Hz = 1000.0;  ///< Simulated tick rate [Hz].
  bool check_penetration = true;  ///< Measure the penetration after every tick.
  /// Sampling step of the crossing check along each shell point's path, in voxels (the smallest
  /// voxel side; see haptics::CrossingVerifier); 0 turns the check off (the report's crossing
  /// fields are then -1, null in JSON: not checked). Outside the timed section. At least
  /// kMinVerifyStep_voxels when not 0, else runHeadless() throws std::invalid_argument.
  double verify_step_voxels = 0.01;
  /// Non-empty: also write one CSV row per tick here for inspecting a run: tick, t_s, the device
  /// position as read (rendered only when `sample` says good or reseeded) and the proxy's [m], the renderer's force fx_N.. [N]
  /// and torque tx_Nm.. [N*m], contacts, exec_us, penetration_m, proxy quaternion, time of
  /// contact, crossing_points (-1 when not checked or the sample was not rendered), the command
  /// the device got after the plausibility test and the safety layer cmd_fx_N.. [N] and
  /// cmd_tx_Nm.. [N*m], sample (good, missing, implausible, reseeded: SampleFilter), isovalue
  /// (requested that tick) and felt_isovalue (rendered; the requested one until the renderer
  /// reports it).
  std::filesystem::path trace_csv;
  /// Non-empty: also write a session recording (recording.h) here: makeSessionMetadata() with
  /// the trajectory's first pose as the initial pose and device kind "scripted", one TickRecord
  /// per tick (tick i + 1, time_s = i / servo_rate_Hz, tick_time_s = the renderer's exec time;
  /// forces are the renderer's, before the safety layer; a sample SampleFilter rejected is
  /// recorded as a bad sample at the last good pose), and the events the writer derives. Replays
  /// bit for bit with replayRecording() (default RendererOptions, as the runner uses).
  std::filesystem::path record;
  /// The scripted device's limits and safety policy, e.g. to stand in for a hardware device
  /// (defaults: a device without hardware; DeviceLimits' default speed limits apply). The
  /// samples pass the same plausibility test (SampleFilter) and the commands the same safety
  /// layer (ForceSafety) as on the coupling thread.
  DeviceLimits device_limits;
  SafetyPolicy safety_policy;
  DofMask actuated_dof = kDofAll;
  std::string record_note;  ///< SessionInfo::note of the recording.
  /// The price of the work budget: also run the same samples through a renderer
  /// without it (outside the timed section) and report how far and how long the budgeted proxy
  /// was from it. Off: the lag fields are -1.
  bool lag_reference = true;
  /// When set, called once per loader notice as soon as the scene is loaded (the headless
  /// command prints them as warnings and goes on).
  std::function<void(const std::string&)> on_notice;
  /// When set, every tick is also published into this channel (tick i + 1, the device pose
  /// used, the proxy pose and force produced, the contact count; steady-clock time), for a
  /// consumer such as the OpenIGTLink link (`run --igtl-port`). Outside the timed section.
  std::shared_ptr<SnapshotChannel> monitor;
  /// When set, called after every tick of a scene with a "drill" section (never without one)
  /// with the burr's state (burr_load.h; tick i + 1, time i / servo rate), e.g. to render its
  /// sound (`run --audio`). Outside the timed section.
  std::function<void(const DrillTick&)> on_drill_tick;
  /// Pace the ticks at servo_rate_Hz in wall-clock time instead of as fast as possible (tick
  /// i + 1 ends no earlier than (i + 1) / rate after the start), so a streamed run plays at the
  /// trajectory's speed. The exec times are unaffected.
  bool realtime = false;
  /// Haptic guidance toward an expert's path (guidance.h; loadExpertPath() checks its scene):
  /// each tick's guidance force (guide_gains, clamped to the device's limits: clampGuidance())
  /// is added to the renderer's before the safety layer, and the recording gets the "guidance"
  /// and "guidance_force" events. Null: no guidance.
  std::shared_ptr<const ExpertPath> guide;
  haptics::GuidanceGains guide_gains;
  /// The simulated trainee's hand (CompliantHand): the trajectory is the hand's intended motion
  /// and the device yields to the commanded force. Unset: the device is a position source.
  std::optional<HandImpedance> hand;
};

/// The work budget's price: how far a budgeted proxy is from an unbudgeted one driven
/// by the same device samples. Used by the run report and `bench table1`.
/// Two figures, because a quasi-static proxy's path depends on its history: once a cut tick
/// has put the two proxies on different sides of a choice (which contact holds, which way a
/// wedged tool slides), they stay apart although neither is late.
/// - max_m / max_rad: how far apart the two proxies are (the force differs by the coupling's
///   stiffness times this);
/// - max_behind_m / max_behind_rad: how much farther from the device the budgeted proxy is
///   than the reference (the extra stretch of the coupling spring: the proxy behind).
struct ProxyLag {
  std::int64_t ticks = 0;   ///< Ticks whose poses differed (by more than 1e-9 m or rad).
  double max_m = 0.0;       ///< Largest distance of the tool origins [m].
  double max_rad = 0.0;     ///< Largest angle between the orientations [rad].
  double max_behind_m = 0.0;    ///< Largest excess of the budgeted proxy's distance to the device [m].
  double max_behind_rad = 0.0;  ///< Largest excess of its angle to the device [rad].
  /// A distance in translation [m] and rotation [rad].
  struct Gap {
    double m = 0.0;
    double rad = 0.0;
  };
  /// How far apart two poses are (W).
  static Gap apart(const haptics::Pose& X_WA, const haptics::Pose& X_WB) noexcept {
    return {(X_WA.p_AB_m - X_WB.p_AB_m).norm(), X_WA.R_AB.angularDistance(X_WB.R_AB)};
  }
  /// How much farther from the device pose X_WD the budgeted proxy is than the reference (W);
  /// negative when it is the closer.
  static Gap behind(const haptics::Pose& X_WP_budgeted, const haptics::Pose& X_WP_reference,
                    const haptics::Pose& X_WD) noexcept {
    const Gap b = apart(X_WD, X_WP_budgeted), r = apart(X_WD, X_WP_reference);
    return {b.m - r.m, b.rad - r.rad};
  }
  /// One tick: the budgeted proxy's pose and the unbudgeted one's (both in W).
  void add(const haptics::Pose& X_WP_budgeted, const haptics::Pose& X_WP_reference) noexcept {
    const Gap g = apart(X_WP_budgeted, X_WP_reference);
    max_m = std::max(max_m, g.m);
    max_rad = std::max(max_rad, g.rad);
    if (g.m > 1e-9 || g.rad > 1e-9) ++ticks;
  }
  /// The same, and the behind figures against the device pose X_WD of the tick (W).
  void add(const haptics::Pose& X_WP_budgeted, const haptics::Pose& X_WP_reference,
           const haptics::Pose& X_WD) noexcept {
    add(X_WP_budgeted, X_WP_reference);
    const Gap b = behind(X_WP_budgeted, X_WP_reference, X_WD);
    max_behind_m = std::max(max_behind_m, b.m);
    max_behind_rad = std::max(max_behind_rad, b.rad);
  }
};

/// Soft tissue in a run (scenes with a "tissue" section): force against indentation.
struct TissueReport {
  double max_indentation_m = 0.0;  ///< Deepest the tissue's surface gave under the tool [m].
  double max_push_N = 0.0;         ///< Largest total push on the tissue [N].
  /// Force against indentation: for each tenth of max_indentation_m (the bins' upper ends, m),
  /// the largest |force| felt on the ticks whose indentation fell in it [N] (0: no tick there).
  std::vector<std::pair<double, double>> force_by_indentation;
  double mean_step_us = 0.0, max_step_us = 0.0;  ///< The tissue's step per tick [us] (wall).
};

/// What one headless run measured. Times are the renderer's TickStats::exec_time_us.
struct RunReport {
  // Inputs.
  std::string scene;                     ///< Scene file (or "builtin ...").
  std::string trajectory;                ///< Trajectory file (or "generated").
  std::string volume;                    ///< Volume path or built-in name.
  /// What the loader corrected or chose (io::VolumeInfo::notices): a gantry tilt resampled,
  /// missing slices filled, which series of a folder was taken.
  std::vector<std::string> volume_notices;
  std::array<int, 3> volume_dims{0, 0, 0};
  Eigen::Vector3d volume_spacing_m = Eigen::Vector3d::Zero();
  double isovalue = 0.0;                 ///< Data units.
  std::string tool;                      ///< Tool mesh path or built-in name.
  std::size_t point_count = 0;           ///< Point shell size.
  double point_spacing_m = 0.0;          ///< Mean nearest-neighbour spacing of the shell [m].
  /// The fit check of the tool on this computer (tool_fit.h), when the command ran it; the run
  /// keeps the tool it was given either way.
  std::optional<ToolFit> tool_fit;
  double epsilon_m = 0.0;                ///< Collision tolerance [m].
  double feature_size_m = 0.0;           ///< f [m].
  double servo_rate_Hz = 1000.0;
  double trajectory_duration_s = 0.0;
  // Timing [us] per tick.
  std::uint64_t ticks = 0;
  double mean_us = 0.0, p50_us = 0.0, p99_us = 0.0, max_us = 0.0;
  std::uint64_t ticks_over_1ms = 0;      ///< Ticks longer than the 1 kHz budget.
  double total_s = 0.0;                  ///< Wall time of the whole replay incl. checks [s].
  // Contacts and forces.
  int max_contacts = 0;
  double mean_contacts = 0.0;
  std::uint64_t ticks_in_contact = 0;
  std::int64_t first_contact_tick = -1;  ///< -1: never.
  double max_force_N = 0.0;              ///< Largest |force|.
  double max_torque_Nm = 0.0;            ///< Largest |torque|.
  /// Felt segments: time in contact, peak force and touches per segment of the
  /// scene's segmentation (empty without one).
  std::vector<SegmentContact> segment_contacts;
  /// Critical segments (critical_proximity.h): per segment the time within its warning and
  /// alarm distances, the entries and the closest approach ("proximity"; empty without any).
  std::vector<SegmentProximityStats> proximity;
  /// Drilling: removed volume in all and per material / segment ("removed_mm3", "removed").
  std::optional<DrillReport> drill;
  std::optional<TissueReport> tissue;    ///< Scenes with a "tissue" section.
  double mean_volume_samples = 0.0;      ///< Trilinear samples per tick.
  // Correctness.
  double max_penetration_m = 0.0;        ///< Largest first-order depth over all ticks [m].
  std::int64_t max_penetration_tick = -1;
  std::uint64_t ticks_penetrating = 0;   ///< Ticks with depth > epsilon.
  std::uint64_t nan_ticks = 0;           ///< Ticks with a non-finite force, torque or proxy pose.
  /// Crossing check (CrossingVerifier after every tick, outside the timed section). The step it
  /// sampled paths with [voxels]; 0: not checked, and the three counts below are -1.
  double verify_step_voxels = 0.0;
  std::int64_t crossings = -1;           ///< Ticks in which some shell point crossed into the isosurface.
  std::int64_t crossing_points = -1;     ///< Sum over ticks of the points that crossed.
  std::int64_t first_crossing_tick = -1; ///< First tick with a crossing; -1: none (or not checked).
  /// Ticks in which the tool's surface between its points crossed: an edge of the point shell's
  /// neighbour graph (haptics::makeShellEdges(), ends inset by epsilon) free where the move
  /// started and inside the isosurface where it ended (CrossingVerifier::checkEdges(), sampled
  /// along each edge at the same step). The renderer guarantees 0 only with
  /// RendererOptions::edge_test on; -1: not checked.
  std::int64_t edge_crossings = -1;
  std::int64_t first_edge_crossing_tick = -1; ///< First tick with an edge crossing; -1: none.
  double verify_s = 0.0;                 ///< Time spent in the crossing check [s] (in total_s).
  std::uint64_t bad_device_samples = 0;  ///< Samples not rendered (implausible) or the renderer rejected.
  /// Of those, samples SampleFilter rejected: faster than the device moves, outside its
  /// workspace, not finite.
  std::uint64_t implausible_samples = 0;
  std::uint64_t held_ticks = 0;          ///< Ticks the safety layer held the last good command.
  double max_command_force_N = 0.0;      ///< Largest |force| commanded (after the safety layer) [N].
  int initial_points_inside = 0;         ///< Shell points inside at the first proxy pose.
  double final_force_N = 0.0;            ///< |force| on the last tick.
  double final_proxy_device_distance_m = 0.0;  ///< |p_P - p_D| (tool origins) on the last tick.
  /// Largest |p_P - p_D| over the run [m]: about the push depth when the proxy slides along the
  /// surface with the device; much more means the proxy lagged or stuck.
  double max_proxy_device_distance_m = 0.0;
  /// Jams (jam_detector.h): runs of more than kJamTicks ticks in which the proxy, in contact and
  /// more than kJamDistance_m from a device pose that is itself free, came no closer to it; the
  /// ticks of those runs past the first kJamTicks, and the first such tick (-1: none). The
  /// recording flags the same ticks (kRecordFlagJam).
  std::uint64_t jams = 0;
  std::uint64_t jam_ticks = 0;
  std::int64_t first_jam_tick = -1;
  /// Technique feedback (technique.h, the scene's "technique" rules): episodes of each rule in
  /// TechniqueRule order (force, speed, shaft), as the recording's "technique" events count them.
  std::array<std::uint64_t, kTechniqueRuleCount> technique_episodes{};
  // The work budget (haptics::RendererOptions::work_budget) and its price.
  std::int64_t work_budget = 0;          ///< Work units per tick; 0: unbounded.
  std::uint64_t budget_cuts = 0;         ///< Ticks the budget cut (the sweep went on next tick).
  std::int64_t max_work = 0;             ///< Largest work of a tick [units].
  /// Against the same run without a budget (RunOptions::lag_reference; else -1): ticks whose
  /// proxy pose differed, and the largest distance of the tool origins [m] and angle [rad].
  std::int64_t lag_ticks = -1;
  double max_lag_m = -1.0, max_lag_rad = -1.0;
  /// Against the same run (else -1): how much farther from the device the budgeted proxy was
  /// than the unbudgeted one at most [m], [rad] (ProxyLag::behind(): the coupling spring's extra
  /// stretch; at most the lag).
  double max_behind_m = -1.0, max_behind_rad = -1.0;

  /// With RunOptions::guide: the guidance's force and how near the device kept to the expert.
  std::optional<GuidanceReport> guidance;

  /// True when the crossing check ran (verify_step_voxels > 0).
  bool crossingsChecked() const noexcept { return verify_step_voxels > 0.0; }

  /// The report as a JSON document (keys as the field names; dims as "volume_dims"; the crossing
  /// counts are null when the check was off).
  std::string toJson() const;
  /// One line: "ticks 4200, exec mean 120 us, ..., penetration 0.01 mm (epsilon 0.03 mm); nan ticks
  /// 0; bad samples 0; crossings 0 (checked at 0.01 voxel), edges 0" ("crossings 3 (5 points, first
  /// at tick 812; ...)" when some crossed, "edges 2 (first at tick 40)" when the tool's surface
  /// between its points did, "crossings not checked" when the check was off).
  std::string summary() const;
};

/// Nearest-rank q-quantile of `sorted` (ascending), q in [0, 1]: the value at rank ceil(q n)
/// (rank 1 for q = 0); 0 for an empty span. Used for the run report's and the benchmarks' tick-time
/// percentiles.
double nearestRankPercentile(std::span<const double> sorted, double q) noexcept;

/// Loads the scene and the trajectory and replays it (the scene's device section is ignored).
/// The proxy starts at the trajectory's first pose.
/// @throws std::runtime_error / io::LoadError naming the file for bad scenes, data or CSV.
RunReport runHeadless(const SceneSpec& scene, const std::filesystem::path& trajectory_csv,
                      const RunOptions& options = {});

/// Longest run replayed [s]: a day. A run keeps one time per tick (8 bytes at the servo rate:
/// 0.7 GB for a day at 1 kHz) and, with --igtl-port, plays in real time.
inline constexpr double kMaxRunDuration_s = 24.0 * 3600.0;

/// Replays `trajectory` on an already loaded scene (the proxy starts at its first pose).
/// A tick whose force, torque or proxy pose is not finite (|F| overflowing to inf included) is
/// counted in RunReport::nan_ticks, not rendered into the maxima.
/// @throws std::invalid_argument when the trajectory lasts longer than kMaxRunDuration_s (or
///         its tick count would not fit memory), naming its duration and the limit.
RunReport runHeadless(const LoadedScene& scene, const Trajectory& trajectory, const RunOptions& options = {});

/// Writes RunReport::toJson() to a file. @throws std::runtime_error naming the file.
void writeRunReport(const RunReport& report, const std::filesystem::path& path);

}  // namespace vh::runtime
