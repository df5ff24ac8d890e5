#include "vh/haptics/distance_field.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "allocation_guard.h"

namespace vh::haptics {
namespace {

// An anisotropic, rotated grid (spacing 0.3 x 0.7 x 1.1 mm, a 30 degree turn about z and a
// 20 degree one about x) with an origin off zero.
VolumeGeometry skewedGrid(int nx, int ny, int nz) {
  VolumeGeometry g;
  g.dims = {nx, ny, nz};
  g.spacing_m = {0.3e-3, 0.7e-3, 1.1e-3};
  g.origin_W_m = {0.01, -0.02, 0.005};
  g.direction_W = (Eigen::AngleAxisd(0.5236, Eigen::Vector3d::UnitZ()) *
                   Eigen::AngleAxisd(0.349, Eigen::Vector3d::UnitX())).toRotationMatrix();
  return g;
}

std::vector<std::uint8_t> randomMask(const VolumeGeometry& g, double fill, std::mt19937& rng) {
  std::bernoulli_distribution in(fill);
  std::vector<std::uint8_t> m(g.voxelCount());
  for (auto& v : m) v = in(rng) ? 1 : 0;
  return m;
}

// Independent oracle: the distance from p_W to the nearest mask voxel centre, over all of them.
double trueDistance(const VolumeGeometry& g, const std::vector<std::uint8_t>& mask, const Eigen::Vector3d& p_W) {
  double best = std::numeric_limits<double>::infinity();
  for (std::size_t idx = 0; idx < mask.size(); ++idx) {
    if (mask[idx] == 0) continue;
    const auto v = g.voxelOf(idx);
    best = std::min(best, (g.pointOf_W(Eigen::Vector3d(v[0], v[1], v[2])) - p_W).norm());
  }
  return best;
}

// A solid ball of voxels (centre c in voxel coordinates, radius r in metres).
std::vector<std::uint8_t> ballMask(const VolumeGeometry& g, const Eigen::Vector3d& c_I, double r_m) {
  std::vector<std::uint8_t> m(g.voxelCount());
  const Eigen::Vector3d c_W = g.pointOf_W(c_I);
  for (std::size_t idx = 0; idx < m.size(); ++idx) {
    const auto v = g.voxelOf(idx);
    m[idx] = (g.pointOf_W(Eigen::Vector3d(v[0], v[1], v[2])) - c_W).norm() <= r_m ? 1 : 0;
  }
  return m;
}

TEST(DistanceField, ExactAgainstAllPairsOnRandomAnisotropicMasks) {
  std::mt19937 rng(7);
  int checked = 0;
  for (const double fill : {0.002, 0.02, 0.2, 0.6}) {
    for (int trial = 0; trial < 3; ++trial) {
      const VolumeGeometry g = skewedGrid(11 + trial, 9, 7 + 2 * trial);
      const auto mask = randomMask(g, fill, rng);
      const auto brute = bruteForceSquaredDistances_m2(g, mask);
      const DistanceField f = DistanceField::FromMask(g, mask, 1.0);  // margin covers the grid
      if (f.empty()) continue;
      ASSERT_EQ(f.boxLo(), (std::array<int, 3>{0, 0, 0}));
      for (std::size_t idx = 0; idx < mask.size(); ++idx) {
        const auto v = g.voxelOf(idx);
        const double want = std::sqrt(brute[idx]);
        ASSERT_NEAR(f.voxelDistance_m(v[0], v[1], v[2]), want, 1e-12 * want)
            << "fill " << fill << " voxel " << v[0] << "," << v[1] << "," << v[2];
        ++checked;
      }
    }
  }
  EXPECT_GT(checked, 5000);
}

TEST(DistanceField, ASmallMarginStoresTheBoxAroundTheMaskExactly) {
  const VolumeGeometry g = skewedGrid(40, 30, 20);
  std::vector<std::uint8_t> mask(g.voxelCount(), 0);
  mask[g.indexOf(20, 15, 10)] = 1;
  mask[g.indexOf(22, 14, 10)] = 1;
  const DistanceField f = DistanceField::FromMask(g, mask, 2e-3);  // 7, 3 and 2 voxels
  EXPECT_EQ(f.boxLo(), (std::array<int, 3>{13, 11, 8}));
  EXPECT_EQ(f.boxHi(), (std::array<int, 3>{29, 18, 12}));
  const auto brute = bruteForceSquaredDistances_m2(g, mask);
  for (int k = 8; k <= 12; ++k)
    for (int j = 11; j <= 18; ++j)
      for (int i = 13; i <= 29; ++i) {
        const double want = std::sqrt(brute[g.indexOf(i, j, k)]);
        ASSERT_NEAR(f.voxelDistance_m(i, j, k), want, 1e-12 * want);
      }
  EXPECT_EQ(f.maskVoxels(), 2u);
}

TEST(DistanceField, SampleIsWithinHalfTheVoxelDiagonalOfTheTrueDistance) {
  std::mt19937 rng(11);
  const VolumeGeometry g = skewedGrid(16, 12, 10);
  const auto mask = randomMask(g, 0.01, rng);
  const DistanceField f = DistanceField::FromMask(g, mask, 1.0);
  const double bound = f.samplingBound_m();
  EXPECT_NEAR(bound, 0.5 * std::sqrt(0.09 + 0.49 + 1.21) * 1e-3, 1e-15);
  std::uniform_real_distribution<double> u(0.0, 1.0);  // anywhere in the grid's box
  double worst = 0.0;
  for (int s = 0; s < 4000; ++s) {
    const Eigen::Vector3d p_W = g.pointOf_W(Eigen::Vector3d(15.0 * u(rng), 11.0 * u(rng), 9.0 * u(rng)));
    const double truth = trueDistance(g, mask, p_W), got = f.sample_m(p_W);
    ASSERT_LE(std::abs(got - truth), bound + 1e-12) << "sample " << s;
    worst = std::max(worst, std::abs(got - truth));
  }
  EXPECT_GT(worst, 0.1 * bound);  // the bound is not vacuous: sampling does err
}

TEST(DistanceField, BeyondTheStoredBoxTheSampleIsConservative) {
  const VolumeGeometry g = skewedGrid(60, 40, 30);
  const auto mask = ballMask(g, {30, 20, 15}, 1.5e-3);
  const DistanceField f = DistanceField::FromMask(g, mask, 1e-3);
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-20.0, 80.0);
  for (int s = 0; s < 500; ++s) {
    const Eigen::Vector3d p_W = g.pointOf_W(Eigen::Vector3d(u(rng), u(rng), u(rng)));
    const double truth = trueDistance(g, mask, p_W);
    ASSERT_LE(f.sample_m(p_W), truth + f.samplingBound_m() + 1e-12);
    ASSERT_GE(f.sample_m(p_W), 0.0);
  }
}

TEST(DistanceField, EmptyMaskAndBadInput) {
  const VolumeGeometry g = skewedGrid(4, 4, 4);
  const DistanceField empty = DistanceField::FromMask(g, std::vector<std::uint8_t>(64, 0), 1e-3);
  EXPECT_TRUE(empty.empty());
  EXPECT_TRUE(std::isinf(empty.sample_m(Eigen::Vector3d::Zero())));
  try {
    (void)DistanceField::FromMask(g, std::vector<std::uint8_t>(63, 0), 1e-3);
    FAIL() << "no throw";
  } catch (const std::invalid_argument& e) {
    EXPECT_STREQ(e.what(), "DistanceField: mask of 63 voxels, expected 64");
  }
  try {
    (void)DistanceField::FromMask(g, std::vector<std::uint8_t>(64, 0), -1.0);
    FAIL() << "no throw";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("margin must be finite and >= 0"), std::string::npos) << e.what();
  }
}

