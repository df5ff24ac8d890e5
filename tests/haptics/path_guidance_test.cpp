// Tests of haptics/path_guidance.h: the grid's nearest point against the brute force, the force
// law (stiffness, cap, deadband, fade) against hand-computed values, no allocation per query.
#include "vh/haptics/path_guidance.h"

#include <cmath>
#include <random>

#include <gtest/gtest.h>

#include "allocation_guard.h"

namespace vh::haptics {
namespace {

std::vector<Eigen::Vector3d> helix(int n) {
  std::vector<Eigen::Vector3d> p;
  for (int i = 0; i < n; ++i) {
    const double t = 0.02 * i;
    p.emplace_back(0.03 * std::cos(t), 0.03 * std::sin(t), 0.0005 * i);
  }
  return p;
}

TEST(GuidancePath, NearestMatchesBruteForceOnRandomQueries) {
  std::mt19937 rng(7);
  std::normal_distribution<double> jitter(0.0, 0.0004);
  // A helix with noise (a recorded hand), with a gap: two polylines in one set.
  std::vector<Eigen::Vector3d> pts = helix(2000);
  for (auto& q : pts) q += Eigen::Vector3d(jitter(rng), jitter(rng), jitter(rng));
  std::vector<GuidancePath::Segment> segs;
  for (std::size_t i = 0; i + 1 < pts.size(); ++i)
    if (i != 900) segs.push_back({pts[i], pts[i + 1]});
  for (int cells : {1, 4, 32, 100}) {
    const GuidancePath path(segs, cells);
    std::uniform_real_distribution<double> u(-0.2, 0.2);  // inside and far outside the grid
    for (int k = 0; k < 3000; ++k) {
      const Eigen::Vector3d q(u(rng), u(rng), u(rng) + 0.5);
      const PathPoint a = path.nearest(q), b = path.nearestBruteForce(q);
      ASSERT_NEAR(a.distance_m, b.distance_m, 1e-15) << "cells " << cells << " query " << k;
      ASSERT_LT((a.p_W_m - b.p_W_m).norm(), 1e-12);
      ASSERT_GE(a.segment, 0);
    }
  }
}

TEST(GuidancePath, NearestOnAKnownSegment) {
  const GuidancePath path = GuidancePath::polyline({{0, 0, 0}, {0.1, 0, 0}, {0.1, 0.1, 0}});
  const PathPoint p = path.nearest({0.04, -0.01, 0.02});
  EXPECT_EQ(p.segment, 0);
  EXPECT_NEAR(p.s, 0.4, 1e-12);
  EXPECT_NEAR(p.distance_m, std::sqrt(0.01 * 0.01 + 0.02 * 0.02), 1e-15);
  const PathPoint corner = path.nearest({0.2, -0.05, 0});  // beyond the corner
  EXPECT_LT((corner.p_W_m - Eigen::Vector3d(0.1, 0, 0)).norm(), 1e-15);
}

TEST(GuidancePath, QueryAllocatesNothing) {
  const GuidancePath path = GuidancePath::polyline(helix(500));
  GuidanceGains gains;
  double sum = 0.0;
  test::AllocationGuard guard;
  for (int k = 0; k < 1000; ++k) sum += guidanceForce(path, gains, Eigen::Vector3d(0.001 * k - 0.5, 0.01, 0.1)).force_W_N.norm();
  EXPECT_EQ(guard.count(), 0u);
  EXPECT_GT(sum, 0.0);
}

TEST(GuidancePath, RejectsANonFinitePoint) {
  const double nan = std::nan("");
  EXPECT_THROW(GuidancePath::polyline({{0, 0, 0}, {nan, 0, 0}}), std::invalid_argument);
}

TEST(GuidanceForce, SpringTowardThePathWithDeadbandAndFade) {
  const GuidancePath path = GuidancePath::polyline({{0, 0, 0}, {1, 0, 0}});
  GuidanceGains g;
  g.stiffness_N_per_m = 200.0;
  g.cap_N = 10.0;
  g.deadband_m = 0.001;
  const GuidanceForce f = guidanceForce(path, g, {0.5, 0.004, 0.0});
  // 200 N/m x (4 mm - 1 mm) = 0.6 N toward -y.
  EXPECT_NEAR(f.force_W_N.y(), -0.6, 1e-12);
  EXPECT_NEAR(f.force_W_N.x(), 0.0, 1e-15);
  EXPECT_EQ(guidanceForce(path, g, {0.5, 0.0009, 0.0}).force_W_N, Eigen::Vector3d::Zero());  // in the deadband
  g.fade = 0.5;
  g.repetition = 2;  // 200 x 0.25 = 50 N/m
  EXPECT_NEAR(g.effectiveStiffness_N_per_m(), 50.0, 1e-12);
  EXPECT_NEAR(guidanceForce(path, g, {0.5, 0.004, 0.0}).force_W_N.y(), -0.15, 1e-12);
  g.fade = 0.0;  // out of range: no force
  EXPECT_EQ(guidanceForce(path, g, {0.5, 0.004, 0.0}).force_W_N, Eigen::Vector3d::Zero());
}

TEST(GuidanceForce, NeverExceedsTheCap) {
  const GuidancePath path = GuidancePath::polyline(helix(300));
  GuidanceGains g;
  g.stiffness_N_per_m = 5000.0;
  g.cap_N = 0.75;
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  double largest = 0.0;
  for (int k = 0; k < 20000; ++k) {
    const Eigen::Vector3d q(u(rng), u(rng), u(rng));
    largest = std::max(largest, guidanceForce(path, g, q).force_W_N.norm());
  }
  EXPECT_LE(largest, g.cap_N);
  EXPECT_GT(largest, 0.99 * g.cap_N);  // the cap is reached (far queries)
}

}  // namespace
}  // namespace vh::haptics
