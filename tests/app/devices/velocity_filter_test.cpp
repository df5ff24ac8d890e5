// VelocityFilter (the drivers' velocity estimate) against its closed form: on a position ramp of
// constant velocity v sampled every dt, the finite difference is exactly v, so from rest the
// filtered velocity after n samples is v (1 - (1 - alpha)^(n - 1)), alpha = 1 - exp(-2 pi f_c dt).
#include "vh/devices/velocity_filter.h"

#include <cmath>
#include <numbers>

#include <gtest/gtest.h>

namespace vh::devices {
namespace {

TEST(VelocityFilter, ARampConvergesToItsVelocityAsTheFirstOrderFilterSays) {
  const double cutoff_Hz = 40.0, dt = 1e-3;
  const Eigen::Vector3d v(0.1, -0.05, 0.02);
  const double alpha = 1.0 - std::exp(-2.0 * std::numbers::pi * cutoff_Hz * dt);
  VelocityFilter filter(cutoff_Hz);
  const auto position = [&](double t) -> Eigen::Vector3d { return Eigen::Vector3d(0.01, 0.02, 0.03) + v * t; };
  filter.update(position(0.5), 0.5);
  EXPECT_TRUE(filter.velocity().isZero()) << "one sample has no velocity";
  for (int n = 2; n <= 200; ++n) {
    const double t = 0.5 + (n - 1) * dt;
    filter.update(position(t), t);
    const Eigen::Vector3d expected = v * (1.0 - std::pow(1.0 - alpha, n - 1));
    ASSERT_TRUE(filter.velocity().isApprox(expected, 1e-9))
        << "sample " << n << ": " << filter.velocity().transpose() << " expected " << expected.transpose();
  }
  EXPECT_TRUE(filter.velocity().isApprox(v, 1e-3));
}

TEST(VelocityFilter, ARepeatedTimeStampMovesTheReferenceButNotTheVelocityAndResetForgets) {
  VelocityFilter filter(40.0);
  filter.update(Eigen::Vector3d::Zero(), 1.0);
  filter.update(Eigen::Vector3d(0.001, 0, 0), 1.001);
  const Eigen::Vector3d v1 = filter.velocity();
  ASSERT_GT(v1.x(), 0.0);
  filter.update(Eigen::Vector3d(0.5, 0, 0), 1.001);  // same time: no division by zero
  EXPECT_EQ(filter.velocity(), v1);
  filter.update(Eigen::Vector3d(0.5, 0, 0), 1.002);  // differenced from the replaced sample
  EXPECT_TRUE(filter.velocity().isApprox(v1 * std::exp(-2.0 * std::numbers::pi * 40.0 * 1e-3), 1e-9));
  filter.reset();
  EXPECT_TRUE(filter.velocity().isZero());
  filter.update(Eigen::Vector3d(1, 1, 1), 5.0);  // the first sample after a reset: no velocity
  EXPECT_TRUE(filter.velocity().isZero());
}

}  // namespace
}  // namespace vh::devices
