// Device faults on both servo paths, the coupling thread (HapticThread) and the headless runner:
// a one-sample glitch of 1 cm to 10.1 m is never rendered as force (the command stays what the
// coupling to the last good sample gives), is counted, is not handed to the solver, and the next
// good sample renders normally; a missing sample while pressing holds the wall; the headless
// trace gives the commanded force and the isovalue asked for each tick.
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <fstream>
#include <map>
#include <optional>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "allocation_guard.h"
#include "runtime_test_support.h"

#include "vh/runtime/haptic_thread.h"
#include "vh/runtime/runner.h"
#include "vh/runtime/sample_filter.h"
#include "vh/runtime/scene.h"

namespace vh::runtime {
namespace {

using haptics::Pose;
using test::waitUntil;

constexpr double kK_N_per_m = 1000.0;  // the sphere scene's coupling stiffness
constexpr double kDepth_m = 0.003;     // the device's depth below the surface while pressing

/// The sphere scene (radius 20 mm, 5 mm ball tool): the tool 5 mm above the top of the sphere
/// (free), and `depth_m` pressed into it.
Pose freePose() { return Pose::FromTranslation({0.0, 0.0, 0.030}); }
Pose pressedPose(double depth_m) { return Pose::FromTranslation({0.0, 0.0, 0.025 - depth_m}); }

/// The read at which FaultyDevice holds the coupling thread until the solver has caught up
/// (settleSolver()): the device has been pressed and still since read 250.
constexpr int kSettleRead = 300;

/// A device that moves from free to pressed over reads 50..250, then holds still; read number
/// `glitch_read` reports the pose `glitch_m` deeper (an encoder glitch), reads
/// [missing_from, missing_from + missing_count) report nothing. Records every commanded force.
/// Read kSettleRead waits until release() (settleSolver()).
class FaultyDevice final : public Device {
 public:
  FaultyDevice(DeviceLimits limits, SafetyPolicy policy) : limits_(limits), policy_(policy) {}
  std::string name() const override { return "faulty"; }
  DeviceLimits limits() const noexcept override { return limits_; }
  SafetyPolicy safetyPolicy() const noexcept override { return policy_; }
  void glitchAt(int read, double glitch_m) { glitch_read_ = read; glitch_m_ = glitch_m; }
  void missingAt(int read, int count) { missing_from_ = read; missing_count_ = count; }

  bool read(DeviceSample& sample) noexcept override {
    const int i = reads_.load(std::memory_order_relaxed);
    if (i == kSettleRead) {
      paused_.store(true, std::memory_order_release);
      while (!released_.load(std::memory_order_acquire)) std::this_thread::sleep_for(std::chrono::microseconds(100));
    }
    reads_.store(i + 1, std::memory_order_release);
    if (i >= missing_from_ && i < missing_from_ + missing_count_) return false;
    const double a = std::clamp((i - 50) / 200.0, 0.0, 1.0);
    const Eigen::Vector3d p = (1.0 - a) * freePose().p_AB_m + a * pressedPose(kDepth_m).p_AB_m;
    sample.X_WD = Pose::FromTranslation(p);
    if (i == glitch_read_) sample.X_WD.p_AB_m.z() -= glitch_m_;
    sample.time_s = 1e-3 * i;
    sample.valid = true;
    return true;
  }
  void command(const Eigen::Vector3d& force_W_N, const Eigen::Vector3d&) noexcept override {
    const std::size_t i = commands_.load(std::memory_order_relaxed);
    if (i < forces_.size()) forces_[i] = force_W_N.norm();
    commands_.store(i + 1, std::memory_order_release);
  }
  int reads() const { return reads_.load(std::memory_order_acquire); }
  std::size_t commands() const { return commands_.load(std::memory_order_acquire); }
  /// The coupling thread waits in read kSettleRead.
  bool paused() const { return paused_.load(std::memory_order_acquire); }
  /// Lets it go on (and every later read).
  void release() { released_.store(true, std::memory_order_release); }
  /// |force| commanded on the tick of read i.
  double force(std::size_t i) const { return forces_[i]; }

