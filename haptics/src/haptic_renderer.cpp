#include "vh/haptics/haptic_renderer.h"

#include <chrono>
#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace vh::haptics {

HapticRenderer::HapticRenderer(std::shared_ptr<const ScalarVolume> volume, std::shared_ptr<const ToolModel> tool,
                               const RendererOptions& options, const Pose& X_WP_initial, double isovalue)
    : volume_(std::move(volume)),
      tool_(std::move(tool)),
      options_(options),
      collision_((volume_ && !volume_->empty()) ? *volume_ : throw std::invalid_argument("HapticRenderer: no volume"),
                 tool_ ? *tool_ : throw std::invalid_argument("HapticRenderer: no tool"), options.epsilon_m,
                 256, options.detection_mode, options.segment_fraction, options.segment_test),
      solver_(),
      coupling_(options.gains),
      X_WP_(X_WP_initial),
      last_isovalue_(isovalue),
      felt_isovalue_(isovalue) {
  if (!X_WP_initial.allFinite()) throw std::invalid_argument("HapticRenderer: the initial proxy pose is not finite");
  if (!std::isfinite(isovalue)) throw std::invalid_argument("HapticRenderer: the isovalue is not finite");
  if (options.max_contacts < 1 || options.max_contacts > 256)
    throw std::invalid_argument("HapticRenderer: max_contacts " + std::to_string(options.max_contacts) +
                                " must be in [1, 256]");
  X_WP_.R_AB.normalize();
  // 1e-9 of the field's range: the proxy's nearest points stay strictly outside the felt surface.
  isovalue_margin_ = 1e-9 * std::max(1.0, volume_->maxValue() - volume_->minValue());
  solver_.setGains(options.gains);
  collision_.setContactCap(static_cast<std::size_t>(options.max_contacts));
  collision_.setWorkBudget(options.work_budget >= 0 ? options.work_budget
                          : options.detection_mode == DetectionMode::kAccelerated ? RendererOptions::kDefaultWorkBudget
                                                                                  : 0);
  if (!(options.deadline_us >= 0.0) || !std::isfinite(options.deadline_us))
    throw std::invalid_argument("HapticRenderer: deadline_us must be finite and >= 0");
  // A NaN or negative limit would read as "no limit" below: a typo must not unbound the step.
  if (!(options.max_travel_per_tick_m >= 0.0) || !std::isfinite(options.max_travel_per_tick_m))
    throw std::invalid_argument("HapticRenderer: max_travel_per_tick_m must be finite and >= 0 (0: unbounded)");
  if (!(options.max_travel_in_contact_per_tick_m >= 0.0) || !std::isfinite(options.max_travel_in_contact_per_tick_m))
    throw std::invalid_argument(
        "HapticRenderer: max_travel_in_contact_per_tick_m must be finite and >= 0 (0: as max_travel_per_tick_m)");
  collision_.setLanes(options.solver_lanes);
  stuck_standoff_fraction_ = options.stuck_standoff_fraction >= 0.0 ? options.stuck_standoff_fraction
                             : options.detection_mode == DetectionMode::kAccelerated ? kStuckStandoffFraction
                                                                                      : 0.0;
  collision_.updateEmbedded(X_WP_, isovalue);
  edge_test_ = options.edge_test > 0 ||
               (options.edge_test < 0 && options.detection_mode == DetectionMode::kAccelerated &&
                options.segment_test == SegmentTest::kExact);
}

namespace {
// The edge test's steps along a move, apart at the farthest point: this fraction of the point
// spacing (the poses the swept test tests, the sub-steps of a stopped move's search;
// haptics/README.md, "Between the points").
constexpr double kEdgeStepFraction = 0.25;
}  // namespace

bool HapticRenderer::graphCrossesAt(const RigidMotion& motion, double t, double isovalue, bool& cut) noexcept {
  const bool crosses = collision_.edgesCrossAt(motion.poseAt(t), isovalue);
  cut = cut || collision_.edgeTestCut();
  return crosses;
}

