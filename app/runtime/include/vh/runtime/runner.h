#pragma once
/// @file
/// The headless runner (`volume-haptics run`): replays a device trajectory through the renderer
/// as fast as possible at simulated servo ticks and reports timing and correctness: tick i runs
/// at t = t_first + i / rate for t up to the trajectory's last time. After every tick, outside
/// the timed section, it measures how deep the proxy's point shell is inside the isosurface
/// (first order: (F(p) - s) / |grad F(p)| over the points with F(p) > s) and counts ticks with a
/// non-finite force, torque or proxy pose.

#include <array>
#include <cstdint>
#include <filesystem>
#include <span>
#include <string>

#include <Eigen/Core>

#include "vh/runtime/scene.h"
#include "vh/runtime/trajectory.h"

namespace vh::runtime {

struct RunOptions {
  double servo_rate_Hz = 1000.0;  ///< Simulated tick rate [Hz].
  bool check_penetration = true;  ///< Measure the penetration after every tick.
  /// Non-empty: also write one CSV row per tick here (t_s, device and proxy positions [m],
  /// force [N], torque [N*m], contacts, exec_us, penetration_m, proxy quaternion, time of
  /// contact) for inspecting a run.
  std::filesystem::path trace_csv;
  /// Non-empty: also write a session recording (recording.h) here: makeSessionMetadata() with
  /// the trajectory's first pose as the initial pose and device kind "scripted", one TickRecord
  /// per tick (tick i + 1, time_s = i / servo_rate_Hz, tick_time_s = the renderer's exec time;
  /// no safety layer, so forces are the renderer's), and the events the writer derives. Replays
  /// bit for bit with replayRecording() (default RendererOptions, as the runner uses).
  std::filesystem::path record;
  std::string record_note;  ///< SessionInfo::note of the recording.
};

/// What one headless run measured. Times are the renderer's TickStats::exec_time_us.
struct RunReport {
  // Inputs.
  std::string scene;                     ///< Scene file (or "builtin ...").
  std::string trajectory;                ///< Trajectory file (or "generated").
  std::string volume;                    ///< Volume path or built-in name.
  std::array<int, 3> volume_dims{0, 0, 0};
  Eigen::Vector3d volume_spacing_m = Eigen::Vector3d::Zero();
  double isovalue = 0.0;                 ///< Data units.
  std::string tool;                      ///< Tool mesh path or built-in name.
  std::size_t point_count = 0;           ///< Point shell size.
  double point_spacing_m = 0.0;          ///< Mean nearest-neighbour spacing of the shell [m].
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
  double mean_volume_samples = 0.0;      ///< Trilinear samples per tick.
  // Correctness.
  double max_penetration_m = 0.0;        ///< Largest first-order depth over all ticks [m].
  std::int64_t max_penetration_tick = -1;
  std::uint64_t ticks_penetrating = 0;   ///< Ticks with depth > epsilon.
  std::uint64_t nan_ticks = 0;           ///< Ticks with a non-finite force, torque or proxy pose.
  std::uint64_t bad_device_samples = 0;  ///< Samples the renderer rejected.
  int initial_points_inside = 0;         ///< Shell points inside at the first proxy pose.
  double final_force_N = 0.0;            ///< |force| on the last tick.
  double final_proxy_device_distance_m = 0.0;  ///< |p_P - p_D| (tool origins) on the last tick.
  /// Largest |p_P - p_D| over the run [m]: about the push depth when the proxy slides along the
  /// surface with the device; much more means the proxy lagged or stuck.
  double max_proxy_device_distance_m = 0.0;

  /// The report as a JSON document (keys as the field names; dims as "volume_dims").
  std::string toJson() const;
  /// One line: "ticks 4200, mean 120 us, p99 310 us, max 900 us, contacts <= 12, penetration
  /// 0.01 mm (epsilon 0.03 mm), nan 0".
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

/// Replays `trajectory` on an already loaded scene (the proxy starts at its first pose).
RunReport runHeadless(const LoadedScene& scene, const Trajectory& trajectory, const RunOptions& options = {});

/// Writes RunReport::toJson() to a file. @throws std::runtime_error naming the file.
void writeRunReport(const RunReport& report, const std::filesystem::path& path);

}  // namespace vh::runtime