 private:
  DeviceLimits limits_;
  SafetyPolicy policy_;
  int glitch_read_ = -1;
  double glitch_m_ = 0.0;
  int missing_from_ = -1, missing_count_ = 0;
  std::atomic<int> reads_{0};
  std::atomic<bool> paused_{false}, released_{false};
  std::array<double, 1 << 14> forces_{};
  std::atomic<std::size_t> commands_{0};
};

/// Holds the coupling thread in FaultyDevice's read kSettleRead until the solver has taken every
/// sample before it (solver ticks plus skipped samples reach the samples pushed) and the proxy
/// rests on the sphere, then lets it go: the faults after it meet a settled proxy however the two
/// threads were scheduled until then. Always releases the device.
void settleSolver(HapticThread& thread, FaultyDevice& device) {
  EXPECT_TRUE(waitUntil([&] { return device.paused(); }));
  HapticSnapshot s;
  EXPECT_TRUE(waitUntil([&] {
    return thread.latestSnapshot(s) && s.solver_tick + s.skipped_samples >= static_cast<std::uint64_t>(kSettleRead) &&
           s.contacts > 0;
  })) << "solver ticks " << s.solver_tick << ", skipped " << s.skipped_samples << ", contacts " << s.contacts;
  device.release();
}

/// A hardware-like policy whose timing gates cannot trip on a loaded test machine (the tests
/// below are about samples, not about the scheduler).
SafetyPolicy pressingPolicy() {
  SafetyPolicy p = SafetyPolicy::forHardware();
  p.watchdog_s = SafetyPolicy::kNever;
  p.silent_s = SafetyPolicy::kNever;
  return p;
}

struct ThreadedRun {
  std::vector<double> force_N;  // per read
  HapticSnapshot last;
  Pose X_WP_before_glitch;
};

ThreadedRun runThreaded(const std::shared_ptr<FaultyDevice>& device, int until_read, int snapshot_read = -1) {
  const LoadedScene& scene = test::sphereBallScene();
  HapticThread thread(scene.makeRenderer(), device, scene.isovalue, 1000.0);
  ThreadedRun run;
  thread.start();
  settleSolver(thread, *device);
  if (snapshot_read >= 0) {
    EXPECT_TRUE(waitUntil([&] { return device->reads() >= snapshot_read; }));
    thread.latestSnapshot(run.last);
    run.X_WP_before_glitch = run.last.X_WP;
  }
  EXPECT_TRUE(waitUntil([&] { return device->reads() >= until_read; }));
  thread.stop();
  thread.latestSnapshot(run.last);
  for (std::size_t i = 0; i < std::min<std::size_t>(device->commands(), static_cast<std::size_t>(until_read)); ++i)
    run.force_N.push_back(device->force(i));
  return run;
}

// ---- The coupling thread ---------------------------------------------------------------------------

class ThreadedGlitch : public ::testing::TestWithParam<double> {};

TEST_P(ThreadedGlitch, IsNeverRenderedIsCountedAndTheNextSampleRendersNormally) {
  const double glitch_m = GetParam();
  const int glitch_read = 600;
  // The filter allows speed x (wall-clock tick interval) + 1 mm: at the default 5 m/s a coupling
  // tick 1.8 ms late (common on a loaded machine) lets a 1 cm glitch through as a real move. The
  // device states 0.05 m/s, its own scripted speed at 1 kHz (0.05 mm per read, well inside the
  // 1 mm slack at any tick interval): a 1 cm glitch then passes only after a 180 ms stall.
  DeviceLimits limits;
  limits.max_speed_m_per_s = 0.05;
  auto device = std::make_shared<FaultyDevice>(limits, pressingPolicy());
  device->glitchAt(glitch_read, glitch_m);
  const ThreadedRun run = runThreaded(device, 700, glitch_read - 20);
  ASSERT_GE(run.force_N.size(), 700u);
  // Steady pressing force: the coupling to the (still) device, k * depth.
  const double steady_N = run.force_N[glitch_read - 1];
  ASSERT_NEAR(steady_N, kK_N_per_m * kDepth_m, 0.3);
  // Oracle: the coupling to the last good sample, plus what the device could have moved in one
  // tick at its speed limit (k (v_max dt + slack)).
  const double bound_N = steady_N + kK_N_per_m * (limits.max_speed_m_per_s * 1e-3 + SampleFilter::kPositionSlack_m);
  double max_N = 0.0;
  for (int i = glitch_read - 50; i < 700; ++i) max_N = std::max(max_N, run.force_N[static_cast<std::size_t>(i)]);
  std::cout << "[ measured ] glitch " << glitch_m << " m: steady " << steady_N << " N, max commanded " << max_N
            << " N, on the glitch tick " << run.force_N[glitch_read] << " N, next " << run.force_N[glitch_read + 1]
            << " N\n";
  EXPECT_LE(max_N, bound_N);
  EXPECT_LE(run.force_N[glitch_read], steady_N + 1e-9);   // the held command, decaying
  EXPECT_GE(run.force_N[glitch_read], 0.85 * steady_N);   // one tick of the 10 ms hold: 90 %
  EXPECT_NEAR(run.force_N[glitch_read + 1], steady_N, 1e-6 * steady_N);  // rendered normally
  EXPECT_EQ(run.last.implausible_samples, 1u);
  EXPECT_EQ(run.last.bad_device_samples, 1u);
  // The solver never got it: the proxy stayed on the surface.
  EXPECT_NEAR(run.last.X_WP.p_AB_m.z(), run.X_WP_before_glitch.p_AB_m.z(), 1e-9);
}

INSTANTIATE_TEST_SUITE_P(GlitchSizes_m, ThreadedGlitch, ::testing::Values(0.01, 0.1, 1.0, 9.9, 10.1));

// The oracle above can fail: without a speed limit (a device that states none) the same glitch
// is coupled to and commanded (only the renderer's 10 m rule would stop it, and only on the
// solver, after the coupling thread commanded it).
TEST(ThreadedGlitchWithoutSpeedLimit, IsCommandedAsTheFullSpringForce) {
  DeviceLimits unlimited;
  unlimited.max_speed_m_per_s = DeviceLimits::kUnbounded;
  auto device = std::make_shared<FaultyDevice>(unlimited, pressingPolicy());
  device->glitchAt(600, 0.1);
  const ThreadedRun run = runThreaded(device, 650);
  ASSERT_GE(run.force_N.size(), 650u);
  std::cout << "[ measured ] 0.1 m glitch without a speed limit: " << run.force_N[600] << " N commanded\n";
  EXPECT_GT(run.force_N[600], kK_N_per_m * 0.1);
}

TEST(ThreadedFaults, AMissingSampleWhilePressingHoldsTheWall) {
  // Hardware policy: engage gate 0.3 N, 0.25 s ramp. Three samples missing while pressing with
  // ~3 N: the command decays linearly over the 10 ms hold (90 %, 80 %, 70 %) and is back to the
  // full force on the next sample, never zero waiting for the hand to let go.
  auto device = std::make_shared<FaultyDevice>(DeviceLimits{}, pressingPolicy());
  device->missingAt(700, 3);
  const ThreadedRun run = runThreaded(device, 760);
  ASSERT_GE(run.force_N.size(), 760u);
  const double steady_N = run.force_N[699];
  ASSERT_NEAR(steady_N, kK_N_per_m * kDepth_m, 0.3);
  for (int k = 0; k < 3; ++k) {
    const double held = run.force_N[static_cast<std::size_t>(700 + k)];
    EXPECT_NEAR(held, (1.0 - 0.1 * (k + 1)) * steady_N, 1e-6) << "missing tick " << k;
    EXPECT_GE(held, 0.7 * steady_N - 1e-9);
  }
  for (int i = 703; i < 760; ++i) EXPECT_NEAR(run.force_N[static_cast<std::size_t>(i)], steady_N, 1e-6) << i;
  EXPECT_EQ(run.last.held_ticks, 3u);
}

TEST(ThreadedFaults, ALongOutageRampsBackWithoutWaitingForRelease) {
  // 30 missing samples (30 ms, longer than the 10 ms hold): zero after the hold, then the force
  // ramps up from zero over the policy's 0.25 s while the hand keeps pressing.
  auto device = std::make_shared<FaultyDevice>(DeviceLimits{}, pressingPolicy());
  device->missingAt(700, 30);
  const ThreadedRun run = runThreaded(device, 1100);
  ASSERT_GE(run.force_N.size(), 1100u);
  const double steady_N = run.force_N[699];
  EXPECT_EQ(run.force_N[720], 0.0);
  // The ramp advances by the coupling thread's wall-clock tick intervals (ForceSafety::step), so
  // how far up it is after a number of ticks depends on how late they were; what follows from
  // the code: it rises monotonically (the proxy rests, the device is still), starts below the
  // full force (the first good tick is far shorter than the 0.25 s ramp), is at least about half
  // way after 125 ticks (PeriodicClock never wakes early: those took at least 124 ms) and done
  // after 360 (at least 359 ms).
  EXPECT_LT(run.force_N[730], 0.9 * steady_N) << "no ramp: the full force at once";
  for (std::size_t i = 721; i <= 1090; ++i)
    EXPECT_GE(run.force_N[i], run.force_N[i - 1] - 1e-9 * steady_N) << "tick " << i;
  EXPECT_GT(run.force_N[730 + 125], 0.4 * steady_N);
  EXPECT_NEAR(run.force_N[1090], steady_N, 1e-6);
  std::cout << "[ measured ] ramp after the outage: " << run.force_N[730] / steady_N << " of the force on the first "
            << "good tick, " << run.force_N[730 + 125] / steady_N << " after 125 ticks\n";
}

TEST(ThreadedFaults, AGainChangeWithPassivityControlDoesNotStepTheRenderedStiffness) {
  // Pressing at 1000 N/m with passivity control on, the stiffness is raised 20x: the command
  // must not jump to 20x the force (the controller keeps its state, the port its stiffness).
  auto device = std::make_shared<FaultyDevice>(DeviceLimits{}, pressingPolicy());
  const LoadedScene& scene = test::sphereBallScene();
  HapticThread thread(scene.makeRenderer(), device, scene.isovalue, 1000.0);
  thread.setGains({kK_N_per_m, 0.0, true});
  thread.start();
  settleSolver(thread, *device);
  ASSERT_TRUE(waitUntil([&] { return device->reads() >= 600; }));
  const std::size_t before = device->commands();
  thread.setGains({20.0 * kK_N_per_m, 0.0, true});
  ASSERT_TRUE(waitUntil([&] { return device->reads() >= static_cast<int>(before) + 100; }));
  thread.stop();
  const double steady_N = device->force(before - 1);
  double max_after_N = 0.0;
  for (std::size_t i = before; i < before + 100; ++i) max_after_N = std::max(max_after_N, device->force(i));
  std::cout << "[ measured ] 20x gain step while pressing: " << steady_N << " N before, max " << max_after_N
            << " N over the next 100 ticks\n";
  EXPECT_LT(max_after_N, 1.5 * steady_N);
}

/// Glitches every 50th read, misses every 70th, and counts the coupling thread's heap
/// allocations between its reads.
class GlitchingAllocationCountingDevice final : public Device {
 public:
  std::string name() const override { return "glitching, allocation counting"; }
  bool read(DeviceSample& sample) noexcept override {
    if (!guard_) {
      guard_.emplace();  // on the servo thread; counts from here on
    } else {
      allocations_.store(guard_->count(), std::memory_order_relaxed);
    }
    const int i = reads_.fetch_add(1, std::memory_order_relaxed);
    if (i % 70 == 69) return false;
    sample.X_WD = pressedPose(kDepth_m);
    if (i % 50 == 49) sample.X_WD.p_AB_m.z() -= 1.0;
    sample.time_s = 1e-3 * i;
    sample.valid = true;
    return true;
  }
  void command(const Eigen::Vector3d&, const Eigen::Vector3d&) noexcept override {}
  std::size_t allocations() const { return allocations_.load(std::memory_order_relaxed); }
  int reads() const { return reads_.load(std::memory_order_relaxed); }

