#pragma once
/// @file
/// A sampled scalar volume queried as a continuous field F(x) (paper section 2.2).
///
/// Frames: W is the volume's physical (world) frame, in metres. Voxel (i, j, k) has its centre at
///   p_W = origin_W_m + direction_W * diag(spacing_m) * (i, j, k)^T.
/// Values: F = value_scale * raw + value_offset, in the data's units (HU for CT). The raw
/// voxels are kept unmodified in their stored type.

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "vh/haptics/min_max_tree.h"

namespace vh::haptics {

/// Stored voxel type.
enum class VoxelType : std::uint8_t { kUInt8, kInt16, kUInt16, kFloat32 };

/// Name of a voxel type ("uint8", "int16", "uint16", "float32").
const char* voxelTypeName(VoxelType type) noexcept;
/// Size of one voxel [bytes].
std::size_t voxelTypeSize(VoxelType type) noexcept;

/// Geometry of a regular grid in the world frame W.
struct VolumeGeometry {
  std::array<int, 3> dims{0, 0, 0};                          ///< Voxels along i, j, k (nx, ny, nz).
  Eigen::Vector3d spacing_m{1e-3, 1e-3, 1e-3};               ///< Voxel size along i, j, k [m].
  Eigen::Vector3d origin_W_m = Eigen::Vector3d::Zero();      ///< Centre of voxel (0,0,0) in W [m].
  Eigen::Matrix3d direction_W = Eigen::Matrix3d::Identity(); ///< Columns: unit i, j, k axes in W.

  /// Number of voxels nx * ny * nz.
  std::size_t voxelCount() const noexcept {
    return static_cast<std::size_t>(dims[0]) * static_cast<std::size_t>(dims[1]) *
           static_cast<std::size_t>(dims[2]);
  }
  /// Smallest voxel side [m].
  double minSpacing() const noexcept { return spacing_m.minCoeff(); }
  /// Whether `other` is the same grid: dims, spacing, origin and direction exactly equal (so
  /// linear indices mean the same voxels in both).
  bool sameGridAs(const VolumeGeometry& other) const noexcept {
    return dims == other.dims && origin_W_m == other.origin_W_m && spacing_m == other.spacing_m &&
           direction_W == other.direction_W;
  }
  /// Linear index (x fastest) of voxel (i, j, k); the voxel must lie within dims.
  std::uint64_t indexOf(long i, long j, long k) const noexcept {
    return static_cast<std::uint64_t>(i) +
           static_cast<std::uint64_t>(dims[0]) *
               (static_cast<std::uint64_t>(j) + static_cast<std::uint64_t>(dims[1]) * static_cast<std::uint64_t>(k));
  }
  /// Voxel (i, j, k) of the linear index `index` (x fastest); index < voxelCount().
  std::array<int, 3> voxelOf(std::uint64_t index) const noexcept {
    const auto nx = static_cast<std::uint64_t>(dims[0]), ny = static_cast<std::uint64_t>(dims[1]);
    return {static_cast<int>(index % nx), static_cast<int>((index / nx) % ny), static_cast<int>(index / (nx * ny))};
  }
  /// The point at voxel coordinates `ijk` (voxel centres at integers; fractions between them) in
  /// W [m]: origin + D diag(spacing) ijk.
  Eigen::Vector3d pointOf_W(const Eigen::Vector3d& ijk) const noexcept {
    return origin_W_m + direction_W * spacing_m.cwiseProduct(ijk);
  }
  /// The 4 x 4 affine taking voxel coordinates (i, j, k, 1) to W [m], pointOf_W() as a matrix:
  /// [D diag(spacing), origin; 0 0 0 1] (NIfTI's and nibabel's affine, in W and metres).
  Eigen::Matrix4d indexToWorld() const noexcept {
    Eigen::Matrix4d a = Eigen::Matrix4d::Identity();
    a.topLeftCorner<3, 3>() = direction_W * spacing_m.asDiagonal();
    a.topRightCorner<3, 1>() = origin_W_m;
    return a;
  }
};

/// Result of ScalarVolume::firstEntryOnSegment(): where a straight segment first enters
/// {F > threshold}, bracketed in the segment's parameter u in [0, 1].
struct SegmentEntry {
  bool hit = false;        ///< The segment enters (or, starting inside, goes deeper).
  double u_outside = 1.0;  ///< Outside end of the bracket: F <= threshold on [0, u_outside].
  double u_inside = 1.0;   ///< Inside end of the bracket (u_inside - u_outside < u_tolerance).
  int cells = 0;           ///< Cells whose cubic was examined (cells skipped by their corners not counted).
  int cells_walked = 0;    ///< Every cell visited, skipped or examined (the walk's cost).
  /// Upper bound of F - threshold [data units] over the walked part of the segment (up to where
  /// the walk stopped): the largest corner of each skipped cell, the cubic's largest value at
  /// its ends and critical points in each examined one. With hit false and the whole segment in
  /// the grid's box, F < threshold + excess_max on the whole segment; a clearance certificate
  /// (CollisionDetector's edge test reuses it while the tool moves less than it proves).
  /// -infinity when no cell was walked.
  double excess_max = -std::numeric_limits<double>::infinity();
};

/// Immutable sampled volume: trilinear F(x) and central-difference gradient (eq. 1).
///
/// Inside/outside (section 2.2): a point is inside the isosurface F = s where F(x) > s.
/// Outside the grid's bounding box (voxel centres 0..n-1 on each axis) counts as empty: such
/// points are never inside, whatever the isovalue.
/// Thread safety: all const members may be called concurrently (no mutable state).
class ScalarVolume {
 public:
  ScalarVolume() = default;

