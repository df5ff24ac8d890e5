// `volume-haptics bench table1`: the paper's Table 1 (Chan et al. 2011, section 3.2) on this
// machine, the paper-faithful and the accelerated detection path side by side in one run.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <functional>
#include <iostream>
#include <numeric>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <atomic>
#include <thread>
#include <unistd.h>

#include <Eigen/Geometry>

#include "vh/bench/report.h"
#include "vh/haptics/crossing_verifier.h"
#include "vh/haptics/haptic_renderer.h"
#include "vh/haptics/penetration.h"
#include "vh/haptics/worker_pool.h"
#include "vh/runtime/placement.h"
#include "vh/runtime/runner.h"
#include "vh/runtime/scene.h"
#include "vh/runtime/servo_factory.h"
#include "vh/runtime/tool_fit.h"
#include "vh/runtime/trajectory.h"
#include "vh/runtime/realtime.h"

namespace vh::bench {

namespace fs = std::filesystem;

namespace {

/// One row of the paper's Table 1 and how this project stands in for it.
struct SceneDef {
  std::string name;
  std::string volume;      ///< "builtin:NAME" or a path relative to the shared datasets folder.
  bool from_archive = false;  ///< Unpacked from classic/ct-bunny.tar.zst into the generated data.
  std::optional<double> isovalue;
  std::string tool_label;  ///< The paper's tool and ours.
  std::string tool_mesh;   ///< "builtin:NAME" or relative to the shared datasets folder.
  double tool_scale_to_m = 1.0;
  Eigen::Quaterniond R_WT = Eigen::Quaterniond::Identity();
  std::size_t paper_points = 0;
  double paper_mean_us = 0.0, paper_max_us = 0.0;
  std::string paper_resolution;
};

std::vector<SceneDef> table1Scenes() {
  std::vector<SceneDef> s;
  // Stanford CT bunny (stored HU + 1024: air ~0-100, ceramic ~2200-2400): isosurface midway.
  // The dental probe mesh (7.1 units long along z, hooked tip) scaled to 100 mm: the paper's cane.
  s.push_back({"Bunny", "classic/ct-bunny/bunny.nhdr", true, 1200.0, "cane (dental probe, 100 mm)",
               "meshes/dental-probe/dental_instrument.obj", 0.1 / 7.13, Eigen::Quaterniond::Identity(), 403, 209.0,
               900.0, "512 x 512 x 361"});
  // GE engine block (uchar, 1 mm voxels); the paper used a 110-slice crop; isovalue midway.
  s.push_back({"Engine", "classic/engine/engine.nhdr", false, std::nullopt, "wrench (150 mm, flat)",
               "meshes/wrench/adjustable-wrench-body.stl", 0.001, Eigen::Quaterniond::Identity(), 2126, 776.0,
               4380.0, "256 x 256 x 110"});
  // The project's 256^3 block with a round hole and the peg that fits it (0.5 mm clearance).
  s.push_back({"Hole", "builtin:block-with-hole", false, 128.0, "peg (snug, 7.5 mm radius)", "builtin:peg", 1.0,
               Eigen::Quaterniond::Identity(), 1307, 414.0, 2135.0, "256 x 256 x 256"});
  // CT head phantom, bone kernel, 400 HU; the CHAI3D drill scaled to 100 mm, burr down.
  s.push_back({"Bone", "ct/philips-head-phantom-bone", false, 400.0, "drill with ball burr (100 mm)",
               "meshes/drill/drill.stl", 0.00044,
               Eigen::Quaterniond(0.7071067811865476, 0.0, -0.7071067811865476, 0.0), 518, 255.0, 1181.0,
               "768 x 768 x 70 (temporal bone)"});
  return s;
}

std::string lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

/// Finds the unpacked CT bunny, unpacking the shipped archive into the generated data folder
/// when needed (tar --zstd). @return the .nhdr path, or nullopt with `why` set.
std::optional<fs::path> findOrUnpackBunny(std::string& why) {
  const fs::path rel = "classic/ct-bunny/bunny.nhdr";
  for (const fs::path& base : {runtime::generatedDataDir(), runtime::sharedDatasetsDir()}) {
    if (fs::exists(base / rel)) {
      std::cout << "bench table1: CT bunny found at " << (base / rel).string() << "\n";
      return base / rel;
    }
  }
  const fs::path archive = runtime::sharedDatasetsDir() / "classic/ct-bunny.tar.zst";
  if (!fs::exists(archive)) {
    why = archive.string() + " is absent";
    return std::nullopt;
  }
  const fs::path dest = runtime::generatedDataDir() / "classic";
  const fs::path tmp = dest / (".unpack-bench-" + std::to_string(::getpid()));
  std::error_code ec;
  fs::create_directories(tmp, ec);
  if (ec) {
    why = "cannot create " + tmp.string() + ": " + ec.message();
    return std::nullopt;
  }
  std::cout << "bench table1: unpacking " << archive.string() << " into " << dest.string() << " (tar --zstd) ..."
            << std::endl;
  const auto t0 = std::chrono::steady_clock::now();
  const std::string cmd = "tar --zstd -xf '" + archive.string() + "' -C '" + tmp.string() + "'";
  const int rc = std::system(cmd.c_str());
  if (rc != 0 || !fs::exists(tmp / rel.lexically_relative("classic"))) {
    fs::remove_all(tmp, ec);
    why = "unpacking " + archive.string() + " failed (" + cmd + " exited with " + std::to_string(rc) + ")";
    return std::nullopt;
  }
  if (!fs::exists(dest / "ct-bunny")) fs::rename(tmp / "ct-bunny", dest / "ct-bunny", ec);
  fs::remove_all(tmp, ec);
  if (!fs::exists(runtime::generatedDataDir() / rel)) {
    why = "unpacked, but " + (runtime::generatedDataDir() / rel).string() + " is missing";
    return std::nullopt;
  }
  std::cout << "bench table1: unpacked in "
            << std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() << " s\n";
  return runtime::generatedDataDir() / rel;
}

Eigen::Vector3d volumeCentre(const haptics::ScalarVolume& v) {
  const haptics::VolumeGeometry& g = v.geometry();
  const Eigen::Vector3d half((g.dims[0] - 1) * 0.5, (g.dims[1] - 1) * 0.5, (g.dims[2] - 1) * 0.5);
  return g.pointOf_W(half);
}

Eigen::Vector3d volumeExtent(const haptics::ScalarVolume& v) {
  const haptics::VolumeGeometry& g = v.geometry();
  Eigen::Vector3d e;
  for (int a = 0; a < 3; ++a) e[a] = g.spacing_m[a] * (g.dims[a] - 1);
  return (g.direction_W * e).cwiseAbs();
}

Eigen::Quaterniond aa(double angle_rad, const Eigen::Vector3d& axis) {
  return Eigen::Quaterniond(Eigen::AngleAxisd(angle_rad, axis.normalized()));
}

}  // namespace

/// The scripted interaction of one Table 1 scene (see the README's Benchmarks section):
/// at each of `locations` spots over the volume (cast straight down onto the surface; a spot
/// whose ray meets nothing, e.g. over a through hole, uses the volume's mid height), the device
///   hovers 10 mm above the contact and circles (free motion, 8 mm radius, tilting 0.2 rad),
///   descends 1 mm past the first contact (contact), pushes to 3 mm (pressing),
///   slides 10 mm in x and 8 mm in y (sliding), turns +-0.3 rad about y (prying),
///   pushes to 6 mm while twisting 0.4 rad about z (wedging),
///   drags 15 mm back in -x at that depth and pulls 15 mm up (hooking), and retracts.
/// Times are scaled so that the whole trajectory lasts ticks / 1 kHz.
runtime::Trajectory table1Trajectory(const haptics::ScalarVolume& volume, const haptics::PointShell& shell,
                                     double isovalue, const Eigen::Quaterniond& R0, int ticks, int locations,
                                     std::vector<std::string>* notes) {
  const Eigen::Vector3d ext = volumeExtent(volume);
  const Eigen::Vector3d centre = volumeCentre(volume);
  const std::vector<Eigen::Vector2d> spots{{0.0, 0.0}, {0.15, 0.0}, {0.0, 0.15}, {-0.12, -0.12}};
  const Eigen::Vector3d ez = Eigen::Vector3d::UnitZ(), ex = Eigen::Vector3d::UnitX(), ey = Eigen::Vector3d::UnitY();
  struct Key {
    double dt;
    Eigen::Vector3d p;
    Eigen::Quaterniond R;
  };
  std::vector<Key> keys;
  const double f = volume.featureSize_m();
  for (int l = 0; l < locations; ++l) {
    const Eigen::Vector2d o = spots[static_cast<std::size_t>(l) % spots.size()];
    haptics::Pose start = runtime::poseAboveVolume(volume, shell, R0, 0.01);
    start.p_AB_m.x() += o.x() * ext.x();
    start.p_AB_m.y() += o.y() * ext.y();
    const std::optional<double> d = runtime::firstContactDistance(volume, shell, start, -ez,
                                                                  ext.z() + 0.2, isovalue, 0.25 * f);
    Eigen::Vector3d c = start.p_AB_m;
    if (d) {
      c.z() -= *d;
    } else {
      c.z() = centre.z();
      if (notes) notes->push_back(format("spot %d: the ray meets no surface; the interaction starts at mid height", l));
    }
    const Eigen::Vector3d hover = c + 0.010 * ez;
    const double gap = keys.empty() ? 0.0 : 0.3;
    keys.push_back({gap, hover, R0});
    for (int k = 1; k <= 8; ++k) {  // free motion: a circle with a tilt
      const double a = 2.0 * M_PI * k / 8.0;
      const Eigen::Vector3d p = hover + 0.008 * (std::cos(a) - 1.0) * ex + 0.008 * std::sin(a) * ey;
      keys.push_back({0.125, p, aa(0.2 * std::sin(a), k % 2 ? ex : ey) * R0});
    }
    keys.push_back({0.4, c - 0.001 * ez, R0});                                     // contact
    keys.push_back({0.3, c - 0.003 * ez, R0});                                     // pressing
    keys.push_back({1.0, c - 0.003 * ez + 0.010 * ex, R0});                        // sliding in x
    keys.push_back({0.6, c - 0.003 * ez + 0.010 * ex + 0.008 * ey, R0});           // sliding in y
    const Eigen::Vector3d q = c - 0.003 * ez + 0.010 * ex + 0.008 * ey;
    keys.push_back({0.6, q, aa(0.3, ey) * R0});                                    // prying
    keys.push_back({0.4, q, aa(-0.3, ey) * R0});
    keys.push_back({0.3, q - 0.003 * ez, aa(0.4, ez) * R0});                       // wedging
    keys.push_back({0.4, q - 0.003 * ez - 0.015 * ex, aa(0.4, ez) * R0});          // hooking: drag
    keys.push_back({0.3, q - 0.003 * ez - 0.015 * ex + 0.015 * ez, R0});           // and pull up
    keys.push_back({0.3, hover, R0});                                              // retract
  }
  double total = 0.0;
  for (const Key& k : keys) total += k.dt;
  const double duration_s = (ticks - 1) / 1000.0;
  const double scale = duration_s / total;
  std::vector<runtime::TrajectorySample> samples;
  double t = 0.0;
  for (const Key& k : keys) {
    t += k.dt * scale;
    samples.push_back({t, haptics::Pose{k.R, k.p}});
  }
  samples.front().t_s = 0.0;
  return runtime::Trajectory(std::move(samples));
}

namespace {

/// One column of the table: a detection mode and a segment test (the "before" column of the exact
/// segment test's comparison is the accelerated mode with the earlier end-sample test).
struct Variant {
  haptics::DetectionMode mode = haptics::DetectionMode::kAccelerated;
  haptics::SegmentTest segment_test = haptics::SegmentTest::kExact;
  std::string key;    ///< JSON key and file-name part: "paper", "accelerated", "accelerated-end-sample".
  std::string label;  ///< For people: "paper", "accelerated", "accelerated (end-sample, before)".
  std::int64_t work_budget = 0;  ///< RendererOptions::work_budget (the bounded tick), 0 = none.
  int max_contacts = haptics::RendererOptions{}.max_contacts;              ///< RendererOptions::max_contacts.
  double max_travel_m = haptics::RendererOptions{}.max_travel_per_tick_m;  ///< RendererOptions::max_travel_per_tick_m.
  int lanes = 1;             ///< RendererOptions::solver_lanes.
  double deadline_us = 0.0;  ///< RendererOptions::deadline_us (0: none).
  int edge_test = 0;         ///< RendererOptions::edge_test.
  bool edge_test_swept = false;  ///< RendererOptions::edge_test_swept.
};

/// The accelerated mode without a work budget: the reference the budgeted proxy's lag is
/// measured against.
constexpr const char* kUnbudgetedKey = "accelerated-unbudgeted";

constexpr const char* kBeforeKey = "accelerated-end-sample";

/// The accelerated mode with the edge test between shell points.
constexpr const char* kEdgesKey = "accelerated-edges";
/// The same without a work budget or deadline: the reference its lag is measured against.
constexpr const char* kEdgesUnbudgetedKey = "accelerated-edges-unbudgeted";
// The crossing check samples the edges between shell points this many path steps apart.
constexpr double kEdgeStepFactor = 5.0;
/// The full solve's own sensitivity to its history (the control beside the budget's lag): the
/// same full solve run again with one device sample in Table1Options::kHeldSampleEvery held,
/// and its distance from the full solve.
constexpr int kHeldSampleEvery = Table1Options::kHeldSampleEvery;

struct ModeRun {
  Variant variant;
  bool checked = true;  ///< Its moves are crossing-checked (the references only with verify_references).
  std::unique_ptr<haptics::HapticRenderer> renderer;
  std::vector<double> times_us, cpu_us, contacts, samples;
  double max_penetration_m = 0.0, max_force_N = 0.0, cells_sum = 0.0;
  // Per tick: TickStats::edge_us (the edge test's own wall time) and TickStats::edge_test_counts
  // (what the edge test did).
  std::vector<double> edge_us;
  std::vector<haptics::EdgeTestCounts> edge_counts;
  std::uint64_t nan_ticks = 0, over_1ms = 0, in_contact = 0;
  // Crossing check (CrossingVerifier after each tick, outside the timed section).
  std::int64_t crossings = 0, crossing_points = 0, first_crossing_tick = -1;
  // Of the tool's surface between its points (CrossingVerifier::checkEdges(), the end of each move).
  std::int64_t edge_crossings = 0, first_edge_crossing_tick = -1;
  double verify_s = 0.0;
  // Each tick's move (its motion and time of contact), for the crossing check after the run.
  struct Move {
    haptics::RigidMotion motion;
    double t = 0.0;
    int tick = 0;
  };
  std::vector<Move> moves;
  double wall_s = 0.0;
  // Ticks the work budget cut; the lag behind the unbudgeted accelerated proxy.
  std::int64_t budget_cuts = 0, deadline_cuts = 0;
  runtime::ProxyLag lag;
  // The full solve only: the same again with one device sample in kHeldSampleEvery held, and how
  // far its proxy was from this one's (held_samples -1: not run).
  runtime::ProxyLag held;
  std::int64_t held_samples = -1;
  double max_work = 0.0;
  // Sums over the ticks of TickStats::work and TickStats::critical_work (the lanes' balance).
  double work_sum = 0.0, critical_work_sum = 0.0;
};

/// What the edge test did per tick (TickStats::edge_test_counts), as means over every tick and
/// over its slowest 0.1 % (at least one tick, by the edge test's own time): the points whose
/// edges certificates held, a box query cleared or the exact walk tested, the edges walked, and
/// the edge test's time per edge walked on those slowest ticks [us].
nlohmann::ordered_json edgeTestPointsJson(const ModeRun& m) {
  const std::size_t n = m.edge_counts.size();
  std::vector<std::size_t> order(n);
  for (std::size_t i = 0; i < n; ++i) order[i] = i;
  const std::size_t slowest = std::max<std::size_t>(1, n / 1000);
  std::partial_sort(order.begin(), order.begin() + static_cast<std::ptrdiff_t>(std::min(slowest, n)), order.end(),
                    [&](std::size_t a, std::size_t b) { return m.edge_us[a] > m.edge_us[b]; });
  const auto means = [&](std::size_t count) {
    double held = 0, boxed = 0, walked = 0, edges = 0, us = 0;
    for (std::size_t k = 0; k < count; ++k) {
      const haptics::EdgeTestCounts& c = m.edge_counts[order[k]];
      held += static_cast<double>(c.points_held);
      boxed += static_cast<double>(c.points_boxed);
      walked += static_cast<double>(c.points_walked);
      edges += static_cast<double>(c.edges_walked);
      us += m.edge_us[order[k]];
    }
    const double d = std::max<double>(1.0, static_cast<double>(count));
    nlohmann::ordered_json j;
    j["ticks"] = count;
    j["points_held"] = held / d;
    j["points_boxed"] = boxed / d;
    j["points_walked"] = walked / d;
    j["edges_walked"] = edges / d;
    j["edge_test_us"] = us / d;
    if (edges > 0.0) j["us_per_edge_walked"] = us / edges;
    return j;
  };
  nlohmann::ordered_json j;
  j["mean_per_tick"] = means(n);
  j["slowest_0_1_percent"] = means(std::min(slowest, n));
  return j;
}

nlohmann::ordered_json modeJson(const ModeRun& m, double epsilon_m, bool verified) {
  const Stats t = summarize(m.times_us), c = summarize(m.contacts), s = summarize(m.samples);
  const Stats cpu = summarize(m.cpu_us);
  nlohmann::ordered_json j;
  j["label"] = m.variant.label;
  j["detection_mode"] = haptics::toString(m.variant.mode);
  j["segment_test"] = haptics::toString(m.variant.segment_test);
  j["lanes"] = m.variant.lanes;
  if (m.variant.deadline_us > 0.0) j["deadline_us"] = m.variant.deadline_us;
  if (m.variant.work_budget > 0 || m.variant.deadline_us > 0.0) {
    j["work_budget"] = m.variant.work_budget;
    j["budget_cuts"] = m.budget_cuts;
    j["deadline_cuts"] = m.deadline_cuts;
    j["max_work"] = m.max_work;
    j["lag_ticks"] = m.lag.ticks;
    j["max_lag_m"] = m.lag.max_m;
    j["max_lag_rad"] = m.lag.max_rad;
    j["max_behind_m"] = m.lag.max_behind_m;
    j["max_behind_rad"] = m.lag.max_behind_rad;
  }
  // How evenly the lanes shared the work: all work / (lanes x the work on the ticks' critical
  // paths); 1 on one lane, and on several when every lane did the same share.
  if (m.critical_work_sum > 0.0 && m.renderer) {
    j["lanes_used"] = m.renderer->solverLanes();
    j["lane_efficiency"] = m.work_sum / (m.renderer->solverLanes() * m.critical_work_sum);
  }
  j["ticks"] = t.n;
  j["mean_us"] = t.mean;
  j["p50_us"] = t.p50;
  j["p99_us"] = t.p99;
  j["p99_9_us"] = t.p999;
  j["max_us"] = t.max;
  j["ticks_over_1ms"] = m.over_1ms;
  // Thread CPU time around tick() (includes ~1 us of clock reads): insensitive to preemption on
  // a shared machine, unlike the wall times above.
  j["cpu_mean_us"] = cpu.mean;
  j["cpu_p99_us"] = cpu.p99;
  j["cpu_p99_9_us"] = cpu.p999;
  j["cpu_max_us"] = cpu.max;
  // The edge test's own time (wall, TickStats::edge_us), and the rest of the tick without it:
  // what the edge test costs by itself, and what the moves it changes (the contacts it adds
  // between the points) cost the sweep and the solve.
  const double edge_us_sum = std::accumulate(m.edge_us.begin(), m.edge_us.end(), 0.0);
  if (edge_us_sum > 0.0 && t.n > 0) {
    j["edge_test_mean_us"] = edge_us_sum / static_cast<double>(t.n);
    j["cpu_mean_without_edge_test_us"] = cpu.mean - edge_us_sum / static_cast<double>(t.n);
    j["edge_test_points"] = edgeTestPointsJson(m);
  }
  j["mean_contacts"] = c.mean;
  j["max_contacts"] = c.max;
  j["ticks_in_contact"] = m.in_contact;
  j["mean_volume_samples"] = s.mean;
  j["max_volume_samples"] = s.max;
  j["mean_cells"] = t.n ? m.cells_sum / static_cast<double>(t.n) : 0.0;
  j["max_penetration_m"] = m.max_penetration_m;
  j["max_penetration_over_epsilon"] = epsilon_m > 0.0 ? m.max_penetration_m / epsilon_m : 0.0;
  j["max_force_N"] = finiteOr(m.max_force_N);
  j["nan_ticks"] = m.nan_ticks;
  j["bad_device_samples"] = m.renderer->badInputCount();
  // Ticks in which the proxy carried a shell point from outside into the isosurface; -1: not
  // checked (--verify-step 0).
  j["crossings"] = verified && m.checked ? m.crossings : -1;
  j["crossing_points"] = verified && m.checked ? m.crossing_points : -1;
  j["first_crossing_tick"] = verified && m.checked ? m.first_crossing_tick : -1;
  // Ticks at whose end an edge of the point shell's neighbour graph (ends inset by epsilon) was
  // inside the isosurface while free at the tick's start; -1: not checked.
  j["edge_crossings"] = verified && m.checked ? m.edge_crossings : -1;
  j["first_edge_crossing_tick"] = verified && m.checked ? m.first_edge_crossing_tick : -1;
  if (m.held_samples >= 0) {
    j["held_samples"] = m.held_samples;
    j["held_every"] = kHeldSampleEvery;
    j["held_apart_max_m"] = m.held.max_m;
    j["held_apart_max_rad"] = m.held.max_rad;
  }
  j["verify_s"] = m.verify_s;
  j["wall_s"] = m.wall_s;
  return j;
}

/// Max of each of `bins` consecutive blocks (keeps the spikes visible in a plot).
Series downsampleMax(const std::string& name, const std::vector<double>& v, std::size_t bins) {
  Series s;
  s.name = name;
  const std::size_t n = v.size();
  if (n == 0) return s;
  const std::size_t step = std::max<std::size_t>(1, n / bins);
  for (std::size_t i = 0; i < n; i += step) {
    double m = 0.0;
    for (std::size_t k = i; k < std::min(n, i + step); ++k) m = std::max(m, v[k]);
    s.x.push_back(static_cast<double>(i));
    s.y.push_back(m);
  }
  return s;
}

/// One run per variant, each with its renderer at the trajectory's first pose and its per-tick
/// vectors reserved for `ticks` (no allocation in the tick loop).
std::vector<ModeRun> makeModeRuns(const runtime::LoadedScene& scene,
                                  const std::shared_ptr<const haptics::ToolModel>& tool,
                                  const std::vector<Variant>& variants, const haptics::Pose& X_WD0, double isovalue,
                                  int ticks) {
  std::vector<ModeRun> runs;
  for (const Variant& variant : variants) {
    ModeRun m;
    m.variant = variant;
    haptics::RendererOptions options;
    options.detection_mode = variant.mode;
    options.segment_test = variant.segment_test;
    options.work_budget = variant.work_budget;
    options.max_contacts = variant.max_contacts;
    options.max_travel_per_tick_m = variant.max_travel_m;
    options.solver_lanes = variant.lanes;
    options.deadline_us = variant.deadline_us;
    options.edge_test = variant.edge_test;
    options.edge_test_swept = variant.edge_test_swept;
    options.gains = scene.spec.gains;
    m.renderer = std::make_unique<haptics::HapticRenderer>(scene.volume.field, tool, options, X_WD0, isovalue);
    m.times_us.reserve(static_cast<std::size_t>(ticks));
    m.cpu_us.reserve(static_cast<std::size_t>(ticks));
    m.contacts.reserve(static_cast<std::size_t>(ticks));
    m.samples.reserve(static_cast<std::size_t>(ticks));
    runs.push_back(std::move(m));
  }
  return runs;
}

/// Index of the run of the variant `key` in `runs`, or -1 when that variant does not run.
int runIndex(const std::vector<ModeRun>& runs, const std::string& key) {
  for (std::size_t r = 0; r < runs.size(); ++r)
    if (runs[r].variant.key == key) return static_cast<int>(r);
  return -1;
}

/// The crossing check of every move a run made (CrossingVerifier, after the run): the points'
/// paths, and the tool's surface between its points (the neighbour graph's edges, ends inset by
/// epsilon) at each move's end, along each edge at kEdgeStepFactor times the path step.
void checkMoves(haptics::CrossingVerifier& verifier, const haptics::ShellEdges& shell_edges, double isovalue,
                double epsilon_m, ModeRun& m) {
  const auto v0 = std::chrono::steady_clock::now();
  for (const ModeRun::Move& move : m.moves) {
    const haptics::CrossingVerifier::Result check = verifier.check(move.motion, move.t, isovalue);
    if (check.crossing_points > 0) {
      ++m.crossings;
      m.crossing_points += check.crossing_points;
      if (m.first_crossing_tick < 0) m.first_crossing_tick = move.tick;
    }
    const haptics::CrossingVerifier::EdgeResult edges = verifier.checkEdges(
        move.motion, move.t, isovalue, shell_edges, epsilon_m, 1, kEdgeStepFactor * verifier.step_m());
    if (edges.crossing_edges > 0) {
      ++m.edge_crossings;
      if (m.first_edge_crossing_tick < 0) m.first_edge_crossing_tick = move.tick;
    }
  }
  m.verify_s += std::chrono::duration<double>(std::chrono::steady_clock::now() - v0).count();
  m.moves = {};
}

/// The control beside the budget's lag: the full solve (`full`'s variant) driven again by the
/// same device samples but for one in kHeldSampleEvery, held (the previous sample repeated, as
/// when a USB packet is lost), and how far its proxy gets from the full solve's proxy
/// (`full_solve_poses`, one per tick). A quasi-static proxy's path depends on its history; this
/// is how far one late sample alone moves it, with no budget anywhere. Untimed; after the run,
/// so it does not share the timed columns' caches.
void runHeldSampleControl(const runtime::LoadedScene& scene, const std::shared_ptr<const haptics::ToolModel>& tool,
                          const runtime::Trajectory& traj, const haptics::Pose& X_WD0, double isovalue,
                          const std::vector<haptics::Pose>& full_solve_poses, ModeRun& full, std::ostream* lag_csv) {
  std::vector<ModeRun> control = makeModeRuns(scene, tool, {full.variant}, X_WD0, isovalue, 0);
  haptics::HapticRenderer& renderer = *control.front().renderer;
  std::size_t cursor = 0;
  haptics::Pose X_WD_last = X_WD0;
  full.held = runtime::ProxyLag{};
  full.held_samples = 0;
  for (int i = 0; static_cast<std::size_t>(i) < full_solve_poses.size(); ++i) {
    const haptics::Pose X_WD = traj.poseAt(i * 1e-3, cursor);
    const bool hold = i % kHeldSampleEvery == kHeldSampleEvery / 2;
    full.held_samples += hold;
    const haptics::TickOutput out = renderer.tick(hold ? X_WD_last : X_WD, isovalue);
    if (!hold) X_WD_last = X_WD;
    const haptics::Pose& X_WP_full = full_solve_poses[static_cast<std::size_t>(i)];
    if (!out.X_WP.allFinite() || !X_WP_full.allFinite()) continue;
    full.held.add(out.X_WP, X_WP_full);
    if (lag_csv) {
      const runtime::ProxyLag::Gap apart = runtime::ProxyLag::apart(out.X_WP, X_WP_full);
      *lag_csv << i << ",held-control," << apart.m << ',' << apart.rad << ",,\n";
    }
  }
}

/// Diagnostics: the folder VH_TABLE1_TICK_CSV names, or nothing when it is not set.
std::optional<fs::path> tickCsvDir() {
  const char* dir = std::getenv("VH_TABLE1_TICK_CSV");
  return dir ? std::optional<fs::path>(dir) : std::nullopt;
}

/// Diagnostics: VH_TABLE1_TICK_CSV=DIR writes one CSV per scene and mode with every
/// tick's times and statistics, to find the worst ticks and what they do.
/// @return one stream per run (header written), or none when the variable is not set.
std::vector<std::unique_ptr<std::ofstream>> openTickCsvs(const std::vector<ModeRun>& runs,
                                                         const std::string& scene_name) {
  std::vector<std::unique_ptr<std::ofstream>> tick_csv;
  if (const std::optional<fs::path> dir = tickCsvDir()) {
    for (const ModeRun& m : runs) {
      tick_csv.push_back(std::make_unique<std::ofstream>(*dir / (scene_name + "_" + m.variant.key + ".csv")));
      *tick_csv.back() << "tick,wall_us,cpu_us,contacts,samples,box_queries,tree_nodes,cells,cells_walked,time_of_contact,device_step_m,"
                          "device_step_rad,proxy_device_m,proxy_device_rad,prune_us,solve_us,sweep_us,sweeps,contacts_us,work,"
                          "budget_cut,edge_us\n";
    }
  }
  return tick_csv;
}

/// What one scene ran on and with, into `row`: the volume, the tool's points, the trajectory and
/// the checks (verify_step_voxels 0: no crossing check).
void describeSceneRun(nlohmann::ordered_json& row, const haptics::ScalarVolume& volume, std::size_t points,
                      double isovalue, double epsilon_m, int ticks, const runtime::Trajectory& traj, int locations,
                      const std::vector<std::string>& notes, int inside0, int penetration_stride,
                      double verify_step_voxels) {
  row["status"] = "ran";
  row["isovalue"] = isovalue;
  row["volume_dims"] = volume.geometry().dims;
  row["volume_spacing_m"] = {volume.geometry().spacing_m.x(), volume.geometry().spacing_m.y(),
                             volume.geometry().spacing_m.z()};
  row["points"] = points;
  row["epsilon_m"] = epsilon_m;
  row["feature_size_m"] = volume.featureSize_m();
  row["ticks"] = ticks;
  row["trajectory"] = {{"duration_s", traj.duration_s()}, {"key_poses", traj.size()}, {"spots", locations},
                       {"notes", notes}};
  row["initial_points_inside"] = inside0;
  row["penetration_every_n_ticks"] = penetration_stride;
  row["verify_step_voxels"] = verify_step_voxels;
}

/// Each mode's statistics into `row` ("modes") and its tick times into `plot_series`; with both
/// modes, the paper / accelerated ratios, and with the "before" column, exact / end-sample.
/// The largest proxy differences [m] come from the tick loop.
void addModeResults(nlohmann::ordered_json& row, const std::vector<ModeRun>& runs, double epsilon_m, bool verified,
                    bool both_modes, bool with_before, double max_mode_difference_m, double max_before_difference_m,
                    std::vector<Series>& plot_series) {
  nlohmann::ordered_json modes_json;
  for (const ModeRun& m : runs) {
    modes_json[m.variant.key] = modeJson(m, epsilon_m, verified);
    plot_series.push_back(
        downsampleMax(m.variant.key == kBeforeKey ? m.variant.label : m.variant.label + " mode", m.times_us, 1500));
  }
  row["modes"] = modes_json;
  const auto ratio = [](double num, double den) { return den > 0.0 ? num / den : 0.0; };
  if (both_modes) {
    const auto& p = modes_json["paper"];
    const auto& a = modes_json["accelerated"];
    row["ratio_paper_over_accelerated"] = {
        {"mean", ratio(p["mean_us"], a["mean_us"])},
        {"p99", ratio(p["p99_us"], a["p99_us"])},
        {"max", ratio(p["max_us"], a["max_us"])},
        {"volume_samples", ratio(p["mean_volume_samples"], a["mean_volume_samples"])}};
    row["max_proxy_difference_between_modes_m"] = max_mode_difference_m;
  }
  if (with_before) {
    // The exact segment test (after) against the earlier end sample (before), same run,
    // thread CPU time (the 1.3x target is on the means).
    const auto& a = modes_json["accelerated"];
    const auto& b = modes_json[kBeforeKey];
    const double mean_ratio = ratio(a["cpu_mean_us"], b["cpu_mean_us"]);
    row["ratio_exact_over_end_sample"] = {{"cpu_mean", mean_ratio},
                                          {"cpu_p99_9", ratio(a["cpu_p99_9_us"], b["cpu_p99_9_us"])},
                                          {"cpu_max", ratio(a["cpu_max_us"], b["cpu_max_us"])},
                                          {"wall_mean", ratio(a["mean_us"], b["mean_us"])},
                                          {"volume_samples", ratio(a["mean_volume_samples"], b["mean_volume_samples"])},
                                          {"within_1_3x", mean_ratio <= 1.3}};
    row["max_proxy_difference_exact_vs_end_sample_m"] = max_before_difference_m;
  }
  if (modes_json.contains(kEdgesKey)) {
    // The edge test's cost, same run, thread CPU time.
    const auto& a = modes_json["accelerated"];
    const auto& e = modes_json[kEdgesKey];
    const double mean_ratio = ratio(e["cpu_mean_us"], a["cpu_mean_us"]);
    row["ratio_edges_over_accelerated"] = {{"cpu_mean", mean_ratio},
                                           {"cpu_p99_9", ratio(e["cpu_p99_9_us"], a["cpu_p99_9_us"])},
                                           {"cpu_max", ratio(e["cpu_max_us"], a["cpu_max_us"])},
                                           {"within_1_2x", mean_ratio <= 1.2}};
    if (e.contains("cpu_mean_without_edge_test_us"))
      row["ratio_edges_over_accelerated"]["cpu_mean_without_edge_test"] =
          ratio(e["cpu_mean_without_edge_test_us"], a["cpu_mean_us"]);
  }
}

/// One mode's tick `i` at the device pose X_WD (X_WD_last: the tick before's), timed (wall and
/// thread CPU); then, outside the timed section, its statistics, its move for the crossing check
/// (`collect_moves`) and its row of the tick CSV (`tick_csv` not null).
/// @return whether its output was finite; then its proxy pose into `proxy`, `proxy_R`.
bool tickMode(ModeRun& m, int i, const haptics::Pose& X_WD, const haptics::Pose& X_WD_last, double s,
              bool collect_moves, std::ostream* tick_csv, const haptics::ScalarVolume& volume,
              const haptics::ToolModel& tool, int penetration_stride, Eigen::Vector3d& proxy,
              Eigen::Quaterniond& proxy_R) {
  const auto w0 = std::chrono::steady_clock::now();
  const double c0 = runtime::threadCpuTime_us();
  const haptics::Pose X_WP_before = m.renderer->proxyPose();
  const haptics::TickOutput out = m.renderer->tick(X_WD, s);
  m.cpu_us.push_back(runtime::threadCpuTime_us() - c0);
  m.wall_s += std::chrono::duration<double>(std::chrono::steady_clock::now() - w0).count();
  // Everything below is outside the timed section.
  m.edge_us.push_back(out.stats.edge_us);
  m.edge_counts.push_back(out.stats.edge_test_counts);
  const bool finite = out.force_W_N.allFinite() && out.torque_W_Nm.allFinite() && out.X_WP.allFinite();
  // The crossing check runs after the run (checkMoves()): between ticks its dense reads of the
  // volume would evict the timed columns' state from the caches, which the application's
  // servo thread does not suffer.
  if (collect_moves && finite) m.moves.push_back({m.renderer->lastMotion(), m.renderer->lastTimeOfContact(), i});
  if (tick_csv != nullptr)
    *tick_csv << i << ',' << out.stats.exec_time_us << ',' << m.cpu_us.back() << ',' << out.stats.contacts << ','
              << out.stats.volume_samples << ',' << out.stats.box_queries << ',' << out.stats.tree_nodes << ','
              << out.stats.cells << ',' << out.stats.cells_walked << ','
              << out.stats.time_of_contact << ',' << (X_WD.p_AB_m - X_WD_last.p_AB_m).norm() << ','
              << X_WD.R_AB.angularDistance(X_WD_last.R_AB) << ','
              << (X_WD.p_AB_m - X_WP_before.p_AB_m).norm() << ','
              << X_WD.R_AB.angularDistance(X_WP_before.R_AB) << ','
              << out.stats.prune_us << ',' << out.stats.solve_us << ',' << out.stats.sweep_us << ',' << out.stats.sweeps << ','
              << out.stats.contacts_us << ',' << out.stats.work << ',' << int(out.stats.budget_cut) << ','
              << out.stats.edge_us << '\n';
  m.times_us.push_back(out.stats.exec_time_us);
  m.contacts.push_back(out.stats.contacts);
  m.samples.push_back(static_cast<double>(out.stats.volume_samples));
  m.cells_sum += static_cast<double>(out.stats.cells);
  m.budget_cuts += out.stats.budget_cut;
  m.deadline_cuts += out.stats.deadline_cut;
  m.max_work = std::max(m.max_work, static_cast<double>(out.stats.work));
  m.work_sum += static_cast<double>(out.stats.work);
  m.critical_work_sum += static_cast<double>(out.stats.critical_work);
  if (out.stats.exec_time_us > 1000.0) ++m.over_1ms;
  if (out.stats.contacts > 0) ++m.in_contact;
  if (!finite) {
    ++m.nan_ticks;
    return false;
  }
  proxy = out.X_WP.p_AB_m;
  proxy_R = out.X_WP.R_AB;
  m.max_force_N = std::max(m.max_force_N, out.force_W_N.norm());
  if (i % penetration_stride == 0)
    m.max_penetration_m = std::max(m.max_penetration_m, haptics::maxPenetration_m(volume, tool.point_shell, out.X_WP, s));
  return true;
}

/// The lag of a budgeted mode (run index `budgeted`) behind the same mode's full solve (`full`)
/// on tick `i`, when both ran and were finite; a row of the lag CSV (`lag_csv` not null).
void addLag(std::vector<ModeRun>& runs, const std::vector<char>& proxy_finite, int budgeted, int full, int i,
            const haptics::Pose& X_WD, std::ostream* lag_csv) {
  if (budgeted < 0 || full < 0 || !proxy_finite[static_cast<std::size_t>(budgeted)] ||
      !proxy_finite[static_cast<std::size_t>(full)])
    return;
  ModeRun& b = runs[static_cast<std::size_t>(budgeted)];
  const haptics::Pose X_WP_b = b.renderer->proxyPose();
  const haptics::Pose X_WP_f = runs[static_cast<std::size_t>(full)].renderer->proxyPose();
  b.lag.add(X_WP_b, X_WP_f, X_WD);
  if (lag_csv) {
    const runtime::ProxyLag::Gap apart = runtime::ProxyLag::apart(X_WP_b, X_WP_f);
    const runtime::ProxyLag::Gap behind = runtime::ProxyLag::behind(X_WP_b, X_WP_f, X_WD);
    *lag_csv << i << ',' << b.variant.key << ',' << apart.m << ',' << apart.rad << ',' << behind.m << ','
             << behind.rad << '\n';
  }
}

/// Runs one scene (loaded) in the selected variants, interleaved tick by tick so that all see
/// the same machine load: the first `ticks` ticks of the trajectory timed to last
/// `trajectory_ticks` (>= ticks; fewer ticks run only its beginning, at the same speed). After
/// each tick, outside the timed section, a CrossingVerifier (verify_step_voxels > 0) checks the
/// path the proxy moved along. Fills `row`.
void runScene(const runtime::LoadedScene& scene, std::shared_ptr<const haptics::ToolModel> tool,
              const std::vector<Variant>& variants, int ticks, int trajectory_ticks, int locations,
              int penetration_stride, double verify_step_voxels, bool verify_references, nlohmann::ordered_json& row,
              std::vector<Series>& plot_series) {
  const haptics::ScalarVolume& volume = *scene.volume.field;
  const double s = scene.isovalue;
  std::vector<std::string> notes;
  const runtime::Trajectory traj = table1Trajectory(volume, tool->point_shell, s, scene.spec.tool.X_WT_initial.R_AB,
                                                    std::max(ticks, trajectory_ticks), locations, &notes);
  const haptics::Pose X_WD0 = traj.samples().front().X_WD;
  const int inside0 = runtime::countPointsInside(volume, tool->point_shell, X_WD0, s);
  std::optional<haptics::CrossingVerifier> verifier;
  haptics::ShellEdges shell_edges;
  if (verify_step_voxels > 0.0) {
    verifier.emplace(volume, tool->point_shell, verify_step_voxels);
    shell_edges = haptics::makeShellEdges(tool->point_shell);
  }

  std::vector<ModeRun> runs = makeModeRuns(scene, tool, variants, X_WD0, s, ticks);
  for (ModeRun& m : runs)
    m.checked = verify_references || (m.variant.key != kUnbudgetedKey && m.variant.key != kEdgesUnbudgetedKey);
  if (verifier)
    for (ModeRun& m : runs)
      if (m.checked) m.moves.reserve(static_cast<std::size_t>(ticks));
  const int i_paper = runIndex(runs, "paper"), i_accel = runIndex(runs, "accelerated");
  const int i_before = runIndex(runs, kBeforeKey);
  const int i_unbudgeted = runIndex(runs, kUnbudgetedKey);
  const int i_edges = runIndex(runs, kEdgesKey), i_edges_unbudgeted = runIndex(runs, kEdgesUnbudgetedKey);
  const double epsilon_m = runs.front().renderer->epsilon_m();
  double max_mode_difference_m = 0.0, max_before_difference_m = 0.0;
  std::vector<std::unique_ptr<std::ofstream>> tick_csv = openTickCsvs(runs, row["name"].get<std::string>());
  // With the tick CSVs, each budgeted mode's lag behind its full solve, tick by tick (and the
  // held-sample control's distance from the full solve, whose behind is left empty).
  std::unique_ptr<std::ofstream> lag_csv;
  if (const std::optional<fs::path> dir = tickCsvDir()) {
    lag_csv = std::make_unique<std::ofstream>(*dir / (row["name"].get<std::string>() + "_lag.csv"));
    *lag_csv << "tick,mode,lag_m,lag_rad,behind_m,behind_rad\n";
  }
  // The full solve's proxy on every tick: the held-sample control is compared with it afterwards.
  std::vector<haptics::Pose> full_solve_poses;
  if (i_unbudgeted >= 0) full_solve_poses.reserve(static_cast<std::size_t>(ticks));
  haptics::Pose X_WD_last = X_WD0;
  std::size_t cursor = 0;
  std::vector<Eigen::Vector3d> proxy(runs.size(), Eigen::Vector3d::Zero());
  std::vector<Eigen::Quaterniond> proxy_R(runs.size(), Eigen::Quaterniond::Identity());
  std::vector<char> proxy_finite(runs.size(), 0);
  for (int i = 0; i < ticks; ++i) {
    const haptics::Pose X_WD = traj.poseAt(i * 1e-3, cursor);
    for (std::size_t r = 0; r < runs.size(); ++r) {
      proxy_finite[r] = tickMode(runs[r], i, X_WD, X_WD_last, s, verifier.has_value() && runs[r].checked,
                                 tick_csv.empty() ? nullptr : tick_csv[r].get(), volume, *tool, penetration_stride,
                                 proxy[r], proxy_R[r]);
    }
    const auto difference = [&](int a, int b) {
      return a >= 0 && b >= 0 && proxy_finite[static_cast<std::size_t>(a)] && proxy_finite[static_cast<std::size_t>(b)]
                 ? (proxy[static_cast<std::size_t>(a)] - proxy[static_cast<std::size_t>(b)]).norm()
                 : 0.0;
    };
    max_mode_difference_m = std::max(max_mode_difference_m, difference(i_paper, i_accel));
    max_before_difference_m = std::max(max_before_difference_m, difference(i_accel, i_before));
    if (i_unbudgeted >= 0) full_solve_poses.push_back(runs[static_cast<std::size_t>(i_unbudgeted)].renderer->proxyPose());
    addLag(runs, proxy_finite, i_accel, i_unbudgeted, i, X_WD, lag_csv.get());
    addLag(runs, proxy_finite, i_edges, i_edges_unbudgeted, i, X_WD, lag_csv.get());
    X_WD_last = X_WD;
  }
  if (verifier)
    for (ModeRun& m : runs)
      if (m.checked) checkMoves(*verifier, shell_edges, s, epsilon_m, m);
  if (i_unbudgeted >= 0)
    runHeldSampleControl(scene, tool, traj, X_WD0, s, full_solve_poses, runs[static_cast<std::size_t>(i_unbudgeted)],
                         lag_csv.get());

  describeSceneRun(row, volume, tool->point_shell.size(), s, epsilon_m, ticks, traj, locations, notes, inside0,
                   penetration_stride, verifier ? verify_step_voxels : 0.0);
  addModeResults(row, runs, epsilon_m, verifier.has_value(), i_paper >= 0 && i_accel >= 0,
                 i_accel >= 0 && i_before >= 0, max_mode_difference_m, max_before_difference_m, plot_series);
}

std::string num(double v, int digits = 0) { return format("%.*f", digits, v); }

/// A mode's crossing count for people: "0", "3 (5 points, first at tick 812)", "0; edges 4 (first
/// at tick 90)" (the tool's surface between its points), "-" (not checked).
std::string crossingsText(const nlohmann::ordered_json& m) {
  const auto n = m["crossings"].get<std::int64_t>();
  if (n < 0) return "-";
  const auto edges = m.contains("edge_crossings") ? m["edge_crossings"].get<std::int64_t>() : 0;
  const std::string edge_text =
      edges > 0 ? format("; edges %lld (first at tick %lld)", static_cast<long long>(edges),
                         static_cast<long long>(m["first_edge_crossing_tick"].get<std::int64_t>()))
                : std::string();
  if (n == 0) return "0" + edge_text;
  const auto points = m["crossing_points"].get<std::int64_t>();
  return format("%lld (%lld point%s, first at tick %lld)", static_cast<long long>(n), static_cast<long long>(points),
                points == 1 ? "" : "s", static_cast<long long>(m["first_crossing_tick"].get<std::int64_t>())) +
         edge_text;
}

/// Busy threads beside the run (a loaded machine, --load) until this object goes out of scope.
class BusyLoad {
 public:
  explicit BusyLoad(int threads) {
    for (int i = 0; i < threads; ++i)
      threads_.emplace_back([this] {
        volatile double x = 1.0;
        while (!stop_.load(std::memory_order_relaxed))
          for (int k = 0; k < 10000; ++k) x = x * 1.0000001 + 1e-9;
      });
  }
  ~BusyLoad() { stop_.store(true); }  // then threads_ joins them

