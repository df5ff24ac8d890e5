// The edge test's clearance certificates (edge_certificates.h): how far an edge found free may
// move and stay free, whether a point's certificate still holds at a new pose (by distance, or
// along the move's direction with F's derivative ranges), and the two kept per point.
#include "collision_detector_impl.h"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <limits>

namespace vh::haptics {

double CollisionDetector::Impl::edgeClearance(const Eigen::Vector3d& a, const Eigen::Vector3d& b, double excess_max,
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

void CollisionDetector::Impl::noteFieldRise(double rise) noexcept {
  if (!(rise >= 0.0) || !std::isfinite(rise)) {
    forgetEdgeCertificates();
    return;
  }
  if (rise == 0.0) return;
  // Rounded upward, so that field_rise_ less a certificate's rise_at_proof is at least the sum
  // of the rises noted since (before the subtraction's own rounding, which edgesStillClear()
  // covers).
  field_rise_ = std::nextafter(field_rise_ + rise, std::numeric_limits<double>::infinity());
}

CollisionDetector::Impl::EdgeHold CollisionDetector::Impl::edgesStillClear(const Pose& X_WP, int j,
                                                               const Eigen::Vector3d& p_W) const noexcept {
  const auto i = static_cast<std::size_t>(edge_clearance_index_[static_cast<std::size_t>(j)]);
  // The newer first (edge_slot_ names the older, which the next certificate replaces): it is
  // the one that holds where either does, more often than not.
  const std::size_t newer = 2 * i + (edge_slot_[i] ^ 1u);
  for (const std::size_t slot : {newer, newer ^ 1u}) {
    const EdgeClearance& proven = edge_clearance_[slot];
    // Where F rose since the proof (noteFieldRise()): the distance certificates end, the
    // directional one holds with its margin less the rise (widened for the subtraction's
    // rounding).
    const double risen = field_rise_ - proven.rise_at_proof;
    const bool still = risen == 0.0;
    const double margin = still ? proven.margin : proven.margin - (risen * (1.0 + 1e-12) + 1e-300);
    const bool by_distance = still && proven.clearance_m > 0.0, by_direction = margin > 0.0;
    if (!by_distance && !by_direction) continue;  // nothing proven, or nothing left
    const Eigen::Vector3d moved_W = p_W - proven.p_W_m;
    const double moved_m = moved_W.norm();
    if (proven.arm_m == 0.0) {  // a ball about point j: any turn stays in it
      if (by_distance && moved_m < proven.clearance_m) return EdgeHold::kBoxQuery;
      continue;
    }
    if (!by_direction && !(moved_m < proven.clearance_m)) continue;
    // Each point of j's edges lies within arm_m (edge_reach_m_[j] + epsilon) of point j
    // (edgeEnd()), so it has moved by point j's move plus at most |R - R'| arm_m since the
    // certificate, with |R - R'| = 2 sin(theta / 2) = 2 |vec(R'^-1 R)|.
    const double lever_m = 2.0 * (proven.R_WT.conjugate() * X_WP.R_AB).vec().norm() * proven.arm_m;
    if (by_distance && moved_m + lever_m < proven.clearance_m) return EdgeHold::kWalk;
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
    if (within && rise * (1.0 + 1e-9) < margin) return EdgeHold::kWalk;
  }
  return EdgeHold::kNone;
}

void CollisionDetector::Impl::keepEdgeClearance(int j, const EdgeClearance& proven) noexcept {
  const auto i = static_cast<std::size_t>(j);
  const auto at = static_cast<std::size_t>(edge_clearance_index_[i]);
  EdgeClearance& kept = edge_clearance_[2 * at + edge_slot_[at]];
  kept = proven;
  kept.rise_at_proof = field_rise_;
  edge_slot_[at] ^= 1;
}

}  // namespace vh::haptics