  /// Builds a volume that owns a copy of `voxels` (x fastest, then y, then z).
  /// @param geometry dims > 1 on every axis, spacing > 0, direction orthonormal.
  /// @param value_scale, value_offset F = value_scale * raw + value_offset (value_scale != 0).
  /// @throws std::invalid_argument on bad geometry, a size mismatch or a non-finite scale.
  template <typename T>
  static ScalarVolume FromVoxels(const VolumeGeometry& geometry, const std::vector<T>& voxels,
                                 double value_scale = 1.0, double value_offset = 0.0);

  /// Builds a volume from raw bytes of `type` (native endianness), x fastest.
  /// @throws std::invalid_argument as FromVoxels.
  static ScalarVolume FromBytes(const VolumeGeometry& geometry, VoxelType type,
                                std::vector<std::byte> bytes, double value_scale = 1.0,
                                double value_offset = 0.0);

  const VolumeGeometry& geometry() const noexcept { return geometry_; }
  VoxelType voxelType() const noexcept { return type_; }
  double valueScale() const noexcept { return scale_; }
  double valueOffset() const noexcept { return offset_; }
  bool empty() const noexcept { return bytes_.empty(); }
  /// Raw voxel storage (voxelCount() * voxelTypeSize() bytes).
  const std::vector<std::byte>& bytes() const noexcept { return bytes_; }

  /// Smallest and largest F over the voxels, in data units.
  double minValue() const noexcept { return min_value_; }
  double maxValue() const noexcept { return max_value_; }

  /// Feature size f = half the smallest voxel side [m] (section 2.3).
  double featureSize_m() const noexcept { return 0.5 * geometry_.minSpacing(); }

  /// Value of voxel (i, j, k) in data units; indices are clamped to the grid.
  double voxel(int i, int j, int k) const noexcept;

  /// Continuous grid coordinates (i, j, k) of a point p_W [m].
  Eigen::Vector3d gridCoordinates(const Eigen::Vector3d& p_W_m) const noexcept;
  /// True when p_W lies inside the grid's bounding box of voxel centres.
  bool inBounds(const Eigen::Vector3d& p_W_m) const noexcept;

  /// Trilinear F(p_W) in data units (section 2.2). Coordinates outside the grid are clamped to
  /// its border for interpolation; use isInside() for the inside test.
  double sample(const Eigen::Vector3d& p_W_m) const noexcept;
  /// sample() at continuous grid coordinates ijk (gridCoordinates()), without the map from W:
  /// for callers that already work in the grid's frame. Clamped to the border like sample().
  double sampleGrid(const Eigen::Vector3d& ijk) const noexcept;

