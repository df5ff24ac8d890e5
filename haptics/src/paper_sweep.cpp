// The paper's sweep (section 2.3, kPaper): each point's arc split into ceil(s / f) equal time
// segments (setupPath()), each segment tested (stepSegment(): the exact first entry along its
// chord, refined on finer chords for a rotating point, or the paper's end sample) and the
// first crossing bisected, all points' segments in one time-ordered queue (sweepPaper()). The
// accelerated sweep takes the same steps (accelerated_sweep.cpp).
#include "collision_detector_impl.h"

#include <algorithm>
#include <cmath>
#include <cstdint>

#include "sweep_queue.h"

namespace vh::haptics {

void CollisionDetector::Impl::setupPath(WorkCounters& k, const RigidMotion& motion, int j) noexcept {
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

double CollisionDetector::Impl::stepSegment(WorkCounters& k, const RigidMotion& motion, int j, std::int64_t segment,
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

bool CollisionDetector::Impl::refineArcEntry(WorkCounters& w, const RigidMotion& motion, int j, double t0, double t1,
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

SweepResult CollisionDetector::Impl::sweepPaper(const RigidMotion& motion, double isovalue) noexcept {
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

}  // namespace vh::haptics
