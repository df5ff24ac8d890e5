#include "vh/haptics/point_shell.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <random>
#include <stdexcept>
#include <cstdint>
#include <unordered_map>
#include <utility>

namespace vh::haptics {

PointShell::PointShell(std::vector<Eigen::Vector3d> points_T_m, std::vector<Eigen::Vector3d> normals_T)
    : points_(std::move(points_T_m)), normals_(std::move(normals_T)) {
  if (!normals_.empty() && normals_.size() != points_.size())
    throw std::invalid_argument("PointShell: " + std::to_string(normals_.size()) + " normals for " +
                                std::to_string(points_.size()) + " points");
  for (const auto& p : points_)
    if (!p.allFinite()) throw std::invalid_argument("PointShell: a point is not finite");
  for (const auto& n : normals_)
    if (!n.allFinite()) throw std::invalid_argument("PointShell: a normal is not finite");
}

namespace {

// Cubic cells over the box [lo, hi], at least `min_cell_m` wide, widened by steps of 25 % until
// there are at most kMaxCells of them (16 MB of int heads), indexed x fastest. A point outside
// the box (a rounding error) falls into the nearest cell.
struct DenseGrid {
  static constexpr double kMaxCells = 4.0 * 1024 * 1024;
  Eigen::Vector3d lo;
  double cell_m;
  Eigen::Array3i dims;
  DenseGrid(const Eigen::Vector3d& lo_m, const Eigen::Vector3d& hi_m, double min_cell_m) : lo(lo_m), cell_m(min_cell_m) {
    Eigen::Array3d d = ((hi_m - lo_m).array() / cell_m).floor() + 1.0;
    while (d.prod() > kMaxCells) {
      cell_m *= 1.25;
      d = ((hi_m - lo_m).array() / cell_m).floor() + 1.0;
    }
    dims = d.cast<int>();
  }
  std::size_t size() const { return static_cast<std::size_t>(dims.prod()); }
  Eigen::Array3i cellOf(const Eigen::Vector3d& p) const {
    return (((p - lo).array() / cell_m).floor().cast<int>()).min(dims - 1).max(0);
  }
  std::size_t index(int x, int y, int z) const { return (static_cast<std::size_t>(z) * dims.y() + y) * dims.x() + x; }
};

}  // namespace

double PointShell::meanNearestNeighbourSpacing_m() const {
  if (points_.size() < 2) return 0.0;
  // Each point's nearest neighbour from a dense grid over the points' bounding box (about two
  // points a cell for a surface), searched ring by ring around its cell until no point outside
  // the rings searched can be nearer: the same minimum as comparing every pair (the same
  // squared norms), in O(n) instead of O(n^2) (0.6-0.8 s at 20,000 points, at every
  // recording's start).
  Eigen::Vector3d lo = points_[0], hi = points_[0];
  for (const auto& p : points_) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  const Eigen::Vector3d extent = hi - lo;
  const double area_estimate = extent.x() * extent.y() + extent.y() * extent.z() + extent.z() * extent.x();
  double cell = std::sqrt(2.0 * area_estimate / static_cast<double>(points_.size()));
  if (!(cell > 0.0)) cell = std::max(extent.maxCoeff(), std::numeric_limits<double>::min());
  const DenseGrid grid(lo, hi, cell);
  const Eigen::Array3i& dims = grid.dims;
  // Counting sort of the points by cell: start[c] .. start[c + 1] index `by_cell`.
  std::vector<int> start(grid.size() + 1, 0), by_cell(points_.size());
  for (const auto& p : points_) {
    const Eigen::Array3i c = grid.cellOf(p);
    ++start[grid.index(c.x(), c.y(), c.z()) + 1];
  }
  for (std::size_t c = 1; c < start.size(); ++c) start[c] += start[c - 1];
  {
    std::vector<int> fill(start.begin(), start.end() - 1);
    for (std::size_t i = 0; i < points_.size(); ++i) {
      const Eigen::Array3i c = grid.cellOf(points_[i]);
      by_cell[static_cast<std::size_t>(fill[grid.index(c.x(), c.y(), c.z())]++)] = static_cast<int>(i);
    }
  }
  const int max_ring = dims.maxCoeff();
  double sum = 0.0;
  for (std::size_t i = 0; i < points_.size(); ++i) {
    const Eigen::Array3i c = grid.cellOf(points_[i]);
    double best = std::numeric_limits<double>::infinity();
    // After ring k every point not yet seen lies at least k cells (k * cell) away.
    for (int k = 0; k <= max_ring; ++k) {
      for (int z = std::max(c.z() - k, 0); z <= std::min(c.z() + k, dims.z() - 1); ++z)
        for (int y = std::max(c.y() - k, 0); y <= std::min(c.y() + k, dims.y() - 1); ++y) {
          const bool inner = std::abs(z - c.z()) < k && std::abs(y - c.y()) < k;
          for (int x = std::max(c.x() - k, 0); x <= std::min(c.x() + k, dims.x() - 1);
               x += (inner && x == c.x() - k) ? 2 * k : 1) {  // the ring only: x = c.x() +- k inside
            const std::size_t f = grid.index(x, y, z);
            for (int q = start[f]; q < start[f + 1]; ++q) {
              const auto j = static_cast<std::size_t>(by_cell[static_cast<std::size_t>(q)]);
              if (j != i) best = std::min(best, (points_[i] - points_[j]).squaredNorm());
            }
          }
        }
      const double reach = k * grid.cell_m;
      if (best <= reach * reach) break;
    }
    sum += std::sqrt(best);
  }
  return sum / static_cast<double>(points_.size());
}

namespace {

// Points of `points` binned in cubic cells of side `cell_m`.
struct PointGrid {
  double cell_m = 1.0;
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();
  std::unordered_map<std::int64_t, std::vector<int>> cells;
  std::int64_t key(int x, int y, int z) const {
    return (static_cast<std::int64_t>(x) * 2097152 + y) * 2097152 + z;
  }
  Eigen::Vector3i index(const Eigen::Vector3d& p) const {
    return ((p - origin) / cell_m).array().floor().cast<int>();
  }
  PointGrid(const std::vector<Eigen::Vector3d>& points, double cell) : cell_m(cell) {
    origin = points[0];
    for (const auto& p : points) origin = origin.cwiseMin(p);
    for (std::size_t i = 0; i < points.size(); ++i) {
      const Eigen::Vector3i c = index(points[i]);
      cells[key(c.x(), c.y(), c.z())].push_back(static_cast<int>(i));
    }
  }
  template <typename F>
  void near(const Eigen::Vector3d& p, F&& f) const {
    const Eigen::Vector3i c = index(p);
    for (int z = c.z() - 1; z <= c.z() + 1; ++z)
      for (int y = c.y() - 1; y <= c.y() + 1; ++y)
        for (int x = c.x() - 1; x <= c.x() + 1; ++x) {
          const auto it = cells.find(key(x, y, z));
          if (it != cells.end())
            for (int k : it->second) f(k);
        }
  }
};

}  // namespace

ShellEdges makeShellEdges(const PointShell& shell) {
  ShellEdges edges;
  const auto& points = shell.points_T_m();
  const std::size_t n = points.size();
  edges.offsets.assign(n + 1, 0);
  if (n < 2) return edges;
  // The spacing: the median nearest-neighbour distance, searched within a first guess (a
  // surface of extent D sampled by n points has a spacing near D / sqrt(n)).
  Eigen::Vector3d lo = points[0], hi = points[0];
  for (const auto& p : points) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  const double guess = std::max((hi - lo).norm() / std::sqrt(static_cast<double>(n)), 1e-9);
  std::vector<double> nearest(n, guess);
  {
    const PointGrid grid(points, guess);
    for (std::size_t j = 0; j < n; ++j)
      grid.near(points[j], [&](int k) {
        if (static_cast<std::size_t>(k) != j) nearest[j] = std::min(nearest[j], (points[k] - points[j]).norm());
      });
  }
  std::nth_element(nearest.begin(), nearest.begin() + static_cast<std::ptrdiff_t>(n / 2), nearest.end());
  edges.spacing_m = nearest[n / 2];
  edges.max_length_m = ShellEdges::kLengthFactor * edges.spacing_m;
  if (!(edges.max_length_m > 0.0)) return edges;
  const PointGrid grid(points, edges.max_length_m);
  std::vector<std::pair<double, int>> candidates;
  std::vector<std::vector<int>> adjacency(n);
  for (std::size_t j = 0; j < n; ++j) {
    candidates.clear();
    grid.near(points[j], [&](int k) {
      if (static_cast<std::size_t>(k) == j) return;
      const double d = (points[k] - points[j]).norm();
      if (d > edges.max_length_m) return;
      if (shell.hasNormals() && shell.normals_T()[j].dot(shell.normals_T()[k]) <= 0.3) return;
      candidates.emplace_back(d, k);
    });
    const std::size_t keep = std::min<std::size_t>(candidates.size(), ShellEdges::kMaxNeighbours);
    std::partial_sort(candidates.begin(), candidates.begin() + static_cast<std::ptrdiff_t>(keep), candidates.end());
    for (std::size_t c = 0; c < keep; ++c) {
      const int k = candidates[c].second;
      const int a = std::min(static_cast<int>(j), k), b = std::max(static_cast<int>(j), k);
      adjacency[static_cast<std::size_t>(a)].push_back(b);
    }
  }
  for (std::size_t j = 0; j < n; ++j) {
    auto& row = adjacency[j];
    std::sort(row.begin(), row.end());
    row.erase(std::unique(row.begin(), row.end()), row.end());
    edges.offsets[j + 1] = edges.offsets[j] + static_cast<int>(row.size());
  }
  edges.targets.reserve(static_cast<std::size_t>(edges.offsets[n]));
  for (const auto& row : adjacency) edges.targets.insert(edges.targets.end(), row.begin(), row.end());
  return edges;
}

namespace {

struct Candidate {
  Eigen::Vector3d p;
  Eigen::Vector3d n;
};

// Area-weighted uniform samples on the mesh, in random order.
std::vector<Candidate> sampleCandidates(const TriangleMesh& mesh, std::size_t count, unsigned seed) {
  std::vector<double> cumulative(mesh.triangles.size());
  double total = 0.0;
  for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
    const auto& tri = mesh.triangles[t];
    total += 0.5 * (mesh.vertices_T_m[tri[1]] - mesh.vertices_T_m[tri[0]])
                       .cross(mesh.vertices_T_m[tri[2]] - mesh.vertices_T_m[tri[0]])
                       .norm();
    cumulative[t] = total;
  }
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> uni(0.0, 1.0);
  std::vector<Candidate> out;
  out.reserve(count);
  for (std::size_t c = 0; c < count; ++c) {
    const double r = uni(rng) * total;
    const std::size_t t = std::min<std::size_t>(
        static_cast<std::size_t>(std::lower_bound(cumulative.begin(), cumulative.end(), r) - cumulative.begin()),
        cumulative.size() - 1);
    const auto& tri = mesh.triangles[t];
    const Eigen::Vector3d& a = mesh.vertices_T_m[tri[0]];
    const Eigen::Vector3d& b = mesh.vertices_T_m[tri[1]];
    const Eigen::Vector3d& cc = mesh.vertices_T_m[tri[2]];
    double u = uni(rng), v = uni(rng);
    if (u + v > 1.0) {
      u = 1.0 - u;
      v = 1.0 - v;
    }
    Eigen::Vector3d n = (b - a).cross(cc - a);
    const double nn = n.norm();
    n = nn > 0.0 ? Eigen::Vector3d(n / nn) : Eigen::Vector3d::UnitZ();
    out.push_back({a + u * (b - a) + v * (cc - a), n});
  }
  return out;
}

// Poisson-disk thinning: dart throwing over the candidates in their (random) order, each one
// accepted when no point accepted before it lies closer than `radius`. The accepted points near
// a candidate are found in a dense grid over the candidates' bounding box, each cell the head of
// a list of its points (flat arrays; a hash map of vectors made the bisection of makePointShell
// take 6 s for 20,000 points). Cells are at least `radius` wide, so every accepted point closer
// than `radius` lies in the 27 cells around the candidate and the decision is exact whatever
// the cell size (cells grow past `radius` only to bound the grid, DenseGrid).
// Stops once `limit` points are accepted: each decision depends only on the points accepted
// before it, so the first `limit` are those of the unlimited thinning.
std::vector<std::size_t> poissonThin(const std::vector<Candidate>& cand, double radius,
                                     std::size_t limit = std::numeric_limits<std::size_t>::max()) {
  std::vector<std::size_t> accepted;
  if (!(radius > 0.0) || cand.empty()) {
    accepted.resize(std::min(limit, cand.size()));
    for (std::size_t i = 0; i < accepted.size(); ++i) accepted[i] = i;
    return accepted;
  }
  Eigen::Vector3d lo = cand[0].p, hi = cand[0].p;
  for (const Candidate& c : cand) {
    lo = lo.cwiseMin(c.p);
    hi = hi.cwiseMax(c.p);
  }
  const DenseGrid grid(lo, hi, radius);
  const Eigen::Array3i& dims = grid.dims;
  std::vector<int> head(grid.size(), -1);  // per cell: its last accepted point
  std::vector<int> next_in_cell;  // per accepted point: the cell's one accepted before it, or -1
  std::vector<Eigen::Vector3d> accepted_p;  // per accepted point: its position (read in place of cand's)
  const double r2 = radius * radius;
  for (std::size_t c = 0; c < cand.size() && accepted.size() < limit; ++c) {
    const Eigen::Vector3d& p = cand[c].p;
    const Eigen::Array3i at = grid.cellOf(p);
    bool ok = true;
    for (int z = std::max(at.z() - 1, 0); z <= std::min(at.z() + 1, dims.z() - 1) && ok; ++z)
      for (int y = std::max(at.y() - 1, 0); y <= std::min(at.y() + 1, dims.y() - 1) && ok; ++y)
        for (int x = std::max(at.x() - 1, 0); x <= std::min(at.x() + 1, dims.x() - 1) && ok; ++x)
          for (int q = head[grid.index(x, y, z)]; q >= 0 && ok; q = next_in_cell[static_cast<std::size_t>(q)])
            ok = (accepted_p[static_cast<std::size_t>(q)] - p).squaredNorm() >= r2;
    if (!ok) continue;
    int& cell_head = head[grid.index(at.x(), at.y(), at.z())];
    next_in_cell.push_back(cell_head);
    cell_head = static_cast<int>(accepted.size());
    accepted.push_back(c);
    accepted_p.push_back(p);
  }
  return accepted;
}

// The points' indices in Morton (Z-curve) order over their bounding box, 21 bits an axis: points
// near each other in space get indices near each other, so a collision query that visits a
// region of the tool (a node of CollisionDetector's point-shell tree) reads its points' state
// from a few neighbouring cache lines instead of from all over memory (the thinning keeps
// points in random order).
void sortSpatially(const std::vector<Candidate>& cand, std::vector<std::size_t>& chosen) {
  if (chosen.size() < 2) return;
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
  for (std::size_t c : chosen) {
    lo = lo.cwiseMin(cand[c].p);
    hi = hi.cwiseMax(cand[c].p);
  }
  constexpr double kCells = double((1u << 21) - 1);
  const double extent = std::max((hi - lo).maxCoeff(), std::numeric_limits<double>::min());
  // Spreads the low 21 bits of v to every third bit.
  const auto spread = [](std::uint64_t v) {
    v &= 0x1fffff;
    v = (v | v << 32) & 0x1f00000000ffffULL;
    v = (v | v << 16) & 0x1f0000ff0000ffULL;
    v = (v | v << 8) & 0x100f00f00f00f00fULL;
    v = (v | v << 4) & 0x10c30c30c30c30c3ULL;
    v = (v | v << 2) & 0x1249249249249249ULL;
    return v;
  };
  std::vector<std::pair<std::uint64_t, std::size_t>> keyed;
  keyed.reserve(chosen.size());
  for (std::size_t c : chosen) {
    const Eigen::Vector3d q = (cand[c].p - lo) / extent * kCells;
    keyed.emplace_back(spread(static_cast<std::uint64_t>(q.x())) | spread(static_cast<std::uint64_t>(q.y())) << 1 |
                           spread(static_cast<std::uint64_t>(q.z())) << 2,
                       c);
  }
  std::sort(keyed.begin(), keyed.end());
  for (std::size_t i = 0; i < keyed.size(); ++i) chosen[i] = keyed[i].second;
}

}  // namespace

