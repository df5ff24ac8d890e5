// Regularising a stack of parallel slices onto a rectilinear grid (see slice_stack.h).
#include "slice_stack.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <type_traits>

namespace vh::io::detail {

namespace {

/// The tolerance within which two spacings near `spacing_mm` count as equal: 1 % + 1 micrometre
/// (the rounding of the positions that scanners write).
double toleranceFor(double spacing_mm) { return 0.01 * spacing_mm + 1e-3; }

/// How far [mm] slices may lie off one another within their planes and still count as one
/// unsheared stack: 0.01 pixel + 0.1 micrometre, the rounding of the positions and orientation
/// cosines that scanners write (cosines to 6 decimals move a slice 100 mm from the isocentre by
/// 0.1 micrometre). The grid keeps the slices' size for such offsets, and sampling clamps to a
/// slice's edge within it, instead of adding a row and a column of background.
double inPlaneToleranceMm(const SliceStack& stack) {
  return 0.01 * std::min(stack.column_spacing_mm, stack.row_spacing_mm) + 1e-4;
}

double medianOf(std::vector<double> v) {
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
  return v[v.size() / 2];
}

/// A run of equal steps: steps first .. last (step k joins slices k and k + 1).
struct Run {
  std::size_t first = 0, last = 0;
  double sum_mm = 0;  ///< Of its steps.
  int steps = 0;
};

/// The parts of a stack with steps `step`: runs of at least 2 equal steps, neighbouring runs of
/// one spacing merged (what lies between them is a gap or jitter within the part); empty unless
/// at least 2 parts of different spacing remain. Then `run_spacing` holds, per step, the spacing
/// of the run it belongs to (0 for a step in no run).
std::vector<SlicePart> partsOf(const std::vector<double>& step, const std::vector<double>& thickness,
                               std::vector<double>& run_spacing) {
  run_spacing.assign(step.size(), 0.0);
  std::vector<Run> runs;
  for (std::size_t k = 0; k < step.size(); ++k) {
    Run* run = runs.empty() ? nullptr : &runs.back();
    const double reference = run != nullptr ? run->sum_mm / run->steps : 0.0;
    if (run != nullptr && run->last + 1 == k && std::abs(step[k] - reference) <= toleranceFor(reference)) {
      run->last = k;
      run->sum_mm += step[k];
      ++run->steps;
    } else {
      if (run != nullptr && run->steps < 2) runs.pop_back();  // a lone step is no part
      runs.push_back({k, k, step[k], 1});
    }
  }
  if (!runs.empty() && runs.back().steps < 2) runs.pop_back();
  std::vector<Run> merged;
  for (const Run& r : runs) {
    if (!merged.empty()) {
      Run& m = merged.back();
      const double s = m.sum_mm / m.steps;
      if (std::abs(r.sum_mm / r.steps - s) <= toleranceFor(s)) {
        m.last = r.last;
        m.sum_mm += r.sum_mm;
        m.steps += r.steps;
        continue;
      }
    }
    merged.push_back(r);
  }
  if (merged.size() < 2) return {};
  std::vector<SlicePart> parts;
  for (const Run& r : runs) {
    for (std::size_t k = r.first; k <= r.last; ++k) run_spacing[k] = r.sum_mm / r.steps;
  }
  for (const Run& r : merged) {
    SlicePart p;
    // A slice shared by two runs that meet without a transition step belongs to the first.
    p.first = static_cast<int>(r.first);
    if (!parts.empty()) p.first = std::max(p.first, parts.back().last + 1);
    p.last = static_cast<int>(r.last) + 1;
    p.spacing_mm = r.sum_mm / r.steps;
    if (!thickness.empty()) {
      p.thickness_mm = medianOf(std::vector<double>(thickness.begin() + p.first, thickness.begin() + p.last + 1));
    }
    parts.push_back(p);
  }
  return parts;
}

/// The spacing around step k (between slices k and k + 1): the median without parts; else that
/// of the run it belongs to, or else the finer of the parts before and after it.
double spacingAround(std::size_t k, const std::vector<SlicePart>& parts, const std::vector<double>& run_spacing,
                     double median_mm) {
  if (parts.empty()) return median_mm;
  if (run_spacing[k] > 0.0) return run_spacing[k];
  double before = 0.0, after = 0.0;
  for (const SlicePart& p : parts) {
    if (p.first <= static_cast<int>(k)) before = p.spacing_mm;
    if (after == 0.0 && p.last >= static_cast<int>(k) + 1) after = p.spacing_mm;
  }
  if (before == 0.0 || after == 0.0) return std::max(before, after);
  return std::min(before, after);
}

/// Whether step k of `g_mm` lies between the spacings of the parts around it (within the
/// tolerance): a step inside a part, or the transition from one part to the next.
bool explainedByParts(std::size_t k, double g_mm, const std::vector<SlicePart>& parts) {
  const SlicePart* before = nullptr;
  const SlicePart* after = nullptr;
  for (const SlicePart& p : parts) {
    if (p.first <= static_cast<int>(k)) before = &p;
    if (after == nullptr && p.last >= static_cast<int>(k) + 1) after = &p;
  }
  if (before == nullptr || after == nullptr) return false;
  const double lo = std::min(before->spacing_mm, after->spacing_mm);
  const double hi = std::max(before->spacing_mm, after->spacing_mm);
  return g_mm >= lo - toleranceFor(lo) && g_mm <= hi + toleranceFor(hi);
}

}  // namespace

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
  a.median_spacing_mm = medianOf(spacing);
  a.min_spacing_mm = *std::min_element(spacing.begin(), spacing.end());
  a.max_spacing_mm = *std::max_element(spacing.begin(), spacing.end());
  const bool thickness_known = stack.thickness_mm.size() == n;
  std::vector<double> step(n - 1);
  for (std::size_t k = 0; k + 1 < n; ++k) step[k] = stack.offset_mm[k + 1].z() - stack.offset_mm[k].z();
  std::vector<double> run_spacing;
  a.parts = partsOf(step, thickness_known ? stack.thickness_mm : std::vector<double>{}, run_spacing);
  a.grid_spacing_mm = a.median_spacing_mm;
  for (const SlicePart& p : a.parts) a.grid_spacing_mm = std::min(a.grid_spacing_mm, p.spacing_mm);
  const double tolerance = toleranceFor(a.median_spacing_mm);
  for (std::size_t k = 0; k + 1 < n; ++k) {
    const double d0 = stack.offset_mm[k].z(), d1 = stack.offset_mm[k + 1].z();
    const double g = d1 - d0;
    if (std::abs(g - a.median_spacing_mm) > tolerance) a.uneven = true;
    const double around = spacingAround(k, a.parts, run_spacing, a.median_spacing_mm);
    bool gap = g > 1.5 * around;
    if (thickness_known) {
      // What the two slices cover: half of each one's thickness. A step within it is a change
      // of slice thickness (or of spacing), not missing slices.
      const double cover = 0.5 * (stack.thickness_mm[k] + stack.thickness_mm[k + 1]);
      gap = gap && g > cover + toleranceFor(cover);
    }
    if (gap) {
      a.gaps.push_back({static_cast<int>(k), d0, d1, std::max(1, static_cast<int>(std::lround(g / around)) - 1)});
    } else if (!a.parts.empty() && run_spacing[k] == 0.0 && !explainedByParts(k, g, a.parts)) {
      a.irregular_steps = true;
    }
  }
  double max_offset = 0.0;
  for (const auto& o : stack.offset_mm) max_offset = std::max(max_offset, o.head<2>().norm());
  a.sheared = max_offset > inPlaneToleranceMm(stack);
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
    grid.dims[axis] = static_cast<int>(std::ceil(cells - inPlaneToleranceMm(stack) / pixel[axis])) + 1;
  }
  const double depth = stack.offset_mm.back().z() - stack.offset_mm.front().z();
  const double spacing = analysis.grid_spacing_mm > 0.0 ? analysis.grid_spacing_mm : analysis.median_spacing_mm;
  grid.dims[2] = static_cast<int>(std::lround(depth / spacing)) + 1;
  const double voxels = static_cast<double>(grid.dims[0]) * grid.dims[1] * grid.dims[2];
  if (grid.dims[2] < 2 || voxels > 2147483647.0) {
    throw std::invalid_argument("the regular grid of the slice stack would be empty or too large");
  }
  grid.origin_mm = Eigen::Vector3d(lo.x(), lo.y(), stack.offset_mm.front().z());
  // The grid spans exactly the first to the last slice: the chosen spacing, evened out.
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
/// slice pixel (i + fx, j + fy); `background` outside the slice's footprint grown by (ex, ey)
/// pixels (within it: the edge's value).
template <typename T>
void addSlice(const T* slice, int columns, int rows, double fx, double fy, double ex, double ey, double weight,
              double background, int nx, int ny, double* plane) {
  for (int j = 0; j < ny; ++j) {
    double* row_out = plane + static_cast<std::size_t>(j) * nx;
    const double y = j + fy;
    if (y < -ey || y > rows - 1 + ey) {
      for (int i = 0; i < nx; ++i) row_out[i] += weight * background;
      continue;
    }
    const int y0 = std::clamp(static_cast<int>(std::floor(y)), 0, std::max(0, rows - 2));
    const double ay = rows > 1 ? std::clamp(y - y0, 0.0, 1.0) : 0.0;
    const T* r0 = slice + static_cast<std::size_t>(y0) * columns;
    const T* r1 = rows > 1 ? r0 + columns : r0;
    for (int i = 0; i < nx; ++i) {
      const double x = i + fx;
      if (x < -ex || x > columns - 1 + ex) {
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
  const double edge_mm = inPlaneToleranceMm(stack);
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
      addSlice(in + s * slice_voxels, stack.columns, stack.rows, fx, fy, edge_mm / stack.column_spacing_mm,
               edge_mm / stack.row_spacing_mm, weight, static_cast<double>(background), nx, ny, plane.data());
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