double HapticRenderer::markEdgesFree(double t, double isovalue) noexcept {
  edges_free_isovalue_ = isovalue;
  edges_free_embedded_ = collision_.embeddedCount();
  return t;
}

int HapticRenderer::edgeTestSteps(const RigidMotion& motion, double t_from, double t_to) const noexcept {
  // Poses a quarter of the point spacing of travel apart at the farthest point.
  const double travel_m = (motion.speed_m() + motion.angle_rad() * collision_.shellRadius_m()) * (t_to - t_from);
  const double spacing_m = std::max(collision_.shellEdges().spacing_m, collision_.epsilon_m());
  return static_cast<int>(std::clamp(std::ceil(travel_m / (kEdgeStepFraction * spacing_m)), 1.0, 64.0));
}

bool HapticRenderer::firstCrossingPose(const RigidMotion& motion, double t_from, double t_to, int tested,
                                       double isovalue, double& t_free, double& cross_t, bool& cut) noexcept {
  bool crossing = false;
  for (int k = 1; k <= tested && !crossing; ++k) {
    const double t = k == tested ? t_to : t_from + (t_to - t_from) * k / tested;
    crossing = graphCrossesAt(motion, t, isovalue, cut);
    if (cut) return crossing;
    if (crossing) cross_t = t; else t_free = t;
  }
  return crossing;
}

void HapticRenderer::bisectListedCrossing(const RigidMotion& motion, double proven_t, int sub_steps, double isovalue,
                                          double& free_t, double& cross_t) noexcept {
  free_t = proven_t;
  const double span = cross_t - proven_t;
  for (int k = 1; k < sub_steps; ++k) {
    const double t = proven_t + span * k / sub_steps;
    if (collision_.listedEdgesCrossAt(motion.poseAt(t), isovalue)) {
      cross_t = t;
      break;
    }
    free_t = t;
  }
  for (int i = 0; i < 8; ++i) {
    const double mid = 0.5 * (free_t + cross_t);
    if (collision_.listedEdgesCrossAt(motion.poseAt(mid), isovalue)) cross_t = mid; else free_t = mid;
  }
}

double HapticRenderer::searchEdgeStop(const RigidMotion& motion, double t_from, double proven_t, double cross_t,
                                      int sub_steps, double isovalue, bool& stopped, bool& cut) noexcept {
  // Sub-steps of at most a quarter of the point spacing of travel at the farthest point, in
  // order, then the first crossing one bisected (8 halvings): on the edges found crossing so
  // far only (a whole-graph test per sub-step cost up to 72 of them a tick). The pose found is
  // then tested with the whole graph; an edge crossing there joins the list and the search
  // starts again from the last pose proven free. After kRounds, the proxy stays there.
  constexpr int kRounds = 4;
  for (int round = 0; round < kRounds; ++round) {
    double free_t = proven_t;
    bisectListedCrossing(motion, proven_t, sub_steps, isovalue, free_t, cross_t);
    if (free_t <= proven_t) return proven_t > t_from ? markEdgesFree(proven_t, isovalue) : t_from;
    const bool crosses = graphCrossesAt(motion, free_t, isovalue, cut);
    if (cut) {
      stopped = false;
      return proven_t > t_from ? markEdgesFree(proven_t, isovalue) : t_from;
    }
    if (!crosses) {
      // The edge contact is taken at the crossing pose just past it.
      collision_.listedEdgesCrossAt(motion.poseAt(cross_t), isovalue);
      return markEdgesFree(free_t, isovalue);
    }
    cross_t = free_t;
  }
  return proven_t > t_from ? markEdgesFree(proven_t, isovalue) : t_from;
}