 private:
  std::atomic<bool> stop_{false};
  std::vector<std::jthread> threads_;
};

/// The table's columns for `options`, with the accelerated mode's solver lanes and deadline [us].
/// @throws std::runtime_error for a lane count of --lanes-sweep outside [1, 64].
std::vector<Variant> table1Variants(const Table1Options& options, int lanes, double deadline_us) {
  std::vector<Variant> variants;
  using haptics::DetectionMode;
  using haptics::SegmentTest;
  // The paper's path as published: no budget, no contact cap (the set's capacity), no velocity
  // limit. The accelerated mode as the application runs it: work budget, 64 contacts, 4 mm per
  // tick; and, with a budget, the same without it, which its lag is measured against.
  if (options.modes != ModeSelection::kAccelerated)
    variants.push_back({DetectionMode::kPaper, SegmentTest::kExact, "paper", "paper", 0, 256, 0.0});
  if (options.modes != ModeSelection::kPaper) {
    std::string budget_text;
    if (options.work_budget > 0) budget_text += "work budget " + std::to_string(options.work_budget);
    if (deadline_us > 0.0) budget_text += (budget_text.empty() ? "" : ", ") + std::string("deadline ") + num(deadline_us) + " us";
    if (lanes > 1) budget_text += (budget_text.empty() ? "" : ", ") + std::to_string(lanes) + " lanes";
    if (!budget_text.empty()) budget_text = " (" + budget_text + ")";
    Variant accelerated{DetectionMode::kAccelerated, SegmentTest::kExact, "accelerated", "accelerated" + budget_text,
                        options.work_budget};
    accelerated.lanes = lanes;
    accelerated.deadline_us = deadline_us;
    variants.push_back(accelerated);
    if (options.work_budget > 0 || deadline_us > 0.0) {
      Variant unbudgeted{DetectionMode::kAccelerated, SegmentTest::kExact, kUnbudgetedKey,
                         "accelerated (unbudgeted" + std::string(lanes > 1 ? ", " + std::to_string(lanes) + " lanes" : "") + ")"};
      unbudgeted.lanes = lanes;
      variants.push_back(unbudgeted);
    }
    for (const int n : options.lane_sweep) {
      if (n < 1 || n > haptics::WorkerPool::kMaxLanes)
        throw std::runtime_error("--lanes-sweep: " + std::to_string(n) + " lanes is outside [1, 64]");
      Variant v{DetectionMode::kAccelerated, SegmentTest::kExact, "accelerated-lanes-" + std::to_string(n),
                "accelerated (unbudgeted, " + std::to_string(n) + (n == 1 ? " lane)" : " lanes)")};
      v.lanes = n;
      variants.push_back(v);
    }
    if (options.edge_test) {
      Variant edges = accelerated;
      edges.key = kEdgesKey;
      edges.label = std::string(options.edge_test_swept ? "accelerated with the swept edge test"
                                                        : "accelerated with the edge test") +
                    budget_text;
      edges.edge_test = 1;
      edges.edge_test_swept = options.edge_test_swept;
      variants.push_back(edges);
      if (options.work_budget > 0 || deadline_us > 0.0) {
        Variant full = edges;
        full.key = kEdgesUnbudgetedKey;
        full.label = "accelerated with the edge test (unbudgeted" +
                     std::string(lanes > 1 ? ", " + std::to_string(lanes) + " lanes" : "") + ")";
        full.work_budget = 0;
        full.deadline_us = 0.0;
        variants.push_back(full);
      }
    }
    if (options.before)
      variants.push_back({DetectionMode::kAccelerated, SegmentTest::kEndSample, kBeforeKey,
                          "accelerated (end-sample, before)", options.work_budget});
  }
  return variants;
}

/// The scenes to run: all of Table 1's, or the one named (case-insensitive; empty: all).
/// @throws std::runtime_error for an unknown name.
std::vector<SceneDef> selectScenes(const std::string& scene) {
  std::vector<SceneDef> defs = table1Scenes();
  if (!scene.empty()) {
    const auto it = std::find_if(defs.begin(), defs.end(),
                                 [&](const SceneDef& d) { return lower(d.name) == lower(scene); });
    if (it == defs.end())
      throw std::runtime_error("unknown scene '" + scene + "' (Bunny, Engine, Hole, Bone)");
    defs = {*it};
  }
  return defs;
}

/// A row's identity: the scene, its tool and the paper's figures (none for the resampled tools).
/// large: 0 the paper's tool, 1 and 2 the same tool resampled to `large_points`.
nlohmann::ordered_json rowHeader(const SceneDef& def, int large, int large_points) {
  nlohmann::ordered_json row;
  row["name"] = large == 0 ? def.name : large == 1 ? def.name + " (large tool)" : def.name + " (50k tool)";
  row["large_tool"] = large > 0;
  row["volume"] = def.volume;
  row["tool"] = def.tool_label;
  row["tool_mesh"] = def.tool_mesh;
  row["paper_points"] = large ? large_points : def.paper_points;
  row["paper"] = {{"mean_us", large ? 0.0 : def.paper_mean_us},
                  {"max_us", large ? 0.0 : def.paper_max_us},
                  {"resolution", def.paper_resolution}};
  return row;
}

/// The scene spec of `def` with a tool of `point_count` points: its volume and tool mesh found
/// (the CT bunny unpacked when needed). @return false with `why` when one of them is absent.
bool resolveSceneSpec(const SceneDef& def, std::size_t point_count, runtime::SceneSpec& spec, std::string& why) {
  std::optional<fs::path> volume_path;
  if (def.volume.rfind("builtin:", 0) == 0) {
    spec.volume.path = def.volume;
  } else if (def.from_archive) {
    volume_path = findOrUnpackBunny(why);
  } else {
    const fs::path p = runtime::sharedDatasetsDir() / def.volume;
    if (fs::exists(p)) volume_path = p;
    else why = p.string() + " is absent";
  }
  if (def.volume.rfind("builtin:", 0) != 0) {
    if (!volume_path) return false;
    spec.volume.path = volume_path->string();
  }
  if (def.tool_mesh.rfind("builtin:", 0) == 0) {
    spec.tool.mesh = def.tool_mesh;
  } else {
    const fs::path p = runtime::sharedDatasetsDir() / def.tool_mesh;
    if (!fs::exists(p)) {
      why = p.string() + " is absent";
      return false;
    }
    spec.tool.mesh = p.string();
  }
  if (def.isovalue) {
    spec.volume.isovalue = *def.isovalue;
    spec.volume.isovalue_set = true;
  }
  spec.tool.scale_to_m = def.tool_scale_to_m;
  spec.tool.point_count = point_count;
  spec.tool.X_WT_initial.R_AB = def.R_WT;
  spec.tool.initial_orientation_set = true;
  return true;
}

/// Prints a row's results per mode, the budget's cuts and lag, and the ratios between modes.
void printRowResults(nlohmann::ordered_json& row) {
  for (const auto& [mode, m] : row["modes"].items()) {
    std::cout << "  " << m["label"].get<std::string>() << ": mean " << num(m["mean_us"], 1) << " us, p50 " << num(m["p50_us"], 1)
              << ", p99 " << num(m["p99_us"], 1) << ", p99.9 " << num(m["p99_9_us"], 1) << ", max "
              << num(m["max_us"], 1) << " us (CPU mean " << num(m["cpu_mean_us"], 1) << ", max "
              << num(m["cpu_max_us"], 1) << "); contacts mean " << num(m["mean_contacts"], 2) << " max "
              << num(m["max_contacts"]) << "; samples/tick " << num(m["mean_volume_samples"]) << "; penetration "
              << num(1e3 * m["max_penetration_m"].get<double>(), 4) << " mm; crossings "
              << crossingsText(m) << "\n";
    if (m.contains("work_budget"))
      std::cout << "    work budget " << num(m["work_budget"]) << ": max work " << num(m["max_work"]) << ", "
                << num(m["budget_cuts"]) << " ticks cut; lag behind the unbudgeted proxy: max "
                << num(1e3 * m["max_lag_m"].get<double>(), 4) << " mm, " << num(m["max_lag_rad"].get<double>(), 4)
                << " rad, " << num(m["lag_ticks"]) << " ticks; behind max " << num(1e3 * m["max_behind_m"].get<double>(), 4)
                << " mm, " << num(m["max_behind_rad"].get<double>(), 4) << " rad\n";
    if (m.contains("held_samples"))
      std::cout << "    control: the same full solve with " << num(m["held_samples"]) << " device samples held, apart max "
                << num(1e3 * m["held_apart_max_m"].get<double>(), 4) << " mm, "
                << num(m["held_apart_max_rad"].get<double>(), 4) << " rad\n";
  }
  if (row.contains("ratio_paper_over_accelerated"))
    std::cout << "  paper / accelerated: mean " << num(row["ratio_paper_over_accelerated"]["mean"], 2)
              << "x, max " << num(row["ratio_paper_over_accelerated"]["max"], 2) << "x\n";
  if (row.contains("ratio_edges_over_accelerated")) {
    const auto& a = row["modes"]["accelerated"];
    const auto& e = row["modes"][kEdgesKey];
    const auto& q = row["ratio_edges_over_accelerated"];
    std::cout << "  with / without the edge test, accelerated, CPU time: mean " << num(e["cpu_mean_us"], 1) << " / "
              << num(a["cpu_mean_us"], 1) << " us = " << num(q["cpu_mean"], 2) << "x"
              << (q["within_1_2x"].get<bool>() ? " (within 1.2x)" : " (OVER 1.2x)") << ", p99.9 "
              << num(e["cpu_p99_9_us"], 1) << " / " << num(a["cpu_p99_9_us"], 1) << " us, max "
              << num(e["cpu_max_us"], 1) << " / " << num(a["cpu_max_us"], 1) << " us; crossings " << crossingsText(e)
              << " / " << crossingsText(a) << "\n";
    if (e.contains("edge_test_mean_us"))
      std::cout << "    of which the edge test itself: mean " << num(e["edge_test_mean_us"], 1)
                << " us; the rest of the tick: mean " << num(e["cpu_mean_without_edge_test_us"], 1) << " us = "
                << num(q["cpu_mean_without_edge_test"], 2) << "x the tick without the edge test\n";
    if (e.contains("edge_test_points")) {
      const auto points = [](const nlohmann::ordered_json& p) {
        return num(p["points_held"], 0) + " / " + num(p["points_boxed"], 0) + " / " + num(p["points_walked"], 0) + " (" +
               num(p["edges_walked"], 0) + " edges)";
      };
      const auto& p = e["edge_test_points"];
      const auto& worst = p["slowest_0_1_percent"];
      std::cout << "    its points per tick, held by certificates / cleared by a box query / walked: mean "
                << points(p["mean_per_tick"]) << "; its slowest " << num(worst["ticks"]) << " ticks ("
                << num(worst["edge_test_us"], 1) << " us): " << points(worst);
      if (worst.contains("us_per_edge_walked"))
        std::cout << ", " << num(worst["us_per_edge_walked"], 3) << " us per edge walked";
      std::cout << "\n";
    }
  }
  if (row.contains("ratio_exact_over_end_sample")) {
    const auto& a = row["modes"]["accelerated"];
    const auto& b = row["modes"][kBeforeKey];
    const auto& q = row["ratio_exact_over_end_sample"];
    std::cout << "  exact / end-sample (before), accelerated, CPU time: mean " << num(a["cpu_mean_us"], 1)
              << " / " << num(b["cpu_mean_us"], 1) << " us = " << num(q["cpu_mean"], 2) << "x"
              << (q["within_1_3x"].get<bool>() ? " (within 1.3x)" : " (OVER 1.3x)") << ", p99.9 "
              << num(a["cpu_p99_9_us"], 1) << " / " << num(b["cpu_p99_9_us"], 1) << " us, max "
              << num(a["cpu_max_us"], 1) << " / " << num(b["cpu_max_us"], 1) << " us; crossings "
              << crossingsText(a) << " / " << crossingsText(b) << "\n";
  }
}

/// One row of the table: `def` with the paper's tool (large 0) or with it resampled to 20,000
/// (1) or 50,000 points (2), loaded and run in the variants `variants_for` gives for the
/// tool's point count (the application's lanes depend on it). @return false when its data are
/// absent (`row` then says "skipped" and why); `series` gets its tick-time plot series.
bool runTableRow(const SceneDef& def, int large, const std::function<std::vector<Variant>(std::size_t)>& variants_for,
                 int ticks, int locations, double verify_step_voxels, bool verify_references, nlohmann::ordered_json& row,
                 std::vector<Series>& series) {
  // The paper's tool, then the same tool resampled to 20,000 and 50,000 points.
  const int large_points = large == 1 ? 20000 : 50000;
  row = rowHeader(def, large, large_points);
  runtime::SceneSpec spec;
  std::string why;
  if (!resolveSceneSpec(def, large ? large_points : def.paper_points, spec, why)) {
    std::cout << "bench table1: " << def.name << ": skipped: " << why << "\n";
    row["status"] = "skipped";
    row["reason"] = why;
    return false;
  }
  const auto t_load = std::chrono::steady_clock::now();
  const runtime::LoadedScene scene = runtime::loadScene(spec);
  const double load_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_load).count();
  // The large tools follow the same hand as the paper's tool, at the same speed: the first
  // quarter of the same trajectory (its first spot, whole), not the whole one in fewer ticks.
  const int run_ticks = large == 0 ? ticks : std::min(ticks, std::max(1000, ticks / 4));
  std::cout << "bench table1: " << row["name"].get<std::string>() << ": " << spec.volume.path << " ("
            << scene.volume.field->geometry().dims[0] << " x " << scene.volume.field->geometry().dims[1] << " x "
            << scene.volume.field->geometry().dims[2] << ", isovalue " << scene.isovalue << "), "
            << def.tool_label << ", " << scene.tool->point_shell.size() << " points (paper "
            << row["paper_points"].get<std::size_t>() << "); loaded in " << num(load_s, 1) << " s; "
            << run_ticks << " ticks ..." << std::endl;
  // The fit check, as the application runs it when a tool is chosen (its own warm-up and
  // calibration), judged against what this row then measures.
  const runtime::ToolFit fit = runtime::checkToolFit(runtime::LiveValues::initial(scene));
  row["tool_fit"] = nlohmann::ordered_json::parse(fit.toJson());
  // The report holds no nulls (a null would read as a non-finite number): no suggestion, no keys.
  for (const char* key : {"suggested_spacing_m", "suggested_points", "suggested_felt_gap_m"})
    if (row["tool_fit"][key].is_null()) row["tool_fit"].erase(key);
  std::cout << "  fit check: " << fit.summary() << " (a work unit " << num(fit.ns_per_work, 1) << " ns; warm-up "
            << num(fit.warmup_s, 2) << " s)" << std::endl;
  const auto t_run = std::chrono::steady_clock::now();
  runScene(scene, scene.tool, variants_for(scene.tool->point_shell.size()), run_ticks, ticks, locations, large ? 5 : 1,
           verify_step_voxels, verify_references, row, series);
  row["load_s"] = load_s;
  row["run_s"] = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_run).count();
  printRowResults(row);
  return true;
}

