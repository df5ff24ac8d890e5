// Tests of the device layer in vh/runtime/device.h: the one safety layer (ForceSafety: engage
// gate, ramp, clamp, watchdog, silent device, NaN, actuated DOF), gain clamping, the workspace
// mapping and MappedDevice, velocities of the devices without hardware, and the haptic thread
// routing every command through the safety layer with a scripted device that stops answering,
// sends NaN or asks for 100 N.
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <functional>
#include <limits>
#include <numbers>
#include <random>
#include <thread>

#include <gtest/gtest.h>

#include "vh/runtime/device.h"
#include "vh/runtime/haptic_thread.h"
#include "vh/runtime/scene.h"

namespace vh::runtime {
namespace {

using namespace std::chrono_literals;
using haptics::Pose;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kTick_s = 1e-3;

DeviceLimits falconLikeLimits() {
  DeviceLimits l;
  l.max_force_N = 8.0;
  l.max_torque_Nm = 0.0;
  l.max_linear_stiffness_N_per_m = 3000.0;
  l.max_angular_stiffness_Nm_per_rad = 0.0;
  l.workspace_radius_m = 0.04;
  return l;
}

/// Safety input for one tick of a device whose sample time advances by one tick.
struct Ticker {
  double t_s = 0.0;
  SafetyInput next(const Eigen::Vector3d& f, const Eigen::Vector3d& tau = Eigen::Vector3d::Zero()) {
    SafetyInput in;
    t_s += kTick_s;
    in.sample_ok = true;
    in.sample_time_s = t_s;
    in.tick_interval_s = kTick_s;
    in.force_W_N = f;
    in.torque_W_Nm = tau;
    return in;
  }
};

// ---- ForceSafety -------------------------------------------------------------------------------

TEST(ForceSafety, DefaultPolicyPassesForcesOfDevicesWithoutHardwareUnchanged) {
  ForceSafety safety;  // unbounded limits, no gates
  safety.enable();
  Ticker t;
  Eigen::Vector3d f, tau;
  safety.step(t.next({100.0, -3.0, 2.0}, {0.5, 0.0, -0.25}), f, tau);
  EXPECT_EQ(f, Eigen::Vector3d(100.0, -3.0, 2.0));
  EXPECT_EQ(tau, Eigen::Vector3d(0.5, 0.0, -0.25));
  EXPECT_EQ(safety.state(), ForceSafety::State::kEngaged);
}

TEST(ForceSafety, DisabledOrNotEnabledSendsZero) {
  ForceSafety safety;
  Ticker t;
  Eigen::Vector3d f, tau;
  safety.step(t.next({1.0, 0.0, 0.0}), f, tau);
  EXPECT_EQ(f, Eigen::Vector3d::Zero());
  safety.enable();
  safety.step(t.next({1.0, 0.0, 0.0}), f, tau);
  EXPECT_EQ(f, Eigen::Vector3d(1.0, 0.0, 0.0));
  safety.disable();
  safety.step(t.next({1.0, 0.0, 0.0}), f, tau);
  EXPECT_EQ(f, Eigen::Vector3d::Zero());
  EXPECT_EQ(safety.state(), ForceSafety::State::kOff);
}

TEST(ForceSafety, ForcesStayOffUntilTheComputedForceIsSmallThenRampUp) {
  ForceSafety safety(falconLikeLimits(), SafetyPolicy::forHardware(), kDofTranslation);
  safety.enable();
  Ticker t;
  Eigen::Vector3d f, tau;
  // Enabled while the hand is pressed into a wall: 5 N computed, nothing sent.
  for (int i = 0; i < 500; ++i) {
    safety.step(t.next({0.0, 0.0, 5.0}), f, tau);
    ASSERT_EQ(f, Eigen::Vector3d::Zero()) << "tick " << i;
  }
  EXPECT_EQ(safety.state(), ForceSafety::State::kWaitingForSmallForce);
  // The hand leaves the wall: the computed force drops below 0.3 N and the layer engages.
  safety.step(t.next({0.0, 0.0, 0.2}), f, tau);
  EXPECT_EQ(safety.state(), ForceSafety::State::kRamping);
  EXPECT_LT(f.norm(), 0.2 * 0.01);  // first ramp tick: 1 ms of 250 ms
  // Pressing again at 5 N: the output ramps up linearly over 0.25 s.
  double previous = f.norm();
  for (int i = 2; i <= 250; ++i) {
    safety.step(t.next({0.0, 0.0, 5.0}), f, tau);
    EXPECT_NEAR(f.z(), 5.0 * i / 250.0, 1e-9) << "ramp tick " << i;
    EXPECT_GE(f.norm(), previous);
    previous = f.norm();
  }
  EXPECT_EQ(safety.state(), ForceSafety::State::kEngaged);
  safety.step(t.next({0.0, 0.0, 5.0}), f, tau);
  EXPECT_EQ(f, Eigen::Vector3d(0.0, 0.0, 5.0));
}

TEST(ForceSafety, AHundredNewtonsAreClampedToTheDeviceMaximumKeepingTheDirection) {
  SafetyPolicy policy = SafetyPolicy::forHardware();
  policy.ramp_time_s = 0.0;
  ForceSafety safety(falconLikeLimits(), policy, kDofTranslation);
  safety.enable();
  Ticker t;
  Eigen::Vector3d f, tau;
  safety.step(t.next(Eigen::Vector3d::Zero()), f, tau);  // engages
  const Eigen::Vector3d request = Eigen::Vector3d(60.0, -80.0, 0.0);  // 100 N
  safety.step(t.next(request), f, tau);
  EXPECT_NEAR(f.norm(), 8.0, 1e-12);
  EXPECT_NEAR(f.normalized().dot(request.normalized()), 1.0, 1e-12);
  EXPECT_EQ(safety.stats().clamped_ticks, 1u);
}

TEST(ForceSafety, AHundredNewtonsRightAfterEngagingAreClampedAndRamped) {
  ForceSafety safety(falconLikeLimits(), SafetyPolicy::forHardware(), kDofTranslation);
  safety.enable();
  Ticker t;
  Eigen::Vector3d f, tau;
  safety.step(t.next(Eigen::Vector3d::Zero()), f, tau);  // small: engages, ramp tick 1
  for (int i = 2; i <= 300; ++i) {
    safety.step(t.next({0.0, 100.0, 0.0}), f, tau);
    const double expected = 8.0 * std::min(1.0, i / 250.0);
    ASSERT_NEAR(f.y(), expected, 1e-9) << "tick " << i;
  }
}

TEST(ForceSafety, AMissingSampleHoldsTheLastCommandAndDecaysIt) {
  // Pressing on a wall with 4 N: one missing sample must not drop the wall (nor wait for the
  // hand to let go): the held command decays linearly over the 10 ms hold.
  SafetyPolicy policy = SafetyPolicy::forHardware();
  policy.ramp_time_s = 0.0;
  ForceSafety safety(falconLikeLimits(), policy, kDofTranslation);
  safety.enable();
  Ticker t;
  Eigen::Vector3d f, tau;
  safety.step(t.next({0.0, 0.0, 0.1}), f, tau);
  safety.step(t.next({0.0, 0.0, 4.0}), f, tau);
  ASSERT_EQ(f.z(), 4.0);
  SafetyInput gone = t.next({0.0, 0.0, 0.0});  // no sample: nothing computed
  gone.sample_ok = false;
  safety.step(gone, f, tau);
  EXPECT_NEAR(f.z(), 0.9 * 4.0, 1e-12);  // 1 ms of the 10 ms hold
  EXPECT_EQ(safety.stats().missing_samples, 1u);
  EXPECT_EQ(safety.stats().held_ticks, 1u);
  // Samples again, still pressing with 4 N: the full force at once.
  safety.step(t.next({0.0, 0.0, 4.0}), f, tau);
  EXPECT_EQ(f.z(), 4.0);
  EXPECT_EQ(safety.state(), ForceSafety::State::kEngaged);
}

TEST(ForceSafety, TheHoldDecaysLinearlyToZeroOverTheHoldTime) {
  SafetyPolicy policy = SafetyPolicy::forHardware();
  policy.ramp_time_s = 0.0;
  ForceSafety safety(falconLikeLimits(), policy, kDofTranslation);
  safety.enable();
  Ticker t;
  Eigen::Vector3d f, tau;
  safety.step(t.next(Eigen::Vector3d::Zero()), f, tau);
  safety.step(t.next({2.0, 0.0, 0.0}), f, tau);
  for (int k = 1; k <= 15; ++k) {
    SafetyInput gone = t.next(Eigen::Vector3d::Zero());
    gone.sample_ok = false;
    gone.period_s = kTick_s;
    safety.step(gone, f, tau);
    EXPECT_NEAR(f.x(), 2.0 * std::max(0.0, 1.0 - k * kTick_s / policy.fault_hold_s), 1e-12) << "fault tick " << k;
  }
  EXPECT_EQ(safety.stats().outages, 1u);
}

TEST(ForceSafety, ALongOutageRampsUpFromTheHeldValueWithoutTheEngageGate) {
  // 30 ms without samples (longer than the hold): zero, then, while the hand still presses with
  // 5 N, the output ramps from the held value (zero by then) over the 0.25 s ramp; it never
  // waits for the force to drop under 0.3 N.
  ForceSafety safety(falconLikeLimits(), SafetyPolicy::forHardware(), kDofTranslation);
  safety.enable();
  Ticker t;
  Eigen::Vector3d f, tau;
  safety.step(t.next(Eigen::Vector3d::Zero()), f, tau);
  for (int i = 0; i < 300; ++i) safety.step(t.next({0.0, 0.0, 5.0}), f, tau);
  ASSERT_EQ(f.z(), 5.0);
  for (int i = 0; i < 30; ++i) {
    SafetyInput gone = t.next(Eigen::Vector3d::Zero());
    gone.sample_ok = false;
    safety.step(gone, f, tau);
  }
  EXPECT_TRUE(f.isZero(0.0));
  EXPECT_EQ(safety.state(), ForceSafety::State::kRamping);
  for (int i = 1; i <= 250; ++i) {
    safety.step(t.next({0.0, 0.0, 5.0}), f, tau);
    ASSERT_NEAR(f.z(), 5.0 * i / 250.0, 1e-9) << "ramp tick " << i;
  }
  EXPECT_EQ(safety.state(), ForceSafety::State::kEngaged);
}

TEST(ForceSafety, ASilentDeviceIsHeldThenZeroedAfterItsTimeout) {
  SafetyPolicy policy = SafetyPolicy::forHardware();
  policy.ramp_time_s = 0.0;
  ForceSafety safety(falconLikeLimits(), policy, kDofTranslation);
  safety.enable();
  Ticker t;
  Eigen::Vector3d f, tau;
  safety.step(t.next(Eigen::Vector3d::Zero()), f, tau);
  // Valid samples whose time no longer advances (the device stopped answering; the driver
  // hands out its last sample).
  const double frozen = t.t_s;
  int zero_from = -1;
  for (int i = 0; i < 100; ++i) {
    SafetyInput in = t.next({0.0, 2.0, 0.0});
    in.sample_time_s = frozen;
    safety.step(in, f, tau);
    if (f.isZero(0.0) && zero_from < 0) zero_from = i;
    if (zero_from >= 0) {
      EXPECT_TRUE(f.isZero(0.0)) << "tick " << i;
    }
  }
  // Silent once stale for 50 ms (tick 49 or 50, up to rounding of the summed intervals): that
  // tick is the hold's first, the tenth (10 ms) is zero.
  EXPECT_NEAR(zero_from, 59, 1);
  EXPECT_EQ(safety.stats().silent_trips, 1u);
  // It speaks again: the output comes back (ramp 0 here) without waiting for a small force.
  safety.step(t.next({0.0, 2.0, 0.0}), f, tau);
  EXPECT_EQ(f, Eigen::Vector3d(0.0, 2.0, 0.0));
  EXPECT_EQ(safety.state(), ForceSafety::State::kEngaged);
}

TEST(ForceSafety, ALateTickHoldsTheLastCommand) {
  SafetyPolicy policy = SafetyPolicy::forHardware();
  policy.ramp_time_s = 0.0;
  ForceSafety safety(falconLikeLimits(), policy, kDofTranslation);
  safety.enable();
  Ticker t;
  Eigen::Vector3d f, tau;
  safety.step(t.next(Eigen::Vector3d::Zero()), f, tau);
  safety.step(t.next({1.0, 0.0, 0.0}), f, tau);
  ASSERT_EQ(f.x(), 1.0);
  SafetyInput late = t.next({3.0, 0.0, 0.0});  // computed after the stall: not sent
  late.tick_interval_s = 0.015;  // 14 ticks missed (watchdog 10 ms)
  late.period_s = kTick_s;
  safety.step(late, f, tau);
  EXPECT_NEAR(f.x(), 0.9, 1e-12);  // the held command, one tick into the hold
  EXPECT_EQ(safety.stats().watchdog_trips, 1u);
  EXPECT_EQ(safety.state(), ForceSafety::State::kEngaged);
  safety.step(t.next({3.0, 0.0, 0.0}), f, tau);
  EXPECT_EQ(f.x(), 3.0);
  // A stall longer than the silent time (50 ms) is an outage: zero, no hold.
  SafetyInput stalled = t.next({3.0, 0.0, 0.0});
  stalled.tick_interval_s = 0.2;
  safety.step(stalled, f, tau);
  EXPECT_TRUE(f.isZero(0.0));
  EXPECT_EQ(safety.stats().outages, 1u);
}

TEST(ForceSafety, AReseededSampleReArmsTheGate) {
  SafetyPolicy policy = SafetyPolicy::forHardware();
  policy.ramp_time_s = 0.0;
  ForceSafety safety(falconLikeLimits(), policy, kDofTranslation);
  safety.enable();
  Ticker t;
  Eigen::Vector3d f, tau;
  safety.step(t.next(Eigen::Vector3d::Zero()), f, tau);
  SafetyInput moved = t.next({0.0, 0.0, 4.0});
  moved.reseeded = true;
  safety.step(moved, f, tau);
  EXPECT_TRUE(f.isZero(0.0));
  EXPECT_EQ(safety.state(), ForceSafety::State::kWaitingForSmallForce);
}

TEST(ForceSafety, NonFiniteForcesAreNeverSent) {
  ForceSafety safety(falconLikeLimits(), SafetyPolicy::forHardware(), kDofTranslation);
  safety.enable();
  Ticker t;
  Eigen::Vector3d f, tau;
  safety.step(t.next(Eigen::Vector3d::Zero()), f, tau);
  for (const Eigen::Vector3d& bad : {Eigen::Vector3d(kNaN, 0.0, 0.0),
                                    Eigen::Vector3d(0.0, std::numeric_limits<double>::infinity(), 0.0)}) {
    safety.step(t.next(bad), f, tau);
    EXPECT_TRUE(f.isZero(0.0));
    EXPECT_TRUE(tau.isZero(0.0));
  }
  safety.step(t.next(Eigen::Vector3d::Zero(), Eigen::Vector3d(kNaN, 0.0, 0.0)), f, tau);  // NaN torque of a 3-DOF device
  EXPECT_TRUE(f.isZero(0.0));
  EXPECT_EQ(safety.stats().nonfinite_commands, 3u);
}

TEST(ForceSafety, ANewConnectionReArmsTheGate) {
  SafetyPolicy policy = SafetyPolicy::forHardware();
  policy.ramp_time_s = 0.0;
  ForceSafety safety(falconLikeLimits(), policy, kDofTranslation);
  safety.enable();
  Ticker t;
  Eigen::Vector3d f, tau;
  safety.step(t.next(Eigen::Vector3d::Zero()), f, tau);
  safety.step(t.next({2.0, 0.0, 0.0}), f, tau);
  ASSERT_EQ(f.x(), 2.0);
  SafetyInput reconnected = t.next({2.0, 0.0, 0.0});
  reconnected.connection = 1;
  safety.step(reconnected, f, tau);
  EXPECT_TRUE(f.isZero(0.0));
}

TEST(ForceSafety, AThreeDofDeviceGetsNoTorqueButItsForce) {
  DeviceLimits limits;  // unbounded
  ForceSafety safety(limits, {}, kDofTranslation);
  safety.enable();
  Ticker t;
  Eigen::Vector3d f, tau;
  safety.step(t.next({1.0, 2.0, 3.0}, {0.1, 0.2, 0.3}), f, tau);
  EXPECT_EQ(f, Eigen::Vector3d(1.0, 2.0, 3.0));
  EXPECT_EQ(tau, Eigen::Vector3d::Zero());
  EXPECT_EQ(safety.stats().dropped_dof_ticks, 1u);
  // An input-only device (SpaceMouse) gets nothing.
  ForceSafety input_only(limits, {}, kDofNone);
  input_only.enable();
  input_only.step(t.next({1.0, 2.0, 3.0}, {0.1, 0.2, 0.3}), f, tau);
  EXPECT_TRUE(f.isZero(0.0));
  EXPECT_TRUE(tau.isZero(0.0));
}

TEST(ForceSafety, EveryOutputIsFiniteAndWithinTheLimitsForRandomInputs) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-200.0, 200.0);
  std::uniform_int_distribution<int> pick(0, 19);
  DeviceLimits limits = falconLikeLimits();
  limits.max_torque_Nm = 0.5;
  ForceSafety safety(limits, SafetyPolicy::forHardware(), kDofAll);
  safety.enable();
  Ticker t;
  Eigen::Vector3d f, tau;
  for (int i = 0; i < 100000; ++i) {
    Eigen::Vector3d fin(u(rng), u(rng), u(rng));
    Eigen::Vector3d tin(u(rng), u(rng), u(rng));
    if (pick(rng) == 0) fin[pick(rng) % 3] = kNaN;
    if (pick(rng) == 0) tin[pick(rng) % 3] = -std::numeric_limits<double>::infinity();
    if (pick(rng) < 5) {  // sometimes small enough to engage
      fin *= 1e-3;
      tin *= 1e-4;
    }
    SafetyInput in = t.next(fin, tin);
    if (pick(rng) == 0) in.sample_ok = false;
    if (pick(rng) == 0) in.tick_interval_s = 0.02;
    safety.step(in, f, tau);
    ASSERT_TRUE(f.allFinite() && tau.allFinite()) << i;
    ASSERT_LE(f.norm(), 8.0 + 1e-12) << i;
    ASSERT_LE(tau.norm(), 0.5 + 1e-12) << i;
  }
  EXPECT_GT(safety.stats().clamped_ticks, 0u);
}

