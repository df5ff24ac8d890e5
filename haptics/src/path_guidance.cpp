#include "vh/haptics/path_guidance.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace vh::haptics {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

int clampCell(double x, double origin, double cell, int dim) noexcept {
  const double c = std::floor((x - origin) / cell);
  if (!(c >= 0.0)) return 0;  // also NaN
  return c >= dim - 1 ? dim - 1 : static_cast<int>(c);
}

}  // namespace

GuidancePath::GuidancePath(std::vector<Segment> segments, int cells_per_axis) : segments_(std::move(segments)) {
  if (cells_per_axis < 1) throw std::invalid_argument("GuidancePath: cells_per_axis must be >= 1");
  if (segments_.empty()) return;
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(kInf), hi = -lo;
  for (std::size_t i = 0; i < segments_.size(); ++i) {
    const Segment& s = segments_[i];
    if (!s.a_W_m.allFinite() || !s.b_W_m.allFinite())
      throw std::invalid_argument("GuidancePath: segment " + std::to_string(i) + " has a non-finite point");
    lo = lo.cwiseMin(s.a_W_m).cwiseMin(s.b_W_m);
    hi = hi.cwiseMax(s.a_W_m).cwiseMax(s.b_W_m);
  }
  // The grid reaches a quarter of the path's extent beyond it on every side: a trainee who
  // wanders off stays inside it, where the ring search stops soonest.
  const double longest = std::max((hi - lo).maxCoeff(), 1e-6);
  lo.array() -= 0.25 * longest;
  hi.array() += 0.25 * longest;
  // Cells of about four segments' length (a few segments per cell along the path), but at
  // most cells_per_axis along the longest side.
  double length_m = 0.0;
  for (const Segment& seg : segments_) length_m += (seg.b_W_m - seg.a_W_m).norm();
  cell_m_ = std::max(1.5 * longest / cells_per_axis, 4.0 * length_m / static_cast<double>(segments_.size()));
  origin_W_m_ = lo;
  for (int k = 0; k < 3; ++k) dims_[k] = std::max(1, static_cast<int>(std::ceil((hi[k] - lo[k]) / cell_m_ + 1e-9)));
  const std::size_t cells = static_cast<std::size_t>(dims_[0]) * static_cast<std::size_t>(dims_[1]) *
                            static_cast<std::size_t>(dims_[2]);
  // Two passes over each segment's cell box: count, then fill (CSR).
  cell_start_.assign(cells + 1, 0);
  const auto forEachCell = [&](const Segment& s, auto&& visit) {
    const Eigen::Vector3d a = s.a_W_m.cwiseMin(s.b_W_m), b = s.a_W_m.cwiseMax(s.b_W_m);
    int l[3], h[3];
    for (int k = 0; k < 3; ++k) {
      l[k] = clampCell(a[k], origin_W_m_[k], cell_m_, dims_[k]);
      h[k] = clampCell(b[k], origin_W_m_[k], cell_m_, dims_[k]);
    }
    for (int z = l[2]; z <= h[2]; ++z)
      for (int y = l[1]; y <= h[1]; ++y)
        for (int x = l[0]; x <= h[0]; ++x) visit(cellIndex(x, y, z));
  };
  for (const Segment& s : segments_) forEachCell(s, [&](std::size_t c) { ++cell_start_[c + 1]; });
  for (std::size_t c = 0; c < cells; ++c) cell_start_[c + 1] += cell_start_[c];
  cell_segments_.resize(cell_start_[cells]);
  std::vector<std::uint32_t> fill(cell_start_.begin(), cell_start_.end() - 1);
  for (std::size_t i = 0; i < segments_.size(); ++i)
    forEachCell(segments_[i], [&](std::size_t c) { cell_segments_[fill[c]++] = static_cast<std::uint32_t>(i); });
  for (std::size_t c = 0; c < cells; ++c)
    if (cell_start_[c + 1] > cell_start_[c]) occupied_cells_.push_back(static_cast<std::uint32_t>(c));
}

GuidancePath GuidancePath::polyline(const std::vector<Eigen::Vector3d>& points, int cells_per_axis) {
  std::vector<Segment> segments;
  if (points.size() == 1) segments.push_back({points[0], points[0]});
  for (std::size_t i = 0; i + 1 < points.size(); ++i) segments.push_back({points[i], points[i + 1]});
  return GuidancePath(std::move(segments), cells_per_axis);
}

PathPoint GuidancePath::nearestOnSegment(std::size_t i, const Eigen::Vector3d& p) const noexcept {
  const Segment& seg = segments_[i];
  const Eigen::Vector3d ab = seg.b_W_m - seg.a_W_m;
  const double len2 = ab.squaredNorm();
  const double s = len2 > 0.0 ? std::clamp((p - seg.a_W_m).dot(ab) / len2, 0.0, 1.0) : 0.0;
  PathPoint out;
  out.p_W_m = seg.a_W_m + s * ab;
  out.distance_m = (p - out.p_W_m).norm();
  out.segment = static_cast<std::int64_t>(i);
  out.s = s;
  return out;
}

PathPoint GuidancePath::nearestBruteForce(const Eigen::Vector3d& p) const noexcept {
  PathPoint best;
  best.distance_m = kInf;
  for (std::size_t i = 0; i < segments_.size(); ++i) {
    const PathPoint c = nearestOnSegment(i, p);
    if (c.distance_m < best.distance_m) best = c;
  }
  return best;
}

