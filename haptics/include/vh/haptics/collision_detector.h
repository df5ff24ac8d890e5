#pragma once
/// @file
/// Continuous collision detection of the point shell against the isosurface F = s along the
/// proxy's motion arc (paper section 2.3) and contact-set pruning (step 2).

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <limits>
#include <memory>
#include <span>
#include <vector>

#include <Eigen/Core>

#include "vh/haptics/contact_set.h"
#include "vh/haptics/pose.h"
#include "vh/haptics/rigid_motion.h"
#include "vh/haptics/scalar_volume.h"
#include "vh/haptics/sweep.h"
#include "vh/haptics/tool_model.h"
#include "vh/haptics/worker_pool.h"

namespace vh::haptics {

/// Collision detector for one point shell against one volume. Owns the contact set and all
/// working memory (sized at construction): no member allocates after construction.
class CollisionDetector {
 public:
  /// @param epsilon_m collision tolerance; 0 selects f / 8 (f = feature size; chosen by `bench accuracy`).
  /// @param max_contacts capacity of the contact set.
  /// @param mode which sweep path runs (both give the same contract).
  /// @param segment_fraction longest sampling segment along a path as a fraction of the
  ///        feature size f, in (0, 1]; 1 is the paper's ceil(s / f) segments (section 2.3).
  /// @param segment_test how each segment is tested (kExact: never misses a thin feature).
  /// @throws std::invalid_argument when epsilon_m >= f, the point shell is empty or
  ///         segment_fraction is outside (0, 1].
  CollisionDetector(const ScalarVolume& volume, const ToolModel& tool, double epsilon_m,
                    std::size_t max_contacts = 256, DetectionMode mode = DetectionMode::kAccelerated,
                    double segment_fraction = 1.0, SegmentTest segment_test = SegmentTest::kExact);

  /// A finished sweep with a hit stops this fraction of epsilon of the hit point's own travel
  /// before the bisection bracket's outside end (proven free), so that a contact is never left
  /// a rounding error from the surface, where a turn along the surface would hold it for good.
  static constexpr double kStopClearanceFraction = 1.0 / 128.0;

  DetectionMode mode() const noexcept { return mode_; }
  SegmentTest segmentTest() const noexcept { return segment_test_; }
  /// Largest deviation of a rotating point's arc from the chords it is tested along [m]
  /// (kExact: epsilon / 64; see haptics/README.md, "Never through").
  double maxSagitta_m() const noexcept { return max_sagitta_; }

  double epsilon_m() const noexcept { return epsilon_; }
  double featureSize_m() const noexcept { return feature_; }
  /// Largest distance of a shell point from the tool's centre of mass [m] (T).
  double shellRadius_m() const noexcept { return shell_radius_m_; }

  /// Step 4: first time of contact along `motion` (eq. 2) for all points not embedded: each
  /// point's path is split into ceil(s / f) equal time segments (s = path-length bound; more
  /// for a rotating point under kExact, so that no chord's sagitta exceeds maxSagitta_m()), the
  /// segments are visited in time order through one priority queue over all points, each is
  /// tested (kExact: the first entry along its chord, exactly; kEndSample: its end sampled) and
  /// the first crossing is refined by bisection until the point's travel over the interval is
  /// below epsilon / 8 (< epsilon as the paper asks; finer so that small steps still make
  /// progress). The returned time is on the outside end of that interval.
  /// kAccelerated takes the same samples except where the volume's min-max tree proves a run
  /// of segments (or a whole node of the point-shell tree) free of inside points: the same t
  /// (bit for bit); on an exact tie between points, hit_point may name another tied point.
  SweepResult sweep(const RigidMotion& motion, double isovalue) noexcept;
  /// kAccelerated, after a sweep() or resumeSweep() that the work budget cut: whether
  /// that sweep can go on. The contact set must not change meanwhile.
  bool sweepPending() const noexcept { return pending_.active; }
  /// The motion of the last accelerated sweep, kept until the next sweep(): while sweepPending(),
  /// the arc the proxy moves along until the sweep is done.
  const RigidMotion& pendingMotion() const noexcept { return pending_.motion; }
  /// Goes on with the pending sweep where the budget stopped it, with this tick's budget: the
  /// same motion and isovalue, the same samples in the same order as one uncut sweep, so the
  /// same result once it is done (budget_cut false). While still cut, t is the time up to which
  /// every path is proven free so far (non-decreasing from call to call).
  /// Without a pending sweep, returns a still result.
  SweepResult resumeSweep() noexcept;
  /// Forgets the pending sweep (the isovalue changed, the proxy was reset).
  void abandonSweep() noexcept { pending_.active = false; }