TEST(ClampGains, LimitsStiffnessToTheDevicesAndRejectsNonsense) {
  const DeviceLimits limits = falconLikeLimits();
  const haptics::CouplingGains g = clampGains({5000.0, 2.0}, limits);
  EXPECT_EQ(g.linear_N_per_m, 3000.0);
  EXPECT_EQ(g.angular_Nm_per_rad, 0.0);
  const haptics::CouplingGains ok = clampGains({1000.0, 1.0}, DeviceLimits{});
  EXPECT_EQ(ok.linear_N_per_m, 1000.0);
  EXPECT_EQ(ok.angular_Nm_per_rad, 1.0);
  const haptics::CouplingGains bad = clampGains({kNaN, -1.0}, DeviceLimits{});
  EXPECT_EQ(bad.linear_N_per_m, 0.0);
  EXPECT_EQ(bad.angular_Nm_per_rad, 0.0);
  // With the passivity controller on, up to the headroom past the rating, and no further.
  const haptics::CouplingGains pc = clampGains({50000.0, 2.0, true}, limits);
  EXPECT_EQ(pc.linear_N_per_m, 50000.0);
  EXPECT_TRUE(pc.passivity_control);
  const haptics::CouplingGains pc_far = clampGains({1e7, 0.0, true}, limits);
  EXPECT_EQ(pc_far.linear_N_per_m, kPassivityStiffnessHeadroom * 3000.0);
}

