#include "vh/haptics/shell_fidelity.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <stdexcept>
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

namespace vh::haptics {

namespace {

// One element of the felt net: a segment between two shell points, or a lone point (a == b).
struct NetElement {
  Eigen::Vector3d a;
  Eigen::Vector3d b;
};

double distanceToSegment(const Eigen::Vector3d& x, const NetElement& e) {
  const Eigen::Vector3d ab = e.b - e.a;
  const double len2 = ab.squaredNorm();
  const double t = len2 > 0.0 ? std::clamp((x - e.a).dot(ab) / len2, 0.0, 1.0) : 0.0;
  return (x - (e.a + t * ab)).norm();
}

std::vector<NetElement> netOf(const PointShell& shell, const ShellEdges& edges) {
  const auto& p = shell.points_T_m();
  std::vector<NetElement> net;
  net.reserve(p.size() + edges.targets.size());
  for (const auto& q : p) net.push_back({q, q});  // a point without edges is felt as a point
  if (edges.offsets.size() == p.size() + 1) {
    for (std::size_t j = 0; j < p.size(); ++j)
      for (int e = edges.offsets[j]; e < edges.offsets[j + 1]; ++e)
        net.push_back({p[j], p[static_cast<std::size_t>(edges.targets[static_cast<std::size_t>(e)])]});
  }
  return net;
}

struct Sample {
  Eigen::Vector3d p;
  double weight;  // the area it stands for [m^2]
};

// The sample grid of one triangle: from the corner `a` opposite its longest side, steps of at
// most step_m along its two shorter sides (so a sliver costs its area, not its length squared),
// plus the longest side itself at the same step.
struct TriangleGrid {
  Eigen::Vector3d a, ab, ac;
  int n1 = 1, n2 = 1, n3 = 1;  // steps along ab, ac and bc
  TriangleGrid(const TriangleMesh& mesh, const std::array<int, 3>& t, double step_m) {
    const Eigen::Vector3d v[3] = {mesh.vertices_T_m[static_cast<std::size_t>(t[0])],
                                  mesh.vertices_T_m[static_cast<std::size_t>(t[1])],
                                  mesh.vertices_T_m[static_cast<std::size_t>(t[2])]};
    int opposite = 0;  // the corner opposite the longest side
    double longest = -1.0;
    for (int i = 0; i < 3; ++i) {
      const double side = (v[(i + 2) % 3] - v[(i + 1) % 3]).norm();
      if (side > longest) {
        longest = side;
        opposite = i;
      }
    }
    a = v[opposite];
    ab = v[(opposite + 1) % 3] - a;
    ac = v[(opposite + 2) % 3] - a;
    n1 = std::max(1, static_cast<int>(std::ceil(ab.norm() / step_m)));
    n2 = std::max(1, static_cast<int>(std::ceil(ac.norm() / step_m)));
    n3 = std::max(1, static_cast<int>(std::ceil(longest / step_m)));
  }
  // Samples: (i, j) with i / n1 + j / n2 <= 1, then the longest side's inner points.
  double count() const {
    double c = 0.0;
    for (int i = 0; i <= n1; ++i) c += std::floor(static_cast<double>(n2) * (n1 - i) / n1) + 1.0;
    return c + (n3 - 1);
  }
  template <typename F>
  void forEach(F&& f) const {
    for (int i = 0; i <= n1; ++i) {
      const int j_max = static_cast<int>(std::floor(static_cast<double>(n2) * (n1 - i) / n1));
      for (int j = 0; j <= j_max; ++j)
        f(Eigen::Vector3d(a + (static_cast<double>(i) / n1) * ab + (static_cast<double>(j) / n2) * ac));
    }
    for (int k = 1; k < n3; ++k) {
      const double u = static_cast<double>(k) / n3;
      f(Eigen::Vector3d(a + (1.0 - u) * ab + u * ac));
    }
  }
};

std::vector<Sample> sampleMesh(const TriangleMesh& mesh, double step_m) {
  if (mesh.empty()) throw std::invalid_argument("measureShellFidelity: the mesh is empty");
  if (!(step_m > 0.0) || !std::isfinite(step_m))
    throw std::invalid_argument("measureShellFidelity: the sample step must be finite and > 0");
  constexpr double kMaxSamples = 20e6;
  double total = 0.0;
  for (const auto& t : mesh.triangles) total += TriangleGrid(mesh, t, step_m).count();
  if (total > kMaxSamples)
    throw std::invalid_argument("measureShellFidelity: a step of " + std::to_string(step_m) + " m needs " +
                                std::to_string(static_cast<long long>(total)) + " samples (at most 20 million)");
  std::vector<Sample> samples;
  samples.reserve(static_cast<std::size_t>(total));
  for (const auto& t : mesh.triangles) {
    const TriangleGrid grid(mesh, t, step_m);
    const double weight = 0.5 * grid.ab.cross(grid.ac).norm() / grid.count();
    grid.forEach([&](const Eigen::Vector3d& p) { samples.push_back({p, weight}); });
  }
  return samples;
}

ShellFidelity summarise(const std::vector<Sample>& samples, const std::vector<double>& gap, bool with_edges) {
  ShellFidelity f;
  f.samples = samples.size();
  f.edges = with_edges;
  double weight_sum = 0.0, weighted = 0.0;
  std::vector<std::pair<double, double>> by_gap;  // (gap, weight)
  by_gap.reserve(samples.size());
  for (std::size_t i = 0; i < samples.size(); ++i) {
    if (gap[i] > f.max_gap_m || i == 0) {
      f.max_gap_m = gap[i];
      f.worst_p_T_m = samples[i].p;
    }
    weight_sum += samples[i].weight;
    weighted += samples[i].weight * gap[i];
    by_gap.emplace_back(gap[i], samples[i].weight);
  }
  if (weight_sum > 0.0) {
    f.mean_gap_m = weighted / weight_sum;
    std::sort(by_gap.begin(), by_gap.end());
    double acc = 0.0;
    f.p99_gap_m = by_gap.back().first;
    for (const auto& [g, w] : by_gap) {
      acc += w;
      if (acc >= 0.99 * weight_sum) {
        f.p99_gap_m = g;
        break;
      }
    }
  }
  return f;
}

void requireShell(const PointShell& shell) {
  if (shell.size() == 0) throw std::invalid_argument("measureShellFidelity: the point shell is empty");
}

// A uniform hash grid of the net's elements, each listed in every cell its bounding box meets.
class NetGrid {
 public:
  NetGrid(const std::vector<NetElement>& net, double cell_m) : net_(net), cell_(cell_m) {
    for (std::size_t e = 0; e < net.size(); ++e) {
      const Eigen::Vector3d lo = net[e].a.cwiseMin(net[e].b), hi = net[e].a.cwiseMax(net[e].b);
      const Eigen::Array3i c0 = cellOf(lo), c1 = cellOf(hi);
      lo_ = e == 0 ? c0 : lo_.min(c0);
      hi_ = e == 0 ? c1 : hi_.max(c1);
      for (int z = c0.z(); z <= c1.z(); ++z)
        for (int y = c0.y(); y <= c1.y(); ++y)
          for (int x = c0.x(); x <= c1.x(); ++x) cells_[key(x, y, z)].push_back(static_cast<int>(e));
    }
  }

