#pragma once
/// @file
/// Regularising a stack of parallel image planes (the slices of a DICOM series as read) onto a
/// rectilinear grid: gantry tilt and other sheared stacks, missing slices and uneven spacing
/// (so every clinical scan opens). What 3D Slicer calls acquisition geometry regularisation.
/// Private to vh::io.
///
/// Frame: the stack's own plane frame, in millimetres: u along the image rows (the direction in
/// which the column index grows, DICOM's ImageOrientationPatient first vector), v along the
/// columns (row index grows, its second vector), d along the normal u x v (or its opposite, so
/// that d grows with the slice index). Slice k's first pixel (DICOM's ImagePositionPatient) sits
/// at (u_k, v_k, d_k) relative to slice 0's.

#include <array>
#include <atomic>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include <Eigen/Core>

namespace vh::io::detail {

/// Slices of equal size and pixel spacing in parallel planes, sorted by d (non-decreasing).
struct SliceStack {
  int columns = 0;                ///< Pixels per row (along u).
  int rows = 0;                   ///< Rows per slice (along v).
  double column_spacing_mm = 1;   ///< Distance between neighbouring columns, along u [mm].
  double row_spacing_mm = 1;      ///< Distance between neighbouring rows, along v [mm].
  /// Per slice k: (u_k, v_k, d_k) of its first pixel relative to slice 0's first pixel [mm].
  std::vector<Eigen::Vector3d> offset_mm;
};

/// A gap in a stack: between slices k and k + 1 the distance along d is well over the median.
struct SliceGap {
  int slice = 0;           ///< The slice before the gap (0-based, in d order).
  double d_before_mm = 0;  ///< d of slice `slice` [mm].
  double d_after_mm = 0;   ///< d of slice `slice` + 1 [mm].
  int missing = 0;         ///< About how many slices of the median spacing are missing.
};

/// What regularising a stack has to correct.
struct StackAnalysis {
  double median_spacing_mm = 0;  ///< Median distance between neighbouring slices along d.
  double min_spacing_mm = 0;     ///< Smallest of those distances.
  double max_spacing_mm = 0;     ///< Largest.
  /// Slices offset in their planes (a sheared stack: gantry tilt). The shear angle [deg]
  /// between the line through the slices' first pixels and the normal.
  bool sheared = false;
  double shear_deg = 0;
  /// Spacing along d uneven beyond the tolerance (missing slices, irregular acquisition).
  bool uneven = false;
  std::vector<SliceGap> gaps;  ///< Spacings over 1.5 times the median.
  bool regular() const { return !sheared && !uneven; }
};

/// Measures the stack. Tolerances: a shear below 0.01 pixel over the whole stack, and spacings
/// within 1 % (+ 1 micrometre) of the median, count as regular (the rounding of the positions
/// that scanners write). Needs at least 2 slices with distinct d.
StackAnalysis analyseStack(const SliceStack& stack);

/// The rectilinear grid a stack is resampled onto: axes u, v, d; in-plane spacings those of the
/// slices, slice spacing the median; in-plane extent the union of every slice's footprint (a
/// tilted stack's anatomy is kept, not cropped), d from slice 0 to the last slice.
struct RegularGrid {
  std::array<int, 3> dims{0, 0, 0};
  Eigen::Vector3d origin_mm = Eigen::Vector3d::Zero();   ///< (u, v, d) of voxel (0, 0, 0).
  Eigen::Vector3d spacing_mm = Eigen::Vector3d::Ones();  ///< Along u, v, d.
};

/// @throws std::invalid_argument when the stack has fewer than 2 slices, non-positive sizes or
///         spacings, or a grid of over 2^31 voxels would result.
RegularGrid regularGridFor(const SliceStack& stack, const StackAnalysis& analysis);

/// Resamples `in` (the stack's voxels: column fastest, then row, then slice, in the stack's
/// order) onto `grid`: bilinear in each slice plane, linear along d between the two slices
/// around each grid plane; a slice contributes `background` where the grid point falls outside
/// its footprint. Exact for fields linear in (u, v, d) inside the footprints. Integer types
/// round to nearest and clamp to their range.
/// @param progress when set, called with the fraction done (0..1), about 100 times.
/// @param cancel when set and true, stops early and returns false.
/// @return true when the whole grid was filled.
template <typename T>
bool resampleStack(const T* in, const SliceStack& stack, const RegularGrid& grid, T background, T* out,
                   const std::function<void(double)>& progress = {}, const std::atomic<bool>* cancel = nullptr);

}  // namespace vh::io::detail