// ---- Workspace mapping ---------------------------------------------------------------------------

WorkspaceMapping exampleMapping() {
  WorkspaceMapping m;
  m.scale = 2.0;
  m.X_WB.R_AB = Eigen::Quaterniond(Eigen::AngleAxisd(0.5 * std::numbers::pi, Eigen::Vector3d::UnitX()));
  m.X_WB.p_AB_m = {0.1, -0.2, 0.3};
  m.R_HD = Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ()));
  return m;
}

TEST(WorkspaceMapping, ScalesRotatesAndOffsetsThePose) {
  const WorkspaceMapping m = exampleMapping();
  // Falcon-like base: y up in B becomes z up in W.
  Pose X_BH = Pose::FromTranslation({0.0, 0.01, 0.0});
  Pose X_WD = m.toWorld(X_BH);
  EXPECT_TRUE(X_WD.p_AB_m.isApprox(Eigen::Vector3d(0.1, -0.2, 0.32), 1e-12));
  EXPECT_TRUE(X_WD.R_AB.isApprox(m.X_WB.R_AB * m.R_HD, 1e-12));
  // A handle rotation composes between R_WB and R_HD.
  X_BH.R_AB = Eigen::Quaterniond(Eigen::AngleAxisd(0.2, Eigen::Vector3d::UnitY()));
  X_WD = m.toWorld(X_BH);
  EXPECT_TRUE(X_WD.R_AB.isApprox(m.X_WB.R_AB * X_BH.R_AB * m.R_HD, 1e-12));
  // Velocities: scaled and rotated; angular rotated only.
  EXPECT_TRUE(m.linearVelocityToWorld({0.0, 0.0, 1.0}).isApprox(Eigen::Vector3d(0.0, -2.0, 0.0), 1e-12));
  EXPECT_TRUE(m.angularVelocityToWorld({0.0, 1.0, 0.0}).isApprox(Eigen::Vector3d(0.0, 0.0, 1.0), 1e-12));
  // Forces go back rotated, not scaled.
  EXPECT_TRUE(m.vectorToDevice({0.0, 0.0, 3.0}).isApprox(Eigen::Vector3d(0.0, 3.0, 0.0), 1e-12));
}

