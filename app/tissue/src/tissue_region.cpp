#include "vh/tissue/tissue_region.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <stdexcept>
#include <string>

namespace vh::tissue {

TissueRegion buildTissueRegion(const VoxelGrid& grid, const RegionSpec& spec, std::vector<Material> materials) {
  if ((grid.dims.array() < 1).any() || !grid.spacing_m.allFinite() || (grid.spacing_m.array() <= 0.0).any())
    throw std::invalid_argument("tissue region: the scan's grid needs >= 1 voxel and a spacing > 0 on every axis");
  if (!std::isfinite(spec.cell_size_m) || spec.cell_size_m < grid.spacing_m.maxCoeff())
    throw std::invalid_argument("tissue region: the cell size must be at least the largest voxel spacing (" +
                                std::to_string(grid.spacing_m.maxCoeff() * 1e3) + " mm)");
  if (!spec.material_of_voxel) throw std::invalid_argument("tissue region: no material function");
  const double h = spec.cell_size_m;
  LatticeGeometry geometry;
  geometry.spacing_m = h;
  geometry.origin_W_m = -0.5 * grid.spacing_m;  // the corner of voxel (0, 0, 0)'s box
  const Eigen::Vector3d extent = grid.dims.cast<double>().cwiseProduct(grid.spacing_m);
  for (int a = 0; a < 3; ++a) geometry.cells(a) = std::max(1, static_cast<int>(std::ceil(extent(a) / h - 1e-9)));
  const std::int64_t cells = geometry.cellCount();
  const auto cellIndex = [&](const Eigen::Vector3i& c) {
    return static_cast<std::size_t>((static_cast<std::int64_t>(c.z()) * geometry.cells.y() + c.y()) * geometry.cells.x() + c.x());
  };
  std::vector<std::map<int, int>> counts(static_cast<std::size_t>(cells));
  std::vector<char> rigid(static_cast<std::size_t>(cells), 0), border(static_cast<std::size_t>(cells), 0);
  const int material_count = static_cast<int>(materials.size());
  int tissue_voxels = 0;
  for (int k = 0; k < grid.dims.z(); ++k)
    for (int j = 0; j < grid.dims.y(); ++j)
      for (int i = 0; i < grid.dims.x(); ++i) {
        const Eigen::Vector3d corner_offset = Eigen::Vector3d(i, j, k).cwiseProduct(grid.spacing_m) + 0.5 * grid.spacing_m;
        Eigen::Vector3i c;
        for (int a = 0; a < 3; ++a) c(a) = std::min(static_cast<int>(std::floor(corner_offset(a) / h)), geometry.cells(a) - 1);
        const std::size_t cell = cellIndex(c);
        if (spec.is_rigid_voxel && spec.is_rigid_voxel(i, j, k)) rigid[cell] = 1;
        const int m = spec.material_of_voxel(i, j, k);
        if (m < 0) continue;
        if (m >= material_count)
          throw std::invalid_argument("tissue region: voxel material " + std::to_string(m) + " but " +
                                      std::to_string(material_count) + " materials");
        ++counts[cell][m];
        ++tissue_voxels;
        if (i == 0 || j == 0 || k == 0 || i == grid.dims.x() - 1 || j == grid.dims.y() - 1 || k == grid.dims.z() - 1)
          border[cell] = 1;
      }
  if (tissue_voxels == 0) throw std::invalid_argument("tissue region: no voxel is tissue of the region");
  std::vector<int> cell_material(static_cast<std::size_t>(cells), -1);
  for (std::size_t cell = 0; cell < counts.size(); ++cell) {
    int best = -1, best_count = 0;
    for (const auto& [m, n] : counts[cell]) {
      const bool stiffer = best >= 0 && materials[static_cast<std::size_t>(m)].youngs_modulus_Pa >
                                            materials[static_cast<std::size_t>(best)].youngs_modulus_Pa;
      if (n > best_count || (n == best_count && stiffer)) {
        best = m;
        best_count = n;
      }
    }
    cell_material[cell] = best;
  }
  HexLattice lattice(geometry, cell_material);
  std::vector<char> held(static_cast<std::size_t>(lattice.nodeCount()), 0);
  for (int e = 0; e < lattice.elementCount(); ++e) {
    const std::size_t cell = cellIndex(lattice.elementCell(e));
    if (rigid[cell] || (spec.hold_at_scan_border && border[cell]))
      for (const int n : lattice.elementNodes(e)) held[static_cast<std::size_t>(n)] = 1;
  }
  std::vector<int> fixed;
  for (int n = 0; n < lattice.nodeCount(); ++n)
    if (held[static_cast<std::size_t>(n)]) fixed.insert(fixed.end(), {3 * n, 3 * n + 1, 3 * n + 2});
  if (fixed.empty())
    throw std::invalid_argument("tissue region: nothing holds the region (it touches no rigid voxel and not the scan's "
                                "border); it would float away");
  return TissueRegion{FemModel(std::move(lattice), std::move(materials)), std::move(fixed), tissue_voxels};
}

std::vector<int> outerLayerNodes(const HexLattice& lattice, int layers) {
  if (layers < 1) throw std::invalid_argument("outer layer nodes: at least one layer of cells");
  std::vector<char> in_layer(static_cast<std::size_t>(lattice.elementCount()), 0);
  static constexpr int kFaces[6][3] = {{-1, 0, 0}, {1, 0, 0}, {0, -1, 0}, {0, 1, 0}, {0, 0, -1}, {0, 0, 1}};
  for (int e = 0; e < lattice.elementCount(); ++e) {
    const Eigen::Vector3i c = lattice.elementCell(e);
    bool on_outside = false;
    for (const auto& d : kFaces) on_outside = on_outside || lattice.elementAt(c.x() + d[0], c.y() + d[1], c.z() + d[2]) < 0;
    in_layer[static_cast<std::size_t>(e)] = on_outside ? 1 : 0;
  }
  // Each further layer: the cells next to (sharing a corner with) a cell of the layers so far.
  for (int layer = 2; layer <= layers; ++layer) {
    std::vector<char> next = in_layer;
    for (int e = 0; e < lattice.elementCount(); ++e) {
      if (in_layer[static_cast<std::size_t>(e)] == 0) continue;
      const Eigen::Vector3i c = lattice.elementCell(e);
      for (int dz = -1; dz <= 1; ++dz)
        for (int dy = -1; dy <= 1; ++dy)
          for (int dx = -1; dx <= 1; ++dx) {
            const int other = lattice.elementAt(c.x() + dx, c.y() + dy, c.z() + dz);
            if (other >= 0) next[static_cast<std::size_t>(other)] = 1;
          }
    }
    in_layer.swap(next);
  }
  std::vector<char> outer(static_cast<std::size_t>(lattice.nodeCount()), 0);
  for (int e = 0; e < lattice.elementCount(); ++e)
    if (in_layer[static_cast<std::size_t>(e)])
      for (const int n : lattice.elementNodes(e)) outer[static_cast<std::size_t>(n)] = 1;
  std::vector<int> nodes;
  for (int n = 0; n < lattice.nodeCount(); ++n)
    if (outer[static_cast<std::size_t>(n)]) nodes.push_back(n);
  return nodes;
}

}  // namespace vh::tissue
