#include "vh/haptics/scalar_volume.h"

#include <cmath>
#include <cstring>
#include <algorithm>
#include <array>
#include <limits>
#include <stdexcept>
#include <string>

#include <Eigen/LU>

#include "float_rounding.h"

namespace vh::haptics {

const char* voxelTypeName(VoxelType type) noexcept {
  switch (type) {
    case VoxelType::kUInt8: return "uint8";
    case VoxelType::kInt16: return "int16";
    case VoxelType::kUInt16: return "uint16";
    case VoxelType::kFloat32: return "float32";
  }
  return "unknown";
}

std::size_t voxelTypeSize(VoxelType type) noexcept {
  switch (type) {
    case VoxelType::kUInt8: return 1;
    case VoxelType::kInt16: return 2;
    case VoxelType::kUInt16: return 2;
    case VoxelType::kFloat32: return 4;
  }
  return 0;
}

namespace {
template <typename T> constexpr VoxelType voxelTypeOf();
template <> constexpr VoxelType voxelTypeOf<std::uint8_t>() { return VoxelType::kUInt8; }
template <> constexpr VoxelType voxelTypeOf<std::int16_t>() { return VoxelType::kInt16; }
template <> constexpr VoxelType voxelTypeOf<std::uint16_t>() { return VoxelType::kUInt16; }
template <> constexpr VoxelType voxelTypeOf<float>() { return VoxelType::kFloat32; }

// One pass over the raw voxels: their range; per level-0 brick of the min-max tree the largest
// |v(i + 1) - v(i)| along each grid axis over the edges booked to the brick (the local
// Lipschitz bound's steps); per step brick (ScalarVolume::kStepBrickCells) the smallest and
// largest v(i + 1) - v(i) (the edge test's derivative ranges). Stops at the first non-finite
// value (only float32 holds one) with finite = false and its index.
struct VoxelScan {
  double lo = 0.0, hi = 0.0;
  bool finite = true;
  std::array<std::ptrdiff_t, 3> first_nonfinite{0, 0, 0};
  std::array<int, 3> bricks{0, 0, 0};
  std::vector<double> step[3];  // per brick, per axis: largest raw step of the edges booked to it
  std::array<int, 3> step_bricks{0, 0, 0};
  std::vector<float> steps;     // per step brick: the smallest steps along i, j, k, then the largest
};

// Widens a brick's range of steps along axis a (steps[a] the smallest, steps[3 + a] the largest)
// by `step`, rounded outward to float (exact for the integer types' steps).
inline void bookStep(float* steps, int a, double step) noexcept {
  steps[a] = std::min(steps[a], floatBelow(step));
  steps[3 + a] = std::max(steps[3 + a], floatAbove(step));
}

// A step brick's range before any edge is booked to it.
inline void emptySteps(float* steps) noexcept {
  for (int a = 0; a < 3; ++a) {
    steps[a] = std::numeric_limits<float>::infinity();
    steps[3 + a] = -std::numeric_limits<float>::infinity();
  }
}

template <typename T>
VoxelScan scanVoxels(const std::vector<std::byte>& bytes, const std::array<int, 3>& dims) {
  const T* d = reinterpret_cast<const T*>(bytes.data());
  const std::ptrdiff_t nx = dims[0], ny = dims[1], nz = dims[2];
  constexpr int kB = MinMaxTree::kBrickCells;
  VoxelScan scan;
  for (int a = 0; a < 3; ++a) scan.bricks[a] = std::max(1, (dims[a] - 1 + kB - 1) / kB);
  const std::size_t brick_count = static_cast<std::size_t>(scan.bricks[0]) * scan.bricks[1] * scan.bricks[2];
  for (auto& s : scan.step) s.assign(brick_count, 0.0);
  constexpr int kS = ScalarVolume::kStepBrickCells;
  for (int a = 0; a < 3; ++a) scan.step_bricks[a] = std::max(1, (dims[a] - 1 + kS - 1) / kS);
  const std::size_t step_brick_count =
      static_cast<std::size_t>(scan.step_bricks[0]) * scan.step_bricks[1] * scan.step_bricks[2];
  scan.steps.resize(6 * step_brick_count);
  for (std::size_t b = 0; b < step_brick_count; ++b) emptySteps(scan.steps.data() + 6 * b);
  const auto step_brick = [&](std::ptrdiff_t ci, std::ptrdiff_t cj, std::ptrdiff_t ck) {
    return static_cast<std::size_t>(ci / kS) +
           static_cast<std::size_t>(scan.step_bricks[0]) *
               (cj / kS + static_cast<std::size_t>(scan.step_bricks[1]) * (ck / kS));
  };
  const auto brick = [&](std::ptrdiff_t ci, std::ptrdiff_t cj, std::ptrdiff_t ck) {
    return static_cast<std::size_t>(ci / kB) +
           static_cast<std::size_t>(scan.bricks[0]) * (cj / kB + static_cast<std::size_t>(scan.bricks[1]) * (ck / kB));
  };
  double mn = std::numeric_limits<double>::infinity(), mx = -mn;
  for (std::ptrdiff_t k = 0; k < nz; ++k)
    for (std::ptrdiff_t j = 0; j < ny; ++j) {
      const T* row = d + nx * (j + ny * k);
      for (std::ptrdiff_t i = 0; i < nx; ++i) {
        const double v = row[i];
        if (!std::isfinite(v)) {
          scan.finite = false;
          scan.first_nonfinite = {i, j, k};
          return scan;
        }
        mn = std::min(mn, v);
        mx = std::max(mx, v);
      }
    }
  // Edges; the values are finite here. Each edge is booked to the brick of its home cell (the
  // cell at its voxel, clipped to the cells); its other cells are within one cell of that one,
  // so within one brick: the 3 x 3 x 3 dilation in initialise() covers them.
  for (std::ptrdiff_t k = 0; k < nz; ++k)
    for (std::ptrdiff_t j = 0; j < ny; ++j) {
      const T* row = d + nx * (j + ny * k);
      const std::ptrdiff_t cj = std::min<std::ptrdiff_t>(j, ny - 2), ck = std::min<std::ptrdiff_t>(k, nz - 2);
      for (std::ptrdiff_t i = 0; i < nx; ++i) {
        const double v = row[i];
        const std::ptrdiff_t ci = std::min<std::ptrdiff_t>(i, nx - 2);
        const std::size_t home = brick(ci, cj, ck);
        float* steps = scan.steps.data() + 6 * step_brick(ci, cj, ck);
        if (i + 1 < nx) {
          const double step = static_cast<double>(row[i + 1]) - v;
          scan.step[0][home] = std::max(scan.step[0][home], std::abs(step));
          bookStep(steps, 0, step);
        }
        if (j + 1 < ny) {
          const double step = static_cast<double>(row[i + nx]) - v;
          scan.step[1][home] = std::max(scan.step[1][home], std::abs(step));
          bookStep(steps, 1, step);
        }
        if (k + 1 < nz) {
          const double step = static_cast<double>(row[i + nx * ny]) - v;
          scan.step[2][home] = std::max(scan.step[2][home], std::abs(step));
          bookStep(steps, 2, step);
        }
      }
    }
  scan.lo = mn;
  scan.hi = mx;
  return scan;
}
}  // namespace

template <typename T>
ScalarVolume ScalarVolume::FromVoxels(const VolumeGeometry& geometry, const std::vector<T>& voxels,
                                      double value_scale, double value_offset) {
  std::vector<std::byte> bytes(voxels.size() * sizeof(T));
  if (!voxels.empty()) std::memcpy(bytes.data(), voxels.data(), bytes.size());
  return FromBytes(geometry, voxelTypeOf<T>(), std::move(bytes), value_scale, value_offset);
}

template ScalarVolume ScalarVolume::FromVoxels<std::uint8_t>(const VolumeGeometry&, const std::vector<std::uint8_t>&, double, double);
template ScalarVolume ScalarVolume::FromVoxels<std::int16_t>(const VolumeGeometry&, const std::vector<std::int16_t>&, double, double);
template ScalarVolume ScalarVolume::FromVoxels<std::uint16_t>(const VolumeGeometry&, const std::vector<std::uint16_t>&, double, double);
template ScalarVolume ScalarVolume::FromVoxels<float>(const VolumeGeometry&, const std::vector<float>&, double, double);

ScalarVolume ScalarVolume::FromBytes(const VolumeGeometry& geometry, VoxelType type, std::vector<std::byte> bytes,
                                     double value_scale, double value_offset) {
  ScalarVolume v;
  v.geometry_ = geometry;
  v.type_ = type;
  v.bytes_ = std::move(bytes);
  v.scale_ = value_scale;
  v.offset_ = value_offset;
  v.initialise();
  return v;
}

void ScalarVolume::initialise() {
  const auto& g = geometry_;
  for (int a = 0; a < 3; ++a) {
    if (g.dims[a] < 2)
      throw std::invalid_argument("ScalarVolume: every axis needs at least 2 voxels (dims " + std::to_string(g.dims[0]) +
                                  " x " + std::to_string(g.dims[1]) + " x " + std::to_string(g.dims[2]) + ")");
    if (!(g.spacing_m[a] > 0.0) || !std::isfinite(g.spacing_m[a]))
      throw std::invalid_argument("ScalarVolume: voxel spacing must be finite and > 0");
  }
  if (!g.origin_W_m.allFinite()) throw std::invalid_argument("ScalarVolume: origin is not finite");
  if (!g.direction_W.allFinite() ||
      !(g.direction_W.transpose() * g.direction_W).isApprox(Eigen::Matrix3d::Identity(), 1e-6))
    throw std::invalid_argument("ScalarVolume: direction matrix is not orthonormal");
  if (!std::isfinite(scale_) || scale_ == 0.0 || !std::isfinite(offset_))
    throw std::invalid_argument("ScalarVolume: value scale must be finite and non-zero, offset finite");
  const std::size_t expected = g.voxelCount() * voxelTypeSize(type_);
  if (bytes_.size() != expected)
    throw std::invalid_argument("ScalarVolume: " + std::to_string(bytes_.size()) + " bytes of voxel data, expected " +
                                std::to_string(expected) + " for " + voxelTypeName(type_));

  W_to_grid_ = (g.direction_W * g.spacing_m.asDiagonal()).inverse();
  upper_ = Eigen::Vector3d(g.dims[0] - 1, g.dims[1] - 1, g.dims[2] - 1);

  VoxelScan scan;
  switch (type_) {
    case VoxelType::kUInt8: scan = scanVoxels<std::uint8_t>(bytes_, g.dims); break;
    case VoxelType::kInt16: scan = scanVoxels<std::int16_t>(bytes_, g.dims); break;
    case VoxelType::kUInt16: scan = scanVoxels<std::uint16_t>(bytes_, g.dims); break;
    case VoxelType::kFloat32: scan = scanVoxels<float>(bytes_, g.dims); break;
  }
  if (!scan.finite) {
    const auto& at = scan.first_nonfinite;
    throw std::invalid_argument("ScalarVolume: voxel data contains NaN or infinity, the first at voxel (" +
                                std::to_string(at[0]) + ", " + std::to_string(at[1]) + ", " + std::to_string(at[2]) +
                                ") (i, j, k from 0)");
  }
  switch (type_) {
    case VoxelType::kUInt8: tree_ = MinMaxTree::Build(reinterpret_cast<const std::uint8_t*>(bytes_.data()), g.dims); break;
    case VoxelType::kInt16: tree_ = MinMaxTree::Build(reinterpret_cast<const std::int16_t*>(bytes_.data()), g.dims); break;
    case VoxelType::kUInt16: tree_ = MinMaxTree::Build(reinterpret_cast<const std::uint16_t*>(bytes_.data()), g.dims); break;
    case VoxelType::kFloat32: tree_ = MinMaxTree::Build(reinterpret_cast<const float*>(bytes_.data()), g.dims); break;
  }
  // Local Lipschitz bounds: |dF/dx_a| <= |scale| step_a / spacing_a inside a cell (a bilinear
  // blend of its four edge differences along a), so |grad F| <= |scale| |(step / spacing)| over
  // the cells whose edges a brick holds; 1e-9 relative and rounding up to float for rounding.
  // Each brick then takes the largest value of its 3 x 3 x 3 neighbourhood, so its bound holds
  // for every cell within one cell of its own (their edges are booked within one brick): an arc that leaves its chord by far less than a voxel stays covered, and
  // one outlier voxel raises the bound only within a brick of it (not the whole volume).
  const std::array<int, 3> nb = scan.bricks;
  bricks_ = nb;
  std::vector<float> own(scan.step[0].size());
  lipschitz_ = 0.0;
  for (std::size_t b = 0; b < own.size(); ++b) {
    const double step[3] = {scan.step[0][b], scan.step[1][b], scan.step[2][b]};
    own[b] = brickBound(step);
    lipschitz_ = std::max(lipschitz_, static_cast<double>(own[b]));
  }
  std::vector<float> dilated(own.size(), 0.0f);
  for (int c = 0; c < nb[2]; ++c)
    for (int b = 0; b < nb[1]; ++b)
      for (int a = 0; a < nb[0]; ++a) {
        float m = 0.0f;
        for (int z = std::max(0, c - 1); z <= std::min(nb[2] - 1, c + 1); ++z)
          for (int y = std::max(0, b - 1); y <= std::min(nb[1] - 1, b + 1); ++y)
            for (int x = std::max(0, a - 1); x <= std::min(nb[0] - 1, a + 1); ++x)
              m = std::max(m, own[static_cast<std::size_t>(x) + static_cast<std::size_t>(nb[0]) * (y + static_cast<std::size_t>(nb[1]) * z)]);
        dilated[static_cast<std::size_t>(a) + static_cast<std::size_t>(nb[0]) * (b + static_cast<std::size_t>(nb[1]) * c)] = m;
      }
  tree_.setLipschitz(std::move(dilated));
  own_lipschitz_ = std::move(own);
  step_bricks_ = scan.step_bricks;
  steps_ = std::move(scan.steps);
  raw_min_ = scan.lo;
  raw_max_ = scan.hi;
  min_value_ = std::min(scale_ * scan.lo + offset_, scale_ * scan.hi + offset_);
  max_value_ = std::max(scale_ * scan.lo + offset_, scale_ * scan.hi + offset_);
}

float ScalarVolume::brickBound(const double* step) const noexcept {
  const Eigen::Vector3d s(step[0], step[1], step[2]);
  const double L = std::abs(scale_) * s.cwiseQuotient(geometry_.spacing_m).norm() * (1.0 + 1e-9);
  // Capped at the largest float: a brick next to a -3e38 "no data" fill keeps a finite bound.
  return floatAbove(std::min(L, static_cast<double>(std::numeric_limits<float>::max())));
}

double ScalarVolume::rawAt(std::size_t idx) const noexcept {
  switch (type_) {
    case VoxelType::kUInt8: return reinterpret_cast<const std::uint8_t*>(bytes_.data())[idx];
    case VoxelType::kInt16: return reinterpret_cast<const std::int16_t*>(bytes_.data())[idx];
    case VoxelType::kUInt16: return reinterpret_cast<const std::uint16_t*>(bytes_.data())[idx];
    case VoxelType::kFloat32: return reinterpret_cast<const float*>(bytes_.data())[idx];
  }
  return 0.0;
}

void ScalarVolume::writeRaw(std::size_t idx, double raw) noexcept {
  switch (type_) {
    case VoxelType::kUInt8: reinterpret_cast<std::uint8_t*>(bytes_.data())[idx] = static_cast<std::uint8_t>(raw); break;
    case VoxelType::kInt16: reinterpret_cast<std::int16_t*>(bytes_.data())[idx] = static_cast<std::int16_t>(raw); break;
    case VoxelType::kUInt16: reinterpret_cast<std::uint16_t*>(bytes_.data())[idx] = static_cast<std::uint16_t>(raw); break;
    case VoxelType::kFloat32: reinterpret_cast<float*>(bytes_.data())[idx] = static_cast<float>(raw); break;
  }
}

void ScalarVolume::refreshRegion(std::array<int, 3> lo, std::array<int, 3> hi) noexcept {
  for (int a = 0; a < 3; ++a) {
    lo[a] = std::max(lo[a], 0);
    hi[a] = std::min(hi[a], geometry_.dims[a] - 1);
    if (lo[a] > hi[a] || bytes_.empty()) return;
  }
  switch (type_) {
    case VoxelType::kUInt8: refreshRegionT<std::uint8_t>(lo, hi); break;
    case VoxelType::kInt16: refreshRegionT<std::int16_t>(lo, hi); break;
    case VoxelType::kUInt16: refreshRegionT<std::uint16_t>(lo, hi); break;
    case VoxelType::kFloat32: refreshRegionT<float>(lo, hi); break;
  }
}

template <typename T>
void ScalarVolume::recountOwnLipschitz(const std::array<int, 3>& e0, const std::array<int, 3>& e1) noexcept {
  constexpr int kB = MinMaxTree::kBrickCells;
  const auto& n = geometry_.dims;
  const T* d = reinterpret_cast<const T*>(bytes_.data());
  const std::ptrdiff_t sy = n[0], sz = static_cast<std::ptrdiff_t>(n[0]) * n[1];
  for (int c = e0[2]; c <= e1[2]; ++c)
    for (int b = e0[1]; b <= e1[1]; ++b)
      for (int a = e0[0]; a <= e1[0]; ++a) {
        // The voxels whose home cell lies in this brick: [4a, 4a + 3], and n - 1 in the last one.
        const int brick[3] = {a, b, c};
        int v0[3], v1[3];
        for (int ax = 0; ax < 3; ++ax) {
          v0[ax] = kB * brick[ax];
          v1[ax] = kB * brick[ax] + kB - 1 >= n[ax] - 2 ? n[ax] - 1 : kB * brick[ax] + kB - 1;
        }
        double step[3] = {0.0, 0.0, 0.0};
        for (std::ptrdiff_t k = v0[2]; k <= v1[2]; ++k)
          for (std::ptrdiff_t j = v0[1]; j <= v1[1]; ++j) {
            const T* row = d + k * sz + j * sy;
            for (std::ptrdiff_t i = v0[0]; i <= v1[0]; ++i) {
              const double v = row[i];
              if (i + 1 < n[0]) step[0] = std::max(step[0], std::abs(static_cast<double>(row[i + 1]) - v));
              if (j + 1 < n[1]) step[1] = std::max(step[1], std::abs(static_cast<double>(row[i + sy]) - v));
              if (k + 1 < n[2]) step[2] = std::max(step[2], std::abs(static_cast<double>(row[i + sz]) - v));
            }
          }
        const float f = brickBound(step);
        own_lipschitz_[ownBrickIndex(a, b, c)] = f;
        lipschitz_ = std::max(lipschitz_, static_cast<double>(f));
      }
}

void ScalarVolume::dilateLipschitz(const std::array<int, 3>& e0, const std::array<int, 3>& e1) noexcept {
  std::array<int, 3> g0, g1;
  for (int a = 0; a < 3; ++a) {
    g0[a] = std::max(0, e0[a] - 1);
    g1[a] = std::min(bricks_[a] - 1, e1[a] + 1);
  }
  for (int c = g0[2]; c <= g1[2]; ++c)
    for (int b = g0[1]; b <= g1[1]; ++b)
      for (int a = g0[0]; a <= g1[0]; ++a) {
        float m = 0.0f;
        for (int z = std::max(0, c - 1); z <= std::min(bricks_[2] - 1, c + 1); ++z)
          for (int y = std::max(0, b - 1); y <= std::min(bricks_[1] - 1, b + 1); ++y)
            for (int x = std::max(0, a - 1); x <= std::min(bricks_[0] - 1, a + 1); ++x)
              m = std::max(m, own_lipschitz_[ownBrickIndex(x, y, z)]);
        tree_.setBrickLipschitz(a, b, c, m);
      }
  tree_.propagateLipschitz(g0, g1);
}

template <typename T>
void ScalarVolume::widenStepRanges(const std::array<int, 3>& lo, const std::array<int, 3>& hi) noexcept {
  constexpr int kS = kStepBrickCells;
  const auto& n = geometry_.dims;
  const T* d = reinterpret_cast<const T*>(bytes_.data());
  const std::ptrdiff_t sy = n[0], sz = static_cast<std::ptrdiff_t>(n[0]) * n[1];
  const auto stepBrick = [&](int i, int j, int k) {  // of the edges from voxel (i, j, k)
    return steps_.data() + stepBrickOffset(std::min(i, n[0] - 2) / kS, std::min(j, n[1] - 2) / kS,
                                           std::min(k, n[2] - 2) / kS);
  };
  for (int k = std::max(0, lo[2] - 1); k <= hi[2]; ++k)
    for (int j = std::max(0, lo[1] - 1); j <= hi[1]; ++j) {
      const T* row = d + k * sz + j * sy;
      for (int i = std::max(0, lo[0] - 1); i <= hi[0]; ++i) {
        const double v = row[i];
        float* steps = stepBrick(i, j, k);
        if (i + 1 < n[0]) bookStep(steps, 0, static_cast<double>(row[i + 1]) - v);
        if (j + 1 < n[1]) bookStep(steps, 1, static_cast<double>(row[i + sy]) - v);
        if (k + 1 < n[2]) bookStep(steps, 2, static_cast<double>(row[i + sz]) - v);
      }
    }
}

template <typename T>
void ScalarVolume::refreshRegionT(const std::array<int, 3>& lo, const std::array<int, 3>& hi) noexcept {
  constexpr int kB = MinMaxTree::kBrickCells;
  const auto& n = geometry_.dims;
  // Ranges: brick a reads voxels [4a, 4a + 4], so the bricks with 4a <= hi and 4a + 4 >= lo.
  std::array<int, 3> r0, r1, e0, e1;
  for (int a = 0; a < 3; ++a) {
    r0[a] = std::max(0, (lo[a] + kB - 1) / kB - 1);
    r1[a] = std::min(bricks_[a] - 1, hi[a] / kB);
    // Edges (v, v + 1) are booked to the brick of cell min(v, n - 2); those touching a written
    // voxel x have v in {x - 1, x}.
    e0[a] = std::max(0, lo[a] - 1) / kB;
    e1[a] = std::min(bricks_[a] - 1, std::min(hi[a], n[a] - 2) / kB);
  }
  tree_.refreshBricks(reinterpret_cast<const T*>(bytes_.data()), r0, r1);
  recountOwnLipschitz<T>(e0, e1);
  // The dilated bounds of the recomputed bricks' neighbours (as initialise()).
  dilateLipschitz(e0, e1);
  // The derivative ranges only widen: every edge that touches a written voxel (from voxel
  // lo - 1 to hi per axis) adds its new step to its step brick; an edge not touching one kept
  // its step, which the range holds already (looser than a recount where a step vanished,
  // never too narrow).
  widenStepRanges<T>(lo, hi);
}

bool ScalarVolume::gridStepRange(const Eigen::Vector3d& lo_ijk, const Eigen::Vector3d& hi_ijk,
                                 Eigen::Vector3d& step_lo, Eigen::Vector3d& step_hi, Eigen::Vector3d* valid_lo_ijk,
                                 Eigen::Vector3d* valid_hi_ijk) const noexcept {
  if (!lo_ijk.allFinite() || !hi_ijk.allFinite() || steps_.empty()) return false;
  // The cells [floor(lo), floor(hi)] (the last cell holds the grid's far face); their edges are
  // booked to the step bricks of the cells up to one further along each axis (scanVoxels()).
  constexpr int kB = kStepBrickCells;
  int b0[3], b1[3];
  for (int a = 0; a < 3; ++a) {
    if (!(lo_ijk[a] >= 0.0 && hi_ijk[a] <= upper_[a] && lo_ijk[a] <= hi_ijk[a])) return false;
    const int top = geometry_.dims[a] - 2;
    b0[a] = std::min(static_cast<int>(lo_ijk[a]), top) / kB;
    b1[a] = std::min(static_cast<int>(hi_ijk[a]) + 1, top) / kB;
  }
  double lo[3], hi[3];
  for (int a = 0; a < 3; ++a) {
    lo[a] = std::numeric_limits<double>::infinity();
    hi[a] = -lo[a];
  }
  for (int c = b0[2]; c <= b1[2]; ++c)
    for (int b = b0[1]; b <= b1[1]; ++b)
      for (int a = b0[0]; a <= b1[0]; ++a) {
        const float* steps = steps_.data() + stepBrickOffset(a, b, c);
        for (int ax = 0; ax < 3; ++ax) {
          lo[ax] = std::min(lo[ax], static_cast<double>(steps[ax]));
          hi[ax] = std::max(hi[ax], static_cast<double>(steps[3 + ax]));
        }
      }
  // F = scale raw + offset: a negative scale swaps the range. Widened by a relative 1e-9 for
  // the product's rounding.
  for (int a = 0; a < 3; ++a) {
    double l = scale_ * lo[a], h = scale_ * hi[a];
    if (l > h) std::swap(l, h);
    const double pad = 1e-9 * std::max(std::abs(l), std::abs(h));
    step_lo[a] = l - pad;
    step_hi[a] = h + pad;
  }
  // The largest box that reads the same bricks: its cells [floor(lo), floor(hi)] run from the
  // first brick's first cell to the one before the last brick's last cell (a cell's derivative
  // also reads the edges of the cells one further along each axis), or to the grid's far face.
  if (!step_lo.allFinite() || !step_hi.allFinite()) return false;
  for (int a = 0; a < 3; ++a) {
    if (valid_lo_ijk != nullptr) (*valid_lo_ijk)[a] = static_cast<double>(b0[a] * kB);
    if (valid_hi_ijk != nullptr)  // just below the last brick's last cell, whose edges go into the next brick
      (*valid_hi_ijk)[a] = b1[a] == (geometry_.dims[a] - 2) / kB
                               ? upper_[a]
                               : std::nextafter(static_cast<double>((b1[a] + 1) * kB - 1), 0.0);
  }
  return true;
}

double ScalarVolume::voxel(int i, int j, int k) const noexcept {
  const auto& d = geometry_.dims;
  i = std::clamp(i, 0, d[0] - 1);
  j = std::clamp(j, 0, d[1] - 1);
  k = std::clamp(k, 0, d[2] - 1);
  const std::size_t idx = static_cast<std::size_t>(i) + static_cast<std::size_t>(d[0]) * (j + static_cast<std::size_t>(d[1]) * k);
  double raw = 0.0;
  switch (type_) {
    case VoxelType::kUInt8: raw = reinterpret_cast<const std::uint8_t*>(bytes_.data())[idx]; break;
    case VoxelType::kInt16: raw = reinterpret_cast<const std::int16_t*>(bytes_.data())[idx]; break;
    case VoxelType::kUInt16: raw = reinterpret_cast<const std::uint16_t*>(bytes_.data())[idx]; break;
    case VoxelType::kFloat32: raw = reinterpret_cast<const float*>(bytes_.data())[idx]; break;
  }
  return scale_ * raw + offset_;
}

Eigen::Vector3d ScalarVolume::gradient(const Eigen::Vector3d& p_W_m) const noexcept {
  // Eq. 1 along the grid axes: delta = one voxel (the spacing) on each axis.
  const Eigen::Vector3d g = gridCoordinates(p_W_m);
  Eigen::Vector3d d_grid;
  for (int a = 0; a < 3; ++a) {
    Eigen::Vector3d plus = g, minus = g;
    plus[a] += 1.0;
    minus[a] -= 1.0;
    d_grid[a] = (sampleGrid(plus) - sampleGrid(minus)) / (2.0 * geometry_.spacing_m[a]);
  }
  return geometry_.direction_W * d_grid;
}

Eigen::Vector3d ScalarVolume::interpolantGradient(const Eigen::Vector3d& p_W_m) const noexcept {
  constexpr double kStep = 1e-3;  // voxels
  const Eigen::Vector3d g = gridCoordinates(p_W_m);
  Eigen::Vector3d d_grid;
  for (int a = 0; a < 3; ++a) {
    Eigen::Vector3d plus = g, minus = g;
    plus[a] += kStep;
    minus[a] -= kStep;
    d_grid[a] = (sampleGrid(plus) - sampleGrid(minus)) / (2.0 * kStep * geometry_.spacing_m[a]);
  }
  return geometry_.direction_W * d_grid;
}

Eigen::Vector3d ScalarVolume::boundsMin_W_m() const noexcept {
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
  for (int c = 0; c < 8; ++c) {
    const Eigen::Vector3d ijk((c & 1) ? upper_.x() : 0.0, (c & 2) ? upper_.y() : 0.0, (c & 4) ? upper_.z() : 0.0);
    lo = lo.cwiseMin(geometry_.pointOf_W(ijk));
  }
  return lo;
}

Eigen::Vector3d ScalarVolume::boundsMax_W_m() const noexcept {
  Eigen::Vector3d hi = Eigen::Vector3d::Constant(-std::numeric_limits<double>::infinity());
  for (int c = 0; c < 8; ++c) {
    const Eigen::Vector3d ijk((c & 1) ? upper_.x() : 0.0, (c & 2) ? upper_.y() : 0.0, (c & 4) ? upper_.z() : 0.0);
    hi = hi.cwiseMax(geometry_.pointOf_W(ijk));
  }
  return hi;
}

}  // namespace vh::haptics
