// The contact set: its contacts measured (normal, clearance), pruned (step 2), added after a
// sweep's hit (addContactsAt()) and reduced to the contact cap by farthest-point selection, and
// a stuck contact's normal refined.
#include "collision_detector_impl.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstddef>
#include <limits>

namespace vh::haptics {

bool CollisionDetector::Impl::inside(const Eigen::Vector3d& p_W, double isovalue) noexcept {
  ++counters_.samples;
  return volume_->isInside(p_W, isovalue);
}

void CollisionDetector::Impl::measureContact(Contact& c, double isovalue, const Eigen::Quaterniond& R_WT) noexcept {
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

void CollisionDetector::Impl::appendContact(int point, const Eigen::Vector3d& p_W, const Eigen::Vector3d& fallback_n_W,
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

void CollisionDetector::Impl::clearContacts() noexcept {
  for (std::size_t i = 0; i < contact_count_; ++i)
    if (contacts_[i].point_index >= 0) in_set_[contacts_[i].point_index] = 0;
  contact_count_ = 0;
}

void CollisionDetector::Impl::pruneContacts(const Pose& X_WP, const Pose& X_WD, double isovalue) noexcept {
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

void CollisionDetector::Impl::releaseClearContacts(const Pose& X_WP, double isovalue, double clearance_m) noexcept {
  std::size_t kept = 0;
  for (std::size_t i = 0; i < contact_count_; ++i) {
    Contact c = contacts_[i];
    const int j = c.point_index;
    c.p_W_m = X_WP * c.p_T_m;
    measureContact(c, isovalue, X_WP.R_AB);
    if (c.clearance_m <= clearance_m || inside(c.p_W_m, isovalue)) {
      contacts_[kept++] = c;
    } else if (j >= 0) {
      in_set_[j] = 0;
    }
  }
  contact_count_ = kept;
}

void CollisionDetector::Impl::addContactsAt(const RigidMotion& motion, const SweepResult& hit, double isovalue) noexcept {
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

void CollisionDetector::Impl::reduceContacts(const RigidMotion& motion, double t, int hit_point, std::size_t& candidates,
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

bool CollisionDetector::Impl::refineStuckContact(const RigidMotion& motion, const SweepResult& hit) noexcept {
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

void CollisionDetector::Impl::refreshPositions(const Pose& X_WP) noexcept {
  for (std::size_t i = 0; i < contact_count_; ++i) contacts_[i].p_W_m = X_WP * contacts_[i].p_T_m;
}

}  // namespace vh::haptics