double HapticRenderer::edgeSafeTime(const RigidMotion& motion, double t_from, double t_to, double isovalue,
                                    bool& stopped, bool& cut) noexcept {
  stopped = false;
  cut = false;
  if (!edge_test_ || !(t_to > t_from)) return t_to;
  collision_.clearCrossingEdges();
  // A whole-graph test the budget or the deadline stopped: nothing is known past t_from.
  // The pose a move ends at, proven free by a whole-graph test, need not be tested again as the
  // next move's start (markEdgesFree()).
  const bool start_proven = edges_free_isovalue_ == isovalue && edges_free_embedded_ == collision_.embeddedCount();
  const int steps = edgeTestSteps(motion, t_from, t_to);
  // Swept: the whole graph at each of those poses along the move, in order, then at its end;
  // else at its end only. The first pose where an edge crosses ends the walk; t_free is the
  // last pose proven free before it.
  double t_free = t_from;
  double cross_t = t_to;
  const bool crossing = firstCrossingPose(motion, t_from, t_to, options_.edge_test_swept ? steps : 1, isovalue, t_free,
                                          cross_t, cut);
  if (cut) return t_free;
  if (!crossing) return markEdgesFree(t_to, isovalue);
  // Already crossing where the move starts (after a reset, or an edge that a lowered isovalue
  // grew a wall through): not held, as embedded points are not.
  if (!start_proven && t_free == t_from) {
    if (graphCrossesAt(motion, t_from, isovalue, cut)) {
      if (cut) return t_from;
      edges_free_isovalue_ = std::numeric_limits<double>::quiet_NaN();
      return t_to;
    }
    if (cut) return t_from;
  }
  stopped = true;
  // Swept: t_free and cross_t are one step apart, so no sub-steps.
  return searchEdgeStop(motion, t_from, t_free, cross_t, options_.edge_test_swept ? 1 : steps, isovalue, stopped, cut);
}

void HapticRenderer::noteEdgeContact(const Contact* added) noexcept {
  stopped_edge_contact_ = added != nullptr ? *added : Contact{};
  if (added == nullptr) stopped_edge_contact_.clearance_m = std::numeric_limits<double>::infinity();  // bounds nothing
}

void HapticRenderer::resetProxy(const Pose& X_WP) noexcept {
  if (!X_WP.allFinite()) return;
  X_WP_ = X_WP;
  X_WP_.R_AB.normalize();
  collision_.abandonSweep();
  collision_.clearContacts();
  coupling_.resetTracking();
  embedded_scan_needed_ = true;
  edge_blocked_last_tick_ = false;
  lift_alone_stopped_ = false;
  edges_free_isovalue_ = std::numeric_limits<double>::quiet_NaN();
  blocked_ticks_ = 0;
}

void HapticRenderer::carryProxy(const Eigen::Vector3d& dp_W_m) noexcept {
  if (!dp_W_m.allFinite()) return;
  X_WP_.p_AB_m += dp_W_m;
  collision_.abandonSweep();
  collision_.clearContacts();
  embedded_scan_needed_ = true;
  edge_blocked_last_tick_ = false;
  edges_free_isovalue_ = std::numeric_limits<double>::quiet_NaN();
}

void HapticRenderer::noteFieldChanged(double max_rise_F) noexcept {
  collision_.forgetFieldProofs(max_rise_F);
  // Contacts the surface moved away from no longer hold the proxy: released beyond an eighth
  // of epsilon (twice the clearance measurement's resolution), so that the proxy follows a
  // receding surface to within that, not to within epsilon (the pruning's rule, for a still one).
  if (std::isfinite(last_isovalue_)) collision_.releaseClearContacts(X_WP_, last_isovalue_, collision_.epsilon_m() / 8.0);
  embedded_scan_needed_ = true;
  edges_free_isovalue_ = std::numeric_limits<double>::quiet_NaN();
}

