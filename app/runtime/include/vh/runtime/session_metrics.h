#pragma once
/// @file
/// What a teacher reads about a recorded session (recording.h): how the hand moved, how hard it
/// pressed, what it touched, what it drilled and how well the servo loop kept time; and how a
/// session compares with a reference (an expert's) recording of the same scene. No Qt and no
/// VTK: the plots and the HTML page are ui/export/session_report.h's.
///
/// Frames and units: every position is in the scene frame W [m], forces [N], torques [N*m],
/// times [s]. The motion metrics are of the device (the hand: TickRecord::p_WD_m), not of the
/// proxy, which stays on the surface; the proxy's path length is given beside them.
///
/// Placements (kRecordFlagPlacement: Touch the Surface, Home, Reset Device moved the tools
/// together) are not the hand's motion: no position difference across one enters the path
/// lengths, the speeds or the jerk, and the placement's own tick enters no force or torque
/// figure.
///
/// Time base: each record stands for one servo period dt = 1 / servo_rate_Hz (the metadata's
/// "servo_rate_Hz"; without it the median spacing of the records' time_s, else 1 kHz). Times
/// "in contact" or "above the threshold" are tick counts times dt, so they are exact for a
/// recording without dropped records.
///
/// Smoothness: the jerk measures of Hogan and Sternad, "Sensitivity of smoothness measures to
/// movement duration, amplitude, and arrests", J. Motor Behavior 41(6), 2009:
///   integrated squared jerk  ISJ = integral over [0, D] of |d^3 p_WD / dt^3|^2 dt   [m^2/s^5]
///   dimensionless jerk       DJ  = ISJ * D^3 / v_peak^2                              [-]
///   log dimensionless jerk   LDLJ = -ln(DJ)                                          [-]
/// with D the session's duration and v_peak its peak speed (the peak-speed form of their
/// dimensionless jerk, as Balasubramanian et al., IEEE TBME 59(8), 2012 use it). Larger DJ
/// (smaller LDLJ) is a jerkier movement. The derivatives are central differences of step h =
/// MetricsOptions::derivative_step_s (a 10 ms step keeps a device's sub-micrometre position
/// noise from dominating the third derivative; for a circle of angular speed w the step's
/// relative error is about (w h)^2 / 6, 1.6e-4 at 0.5 Hz); the integral is the mean of |jerk|^2
/// over the samples where the differences fit, times D.
///
/// Path alignment: dynamic time warping, Sakoe and Chiba, "Dynamic programming algorithm
/// optimization for spoken word recognition", IEEE Trans. ASSP 26(1), 1978 (the symmetric
/// recurrence without slope constraint, Euclidean local distance in W): both recordings are in
/// the scene frame W of the same scene, so the paths need no spatial registration, only the
/// time alignment.

#include <array>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "vh/runtime/recording.h"
#include "vh/runtime/technique.h"

namespace vh::runtime {

/// How computeSessionMetrics() measures.
struct MetricsOptions {
  /// |F| above which time is counted as "above the threshold" [N] (strictly greater).
  double force_threshold_N = 2.0;
  /// Step of the central differences for speed and jerk [s] (rounded to whole ticks, >= 1).
  double derivative_step_s = 0.01;
};

/// Contact with one segment of the recording's segmentation, and what the drill removed of it.
struct SegmentMetrics {
  std::string name;
  bool critical = false;
  double time_in_contact_s = 0.0;      ///< Ticks touching it times dt [s].
  double peak_force_N = 0.0;           ///< Largest |F| while touching it [N].
  std::uint64_t touches = 0;           ///< Separate entries into contact.
  /// Voxels of it the drill removed, from the recording's "critical_removed" events (so only
  /// for critical segments), and their volume [mm^3].
  std::uint64_t removed_voxels = 0;
  double removed_mm3 = 0.0;
};

/// The metrics of one recording (computeSessionMetrics()). A recording without records gives
/// zeros and a notice.
struct SessionMetrics {
  // Identity, from the metadata ("" when absent).
  std::string scene;           ///< The scene file, else the volume's path or built-in name.
  std::string dataset_sha256;  ///< The dataset's checksum (session_metadata.h).
  std::string label;           ///< The metadata's "user", else its "note" (writeCohortTable(): else the file name).
  std::string start_time_utc;  ///< When the recording started (ISO-8601).
  double servo_rate_Hz = 0.0;  ///< The rate dt comes from [Hz].
  std::size_t records = 0;

  double duration_s = 0.0;     ///< Last record's time_s minus the first's [s].

