#pragma once
/// @file
/// Continuous collision detection of the point shell against the isosurface F = s along the
/// proxy's motion arc (paper section 2.3) and contact-set pruning (step 2).

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <memory>
#include <span>

#include "vh/haptics/contact_set.h"
#include "vh/haptics/pose.h"
#include "vh/haptics/rigid_motion.h"
#include "vh/haptics/scalar_volume.h"
#include "vh/haptics/sweep.h"
#include "vh/haptics/tool_model.h"

namespace vh::haptics {

/// What the edge test between the points (haptics/README.md, "Between the points") did with the
/// points it reached: each point's edges were held by a clearance certificate of an earlier
/// test, proven free by one box query of the min-max tree, or walked with the exact segment
/// test (`edges_walked` edges in all). Diagnostics of its cost: the walks and the box queries
/// are its work (CollisionDetector::work()); counts, no units.
struct EdgeTestCounts {
  std::int64_t points_held = 0;    ///< Points whose edges a certificate held (no query).
  std::int64_t points_boxed = 0;   ///< Points whose edges one box query proved free.
  std::int64_t points_walked = 0;  ///< Points whose edges were walked cell by cell.
  std::int64_t edges_walked = 0;   ///< Edges those walks tested.
};

/// Collision detector for one point shell against one volume. Owns the contact set and all
/// working memory (sized at construction): no member allocates after construction. A facade:
/// its parts (the paper's sweep, the accelerated sweep and its lanes, the contact set, the
/// edge test) live in haptics/src behind one pointer (collision_detector_impl.h). Movable, not
/// copyable; a moved-from detector may only be destroyed or assigned to.
class CollisionDetector {
 public:
  /// @param epsilon_m collision tolerance; 0 selects f / 8 (f = feature size; chosen by `bench accuracy`).
  /// @param max_contacts capacity of the contact set.
  /// @param mode which sweep path runs (both give the same contract).
  /// @param segment_fraction longest sampling segment along a path as a fraction of the
  ///        feature size f, in (0, 1]; 1 is the paper's ceil(s / f) segments (section 2.3).
  /// @param segment_test how each segment is tested (kExact: never misses a thin feature).
  /// @throws std::invalid_argument when epsilon_m >= f, the point shell or the volume is empty,
  ///         or segment_fraction is outside (0, 1].
  CollisionDetector(const ScalarVolume& volume, const ToolModel& tool, double epsilon_m,
                    std::size_t max_contacts = 256, DetectionMode mode = DetectionMode::kAccelerated,
                    double segment_fraction = 1.0, SegmentTest segment_test = SegmentTest::kExact);
  ~CollisionDetector();
  CollisionDetector(CollisionDetector&&) noexcept;
  CollisionDetector& operator=(CollisionDetector&&) noexcept;

  /// A finished sweep with a hit stops this fraction of epsilon of the hit point's own travel
  /// before the bisection bracket's outside end (proven free), so that a contact is never left
  /// a rounding error from the surface, where a turn along the surface would hold it for good.
  static constexpr double kStopClearanceFraction = 1.0 / 128.0;

  DetectionMode mode() const noexcept;
  SegmentTest segmentTest() const noexcept;
  /// Largest deviation of a rotating point's arc from the chords it is tested along [m]
  /// (kExact: epsilon / 64; see haptics/README.md, "Never through").
  double maxSagitta_m() const noexcept;

