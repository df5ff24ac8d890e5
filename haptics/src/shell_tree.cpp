// The point-shell tree (kAccelerated) and the question every walk of it asks: can a ball in W
// hold an inside point? Answered by the volume's min-max tree with its local Lipschitz bounds,
// then, for a small box, by its voxels (ballMayBeInside()).
#include "collision_detector_impl.h"

#include <algorithm>
#include <limits>

namespace vh::haptics {

int CollisionDetector::Impl::buildShellTree(int begin, int end, int depth) {
  constexpr int kLeafPoints = 8;
  const auto& points = tool_->point_shell.points_T_m();
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
  for (int i = begin; i < end; ++i) {
    lo = lo.cwiseMin(points[order_[i]]);
    hi = hi.cwiseMax(points[order_[i]]);
  }
  const int index = static_cast<int>(nodes_.size());
  nodes_.push_back({});
  ShellNode node;
  node.center_T_m = 0.5 * (lo + hi);
  for (int i = begin; i < end; ++i) node.radius_m = std::max(node.radius_m, (points[order_[i]] - node.center_T_m).norm());
  node.begin = begin;
  node.end = end;
  if (end - begin > kLeafPoints && depth < 40) {
    int axis = 0;
    (hi - lo).maxCoeff(&axis);
    const int mid = begin + (end - begin) / 2;
    std::nth_element(order_.begin() + begin, order_.begin() + mid, order_.begin() + end,
                     [&](int a, int b) { return points[a][axis] < points[b][axis]; });
    node.left = buildShellTree(begin, mid, depth + 1);
    node.right = buildShellTree(mid, end, depth + 1);
  }
  nodes_[index] = node;
  return index;
}

void CollisionDetector::Impl::ballGridBox(const Eigen::Vector3d& centre_W_m, double radius_m, Eigen::Vector3d& lo_ijk,
                                    Eigen::Vector3d& hi_ijk) const noexcept {
  const Eigen::Vector3d g = volume_->gridCoordinates(centre_W_m);
  // A W ball maps to an ellipsoid with half-axes radius / spacing along the grid axes (the
  // direction matrix is orthonormal); 1e-6 voxel covers the rounding of both paths.
  const Eigen::Vector3d half = (radius_m * grid_per_m_).array() + 1e-6;
  lo_ijk = g - half;
  hi_ijk = g + half;
}

bool CollisionDetector::Impl::ballMayBeInside(WorkCounters& k, const Eigen::Vector3d& center_W_m, double radius_m,
                                        double isovalue, double arc_sagitta_m) const noexcept {
  ++k.box_queries;
  Eigen::Vector3d lo, hi;
  ballGridBox(center_W_m, radius_m, lo, hi);
  int nodes_read = 0;
  double without_arc = 0.0, arc = 0.0;
  // The tree stops reading at the first node above the isovalue (the box itself may then hold
  // the surface: only the arc term is left unknown, 0 here, and computed below where needed).
  bool may_be_inside = volume_->upperBoundInBox(lo, hi, &nodes_read, arc_sagitta_m, &without_arc, &arc,
                                                isovalue == stop_isovalue_ ? tree_stop_ : MinMaxTree::RawStop{}) > isovalue;
  // Stopped, the tree leaves the arc term at 0: a non-zero one is the whole query's already
  // (always so for a box within one brick, which the tree reads whole).
  const bool arc_unknown = arc_sagitta_m > 0.0 && without_arc > isovalue && arc == 0.0;
  k.tree_nodes += nodes_read;
  // Only the bubble's term lifted it over the isovalue: the dilated box may still prove it empty
  // (a voxel of the box itself above the isovalue decides it at once).
  if (may_be_inside && arc_sagitta_m > 0.0 && without_arc <= isovalue) {
    // The arc is within one cell of the ball: no voxel there above the isovalue also proves it
    // empty (as the segment test's own second criterion), where the Lipschitz bubble of a wild
    // outlier (a -3e38 "no data" border) cannot.
    ++k.box_queries;
    may_be_inside = volume_->upperBoundInBox(lo - Eigen::Vector3d::Ones(), hi + Eigen::Vector3d::Ones(),
                                             &nodes_read) > isovalue;
    k.tree_nodes += nodes_read;
  }
  if (may_be_inside) {
    // The bricks hold the surface; a small box (a voxel or two from it) may still be clear of
    // it: its own voxels decide (the same two criteria, at one voxel's resolution).
    int voxels = 0;
    const double own = volume_->voxelUpperBoundInBox(lo, hi, detail::kVoxelQueryMax, &voxels);
    if (voxels > 0) {
      ++k.voxel_queries;
      k.voxels += voxels;
      if (arc_unknown && own <= isovalue) {  // the arc term decides: the whole tree query
        ++k.box_queries;
        volume_->upperBoundInBox(lo, hi, &nodes_read, arc_sagitta_m, nullptr, &arc);
        k.tree_nodes += nodes_read;
      }
      may_be_inside = own + arc > isovalue;
      if (may_be_inside && arc_sagitta_m > 0.0 && own <= isovalue) {
        ++k.voxel_queries;
        may_be_inside = volume_->voxelUpperBoundInBox(lo - Eigen::Vector3d::Ones(),
                                                      hi + Eigen::Vector3d::Ones(), 8 * detail::kVoxelQueryMax,
                                                      &voxels) > isovalue;
        k.voxels += voxels;
      }
    }
  }
  return may_be_inside;
}

}  // namespace vh::haptics
