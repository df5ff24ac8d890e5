#include "vh/haptics/rigid_motion.h"

#include <random>

#include <gtest/gtest.h>

namespace vh::haptics {
namespace {

Pose randomPose(std::mt19937& rng) {
  std::normal_distribution<double> nd;
  Pose X;
  X.R_AB = Eigen::Quaterniond(nd(rng), nd(rng), nd(rng), nd(rng)).normalized();
  X.p_AB_m = 0.05 * Eigen::Vector3d(nd(rng), nd(rng), nd(rng));
  return X;
}

TEST(RigidMotion, StartsAtTheInitialAndEndsAtTheTargetConfiguration) {
  std::mt19937 rng(11);
  for (int n = 0; n < 200; ++n) {
    const Pose X0 = randomPose(rng), X1 = randomPose(rng);
    const Eigen::Vector3d p_TC(0.01, -0.02, 0.03);
    const RigidMotion m = RigidMotion::Between(X0, X1, p_TC);
    const Pose A = m.poseAt(0.0), B = m.poseAt(1.0);
    EXPECT_LT((A.p_AB_m - X0.p_AB_m).norm(), 1e-12);
    EXPECT_LT((B.p_AB_m - X1.p_AB_m).norm(), 1e-12);
    EXPECT_GT(std::abs(B.R_AB.dot(X1.R_AB)), 1.0 - 1e-12);
    // Eq. 2 for a tool point agrees with the pose at any time.
    const Eigen::Vector3d p_T(0.02, 0.01, -0.04);
    for (double t : {0.0, 0.3, 0.77, 1.0}) {
      EXPECT_LT((m.pointAt(m.radial_W(p_T), t) - m.poseAt(t) * p_T).norm(), 1e-12);
    }
  }
}

TEST(RigidMotion, PathLengthBoundIsConservative) {
  std::mt19937 rng(5);
  for (int n = 0; n < 200; ++n) {
    const Pose X0 = randomPose(rng), X1 = randomPose(rng);
    const RigidMotion m = RigidMotion::Between(X0, X1, Eigen::Vector3d(0.0, 0.0, 0.02));
    const Eigen::Vector3d r0 = m.radial_W(Eigen::Vector3d(0.03, -0.01, 0.05));
    double arc = 0.0;
    Eigen::Vector3d prev = m.pointAt(r0, 0.0);
    for (int i = 1; i <= 4000; ++i) {
      const Eigen::Vector3d p = m.pointAt(r0, i / 4000.0);
      arc += (p - prev).norm();
      prev = p;
    }
    EXPECT_LE(arc, m.pathLengthBound(r0) * (1 + 1e-9));
  }
}

TEST(RigidMotion, PathLengthBoundCountsOnlyTheDistanceFromTheAxis) {
  // A pure rotation: the bound is the arc's own length |omega| rho; a point on the axis does
  // not move (the paper's |omega| |r0| would give it 3 rad x 50 mm of path).
  Pose X0;
  const RigidMotion spin = RigidMotion::FromVelocity(X0, Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(),
                                                     Eigen::Vector3d(0.0, 0.0, 3.0));
  const Eigen::Vector3d on_axis(0.0, 0.0, 0.05), off_axis(0.004, 0.0, 0.05);
  EXPECT_EQ(spin.pathLengthBound(spin.radial_W(on_axis)), 0.0);
  double arc = 0.0;
  Eigen::Vector3d prev = spin.pointAt(spin.radial_W(off_axis), 0.0);
  for (int i = 1; i <= 10000; ++i) {
    const Eigen::Vector3d p = spin.pointAt(spin.radial_W(off_axis), i / 10000.0);
    arc += (p - prev).norm();
    prev = p;
  }
  EXPECT_NEAR(spin.pathLengthBound(spin.radial_W(off_axis)), 3.0 * 0.004, 1e-12);
  EXPECT_NEAR(arc, 3.0 * 0.004, 1e-8);
}

TEST(RigidMotion, RotationVectorRoundTrip) {
  std::mt19937 rng(2);
  std::normal_distribution<double> nd;
  for (int n = 0; n < 100; ++n) {
    Eigen::Vector3d theta(nd(rng), nd(rng), nd(rng));
    if (theta.norm() > 3.1) theta *= 3.1 / theta.norm();
    EXPECT_LT((rotationVector(quaternionFromRotationVector(theta)) - theta).norm(), 1e-12);
  }
  EXPECT_LT(rotationVector(quaternionFromRotationVector(Eigen::Vector3d(1e-14, 0, 0))).x() - 1e-14, 1e-20);
}

}  // namespace
}  // namespace vh::haptics