/// The Markdown's heading and the paragraph on how the run was made.
void writeMarkdownIntro(std::ostringstream& md, const nlohmann::ordered_json& report, const Table1Options& options,
                        int ticks, bool short_run, bool verified) {
  md << "## Table 1 (`volume-haptics bench table1" << (short_run ? " --short" : "") << "`)\n\n";
  md << "Run " << report["date_utc"].get<std::string>() << " on " << report["cpu_model"].get<std::string>() << " ("
     << cpuCount() << " CPUs, " << report["build"].get<std::string>() << "); the paper: "
     << report["paper_machine"].get<std::string>() << ". " << ticks
     << " ticks per scene and mode at a simulated 1 kHz, modes interleaved tick by tick; times are "
        "TickStats::exec_time_us (wall) of one tick on one core; the CPU-time column is the thread's CPU time "
        "around tick(), which a busy machine's preemption does not inflate. Every mode uses the exact segment "
        "test except \"accelerated (end-sample, before)\", the earlier end-sample test. "
     << (verified ? format("Crossings: ticks in which haptics::CrossingVerifier, sampling each shell point's path "
                           "over the tick every %g voxel (after the run, outside the timed section), found a point carried from "
                           "outside into the isosurface; \"edges N\": ticks at whose end the tool's surface "
                           "between its points (the point shell's neighbour edges, ends inset by epsilon, sampled "
                           "every %g voxel) was inside while free at the tick's start.",
                           options.verify_step_voxels, kEdgeStepFactor * options.verify_step_voxels)
                  : std::string("Crossings: not checked (--verify-step 0)."))
     << "\n\n";
}

