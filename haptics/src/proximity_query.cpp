// The point shell's smallest distance to each segment per tick (ProximityQuery, distance_field.h).
#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "vh/haptics/distance_field.h"

namespace vh::haptics {
namespace {

/// The centre of the bounding box of points [begin, end) and the largest distance to it.
std::pair<Eigen::Vector3d, double> ballOf(const std::vector<Eigen::Vector3d>& p, std::size_t begin, std::size_t end) {
  if (begin >= end) return {Eigen::Vector3d::Zero(), 0.0};
  Eigen::Vector3d lo = p[begin], hi = p[begin];
  for (std::size_t i = begin; i < end; ++i) {
    lo = lo.cwiseMin(p[i]);
    hi = hi.cwiseMax(p[i]);
  }
  const Eigen::Vector3d c = 0.5 * (lo + hi);
  double r = 0.0;
  for (std::size_t i = begin; i < end; ++i) r = std::max(r, (p[i] - c).norm());
  return {c, r};
}

}  // namespace

ProximityQuery::ProximityQuery(std::vector<std::shared_ptr<const DistanceField>> fields, const PointShell& shell,
                               double range_m)
    : fields_(std::move(fields)), points_T_m_(shell.points_T_m()), range_m_(range_m) {
  for (const auto& f : fields_)
    if (!f) throw std::invalid_argument("ProximityQuery: a distance field is null");
  if (std::isnan(range_m) || range_m <= 0.0)
    throw std::invalid_argument("ProximityQuery: range must be > 0 (got " + std::to_string(range_m) + ")");
  const std::size_t n = points_T_m_.size();
  for (std::size_t b = 0; b < n; b += kGroupPoints) {
    const std::size_t e = std::min(n, b + kGroupPoints);
    const auto [c, r] = ballOf(points_T_m_, b, e);
    groups_.push_back({c, r, static_cast<int>(b), static_cast<int>(e)});
  }
  std::tie(centre_T_m_, radius_m_) = ballOf(points_T_m_, 0, n);
  order_.resize(groups_.size());
  results_.resize(fields_.size());
}

SegmentProximity ProximityQuery::evaluateField(const DistanceField& field, const Pose& X_WP) noexcept {
  SegmentProximity out;
  if (field.empty() || groups_.empty()) return out;
  const double slack_m = 2.0 * field.samplingBound_m();  // sample vs true distance, twice
  // The whole tool: every point lies within radius_m_ of its ball's centre (1-Lipschitz).
  ++points_sampled_;
  if (field.sample_m(X_WP * centre_T_m_) - radius_m_ - slack_m > range_m_) return out;
  for (std::size_t g = 0; g < groups_.size(); ++g) {
    const Group& group = groups_[g];
    order_[g] = {field.sample_m(X_WP * group.centre_T_m) - group.radius_m - slack_m, static_cast<int>(g)};
  }
  points_sampled_ += groups_.size();
  std::sort(order_.begin(), order_.end());  // in place: no allocation
  double best = std::numeric_limits<double>::infinity();
  for (const auto& [lower_bound_m, g] : order_) {
    // No later group can hold a nearer point, or one within the range.
    if (lower_bound_m >= best || lower_bound_m > range_m_) break;
    const Group& group = groups_[static_cast<std::size_t>(g)];
    for (int p = group.begin; p < group.end; ++p) {
      const double d = field.sample_m(X_WP * points_T_m_[static_cast<std::size_t>(p)]);
      if (d < best) {
        best = d;
        out.point = p;
      }
    }
    points_sampled_ += static_cast<std::size_t>(group.end - group.begin);
  }
  if (best > range_m_) return SegmentProximity{};
  out.distance_m = best;
  return out;
}

NearestProximity ProximityQuery::evaluate(const Pose& X_WP) noexcept {
  points_sampled_ = 0;
  NearestProximity nearest;
  if (!X_WP.allFinite()) {
    std::fill(results_.begin(), results_.end(), SegmentProximity{});
    return nearest;
  }
  for (std::size_t f = 0; f < fields_.size(); ++f) {
    results_[f] = evaluateField(*fields_[f], X_WP);
    if (results_[f].distance_m < nearest.distance_m) nearest = {static_cast<int>(f), results_[f].distance_m};
  }
  return nearest;
}

}  // namespace vh::haptics
