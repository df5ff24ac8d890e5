#pragma once
/// @file
/// One servo tick of the constraint-based 6-DOF rendering algorithm (paper section 2.1):
///   1. unconstrained motion from the proxy to the device configuration     (configuration solver)
///   2. verify and prune the contact set                                     (collision detector)
///   3. constrained motion from the contact set, Gauss' principle, eq. 3-4  (configuration solver)
///   4. continuous collision detection along the constrained path           (collision detector)
///   5. move the proxy to the first contact (or the target)                  (configuration solver)
///   6. force and torque from the virtual coupling, eq. 5                    (virtual coupling)
///
/// Frames: W = the volume's physical frame [m]; T = tool frame; D = the device's tool frame
/// (where the device holds the tool); P = the proxy's tool frame. Forces are expressed in W and
/// act on the user's hand at the tool's centre of mass.

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <limits>
#include <memory>
#include <span>

#include <Eigen/Core>

#include "vh/haptics/collision_detector.h"
#include "vh/haptics/configuration_solver.h"
#include "vh/haptics/pose.h"
#include "vh/haptics/scalar_volume.h"
#include "vh/haptics/tool_model.h"
#include "vh/haptics/virtual_coupling.h"

namespace vh::haptics {

/// Settings of the renderer; constant while it runs except where noted.
struct RendererOptions {
  /// Collision tolerance epsilon [m] (section 2.3); 0 selects feature size / 8 (chosen by `bench accuracy`). Must be < f.
  double epsilon_m = 0.0;
  /// Optional clearance kept between contact points and the surface, as a fraction of epsilon
  /// (see ConfigurationSolver::standoffTranslation); 0, the default, is the paper's plain
  /// behaviour. Measured: once blocked contacts get crossing normals it is not needed (CT phantom
  /// slide, curved surfaces), and a lift drove a hook hanging from one contact into a 2-cycle.
  /// When set, it is applied only on the tick after one whose sweep stopped before 1 % of its
  /// path, and not while points are embedded after an isovalue change.
  double standoff_fraction = 0.0;
  /// The lift after a stuck contact, as a fraction of epsilon: after two moves in a row that a
  /// point stopped before 1 % of their path, the next solve lifts contacts to at least this
  /// (a probe spun about its shaft on a ball at 2 mm point spacing: its one contact creeps along
  /// the interpolant's bumps to zero clearance and, without it, holds the turn at 0.43 of 0.5
  /// rad). -1 (default): 0.25 in kAccelerated, 0 in kPaper (the paper's algorithm as
  /// published); 0 off.
  double stuck_standoff_fraction = -1.0;
  /// Collision-detection path: the paper's (section 2.3) or the accelerated one with the same
  /// contract (haptics/README.md, "Speed").
  DetectionMode detection_mode = DetectionMode::kAccelerated;
  /// Longest sampling segment along a point's path as a fraction of the feature size, (0, 1];
  /// 1 is the paper's (section 2.3). Smaller trades time for catching thinner features.
  double segment_fraction = 1.0;
  /// How each segment is tested: kExact (default) finds a feature of any thickness; kEndSample
  /// is the earlier end-sample test, kept for the before/after benchmark (see SegmentTest).
  SegmentTest segment_test = SegmentTest::kExact;
  /// Work per tick, in units of one trilinear sample's cost (CollisionDetector::work(): samples,
  /// cells and box queries weighted by their measured cost, plus the cone projection's rows);
  /// 0 = unbounded (the default). Pruning, the solve and the sweep share it, so a tick
  /// respects a time budget. When it runs out, the proxy moves only as far as every
  /// point is proven free; kAccelerated then resumes the same sweep on the next ticks where it
  /// stopped (no work is lost, so it always finishes; shortening the next motion would not
  /// help much, as a sweep's cost near a surface is mostly the points it must look at, and
  /// max_travel_per_tick_m bounds the rest). kPaper starts over with a halved step (down to
  /// 1/4096, doubling back after each tick that finishes; its sweep samples every point's first segment, so a
  /// budget below the point count stalls it: the paper-faithful runs set 0). The overshoot is at
  /// most one queue step, and the pruning of a full contact set before the sweep (about 8 units
  /// per contact). The default, 150,000 units, is more than the servo period on every tool
  /// measured (a unit cost 18 ns with Engine's 2,126-point wrench, 15 ns with its 20,000-point
  /// one, 7 to 10 ns with its 50,000-point one, on a 2.6 GHz EPYC core): where the application
  /// sets deadline_us (900 us) the clock decides and the budget is the last line of defence,
  /// not the way the deadline is met. At 40,000 (0.4 to 0.7 ms there) it cut 1,015 of the
  /// 20,000-point wrench's 5,000 table1 ticks, where the clock alone cut 53; at 12,000 it cut
  /// 101 Engine ticks whose full solve took under 0.5 ms.
  /// -1 (the default) selects kDefaultWorkBudget in kAccelerated and no budget in kPaper.
  static constexpr std::int64_t kDefaultWorkBudget = 150000;
  std::int64_t work_budget = -1;
  /// The velocity limit of section 2.3: no point of the shell travels farther than
  /// this in one tick [m] (bound |v| + |omega| R, R the shell's radius about the centre of
  /// mass); the constrained motion is scaled down along itself. 0 = unbounded (the paper's).
  /// At 1 kHz the default 4 mm is 4 m/s at the farthest point of the tool; it keeps a lagging
  /// tool's catch-up ticks short (a 0.3 rad turn of the 150 mm wrench swept 22 mm per tick).
  double max_travel_per_tick_m = 0.004;
  /// The same limit while the tool is in contact (the contact set not empty when the tick's
  /// motion is solved) [m]; 0 = as max_travel_per_tick_m. In contact nearly every point of a
  /// tool lying on a surface or held in a snug hole is near the isosurface, so a sweep's work
  /// grows with the step: the peg turned in its hole at 4 mm a tick took up to 1.5-2.1 ms, at 2
  /// mm under 0.85 ms (haptics/README.md, "Never late"). The default 2 mm is 2 m/s at the
  /// farthest point of the tool, faster than a hand slides a tool along bone.
  double max_travel_in_contact_per_tick_m = 0.002;
  /// Most contacts in the contact set, 1 to 256: more are reduced by farthest-point
  /// selection (CollisionDetector::addContactsAt()), which bounds the pruning (about 12 work
  /// units per contact) and the cone projection's rows. 256, the set's capacity, is the paper's
  /// path (table1's paper mode); the cap never lets the proxy penetrate (the sweep tests every
  /// point, in the set or not).
  int max_contacts = 64;
  /// Coupling gains (section 2.5); may be changed between ticks with setGains().
  CouplingGains gains;
  /// The tool's surface between its points (haptics/README.md, "Between the points"): after
  /// each move, the point shell's neighbour edges are tested at the new pose; when one meets
  /// the isosurface, the move is subdivided and the proxy stops before the first sub-step where
  /// one does. 0 (default) off; 1 on; -1 on in kAccelerated with SegmentTest::kExact, off in
  /// kPaper (the paper's algorithm as published). It shares the tick's work budget and deadline
  /// (a test they stop holds the proxy where it is, and the next ticks take shorter steps); off
  /// by default for its mean cost (haptics/README.md, "Between the points").
  int edge_test = 0;
  /// With the edge test: the edges are also tested at poses along every move, at most a quarter
  /// of the point spacing apart at the farthest point, not only where it ends (haptics/README.md,
  /// "Between the points": what that catches and what it costs). false (default): at the move's
  /// end only, so a feature shorter than a move can enter the tool's surface between its points
  /// and leave it again within that move; on, Engine's wrench had 55 of 4,000 ticks cut by the
  /// deadline (4 at the end only) and its proxy up to 4.5 mm farther behind the device.
  bool edge_test_swept = false;
  /// Largest distance accepted between the device pose and the proxy [m]; a device farther
  /// from the proxy is treated as bad input (zero force, the proxy stays). A last line only:
  /// implausible jumps between samples are rejected before the renderer, at the coupling
  /// thread (runtime's SampleFilter, with each device's speed limit).
  double max_device_distance_m = 10.0;
  /// Cores the accelerated sweep runs on (CollisionDetector::setLanes(); haptics/README.md,
  /// "Several cores"): the caller plus solver_lanes - 1 pool threads, which spin between the
  /// forks of a tick. 1 (default): no thread is started. The result does not depend on it.
  int solver_lanes = 1;
  /// The tick's deadline on the clock [us after tick() starts], the work budget's last line
  /// (CollisionDetector::setDeadline()): past it the tick stops as at an exhausted budget, so a
  /// busy machine cannot push a tick past its servo period. 0 (default): none, and every
  /// result is independent of timing (tests, replays). The application's solver thread sets it.
  double deadline_us = 0.0;
};

/// Statistics of one tick.
struct TickStats {
  double exec_time_us = 0.0;        ///< Wall time of the tick [us].
  int contacts = 0;                 ///< Contact set size after the tick.
  std::int64_t volume_samples = 0;  ///< Trilinear F samples taken (a gradient counts 6).
  std::int64_t box_queries = 0;     ///< Min-max tree box queries (kAccelerated; 0 for kPaper).
  std::int64_t tree_nodes = 0;      ///< Min-max tree nodes those queries read (1 to 64 each).
  std::int64_t cells = 0;           ///< Cells whose cubic the exact segment test examined.
  std::int64_t cells_walked = 0;    ///< Cells the exact segment test visited (examined or skipped).
  std::int64_t work = 0;            ///< CollisionDetector::work(): samples, box queries, tree nodes, cells (RendererOptions::work_budget's unit).
  /// CollisionDetector::budgetWork(): the tick's work on its critical path, the busiest lane's
  /// share of each forked part plus the serial rest (what the work budget counts). work /
  /// (lanes x critical_work) is how evenly the lanes shared the tick (1 = perfectly).
  std::int64_t critical_work = 0;
  /// The work budget was reached: the sweep stopped before its end (and goes on next tick), or
  /// the contact update or the re-solve was shortened.
  bool budget_cut = false;
  /// Of those, the deadline on the clock stopped it (RendererOptions::deadline_us).
  bool deadline_cut = false;
  /// With deadline_cut: 1 + the work [sample units] at the clock's read that found the deadline
  /// passed (CollisionDetector::deadlineWork()); 0 otherwise. Handed to
  /// HapticRenderer::cutNextTickAtWork() for the same sample in the same state, a tick with no
  /// clock stops where this one did, so a recording of a busy machine replays bit for bit.
  std::int64_t deadline_work = 0;
  double time_of_contact = 1.0;     ///< Fraction of the constrained path travelled (1 = free).
  /// Wall time of the tick's phases [us] (diagnostics; they sum to about exec_time_us):
  /// embedded-point scan and step 2 (prune), steps 1 + 3 (solve, every attempt), step 4 (sweep,
  /// every attempt), step 5's contact update (contacts).
  double prune_us = 0.0, solve_us = 0.0, sweep_us = 0.0, contacts_us = 0.0;
  /// The edge test's own wall time [us] (RendererOptions::edge_test: its whole-graph tests, the
  /// subdivision of a stopped move and the contact that adds; part of contacts_us on a tick
  /// that sweeps); 0 without it. The rest of the tick cost exec_time_us - edge_us.
  double edge_us = 0.0;
  /// What the edge test did with the points it reached this tick (CollisionDetector::
  /// edgeTestCounts()): its cost grows with the points walked, those near the surface whose
  /// certificates the move outran.
  EdgeTestCounts edge_test_counts;
  /// Sweeps this tick ran (steps 3-4 solved again after a stuck contact's normal was refined:
  /// 1 to 3; 0 on a tick that only resumed a cut sweep or rejected its sample).
  int sweeps = 0;
  bool bad_input = false;           ///< The device pose was rejected this tick.
  /// The move was shortened because the tool's surface between two shell points would have met
  /// the isosurface (RendererOptions::edge_test).
  bool edge_stop = false;
  /// The isovalue the hand felt this tick [data units]: the requested one, except while a
  /// lowered isovalue would swallow part of the proxy; then the lowest value that swallows none
  /// (haptics/README.md, "Isovalue changes"). NaN until the first tick.
  double felt_isovalue = std::numeric_limits<double>::quiet_NaN();
};

/// Result of one tick.
struct TickOutput {
  Pose X_WP;                                          ///< Proxy pose after the tick.
  Eigen::Vector3d force_W_N = Eigen::Vector3d::Zero();   ///< Force on the user's hand, in W [N].
  Eigen::Vector3d torque_W_Nm = Eigen::Vector3d::Zero(); ///< Torque on the hand about Cm, W [N*m].
  TickStats stats;
};

/// The haptic rendering algorithm for one tool against one volume.
/// Owns all working memory, sized at construction: tick() never allocates, throws or blocks.
/// Not thread safe: one thread (the servo thread) calls tick(); others read snapshots it
/// publishes elsewhere.
class HapticRenderer {
 public:
  /// @param volume, tool shared, immutable; must outlive nothing (held by shared_ptr).
  /// @param X_WP_initial initial proxy pose; should be outside the isosurface.
  /// @throws std::invalid_argument for an empty volume or point shell, a non-finite pose,
  ///         epsilon >= feature size, segment_fraction outside (0, 1], max_contacts outside
  ///         [1, 256], a negative or non-finite deadline_us, max_travel_per_tick_m or
  ///         max_travel_in_contact_per_tick_m.
  HapticRenderer(std::shared_ptr<const ScalarVolume> volume, std::shared_ptr<const ToolModel> tool,
                 const RendererOptions& options, const Pose& X_WP_initial, double isovalue);