TEST(WorkspaceMapping, LimitsInTheWorldAccountForTheScale) {
  const WorkspaceMapping m = exampleMapping();
  const DeviceLimits w = m.limitsInWorld(falconLikeLimits());
  EXPECT_EQ(w.max_force_N, 8.0);
  EXPECT_EQ(w.max_linear_stiffness_N_per_m, 1500.0);  // k * scale felt at the device <= 3000
  EXPECT_EQ(w.workspace_radius_m, 0.08);
}

TEST(WorkspaceMapping, InvalidMappingsAreRejectedWithTheField) {
  WorkspaceMapping m;
  m.scale = 0.0;
  EXPECT_FALSE(m.valid());
  try {
    m.validate();
    FAIL() << "no exception";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("scale"), std::string::npos) << e.what();
  }
  m.scale = 1.0;
  m.X_WB.R_AB = Eigen::Quaterniond(0.0, 0.0, 0.0, 0.0);
  EXPECT_THROW(m.validate(), std::invalid_argument);
  m.X_WB.R_AB = Eigen::Quaterniond::Identity();
  m.X_WB.p_AB_m.x() = kNaN;
  EXPECT_THROW(m.validate(), std::invalid_argument);
}

Trajectory lineTrajectory() {
  return Trajectory({{0.0, Pose::FromTranslation({0.0, 0.0, 0.0})}, {1.0, Pose::FromTranslation({0.0, 0.01, 0.0})}});
}

