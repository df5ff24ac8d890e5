#pragma once
// Small tools and volumes shared by the core's tests.
#include <cstdint>
#include <memory>
#include <vector>

#include "vh/datasets/synthetic.h"
#include "vh/haptics/tool_model.h"

namespace vh::test {

/// A tool whose point shell is the single point p_T (its centre of mass at p_T too).
inline std::shared_ptr<haptics::ToolModel> pointTool(const Eigen::Vector3d& p_T = Eigen::Vector3d::Zero()) {
  auto tool = std::make_shared<haptics::ToolModel>();
  tool->mesh_T = datasets::translated(datasets::makeSphereMesh(0.001, 1), p_T);
  tool->mass = haptics::massPropertiesFromMesh(tool->mesh_T);
  tool->point_shell = haptics::PointShell({p_T});
  return tool;
}

/// A resampled tool from a mesh.
inline std::shared_ptr<haptics::ToolModel> meshTool(const haptics::TriangleMesh& mesh, double spacing_m) {
  haptics::PointShellOptions o;
  o.spacing_m = spacing_m;
  return std::make_shared<haptics::ToolModel>(haptics::makeToolModel(mesh, o));
}

/// 64^3 grid of 1 mm centred on the origin.
inline datasets::GridSpec grid1mm(int n = 64) {
  datasets::GridSpec g;
  g.dims = {n, n, n};
  g.spacing_m = Eigen::Vector3d::Constant(1e-3);
  return g;
}

/// A flat floor and a one-voxel wall standing on it: a 64 x 24 x 40 uint8 grid of 1 mm from
/// the origin, 255 up to k = 20 (the isosurface at 128 lies at k = 20.5) and on the column
/// i = 40 up to k = 30, 0 elsewhere. Along x at a height z in (20, 21) mm above the floor,
/// F = 255 (21 - z) up to i = 39, rising linearly to 255 at i = 40.
inline haptics::ScalarVolume floorAndWallVolume() {
  haptics::VolumeGeometry g;
  g.dims = {64, 24, 40};
  g.spacing_m = Eigen::Vector3d::Constant(1e-3);
  std::vector<std::uint8_t> voxels(g.voxelCount(), 0);
  for (int k = 0; k < g.dims[2]; ++k)
    for (int j = 0; j < g.dims[1]; ++j)
      for (int i = 0; i < g.dims[0]; ++i)
        if (k <= 20 || (i == 40 && k <= 30)) voxels[g.indexOf(i, j, k)] = 255;
  return haptics::ScalarVolume::FromVoxels(g, voxels);
}

}  // namespace vh::test
