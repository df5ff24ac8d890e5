// Haptic guidance from an expert's recording (guidance.h) in the headless run: a scripted
// trainee whose path is the expert's offset by 3 mm with noise ends nearer the expert's with
// guidance than without (mean distance and the DTW of `report --reference`); the guidance force
// never exceeds its cap; fading weakens it repetition by repetition; a recording of another scan
// is refused; the hand model yields to a force as its impedance says.
#include "vh/runtime/guidance.h"

#include <cmath>
#include <fstream>
#include <iterator>
#include <random>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "runtime_test_support.h"
#include "vh/runtime/haptic_thread.h"
#include "vh/runtime/placement.h"
#include "vh/runtime/runner.h"
#include "vh/runtime/session_metadata.h"
#include "vh/runtime/sha256.h"

namespace vh::runtime {
namespace {

using haptics::Pose;

struct GuideFixture {
  LoadedScene scene;
  Trajectory expert, trainee;
  std::filesystem::path expert_file;
  std::shared_ptr<const ExpertPath> path;
};

/// The sphere-probe scene, an expert's push-and-slide (recorded with the compliant hand), and a
/// trainee who means to do the same 3 mm to the side, with 0.5 mm of noise every 20 ms.
const GuideFixture& fixture() {
  static const GuideFixture f = [] {
    GuideFixture g{loadScene(loadSceneFile(test::sourceDir() / "resources" / "scenes" / "sphere-probe.json")), {}, {}, {}, {}};
    const auto& field = *g.scene.volume.field;
    const Pose start = poseAboveVolume(field, g.scene.tool->point_shell, g.scene.X_WT_initial.R_AB, 0.01);
    PushSlideOptions push;
    push.slide_dir_W = Eigen::Vector3d::UnitX();
    g.expert = makePushSlideTrajectory(field, g.scene.tool->point_shell, g.scene.isovalue, start, push).trajectory;
    std::mt19937 rng(11);
    std::normal_distribution<double> noise(0.0, 0.0005);
    std::vector<TrajectorySample> keys;
    for (double t = g.expert.startTime_s(); t <= g.expert.endTime_s() + 1e-9; t += 0.02) {
      TrajectorySample k;
      k.t_s = t;
      k.X_WD = g.expert.poseAt(t);
      k.X_WD.p_AB_m += Eigen::Vector3d(noise(rng), 0.003 + noise(rng), noise(rng));
      keys.push_back(k);
    }
    g.trainee = Trajectory(std::move(keys));
    RunOptions options;
    options.verify_step_voxels = 0.0;
    options.lag_reference = false;
    options.hand = HandImpedance{};
    options.record = test::scratchDir() / "expert.vhrec";
    runHeadless(g.scene, g.expert, options);
    g.expert_file = options.record;
    g.path = loadExpertPath(g.expert_file, makeSessionMetadata(g.scene, SessionInfo{}));
    return g;
  }();
  return f;
}

RunReport traineeRun(const haptics::GuidanceGains& gains, const std::filesystem::path& record = {}) {
  const GuideFixture& f = fixture();
  RunOptions options;
  options.verify_step_voxels = 0.0;
  options.lag_reference = false;
  options.hand = HandImpedance{};
  options.guide = f.path;
  options.guide_gains = gains;
  options.record = record;
  return runHeadless(f.scene, f.trainee, options);
}

double dtwAgainstExpert(const std::filesystem::path& trainee_file) {
  const Recording trainee = readRecording(trainee_file), expert = readRecording(fixture().expert_file);
  return compareWithReference(trainee, computeSessionMetrics(trainee), expert, computeSessionMetrics(expert))
      .alignment.mean_distance_m;
}

TEST(Guidance, PullsTheTraineeTowardTheExpertsPath) {
  const std::filesystem::path dir = test::scratchDir();
  haptics::GuidanceGains on, off;
  off.stiffness_N_per_m = 0.0;
  const RunReport guided = traineeRun(on, dir / "guided.vhrec");
  const RunReport unguided = traineeRun(off, dir / "unguided.vhrec");
  ASSERT_TRUE(guided.guidance && unguided.guidance);
  EXPECT_EQ(unguided.guidance->max_force_N, 0.0);
  EXPECT_GT(guided.guidance->max_force_N, 0.1);
  // Unguided, the hand keeps about its 3 mm offset; guided, K / (k + K) = 0.4 of it is pulled in.
  EXPECT_GT(unguided.guidance->mean_distance_m, 0.002);
  EXPECT_LT(guided.guidance->mean_distance_m, 0.8 * unguided.guidance->mean_distance_m)
      << guided.guidance->summary() << " vs " << unguided.guidance->summary();
  // The same DTW as `report --reference`, from the recordings.
  const double dtw_guided = dtwAgainstExpert(dir / "guided.vhrec"), dtw_unguided = dtwAgainstExpert(dir / "unguided.vhrec");
  EXPECT_LT(dtw_guided, 0.85 * dtw_unguided) << dtw_guided << " vs " << dtw_unguided;
  EXPECT_NEAR(guided.guidance->dtw_mean_m, dtw_guided, 2e-4);
  EXPECT_EQ(guided.nan_ticks, 0u);
}

TEST(Guidance, ForceNeverExceedsItsCapAndIsRecorded) {
  const std::filesystem::path file = test::scratchDir() / "capped.vhrec";
  haptics::GuidanceGains g;
  g.stiffness_N_per_m = 2000.0;
  g.cap_N = 0.4;
  const RunReport r = traineeRun(g, file);
  ASSERT_TRUE(r.guidance);
  EXPECT_LE(r.guidance->max_force_N, g.cap_N);
  EXPECT_GT(r.guidance->max_force_N, 0.99 * g.cap_N);  // the cap was reached
  const Recording rec = readRecording(file);
  int settings = 0, forces = 0;
  double peak = 0.0;
  for (const RecordingEvent& e : rec.events) {
    const nlohmann::json d = nlohmann::json::parse(e.detail_json);
    if (e.type == "guidance") {
      ++settings;
      EXPECT_EQ(d.at("expert_sha256"), sha256File(fixture().expert_file));
      EXPECT_EQ(d.at("cap_N"), g.cap_N);
      EXPECT_EQ(d.at("stiffness_N_per_m"), g.stiffness_N_per_m);
      EXPECT_EQ(d.at("repetition"), 0);
    } else if (e.type == "guidance_force") {
      ++forces;
      peak = std::max(peak, d.at("peak_N").get<double>());
    }
  }
  EXPECT_EQ(settings, 1);
  EXPECT_EQ(static_cast<std::size_t>(forces), r.ticks / kGuidanceEventTicks);
  EXPECT_EQ(peak, r.guidance->max_force_N);
}

TEST(Guidance, FadesOverRepetitions) {
  haptics::GuidanceGains g;
  g.fade = 0.5;
  double last = 0.0;
  for (int rep : {0, 1, 3}) {
    g.repetition = rep;
    const RunReport r = traineeRun(g);
    ASSERT_TRUE(r.guidance);
    EXPECT_NEAR(r.guidance->stiffness_N_per_m, 200.0 * std::pow(0.5, rep), 1e-9);
    EXPECT_GT(r.guidance->mean_distance_m, last) << "repetition " << rep;
    last = r.guidance->mean_distance_m;
  }
  g.stiffness_N_per_m = 0.0;
  EXPECT_GT(traineeRun(g).guidance->mean_distance_m, last);
}

TEST(Guidance, RefusesARecordingOfAnotherScan) {
  const LoadedScene other = loadScene(loadSceneFile(test::sourceDir() / "resources" / "scenes" / "block-peg.json"));
  try {
    loadExpertPath(fixture().expert_file, makeSessionMetadata(other, SessionInfo{}));
    FAIL() << "a recording of the sphere guided a session on the block";
  } catch (const std::invalid_argument& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("the guide recording expert.vhrec was recorded on another scene"), std::string::npos) << what;
    EXPECT_NE(what.find("guidance needs the same dataset"), std::string::npos) << what;
  }
}

// A damaged expert recording (killed: its tail and end marker gone) guides along what could be
// read, and says so with how much: ExpertPath::damage(), which the run prints, the window shows
// and the run's report carries; a whole one says nothing.
TEST(Guidance, ADamagedExpertRecordingIsSaidWithHowMuchOfItGuides) {
  const GuideFixture& f = fixture();
  EXPECT_EQ(f.path->damage(), "") << "the whole recording";
  std::ifstream in(f.expert_file, std::ios::binary);
  std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  bytes.resize(bytes.size() * 2 / 3);  // killed mid-session
  const std::filesystem::path cut = test::writeText(f.expert_file.parent_path() / "killed.vhrec", bytes);
  const auto path = loadExpertPath(cut, makeSessionMetadata(f.scene, SessionInfo{}));
  const Recording read = readRecording(cut);
  const std::string said = path->damage();
  EXPECT_NE(said.find("killed.vhrec is damaged or unfinished"), std::string::npos) << said;
  EXPECT_NE(said.find("follows the " + std::to_string(read.records.size()) + " records read"), std::string::npos) << said;
  EXPECT_NE(said.find("unfinished recording"), std::string::npos) << said;
  EXPECT_LT(read.records.size(), readRecording(f.expert_file).records.size());
  RunOptions options;
  options.verify_step_voxels = 0.0;
  options.lag_reference = false;
  options.hand = HandImpedance{};
  options.guide = path;
  const RunReport r = runHeadless(f.scene, f.trainee, options);
  ASSERT_TRUE(r.guidance.has_value());
  EXPECT_EQ(r.guidance->expert_damage, said);
  EXPECT_NE(r.toJson().find("expert_damage"), std::string::npos);
}

TEST(Guidance, ClampedToTheDevicesRating) {
  DeviceLimits limits;
  limits.max_linear_stiffness_N_per_m = 150.0;
  limits.max_force_N = 1.0;
  haptics::GuidanceGains g;
  g.stiffness_N_per_m = 400.0;
  g.cap_N = 3.0;
  const haptics::GuidanceGains c = clampGuidance(g, limits);
  EXPECT_EQ(c.stiffness_N_per_m, 150.0);
  EXPECT_EQ(c.cap_N, 1.0);
}

/// An expert's path as a recording: a straight line along x through `p_W_m`, 100 records.
Recording lineRecording(const Eigen::Vector3d& p_W_m, const std::string& metadata_json) {
  Recording r;
  r.metadata_json = metadata_json;
  for (int i = 0; i < 100; ++i) {
    TickRecord t;
    t.tick = static_cast<std::uint64_t>(i + 1);
    for (int k = 0; k < 3; ++k) t.p_WD_m[k] = p_W_m[k];
    t.p_WD_m[0] += 0.001 * (i - 50);
    r.records.push_back(t);
  }
  return r;
}

// On the coupling thread: the device held 4 mm off the expert's line in free space feels the
// guidance spring through the safety layer (the command the device got), and the snapshot
// shows the nearest point; off again, the command is the coupling's alone.
TEST(Guidance, TheCouplingThreadAddsTheSpringBeforeTheSafetyLayer) {
  const LoadedScene& scene = test::sphereBallScene();
  auto device = std::make_shared<SimulatedDevice>(scene.X_WT_initial);
  auto thread = scene.makeHapticThread(device);
  const Eigen::Vector3d line = scene.X_WT_initial.p_AB_m + Eigen::Vector3d(0.0, 0.004, 0.0);
  auto expert = std::make_shared<const ExpertPath>(lineRecording(line, makeSessionMetadata(scene, SessionInfo{})));
  haptics::GuidanceGains g;
  g.stiffness_N_per_m = 100.0;  // 0.4 N at 4 mm
  thread->start();
  thread->setGuidance(expert, g);
  HapticSnapshot snap;
  ASSERT_TRUE(test::waitUntil([&] { return thread->latestSnapshot(snap) && snap.guidance_on && snap.tick > 50; }));
  EXPECT_NEAR(snap.guidance_force_W_N.y(), 0.4, 1e-6);
  EXPECT_NEAR((snap.guidance_nearest_W_m - Eigen::Vector3d(scene.X_WT_initial.p_AB_m.x(), line.y(), line.z())).norm(), 0.0, 1e-9);
  DeviceCommand cmd;
  ASSERT_TRUE(test::waitUntil([&] { return device->lastCommand(cmd) && cmd.count > snap.tick; }));
  EXPECT_NEAR(cmd.force_W_N.y(), 0.4, 1e-3) << "the device gets the guidance force (proxy and device together: no coupling force)";
  EXPECT_EQ(thread->guidance(), expert);
  thread->setGuidance(nullptr, g);
  ASSERT_TRUE(test::waitUntil([&] { return thread->latestSnapshot(snap) && !snap.guidance_on; }));
  std::uint64_t after = snap.tick + 5;
  ASSERT_TRUE(test::waitUntil([&] { return device->lastCommand(cmd) && cmd.count > after; }));
  EXPECT_NEAR(cmd.force_W_N.norm(), 0.0, 1e-6);
  thread->stop();
}

TEST(CompliantHand, SettlesWhereTheForceBalancesItsStiffness) {
  Trajectory still({TrajectorySample{0.0, Pose::FromTranslation({0.01, 0.0, 0.0})},
                    TrajectorySample{10.0, Pose::FromTranslation({0.01, 0.0, 0.0})}});
  ScriptedDevice scripted(still, 1e-3);
  HandImpedance h;
  CompliantHand hand(scripted, h, 1e-3);
  DeviceSample s;
  for (int i = 0; i < 5000; ++i) {
    ASSERT_TRUE(hand.read(s));
    hand.command(Eigen::Vector3d(0.0, 0.6, 0.0), Eigen::Vector3d::Zero());
  }
  // 0.6 N on 300 N/m: 2 mm off its intended position, along the force.
  EXPECT_NEAR(s.X_WD.p_AB_m.y(), 0.6 / h.stiffness_N_per_m, 1e-6);
  EXPECT_NEAR(s.X_WD.p_AB_m.x(), 0.01, 1e-12);
}

// A stiffness the integration cannot hold is refused with its limit (before: 1e300 N/m was
// accepted and 4,400 of 4,601 samples came out bad with exit status 0); just under the limit the
// hand still settles where the force balances it (the oracle: the force over the stiffness).
TEST(CompliantHand, AStiffnessItsStepCannotHoldIsRefusedWithTheLimit) {
  Trajectory still({TrajectorySample{0.0, Pose::FromTranslation({0.0, 0.0, 0.0})},
                    TrajectorySample{100.0, Pose::FromTranslation({0.0, 0.0, 0.0})}});
  ScriptedDevice scripted(still, 1e-3);
  HandImpedance h;
  h.stiffness_N_per_m = 1e300;
  try {
    CompliantHand hand(scripted, h, 1e-3);
    ADD_FAILURE() << "1e300 N/m was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("must be below 1.96e+06 N/m"), std::string::npos) << e.what();
  }
  h.stiffness_N_per_m = 1.9e6;  // under the limit (4 m - 2 b dt) / dt^2 = 1.96e6 N/m: stable
  CompliantHand hand(scripted, h, 1e-3);
  DeviceSample s;
  const double balance_m = 95.0 / h.stiffness_N_per_m;
  double last_swing = 0.0;  // the farthest from the balance over the last 1,000 reads
  for (int i = 0; i < 60000; ++i) {
    ASSERT_TRUE(hand.read(s));
    hand.command(Eigen::Vector3d(0.0, 95.0, 0.0), Eigen::Vector3d::Zero());
    if (i >= 59000) last_swing = std::max(last_swing, std::abs(s.X_WD.p_AB_m.y() - balance_m));
  }
  EXPECT_TRUE(s.X_WD.p_AB_m.allFinite());
  EXPECT_LT(last_swing, 1e-3 * balance_m) << "the hand has not settled (an unstable step grows instead)";
}

}  // namespace
}  // namespace vh::runtime
