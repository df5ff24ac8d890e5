#pragma once
/// @file
/// The tools a user can pick in the haptics panel: the project's built-in parametric tools and
/// the shared tool meshes (../shared/datasets/meshes) when present, each with a real-world size
/// and a placement orientation; and building one into a ToolModel for a volume (off the GUI
/// thread: resampling the point shell takes up to seconds for fine spacings). No Qt.

#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "vh/haptics/pose.h"
#include "vh/haptics/scalar_volume.h"
#include "vh/haptics/tool_model.h"

namespace vh::runtime {
struct ToolSpec;
}

namespace vh::ui {

/// One entry of the tool list.
struct ToolChoice {
  std::string id;            ///< Stable key for settings: "builtin:probe", "mesh:drill", "scene".
  std::string label;         ///< What the GUI shows, e.g. "Drill (CHAI3D mesh)".
  std::string mesh;          ///< "builtin:NAME" or an absolute mesh path (STL/OBJ/PLY).
  double scale_to_m = 1.0;   ///< Mesh coordinates -> metres.
  /// Orientation R_WT the tool is placed with (its working end towards -z of W, the volume).
  Eigen::Quaterniond R_WT = Eigen::Quaterniond::Identity();
  std::string credit;        ///< Source and licence of a shared mesh; empty for built-ins.
};

/// The built-in tools (probe, drill, peg, sphere), then the shared meshes found under
/// `shared_datasets_dir` (drill, dental probe, round peg, wrench), each scaled to its real size.
std::vector<ToolChoice> toolCatalog(const std::filesystem::path& shared_datasets_dir);

/// The entry for a scene's tool: the catalog entry with the same mesh (and scale) when there is
/// one, else a new "scene" entry labelled with the mesh's file name.
/// @return index into `catalog` (the new entry is appended when needed).
int findOrAddSceneTool(std::vector<ToolChoice>& catalog, const runtime::ToolSpec& spec);

/// A tool built for a volume.
struct BuiltTool {
  std::shared_ptr<const haptics::ToolModel> tool;  ///< Mesh, point shell, mass in T [m].
  double point_spacing_m = 0.0;                    ///< Spacing used [m].
  haptics::Pose X_WT_initial;                      ///< A free pose above the surface in W [m].
};

/// Loads / generates the mesh of `choice`, resamples it at `point_spacing_m` (0: automatic,
/// runtime::automaticPointSpacing_m())
/// and places it (runtime::defaultInitialPose: over the volume's centre, just clear of F = s).
/// @throws std::runtime_error (or io::LoadError) naming the tool and the problem.
BuiltTool buildTool(const ToolChoice& choice, double point_spacing_m, const haptics::ScalarVolume& volume,
                    double isovalue);

}  // namespace vh::ui