  // The distance from x to the nearest element: rings of cells about x's cell, until the next
  // ring cannot hold anything nearer than the best so far.
  double nearest(const Eigen::Vector3d& x) const {
    const Eigen::Array3i c = cellOf(x);
    double best = std::numeric_limits<double>::infinity();
    const int max_ring = ((hi_ - c).abs().max((lo_ - c).abs())).maxCoeff() + 1;
    for (int r = 0; r <= max_ring; ++r) {
      for (int z = c.z() - r; z <= c.z() + r; ++z)
        for (int y = c.y() - r; y <= c.y() + r; ++y)
          for (int x_ = c.x() - r; x_ <= c.x() + r; ++x_) {
            if (std::max({std::abs(z - c.z()), std::abs(y - c.y()), std::abs(x_ - c.x())}) != r) continue;
            const auto it = cells_.find(key(x_, y, z));
            if (it == cells_.end()) continue;
            for (int e : it->second) best = std::min(best, distanceToSegment(x, net_[static_cast<std::size_t>(e)]));
          }
      if (best <= static_cast<double>(r) * cell_) break;  // ring r + 1 is at least r cells away
    }
    return best;
  }

 private:
  Eigen::Array3i cellOf(const Eigen::Vector3d& p) const { return (p.array() / cell_).floor().cast<int>(); }
  static std::int64_t key(int x, int y, int z) {
    return (static_cast<std::int64_t>(x) & 0x1FFFFF) | ((static_cast<std::int64_t>(y) & 0x1FFFFF) << 21) |
           ((static_cast<std::int64_t>(z) & 0x1FFFFF) << 42);
  }
  const std::vector<NetElement>& net_;
  double cell_;
  Eigen::Array3i lo_ = Eigen::Array3i::Zero(), hi_ = Eigen::Array3i::Zero();
  std::unordered_map<std::int64_t, std::vector<int>> cells_;
};

}  // namespace

ShellFidelity measureShellFidelity(const TriangleMesh& mesh_T, const PointShell& shell, const ShellEdges& edges,
                                   double sample_step_m) {
  requireShell(shell);
  const std::vector<Sample> samples = sampleMesh(mesh_T, sample_step_m);
  const std::vector<NetElement> net = netOf(shell, edges);
  // Cells of about the spacing: an edge spans a few, a query reads a few rings.
  double cell = edges.spacing_m > 0.0 ? edges.spacing_m : shell.meanNearestNeighbourSpacing_m();
  if (!(cell > 0.0)) cell = std::max((mesh_T.boundsMax_T_m() - mesh_T.boundsMin_T_m()).norm(), 1e-6);
  const NetGrid grid(net, cell);
  std::vector<double> gap(samples.size());
  for (std::size_t i = 0; i < samples.size(); ++i) gap[i] = grid.nearest(samples[i].p);
  return summarise(samples, gap, !edges.targets.empty());
}

ShellFidelity measureShellFidelityBruteForce(const TriangleMesh& mesh_T, const PointShell& shell,
                                             const ShellEdges& edges, double sample_step_m) {
  requireShell(shell);
  const std::vector<Sample> samples = sampleMesh(mesh_T, sample_step_m);
  const std::vector<NetElement> net = netOf(shell, edges);
  std::vector<double> gap(samples.size(), std::numeric_limits<double>::infinity());
  for (std::size_t i = 0; i < samples.size(); ++i)
    for (const NetElement& e : net) gap[i] = std::min(gap[i], distanceToSegment(samples[i].p, e));
  return summarise(samples, gap, !edges.targets.empty());
}

}  // namespace vh::haptics
