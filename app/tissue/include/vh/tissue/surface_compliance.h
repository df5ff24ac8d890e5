#pragma once
/// @file
/// The condensed compliance of the nodes a tool can touch: for every pair (a, b) of those nodes
/// the 3 x 3 block C_ab [m/N] of K^-1 (node a's displacement under a unit force on node b), made
/// once from the static solver's factorisation (3 solves per node, on worker threads) and stored
/// densely in single precision. It is what lets contact with the tissue run at the servo rate:
/// a tick gathers the blocks of the few nodes under the tool and solves a small complementarity
/// problem, exact for the linear model (no modal truncation), with no sparse solve in the tick.
/// Cotin, Delingette and Ayache 1999 ("Real-time elastic deformations of soft tissues for surgery
/// simulation", IEEE TVCG 5(1)) precompute the same responses to unit surface forces.
#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "vh/tissue/static_solver.h"

namespace vh::tissue {

class SurfaceCompliance {
 public:
  /// @param nodes the touchable nodes (free ones; held nodes are skipped), any order.
  /// @param threads worker threads for the 3 n solves (>= 1).
  /// @throws std::invalid_argument on a node out of range or no free node.
  SurfaceCompliance(const StaticSolver& solver, const std::vector<int>& nodes, int threads = 1);

  /// Number of touchable nodes S.
  int nodeCount() const noexcept { return static_cast<int>(nodes_.size()); }
  /// Position of lattice node n among them, or -1 when it is held or not touchable.
  int indexOf(int node) const noexcept {
    return node >= 0 && node < static_cast<int>(index_.size()) ? index_[static_cast<std::size_t>(node)] : -1;
  }
  /// The lattice node of position s.
  int node(int s) const { return nodes_[static_cast<std::size_t>(s)]; }
  /// Column `col` of the table (3 S floats): the displacements of every position under a unit
  /// force along col % 3 on position col / 3.
  const float* column(int col) const noexcept { return table_.data() + static_cast<std::size_t>(col) * 3 * nodes_.size(); }
  /// Memory held by the table [bytes] (9 S^2 floats).
  std::size_t bytes() const noexcept { return table_.size() * sizeof(float); }

 private:
  std::vector<int> nodes_;
  std::vector<int> index_;
  std::vector<float> table_;  ///< (3 S) x (3 S), column-major: entry (3a + r, 3b + c).
};

}  // namespace vh::tissue