TEST(MappedDevice, MapsSamplesIntoTheSceneAndCommandsBackToTheDevice) {
  auto raw = std::make_shared<ScriptedDevice>(lineTrajectory());
  raw->setLimits(falconLikeLimits());
  raw->setActuatedDof(kDofTranslation);
  MappedDevice device(raw, exampleMapping());
  EXPECT_EQ(device.actuatedDof(), kDofTranslation);
  EXPECT_EQ(device.limits().max_linear_stiffness_N_per_m, 1500.0);
  DeviceSample s;
  ASSERT_TRUE(device.read(s));
  ASSERT_TRUE(device.read(s));  // t = 1 ms: y = 10 um in B
  EXPECT_TRUE(s.X_WD.p_AB_m.isApprox(Eigen::Vector3d(0.1, -0.2, 0.3 + 2.0 * 1e-5), 1e-12));
  EXPECT_TRUE(s.v_WD_m_per_s.isApprox(Eigen::Vector3d(0.0, 0.0, 0.02), 1e-9));  // 0.01 m/s, scaled by 2, y -> z
  device.command({0.0, 0.0, 4.0}, Eigen::Vector3d::Zero());
  DeviceCommand c;
  ASSERT_TRUE(raw->lastCommand(c));
  EXPECT_TRUE(c.force_W_N.isApprox(Eigen::Vector3d(0.0, 4.0, 0.0), 1e-12));  // W's up is B's y
}