// --- ProximityQuery ------------------------------------------------------------------------

PointShell randomShell(int n, double radius_m, std::mt19937& rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<Eigen::Vector3d> p;
  while (static_cast<int>(p.size()) < n) {
    const Eigen::Vector3d x(u(rng), u(rng), u(rng));
    if (x.norm() <= 1.0) p.push_back(radius_m * x + Eigen::Vector3d(0.0, 0.0, 2.0 * radius_m));
  }
  return PointShell(std::move(p));
}

// A pose that keeps randomShell(_, 2 mm) 1 mm or more inside the grid's box (6 mm from its faces).
Pose randomPose(const VolumeGeometry& g, std::mt19937& rng) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  Eigen::Vector3d ijk;
  for (int a = 0; a < 3; ++a) {
    const double margin = 6e-3 / g.spacing_m[a];
    ijk[a] = margin + u(rng) * (g.dims[static_cast<std::size_t>(a)] - 1 - 2.0 * margin);
  }
  Pose X;
  X.R_AB = Eigen::Quaterniond::UnitRandom();
  X.p_AB_m = g.pointOf_W(ijk);
  return X;
}

TEST(ProximityQuery, MatchesAllPairsOverShellPointsAndMaskVoxels) {
  std::mt19937 rng(5);
  const VolumeGeometry g = skewedGrid(80, 40, 24);
  const auto ball = ballMask(g, {30, 20, 12}, 2.0e-3);
  const auto specks = randomMask(g, 0.0005, rng);
  const std::vector<std::vector<std::uint8_t>> masks{ball, specks};
  std::vector<std::shared_ptr<const DistanceField>> fields;
  for (const auto& m : masks) fields.push_back(std::make_shared<DistanceField>(DistanceField::FromMask(g, m, 0.02)));
  const PointShell shell = randomShell(150, 2e-3, rng);
  ProximityQuery query(fields, shell, std::numeric_limits<double>::infinity());
  for (int trial = 0; trial < 40; ++trial) {
    const Pose X_WP = randomPose(g, rng);
    const NearestProximity nearest = query.evaluate(X_WP);
    double want_nearest = std::numeric_limits<double>::infinity();
    for (std::size_t f = 0; f < masks.size(); ++f) {
      double oracle = std::numeric_limits<double>::infinity(), sampled = oracle;
      for (const auto& p_T : shell.points_T_m()) {
        oracle = std::min(oracle, trueDistance(g, masks[f], X_WP * p_T));
        sampled = std::min(sampled, fields[f]->sample_m(X_WP * p_T));
      }
      const double got = query.results()[f].distance_m;
      EXPECT_EQ(got, sampled) << "trial " << trial << " field " << f;  // pruning loses nothing
      EXPECT_LE(std::abs(got - oracle), fields[f]->samplingBound_m() + 1e-12) << "trial " << trial;
      want_nearest = std::min(want_nearest, got);
    }
    EXPECT_EQ(nearest.distance_m, want_nearest);
  }
}

