#include "vh/tissue/hex_lattice.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace vh::tissue {

HexLattice::HexLattice(const LatticeGeometry& geometry, std::vector<int> cell_material) : geometry_(geometry) {
  if (!std::isfinite(geometry.spacing_m) || geometry.spacing_m <= 0.0)
    throw std::invalid_argument("tissue lattice: the cell spacing must be finite and > 0 m");
  if (!geometry.origin_W_m.allFinite()) throw std::invalid_argument("tissue lattice: the origin must be finite");
  if ((geometry.cells.array() < 1).any())
    throw std::invalid_argument("tissue lattice: every axis needs at least one cell");
  const std::int64_t cells = geometry.cellCount();
  if (cells > (std::int64_t{1} << 28)) throw std::invalid_argument("tissue lattice: more than 2^28 cells");
  if (static_cast<std::int64_t>(cell_material.size()) != cells)
    throw std::invalid_argument("tissue lattice: " + std::to_string(cell_material.size()) + " cell materials for " +
                                std::to_string(cells) + " cells");
  const Eigen::Vector3i nodes_per_axis = geometry.cells + Eigen::Vector3i::Ones();
  const std::int64_t grid_nodes = static_cast<std::int64_t>(nodes_per_axis.x()) * nodes_per_axis.y() * nodes_per_axis.z();
  cell_element_.assign(static_cast<std::size_t>(cells), -1);
  grid_node_.assign(static_cast<std::size_t>(grid_nodes), -1);
  const auto gridIndex = [&](int i, int j, int k) {
    return (static_cast<std::int64_t>(k) * nodes_per_axis.y() + j) * nodes_per_axis.x() + i;
  };
  // First pass: which grid points are nodes.
  for (int k = 0; k < geometry.cells.z(); ++k)
    for (int j = 0; j < geometry.cells.y(); ++j)
      for (int i = 0; i < geometry.cells.x(); ++i) {
        const int material = cell_material[static_cast<std::size_t>((static_cast<std::int64_t>(k) * geometry.cells.y() + j) *
                                                                        geometry.cells.x() + i)];
        if (material < -1) throw std::invalid_argument("tissue lattice: a material index below -1");
        if (material < 0) continue;
        for (int a = 0; a < 8; ++a) grid_node_[static_cast<std::size_t>(gridIndex(i + (a & 1), j + ((a >> 1) & 1), k + ((a >> 2) & 1)))] = 0;
      }
  // Number the nodes x fastest.
  for (int k = 0; k < nodes_per_axis.z(); ++k)
    for (int j = 0; j < nodes_per_axis.y(); ++j)
      for (int i = 0; i < nodes_per_axis.x(); ++i) {
        int& n = grid_node_[static_cast<std::size_t>(gridIndex(i, j, k))];
        if (n < 0) continue;
        n = static_cast<int>(node_grid_.size());
        node_grid_.emplace_back(i, j, k);
      }
  if (node_grid_.empty()) throw std::invalid_argument("tissue lattice: no cell holds tissue");
  for (int k = 0; k < geometry.cells.z(); ++k)
    for (int j = 0; j < geometry.cells.y(); ++j)
      for (int i = 0; i < geometry.cells.x(); ++i) {
        const std::size_t cell = static_cast<std::size_t>((static_cast<std::int64_t>(k) * geometry.cells.y() + j) * geometry.cells.x() + i);
        const int material = cell_material[cell];
        if (material < 0) continue;
        std::array<int, 8> nodes{};
        for (int a = 0; a < 8; ++a)
          nodes[static_cast<std::size_t>(a)] =
              grid_node_[static_cast<std::size_t>(gridIndex(i + (a & 1), j + ((a >> 1) & 1), k + ((a >> 2) & 1)))];
        cell_element_[cell] = static_cast<int>(elements_.size());
        elements_.push_back(nodes);
        element_material_.push_back(material);
        element_cell_.emplace_back(i, j, k);
        if (material > max_material_) max_material_ = material;
      }
}

HexLattice HexLattice::Box(const Eigen::Vector3d& origin_W_m, double spacing_m, const Eigen::Vector3i& cells) {
  LatticeGeometry g;
  g.origin_W_m = origin_W_m;
  g.spacing_m = spacing_m;
  g.cells = cells;
  if ((cells.array() < 1).any()) throw std::invalid_argument("tissue lattice: every axis needs at least one cell");
  return HexLattice(g, std::vector<int>(static_cast<std::size_t>(g.cellCount()), 0));
}

Eigen::Vector3d HexLattice::nodePosition_W(int node) const {
  return geometry_.origin_W_m + geometry_.spacing_m * nodeGrid(node).cast<double>();
}

int HexLattice::nodeAt(int i, int j, int k) const noexcept {
  const Eigen::Vector3i n = geometry_.cells + Eigen::Vector3i::Ones();
  if (i < 0 || j < 0 || k < 0 || i >= n.x() || j >= n.y() || k >= n.z()) return -1;
  return grid_node_[static_cast<std::size_t>((static_cast<std::int64_t>(k) * n.y() + j) * n.x() + i)];
}

int HexLattice::elementAt(int i, int j, int k) const noexcept {
  const Eigen::Vector3i& c = geometry_.cells;
  if (i < 0 || j < 0 || k < 0 || i >= c.x() || j >= c.y() || k >= c.z()) return -1;
  return cell_element_[static_cast<std::size_t>((static_cast<std::int64_t>(k) * c.y() + j) * c.x() + i)];
}

HexLattice::Location HexLattice::locate(const Eigen::Vector3d& p_W_m) const noexcept {
  Location out;
  if (!p_W_m.allFinite()) return out;
  const Eigen::Vector3d g = (p_W_m - geometry_.origin_W_m) / geometry_.spacing_m;
  Eigen::Vector3i cell;
  for (int a = 0; a < 3; ++a) {
    if (g(a) < 0.0 || g(a) > geometry_.cells(a)) return out;
    cell(a) = std::min(static_cast<int>(std::floor(g(a))), geometry_.cells(a) - 1);
  }
  int e = elementAt(cell.x(), cell.y(), cell.z());
  if (e < 0) {  // on (or within rounding of) a face of a non-empty neighbour: that one holds it
    constexpr double kOnFace = 1e-9;
    for (int a = 0; a < 3 && e < 0; ++a) {
      const double frac = g(a) - cell(a);
      const int step = frac < kOnFace ? -1 : (frac > 1.0 - kOnFace ? 1 : 0);
      if (step == 0) continue;
      Eigen::Vector3i other = cell;
      other(a) += step;
      e = elementAt(other.x(), other.y(), other.z());
      if (e >= 0) cell = other;
    }
    if (e < 0) return out;
  }
  out.element = e;
  out.xi = (2.0 * (g - cell.cast<double>()) - Eigen::Vector3d::Ones()).cwiseMax(-1.0).cwiseMin(1.0);
  return out;
}

}  // namespace vh::tissue
