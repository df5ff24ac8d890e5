// Tests of vh/runtime/runner.h (the headless runner) on synthetic volumes with generated
// push-and-slide trajectories: the proxy never penetrates deeper than epsilon, no tick produces a
// non-finite value, contacts and forces happen, and the proxy follows the device back into free
// space, and the crossing check (haptics::CrossingVerifier after every tick) finds no crossing.
// Also the penetration measure itself, the report, determinism through the CSV, errors.
#include "vh/runtime/runner.h"

#include <cmath>
#include <cstdio>
#include <fstream>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "runtime_test_support.h"
#include "vh/datasets/synthetic.h"
#include "vh/runtime/placement.h"

namespace vh::runtime {
namespace {

namespace fs = std::filesystem;
using haptics::Pose;

const LoadedScene& blockScene() {
  static const LoadedScene scene = [] {
    SceneSpec spec = builtinBlockWithHoleScene();
    spec.tool.point_spacing_m = 0.001;
    return loadScene(spec);
  }();
  return scene;
}

LoadedScene blockSceneWith(const std::string& tool) {
  SceneSpec spec = builtinBlockWithHoleScene();
  spec.tool.mesh = tool;
  return loadScene(spec);
}

/// The checks every replay must pass; `what` names the run in failure messages.
void expectSoundRun(const RunReport& r, const Trajectory& trajectory, const std::string& what) {
  SCOPED_TRACE(what + ": " + r.summary());
  EXPECT_EQ(r.ticks, static_cast<std::uint64_t>(std::floor(trajectory.duration_s() * 1000.0 + 1e-9)) + 1);
  EXPECT_EQ(r.nan_ticks, 0u);
  EXPECT_EQ(r.bad_device_samples, 0u);
  EXPECT_EQ(r.initial_points_inside, 0);
  EXPECT_GT(r.epsilon_m, 0.0);
  EXPECT_LT(r.epsilon_m, r.feature_size_m);
  EXPECT_LE(r.max_penetration_m, r.epsilon_m) << "deepest at tick " << r.max_penetration_tick;
  EXPECT_EQ(r.ticks_penetrating, 0u);
  // The default run checks every tick's proxy motion for crossings: none.
  EXPECT_TRUE(r.crossingsChecked());
  EXPECT_EQ(r.verify_step_voxels, RunOptions{}.verify_step_voxels);
  EXPECT_EQ(r.crossings, 0) << "first at tick " << r.first_crossing_tick;
  EXPECT_EQ(r.crossing_points, 0);
  EXPECT_EQ(r.first_crossing_tick, -1);
  // The tool's surface between its points is checked too (counted, not promised: the edge test
  // is off by default).
  EXPECT_GE(r.edge_crossings, 0);
  EXPECT_NE(r.summary().find(", edges "), std::string::npos);
  EXPECT_GE(r.verify_s, 0.0);
  EXPECT_LE(r.verify_s, r.total_s);
  EXPECT_GT(r.max_contacts, 0);
  EXPECT_GT(r.ticks_in_contact, 500u);  // in contact through most of the push and the slide
  EXPECT_GT(r.max_force_N, 1.0);        // the device is pushed 5 mm past the surface
  // Retracted into free space: the proxy follows the device and the force vanishes.
  EXPECT_LT(r.final_proxy_device_distance_m, 1e-4);
  EXPECT_LT(r.final_force_N, 0.1);
  EXPECT_GT(r.mean_us, 0.0);
  EXPECT_LE(r.p50_us, r.p99_us);
  EXPECT_LE(r.p99_us, r.max_us);
  // The work budget and its price against the unbudgeted run of the same samples.
  EXPECT_EQ(r.work_budget, haptics::RendererOptions::kDefaultWorkBudget);
  EXPECT_LE(r.max_work, r.work_budget + 64 * 12 + 300);
  EXPECT_GE(r.lag_ticks, 0);
  EXPECT_LE(static_cast<std::uint64_t>(r.lag_ticks), r.ticks);
  EXPECT_GE(r.max_lag_m, 0.0);
  EXPECT_GE(r.max_lag_rad, 0.0);
  // Behind: the extra distance to the device, never more than how far apart the proxies are
  // (the triangle inequality), and not negative (0 on a tick where they agree).
  EXPECT_GE(r.max_behind_m, 0.0);
  EXPECT_GE(r.max_behind_rad, 0.0);
  EXPECT_LE(r.max_behind_m, r.max_lag_m + 1e-12);
  EXPECT_LE(r.max_behind_rad, r.max_lag_rad + 1e-12);
  if (r.budget_cuts == 0) {
    EXPECT_EQ(r.lag_ticks, 0) << "no tick cut, yet the proxy differs from the unbudgeted one";
  }
  EXPECT_NE(r.summary().find("work budget"), std::string::npos) << r.summary();
}

TEST(Runner, NearestRankPercentileIsTheValueAtRankCeilQN) {
  std::vector<double> sorted;
  for (int i = 1; i <= 200; ++i) sorted.push_back(0.5 * i);  // 0.5, 1.0, ..., 100.0
  EXPECT_EQ(nearestRankPercentile(sorted, 0.0), 0.5);      // rank 1
  EXPECT_EQ(nearestRankPercentile(sorted, 0.50), 50.0);    // rank 100
  EXPECT_EQ(nearestRankPercentile(sorted, 0.99), 99.0);    // rank 198
  EXPECT_EQ(nearestRankPercentile(sorted, 0.999), 100.0);  // rank ceil(199.8) = 200
  EXPECT_EQ(nearestRankPercentile(sorted, 1.0), 100.0);
  EXPECT_EQ(nearestRankPercentile(std::vector<double>{}, 0.5), 0.0);
  EXPECT_EQ(nearestRankPercentile(std::vector<double>{7.0}, 0.99), 7.0);
}

TEST(Runner, ProxyLagSeparatesApartFromBehind) {
  // The device at the origin, turned 0.3 rad about z. Reference proxy 1 mm along +x and turned
  // 0.1 rad; the budgeted proxy 3 mm along -x and turned 0.6 rad: 4 mm and 0.5 rad apart, and
  // 2 mm and 0.1 rad farther from the device than the reference (behind). Then a budgeted proxy
  // as far from the device as the reference, on the other side: apart, but not behind.
  const auto pose = [](double x_m, double angle_rad) {
    haptics::Pose X;
    X.p_AB_m = Eigen::Vector3d(x_m, 0.0, 0.0);
    X.R_AB = Eigen::Quaterniond(Eigen::AngleAxisd(angle_rad, Eigen::Vector3d::UnitZ()));
    return X;
  };
  const haptics::Pose X_WD = pose(0.0, 0.3);
  ProxyLag lag;
  lag.add(pose(-3e-3, 0.6), pose(1e-3, 0.1), X_WD);
  EXPECT_NEAR(lag.max_m, 4e-3, 1e-12);
  EXPECT_NEAR(lag.max_rad, 0.5, 1e-9);
  EXPECT_NEAR(lag.max_behind_m, 2e-3, 1e-12);
  EXPECT_NEAR(lag.max_behind_rad, 0.1, 1e-9);
  EXPECT_EQ(lag.ticks, 1);
  ProxyLag mirrored;
  mirrored.add(pose(-1e-3, 0.5), pose(1e-3, 0.1), X_WD);
  EXPECT_NEAR(mirrored.max_m, 2e-3, 1e-12);
  EXPECT_NEAR(mirrored.max_rad, 0.4, 1e-9);
  EXPECT_NEAR(mirrored.max_behind_m, 0.0, 1e-12);
  EXPECT_NEAR(mirrored.max_behind_rad, 0.0, 1e-9);
  // Closer to the device than the reference: never negative (the maximum starts at 0).
  ProxyLag ahead;
  ahead.add(pose(0.5e-3, 0.3), pose(1e-3, 0.1), X_WD);
  EXPECT_EQ(ahead.max_behind_m, 0.0);
  EXPECT_EQ(ahead.max_behind_rad, 0.0);
}

TEST(Runner, PegPushedOntoTheBlockAndSlidAlongIt) {
  const LoadedScene& scene = blockScene();
  const auto& field = *scene.volume.field;
  // Between the hole (radius 8 mm) and the block's edge (24 mm): the peg (7.5 mm) lands flat on
  // the top face, the paper's pathological case of many coplanar contacts.
  Pose start = poseAboveVolume(field, scene.tool->point_shell, Eigen::Quaterniond::Identity(), 0.005);
  start.p_AB_m.x() = 0.015;
  PushSlideOptions push;
  push.slide_dir_W = Eigen::Vector3d::UnitY();
  const PushSlidePlan plan = makePushSlideTrajectory(field, scene.tool->point_shell, scene.isovalue, start, push);
  EXPECT_NEAR(plan.X_WD_contact.p_AB_m.z(), datasets::kBlockHalfHeight_m, 2 * field.featureSize_m());
  const RunReport r = runHeadless(scene, plan.trajectory);
  expectSoundRun(r, plan.trajectory, "peg on the block");
  EXPECT_GE(r.max_contacts, 3);  // a flat face rests on at least three points
  // Pressed 5 mm in with 1000 N/m: about 5 N.
  EXPECT_NEAR(r.max_force_N, 5.0, 1.0);
}

TEST(Runner, ProbeSlidesOverTheHoleEdgeAndDropsIn) {
  const LoadedScene scene = blockSceneWith("builtin:probe");
  const auto& field = *scene.volume.field;
  Pose start = poseAboveVolume(field, scene.tool->point_shell, Eigen::Quaterniond::Identity(), 0.005);
  start.p_AB_m.x() = 0.014;
  PushSlideOptions push;
  push.slide_dir_W = -Eigen::Vector3d::UnitX();  // from x = 14 mm to -6 mm, across the hole's rim
  const PushSlidePlan plan = makePushSlideTrajectory(field, scene.tool->point_shell, scene.isovalue, start, push);
  const RunReport r = runHeadless(scene, plan.trajectory);
  expectSoundRun(r, plan.trajectory, "probe over the hole");
}

TEST(Runner, SlideWithRotationOnASphere) {
  SceneSpec spec;
  spec.volume.path = "builtin:sphere";
  spec.tool.mesh = "builtin:drill";
  spec.tool.point_spacing_m = 0.001;
  const LoadedScene scene = loadScene(spec);
  const auto& field = *scene.volume.field;
  const Pose start = poseAboveVolume(field, scene.tool->point_shell, Eigen::Quaterniond::Identity(), 0.002);
  PushSlideOptions push;
  push.slide_rotation_rad = 0.3;  // tilt the drill while sliding over the curved surface
  const PushSlidePlan plan = makePushSlideTrajectory(field, scene.tool->point_shell, scene.isovalue, start, push);
  const RunReport r = runHeadless(scene, plan.trajectory);
  expectSoundRun(r, plan.trajectory, "rotating drill on the sphere");
  EXPECT_GT(r.max_torque_Nm, 0.0);
}

TEST(Runner, ProbeFollowsTheDeviceAcrossASphere) {
  // resources/scenes/sphere-probe.json: frictionless sliding over a convex surface. With the
  // device 5 mm inside, the coupling force stays near k * 5 mm unless the proxy lags behind.
  const SceneSpec spec = loadSceneFile(test::sourceDir() / "resources" / "scenes" / "sphere-probe.json");
  const LoadedScene scene = loadScene(spec);
  const auto& field = *scene.volume.field;
  const Pose start = poseAboveVolume(field, scene.tool->point_shell, scene.X_WT_initial.R_AB, 0.01);
  PushSlideOptions push;
  const PushSlidePlan plan = makePushSlideTrajectory(field, scene.tool->point_shell, scene.isovalue, start, push);
  RunOptions options;
  options.trace_csv = test::scratchDir() / "trace.csv";
  const RunReport r = runHeadless(scene, plan.trajectory, options);
  expectSoundRun(r, plan.trajectory, "probe across the sphere (trace: " + options.trace_csv.string() + ")");
  EXPECT_LT(r.max_force_N, spec.gains.linear_N_per_m * (push.push_depth_m + 0.001))
      << "the proxy lagged behind the device (stuck on the surface); trace: " << options.trace_csv;
}

TEST(Runner, ReplayThroughTheCsvIsIdenticalAndTheReportIsComplete) {
  const fs::path dir = test::scratchDir();
  const fs::path scene_file = test::writeText(dir / "plane.json", R"({
    "volume": {"path": "builtin:plane"},
    "tool": {"mesh": "builtin:sphere", "point_spacing_m": 0.001},
    "coupling": {"linear_N_per_m": 800}
  })");
  const SceneSpec spec = loadSceneFile(scene_file);
  const LoadedScene scene = loadScene(spec);
  const Pose start = poseAboveVolume(*scene.volume.field, scene.tool->point_shell, Eigen::Quaterniond::Identity(), 0.002);
  PushSlideOptions push;
  push.slide_time_s = 1.0;
  const PushSlidePlan plan =
      makePushSlideTrajectory(*scene.volume.field, scene.tool->point_shell, scene.isovalue, start, push);
  const fs::path csv = dir / "trajectory.csv";
  writeTrajectoryCsv(plan.trajectory, csv);

