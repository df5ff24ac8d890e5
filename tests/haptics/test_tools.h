#pragma once
// Small tools and volumes shared by the core's tests.
#include <memory>

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

}  // namespace vh::test
