#pragma once
/// @file
/// The tool as a point-sampled surface: the point shell (paper section 2.2, [5]).

#include <cstddef>
#include <vector>

#include <Eigen/Core>

#include "vh/haptics/triangle_mesh.h"

namespace vh::haptics {

/// Points on the tool's surface in the tool frame T, with optional outward normals.
class PointShell {
 public:
  PointShell() = default;
  /// @param points_T_m (n x 3) positions in T [m]; @param normals_T (n x 3) unit outward
  /// normals in T, or empty.
  /// @throws std::invalid_argument when a point or normal is not finite, or sizes differ.
  PointShell(std::vector<Eigen::Vector3d> points_T_m, std::vector<Eigen::Vector3d> normals_T = {});

  std::size_t size() const noexcept { return points_.size(); }
  bool empty() const noexcept { return points_.empty(); }
  bool hasNormals() const noexcept { return !normals_.empty(); }
  /// Points (n x 3) in T [m].
  const std::vector<Eigen::Vector3d>& points_T_m() const noexcept { return points_; }
  /// Unit outward normals (n x 3) in T, or empty.
  const std::vector<Eigen::Vector3d>& normals_T() const noexcept { return normals_; }

  /// Mean distance from each point to its nearest neighbour [m] (a grid search, O(n) for a
  /// shell; for reports and tests). 0 for fewer than two points.
  double meanNearestNeighbourSpacing_m() const;

 private:
  std::vector<Eigen::Vector3d> points_;
  std::vector<Eigen::Vector3d> normals_;
};

/// The point shell's neighbour graph: the edges along which the tool's surface between its
/// points is tested (haptics/README.md, "Between the points"). Each point is joined to at most
/// kMaxNeighbours of its nearest points within max_length_m whose normals differ by less than
/// about 73 degrees (dot > 0.3; no test without normals), so an edge runs along the tool's
/// surface, never across a concave corner of the tool (where the solid may touch the tool
/// legitimately between its points). Stored once per edge (j < k), in compressed rows.
struct ShellEdges {
  static constexpr int kMaxNeighbours = 8;
  std::vector<int> offsets;   ///< Edges of point j: targets[offsets[j], offsets[j + 1]) (size n + 1).
  std::vector<int> targets;   ///< Indices k > j.
  double spacing_m = 0.0;     ///< Median nearest-neighbour distance of the shell [m].
  double max_length_m = 0.0;  ///< Longest edge allowed [m] (kLengthFactor x spacing_m).
  static constexpr double kLengthFactor = 1.8;
  std::size_t size() const noexcept { return targets.size(); }
};

/// Builds the neighbour graph of `shell` (a uniform grid of cells of the edge length; O(n)).
/// An empty or one-point shell has no edges.
ShellEdges makeShellEdges(const PointShell& shell);

/// How to resample a mesh into a point shell.
struct PointShellOptions {
  /// Target spacing between neighbouring points [m]; used when point_count == 0.
  double spacing_m = 1e-3;
  /// Requested number of points; 0 means "use spacing_m". The result has this many points.
  std::size_t point_count = 0;
  /// Seed of the deterministic candidate sampler.
  unsigned seed = 1;
};

/// Resamples a triangle mesh into an evenly spaced point shell with per-point normals
/// (area-weighted dense candidates, then farthest-point / Poisson-disk thinning), because mesh
/// vertices alone are uneven (section 2.2). The points come in Morton (Z-curve) order, so that
/// points near each other on the tool lie near each other in memory (the collision detector
/// visits the tool region by region).
/// @throws std::invalid_argument for an empty mesh, spacing <= 0, or a spacing that would need
///         more than 200,000 points.
PointShell makePointShell(const TriangleMesh& mesh, const PointShellOptions& options);

}  // namespace vh::haptics
