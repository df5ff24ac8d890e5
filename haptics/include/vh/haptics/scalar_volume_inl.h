#pragma once
// Inline hot paths of ScalarVolume (included from scalar_volume.h).

#include <algorithm>
#include <cmath>
#include <limits>

namespace vh::haptics {

template <typename T>
double ScalarVolume::trilinear(const Eigen::Vector3d& ijk) const noexcept {
  const T* data = reinterpret_cast<const T*>(bytes_.data());
  const int nx = geometry_.dims[0], ny = geometry_.dims[1];
  // Clamp to the grid, then pick the cell so that the upper corner stays inside.
  const double x = std::clamp(ijk.x(), 0.0, upper_.x());
  const double y = std::clamp(ijk.y(), 0.0, upper_.y());
  const double z = std::clamp(ijk.z(), 0.0, upper_.z());
  const int i = std::min(static_cast<int>(x), geometry_.dims[0] - 2);
  const int j = std::min(static_cast<int>(y), geometry_.dims[1] - 2);
  const int k = std::min(static_cast<int>(z), geometry_.dims[2] - 2);
  const double fx = x - i, fy = y - j, fz = z - k;
  const std::ptrdiff_t sx = 1, sy = nx, sz = static_cast<std::ptrdiff_t>(nx) * ny;
  const T* c = data + i + sy * j + sz * k;
  const double c000 = c[0], c100 = c[sx], c010 = c[sy], c110 = c[sx + sy];
  const double c001 = c[sz], c101 = c[sx + sz], c011 = c[sy + sz], c111 = c[sx + sy + sz];
  const double c00 = c000 + fx * (c100 - c000);
  const double c10 = c010 + fx * (c110 - c010);
  const double c01 = c001 + fx * (c101 - c001);
  const double c11 = c011 + fx * (c111 - c011);
  const double c0 = c00 + fy * (c10 - c00);
  const double c1 = c01 + fy * (c11 - c01);
  return c0 + fz * (c1 - c0);
}

inline Eigen::Vector3d ScalarVolume::gridCoordinates(const Eigen::Vector3d& p_W_m) const noexcept {
  return W_to_grid_ * (p_W_m - geometry_.origin_W_m);
}

inline bool ScalarVolume::gridInBounds(const Eigen::Vector3d& g) const noexcept {
  return g.x() >= 0.0 && g.y() >= 0.0 && g.z() >= 0.0 && g.x() <= upper_.x() && g.y() <= upper_.y() &&
         g.z() <= upper_.z();
}

inline bool ScalarVolume::inBounds(const Eigen::Vector3d& p_W_m) const noexcept {
  return gridInBounds(gridCoordinates(p_W_m));
}

inline double ScalarVolume::sampleGrid(const Eigen::Vector3d& g) const noexcept {
  double raw = 0.0;
  switch (type_) {
    case VoxelType::kUInt8: raw = trilinear<std::uint8_t>(g); break;
    case VoxelType::kInt16: raw = trilinear<std::int16_t>(g); break;
    case VoxelType::kUInt16: raw = trilinear<std::uint16_t>(g); break;
    case VoxelType::kFloat32: raw = trilinear<float>(g); break;
  }
  return scale_ * raw + offset_;
}

inline double ScalarVolume::sample(const Eigen::Vector3d& p_W_m) const noexcept {
  return sampleGrid(gridCoordinates(p_W_m));
}

inline bool ScalarVolume::isInside(const Eigen::Vector3d& p_W_m, double isovalue) const noexcept {
  const Eigen::Vector3d g = gridCoordinates(p_W_m);
  return gridInBounds(g) && sampleGrid(g) > isovalue;
}

inline double ScalarVolume::upperBoundInBox(const Eigen::Vector3d& lo_ijk, const Eigen::Vector3d& hi_ijk,
                                            int* nodes_read, double arc_sagitta_m, double* without_arc) const noexcept {
  float raw_min = 0.0f, raw_max = 0.0f, lipschitz = 0.0f;
  if (!tree_.rawRange(lo_ijk, hi_ijk, raw_min, raw_max, nodes_read, arc_sagitta_m > 0.0 ? &lipschitz : nullptr)) {
    if (without_arc != nullptr) *without_arc = -std::numeric_limits<double>::infinity();
    return -std::numeric_limits<double>::infinity();
  }
  // trilinear() lerps in double: a + f (b - a) with f in [0, 1] stays within [a, b] when b - a
  // is exact, which it is for the integer types; for float32 corners of very different
  // magnitude it may not be, so widen by a few units in the last place. F = scale raw + offset
  // is monotone in raw under rounding.
  double raw = scale_ > 0.0 ? static_cast<double>(raw_max) : static_cast<double>(raw_min);
  if (type_ == VoxelType::kFloat32) raw += (scale_ > 0.0 ? 1.0 : -1.0) * std::abs(raw) * 0x1p-40;
  const double bound = scale_ * raw + offset_;
  if (without_arc != nullptr) *without_arc = bound;
  return bound + static_cast<double>(lipschitz) * arc_sagitta_m;
}

}  // namespace vh::haptics