TEST(MappedDevice, ANewMappingTakesEffectAtTheNextReadAndChangesTheConnection) {
  auto raw = std::make_shared<ScriptedDevice>(lineTrajectory());
  MappedDevice device(raw, WorkspaceMapping{});
  DeviceSample s;
  ASSERT_TRUE(device.read(s));
  const std::uint32_t before = s.connection;
  WorkspaceMapping m;
  m.X_WB.p_AB_m = {1.0, 2.0, 3.0};
  device.setMapping(m);
  EXPECT_EQ(device.mapping().X_WB.p_AB_m, Eigen::Vector3d(1.0, 2.0, 3.0));
  ASSERT_TRUE(device.read(s));
  EXPECT_NE(s.connection, before);
  EXPECT_NEAR(s.X_WD.p_AB_m.x(), 1.0, 1e-12);
  ASSERT_TRUE(device.read(s));
  EXPECT_EQ(device.read(s), true);
  WorkspaceMapping bad;
  bad.scale = -1.0;
  EXPECT_THROW(device.setMapping(bad), std::invalid_argument);
  EXPECT_THROW(MappedDevice(nullptr, WorkspaceMapping{}), std::invalid_argument);
}

TEST(DevicesWithoutHardware, ReportVelocitiesAndDefaultCapabilities) {
  ScriptedDevice scripted(lineTrajectory());
  DeviceSample s;
  ASSERT_TRUE(scripted.read(s));
  EXPECT_EQ(s.v_WD_m_per_s, Eigen::Vector3d::Zero());
  ASSERT_TRUE(scripted.read(s));
  EXPECT_TRUE(s.v_WD_m_per_s.isApprox(Eigen::Vector3d(0.0, 0.01, 0.0), 1e-9));
  EXPECT_EQ(scripted.actuatedDof(), kDofAll);
  EXPECT_TRUE(std::isinf(scripted.limits().max_force_N));
  EXPECT_EQ(scripted.identity().backend, "virtual");

  SimulatedDevice simulated(Pose::Identity());
  ASSERT_TRUE(simulated.read(s));
  simulated.setPose(Pose::FromTranslation({0.01, 0.0, 0.0}));
  std::this_thread::sleep_for(2ms);
  ASSERT_TRUE(simulated.read(s));
  EXPECT_GT(s.v_WD_m_per_s.x(), 0.0);
  EXPECT_TRUE(s.v_WD_m_per_s.allFinite());
  EXPECT_EQ(simulated.identity().model, simulated.name());
}

// ---- The haptic thread routes every command through the safety layer ----------------------------

/// The built-in sphere (radius 20 mm, F = signed distance in mm, isovalue 0) with the 5 mm ball
/// tool; coupling 5000 N/m (100 N at 20 mm).
const LoadedScene& sphereScene() {
  static const LoadedScene scene = [] {
    SceneSpec spec;
    spec.volume.path = "builtin:sphere";
    spec.tool.mesh = "builtin:sphere";
    spec.tool.point_spacing_m = 0.0015;
    spec.gains.linear_N_per_m = 5000.0;
    spec.tool.X_WT_initial = Pose::FromTranslation({0.0, 0.0, 0.030});
    spec.tool.initial_pose_set = true;
    spec.device = DeviceSpec{};
    return loadScene(spec);
  }();
  return scene;
}

