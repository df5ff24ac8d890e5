#pragma once
/// @file
/// Distance to a segment: an exact Euclidean distance transform of a binary mask, sampled
/// trilinearly, and the point shell's smallest distance to each of a few segments per tick
/// (ProximityQuery). What the warnings before harm near a critical structure measure.
///
/// The distance is from a point to the nearest *voxel centre* of the mask, in metres, on the
/// mask's own grid (anisotropic spacing, any orthonormal direction). At voxel centres it is
/// exact (Felzenszwalb and Huttenlocher, "Distance Transforms of Sampled Functions", Theory of
/// Computing 8, 2012, section 4: the lower envelope of parabolas, one axis after the other).
/// Between voxel centres it is interpolated trilinearly. The true distance d is 1-Lipschitz, so
/// with trilinear weights w_c at the corners c of the cell around p,
///   |sample(p) - d(p)| <= sum_c w_c |c - p| <= sqrt(sum_c w_c |c - p|^2)
///                       = sqrt(sum_a h_a^2 t_a (1 - t_a)) <= 0.5 * |(h_x, h_y, h_z)|,
/// half the voxel diagonal (DistanceField::samplingBound_m()). Beyond the stored box (the mask's bounding box
/// grown by the margin, clipped to the grid) a point p is projected onto the box (p_b) and
///   sample(p) = sqrt(|p - p_b|^2 + sample(p_b)^2),
/// which is at most d(p) plus the same bound (projection onto a convex set that holds every
/// mask voxel: the angle at p_b to any of them is obtuse), a conservative estimate far away.

#include <array>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <memory>
#include <span>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "vh/haptics/point_shell.h"
#include "vh/haptics/pose.h"
#include "vh/haptics/scalar_volume.h"

namespace vh::haptics {

/// Exact Euclidean distance transform of a binary mask, stored on the part of its grid that
/// lies within `margin_m` of the mask's bounding box. Immutable; const members are thread-safe.
class DistanceField {
 public:
  DistanceField() = default;

  /// Builds the field of `mask` (one byte per voxel, x fastest, non-zero: in the segment) on
  /// `geometry` (the index -> W affine of ScalarVolume; dims >= 1 on every axis).
  /// Cost: O(voxels of the stored box), three passes; memory 8 bytes per stored voxel.
  /// @param margin_m how far around the mask's bounding box distances are stored [m] (>= 0):
  ///        samples within it are exact to samplingBound_m(); farther away conservative.
  /// @throws std::invalid_argument for a mask of the wrong size, bad geometry (dims < 1,
  ///         spacing <= 0 or not finite) or a negative / non-finite margin.
  static DistanceField FromMask(const VolumeGeometry& geometry, std::span<const std::uint8_t> mask,
                                double margin_m);

  /// True when the mask had no voxel (every distance is +infinity).
  bool empty() const noexcept { return distance_m_.empty(); }
  /// The whole mask grid's geometry.
  const VolumeGeometry& geometry() const noexcept { return geometry_; }
  /// The stored box in voxel indices of the grid: [lo, hi] inclusive on each axis.
  const std::array<int, 3>& boxLo() const noexcept { return lo_; }
  const std::array<int, 3>& boxHi() const noexcept { return hi_; }
  /// Voxels of the mask.
  std::size_t maskVoxels() const noexcept { return mask_voxels_; }
  /// Half the voxel diagonal [m]: the bound of |sample(p) - d(p)| (the file's comment).
  double samplingBound_m() const noexcept { return 0.5 * geometry_.spacing_m.norm(); }

  /// Exact distance [m] from the centre of voxel (i, j, k) (inside the stored box) to the
  /// nearest mask voxel centre; 0 on the mask.
  double voxelDistance_m(int i, int j, int k) const noexcept;
  /// Sampled distance at p_W [m] (trilinear inside the stored box, projected beyond it; see
  /// the file's comment); +infinity for an empty mask or a non-finite point. No allocation.
  double sample_m(const Eigen::Vector3d& p_W_m) const noexcept;