  /// Step 2: keeps the contacts that, moved epsilon from X_WP towards X_WD, are inside or move
  /// against their normal (the first-order form of the same test, needed because contacts are
  /// held at a small stand-off clearance); positions, normals and clearances are refreshed at
  /// X_WP.
  void pruneContacts(const Pose& X_WP, const Pose& X_WD, double isovalue) noexcept;

  /// After step 5: adds the point that collided and every point that at time `hit.t` of the
  /// last sweep's `motion` is within epsilon of collision (moving a further epsilon along its
  /// path puts it inside), with normals, to the contact set. Call after sweep() with the same
  /// motion. When the set would exceed contactCap(), the union of the set and the new points is
  /// reduced to contactCap() by farthest-point selection over positions, seeded with the hit
  /// point (capped contact rows keep pruning and the cone projection bounded).
  void addContactsAt(const RigidMotion& motion, const SweepResult& hit, double isovalue) noexcept;

  /// When the sweep's first hit is a point already in the contact set and the proxy could not
  /// move (travel below the bisection tolerance), its eq. 1 normal disagrees with the trilinear
  /// surface there; the contact's normal is replaced by the interpolant's own gradient at the
  /// crossing, which by construction opposes the blocked direction. When the contact already has
  /// the interpolant's normal, the point sits on a crease of the trilinear surface (a cell face):
  /// the new normal joins the set as a second contact of the same point (point_index -1), so the
  /// solver holds both sides of the crease.
  /// @return true when a normal was replaced or added (re-solve steps 3-5 within the tick).
  bool refineStuckContact(const RigidMotion& motion, const SweepResult& hit) noexcept;

  /// Moves the stored contact positions to the proxy pose X_WP (after step 5).
  void refreshPositions(const Pose& X_WP) noexcept;