  double epsilon_m() const noexcept;
  double featureSize_m() const noexcept;
  /// Largest distance of a shell point from the tool's centre of mass [m] (T).
  double shellRadius_m() const noexcept;

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
  bool sweepPending() const noexcept;
  /// The motion of the last accelerated sweep, kept until the next sweep(): while sweepPending(),
  /// the arc the proxy moves along until the sweep is done.
  const RigidMotion& pendingMotion() const noexcept;
  /// Goes on with the pending sweep where the budget stopped it, with this tick's budget: the
  /// same motion and isovalue, the same samples in the same order as one uncut sweep, so the
  /// same result once it is done (budget_cut false). While still cut, t is the time up to which
  /// every path is proven free so far (non-decreasing from call to call).
  /// Without a pending sweep, returns a still result.
  SweepResult resumeSweep() noexcept;
  /// Forgets the pending sweep (the isovalue changed, the proxy was reset).
  void abandonSweep() noexcept;
  /// The field was rewritten between ticks and may have risen somewhere (deformable tissue
  /// rewrites the renderer's private copy): forgets the pending sweep, and weakens the edge
  /// test's clearance certificates (which assume a field that only falls, as drilling's) by
  /// `max_rise`: the most F rose at any voxel since the last call [F units] (a bound on the
  /// trilinear interpolant's rise everywhere: each value is a convex combination of voxels).
  /// A directional certificate then holds with its margin less the rises since it was made;
  /// the distance certificates made before end. When `max_rise` is not finite and >= 0 (unknown,
  /// the default), every certificate is forgotten. The caller must not understate it: a
  /// certificate would then hide an edge the rise carried into the surface. No allocation.
  void forgetFieldProofs(double max_rise = std::numeric_limits<double>::infinity()) noexcept;
  /// After the field was rewritten: each contact is measured again at the proxy pose X_WP and
  /// released when it is now farther than `clearance_m` from the isosurface (the surface moved
  /// away from it: it no longer holds the proxy, which may follow the surface). No allocation.
  void releaseClearContacts(const Pose& X_WP, double isovalue, double clearance_m) noexcept;

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
  bool edgeTestCut() const noexcept;
  /// The edges edgesCrossAt() found crossing since the last clearCrossingEdges() (at most
  /// kListedEdges, the first ones): whether one of them meets the isosurface at pose X_WP. The
  /// renderer's subdivision of a stopped move tests these only, and then the whole graph once
  /// at the pose it stops at (HapticRenderer, "Between the points" in haptics/README.md).
  bool listedEdgesCrossAt(const Pose& X_WP, double isovalue) noexcept;
  void clearCrossingEdges() noexcept;
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
  const ShellEdges& shellEdges() const noexcept;
  /// Re-tests only the embedded points (cheap when there are none).
  int releaseEmbedded(const Pose& X_WP, double isovalue) noexcept;
  int embeddedCount() const noexcept;

  void clearContacts() noexcept;
  std::span<const Contact> contacts() const noexcept;