 private:
  VolumeGeometry geometry_;
  std::array<int, 3> lo_{0, 0, 0}, hi_{-1, -1, -1};
  std::array<int, 3> n_{0, 0, 0};  // stored box's size per axis
  std::vector<double> distance_m_;  // stored box, x fastest
  std::size_t mask_voxels_ = 0;
  Eigen::Matrix3d W_to_I_ = Eigen::Matrix3d::Identity();  // p_I = W_to_I (p_W - origin)
};

/// The reference squared distance transform: for every voxel the smallest squared distance to
/// a mask voxel centre [m^2], over all pairs (O(n m)); for tests only.
std::vector<double> bruteForceSquaredDistances_m2(const VolumeGeometry& geometry,
                                                  std::span<const std::uint8_t> mask);

/// One segment's result of ProximityQuery::evaluate().
struct SegmentProximity {
  /// Smallest sampled distance [m] from any point of the shell to the segment (0: a point is
  /// inside it), or +infinity when the whole tool is farther than the query's range.
  double distance_m = std::numeric_limits<double>::infinity();
  int point = -1;  ///< The shell point that gave it, or -1 beyond the range.
};

/// The nearest of the segments on one tick.
struct NearestProximity {
  int field = -1;  ///< Index into the query's fields of the nearest, or -1: all beyond the range.
  double distance_m = std::numeric_limits<double>::infinity();  ///< Its distance [m].
};

/// The point shell's smallest distance to each of a few segments (their DistanceField), per
/// tick, without allocating: the points are grouped (runs of kGroupPoints of the shell's Morton
/// order, each with its bounding ball in T); a group whose ball's centre samples farther than
/// its radius plus twice the sampling bound beyond the best distance so far cannot hold a
/// nearer point (1-Lipschitz) and is skipped, the groups are visited nearest first, and a
/// segment whose distance from the whole tool's ball exceeds the range is reported beyond it.
/// The result is the exact minimum of DistanceField::sample_m() over the shell's points.
class ProximityQuery {
 public:
  static constexpr std::size_t kGroupPoints = 32;

  /// @param fields one per segment (non-null); @param shell the tool's points in T [m];
  /// @param range_m distances beyond it need not be computed (> 0; +infinity: always computed).
  /// @throws std::invalid_argument for a null field or a range <= 0 or NaN.
  ProximityQuery(std::vector<std::shared_ptr<const DistanceField>> fields, const PointShell& shell, double range_m);

  /// Evaluates every segment at the proxy pose X_WP (tool frame P = T placed in W); writes
  /// results() and returns the nearest. No allocation, never throws.
  NearestProximity evaluate(const Pose& X_WP) noexcept;
  /// One per field, from the last evaluate().
  std::span<const SegmentProximity> results() const noexcept { return results_; }
  /// Shell points sampled by the last evaluate() (all fields; the cost).
  std::size_t pointsSampled() const noexcept { return points_sampled_; }
  std::size_t fieldCount() const noexcept { return fields_.size(); }
  double range_m() const noexcept { return range_m_; }

 private:
  SegmentProximity evaluateField(const DistanceField& field, const Pose& X_WP) noexcept;

  struct Group {
    Eigen::Vector3d centre_T_m;
    double radius_m = 0.0;
    int begin = 0, end = 0;  // shell points [begin, end)
  };
  std::vector<std::shared_ptr<const DistanceField>> fields_;
  std::vector<Eigen::Vector3d> points_T_m_;
  std::vector<Group> groups_;
  Eigen::Vector3d centre_T_m_ = Eigen::Vector3d::Zero();  // the whole shell's ball
  double radius_m_ = 0.0;
  double range_m_ = std::numeric_limits<double>::infinity();
  std::vector<std::pair<double, int>> order_;  // per evaluate: (group lower bound, group)
  std::vector<SegmentProximity> results_;
  std::size_t points_sampled_ = 0;
};

}  // namespace vh::haptics