  RunOptions options;
  options.trace_csv = dir / "trace.csv";
  const RunReport in_process = runHeadless(scene, plan.trajectory, options);
  const RunReport from_files = runHeadless(spec, csv);
  expectSoundRun(from_files, plan.trajectory, "ball on a plane via CSV");
  EXPECT_EQ(from_files.ticks, in_process.ticks);
  EXPECT_EQ(from_files.max_contacts, in_process.max_contacts);
  EXPECT_EQ(from_files.mean_contacts, in_process.mean_contacts);
  EXPECT_EQ(from_files.max_force_N, in_process.max_force_N);
  EXPECT_EQ(from_files.max_penetration_m, in_process.max_penetration_m);
  EXPECT_EQ(from_files.trajectory, csv.string());
  EXPECT_NEAR(from_files.max_force_N, 800.0 * push.push_depth_m, 0.2 * 800.0 * push.push_depth_m);

  const fs::path report_file = dir / "report.json";
  writeRunReport(from_files, report_file);
  std::ifstream in(report_file);
  const nlohmann::json j = nlohmann::json::parse(in);
  for (const char* key : {"ticks", "mean_us", "p50_us", "p99_us", "max_us", "max_contacts", "mean_contacts",
                          "max_penetration_m", "nan_ticks", "max_force_N", "epsilon_m", "point_count", "volume_dims",
                          "isovalue", "bad_device_samples", "crossings", "crossing_points", "first_crossing_tick",
                          "edge_crossings", "first_edge_crossing_tick", "verify_step_voxels", "verify_s"}) {
    EXPECT_TRUE(j.contains(key)) << key;
  }
  ASSERT_TRUE(j["crossings"].is_number_integer());
  EXPECT_EQ(j["crossings"].get<std::int64_t>(), 0);
  EXPECT_EQ(j["crossing_points"].get<std::int64_t>(), 0);
  EXPECT_EQ(j["first_crossing_tick"].get<std::int64_t>(), -1);
  EXPECT_DOUBLE_EQ(j["verify_step_voxels"].get<double>(), 0.01);
  EXPECT_NE(from_files.summary().find("crossings 0 (checked at 0.01 voxel)"), std::string::npos)
      << from_files.summary();
  EXPECT_EQ(j["ticks"].get<std::uint64_t>(), from_files.ticks);
  EXPECT_EQ(j["volume_dims"], nlohmann::json({64, 64, 64}));
  EXPECT_EQ(j["point_count"].get<std::size_t>(), scene.tool->point_shell.size());
  EXPECT_DOUBLE_EQ(j["max_penetration_m"].get<double>(), from_files.max_penetration_m);
  EXPECT_NE(from_files.summary().find("ticks " + std::to_string(from_files.ticks)), std::string::npos);
}

TEST(Runner, CrossingCheckOffIsReportedAsNotCheckedNotAsZero) {
  const LoadedScene& scene = blockScene();
  const auto& field = *scene.volume.field;
  Pose start = poseAboveVolume(field, scene.tool->point_shell, Eigen::Quaterniond::Identity(), 0.005);
  start.p_AB_m.x() = 0.015;
  PushSlideOptions push;
  push.slide_time_s = 0.5;
  const PushSlidePlan plan = makePushSlideTrajectory(field, scene.tool->point_shell, scene.isovalue, start, push);
  RunOptions options;
  options.verify_step_voxels = 0.0;
  const RunReport r = runHeadless(scene, plan.trajectory, options);
  EXPECT_FALSE(r.crossingsChecked());
  EXPECT_EQ(r.verify_step_voxels, 0.0);
  EXPECT_EQ(r.crossings, -1);
  EXPECT_EQ(r.crossing_points, -1);
  EXPECT_EQ(r.first_crossing_tick, -1);
  EXPECT_EQ(r.edge_crossings, -1);
  EXPECT_EQ(r.verify_s, 0.0);
  EXPECT_NE(r.summary().find("crossings not checked"), std::string::npos) << r.summary();
  const nlohmann::json j = nlohmann::json::parse(r.toJson());
  EXPECT_TRUE(j["crossings"].is_null());
  EXPECT_TRUE(j["crossing_points"].is_null());
  EXPECT_TRUE(j["first_crossing_tick"].is_null());
  EXPECT_TRUE(j["edge_crossings"].is_null());
  EXPECT_EQ(j["verify_step_voxels"].get<double>(), 0.0);
  // The lag reference ran (the default); without it the lag is null, not 0.
  EXPECT_TRUE(j["lag_ticks"].is_number());
  EXPECT_TRUE(j["max_behind_m"].is_number());
  EXPECT_TRUE(j["max_behind_rad"].is_number());
  options.lag_reference = false;
  const nlohmann::json j2 = nlohmann::json::parse(runHeadless(scene, plan.trajectory, options).toJson());
  EXPECT_TRUE(j2["lag_ticks"].is_null());
  EXPECT_TRUE(j2["max_lag_m"].is_null());
  EXPECT_TRUE(j2["max_behind_m"].is_null());
  EXPECT_EQ(j2["work_budget"].get<std::int64_t>(), haptics::RendererOptions::kDefaultWorkBudget);

  options.verify_step_voxels = -1.0;
  EXPECT_THROW(runHeadless(scene, plan.trajectory, options), std::invalid_argument);
  // A step so fine that the check would run for hours (1e-12 voxel ran past 65 s) is refused
  // before anything is set up, naming the finest step accepted.
  options.verify_step_voxels = 1e-12;
  try {
    (void)runHeadless(scene, plan.trajectory, options);
    ADD_FAILURE() << "a crossing-check step of 1e-12 voxel was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("at least 0.001 voxel"), std::string::npos) << e.what();
  }
}

TEST(Runner, PenetrationMeasureIsTheDepthBelowAPlane) {
  // F = 1000 (0 - z) [mm]: |grad F| = 1000 per metre, so the first-order depth is exact.
  const haptics::ScalarVolume plane = datasets::makeBuiltinVolume("plane");
  haptics::PointShellOptions options;
  options.spacing_m = 0.001;
  const haptics::PointShell shell = haptics::makePointShell(datasets::makeBuiltinTool("sphere"), options);
  double lowest = 0.0;
  for (const auto& p : shell.points_T_m()) lowest = std::min(lowest, p.z());
  const Pose above = Pose::FromTranslation({0, 0, 0.010});
  EXPECT_EQ(haptics::maxPenetration_m(plane, shell, above, 0.0), 0.0);
  EXPECT_EQ(countPointsInside(plane, shell, above, 0.0), 0);
  int deepest = -2;
  const Pose sunk = Pose::FromTranslation({0, 0, -lowest - 0.002});  // lowest point 2 mm below z = 0
  EXPECT_NEAR(haptics::maxPenetration_m(plane, shell, sunk, 0.0, &deepest), 0.002, 1e-9);
  ASSERT_GE(deepest, 0);
  EXPECT_DOUBLE_EQ(shell.points_T_m()[static_cast<std::size_t>(deepest)].z(), lowest);
  EXPECT_GT(countPointsInside(plane, shell, sunk, 0.0), 0);
}

TEST(Runner, ErrorsNameTheFile) {
  const SceneSpec spec = builtinBlockWithHoleScene();
  VH_EXPECT_THROW_WITH(runHeadless(spec, "/no/such/trajectory.csv"), std::runtime_error, "/no/such/trajectory.csv");
  const fs::path bad = test::writeText(test::scratchDir() / "bad.csv", "0,0,0,0,1,0,0,0\n1,0,0\n");
  VH_EXPECT_THROW_WITH(runHeadless(spec, bad), std::runtime_error, bad.string() + ":2:");
  VH_EXPECT_THROW_WITH(writeRunReport(RunReport{}, "/no/such/folder/report.json"), std::runtime_error,
                       "/no/such/folder/report.json");
}

TEST(Runner, TrajectoriesLongerThanADayAreRefusedBeforeAnyTick) {
  const LoadedScene& scene = blockScene();
  const Pose X_WD = poseAboveVolume(*scene.volume.field, scene.tool->point_shell, Eigen::Quaterniond::Identity(), 0.01);
  // 1e19 s overflowed the tick count (one tick ran), 1e9 s asked for 8 TB of tick times
  // (std::bad_alloc), 1e6 s ran 10^9 ticks: each is refused with its duration and the limit.
  const auto still = [&](double end_s) {
    TrajectorySample a, b;
    a.X_WD = X_WD;
    b.X_WD = X_WD;
    b.t_s = end_s;
    return Trajectory({a, b});
  };
  for (const double end_s : {1e19, 1e9, 1e6, 86400.5}) {
    const Trajectory t = still(end_s);
    try {
      runHeadless(scene, t);
      ADD_FAILURE() << end_s << " s was run";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find("at most 86400 s (24 h)"), std::string::npos) << e.what();
      char duration[32];
      std::snprintf(duration, sizeof duration, "lasts %g s", end_s);
      EXPECT_NE(std::string(e.what()).find(duration), std::string::npos) << e.what();
    }
  }
  // A short one still runs (the limit is not the cause of the refusals above).
  const RunReport r = runHeadless(scene, still(0.01));
  EXPECT_EQ(r.ticks, 11u);
}

