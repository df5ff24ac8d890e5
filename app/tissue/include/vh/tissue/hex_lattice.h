#pragma once
/// @file
/// The finite-element lattice of a tissue region: cubic cells of side h on a regular grid in the
/// volume frame W (axis-aligned with W), each cell either empty or one 8-node hexahedron of one
/// material. Only the nodes of non-empty cells exist; they are numbered compactly, x fastest.
#include <array>
#include <cstdint>
#include <vector>

#include <Eigen/Core>

namespace vh::tissue {

/// Where the lattice lies: node (i, j, k) is at origin_W_m + spacing_m * (i, j, k); cell
/// (i, j, k) spans nodes (i..i+1, j..j+1, k..k+1).
struct LatticeGeometry {
  Eigen::Vector3d origin_W_m = Eigen::Vector3d::Zero();  ///< Node (0, 0, 0) in W [m].
  double spacing_m = 1e-3;                               ///< Cell side h [m] (> 0).
  Eigen::Vector3i cells = Eigen::Vector3i::Ones();       ///< Cells per axis (each >= 1).

  /// Number of grid cells, empty ones included.
  std::int64_t cellCount() const noexcept {
    return static_cast<std::int64_t>(cells.x()) * cells.y() * cells.z();
  }
};

/// A hexahedral lattice. Corner a of a cell (0..7) is at offset (a & 1, (a >> 1) & 1, (a >> 2) & 1)
/// from the cell's lowest node; elementNodes() lists the nodes in that order.
class HexLattice {
 public:
  HexLattice() = default;

  /// @param cell_material geometry.cellCount() entries, x fastest: -1 for an empty cell, else the
  ///        index of the cell's material (>= 0).
  /// @throws std::invalid_argument on a non-positive or non-finite spacing, a cell count < 1 on an
  ///         axis, a size mismatch, a material index < -1, or no cell at all.
  HexLattice(const LatticeGeometry& geometry, std::vector<int> cell_material);

  /// A full box of cells, all of material 0.
  /// @throws std::invalid_argument as the constructor.
  static HexLattice Box(const Eigen::Vector3d& origin_W_m, double spacing_m, const Eigen::Vector3i& cells);

  const LatticeGeometry& geometry() const noexcept { return geometry_; }
  int nodeCount() const noexcept { return static_cast<int>(node_grid_.size()); }
  int elementCount() const noexcept { return static_cast<int>(elements_.size()); }
  /// Degrees of freedom: 3 per node (x, y, z displacement of node n are 3n, 3n + 1, 3n + 2).
  int dofCount() const noexcept { return 3 * nodeCount(); }

  /// Grid index (i, j, k) of node n.
  const Eigen::Vector3i& nodeGrid(int node) const { return node_grid_[static_cast<std::size_t>(node)]; }
  /// Rest position of node n in W [m].
  Eigen::Vector3d nodePosition_W(int node) const;
  /// The node at grid index (i, j, k), or -1 when no non-empty cell has it (or it is off the grid).
  int nodeAt(int i, int j, int k) const noexcept;

  /// The 8 nodes of element e, corner order as above.
  const std::array<int, 8>& elementNodes(int element) const { return elements_[static_cast<std::size_t>(element)]; }
  /// Material index of element e.
  int elementMaterial(int element) const { return element_material_[static_cast<std::size_t>(element)]; }
  /// Grid index of element e's cell.
  const Eigen::Vector3i& elementCell(int element) const { return element_cell_[static_cast<std::size_t>(element)]; }
  /// The element of cell (i, j, k), or -1 when the cell is empty or off the grid.
  int elementAt(int i, int j, int k) const noexcept;
  /// The element holding point p_W and the point's local coordinates xi in [-1, 1]^3 there, or
  /// element -1 when p_W lies in no non-empty cell. A point on a face (within 1e-9 of a cell's
  /// side, rounding) goes to the non-empty cell beside it when its own is empty.
  struct Location {
    int element = -1;
    Eigen::Vector3d xi = Eigen::Vector3d::Zero();
  };
  Location locate(const Eigen::Vector3d& p_W_m) const noexcept;
  /// The largest material index used (-1 for none).
  int maxMaterial() const noexcept { return max_material_; }

 private:
  LatticeGeometry geometry_;
  std::vector<int> cell_element_;  ///< geometry.cellCount() entries: element of each cell or -1.
  std::vector<int> grid_node_;     ///< (cells + 1) per axis entries: node at each grid point or -1.
  std::vector<Eigen::Vector3i> node_grid_;
  std::vector<std::array<int, 8>> elements_;
  std::vector<int> element_material_;
  std::vector<Eigen::Vector3i> element_cell_;
  int max_material_ = -1;
};

}  // namespace vh::tissue
