#pragma once
/// @file
/// One point of the contact set that CollisionDetector (collision_detector.h) keeps, prunes
/// (paper section 2.3, step 2) and adds to after a hit (contact_set.cpp).

#include <Eigen/Core>

namespace vh::haptics {

/// One point of the contact set.
struct Contact {
  /// Index into the point shell, or -1 for a contact of the tool's surface between two points
  /// (an edge of the neighbour graph: CollisionDetector::addEdgeContact()).
  int point_index = -1;
  /// The contact's point on the tool, in T [m]: the shell point, or the point of the edge where
  /// the isosurface met it.
  Eigen::Vector3d p_T_m = Eigen::Vector3d::Zero();
  Eigen::Vector3d p_W_m = Eigen::Vector3d::Zero(); ///< Point position on the proxy, in W [m].
  Eigen::Vector3d n_W = Eigen::Vector3d::UnitZ();  ///< Unit surface normal -grad F / |grad F|, W.
  /// Distance from p to the isosurface along -n_W [m], measured by bisection with the inside
  /// test to epsilon / 16, capped at epsilon.
  double clearance_m = 0.0;
  /// True when n_W comes from the interpolant's own gradient (see refineStuckContact()).
  bool crossing_normal = false;
  /// For a contact between two points: the edge's unit direction, in T; zero for a shell point.
  /// Its normal is the gradient's part perpendicular to the edge (an edge meets a ridge of the
  /// isosurface along their common perpendicular, not along the ridge's diagonal gradient).
  Eigen::Vector3d edge_T = Eigen::Vector3d::Zero();
};

}  // namespace vh::haptics