  /// Runs the six steps once for the device pose X_WD and the requested isovalue s (data
  /// units). A raised isovalue takes effect on this tick; a lowered one moves the surface
  /// towards the tool and is felt only as far as it swallows no point of the proxy (the rest
  /// follows, tick by tick, as the tool moves away: TickStats::felt_isovalue).
  /// A non-finite pose, a quaternion whose norm is off by more than 1e-3, or a jump beyond
  /// max_device_distance_m yields zero force, leaves the proxy in place and counts a bad sample.
  TickOutput tick(const Pose& X_WD, double isovalue) noexcept;
  /// The next tick() stops its work as if the deadline had passed at `work` sample units
  /// (TickStats::deadline_work of the live tick it repeats; CollisionDetector::setWorkDeadline()):
  /// how a replay, which has no clock, repeats a tick the live solver's deadline cut. Applies to
  /// one tick only; 0 or less: none.
  void cutNextTickAtWork(std::int64_t work) noexcept { next_tick_deadline_work_ = work > 0 ? work : 0; }

  /// Moves the proxy (and clears the contact set) without collision checking.
  void resetProxy(const Pose& X_WP) noexcept;
  /// The volume was rewritten between ticks by its owner and F may have risen somewhere
  /// (deformable tissue writes its deformed field into the renderer's copy; drilling only lowers
  /// F and needs no call). The proxy and its contact set stay (step 2 verifies the contacts
  /// against the new field); what was proven about the old field is dropped: a pending cut
  /// sweep and the proof of the proxy's pose, and the embedded points are scanned again. The
  /// edge test's certificates are weakened by `max_rise_F`, the most any voxel's value rose
  /// since the last call [F units] (CollisionDetector::forgetFieldProofs(): those with margin
  /// left are kept), or all dropped when it is unknown (not finite and >= 0, the default); it
  /// must not be understated. The writer must leave no point of the proxy inside (it is then
  /// never inside: tissue's felt deformation, vh::tissue::DeformableScene). No allocation.
  void noteFieldChanged(double max_rise_F = std::numeric_limits<double>::infinity()) noexcept;
  /// The surface moved onto the proxy and carries it (deformable tissue springing back under a
  /// held tool, the proxy being massless): the proxy is translated by `dp_W_m` [m, frame W]
  /// without collision checking (the writer checked that no point of the moved proxy is inside
  /// the new field); its contact set is dropped and found again by the next tick, the coupling's
  /// tracking kept. Call noteFieldChanged() after. A non-finite `dp_W_m` changes nothing. No
  /// allocation.
  void carryProxy(const Eigen::Vector3d& dp_W_m) noexcept;
  /// New coupling gains; also the solver's metric (ConfigurationSolver::setGains()).
  void setGains(const CouplingGains& gains) noexcept {
    coupling_.setGains(gains);
    solver_.setGains(gains);
  }