  /// Trilinear samples taken since the last resetSampleCount() (a gradient counts 6).
  std::int64_t sampleCount() const noexcept;
  /// Min-max tree box queries since the last resetSampleCount() (kAccelerated only).
  std::int64_t boxQueryCount() const noexcept;
  /// Min-max tree nodes those box queries read (1 to 64 each: MinMaxTree::rawRange()).
  std::int64_t treeNodeCount() const noexcept;
  /// Cells walked by the exact segment test whose cubic was examined, since the last resetSampleCount().
  std::int64_t cellCount() const noexcept;
  /// Every cell the exact segment test visited (examined or skipped by its corners).
  std::int64_t cellsWalkedCount() const noexcept;
  /// What the edge test decided for each point it reached since the last resetSampleCount()
  /// (edgesCrossAt(); a point with edges counts once per whole-graph test that reaches it).
  EdgeTestCounts edgeTestCounts() const noexcept;
  /// Work since the last resetSampleCount(), in units of one trilinear sample's cost (about
  /// 0.05 us on a 2-core 2.0 GHz Xeon): samples plus box queries, tree nodes, walked and
  /// examined cells, each weighed by its cost in samples (fitted to measured thread CPU time;
  /// the weights are in haptics/src/detector_work.h), plus the other work counted in sample
  /// units: a point's path set-up, the contact candidates' sort and reduction, and addWork().
  std::int64_t work() const noexcept;
  /// The work the budget counts: work() less what the lanes did beside the busiest one while
  /// the sweep ran on several cores (the budget stands for time, and lanes run side by side).
  std::int64_t budgetWork() const noexcept;
  /// Most contacts kept in the set (at least 1, at most the capacity given to the
  /// constructor, which is the default). See addContactsAt().
  void setContactCap(std::size_t cap) noexcept;
  std::size_t contactCap() const noexcept;
  /// Work budget per resetSampleCount() period (a servo tick), 0 = none. Once budgetWork()
  /// reaches it, sweep() stops at the time up to which every path is proven free (the
  /// time-ordered queue's front; 0 before the queue starts) and addContactsAt() adds only the
  /// hit point: the overshoot is at most one queue step. The proxy never crosses the surface
  /// because of it: it moves less far, and the rest of the motion continues next tick.
  void setWorkBudget(std::int64_t units) noexcept;
  /// The deadline on the clock, the budget's last line: once the steady clock passes it, the
  /// detector stops as at an exhausted work budget (the same guarantees: the proxy moves only
  /// as far as every path is proven free, and the sweep goes on next tick). The clock is read
  /// between chunks of work, every kClockCheckWork units (about 10 us), so a tick ends at most
  /// about one chunk past it. Holds until clearDeadline(); resetSampleCount() re-arms it.
  void setDeadline(std::chrono::steady_clock::time_point deadline) noexcept;
  void clearDeadline() noexcept;
  /// True when the deadline stopped work since the last resetSampleCount().
  bool deadlineReached() const noexcept;
  /// The deadline as work instead of time, for a replay (no clock) of a tick the clock cut:
  /// the clock's reads (every kClockCheckWork units) find it passed from the first read at or
  /// above `work` - 1 units of budgetWork() on. Given the deadlineWork() of the live tick, the same
  /// read stops the same work, so the tick ends as it did (exact on one lane; on several the
  /// lanes' shares of the work are not repeatable). Holds until set to 0; resetSampleCount()
  /// re-arms it.
  void setWorkDeadline(std::int64_t work) noexcept;
  /// 1 + the work (budgetWork()) at the clock's read that found the deadline passed since the
  /// last resetSampleCount() (of the first lane that found it, with several); 0 when none did.
  /// (The 1 keeps a read at work 0, a tick late from its start, apart from none.)
  std::int64_t deadlineWork() const noexcept;
  static constexpr std::int64_t kClockCheckWork = 200;
  /// Runs the accelerated sweep's point-shell walk and time-ordered search on `lanes` cores
  /// (haptics/README.md, "Several cores"): the point-shell tree's upper nodes are dealt round
  /// robin to the lanes for the first sweep, then before each new sweep each to the lane with
  /// the least work so far, weighed by the work the last sweep measured on it (up to 16 lanes,
  /// kMaxBalancedLanes, whose queues then hold room for every point); each lane searches its
  /// points in time order with its own queue, and the lanes share the first time of contact
  /// found so far (an atomic bound). The result is the same first time of contact as one lane
  /// (on an exact tie between points of different lanes, hit_point may name another tied
  /// point); the contact pass, pruning and contact set stay on the caller. kPaper ignores it.
  /// Shares the process's pool of that many lanes (WorkerPool::shared(): lanes - 1 threads
  /// started on first use; not on the servo path, call it at set-up).
  /// @throws std::invalid_argument when lanes is outside [1, WorkerPool::kMaxLanes];
  ///         std::system_error when a thread cannot be started.
  void setLanes(int lanes);
  int lanes() const noexcept;
  /// Work done outside the detector that shares the tick's budget (the configuration solver's
  /// cone projection), counted as samples.
  void addWork(std::int64_t units) noexcept;
  /// True once work() has reached a non-zero work budget.
  bool budgetSpent() const noexcept;
  std::int64_t workBudget() const noexcept;
  void resetSampleCount() noexcept;

 private:
  class Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace vh::haptics