namespace {

using Clock = std::chrono::steady_clock;

inline double usSince(Clock::time_point a, Clock::time_point b) noexcept {
  return std::chrono::duration<double, std::micro>(b - a).count();
}

// Validates the device sample in place: finite, a unit quaternion to 1e-3 (then normalised),
// within max_device_distance_m of the proxy. False: the sample is rejected.
inline bool acceptDeviceSample(Pose& X_WD, double requested_isovalue, const Pose& X_WP,
                               double max_device_distance_m) noexcept {
  const double qn = X_WD.R_AB.norm();
  const bool finite = X_WD.allFinite() && std::isfinite(requested_isovalue);
  if (!finite || std::abs(qn - 1.0) > 1e-3 || (X_WD.p_AB_m - X_WP.p_AB_m).norm() > max_device_distance_m)
    return false;
  X_WD.R_AB.coeffs() /= qn;
  return true;
}

// A rejected device sample: zero force, proxy in place (at rest), counted; bad input never throws.
inline TickOutput rejectedTick(const CollisionDetector& collision, const MassProperties& mass, const Pose& X_WP,
                               double felt_isovalue, Clock::time_point start, std::int64_t& bad_inputs,
                               RigidMotion& last_motion, double& last_t) noexcept {
  TickOutput out;
  ++bad_inputs;
  last_motion = RigidMotion::FromVelocity(X_WP, mass.p_TCm_m, Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero());
  last_t = 0.0;
  out.X_WP = X_WP;
  out.stats.bad_input = true;
  out.stats.felt_isovalue = felt_isovalue;
  out.stats.contacts = static_cast<int>(collision.contacts().size());
  out.stats.exec_time_us = usSince(start, Clock::now());
  return out;
}

// The isovalue the hand feels. Raised, it shrinks the solid: at once. Lowered, the surface
// advances towards the tool and could swallow part of it, or grow a thin wall through it:
// the hand feels it lowered only as far as no point of the proxy is inside (the largest F on
// the shell), and the rest follows as the tool moves away. Nothing is pushed, so the force
// never jumps; the proxy never ends inside, and the sweep works at this value as always.
inline double limitLoweredIsovalue(CollisionDetector& collision, const Pose& X_WP, double requested_isovalue,
                           double felt_isovalue, double isovalue_margin) noexcept {
  double isovalue = requested_isovalue;
  if (requested_isovalue < felt_isovalue) {
    const double highest = collision.maxFieldOnShell(X_WP, requested_isovalue);
    if (highest > requested_isovalue) isovalue = std::min(felt_isovalue, highest + isovalue_margin);
  }
  return isovalue;
}

// A new felt isovalue, or a reset: points inside (only after a reset or at the first pose;
// a lowered isovalue is deferred for the hand, see limitLoweredIsovalue()) are embedded and released
// once outside again (see haptics/README.md, "Isovalue changes"). Then step 2: verify and
// prune the contact set.
inline void prepareContactSet(CollisionDetector& collision, const Pose& X_WP, const Pose& X_WD, double isovalue,
                              bool& embedded_scan_needed, double& last_isovalue) noexcept {
  if (embedded_scan_needed || isovalue != last_isovalue) {
    collision.updateEmbedded(X_WP, isovalue);
    last_isovalue = isovalue;
    embedded_scan_needed = false;
  } else {
    collision.releaseEmbedded(X_WP, isovalue);
  }
  collision.pruneContacts(X_WP, X_WD, isovalue);
}

// Steps 1 and 3: unconstrained, then constrained motion (Gauss' principle); step 4: collision
// detection along the constrained path. When a contact blocks its own tangent step (its eq. 1
// normal disagrees with the trilinear surface), its normal is refined and steps 3-4 are solved
// again, at most twice per tick. phase: the time the last phase ended (solve_us, sweep_us).
inline void solveAndSweep(ConfigurationSolver& solver, CollisionDetector& collision, const VirtualCoupling& coupling,
                          const RendererOptions& options, double motion_scale, const Pose& X_WP, const Pose& X_WD,
                          const MassProperties& mass, double standoff_m, double isovalue, RigidMotion& motion,
                          SweepResult& hit, TickStats& stats, Clock::time_point& phase) noexcept {
  for (int attempt = 0; attempt < 3; ++attempt) {
    motion = solver.constrainedMotion(X_WP, X_WD, mass, collision.contacts(), standoff_m,
                                      &coupling.trackedRotation_W());
    {
      const auto now = Clock::now();
      stats.solve_us += usSince(phase, now);
      phase = now;
    }
    // The motion per tick is bounded (the velocity limit of section 2.3): no point of the
    // shell travels farther than max_travel_per_tick_m (path bound |v| + |omega| R, R the
    // shell's radius about the centre of mass), and after ticks the work budget cut, a
    // shorter step along the same constrained motion: fewer segments, smaller balls. Scaling
    // keeps the motion in the cone of allowed motions (eq. 4).
    // In contact, the limit in contact (RendererOptions::max_travel_in_contact_per_tick_m).
    double scale = motion_scale;
    const double travel_m = motion.speed_m() + motion.angle_rad() * collision.shellRadius_m();
    double limit_m = options.max_travel_per_tick_m;
    if (!collision.contacts().empty() && options.max_travel_in_contact_per_tick_m > 0.0)
      limit_m = limit_m > 0.0 ? std::min(limit_m, options.max_travel_in_contact_per_tick_m)
                              : options.max_travel_in_contact_per_tick_m;
    if (limit_m > 0.0 && travel_m * scale > limit_m) scale = limit_m / travel_m;
    if (scale < 1.0)
      motion = RigidMotion::FromVelocity(X_WP, mass.p_TCm_m, motion.v_W_m() * scale, motion.omega_W_rad() * scale);
    // The projection shares the work budget: about a sample's cost per 4 rows per iteration.
    const ConeProjection& projection = solver.lastProjection();
    collision.addWork(static_cast<std::int64_t>(collision.contacts().size()) * (projection.iterations + 2) / 4);
    hit = collision.sweep(motion, isovalue);
    ++stats.sweeps;
    {
      const auto now = Clock::now();
      stats.sweep_us += usSince(phase, now);
      phase = now;
    }
    if (attempt == 2 || hit.budget_cut || !collision.refineStuckContact(motion, hit)) break;
  }
}

// The step length after this tick's sweep: after a cut for good (kPaper), halved for the next
// tick (at least 1/4096); after a full sweep, doubled back towards 1.
inline void adaptMotionScale(bool budget_cut, double& motion_scale) noexcept {
  if (budget_cut) {
    motion_scale = std::max(1.0 / 4096.0, 0.5 * motion_scale);
  } else if (motion_scale < 1.0) {
    motion_scale = std::min(1.0, 2.0 * motion_scale);
  }
}

// The tick's work counters from the detector, and its wall time.
inline void fillWorkStatistics(const CollisionDetector& collision, Clock::time_point start, TickStats& stats) noexcept {
  stats.contacts = static_cast<int>(collision.contacts().size());
  stats.volume_samples = collision.sampleCount();
  stats.box_queries = collision.boxQueryCount();
  stats.tree_nodes = collision.treeNodeCount();
  stats.cells_walked = collision.cellsWalkedCount();
  stats.cells = collision.cellCount();
  stats.edge_test_counts = collision.edgeTestCounts();
  stats.work = collision.work();
  stats.critical_work = collision.budgetWork();
  // Also a tick whose sweep finished but whose contact update (or re-solve) the budget shortened.
  stats.budget_cut = stats.budget_cut || collision.budgetSpent();
  stats.deadline_cut = stats.budget_cut && collision.deadlineReached();
  stats.deadline_work = stats.deadline_cut ? collision.deadlineWork() : 0;
  stats.exec_time_us = usSince(start, Clock::now());
}

}  // namespace

