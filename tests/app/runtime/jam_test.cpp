// Never stuck: the GUI sequence that held the drill's proxy at the skull of the shared head
// phantom (the CHAI3D drill at the probe's automatic spacing; touch from the default view, keys
// Page Up / Down / Left, then Home), replayed headless with the keys' own moves; the jam detector
// on a contrived jam; Reset Device and a restart landing at a legal pose.
#include <cmath>
#include <filesystem>
#include <numbers>
#include <optional>
#include <string>

#include <gtest/gtest.h>

#include "vh/haptics/haptic_renderer.h"
#include "vh/haptics/tool_model.h"
#include "vh/io/volume_loader.h"
#include "vh/runtime/drilling.h"
#include "vh/runtime/jam_detector.h"
#include "vh/runtime/placement.h"
#include "vh/runtime/runner.h"
#include "vh/runtime/trajectory.h"
#include "vh/runtime/scene.h"
#include "vh/runtime/servo_factory.h"

namespace vh::runtime {
namespace {

using Eigen::Vector3d;
using haptics::Pose;
namespace fs = std::filesystem;

const fs::path kShared = VH_SHARED_DATASETS_DIR;

// The jam detector counts a run of stuck ticks longer than kJamTicks, once.
TEST(JamDetector, CountsOnlyRunsLongerThanTheThreshold) {
  JamDetector jam;
  for (int i = 0; i < kJamTicks; ++i) EXPECT_FALSE(jam.update(true));
  EXPECT_TRUE(jam.update(true));
  EXPECT_TRUE(jam.update(true));
  EXPECT_FALSE(jam.update(false));
  EXPECT_EQ(jam.jams(), 1u);
  EXPECT_EQ(jam.jamTicks(), 2u);
  const Vector3d cm(0, 0, 0.01);
  const Pose P = Pose::FromTranslation({0, 0, 0});
  const Pose far = Pose::FromTranslation({0, 0, 0.05});
  EXPECT_TRUE(JamDetector::candidate(P, P, far, cm, 2)) << "in contact, 50 mm away, still";
  EXPECT_FALSE(JamDetector::candidate(P, P, far, cm, 0)) << "out of contact";
  EXPECT_FALSE(JamDetector::candidate(P, Pose::FromTranslation({0, 0, 0.001}), far, cm, 2)) << "it moved 1 mm closer";
  EXPECT_FALSE(JamDetector::candidate(P, P, Pose::FromTranslation({0, 0, 0.005}), cm, 2)) << "5 mm: within reach";
}

// touchSurface's approach, as the GUI's (ui/src/devices/device_input.cpp) computes it: the
// device from outside the volume along dir_W until the tool meets the surface, depth_m deeper.
std::optional<Pose> touchTarget(const LiveValues& live, const Pose& X_WD, const Vector3d& dir_W, double depth_m) {
  const haptics::ScalarVolume& field = *live.hapticField();
  const Vector3d lo = field.boundsMin_W_m(), hi = field.boundsMax_W_m(), centre = 0.5 * (lo + hi);
  const double extent = (hi - lo).norm();
  const Vector3d p_TCm = live.tool->mass.p_TCm_m;
  double reach = 0.0;
  for (const Vector3d& p : live.tool->point_shell.points_T_m()) reach = std::max(reach, (p - p_TCm).norm());
  const double outside = 0.5 * extent + reach + std::max(0.005, 0.05 * extent);
  Pose from = X_WD;
  from.p_AB_m = centre - outside * dir_W - from.R_AB * p_TCm;
  const auto free_m = firstContactDistance(field, live.tool->point_shell, from, dir_W, outside + 0.5 * extent + reach,
                                           live.hapticIsovalue(), 0.05 * field.featureSize_m());
  if (!free_m) return std::nullopt;
  from.p_AB_m += (*free_m + depth_m) * dir_W;
  return from;
}

TEST(NeverStuck, TheDrillFollowsTheDeviceOffTheSkullAfterTheGuiSequence) {
  const fs::path phantom = kShared / "ct/philips-head-phantom-bone";
  const fs::path drill_mesh = kShared / "meshes/drill/drill.stl";
  if (!fs::exists(phantom) || !fs::exists(drill_mesh)) GTEST_SKIP() << "needs " << phantom << " and " << drill_mesh;
  const LoadedScene scene = loadScene(sceneForVolume(phantom));
  LiveValues live = LiveValues::initial(scene);
  // Mesh = Drill (CHAI3D, 10 cm, shaft up) at the spacing the Haptics panel shows (the probe's).
  haptics::PointShellOptions shell;
  shell.spacing_m = live.pointSpacing_m();
  live.tool = std::make_shared<const haptics::ToolModel>(haptics::makeToolModel(io::loadMesh(drill_mesh, 0.00044), shell));
  const Eigen::Quaterniond xUp(Eigen::AngleAxisd(-0.5 * std::numbers::pi, Vector3d::UnitY()));
  live.X_WT_initial = defaultInitialPose(*live.hapticField(), live.tool->point_shell, xUp, live.hapticIsovalue());
  // The default view: from the front turned 30 degrees to the patient's right and 25 up (LPS).
  const double az = -30.0 * std::numbers::pi / 180.0, el = 25.0 * std::numbers::pi / 180.0;
  const Vector3d forward = -Vector3d(std::sin(az) * std::cos(el), -std::cos(az) * std::cos(el), std::sin(el));
  const Vector3d right = forward.cross(Vector3d::UnitZ()).normalized();
  const Vector3d up = right.cross(forward).normalized();
  const auto& f = *live.hapticField();
  const double key_m = std::clamp((f.boundsMax_W_m() - f.boundsMin_W_m()).norm() / 200.0, 0.5e-3, 5e-3);

  // Ctrl+T, then Ctrl+B (the threads rebuilt with the drill where the proxy is, the device there).
  const std::optional<Pose> touch = touchTarget(live, live.X_WT_initial, forward, 0.003);
  ASSERT_TRUE(touch.has_value());
  haptics::RendererOptions options;
  DrillingRenderer first = makeServoRenderer(live, options, *touch, 1000.0);
  Pose X_WD = *touch;
  X_WD.p_AB_m -= 0.003 * forward;  // from just outside, as the touch path ends
  first.renderer->resetProxy(X_WD);
  for (int i = 0; i < 1500; ++i) first.renderer->tick(*touch, live.hapticIsovalue());
  live.drill = DrillSpec{};
  live.drill->on = true;
  DrillingRenderer d = makeServoRenderer(live, options, first.renderer->proxyPose(), 1000.0);
  haptics::HapticRenderer& r = *d.renderer;
  X_WD = r.proxyPose();
  JamDetector jam;
  const auto run = [&](int ticks) {
    for (int i = 0; i < ticks; ++i) {
      const Pose before = r.proxyPose();
      const haptics::TickOutput out = r.tick(X_WD, live.hapticIsovalue());
      d.drill->step(r, out);
      const bool stuck = JamDetector::candidate(before, r.proxyPose(), X_WD, live.tool->mass.p_TCm_m,
                                                static_cast<int>(r.contacts().size())) &&
                         countPointsInside(r.volume(), live.tool->point_shell, X_WD, r.feltIsovalue()) == 0;
      jam.update(stuck);
    }
  };
  run(1000);
  // Page Up x16 with arrow keys, a second between keys.
  for (const char key : std::string("PPPPDDPPPPDDPPPPLLPPPP")) {
    X_WD.p_AB_m += key == 'P' ? Vector3d(key_m * forward) : key == 'D' ? Vector3d(-key_m * up) : Vector3d(-key_m * right);
    run(1000);
  }
  EXPECT_EQ(jam.jams(), 0u) << "pressing into bone is not a jam";
  // Home: the device back to its starting pose above the head, in free space.
  X_WD = live.X_WT_initial;
  ASSERT_EQ(countPointsInside(r.volume(), live.tool->point_shell, X_WD, r.feltIsovalue()), 0);
  run(3000);
  const Vector3d gap = X_WD * live.tool->mass.p_TCm_m - r.proxyPose() * live.tool->mass.p_TCm_m;
  EXPECT_LT(gap.norm(), 1e-3) << "the proxy follows the device off the skull (it stayed held at "
                              << 1e3 * gap.norm() << " mm, " << gap.norm() * 1000.0 << " N at 1000 N/m)";
  EXPECT_EQ(jam.jams(), 0u) << jam.jamTicks() << " jammed ticks";
}

// The drill pushed 4 mm into the head phantom's skull and slid 20 mm through it, with the edge
// test on (the default): a lift after an edge stop that went into the edge contact the pruning
// had dropped was stopped at once, tick after tick, and held the drill in its cavity while the
// device slid and retracted (25 N, 891 ticks jammed). The oracle is the device's own path: once
// it has retracted to the start height, the proxy must be near it and the force small.
TEST(NeverStuck, TheDrillSlidesThroughBoneAndRetractsWithTheEdgeTestOn) {
  const fs::path phantom = kShared / "ct/philips-head-phantom-bone";
  const fs::path drill_mesh = kShared / "meshes/drill/drill.stl";
  if (!fs::exists(phantom) || !fs::exists(drill_mesh)) GTEST_SKIP() << "needs " << phantom << " and " << drill_mesh;
  const LoadedScene scene = loadScene(parseScene(R"({
    "volume": {"path": ")" + phantom.string() + R"(", "isovalue": 400},
    "tool": {"mesh": ")" + drill_mesh.string() + R"(", "scale_to_m": 0.00044, "point_spacing_m": 0.001,
             "initial_pose": {"q_wxyz": [0.7071067811865476, 0, -0.7071067811865476, 0]}},
    "device": {"kind": "simulated"}, "drill": {"on": true}})", "drill.json", "."));
  ASSERT_TRUE(scene.spec.tool.edge_test) << "the default this test is about";
  PushSlideOptions push;
  push.push_depth_m = 0.004;
  const Pose start = poseAboveVolume(*scene.hapticField(), scene.tool->point_shell, scene.X_WT_initial.R_AB, 0.01);
  const PushSlidePlan plan =
      makePushSlideTrajectory(*scene.hapticField(), scene.tool->point_shell, scene.hapticIsovalue(), start, push);
  RunOptions options;
  options.verify_step_voxels = 0.0;
  const RunReport report = runHeadless(scene, plan.trajectory, options);
  ASSERT_TRUE(report.drill.has_value());
  EXPECT_GT(report.drill->removed_mm3, 1.0) << "the burr cut";
  EXPECT_EQ(report.jams, 0u) << report.jam_ticks << " jammed ticks from tick " << report.first_jam_tick;
  EXPECT_LT(report.final_force_N, 1.0) << "retracted to the start height, the device is in free space";
  EXPECT_LT(report.final_proxy_device_distance_m, 1e-3);
  EXPECT_LT(report.max_force_N, 12.0) << "the device's push is 4 mm (4 N at 1000 N/m) plus the slide's cutting";
  EXPECT_LT(report.lag_ticks, 0) << "no lag figure: a reference without the burr parts from the proxy by the cavity";
}

// Reset Device's and a restart's placement: a pose with no shell point inside, the device's own
// when it is free, else the fallback, else above the volume.
TEST(NeverStuck, LegalPoseNearIsFreeAndNearTheDevice) {
  const LoadedScene scene = loadScene(parseScene(
      R"({"volume": {"path": "builtin:sphere"}, "tool": {"mesh": "builtin:sphere", "point_spacing_m": 0.001}})", "s.json", "."));
  const haptics::ScalarVolume& field = *scene.hapticField();
  const haptics::PointShell& shell = scene.tool->point_shell;
  const double s = scene.hapticIsovalue();
  const Pose free = Pose::FromTranslation({0, 0, 0.027});     // above the 20 mm sphere
  const Pose inside = Pose::FromTranslation({0, 0, 0.0});     // at its centre
  const Pose beside = Pose::FromTranslation({0.027, 0, 0.0});
  ASSERT_EQ(countPointsInside(field, shell, free, s), 0);
  ASSERT_GT(countPointsInside(field, shell, inside, s), 0);
  EXPECT_TRUE(legalPoseNear(field, shell, free, s).p_AB_m.isApprox(free.p_AB_m));
  EXPECT_TRUE(legalPoseNear(field, shell, inside, s, beside).p_AB_m.isApprox(beside.p_AB_m));
  const Pose above = legalPoseNear(field, shell, inside, s);
  EXPECT_EQ(countPointsInside(field, shell, above, s), 0) << "above the volume";
  EXPECT_GT(above.p_AB_m.z(), 0.02);
}

}  // namespace
}  // namespace vh::runtime