  /// Central-difference gradient of F at p_W (eq. 1), in data units per metre, expressed in W.
  /// Differences are taken along the grid axes with delta = the voxel spacing on each axis and
  /// divided by 2 delta, then rotated into W (eq. 1 up to that scale, which keeps the direction).
  Eigen::Vector3d gradient(const Eigen::Vector3d& p_W_m) const noexcept;

  /// Gradient of the trilinear interpolant itself at p_W (central difference over 1e-3 voxel),
  /// in data units per metre, in W: consistent with isInside() where eq. 1's smoothing is not
  /// (sharp edges of CT data). Used for the normal of a contact that blocks its own tangent step.
  Eigen::Vector3d interpolantGradient(const Eigen::Vector3d& p_W_m) const noexcept;

  /// Inside test for the isosurface F = isovalue: inBounds(p) && F(p) > isovalue.
  bool isInside(const Eigen::Vector3d& p_W_m, double isovalue) const noexcept;


  /// Exact first entry of the straight segment g(u) = a + u (b - a), u in [0, 1], given in grid
  /// coordinates (i, j, k), into {F > threshold}. Along a straight line inside one
  /// cell the trilinear field is a cubic in u: the cells the segment crosses are walked in order
  /// (3-D DDA), a cell whose largest corner is <= threshold is skipped (the trilinear field is a
  /// convex combination of its corners), and in the others the cubic is split at its critical
  /// points into monotone pieces whose ends decide, exactly up to rounding, whether and where it
  /// rises above the threshold; the crossing is then bisected on the cubic to u_tolerance. Parts
  /// of the segment outside the grid's box of voxel centres are never inside (as isInside()).
  /// Hence a feature of any non-zero thickness above the threshold is found, however thin.
  /// A segment that starts inside (F(a) > threshold; rounding, or a point the surface moved
  /// onto) is not stopped while F decreases along it (it is leaving); it is stopped where F
  /// starts to increase while still inside (going deeper), and at any later entry.
  /// Cells that start after u_limit are not examined (the caller knows an earlier hit).
  /// With arc_sagitta_m delta > 0 [m] the threshold is lowered along the segment, in each cell,
  /// to threshold - 4 h u (1 - u), h = delta times the cell's local Lipschitz bound
  /// (localLipschitzBound(); h at the middle, none at the ends; the test stays a cubic): for a
  /// rotating point whose arc leaves its chord by at most 4 delta u (1 - u), this makes "no
  /// entry" a statement about the arc itself. delta must be below one voxel (the local bound
  /// holds within a cell of the cell it is read for); the detector's is below 1/128 voxel.
  /// With reach_ijk > 0 (per grid axis, in voxels), points of the grid's box within that reach
  /// of the segment count too: the segment's projection onto the box is walked where the
  /// segment is within reach of the box (for the arcs of rotating points, which may leave their
  /// chord by the sagitta; the threshold is then lowered by the caller, see lipschitzBound()).
  /// A non-finite end, or a segment crossing more than 2^20 cells (some 350,000 voxels long),
  /// is answered conservatively: a hit at u = 0, or where the walk stopped.
  /// @param u_tolerance bracket width at which the bisection stops, > 0.
  SegmentEntry firstEntryOnSegment(const Eigen::Vector3d& a_ijk, const Eigen::Vector3d& b_ijk, double threshold,
                                   double u_limit, double u_tolerance,
                                   const Eigen::Vector3d& reach_ijk = Eigen::Vector3d::Zero(),
                                   double arc_sagitta_m = 0.0) const noexcept;