  /// Marks the points inside the isosurface at pose X_WP as embedded (they do not constrain
  /// the proxy until they are outside again) and releases the embedded ones that are now
  /// outside. Called when the isovalue changed or the proxy was reset (see haptics/README.md).
  /// @return number of embedded points.
  int updateEmbedded(const Pose& X_WP, double isovalue) noexcept;
  /// The largest F over the point shell's points at pose X_WP that are not embedded and lie in
  /// the grid, or `floor` when none exceeds it [data units]. The renderer lowers the isovalue
  /// the hand feels no further than this (HapticRenderer::tick(), "Isovalue changes").
  /// kAccelerated culls the point-shell tree's nodes that cannot exceed the running maximum.
  double maxFieldOnShell(const Pose& X_WP, double floor) noexcept;
  /// Whether the tool's surface between its points meets the isosurface at pose X_WP: each edge
  /// of the point shell's neighbour graph (shellEdges()) whose two ends are not embedded is
  /// tested as a segment with the exact segment test (ScalarVolume::firstEntryOnSegment), so a
  /// wall thinner than the point spacing that lies between two points is found however thin.
  /// kAccelerated culls the point-shell tree's nodes (balls dilated by the longest edge) that
  /// the min-max tree proves empty. Counts its work like a sweep's and shares its budget and
  /// deadline: once they are spent (checked after each point's edges, the first walked point
  /// always done) it stops and returns true with edgeTestCut() set, nothing known past there.
  /// Clearance certificates from its walks are kept across calls (see EdgeClearance), so a
  /// test stopped on one tick skips, on the next, what it proved then where the tool moved less.
  /// On several lanes (setLanes(), kAccelerated) the walk is forked over the lanes' shares of
  /// the tree and gives the one-lane walk's answer and crossing edge (haptics/README.md,
  /// "Between the points"); the budget counts the busiest lane, as a sweep's does.
  bool edgesCrossAt(const Pose& X_WP, double isovalue) noexcept;
  /// Whether the last edgesCrossAt() was stopped by the work budget or the deadline.
  bool edgeTestCut() const noexcept { return edge_cut_; }
  /// The edges edgesCrossAt() found crossing since the last clearCrossingEdges() (at most
  /// kListedEdges, the first ones): whether one of them meets the isosurface at pose X_WP. The
  /// renderer's subdivision of a stopped move tests these only, and then the whole graph once
  /// at the pose it stops at (HapticRenderer, "Between the points" in haptics/README.md).
  bool listedEdgesCrossAt(const Pose& X_WP, double isovalue) noexcept;
  void clearCrossingEdges() noexcept { listed_count_ = 0; }
  static constexpr int kListedEdges = 16;
  /// After edgesCrossAt() found a crossing at a pose a little farther along the move, adds the
  /// point of that edge where the isosurface entered it to the contact set as a contact of the
  /// tool's surface between points (point_index -1), at the proxy's pose X_WP (where it is
  /// free): its normal from the volume's gradient there, so that the configuration solver
  /// slides the tool along the wall it met between its points instead of holding it. A new one
  /// within epsilon / 4 of an earlier edge contact (in T) replaces it; none is added once the
  /// contact set holds the contact cap. Pruned like any contact (pruneContacts()).
  /// @return the contact added or replaced (valid until the contact set changes), or null.
  const Contact* addEdgeContact(const Pose& X_WP, double isovalue) noexcept;
  /// The neighbour graph edgesCrossAt() tests (built in the constructor).
  const ShellEdges& shellEdges() const noexcept { return edges_; }
  /// Re-tests only the embedded points (cheap when there are none).
  int releaseEmbedded(const Pose& X_WP, double isovalue) noexcept;
  int embeddedCount() const noexcept { return embedded_count_; }

  void clearContacts() noexcept;
  std::span<const Contact> contacts() const noexcept { return {contacts_.data(), contact_count_}; }