/// The main table: one line per scene and mode (a skipped scene: one line with the reason).
void writeTimesTable(std::ostringstream& md, const nlohmann::ordered_json& rows) {
  md << "| scene | tool | points (paper) | mode | mean [us] | p50 | p99 | p99.9 | max [us] | paper mean (max) [us] | "
        "CPU time mean / max [us] | contacts mean / max | samples / tick | max penetration [mm] (epsilon) | "
        "crossings |\n";
  md << "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n";
  for (const auto& row : rows) {
    if (row["status"] != "ran") {
      md << "| " << row["name"].get<std::string>() << " | " << row["tool"].get<std::string>()
         << " | | skipped | " << row["reason"].get<std::string>() << " | | | | | | | | | | |\n";
      continue;
    }
    for (const auto& [mode, m] : row["modes"].items()) {
      const bool large = row["large_tool"].get<bool>();
      md << "| " << row["name"].get<std::string>() << " | " << row["tool"].get<std::string>() << " | "
         << row["points"].get<std::size_t>() << " (" << row["paper_points"].get<std::size_t>() << ") | "
         << m["label"].get<std::string>() << " | " << num(m["mean_us"], 1) << " | " << num(m["p50_us"], 1) << " | "
         << num(m["p99_us"], 1) << " | " << num(m["p99_9_us"], 1) << " | " << num(m["max_us"], 1) << " | "
         << (large ? std::string("-")
                   : num(row["paper"]["mean_us"]) + " (" + num(row["paper"]["max_us"]) + ")")
         << " | " << num(m["cpu_mean_us"], 1) << " / " << num(m["cpu_max_us"], 1) << " | " << num(m["mean_contacts"], 2) << " / " << num(m["max_contacts"]) << " | "
         << num(m["mean_volume_samples"]) << " | " << num(1e3 * m["max_penetration_m"].get<double>(), 4) << " ("
         << num(1e3 * row["epsilon_m"].get<double>(), 4) << ") | " << crossingsText(m) << " |\n";
    }
  }
}

