// The edge test (haptics/README.md, "Between the points"): whether the tool's surface between
// its points meets the isosurface, each edge of the point shell's neighbour graph tested with
// the exact segment test, culled by the point-shell tree and by the certificates of earlier
// walks (edge_certificates.cpp), forked over the lanes; and the contact it adds where a wall
// came between two points.
#include "collision_detector_impl.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>

#include "float_rounding.h"

namespace vh::haptics {

Eigen::Vector3d CollisionDetector::Impl::edgeEnd(WorkCounters& w, const Pose& X_WP, int i) const noexcept {
  // Moved epsilon into the tool along its normal: the surface is allowed to come within epsilon
  // of the tool between its points, as at its points (a facet of the tool resting on a curved
  // trilinear surface touches it by fractions of a micrometre between two points); a wall that
  // passes through the tool is found all the same.
  ++w.samples;
  const auto& shell = tool_->point_shell;
  const Eigen::Vector3d p_T = shell.hasNormals() ? Eigen::Vector3d(shell.points_T_m()[i] - epsilon_ * shell.normals_T()[i])
                                                 : shell.points_T_m()[i];
  return volume_->gridCoordinates(X_WP * p_T);
}

bool CollisionDetector::Impl::segmentCrosses(WorkCounters& w, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                                       double isovalue, double* excess_max) const noexcept {
  // Only whether it enters: a coarse bracket is enough.
  const SegmentEntry entry = volume_->firstEntryOnSegment(a, b, isovalue, 1.0, 0.5);
  w.cells += entry.cells;
  w.cells_walked += entry.cells_walked;
  if (excess_max != nullptr) *excess_max = entry.excess_max;
  return entry.hit;
}

void CollisionDetector::Impl::recordCrossingEdge(int j, int k, const Pose& X_WP) noexcept {
  edge_hit_ = {j, k, X_WP};
  if (listed_count_ < kListedEdges) {
    bool known = false;
    for (int i = 0; i < listed_count_; ++i) known |= listed_[i].first == j && listed_[i].second == k;
    if (!known) listed_[listed_count_++] = {j, k};
  }
}

int CollisionDetector::Impl::edgeCrosses(WorkCounters& w, const Pose& X_WP, int j, const Eigen::Vector3d& p_W,
                                   double isovalue) noexcept {
  if (embedded_[j]) return -1;
  ++w.edge.points_walked;
  const auto i = static_cast<std::size_t>(j);
  const Eigen::Vector3d a = edgeEnd(w, X_WP, j);  // once for all of j's edges
  double clearance_m = std::numeric_limits<double>::infinity();
  double excess_all = -std::numeric_limits<double>::infinity();  // F - s's bound over all of j's edges
  Eigen::Vector3d box_lo = a, box_hi = a;                         // their box, grid coordinates
  for (int e = edges_.offsets[j]; e < edges_.offsets[j + 1]; ++e) {
    const int k = edges_.targets[e];
    if (embedded_[k]) {  // untested: nothing proven for j's edges
      clearance_m = -1.0;
      excess_all = std::numeric_limits<double>::infinity();
      continue;
    }
    const Eigen::Vector3d b = edgeEnd(w, X_WP, k);
    ++w.edge.edges_walked;
    double excess_max = 0.0;
    if (segmentCrosses(w, a, b, isovalue, &excess_max)) return k;
    clearance_m = std::min(clearance_m, edgeClearance(a, b, excess_max, isovalue));
    excess_all = std::max(excess_all, excess_max);
    box_lo = box_lo.cwiseMin(b);
    box_hi = box_hi.cwiseMax(b);
  }
  // Two certificates a point, the newer replacing the older: a move stopped by an edge tests
  // the pose it ends at and the one past it in turn, tick after tick.
  EdgeClearance proven{p_W, X_WP.R_AB, std::isfinite(clearance_m) && clearance_m > 0.0 ? clearance_m : -1.0,
                       edge_reach_m_[i] + epsilon_};
  if (excess_all < 0.0) {
    const Eigen::Vector3d reach = Eigen::Vector3d::Constant(kCertificateReachSteps);
    Eigen::Vector3d step_lo, step_hi, valid_lo, valid_hi;
    if (volume_->gridStepRange(box_lo - reach, box_hi + reach, step_lo, step_hi, &valid_lo, &valid_hi)) {
      // The cubic's value at a rounded critical point: a relative tolerance, as edgeClearance().
      const double steepest = std::max(step_lo.cwiseAbs().maxCoeff(), step_hi.cwiseAbs().maxCoeff());
      proven.margin = -(excess_all + 1e-9 * (std::abs(isovalue) + steepest) + 1e-300);
      // Kept as floats: the ranges widened, the reaches shortened by the rounding.
      for (int axis = 0; axis < 3; ++axis) {
        proven.step_lo[axis] = floatBelow(step_lo[axis]);
        proven.step_hi[axis] = floatAbove(step_hi[axis]);
        proven.reach_lo[axis] = floatBelow(box_lo[axis] - valid_lo[axis]);
        proven.reach_hi[axis] = floatBelow(valid_hi[axis] - box_hi[axis]);
      }
      ++w.samples;  // the ranges of 1 to 8 step bricks, charged as one sample
    }
  }
  if (proven.clearance_m > 0.0 || proven.margin > 0.0) keepEdgeClearance(j, proven);
  return -1;
}

bool CollisionDetector::Impl::listedEdgesCrossAt(const Pose& X_WP, double isovalue) noexcept {
  for (int i = 0; i < listed_count_; ++i) {
    const auto [j, k] = listed_[i];
    if (embedded_[j] || embedded_[k]) continue;
    if (segmentCrosses(counters_, edgeEnd(counters_, X_WP, j), edgeEnd(counters_, X_WP, k), isovalue)) {
      recordCrossingEdge(j, k, X_WP);
      return true;
    }
  }
  return false;
}

const Contact* CollisionDetector::Impl::addEdgeContact(const Pose& X_WP, double isovalue) noexcept {
  if (edge_hit_.j < 0 || contact_count_ >= std::min(contact_cap_, contacts_.size())) return nullptr;
  const auto& shell = tool_->point_shell;
  const auto inset = [&](int i) {
    return shell.hasNormals() ? Eigen::Vector3d(shell.points_T_m()[i] - epsilon_ * shell.normals_T()[i])
                              : shell.points_T_m()[i];
  };
  const Eigen::Vector3d a = inset(edge_hit_.j), b = inset(edge_hit_.k);
  // Where the isosurface entered the edge at the crossing pose, to epsilon / 16 along it (the
  // test itself brackets it coarsely: whether it enters is all it asks).
  const double length_m = (b - a).norm();
  ++counters_.samples;
  const SegmentEntry entry = volume_->firstEntryOnSegment(
      volume_->gridCoordinates(edge_hit_.X_WP * a), volume_->gridCoordinates(edge_hit_.X_WP * b), isovalue, 1.0,
      length_m > 0.0 ? std::min(0.5, epsilon_ / (16.0 * length_m)) : 0.5);
  counters_.cells += entry.cells;
  counters_.cells_walked += entry.cells_walked;
  const Eigen::Vector3d p_T = a + (entry.hit ? entry.u_outside : 0.5) * (b - a);
  // Against the tool's own outward normal there, when the gradient is flat.
  Eigen::Vector3d fallback_n_W = Eigen::Vector3d::UnitZ();
  if (shell.hasNormals()) {
    const Eigen::Vector3d n_T = shell.normals_T()[edge_hit_.j] + shell.normals_T()[edge_hit_.k];
    if (n_T.norm() > 0.0) fallback_n_W = -(X_WP.R_AB * n_T).normalized();
  }
  // One contact per place on the tool: a new one within a quarter epsilon of an earlier edge
  // contact replaces it.
  std::size_t slot = contact_count_;
  for (std::size_t i = 0; i < contact_count_; ++i)
    if (contacts_[i].point_index < 0 && (contacts_[i].p_T_m - p_T).norm() < 0.25 * epsilon_) slot = i;
  Contact& c = contacts_[slot];
  c.point_index = -1;
  c.p_T_m = p_T;
  c.edge_T = length_m > 0.0 ? Eigen::Vector3d((b - a) / length_m) : Eigen::Vector3d::Zero();
  c.p_W_m = X_WP * p_T;
  c.n_W = fallback_n_W;
  c.crossing_normal = false;
  measureContact(c, isovalue, X_WP.R_AB);
  if (slot == contact_count_) ++contact_count_;
  edge_hit_ = {};
  return &c;
}

CollisionDetector::Impl::EdgeWalk CollisionDetector::Impl::edgeNodeWalk(WorkCounters& w, Lane* lane, int index, const Pose& X_WP,
                                                            const Eigen::Matrix3d& R_WT, double isovalue, int& walked,
                                                            int& j_hit, int& k_hit) noexcept {
  const ShellNode& node = nodes_[static_cast<std::size_t>(index)];
  std::uint8_t& near = node_edge_near_[static_cast<std::size_t>(index)];
  // Point j's edges lie within the longest edge of j, plus the epsilon their ends are inset by
  // (edgeEnd()), of point j: a node's ball dilated by both holds them.
  const bool asked = near == 0;
  if (asked && !ballMayBeInside(w, R_WT * node.center_T_m + X_WP.p_AB_m,
                                (node.radius_m + edges_.max_length_m + epsilon_) * (1.0 + 1e-9) + 1e-12, isovalue))
    return EdgeWalk::kClear;
  bool found_near = false;
  if (node.left >= 0) {
    for (const int child : {node.left, node.right}) {
      const EdgeWalk result = edgeNodeWalk(w, lane, child, X_WP, R_WT, isovalue, walked, j_hit, k_hit);
      if (result != EdgeWalk::kClear) return result;
      found_near = found_near || node_edge_near_[static_cast<std::size_t>(child)] != 0;
    }
  } else {
    for (int i = node.begin; i < node.end; ++i) {
      const int j = order_[static_cast<std::size_t>(i)];
      if (edges_.offsets[j + 1] == edges_.offsets[j]) continue;
      const Eigen::Vector3d p_W = R_WT * tool_->point_shell.points_T_m()[static_cast<std::size_t>(j)] + X_WP.p_AB_m;
      const EdgeHold held = edgesStillClear(X_WP, j, p_W);
      if (held != EdgeHold::kNone) {
        ++w.edge.points_held;
        found_near = found_near || held == EdgeHold::kWalk;
        continue;
      }
      // The point's own edges, within its longest edge plus epsilon of it: one box query
      // instead of a walk per edge where the leaf is near the surface but this point is not.
      // Proven empty with a margin, the ball is a certificate too (EdgeClearance::arm_m = 0):
      // until point j has moved the margin, its edges stay in the ball however the tool turns.
      if (!ballMayBeInside(w, p_W, (edge_reach_m_[j] + epsilon_ + ballMargin_m()) * (1.0 + 1e-9) + 1e-12, isovalue)) {
        keepEdgeClearance(j, {p_W, X_WP.R_AB, ballMargin_m(), 0.0});
        ++w.edge.points_boxed;
        continue;
      }
      found_near = true;
      if (walked++ > 0 && (lane != nullptr ? overBudget(*lane) : overBudget())) return EdgeWalk::kCut;
      const int k = edgeCrosses(w, X_WP, j, p_W, isovalue);
      if (k >= 0) {
        j_hit = j;
        k_hit = k;
        return EdgeWalk::kCrossing;
      }
    }
  }
  near = found_near ? 1 : 0;
  return EdgeWalk::kClear;
}

void CollisionDetector::Impl::edgeLaneJob(void* detector, int lane) noexcept {
  auto* self = static_cast<CollisionDetector::Impl*>(detector);
  self->runEdgeLane(self->lanes_[static_cast<std::size_t>(lane)]);
}

void CollisionDetector::Impl::runEdgeLane(Lane& lane) noexcept {
  // The lane's roots in the single-lane walk's order; a root after one where some lane found a
  // crossing cannot hold the first crossing of that walk, and is not walked.
  int walked = 0;
  std::atomic<int>& bound = *edge_bound_;
  const Eigen::Matrix3d R_WT = edge_job_.X_WP.R_AB.toRotationMatrix();
  for (std::size_t r = 0; r < lane.roots.size(); ++r) {
    const int rank = lane.root_ranks[r];
    if (rank > bound.load(std::memory_order_relaxed)) return;
    int j = -1, k = -1;
    std::int64_t mark = lane.counters.total();
    const EdgeWalk result =
        edgeNodeWalk(lane.counters, &lane, lane.roots[r], edge_job_.X_WP, R_WT, edge_job_.isovalue, walked, j, k);
    if (balanced_lanes_) chargeRoot(lane, rank, mark);
    if (result == EdgeWalk::kCrossing) {
      lane.edge_rank = rank;
      lane.edge_j = j;
      lane.edge_k = k;
      int seen = bound.load(std::memory_order_relaxed);
      while (rank < seen && !bound.compare_exchange_weak(seen, rank, std::memory_order_relaxed)) {
      }
      return;
    }
    if (result == EdgeWalk::kCut) {
      lane.edge_cut_rank = rank;
      return;
    }
  }
}

bool CollisionDetector::Impl::edgesCrossAt(const Pose& X_WP, double isovalue) noexcept {
  edge_cut_ = false;
  if (edges_.size() == 0) return false;
  prepareTreeStop(isovalue);
  if (!(isovalue == edge_clearance_isovalue_)) {  // certificates hold for their isovalue only
    for (auto& proven : edge_clearance_) proven.clearance_m = proven.margin = -1.0;
    edge_clearance_isovalue_ = isovalue;
  }
  if (mode_ == DetectionMode::kAccelerated && pool_ && lanes_.size() > 1) {
    // Forked: each lane walks its roots (the tree's upper nodes, in the single-lane walk's
    // order). The answer is the single-lane walk's: the crossing edge of the lowest-ranked root
    // that holds one, once every root before it was walked to its end; a lane stopped by the
    // budget before that leaves nothing known (cut), as the single-lane walk would have been.
    edge_job_ = {X_WP, isovalue};
    edge_bound_->store(std::numeric_limits<int>::max(), std::memory_order_relaxed);
    for (Lane& lane : lanes_) {
      startLaneWork(lane);
      lane.edge_rank = lane.edge_cut_rank = std::numeric_limits<int>::max();
      lane.edge_j = lane.edge_k = -1;
    }
    pool_->run(&CollisionDetector::Impl::edgeLaneJob, this, static_cast<int>(lanes_.size()));
    joinLaneWork();
    const Lane* found = nullptr;
    int cut_rank = std::numeric_limits<int>::max();
    for (const Lane& lane : lanes_) {
      cut_rank = std::min(cut_rank, lane.edge_cut_rank);
      if (lane.edge_j >= 0 && (found == nullptr || lane.edge_rank < found->edge_rank)) found = &lane;
    }
    if (found != nullptr && found->edge_rank < cut_rank) {
      recordCrossingEdge(found->edge_j, found->edge_k, X_WP);
      return true;
    }
    if (cut_rank != std::numeric_limits<int>::max()) return edge_cut_ = true;
    return false;
  }
  if (mode_ == DetectionMode::kAccelerated) {
    int walked = 0, j = -1, k = -1;
    const EdgeWalk result =
        edgeNodeWalk(counters_, nullptr, 0, X_WP, X_WP.R_AB.toRotationMatrix(), isovalue, walked, j, k);
    if (result == EdgeWalk::kCrossing) {
      recordCrossingEdge(j, k, X_WP);
      return true;
    }
    if (result == EdgeWalk::kCut) return edge_cut_ = true;
    return false;
  }
  int walked = 0;
  for (int j = 0; j + 1 < static_cast<int>(edges_.offsets.size()); ++j) {
    if (edges_.offsets[j + 1] == edges_.offsets[j]) continue;
    const Eigen::Vector3d p_W = X_WP * tool_->point_shell.points_T_m()[static_cast<std::size_t>(j)];
    if (edgesStillClear(X_WP, j, p_W) != EdgeHold::kNone) {
      ++counters_.edge.points_held;
      continue;
    }
    if (walked++ > 0 && overBudget()) return edge_cut_ = true;
    const int k = edgeCrosses(counters_, X_WP, j, p_W, isovalue);
    if (k >= 0) {
      recordCrossingEdge(j, k, X_WP);
      return true;
    }
  }
  return false;
}

}  // namespace vh::haptics