  /// Lipschitz bound of F over the whole grid [data units per metre]: |F(p) - F(q)| <=
  /// lipschitzBound() |p - q| for p, q in W (trilinear partial derivatives are bounded by the
  /// largest difference of neighbouring voxels along their axis, divided by the spacing).
  /// Diagnostics only: the segment test and the culling use the local bounds below, so that
  /// one outlier voxel (a 1e30, a -3e38 "no data" border) weighs only near itself.
  double lipschitzBound() const noexcept { return lipschitz_; }
  /// Local Lipschitz bound [data units per metre] at the cell holding grid coordinates ijk: valid
  /// for every point of that cell and of the cells next to it (per brick of the min-max tree,
  /// taken over the brick and its 26 neighbours). Used to cover the deviation of a rotating
  /// point's arc from its chord (haptics/README.md, "Never through").
  double localLipschitzBound(const Eigen::Vector3d& ijk) const noexcept {
    const auto cell = [&](int a) {
      return static_cast<int>(std::clamp(std::floor(ijk[a]), 0.0, static_cast<double>(geometry_.dims[a] - 2)));
    };
    return ijk.allFinite() ? tree_.brickLipschitz(cell(0), cell(1), cell(2)) : lipschitz_;
  }

  /// Cells per side of the bricks gridStepRange() keeps its ranges for: 24 bytes per 512
  /// voxels (ranges per 4-cell brick of the min-max tree, 8x the memory, made the edge test no
  /// cheaper on the paper's scenes).
  static constexpr int kStepBrickCells = 8;
  /// The range of F's partial derivatives along each grid axis over the cells that meet the box
  /// [lo_ijk, hi_ijk] (grid coordinates), in data units per grid step: for every point of those
  /// cells, step_lo[a] <= dF/di_a <= step_hi[a] (inside a cell dF/di_a is a bilinear blend of
  /// the differences of its four edges along a, so their smallest and largest bound it). With
  /// them, F(x + d) - F(x) <= sum_a max(step_lo[a] d_a, step_hi[a] d_a) whenever the straight
  /// path from x to x + d stays in the box: a bound that knows the direction of a move, where a
  /// Lipschitz bound knows only its length (the edge test's directional certificates and the
  /// sweep's runs proven free along their direction, haptics/README.md, "Between the points"
  /// and "Speed").
  /// The ranges are kept per step brick, so they hold beyond the box: where `valid_lo_ijk` and
  /// `valid_hi_ijk` are given, they receive the largest box (grid coordinates, containing
  /// [lo_ijk, hi_ijk]) that reads the same bricks, over whose cells the same bounds hold. A
  /// move may go that far before the ranges are read again (the edge test's certificates).
  /// @return false, with nothing written, when the box is not inside the grid's box of voxel
  ///         centres or is not finite. Reads the ranges kept per step brick (the bricks that
  ///         book the cells' edges: usually 1 to 8), no voxel; no allocation.
  bool gridStepRange(const Eigen::Vector3d& lo_ijk, const Eigen::Vector3d& hi_ijk, Eigen::Vector3d& step_lo,
                     Eigen::Vector3d& step_hi, Eigen::Vector3d* valid_lo_ijk = nullptr,
                     Eigen::Vector3d* valid_hi_ijk = nullptr) const noexcept;

  /// Min/max bricks over the raw voxels (built once with the volume; independent of any
  /// isovalue). See haptics/README.md, "Speed".
  const MinMaxTree& minMaxTree() const noexcept { return tree_; }

  /// Upper bound of F over every point with grid coordinates in the closed box [lo_ijk, hi_ijk]
  /// that isInside() could report inside: -infinity when the box misses the grid's box (out of
  /// bounds is never inside). Conservative under rounding: sampleGrid(g) <= the bound for every
  /// in-bounds g in the box, so "bound <= isovalue" proves that no point of the box is inside.
  /// With arc_sagitta_m delta > 0 [m], the bound also covers every point within delta of an
  /// in-bounds point of the box: the largest local Lipschitz bound over the box times delta is
  /// added (delta below one voxel; as the segment test's bubble, so a cull never skips what the
  /// segment test would find).
  /// @param nodes_read when set, receives the min-max tree nodes read (MinMaxTree::rawRange()).
  /// @param without_arc when set, receives the bound of the box itself (the same without the
  ///        arc_sagitta_m term), from the same nodes.
  /// @param arc_term when set, receives the arc_sagitta_m term alone (what was added to it).
  /// @param stop where the tree may stop reading (rawStopAbove(v) for a caller that asks "may the
  ///        box hold F > v?"): once the bound of the box itself is known to exceed v, the result
  ///        and without_arc are a smaller bound that still exceeds v, and the arc term is 0. The
  ///        answer to "result > v" is the same as without it. None by default.
  double upperBoundInBox(const Eigen::Vector3d& lo_ijk, const Eigen::Vector3d& hi_ijk,
                         int* nodes_read = nullptr, double arc_sagitta_m = 0.0,
                         double* without_arc = nullptr, double* arc_term = nullptr,
                         MinMaxTree::RawStop stop = {}) const noexcept;
  /// The tree's stop for upperBoundInBox() callers that ask whether F may exceed `value` (a
  /// raw value every node reaching which bounds its box above `value`); none (NaN) when
  /// `value` is not finite. Computed once per isovalue by its callers (a few divisions).
  MinMaxTree::RawStop rawStopAbove(double value) const noexcept;

