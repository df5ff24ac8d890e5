// The collision detector's parts behind its facade (vh/haptics/collision_detector.h): their
// state and functions, one job a file:
//   paper_sweep.cpp                           the paper's sweep (sweep_queue.h: its queue)
//   accelerated_sweep.cpp, .h                 the accelerated sweep and its per-point state
//   sweep_lanes.cpp, .h                       its lanes on several cores
//   shell_tree.cpp, .h                        the point-shell tree and the ball query
//   contact_set.cpp                           the contact set (step 2, add, reduce to the cap)
//   embedded_points.cpp                       embedded points, the field over the shell
//   edge_test.cpp, .h, edge_certificates.cpp  the edge test between the points, its certificates
//   detector_work.h                           the work counters and the deadline's clock reads
// The facade forwards each call to one Impl, built once in the constructor (no member
// allocates after it); the hot loops run inside the parts, behind that one pointer.
// Private to haptics/src.
#pragma once

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <memory>
#include <span>
#include <utility>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "vh/haptics/collision_detector.h"
#include "vh/haptics/worker_pool.h"

#include "accelerated_sweep.h"
#include "detector_work.h"
#include "edge_test.h"
#include "shell_tree.h"
#include "sweep_lanes.h"
#include "sweep_queue.h"

namespace vh::haptics {

class CollisionDetector::Impl {
 public:
  // The facade's calls, one to one (documented in collision_detector.h).
  Impl(const ScalarVolume& volume, const ToolModel& tool, double epsilon_m, std::size_t max_contacts,
       DetectionMode mode, double segment_fraction, SegmentTest segment_test);
  DetectionMode mode() const noexcept { return mode_; }
  SegmentTest segmentTest() const noexcept { return segment_test_; }
  double maxSagitta_m() const noexcept { return max_sagitta_; }
  double epsilon_m() const noexcept { return epsilon_; }
  double featureSize_m() const noexcept { return feature_; }
  double shellRadius_m() const noexcept { return shell_radius_m_; }
  SweepResult sweep(const RigidMotion& motion, double isovalue) noexcept;
  bool sweepPending() const noexcept { return pending_.active; }
  const RigidMotion& pendingMotion() const noexcept { return pending_.motion; }
  SweepResult resumeSweep() noexcept;
  void abandonSweep() noexcept { pending_.active = false; }
  void pruneContacts(const Pose& X_WP, const Pose& X_WD, double isovalue) noexcept;
  void releaseClearContacts(const Pose& X_WP, double isovalue, double clearance_m) noexcept;
  void addContactsAt(const RigidMotion& motion, const SweepResult& hit, double isovalue) noexcept;
  bool refineStuckContact(const RigidMotion& motion, const SweepResult& hit) noexcept;
  void refreshPositions(const Pose& X_WP) noexcept;
  int updateEmbedded(const Pose& X_WP, double isovalue) noexcept;
  double maxFieldOnShell(const Pose& X_WP, double floor) noexcept;
  bool edgesCrossAt(const Pose& X_WP, double isovalue) noexcept;
  bool edgeTestCut() const noexcept { return edge_cut_; }
  bool listedEdgesCrossAt(const Pose& X_WP, double isovalue) noexcept;
  void clearCrossingEdges() noexcept { listed_count_ = 0; }
  const Contact* addEdgeContact(const Pose& X_WP, double isovalue) noexcept;
  const ShellEdges& shellEdges() const noexcept { return edges_; }
  int releaseEmbedded(const Pose& X_WP, double isovalue) noexcept;
  int embeddedCount() const noexcept { return embedded_count_; }
  void clearContacts() noexcept;
  std::span<const Contact> contacts() const noexcept { return {contacts_.data(), contact_count_}; }
  std::int64_t sampleCount() const noexcept { return counters_.samples; }
  std::int64_t boxQueryCount() const noexcept { return counters_.box_queries; }
  std::int64_t treeNodeCount() const noexcept { return counters_.tree_nodes; }
  std::int64_t cellCount() const noexcept { return counters_.cells; }
  std::int64_t cellsWalkedCount() const noexcept { return counters_.cells_walked; }
  EdgeTestCounts edgeTestCounts() const noexcept { return counters_.edge; }
  std::int64_t work() const noexcept { return counters_.total(); }
  std::int64_t budgetWork() const noexcept { return counters_.total() - parallel_credit_; }
  void setContactCap(std::size_t cap) noexcept { contact_cap_ = std::clamp<std::size_t>(cap, 1, contacts_.size()); }
  std::size_t contactCap() const noexcept { return std::min(contact_cap_, contacts_.size()); }
  void setWorkBudget(std::int64_t units) noexcept { work_budget_ = units > 0 ? units : 0; }
  void setDeadline(std::chrono::steady_clock::time_point deadline) noexcept {
    deadline_ = deadline;
    has_deadline_ = true;
    clock_ = {};
  }
  void clearDeadline() noexcept { has_deadline_ = false; }
  void setWorkDeadline(std::int64_t work) noexcept {
    work_deadline_ = work > 0 ? work : 0;
    clock_ = {};
  }
  bool deadlineReached() const noexcept { return deadline_hit_ || clock_.late; }
  // 1 + the work at the first read that found the deadline passed (0: none; a read at work 0
  // counts). Work only grows within a tick, so the first read is the one at the least work: a
  // lane's (the sweep's) before the caller's later reads.
  std::int64_t deadlineWork() const noexcept {
    if (clock_.late && deadline_hit_) return std::min(clock_.late_work, lane_late_work_) + 1;
    if (clock_.late) return clock_.late_work + 1;
    return deadline_hit_ ? lane_late_work_ + 1 : 0;
  }
  void setLanes(int lanes);
  int lanes() const noexcept { return static_cast<int>(lanes_.size()); }
  void addWork(std::int64_t units) noexcept { counters_.other += units > 0 ? units : 0; }
  bool budgetSpent() const noexcept { return overBudget(); }
  std::int64_t workBudget() const noexcept { return work_budget_; }
  void resetSampleCount() noexcept {
    counters_ = {};
    parallel_credit_ = 0;
    clock_ = {};
    deadline_hit_ = false;
    lane_late_work_ = 0;
  }