  // Motion of the device (the hand), p_WD.
  double path_length_m = 0.0;          ///< Sum of |p_WD(i+1) - p_WD(i)| [m].
  double proxy_path_length_m = 0.0;    ///< The same of the proxy, p_WP [m].
  double mean_speed_m_per_s = 0.0;     ///< path_length_m / duration_s [m/s].
  double peak_speed_m_per_s = 0.0;     ///< Largest central-difference speed [m/s].
  double integrated_squared_jerk = 0.0;  ///< ISJ [m^2/s^5] (see the file comment).
  double dimensionless_jerk = 0.0;       ///< DJ [-]; 0 when the device did not move.
  double log_dimensionless_jerk = 0.0;   ///< LDLJ = -ln(DJ) [-]; 0 when DJ is 0.

  // Force on the hand, |F| of every record.
  double force_threshold_N = 0.0;        ///< MetricsOptions::force_threshold_N [N].
  double mean_force_N = 0.0;
  double mean_contact_force_N = 0.0;     ///< Mean |F| over the ticks with contacts [N].
  double p95_force_N = 0.0;              ///< Nearest-rank 95th percentile [N].
  double max_force_N = 0.0;
  double time_above_threshold_s = 0.0;   ///< Ticks with |F| > threshold, times dt [s].
  double mean_torque_Nm = 0.0;
  double max_torque_Nm = 0.0;
  double time_in_contact_s = 0.0;        ///< Ticks with contacts > 0, times dt [s].
  double critical_contact_s = 0.0;       ///< Time touching any critical segment [s].
  std::uint64_t critical_touches = 0;    ///< Touches of critical segments.

  // Drilling.
  double drill_on_s = 0.0;               ///< Ticks with the burr spinning, times dt [s].
  /// Drilling, by one rule for every recording whoever wrote it (the window or `run`): the cavity
  /// the scene held when the recording began (the metadata's scene.drill.cavity, which a replay
  /// starts from), what the burr removed during it, and the two together: the cavity at its end.
  /// Volumes are voxels times the felt field's voxel volume (the metadata's
  /// drilling.felt_voxel_volume_mm3; for older recordings the cavity's own grid).
  std::uint64_t cavity_at_start_voxels = 0;
  double cavity_at_start_mm3 = 0.0;
  /// Removed during the recording: the sum of the records' TickRecord::removed_voxels (format
  /// version 5 on; records the writer dropped are not counted, and a notice says so); in older
  /// recordings the last "drilled" event {"voxels": N, "mm3": V}, which only `run` wrote; 0
  /// without either.
  std::uint64_t removed_voxels = 0;
  double removed_mm3 = 0.0;
  std::uint64_t cavity_voxels = 0;  ///< cavity_at_start_voxels + removed_voxels.
  double cavity_mm3 = 0.0;          ///< cavity_at_start_mm3 + removed_mm3.
  std::uint64_t critical_removed_voxels = 0;  ///< Sum of the "critical_removed" events.
  double critical_removed_mm3 = 0.0;

  // The run's own quality.
  std::uint64_t deadline_misses = 0;     ///< Ticks flagged kRecordFlagDeadlineMiss.
  /// Ticks flagged kRecordFlagDeadlineCut: the solver's deadline stopped their work, so the proxy
  /// moved less far than the full solve would have (the force on time, the proxy behind).
  std::uint64_t deadline_cuts = 0;
  std::uint64_t bad_samples = 0;         ///< Ticks without a usable device sample.
  std::uint64_t force_limited_ticks = 0; ///< Ticks where the safety layer changed the force.
  std::uint64_t non_finite_ticks = 0;    ///< Ticks where the renderer computed a NaN / inf.
  std::uint64_t dropped_records = 0;     ///< Records the writer dropped (ring overflow).
  double mean_tick_s = 0.0;              ///< Mean solver compute time per tick [s].
  double max_tick_s = 0.0;               ///< Longest solver compute time [s].