/// The fit check (runtime::checkToolFit(), tool_fit.h) of each row against what the row
/// measured: its verdict on its warm-up beside the ticks the application's mode (the edge test,
/// budget and deadline) cut and how far it fell behind over the whole run.
void writeFitTable(std::ostringstream& md, const nlohmann::ordered_json& rows) {
  bool any = false;
  for (const auto& row : rows) any = any || (row["status"] == "ran" && row.contains("tool_fit"));
  if (!any) return;
  md << "\nThe fit check against the run: its verdict on its own warm-up (the calibrated cost of a work unit, the "
        "deadline as a work budget, the ticks it would cut and how far behind), beside what the run measured in "
        "the application's mode (edge test, budget, deadline):\n\n";
  md << "| scene | points | a work unit [ns] | warm-up: cut / ticks, behind [mm] | verdict | run: ticks cut, behind max [mm] |\n";
  md << "|---|---|---|---|---|---|\n";
  for (const auto& row : rows) {
    if (row["status"] != "ran" || !row.contains("tool_fit")) continue;
    const auto& f = row["tool_fit"];
    const char* key = row["modes"].contains("accelerated-edges") ? "accelerated-edges" : "accelerated";
    std::string run = "-";
    if (row["modes"].contains(key) && row["modes"][key].contains("budget_cuts")) {
      const auto& m = row["modes"][key];
      run = num(m["budget_cuts"]) + " of " + num(m["ticks"]) + ", " + num(1e3 * m["max_behind_m"].get<double>(), 3);
    }
    md << "| " << row["name"].get<std::string>() << " | " << row["points"].get<std::size_t>() << " | "
       << num(f["ns_per_work"], 1) << " | " << num(f["cut_ticks"]) << " / " << num(f["ticks"]) << ", "
       << num(1e3 * f["behind_max_m"].get<double>(), 3) << " | "
       << (f["fits"].get<bool>() ? std::string("fits")
                                 : "flagged" + (f.contains("suggested_spacing_m")
                                                    ? "; suggests " + num(1e3 * f["suggested_spacing_m"].get<double>(), 2) +
                                                          " mm (" + num(f["suggested_points"]) + " points)"
                                                    : std::string()))
       << " | " << run << " |\n";
  }
}

