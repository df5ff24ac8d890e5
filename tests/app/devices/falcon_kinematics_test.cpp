// Tests of vh/devices/falcon_kinematics.h: forward kinematics (Newton-Raphson) against inverse
// kinematics over the whole workspace ball (round trip to 1e-9 m), the Jacobian against finite
// differences, torques by virtual work, encoder conversion, motor command scaling.
#include "vh/devices/falcon_kinematics.h"

#include <cmath>
#include <numbers>
#include <random>

#include <gtest/gtest.h>

namespace vh::devices::falcon {
namespace {

const Eigen::Vector3d kCentre(0.0, 0.0, kWorkspaceCentreZ_m);
constexpr double kRadius_m = 0.04;

/// Points filling the workspace ball (radius 0.04 m around the centre), its surface included.
std::vector<Eigen::Vector3d> workspacePoints(int n, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<Eigen::Vector3d> out;
  while (static_cast<int>(out.size()) < n) {
    Eigen::Vector3d d(u(rng), u(rng), u(rng));
    if (d.norm() > 1.0) continue;
    if (out.size() % 10 == 0) d.normalize();  // every tenth on the boundary
    out.push_back(kCentre + kRadius_m * d);
  }
  return out;
}

TEST(FalconKinematics, TheAxisIsSymmetric) {
  Eigen::Vector3d theta;
  ASSERT_TRUE(inverseKinematics(kCentre, theta));
  EXPECT_NEAR(theta[0], theta[1], 1e-12);
  EXPECT_NEAR(theta[1], theta[2], 1e-12);
  // Deeper along z opens the arms (theta grows).
  Eigen::Vector3d deeper;
  ASSERT_TRUE(inverseKinematics(kCentre + Eigen::Vector3d(0.0, 0.0, 0.02), deeper));
  EXPECT_GT(deeper[0], theta[0]);
}

TEST(FalconKinematics, ForwardRoundTripsInverseTo1e9MetresOverTheWorkspace) {
  double worst = 0.0;
  for (const Eigen::Vector3d& p : workspacePoints(5000, 11)) {
    Eigen::Vector3d theta, q;
    ASSERT_TRUE(inverseKinematics(p, theta)) << p.transpose();
    ASSERT_TRUE(forwardKinematics(theta, q)) << "from the default start, p = " << p.transpose();
    worst = std::max(worst, (q - p).norm());
    // Fewer iterations suffice from a warm start.
    Eigen::Vector3d warm;
    ASSERT_TRUE(forwardKinematics(theta, warm, p + Eigen::Vector3d(1e-4, -1e-4, 1e-4), 4));
    EXPECT_LT((warm - p).norm(), 1e-9);
  }
  EXPECT_LT(worst, 1e-9) << "worst round trip error [m]";
  RecordProperty("worst_round_trip_m", std::to_string(worst));
}

TEST(FalconKinematics, ForwardKinematicsRefusesWhatItCannotSolve) {
  Eigen::Vector3d p(1.0, 2.0, 3.0);
  EXPECT_FALSE(forwardKinematics(Eigen::Vector3d(std::nan(""), 0.0, 0.0), p));
  EXPECT_EQ(p, Eigen::Vector3d(1.0, 2.0, 3.0));
  EXPECT_FALSE(forwardKinematics(Eigen::Vector3d(0.3, 0.3, 0.3), p, Eigen::Vector3d(0.0, 0.0, 0.11), 0));
  Eigen::Vector3d theta;
  EXPECT_FALSE(inverseKinematics(Eigen::Vector3d(0.0, 0.0, 1.0), theta));  // out of reach
}

TEST(FalconKinematics, JacobianMatchesFiniteDifferences) {
  constexpr double h = 1e-7;
  double worst = 0.0;
  for (const Eigen::Vector3d& p : workspacePoints(500, 5)) {
    Eigen::Matrix3d A, J;
    ASSERT_TRUE(angleJacobian(p, A));
    ASSERT_TRUE(positionJacobian(p, J));
    // d theta / d p by central differences of the inverse kinematics.
    Eigen::Matrix3d A_fd;
    for (int k = 0; k < 3; ++k) {
      Eigen::Vector3d tp, tm;
      ASSERT_TRUE(inverseKinematics(p + h * Eigen::Vector3d::Unit(k), tp));
      ASSERT_TRUE(inverseKinematics(p - h * Eigen::Vector3d::Unit(k), tm));
      A_fd.col(k) = (tp - tm) / (2.0 * h);
    }
    worst = std::max(worst, (A - A_fd).norm() / A.norm());
    // d p / d theta by central differences of the forward kinematics.
    Eigen::Vector3d theta;
    ASSERT_TRUE(inverseKinematics(p, theta));
    Eigen::Matrix3d J_fd;
    for (int k = 0; k < 3; ++k) {
      Eigen::Vector3d pp, pm;
      ASSERT_TRUE(forwardKinematics(theta + 1e-6 * Eigen::Vector3d::Unit(k), pp, p));
      ASSERT_TRUE(forwardKinematics(theta - 1e-6 * Eigen::Vector3d::Unit(k), pm, p));
      J_fd.col(k) = (pp - pm) / 2e-6;
    }
    EXPECT_LT((J - J_fd).norm(), 1e-6 * J.norm()) << p.transpose();
  }
  EXPECT_LT(worst, 1e-6);
}

TEST(FalconKinematics, TorquesDoTheSameVirtualWorkAsTheForce) {
  // tau . d theta = F . d p for a small joint motion: tau = J^T F.
  for (const Eigen::Vector3d& p : workspacePoints(200, 9)) {
    const Eigen::Vector3d F(1.5, -2.0, 3.0);
    Eigen::Vector3d tau, theta, theta2, p2;
    ASSERT_TRUE(jointTorques(p, F, tau));
    ASSERT_TRUE(inverseKinematics(p, theta));
    const Eigen::Vector3d dtheta(1e-5, -2e-5, 0.5e-5);
    ASSERT_TRUE(forwardKinematics(theta + dtheta, p2, p));
    const double work = tau.dot(dtheta);
    EXPECT_NEAR(work, F.dot(p2 - p), 1e-3 * std::abs(work) + 1e-12);
  }
  Eigen::Vector3d tau(1.0, 1.0, 1.0);
  EXPECT_FALSE(jointTorques(Eigen::Vector3d(0.0, 0.0, 1.0), Eigen::Vector3d::UnitX(), tau));
  EXPECT_EQ(tau, Eigen::Vector3d::Zero());
}

TEST(FalconKinematics, EncoderCountsToAngles) {
  EXPECT_NEAR(encoderToAngle_rad(0) * 180.0 / std::numbers::pi, 35.0, 1e-12);
  const double per_count_deg = (std::numbers::pi * 0.01425 / 1280.0) / (std::numbers::pi * 0.110 / 360.0);
  EXPECT_NEAR(encoderToAngle_rad(1000) * 180.0 / std::numbers::pi, 35.0 + 1000.0 * per_count_deg, 1e-9);
  EXPECT_NEAR(encoderToAngle_rad(-1000) * 180.0 / std::numbers::pi, 35.0 - 1000.0 * per_count_deg, 1e-9);
  for (int e : {-20000, -1, 0, 1, 777, 20000}) {
    EXPECT_EQ(angleToEncoder(encoderToAngle_rad(static_cast<std::int16_t>(e))), e);
  }
}

TEST(FalconKinematics, MotorCommandsScaleDownUniformlyAndFitInt16) {
  auto cmd = motorCommands(Eigen::Vector3d(0.1, -0.2, 0.0));
  EXPECT_EQ(cmd[0], -1000);
  EXPECT_EQ(cmd[1], 2000);
  EXPECT_EQ(cmd[2], 0);
  // Beyond int16: scaled down uniformly (direction kept).
  cmd = motorCommands(Eigen::Vector3d(6.0, 3.0, -1.5));
  EXPECT_EQ(cmd[0], -32767);
  EXPECT_NEAR(cmd[1], -16384, 1);
  EXPECT_NEAR(cmd[2], 8192, 1);
  // Beyond the 30 N*m torque limit: scaled the same way first.
  cmd = motorCommands(Eigen::Vector3d(300.0, 0.0, 0.0));
  EXPECT_EQ(cmd[0], -32767);
  cmd = motorCommands(Eigen::Vector3d(std::nan(""), 0.0, 1.0));
  EXPECT_EQ(cmd, (std::array<std::int16_t, 3>{0, 0, 0}));
}

}  // namespace
}  // namespace vh::devices::falcon