// A sweep the work budget cut on an earlier tick goes on where it stopped: the same motion,
// this tick's budget; the proxy moves as far as every path is proven free.
void HapticRenderer::resumeCutSweep(const Pose& X_WD, double isovalue, TickStats& stats) noexcept {
  const MassProperties& mass = tool_->mass;
  const auto phase = Clock::now();
  // The detector keeps it until the next sweep() (resumeSweep() only ends the sweep).
  const RigidMotion& pending_motion = collision_.pendingMotion();
  const SweepResult hit = collision_.resumeSweep();
  stats.sweep_us = usSince(phase, Clock::now());
  // The motion was solved for an older device pose: along it, the proxy moves to the point,
  // among eight from where it is to where the sweep has proven free, where the coupling to
  // the device now has done the most positive work on it (a line search; the trapezoidal
  // work of the coupling wrench over the move). Never negative work (the solver's own
  // guarantee, ConfigurationSolver::setGains(), for the pose it solved for); when every
  // candidate would do negative work the proxy waits, proven free where it is, while the
  // sweep goes on.
  const double pending_t = pending_t_;
  double t = pending_t;
  const Pose X_from = pending_motion.poseAt(pending_t);
  const Wrench w0 = coupling_.compute(X_from, X_WD, mass);
  const double t_end = std::max(pending_t, hit.t);
  double best_work_J = 0.0;
  for (int k = 1; k <= 8 && t_end > pending_t; ++k) {
    const double t_try = k == 8 ? t_end : pending_t + (t_end - pending_t) * (k / 8.0);
    const Pose X_to = pending_motion.poseAt(t_try);
    const Wrench w1 = coupling_.compute(X_to, X_WD, mass);
    const Vector6d dx = displacement_W(X_from, X_to, mass.p_TCm_m);
    const double work_J = -0.5 * ((w0.force_W_N + w1.force_W_N).dot(dx.head<3>()) +
                                  (w0.torque_W_Nm + w1.torque_W_Nm).dot(dx.tail<3>()));
    if (work_J > best_work_J) {
      best_work_J = work_J;
      t = t_try;
    }
  }
  bool edge_stop = false, edge_cut = false;
  const auto edge_start = edge_test_ ? Clock::now() : Clock::time_point{};  // no clock read without it
  t = edgeSafeTime(pending_motion, pending_t, t, isovalue, edge_stop, edge_cut);
  if (edge_test_) stats.edge_us = usSince(edge_start, Clock::now());
  stats.edge_stop = edge_stop;
  last_motion_ = pending_motion.part(pending_t, t);
  last_t_ = 1.0;
  X_WP_ = pending_motion.poseAt(t);
  pending_t_ = t;
  collision_.refreshPositions(X_WP_);
  // A resumed sweep counts as at most one blocked move: not a contact stuck at its start.
  if (edge_stop) {
    collision_.abandonSweep();
    const auto edge_contact_start = Clock::now();
    noteEdgeContact(collision_.addEdgeContact(X_WP_, isovalue));
    stats.edge_us += usSince(edge_contact_start, Clock::now());
    blocked_ticks_ = 1;
    edge_blocked_last_tick_ = t < pending_t + 0.01;
  } else if (!hit.budget_cut && !edge_cut) {
    const auto contacts_start = Clock::now();
    // The contacts at the hit, when the proxy got there.
    if (hit.hit_point >= 0 && t == hit.t) collision_.addContactsAt(pending_motion, hit, isovalue);
    stats.contacts_us = usSince(contacts_start, Clock::now());
    blocked_ticks_ = hit.hit_point >= 0 && hit.t < 0.01 ? 1 : 0;
    edge_blocked_last_tick_ = false;
  } else {
    blocked_ticks_ = std::min(blocked_ticks_, 1);
  }
  stats.budget_cut = hit.budget_cut || edge_cut;
  stats.time_of_contact = t;
}