/// A scripted device standing in for hardware, with faults injected from a given read on, that
/// records the norm of every command.
class FaultyDevice final : public Device {
 public:
  enum class Fault { kNone, kStopsAnswering, kNaNPose, kFrozenTime };
  FaultyDevice(std::shared_ptr<ScriptedDevice> inner, Fault fault, std::uint64_t from_read)
      : inner_(std::move(inner)), fault_(fault), from_(from_read) {}
  std::string name() const override { return "faulty " + inner_->name(); }
  DeviceLimits limits() const noexcept override { return inner_->limits(); }
  SafetyPolicy safetyPolicy() const noexcept override { return inner_->safetyPolicy(); }
  DofMask actuatedDof() const noexcept override { return inner_->actuatedDof(); }
  bool read(DeviceSample& sample) noexcept override {
    const std::uint64_t n = reads_.load(std::memory_order_relaxed);
    reads_.store(n + 1, std::memory_order_relaxed);
    const bool faulty = fault_ != Fault::kNone && n >= from_;
    if (faulty && fault_ == Fault::kStopsAnswering) return false;
    if (faulty && fault_ == Fault::kFrozenTime) {
      sample = frozen_;
      return true;
    }
    inner_->read(sample);
    if (faulty && fault_ == Fault::kNaNPose) sample.X_WD.p_AB_m.x() = kNaN;
    frozen_ = sample;
    return true;
  }
  void command(const Eigen::Vector3d& force_W_N, const Eigen::Vector3d& torque_W_Nm) noexcept override {
    const std::uint64_t tick = reads_.load(std::memory_order_relaxed) - 1;  // the tick's read
    if (tick < forces_.size()) {
      forces_[tick] = force_W_N.norm();
      torques_[tick] = torque_W_Nm.norm();
    }
    commands_.store(tick + 1, std::memory_order_release);
  }
  std::uint64_t commands() const { return commands_.load(std::memory_order_acquire); }
  double force(std::uint64_t tick) const { return forces_[tick]; }
  double torque(std::uint64_t tick) const { return torques_[tick]; }

 private:
  std::shared_ptr<ScriptedDevice> inner_;
  Fault fault_;
  std::uint64_t from_;
  DeviceSample frozen_;
  std::atomic<std::uint64_t> reads_{0};
  std::atomic<std::uint64_t> commands_{0};
  std::array<double, 1 << 13> forces_{};
  std::array<double, 1 << 13> torques_{};
};

/// Starts at the scene's initial pose (tool 5 mm above the sphere), presses 20 mm into the
/// surface over 50 ms (about 100 N at 5000 N/m) and holds.
std::shared_ptr<ScriptedDevice> pressingDevice() {
  const Trajectory trajectory({{0.0, Pose::FromTranslation({0.0, 0.0, 0.030})},
                               {0.050, Pose::FromTranslation({0.0, 0.0, 0.025 - 0.020})},
                               {10.0, Pose::FromTranslation({0.0, 0.0, 0.025 - 0.020})}});
  auto device = std::make_shared<ScriptedDevice>(trajectory, kTick_s, "press");
  DeviceLimits limits = falconLikeLimits();
  limits.max_linear_stiffness_N_per_m = 10000.0;  // keep the scene's 5000 N/m
  limits.max_torque_Nm = 0.2;
  device->setLimits(limits);
  SafetyPolicy policy = SafetyPolicy::forHardware();
  policy.ramp_time_s = 1.0;   // long, so that the ramp is visible whatever the machine's load
  policy.watchdog_s = 0.5;    // lenient: late ticks on a loaded machine must not re-arm here
  device->setSafetyPolicy(policy);
  device->setActuatedDof(kDofTranslation);
  return device;
}

/// Polls `condition` until it holds or `timeout` passes (generous: a loaded machine runs the
/// haptic threads late, and a condition that holds returns at once).
bool waitFor(const std::function<bool()>& condition, std::chrono::milliseconds timeout = 30000ms) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  while (std::chrono::steady_clock::now() < deadline) {
    if (condition()) return true;
    std::this_thread::sleep_for(2ms);
  }
  return condition();
}

TEST(HapticThreadSafety, AHundredNewtonsAreRampedAndClampedToTheDeviceMaximum) {
  auto device = std::make_shared<FaultyDevice>(pressingDevice(), FaultyDevice::Fault::kNone, 0);
  auto thread = sphereScene().makeHapticThread(device);
  thread->start();
  ASSERT_TRUE(waitFor([&] { return device->commands() > 1600; }));
  HapticSnapshot snap;
  thread->latestSnapshot(snap);
  thread->stop();
  // The renderer asks for about 100 N once the device is 20 mm in ...
  // ... but no command ever exceeds the device's 8 N, and none has torque (3-DOF device).
  double max_force = 0.0;
  for (std::uint64_t i = 0; i < 1600; ++i) {
    max_force = std::max(max_force, device->force(i));
    ASSERT_EQ(device->torque(i), 0.0) << "tick " << i;
  }
  EXPECT_LE(max_force, 8.0 + 1e-9);
  // Ramped: 20 ticks in, the device 5 mm below the resting proxy, the request (25 N or more) is
  // far above 8 N but the output is still ramping up (1 s ramp), and it grows monotonically
  // while the device presses in. The ramp runs on the coupling thread's wall-clock tick
  // intervals: those 20 ticks would have to average 25 ms for it to be half way.
  EXPECT_GT(device->force(20), 0.0);
  EXPECT_LT(device->force(20), 0.5 * 8.0) << "not ramped";
  for (std::uint64_t i = 100; i < 400; ++i) EXPECT_GE(device->force(i + 1), device->force(i) - 1e-9) << "tick " << i;
  // Clamped: after the ramp, exactly the maximum.
  EXPECT_NEAR(device->force(1500), 8.0, 1e-6);
  EXPECT_NEAR(snap.force_W_N.norm(), 8.0, 1e-6);  // the snapshot shows what was sent
  EXPECT_GT(snap.force_W_N.z(), 0.0);             // pushing the hand out of the sphere
}