/// "Never behind": the full solve inside the 1 ms servo period, the budget and the deadline only
/// a last line. Targets: the paper's four scenes, 0 ticks cut and every tick under 1 ms; the
/// 20,000-point tools, lag <= 1 mm and <= 0.01 rad behind the full solve and every tick under
/// 1 ms; the 50,000-point tools reported. Adds each verdict to its row ("never_behind").
/// `load_threads`: the busy threads beside the run (--load). @return false (and writes nothing)
/// when no row ran the accelerated mode with a budget or a deadline.
bool writeNeverBehindTable(std::ostringstream& md, nlohmann::ordered_json& rows, int load_threads) {
  bool any_budget = false;
  for (const auto& row : rows)
    any_budget = any_budget || (row["status"] == "ran" && row["modes"].contains("accelerated") &&
                                row["modes"]["accelerated"].contains("budget_cuts"));
  if (!any_budget) return false;
  md << "\nNever behind: the accelerated mode as the application runs it (work budget, deadline, lanes) beside the "
        "same without budget or deadline (the full solve). Wall and thread CPU time per tick (the caller's thread; "
        "the lanes' threads run beside it), the ticks the budget or the deadline cut and the lag behind the full "
        "solve's proxy on the same device samples (how far apart the two proxies are), with how much farther from "
        "the device the budgeted proxy is (behind: the coupling spring's extra stretch) and, as the control, how far "
        "the full solve moves from itself when one device sample in " +
            format("%d", kHeldSampleEvery) +
            " is held (the previous one repeated, as when a USB packet is lost; no budget anywhere): a quasi-static "
            "proxy's path depends on its history, and once the two proxies took different sides of a choice (which "
            "contact holds, which way a wedged tool slides) they stay apart although neither is late. Targets: the "
            "paper's scenes 0 ticks cut and max < 1000 us; 20,000-point tools lag <= 1 mm and <= 0.01 rad and max < "
            "1000 us; 50,000-point tools reported"
     << (load_threads > 0 ? format("; %d busy threads ran beside it (--load)", load_threads) : std::string())
     << ":\n\n";
  md << "| scene | points | lanes | budget / deadline [us] | wall mean / p99.9 / max [us] | CPU mean / p99.9 / max [us] "
        "| full solve wall p99.9 / max, CPU max [us] | ticks cut (by the deadline) | lag max [mm] / [rad] | behind max "
        "[mm] / [rad] | control: full solve, one sample held, apart max [mm] / [rad] | target | met |\n"
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|\n";
  // The accelerated mode, then (with --edge-test) the same with the edge test between shell
  // points against its own full solve.
  const std::pair<const char*, const char*> kModes[] = {{"accelerated", kUnbudgetedKey},
                                                        {kEdgesKey, kEdgesUnbudgetedKey}};
  for (auto& row : rows) {
    for (const auto& [key, full_key] : kModes) {
      if (row["status"] != "ran" || !row["modes"].contains(key)) continue;
      const auto& a = row["modes"][key];
      if (!a.contains("budget_cuts")) continue;
      const bool edges = std::string(key) == kEdgesKey;
      const bool large = row["large_tool"].get<bool>();
      const bool fifty = row["points"].get<std::size_t>() > 30000;
      const double mx = std::max(a["max_us"].get<double>(), a["cpu_max_us"].get<double>());
      const double cuts = a["budget_cuts"], lag_m = a["max_lag_m"], lag_rad = a["max_lag_rad"];
      std::string full = "-", control = "-";
      if (row["modes"].contains(full_key)) {
        const auto& u = row["modes"][full_key];
        full = num(u["p99_9_us"], 1) + " / " + num(u["max_us"], 1) + ", " + num(u["cpu_max_us"], 1);
        if (u.contains("held_apart_max_m"))
          control = num(1e3 * u["held_apart_max_m"].get<double>(), 3) + " / " + num(u["held_apart_max_rad"], 4) +
                    " (" + num(u["held_samples"]) + " held)";
      }
      const std::string behind = a.contains("max_behind_m") ? num(1e3 * a["max_behind_m"].get<double>(), 3) + " / " +
                                                                   num(a["max_behind_rad"], 4)
                                                             : std::string("-");
      const std::string target = !large ? "0 cut, max < 1000" : fifty ? "reported" : "lag <= 1 mm, 0.01 rad; max < 1000";
      const bool met = !large ? (cuts == 0.0 && mx < 1000.0)
                       : fifty ? true
                               : (lag_m <= 1e-3 && lag_rad <= 0.01 && mx < 1000.0);
      md << "| " << row["name"].get<std::string>() << (edges ? ", edge test" : "") << " | "
         << row["points"].get<std::size_t>() << " | " << num(a["lanes"]) << " | " << num(a["work_budget"]) << " / "
         << (a.contains("deadline_us") ? num(a["deadline_us"]) : std::string("-")) << " | " << num(a["mean_us"], 1)
         << " / " << num(a["p99_9_us"], 1) << " / " << num(a["max_us"], 1) << " | " << num(a["cpu_mean_us"], 1)
         << " / " << num(a["cpu_p99_9_us"], 1) << " / " << num(a["cpu_max_us"], 1) << " | " << full << " | "
         << num(cuts) << " (" << num(a["deadline_cuts"]) << ") | " << num(1e3 * lag_m, 3) << " / " << num(lag_rad, 4)
         << " | " << behind << " | " << control << " | " << target << " | " << (fifty ? "-" : met ? "yes" : "NO") << " |\n";
      // Last: a new key moves row's members (ordered_map), which `a` refers into.
      row[edges ? "never_behind_edges" : "never_behind"] = {{"target", target}, {"met", met}};
    }
  }
  return true;
}

