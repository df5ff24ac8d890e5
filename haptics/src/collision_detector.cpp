#include "vh/haptics/collision_detector.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include "float_rounding.h"

namespace vh::haptics {
namespace {
// Min-heap on t_begin over a preallocated array.
struct Later {
  template <typename E>
  bool operator()(const E& a, const E& b) const noexcept { return a.t_begin > b.t_begin; }
};

// Puts `entry` at the root of the binary min-heap h[0, count) (on t_begin) and sifts it down:
// the accelerated sweep replaces the popped minimum by its successor in one sift instead of a
// pop and a push (the heap was the largest cost of the sweep on a wrench lying on the Engine).
template <typename E>
void replaceTop(E* h, std::size_t count, const E& entry) noexcept {
  std::size_t i = 0;
  for (;;) {
    std::size_t child = 2 * i + 1;
    if (child >= count) break;
    if (child + 1 < count && h[child + 1].t_begin < h[child].t_begin) ++child;
    if (!(h[child].t_begin < entry.t_begin)) break;
    h[i] = h[child];
    i = child;
  }
  h[i] = entry;
}
}  // namespace

const char* toString(DetectionMode mode) noexcept {
  return mode == DetectionMode::kPaper ? "paper" : "accelerated";
}

const char* toString(SegmentTest test) noexcept {
  return test == SegmentTest::kExact ? "exact" : "end-sample";
}

CollisionDetector::CollisionDetector(const ScalarVolume& volume, const ToolModel& tool, double epsilon_m,
                                     std::size_t max_contacts, DetectionMode mode, double segment_fraction,
                                     SegmentTest segment_test)
    : volume_(&volume), tool_(&tool), mode_(mode), segment_test_(segment_test), feature_(volume.featureSize_m()) {
  if (!(segment_fraction > 0.0 && segment_fraction <= 1.0))
    throw std::invalid_argument("CollisionDetector: segment_fraction " + std::to_string(segment_fraction) +
                                " must be in (0, 1]");
  segment_length_m_ = feature_ * segment_fraction;
  if (tool.point_shell.empty()) throw std::invalid_argument("CollisionDetector: the point shell is empty");
  if (volume.empty()) throw std::invalid_argument("CollisionDetector: the volume is empty");
  epsilon_ = epsilon_m > 0.0 ? epsilon_m : 0.125 * feature_;  // f / 8: bench accuracy
  bisection_tolerance_ = epsilon_ / 8.0;
  if (!(epsilon_ < feature_) || !std::isfinite(epsilon_))
    throw std::invalid_argument("CollisionDetector: epsilon " + std::to_string(epsilon_) +
                                " m must be smaller than the feature size " + std::to_string(feature_) + " m");
  // A rotating point's arc leaves its chord by at most this much; the exact test lowers the
  // threshold by the Lipschitz bound times it (README, "Never through").
  if (segment_test_ == SegmentTest::kExact) max_sagitta_ = epsilon_ / 64.0;
  for (const auto& p : tool.point_shell.points_T_m())
    shell_radius_m_ = std::max(shell_radius_m_, (p - tool.mass.p_TCm_m).norm());
  const std::size_t n = tool.point_shell.size();
  pt_.assign(n, PointState{});
  search_.assign(n, PointSearch{});
  started_.assign(n, 0u);
  heap_.resize(n);
  embedded_.assign(n, 0);
  in_set_.assign(n, 0);
  contacts_.resize(std::max<std::size_t>(max_contacts, 1));
  if (mode_ == DetectionMode::kAccelerated) {
    order_.resize(n);
    for (std::size_t j = 0; j < n; ++j) order_[j] = static_cast<int>(j);
    nodes_.reserve(2 * n);
    buildShellTree(0, static_cast<int>(n), 0);
    stack_.resize(nodes_.size() + 1);
    node_near_.assign(nodes_.size(), 0);
    active_.resize(n);
    setLanesPartition(1);
  }
  candidate_.resize(n);
  setup_work_ = std::max<std::int64_t>(1, static_cast<std::int64_t>(n) / 5000);
  reduce_position_.resize(n + contacts_.size());
  reduce_distance_.resize(n + contacts_.size());
  reduce_chosen_.resize(n + contacts_.size());
  grid_per_m_ = volume.geometry().spacing_m.cwiseInverse();
  grid_from_W_ = grid_per_m_.asDiagonal() * volume.geometry().direction_W.transpose();
  edges_ = makeShellEdges(tool.point_shell);
  edge_reach_m_.assign(n, 0.0);
  edge_clearance_.assign(2 * n, EdgeClearance{});
  edge_slot_.assign(n, 0);
  for (std::size_t j = 0; j < n; ++j)
    for (int e = edges_.offsets[j]; e < edges_.offsets[j + 1]; ++e)
      edge_reach_m_[j] = std::max(edge_reach_m_[j], (tool.point_shell.points_T_m()[static_cast<std::size_t>(edges_.targets[e])] -
                                                     tool.point_shell.points_T_m()[j]).norm());
  node_edge_near_.assign(nodes_.size(), 0);
  // The certificates in tree order where there is a tree: a leaf's points read theirs together.
  edge_clearance_index_.resize(n);
  for (std::size_t j = 0; j < n; ++j) edge_clearance_index_[j] = static_cast<int>(j);
  if (!order_.empty())
    for (std::size_t i = 0; i < n; ++i) edge_clearance_index_[static_cast<std::size_t>(order_[i])] = static_cast<int>(i);
}

Eigen::Vector3d CollisionDetector::edgeEnd(WorkCounters& w, const Pose& X_WP, int i) const noexcept {
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

bool CollisionDetector::segmentCrosses(WorkCounters& w, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                                       double isovalue, double* excess_max) const noexcept {
  // Only whether it enters: a coarse bracket is enough.
  const SegmentEntry entry = volume_->firstEntryOnSegment(a, b, isovalue, 1.0, 0.5);
  w.cells += entry.cells;
  w.cells_walked += entry.cells_walked;
  if (excess_max != nullptr) *excess_max = entry.excess_max;
  return entry.hit;
}

void CollisionDetector::recordCrossingEdge(int j, int k, const Pose& X_WP) noexcept {
  edge_hit_ = {j, k, X_WP};
  if (listed_count_ < kListedEdges) {
    bool known = false;
    for (int i = 0; i < listed_count_; ++i) known |= listed_[i].first == j && listed_[i].second == k;
    if (!known) listed_[listed_count_++] = {j, k};
  }
}

double CollisionDetector::edgeClearance(const Eigen::Vector3d& a, const Eigen::Vector3d& b, double excess_max,
                                        double isovalue) const noexcept {
  // Only an edge wholly in the grid's box: outside it the field counts as empty, which no
  // Lipschitz bound carries across the box's faces.
  const auto& dims = volume_->geometry().dims;
  const Eigen::Vector3d upper(dims[0] - 1.0, dims[1] - 1.0, dims[2] - 1.0);
  if (!(a.minCoeff() >= 0.0 && b.minCoeff() >= 0.0 && (upper - a).minCoeff() >= 0.0 && (upper - b).minCoeff() >= 0.0))
    return -1.0;
  // Every point of the edge lies within half its length of an end. Each end's local Lipschitz
  // bound holds within one brick of the end's brick (MinMaxTree::setLipschitz), so for a move
  // of at most d with half the length plus d inside one brick, F rises by at most L d from its
  // largest value on the edge.
  const Eigen::Vector3d& spacing_m = volume_->geometry().spacing_m;
  const double length_m = (b - a).cwiseProduct(spacing_m).norm();
  const double reach_m = MinMaxTree::kBrickCells * spacing_m.minCoeff() - 0.5 * length_m;
  const double lipschitz = std::max(volume_->localLipschitzBound(a), volume_->localLipschitzBound(b));
  if (!(reach_m > 0.0) || !std::isfinite(lipschitz)) return -1.0;
  // The cubic's value at a rounded critical point: a relative tolerance on the values near here.
  const double tolerance = 1e-9 * (std::abs(isovalue) + lipschitz * spacing_m.maxCoeff()) + 1e-300;
  if (!(excess_max + tolerance < 0.0)) return -1.0;
  if (lipschitz <= 0.0) return reach_m;  // a constant field below the isovalue near the edge
  return std::min(reach_m, -(excess_max + tolerance) / lipschitz);
}

CollisionDetector::EdgeHold CollisionDetector::edgesStillClear(const Pose& X_WP, int j,
                                                               const Eigen::Vector3d& p_W) const noexcept {
  const auto i = static_cast<std::size_t>(edge_clearance_index_[static_cast<std::size_t>(j)]);
  // The newer first (edge_slot_ names the older, which the next certificate replaces): it is
  // the one that holds where either does, more often than not.
  const std::size_t newer = 2 * i + (edge_slot_[i] ^ 1u);
  for (const std::size_t slot : {newer, newer ^ 1u}) {
    const EdgeClearance& proven = edge_clearance_[slot];
    const bool by_distance = proven.clearance_m > 0.0, by_direction = proven.margin > 0.0;
    if (!by_distance && !by_direction) continue;  // nothing proven
    const Eigen::Vector3d moved_W = p_W - proven.p_W_m;
    const double moved_m = moved_W.norm();
    if (proven.arm_m == 0.0) {  // a ball about point j: any turn stays in it
      if (moved_m < proven.clearance_m) return EdgeHold::kBoxQuery;
      continue;
    }
    if (!by_direction && !(moved_m < proven.clearance_m)) continue;
    // Each point of j's edges lies within arm_m (edge_reach_m_[j] + epsilon) of point j
    // (edgeEnd()), so it has moved by point j's move plus at most |R - R'| arm_m since the
    // certificate, with |R - R'| = 2 sin(theta / 2) = 2 |vec(R'^-1 R)|.
    const double lever_m = 2.0 * (proven.R_WT.conjugate() * X_WP.R_AB).vec().norm() * proven.arm_m;
    if (moved_m + lever_m < proven.clearance_m) return EdgeHold::kWalk;
    if (!by_direction) continue;
    // The directional certificate: along grid axis a each point of j's edges has moved by d_a
    // within r_a = |row a of grid_from_W| lever of point j's own move. While that stays within
    // the certificate's reach, F rose on the straight path by at most sum_a max(step_lo_a d_a,
    // step_hi_a d_a), largest at an end of each axis' interval (the sum is convex in d).
    const Eigen::Vector3d d = grid_from_W_ * moved_W;
    double rise = 0.0;
    bool within = true;
    for (int a = 0; a < 3; ++a) {
      const double r = lever_m * grid_per_m_[a];
      const double lo = d[a] - r, hi = d[a] + r;
      within = within && -lo <= proven.reach_lo[a] && hi <= proven.reach_hi[a];
      const auto rise_along = [&](double x) { return x >= 0.0 ? proven.step_hi[a] * x : proven.step_lo[a] * x; };
      rise += std::max(rise_along(lo), rise_along(hi));
    }
    if (within && rise * (1.0 + 1e-9) < proven.margin) return EdgeHold::kWalk;
  }
  return EdgeHold::kNone;
}

void CollisionDetector::keepEdgeClearance(int j, const EdgeClearance& proven) noexcept {
  const auto i = static_cast<std::size_t>(j);
  const auto at = static_cast<std::size_t>(edge_clearance_index_[i]);
  edge_clearance_[2 * at + edge_slot_[at]] = proven;
  edge_slot_[at] ^= 1;
}

int CollisionDetector::edgeCrosses(WorkCounters& w, const Pose& X_WP, int j, const Eigen::Vector3d& p_W,
                                   double isovalue) noexcept {
  if (embedded_[j]) return -1;
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

bool CollisionDetector::listedEdgesCrossAt(const Pose& X_WP, double isovalue) noexcept {
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

void CollisionDetector::addEdgeContact(const Pose& X_WP, double isovalue) noexcept {
  if (edge_hit_.j < 0 || contact_count_ >= std::min(contact_cap_, contacts_.size())) return;
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
}

template <typename MayHold, typename Visit>
bool CollisionDetector::walkShellTree(int* stack, int root, MayHold&& may_hold, Visit&& visit) const noexcept {
  int top = 0;
  stack[top++] = root;
  while (top > 0) {
    const ShellNode& node = nodes_[stack[--top]];
    if (!may_hold(node)) continue;
    if (node.left >= 0) {
      stack[top++] = node.right;
      stack[top++] = node.left;
      continue;
    }
    for (int i = node.begin; i < node.end; ++i)
      if (visit(order_[i])) return true;
  }
  return false;
}

CollisionDetector::EdgeWalk CollisionDetector::edgeNodeWalk(WorkCounters& w, Lane* lane, int index, const Pose& X_WP,
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
        found_near = found_near || held == EdgeHold::kWalk;
        continue;
      }
      // The point's own edges, within its longest edge plus epsilon of it: one box query
      // instead of a walk per edge where the leaf is near the surface but this point is not.
      // Proven empty with a margin, the ball is a certificate too (EdgeClearance::arm_m = 0):
      // until point j has moved the margin, its edges stay in the ball however the tool turns.
      if (!ballMayBeInside(w, p_W, (edge_reach_m_[j] + epsilon_ + ballMargin_m()) * (1.0 + 1e-9) + 1e-12, isovalue)) {
        keepEdgeClearance(j, {p_W, X_WP.R_AB, ballMargin_m(), 0.0});
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

void CollisionDetector::edgeLaneJob(void* detector, int lane) noexcept {
  auto* self = static_cast<CollisionDetector*>(detector);
  self->runEdgeLane(self->lanes_[static_cast<std::size_t>(lane)]);
}

void CollisionDetector::runEdgeLane(Lane& lane) noexcept {
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

bool CollisionDetector::edgesCrossAt(const Pose& X_WP, double isovalue) noexcept {
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
    pool_->run(&CollisionDetector::edgeLaneJob, this, static_cast<int>(lanes_.size()));
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
    if (edgesStillClear(X_WP, j, p_W) != EdgeHold::kNone) continue;
    if (walked++ > 0 && overBudget()) return edge_cut_ = true;
    const int k = edgeCrosses(counters_, X_WP, j, p_W, isovalue);
    if (k >= 0) {
      recordCrossingEdge(j, k, X_WP);
      return true;
    }
  }
  return false;
}

int CollisionDetector::buildShellTree(int begin, int end, int depth) {
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

void CollisionDetector::ballGridBox(const Eigen::Vector3d& centre_W_m, double radius_m, Eigen::Vector3d& lo_ijk,
                                    Eigen::Vector3d& hi_ijk) const noexcept {
  const Eigen::Vector3d g = volume_->gridCoordinates(centre_W_m);
  // A W ball maps to an ellipsoid with half-axes radius / spacing along the grid axes (the
  // direction matrix is orthonormal); 1e-6 voxel covers the rounding of both paths.
  const Eigen::Vector3d half = (radius_m * grid_per_m_).array() + 1e-6;
  lo_ijk = g - half;
  hi_ijk = g + half;
}

bool CollisionDetector::ballMayBeInside(WorkCounters& k, const Eigen::Vector3d& center_W_m, double radius_m,
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
    const double own = volume_->voxelUpperBoundInBox(lo, hi, kVoxelQueryMax, &voxels);
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
                                                      hi + Eigen::Vector3d::Ones(), 8 * kVoxelQueryMax,
                                                      &voxels) > isovalue;
        k.voxels += voxels;
      }
    }
  }
  return may_be_inside;
}

bool CollisionDetector::runMayHit(WorkCounters& w, const RigidMotion& motion, int j, std::int64_t k,
                                  std::int64_t run, double isovalue) noexcept {
  // The run's points stay within half its path-length bound of its mid-time position.
  const std::int64_t total = pt_[j].segments;
  const double t0 = segmentBegin(j, k);
  const double t1 = k + run >= total ? 1.0 : static_cast<double>(k + run) * pt_[j].dt;
  const double radius = 0.5 * pt_[j].path * (t1 - t0) * (1.0 + 1e-9) + 1e-12;
  // The directional bound first: it is cheaper than the ball's tree query, and proves the runs
  // of a tool grazing a wall free where the ball, which holds the wall, cannot.
  if (runFreeAlongItsDirection(w, motion, j, t0, t1, isovalue)) return false;
  return ballMayBeInside(w, motion.pointAt(pt_[j].r0, 0.5 * (t0 + t1)), radius, isovalue, pt_[j].sagitta);
}

bool CollisionDetector::runFreeAlongItsDirection(WorkCounters& w, const RigidMotion& motion, int j, double t0,
                                                 double t1, double isovalue, const Eigen::Vector3d* ranges_lo,
                                                 const Eigen::Vector3d* ranges_hi, bool* within_a_voxel) const noexcept {
  // The run's arc lies within its sagitta delta = rho (angle (t1 - t0))^2 / 8 of its chord a -> b
  // at the same parameter (the interpolation error bound, as setupPath()), so in the box of the
  // chord dilated by delta per grid axis. There F's derivative per grid step along axis i is
  // within [lo_i, hi_i] (ScalarVolume::gridStepRange()), so at the arc's point of parameter u
  // F <= F(a) + u sum_i max(lo_i D_i, hi_i D_i) + sum_i delta_i max(|lo_i|, |hi_i|), D = b - a:
  // below the isovalue at both ends of u, below it on the whole run. A tool sliding along a
  // wall, or leaving it, is proven free here where the ball about its run holds the wall.
  w.samples += 2;
  const Eigen::Vector3d p0_W = motion.pointAt(pt_[j].r0, t0);
  const Eigen::Vector3d a = volume_->gridCoordinates(p0_W);
  const Eigen::Vector3d b = volume_->gridCoordinates(motion.pointAt(pt_[j].r0, t1));
  const double turn = motion.angle_rad() * (t1 - t0);
  const Eigen::Vector3d bulge =
      (motion.radiusAboutAxis(pt_[j].r0) * turn * turn / 8.0 * (1.0 + 1e-9) + 1e-12) * grid_per_m_;
  Eigen::Vector3d lo, hi;
  if (ranges_lo) {
    lo = *ranges_lo;
    hi = *ranges_hi;
  } else if (!volume_->gridStepRange(a.cwiseMin(b) - bulge, a.cwiseMax(b) + bulge, lo, hi)) {
    return false;
  }
  const Eigen::Vector3d d = b - a;
  double rise = 0.0, off_chord = 0.0, size = 0.0, voxel_rise = 0.0;
  for (int i = 0; i < 3; ++i) {
    const double steepest = std::max(std::abs(lo[i]), std::abs(hi[i]));
    rise += std::max(lo[i] * d[i], hi[i] * d[i]);
    off_chord += bulge[i] * steepest;
    size += steepest * std::abs(d[i]);
    voxel_rise += steepest;
  }
  const double f0 = volume_->sample(p0_W);
  // A hint, not a proof: F could reach the isovalue within a grid step along each axis.
  if (within_a_voxel) *within_a_voxel = f0 + voxel_rise >= isovalue;
  const double tolerance = 1e-9 * (std::abs(isovalue) + std::abs(f0) + size + off_chord) + 1e-300;
  return f0 + std::max(0.0, rise) + off_chord + tolerance < isovalue;
}

bool CollisionDetector::inside(const Eigen::Vector3d& p_W, double isovalue) noexcept {
  ++counters_.samples;
  return volume_->isInside(p_W, isovalue);
}

void CollisionDetector::measureContact(Contact& c, double isovalue, const Eigen::Quaterniond& R_WT) noexcept {
  counters_.samples += 6;
  const Eigen::Vector3d g = c.crossing_normal ? volume_->interpolantGradient(c.p_W_m) : volume_->gradient(c.p_W_m);
  double norm = g.norm();
  if (norm > 0.0 && std::isfinite(norm)) {
    c.n_W = -g / norm;
    // Between two points: the part perpendicular to the edge (Contact::edge_T), unless the
    // gradient runs almost along the edge (then the edge is entering the wall head-on).
    if (c.point_index < 0 && c.edge_T.squaredNorm() > 0.0) {
      const Eigen::Vector3d e_W = R_WT * c.edge_T;
      const Eigen::Vector3d n_perp = c.n_W - c.n_W.dot(e_W) * e_W;
      if (n_perp.norm() > 0.25) c.n_W = n_perp.normalized();
    }
  }  // else keep the previous/fallback
  // Clearance measured with the inside test itself, along -n, up to epsilon: a linearised
  // (s - F) / |grad F| overestimates it where the central difference smooths a sharp edge.
  const Eigen::Vector3d& n = c.n_W;
  if (!inside(c.p_W_m - epsilon_ * n, isovalue)) {
    c.clearance_m = epsilon_;
    return;
  }
  double lo = 0.0, hi = epsilon_;  // outside at lo, inside at hi
  for (int i = 0; i < 4; ++i) {
    const double mid = 0.5 * (lo + hi);
    if (inside(c.p_W_m - mid * n, isovalue)) hi = mid; else lo = mid;
  }
  c.clearance_m = lo;
}

void CollisionDetector::appendContact(int point, const Eigen::Vector3d& p_W, const Eigen::Vector3d& fallback_n_W,
                                      double isovalue) noexcept {
  if (in_set_[point] || contact_count_ >= contacts_.size()) return;
  Contact& c = contacts_[contact_count_++];
  c.point_index = point;
  c.p_T_m = tool_->point_shell.points_T_m()[point];
  c.p_W_m = p_W;
  c.n_W = fallback_n_W;
  c.crossing_normal = false;
  c.edge_T.setZero();
  measureContact(c, isovalue, Eigen::Quaterniond::Identity());
  in_set_[point] = 1;
}

void CollisionDetector::clearContacts() noexcept {
  for (std::size_t i = 0; i < contact_count_; ++i)
    if (contacts_[i].point_index >= 0) in_set_[contacts_[i].point_index] = 0;
  contact_count_ = 0;
}

SweepResult CollisionDetector::sweep(const RigidMotion& motion, double isovalue) noexcept {
  if (++chord_stamp_ == 0) {  // wrapped: forget every cached chord end
    for (PointSearch& q : search_) q.chord_end_stamp = 0u;
    chord_stamp_ = 1;
  }
  // The largest chord sagitta of any point this sweep (for the point-shell tree's node tests):
  // every point's sagitta is <= min(max_sagitta_, R angle^2 / 8), R the shell's radius.
  const double angle = motion.angle_rad();
  sweep_sagitta_ = max_sagitta_ > 0.0 && angle > 0.0
      ? std::min(max_sagitta_, shell_radius_m_ * angle * angle / 8.0) * (1.0 + 1e-9)
      : 0.0;
  return stopClear(mode_ == DetectionMode::kAccelerated ? sweepAccelerated(motion, isovalue) : sweepPaper(motion, isovalue));
}

void CollisionDetector::setupPath(WorkCounters& k, const RigidMotion& motion, int j) noexcept {
  k.other += setup_work_;  // a point's path set-up: its state is touched (see setup_work_)
  pt_[j].r0 = motion.radial_W(tool_->point_shell.points_T_m()[j]);
  const double angle = motion.angle_rad();
  const double rho = motion.radiusAboutAxis(pt_[j].r0);
  pt_[j].path = motion.speed_m() + angle * rho;  // = pathLengthBound(r0), rho computed once
  if (embedded_[j] || !(pt_[j].path > 0.0)) return;
  // ceil(s / f) equal time segments, none longer than the feature size (section 2.3). At most
  // 2^30 (a path of tens of kilometres at the finest feature size, or not finite: the input
  // gate stops a device far sooner), so that the count converts to an integer; dt and the
  // chords' sagitta below are those of the count used.
  constexpr double kMaxSegments = 0x1p30;
  double segments = std::min(kMaxSegments, std::max(1.0, std::ceil(pt_[j].path / segment_length_m_)));
  pt_[j].sagitta = 0.0;
  if (max_sagitta_ > 0.0 && rho > 0.0) {
    // Chords of the rotation: sagitta delta = rho (angle / segments)^2 / 8 <= max_sagitta_. At
    // the same time the arc is within 4 delta u (1 - u) of its chord (the interpolation error
    // bound with |p''| = rho omega^2), so a chord whose F stays <= s - 4 L delta u (1 - u)
    // keeps the arc at F <= s (L = the local Lipschitz bound, ScalarVolume::localLipschitzBound()).
    const double sagitta_of_one = rho * angle * angle / 8.0;  // one chord over the whole arc
    if (sagitta_of_one > max_sagitta_ * segments * segments)
      segments = std::min(kMaxSegments, std::ceil(angle * std::sqrt(rho / (8.0 * max_sagitta_))));
    pt_[j].sagitta = sagitta_of_one / (segments * segments) * (1.0 + 1e-9);
  }
  pt_[j].dt = 1.0 / segments;
  if (mode_ == DetectionMode::kAccelerated) pt_[j].segments = static_cast<std::int32_t>(segments);
}

void CollisionDetector::startPoint(WorkCounters& k, const RigidMotion& motion, int j) noexcept {
  setupPath(k, motion, j);
  pt_[j].clear_until = -1.0;
}

void CollisionDetector::startSearch(int j) noexcept {
  search_[j].clear_segments = 0;
  search_[j].backoff = 0;
}

double CollisionDetector::stepSegment(WorkCounters& k, const RigidMotion& motion, int j, std::int64_t segment,
                                      double t_begin, double isovalue, double t_limit, SweepResult& result) noexcept {
  const std::int64_t next = segment + 1;
  const double t_end = (static_cast<double>(next) * pt_[j].dt >= 1.0 - 1e-12) ? 1.0 : static_cast<double>(next) * pt_[j].dt;
  double lo = t_begin, hi = t_end;
  if (segment_test_ == SegmentTest::kExact) {
    // The chord between the arc's points at t_begin and t_end, walked cell by cell; the
    // threshold is lowered by the arc's margin in the middle of the chord, 4 m u (1 - u), none
    // at its ends (m = 0 without rotation).
    const double span = t_end - t_begin;
    // The chord's start is the previous segment's end when the point's segments are taken in
    // turn (the same double either way: pointAt at the same t).
    Eigen::Vector3d a;
    if (search_[j].chord_end_t == t_begin && search_[j].chord_end_stamp == chord_stamp_) {
      a = search_[j].chord_end_ijk;
    } else {
      ++k.samples;
      a = volume_->gridCoordinates(motion.pointAt(pt_[j].r0, t_begin));
    }
    ++k.samples;
    const Eigen::Vector3d b = volume_->gridCoordinates(motion.pointAt(pt_[j].r0, t_end));
    search_[j].chord_end_ijk = b;
    search_[j].chord_end_t = t_end;
    search_[j].chord_end_stamp = chord_stamp_;
    const double u_limit = t_limit >= t_end ? 1.0 : (t_limit - t_begin) / span;
    // The arc's reach beyond its chord (the sagitta), per grid axis, for the grid's border.
    const Eigen::Vector3d reach = pt_[j].sagitta * grid_per_m_;
    const SegmentEntry entry = volume_->firstEntryOnSegment(a, b, isovalue, u_limit,
                                                            bisection_tolerance_ / (pt_[j].path * span), reach, pt_[j].sagitta);
    k.cells += entry.cells;
    k.cells_walked += entry.cells_walked;
    if (entry.cells > 0) pt_[j].near_surface = 1;
    if (!entry.hit) return t_end;
    lo = entry.u_outside >= 1.0 ? t_end : t_begin + entry.u_outside * span;
    hi = entry.u_inside >= 1.0 ? t_end : t_begin + entry.u_inside * span;
    // A rotating point's hit may be the bubble's alone (a contact resting on the surface and
    // turning along it: its chord dips under the arc by the sagitta). When the arc itself is
    // inside at the bracket's inside end, the hit is real (the arc is free up to its outside
    // end): one sample. Otherwise confirm it on finer chords over [t_begin, hi]: none of them
    // hitting proves the arc free there.
    if (pt_[j].sagitta > 0.0 && (++k.samples, !volume_->isInside(motion.pointAt(pt_[j].r0, hi), isovalue))) {
      if (!refineArcEntry(k, motion, j, t_begin, t_end, pt_[j].sagitta, isovalue, std::min(t_limit, t_end), kArcRefinements,
                          lo, hi))
        return t_end;
    }
  } else {
    const auto inside_at = [&](double t) {
      ++k.samples;
      return volume_->isInside(motion.pointAt(pt_[j].r0, t), isovalue);
    };
    if (!inside_at(t_end)) return t_end;
    while (pt_[j].path * (hi - lo) >= bisection_tolerance_) {
      const double mid = 0.5 * (lo + hi);
      if (inside_at(mid)) hi = mid; else lo = mid;
    }
  }
  // Of tied points, the lower index among those popped (the paper path: the first popped).
  if (lo < result.t || (lo == result.t && j < result.hit_point)) {
    result.t = lo;
    result.t_inside = hi;
    result.hit_point = j;
  }
  return -1.0;
}

bool CollisionDetector::refineArcEntry(WorkCounters& w, const RigidMotion& motion, int j, double t0, double t1,
                                       double sagitta_m, double isovalue, double t_limit, int depth, double& lo,
                                       double& hi) noexcept {
  // Four chords of a quarter of the time each: a sixteenth of the sagitta (delta ~ angle^2).
  const double step = 0.25 * (t1 - t0);
  const double sub_sagitta = sagitta_m / 16.0;
  for (int k = 0; k < 4; ++k) {
    const double a_t = t0 + k * step, b_t = k == 3 ? t1 : t0 + (k + 1) * step;
    if (a_t > t_limit) return false;
    w.samples += 2;
    const Eigen::Vector3d a = volume_->gridCoordinates(motion.pointAt(pt_[j].r0, a_t));
    const Eigen::Vector3d b = volume_->gridCoordinates(motion.pointAt(pt_[j].r0, b_t));
    const double span = b_t - a_t;
    const double u_limit = t_limit >= b_t ? 1.0 : (t_limit - a_t) / span;
    const SegmentEntry entry = volume_->firstEntryOnSegment(a, b, isovalue, u_limit, bisection_tolerance_ / (pt_[j].path * span),
                                                            sub_sagitta * grid_per_m_, sub_sagitta);
    w.cells += entry.cells;
    w.cells_walked += entry.cells_walked;
    if (!entry.hit) continue;
    if (depth <= 1) {
      lo = entry.u_outside >= 1.0 ? b_t : a_t + entry.u_outside * span;
      hi = entry.u_inside >= 1.0 ? b_t : a_t + entry.u_inside * span;
      return true;
    }
    if (refineArcEntry(w, motion, j, a_t, b_t, sub_sagitta, isovalue, t_limit, depth - 1, lo, hi)) return true;
  }
  return false;
}

std::size_t CollisionDetector::collectActive(Lane& lane, const RigidMotion& motion, double t_max, double isovalue,
                                             bool queue, bool resume) noexcept {
  WorkCounters& k = lane.counters;
  const double angle = motion.omega_W_rad().norm();
  const Eigen::Matrix3d R_mid = angle > 0.0 && t_max > 0.0
      ? Eigen::AngleAxisd(0.5 * t_max * angle, motion.omega_W_rad() / angle).toRotationMatrix()
      : Eigen::Matrix3d::Identity();
  const Eigen::Vector3d c_mid = motion.c0_W_m() + (0.5 * t_max) * motion.v_W_m();
  // Point-shell tree, top down: a node whose points' arcs over [0, t_max], plus epsilon of
  // further travel (addContactsAt's look-ahead), lie in bricks that cannot hold an inside point
  // is skipped. A point at r = r_c + d (|d| <= node radius) stays within t_max path(r_c) / 2 +
  // radius of the node centre's position at t_max / 2.
  // The ball in W about the node centre's position at t_max / 2 that holds all its points' arcs.
  const auto nodeBall = [&](const ShellNode& node, Eigen::Vector3d& centre_W) {
    const Eigen::Vector3d r_c = motion.radial_W(node.center_T_m);
    centre_W = c_mid + R_mid * r_c;
    return (0.5 * t_max * motion.pathLengthBound(r_c) + node.radius_m + epsilon_) * (1.0 + 1e-9) + 1e-12;
  };
  std::size_t count = 0;
  int top = 0;
  int* const stack = lane.stack.data();
  QueueEntry* const heap = lane.heap.data() + lane.queued;
  if (resume) {
    count = lane.walk_count;
    top = lane.walk_top;
  } else {
    lane.active_count = 0;
    lane.walk_root = 0;
    lane.walk_logged = 0;
  }
  lane.walk_stopped = false;
  // The lane's roots one after the other (the order of pushing them all at once), each one's
  // work charged to it for the next deal (rebalanceLanes()).
  std::int64_t mark = k.total();
  for (;;) {
    if (top == 0) {
      if (balanced_lanes_ && lane.walk_root > 0) chargeRoot(lane, lane.root_ranks[lane.walk_root - 1], mark);
      if (lane.walk_root == lane.roots.size()) {
        markNearNodes(lane);
        break;
      }
      stack[top++] = lane.roots[lane.walk_root++];
    }
    if (overBudget(lane)) {
      if (balanced_lanes_) chargeRoot(lane, lane.root_ranks[lane.walk_root - 1], mark);
      lane.walk_stopped = true;
      lane.walk_top = top;
      lane.walk_count = count;
      return count;
    }
    const int node_index = stack[--top];
    const ShellNode& node = nodes_[node_index];
    // A node near the surface in the last walk is let through unasked (node_near_; a leaf only
    // in a walk that tests its points one by one).
    if (!node_near_[node_index] || (node.left < 0 && !queue)) {
      Eigen::Vector3d centre_W;
      const double radius = nodeBall(node, centre_W);
      // Culled points are not touched at all (addContactsAt visits only the active ones).
      if (!ballMayBeInside(k, centre_W, radius, isovalue, sweep_sagitta_)) {
        lane.walk_log[lane.walk_logged++] = ~node_index;
        continue;
      }
    }
    const std::size_t logged = lane.walk_logged++;
    lane.walk_log[logged] = node_index;
    if (node.left >= 0) {
      stack[top++] = node.right;
      stack[top++] = node.left;
      continue;
    }
    // Tested one by one, a leaf is near when one of its points is not culled by its own test.
    if (queue) lane.walk_log[logged] = ~node_index;
    // F's steps per grid axis over the leaf's ball, for its points' direction tests: one read
    // of the step bricks per leaf instead of one per point. The ball holds every point's arc
    // over [0, t_max], and so its chord and the straight lines from the chord to the arc that
    // runFreeAlongItsDirection() bounds F along (the ball is convex). 0: not read yet; -1: the
    // ball leaves the grid (each point then reads its own).
    int leaf_ranges = 0;
    Eigen::Vector3d leaf_lo, leaf_hi;
    for (int i = node.begin; i < node.end; ++i) {
      const int j = order_[i];
      lane.active[lane.active_count++] = j;
      if (started_[j] == sweep_stamp_) {  // a contact point: started (and queued) already
        lane.walk_log[logged] = node_index;
        continue;
      }
      startPoint(k, motion, j);
      if (!queue || embedded_[j] || !(pt_[j].path > 0.0)) continue;
      // A point whose walk met the surface last sweep (near_surface) is walked at once: its
      // first segment directly, then run tests. Only a cull is skipped, so the first time of
      // contact is the same; this sweep's walks decide the flag again.
      const bool near = pt_[j].near_surface != 0;
      pt_[j].near_surface = 0;
      if (near) {
        // Unless its whole path is proven free by F at its start and the most F can rise along
        // it: a point gliding along a wall or leaving it is neither walked nor queued.
        if (leaf_ranges == 0) {
          Eigen::Vector3d centre_W, box_lo, box_hi;
          const double radius = nodeBall(node, centre_W);
          ballGridBox(centre_W, radius, box_lo, box_hi);
          leaf_ranges = volume_->gridStepRange(box_lo, box_hi, leaf_lo, leaf_hi) ? 1 : -1;
        }
        bool within_a_voxel = false;
        if (runFreeAlongItsDirection(k, motion, j, 0.0, t_max, isovalue, leaf_ranges > 0 ? &leaf_lo : nullptr,
                                     leaf_ranges > 0 ? &leaf_hi : nullptr, &within_a_voxel)) {
          pt_[j].clear_until = t_max;
          // Still within about a voxel of the surface: the same test next sweep, where its
          // ball would only say "may hit" and a walk follow; farther, the ball culls it.
          pt_[j].near_surface = within_a_voxel ? 1 : 0;
          if (within_a_voxel) lane.walk_log[logged] = node_index;
          continue;
        }
        lane.walk_log[logged] = node_index;
        startSearch(j);
        heap[count++] = {0.0, j, 0, pt_[j].segments == 1 ? 0 : -1};
        continue;
      }
      // The path over [0, t_max] first: its own ball culls the point at once (on the Engine
      // wrench 62 % of the points with several segments, which otherwise cost about two run
      // tests and two heap steps each).
      const double radius_j = 0.5 * t_max * pt_[j].path * (1.0 + 1e-9) + 1e-12;
      if (!ballMayBeInside(k, c_mid + R_mid * pt_[j].r0, radius_j, isovalue, pt_[j].sagitta)) {
        pt_[j].clear_until = t_max;
        continue;
      }
      // One segment: sample it; several: resolved lazily, in time order.
      lane.walk_log[logged] = node_index;
      startSearch(j);
      heap[count++] = {0.0, j, 0, pt_[j].segments == 1 ? 0 : 1};
    }
  }
  return count;
}

void CollisionDetector::markNearNodes(Lane& lane) noexcept {
  // Backwards through the walk's preorder: a node's children (both logged after it whenever it
  // was passed on) are marked before it.
  for (std::size_t e = lane.walk_logged; e-- > 0;) {
    const int logged = lane.walk_log[e];
    if (logged < 0) {
      node_near_[static_cast<std::size_t>(~logged)] = 0;
      continue;
    }
    const ShellNode& node = nodes_[static_cast<std::size_t>(logged)];
    node_near_[static_cast<std::size_t>(logged)] =
        node.left < 0 ? 1 : static_cast<std::uint8_t>(node_near_[node.left] | node_near_[node.right]);
  }
  lane.walk_logged = 0;
}

void CollisionDetector::startLaneWork(Lane& lane) const noexcept {
  lane.base_work = budgetWork();
  lane.counters = {};
  lane.clock = clock_;
}

void CollisionDetector::setLanes(int lanes) {
  if (lanes < 1 || lanes > WorkerPool::kMaxLanes)
    throw std::invalid_argument("CollisionDetector: " + std::to_string(lanes) + " lanes, must be in [1, " +
                                std::to_string(WorkerPool::kMaxLanes) + "]");
  if (mode_ != DetectionMode::kAccelerated) return;
  pending_.active = false;  // a sweep in progress was dealt to the old lanes
  pool_.reset();
  setLanesPartition(lanes);
  if (lanes_.size() > 1) pool_ = WorkerPool::shared(static_cast<int>(lanes_.size()));
}

void CollisionDetector::setLanesPartition(int lanes) {
  // The tree's upper nodes, split until there are kRootsPerLane per lane (or nodes of at most
  // kMinRootPoints points): dealt round robin in tree order for the first sweep (then by their
  // work, rebalanceLanes()), so that the part of the tool near a surface (a spatial cluster of
  // nodes) is shared by the lanes instead of falling to one. The
  // work of a tool touching with a small part of itself (a drill's burr) lies in a few nodes of
  // the tree: at 8 roots per lane the 20,000-point drill on the CT's bone gained nothing from a
  // second lane (0.99x), at 64 it ran 1.5x faster. Nodes are not split below kMinRootPoints, so
  // a small tool keeps the culling of its upper nodes (roots that are single leaves cost a box
  // query each per tick).
  constexpr std::size_t kRootsPerLane = 64;
  constexpr int kMinRootPoints = 32;
  std::vector<int> frontier{0};
  const std::size_t wanted = static_cast<std::size_t>(lanes) * kRootsPerLane;
  while (lanes > 1 && frontier.size() < wanted) {
    std::vector<int> next;
    bool split = false;
    for (const int node : frontier) {
      if (nodes_[node].left >= 0 && nodes_[node].end - nodes_[node].begin > kMinRootPoints) {
        next.push_back(nodes_[node].left);
        next.push_back(nodes_[node].right);
        split = true;
      } else {
        next.push_back(node);
      }
    }
    frontier.swap(next);
    if (!split) break;
  }
  const int used = static_cast<int>(std::min<std::size_t>(static_cast<std::size_t>(lanes), frontier.size()));
  const std::size_t n = tool_->point_shell.size();
  balanced_lanes_ = used > 1 && used <= kMaxBalancedLanes;
  lanes_.assign(static_cast<std::size_t>(used), Lane{});
  rank_of_point_.assign(n, 0);
  root_lane_.assign(frontier.size(), 0);
  std::vector<std::size_t> points(static_cast<std::size_t>(used), 0);
  for (Lane& l : lanes_) {
    l.roots.reserve(frontier.size());  // a rebalance never allocates
    l.root_ranks.reserve(frontier.size());
    if (balanced_lanes_) l.root_work.assign(frontier.size(), 0);
  }
  for (std::size_t i = 0; i < frontier.size(); ++i) {
    const int lane = static_cast<int>(i % static_cast<std::size_t>(used));
    const ShellNode& node = nodes_[frontier[i]];
    lanes_[lane].roots.push_back(frontier[i]);
    lanes_[lane].root_ranks.push_back(static_cast<int>(i));
    root_lane_[i] = lane;
    points[lane] += static_cast<std::size_t>(node.end - node.begin);
    for (int p = node.begin; p < node.end; ++p) rank_of_point_[order_[p]] = static_cast<int>(i);
  }
  for (int lane = 0; lane < used; ++lane) {
    Lane& l = lanes_[lane];
    const std::size_t room = balanced_lanes_ ? n : points[lane];  // balanced: any share fits
    l.heap.resize(std::max<std::size_t>(room, 1));
    l.active.resize(std::max<std::size_t>(room, 1));
    l.stack.resize(nodes_.size() + 1);
    l.walk_log.resize(nodes_.size() + 1);
    l.walk_logged = 0;
  }
  frontier_ = std::move(frontier);
}

void CollisionDetector::rebalanceLanes() noexcept {
  // The first deal is round robin (setLanesPartition()); from then on the nodes, in the tree's
  // order, each go to the lane with the least work so far, weighed by their work last time
  // (every node at least 1, so unworked ones spread too). Neighbouring heavy nodes (a drill's
  // burr) so go to different lanes, as round robin would deal them, and light ones fill the rest.
  const std::size_t roots = frontier_.size();
  bool measured = false;
  for (std::size_t r = 0; r < roots && !measured; ++r)
    measured = lanes_[static_cast<std::size_t>(root_lane_[r])].root_work[r] > 0;
  if (!measured) return;  // no lane has worked since the last deal (a sweep ended at its contacts)
  std::array<std::int64_t, kMaxBalancedLanes> load{};
  const int lanes = static_cast<int>(lanes_.size());
  for (Lane& lane : lanes_) {
    lane.roots.clear();  // within their reserved capacity from here on
    lane.root_ranks.clear();
  }
  for (std::size_t r = 0; r < roots; ++r) {
    // The work charged to node r since the last deal, by the lane that held it (read and
    // cleared before the node changes lanes below).
    std::int64_t& work = lanes_[static_cast<std::size_t>(root_lane_[r])].root_work[r];
    const std::int64_t weight = work + 1;
    work = 0;
    int lane = 0;
    for (int l = 1; l < lanes; ++l)
      if (load[static_cast<std::size_t>(l)] < load[static_cast<std::size_t>(lane)]) lane = l;
    load[static_cast<std::size_t>(lane)] += weight;
    root_lane_[r] = lane;
    lanes_[static_cast<std::size_t>(lane)].roots.push_back(frontier_[r]);
    lanes_[static_cast<std::size_t>(lane)].root_ranks.push_back(static_cast<int>(r));
  }
}

SweepResult CollisionDetector::sweepAccelerated(const RigidMotion& motion, double isovalue) noexcept {
  pending_.active = false;
  active_complete_ = true;
  if (motion.isStill()) return {};
  prepareTreeStop(isovalue);
  if (++sweep_stamp_ == 0) {  // wrapped: forget every old stamp
    std::fill(started_.begin(), started_.end(), 0u);
    sweep_stamp_ = 1;
  }
  if (balanced_lanes_) rebalanceLanes();
  for (Lane& lane : lanes_) {
    lane.queued = 0;
    lane.active_count = 0;
  }
  pending_.motion = motion;
  pending_.isovalue = isovalue;
  pending_.phase = 0;
  pending_.contact_index = 0;
  pending_.result = SweepResult{};
  return runAccelerated();
}

SweepResult CollisionDetector::resumeSweep() noexcept {
  if (!pending_.active) return {};
  if (++chord_stamp_ == 0) {  // a new tick: the cached chord ends are recomputed (same values)
    for (PointSearch& q : search_) q.chord_end_stamp = 0u;
    chord_stamp_ = 1;
  }
  return stopClear(runAccelerated());
}

SweepResult CollisionDetector::stopClear(SweepResult result) const noexcept {
  // The bisection's outside end may lie a rounding error from the surface; a contact that then
  // turns along the surface (a probe spun on a ball) has chords that dip under it by less than
  // any sagitta can be made, and would be held for good. Stopping the hit point a further
  // epsilon / 128 of its own travel earlier (proven free: it is before the first hit) leaves it
  // a clearance that the arc refinement resolves (its finest sagitta is epsilon / 262,144).
  if (result.hit_point < 0 || result.budget_cut || !(result.t > 0.0)) return result;
  const double path = pt_[static_cast<std::size_t>(result.hit_point)].path;
  if (path > 0.0) result.t = std::max(0.0, result.t - kStopClearanceFraction * epsilon_ / path);
  return result;
}

void CollisionDetector::laneJob(void* detector, int lane) noexcept {
  auto* self = static_cast<CollisionDetector*>(detector);
  Lane& l = self->lanes_[static_cast<std::size_t>(lane)];
  if (l.phase == 1 || l.phase == 2) self->runLane(l);
}

SweepResult CollisionDetector::runAccelerated() noexcept {
  PendingSweep& st = pending_;
  const RigidMotion& motion = st.motion;
  const double isovalue = st.isovalue;
  SweepResult& result = st.result;
  st.active = false;
  // The contact points first: they are the likely first hits (a proxy resting or pushed
  // against the surface is blocked by one of them, often at t = 0). Their first segment is
  // taken before any other point's, which is one of the orders the queue may pop segments
  // starting at t = 0 in. A hit here bounds the search: the tree and the other points are then
  // only tested over [0, t]; a hit at t = 0 ends the sweep at once (addContactsAt then
  // collects the points near the proxy itself).
  // Budget cut before the lanes: nothing is proven for the points not yet looked at; the
  // sweep can be resumed where it stopped.
  const auto cutAtStart = [&] {
    st.active = true;
    active_complete_ = false;
    SweepResult cut;
    cut.t = cut.t_inside = 0.0;
    cut.budget_cut = true;
    return cut;
  };
  if (st.phase == 0) {
    for (; st.contact_index < contact_count_; ++st.contact_index) {
      if (overBudget()) return cutAtStart();
      const int j = contacts_[st.contact_index].point_index;
      if (j < 0 || embedded_[j]) continue;  // an edge contact has no path of its own
      startPoint(counters_, motion, j);
      if (!(pt_[j].path > 0.0)) continue;
      started_[j] = sweep_stamp_;
      startSearch(j);
      const double t_end = stepSegment(counters_, motion, j, 0, 0.0, isovalue, result.t, result);
      // Outside at the end of its first segment: a run test next (in the lane that holds it).
      if (t_end >= 0.0 && t_end < 1.0) {
        Lane& lane = lanes_[static_cast<std::size_t>(root_lane_[static_cast<std::size_t>(rank_of_point_[j])])];
        lane.heap[lane.queued++] = {t_end, j, 1, 1};
      }
      if (result.t == 0.0) break;  // nothing can come earlier
    }
    if (result.t == 0.0) {
      active_complete_ = false;
      return result;
    }
    st.phase = 1;
    st.walk_t = result.t;
    for (Lane& lane : lanes_) {
      lane.phase = 1;
      lane.walk_top = -1;  // not started
      lane.count = 0;
      lane.result = SweepResult{};
    }
  }
  // The lanes: each walks its share of the point-shell tree, then searches its points in time
  // order, all bounded by the earliest hit any has found.
  bound_->store(result.t, std::memory_order_relaxed);
  for (Lane& lane : lanes_) {
    startLaneWork(lane);
    lane.cut = false;
    if (lane.phase == 3 && lane.result.t < bound_->load(std::memory_order_relaxed))
      bound_->store(lane.result.t, std::memory_order_relaxed);
  }
  if (pool_) {
    pool_->run(&CollisionDetector::laneJob, this, static_cast<int>(lanes_.size()));
  } else {
    for (Lane& lane : lanes_)
      if (lane.phase == 1 || lane.phase == 2) runLane(lane);
  }
  joinLaneWork();
  SweepResult best = result;
  double cut_t = 2.0;
  bool walked = true;
  for (const Lane& lane : lanes_) {
    if (lane.phase == 1) walked = false;
    if (lane.cut) cut_t = std::min(cut_t, lane.cut_t);
    const SweepResult& r = lane.result;
    if (r.hit_point >= 0 && (r.t < best.t || (r.t == best.t && (best.hit_point < 0 || r.hit_point < best.hit_point))))
      best = r;
  }
  if (!(best.t <= cut_t)) {
    // A lane was stopped before every path up to the first hit was proven free: proven free up
    // to the earliest place a lane stopped (0 while a lane still walks the tree).
    st.active = true;
    active_complete_ = walked;
    SweepResult cut;
    cut.t = cut.t_inside = walked ? std::min(cut_t, best.t) : 0.0;
    cut.budget_cut = true;
    return cut;
  }
  active_complete_ = true;
  return best;
}

void CollisionDetector::joinLaneWork() noexcept {
  // The work adds up; the budget counts the busiest lane (they ran side by side).
  std::int64_t busiest = 0, sum = 0;
  for (const Lane& lane : lanes_) {
    const std::int64_t w = lane.counters.total();
    counters_ += lane.counters;
    sum += w;
    busiest = std::max(busiest, w);
    if (lane.clock.late) deadline_hit_ = true;
  }
  parallel_credit_ += sum - busiest;
}

void CollisionDetector::runLane(Lane& lane) noexcept {
  PendingSweep& st = pending_;
  const RigidMotion& motion = st.motion;
  const double isovalue = st.isovalue;
  WorkCounters& k = lane.counters;
  SweepResult& result = lane.result;
  if (lane.phase == 1) {
    const bool resume = lane.walk_top >= 0;
    lane.count = lane.queued + collectActive(lane, motion, st.walk_t, isovalue, true, resume);
    if (lane.walk_stopped) {
      lane.cut = true;
      lane.cut_t = 0.0;
      return;
    }
    std::make_heap(lane.heap.begin(), lane.heap.begin() + static_cast<std::ptrdiff_t>(lane.count), Later{});
    lane.phase = 2;
    lane.pop_pending = false;
  }
  // The paper's time-ordered search over the segments that remain; the samples and the
  // bisection are the paper's, so the first time of contact is the same double.
  // Entries with run <= 0 are single segments sampled as the paper does (0: after a run test,
  // -1: a direct step). Runs of segments are resolved lazily, in time order: a run proven empty is skipped and the
  // next one doubles (conservative advancement); a run that may hit is halved down to one
  // segment, whose end is then sampled as the paper does, and after a sample that stays
  // outside the next segment is sampled directly once more before testing resumes.
  // Each step replaces the minimum by at most one successor (replaceTop: one sift).
  // The minimum stays at the root while it is processed; push() (at most once per step) puts
  // its successor there, else it is popped at the top of the next step.
  // With several lanes the search stops at the earliest hit of any lane (bound_).
  QueueEntry* const heap = lane.heap.data();
  std::size_t& count = lane.count;
  bool& pop_pending = lane.pop_pending;
  std::atomic<double>& bound = *bound_;
  const auto push = [&](const QueueEntry& entry) {
    replaceTop(heap, count, entry);
    pop_pending = false;
  };
  // Each step's work is charged to the upper node holding its point (rebalanceLanes()).
  std::int64_t mark = k.total();
  int stepped = -1;
  const auto charge = [&] {
    if (balanced_lanes_ && stepped >= 0) chargeRoot(lane, rank_of_point_[static_cast<std::size_t>(stepped)], mark);
  };
  for (;;) {
    charge();
    if (pop_pending) {
      pop_pending = false;
      if (--count > 0) replaceTop(heap, count, heap[count]);
    }
    const double limit = std::min(result.t, bound.load(std::memory_order_relaxed));
    if (!(count > 0 && heap[0].t_begin < limit)) break;
    if (overBudget(lane)) {  // every path of the lane is proven free up to the queue's front
      lane.cut = true;
      lane.cut_t = heap[0].t_begin;
      return;
    }
    const QueueEntry e = heap[0];
    pop_pending = true;
    const int j = e.point;
    stepped = j;
    const std::int64_t total = pt_[j].segments;
    if (e.run > 0) {  // an unresolved run
      const std::int64_t run = std::min(e.run, total - e.segment);
      if (!runMayHit(k, motion, j, e.segment, run, isovalue)) {
        search_[j].backoff = 0;
        const std::int64_t after = e.segment + run;
        if (search_[j].clear_segments == e.segment) {
          search_[j].clear_segments = after;
          pt_[j].clear_until = after >= total ? 1.0 : segmentBegin(j, after);
        }
        if (after < total) push({segmentBegin(j, after), j, after, std::min(2 * run, total - after)});
      } else {
        push({e.t_begin, j, e.segment, run / 2});  // run 1 becomes 0: sample it
      }
      continue;
    }
    const double t_end = stepSegment(k, motion, j, e.segment, e.t_begin, isovalue, limit, result);
    if (result.hit_point == j && result.t < bound.load(std::memory_order_relaxed)) {
      double seen = bound.load(std::memory_order_relaxed);
      while (result.t < seen && !bound.compare_exchange_weak(seen, result.t, std::memory_order_relaxed)) {
      }
    }
    if (t_end >= 0.0 && t_end < 1.0) {
      // Near the surface, after a failed test of one segment (run 0): 2^b direct steps (-2^b,
      // counting up to -1), then test a run again (1); b grows with each failure in a row and
      // is reset by a run proven empty. Along a surface (a tool sliding in a hole) the tests
      // fail nearly always and this keeps them to a few per point instead of one per 2 samples.
      std::int64_t successor = 1;
      if (e.run == 0) {
        successor = -(std::int64_t{1} << search_[j].backoff);
        if (search_[j].backoff < 6) ++search_[j].backoff;
      } else if (e.run < -1) {
        successor = e.run + 1;
      }
      push({t_end, j, e.segment + 1, successor});
    }
  }
  lane.phase = 3;
}

SweepResult CollisionDetector::sweepPaper(const RigidMotion& motion, double isovalue) noexcept {
  SweepResult result;
  if (motion.isStill()) return result;
  const int n = static_cast<int>(tool_->point_shell.size());
  std::size_t count = 0;
  for (int j = 0; j < n; ++j) {
    setupPath(counters_, motion, j);
    if (embedded_[j] || !(pt_[j].path > 0.0)) continue;
    heap_[count++] = {0.0, j, 0};
  }
  std::make_heap(heap_.begin(), heap_.begin() + static_cast<std::ptrdiff_t>(count), Later{});
  // Time-prioritised search: always advance the segment that starts earliest; stop once no
  // pending segment starts before the earliest contact found.
  while (count > 0 && heap_[0].t_begin < result.t) {
    if (overBudget()) {  // every path is proven free up to the queue's front
      result.t = result.t_inside = heap_[0].t_begin;
      result.hit_point = -1;
      result.budget_cut = true;
      break;
    }
    std::pop_heap(heap_.begin(), heap_.begin() + static_cast<std::ptrdiff_t>(count), Later{});
    const QueueEntry e = heap_[--count];
    // The segment's test (exact, or the paper's end sample), then interval bisection until the
    // point travels less than epsilon over the interval (here epsilon / 8: a stop within the
    // full epsilon can be t = 0 for every small step).
    const double t_end = stepSegment(counters_, motion, e.point, e.segment, e.t_begin, isovalue, result.t, result);
    if (t_end >= 0.0 && t_end < 1.0) {
      heap_[count++] = {t_end, e.point, e.segment + 1};
      std::push_heap(heap_.begin(), heap_.begin() + static_cast<std::ptrdiff_t>(count), Later{});
    }
  }
  return result;
}

void CollisionDetector::pruneContacts(const Pose& X_WP, const Pose& X_WD, double isovalue) noexcept {
  const RigidMotion motion = RigidMotion::Between(X_WP, X_WD, tool_->mass.p_TCm_m);
  std::size_t kept = 0;
  for (std::size_t i = 0; i < contact_count_; ++i) {
    Contact c = contacts_[i];
    const int j = c.point_index;
    const Eigen::Vector3d r0 = motion.radial_W(c.p_T_m);
    const double path = motion.pathLengthBound(r0);
    bool keep = false;
    if (path > 0.0 && (j < 0 || !embedded_[j])) {
      c.p_W_m = X_WP * c.p_T_m;
      measureContact(c, isovalue, X_WP.R_AB);
      // Move the point epsilon towards the target; still inside means it still blocks. A
      // contact within epsilon of the surface (held at the stand-off clearance) also blocks when
      // that move heads into the surface (the same test to first order): without this, two
      // contacts of a resting tool are dropped in turn and the proxy chatters between them.
      const Eigen::Vector3d p_eps = motion.pointAt(r0, std::min(1.0, epsilon_ / path));
      keep = (c.clearance_m < epsilon_ && c.n_W.dot(p_eps - c.p_W_m) < 0.0) || inside(p_eps, isovalue);
    }
    if (keep) {
      contacts_[kept++] = c;
    } else if (j >= 0) {
      in_set_[j] = 0;
    }
  }
  contact_count_ = kept;
}

void CollisionDetector::addContactsAt(const RigidMotion& motion, const SweepResult& hit, double isovalue) noexcept {
  if (hit.hit_point < 0) return;
  const auto& points = tool_->point_shell.points_T_m();
  const int n = static_cast<int>(points.size());
  const double t = hit.t;
  auto direction = [&](int j) {  // fallback normal: against the point's motion
    const Eigen::Vector3d d = motion.pointAt(pt_[j].r0, t + 1e-3) - motion.pointAt(pt_[j].r0, t);
    const double nd = d.norm();
    return nd > 0.0 ? Eigen::Vector3d(-d / nd) : Eigen::Vector3d(Eigen::Vector3d::UnitZ());
  };
  // The points within epsilon of collision (moving a further epsilon along the path puts them
  // inside) become candidates, in index order (the paper's contact order); the hit point first.
  std::size_t candidates = 0;
  if (!in_set_[hit.hit_point]) candidate_[candidates++] = hit.hit_point;
  if (mode_ == DetectionMode::kAccelerated) {
    // A sweep that ended at t = 0 on a contact point skipped the tree: collect the points near
    // the proxy now (the tree over [0, t], t = 0, with the epsilon look-ahead).
    // This walk shares the work budget: cut, it leaves fewer candidates (the contact set is an
    // aid to the solver; the sweep alone keeps the proxy out).
    if (!active_complete_) {
      bool stopped = false;
      for (Lane& lane : lanes_) lane.active_count = 0;
      for (Lane& lane : lanes_) {
        startLaneWork(lane);
        collectActive(lane, motion, t, isovalue, false);
        counters_ += lane.counters;
        clock_ = lane.clock;
        if ((stopped = lane.walk_stopped)) break;
      }
      active_complete_ = !stopped;
    }
    // Only the points the sweep did not cull, in index order; a point whose look-ahead time lies
    // in its proven-outside prefix is skipped. The skip tests first, then only the few
    // candidates left are sorted (sorting every active point cost 4 % of a tick on Engine).
    // active_ keeps just the candidates afterwards.
    std::size_t kept = 0;
    for (const Lane& lane : lanes_) {
      for (std::size_t i = 0; i < lane.active_count; ++i) {
        const int j = lane.active[i];
        if (j == hit.hit_point || in_set_[j] || embedded_[j] || !(pt_[j].path > 0.0)) continue;
        if (t + epsilon_ / pt_[j].path <= pt_[j].clear_until) continue;
        active_[kept++] = j;
      }
    }
    // Sorted when few (the paper's order); many (a large face landing) are tested in the walk's
    // order, which the budget may stop early and reduceContacts() thins out anyway.
    if (kept <= 4 * contact_cap_) {
      std::sort(active_.begin(), active_.begin() + static_cast<std::ptrdiff_t>(kept));
      counters_.other += static_cast<std::int64_t>(kept * static_cast<std::size_t>(std::bit_width(kept)) / 8);
    }
    for (std::size_t i = 0; i < kept && !overBudget(); ++i) {
      const int j = active_[i];
      if (inside(motion.pointAt(pt_[j].r0, t + epsilon_ / pt_[j].path), isovalue)) candidate_[candidates++] = j;
    }
  } else {
    for (int j = 0; j < n && !overBudget(); ++j) {
      if (j == hit.hit_point || in_set_[j] || embedded_[j] || !(pt_[j].path > 0.0)) continue;
      if (inside(motion.pointAt(pt_[j].r0, t + epsilon_ / pt_[j].path), isovalue)) candidate_[candidates++] = j;
    }
  }
  const std::size_t cap = std::min(contact_cap_, contacts_.size());
  if (contact_count_ + candidates > cap) reduceContacts(motion, t, hit.hit_point, candidates, cap);
  for (std::size_t i = 0; i < candidates; ++i) {
    const int j = candidate_[i];
    if (j != hit.hit_point && overBudget()) continue;  // measuring a contact costs 7+ samples
    appendContact(j, motion.pointAt(pt_[j].r0, t), direction(j), isovalue);
  }
}

void CollisionDetector::reduceContacts(const RigidMotion& motion, double t, int hit_point, std::size_t& candidates,
                                       std::size_t cap) noexcept {
  // Farthest-point selection over the union of the contact set and the candidates, by position
  // at the proxy's new pose, seeded with the hit point (always kept: it is what stopped the
  // proxy). On a flat or gently curved face the constraint of a contact is affine in its
  // position, so contacts inside the hull of the kept ones add (almost) nothing; spreading the
  // kept ones over the face keeps the hull. A dropped contact that the next motion would push
  // in is caught by the sweep like any point (the cap never lets the proxy penetrate).
  // Over the budget: the hit point and the set as it is. Many candidates (a flat face landing
  // on a flat surface): every k-th one, so the selection below costs at most about
  // cap * max(4 cap, 256) / 16 units.
  if (overBudget()) {
    std::size_t kept_candidates = 0;
    for (std::size_t i = 0; i < candidates; ++i)
      if (candidate_[i] == hit_point) candidate_[kept_candidates++] = candidate_[i];
    candidates = kept_candidates;
    if (contact_count_ + candidates <= cap) return;
  }
  const std::size_t limit = std::max<std::size_t>(4 * cap, 256);
  if (candidates > limit) {
    const std::size_t stride = (candidates + limit - 1) / limit;
    std::size_t kept_candidates = 0;
    for (std::size_t i = 0; i < candidates; ++i)
      if (i % stride == 0 || candidate_[i] == hit_point) candidate_[kept_candidates++] = candidate_[i];
    candidates = kept_candidates;
  }
  const std::size_t existing = contact_count_;
  const std::size_t total = existing + candidates;
  auto position = [&](std::size_t u) {
    return u < existing ? contacts_[u].p_W_m : motion.pointAt(pt_[candidate_[u - existing]].r0, t);
  };
  auto point_of = [&](std::size_t u) { return u < existing ? contacts_[u].point_index : candidate_[u - existing]; };
  for (std::size_t u = 0; u < total; ++u) {
    reduce_position_[u] = position(u);
    reduce_distance_[u] = std::numeric_limits<double>::infinity();
    reduce_chosen_[u] = 0;
  }
  std::size_t seed = 0;
  for (std::size_t u = 0; u < total; ++u)
    if (point_of(u) == hit_point) seed = u;
  std::size_t chosen = 0;
  std::size_t next = seed;
  while (chosen < cap) {
    reduce_chosen_[next] = 1;
    ++chosen;
    if (chosen == cap || overBudget()) break;  // over budget: the ones chosen so far
    double farthest = -1.0;
    std::size_t best = next;
    const Eigen::Vector3d& p = reduce_position_[next];
    for (std::size_t u = 0; u < total; ++u) {
      if (reduce_chosen_[u]) continue;
      reduce_distance_[u] = std::min(reduce_distance_[u], (reduce_position_[u] - p).squaredNorm());
      if (reduce_distance_[u] > farthest) {
        farthest = reduce_distance_[u];
        best = u;
      }
    }
    counters_.other += static_cast<std::int64_t>(total / 16 + 1);  // ~16 distance updates per sample's cost
    if (farthest < 0.0) break;
    next = best;
  }
  std::size_t kept = 0;
  for (std::size_t u = 0; u < existing; ++u) {
    if (reduce_chosen_[u]) {
      contacts_[kept++] = contacts_[u];
    } else if (contacts_[u].point_index >= 0) {
      in_set_[contacts_[u].point_index] = 0;
    }
  }
  contact_count_ = kept;
  std::size_t kept_candidates = 0;
  for (std::size_t i = 0; i < candidates; ++i)
    if (reduce_chosen_[existing + i]) candidate_[kept_candidates++] = candidate_[i];
  candidates = kept_candidates;
}

bool CollisionDetector::refineStuckContact(const RigidMotion& motion, const SweepResult& hit) noexcept {
  if (hit.hit_point < 0 || !in_set_[hit.hit_point]) return false;
  const int j = hit.hit_point;
  if (pt_[j].path * hit.t >= bisection_tolerance_) return false;  // it did make progress
  for (std::size_t i = 0; i < contact_count_; ++i) {
    Contact& c = contacts_[i];
    if (c.point_index != j) continue;
    counters_.samples += 6;
    const Eigen::Vector3d g = volume_->interpolantGradient(motion.pointAt(pt_[j].r0, hit.t_inside));
    const double norm = g.norm();
    if (!(norm > 0.0) || !std::isfinite(norm)) return false;
    const Eigen::Vector3d n = -g / norm;
    if (c.crossing_normal && (n - c.n_W).norm() < 1e-9) return false;  // nothing new to try
    // Already the interpolant's own normal and still blocked at once: the point sits on a crease
    // of the trilinear surface (a cell face, where the gradient jumps), which one normal cannot
    // hold: each side's normal lets the motion into the other. Both sides are kept, the crease's
    // other side as a second contact of the point (point_index -1: not the point's own entry).
    if (c.crossing_normal) {
      std::size_t slot = contact_count_;  // the point's crease contact, when it has one already
      for (std::size_t k = 0; k < contact_count_; ++k)
        if (contacts_[k].point_index < 0 && (contacts_[k].p_T_m - c.p_T_m).norm() < 0.25 * epsilon_) slot = k;
      if (slot < contact_count_ && (contacts_[slot].n_W - n).norm() < 1e-9) return false;
      if (slot == contact_count_ && contact_count_ >= contactCap()) return false;
      Contact crease = c;
      crease.point_index = -1;
      crease.n_W = n;
      contacts_[slot] = crease;
      if (slot == contact_count_) ++contact_count_;
      return true;
    }
    c.n_W = n;
    c.crossing_normal = true;
    return true;
  }
  return false;
}

void CollisionDetector::refreshPositions(const Pose& X_WP) noexcept {
  for (std::size_t i = 0; i < contact_count_; ++i) contacts_[i].p_W_m = X_WP * contacts_[i].p_T_m;
}

double CollisionDetector::maxFieldOnShell(const Pose& X_WP, double floor) noexcept {
  const auto& points = tool_->point_shell.points_T_m();
  double m = floor;
  const auto visit = [&](int j) {
    if (embedded_[j]) return;
    ++counters_.samples;
    const Eigen::Vector3d p = X_WP * points[j];
    if (!volume_->inBounds(p)) return;  // out of the grid is never inside, at any isovalue
    m = std::max(m, volume_->sample(p));
  };
  if (mode_ == DetectionMode::kAccelerated) {
    // A node whose ball lies in bricks whose values stay <= m cannot raise m.
    walkShellTree(
        stack_.data(), 0,
        [&](const ShellNode& node) {
          return ballMayBeInside(counters_, X_WP * node.center_T_m, node.radius_m * (1.0 + 1e-9) + 1e-12, m);
        },
        [&](int j) {
          visit(j);
          return false;
        });
  } else {
    for (std::size_t j = 0; j < points.size(); ++j) visit(static_cast<int>(j));
  }
  return m;
}

int CollisionDetector::updateEmbedded(const Pose& X_WP, double isovalue) noexcept {
  const auto& points = tool_->point_shell.points_T_m();
  embedded_count_ = 0;
  if (mode_ == DetectionMode::kAccelerated) {
    // The point-shell tree at the pose X_WP: a node whose ball lies in bricks that cannot hold
    // an inside point has no embedded point (its points are cleared as it is skipped); the test
    // of each point is the paper's.
    walkShellTree(
        stack_.data(), 0,
        [&](const ShellNode& node) {
          if (ballMayBeInside(counters_, X_WP * node.center_T_m, node.radius_m * (1.0 + 1e-9) + 1e-12, isovalue))
            return true;
          for (int i = node.begin; i < node.end; ++i) embedded_[order_[i]] = 0;
          return false;
        },
        [&](int j) {
          embedded_[j] = inside(X_WP * points[j], isovalue) ? 1 : 0;
          embedded_count_ += embedded_[j];
          return false;
        });
  } else {
    for (std::size_t j = 0; j < points.size(); ++j) {
      embedded_[j] = inside(X_WP * points[j], isovalue) ? 1 : 0;
      embedded_count_ += embedded_[j];
    }
  }
  if (embedded_count_ > 0) {  // embedded points leave the contact set
    std::size_t kept = 0;
    for (std::size_t i = 0; i < contact_count_; ++i) {
      const int j = contacts_[i].point_index;
      if (j >= 0 && embedded_[j]) in_set_[j] = 0;
      else contacts_[kept++] = contacts_[i];
    }
    contact_count_ = kept;
  }
  return embedded_count_;
}

int CollisionDetector::releaseEmbedded(const Pose& X_WP, double isovalue) noexcept {
  if (embedded_count_ == 0) return 0;
  const auto& points = tool_->point_shell.points_T_m();
  for (std::size_t j = 0; j < points.size(); ++j)
    if (embedded_[j] && !inside(X_WP * points[j], isovalue)) {
      embedded_[j] = 0;
      --embedded_count_;
    }
  return embedded_count_;
}

}  // namespace vh::haptics
