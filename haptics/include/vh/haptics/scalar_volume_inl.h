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

inline double ScalarVolume::rawBound(float raw_min, float raw_max) const noexcept {
  // trilinear() lerps in double: a + f (b - a) with f in [0, 1] stays within [a, b] when b - a
  // is exact, which it is for the integer types; for float32 corners of very different
  // magnitude it may not be, so widen by a few units in the last place. F = scale raw + offset
  // is monotone in raw under rounding.
  double raw = scale_ > 0.0 ? static_cast<double>(raw_max) : static_cast<double>(raw_min);
  if (type_ == VoxelType::kFloat32) raw += (scale_ > 0.0 ? 1.0 : -1.0) * std::abs(raw) * 0x1p-40;
  return scale_ * raw + offset_;
}

inline MinMaxTree::RawStop ScalarVolume::rawStopAbove(double value) const noexcept {
  // A raw value r whose bound rawBound(r, r) exceeds `value`; the bound is monotone in the raw
  // value (non-decreasing for scale > 0, non-increasing for scale < 0), so every node reaching r
  // bounds the box above `value` too. None (NaN) when no float is found within a few steps.
  MinMaxTree::RawStop stop;
  stop.above = scale_ > 0.0;
  if (!std::isfinite(value)) return stop;
  float r = static_cast<float>((value - offset_) / scale_);
  const float towards = stop.above ? std::numeric_limits<float>::infinity() : -std::numeric_limits<float>::infinity();
  for (int i = 0; i < 4 && std::isfinite(r); ++i, r = std::nextafter(r, towards))
    if (rawBound(r, r) > value) {
      stop.raw = r;
      break;
    }
  return stop;
}

inline double ScalarVolume::upperBoundInBox(const Eigen::Vector3d& lo_ijk, const Eigen::Vector3d& hi_ijk,
                                            int* nodes_read, double arc_sagitta_m, double* without_arc,
                                            double* arc_term, MinMaxTree::RawStop stop) const noexcept {
  float raw_min = 0.0f, raw_max = 0.0f, lipschitz = 0.0f;
  if (arc_term != nullptr) *arc_term = 0.0;
  if (!tree_.rawRange(lo_ijk, hi_ijk, raw_min, raw_max, nodes_read, arc_sagitta_m > 0.0 ? &lipschitz : nullptr,
                      stop)) {
    if (without_arc != nullptr) *without_arc = -std::numeric_limits<double>::infinity();
    return -std::numeric_limits<double>::infinity();
  }
  const double bound = rawBound(raw_min, raw_max);
  if (without_arc != nullptr) *without_arc = bound;
  const double arc = static_cast<double>(lipschitz) * arc_sagitta_m;
  if (arc_term != nullptr) *arc_term = arc;
  return bound + arc;
}

template <typename T>
double ScalarVolume::rawMaxInVoxels(const int* v0, const int* v1) const noexcept {
  const T* data = reinterpret_cast<const T*>(bytes_.data());
  const std::ptrdiff_t sy = geometry_.dims[0], sz = sy * geometry_.dims[1];
  const bool highest = scale_ > 0.0;  // F grows with raw: the largest raw gives the largest F
  T best = data[v0[0] + sy * v0[1] + sz * v0[2]];
  for (int k = v0[2]; k <= v1[2]; ++k)
    for (int j = v0[1]; j <= v1[1]; ++j) {
      const T* row = data + sy * j + sz * k;
      for (int i = v0[0]; i <= v1[0]; ++i) best = highest ? std::max(best, row[i]) : std::min(best, row[i]);
    }
  return static_cast<double>(best);
}

inline double ScalarVolume::voxelUpperBoundInBox(const Eigen::Vector3d& lo_ijk, const Eigen::Vector3d& hi_ijk,
                                                 int max_voxels, int* voxels_read) const noexcept {
  if (voxels_read != nullptr) *voxels_read = 0;
  if (!lo_ijk.allFinite() || !hi_ijk.allFinite()) return std::numeric_limits<double>::infinity();
  int v0[3], v1[3];
  long count = 1;
  for (int a = 0; a < 3; ++a) {
    const double upper = upper_[a];
    if (hi_ijk[a] < 0.0 || lo_ijk[a] > upper) return -std::numeric_limits<double>::infinity();
    const double lo = std::clamp(lo_ijk[a], 0.0, upper), hi = std::clamp(hi_ijk[a], 0.0, upper);
    // The cells trilinear() reads for x in [lo, hi]: min(floor(x), n - 2); their corners.
    v0[a] = std::min(static_cast<int>(lo), geometry_.dims[a] - 2);
    v1[a] = std::min(static_cast<int>(hi), geometry_.dims[a] - 2) + 1;
    count *= v1[a] - v0[a] + 1;
  }
  if (count > max_voxels) return std::numeric_limits<double>::infinity();
  if (voxels_read != nullptr) *voxels_read = static_cast<int>(count);
  double raw = 0.0;
  switch (type_) {
    case VoxelType::kUInt8: raw = rawMaxInVoxels<std::uint8_t>(v0, v1); break;
    case VoxelType::kInt16: raw = rawMaxInVoxels<std::int16_t>(v0, v1); break;
    case VoxelType::kUInt16: raw = rawMaxInVoxels<std::uint16_t>(v0, v1); break;
    case VoxelType::kFloat32:
      raw = rawMaxInVoxels<float>(v0, v1);
      raw += (scale_ > 0.0 ? 1.0 : -1.0) * std::abs(raw) * 0x1p-40;  // as upperBoundInBox()
      break;
  }
  return scale_ * raw + offset_;
}

}  // namespace vh::haptics
