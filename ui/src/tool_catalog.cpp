#include "vh/ui/tool_catalog.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>
#include <system_error>

#include "vh/datasets/synthetic.h"
#include "vh/io/volume_loader.h"
#include "vh/runtime/placement.h"
#include "vh/runtime/scene.h"

namespace vh::ui {
namespace {

namespace fs = std::filesystem;

constexpr std::string_view kBuiltin = "builtin:";

bool sameFile(const std::string& a, const std::string& b) {
  if (a == b) return true;
  std::error_code ec;
  const bool eq = fs::equivalent(a, b, ec);
  return !ec && eq;
}

/// Rotation taking T's +x onto W's +z (a tool modelled lying along +x with its tip at the origin
/// then points down, at the volume).
Eigen::Quaterniond xUp() {
  return Eigen::Quaterniond(Eigen::AngleAxisd(-0.5 * std::numbers::pi, Eigen::Vector3d::UnitY()));
}

}  // namespace

std::vector<ToolChoice> toolCatalog(const fs::path& shared) {
  std::vector<ToolChoice> tools = {
      {"builtin:probe", "Probe (built-in: 2 mm ball tip, 60 mm)", "builtin:probe", 1.0, Eigen::Quaterniond::Identity(), {}},
      {"builtin:drill", "Drill (built-in: 2.5 mm burr)", "builtin:drill", 1.0, Eigen::Quaterniond::Identity(), {}},
      {"builtin:peg", "Peg (built-in: 7.5 mm radius, 40 mm)", "builtin:peg", 1.0, Eigen::Quaterniond::Identity(), {}},
      {"builtin:sphere", "Sphere (built-in: 5 mm radius)", "builtin:sphere", 1.0, Eigen::Quaterniond::Identity(), {}},
  };
  struct Shared {
    const char* id;
    const char* label;
    const char* path;
    double scale;
    Eigen::Quaterniond R_WT;
    const char* credit;
  };
  const Shared shared_meshes[] = {
      // 227 units long -> 10 cm; burr at the origin, shaft along +x.
      {"mesh:drill", "Drill (CHAI3D mesh, 10 cm)", "meshes/drill/drill.stl", 0.00044, xUp(), "CHAI3D, BSD-3-Clause"},
      // 7.13 units long along z -> 12 cm.
      {"mesh:dental-probe", "Dental probe (SOFA mesh, 12 cm)", "meshes/dental-probe/dental_instrument.obj", 0.0168,
       Eigen::Quaterniond::Identity(), "SOFA, LGPL-2.1"},
      // Metres; 16 mm diameter, 50 mm along +z from the origin.
      {"mesh:peg-round", "Round peg (IsaacGymEnvs mesh, 16 mm)", "meshes/peg-in-hole/factory_round_peg_16mm_tight.obj",
       1.0, Eigen::Quaterniond::Identity(), "NVIDIA IsaacGymEnvs, BSD-3-Clause"},
      // Millimetres: 150 x 65 x 11 mm.
      {"mesh:wrench", "Wrench (DrLex0 mesh, 15 cm)", "meshes/wrench/adjustable-wrench-body.stl", 0.001,
       Eigen::Quaterniond::Identity(), "DrLex0, CC BY 4.0"},
  };
  for (const Shared& s : shared_meshes) {
    const fs::path path = shared / s.path;
    std::error_code ec;
    if (!shared.empty() && fs::is_regular_file(path, ec)) {
      tools.push_back({s.id, s.label, path.lexically_normal().string(), s.scale, s.R_WT, s.credit});
    }
  }
  return tools;
}

int findOrAddSceneTool(std::vector<ToolChoice>& catalog, const runtime::ToolSpec& spec) {
  for (std::size_t i = 0; i < catalog.size(); ++i) {
    const ToolChoice& c = catalog[i];
    if (sameFile(c.mesh, spec.mesh) && std::abs(c.scale_to_m - spec.scale_to_m) <= 1e-9 * std::abs(c.scale_to_m)) {
      if (spec.initial_pose_set || spec.initial_orientation_set) {
        // Same mesh, the scene's own orientation: keep the entry, adopt the orientation.
        catalog[i].R_WT = spec.X_WT_initial.R_AB;
      }
      return static_cast<int>(i);
    }
  }
  ToolChoice scene;
  scene.id = "scene";
  const std::string name = spec.mesh.rfind(kBuiltin, 0) == 0 ? spec.mesh : fs::path(spec.mesh).filename().string();
  scene.label = "Scene tool (" + name + ")";
  scene.mesh = spec.mesh;
  scene.scale_to_m = spec.scale_to_m;
  scene.R_WT = spec.X_WT_initial.R_AB;
  catalog.insert(catalog.begin(), scene);
  return 0;
}


BuiltTool buildTool(const ToolChoice& choice, double point_spacing_m, const haptics::ScalarVolume& volume,
                    double isovalue) {
  haptics::TriangleMesh mesh;
  try {
    if (choice.mesh.rfind(kBuiltin, 0) == 0) {
      mesh = datasets::makeBuiltinTool(choice.mesh.substr(kBuiltin.size()));
      if (choice.scale_to_m != 1.0) mesh.scale(choice.scale_to_m);
    } else {
      mesh = io::loadMesh(choice.mesh, choice.scale_to_m);
    }
  } catch (const io::LoadError&) {
    throw;
  } catch (const std::exception& e) {
    throw std::runtime_error("tool '" + choice.label + "': " + e.what());
  }
  BuiltTool out;
  out.point_spacing_m = point_spacing_m > 0.0 ? point_spacing_m : runtime::automaticPointSpacing_m(mesh, volume);
  haptics::PointShellOptions options;
  options.spacing_m = out.point_spacing_m;
  try {
    out.tool = std::make_shared<const haptics::ToolModel>(haptics::makeToolModel(std::move(mesh), options));
  } catch (const std::exception& e) {
    throw std::runtime_error("tool '" + choice.label + "' at " + std::to_string(out.point_spacing_m * 1e3) +
                             " mm spacing: " + e.what());
  }
  out.X_WT_initial = runtime::defaultInitialPose(volume, out.tool->point_shell, choice.R_WT, isovalue);
  return out;
}

}  // namespace vh::ui