  /// Upper bound of F over the closed box [lo_ijk, hi_ijk] (grid coordinates) from the voxels
  /// themselves: the largest corner of every cell that trilinear interpolation uses for a point of
  /// the box (the cell of x is min(floor(x), n - 2), clamped to the grid). The same contract as
  /// upperBoundInBox() without the arc term, at one voxel's resolution instead of one brick's (a
  /// level-0 brick spans MinMaxTree::kBrickCells cells): a box a voxel from the surface that the
  /// brick holding the surface cannot clear is cleared here. Reads at most max_voxels voxels;
  /// +infinity (no bound) when the box covers more, or is not finite; -infinity when it misses
  /// the grid.
  /// @param voxels_read when set, receives the voxels read (0 when none was).
  double voxelUpperBoundInBox(const Eigen::Vector3d& lo_ijk, const Eigen::Vector3d& hi_ijk, int max_voxels,
                              int* voxels_read = nullptr) const noexcept;

  // ---- Material removal (drilling) -------------------------------------------------------------
  // The volume is immutable to every holder of a const reference. MaterialRemoval, which holds
  // the one non-const reference to a renderer's private copy, carves it on the servo thread
  // between ticks (no query runs concurrently): writeRaw() then refreshRegion().

  /// Raw value (stored type, as double) that gives the lowest F of the volume as built: what a
  /// removed voxel becomes (air or background in a scan).
  double lowestRaw() const noexcept { return scale_ > 0.0 ? raw_min_ : raw_max_; }
  /// Raw value of the voxel at linear index `index` (x fastest); no bounds check.
  double rawAt(std::size_t index) const noexcept;
  /// Writes the raw value of the voxel at linear index `index` (converted to the stored type; no
  /// bounds check). The min-max tree and Lipschitz bounds are stale until refreshRegion().
  /// Not thread safe: no other thread may query the volume meanwhile.
  void writeRaw(std::size_t index, double raw) noexcept;
  /// Brings the min-max tree (ranges) and the local Lipschitz bounds up to date after writeRaw()
  /// on voxels inside the box [lo, hi] (voxel indices i, j, k, inclusive; clipped to the grid):
  /// only the level-0 bricks that read those voxels or book their edges, their neighbours'
  /// dilated bounds and their ancestors are recomputed (haptics/README.md, "Drilling"). No
  /// allocation. lipschitzBound() only grows; minValue() and maxValue() keep the values of the
  /// volume as built (bounds of the carved one).
  void refreshRegion(std::array<int, 3> lo, std::array<int, 3> hi) noexcept;

  /// Axis-aligned bounding box of the grid in W [m].
  Eigen::Vector3d boundsMin_W_m() const noexcept;
  Eigen::Vector3d boundsMax_W_m() const noexcept;

 private:
  // The bound on F of a tree range (upperBoundInBox()'s rounding).
  double rawBound(float raw_min, float raw_max) const noexcept;