/// Scaling: the full solve on each lane count of --lanes-sweep, side by side in one run (nothing
/// without --lanes-sweep).
void writeScalingTable(std::ostringstream& md, const nlohmann::ordered_json& rows, const Table1Options& options) {
  if (options.lane_sweep.empty()) return;
  md << "\nScaling: the accelerated mode without budget or deadline on 1 to N lanes (cores), interleaved tick by "
        "tick in one run on "
     << cpuCount() << " CPUs"
     << (options.load > 0 ? format(" with %d busy threads beside it", options.load) : std::string())
     << "; speed-up = the first lane count's time / this one's; paper / this = the paper mode's mean in the same "
        "run / this mean (where the paper mode ran):\n\n";
  md << "| scene | points | lanes | wall mean / p99.9 / max [us] | ticks over 1 ms | speed-up mean / max | lane "
        "efficiency | paper / this (mean) |\n"
        "|---|---|---|---|---|---|---|---|\n";
  for (const auto& row : rows) {
    if (row["status"] != "ran") continue;
    const std::string first_key = "accelerated-lanes-" + std::to_string(options.lane_sweep.front());
    if (!row["modes"].contains(first_key)) continue;
    const auto& f = row["modes"][first_key];
    for (const int n : options.lane_sweep) {
      const auto& m = row["modes"]["accelerated-lanes-" + std::to_string(n)];
      const double mean = m["mean_us"], mx = m["max_us"];
      md << "| " << row["name"].get<std::string>() << " | " << row["points"].get<std::size_t>() << " | " << n << " | "
         << num(mean, 1) << " / " << num(m["p99_9_us"], 1) << " / " << num(mx, 1) << " | " << num(m["ticks_over_1ms"])
         << " | " << num(f["mean_us"].get<double>() / mean, 2) << "x / " << num(f["max_us"].get<double>() / mx, 2)
         << "x | " << (m.contains("lane_efficiency") ? num(m["lane_efficiency"], 2) : std::string("-")) << " | "
         << (row["modes"].contains("paper") ? num(row["modes"]["paper"]["mean_us"].get<double>() / mean, 1) + "x"
                                            : std::string("-"))
         << " |\n";
    }
  }
}