TEST(ProximityQuery, InsideIsZeroFarIsBeyondTheRangeAndNothingAllocates) {
  const VolumeGeometry g = skewedGrid(60, 30, 20);
  const auto ball = ballMask(g, {30, 15, 10}, 3.0e-3);
  auto field = std::make_shared<DistanceField>(DistanceField::FromMask(g, ball, 5e-3));
  std::mt19937 rng(9);
  const PointShell shell = randomShell(1000, 1e-3, rng);
  ProximityQuery query({field}, shell, 5e-3);
  Pose X_WP;
  X_WP.p_AB_m = g.pointOf_W(Eigen::Vector3d(30, 15, 10)) - Eigen::Vector3d(0, 0, 2e-3);  // shell centre on the ball's
  NearestProximity n{};
  {
    test::AllocationGuard guard;
    n = query.evaluate(X_WP);
    EXPECT_EQ(guard.count(), 0u);
  }
  EXPECT_EQ(n.field, 0);
  EXPECT_EQ(n.distance_m, 0.0);
  X_WP.p_AB_m += Eigen::Vector3d(0.5, 0.0, 0.0);  // half a metre away
  n = query.evaluate(X_WP);
  EXPECT_EQ(n.field, -1);
  EXPECT_TRUE(std::isinf(n.distance_m));
  EXPECT_EQ(query.results()[0].point, -1);
  EXPECT_EQ(query.pointsSampled(), 1u);  // the tool's ball alone said so
}

TEST(ProximityQuery, RejectsANullFieldAndABadRange) {
  const PointShell shell({Eigen::Vector3d::Zero()});
  EXPECT_THROW(ProximityQuery({nullptr}, shell, 1.0), std::invalid_argument);
  EXPECT_THROW(ProximityQuery({}, shell, 0.0), std::invalid_argument);
}

}  // namespace
}  // namespace vh::haptics