  const Pose& proxyPose() const noexcept { return X_WP_; }
  /// The constrained motion the last tick swept (eq. 2; from the proxy pose before the tick) and
  /// the time it stopped at: the proxy moved along lastMotion() over [0, lastTimeOfContact()]
  /// (a still motion on a tick with bad input). For CrossingVerifier.
  const RigidMotion& lastMotion() const noexcept { return last_motion_; }
  double lastTimeOfContact() const noexcept { return last_t_; }
  /// Current contact set (points on the proxy within epsilon of the surface).
  std::span<const Contact> contacts() const noexcept { return collision_.contacts(); }
  std::int64_t badInputCount() const noexcept { return bad_inputs_; }
  /// The isovalue the hand feels now (TickStats::felt_isovalue of the last tick) [data units].
  double feltIsovalue() const noexcept { return felt_isovalue_; }
  double epsilon_m() const noexcept { return collision_.epsilon_m(); }
  /// Largest stand-off lift a tick may apply [m]: the largest of RendererOptions::
  /// standoff_fraction, the lift after a stuck contact (stuck_standoff_fraction) and, with the
  /// edge test, the lift after an edge stop (0.5), times epsilon.
  /// ConfigurationSolver::standoffTranslation moves the proxy by at most twice it.
  double largestStandoff_m() const noexcept {
    return std::max({options_.standoff_fraction, stuck_standoff_fraction_, edge_test_ ? kEdgeStandoffFraction : 0.0}) *
           collision_.epsilon_m();
  }
  const ScalarVolume& volume() const noexcept { return *volume_; }
  const ToolModel& tool() const noexcept { return *tool_; }
  const VirtualCoupling& coupling() const noexcept { return coupling_; }
  /// The work budget in force (RendererOptions::work_budget with its default resolved); 0: none.
  std::int64_t workBudget() const noexcept { return collision_.workBudget(); }
  /// Lanes the accelerated sweep runs on: RendererOptions::solver_lanes, fewer for a tool whose
  /// point-shell tree has fewer upper nodes (CollisionDetector::lanes()); 1 in kPaper.
  int solverLanes() const noexcept { return std::max(1, collision_.lanes()); }