TEST(Runner, ForcesThatOverflowAreCountedAsNonFinite) {
  SceneSpec spec = builtinBlockWithHoleScene();
  spec.tool.point_spacing_m = 0.001;
  spec.gains.linear_N_per_m = 1e300;  // past the scene file's limit: only the API reaches it
  const LoadedScene scene = loadScene(spec);
  const auto& field = *scene.volume.field;
  Pose start = poseAboveVolume(field, scene.tool->point_shell, Eigen::Quaterniond::Identity(), 0.005);
  start.p_AB_m.x() = 0.015;  // onto the top face, beside the hole
  PushSlideOptions push;
  push.slide_dir_W = Eigen::Vector3d::UnitY();
  const PushSlidePlan plan = makePushSlideTrajectory(field, scene.tool->point_shell, scene.isovalue, start, push);
  RunOptions options;
  options.verify_step_voxels = 0.0;
  options.lag_reference = false;
  const RunReport r = runHeadless(scene, plan.trajectory, options);
  // In contact, |F| = 1e300 N/m x millimetres overflows to inf: those ticks are non-finite (what
  // `run --check` fails on), and the maximum force stays a number.
  EXPECT_GT(r.nan_ticks, 0u) << r.summary();
  EXPECT_TRUE(std::isfinite(r.max_force_N)) << r.summary();
  EXPECT_EQ(r.summary().find("inf N"), std::string::npos) << r.summary();
}

}  // namespace
}  // namespace vh::runtime
