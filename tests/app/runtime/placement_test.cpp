// Placements: Touch the Surface's approach as a pure function (touchSurfacePose(),
// insideBoxCentre_W()) against analytic spheres and balls; a placement on running haptic
// threads (HapticThread::place()) feels only the resting force, is recorded as a placement and
// replays bit for bit; and the session's metrics leave a placement's jump out.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "runtime_test_support.h"
#include "vh/runtime/haptic_thread.h"
#include "vh/runtime/placement.h"
#include "vh/runtime/recording.h"
#include "vh/runtime/replay.h"
#include "vh/runtime/scene.h"
#include "vh/runtime/session_metrics.h"

namespace vh::runtime {
namespace {

using haptics::Pose;

/// The shell point nearest the origin, its distance [m]: the sphere's surface is at 20 mm.
double nearestRadius_m(const haptics::PointShell& shell, const Pose& X_WT) {
  double r = std::numeric_limits<double>::infinity();
  for (const Eigen::Vector3d& p_T : shell.points_T_m()) r = std::min(r, (X_WT * p_T).norm());
  return r;
}

TEST(TouchSurfacePose, RestsTheBallToolOnTheSphereAlongTheApproach) {
  const LoadedScene& scene = test::sphereBallScene();  // sphere of 20 mm, ball tool of 5 mm
  const haptics::ScalarVolume& field = *scene.volume.field;
  const haptics::PointShell& shell = scene.tool->point_shell;
  const Eigen::Vector3d p_TCm = scene.tool->mass.p_TCm_m;
  const Eigen::Vector3d dir_W = Eigen::Vector3d(0.3, 1.0, -0.4).normalized();
  const auto touch = touchSurfacePose(field, shell, p_TCm, Eigen::Quaterniond::Identity(), 2.0 * dir_W,
                                      Eigen::Vector3d::Zero(), 0.0, 0.003);
  ASSERT_TRUE(touch.has_value());
  EXPECT_LT((touch->dir_W - dir_W).norm(), 1e-12);
  // The proxy is free and touches: a shell point on the sphere (20 mm, to the field's
  // trilinear error and the search's tolerance), and 0.2 mm further some point is inside.
  EXPECT_EQ(countPointsInside(field, shell, touch->X_WP, 0.0), 0);
  EXPECT_NEAR(nearestRadius_m(shell, touch->X_WP), 0.020, 0.25e-3);
  EXPECT_GT(countPointsInside(field, shell, Pose{touch->X_WP.R_AB, touch->X_WP.p_AB_m + 0.2e-3 * dir_W}, 0.0), 0);
  // On the viewer's side of the line through the aim (the origin), the orientation kept.
  const Eigen::Vector3d c_W = touch->X_WP * p_TCm;
  EXPECT_LT((c_W - c_W.dot(dir_W) * dir_W).norm(), 1e-9);
  EXPECT_LT(c_W.dot(dir_W), 0.0);
  EXPECT_LT(touch->X_WP.R_AB.angularDistance(Eigen::Quaterniond::Identity()), 1e-12);
  // The device the depth asked for further along the approach.
  EXPECT_LT((touch->X_WD.p_AB_m - touch->X_WP.p_AB_m - 0.003 * dir_W).norm(), 1e-12);
  // Nothing to meet: no surface at an isovalue above the field's maximum; no direction.
  EXPECT_FALSE(touchSurfacePose(field, shell, p_TCm, Eigen::Quaterniond::Identity(), dir_W, Eigen::Vector3d::Zero(),
                                field.maxValue() + 1.0, 0.003));
  EXPECT_FALSE(touchSurfacePose(field, shell, p_TCm, Eigen::Quaterniond::Identity(), Eigen::Vector3d::Zero(),
                                Eigen::Vector3d::Zero(), 0.0, 0.003));
}

/// 48^3 voxels of 1 mm centred on the origin, 1 inside a ball of `radius_m` about `c_W`, else 0.
haptics::ScalarVolume ballField(const Eigen::Vector3d& c_W, double radius_m) {
  haptics::VolumeGeometry g;
  g.dims = {48, 48, 48};
  g.spacing_m = Eigen::Vector3d::Constant(0.001);
  g.origin_W_m = Eigen::Vector3d::Constant(-0.0235);
  std::vector<float> v(g.voxelCount(), 0.0f);
  for (std::uint64_t n = 0; n < v.size(); ++n) {
    const auto ijk = g.voxelOf(n);
    if ((g.pointOf_W(Eigen::Vector3d(ijk[0], ijk[1], ijk[2])) - c_W).norm() <= radius_m) v[n] = 1.0f;
  }
  return haptics::ScalarVolume::FromVoxels(g, v);
}

TEST(TouchSurfacePose, AimedAtAnOffCentreSegmentReachesItsNearSide) {
  // A felt segment off the volume's centre (its indicator at level 0.5): the approach through
  // the volume's centre would miss it; aimed at the centre of its inside voxels it lands on it.
  const Eigen::Vector3d c_W(0.0085, -0.0065, 0.0045);  // a voxel centre
  const haptics::ScalarVolume field = ballField(c_W, 0.00605);  // no voxel centre on the sphere: no rounding ties
  const auto centre = insideBoxCentre_W(field, 0.5);
  ASSERT_TRUE(centre.has_value());
  EXPECT_LT((*centre - c_W).norm(), 1e-9) << "a ball about a voxel centre has its box centred there";
  EXPECT_FALSE(insideBoxCentre_W(field, 2.0).has_value());

  const LoadedScene& scene = test::sphereBallScene();
  const haptics::PointShell& shell = scene.tool->point_shell;  // ball tool, radius 5 mm
  const Eigen::Vector3d p_TCm = scene.tool->mass.p_TCm_m;
  const Eigen::Vector3d dir_W(0.0, 0.0, -1.0);
  const auto touch = touchSurfacePose(field, shell, p_TCm, Eigen::Quaterniond::Identity(), dir_W, *centre, 0.5, 0.002);
  ASSERT_TRUE(touch.has_value());
  // The ball tool rests on top of the segment's ball, on the approach line through its centre:
  // 6 mm (the ball) + 5 mm (the tool) apart, to a voxel (the binary indicator's 0.5 level lies
  // within a voxel of the ball's surface, and the shell's points sit 1.5 mm apart).
  const Eigen::Vector3d tool_W = touch->X_WP * p_TCm;
  EXPECT_NEAR((tool_W - c_W).norm(), 0.011, 1.0e-3);
  EXPECT_LT(Eigen::Vector2d(tool_W.x() - c_W.x(), tool_W.y() - c_W.y()).norm(), 1e-9);
  EXPECT_GT(tool_W.z(), c_W.z() + 0.010);
}

TEST(HapticThreadPlacement, FeelsOnlyTheRestingForceAndReplaysBitForBit) {
  const LoadedScene& scene = test::sphereBallScene();  // coupling 1000 N/m
  const double k_N_per_m = scene.spec.gains.linear_N_per_m;
  const double depth_m = 0.003;
  auto device = std::make_shared<SimulatedDevice>(scene.X_WT_initial);
  // The scene's renderer without the live solver's deadline on the clock (makeHapticThread()
  // sets one): a tick a loaded machine lets the deadline cut would not replay bit for bit.
  auto thread = std::make_unique<HapticThread>(scene.makeRenderer(), device, scene.isovalue, 1000.0);
  const std::filesystem::path path = test::scratchDir() / "placement.vhrec";
  RecordingWriter writer(path, "{}");
  thread->setRecorder(&writer);
  thread->start();
  HapticSnapshot snap;
  ASSERT_TRUE(test::waitUntil([&] { return thread->latestSnapshot(snap) && snap.tick > 200; }));
  EXPECT_LT(snap.force_W_N.norm(), 1e-9) << "the tool starts free";

  // From the side (the tool starts above the sphere: a hand would go round; a placement jumps).
  const auto touch = touchSurfacePose(*scene.volume.field, scene.tool->point_shell, scene.tool->mass.p_TCm_m,
                                      scene.X_WT_initial.R_AB, Eigen::Vector3d(1.0, 0.0, 0.0), Eigen::Vector3d::Zero(),
                                      0.0, depth_m);
  ASSERT_TRUE(touch.has_value());
  const std::uint64_t placed_at = snap.tick;
  ASSERT_TRUE(thread->place(touch->X_WP, touch->X_WD));
  // Watched for 600 coupling ticks after the placement was applied (counted, not timed: a loaded
  // machine takes longer, not fewer ticks); the deadline only ends a run that never gets there.
  double peak_N = 0.0;
  const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  bool watched = false;
  while (!watched && std::chrono::steady_clock::now() < give_up) {
    if (thread->latestSnapshot(snap)) peak_N = std::max(peak_N, snap.force_W_N.norm());
    watched = thread->placementsApplied() == 1u && snap.tick > placed_at + 600;
    std::this_thread::sleep_for(std::chrono::microseconds(200));
  }
  EXPECT_TRUE(watched) << "coupling ticks since the placement: " << snap.tick - placed_at;
  thread->latestSnapshot(snap);
  const double resting_N = snap.force_W_N.norm();
  thread->stop();
  thread->setRecorder(nullptr);
  writer.close();
  EXPECT_EQ(thread->placementsApplied(), 1u);
  // The oracle: at rest on the sphere with the approach through its centre (normal along the
  // approach), the spring is stretched by the depth: F = k d.
  EXPECT_NEAR(resting_N, k_N_per_m * depth_m, 0.05 * k_N_per_m * depth_m);
  EXPECT_LE(peak_N, k_N_per_m * depth_m * 1.05 + 0.05) << "a force spike over the resting force";
  EXPECT_LT((snap.X_WD.p_AB_m - touch->X_WD.p_AB_m).norm(), 1e-12);

  // Recorded as a placement: one flagged tick, one event; the recording replays bit for bit.
  const Recording rec = readRecording(path);
  ASSERT_FALSE(rec.records.empty());
  const auto flagged = std::count_if(rec.records.begin(), rec.records.end(),
                                     [](const TickRecord& r) { return (r.flags & kRecordFlagPlacement) != 0; });
  EXPECT_EQ(flagged, 1);
  const auto events = std::count_if(rec.events.begin(), rec.events.end(),
                                    [](const RecordingEvent& e) { return e.type == "placement"; });
  EXPECT_EQ(events, 1);
  const ReplayComparison replay = replayRecording(scene, rec);
  EXPECT_TRUE(replay.identical) << "first difference at tick " << replay.first_mismatch_tick.value_or(0) << ": "
                                << replay.mismatch;
  // The metrics: the placement's jump is not the hand's speed, its tick not the hand's force.
  const SessionMetrics m = computeSessionMetrics(rec);
  EXPECT_LT(m.peak_speed_m_per_s, 0.01) << "the hand never moved; only the placement did";
  EXPECT_LE(m.max_force_N, k_N_per_m * depth_m * 1.05 + 0.05);
}

// A placement asked for at once after start() (Touch the Surface as the scene opens, `--touch`)
// is applied: the coupling thread may begin its loop after the request. Repeated, since the
// order of the two is up to the scheduler.
TEST(HapticThreadPlacement, APlacementRightAfterStartIsApplied) {
  const LoadedScene& scene = test::sphereBallScene();
  const auto touch = touchSurfacePose(*scene.volume.field, scene.tool->point_shell, scene.tool->mass.p_TCm_m,
                                      scene.X_WT_initial.R_AB, Eigen::Vector3d(1.0, 0.0, 0.0), Eigen::Vector3d::Zero(),
                                      0.0, 0.003);
  ASSERT_TRUE(touch.has_value());
  for (int round = 0; round < 20; ++round) {
    SCOPED_TRACE(round);
    auto device = std::make_shared<SimulatedDevice>(scene.X_WT_initial);
    auto thread = scene.makeHapticThread(device);
    thread->start();
    ASSERT_TRUE(thread->place(touch->X_WP, touch->X_WD));
    EXPECT_TRUE(test::waitUntil([&] { return thread->placementsApplied() == 1u; }))
        << "the placement was never applied";
    thread->stop();
  }
}

TEST(SessionMetricsPlacement, APlacementsJumpEntersNeitherPathSpeedJerkNorForce) {
  // The hand moves along x at 50 mm/s for 2 s at 1 kHz, pressing with 1 N; at record 1000 a
  // placement moves the tools 100 mm along y (that tick's force 50 N).
  const double v_m_per_s = 0.05, dt_s = 0.001;
  Recording rec;
  rec.metadata_json = R"({"servo_rate_Hz": 1000})";
  for (int i = 0; i < 2000; ++i) {
    TickRecord r;
    r.tick = static_cast<std::uint64_t>(i + 1);
    r.time_s = i * dt_s;
    r.p_WD_m[0] = r.p_WP_m[0] = v_m_per_s * r.time_s;
    r.p_WD_m[1] = r.p_WP_m[1] = i >= 1000 ? 0.1 : 0.0;
    r.q_WD[0] = r.q_WP[0] = 1.0;
    r.force_W_N[2] = i == 1000 ? 50.0 : 1.0;
    if (i == 1000) r.flags |= kRecordFlagPlacement;
    rec.records.push_back(r);
  }
  const SessionMetrics m = computeSessionMetrics(rec);
  EXPECT_NEAR(m.path_length_m, v_m_per_s * dt_s * 1998, 1e-12);  // 1999 steps less the jump's
  EXPECT_NEAR(m.proxy_path_length_m, m.path_length_m, 1e-12);
  EXPECT_NEAR(m.peak_speed_m_per_s, v_m_per_s, 1e-9);
  EXPECT_LT(m.integrated_squared_jerk, 1e-12) << "a straight line at constant speed has no jerk";
  EXPECT_DOUBLE_EQ(m.max_force_N, 1.0);
  EXPECT_DOUBLE_EQ(m.mean_force_N, 1.0);
}

}  // namespace
}  // namespace vh::runtime
