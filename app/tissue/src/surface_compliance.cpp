#include "vh/tissue/surface_compliance.h"

#include <algorithm>
#include <atomic>
#include <stdexcept>
#include <string>
#include <thread>

namespace vh::tissue {

SurfaceCompliance::SurfaceCompliance(const StaticSolver& solver, const std::vector<int>& nodes, int threads) {
  const int lattice_nodes = solver.dofCount() / 3;
  index_.assign(static_cast<std::size_t>(lattice_nodes), -1);
  for (const int n : nodes) {
    if (n < 0 || n >= lattice_nodes) throw std::invalid_argument("surface compliance: node " + std::to_string(n) + " out of range");
    if (index_[static_cast<std::size_t>(n)] >= 0) continue;
    if (solver.isFixed(3 * n) || solver.isFixed(3 * n + 1) || solver.isFixed(3 * n + 2)) continue;
    index_[static_cast<std::size_t>(n)] = static_cast<int>(nodes_.size());
    nodes_.push_back(n);
  }
  if (nodes_.empty()) throw std::invalid_argument("surface compliance: no free node to touch");
  const std::size_t dim = 3 * nodes_.size();
  table_.assign(dim * dim, 0.0f);
  std::atomic<std::size_t> next{0};
  const auto work = [&] {
    Eigen::VectorXd f = Eigen::VectorXd::Zero(solver.dofCount());
    for (std::size_t col = next++; col < dim; col = next++) {
      const int dof = 3 * nodes_[col / 3] + static_cast<int>(col % 3);
      f(dof) = 1.0;
      const Eigen::VectorXd u = solver.solve(f);
      f(dof) = 0.0;
      float* out = table_.data() + col * dim;
      for (std::size_t s = 0; s < nodes_.size(); ++s)
        for (int r = 0; r < 3; ++r) out[3 * s + static_cast<std::size_t>(r)] = static_cast<float>(u(3 * nodes_[s] + r));
    }
  };
  std::vector<std::thread> pool;
  for (int t = 1; t < std::max(1, threads); ++t) pool.emplace_back(work);
  work();
  for (std::thread& t : pool) t.join();
}

}  // namespace vh::tissue
