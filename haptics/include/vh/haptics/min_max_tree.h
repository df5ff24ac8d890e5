#pragma once
/// @file
/// Min/max bricks over the raw voxel values of a volume, arranged as a tree ("Speed" in
/// haptics/README.md). Independent of the isovalue: built once per volume, it answers "which
/// raw values can a trilinear sample take inside this box?", and the caller compares that with
/// the isovalue of the current tick, so a moved isovalue slider needs no rebuild.

#include <algorithm>
#include <array>
#include <cstddef>
#include <limits>
#include <vector>

#include <Eigen/Core>

namespace vh::haptics {

/// Tree of raw-value ranges over the cells of a regular grid.
///
/// Level 0 brick (a, b, c) covers the cells [4a, 4a + 4) x [4b, 4b + 4) x [4c, 4c + 4) (cell
/// i spans grid coordinates [i, i + 1] and uses voxels i and i + 1, so a brick reads the voxels
/// [4a, 4a + 4] on each axis, its one-voxel upper border included); level L + 1 merges 2 x 2 x 2
/// nodes of level L, up to one root. Ranges are stored as float: every supported voxel type
/// (uint8, int16, uint16, float32) converts to float exactly.
class MinMaxTree {
 public:
  static constexpr int kBrickCells = 4;  ///< Cells per brick side at level 0.

  MinMaxTree() = default;
  /// Builds the tree over `voxels` (x fastest, then y, then z) of a grid with `dims`.
  /// @param dims voxels per axis, each >= 2 (the caller validates).
  template <typename T>
  static MinMaxTree Build(const T* voxels, const std::array<int, 3>& dims);

  /// Range of the raw values that a trilinear sample (ScalarVolume's: coordinates clamped to
  /// the grid, cell min(floor(x), n - 2)) can take at grid coordinates in the closed box
  /// [lo_ijk, hi_ijk], clipped to the grid's box [0, n - 1]^3. Every such sample lies within
  /// the 8 corner voxels of its cell, so within [raw_min, raw_max] (as computed in double by
  /// ScalarVolume, up to rounding: see ScalarVolume::upperBoundInBox()).
  /// @param nodes_read when set, receives the number of tree nodes read (0 when the box misses
  ///        the grid, 1 for one brick or the root, at most (kSpan + 1)^3 = 64): a query's cost,
  ///        which the work budget counts.
  /// @param lipschitz_max when set, receives the largest local Lipschitz bound (see
  ///        setLipschitz()) over the same nodes; 0 until setLipschitz() was called.
  /// @return false when the box does not meet the grid (no sample there is in bounds); the
  ///         whole volume's range when a coordinate is not finite.
  bool rawRange(const Eigen::Vector3d& lo_ijk, const Eigen::Vector3d& hi_ijk, float& raw_min,
                float& raw_max, int* nodes_read = nullptr, float* lipschitz_max = nullptr) const noexcept {
    return rawRange(lo_ijk, hi_ijk, raw_min, raw_max, nodes_read, lipschitz_max, RawStop{});
  }

  /// Where a query may stop reading: a caller that only asks whether the box's raw maximum
  /// reaches `raw` (above) or its minimum falls to it (!above) needs no further node once one
  /// does. Off by default (raw = NaN).
  struct RawStop {
    float raw = std::numeric_limits<float>::quiet_NaN();
    bool above = true;
  };
  /// rawRange() that stops at the first node whose maximum is >= stop.raw (stop.above) or whose
  /// minimum is <= stop.raw (!stop.above). Stopped, it returns true with the range of the nodes
  /// read so far in raw_min and raw_max (so raw_max >= stop.raw, or raw_min <= stop.raw),
  /// nodes_read counting them, and lipschitz_max not computed (0); not stopped, the same as
  /// rawRange(). The caller's question ("does the box reach the threshold?") has the same answer
  /// either way.
  bool rawRange(const Eigen::Vector3d& lo_ijk, const Eigen::Vector3d& hi_ijk, float& raw_min, float& raw_max,
                int* nodes_read, float* lipschitz_max, RawStop stop) const noexcept;

  /// Stores a local Lipschitz bound per level-0 brick (data units per metre, one float per
  /// brick, a fastest: `nodes(0)` of them) and the maximum over each node of the upper levels.
  /// The caller (ScalarVolume) makes each brick's value valid for every point within one brick
  /// of it, so a bound read for a box also covers points slightly outside the box.
  /// @throws std::invalid_argument when the size does not match nodes(0).
  void setLipschitz(std::vector<float> per_brick);
  /// Local Lipschitz bound of the level-0 brick holding cell (i, j, k) (clamped to the grid).
  float brickLipschitz(int i, int j, int k) const noexcept {
    const Level& l = levels_[0];
    const int a = std::clamp(i / kBrickCells, 0, l.n[0] - 1), b = std::clamp(j / kBrickCells, 0, l.n[1] - 1),
              c = std::clamp(k / kBrickCells, 0, l.n[2] - 1);
    return l.lipschitz.empty() ? 0.0f
                               : l.lipschitz[static_cast<std::size_t>(a) +
                                             static_cast<std::size_t>(l.n[0]) * (b + static_cast<std::size_t>(l.n[1]) * c)];
  }