  // The parts' own functions and state.
  using QueueEntry = detail::QueueEntry;
  using ShellNode = detail::ShellNode;
  using WorkCounters = detail::WorkCounters;
  using ClockCheck = detail::ClockCheck;
  using Lane = detail::Lane;
  SweepResult sweepPaper(const RigidMotion& motion, double isovalue) noexcept;
  SweepResult sweepAccelerated(const RigidMotion& motion, double isovalue) noexcept;
  // kAccelerated: runs (or resumes) the sweep held in pending_.
  SweepResult runAccelerated() noexcept;
  // kAccelerated: one lane's walk and time-ordered search (resumable).
  void runLane(Lane& lane) noexcept;
  static void laneJob(void* detector, int lane) noexcept;
  // kAccelerated, the sweep's first phase: each contact point's first segment, taken before any
  // other point's (a hit recorded in pending_.result; an outside end queued for a run test in
  // the lane holding the point), up to a hit at t = 0. False when the budget stopped it (it goes
  // on at pending_.contact_index).
  bool runContactPass() noexcept;
  // A sweep the budget stopped in its contact pass: nothing proven (t = 0), to be resumed.
  SweepResult cutBeforeLanes() noexcept;
  // After the contact pass: every lane starts its walk over [0, the pass's first hit] afresh.
  void startLanePhase() noexcept;
  // The lanes' walks and searches (on the pool, else one after the other on the caller), their
  // shared first time of contact (bound_) starting at t_bound or a finished lane's earlier hit;
  // then their work added to the caller's.
  void forkLanes(double t_bound) noexcept;
  // The sweep's result from the lanes': the earliest of contact_hit and their hits (on a tie the
  // lowest point index), or, where a lane stopped before it, a budget cut proven free up to
  // where the first lane stopped.
  SweepResult mergeLanes(const SweepResult& contact_hit) noexcept;
  // A lane's walk of its share of the point-shell tree over [0, pending_.walk_t] (collectActive()
  // with queue), its queue then made a heap; false when the budget stopped it (lane.cut at 0).
  bool walkLane(Lane& lane) noexcept;
  // A lane's time-ordered search (resumable): until its queue's front reaches its own hit or
  // bound_, or the budget stops it (lane.cut at the front's time).
  void searchLane(Lane& lane) noexcept;
  // Puts `entry` in place of the lane's queue minimum, the entry being processed (one sift).
  static inline void pushSuccessor(Lane& lane, const QueueEntry& entry) noexcept;
  // An unresolved run of segments (e.run > 0): proven empty by runMayHit() and skipped (the next
  // run twice as long), else halved in place (a run of 1 becomes a sample).
  inline void resolveRun(Lane& lane, const QueueEntry& e) noexcept;
  // A single segment (e.run <= 0) stepped as the paper does, looking no later than `limit`: a
  // hit lowers bound_; an end outside queues the next segment.
  inline void stepQueuedSegment(Lane& lane, const QueueEntry& e, double limit) noexcept;
  using PendingSweep = detail::PendingSweep;
  PendingSweep pending_;
  int buildShellTree(int begin, int end, int depth);
  // After a lane's walk: node_near_ of the nodes it reached, from its walk_log, leaves first.
  void markNearNodes(Lane& lane) noexcept;
  // Walks the point-shell tree below node `root` depth first, left before right, on `stack`
  // (capacity: the nodes): a node for which may_hold(node) is false is skipped with all below
  // it; visit(j) is called on each point of the leaves reached, in tree order, and ends the walk
  // by returning true. Returns whether a visit ended it.
  template <typename MayHold, typename Visit>
  bool walkShellTree(int* stack, int root, MayHold&& may_hold, Visit&& visit) const noexcept;
  // False when no point of the W ball (centre, radius), nor within arc_sagitta_m of it, can be
  // inside (min-max tree bound with the local Lipschitz bounds).
  // The box in grid coordinates [voxels] that holds the ball of radius_m [m] about centre_W_m (W).
  void ballGridBox(const Eigen::Vector3d& centre_W_m, double radius_m, Eigen::Vector3d& lo_ijk,
                   Eigen::Vector3d& hi_ijk) const noexcept;
  bool ballMayBeInside(WorkCounters& k, const Eigen::Vector3d& center_W_m, double radius_m, double isovalue,
                       double arc_sagitta_m = 0.0) const noexcept;
  // Start time of segment k of point j (the same double the paper path computes).
  double segmentBegin(int j, std::int64_t k) const noexcept { return k == 0 ? 0.0 : static_cast<double>(k) * pt_[j].dt; }
  // False when the swept ball of segments [k, k + run) of point j holds no inside point.
  bool runMayHit(WorkCounters& w, const RigidMotion& motion, int j, std::int64_t k, std::int64_t run,
                 double isovalue) noexcept;
  // True when point j's arc over [t0, t1] is proven free by F at its start and the most F can
  // rise along its direction (ScalarVolume::gridStepRange() over the box of its chord dilated by
  // the arc's sagitta, or ranges_lo/hi when given: F's steps over a convex region that holds
  // the arc, such as its point-shell leaf's ball); false proves nothing. within_a_voxel, when
  // given: whether F at the start plus one grid step's steepest rise per axis reaches the
  // isovalue (the surface may be about a voxel away; a hint for the next sweep).
  bool runFreeAlongItsDirection(WorkCounters& w, const RigidMotion& motion, int j, double t0, double t1,
                                double isovalue, const Eigen::Vector3d* ranges_lo = nullptr,
                                const Eigen::Vector3d* ranges_hi = nullptr, bool* within_a_voxel = nullptr) const noexcept;
  bool inside(const Eigen::Vector3d& p_W, double isovalue) noexcept;
  // r0, path, segments, segment time and arc margin of point j for `motion` (both modes).
  void setupPath(WorkCounters& k, const RigidMotion& motion, int j) noexcept;
  // kAccelerated: setupPath() and clears the proven-free time of point j (clear_until).
  void startPoint(WorkCounters& k, const RigidMotion& motion, int j) noexcept;
  // kAccelerated: point j is queued for the time-ordered search: its proven-empty prefix and its
  // back-off start afresh (PointSearch; culled points never touch it).
  void startSearch(int j) noexcept;
  // The paper's step for segment `segment` of point j (kExact: the first entry along its
  // chord; kEndSample: its end sampled; a hit bisected) looking no later than t_limit (<=
  // result.t), a hit recorded in `result`. Returns the segment's end time, or -1 when inside.
  double stepSegment(WorkCounters& k, const RigidMotion& motion, int j, std::int64_t segment, double t_begin,
                     double isovalue, double t_limit, SweepResult& result) noexcept;
  // kExact, a rotating point j whose chord over [t0, t1] (sagitta sagitta_m) reported a hit:
  // tests four chords of a quarter of the time each (a sixteenth of the sagitta) in time order,
  // recursing into the first that hits, `depth` levels in all; the first hit of the finest level
  // is the arc's (bracket [lo, hi] in time). False when none hits: the coarse hit came from the
  // bubble (the chord's own pessimism), and the arc is free over [t0, min(t1, t_limit)].
  bool refineArcEntry(WorkCounters& k, const RigidMotion& motion, int j, double t0, double t1, double sagitta_m,
                      double isovalue, double t_limit, int depth, double& lo, double& hi) noexcept;
  static constexpr int kArcRefinements = 3;  // down to 1/4096 of the sagitta
  // A finished sweep's hit: the proxy stops kStopClearanceFraction * epsilon of the hit point's
  // travel before the bracket's outside end (see the definition).
  SweepResult stopClear(SweepResult result) const noexcept;
  // kAccelerated: walks the lane's share of the point-shell tree over the arc [0, t_max] (plus
  // epsilon) and fills lane.active with the points not culled; with `queue`, also tests each
  // point's path over [0, t_max] and writes heap entries from lane.heap[lane.queued]. Returns
  // the entries written. With `queue`, the walk stops when the work budget runs out and sets
  // lane.walk_stopped. With `resume`, goes on with a walk the budget stopped.
  std::size_t collectActive(Lane& lane, const RigidMotion& motion, double t_max, double isovalue, bool queue,
                            bool resume = false) noexcept;
  using WalkArc = detail::WalkArc;
  // The ball in W about `node`'s centre at t_max / 2 that holds its points' arcs over [0, t_max]
  // plus epsilon of further travel: returns its radius [m], its centre in centre_W [m].
  inline double nodeBall(const WalkArc& arc, const ShellNode& node, Eigen::Vector3d& centre_W) const noexcept;
  using LeafSteps = detail::LeafSteps;
  // Point j of leaf `node`, near the surface last sweep (PointState::near_surface): whether its
  // path over [0, t_max] is proven free along its direction (runFreeAlongItsDirection() with the
  // leaf's steps); within_a_voxel: the surface may be about a voxel away.
  inline bool nearPathFree(WorkCounters& k, const WalkArc& arc, const ShellNode& node, int j, LeafSteps& steps,
                    bool& within_a_voxel) const noexcept;
  // A leaf the walk reached (logged at lane.walk_log[logged]): its points made active; with
  // arc.queue, each point the contact pass did not start is proven free by its own test or
  // queued at heap[count]. Returns the new count of queued entries.
  inline std::size_t collectLeaf(Lane& lane, const WalkArc& arc, int node_index, std::size_t logged, QueueEntry* heap,
                          std::size_t count) noexcept;
  // Readies a lane for work on the caller's budget and clock (base work, counters, clock reads).
  void startLaneWork(Lane& lane) const noexcept;
  // After a fork: adds the lanes' work to the caller's (the budget counting the busiest lane's)
  // and notes a lane that reached the deadline.
  void joinLaneWork() noexcept;
  // Fills c.n_W and c.clearance_m at c.p_W_m (7 samples); R_WT: the tool's orientation (an edge
  // contact's direction, Contact::edge_T).
  void measureContact(Contact& c, double isovalue, const Eigen::Quaterniond& R_WT) noexcept;
  void appendContact(int point, const Eigen::Vector3d& p_W, const Eigen::Vector3d& fallback_n_W, double isovalue) noexcept;