PointShell makePointShell(const TriangleMesh& mesh, const PointShellOptions& options) {
  if (mesh.triangles.empty()) throw std::invalid_argument("makePointShell: the mesh has no triangles");
  const double area = mesh.area_m2();
  if (!(area > 0.0) || !std::isfinite(area)) throw std::invalid_argument("makePointShell: the mesh has zero area");
  constexpr std::size_t kMaxPoints = 200000;
  // A Poisson-disk set of radius r covers about 0.6 r^2 of area per point... use the hexagonal
  // packing density (sqrt(3)/2 r^2 per point) with a margin for the estimate.
  double radius = options.spacing_m;
  if (options.point_count > 0) {
    if (options.point_count > kMaxPoints) throw std::invalid_argument("makePointShell: more than 200000 points requested");
    radius = std::sqrt(area / (0.7 * static_cast<double>(options.point_count)));
  } else if (!(options.spacing_m > 0.0) || !std::isfinite(options.spacing_m)) {
    throw std::invalid_argument("makePointShell: point spacing must be > 0");
  }
  const double expected = area / (0.7 * radius * radius);
  if (expected > 1.5 * kMaxPoints)
    throw std::invalid_argument("makePointShell: spacing " + std::to_string(options.spacing_m) +
                                " m would need about " + std::to_string(static_cast<long long>(expected)) +
                                " points (limit 200000)");
  const std::size_t want = options.point_count > 0 ? options.point_count : static_cast<std::size_t>(expected);
  const std::size_t n_candidates = std::clamp<std::size_t>(30 * std::max<std::size_t>(want, 1), 2000, 3000000);
  const std::vector<Candidate> cand = sampleCandidates(mesh, n_candidates, options.seed);

  std::vector<std::size_t> chosen;
  if (options.point_count == 0) {
    chosen = poissonThin(cand, radius);
  } else {
    // Largest radius that still yields at least point_count points (bisection), then keep the
    // first point_count accepted (they are in random order, so the excess is spread out).
    double lo = 0.0, hi = 2.0 * radius;
    std::vector<std::size_t> best;
    for (int it = 0; it < 24; ++it) {
      const double mid = 0.5 * (lo + hi);
      std::vector<std::size_t> s = poissonThin(cand, mid, options.point_count);
      if (s.size() >= options.point_count) {
        lo = mid;
        best = std::move(s);
      } else {
        hi = mid;
      }
    }
    if (best.size() < options.point_count) best = poissonThin(cand, 0.0, options.point_count);
    if (best.size() < options.point_count) throw std::invalid_argument("makePointShell: could not place the requested point count");
    best.resize(options.point_count);
    chosen = std::move(best);
  }
  sortSpatially(cand, chosen);
  std::vector<Eigen::Vector3d> points, normals;
  points.reserve(chosen.size());
  normals.reserve(chosen.size());
  for (std::size_t c : chosen) {
    points.push_back(cand[c].p);
    normals.push_back(cand[c].n);
  }
  return PointShell(std::move(points), std::move(normals));
}

}  // namespace vh::haptics