 private:
  std::shared_ptr<const ScalarVolume> volume_;
  std::shared_ptr<const ToolModel> tool_;
  RendererOptions options_;
  CollisionDetector collision_;
  ConfigurationSolver solver_;
  VirtualCoupling coupling_;
  Pose X_WP_;
  RigidMotion last_motion_;
  double last_t_ = 0.0;
  // RendererOptions::edge_test: the move along `motion` from t_from (edges free there) to t_to
  // (points proven free), shortened to before the first sub-step where an edge crosses (swept:
  // the first of the poses tested along it). When the work budget or the deadline stops the
  // edge test (cut true), the last pose it proved free (t_from at first): the proxy stays.
  /// Keeps the edge contact that stopped this move (null: none was added) for the next lift.
  void noteEdgeContact(const Contact* added) noexcept;
  double edgeSafeTime(const RigidMotion& motion, double t_from, double t_to, double isovalue, bool& stopped,
                      bool& cut) noexcept;
  // Goes on with the sweep the work budget cut on an earlier tick (CollisionDetector::
  // resumeSweep()) and moves the proxy along its motion as far as proven free.
  void resumeCutSweep(const Pose& X_WD, double isovalue, TickStats& stats) noexcept;
  // The whole neighbour graph's edge test at motion.poseAt(t) (CollisionDetector::edgesCrossAt()):
  // whether an edge crosses; cut set when the budget or the deadline stopped it.
  bool graphCrossesAt(const RigidMotion& motion, double t, double isovalue, bool& cut) noexcept;
  // Notes that the pose the move ends at, time t, was proven free by a whole-graph test at this
  // isovalue, so the next move need not test its start (the field only falls under drilling; a
  // new isovalue or a released point redoes it). Returns t.
  double markEdgesFree(double t, double isovalue) noexcept;
  // The poses the edge test takes along motion over [t_from, t_to]: a quarter of the point
  // spacing (at least epsilon) of travel apart at the farthest point, 1 to 64.
  int edgeTestSteps(const RigidMotion& motion, double t_from, double t_to) const noexcept;
  // The whole graph at `tested` poses evenly along [t_from, t_to] in order, the last at t_to, up
  // to the first where an edge crosses (then its time in cross_t); t_free: the last pose proven
  // free before it. Returns whether one crosses; stops at once when the test is cut.
  bool firstCrossingPose(const RigidMotion& motion, double t_from, double t_to, int tested, double isovalue,
                         double& t_free, double& cross_t, bool& cut) noexcept;
  // On the edges listed as crossing only: sub_steps sub-steps from proven_t (free) towards
  // cross_t (crossing) in order, then 8 halvings of the first crossing one; free_t and cross_t:
  // the bracket found (free_t == proven_t when none was free).
  void bisectListedCrossing(const RigidMotion& motion, double proven_t, int sub_steps, double isovalue, double& free_t,
                            double& cross_t) noexcept;
  // A move stopped by an edge between proven_t (free) and cross_t: up to four rounds of
  // bisectListedCrossing(), each pose found tested with the whole graph (an edge crossing there
  // joins the list and the next round starts again from proven_t). Returns the time the proxy
  // may move to (t_from when nothing past it is proven); a cut test clears `stopped`.
  double searchEdgeStop(const RigidMotion& motion, double t_from, double proven_t, double cross_t, int sub_steps,
                        double isovalue, bool& stopped, bool& cut) noexcept;
  // The tick's stand-off lift [m] (0: none) and in `lift` whether it is on: after a move blocked
  // almost at once and with no point embedded; at least kEdgeStandoffFraction of epsilon after
  // an edge stopped it, kStuckStandoffFraction after two blocked moves in a row.
  double liftStandoff_m(bool& lift) const noexcept;
  // A move of the lift alone (lift_W [m] in W, no rotation), swept; the next tick slides from
  // the lifted pose. Counts the sweep and ends the phase (phase = now).
  void sweepLiftAlone(const Eigen::Vector3d& lift_W, double isovalue, RigidMotion& motion, SweepResult& hit,
                      TickStats& stats, std::chrono::steady_clock::time_point& phase) noexcept;
  // Steps 3 and 4 of a new move: the constrained motion solved and swept (solveAndSweep()), or
  // the stand-off lift alone where the last move was stopped at once (see tick()).
  void solveOrLift(const Pose& X_WD, double isovalue, bool lift, double standoff_m, RigidMotion& motion,
                   SweepResult& hit, TickStats& stats, std::chrono::steady_clock::time_point& phase) noexcept;
  // Step 5: moves the proxy along `motion` to the first contact (or the target, or as far as
  // the budget proved free), and no farther than the tool's surface between its points allows
  // (edgeSafeTime()); then the contact set: the contacts at the hit, or the edge's contact.
  // phase: when the sweep ended (contacts_us is counted from there).
  void moveProxy(const RigidMotion& motion, const SweepResult& hit, double isovalue, TickStats& stats,
                 std::chrono::steady_clock::time_point phase) noexcept;
  // A tick with no cut sweep pending: step 2 (prune the contact set), the stand-off, steps 3-5
  // (solveOrLift(), moveProxy()); start: the tick's start (prune_us is counted from there).
  void sweepNewMove(const Pose& X_WD, double isovalue, std::chrono::steady_clock::time_point start,
                    TickStats& stats) noexcept;
  bool edge_test_ = false;
  bool edge_blocked_last_tick_ = false;  // the last move was stopped at once by an edge
  // The edge contact that stopped the last move (valid while edge_blocked_last_tick_): the lift
  // after it must clear it too, though the pruning, which looks towards the device, drops it.
  Contact stopped_edge_contact_;
  bool lifted_alone_ = false;        // this tick's move is a lift alone (sweepLiftAlone())
  bool lift_alone_stopped_ = false;  // the last tick's lift alone was stopped at once: not again
  // The edge test proved the proxy's pose free at this isovalue with this many embedded points
  // (NaN: not proven). Then a stopped move need not test its start again (edgeSafeTime()).
  double edges_free_isovalue_ = std::numeric_limits<double>::quiet_NaN();
  int edges_free_embedded_ = -1;
  // The stand-off lift after such a move, as a fraction of epsilon (see tick()).
  static constexpr double kEdgeStandoffFraction = 0.5;
  // After two moves in a row that a point stopped at once (a stuck contact), the lift is on at
  // least this fraction (RendererOptions::stuck_standoff_fraction resolved; see tick()).
  static constexpr double kStuckStandoffFraction = 0.25;
  double stuck_standoff_fraction_ = 0.0;
  int blocked_ticks_ = 0;  // moves in a row stopped before 1 % of their path (0: the last was not)
  double last_isovalue_;
  double felt_isovalue_;        // see TickStats::felt_isovalue
  std::int64_t next_tick_deadline_work_ = 0;  // cutNextTickAtWork()
  double isovalue_margin_ = 0.0;  // a felt isovalue this far above the shell's largest F
  bool embedded_scan_needed_ = false;
  double motion_scale_ = 1.0;  // < 1 after ticks the work budget cut (RendererOptions::work_budget)
  std::int64_t bad_inputs_ = 0;
  // The time the proxy has reached along the motion of the sweep the work budget cut, which is
  // resumed on the next ticks (CollisionDetector::sweepPending(), pendingMotion()).
  double pending_t_ = 0.0;
};

}  // namespace vh::haptics