  const ScalarVolume* volume_;
  const ToolModel* tool_;
  ShellEdges edges_;
  std::vector<double> edge_reach_m_;  // per point j: its longest edge (j, k > j) [m]
  // The margin of a box query's certificate (EdgeClearance::arm_m = 0) [m]: the query is for a
  // ball that much larger than j's edges need; half a voxel (the feature size) barely changes
  // what the min-max tree's bricks answer.
  double ballMargin_m() const noexcept { return feature_; }
  // The edges (j, k > j) at pose X_WP, with p_W = X_WP * point j (walked; a certificate of their
  // clearance kept when free). Returns the first crossing edge's other end, or -1 when none crosses.
  int edgeCrosses(WorkCounters& w, const Pose& X_WP, int j, const Eigen::Vector3d& p_W, double isovalue) noexcept;
  // Records edge (j, k), found crossing at X_WP: the last hit (addEdgeContact()) and the list.
  void recordCrossingEdge(int j, int k, const Pose& X_WP) noexcept;
  // One lane's share of a forked edge test (edgesCrossAt()).
  void runEdgeLane(Lane& lane) noexcept;
  static void edgeLaneJob(void* detector, int lane) noexcept;
  // The pose and isovalue of the forked edge test; the lowest root rank a lane found crossing.
  using EdgeJob = detail::EdgeJob;
  EdgeJob edge_job_;
  std::unique_ptr<std::atomic<int>> edge_bound_ = std::make_unique<std::atomic<int>>(0);
  // Which of j's clearance certificates (EdgeClearance) still holds at pose X_WP, with p_W =
  // X_WP * point j (the caller has it): none, a box query's, or an exact walk's (then j's edges
  // are near the surface).
  enum class EdgeHold { kNone, kBoxQuery, kWalk };
  EdgeHold edgesStillClear(const Pose& X_WP, int j, const Eigen::Vector3d& p_W) const noexcept;
  // The edge test over the subtree of node `index` (kAccelerated), R_WT = X_WP's rotation:
  // kCrossing with the crossing edge (j, k) first in the subtree's walk order in `j_hit`,
  // `k_hit`; kCut where the budget stopped it; else kClear. `walked`: points walked so far in
  // this edge test on this lane (the first is never stopped).
  enum class EdgeWalk { kClear, kCrossing, kCut };
  EdgeWalk edgeNodeWalk(WorkCounters& w, Lane* lane, int index, const Pose& X_WP, const Eigen::Matrix3d& R_WT,
                        double isovalue, int& walked, int& j_hit, int& k_hit) noexcept;
  // Per node of nodes_ (the edge test's temporal coherence): 1 when its last walk found a point
  // below it whose edges are near the surface (walked, or asked by a box query that did not
  // prove them free, or held by an exact walk's certificate). The next walk lets it through
  // without a box query of its own: near the surface the answer seldom changes from one tick
  // to the next, and a node let through that its ball would have culled costs only its points'
  // own tests, which cull what it would have. Written by the lane that walks the node.
  std::vector<std::uint8_t> node_edge_near_;
  using EdgeClearance = detail::EdgeClearance;
  // How far (grid steps per axis) a directional certificate's edges may move at least: the box
  // whose derivative ranges it reads is its edges' box dilated by this much.
  static constexpr double kCertificateReachSteps = 2.0;
  Eigen::Matrix3d grid_from_W_ = Eigen::Matrix3d::Identity();  // a move in W [m] -> grid steps
  std::vector<EdgeClearance> edge_clearance_;  // two per point: 2 j and 2 j + 1
  std::vector<int> edge_clearance_index_;       // per point: where its two are (its place in order_)
  std::vector<unsigned char> edge_slot_;        // per point: the slot the next certificate replaces
  // Keeps `proven` as point j's newer certificate, in place of its older one.
  void keepEdgeClearance(int j, const EdgeClearance& proven) noexcept;
  bool edge_cut_ = false;  // the last edgesCrossAt() stopped at the budget or the deadline
  double edge_clearance_isovalue_ = std::numeric_limits<double>::quiet_NaN();  // the certificates' isovalue
  // Drops every certificate: the next edge test proves them again (forgetFieldProofs()).
  void forgetEdgeCertificates() noexcept { edge_clearance_isovalue_ = std::numeric_limits<double>::quiet_NaN(); }
  // The field rose by at most `rise` (F units) anywhere since the last call: the certificates
  // weaken by it (EdgeClearance::rise_at_proof); a rise that is not finite and >= 0 forgets them.
  void noteFieldRise(double rise) noexcept;
  // The rises noted since the detector was built, summed rounding upward (certificates keep
  // the sum at their proof; the difference bounds the rise since).
  double field_rise_ = 0.0;
  // How far edge (a, b) (grid coordinates), which the walk found free with F - s <= excess_max
  // on it, may move and stay free [m]; <= 0 when nothing is proven (see EdgeClearance).
  double edgeClearance(const Eigen::Vector3d& a, const Eigen::Vector3d& b, double excess_max,
                       double isovalue) const noexcept;
  // Point i's end of its edges at pose X_WP, in grid coordinates (inset by epsilon; 1 sample).
  Eigen::Vector3d edgeEnd(WorkCounters& w, const Pose& X_WP, int i) const noexcept;
  // An edge with its ends a, b in grid coordinates: whether the isosurface enters it. With
  // `excess_max`, also F - s's upper bound on the edge (SegmentEntry::excess_max).
  bool segmentCrosses(WorkCounters& w, const Eigen::Vector3d& a, const Eigen::Vector3d& b, double isovalue,
                      double* excess_max = nullptr) const noexcept;
  std::array<std::pair<int, int>, kListedEdges> listed_{};  // edges found crossing (edgesCrossAt())
  int listed_count_ = 0;
  using EdgeHit = detail::EdgeHit;
  EdgeHit edge_hit_;  // the last edge edgesCrossAt() found crossing
  DetectionMode mode_;
  SegmentTest segment_test_;
  double feature_;
  double max_sagitta_ = 0.0;  // kExact: largest chord sagitta of an arc [m]
  double shell_radius_m_ = 0.0;  // largest |p_T - Cm| over the point shell
  double sweep_sagitta_ = 0.0;   // per sweep: largest sagitta_[j] of any point (node tests)
  double segment_length_m_;  // feature size * segment_fraction
  double epsilon_;
  double bisection_tolerance_;
  using PointState = detail::PointState;
  std::vector<PointState> pt_;  // per point: its path in the current sweep (both modes)
  using PointSearch = detail::PointSearch;
  std::vector<PointSearch> search_;  // per point: its time-ordered search
  // The run of the entry that follows a step of one segment (run <= 0) ending outside: 2^backoff
  // direct steps after a failed run test, then a run test again (see stepQueuedSegment()).
  static inline std::int64_t runAfterOutsideStep(PointSearch& search, std::int64_t run) noexcept;
  // kAccelerated, per point: sweep_stamp_ when started by the contact pre-pass (written before
  // the lanes run, read by them).
  std::vector<std::uint32_t> started_;
  std::uint32_t chord_stamp_ = 0;
  // ballMayBeInside()'s early stop in the min-max tree (ScalarVolume::rawStopAbove()) for
  // stop_isovalue_: set by the caller's thread before the lanes fork (prepareTreeStop()).
  double stop_isovalue_ = std::numeric_limits<double>::quiet_NaN();
  MinMaxTree::RawStop tree_stop_{};
  void prepareTreeStop(double isovalue) noexcept {
    if (isovalue == stop_isovalue_) return;
    stop_isovalue_ = isovalue;
    tree_stop_ = volume_->rawStopAbove(isovalue);
  }
  std::vector<QueueEntry> heap_;         // kPaper's queue, capacity = number of points
  // kAccelerated state (see haptics/README.md, "Speed").
  std::vector<ShellNode> nodes_;         // point-shell tree, root at 0
  // Per node of nodes_ (temporal coherence): 1 when the last walk that reached it found a point
  // below it near the surface (in a walk that tests points one by one: a point its own test did
  // not cull; else a leaf its ball test let through). The next walk lets such a node through
  // without asking the min-max tree: near the surface the answer seldom changes from one tick
  // to the next, and a node let through that its ball would have culled costs only its
  // children's (or its points') own tests, which cull what it would have. The walk reaches a
  // superset of the points, each proven free or searched as before, so the first time of
  // contact is the same double. Written by the lane that walks the node (markNearNodes()).
  std::vector<std::uint8_t> node_near_;
  std::vector<int> order_;               // point indices in tree order
  std::vector<int> stack_;               // traversal stack of the caller's walks, capacity = nodes
  std::vector<int> active_;              // addContactsAt(): the lanes' active points it keeps, capacity = points
  bool active_complete_ = true;          // false: the last sweep stopped before its lanes collected their active points
  std::uint32_t sweep_stamp_ = 0;
  std::vector<Lane> lanes_;              // at least one (setLanes())
  // The lanes' shares (setLanesPartition(), rebalanceLanes()): the tree's upper nodes in the
  // single-lane walk's order (a node's rank is its index), per rank the lane holding it, per
  // point the rank of the node that holds it (so point j's lane is root_lane_[rank_of_point_[j]]).
  std::vector<int> frontier_, root_lane_, rank_of_point_;
  bool balanced_lanes_ = false;          // the shares follow the work (rebalanceLanes())
  // Up to this many lanes the shares follow the measured work; each lane's queue then has room
  // for every point (36 bytes a point a lane).
  static constexpr int kMaxBalancedLanes = 16;
  // Before a new sweep: deals the upper nodes again, in order, each to the lane with the least
  // work so far, weighed by the work the node cost since the last deal (its walk, its points'
  // queue steps and edge tests). Kept as it is when no lane has worked since.
  void rebalanceLanes() noexcept;
  // The work a lane did since `mark` (its counters' total), charged to the node of rank `rank`.
  static void chargeRoot(Lane& lane, int rank, std::int64_t& mark) noexcept {
    const std::int64_t now = lane.counters.total();
    lane.root_work[static_cast<std::size_t>(rank)] += now - mark;
    mark = now;
  }
  std::shared_ptr<WorkerPool> pool_;     // WorkerPool::shared(lanes), none for one lane
  // The lanes' shared first time of contact so far (read relaxed: a stale value only costs work).
  std::unique_ptr<std::atomic<double>> bound_ = std::make_unique<std::atomic<double>>(1.0);
  void setLanesPartition(int lanes);
  Eigen::Vector3d grid_per_m_ = Eigen::Vector3d::Ones();  // 1 / spacing per grid axis
  std::vector<unsigned char> embedded_;  // per point
  std::vector<unsigned char> in_set_;    // per point: in the contact set
  int embedded_count_ = 0;
  std::vector<Contact> contacts_;
  std::size_t contact_count_ = 0;
  WorkCounters counters_;               // the caller's work, plus the lanes' after each fork
  std::int64_t parallel_credit_ = 0;    // the lanes' work beside the busiest lane (budgetWork())
  std::chrono::steady_clock::time_point deadline_{};
  bool has_deadline_ = false;
  bool deadline_hit_ = false;           // a lane stopped at the deadline since resetSampleCount()
  std::int64_t lane_late_work_ = 0;     // the work at which that lane found it passed
  // The deadline as work (setWorkDeadline(): a replay's stand-in for the clock), 0: none.
  std::int64_t work_deadline_ = 0;
  mutable ClockCheck clock_;            // the caller's clock reads
  std::int64_t work_budget_ = 0;
  std::size_t contact_cap_ = static_cast<std::size_t>(-1);
  // Work units of one point's path set-up: max(1, points / 5000). The per-point state of a large
  // shell no longer fits in the caches: on Engine a unit of work cost 0.039 us with the
  // 2,126-point wrench, 0.088 us with 20,000 points and 0.071 us with 50,000 (cut ticks).
  std::int64_t setup_work_ = 1;
  // addContactsAt(): the new contact points (capacity = points); reduceContacts()' scratch
  // (capacity = points + contact capacity).
  std::vector<int> candidate_;
  std::vector<Eigen::Vector3d> reduce_position_;
  std::vector<double> reduce_distance_;
  std::vector<unsigned char> reduce_chosen_;
  void reduceContacts(const RigidMotion& motion, double t, int hit_point, std::size_t& candidates,
                      std::size_t cap) noexcept;
  // The deadline has passed (read every kClockCheckWork units of `work`).
  // With a work deadline instead, the same reads find it passed once `work` reaches it: the
  // read at which the clock found it passed in a live tick (deadlineWork()) is found again.
  bool pastDeadline(ClockCheck& clock, std::int64_t work) const noexcept {
    if (!has_deadline_ && work_deadline_ == 0) return false;
    if (clock.late) return true;
    if (work < clock.next) return false;
    clock.next = work + kClockCheckWork;
    clock.late = work_deadline_ > 0 ? work + 1 >= work_deadline_ : std::chrono::steady_clock::now() >= deadline_;
    if (clock.late) clock.late_work = work;
    return clock.late;
  }
  bool overBudget() const noexcept {
    const std::int64_t w = budgetWork();
    return (work_budget_ > 0 && w >= work_budget_) || pastDeadline(clock_, w);
  }
  bool overBudget(Lane& lane) const noexcept {
    const std::int64_t w = lane.base_work + lane.counters.total();
    return (work_budget_ > 0 && w >= work_budget_) || pastDeadline(lane.clock, w);
  }
};

template <typename MayHold, typename Visit>
bool CollisionDetector::Impl::walkShellTree(int* stack, int root, MayHold&& may_hold, Visit&& visit) const noexcept {
  return detail::walkShellTree(nodes_, order_, stack, root, std::forward<MayHold>(may_hold), std::forward<Visit>(visit));
}

}  // namespace vh::haptics