 private:
  std::optional<test::AllocationGuard> guard_;
  std::atomic<std::size_t> allocations_{0};
  std::atomic<int> reads_{0};
};

TEST(ThreadedFaults, RejectingAndHoldingDoNotAllocate) {
  const LoadedScene& scene = test::sphereBallScene();
  auto device = std::make_shared<GlitchingAllocationCountingDevice>();
  HapticThread thread(scene.makeRenderer(), device, scene.isovalue, 1000.0);
  thread.setGains({kK_N_per_m, 0.0, true});
  thread.start();
  ASSERT_TRUE(waitUntil([&] { return device->reads() > 400; }));
  thread.setGains({5.0 * kK_N_per_m, 0.0, true});  // a gain change with passivity control on
  ASSERT_TRUE(waitUntil([&] { return device->reads() > 800; }));
  HapticSnapshot snap;
  thread.latestSnapshot(snap);
  thread.stop();
  EXPECT_EQ(device->allocations(), 0u) << "heap allocations on the coupling thread over " << device->reads()
                                       << " ticks";
  EXPECT_GE(snap.implausible_samples, 10u);
  EXPECT_GE(snap.held_ticks, 20u);
}

// ---- The headless runner ---------------------------------------------------------------------------

/// The trace CSV as columns by name.
std::map<std::string, std::vector<std::string>> readTrace(const std::filesystem::path& path) {
  std::ifstream in(path);
  std::string line;
  std::getline(in, line);
  std::vector<std::string> names;
  std::stringstream header(line);
  for (std::string name; std::getline(header, name, ',');) names.push_back(name);
  std::map<std::string, std::vector<std::string>> columns;
  while (std::getline(in, line)) {
    std::stringstream row(line);
    std::size_t k = 0;
    for (std::string field; std::getline(row, field, ','); ++k) columns[names.at(k)].push_back(field);
  }
  return columns;
}

double commandNorm(const std::map<std::string, std::vector<std::string>>& trace, std::size_t i) {
  return Eigen::Vector3d(std::stod(trace.at("cmd_fx_N")[i]), std::stod(trace.at("cmd_fy_N")[i]),
                         std::stod(trace.at("cmd_fz_N")[i]))
      .norm();
}

/// Free to pressed over 0.05..0.25 s, held to 0.5 s, with one glitch key at 0.3 s.
Trajectory glitchTrajectory(double glitch_m) {
  std::vector<TrajectorySample> keys;
  keys.push_back({0.0, freePose()});
  keys.push_back({0.05, freePose()});
  keys.push_back({0.25, pressedPose(kDepth_m)});
  keys.push_back({0.299, pressedPose(kDepth_m)});
  Pose glitch = pressedPose(kDepth_m);
  glitch.p_AB_m.z() -= glitch_m;
  keys.push_back({0.300, glitch});
  keys.push_back({0.301, pressedPose(kDepth_m)});
  keys.push_back({0.5, pressedPose(kDepth_m)});
  return Trajectory(keys);
}

class HeadlessGlitch : public ::testing::TestWithParam<double> {};

TEST_P(HeadlessGlitch, IsNeverRenderedIsCountedAndTheNextSampleRendersNormally) {
  const double glitch_m = GetParam();
  RunOptions options;
  options.verify_step_voxels = 0.0;
  options.trace_csv = test::scratchDir() / "trace.csv";
  const RunReport r = runHeadless(test::sphereBallScene(), glitchTrajectory(glitch_m), options);
  const auto trace = readTrace(options.trace_csv);
  ASSERT_EQ(trace.at("cmd_fx_N").size(), r.ticks);
  const std::size_t glitch_tick = 300;
  ASSERT_EQ(trace.at("sample")[glitch_tick], "implausible");
  const double steady_N = commandNorm(trace, glitch_tick - 1);
  ASSERT_NEAR(steady_N, kK_N_per_m * kDepth_m, 0.3);
  const double bound_N = steady_N + kK_N_per_m * (DeviceLimits::kHandleMaxSpeed_m_per_s * 1e-3 + SampleFilter::kPositionSlack_m);
  std::cout << "[ measured ] headless glitch " << glitch_m << " m: steady " << steady_N << " N, max commanded "
            << r.max_command_force_N << " N, on the glitch tick " << commandNorm(trace, glitch_tick) << " N\n";
  EXPECT_LE(r.max_command_force_N, bound_N);
  EXPECT_NEAR(commandNorm(trace, glitch_tick), 0.9 * steady_N, 1e-6);  // held, one tick of 10 ms
  EXPECT_EQ(trace.at("sample")[glitch_tick + 1], "good");
  EXPECT_NEAR(commandNorm(trace, glitch_tick + 1), steady_N, 1e-6);
  EXPECT_EQ(r.implausible_samples, 1u);
  EXPECT_EQ(r.bad_device_samples, 1u);
  // The trace shows the sample as read; the proxy did not follow it.
  EXPECT_NEAR(std::stod(trace.at("zd_m")[glitch_tick]), pressedPose(kDepth_m).p_AB_m.z() - glitch_m, 1e-9);
  EXPECT_EQ(trace.at("zp_m")[glitch_tick], trace.at("zp_m")[glitch_tick - 1]);
}

INSTANTIATE_TEST_SUITE_P(GlitchSizes_m, HeadlessGlitch, ::testing::Values(0.01, 0.1, 1.0, 9.9, 10.1));

TEST(HeadlessGlitchWithoutSpeedLimit, IsRenderedAsTheFullSpringForce) {
  RunOptions options;
  options.verify_step_voxels = 0.0;
  options.device_limits.max_speed_m_per_s = DeviceLimits::kUnbounded;
  const RunReport r = runHeadless(test::sphereBallScene(), glitchTrajectory(1.0), options);
  std::cout << "[ measured ] headless 1 m glitch without a speed limit: max commanded " << r.max_command_force_N
            << " N\n";
  EXPECT_GT(r.max_command_force_N, kK_N_per_m * 1.0);
  EXPECT_EQ(r.implausible_samples, 0u);
}

TEST(HeadlessIsovalue, TheTraceGivesTheIsovalueAskedForEachTick) {
  // Ninth column: none at 0 s (the scene's, 0), 1.0 at 0.1 s and 0.2 s, none again at 0.3 s.
  std::istringstream csv(
      "t_s,x_m,y_m,z_m,qw,qx,qy,qz,isovalue\n"
      "0,0,0,0.03,1,0,0,0,\n"
      "0.1,0,0,0.03,1,0,0,0,1.0\n"
      "0.2,0,0,0.03,1,0,0,0,1\n"
      "0.3,0,0,0.03,1,0,0,0,\n");
  const Trajectory trajectory = parseTrajectoryCsv(csv, "iso.csv");
  RunOptions options;
  options.verify_step_voxels = 0.0;
  options.trace_csv = test::scratchDir() / "trace.csv";
  const RunReport r = runHeadless(test::sphereBallScene(), trajectory, options);
  const auto trace = readTrace(options.trace_csv);
  ASSERT_EQ(r.ticks, 301u);
  // Linear between keys, a blank key counting as the scene's isovalue (0).
  const auto expected = [](std::size_t tick) {
    const double t = 1e-3 * static_cast<double>(tick);
    if (t <= 0.1) return t / 0.1;
    if (t <= 0.2) return 1.0;
    return 1.0 - (t - 0.2) / 0.1;
  };
  for (const std::size_t tick : {0u, 25u, 50u, 100u, 150u, 200u, 250u, 300u}) {
    EXPECT_NEAR(std::stod(trace.at("isovalue")[tick]), expected(tick), 1e-6) << "tick " << tick;
    EXPECT_EQ(trace.at("felt_isovalue")[tick], trace.at("isovalue")[tick]) << "tick " << tick;
  }
}

}  // namespace
}  // namespace vh::runtime