/// A fault from tick 700 on: the command of tick 699 held, decaying linearly over the 10 ms
/// hold (SafetyPolicy::fault_hold_s), then zero.
void expectHeldThenZero(const FaultyDevice& device) {
  const double pressing = device.force(699);
  EXPECT_GT(pressing, 1.0);  // pressing, ramping up
  for (std::uint64_t k = 0; k < 9; ++k)
    EXPECT_NEAR(device.force(700 + k), (1.0 - 0.1 * static_cast<double>(k + 1)) * pressing, 1e-9) << "hold tick " << k;
  for (std::uint64_t i = 710; i < 800; ++i) ASSERT_EQ(device.force(i), 0.0) << "tick " << i;
}

TEST(HapticThreadSafety, ADeviceThatStopsAnsweringIsHeldBrieflyThenGetsZeroForce) {
  auto device = std::make_shared<FaultyDevice>(pressingDevice(), FaultyDevice::Fault::kStopsAnswering, 700);
  auto thread = sphereScene().makeHapticThread(device);
  thread->start();
  ASSERT_TRUE(waitFor([&] { return device->commands() > 800; }));
  HapticSnapshot snap;
  thread->latestSnapshot(snap);
  thread->stop();
  expectHeldThenZero(*device);
  EXPECT_EQ(snap.force_W_N, Eigen::Vector3d::Zero());
  EXPECT_GE(snap.bad_device_samples, 100u);
}

TEST(HapticThreadSafety, ASilentDeviceGetsZeroForceAfterItsTimeout) {
  auto device = std::make_shared<FaultyDevice>(pressingDevice(), FaultyDevice::Fault::kFrozenTime, 700);
  auto thread = sphereScene().makeHapticThread(device);
  thread->start();
  ASSERT_TRUE(waitFor([&] { return device->commands() > 900; }));
  thread->stop();
  EXPECT_GT(device->force(699), 1.0);
  // The same sample over and over: zero once it is older than 50 ms (of wall time, so within
  // at most 50 ticks), and zero from then on.
  std::uint64_t first_zero = 0;
  for (std::uint64_t i = 700; i < 900; ++i) {
    if (device->force(i) == 0.0) {
      first_zero = i;
      break;
    }
  }
  ASSERT_GT(first_zero, 0u) << "never zeroed";
  EXPECT_LE(first_zero, 780u);
  for (std::uint64_t i = first_zero; i < 900; ++i) ASSERT_EQ(device->force(i), 0.0) << "tick " << i;
}

TEST(HapticThreadSafety, ANaNPoseIsNeverRenderedHeldBrieflyThenZero) {
  auto device = std::make_shared<FaultyDevice>(pressingDevice(), FaultyDevice::Fault::kNaNPose, 700);
  auto thread = sphereScene().makeHapticThread(device);
  thread->start();
  ASSERT_TRUE(waitFor([&] { return device->commands() > 800; }));
  HapticSnapshot snap;
  thread->latestSnapshot(snap);
  thread->stop();
  expectHeldThenZero(*device);
  EXPECT_GE(snap.implausible_samples, 90u);
  EXPECT_TRUE(snap.force_W_N.allFinite());
  EXPECT_TRUE(snap.X_WP.allFinite());
}

TEST(HapticThreadSafety, GainsAreClampedToTheDevicesStiffness) {
  auto scripted = pressingDevice();
  DeviceLimits limits = scripted->limits();
  limits.max_linear_stiffness_N_per_m = 1000.0;  // the scene asks for 5000 N/m
  limits.max_force_N = 1000.0;
  scripted->setLimits(limits);
  SafetyPolicy policy = scripted->safetyPolicy();
  policy.ramp_time_s = 0.0;
  scripted->setSafetyPolicy(policy);
  auto device = std::make_shared<FaultyDevice>(scripted, FaultyDevice::Fault::kNone, 0);
  auto thread = sphereScene().makeHapticThread(device);
  thread->start();
  // The force 50 ticks after the solver is seen resting the proxy on the sphere (in contact,
  // the device held still since tick 50): however late a loaded machine ran the solver.
  HapticSnapshot snap;
  ASSERT_TRUE(waitFor([&] { return thread->latestSnapshot(snap) && snap.tick > 300 && snap.contacts > 0; }));
  const std::uint64_t resting_at = snap.tick;
  ASSERT_LT(resting_at + 60, std::uint64_t{1} << 13) << "past the ticks the device records";
  ASSERT_TRUE(waitFor([&] { return device->commands() > resting_at + 60; }));
  thread->stop();
  // 20 mm deep at 1000 N/m: about 20 N, not 100 N.
  EXPECT_NEAR(device->force(resting_at + 50), 20.0, 3.0);
}

}  // namespace
}  // namespace vh::runtime
