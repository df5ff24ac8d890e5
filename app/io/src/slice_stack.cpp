// Regularising a stack of parallel slices onto a rectilinear grid (see slice_stack.h).
#include "slice_stack.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <type_traits>

namespace vh::io::detail {

StackAnalysis analyseStack(const SliceStack& stack) {
  StackAnalysis a;
  const std::size_t n = stack.offset_mm.size();
  if (n < 2) return a;
  std::vector<double> spacing;
  spacing.reserve(n - 1);
  for (std::size_t k = 0; k + 1 < n; ++k) {
    const double g = stack.offset_mm[k + 1].z() - stack.offset_mm[k].z();
    if (g > 0.0) spacing.push_back(g);
  }
  if (spacing.empty()) return a;
  std::vector<double> sorted = spacing;
  std::nth_element(sorted.begin(), sorted.begin() + static_cast<std::ptrdiff_t>(sorted.size() / 2), sorted.end());
  a.median_spacing_mm = sorted[sorted.size() / 2];
  a.min_spacing_mm = *std::min_element(spacing.begin(), spacing.end());
  a.max_spacing_mm = *std::max_element(spacing.begin(), spacing.end());
  const double tolerance = 0.01 * a.median_spacing_mm + 1e-3;
  for (std::size_t k = 0; k + 1 < n; ++k) {
    const double d0 = stack.offset_mm[k].z(), d1 = stack.offset_mm[k + 1].z();
    const double g = d1 - d0;
    if (std::abs(g - a.median_spacing_mm) > tolerance) a.uneven = true;
    if (g > 1.5 * a.median_spacing_mm) {
      a.gaps.push_back({static_cast<int>(k), d0, d1,
                        std::max(1, static_cast<int>(std::lround(g / a.median_spacing_mm)) - 1)});
    }
  }
  double max_offset = 0.0;
  for (const auto& o : stack.offset_mm) max_offset = std::max(max_offset, o.head<2>().norm());
  const double pixel = std::min(stack.column_spacing_mm, stack.row_spacing_mm);
  a.sheared = max_offset > 0.01 * pixel + 1e-4;
  const Eigen::Vector3d& last = stack.offset_mm.back();
  a.shear_deg = std::atan2(last.head<2>().norm(), last.z()) * 180.0 / M_PI;
  return a;
}

RegularGrid regularGridFor(const SliceStack& stack, const StackAnalysis& analysis) {
  const std::size_t n = stack.offset_mm.size();
  if (n < 2 || stack.columns < 1 || stack.rows < 1 || !(stack.column_spacing_mm > 0.0) ||
      !(stack.row_spacing_mm > 0.0) || !(analysis.median_spacing_mm > 0.0)) {
    throw std::invalid_argument("a slice stack needs 2 or more slices of positive size and spacing");
  }
  Eigen::Vector2d lo = stack.offset_mm.front().head<2>(), hi = lo;
  for (const auto& o : stack.offset_mm) {
    lo = lo.cwiseMin(o.head<2>());
    hi = hi.cwiseMax(o.head<2>());
  }
  const Eigen::Vector2d pixel(stack.column_spacing_mm, stack.row_spacing_mm);
  const Eigen::Vector2d slice_extent(pixel.x() * (stack.columns - 1), pixel.y() * (stack.rows - 1));
  RegularGrid grid;
  for (int axis = 0; axis < 2; ++axis) {
    const double cells = (hi[axis] + slice_extent[axis] - lo[axis]) / pixel[axis];
    grid.dims[axis] = static_cast<int>(std::ceil(cells - 1e-6)) + 1;
  }
  const double depth = stack.offset_mm.back().z() - stack.offset_mm.front().z();
  grid.dims[2] = static_cast<int>(std::lround(depth / analysis.median_spacing_mm)) + 1;
  const double voxels = static_cast<double>(grid.dims[0]) * grid.dims[1] * grid.dims[2];
  if (grid.dims[2] < 2 || voxels > 2147483647.0) {
    throw std::invalid_argument("the regular grid of the slice stack would be empty or too large");
  }
  grid.origin_mm = Eigen::Vector3d(lo.x(), lo.y(), stack.offset_mm.front().z());
  // The grid spans exactly the first to the last slice: the median spacing, evened out.
  grid.spacing_mm = Eigen::Vector3d(pixel.x(), pixel.y(), depth / (grid.dims[2] - 1));
  return grid;
}

namespace {

template <typename T>
T roundTo(double v) {
  if constexpr (std::is_integral_v<T>) {
    const double lo = static_cast<double>(std::numeric_limits<T>::lowest());
    const double hi = static_cast<double>(std::numeric_limits<T>::max());
    return static_cast<T>(std::clamp(std::nearbyint(v), lo, hi));
  } else {
    return static_cast<T>(v);
  }
}

/// Adds weight * slice(x, y) for every grid pixel of a plane, where grid pixel (i, j) lies at
/// slice pixel (i + fx, j + fy); `background` outside the slice's footprint.
template <typename T>
void addSlice(const T* slice, int columns, int rows, double fx, double fy, double weight, double background,
              int nx, int ny, double* plane) {
  constexpr double kEps = 1e-6;
  for (int j = 0; j < ny; ++j) {
    double* row_out = plane + static_cast<std::size_t>(j) * nx;
    const double y = j + fy;
    if (y < -kEps || y > rows - 1 + kEps) {
      for (int i = 0; i < nx; ++i) row_out[i] += weight * background;
      continue;
    }
    const int y0 = std::clamp(static_cast<int>(std::floor(y)), 0, std::max(0, rows - 2));
    const double ay = rows > 1 ? std::clamp(y - y0, 0.0, 1.0) : 0.0;
    const T* r0 = slice + static_cast<std::size_t>(y0) * columns;
    const T* r1 = rows > 1 ? r0 + columns : r0;
    for (int i = 0; i < nx; ++i) {
      const double x = i + fx;
      if (x < -kEps || x > columns - 1 + kEps) {
        row_out[i] += weight * background;
        continue;
      }
      const int x0 = std::clamp(static_cast<int>(std::floor(x)), 0, std::max(0, columns - 2));
      const int x1 = columns > 1 ? x0 + 1 : x0;
      const double ax = columns > 1 ? std::clamp(x - x0, 0.0, 1.0) : 0.0;
      const double top = r0[x0] + ax * (static_cast<double>(r0[x1]) - r0[x0]);
      const double bottom = r1[x0] + ax * (static_cast<double>(r1[x1]) - r1[x0]);
      row_out[i] += weight * (top + ay * (bottom - top));
    }
  }
}

}  // namespace

template <typename T>
bool resampleStack(const T* in, const SliceStack& stack, const RegularGrid& grid, T background, T* out,
                   const std::function<void(double)>& progress, const std::atomic<bool>* cancel) {
  const int nx = grid.dims[0], ny = grid.dims[1], nz = grid.dims[2];
  const std::size_t n = stack.offset_mm.size();
  const std::size_t slice_voxels = static_cast<std::size_t>(stack.columns) * stack.rows;
  const std::size_t plane_voxels = static_cast<std::size_t>(nx) * ny;
  std::vector<double> plane(plane_voxels);
  const int report_every = std::max(1, nz / 100);
  std::size_t k = 0;
  for (int z = 0; z < nz; ++z) {
    if (cancel != nullptr && cancel->load(std::memory_order_relaxed)) return false;
    const double d = grid.origin_mm.z() + z * grid.spacing_mm.z();
    // Slices k and k + 1 around d (d_k <= d < d_k+1; the last pair at the far end).
    while (k + 2 < n && stack.offset_mm[k + 1].z() <= d) ++k;
    const double d0 = stack.offset_mm[k].z(), d1 = stack.offset_mm[k + 1].z();
    const double t = d1 > d0 ? std::clamp((d - d0) / (d1 - d0), 0.0, 1.0) : 0.0;
    std::fill(plane.begin(), plane.end(), 0.0);
    for (const std::size_t s : {k, k + 1}) {
      const double weight = s == k ? 1.0 - t : t;
      if (weight == 0.0) continue;
      const double fx = (grid.origin_mm.x() - stack.offset_mm[s].x()) / stack.column_spacing_mm;
      const double fy = (grid.origin_mm.y() - stack.offset_mm[s].y()) / stack.row_spacing_mm;
      addSlice(in + s * slice_voxels, stack.columns, stack.rows, fx, fy, weight, static_cast<double>(background),
               nx, ny, plane.data());
    }
    T* dst = out + static_cast<std::size_t>(z) * plane_voxels;
    for (std::size_t p = 0; p < plane_voxels; ++p) dst[p] = roundTo<T>(plane[p]);
    if (progress && (z + 1) % report_every == 0) progress(static_cast<double>(z + 1) / nz);
  }
  if (progress) progress(1.0);
  return true;
}

template bool resampleStack<std::uint8_t>(const std::uint8_t*, const SliceStack&, const RegularGrid&, std::uint8_t,
                                          std::uint8_t*, const std::function<void(double)>&, const std::atomic<bool>*);
template bool resampleStack<std::int8_t>(const std::int8_t*, const SliceStack&, const RegularGrid&, std::int8_t,
                                         std::int8_t*, const std::function<void(double)>&, const std::atomic<bool>*);
template bool resampleStack<std::int16_t>(const std::int16_t*, const SliceStack&, const RegularGrid&, std::int16_t,
                                          std::int16_t*, const std::function<void(double)>&, const std::atomic<bool>*);
template bool resampleStack<std::uint16_t>(const std::uint16_t*, const SliceStack&, const RegularGrid&,
                                           std::uint16_t, std::uint16_t*, const std::function<void(double)>&,
                                           const std::atomic<bool>*);
template bool resampleStack<std::int32_t>(const std::int32_t*, const SliceStack&, const RegularGrid&, std::int32_t,
                                          std::int32_t*, const std::function<void(double)>&, const std::atomic<bool>*);
template bool resampleStack<std::uint32_t>(const std::uint32_t*, const SliceStack&, const RegularGrid&,
                                           std::uint32_t, std::uint32_t*, const std::function<void(double)>&,
                                           const std::atomic<bool>*);
template bool resampleStack<float>(const float*, const SliceStack&, const RegularGrid&, float, float*,
                                   const std::function<void(double)>&, const std::atomic<bool>*);
template bool resampleStack<double>(const double*, const SliceStack&, const RegularGrid&, double, double*,
                                    const std::function<void(double)>&, const std::atomic<bool>*);

}  // namespace vh::io::detail