  /// Recomputes the ranges of the level-0 bricks in the box [lo_brick, hi_brick] (brick indices,
  /// inclusive, clipped to the grid) from `voxels` (the same grid as Build()), and of their
  /// ancestors on every upper level; nothing else is read or written (material removal: only the
  /// bricks touched, no rebuild). No allocation.
  template <typename T>
  void refreshBricks(const T* voxels, std::array<int, 3> lo_brick, std::array<int, 3> hi_brick) noexcept;
  /// Sets the local Lipschitz bound of level-0 brick (a, b, c) (see setLipschitz()); the upper
  /// levels follow with propagateLipschitz(). No allocation; a no-op before setLipschitz().
  void setBrickLipschitz(int a, int b, int c, float value) noexcept;
  /// Recomputes the upper levels' Lipschitz maxima over the ancestors of the level-0 bricks in
  /// the box [lo_brick, hi_brick] (inclusive, clipped). No allocation.
  void propagateLipschitz(std::array<int, 3> lo_brick, std::array<int, 3> hi_brick) noexcept;

  /// Number of levels (0 when empty).
  int levels() const noexcept { return static_cast<int>(levels_.size()); }
  /// Nodes per axis at `level`.
  std::array<int, 3> nodes(int level) const noexcept { return levels_[level].n; }
  /// Range stored at node (a, b, c) of `level`.
  void node(int level, int a, int b, int c, float& raw_min, float& raw_max) const noexcept;
  bool empty() const noexcept { return levels_.empty(); }

 private:
  struct Level {
    std::array<int, 3> n{0, 0, 0};
    std::vector<float> range;  // (min, max) per node, n[0] * n[1] * n[2] nodes, a fastest
    std::vector<float> lipschitz;  // local Lipschitz bound per node (empty until setLipschitz())
  };
  // rawRange() for a box that spans several level-0 bricks (out of line: the rare case).
  // Returns the number of nodes read.
  int rawRangeSpread(const int* b0, const int* b1, int spread, float& raw_min, float& raw_max,
                     float* lipschitz_max, RawStop stop) const noexcept;

  std::array<int, 3> dims_{0, 0, 0};
  std::vector<Level> levels_;
};

// ---- Inline hot path --------------------------------------------------------------------------

inline void MinMaxTree::node(int level, int a, int b, int c, float& raw_min, float& raw_max) const noexcept {
  const Level& l = levels_[level];
  const std::size_t o = static_cast<std::size_t>(a) + static_cast<std::size_t>(l.n[0]) * (b + static_cast<std::size_t>(l.n[1]) * c);
  raw_min = l.range[2 * o];
  raw_max = l.range[2 * o + 1];
}

inline bool MinMaxTree::rawRange(const Eigen::Vector3d& lo_ijk, const Eigen::Vector3d& hi_ijk, float& raw_min,
                                 float& raw_max, int* nodes_read, float* lipschitz_max, RawStop stop) const noexcept {
  if (nodes_read != nullptr) *nodes_read = 0;
  if (lipschitz_max != nullptr) *lipschitz_max = 0.0f;
  if (levels_.empty()) return false;
  if (!lo_ijk.allFinite() || !hi_ijk.allFinite()) {
    node(levels() - 1, 0, 0, 0, raw_min, raw_max);
    if (nodes_read != nullptr) *nodes_read = 1;
    if (lipschitz_max != nullptr && !levels_.back().lipschitz.empty()) *lipschitz_max = levels_.back().lipschitz[0];
    return true;
  }
  int b0[3], b1[3];
  int spread = 0;  // OR of b0 ^ b1: its bit length bounds the level needed
  for (int a = 0; a < 3; ++a) {
    const double upper = dims_[a] - 1;
    if (hi_ijk[a] < 0.0 || lo_ijk[a] > upper) return false;
    const double lo = std::clamp(lo_ijk[a], 0.0, upper), hi = std::clamp(hi_ijk[a], 0.0, upper);
    // The cell trilinear interpolation uses at x: min(floor(x), n - 2).
    b0[a] = std::min(static_cast<int>(lo), dims_[a] - 2) / kBrickCells;
    b1[a] = std::min(static_cast<int>(hi), dims_[a] - 2) / kBrickCells;
    spread |= b1[a] - b0[a];
  }
  if (spread == 0) {  // one brick: the common case of a short segment
    node(0, b0[0], b0[1], b0[2], raw_min, raw_max);
    if (nodes_read != nullptr) *nodes_read = 1;
    if (lipschitz_max != nullptr) *lipschitz_max = brickLipschitz(b0[0] * kBrickCells, b0[1] * kBrickCells, b0[2] * kBrickCells);
    return true;
  }
  const int read = rawRangeSpread(b0, b1, spread, raw_min, raw_max, lipschitz_max, stop);
  if (nodes_read != nullptr) *nodes_read = read;
  return true;
}

}  // namespace vh::haptics