double HapticRenderer::liftStandoff_m(bool& lift) const noexcept {
  // The stand-off lift (an option, off by default) is a recovery: only after a tick that was
  // blocked almost at once (a lift on every tick drove a hook hanging from one contact into a
  // 2-cycle), and never while the surface has swallowed part of the tool (a moving surface must
  // not push the proxy against the user).
  // After a move the tool's surface between its points stopped at once, the lift is on (at
  // least kEdgeStandoffFraction): an edge contact is found at the crossing itself, with no
  // clearance, and an edge tangent to a rounded ridge cuts into it at second order as soon as
  // it turns, so a plain tangent move is stopped again at its start, tick after tick (the
  // tool held at a convex edge of the block).
  // A point contact stopped at once on two moves in a row is stuck the same way (a probe spun
  // about its shaft on a ball at 2 mm point spacing: its one contact creeps along the
  // interpolant's bumps to zero clearance and holds the turn at 0.43 of 0.5 rad): the lift is
  // on (at least RendererOptions::stuck_standoff_fraction).
  lift = blocked_ticks_ > 0 && collision_.embeddedCount() == 0;
  const double fraction = edge_blocked_last_tick_ ? std::max(options_.standoff_fraction, kEdgeStandoffFraction)
                          : blocked_ticks_ >= 2   ? std::max(options_.standoff_fraction, stuck_standoff_fraction_)
                                                  : options_.standoff_fraction;
  return lift ? fraction * collision_.epsilon_m() : 0.0;
}