void GuidancePath::searchCell(int ix, int iy, int iz, const Eigen::Vector3d& p, PathPoint& best) const noexcept {
  const std::size_t c = cellIndex(ix, iy, iz);
  for (std::uint32_t k = cell_start_[c]; k < cell_start_[c + 1]; ++k) {
    const std::uint32_t i = cell_segments_[k];
    const PathPoint cand = nearestOnSegment(i, p);
    // Ties: the lower segment index, as the brute force keeps the first it meets.
    if (cand.distance_m < best.distance_m || (cand.distance_m == best.distance_m && cand.segment < best.segment))
      best = cand;
  }
}

PathPoint GuidancePath::nearest(const Eigen::Vector3d& p) const noexcept {
  PathPoint best;
  best.distance_m = kInf;
  if (segments_.empty() || !p.allFinite()) return best;
  int c[3];
  for (int k = 0; k < 3; ++k) c[k] = clampCell(p[k], origin_W_m_[k], cell_m_, dims_[k]);
  for (int r = 0; r <= kMaxRings; ++r) {
    // The cells at Chebyshev distance r from c (the shell of the (2r + 1)^3 cube), in the grid.
    const int z0 = std::max(0, c[2] - r), z1 = std::min(dims_[2] - 1, c[2] + r);
    const int y0 = std::max(0, c[1] - r), y1 = std::min(dims_[1] - 1, c[1] + r);
    const int x0 = std::max(0, c[0] - r), x1 = std::min(dims_[0] - 1, c[0] + r);
    for (int z = z0; z <= z1; ++z) {
      for (int y = y0; y <= y1; ++y) {
        const bool face = std::abs(z - c[2]) == r || std::abs(y - c[1]) == r;
        if (face) {
          for (int x = x0; x <= x1; ++x) searchCell(x, y, z, p, best);
        } else {  // only the two cells at x = c -+ r
          if (c[0] - r >= 0) searchCell(c[0] - r, y, z, p, best);
          if (r > 0 && c[0] + r < dims_[0]) searchCell(c[0] + r, y, z, p, best);
        }
      }
    }
    // Every segment not met yet lies in a cell beyond one of the searched cube's faces that
    // has cells beyond it: at least that face's distance from p away.
    const int lo[3] = {x0, y0, z0}, hi[3] = {x1, y1, z1};
    double bound = kInf;
    for (int k = 0; k < 3; ++k) {
      if (lo[k] > 0) bound = std::min(bound, p[k] - (origin_W_m_[k] + lo[k] * cell_m_));
      if (hi[k] < dims_[k] - 1) bound = std::min(bound, origin_W_m_[k] + (hi[k] + 1) * cell_m_ - p[k]);
    }
    if (best.distance_m <= bound) return best;  // infinity: every cell searched
  }
  searchOccupiedCells(p, best);  // far from the path: the cells that hold segments, pruned by distance
  return best;
}

void GuidancePath::searchOccupiedCells(const Eigen::Vector3d& p, PathPoint& best) const noexcept {
  // A first bound from a few segments spread over the path, then every occupied cell nearer
  // than the best so far.
  const std::size_t stride = std::max<std::size_t>(1, segments_.size() / 16);
  for (std::size_t i = 0; i < segments_.size(); i += stride) {
    const PathPoint c = nearestOnSegment(i, p);
    if (c.distance_m < best.distance_m) best = c;
  }
  const std::size_t nx = static_cast<std::size_t>(dims_[0]), ny = static_cast<std::size_t>(dims_[1]);
  for (const std::uint32_t c : occupied_cells_) {
    const int ix = static_cast<int>(c % nx), iy = static_cast<int>((c / nx) % ny), iz = static_cast<int>(c / (nx * ny));
    const Eigen::Vector3d lo = origin_W_m_ + cell_m_ * Eigen::Vector3d(ix, iy, iz);
    const Eigen::Vector3d gap = (lo - p).cwiseMax(p - (lo.array() + cell_m_).matrix()).cwiseMax(0.0);
    if (gap.squaredNorm() < best.distance_m * best.distance_m) searchCell(ix, iy, iz, p, best);
  }
}

double GuidanceGains::effectiveStiffness_N_per_m() const noexcept {
  return stiffness_N_per_m * std::pow(fade, static_cast<double>(std::max(repetition, 0)));
}

bool GuidanceGains::valid() const noexcept {
  return std::isfinite(stiffness_N_per_m) && stiffness_N_per_m >= 0.0 && std::isfinite(cap_N) && cap_N >= 0.0 &&
         std::isfinite(deadband_m) && deadband_m >= 0.0 && std::isfinite(fade) && fade > 0.0 && fade <= 1.0 &&
         repetition >= 0;
}

GuidanceForce guidanceForce(const GuidancePath& path, const GuidanceGains& gains, const Eigen::Vector3d& p_WD_m) noexcept {
  GuidanceForce out;
  if (path.empty() || !gains.valid() || !p_WD_m.allFinite()) return out;
  out.nearest = path.nearest(p_WD_m);
  const double d = out.nearest.distance_m;
  if (!(d > gains.deadband_m) || !(d > 0.0)) return out;
  const double magnitude = std::min(gains.effectiveStiffness_N_per_m() * (d - gains.deadband_m), gains.cap_N);
  out.force_W_N = (magnitude / d) * (out.nearest.p_W_m - p_WD_m);
  // Rounding can put |F| an ulp or two above the cap: scale back until it is not.
  for (int k = 0; k < 8 && out.force_W_N.norm() > gains.cap_N; ++k)
    out.force_W_N *= std::nextafter(gains.cap_N / out.force_W_N.norm(), 0.0);
  return out;
}

}  // namespace vh::haptics
