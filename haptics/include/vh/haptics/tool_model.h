#pragma once
/// @file
/// The constant model of a virtual tool: point shell, mass properties and display mesh.

#include "vh/haptics/point_shell.h"
#include "vh/haptics/triangle_mesh.h"

namespace vh::haptics {

/// Everything the renderer needs to know about a tool; constant while a scene runs.
/// The tool frame T is the mesh's own frame (after scaling to metres). The configuration
/// solver rotates the proxy about the centre of mass `mass.p_TCm_m` (section 2.3).
struct ToolModel {
  TriangleMesh mesh_T;     ///< Display mesh in T [m] (may be empty for a bare point shell).
  PointShell point_shell;  ///< Contact points in T [m].
  MassProperties mass;     ///< From the tool's geometry (section 2.4).
};

/// Builds a tool from a mesh in metres: resampled point shell plus solid/shell mass properties.
/// @throws std::invalid_argument as makePointShell() and massPropertiesFromMesh().
ToolModel makeToolModel(TriangleMesh mesh_T, const PointShellOptions& options,
                        double density_kg_per_m3 = 7800.0);

}  // namespace vh::haptics
