#pragma once
/// @file
/// A deformable region cut from a scan: the voxels that are tissue (a segment of a segmentation,
/// or a value band of the scan such as CT soft tissue between two HU values) are covered by a
/// coarse hexahedral lattice whose cells are several voxels wide; the scan's own voxels keep
/// carrying the surface (the lattice only carries the displacement). Nodes where the tissue meets
/// rigid voxels (bone) or is cut by the scan's border are held: bone stays rigid and the tissue
/// cannot be pushed through it.
///
/// Frame G: the scan's grid frame, axes along the voxel axes, metres, origin at voxel (0, 0, 0)'s
/// centre (voxel (i, j, k) is at (i s_x, j s_y, k s_z)). The caller maps G to the world frame W
/// with the scan's direction and origin.
#include <functional>
#include <vector>

#include <Eigen/Core>

#include "vh/tissue/fem_model.h"
#include "vh/tissue/hex_lattice.h"
#include "vh/tissue/material.h"

namespace vh::tissue {

struct VoxelGrid {
  Eigen::Vector3i dims = Eigen::Vector3i::Ones();              ///< Voxels per axis (each >= 1).
  Eigen::Vector3d spacing_m = Eigen::Vector3d::Constant(1e-3);  ///< Voxel size per axis [m] (> 0).
};

struct RegionSpec {
  /// The lattice's cell side h [m]: at least the largest voxel spacing; each cell covers about
  /// (h / s)^3 voxels.
  double cell_size_m = 4e-3;
  /// The material index of voxel (i, j, k) (an index into the region's materials), or -1 when the
  /// voxel is not tissue of the region.
  std::function<int(int i, int j, int k)> material_of_voxel;
  /// True for a rigid voxel (bone): the nodes of a tissue cell holding one are held fixed.
  /// May be empty (no bone).
  std::function<bool(int i, int j, int k)> is_rigid_voxel;
  /// Also hold the nodes of tissue cells that reach the scan's border (the region is cut there).
  bool hold_at_scan_border = true;
};

/// A region ready for the solvers: the model (lattice in G, materials) and the held dofs.
struct TissueRegion {
  FemModel model;
  std::vector<int> fixed_dofs;
  int tissue_voxels = 0;  ///< Voxels of the region (material >= 0).
};

/// Builds the region. A cell takes the material most of its tissue voxels have (the stiffer on a
/// tie, so an inclusion is never lost), and is empty when it holds no tissue voxel.
/// @throws std::invalid_argument on a bad grid, a cell size below the largest voxel spacing, no
///         material function, a material index out of range, no tissue voxel, or a region that
///         nothing holds (no rigid voxel and no border reached: it would float away).
TissueRegion buildTissueRegion(const VoxelGrid& grid, const RegionSpec& spec, std::vector<Material> materials);

/// The nodes a tool can touch: every node of a cell with a face on the region's outside (an
/// empty cell or the lattice's edge), ascending. The surface the tool touches lies in those cells.
/// With layers > 1, also the nodes of the cells up to layers - 1 cells further in (sharing a
/// corner, step by step): where a surface blurred over several voxels, or pushed deep, lies.
/// @throws std::invalid_argument on layers < 1.
std::vector<int> outerLayerNodes(const HexLattice& lattice, int layers = 1);

}  // namespace vh::tissue
