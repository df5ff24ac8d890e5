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
  /// Per slice k: its thickness along d [mm] (DICOM's SliceThickness); empty when unknown for
  /// any slice.
  std::vector<double> thickness_mm;
};

/// A gap in a stack: slices are missing between slices k and k + 1 (see analyseStack()).
struct SliceGap {
  int slice = 0;           ///< The slice before the gap (0-based, in d order).
  double d_before_mm = 0;  ///< d of slice `slice` [mm].
  double d_after_mm = 0;   ///< d of slice `slice` + 1 [mm].
  int missing = 0;         ///< About how many slices of the spacing around the gap are missing.
};

/// A part of a stack acquired at one spacing (a two-part head CT: 4 mm slices, then 7 mm).
struct SlicePart {
  int first = 0;             ///< Its first slice (0-based, in d order).
  int last = 0;              ///< Its last slice.
  double spacing_mm = 0;     ///< The mean of its equal steps along d.
  double thickness_mm = 0;   ///< The median thickness of its slices; 0 when unknown.
  int slices() const { return last - first + 1; }
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
  /// Spacing along d uneven beyond the tolerance (missing slices, parts of different spacing,
  /// irregular acquisition).
  bool uneven = false;
  std::vector<SliceGap> gaps;  ///< Where slices are missing.
  /// Parts of different spacing, in d order; empty when the stack has one spacing (at most
  /// jittered or gapped).
  std::vector<SlicePart> parts;
  /// Steps along d that neither the parts, their transitions nor the gaps explain.
  bool irregular_steps = false;
  /// The slice spacing to resample to: the finest part's spacing, else the median.
  double grid_spacing_mm = 0;
  bool regular() const { return !sheared && !uneven; }
};

/// Measures the stack. Tolerances: a shear below 0.01 pixel over the whole stack, and spacings
/// within 1 % (+ 1 micrometre) of the median (or of each other within a part), count as regular
/// (the rounding of the positions that scanners write). Parts: runs of at least 2 equal steps,
/// neighbouring runs of one spacing merged. A gap is a step over 1.5 times the spacing around
/// it (the median, or the finer neighbouring part's); where every slice's thickness is known it
/// must also exceed what the two slices cover, half of each thickness (+ the tolerance), so a
/// change of slice thickness is not a gap. Needs at least 2 slices with distinct d.
StackAnalysis analyseStack(const SliceStack& stack);

/// The rectilinear grid a stack is resampled onto: axes u, v, d; in-plane spacings those of the
/// slices, slice spacing analysis.grid_spacing_mm (the median when that is 0), evened out so
/// that the grid spans d from slice 0 to the last slice exactly; in-plane extent the union of
/// every slice's footprint (a tilted stack's anatomy is kept, not cropped), less the offsets
/// analyseStack() counts as rounding (a stack of 384 x 512 slices stays 384 x 512).
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
/// its footprint (grown by the rounding tolerance of analyseStack(), where it gives its edge's
/// value). Exact for fields linear in (u, v, d) inside the footprints. Integer types
/// round to nearest and clamp to their range.
/// @param progress when set, called with the fraction done (0..1), about 100 times.
/// @param cancel when set and true, stops early and returns false.
/// @return true when the whole grid was filled.
template <typename T>
bool resampleStack(const T* in, const SliceStack& stack, const RegularGrid& grid, T background, T* out,
                   const std::function<void(double)>& progress = {}, const std::atomic<bool>* cancel = nullptr);

}  // namespace vh::io::detail