  /// Trilinear samples taken since the last resetSampleCount() (a gradient counts 6).
  std::int64_t sampleCount() const noexcept { return counters_.samples; }
  /// Min-max tree box queries since the last resetSampleCount() (kAccelerated only).
  std::int64_t boxQueryCount() const noexcept { return counters_.box_queries; }
  /// Min-max tree nodes those box queries read (1 to 64 each: MinMaxTree::rawRange()).
  std::int64_t treeNodeCount() const noexcept { return counters_.tree_nodes; }
  /// Cells walked by the exact segment test whose cubic was examined, since the last resetSampleCount().
  std::int64_t cellCount() const noexcept { return counters_.cells; }
  /// Every cell the exact segment test visited (examined or skipped by its corners).
  std::int64_t cellsWalkedCount() const noexcept { return counters_.cells_walked; }
  /// Relative costs, in trilinear samples, of a min-max tree box query (plus 1 per
  /// kTreeNodesPerWork nodes it reads), of a cell the exact segment test walks, and of the extra
  /// for a cell whose cubic it examines. A least-squares fit of the thread CPU time of 40,000
  /// Engine and Hole ticks (2-core Xeon, 2.0 GHz) to the counts gave 0.044 us per sample, 0.07
  /// per box query, 0.001 to 0.025 per tree node, 0.14 per walked cell and 0.02 to 0.2 more per
  /// examined cell. Walked cells are counted because, uncounted, Hole's worst ticks walked
  /// about 1,200 cells (150 us) beyond their budget.
  static constexpr std::int64_t kBoxQueryWork = 2;
  static constexpr std::int64_t kTreeNodesPerWork = 4;
  /// A box query the bricks could not clear is asked again of the voxels themselves
  /// (ScalarVolume::voxelUpperBoundInBox()) when its box covers at most kVoxelQueryMax voxels
  /// (4 x 4 x 4: a ball of about one voxel's radius); counted as one sample plus one per
  /// kVoxelsPerWork voxels read (an estimate from the tree nodes' cost, not fitted). 64 against
  /// 216 and 512: the same samples saved on table1's scenes, for less reading.
  static constexpr int kVoxelQueryMax = 64;
  static constexpr std::int64_t kVoxelsPerWork = 16;
  static constexpr std::int64_t kCellWalkWork = 3;
  static constexpr std::int64_t kCellWork = 3;
  /// Work since the last resetSampleCount(), in units of one trilinear sample's cost (about
  /// 0.05 us on the machine above): samples + kBoxQueryWork * box queries + tree nodes /
  /// kTreeNodesPerWork + kCellWalkWork * walked cells + kCellWork * examined cells, plus the
  /// other work counted in sample units: a point's path set-up, the contact candidates' sort and
  /// reduction, and addWork().
  std::int64_t work() const noexcept { return counters_.total(); }
  /// The work the budget counts: work() less what the lanes did beside the busiest one while
  /// the sweep ran on several cores (the budget stands for time, and lanes run side by side).
  std::int64_t budgetWork() const noexcept { return counters_.total() - parallel_credit_; }
  /// Work budget per resetSampleCount() period (a servo tick), 0 = none. Once work()
  /// reaches it, sweep() stops at the time up to which every path is proven free (the
  /// time-ordered queue's front; 0 before the queue starts) and addContactsAt() adds only the
  /// hit point: the overshoot is at most one queue step. The proxy never crosses the surface
  /// because of it: it moves less far, and the rest of the motion continues next tick.
  /// Most contacts kept in the set (at least 1, at most the capacity given to the
  /// constructor, which is the default). See addContactsAt().
  void setContactCap(std::size_t cap) noexcept { contact_cap_ = std::clamp<std::size_t>(cap, 1, contacts_.size()); }
  std::size_t contactCap() const noexcept { return std::min(contact_cap_, contacts_.size()); }
  void setWorkBudget(std::int64_t units) noexcept { work_budget_ = units > 0 ? units : 0; }
  /// The deadline on the clock, the budget's last line: once the steady clock passes it, the
  /// detector stops as at an exhausted work budget (the same guarantees: the proxy moves only
  /// as far as every path is proven free, and the sweep goes on next tick). The clock is read
  /// between chunks of work, every kClockCheckWork units (about 10 us), so a tick ends at most
  /// about one chunk past it. Holds until clearDeadline(); resetSampleCount() re-arms it.
  void setDeadline(std::chrono::steady_clock::time_point deadline) noexcept {
    deadline_ = deadline;
    has_deadline_ = true;
    clock_ = {};
  }
  void clearDeadline() noexcept { has_deadline_ = false; }
  /// True when the deadline stopped work since the last resetSampleCount().
  bool deadlineReached() const noexcept { return deadline_hit_ || clock_.late; }
  static constexpr std::int64_t kClockCheckWork = 200;
  /// Runs the accelerated sweep's point-shell walk and time-ordered search on `lanes` cores
  /// (haptics/README.md, "Several cores"): the point-shell tree's upper nodes are dealt round
  /// robin to the lanes for the first sweep, then before each new sweep each to the lane with
  /// the least work so far, weighed by the work the last sweep measured on it (up to 16 lanes,
  /// kMaxBalancedLanes, whose queues then hold room for every point); each lane searches its
  /// points in time order with its own queue, and the lanes share the first time of contact
  /// found so far (an atomic bound). The result is the same first time of contact as one lane (on an exact tie between
  /// points of different lanes, hit_point may name another tied point); the contact pass,
  /// pruning and contact set stay on the caller.
  /// kPaper ignores it. Shares the process's pool of that many lanes (WorkerPool::shared(): lanes - 1
  /// threads started on first use; not on the servo path, call it at set-up).
  /// @throws std::invalid_argument when lanes is outside [1, WorkerPool::kMaxLanes];
  ///         std::system_error when a thread cannot be started.
  void setLanes(int lanes);
  int lanes() const noexcept { return static_cast<int>(lanes_.size()); }
  /// Work done outside the detector that shares the tick's budget (the configuration solver's
  /// cone projection), counted as samples.
  void addWork(std::int64_t units) noexcept { counters_.other += units > 0 ? units : 0; }
  /// True once work() has reached a non-zero work budget.
  bool budgetSpent() const noexcept { return overBudget(); }
  std::int64_t workBudget() const noexcept { return work_budget_; }
  void resetSampleCount() noexcept {
    counters_ = {};
    parallel_credit_ = 0;
    clock_ = {};
    deadline_hit_ = false;
  }

