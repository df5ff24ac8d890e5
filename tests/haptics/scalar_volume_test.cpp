#include "vh/haptics/scalar_volume.h"

#include <array>
#include <cstdint>
#include <limits>
#include <random>
#include <string>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include "vh/datasets/synthetic.h"

namespace vh::haptics {
namespace {

VolumeGeometry rotatedGeometry() {
  VolumeGeometry g;
  g.dims = {12, 10, 8};
  g.spacing_m = {0.5e-3, 0.8e-3, 2e-3};
  g.origin_W_m = {0.01, -0.02, 0.005};
  g.direction_W = Eigen::AngleAxisd(0.4, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  return g;
}

// F(i,j,k) = a + b.(i,j,k) in raw units; trilinear interpolation reproduces it exactly.
template <typename T>
ScalarVolume linearVolume(const VolumeGeometry& g, double a, const Eigen::Vector3d& b) {
  std::vector<T> v(g.voxelCount());
  std::size_t idx = 0;
  for (int k = 0; k < g.dims[2]; ++k)
    for (int j = 0; j < g.dims[1]; ++j)
      for (int i = 0; i < g.dims[0]; ++i) v[idx++] = static_cast<T>(a + b.dot(Eigen::Vector3d(i, j, k)));
  return ScalarVolume::FromVoxels(g, v, 2.0, -5.0);
}

// Random int16 voxels in [-2000, 2000], except i < 10: the ramp slope . (i, j, k).
std::vector<std::int16_t> noiseBesideARamp(const VolumeGeometry& g, std::mt19937& rng, const std::array<int, 3>& slope) {
  std::vector<std::int16_t> raw(g.voxelCount());
  for (auto& v : raw) v = static_cast<std::int16_t>(static_cast<int>(rng() % 4001) - 2000);
  for (int k = 0; k < g.dims[2]; ++k)
    for (int j = 0; j < g.dims[1]; ++j)
      for (int i = 0; i < 10; ++i)
        raw[g.indexOf(i, j, k)] = static_cast<std::int16_t>(slope[0] * i + slope[1] * j + slope[2] * k);
  return raw;
}

template <typename T>
void expectExactOnLinearField() {
  const VolumeGeometry g = rotatedGeometry();
  const Eigen::Vector3d b(3, 2, 5);  // integer steps so every voxel type stores them exactly
  const ScalarVolume vol = linearVolume<T>(g, 10.0, b);
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(1.05, 5.95);  // gradient samples stay inside the grid
  const Eigen::Matrix3d A = g.direction_W * g.spacing_m.asDiagonal();
  for (int n = 0; n < 200; ++n) {
    const Eigen::Vector3d ijk(u(rng), u(rng), u(rng));
    const Eigen::Vector3d p = g.origin_W_m + A * ijk;
    const double expected = 2.0 * (10.0 + b.dot(ijk)) - 5.0;
    EXPECT_NEAR(vol.sample(p), expected, 1e-9 * std::abs(expected)) << voxelTypeName(vol.voxelType());
    // The gradient of F = 2 b.(A^-1 (p - o)) is 2 A^-T b, exactly (central differences of a
    // linear field are exact).
    const Eigen::Vector3d grad = 2.0 * A.inverse().transpose() * b;
    EXPECT_LT((vol.gradient(p) - grad).norm(), 1e-9 * grad.norm());
  }
}

TEST(ScalarVolume, TrilinearIsExactOnLinearFieldsForEveryVoxelType) {
  expectExactOnLinearField<std::uint8_t>();
  expectExactOnLinearField<std::int16_t>();
  expectExactOnLinearField<std::uint16_t>();
  expectExactOnLinearField<float>();
}

TEST(ScalarVolume, GradientMatchesFiniteDifferencesOfTheField) {
  // A smooth non-linear field: the central difference with delta = spacing must agree with a
  // fine finite difference of the trilinear field to first order in the spacing.
  datasets::GridSpec grid;
  grid.dims = {48, 48, 48};
  grid.spacing_m = Eigen::Vector3d::Constant(0.5e-3);
  const ScalarVolume vol = datasets::makeSphereVolume(grid, Eigen::Vector3d::Zero(), 0.008);
  std::mt19937 rng(3);
  std::normal_distribution<double> nd;
  for (int n = 0; n < 100; ++n) {
    Eigen::Vector3d dir(nd(rng), nd(rng), nd(rng));
    dir.normalize();
    const Eigen::Vector3d p = dir * (0.004 + 0.006 * (n % 10) / 10.0);
    const Eigen::Vector3d g = vol.gradient(p);
    // F = 1000 (R - |p|) [mm units]: gradient -1000 * p/|p| per metre... in mm per m.
    EXPECT_NEAR(g.norm(), 1000.0, 40.0);
    EXPECT_GT(g.normalized().dot(-dir), 0.995);
  }
}

TEST(ScalarVolume, InsideOnlyWhereFExceedsTheIsovalueAndNeverOutsideTheGrid) {
  const ScalarVolume vol = datasets::makePlaneVolume([] {
    datasets::GridSpec g;
    g.dims = {16, 16, 16};
    return g;
  }(), Eigen::Vector3d::UnitZ(), 0.0);
  EXPECT_TRUE(vol.isInside(Eigen::Vector3d(0, 0, -0.001), 0.0));
  EXPECT_FALSE(vol.isInside(Eigen::Vector3d(0, 0, 0.001), 0.0));
  EXPECT_FALSE(vol.isInside(Eigen::Vector3d(0, 0, 1e-6), 0.0));
  EXPECT_TRUE(vol.isInside(Eigen::Vector3d(0, 0, 0.002), -2.5));  // the isovalue moves the surface
  // Below the plane but outside the grid: empty, whatever the isovalue.
  EXPECT_FALSE(vol.isInside(Eigen::Vector3d(0.5, 0, -0.001), -1e9));
  EXPECT_FALSE(vol.isInside(Eigen::Vector3d(0, 0, -0.1), -1e9));
  EXPECT_DOUBLE_EQ(vol.featureSize_m(), 0.5e-3);
}

TEST(ScalarVolume, RejectsBadGeometryWithAClearMessage) {
  VolumeGeometry g;
  g.dims = {4, 4, 4};
  std::vector<float> v(63);
  try {
    ScalarVolume::FromVoxels(g, v);
    FAIL() << "expected a size mismatch";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("expected 256"), std::string::npos) << e.what();
  }
  v.resize(64);
  g.spacing_m.x() = 0.0;
  EXPECT_THROW(ScalarVolume::FromVoxels(g, v), std::invalid_argument);
  g.spacing_m.x() = 1e-3;
  g.dims = {1, 8, 8};
  EXPECT_THROW(ScalarVolume::FromVoxels(g, v), std::invalid_argument);
  g.dims = {4, 4, 4};
  v[5] = std::numeric_limits<float>::quiet_NaN();
  EXPECT_THROW(ScalarVolume::FromVoxels(g, v), std::invalid_argument);
  // The message names the first non-finite voxel (index 5 + 4 * 2 = (1, 2, 0)).
  v[5] = 0.0f;
  v[9] = std::numeric_limits<float>::infinity();
  v[40] = std::numeric_limits<float>::quiet_NaN();
  try {
    (void)ScalarVolume::FromVoxels(g, v);
    ADD_FAILURE() << "no exception";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("(1, 2, 0)"), std::string::npos) << e.what();
  }
}

// VolumeGeometry's index arithmetic against two independent oracles: the running counter of an
// x-fastest triple loop (the voxel order of every field), and ScalarVolume::gridCoordinates(),
// which inverts the grid's map to W, on an anisotropic, rotated, offset grid with odd dims.
TEST(VolumeGeometry, IndexVoxelAndPointAgreeWithTheVoxelOrderAndTheInverseMap) {
  VolumeGeometry g;
  g.dims = {5, 3, 7};
  g.spacing_m = Eigen::Vector3d(0.4e-3, 0.7e-3, 1.3e-3);
  g.origin_W_m = Eigen::Vector3d(0.01, -0.02, 0.035);
  g.direction_W = Eigen::AngleAxisd(0.7, Eigen::Vector3d(1.0, 2.0, -0.5).normalized()).toRotationMatrix();
  const ScalarVolume volume = ScalarVolume::FromVoxels(g, std::vector<float>(g.voxelCount(), 0.0f));
  std::uint64_t counter = 0;
  for (int k = 0; k < g.dims[2]; ++k)
    for (int j = 0; j < g.dims[1]; ++j)
      for (int i = 0; i < g.dims[0]; ++i, ++counter) {
        ASSERT_EQ(g.indexOf(i, j, k), counter) << i << " " << j << " " << k;
        const std::array<int, 3> v = g.voxelOf(counter);
        ASSERT_EQ(v, (std::array<int, 3>{i, j, k})) << counter;
        const Eigen::Vector3d ijk(i + 0.25, j - 0.5, k + 0.75);
        ASSERT_LT((volume.gridCoordinates(g.pointOf_W(ijk)) - ijk).norm(), 1e-9) << counter;
      }
  EXPECT_EQ(counter, g.voxelCount());
  VolumeGeometry other = g;
  EXPECT_TRUE(g.sameGridAs(other));
  other.spacing_m.z() += 1e-12;
  EXPECT_FALSE(g.sameGridAs(other));
  other = g;
  other.direction_W(0, 1) = -other.direction_W(0, 1);
  EXPECT_FALSE(g.sameGridAs(other));
}

TEST(ScalarVolume, LocalLipschitzBoundHoldsNearEachCellAndIgnoresFarOutliers) {
  // Oracle: |F(p) - F(q)| <= L_local(p) |p - q| for random p and q within one voxel of p (the
  // local bound is valid over p's cell and the cells next to it), on a random int16 field with
  // anisotropic voxels in a rotated grid and a negative value scale; and one outlier voxel (1e30)
  // or a -3e38 border raise the local bound only within two bricks (8 voxels) of themselves.
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> U(0.0, 1.0);
  VolumeGeometry g = rotatedGeometry();
  g.dims = {20, 18, 16};
  // A smooth region (small steps) beside the noise, so that the local bounds differ.
  const std::vector<std::int16_t> raw = noiseBesideARamp(g, rng, {1, 1, 1});
  const ScalarVolume vol = ScalarVolume::FromVoxels(g, raw, -0.5, 3.0);
  const Eigen::Matrix3d A = g.direction_W * g.spacing_m.asDiagonal();
  const Eigen::Vector3d upper(g.dims[0] - 1, g.dims[1] - 1, g.dims[2] - 1);
  double worst = 0.0, smallest_local = std::numeric_limits<double>::infinity();
  for (int n = 0; n < 40000; ++n) {
    const Eigen::Vector3d a = upper.cwiseProduct(Eigen::Vector3d(U(rng), U(rng), U(rng)));
    const Eigen::Vector3d b = (a + 2.0 * Eigen::Vector3d(U(rng) - 0.5, U(rng) - 0.5, U(rng) - 0.5)).cwiseMax(0.0).cwiseMin(upper);
    const Eigen::Vector3d p = g.origin_W_m + A * a, q = g.origin_W_m + A * b;
    if ((p - q).norm() == 0.0) continue;
    const double L = vol.localLipschitzBound(a);
    ASSERT_LE(L, vol.lipschitzBound() * (1.0 + 1e-6));
    const double ratio = std::abs(vol.sample(p) - vol.sample(q)) / (p - q).norm();
    ASSERT_LE(ratio, L) << "pair " << n << " at " << a.transpose() << " and " << b.transpose();
    worst = std::max(worst, ratio / L);
    smallest_local = std::min(smallest_local, L);
  }
  EXPECT_GT(worst, 0.2);                                       // not a vacuous bound
  EXPECT_LT(smallest_local, 0.05 * vol.lipschitzBound());      // and local: the smooth part is far below

  // Outliers: a float ball field with one far voxel at 1e30, then a -3e38 border.
  VolumeGeometry gb;
  gb.dims = {64, 64, 64};
  gb.spacing_m = Eigen::Vector3d::Constant(0.5e-3);
  std::vector<float> ball(gb.voxelCount());
  const auto at = [&](int i, int j, int k) -> float& { return ball[i + 64 * (j + 64 * static_cast<std::size_t>(k))]; };
  for (int k = 0; k < 64; ++k)
    for (int j = 0; j < 64; ++j)
      for (int i = 0; i < 64; ++i) at(i, j, k) = static_cast<float>(10.0 - Eigen::Vector3d(i - 31.5, j - 31.5, k - 31.5).norm());
  const ScalarVolume clean = ScalarVolume::FromVoxels(gb, ball);
  std::vector<float> clean_voxels = ball;
  at(62, 62, 62) = 1e30f;
  const ScalarVolume outlier = ScalarVolume::FromVoxels(gb, ball);
  ball = clean_voxels;
  for (int k = 0; k < 64; ++k)
    for (int j = 0; j < 64; ++j)
      for (int i = 0; i < 64; ++i)
        if (i == 0 || j == 0 || k == 0 || i == 63 || j == 63 || k == 63) at(i, j, k) = -3e38f;
  const ScalarVolume border = ScalarVolume::FromVoxels(gb, ball);
  EXPECT_GT(outlier.lipschitzBound(), 1e30);
  EXPECT_GT(border.lipschitzBound(), 1e38);
  int compared = 0;
  for (int k = 0; k < 63; ++k)
    for (int j = 0; j < 63; ++j)
      for (int i = 0; i < 63; ++i) {
        const Eigen::Vector3d c(i + 0.5, j + 0.5, k + 0.5);
        const double L0 = clean.localLipschitzBound(c);
        if (std::max({std::abs(i - 62), std::abs(j - 62), std::abs(k - 62)}) > 8) {
          ASSERT_EQ(outlier.localLipschitzBound(c), L0) << "cell " << c.transpose();
        }
        if (std::min({i, j, k, 62 - i, 62 - j, 62 - k}) > 8) {
          ASSERT_EQ(border.localLipschitzBound(c), L0) << "cell " << c.transpose();
          ++compared;
        }
      }
  EXPECT_GT(compared, 40 * 40 * 40);
  // The clean ball's local bound is about its gradient, |grad F| = 1 per voxel = 2000 per m,
  // times sqrt(3) at most (the per-axis steps of a brick may come from different voxels).
  EXPECT_LT(clean.localLipschitzBound(Eigen::Vector3d(31.5, 31.5, 41.5)), 2000.0 * std::sqrt(3.0) * 1.01);
}

TEST(ScalarVolume, GridStepRangeBoundsEveryMoveInItsBoxByItsDirection) {
  // Oracle: for x and x + d in a box, F(x + d) - F(x) lies between sum_a min(lo_a d_a, hi_a d_a)
  // and sum_a max(...) with [lo, hi] = gridStepRange(box) (F sampled in W, so the trilinear
  // interpolant is the oracle), on the random int16 field with a smooth corner (anisotropic
  // voxels, rotated grid, negative value scale) of the Lipschitz test. On a ramp the range is
  // the ramp's slope itself; after a voxel is written and its region refreshed, the range there
  // takes the new step in and keeps its old width far away.
  std::mt19937 rng(12);
  std::uniform_real_distribution<double> U(0.0, 1.0);
  VolumeGeometry g = rotatedGeometry();
  g.dims = {20, 18, 16};
  const std::vector<std::int16_t> raw = noiseBesideARamp(g, rng, {2, -1, 3});
  const ScalarVolume vol = ScalarVolume::FromVoxels(g, raw, -0.5, 3.0);
  const Eigen::Vector3d upper(g.dims[0] - 1, g.dims[1] - 1, g.dims[2] - 1);
  double tightest = 0.0;
  int extended = 0;  // boxes whose ranges hold two steps or more beyond them
  for (int n = 0; n < 40000; ++n) {
    Eigen::Vector3d lo = upper.cwiseProduct(Eigen::Vector3d(U(rng), U(rng), U(rng)));
    Eigen::Vector3d hi = (lo + 4.0 * Eigen::Vector3d(U(rng), U(rng), U(rng))).cwiseMin(upper);
    Eigen::Vector3d step_lo, step_hi, valid_lo, valid_hi;
    ASSERT_TRUE(vol.gridStepRange(lo, hi, step_lo, step_hi, &valid_lo, &valid_hi));
    ASSERT_TRUE((step_lo.array() <= step_hi.array()).all());
    // The box the same ranges hold over contains the asked box and stays in the grid.
    ASSERT_TRUE((valid_lo.array() <= lo.array()).all() && (hi.array() <= valid_hi.array()).all());
    ASSERT_TRUE((valid_lo.array() >= 0.0).all() && (valid_hi.array() <= upper.array()).all());
    if (((lo - valid_lo).array() >= 2.0).any() || ((valid_hi - hi).array() >= 2.0).any()) ++extended;
    // Every edge of the cells of that box (voxel by voxel), and so of the asked box's, lies in
    // the range.
    const auto F = [&](int i, int j, int k) { return -0.5 * raw[g.indexOf(i, j, k)] + 3.0; };
    const auto lastCell = [&](int a) { return std::min(static_cast<int>(valid_hi[a]), g.dims[a] - 2); };
    for (int k = static_cast<int>(valid_lo[2]); k <= lastCell(2) + 1; ++k)
      for (int j = static_cast<int>(valid_lo[1]); j <= lastCell(1) + 1; ++j)
        for (int i = static_cast<int>(valid_lo[0]); i <= lastCell(0) + 1; ++i) {
          const int cell[3] = {i, j, k};
          for (int a = 0; a < 3; ++a) {
            if (cell[a] > lastCell(a)) continue;  // the far voxels start no edge along a
            const int next[3] = {i + (a == 0), j + (a == 1), k + (a == 2)};
            const double step = F(next[0], next[1], next[2]) - F(i, j, k);
            ASSERT_GE(step, step_lo[a]) << "axis " << a << " at " << i << " " << j << " " << k;
            ASSERT_LE(step, step_hi[a]) << "axis " << a << " at " << i << " " << j << " " << k;
          }
        }
    const auto inBox = [&]() -> Eigen::Vector3d { return lo + (hi - lo).cwiseProduct(Eigen::Vector3d(U(rng), U(rng), U(rng))); };
    const Eigen::Vector3d x = inBox(), y = inBox(), d = y - x;
    double rise_max = 0.0, rise_min = 0.0;
    for (int a = 0; a < 3; ++a) {
      rise_max += std::max(step_lo[a] * d[a], step_hi[a] * d[a]);
      rise_min += std::min(step_lo[a] * d[a], step_hi[a] * d[a]);
    }
    const double rise = vol.sample(g.pointOf_W(y)) - vol.sample(g.pointOf_W(x));
    const double slack = 1e-9 * (std::abs(vol.sample(g.pointOf_W(x))) + 1.0);
    ASSERT_LE(rise, rise_max + slack) << "box " << lo.transpose() << " to " << hi.transpose();
    ASSERT_GE(rise, rise_min - slack) << "box " << lo.transpose() << " to " << hi.transpose();
    if (rise_max > 1.0) tightest = std::max(tightest, rise / rise_max);
  }
  EXPECT_GT(tightest, 0.2);  // not a vacuous bound
  EXPECT_GT(extended, 20000) << "the bricks' ranges hold beyond most boxes";
  // The smooth corner: raw 2 i - j + 3 k, F = -0.5 raw + 3, so dF/di = -1, dF/dj = 0.5,
  // dF/dk = -1.5 per step exactly (its step brick books no edge of the noise: cells up to i = 7).
  Eigen::Vector3d step_lo, step_hi;
  ASSERT_TRUE(vol.gridStepRange(Eigen::Vector3d(0.5, 2.0, 2.0), Eigen::Vector3d(2.5, 9.0, 12.0), step_lo, step_hi));
  EXPECT_NEAR(step_lo[0], -1.0, 1e-6);
  EXPECT_NEAR(step_hi[0], -1.0, 1e-6);
  EXPECT_NEAR(step_lo[1], 0.5, 1e-6);
  EXPECT_NEAR(step_hi[1], 0.5, 1e-6);
  EXPECT_NEAR(step_lo[2], -1.5, 1e-6);
  EXPECT_NEAR(step_hi[2], -1.5, 1e-6);
  // Outside the grid's box of voxel centres, or not finite: nothing.
  EXPECT_FALSE(vol.gridStepRange(Eigen::Vector3d(-0.1, 1, 1), Eigen::Vector3d(2, 2, 2), step_lo, step_hi));
  EXPECT_FALSE(vol.gridStepRange(Eigen::Vector3d(1, 1, 1), Eigen::Vector3d(2, 2, upper[2] + 0.1), step_lo, step_hi));
  EXPECT_FALSE(vol.gridStepRange(Eigen::Vector3d(1, 1, 1), Eigen::Vector3d(2, std::nan(""), 2), step_lo, step_hi));

  // Written and refreshed (as drilling does): a voxel of the smooth corner set to 1000 raw.
  ScalarVolume carved = ScalarVolume::FromVoxels(g, raw, -0.5, 3.0);
  carved.writeRaw(g.indexOf(1, 5, 6), 1000.0);
  carved.refreshRegion({1, 5, 6}, {1, 5, 6});
  const double old_step = 2 * 2 - 5 + 3 * 6;  // raw at (2, 5, 6): its step from (1, 5, 6) is now old - 1000
  ASSERT_TRUE(carved.gridStepRange(Eigen::Vector3d(1.0, 5.0, 6.0), Eigen::Vector3d(1.5, 5.5, 6.5), step_lo, step_hi));
  EXPECT_LE(step_lo[0], -0.5 * (old_step - 1000.0) - 1.0 + 1e-6);  // F falls by 1000 / 2 - ... then rises
  EXPECT_GE(step_hi[0], -0.5 * (old_step - 1000.0) - 1e-6);
  ASSERT_TRUE(carved.gridStepRange(Eigen::Vector3d(0.5, 14.0, 2.0), Eigen::Vector3d(2.5, 16.0, 4.0), step_lo, step_hi));
  EXPECT_NEAR(step_lo[0], -1.0, 1e-6);  // far from it, as before
  EXPECT_NEAR(step_hi[0], -1.0, 1e-6);
}

TEST(ScalarVolume, BoundsCoverTheRotatedGrid) {
  const VolumeGeometry g = rotatedGeometry();
  const ScalarVolume vol = linearVolume<float>(g, 0.0, Eigen::Vector3d(1, 1, 1));
  const Eigen::Matrix3d A = g.direction_W * g.spacing_m.asDiagonal();
  const Eigen::Vector3d far_corner = g.origin_W_m + A * Eigen::Vector3d(11, 9, 7);
  EXPECT_TRUE((far_corner.array() <= vol.boundsMax_W_m().array() + 1e-12).all());
  EXPECT_TRUE((g.origin_W_m.array() >= vol.boundsMin_W_m().array() - 1e-12).all());
  EXPECT_TRUE(vol.inBounds(g.origin_W_m + A * Eigen::Vector3d(5, 5, 5)));
  EXPECT_FALSE(vol.inBounds(g.origin_W_m + A * Eigen::Vector3d(-0.1, 5, 5)));
}

TEST(ScalarVolume, LipschitzBoundHoldsBetweenRandomPointsAndIsTightOnARamp) {
  // Oracle: |F(p) - F(q)| <= L |p - q| for random pairs (p, q) of a random int16 field with
  // anisotropic voxels in a rotated grid and a negative value scale; on a ramp of slope g along
  // one axis the bound is g itself.
  std::mt19937 rng(9);
  std::uniform_real_distribution<double> U(0.0, 1.0);
  VolumeGeometry g = rotatedGeometry();
  std::vector<std::int16_t> raw(g.voxelCount());
  for (auto& v : raw) v = static_cast<std::int16_t>(static_cast<int>(rng() % 4001) - 2000);
  const ScalarVolume vol = ScalarVolume::FromVoxels(g, raw, -0.5, 3.0);
  const double L = vol.lipschitzBound();
  const Eigen::Matrix3d A = g.direction_W * g.spacing_m.asDiagonal();
  const Eigen::Vector3d upper(g.dims[0] - 1, g.dims[1] - 1, g.dims[2] - 1);
  double worst = 0.0;
  for (int n = 0; n < 20000; ++n) {
    const Eigen::Vector3d a = upper.cwiseProduct(Eigen::Vector3d(U(rng), U(rng), U(rng)));
    const Eigen::Vector3d b = (a + 0.3 * Eigen::Vector3d(U(rng) - 0.5, U(rng) - 0.5, U(rng) - 0.5)).cwiseMax(0.0).cwiseMin(upper);
    const Eigen::Vector3d p = g.origin_W_m + A * a, q = g.origin_W_m + A * b;
    if ((p - q).norm() == 0.0) continue;
    const double ratio = std::abs(vol.sample(p) - vol.sample(q)) / (p - q).norm();
    ASSERT_LE(ratio, L) << "pair " << n;
    worst = std::max(worst, ratio);
  }
  EXPECT_GT(worst, 0.2 * L);  // not a vacuous bound
  const ScalarVolume ramp = linearVolume<float>(g, 0.0, Eigen::Vector3d(2.0, 0.0, 0.0));
  const double slope = (ramp.sample(g.origin_W_m + A * Eigen::Vector3d(2, 1, 1)) -
                        ramp.sample(g.origin_W_m + A * Eigen::Vector3d(1, 1, 1))) / (A.col(0)).norm();
  EXPECT_NEAR(ramp.lipschitzBound(), std::abs(slope), 1e-6 * std::abs(slope));
}

}  // namespace
}  // namespace vh::haptics
