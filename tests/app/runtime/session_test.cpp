// Tests of vh/runtime/session.h: the session is the one owner of the scene (as loaded), the live
// values (isovalue, gains, tool, segments), the device and the haptic threads. Oracles: the analytic sphere (radius 20 mm, F =
// signed distance in mm) for where the proxy rests, the field's own min / max for clamping, and
// the haptic thread's snapshot for what reached the hand.
#include <atomic>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <functional>
#include <memory>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "runtime_test_support.h"
#include "vh/haptics/tool_model.h"
#include "vh/runtime/session.h"
#include "vh/runtime/snapshot_channel.h"
#include "vh/runtime/session_metadata.h"

namespace vh::runtime {
namespace {

using namespace std::chrono_literals;
using haptics::Pose;

using test::waitUntil;

/// The ball tool's centre `depth_m` below the top of the sphere (its lowest point 5 mm lower).
Pose pressedPose(double depth_m) { return Pose::FromTranslation({0.0, 0.0, 0.020 + 0.005 - depth_m}); }

/// The scene's tool resampled at 3 mm point spacing (a tool picker's rebuild).
std::shared_ptr<const haptics::ToolModel> coarseTool(const LoadedScene& loaded) {
  haptics::PointShellOptions options;
  options.spacing_m = 0.003;
  return std::make_shared<const haptics::ToolModel>(haptics::makeToolModel(loaded.tool->mesh_T, options));
}

/// Records what observers were told.
struct Heard {
  std::vector<SessionChange> changes;
  bool any(SessionChange bit) const {
    for (SessionChange c : changes) {
      if (has(c, bit)) return true;
    }
    return false;
  }
};

TEST(Session, WithoutASceneNothingRunsAndCommandsAreKeptOrIgnored) {
  Session session;
  EXPECT_FALSE(session.hasScene());
  EXPECT_EQ(session.hapticThread(), nullptr);
  session.setIsovalue(5.0);  // no scene: nothing to clamp against, ignored
  EXPECT_EQ(session.isovalue(), 0.0);
  session.setGains({1500.0, 0.5});
  EXPECT_EQ(session.gains().linear_N_per_m, 1500.0);
  session.startHaptics();  // nothing to start
  EXPECT_FALSE(session.hapticsRunning());
  HapticSnapshot s;
  EXPECT_FALSE(session.latestSnapshot(s));
  EXPECT_THROW(Session(0.0), std::invalid_argument);
  EXPECT_THROW(session.setScene(LoadedScene{}, nullptr), std::invalid_argument);
}

TEST(Session, OwnsTheIsovalueClampedToTheFieldAndSendsItToTheHapticThread) {
  const LoadedScene& loaded = test::sphereBallScene();
  Session session;
  Heard heard;
  session.addObserver([&](SessionChange c) { heard.changes.push_back(c); });
  session.setScene(loaded, std::make_shared<SimulatedDevice>(loaded.X_WT_initial));
  ASSERT_TRUE(heard.any(SessionChange::kScene));
  ASSERT_NE(session.hapticThread(), nullptr);
  EXPECT_FALSE(session.hapticsRunning());  // built, not started

  heard.changes.clear();
  session.setIsovalue(-2.0);
  EXPECT_EQ(session.isovalue(), -2.0);
  EXPECT_EQ(session.live().isovalue, -2.0);  // what a recording's metadata says
  EXPECT_EQ(session.hapticThread()->isovalue(), -2.0);
  ASSERT_EQ(heard.changes.size(), 1u);
  EXPECT_TRUE(has(heard.changes[0], SessionChange::kIsovalue));

  const double max = loaded.volume.field->maxValue();
  const double min = loaded.volume.field->minValue();
  session.setIsovalue(max + 1000.0);
  EXPECT_EQ(session.isovalue(), max);
  session.setIsovalue(min - 1000.0);
  EXPECT_EQ(session.isovalue(), min);
  EXPECT_EQ(session.valueRange().first, min);
  EXPECT_EQ(session.valueRange().second, max);

  heard.changes.clear();
  session.setIsovalue(std::numeric_limits<double>::quiet_NaN());
  EXPECT_EQ(session.isovalue(), min);
  EXPECT_TRUE(heard.changes.empty());
}

TEST(Session, TheProxyRestsOnTheAnalyticSphereAndIsovalueAndGainsReachTheHand) {
  const LoadedScene& loaded = test::sphereBallScene();
  Session session;
  auto device = std::make_shared<SimulatedDevice>(pressedPose(0.003));
  session.setScene(loaded, device);
  session.setGains({1000.0, 1.0});
  session.startHaptics();
  ASSERT_TRUE(session.hapticsRunning());
  HapticSnapshot snap;
  ASSERT_TRUE(waitUntil([&] { return session.latestSnapshot(snap) && snap.tick > 100 && snap.contacts > 0; }));
  // 20 coupling ticks later: the snapshot that first shows the solver's contacts may carry a
  // coupling tick that still used the proxy before them.
  const std::uint64_t contact_at = snap.tick;
  ASSERT_TRUE(waitUntil([&] { session.latestSnapshot(snap); return snap.tick > contact_at + 20; }));
  // The ball (radius 5 mm) rests on the sphere (radius 20 mm): its centre 25 mm from the origin,
  // within a voxel's worth of the trilinear surface.
  EXPECT_NEAR(snap.X_WP.p_AB_m.norm(), 0.025, 0.5e-3);
  const double before = snap.force_W_N.norm();
  EXPECT_NEAR(before, 1000.0 * 0.003, 0.6);  // k * depth, the same half-millimetre

  session.setGains({2000.0, 1.0});
  const std::uint64_t at = snap.tick;
  ASSERT_TRUE(waitUntil([&] { session.latestSnapshot(snap); return snap.tick > at + 30; }));
  EXPECT_NEAR(snap.force_W_N.norm(), 2.0 * before, 0.1 * before);

  // F = 20 mm - r: isovalue 2 shrinks the surface to r = 18 mm. The device's ball (centre at
  // 22 mm) still reaches 1 mm into it, so the proxy settles at 23 mm.
  session.setIsovalue(2.0);
  ASSERT_TRUE(waitUntil([&] { session.latestSnapshot(snap); return snap.isovalue == 2.0 && snap.tick > at + 60; }));
  ASSERT_TRUE(waitUntil([&] { session.latestSnapshot(snap); return snap.X_WP.p_AB_m.norm() < 0.0235; }));
  // Then 50 more solver ticks: a tick the solver's deadline cut on a loaded machine moves the
  // proxy only part of the way, and the check is of where it rests.
  const std::uint64_t below_at = snap.solver_tick;
  ASSERT_TRUE(waitUntil([&] { session.latestSnapshot(snap); return snap.solver_tick > below_at + 50; }));
  EXPECT_NEAR(snap.X_WP.p_AB_m.norm(), 0.023, 0.5e-3);
  EXPECT_NEAR(snap.force_W_N.norm(), 2000.0 * 0.001, 0.6);
  session.stopHaptics();
  EXPECT_FALSE(session.hapticsRunning());
}

TEST(Session, ASwappedDeviceTakesOverAtTheProxysPoseAndKeepsRunning) {
  const LoadedScene& loaded = test::sphereBallScene();
  Session session;
  session.setScene(loaded, std::make_shared<SimulatedDevice>(pressedPose(0.003)));
  session.startHaptics();
  HapticSnapshot snap;
  // 1000 ticks on the old thread: the new one below could only count as many if this thread were
  // held up for about a second between the swap and its next read.
  ASSERT_TRUE(waitUntil([&] { return session.latestSnapshot(snap) && snap.tick > 1000 && snap.contacts > 0; }));
  const Pose X_WP = snap.X_WP;
  const std::uint64_t old_ticks = snap.tick;

  Heard heard;
  session.addObserver([&](SessionChange c) { heard.changes.push_back(c); });
  auto next = std::make_shared<SimulatedDevice>(Pose::FromTranslation({0.0, 0.0, 0.1}));
  session.setDevice(next);
  EXPECT_TRUE(heard.any(SessionChange::kDevice));
  EXPECT_EQ(session.device(), next.get());
  EXPECT_EQ(session.simulatedDevice(), next.get());
  ASSERT_NE(session.hapticThread(), nullptr);
  EXPECT_TRUE(session.hapticsRunning());
  ASSERT_TRUE(waitUntil([&] { return session.latestSnapshot(snap); }));
  EXPECT_LT(snap.tick, old_ticks);  // a new thread counts from its own start
  // The new device was moved to where the proxy was: no jump, no force spike.
  EXPECT_LT((next->pose().p_AB_m - X_WP.p_AB_m).norm(), 1e-12);
  ASSERT_TRUE(waitUntil([&] { return session.latestSnapshot(snap) && snap.tick > 50; }));
  EXPECT_LT((snap.X_WP.p_AB_m - X_WP.p_AB_m).norm(), 0.5e-3);
  EXPECT_LT(snap.force_W_N.norm(), 0.5);

  session.setDevice(nullptr);  // haptics off
  EXPECT_EQ(session.hapticThread(), nullptr);
  EXPECT_FALSE(session.hapticsRunning());
  EXPECT_TRUE(heard.any(SessionChange::kRunning));
}

TEST(Session, ASwappedToolReplacesTheSpecAndRestartsAtItsFreePose) {
  const LoadedScene& loaded = test::sphereBallScene();
  Session session;
  auto device = std::make_shared<SimulatedDevice>(pressedPose(0.003));
  session.setScene(loaded, device);
  session.startHaptics();
  const auto coarse = coarseTool(loaded);
  ToolSpec spec = loaded.spec.tool;
  spec.point_spacing_m = 0.003;
  const Pose free_pose = Pose::FromTranslation({0.0, 0.0, 0.040});
  session.setTool(coarse, spec, free_pose);
  EXPECT_EQ(session.live().tool, coarse);
  EXPECT_EQ(session.live().tool_spec.point_spacing_m, 0.003);
  EXPECT_EQ(session.live().pointSpacing_m(), 0.003);
  EXPECT_TRUE(session.hapticsRunning());
  EXPECT_LT((device->pose().p_AB_m - free_pose.p_AB_m).norm(), 1e-12);
  HapticSnapshot snap;
  ASSERT_TRUE(waitUntil([&] { return session.latestSnapshot(snap) && snap.tick > 50; }));
  EXPECT_LT((snap.X_WP.p_AB_m - free_pose.p_AB_m).norm(), 1e-6);
  EXPECT_EQ(snap.contacts, 0);
  EXPECT_THROW(session.setTool(nullptr, spec, free_pose), std::invalid_argument);
}

TEST(Session, TheEdgeTestSwitchesOffWhereTheProxyIsAndTheHandStillRestsOnTheSphere) {
  const LoadedScene& loaded = test::sphereBallScene();
  Session session;
  EXPECT_THROW(session.setEdgeTest(true), std::invalid_argument);
  auto device = std::make_shared<SimulatedDevice>(pressedPose(0.003));
  session.setScene(loaded, device);
  session.startHaptics();
  ASSERT_TRUE(session.live().tool_spec.edge_test) << "on by default";
  HapticSnapshot snap;
  ASSERT_TRUE(waitUntil([&] { return session.latestSnapshot(snap) && snap.tick > 100 && snap.contacts > 0; }));
  Heard heard;
  session.addObserver([&](SessionChange c) { heard.changes.push_back(c); });
  session.setEdgeTest(false);
  EXPECT_FALSE(session.live().tool_spec.edge_test);
  EXPECT_TRUE(heard.any(SessionChange::kTool));
  EXPECT_TRUE(session.hapticsRunning());
  // The rebuilt threads start where the proxy was and, pressed 3 mm into the sphere, the ball
  // (radius 5 mm) rests on it again: its centre 25 mm from the sphere's centre.
  ASSERT_TRUE(waitUntil([&] { return session.latestSnapshot(snap) && snap.tick > 100 && snap.contacts > 0; }));
  EXPECT_NEAR(snap.X_WP.p_AB_m.norm(), 0.025, 0.5e-3);
  heard.changes.clear();
  session.setEdgeTest(false);  // the same value: nothing happens
  EXPECT_TRUE(heard.changes.empty());
  session.stopHaptics();
}

TEST(Session, RestartsOfRunningThreadsKeepTheMemoryLocked) {
  // A new tool, edge test, device or monitor restarts the haptic threads. While they run, the
  // process's memory is locked where the system allows, and a restart must not unlock it (on a
  // CT, munlockall took 20 to 40 ms of the stop, with the force off, and the new threads then
  // locked it again). Oracle: the kernel's count of locked memory, read all along on another
  // thread.
  const LoadedScene& loaded = test::sphereBallScene();
  Session session;
  session.setScene(loaded, std::make_shared<SimulatedDevice>(pressedPose(0.003)));
  session.startHaptics();
  HapticSnapshot snap;
  ASSERT_TRUE(waitUntil([&] { return session.latestSnapshot(snap) && snap.tick > 20; }));
  if (!session.hapticThread()->memoryLocked()) {
    session.stopHaptics();
    GTEST_SKIP() << "the coupling thread may not lock memory here (needs SCHED_FIFO and root or an unlimited "
                    "RLIMIT_MEMLOCK)";
  }
  std::atomic<bool> done{false};
  std::atomic<long> lowest_kB{std::numeric_limits<long>::max()};
  std::atomic<int> reads{0};
  std::thread sampler([&] {
    while (!done.load()) {
      lowest_kB.store(std::min(lowest_kB.load(), test::lockedMemory_kB()));
      reads.fetch_add(1);
    }
  });
  ToolSpec spec = loaded.spec.tool;
  spec.point_spacing_m = 0.003;
  session.setTool(coarseTool(loaded), spec, Pose::FromTranslation({0.0, 0.0, 0.040}));
  session.setEdgeTest(true);
  session.setDevice(std::make_shared<SimulatedDevice>(Pose::FromTranslation({0.0, 0.0, 0.040})));
  session.setMonitor(std::make_shared<SnapshotChannel>());
  ASSERT_TRUE(waitUntil([&] { return session.latestSnapshot(snap) && snap.tick > 20; }));
  // Enough reads however little time the sampler got during the restarts on a loaded machine.
  EXPECT_TRUE(waitUntil([&] { return reads.load() > 100; }));
  done.store(true);
  sampler.join();
  EXPECT_TRUE(session.hapticsRunning());
  EXPECT_TRUE(session.hapticThread()->memoryLocked());
  EXPECT_GT(reads.load(), 100);
  EXPECT_GT(lowest_kB.load(), 0) << "a restart unlocked the memory (over " << reads.load() << " reads)";
  session.stopHaptics();
  EXPECT_TRUE(waitUntil([] { return test::lockedMemory_kB() == 0; })) << "the last user gone, the memory is unlocked";
}

TEST(Session, TheLoadedSceneStaysAsLoadedAndTheRecordingDescribesTheLiveValues) {
  const LoadedScene& loaded = test::sphereBallScene();
  Session session;
  session.setScene(loaded, std::make_shared<SimulatedDevice>(loaded.X_WT_initial));
  session.setIsovalue(-2.0);
  session.setGains({1234.0, 0.25, false});
  const auto coarse = coarseTool(loaded);
  ToolSpec spec = loaded.spec.tool;
  spec.point_spacing_m = 0.003;
  const Pose free_pose = Pose::FromTranslation({0.0, 0.0, 0.040});
  session.setTool(coarse, spec, free_pose);
  // What was loaded has not moved: one owner of each live value, no mirror in the scene.
  EXPECT_EQ(session.loaded().isovalue, loaded.isovalue);
  EXPECT_EQ(session.loaded().tool, loaded.tool);
  EXPECT_EQ(session.loaded().spec.gains.linear_N_per_m, loaded.spec.gains.linear_N_per_m);
  EXPECT_EQ(session.loaded().spec.tool.point_spacing_m, loaded.spec.tool.point_spacing_m);
  EXPECT_EQ(session.loaded().X_WT_initial.p_AB_m, loaded.X_WT_initial.p_AB_m);
  // A recording started now describes what is felt, and reloads to it.
  const SceneSpec recorded = sceneFromSessionMetadata(makeSessionMetadata(session.loaded(), session.live(), {}));
  EXPECT_EQ(recorded.volume.isovalue, -2.0);
  EXPECT_EQ(recorded.gains.linear_N_per_m, 1234.0);
  EXPECT_EQ(recorded.gains.angular_Nm_per_rad, 0.25);
  EXPECT_EQ(recorded.tool.point_spacing_m, 0.003);
  EXPECT_EQ(recorded.tool.X_WT_initial.p_AB_m, free_pose.p_AB_m);
  // The haptic thread was rebuilt for the new tool from the live values, not the loaded ones.
  ASSERT_NE(session.hapticThread(), nullptr);
  EXPECT_EQ(session.hapticThread()->isovalue(), -2.0);
}

TEST(Session, ARemovedObserverHearsNothingAndClearForgetsTheScene) {
  const LoadedScene& loaded = test::sphereBallScene();
  Session session;
  int calls = 0;
  const int id = session.addObserver([&](SessionChange) { ++calls; });
  session.setScene(loaded, nullptr);  // no device: no haptic thread
  EXPECT_EQ(calls, 1);
  EXPECT_EQ(session.hapticThread(), nullptr);
  session.removeObserver(id);
  session.setIsovalue(1.0);
  EXPECT_EQ(calls, 1);
  session.clear();
  EXPECT_FALSE(session.hasScene());
  EXPECT_EQ(session.device(), nullptr);
}

TEST(Session, LoadSceneRecordsTheSpacingItSampledTheToolAt) {
  // The one point-spacing rule (toolPointSpacing_m): a spacing as given, a count as
  // sqrt(area / count), else automatic.
  const LoadedScene& loaded = test::sphereBallScene();
  EXPECT_EQ(loaded.pointSpacing_m(), 0.0015);
  ToolSpec by_count;
  by_count.point_count = 400;
  EXPECT_NEAR(toolPointSpacing_m(by_count, loaded.tool->mesh_T, *loaded.volume.field),
              std::sqrt(loaded.tool->mesh_T.area_m2() / 400.0), 1e-15);
  ToolSpec automatic;
  EXPECT_EQ(toolPointSpacing_m(automatic, loaded.tool->mesh_T, *loaded.volume.field),
            automaticPointSpacing_m(loaded.tool->mesh_T, *loaded.volume.field));
  EXPECT_GE(automaticPointSpacing_m(loaded.tool->mesh_T, *loaded.volume.field),
            0.5 * loaded.volume.field->geometry().minSpacing());
}

}  // namespace
}  // namespace vh::runtime