void HapticRenderer::sweepLiftAlone(const Eigen::Vector3d& lift_W, double isovalue, RigidMotion& motion,
                                    SweepResult& hit, TickStats& stats, Clock::time_point& phase) noexcept {
  motion = RigidMotion::FromVelocity(X_WP_, tool_->mass.p_TCm_m, lift_W, Eigen::Vector3d::Zero());
  hit = collision_.sweep(motion, isovalue);
  ++stats.sweeps;
  phase = Clock::now();
  lifted_alone_ = true;
}

void HapticRenderer::solveOrLift(const Pose& X_WD, double isovalue, bool lift, double standoff_m, RigidMotion& motion,
                                 SweepResult& hit, TickStats& stats, Clock::time_point& phase) noexcept {
  // After a move the tool's surface between its points stopped at once: the lift alone this
  // tick. The edge contact is a line touching a rounded ridge, and its one normal (the
  // gradient's part perpendicular to the edge) holds to first order only; a solved slide,
  // mostly tangential, with the lift spread along it, cuts the ridge again at its first
  // sub-step, tick after tick (the probe held at the block's hole rim). Lifted first, the next
  // slide has the stand-off to spend.
  // The lift clears the edge contact that stopped the move too (the pruning, which looks
  // towards the device, may have dropped it: a lift into it was stopped at once, tick after
  // tick, the drill held in its cavity at 25 N). A lift alone stopped at once is not repeated:
  // the next tick takes the solved move, so that no tick repeats the one before it.
  const Eigen::Vector3d edge_lift_W =
      lift && edge_blocked_last_tick_ && !lift_alone_stopped_
          ? ConfigurationSolver::standoffTranslation(collision_.contacts(), standoff_m, &stopped_edge_contact_)
          : Eigen::Vector3d::Zero();
  if (edge_lift_W.squaredNorm() > 0.0) {
    sweepLiftAlone(edge_lift_W, isovalue, motion, hit, stats, phase);
    return;
  }
  solveAndSweep(solver_, collision_, coupling_, options_, motion_scale_, X_WP_, X_WD, tool_->mass, standoff_m, isovalue,
                motion, hit, stats, phase);
  // Still stopped at once with the lift on: the point sits nanometres from the interpolant's
  // surface and slides almost along it, so a bump a few nanometres high stops it before the
  // lift, spread along the whole step, has raised it (the drill held at 117 N on the head
  // phantom, its contact at F - s = -0.001 HU). The lift alone this tick.
  if (standoff_m > 0.0 && hit.hit_point >= 0 && !hit.budget_cut && hit.t < 0.01) {
    const Eigen::Vector3d lift_W = ConfigurationSolver::standoffTranslation(collision_.contacts(), standoff_m);
    if (lift_W.squaredNorm() > 0.0) sweepLiftAlone(lift_W, isovalue, motion, hit, stats, phase);
  }
}