  void initialise();  // validates and caches derived data
  template <typename T>
  double trilinear(const Eigen::Vector3d& ijk) const noexcept;
  template <typename T>
  double rawMaxInVoxels(const int* v0, const int* v1) const noexcept;
  // The bubble over a piece of a chord: sagitta, chord parameter U = u0 + du * (piece's u).
  struct SegmentBubble {
    double sagitta_m = 0.0, u0 = 0.0, du = 1.0;  // height per cell: local Lipschitz bound x sagitta
  };
  template <typename T>
  SegmentEntry firstEntry(const Eigen::Vector3d& a, const Eigen::Vector3d& b, double threshold, double u_limit,
                          double u_tolerance, bool at_segment_start, const SegmentBubble& bubble) const noexcept;
  SegmentEntry walkSegment(const Eigen::Vector3d& a, const Eigen::Vector3d& b, double threshold, double u_limit,
                           double u_tolerance, bool at_segment_start, const SegmentBubble& bubble) const noexcept;
  bool gridInBounds(const Eigen::Vector3d& ijk) const noexcept;

  VolumeGeometry geometry_;
  VoxelType type_ = VoxelType::kUInt8;
  std::vector<std::byte> bytes_;
  double scale_ = 1.0;
  double offset_ = 0.0;
  double min_value_ = 0.0;
  double max_value_ = 0.0;
  double lipschitz_ = 0.0;  // see lipschitzBound()
  double raw_min_ = 0.0, raw_max_ = 0.0;  // range of the raw voxels as built
  std::vector<float> own_lipschitz_;      // per level-0 brick, before the 3 x 3 x 3 dilation
  // Per step brick (kStepBrickCells cells a side), the smallest raw steps v(i + 1) - v(i) along
  // i, j, k of the edges booked to it, then the largest (gridStepRange()); rounded outward to
  // float. Drilling only widens them (refreshRegion()).
  std::vector<float> steps_;
  std::array<int, 3> step_bricks_{0, 0, 0};  // step bricks per axis
  // Where step brick (a, b, c)'s six values start in steps_.
  std::size_t stepBrickOffset(int a, int b, int c) const noexcept {
    return 6 * (static_cast<std::size_t>(a) +
                static_cast<std::size_t>(step_bricks_[0]) * (b + static_cast<std::size_t>(step_bricks_[1]) * c));
  }
  std::array<int, 3> bricks_{0, 0, 0};    // level-0 bricks per axis
  float brickBound(const double* step) const noexcept;  // Lipschitz bound from a brick's raw steps
  template <typename T>
  void refreshRegionT(const std::array<int, 3>& lo, const std::array<int, 3>& hi) noexcept;
  // Where level-0 brick (a, b, c)'s own Lipschitz bound is in own_lipschitz_.
  std::size_t ownBrickIndex(int a, int b, int c) const noexcept {
    return static_cast<std::size_t>(a) +
           static_cast<std::size_t>(bricks_[0]) * (b + static_cast<std::size_t>(bricks_[1]) * c);
  }
  // refreshRegion(): the own Lipschitz bound of the level-0 bricks [e0, e1] per axis (those the
  // written voxels' edges are booked to) recounted from their raw steps; lipschitz_ grows with it.
  template <typename T>
  void recountOwnLipschitz(const std::array<int, 3>& e0, const std::array<int, 3>& e1) noexcept;
  // refreshRegion(): the 3 x 3 x 3-dilated bound of the bricks [e0 - 1, e1 + 1] per axis (those
  // next to a recounted brick) set again in the min-max tree, and propagated up it.
  void dilateLipschitz(const std::array<int, 3>& e0, const std::array<int, 3>& e1) noexcept;
  // refreshRegion(): each edge touching a written voxel of [lo, hi] (voxel indices) adds its new
  // raw step to its step brick's range (steps_), which only widens.
  template <typename T>
  void widenStepRanges(const std::array<int, 3>& lo, const std::array<int, 3>& hi) noexcept;
  Eigen::Matrix3d W_to_grid_ = Eigen::Matrix3d::Identity();  // (D diag(s))^-1
  Eigen::Vector3d upper_{0, 0, 0};                           // n - 1 per axis
  MinMaxTree tree_;
};

}  // namespace vh::haptics

#include "vh/haptics/scalar_volume_inl.h"
