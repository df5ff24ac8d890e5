#include "vh/haptics/tool_model.h"

namespace vh::haptics {

ToolModel makeToolModel(TriangleMesh mesh_T, const PointShellOptions& options, double density_kg_per_m3) {
  ToolModel tool;
  tool.point_shell = makePointShell(mesh_T, options);
  tool.mass = massPropertiesFromMesh(mesh_T, density_kg_per_m3);
  tool.mesh_T = std::move(mesh_T);
  return tool;
}

}  // namespace vh::haptics
