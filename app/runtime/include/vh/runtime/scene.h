#pragma once
/// @file
/// Scene files (JSON, nlohmann-json): what to load and which parts to start.
/// A scene starts only what it uses: no "device" section means no haptic thread.
///
/// Example:
/// {
///   "volume": {"path": "ct/philips-head-phantom-bone", "isovalue": 400},
///   "tool": {"mesh": "meshes/drill/drill.stl", "scale_to_m": 0.00044,
///            "point_spacing_m": 0.001,            // or "point_count": 500
///            "initial_pose": {"p_m": [0, 0, 0.1], "q_wxyz": [1, 0, 0, 0]}},
///   "coupling": {"linear_N_per_m": 2000, "angular_Nm_per_rad": 2.0},
///   "device": {"kind": "simulated"}               // or "scripted" with "trajectory": "T.csv"
/// }
/// Relative paths resolve against the scene file's folder, then the shared datasets folder.
/// Tool meshes may also be "builtin:peg", "builtin:probe", "builtin:drill" (see vh::datasets).

#include <filesystem>
#include <optional>
#include <string>

#include "vh/haptics/haptic_renderer.h"
#include "vh/haptics/pose.h"

namespace vh::runtime {

struct VolumeSpec {
  std::string path;          ///< File, DICOM folder, or "builtin:block-with-hole" etc.
  double isovalue = 0.0;     ///< In the data's units (HU for CT).
  bool isovalue_set = false; ///< False: choose one from the data (midway between min and max).
};

struct ToolSpec {
  std::string mesh = "builtin:probe";  ///< Mesh path (STL/OBJ/PLY) or "builtin:NAME".
  double scale_to_m = 1.0;             ///< Multiplies mesh coordinates into metres.
  double point_spacing_m = 0.0;        ///< Point shell spacing [m]; 0 = use point_count.
  std::size_t point_count = 0;         ///< Point count; 0 with spacing 0 = an automatic spacing.
  haptics::Pose X_WT_initial;          ///< Initial proxy/device pose in W [m].
  bool initial_pose_set = false;       ///< False: placed above the volume's centre.
};

struct DeviceSpec {
  std::string kind = "simulated";  ///< "simulated" | "scripted".
  std::string trajectory;          ///< Trajectory CSV for "scripted".
};

/// A parsed scene (paths already resolved to absolute ones where they exist).
struct SceneSpec {
  std::filesystem::path source;  ///< Scene file (empty for built-in scenes).
  VolumeSpec volume;
  ToolSpec tool;
  haptics::CouplingGains gains;
  std::optional<DeviceSpec> device;  ///< Absent: no haptic thread.
};

/// Parses a scene file.
/// @throws std::runtime_error naming the file and the problem (missing file, bad JSON, a
///         missing or mistyped field).
SceneSpec loadSceneFile(const std::filesystem::path& path);

/// The built-in scene: the paper's 256^3 block with a hole and a peg that fits it, simulated
/// device.
SceneSpec builtinBlockWithHoleScene();

/// A scene for a volume path (DICOM folder, NRRD, MetaImage) with the default tool and a
/// simulated device.
SceneSpec sceneForVolume(const std::filesystem::path& volume_path);

}  // namespace vh::runtime
