#include "vh/haptics/haptic_renderer.h"
#include "vh/haptics/penetration.h"

#include <cmath>
#include <limits>
#include <string>

#include <gtest/gtest.h>

#include "allocation_guard.h"
#include "test_tools.h"

namespace vh::haptics {
namespace {

// Largest depth of any proxy point inside the isosurface, (F - s) / |grad F|.
double maxPenetration(const ScalarVolume& vol, const ToolModel& tool, const Pose& X_WP, double s) {
  return maxPenetration_m(vol, tool.point_shell, X_WP, s);
}

struct PlaneScene {
  std::shared_ptr<const ScalarVolume> volume =
      std::make_shared<ScalarVolume>(datasets::makePlaneVolume(test::grid1mm(), Eigen::Vector3d::UnitZ(), 0.0));
  // A flat-bottomed box tool 10 x 10 x 4 mm, its bottom face at z = -2 mm in T.
  std::shared_ptr<const ToolModel> tool = test::meshTool(datasets::makeBoxMesh({0.005, 0.005, 0.002}), 1e-3);
};

RendererOptions inMode(DetectionMode mode) {
  RendererOptions o;
  o.detection_mode = mode;
  return o;
}

// Every test runs in both detection modes: the paper's path and the accelerated one.
class HapticRendererModes : public ::testing::TestWithParam<DetectionMode> {};
INSTANTIATE_TEST_SUITE_P(Modes, HapticRendererModes, ::testing::Values(DetectionMode::kPaper, DetectionMode::kAccelerated),
                         [](const ::testing::TestParamInfo<DetectionMode>& p) { return std::string(toString(p.param)); });

TEST_P(HapticRendererModes, FreeMotionReachesTheDeviceWithZeroForce) {
  PlaneScene scene;
  RendererOptions o = inMode(GetParam());
  o.max_travel_per_tick_m = 0.0;  // the paper's: no velocity limit
  HapticRenderer r(scene.volume, scene.tool, o, Pose::FromTranslation({0, 0, 0.01}), 0.0);
  Pose X_WD = Pose::FromTranslation({0.003, -0.002, 0.012});
  X_WD.R_AB = Eigen::Quaterniond(Eigen::AngleAxisd(0.4, Eigen::Vector3d::UnitZ()));
  const TickOutput out = r.tick(X_WD, 0.0);
  EXPECT_LT((out.X_WP.p_AB_m - X_WD.p_AB_m).norm(), 1e-12);
  EXPECT_LT(out.force_W_N.norm(), 1e-9);
  EXPECT_EQ(out.stats.contacts, 0);
  EXPECT_DOUBLE_EQ(out.stats.time_of_contact, 1.0);
}

// The velocity limit (section 2.3's alternative): in free space no shell point moves
// farther than max_travel_per_tick_m in a tick (checked point by point), and the proxy reaches
// the device after ceil(travel / limit) ticks.
TEST_P(HapticRendererModes, VelocityLimitBoundsEveryPointsTravelPerTick) {
  PlaneScene scene;
  RendererOptions o = inMode(GetParam());
  o.max_travel_per_tick_m = 0.001;
  HapticRenderer r(scene.volume, scene.tool, o, Pose::FromTranslation({0, 0, 0.01}), 0.0);
  Pose X_WD = Pose::FromTranslation({0.003, -0.002, 0.012});
  X_WD.R_AB = Eigen::Quaterniond(Eigen::AngleAxisd(0.4, Eigen::Vector3d::UnitZ()));
  int ticks = 0;
  double max_travel_m = 0.0;
  for (; ticks < 100 && (r.proxyPose().p_AB_m - X_WD.p_AB_m).norm() > 1e-12; ++ticks) {
    const Pose before = r.proxyPose();
    const TickOutput out = r.tick(X_WD, 0.0);
    for (const auto& p : scene.tool->point_shell.points_T_m())
      max_travel_m = std::max(max_travel_m, (out.X_WP * p - before * p).norm());
  }
  EXPECT_LE(max_travel_m, 0.001 * (1.0 + 1e-9));
  EXPECT_GT(max_travel_m, 0.0009);  // the limit binds
  EXPECT_GT(ticks, 2);
  EXPECT_LT(ticks, 100);
  EXPECT_LT(r.tick(X_WD, 0.0).force_W_N.norm(), 1e-9);
}

// In contact the limit is max_travel_in_contact_per_tick_m (2 mm): the box pressed on the plane,
// then the device 30 mm away along it. Every tick that starts in contact moves no shell point
// farther than 2 mm (checked point by point) and the limit binds; with the in-contact limit off,
// the same slide takes the free-space limit's 4 mm steps.
TEST_P(HapticRendererModes, InContactTheVelocityLimitIsTheContactOne) {
  PlaneScene scene;
  const auto slide = [&](double in_contact_m) {
    RendererOptions o = inMode(GetParam());
    o.max_travel_in_contact_per_tick_m = in_contact_m;
    HapticRenderer r(scene.volume, scene.tool, o, Pose::FromTranslation({0, 0, 0.003}), 0.0);
    for (int i = 0; i < 30; ++i) r.tick(Pose::FromTranslation({0, 0, -0.001}), 0.0);  // press
    EXPECT_GE(r.tick(Pose::FromTranslation({0, 0, -0.001}), 0.0).stats.contacts, 1);
    const Pose X_WD = Pose::FromTranslation({0.030, 0.0, -0.001});
    double max_travel_m = 0.0;
    for (int tick = 0; tick < 40; ++tick) {
      const Pose before = r.proxyPose();
      const TickOutput out = r.tick(X_WD, 0.0);
      EXPECT_GE(out.stats.contacts, 1) << "tick " << tick << ": the box left the plane";
      for (const auto& p : scene.tool->point_shell.points_T_m())
        max_travel_m = std::max(max_travel_m, (out.X_WP * p - before * p).norm());
    }
    EXPECT_NEAR(r.proxyPose().p_AB_m.x(), 0.030, 1e-6) << "the proxy reaches the device's projection";
    return max_travel_m;
  };
  const double in_contact_m = RendererOptions{}.max_travel_in_contact_per_tick_m;
  ASSERT_EQ(in_contact_m, 0.002);
  const double limited_m = slide(in_contact_m);
  EXPECT_LE(limited_m, in_contact_m * (1.0 + 1e-9));
  EXPECT_GT(limited_m, 0.9 * in_contact_m);  // the limit binds
  EXPECT_GT(slide(0.0), 0.9 * RendererOptions{}.max_travel_per_tick_m) << "off: the free-space limit";
}

TEST_P(HapticRendererModes, PressingIntoAPlaneGivesKTimesDepth) {
  PlaneScene scene;
  RendererOptions o = inMode(GetParam());
  o.epsilon_m = 0.01e-3;  // tight tolerance so the stand-off stays well under 1 % of 5 mm
  o.gains.linear_N_per_m = 1000.0;
  HapticRenderer r(scene.volume, scene.tool, o, Pose::FromTranslation({0, 0, 0.01}), 0.0);
  // Device lowered until the box's bottom face is 5 mm below the plane, then held.
  TickOutput out;
  for (int i = 0; i <= 100; ++i) {
    const double z = 0.01 - (0.01 - (0.002 - 0.005)) * std::min(1.0, i / 50.0);
    out = r.tick(Pose::FromTranslation({0, 0, z}), 0.0);
    ASSERT_LE(maxPenetration(*scene.volume, *scene.tool, out.X_WP, 0.0), r.epsilon_m());
  }
  const double expected = 1000.0 * 0.005;
  EXPECT_NEAR(out.force_W_N.z(), expected, 0.01 * expected);
  EXPECT_NEAR(out.force_W_N.head<2>().norm(), 0.0, 1e-6);
  EXPECT_GE(out.stats.contacts, 3);
  EXPECT_LT(out.torque_W_Nm.norm(), 1e-3);
}

TEST_P(HapticRendererModes, SlidingFollowsTheDeviceProjectionOntoThePlane) {
  PlaneScene scene;
  HapticRenderer r(scene.volume, scene.tool, inMode(GetParam()), Pose::FromTranslation({0, 0, 0.003}), 0.0);
  TickOutput out;
  for (int i = 0; i < 30; ++i) out = r.tick(Pose::FromTranslation({0, 0, -0.001}), 0.0);  // press
  for (int i = 0; i <= 300; ++i) {
    const Eigen::Vector3d device(0.01 * i / 300.0, -0.005 * i / 300.0, -0.001);
    out = r.tick(Pose::FromTranslation(device), 0.0);
    ASSERT_LE(maxPenetration(*scene.volume, *scene.tool, out.X_WP, 0.0), r.epsilon_m());
  }
  for (int i = 0; i < 20; ++i) out = r.tick(Pose::FromTranslation({0.01, -0.005, -0.001}), 0.0);
  // Friction-free: the proxy ends above the device, resting on the plane.
  EXPECT_NEAR(out.X_WP.p_AB_m.x(), 0.01, 1e-6);
  EXPECT_NEAR(out.X_WP.p_AB_m.y(), -0.005, 1e-6);
  EXPECT_NEAR(out.X_WP.p_AB_m.z(), 0.002, r.epsilon_m() + 1e-9);
  EXPECT_NEAR(out.force_W_N.head<2>().norm(), 0.0, 1e-3);
}

TEST_P(HapticRendererModes, ThinPlateIsNotTunnelledThroughAtOneMetrePerSecond) {
  auto vol = std::make_shared<ScalarVolume>(datasets::makeThinPlateVolume(test::grid1mm()));
  const double s = datasets::builtinIsovalue("thin-plate");
  const auto tool = test::pointTool();
  const double z_plate = vol->geometry().origin_W_m.z() + 32e-3;
  HapticRenderer r(vol, tool, inMode(GetParam()), Pose::FromTranslation({0, 0, z_plate + 0.01}), s);
  for (int i = 0; i < 40; ++i) {  // 1 mm per tick at 1 kHz = 1 m/s, ending 30 mm below the plate
    const TickOutput out = r.tick(Pose::FromTranslation({0, 0, z_plate + 0.01 - 0.001 * i}), s);
    ASSERT_GT(out.X_WP.p_AB_m.z(), z_plate) << "tick " << i;
  }
}

TEST_P(HapticRendererModes, BadDeviceInputGivesZeroForceAndRecovers) {
  PlaneScene scene;
  HapticRenderer r(scene.volume, scene.tool, inMode(GetParam()), Pose::FromTranslation({0, 0, 0.003}), 0.0);
  TickOutput out = r.tick(Pose::FromTranslation({0, 0, -0.001}), 0.0);
  const Pose before = out.X_WP;
  const double nan = std::numeric_limits<double>::quiet_NaN();
  Pose bad_nan = Pose::FromTranslation({nan, 0, 0});
  Pose bad_quat = Pose::FromTranslation({0, 0, 0});
  bad_quat.R_AB.coeffs() << 0.5, 0.5, 0.5, 0.9;
  Pose far = Pose::FromTranslation({1000.0, 0, 0});
  for (const Pose& bad : {bad_nan, bad_quat, far}) {
    out = r.tick(bad, 0.0);
    EXPECT_TRUE(out.stats.bad_input);
    EXPECT_EQ(out.force_W_N, Eigen::Vector3d::Zero());
    EXPECT_EQ(out.X_WP.p_AB_m, before.p_AB_m);
  }
  EXPECT_EQ(r.badInputCount(), 3);
  out = r.tick(Pose::FromTranslation({0, 0, -0.001}), 0.0);
  EXPECT_FALSE(out.stats.bad_input);
  EXPECT_GT(out.force_W_N.z(), 0.0);
  EXPECT_TRUE(out.force_W_N.allFinite());
}

TEST_P(HapticRendererModes, IsovalueChangeInContactCausesNoForceSpike) {
  auto vol = std::make_shared<ScalarVolume>(datasets::makePlaneVolume(test::grid1mm(), Eigen::Vector3d::UnitZ(), 0.0));
  const auto tool = test::meshTool(datasets::makeSphereMesh(0.004, 3), 1e-3);
  HapticRenderer r(vol, tool, inMode(GetParam()), Pose::FromTranslation({0, 0, 0.006}), 0.0);
  TickOutput out;
  for (int i = 0; i < 20; ++i) out = r.tick(Pose::FromTranslation({0, 0, 0.002}), 0.0);
  const double felt = out.force_W_N.norm();
  ASSERT_GT(felt, 0.5);
  // Raise the surface by 3 mm (F = 1000 (0 - z) mm > -3 inside): the proxy is swallowed.
  for (int i = 0; i < 20; ++i) {
    out = r.tick(Pose::FromTranslation({0, 0, 0.002}), -3.0);
    EXPECT_TRUE(out.force_W_N.allFinite());
    EXPECT_LE(out.force_W_N.norm(), felt + 1e-9);
  }
  // Lower it below the original: contact is lost, no spike either.
  for (int i = 0; i < 20; ++i) {
    out = r.tick(Pose::FromTranslation({0, 0, 0.002}), 3.0);
    EXPECT_LE(out.force_W_N.norm(), felt + 1e-9);
  }
  // Move out and back in at the original isovalue: contact works again.
  for (int i = 0; i < 20; ++i) out = r.tick(Pose::FromTranslation({0, 0, 0.02}), 0.0);
  EXPECT_LT(out.force_W_N.norm(), 1e-9);
  for (int i = 0; i < 40; ++i) out = r.tick(Pose::FromTranslation({0, 0, 0.002}), 0.0);
  EXPECT_NEAR(out.force_W_N.norm(), felt, 0.05 * felt);
  EXPECT_LE(maxPenetration(*vol, *tool, out.X_WP, 0.0), r.epsilon_m());
}

TEST_P(HapticRendererModes, ProxyComesToRestWhenTheDeviceIsStill) {
  // A point-sampled ball pressed onto a sphere: rotating it rolls other points into contact, the
  // hardest case for settling (a stand-off of epsilon / 2 made it cycle with a 28-tick period).
  auto vol = std::make_shared<ScalarVolume>(datasets::makeBuiltinVolume("sphere"));
  const auto tool = test::meshTool(datasets::makeBuiltinTool("sphere"), 1.5e-3);
  HapticRenderer r(vol, tool, inMode(GetParam()), Pose::FromTranslation({0, 0, 0.03}), 0.0);
  const Pose device = Pose::FromTranslation({0.0, 0.0, 0.022});
  TickOutput out;
  for (int i = 0; i < 400; ++i) out = r.tick(device, 0.0);
  const Pose rest = out.X_WP;
  for (int i = 0; i < 1000; ++i) {
    out = r.tick(device, 0.0);
    ASSERT_LT((out.X_WP.p_AB_m - rest.p_AB_m).norm(), 1e-9) << "tick " << i;
    ASSERT_LT(rest.R_AB.angularDistance(out.X_WP.R_AB), 1e-9) << "tick " << i;
  }
  EXPECT_GT(out.stats.contacts, 0);
  EXPECT_LE(maxPenetration(*vol, *tool, out.X_WP, 0.0), r.epsilon_m());
}

// The drill swung over the ball, half the ticks at another isovalue: no tick allocates.
void expectTicksDoNotAllocate(const RendererOptions& options, double spacing_m, int lanes = 1) {
  auto vol = std::make_shared<ScalarVolume>(datasets::makeSphereVolume(test::grid1mm(), Eigen::Vector3d::Zero(), 0.015));
  const auto tool = test::meshTool(datasets::makeBuiltinTool("drill"), spacing_m);
  HapticRenderer r(vol, tool, options, Pose::FromTranslation({0, 0, 0.02}), 0.0);
  ASSERT_EQ(r.solverLanes(), lanes);
  Pose X_WD = Pose::FromTranslation({0.002, 0.0, 0.012});
  X_WD.R_AB = Eigen::Quaterniond(Eigen::AngleAxisd(0.2, Eigen::Vector3d::UnitX()));
  r.tick(X_WD, 0.0);  // warm-up
  test::AllocationGuard guard;
  int contacts = 0;
  for (int i = 0; i < 200; ++i) {
    X_WD.p_AB_m.x() = 0.002 * std::sin(i * 0.05);
    contacts = std::max(contacts, r.tick(X_WD, i < 100 ? 0.0 : -1.0).stats.contacts);
  }
  EXPECT_EQ(guard.count(), 0u);
  EXPECT_GT(contacts, 0);
}

TEST_P(HapticRendererModes, TickDoesNotAllocate) { expectTicksDoNotAllocate(inMode(GetParam()), 1.5e-3); }

// On several lanes the tree's nodes are dealt to them again before every sweep, on the servo
// thread (CollisionDetector::rebalanceLanes()), and the edge test is forked too.
TEST(HapticRenderer, TickOnSeveralLanesWithTheEdgeTestDoesNotAllocate) {
  RendererOptions o = inMode(DetectionMode::kAccelerated);
  o.solver_lanes = 3;
  o.edge_test = true;
  expectTicksDoNotAllocate(o, 0.7e-3, 3);
}

TEST_P(HapticRendererModes, ReportsStatistics) {
  PlaneScene scene;
  RendererOptions o = inMode(GetParam());
  o.work_budget = 0;  // the whole tick: with a budget, contacts may come on a later tick
  HapticRenderer r(scene.volume, scene.tool, o, Pose::FromTranslation({0, 0, 0.003}), 0.0);
  const TickOutput out = r.tick(Pose::FromTranslation({0, 0, -0.002}), 0.0);
  EXPECT_GT(out.stats.volume_samples, 0);
  EXPECT_GT(out.stats.exec_time_us, 0.0);
  EXPECT_LT(out.stats.time_of_contact, 1.0);
  EXPECT_GT(out.stats.contacts, 0);
  // One sweep at least (steps 3-4), at most three (two re-solves after refined stuck contacts).
  EXPECT_GE(out.stats.sweeps, 1);
  EXPECT_LE(out.stats.sweeps, 3);
  EXPECT_EQ(out.stats.edge_us, 0.0) << "no edge test: none of its time";
  // A rejected device sample runs none.
  const double nan = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(r.tick(Pose::FromTranslation({nan, 0.0, 0.0}), 0.0).stats.sweeps, 0);
  // With the edge test, its own time is part of the tick's.
  o.edge_test = 1;
  HapticRenderer with_edges(scene.volume, scene.tool, o, Pose::FromTranslation({0, 0, 0.003}), 0.0);
  const TickOutput edged = with_edges.tick(Pose::FromTranslation({0, 0, -0.002}), 0.0);
  EXPECT_GT(edged.stats.edge_us, 0.0);
  EXPECT_LE(edged.stats.edge_us, edged.stats.exec_time_us);
}

TEST(HapticRenderer, ATickThatOnlyResumesACutSweepRunsNoNewSweep) {
  // A work budget too small for one sweep: the first tick sweeps and is cut; the next ones go on
  // with the same sweep (CollisionDetector::resumeSweep()) and solve nothing new.
  PlaneScene scene;
  RendererOptions o;
  o.detection_mode = DetectionMode::kAccelerated;
  o.work_budget = 20;
  o.deadline_us = 0.0;
  HapticRenderer r(scene.volume, scene.tool, o, Pose::FromTranslation({0, 0, 0.003}), 0.0);
  const TickOutput first = r.tick(Pose::FromTranslation({0, 0, -0.002}), 0.0);
  ASSERT_TRUE(first.stats.budget_cut);
  EXPECT_EQ(first.stats.sweeps, 1);
  const TickOutput second = r.tick(Pose::FromTranslation({0, 0, -0.002}), 0.0);
  EXPECT_EQ(second.stats.sweeps, 0);
}

}  // namespace
}  // namespace vh::haptics