/// Speed-up of the accelerated path over the paper's, per scene where both modes ran.
void writeSpeedupTable(std::ostringstream& md, const nlohmann::ordered_json& rows) {
  bool any_ratio = false;
  for (const auto& row : rows) any_ratio = any_ratio || row.contains("ratio_paper_over_accelerated");
  if (!any_ratio) return;
  md << "\nSpeed-up of the accelerated path (paper-mode time / accelerated-mode time, same run):\n\n";
  md << "| scene | mean | p99 | max | volume samples | max proxy difference between modes [mm] |\n|---|---|---|---|---|---|\n";
  for (const auto& row : rows) {
    if (!row.contains("ratio_paper_over_accelerated")) continue;
    const auto& r = row["ratio_paper_over_accelerated"];
    md << "| " << row["name"].get<std::string>() << " | " << num(r["mean"], 2) << "x | " << num(r["p99"], 2)
       << "x | " << num(r["max"], 2) << "x | " << num(r["volume_samples"], 2) << "x | "
       << num(1e3 * row["max_proxy_difference_between_modes_m"].get<double>(), 4) << " |\n";
  }
}

/// The exact segment test (after) against the earlier end sample (before), per scene where the
/// "before" column ran, and the 1.3x target's verdict.
void writeBeforeAfterTable(std::ostringstream& md, const nlohmann::ordered_json& rows) {
  bool any_before = false;
  for (const auto& row : rows) any_before = any_before || row.contains("ratio_exact_over_end_sample");
  if (!any_before) return;
  int met = 0, compared = 0;
  std::string over;
  md << "\nBefore and after the exact segment test, accelerated mode, same run, thread CPU time per "
        "tick; ratio: exact / end-sample:\n\n";
  md << "| scene | end-sample (before) mean / p99.9 / max [us] | exact (after) mean / p99.9 / max [us] | "
        "mean ratio | cells / tick (exact) | crossings before / after | max proxy difference [mm] |\n"
        "|---|---|---|---|---|---|---|\n";
  for (const auto& row : rows) {
    if (!row.contains("ratio_exact_over_end_sample")) continue;
    const auto& a = row["modes"]["accelerated"];
    const auto& b = row["modes"][kBeforeKey];
    const auto& q = row["ratio_exact_over_end_sample"];
    ++compared;
    if (q["within_1_3x"].get<bool>()) ++met;
    else over += (over.empty() ? "" : ", ") + row["name"].get<std::string>() + " " + num(q["cpu_mean"], 2) + "x";
    md << "| " << row["name"].get<std::string>() << " | " << num(b["cpu_mean_us"], 1) << " / "
       << num(b["cpu_p99_9_us"], 1) << " / " << num(b["cpu_max_us"], 1) << " | " << num(a["cpu_mean_us"], 1)
       << " / " << num(a["cpu_p99_9_us"], 1) << " / " << num(a["cpu_max_us"], 1) << " | "
       << num(q["cpu_mean"], 2) << "x | " << num(a["mean_cells"], 1) << " | " << crossingsText(b) << " / "
       << crossingsText(a) << " | " << num(1e3 * row["max_proxy_difference_exact_vs_end_sample_m"].get<double>(), 4)
       << " |\n";
  }
  md << "\nExact segment test target: the accelerated mode's mean with the exact test within 1.3x of the "
        "end sample's on every scene: met on "
     << met << " of " << compared << (over.empty() ? std::string("") : " (over: " + over + ")") << ".\n";
}

/// The PNG charts: each scene's tick times, and the mean and worst tick per scene of the paper's
/// tools beside the paper's figures. @return the files written (in `out`).
std::vector<std::string> table1Plots(const fs::path& out,
                                     const std::vector<std::pair<std::string, std::vector<Series>>>& scene_plots,
                                     const nlohmann::ordered_json& rows, const std::vector<std::string>& mode_names,
                                     const std::vector<std::string>& mode_labels) {
  std::vector<std::string> plots;
  for (const auto& [name, series] : scene_plots) {
    std::string file = "table1_" + lower(name) + ".png";
    std::replace(file.begin(), file.end(), ' ', '_');
    file.erase(std::remove_if(file.begin(), file.end(), [](char c) { return c == '(' || c == ')'; }), file.end());
    if (plotXY(out / file, name + ": tick time (max per bin)", "tick", "exec time [us]", series, false, true))
      plots.push_back(file);
  }
  std::vector<std::string> cats;
  std::vector<Series> mean_series{{"paper (2.67 GHz i7)", {}, {}}}, max_series{{"paper (2.67 GHz i7)", {}, {}}};
  for (std::size_t k = 0; k < mode_labels.size(); ++k) {
    const std::string name = "ours, " + mode_labels[k] + (mode_names[k] == kBeforeKey ? "" : " mode");
    mean_series.push_back({name, {}, {}});
    max_series.push_back({name, {}, {}});
  }
  for (const auto& row : rows) {
    if (row["status"] != "ran" || row["large_tool"].get<bool>()) continue;
    cats.push_back(row["name"].get<std::string>());
    mean_series[0].y.push_back(row["paper"]["mean_us"]);
    max_series[0].y.push_back(row["paper"]["max_us"]);
    for (std::size_t k = 0; k < mode_names.size(); ++k) {
      mean_series[k + 1].y.push_back(row["modes"][mode_names[k]]["mean_us"]);
      max_series[k + 1].y.push_back(row["modes"][mode_names[k]]["max_us"]);
    }
  }
  if (!cats.empty()) {
    if (plotBars(out / "table1_mean.png", "Mean tick time per scene", cats, "mean [us]", mean_series, true))
      plots.push_back("table1_mean.png");
    if (plotBars(out / "table1_max.png", "Worst tick per scene", cats, "max [us]", max_series, true))
      plots.push_back("table1_max.png");
  }
  return plots;
}

}  // namespace

fs::path runTable1(const Table1Options& options) {
  const fs::path out = outputDir(options.common, "table1");
  const bool short_run = options.common.short_run;
  const int ticks = options.ticks > 0 ? options.ticks : (short_run ? 1000 : 20000);
  const int locations = short_run ? 1 : 4;
  if (!(options.verify_step_voxels >= 0.0) || !std::isfinite(options.verify_step_voxels))
    throw std::runtime_error("the crossing-check step must be >= 0 voxels (0: off)");
  const bool verified = options.verify_step_voxels > 0.0;
  // The accelerated modes' lanes: --lanes, else the application's for each tool
  // (runtime::solverLanesFor: one lane below 800 points); `lanes` is the most of those.
  const auto t_start = std::chrono::steady_clock::now();
  const int lanes = options.lanes > 0 ? options.lanes : runtime::defaultSolverLanes();
  const double deadline_us = options.deadline_us < 0.0 ? runtime::solverDeadline_us(1000.0) : options.deadline_us;
  if (options.load < 0 || options.load > 256) throw std::runtime_error("--load must be in [0, 256] threads");
  // A loaded machine: busy threads beside the run until it ends.
  BusyLoad load(options.load);
  const std::vector<Variant> variants = table1Variants(options, lanes, deadline_us);
  const std::vector<SceneDef> defs = selectScenes(options.scene);
  // One set of solver threads for every mode and lane count (the largest asked for first): pools
  // per lane count would all spin between their interleaved ticks and outnumber the cores.
  int most_lanes = 1;
  for (const Variant& v : variants) most_lanes = std::max(most_lanes, v.lanes);
  const std::shared_ptr<haptics::WorkerPool> solver_threads =
      most_lanes > 1 ? haptics::WorkerPool::shared(most_lanes) : nullptr;

  nlohmann::ordered_json report = reportHeader("table1", short_run);
  report["ticks_per_run"] = ticks;
  report["load_threads"] = options.load;
  report["solver_lanes"] = lanes;
  report["deadline_us"] = deadline_us;
  report["servo_rate_Hz"] = 1000.0;
  std::vector<std::string> mode_names, mode_labels;
  for (const Variant& v : variants) {
    mode_names.push_back(v.key);
    mode_labels.push_back(v.label);
  }
  report["modes"] = mode_names;
  report["mode_labels"] = mode_labels;
  report["verify_step_voxels"] = options.verify_step_voxels;
  report["verify_references"] = options.verify_references;
  report["paper_machine"] = "2.67 GHz Intel Core i7 (Chan et al., WHC 2011, Table 1)";
  nlohmann::ordered_json rows = nlohmann::ordered_json::array();
  std::vector<std::pair<std::string, std::vector<Series>>> scene_plots;

  std::cout << "bench table1: " << ticks << " ticks per scene and mode (" << mode_names.size()
            << " modes, interleaved tick by tick) on " << cpuModel() << "; crossing check "
            << (verified ? format("every tick at %g voxel", options.verify_step_voxels) : std::string("off")) << "\n";
  const auto variants_for = [&](std::size_t points) {
    return options.lanes > 0 ? variants : table1Variants(options, runtime::solverLanesFor(points), deadline_us);
  };
  for (const SceneDef& def : defs) {
    for (int large = 0; large < 3; ++large) {
      if (large && (short_run || !options.large_tools || (def.name != "Bone" && def.name != "Engine"))) continue;
      if (large == 2 && !options.tools_50k && options.tool_rows != "50000") continue;
      if (!options.tool_rows.empty() && options.tool_rows != Table1Options::kToolRows[static_cast<std::size_t>(large)])
        continue;
      nlohmann::ordered_json row;
      std::vector<Series> series;
      if (runTableRow(def, large, variants_for, ticks, locations, options.verify_step_voxels, options.verify_references,
                      row, series))
        scene_plots.emplace_back(row["name"].get<std::string>(), std::move(series));
      rows.push_back(row);
    }
  }
  report["scenes"] = rows;
  report["wall_s"] = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
  std::cout << "bench table1: the rows took " << num(report["wall_s"].get<double>() / 60.0, 1) << " min\n";

  std::ostringstream md;
  writeMarkdownIntro(md, report, options, ticks, short_run, verified);
  writeTimesTable(md, rows);
  if (writeNeverBehindTable(md, rows, options.load)) report["scenes"] = rows;  // with the never_behind verdicts
  writeScalingTable(md, rows, options);
  writeSpeedupTable(md, rows);
  writeBeforeAfterTable(md, rows);
  writeFitTable(md, rows);
  md << "\nSpeed targets: mean at most a tenth of the paper's (Bunny 21, Engine 78, Hole 41, Bone 26 us), max "
        "under 250 us; a 20,000-point tool on Bone and Engine: mean under 200 us, max under 1000 us.\n";

  std::vector<std::string> plots;
  if (options.common.plots) plots = table1Plots(out, scene_plots, rows, mode_names, mode_labels);
  writeReport(out, "table1", report, md, plots);
  return out;
}

std::optional<runtime::SceneSpec> table1SceneSpec(const std::string& name, std::size_t point_count, std::string& why) {
  const std::vector<SceneDef> defs = selectScenes(name);
  runtime::SceneSpec spec;
  if (name.empty()) {
    why = "no scene named";
    return std::nullopt;
  }
  if (defs.size() != 1 || !resolveSceneSpec(defs.front(), point_count > 0 ? point_count : defs.front().paper_points,
                                           spec, why))
    return std::nullopt;
  return spec;
}

}  // namespace vh::bench