  std::size_t markers = 0;               ///< "marker" events.
  /// "technique" events per rule (technique.h: force, speed, shaft): the feedback the trainee got.
  std::array<std::uint64_t, kTechniqueRuleCount> technique_events{};
  std::vector<SegmentMetrics> segments;  ///< Per segment of the metadata's segmentation.
  /// Per critical segment: time within its warning and alarm distances, entries, closest
  /// approach (segmentProximity(); closest_m NaN for a recording that did not measure it).
  std::vector<SegmentProximityStats> proximity;
  /// What the reader and the metrics could not do: the recording's warnings (a truncated or
  /// damaged tail), no records, no servo rate.
  std::vector<std::string> notices;
};

/// The metrics of `recording` (see the file comment for the definitions and sources).
/// @throws std::invalid_argument when options are out of range (threshold negative or not
///         finite, derivative step not positive).
SessionMetrics computeSessionMetrics(const Recording& recording, const MetricsOptions& options = {});

/// The label a cohort table gives the recording `file` with metrics `m`: its user, else its
/// note (SessionMetrics::label), else the file's name without its extension.
std::string cohortLabel(const SessionMetrics& m, const std::filesystem::path& file);

/// One scalar metric, for tables: a stable column key, its unit and a label for people.
struct MetricValue {
  std::string key;    ///< Column name, unit suffixed ("path_length_m").
  std::string label;  ///< "Path length of the device".
  std::string unit;   ///< "m", "N", "s", "" (dimensionless or a count).
  double value = 0.0;
};

/// Every scalar metric of `m`, always the same keys in the same order (the cohort table's
/// columns, the report's tables).
std::vector<MetricValue> metricValues(const SessionMetrics& m);

/// The device's speed over a recording, as the report draws it: central differences over
/// `derivative_step_s` (whole ticks, >= 1) at every `stride`-th record, in pieces: no difference
/// across a placement (kRecordFlagPlacement: Touch the Surface, Home, Reset Device moved the
/// tools, not the hand) is taken, so a piece ends before one and the next starts after it, as
/// the metrics leave the jump out (peak_speed_m_per_s).
struct DeviceSpeedSeries {
  /// (time [s], speed [m/s]) pairs, each piece without a placement inside.
  std::vector<std::vector<std::pair<double, double>>> pieces;
  std::vector<double> placements_s;  ///< Times of the records flagged as placements [s].
  double max_m_per_s = 0.0;          ///< The largest speed in the pieces [m/s].
};
/// @param servo_rate_Hz the recording's servo rate (SessionMetrics::servo_rate_Hz), > 0.
DeviceSpeedSeries deviceSpeedSeries(const Recording& recording, double servo_rate_Hz, double derivative_step_s,
                                    std::size_t stride);

/// `count` device positions p_WD [m] (count x 3) taken evenly over the records (index
/// round(j (n - 1) / (count - 1))), every record when there are fewer. Empty for no records.
std::vector<Eigen::Vector3d> devicePathSamples(const Recording& recording, std::size_t count);

/// What dynamicTimeWarping() found.
struct DtwAlignment {
  double total_distance_m = 0.0;  ///< Sum of |a_i - b_j| along the warping path [m].
  double mean_distance_m = 0.0;   ///< total / number of pairs on the path [m].
  /// The warping path: pairs (i, j) from (0, 0) to (n - 1, m - 1), each step +1 in i, j or both.
  std::vector<std::pair<std::size_t, std::size_t>> path;
};

/// Dynamic time warping (Sakoe and Chiba 1978) of two paths in W [m] with the Euclidean
/// distance: D(i, j) = |a_i - b_j| + min(D(i-1, j), D(i, j-1), D(i-1, j-1)). O(n m) time and
/// memory (keep n m to a few million: devicePathSamples() thins long recordings first).
/// @throws std::invalid_argument when either path is empty.
DtwAlignment dynamicTimeWarping(const std::vector<Eigen::Vector3d>& a, const std::vector<Eigen::Vector3d>& b);

/// A session against a reference recording of the same scene.
struct ReferenceComparison {
  std::vector<MetricValue> session;     ///< metricValues() of the session.
  std::vector<MetricValue> reference;   ///< metricValues() of the reference, same keys.
  DtwAlignment alignment;               ///< DTW of the two thinned device paths.
  std::size_t path_samples = 0;         ///< Points per thinned path (at most).
  std::vector<Eigen::Vector3d> session_path, reference_path;  ///< The thinned paths [m].
};

/// What identifies the scene a recording was made on (from its metadata, session_metadata.h):
/// the dataset's SHA-256, else the scene file or the volume's path ("" when absent).
struct SceneIdentity {
  std::string scene;
  std::string dataset_sha256;
};

/// The SceneIdentity in a metadata JSON text (empty fields when it is not JSON).
SceneIdentity sceneIdentity(const std::string& metadata_json);

/// Checks that `other` (a reference, an expert's recording to guide with) was recorded on the
/// scene of `session`: the same dataset SHA-256 when either has one, else the same scene path.
/// `role` names the other recording in the message ("the reference"), `purpose` what needs the
/// same dataset ("paths can only be compared on the same dataset").
/// @throws std::invalid_argument naming both datasets when they differ.
void requireSameScene(const SceneIdentity& session, const SceneIdentity& other,
                      const std::string& role = "the reference",
                      const std::string& purpose = "paths can only be compared on the same dataset");

/// Checks that both recordings are of the same scene (requireSameScene()) (the dataset's SHA-256 in their metadata,
/// else the volume's path) and compares them: metrics side by side and the DTW of their device
/// paths, each thinned to `path_samples` points.
/// @throws std::invalid_argument naming both datasets when the scenes differ, or when either
///         recording has no records.
ReferenceComparison compareWithReference(const Recording& session, const SessionMetrics& session_metrics,
                                         const Recording& reference, const SessionMetrics& reference_metrics,
                                         std::size_t path_samples = 1000);

/// The recordings (`*.vhrec`) under `dir`, recursively, sorted by path.
/// @throws std::runtime_error when `dir` is not a readable folder.
std::vector<std::filesystem::path> findRecordings(const std::filesystem::path& dir);

}  // namespace vh::runtime
