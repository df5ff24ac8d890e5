// Tests of vh/runtime/sample_filter.h: glitches are rejected against the last good sample and
// the time since it, good samples after a glitch pass, a device that really moved is re-seeded,
// and a gap lets any jump the device could have made meanwhile pass.
#include "vh/runtime/sample_filter.h"

#include <cmath>
#include <limits>

#include <gtest/gtest.h>

namespace vh::runtime {
namespace {

using haptics::Pose;
using Verdict = SampleFilter::Verdict;

constexpr double kTick_s = 1e-3;

DeviceSample at(const Eigen::Vector3d& p_m, const Eigen::Quaterniond& R = Eigen::Quaterniond::Identity()) {
  DeviceSample s;
  s.X_WD = Pose{R, p_m};
  s.valid = true;
  return s;
}

DeviceLimits limits(double speed_m_per_s, double radius_m = DeviceLimits::kUnbounded) {
  DeviceLimits l;
  l.max_speed_m_per_s = speed_m_per_s;
  l.workspace_radius_m = radius_m;
  return l;
}

TEST(SampleFilter, OneGlitchIsRejectedAndTheNextGoodSampleRenders) {
  // 3 m/s at 1 kHz: 3 mm per tick plus the 1 mm slack are plausible, 4.1 mm are not.
  for (const double glitch_m : {0.01, 0.1, 1.0, 9.9, 10.1}) {
    SampleFilter filter(limits(3.0));
    EXPECT_EQ(filter.check(at({0.0, 0.0, 0.0}), true, kTick_s), Verdict::kGood);
    EXPECT_EQ(filter.check(at({0.001, 0.0, 0.0}), true, kTick_s), Verdict::kGood);
    EXPECT_EQ(filter.check(at({0.001 + glitch_m, 0.0, 0.0}), true, kTick_s), Verdict::kImplausible) << glitch_m;
    // The next sample continues the real motion: compared with the last GOOD one, two ticks ago.
    EXPECT_EQ(filter.check(at({0.003, 0.0, 0.0}), true, kTick_s), Verdict::kGood) << glitch_m;
    EXPECT_EQ(filter.stats().implausible, 1u);
    EXPECT_EQ(filter.stats().too_fast, 1u);
    EXPECT_EQ(filter.lastGood().p_AB_m, Eigen::Vector3d(0.003, 0.0, 0.0));
  }
}

TEST(SampleFilter, TheSpeedLimitIsSpeedTimesElapsedTimePlusTheSlack) {
  SampleFilter filter(limits(3.0));
  ASSERT_EQ(filter.check(at({0.0, 0.0, 0.0}), true, kTick_s), Verdict::kGood);
  const double allowed_m = 3.0 * kTick_s + SampleFilter::kPositionSlack_m;
  EXPECT_EQ(filter.check(at({0.999 * allowed_m, 0.0, 0.0}), true, kTick_s), Verdict::kGood);
  EXPECT_EQ(filter.check(at({0.999 * allowed_m + 1.001 * allowed_m, 0.0, 0.0}), true, kTick_s),
            Verdict::kImplausible);
}

TEST(SampleFilter, RotationsFasterThanTheAngularLimitAreRejected) {
  DeviceLimits l;
  l.max_angular_speed_rad_per_s = 10.0;  // 10 mrad per tick + 10 mrad slack
  SampleFilter filter(l);
  ASSERT_EQ(filter.check(at(Eigen::Vector3d::Zero()), true, kTick_s), Verdict::kGood);
  const auto turned = [](double rad) { return Eigen::Quaterniond(Eigen::AngleAxisd(rad, Eigen::Vector3d::UnitZ())); };
  EXPECT_EQ(filter.check(at(Eigen::Vector3d::Zero(), turned(0.019)), true, kTick_s), Verdict::kGood);
  EXPECT_EQ(filter.check(at(Eigen::Vector3d::Zero(), turned(0.5)), true, kTick_s), Verdict::kImplausible);
}

TEST(SampleFilter, NonFiniteAndOutsideTheWorkspaceAreImplausibleNeverReseeded) {
  SampleFilter filter(limits(DeviceLimits::kUnbounded, 0.05));  // no speed limit: only these tests
  ASSERT_EQ(filter.check(at({0.0, 0.0, 0.0}), true, kTick_s), Verdict::kGood);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  for (int i = 0; i < 2 * SampleFilter::kReseedSamples; ++i) {
    EXPECT_EQ(filter.check(at({nan, 0.0, 0.0}), true, kTick_s), Verdict::kImplausible);
    EXPECT_EQ(filter.check(at({0.21 + 0.001 * i, 0.0, 0.0}), true, kTick_s), Verdict::kImplausible);  // > 4 x 5 cm
  }
  DeviceSample bad_quaternion = at({0.0, 0.0, 0.0});
  bad_quaternion.X_WD.R_AB.coeffs() *= 1.01;
  EXPECT_EQ(filter.check(bad_quaternion, true, kTick_s), Verdict::kImplausible);
  EXPECT_EQ(filter.stats().nonfinite, 2u * SampleFilter::kReseedSamples + 1u);
  EXPECT_EQ(filter.stats().outside, 2u * SampleFilter::kReseedSamples);
  EXPECT_EQ(filter.stats().reseeds, 0u);
  // Inside 4 stated radii (a corner of a box workspace): fine.
  EXPECT_EQ(filter.check(at({0.19, 0.0, 0.0}), true, kTick_s), Verdict::kGood);
}

TEST(SampleFilter, MissingSamplesAreNotImplausible) {
  SampleFilter filter(limits(3.0));
  DeviceSample s = at({0.0, 0.0, 0.0});
  EXPECT_EQ(filter.check(s, false, kTick_s), Verdict::kMissing);
  s.valid = false;
  EXPECT_EQ(filter.check(s, true, kTick_s), Verdict::kMissing);
  EXPECT_EQ(filter.stats().implausible, 0u);
}

TEST(SampleFilter, AfterAGapAJumpTheDeviceCouldHaveMadeMeanwhilePasses) {
  SampleFilter filter(limits(3.0));
  ASSERT_EQ(filter.check(at({0.0, 0.0, 0.0}), true, kTick_s), Verdict::kGood);
  // 100 ms without a sample (unplugged): 0.3 m + slack become plausible.
  for (int i = 0; i < 100; ++i) ASSERT_EQ(filter.check(at(Eigen::Vector3d::Zero()), false, kTick_s), Verdict::kMissing);
  EXPECT_EQ(filter.check(at({0.25, 0.0, 0.0}), true, kTick_s), Verdict::kGood);
}

TEST(SampleFilter, ADeviceThatReallyMovedIsReseededAfterConsistentSamples) {
  SampleFilter filter(limits(3.0));
  ASSERT_EQ(filter.check(at({0.0, 0.0, 0.0}), true, kTick_s), Verdict::kGood);
  // Re-homed: the device now reports 0.5 m away, consistently, and moves slowly from there.
  for (int i = 1; i < SampleFilter::kReseedSamples; ++i) {
    EXPECT_EQ(filter.check(at({0.5 + 1e-4 * i, 0.0, 0.0}), true, kTick_s), Verdict::kImplausible) << i;
  }
  EXPECT_EQ(filter.check(at({0.5 + 1e-4 * SampleFilter::kReseedSamples, 0.0, 0.0}), true, kTick_s),
            Verdict::kReseeded);
  EXPECT_EQ(filter.check(at({0.5 + 1e-4 * (SampleFilter::kReseedSamples + 1), 0.0, 0.0}), true, kTick_s),
            Verdict::kGood);
  EXPECT_EQ(filter.stats().reseeds, 1u);
  EXPECT_EQ(filter.stats().implausible, static_cast<std::uint64_t>(SampleFilter::kReseedSamples - 1));
}

TEST(SampleFilter, GlitchesThatDisagreeWithEachOtherNeverReseed) {
  SampleFilter filter(limits(3.0));
  ASSERT_EQ(filter.check(at({0.0, 0.0, 0.0}), true, kTick_s), Verdict::kGood);
  for (int i = 0; i < 50; ++i) {
    const double x = (i % 2 == 0) ? 1.0 : -1.0;  // a noisy cable: each glitch elsewhere
    ASSERT_EQ(filter.check(at({x, 0.0, 0.0}), true, kTick_s), Verdict::kImplausible) << i;
  }
  EXPECT_EQ(filter.stats().reseeds, 0u);
}

TEST(SampleFilter, ANewConnectionStartsAfresh) {
  SampleFilter filter(limits(3.0));
  ASSERT_EQ(filter.check(at({0.0, 0.0, 0.0}), true, kTick_s), Verdict::kGood);
  DeviceSample s = at({0.3, 0.0, 0.0});
  s.connection = 1;
  EXPECT_EQ(filter.check(s, true, kTick_s), Verdict::kGood);
}

}  // namespace
}  // namespace vh::runtime