void HapticRenderer::moveProxy(const RigidMotion& motion, const SweepResult& hit, double isovalue, TickStats& stats,
                               Clock::time_point phase) noexcept {
  bool edge_stop = false, edge_cut = false;
  const auto edge_start = edge_test_ ? Clock::now() : Clock::time_point{};  // no clock read without it
  const double t_move = edgeSafeTime(motion, 0.0, hit.t, isovalue, edge_stop, edge_cut);
  if (edge_test_) stats.edge_us = usSince(edge_start, Clock::now());
  stats.edge_stop = edge_stop;
  if (edge_stop) collision_.abandonSweep();
  // An edge test the budget stopped holds the proxy like a cut sweep: not a blocked move.
  if (!edge_cut) blocked_ticks_ = (hit.hit_point >= 0 || edge_stop) && t_move < 0.01 ? blocked_ticks_ + 1 : 0;
  edge_blocked_last_tick_ = edge_stop && t_move < 0.01;
  lift_alone_stopped_ = lifted_alone_ && (hit.hit_point >= 0 || edge_stop) && t_move < 0.01;
  X_WP_ = motion.poseAt(t_move);
  last_motion_ = motion;
  last_t_ = t_move;
  collision_.refreshPositions(X_WP_);
  if (collision_.sweepPending()) {  // cut: goes on next tick, from where the proxy is
    pending_t_ = t_move;
  } else {
    // After a cut edge test, a shorter step too: the edges' clearance certificates then hold
    // over more of it (CollisionDetector::edgesCrossAt()), so the test gets through.
    adaptMotionScale(hit.budget_cut || edge_cut, motion_scale_);
  }
  if (hit.hit_point >= 0 && !hit.budget_cut && !edge_stop && !edge_cut) collision_.addContactsAt(motion, hit, isovalue);
  // Stopped by the tool's surface between its points: that place on the wall joins the contact
  // set, so that the next tick's configuration solver slides along it.
  if (edge_stop) {
    const auto edge_contact_start = Clock::now();
    noteEdgeContact(collision_.addEdgeContact(X_WP_, isovalue));
    stats.edge_us += usSince(edge_contact_start, Clock::now());
  }
  stats.contacts_us = usSince(phase, Clock::now());
  stats.budget_cut = hit.budget_cut || edge_cut;
  stats.time_of_contact = t_move;
}

void HapticRenderer::sweepNewMove(const Pose& X_WD, double isovalue, Clock::time_point start,
                                  TickStats& stats) noexcept {
  prepareContactSet(collision_, X_WP_, X_WD, isovalue, embedded_scan_needed_, last_isovalue_);
  auto phase = Clock::now();
  stats.prune_us = usSince(start, phase);
  bool lift = false;
  const double standoff_m = liftStandoff_m(lift);
  RigidMotion motion;
  SweepResult hit;
  lifted_alone_ = false;
  solveOrLift(X_WD, isovalue, lift, standoff_m, motion, hit, stats, phase);
  moveProxy(motion, hit, isovalue, stats, phase);
}

TickOutput HapticRenderer::tick(const Pose& X_WD_in, double requested_isovalue) noexcept {
  const auto start = Clock::now();
  TickOutput out;
  collision_.resetSampleCount();
  if (options_.deadline_us > 0.0)
    collision_.setDeadline(start + std::chrono::duration_cast<Clock::duration>(
                                       std::chrono::duration<double, std::micro>(options_.deadline_us)));
  collision_.setWorkDeadline(next_tick_deadline_work_);
  next_tick_deadline_work_ = 0;

  const MassProperties& mass = tool_->mass;
  Pose X_WD = X_WD_in;
  if (!acceptDeviceSample(X_WD, requested_isovalue, X_WP_, options_.max_device_distance_m))
    return rejectedTick(collision_, mass, X_WP_, felt_isovalue_, start, bad_inputs_, last_motion_, last_t_);

  const double isovalue =
      limitLoweredIsovalue(collision_, X_WP_, requested_isovalue, felt_isovalue_, isovalue_margin_);
  felt_isovalue_ = isovalue;
  out.stats.felt_isovalue = isovalue;

  // A cut sweep goes on (resumeCutSweep()); a new isovalue or a reset abandons it (the proxy
  // stays where it is, which is proven free).
  if (collision_.sweepPending() && (embedded_scan_needed_ || isovalue != last_isovalue_)) collision_.abandonSweep();
  if (collision_.sweepPending()) {
    resumeCutSweep(X_WD, isovalue, out.stats);
  } else {
    sweepNewMove(X_WD, isovalue, start, out.stats);
  }
  // Step 6: virtual coupling (the relative rotation tracked through the ticks: continuous past pi).
  const Wrench w = coupling_.track(X_WP_, X_WD, mass);

  out.X_WP = X_WP_;
  out.force_W_N = w.force_W_N;
  out.torque_W_Nm = w.torque_W_Nm;
  fillWorkStatistics(collision_, start, out.stats);
  return out;
}

}  // namespace vh::haptics
