#include "vh/haptics/min_max_tree.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <stdexcept>

namespace vh::haptics {
namespace {
constexpr float kInf = std::numeric_limits<float>::infinity();

// Merges 2 nodes into one along `axis` (no shared border: nodes partition the cells).
void mergeAxis(const std::vector<float>& in_lo, const std::vector<float>& in_hi, const std::array<int, 3>& n_in,
               int axis, std::vector<float>& out_lo, std::vector<float>& out_hi, std::array<int, 3>& n_out) {
  n_out = n_in;
  n_out[axis] = (n_in[axis] + 1) / 2;
  const std::size_t count = static_cast<std::size_t>(n_out[0]) * n_out[1] * n_out[2];
  out_lo.assign(count, kInf);
  out_hi.assign(count, -kInf);
  const std::ptrdiff_t stride_in[3] = {1, n_in[0], static_cast<std::ptrdiff_t>(n_in[0]) * n_in[1]};
  for (int k = 0; k < n_out[2]; ++k)
    for (int j = 0; j < n_out[1]; ++j)
      for (int i = 0; i < n_out[0]; ++i) {
        const int idx[3] = {i, j, k};
        std::ptrdiff_t base_in = 0;
        for (int a = 0; a < 3; ++a)
          if (a != axis) base_in += idx[a] * stride_in[a];
        const std::ptrdiff_t o = i + static_cast<std::ptrdiff_t>(n_out[0]) * (j + static_cast<std::ptrdiff_t>(n_out[1]) * k);
        float lo = kInf, hi = -kInf;
        for (int v = 2 * idx[axis]; v <= std::min(2 * idx[axis] + 1, n_in[axis] - 1); ++v) {
          const std::ptrdiff_t p = base_in + v * stride_in[axis];
          lo = std::min(lo, in_lo[p]);
          hi = std::max(hi, in_hi[p]);
        }
        out_lo[o] = lo;
        out_hi[o] = hi;
      }
}
// The raw range of level-0 brick (a, b, c): voxels [4a, 4a + 4] on each axis, clipped to the grid
// (Build() and refreshBricks() alike).
template <typename T>
void brickRange(const T* voxels, const std::array<int, 3>& dims, int a, int b, int c, float& lo, float& hi) {
  constexpr int kB = MinMaxTree::kBrickCells;
  const std::ptrdiff_t sy = dims[0], sz = static_cast<std::ptrdiff_t>(dims[0]) * dims[1];
  float l = kInf, h = -kInf;
  const int x1 = std::min(kB * a + kB, dims[0] - 1), y1 = std::min(kB * b + kB, dims[1] - 1),
            z1 = std::min(kB * c + kB, dims[2] - 1);
  for (int z = kB * c; z <= z1; ++z)
    for (int y = kB * b; y <= y1; ++y) {
      const T* row = voxels + z * sz + y * sy;
      for (int x = kB * a; x <= x1; ++x) {
        const float v = static_cast<float>(row[x]);
        l = std::min(l, v);
        h = std::max(h, v);
      }
    }
  lo = l;
  hi = h;
}

}  // namespace

template <typename T>
MinMaxTree MinMaxTree::Build(const T* voxels, const std::array<int, 3>& dims) {
  MinMaxTree tree;
  tree.dims_ = dims;
  // Level 0 straight from the voxels, brick by brick (no copy of the volume): brick a reads
  // voxels [4a, 4a + 4] clipped to the grid on each axis.
  std::array<int, 3> n;
  for (int a = 0; a < 3; ++a) n[a] = std::max(1, (dims[a] - 1 + kBrickCells - 1) / kBrickCells);
  const std::size_t count = static_cast<std::size_t>(n[0]) * n[1] * n[2];
  std::vector<float> lo(count, kInf), hi(count, -kInf);
  std::size_t o = 0;
  for (int c = 0; c < n[2]; ++c)
    for (int b = 0; b < n[1]; ++b)
      for (int a = 0; a < n[0]; ++a, ++o) brickRange(voxels, dims, a, b, c, lo[o], hi[o]);
  const auto interleave = [](const std::vector<float>& mins, const std::vector<float>& maxs) {
    std::vector<float> range(2 * mins.size());
    for (std::size_t i = 0; i < mins.size(); ++i) {
      range[2 * i] = mins[i];
      range[2 * i + 1] = maxs[i];
    }
    return range;
  };
  tree.levels_.push_back({n, interleave(lo, hi), {}});
  while (n[0] > 1 || n[1] > 1 || n[2] > 1) {
    for (int axis = 0; axis < 3; ++axis) {
      std::vector<float> out_lo, out_hi;
      std::array<int, 3> n_out;
      mergeAxis(lo, hi, n, axis, out_lo, out_hi, n_out);
      lo.swap(out_lo);
      hi.swap(out_hi);
      n = n_out;
    }
    tree.levels_.push_back({n, interleave(lo, hi), {}});
  }
  return tree;
}

// rawRange() reads at most (kSpan + 1)^3 nodes, at the finest level where the box spans that
// few per axis. 1 (8 reads) culled too little for the point-shell tree's balls; 3 (64 reads)
// was the fastest on the Table 1 scenes (Engine mean -25 %), 7 slower again.
constexpr int kSpan = 3;
int MinMaxTree::rawRangeSpread(const int* b0, const int* b1, int spread, float& raw_min, float& raw_max,
                               float* lipschitz_max, RawStop stop) const noexcept {
  // The finest level at which the box spans at most kSpan + 1 nodes per axis.
  int level = 0;
  while ((spread >> level) > kSpan && level + 1 < levels()) ++level;
  while (level + 1 < levels() &&
         ((b1[0] >> level) - (b0[0] >> level) > kSpan || (b1[1] >> level) - (b0[1] >> level) > kSpan ||
          (b1[2] >> level) - (b0[2] >> level) > kSpan))
    ++level;
  const Level& l = levels_[level];
  float lo = kInf, hi = -kInf;
  const int a0 = b0[0] >> level, a1 = b1[0] >> level;
  int rows = 0;
  for (int c = b0[2] >> level; c <= (b1[2] >> level); ++c)
    for (int b = b0[1] >> level; b <= (b1[1] >> level); ++b) {
      const std::size_t row = static_cast<std::size_t>(l.n[0]) * (b + static_cast<std::size_t>(l.n[1]) * c);
      for (int a = a0; a <= a1; ++a) {
        lo = std::min(lo, l.range[2 * (row + a)]);
        hi = std::max(hi, l.range[2 * (row + a) + 1]);
      }
      ++rows;
      // A row that reaches the caller's threshold answers its question: the rest is not read.
      // (NaN, no stop, compares false.)
      if (stop.above ? hi >= stop.raw : lo <= stop.raw) {
        raw_min = lo;
        raw_max = hi;
        if (lipschitz_max != nullptr) *lipschitz_max = 0.0f;
        return rows * (a1 - a0 + 1);
      }
    }
  raw_min = lo;
  raw_max = hi;
  if (lipschitz_max != nullptr && !l.lipschitz.empty()) {
    float lip = 0.0f;
    for (int c = b0[2] >> level; c <= (b1[2] >> level); ++c)
      for (int b = b0[1] >> level; b <= (b1[1] >> level); ++b) {
        const std::size_t row = static_cast<std::size_t>(l.n[0]) * (b + static_cast<std::size_t>(l.n[1]) * c);
        for (int a = b0[0] >> level; a <= (b1[0] >> level); ++a) lip = std::max(lip, l.lipschitz[row + a]);
      }
    *lipschitz_max = lip;
  }
  return ((b1[0] >> level) - (b0[0] >> level) + 1) * ((b1[1] >> level) - (b0[1] >> level) + 1) *
         ((b1[2] >> level) - (b0[2] >> level) + 1);
}

void MinMaxTree::setLipschitz(std::vector<float> per_brick) {
  if (levels_.empty()) return;
  const std::array<int, 3> n0 = levels_[0].n;
  if (per_brick.size() != static_cast<std::size_t>(n0[0]) * n0[1] * n0[2])
    throw std::invalid_argument("MinMaxTree::setLipschitz: one value per level-0 brick expected");
  std::vector<float> cur = std::move(per_brick);
  std::array<int, 3> n = n0;
  levels_[0].lipschitz = cur;
  // The same 2 x 2 x 2 merges as Build(), taking the maximum.
  for (std::size_t level = 1; level < levels_.size(); ++level) {
    for (int axis = 0; axis < 3; ++axis) {
      std::vector<float> out_lo, out_hi;
      std::array<int, 3> n_out;
      mergeAxis(cur, cur, n, axis, out_lo, out_hi, n_out);
      cur.swap(out_hi);
      n = n_out;
    }
    levels_[level].lipschitz = cur;
  }
}

namespace {
// Clips a box of node indices to a level's nodes; false when it is empty.
bool clipBox(std::array<int, 3>& lo, std::array<int, 3>& hi, const std::array<int, 3>& n) {
  for (int a = 0; a < 3; ++a) {
    lo[a] = std::max(lo[a], 0);
    hi[a] = std::min(hi[a], n[a] - 1);
    if (lo[a] > hi[a]) return false;
  }
  return true;
}

// Recomputes the nodes above the level-0 node box [lo, hi], level by level, from their clipped
// 2 x 2 x 2 children: start(l, o) resets node o of level l, merge(l, o, below, i) folds child i of
// the level below into it (the ranges after drilling, the Lipschitz bounds: one walk for both).
template <typename Levels, typename Start, typename Merge>
void updateAncestors(Levels& levels, std::array<int, 3> lo, std::array<int, 3> hi, Start start, Merge merge) {
  for (std::size_t level = 1; level < levels.size(); ++level) {
    const auto& below = levels[level - 1];
    auto& l = levels[level];
    for (int a = 0; a < 3; ++a) {
      lo[a] >>= 1;
      hi[a] >>= 1;
    }
    clipBox(lo, hi, l.n);
    for (int c = lo[2]; c <= hi[2]; ++c)
      for (int b = lo[1]; b <= hi[1]; ++b)
        for (int a = lo[0]; a <= hi[0]; ++a) {
          const std::size_t o = static_cast<std::size_t>(a) + static_cast<std::size_t>(l.n[0]) * (b + static_cast<std::size_t>(l.n[1]) * c);
          start(l, o);
          for (int z = 2 * c; z <= std::min(2 * c + 1, below.n[2] - 1); ++z)
            for (int y = 2 * b; y <= std::min(2 * b + 1, below.n[1] - 1); ++y)
              for (int x = 2 * a; x <= std::min(2 * a + 1, below.n[0] - 1); ++x)
                merge(l, o, below, static_cast<std::size_t>(x) + static_cast<std::size_t>(below.n[0]) * (y + static_cast<std::size_t>(below.n[1]) * z));
        }
  }
}
}  // namespace

template <typename T>
void MinMaxTree::refreshBricks(const T* voxels, std::array<int, 3> lo, std::array<int, 3> hi) noexcept {
  if (levels_.empty() || !clipBox(lo, hi, levels_[0].n)) return;
  Level& l0 = levels_[0];
  for (int c = lo[2]; c <= hi[2]; ++c)
    for (int b = lo[1]; b <= hi[1]; ++b)
      for (int a = lo[0]; a <= hi[0]; ++a) {
        const std::size_t o = static_cast<std::size_t>(a) + static_cast<std::size_t>(l0.n[0]) * (b + static_cast<std::size_t>(l0.n[1]) * c);
        brickRange(voxels, dims_, a, b, c, l0.range[2 * o], l0.range[2 * o + 1]);
      }
  // Each upper node merges the 2 x 2 x 2 nodes below it (clipped), as Build()'s mergeAxis().
  updateAncestors(
      levels_, lo, hi,
      [](auto& l, std::size_t o) {
        l.range[2 * o] = kInf;
        l.range[2 * o + 1] = -kInf;
      },
      [](auto& l, std::size_t o, const auto& below, std::size_t i) {
        l.range[2 * o] = std::min(l.range[2 * o], below.range[2 * i]);
        l.range[2 * o + 1] = std::max(l.range[2 * o + 1], below.range[2 * i + 1]);
      });
}

void MinMaxTree::setBrickLipschitz(int a, int b, int c, float value) noexcept {
  if (levels_.empty() || levels_[0].lipschitz.empty()) return;
  Level& l = levels_[0];
  if (a < 0 || b < 0 || c < 0 || a >= l.n[0] || b >= l.n[1] || c >= l.n[2]) return;
  l.lipschitz[static_cast<std::size_t>(a) + static_cast<std::size_t>(l.n[0]) * (b + static_cast<std::size_t>(l.n[1]) * c)] = value;
}

void MinMaxTree::propagateLipschitz(std::array<int, 3> lo, std::array<int, 3> hi) noexcept {
  if (levels_.empty() || levels_[0].lipschitz.empty() || !clipBox(lo, hi, levels_[0].n)) return;
  updateAncestors(
      levels_, lo, hi, [](auto& l, std::size_t o) { l.lipschitz[o] = 0.0f; },
      [](auto& l, std::size_t o, const auto& below, std::size_t i) { l.lipschitz[o] = std::max(l.lipschitz[o], below.lipschitz[i]); });
}

template void MinMaxTree::refreshBricks<std::uint8_t>(const std::uint8_t*, std::array<int, 3>, std::array<int, 3>) noexcept;
template void MinMaxTree::refreshBricks<std::int16_t>(const std::int16_t*, std::array<int, 3>, std::array<int, 3>) noexcept;
template void MinMaxTree::refreshBricks<std::uint16_t>(const std::uint16_t*, std::array<int, 3>, std::array<int, 3>) noexcept;
template void MinMaxTree::refreshBricks<float>(const float*, std::array<int, 3>, std::array<int, 3>) noexcept;

template MinMaxTree MinMaxTree::Build<std::uint8_t>(const std::uint8_t*, const std::array<int, 3>&);
template MinMaxTree MinMaxTree::Build<std::int16_t>(const std::int16_t*, const std::array<int, 3>&);
template MinMaxTree MinMaxTree::Build<std::uint16_t>(const std::uint16_t*, const std::array<int, 3>&);
template MinMaxTree MinMaxTree::Build<float>(const float*, const std::array<int, 3>&);

}  // namespace vh::haptics
