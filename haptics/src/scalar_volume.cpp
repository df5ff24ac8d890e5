#include "vh/haptics/scalar_volume.h"

#include <cmath>
#include <cstring>
#include <limits>
#include <stdexcept>
#include <string>

#include <Eigen/LU>

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

// One pass over the raw voxels: their range, and the largest |v(i + 1) - v(i)| along each grid
// axis (the Lipschitz bound's steps). Stops at the first non-finite value (only float32 holds
// one) with finite = false.
struct VoxelScan {
  double lo = 0.0, hi = 0.0;
  Eigen::Vector3d step = Eigen::Vector3d::Zero();
  bool finite = true;
};

template <typename T>
VoxelScan scanVoxels(const std::vector<std::byte>& bytes, const std::array<int, 3>& dims) {
  const T* d = reinterpret_cast<const T*>(bytes.data());
  const std::ptrdiff_t nx = dims[0], ny = dims[1], nz = dims[2];
  VoxelScan scan;
  double mn = std::numeric_limits<double>::infinity(), mx = -mn, sx = 0.0, sy = 0.0, sz = 0.0;
  for (std::ptrdiff_t k = 0; k < nz; ++k)
    for (std::ptrdiff_t j = 0; j < ny; ++j) {
      const T* row = d + nx * (j + ny * k);
      for (std::ptrdiff_t i = 0; i < nx; ++i) {
        const double v = row[i];
        if (!std::isfinite(v)) {
          scan.finite = false;
          return scan;
        }
        mn = std::min(mn, v);
        mx = std::max(mx, v);
        if (i + 1 < nx) sx = std::max(sx, std::abs(static_cast<double>(row[i + 1]) - v));
        if (j + 1 < ny) sy = std::max(sy, std::abs(static_cast<double>(row[i + nx]) - v));
        if (k + 1 < nz) sz = std::max(sz, std::abs(static_cast<double>(row[i + nx * ny]) - v));
      }
    }
  scan.lo = mn;
  scan.hi = mx;
  scan.step = {sx, sy, sz};
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
  if (!scan.finite) throw std::invalid_argument("ScalarVolume: voxel data contains NaN or infinity");
  switch (type_) {
    case VoxelType::kUInt8: tree_ = MinMaxTree::Build(reinterpret_cast<const std::uint8_t*>(bytes_.data()), g.dims); break;
    case VoxelType::kInt16: tree_ = MinMaxTree::Build(reinterpret_cast<const std::int16_t*>(bytes_.data()), g.dims); break;
    case VoxelType::kUInt16: tree_ = MinMaxTree::Build(reinterpret_cast<const std::uint16_t*>(bytes_.data()), g.dims); break;
    case VoxelType::kFloat32: tree_ = MinMaxTree::Build(reinterpret_cast<const float*>(bytes_.data()), g.dims); break;
  }
  // |dF/dx_a| <= |scale| step_a / spacing_a inside every cell; 1e-9 relative for rounding.
  lipschitz_ = std::abs(scale_) * scan.step.cwiseQuotient(g.spacing_m).norm() * (1.0 + 1e-9);
  min_value_ = std::min(scale_ * scan.lo + offset_, scale_ * scan.hi + offset_);
  max_value_ = std::max(scale_ * scan.lo + offset_, scale_ * scan.hi + offset_);
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
    lo = lo.cwiseMin(geometry_.origin_W_m + geometry_.direction_W * geometry_.spacing_m.cwiseProduct(ijk));
  }
  return lo;
}

Eigen::Vector3d ScalarVolume::boundsMax_W_m() const noexcept {
  Eigen::Vector3d hi = Eigen::Vector3d::Constant(-std::numeric_limits<double>::infinity());
  for (int c = 0; c < 8; ++c) {
    const Eigen::Vector3d ijk((c & 1) ? upper_.x() : 0.0, (c & 2) ? upper_.y() : 0.0, (c & 4) ? upper_.z() : 0.0);
    hi = hi.cwiseMax(geometry_.origin_W_m + geometry_.direction_W * geometry_.spacing_m.cwiseProduct(ijk));
  }
  return hi;
}

}  // namespace vh::haptics
