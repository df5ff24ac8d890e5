// The accelerated sweep (kAccelerated; haptics/README.md, "Speed"): the same first time of
// contact as the paper's sweep with fewer samples. The contact points first, then per lane a
// walk of its share of the point-shell tree that culls what the min-max tree proves free, then
// a time-ordered search whose runs of segments are proven empty by their direction or their
// ball, the paper's steps (paper_sweep.cpp) where they are not. Resumable: a sweep the work
// budget or the deadline cut goes on next tick where it stopped (resumeSweep(), "Never late").
#include "collision_detector_impl.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstddef>
#include <cstdint>

#include <Eigen/Geometry>

#include "sweep_queue.h"

namespace vh::haptics {
namespace {
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

bool CollisionDetector::Impl::runMayHit(WorkCounters& w, const RigidMotion& motion, int j, std::int64_t k,
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

bool CollisionDetector::Impl::runFreeAlongItsDirection(WorkCounters& w, const RigidMotion& motion, int j, double t0,
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

void CollisionDetector::Impl::startPoint(WorkCounters& k, const RigidMotion& motion, int j) noexcept {
  setupPath(k, motion, j);
  pt_[j].clear_until = -1.0;
}

void CollisionDetector::Impl::startSearch(int j) noexcept {
  search_[j].clear_segments = 0;
  search_[j].backoff = 0;
}

double CollisionDetector::Impl::nodeBall(const WalkArc& arc, const ShellNode& node, Eigen::Vector3d& centre_W) const noexcept {
  const Eigen::Vector3d r_c = arc.motion.radial_W(node.center_T_m);
  centre_W = arc.c_mid_W_m + arc.R_mid * r_c;
  return (0.5 * arc.t_max * arc.motion.pathLengthBound(r_c) + node.radius_m + epsilon_) * (1.0 + 1e-9) + 1e-12;
}

bool CollisionDetector::Impl::nearPathFree(WorkCounters& k, const WalkArc& arc, const ShellNode& node, int j,
                                     LeafSteps& steps, bool& within_a_voxel) const noexcept {
  // F's steps per grid axis over the leaf's ball, for its points' direction tests: one read
  // of the step bricks per leaf instead of one per point. The ball holds every point's arc
  // over [0, t_max], and so its chord and the straight lines from the chord to the arc that
  // runFreeAlongItsDirection() bounds F along (the ball is convex).
  if (steps.state == 0) {
    Eigen::Vector3d centre_W, box_lo, box_hi;
    const double radius = nodeBall(arc, node, centre_W);
    ballGridBox(centre_W, radius, box_lo, box_hi);
    steps.state = volume_->gridStepRange(box_lo, box_hi, steps.lo, steps.hi) ? 1 : -1;
  }
  return runFreeAlongItsDirection(k, arc.motion, j, 0.0, arc.t_max, arc.isovalue, steps.state > 0 ? &steps.lo : nullptr,
                                  steps.state > 0 ? &steps.hi : nullptr, &within_a_voxel);
}

std::size_t CollisionDetector::Impl::collectLeaf(Lane& lane, const WalkArc& arc, int node_index, std::size_t logged,
                                           QueueEntry* heap, std::size_t count) noexcept {
  WorkCounters& k = lane.counters;
  const ShellNode& node = nodes_[node_index];
  // Tested one by one, a leaf is near when one of its points is not culled by its own test.
  if (arc.queue) lane.walk_log[logged] = ~node_index;
  LeafSteps steps;
  for (int i = node.begin; i < node.end; ++i) {
    const int j = order_[i];
    lane.active[lane.active_count++] = j;
    if (started_[j] == sweep_stamp_) {  // a contact point: started (and queued) already
      lane.walk_log[logged] = node_index;
      continue;
    }
    startPoint(k, arc.motion, j);
    if (!arc.queue || embedded_[j] || !(pt_[j].path > 0.0)) continue;
    // A point whose walk met the surface last sweep (near_surface) is walked at once: its
    // first segment directly, then run tests. Only a cull is skipped, so the first time of
    // contact is the same; this sweep's walks decide the flag again.
    const bool near = pt_[j].near_surface != 0;
    pt_[j].near_surface = 0;
    if (near) {
      // Unless its whole path is proven free by F at its start and the most F can rise along
      // it: a point gliding along a wall or leaving it is neither walked nor queued.
      bool within_a_voxel = false;
      if (nearPathFree(k, arc, node, j, steps, within_a_voxel)) {
        pt_[j].clear_until = arc.t_max;
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
    const double radius_j = 0.5 * arc.t_max * pt_[j].path * (1.0 + 1e-9) + 1e-12;
    if (!ballMayBeInside(k, arc.c_mid_W_m + arc.R_mid * pt_[j].r0, radius_j, arc.isovalue, pt_[j].sagitta)) {
      pt_[j].clear_until = arc.t_max;
      continue;
    }
    // One segment: sample it; several: resolved lazily, in time order.
    lane.walk_log[logged] = node_index;
    startSearch(j);
    heap[count++] = {0.0, j, 0, pt_[j].segments == 1 ? 0 : 1};
  }
  return count;
}

std::size_t CollisionDetector::Impl::collectActive(Lane& lane, const RigidMotion& motion, double t_max, double isovalue,
                                             bool queue, bool resume) noexcept {
  WorkCounters& k = lane.counters;
  const double angle = motion.omega_W_rad().norm();
  const WalkArc arc{motion, t_max, isovalue, queue,
                    angle > 0.0 && t_max > 0.0
                        ? Eigen::AngleAxisd(0.5 * t_max * angle, motion.omega_W_rad() / angle).toRotationMatrix()
                        : Eigen::Matrix3d::Identity(),
                    motion.c0_W_m() + (0.5 * t_max) * motion.v_W_m()};
  // Point-shell tree, top down: a node whose points' arcs over [0, t_max], plus epsilon of
  // further travel (addContactsAt's look-ahead), lie in bricks that cannot hold an inside point
  // is skipped. A point at r = r_c + d (|d| <= node radius) stays within t_max path(r_c) / 2 +
  // radius of the node centre's position at t_max / 2 (nodeBall()).
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
      const double radius = nodeBall(arc, node, centre_W);
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
    count = collectLeaf(lane, arc, node_index, logged, heap, count);
  }
  return count;
}

void CollisionDetector::Impl::markNearNodes(Lane& lane) noexcept {
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

SweepResult CollisionDetector::Impl::sweepAccelerated(const RigidMotion& motion, double isovalue) noexcept {
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

SweepResult CollisionDetector::Impl::resumeSweep() noexcept {
  if (!pending_.active) return {};
  if (++chord_stamp_ == 0) {  // a new tick: the cached chord ends are recomputed (same values)
    for (PointSearch& q : search_) q.chord_end_stamp = 0u;
    chord_stamp_ = 1;
  }
  return stopClear(runAccelerated());
}

void CollisionDetector::Impl::laneJob(void* detector, int lane) noexcept {
  auto* self = static_cast<CollisionDetector::Impl*>(detector);
  Lane& l = self->lanes_[static_cast<std::size_t>(lane)];
  if (l.phase == 1 || l.phase == 2) self->runLane(l);
}

bool CollisionDetector::Impl::runContactPass() noexcept {
  PendingSweep& st = pending_;
  const RigidMotion& motion = st.motion;
  SweepResult& result = st.result;
  for (; st.contact_index < contact_count_; ++st.contact_index) {
    if (overBudget()) return false;
    const int j = contacts_[st.contact_index].point_index;
    if (j < 0 || embedded_[j]) continue;  // an edge contact has no path of its own
    startPoint(counters_, motion, j);
    if (!(pt_[j].path > 0.0)) continue;
    started_[j] = sweep_stamp_;
    startSearch(j);
    const double t_end = stepSegment(counters_, motion, j, 0, 0.0, st.isovalue, result.t, result);
    // Outside at the end of its first segment: a run test next (in the lane that holds it).
    if (t_end >= 0.0 && t_end < 1.0) {
      Lane& lane = lanes_[static_cast<std::size_t>(root_lane_[static_cast<std::size_t>(rank_of_point_[j])])];
      lane.heap[lane.queued++] = {t_end, j, 1, 1};
    }
    if (result.t == 0.0) break;  // nothing can come earlier
  }
  return true;
}

SweepResult CollisionDetector::Impl::cutBeforeLanes() noexcept {
  pending_.active = true;
  active_complete_ = false;
  SweepResult cut;
  cut.t = cut.t_inside = 0.0;
  cut.budget_cut = true;
  return cut;
}

void CollisionDetector::Impl::startLanePhase() noexcept {
  pending_.phase = 1;
  pending_.walk_t = pending_.result.t;
  for (Lane& lane : lanes_) {
    lane.phase = 1;
    lane.walk_top = -1;  // not started
    lane.count = 0;
    lane.result = SweepResult{};
  }
}

void CollisionDetector::Impl::forkLanes(double t_bound) noexcept {
  bound_->store(t_bound, std::memory_order_relaxed);
  for (Lane& lane : lanes_) {
    startLaneWork(lane);
    lane.cut = false;
    if (lane.phase == 3 && lane.result.t < bound_->load(std::memory_order_relaxed))
      bound_->store(lane.result.t, std::memory_order_relaxed);
  }
  if (pool_) {
    pool_->run(&CollisionDetector::Impl::laneJob, this, static_cast<int>(lanes_.size()));
  } else {
    for (Lane& lane : lanes_)
      if (lane.phase == 1 || lane.phase == 2) runLane(lane);
  }
  joinLaneWork();
}

SweepResult CollisionDetector::Impl::mergeLanes(const SweepResult& contact_hit) noexcept {
  SweepResult best = contact_hit;
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
    pending_.active = true;
    active_complete_ = walked;
    SweepResult cut;
    cut.t = cut.t_inside = walked ? std::min(cut_t, best.t) : 0.0;
    cut.budget_cut = true;
    return cut;
  }
  active_complete_ = true;
  return best;
}

SweepResult CollisionDetector::Impl::runAccelerated() noexcept {
  PendingSweep& st = pending_;
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
  if (st.phase == 0) {
    if (!runContactPass()) return cutBeforeLanes();
    if (result.t == 0.0) {
      active_complete_ = false;
      return result;
    }
    startLanePhase();
  }
  // The lanes: each walks its share of the point-shell tree, then searches its points in time
  // order, all bounded by the earliest hit any has found.
  forkLanes(result.t);
  return mergeLanes(result);
}

bool CollisionDetector::Impl::walkLane(Lane& lane) noexcept {
  const PendingSweep& st = pending_;
  const bool resume = lane.walk_top >= 0;
  lane.count = lane.queued + collectActive(lane, st.motion, st.walk_t, st.isovalue, true, resume);
  if (lane.walk_stopped) {
    lane.cut = true;
    lane.cut_t = 0.0;
    return false;
  }
  std::make_heap(lane.heap.begin(), lane.heap.begin() + static_cast<std::ptrdiff_t>(lane.count), Later{});
  lane.phase = 2;
  lane.pop_pending = false;
  return true;
}

void CollisionDetector::Impl::pushSuccessor(Lane& lane, const QueueEntry& entry) noexcept {
  replaceTop(lane.heap.data(), lane.count, entry);
  lane.pop_pending = false;
}

void CollisionDetector::Impl::resolveRun(Lane& lane, const QueueEntry& e) noexcept {
  const int j = e.point;
  const std::int64_t total = pt_[j].segments;
  const std::int64_t run = std::min(e.run, total - e.segment);
  if (!runMayHit(lane.counters, pending_.motion, j, e.segment, run, pending_.isovalue)) {
    search_[j].backoff = 0;
    const std::int64_t after = e.segment + run;
    if (search_[j].clear_segments == e.segment) {
      search_[j].clear_segments = after;
      pt_[j].clear_until = after >= total ? 1.0 : segmentBegin(j, after);
    }
    if (after < total) pushSuccessor(lane, {segmentBegin(j, after), j, after, std::min(2 * run, total - after)});
  } else {
    pushSuccessor(lane, {e.t_begin, j, e.segment, run / 2});  // run 1 becomes 0: sample it
  }
}

std::int64_t CollisionDetector::Impl::runAfterOutsideStep(PointSearch& search, std::int64_t run) noexcept {
  // Near the surface, after a failed test of one segment (run 0): 2^b direct steps (-2^b,
  // counting up to -1), then test a run again (1); b grows with each failure in a row and
  // is reset by a run proven empty. Along a surface (a tool sliding in a hole) the tests
  // fail nearly always and this keeps them to a few per point instead of one per 2 samples.
  std::int64_t successor = 1;
  if (run == 0) {
    successor = -(std::int64_t{1} << search.backoff);
    if (search.backoff < 6) ++search.backoff;
  } else if (run < -1) {
    successor = run + 1;
  }
  return successor;
}

void CollisionDetector::Impl::stepQueuedSegment(Lane& lane, const QueueEntry& e, double limit) noexcept {
  const int j = e.point;
  std::atomic<double>& bound = *bound_;
  SweepResult& result = lane.result;
  const double t_end = stepSegment(lane.counters, pending_.motion, j, e.segment, e.t_begin, pending_.isovalue, limit,
                                   result);
  if (result.hit_point == j && result.t < bound.load(std::memory_order_relaxed)) {
    double seen = bound.load(std::memory_order_relaxed);
    while (result.t < seen && !bound.compare_exchange_weak(seen, result.t, std::memory_order_relaxed)) {
    }
  }
  if (t_end >= 0.0 && t_end < 1.0) pushSuccessor(lane, {t_end, j, e.segment + 1, runAfterOutsideStep(search_[j], e.run)});
}

void CollisionDetector::Impl::searchLane(Lane& lane) noexcept {
  // The paper's time-ordered search over the segments that remain; the samples and the
  // bisection are the paper's, so the first time of contact is the same double.
  // Entries with run <= 0 are single segments sampled as the paper does (0: after a run test,
  // -1: a direct step). Runs of segments are resolved lazily, in time order: a run proven empty is skipped and the
  // next one doubles (conservative advancement); a run that may hit is halved down to one
  // segment, whose end is then sampled as the paper does, and after a sample that stays
  // outside the next segment is sampled directly once more before testing resumes.
  // Each step replaces the minimum by at most one successor (replaceTop: one sift).
  // The minimum stays at the root while it is processed; pushSuccessor() (at most once per
  // step) puts its successor there, else it is popped at the top of the next step.
  // With several lanes the search stops at the earliest hit of any lane (bound_).
  QueueEntry* const heap = lane.heap.data();
  std::atomic<double>& bound = *bound_;
  // Each step's work is charged to the upper node holding its point (rebalanceLanes()).
  std::int64_t mark = lane.counters.total();
  int stepped = -1;
  for (;;) {
    if (balanced_lanes_ && stepped >= 0) chargeRoot(lane, rank_of_point_[static_cast<std::size_t>(stepped)], mark);
    if (lane.pop_pending) {
      lane.pop_pending = false;
      if (--lane.count > 0) replaceTop(heap, lane.count, heap[lane.count]);
    }
    const double limit = std::min(lane.result.t, bound.load(std::memory_order_relaxed));
    if (!(lane.count > 0 && heap[0].t_begin < limit)) break;
    if (overBudget(lane)) {  // every path of the lane is proven free up to the queue's front
      lane.cut = true;
      lane.cut_t = heap[0].t_begin;
      return;
    }
    const QueueEntry e = heap[0];
    lane.pop_pending = true;
    stepped = e.point;
    if (e.run > 0) {  // an unresolved run
      resolveRun(lane, e);
    } else {
      stepQueuedSegment(lane, e, limit);
    }
  }
  lane.phase = 3;
}

void CollisionDetector::Impl::runLane(Lane& lane) noexcept {
  if (lane.phase == 1 && !walkLane(lane)) return;
  searchLane(lane);
}

}  // namespace vh::haptics
