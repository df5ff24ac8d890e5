// The min-max tree against brute force: its range must contain every trilinear
// sample in a box (random volumes of every voxel type, random boxes, partly outside the grid),
// and it must be exact where its definition says so (level-0 bricks, parents).
#include "vh/haptics/min_max_tree.h"

#include <algorithm>
#include <cstdint>
#include <limits>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "vh/haptics/scalar_volume.h"

namespace vh::haptics {
namespace {

VolumeGeometry unitGeometry(const std::array<int, 3>& dims) {
  VolumeGeometry g;
  g.dims = dims;
  g.spacing_m = Eigen::Vector3d::Ones();  // grid coordinates = W coordinates
  return g;
}

template <typename T>
ScalarVolume randomVolume(std::mt19937& rng, const std::array<int, 3>& dims, double scale = 1.0) {
  std::vector<T> v(static_cast<std::size_t>(dims[0]) * dims[1] * dims[2]);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (auto& x : v) {
    if constexpr (std::is_same_v<T, float>) x = static_cast<float>(2000.0 * u(rng) - 1000.0);
    else if constexpr (std::is_same_v<T, std::int16_t>) x = static_cast<T>(std::lround(4000.0 * u(rng) - 2000.0));
    else x = static_cast<T>(std::lround(static_cast<double>(std::numeric_limits<T>::max()) * u(rng)));
  }
  return ScalarVolume::FromVoxels(unitGeometry(dims), v, scale, 0.0);
}

// Every trilinear sample at random points of the box (and its corners), clipped to the grid,
// lies within the tree's range; the raw range is F's when scale = 1, offset = 0.
template <typename T>
void checkContainsSamples(std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> dim(2, 23);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (int volume = 0; volume < 20; ++volume) {
    const std::array<int, 3> dims{dim(rng), dim(rng), dim(rng)};
    const ScalarVolume vol = randomVolume<T>(rng, dims);
    const MinMaxTree& tree = vol.minMaxTree();
    for (int box = 0; box < 200; ++box) {
      Eigen::Vector3d lo, hi;
      for (int a = 0; a < 3; ++a) {
        const double n = dims[a] - 1;
        const double c = (1.4 * u(rng) - 0.2) * n, w = (box % 3 == 0 ? 0.3 : 0.6 * n) * u(rng);
        lo[a] = c - w;
        hi[a] = c + w;
      }
      float mn = 0.0f, mx = 0.0f;
      const bool meets = tree.rawRange(lo, hi, mn, mx);
      const Eigen::Vector3d upper(dims[0] - 1, dims[1] - 1, dims[2] - 1);
      const bool expected_meets = (hi.array() >= 0.0).all() && (lo.array() <= upper.array()).all();
      ASSERT_EQ(meets, expected_meets) << "volume " << volume << " box " << box;
      if (!meets) {
        EXPECT_EQ(vol.upperBoundInBox(lo, hi), -std::numeric_limits<double>::infinity());
        continue;
      }
      const Eigen::Vector3d clo = lo.cwiseMax(Eigen::Vector3d::Zero()), chi = hi.cwiseMin(upper);
      for (int k = 0; k < 300; ++k) {
        Eigen::Vector3d g;
        for (int a = 0; a < 3; ++a) {
          const double r = k < 8 ? ((k >> a) & 1) : u(rng);  // the 8 corners first
          g[a] = clo[a] + r * (chi[a] - clo[a]);
        }
        const double F = vol.sample(g);
        ASSERT_GE(F, mn) << "volume " << volume << " box " << box << " sample " << g.transpose();
        ASSERT_LE(F, mx) << "volume " << volume << " box " << box << " sample " << g.transpose();
        ASSERT_LE(F, vol.upperBoundInBox(lo, hi));
      }
    }
  }
}

TEST(MinMaxTree, RangeContainsEveryTrilinearSampleInTheBoxUInt8) { checkContainsSamples<std::uint8_t>(1); }
TEST(MinMaxTree, RangeContainsEveryTrilinearSampleInTheBoxInt16) { checkContainsSamples<std::int16_t>(2); }
TEST(MinMaxTree, RangeContainsEveryTrilinearSampleInTheBoxUInt16) { checkContainsSamples<std::uint16_t>(3); }
TEST(MinMaxTree, RangeContainsEveryTrilinearSampleInTheBoxFloat32) { checkContainsSamples<float>(4); }

TEST(MinMaxTree, LevelZeroBricksHoldExactlyTheirVoxelsAndParentsTheirChildren) {
  std::mt19937 rng(5);
  const std::array<int, 3> dims{18, 9, 13};  // not multiples of the brick size
  const ScalarVolume vol = randomVolume<std::int16_t>(rng, dims);
  const MinMaxTree& tree = vol.minMaxTree();
  ASSERT_GE(tree.levels(), 2);
  const auto n0 = tree.nodes(0);
  constexpr int B = MinMaxTree::kBrickCells;
  EXPECT_EQ(n0[0], (dims[0] - 1 + B - 1) / B);
  for (int c = 0; c < n0[2]; ++c)
    for (int b = 0; b < n0[1]; ++b)
      for (int a = 0; a < n0[0]; ++a) {
        double lo = std::numeric_limits<double>::infinity(), hi = -lo;
        for (int z = B * c; z <= std::min(B * c + B, dims[2] - 1); ++z)
          for (int y = B * b; y <= std::min(B * b + B, dims[1] - 1); ++y)
            for (int x = B * a; x <= std::min(B * a + B, dims[0] - 1); ++x) {
              lo = std::min(lo, vol.voxel(x, y, z));
              hi = std::max(hi, vol.voxel(x, y, z));
            }
        float mn, mx;
        tree.node(0, a, b, c, mn, mx);
        EXPECT_EQ(mn, lo);
        EXPECT_EQ(mx, hi);
      }
  for (int level = 1; level < tree.levels(); ++level) {
    const auto n = tree.nodes(level), m = tree.nodes(level - 1);
    for (int c = 0; c < n[2]; ++c)
      for (int b = 0; b < n[1]; ++b)
        for (int a = 0; a < n[0]; ++a) {
          float lo = std::numeric_limits<float>::infinity(), hi = -lo;
          for (int z = 2 * c; z <= std::min(2 * c + 1, m[2] - 1); ++z)
            for (int y = 2 * b; y <= std::min(2 * b + 1, m[1] - 1); ++y)
              for (int x = 2 * a; x <= std::min(2 * a + 1, m[0] - 1); ++x) {
                float l, h;
                tree.node(level - 1, x, y, z, l, h);
                lo = std::min(lo, l);
                hi = std::max(hi, h);
              }
          float mn, mx;
          tree.node(level, a, b, c, mn, mx);
          EXPECT_EQ(mn, lo);
          EXPECT_EQ(mx, hi);
        }
  }
  const auto top = tree.nodes(tree.levels() - 1);
  EXPECT_EQ(top, (std::array<int, 3>{1, 1, 1}));
}

TEST(MinMaxTree, TightOnASingleBrightVoxel) {
  const std::array<int, 3> dims{17, 17, 17};
  std::vector<std::uint8_t> v(17 * 17 * 17, 0);
  v[8 + 17 * (8 + 17 * 8)] = 100;  // voxel (8, 8, 8): a corner of the bricks around it
  const ScalarVolume vol = ScalarVolume::FromVoxels(unitGeometry(dims), v);
  float mn, mx;
  // Far from the voxel: exactly 0.
  ASSERT_TRUE(vol.minMaxTree().rawRange({1.2, 1.3, 1.1}, {2.5, 2.5, 2.5}, mn, mx));
  EXPECT_EQ(mn, 0.0f);
  EXPECT_EQ(mx, 0.0f);
  // A box in the cell just above the voxel, and one in the brick holding it as its border.
  ASSERT_TRUE(vol.minMaxTree().rawRange({8.2, 8.2, 8.2}, {8.3, 8.3, 8.3}, mn, mx));
  EXPECT_EQ(mx, 100.0f);
  ASSERT_TRUE(vol.minMaxTree().rawRange({7.2, 7.2, 7.2}, {7.3, 7.3, 7.3}, mn, mx));
  EXPECT_EQ(mx, 100.0f);
  // The brick [0, 4] cells on each axis does not reach voxel 8.
  ASSERT_TRUE(vol.minMaxTree().rawRange({0.0, 0.0, 0.0}, {3.9, 3.9, 3.9}, mn, mx));
  EXPECT_EQ(mx, 0.0f);
  // isInside agrees: no point of the far box can be inside for any isovalue >= 0.
  EXPECT_EQ(vol.upperBoundInBox({1.2, 1.3, 1.1}, {2.5, 2.5, 2.5}), 0.0);
  // Outside the grid entirely: no sample is in bounds.
  EXPECT_FALSE(vol.minMaxTree().rawRange({17.0, 0.0, 0.0}, {18.0, 1.0, 1.0}, mn, mx));
}

// A box spanning up to 4 bricks per axis is read brick by brick (level 0), not from a coarser
// node that also covers the voxels next to it (the point-shell tree's balls span several
// bricks; a coarse read culled too little).
TEST(MinMaxTree, ReadsBricksAcrossFourBricksPerAxis) {
  const std::array<int, 3> dims{65, 65, 65};  // 16 bricks per axis
  std::vector<std::uint8_t> v(65 * 65 * 65, 0);
  v[0 + 65 * (0 + 65 * 0)] = 100;  // voxel (0, 0, 0): only the first brick holds it
  const ScalarVolume vol = ScalarVolume::FromVoxels(unitGeometry(dims), v);
  float mn, mx;
  // Bricks 1..4 on each axis (cells 4 to 19): brute force says 0; a level-2 node would hold 100.
  ASSERT_TRUE(vol.minMaxTree().rawRange({4.5, 4.5, 4.5}, {19.5, 19.5, 19.5}, mn, mx));
  EXPECT_EQ(mx, 0.0f);
  // One cell further down reaches brick 0 and the bright voxel.
  ASSERT_TRUE(vol.minMaxTree().rawRange({3.5, 4.5, 4.5}, {19.5, 19.5, 19.5}, mn, mx));
  EXPECT_EQ(mx, 100.0f);
}

TEST(MinMaxTree, NegativeValueScaleBoundsWithTheRawMinimum) {
  std::mt19937 rng(6);
  const std::array<int, 3> dims{12, 10, 9};
  const ScalarVolume vol = randomVolume<std::uint16_t>(rng, dims, -0.5);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (int k = 0; k < 2000; ++k) {
    const Eigen::Vector3d g(u(rng) * 11, u(rng) * 9, u(rng) * 8);
    const Eigen::Vector3d half = Eigen::Vector3d::Constant(0.7 * u(rng));
    ASSERT_LE(vol.sample(g), vol.upperBoundInBox(g - half, g + half));
  }
}

// The early stop (ScalarVolume::rawStopAbove(), MinMaxTree::RawStop): a query that may stop at
// the first node above a value answers "may the box hold F > value?" as the whole query does, on
// every voxel type and both signs of the value scale, with values taken at the voxels' own F
// (the rounding edge: a box whose largest voxel equals the value must not hold it) and between;
// the brute-force largest F over the box's cells' corners above the value always gets yes; and
// the stop does end queries early (fewer nodes read).
template <typename T>
void checkStoppedQuery(std::uint32_t seed, double scale) {
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> dim(6, 48);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  int stopped = 0, yes = 0, no = 0;
  for (int volume = 0; volume < 12; ++volume) {
    const std::array<int, 3> dims{dim(rng), dim(rng), dim(rng)};
    const ScalarVolume vol = randomVolume<T>(rng, dims, scale);
    const Eigen::Vector3d upper(dims[0] - 1, dims[1] - 1, dims[2] - 1);
    for (int box = 0; box < 150; ++box) {
      Eigen::Vector3d lo, hi;
      for (int a = 0; a < 3; ++a) {
        const double c = (1.2 * u(rng) - 0.1) * upper[a], w = (box % 2 == 0 ? 2.0 : 0.5 * upper[a]) * u(rng);
        lo[a] = c - w;
        hi[a] = c + w;
      }
      // The value: F at a random voxel, exactly, or just above or below it.
      const int x = static_cast<int>(u(rng) * dims[0]) % dims[0], y = static_cast<int>(u(rng) * dims[1]) % dims[1],
                z = static_cast<int>(u(rng) * dims[2]) % dims[2];
      double value = vol.voxel(x, y, z);
      if (box % 3 == 1) value = std::nextafter(value, std::numeric_limits<double>::infinity());
      if (box % 3 == 2) value -= 0.25 * std::abs(scale);
      const MinMaxTree::RawStop stop = vol.rawStopAbove(value);
      int read_whole = 0, read_stopped = 0;
      const bool whole = vol.upperBoundInBox(lo, hi, &read_whole) > value;
      const bool early = vol.upperBoundInBox(lo, hi, &read_stopped, 0.0, nullptr, nullptr, stop) > value;
      ASSERT_EQ(early, whole) << "volume " << volume << " box " << box << " value " << value;
      ASSERT_LE(read_stopped, read_whole);
      if (read_stopped < read_whole) ++stopped;
      (whole ? yes : no) += 1;
      // Brute force: the largest F over the corners of the cells the box's samples use.
      const bool meets = (hi.array() >= 0.0).all() && (lo.array() <= upper.array()).all();
      if (!meets) continue;
      double corner_max = -std::numeric_limits<double>::infinity();
      int v0[3], v1[3];
      for (int a = 0; a < 3; ++a) {
        v0[a] = std::min(static_cast<int>(std::clamp(lo[a], 0.0, upper[a])), dims[a] - 2);
        v1[a] = std::min(static_cast<int>(std::clamp(hi[a], 0.0, upper[a])), dims[a] - 2) + 1;
      }
      for (int k = v0[2]; k <= v1[2]; ++k)
        for (int j = v0[1]; j <= v1[1]; ++j)
          for (int i = v0[0]; i <= v1[0]; ++i) corner_max = std::max(corner_max, vol.voxel(i, j, k));
      if (corner_max > value) ASSERT_TRUE(early) << "volume " << volume << " box " << box;
    }
  }
  EXPECT_GT(stopped, 100) << "the stop never ended a query early";
  EXPECT_GT(yes, 100);
  EXPECT_GT(no, 100);
}

TEST(MinMaxTree, AStoppedQueryAnswersAsTheWholeQueryUInt8) { checkStoppedQuery<std::uint8_t>(21, 1.0); }
TEST(MinMaxTree, AStoppedQueryAnswersAsTheWholeQueryInt16) { checkStoppedQuery<std::int16_t>(22, 0.75); }
TEST(MinMaxTree, AStoppedQueryAnswersAsTheWholeQueryUInt16NegativeScale) { checkStoppedQuery<std::uint16_t>(23, -0.5); }
TEST(MinMaxTree, AStoppedQueryAnswersAsTheWholeQueryFloat32) { checkStoppedQuery<float>(24, 1.0); }

// The voxel-level bound (ScalarVolume::voxelUpperBoundInBox) against brute force: it contains
// every trilinear sample of the box (dense random samples and the box's corners), it is no
// higher than the largest voxel within one voxel of the box (the voxels a sample there can
// weigh), it never exceeds the brick-level bound, and it keeps its contract at the edges: a box
// that misses the grid gives -infinity, one over the voxel limit +infinity and reads nothing.
template <typename T>
void checkVoxelBound(std::uint32_t seed, double scale) {
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> dim(2, 15);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  int bounded = 0, tighter = 0;
  for (int volume = 0; volume < 20; ++volume) {
    const std::array<int, 3> dims{dim(rng), dim(rng), dim(rng)};
    const ScalarVolume vol = randomVolume<T>(rng, dims, scale);
    const Eigen::Vector3d upper(dims[0] - 1, dims[1] - 1, dims[2] - 1);
    for (int box = 0; box < 200; ++box) {
      Eigen::Vector3d lo, hi;
      for (int a = 0; a < 3; ++a) {
        const double c = (1.4 * u(rng) - 0.2) * upper[a], w = 1.6 * u(rng);
        lo[a] = c - w;
        hi[a] = c + w;
      }
      int read = -1;
      const double bound = vol.voxelUpperBoundInBox(lo, hi, 64, &read);
      const bool meets = (hi.array() >= 0.0).all() && (lo.array() <= upper.array()).all();
      if (!meets) {
        ASSERT_EQ(bound, -std::numeric_limits<double>::infinity()) << "volume " << volume << " box " << box;
        ASSERT_EQ(read, 0);
        continue;
      }
      if (bound == std::numeric_limits<double>::infinity()) {
        ASSERT_EQ(read, 0);
        ASSERT_EQ(vol.voxelUpperBoundInBox(lo, hi, 1 << 20, &read), vol.voxelUpperBoundInBox(lo, hi, 1 << 20));
        ASSERT_GT(read, 64) << "refused a box of " << read << " voxels";
        continue;
      }
      ASSERT_GT(read, 0);
      ASSERT_LE(read, 64);
      ++bounded;
      const Eigen::Vector3d clo = lo.cwiseMax(Eigen::Vector3d::Zero()), chi = hi.cwiseMin(upper);
      for (int k = 0; k < 300; ++k) {
        Eigen::Vector3d g;
        for (int a = 0; a < 3; ++a) g[a] = clo[a] + (k < 8 ? ((k >> a) & 1) : u(rng)) * (chi[a] - clo[a]);
        ASSERT_LE(vol.sample(g), bound) << "volume " << volume << " box " << box << " sample " << g.transpose();
      }
      double near = -std::numeric_limits<double>::infinity();
      for (int z = 0; z < dims[2]; ++z)
        for (int y = 0; y < dims[1]; ++y)
          for (int x = 0; x < dims[0]; ++x) {
            const Eigen::Vector3d v(x, y, z);
            if (((v - clo).array() >= -1.0).all() && ((v - chi).array() <= 1.0).all())
              near = std::max(near, vol.voxel(x, y, z));
          }
      ASSERT_LE(bound, near + std::abs(near) * 1e-9) << "volume " << volume << " box " << box;
      const double brick = vol.upperBoundInBox(lo, hi);
      ASSERT_LE(bound, brick + std::abs(brick) * 1e-9) << "volume " << volume << " box " << box;
      if (bound < brick) ++tighter;
    }
  }
  EXPECT_GT(bounded, 500) << "too few boxes within the voxel limit to say anything";
  EXPECT_GT(tighter, 50) << "the voxels never gave a lower bound than the bricks";
}

TEST(VoxelUpperBound, ContainsEverySampleAndIsNoLooserThanTheVoxelsNearTheBoxUInt8) { checkVoxelBound<std::uint8_t>(11, 1.0); }
TEST(VoxelUpperBound, ContainsEverySampleAndIsNoLooserThanTheVoxelsNearTheBoxInt16) { checkVoxelBound<std::int16_t>(12, 1.0); }
TEST(VoxelUpperBound, ContainsEverySampleAndIsNoLooserThanTheVoxelsNearTheBoxUInt16) { checkVoxelBound<std::uint16_t>(13, -0.5); }
TEST(VoxelUpperBound, ContainsEverySampleAndIsNoLooserThanTheVoxelsNearTheBoxFloat32) { checkVoxelBound<float>(14, 1.0); }

// What the voxel-level bound is for: a box two voxels from a bright voxel in the same brick,
// which the brick cannot clear.
TEST(VoxelUpperBound, ClearsABoxNextToTheSurfaceThatItsBrickCannot) {
  const std::array<int, 3> dims{17, 17, 17};
  std::vector<std::uint8_t> v(17 * 17 * 17, 0);
  v[7 + 17 * (7 + 17 * 7)] = 100;  // voxel (7, 7, 7), inside brick [4, 8] on each axis
  const ScalarVolume vol = ScalarVolume::FromVoxels(unitGeometry(dims), v);
  const Eigen::Vector3d lo(4.2, 4.2, 4.2), hi(5.8, 5.8, 5.8);  // cells 4 and 5: voxels 4 to 6
  EXPECT_EQ(vol.upperBoundInBox(lo, hi), 100.0);
  EXPECT_EQ(vol.voxelUpperBoundInBox(lo, hi, 64), 0.0);
  // Reaching into cell 6 reads voxel 7: the bound is the voxel's.
  EXPECT_EQ(vol.voxelUpperBoundInBox(lo, Eigen::Vector3d(6.1, 5.8, 5.8), 64), 0.0);
  EXPECT_EQ(vol.voxelUpperBoundInBox(lo, Eigen::Vector3d(6.1, 6.1, 6.1), 64), 100.0);
}

}  // namespace
}  // namespace vh::haptics