 private:
  struct QueueEntry {
    double t_begin;  // start of the segment to test
    int point;
    std::int64_t segment;  // segment index along the point's path
    // kAccelerated: segments [segment, segment + run) are not yet proven empty; 0 means sample
    // the end of `segment` directly (the paper's step).
    std::int64_t run = 0;
  };
  // Node of the point-shell tree (kAccelerated): a ball in T holding points order_[begin, end).
  struct ShellNode {
    Eigen::Vector3d center_T_m = Eigen::Vector3d::Zero();
    double radius_m = 0.0;
    int begin = 0, end = 0;
    int left = -1, right = -1;  // children, -1 for a leaf
  };
  // Work counted in the units of work() (see there), per thread of work.
  struct WorkCounters {
    std::int64_t samples = 0, box_queries = 0, tree_nodes = 0, cells_walked = 0, cells = 0;
    std::int64_t voxel_queries = 0, voxels = 0;  // voxel-level box queries and the voxels they read
    std::int64_t other = 0;  // beyond samples, cells and box queries (sample units)
    std::int64_t total() const noexcept {
      return samples + other + kCellWork * cells + kCellWalkWork * cells_walked + kBoxQueryWork * box_queries +
             voxel_queries + voxels / kVoxelsPerWork + tree_nodes / kTreeNodesPerWork;
    }
    WorkCounters& operator+=(const WorkCounters& o) noexcept {
      samples += o.samples;
      box_queries += o.box_queries;
      voxel_queries += o.voxel_queries;
      voxels += o.voxels;
      tree_nodes += o.tree_nodes;
      cells_walked += o.cells_walked;
      cells += o.cells;
      other += o.other;
      return *this;
    }
  };
  // When the clock was last read, in work units, and whether the deadline had passed then.
  struct ClockCheck {
    std::int64_t next = 0;
    bool late = false;
  };
  // One lane of the accelerated sweep (setLanes()): its share of the point-shell tree, its own
  // queue and counters. Lane 0 runs on the caller.
  struct alignas(64) Lane {  // a cache line of its own: the lanes write their counters all the time
    WorkCounters counters;
    ClockCheck clock;
    std::int64_t base_work = 0;       // budgetWork() when the lanes were forked
    std::vector<int> roots;           // point-shell tree nodes it walks, in order
    std::vector<QueueEntry> heap;     // capacity: its points
    std::vector<int> stack;           // traversal stack, capacity = nodes
    // collectActive(): the nodes its walk reached, in walk order (~node when culled), capacity =
    // nodes; read backwards when the walk is done, to mark the nodes it found near the surface.
    std::vector<int> walk_log;
    std::size_t walk_logged = 0;
    std::vector<int> active;          // its points not culled by the walk, capacity: its points
    std::size_t active_count = 0;
    std::size_t queued = 0;           // heap entries of the contact pass (at the front)
    std::size_t count = 0;            // heap entries
    std::size_t walk_count = 0;       // collectActive(): entries written when the budget stopped it
    int walk_top = 0;                 // collectActive(): stack height when the budget stopped it
    int phase = 0;                    // 1: walk, 2: time-ordered queue, 3: done
    bool walk_stopped = false;        // the walk was stopped by the budget
    bool pop_pending = false;
    bool cut = false;                 // stopped by the budget; proven free over [0, cut_t]
    double cut_t = 0.0;
    SweepResult result;               // its first hit so far
    std::vector<int> root_ranks;      // per root: its place in the single-lane walk's order
    // Per rank (frontier_): the work this lane did on that root since the last rebalance
    // (only the lane holding a root writes its entry; rebalanceLanes() reads and clears it).
    std::vector<std::int64_t> root_work;
    std::size_t walk_root = 0;        // collectActive(): roots started so far
    // Its share of a forked edge test (edgesCrossAt()): the rank of the root where it found the
    // first crossing edge (j, k) or was stopped by the budget; INT_MAX: neither.
    int edge_rank = std::numeric_limits<int>::max(), edge_cut_rank = std::numeric_limits<int>::max();
    int edge_j = -1, edge_k = -1;
  };  // (alignas rounds its size up to whole lines: nothing of the next lane shares its last line)
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
  // The state of an accelerated sweep between ticks (a cut sweep resumes on the next tick).
  struct PendingSweep {
    bool active = false;         // a cut sweep can be resumed
    RigidMotion motion;
    double isovalue = 0.0;
    int phase = 0;               // 0: contact points, 1: the lanes (walk, then time-ordered queue)
    std::size_t contact_index = 0;
    double walk_t = 1.0;         // the lanes walk the tree over [0, walk_t] (the contact pass's hit)
    SweepResult result;          // first hit of the contact pass
  };
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
  // collectActive()'s arc over [0, t_max]: the tool's rotation and its centre of mass in W [m]
  // at t_max / 2, about which the balls that hold a node's points' arcs, or one point's, are
  // centred; with `queue`, each point's path is tested and queued.
  struct WalkArc {
    const RigidMotion& motion;
    double t_max;
    double isovalue;
    bool queue;
    Eigen::Matrix3d R_mid;
    Eigen::Vector3d c_mid_W_m;
  };
  // The ball in W about `node`'s centre at t_max / 2 that holds its points' arcs over [0, t_max]
  // plus epsilon of further travel: returns its radius [m], its centre in centre_W [m].
  inline double nodeBall(const WalkArc& arc, const ShellNode& node, Eigen::Vector3d& centre_W) const noexcept;
  // F's steps per grid axis over a leaf's ball (ScalarVolume::gridStepRange()), read at its
  // first near point: state 0 not read yet, 1 read, -1 the ball leaves the grid.
  struct LeafSteps {
    int state = 0;
    Eigen::Vector3d lo, hi;
  };
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
  struct EdgeJob {
    Pose X_WP;
    double isovalue = 0.0;
  } edge_job_;
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
  // Temporal coherence of the edge test (haptics/README.md, "Between the points"): per point j,
  // the clearances proven for all of j's edges at the last two poses they were found free at,
  // by the exact walk or by the box query around them. Until the tool has moved j's edges that
  // far, they cannot meet the isosurface (the field only ever decreases under drilling), and
  // neither is done again.
  struct EdgeClearance {
    Eigen::Vector3d p_W_m = Eigen::Vector3d::Zero();               // point j at that pose, in W [m]
    Eigen::Quaterniond R_WT = Eigen::Quaterniond::Identity();      // the tool's orientation there
    double clearance_m = -1.0;                                     // <= 0: nothing proven
    // The lever the tool's turn since then acts on: j's edge reach plus epsilon for the exact
    // walk's certificate (its clearance is from the edges themselves); 0 for a box query's (its
    // clearance is the margin of a ball about point j that holds j's edges however it turns).
    double arm_m = 0.0;
    // The exact walk's directional certificate: F - s <= -margin on all of j's edges there, and
    // F's derivative per grid step along each grid axis within [step_lo, step_hi] over the
    // cells their box reaches, reach_lo below it and reach_hi above it along each grid axis (at
    // least kCertificateReachSteps: the whole step bricks read, ScalarVolume::gridStepRange());
    // margin <= 0: none. A tool sliding along a wall moves its edges along the wall, where F
    // hardly changes, and away from it, where F falls: a bound that knows the move's direction
    // keeps them proven for many ticks where the distance (clearance_m) lasts about one.
    // Floats rounded outward (the ranges) and inward (the reaches): 128 bytes a certificate.
    double margin = -1.0;
    Eigen::Vector3f step_lo = Eigen::Vector3f::Zero(), step_hi = Eigen::Vector3f::Zero();
    Eigen::Vector3f reach_lo = Eigen::Vector3f::Zero(), reach_hi = Eigen::Vector3f::Zero();  // grid steps
  };
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
  // The last edge edgesCrossAt() found crossing: its ends and the pose it was tested at.
  struct EdgeHit {
    int j = -1, k = -1;
    Pose X_WP;
  } edge_hit_;
  DetectionMode mode_;
  SegmentTest segment_test_;
  double feature_;
  double max_sagitta_ = 0.0;  // kExact: largest chord sagitta of an arc [m]
  double shell_radius_m_ = 0.0;  // largest |p_T - Cm| over the point shell
  double sweep_sagitta_ = 0.0;   // per sweep: largest sagitta_[j] of any point (node tests)
  double segment_length_m_;  // feature size * segment_fraction
  double epsilon_;
  double bisection_tolerance_;
  // Per point, the path of the current sweep: one cache line per point, so that lanes working on
  // different points never write to the same line. Every point the tree walk reaches is set up
  // here (setupPath()); most are then culled by their own ball and touch nothing else.
  struct alignas(64) PointState {
    Eigen::Vector3d r0 = Eigen::Vector3d::Zero();  // radial vector at t = 0 (W)
    double dt = 1.0;                // segment length in time
    double path = 0.0;              // path-length bound
    double sagitta = 0.0;           // its chords' sagitta [m] (kExact with rotation, else 0)
    double clear_until = 0.0;       // kAccelerated: proven outside over [0, clear_until] of the last sweep
    std::int32_t segments = 0;      // kAccelerated: segment count of the last sweep
    // kAccelerated: the last sweep's exact walk of this point examined a cell (a cell with a
    // corner above the threshold: the surface is within a voxel of its path), or a near point's
    // path was proven free along its direction. The next sweep then tests it along its
    // direction and walks it without first asking the min-max tree about its path's ball, which
    // near the surface only says "may hit" (a point resting on the surface, or sliding along it).
    std::uint8_t near_surface = 0;
  };
  static_assert(sizeof(PointState) == 64, "one cache line per point");
  std::vector<PointState> pt_;
  // Per point, the search's own state: touched only for the points that are sampled or queued
  // (a line of its own per point, as PointState).
  struct alignas(64) PointSearch {
    Eigen::Vector3d chord_end_ijk = Eigen::Vector3d::Zero();  // grid coordinates of the last chord's end
    double chord_end_t = -1.0;          // ... the last chord end's time
    std::int64_t clear_segments = 0;    // kAccelerated: leading segments proven empty
    std::uint32_t chord_end_stamp = 0;  // the chord end is valid when equal to chord_stamp_ (this sweep)
    unsigned char backoff = 0;          // kAccelerated: direct steps after a failed test = 2^backoff
  };
  std::vector<PointSearch> search_;
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
  bool pastDeadline(ClockCheck& clock, std::int64_t work) const noexcept {
    if (!has_deadline_) return false;
    if (clock.late) return true;
    if (work < clock.next) return false;
    clock.next = work + kClockCheckWork;
    clock.late = std::chrono::steady_clock::now() >= deadline_;
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

}  // namespace vh::haptics
