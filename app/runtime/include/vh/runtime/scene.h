#pragma once
/// @file
/// Scene files (JSON, nlohmann-json): what to load and which parts to start.
/// A scene starts only what it uses: no "device" section means no haptic thread.
///
/// Example:
/// {
///   "volume": {"path": "ct/philips-head-phantom-bone", "isovalue": 400,
///              "series": "BONE", "phase": 0},          // both optional (DICOM folders)
///   "tool": {"mesh": "meshes/drill/drill.stl", "scale_to_m": 0.00044,
///            "point_spacing_m": 0.001,            // or "point_count": 500
///            "initial_pose": {"p_m": [0, 0, 0.1], "q_wxyz": [1, 0, 0, 0]}},
///   "coupling": {"linear_N_per_m": 2000, "angular_Nm_per_rad": 2.0,
///                "passivity_control": false},     // optional (default false): CouplingGains
///   "device": {"kind": "simulated"},              // or "scripted" with "trajectory": "T.csv"
///   "segmentation": {"path": "case.seg.nrrd",     // optional: 3D Slicer segments (segments.h)
///                    "felt": ["facial nerve"], "shown": ["facial nerve", "sigmoid sinus"],
///                    "critical": ["facial nerve"], "smoothing_voxels": 1.0},
///   "openigtlink": {"port": 18944, "rate_Hz": 60}, // optional: stream to 3D Slicer (off when absent)
///   "tissue": {"bands": [{"min": 20, "max": 80, "material": "brain grey matter"}]},  // optional:
///                                                // soft tissue that yields (tissue_scene.h)
///   "technique": {"safe_force_N": 3.0, "safe_force_by_material_N": {"facial nerve": 0.5},
///                 "force_hold_s": 0.5, "near_critical_m": 0.003,
///                 "max_speed_near_critical_m_per_s": 0.01, "shaft_margin_m": 0.0005,
///                 "shaft_hold_s": 0.1, "clear_s": 0.5, "on": true}  // optional: technique.h
/// }
/// "felt" absent or empty: the scan's isosurface is felt and the segments are only shown;
/// "shown" absent: every segment is shown.
/// Hardware devices: "device": {"kind": "falcon", "firmware": "/path/nvent_firmware.bin",
///   "select": "SERIAL-or-path", "workspace": {"scale": 1.5, "offset_m": [0, 0, 0.05],
///   "q_wxyz": [1, 0, 0, 0]}}; "spacemouse" takes "select" and "workspace".
/// Relative paths resolve against the scene file's folder, then the shared datasets folder, then
/// the build's generated data folder (which mirrors the shared layout for unpacked archives, e.g.
/// "classic/ct-bunny/bunny.nhdr" from classic/ct-bunny.tar.zst).
/// Tool meshes may also be "builtin:peg", "builtin:probe", "builtin:drill" (see vh::datasets).
/// Volumes may be "builtin:block-with-hole", "builtin:plane", "builtin:sphere", "builtin:thin-plate",
/// "builtin:thin-shell", "builtin:thin-tube", "builtin:gel-with-inclusion" (soft tissue: "tissue").
/// Optional keys: a top-level "description" (text, ignored); "initial_pose" may give only
/// "q_wxyz" (the tool keeps that orientation and is placed automatically). Every other key is
/// an error (typos are caught), as are unreadable or missing referenced files.

#include <atomic>
#include <cstddef>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <string>

#include "vh/haptics/haptic_renderer.h"
#include "vh/haptics/pose.h"
#include "vh/haptics/tool_model.h"
#include "vh/io/volume_loader.h"
#include "vh/runtime/device.h"
#include "vh/runtime/drilling.h"
#include "vh/runtime/haptic_thread.h"
#include "vh/runtime/segments.h"
#include "vh/runtime/technique.h"
#include "vh/runtime/tissue_scene.h"

namespace vh::runtime {

struct VolumeSpec {
  std::string path;          ///< File, DICOM folder, or "builtin:block-with-hole" etc.
  double isovalue = 0.0;     ///< In the data's units (HU for CT).
  bool isovalue_set = false; ///< False: from the data (400 HU, bone, for CT in HU; else midway).
  /// DICOM folder: which series (io::VolumeLoadOptions::dicom_series: a series number, a
  /// Series Instance UID or text of the description); empty = the largest that loads.
  std::string series;
  int phase = 0;             ///< 4-D DICOM series: the time point (phase, echo), 0-based.
};

struct ToolSpec {
  std::string mesh = "builtin:probe";  ///< Mesh path (STL/OBJ/PLY) or "builtin:NAME".
  double scale_to_m = 1.0;             ///< Multiplies mesh coordinates into metres.
  double point_spacing_m = 0.0;        ///< Point shell spacing [m]; 0 = use point_count.
  std::size_t point_count = 0;         ///< Point count; 0 with spacing 0 = an automatic spacing.
  haptics::Pose X_WT_initial;          ///< Initial proxy/device pose in W [m].
  bool initial_pose_set = false;       ///< False: placed above the volume's centre.
  /// Only the orientation of X_WT_initial was given ("initial_pose": {"q_wxyz": [...]}): the
  /// tool keeps it and is placed above the volume's centre (initial_pose_set stays false).
  bool initial_orientation_set = false;
  /// "edge_test": the tool's surface between its shell points is kept outside the isosurface
  /// too, not only its points (haptics::RendererOptions::edge_test; haptics/README.md, "Between
  /// the points"), so bone thinner than the point spacing cannot slip between them. On by
  /// default; false gives the paper's points-only proxy (for comparison with the published
  /// method), at about half the solver's time.
  bool edge_test = true;
};

/// Where a hardware device's workspace lands in the scene ("device": {"workspace": {...}}).
/// Unset fields take the driver's defaults: the workspace centre at the tool's initial
/// position, the driver's axes (e.g. the Falcon's "up" along +z of W).
struct WorkspaceSpec {
  double scale = 1.0;                         ///< "scale": metres in W per metre at the device.
  std::optional<Eigen::Vector3d> offset_W_m;  ///< "offset_m": workspace centre in W [m].
  std::optional<Eigen::Quaterniond> R_WB;     ///< "q_wxyz": device base frame B in W.
};

struct DeviceSpec {
  /// "simulated" | "scripted" | "spacemouse" | "falcon" | "forcedimension" | "openhaptics" (the
  /// last two load the vendor's SDK at run time: vh::devices). A hardware kind parses once its driver
  /// is registered (registerDeviceKind(); vh::devices::registerDeviceKinds() registers the drivers
  /// the build has); before that the parse error names the library the driver needs.
  std::string kind = "simulated";
  std::string trajectory;          ///< Trajectory CSV for "scripted".
  /// "falcon": the Novint firmware file (user-supplied, never shipped; "firmware"). Optional:
  /// without it a Falcon whose firmware is not loaded yet fails to open with a message.
  std::string firmware;
  /// Hardware: which device ("device": serial number or device path); empty: the first found.
  std::string select;
  WorkspaceSpec workspace;         ///< Hardware: workspace mapping ("workspace").
};

/// Makes a hardware device for a scene's device section, already mapped into W (e.g. a
/// MappedDevice); `X_WT_initial` is the tool's initial pose [m].
/// @throws std::runtime_error when the device cannot be found or opened (the message says why).
using DeviceFactory =
    std::function<std::shared_ptr<Device>(const DeviceSpec& spec, const haptics::Pose& X_WT_initial)>;

/// Registers (or replaces) the factory of a device kind other than "simulated" / "scripted";
/// thread-safe. vh::devices registers "spacemouse" and "falcon" when their libraries were found.
/// @throws std::invalid_argument for an empty kind, a built-in kind or a null factory.
void registerDeviceKind(const std::string& kind, DeviceFactory factory);
/// True when makeDevice() can make `kind` (built-in or registered); thread-safe.
bool deviceKindAvailable(const std::string& kind);

/// The OpenIGTLink server of a scene ("openigtlink": {"port": 18944, "rate_Hz": 60}; both keys
/// optional): the link (vh/igtl/igtl_link.h) listens on `port` and streams the proxy and device
/// poses, force and contact state to one client (e.g. 3D Slicer's OpenIGTLinkIF) at `rate_Hz`.
struct OpenIgtlinkSpec {
  int port = 18944;      ///< TCP port, 1..65535 (OpenIGTLink's registered port by default).
  double rate_Hz = 60.0; ///< Messages per second per kind, > 0 (the link clamps it to the servo rate) [Hz].
};

/// Largest coupling stiffnesses a scene file may ask for (the Haptics panel's limits): far past
/// any desktop device's rating (a Phantom Premium's is about 3.5 kN/m), below where forces
/// overflow. Larger ones are refused naming the field.
inline constexpr double kMaxLinearStiffness_N_per_m = 1e5;
inline constexpr double kMaxAngularStiffness_Nm_per_rad = 50.0;

/// A parsed scene (paths already resolved to absolute ones where they exist).
struct SceneSpec {
  std::filesystem::path source;  ///< Scene file (empty for built-in scenes).
  VolumeSpec volume;
  ToolSpec tool;
  haptics::CouplingGains gains;
  std::optional<DeviceSpec> device;  ///< Absent: no haptic thread.
  std::optional<SegmentationSpec> segmentation;  ///< Absent: no segments.
  std::optional<OpenIgtlinkSpec> openigtlink;  ///< Absent: no OpenIGTLink server (the default).
  std::optional<DrillSpec> drill;  ///< Absent: the tool only touches (no drilling state at all).
  /// Soft tissue (tissue_scene.h): a region of the scan that yields. Absent: all rigid, and no
  /// tissue state at all.
  std::optional<TissueSpec> tissue;
  /// Live feedback on technique (technique.h); absent from the file: the default rules.
  TechniqueRules technique;
};

/// Parses a scene file.
/// @throws std::runtime_error naming the file and the problem (missing file, bad JSON, a
///         missing or mistyped field).
SceneSpec loadSceneFile(const std::filesystem::path& path);

/// Parses scene JSON text ('//' and '/* */' comments allowed). Unknown keys are errors (they are
/// usually typos). Relative paths resolve against `base_dir`, then sharedDatasetsDir(), then
/// generatedDataDir(); a referenced file or folder found in none of them is an error.
/// @param source names the scene in error messages ("FILE: problem").
/// @throws std::runtime_error "SOURCE: problem", e.g. "s.json: volume.isovalue: expected a
///         number, found string".
SceneSpec parseScene(const std::string& json_text, const std::string& source,
                     const std::filesystem::path& base_dir);

/// The installed program's data folder, PREFIX/share/volume-haptics (found relative to the running
/// executable, PREFIX/bin/), when it exists; empty when running from the build tree.
std::filesystem::path installedDataDir();

/// The folder of the real shared datasets: $VH_SHARED_DATASETS_DIR when set, else the folder
/// the user chose (setPreferredSharedDatasetsDir(): the GUI's File > Data Folder), else for an
/// installed copy installedDataDir()/datasets (absent unless someone puts datasets there), else
/// the folder configured at build time (CMake cache VH_SHARED_DATASETS_DIR). Thread-safe.
std::filesystem::path sharedDatasetsDir();

/// The folder the user chose for the shared datasets (the GUI's Data Folder preference), used
/// by sharedDatasetsDir() when VH_SHARED_DATASETS_DIR is not set; empty forgets it. Thread-safe.
void setPreferredSharedDatasetsDir(const std::filesystem::path& dir);

/// Whether VH_SHARED_DATASETS_DIR is set (it then wins over the chosen folder).
bool sharedDatasetsDirFromEnvironment();

/// Where the shared datasets are looked for and how to get them, for messages and Help > About:
/// the folder (sharedDatasetsDir(), "(absent)" when it does not exist), that File > Data Folder
/// in the window or VH_SHARED_DATASETS_DIR points the program at another folder holding them
/// (ct/, nrrd/, classic/, meshes/: the tool meshes too), and that Help > About and datasets/manifest.json
/// list each dataset with its public source. One paragraph, no trailing newline.
std::string sharedDatasetsNote();

/// The generated data folder (synthetic volumes, unpacked archives): $VH_GENERATED_DATA_DIR
/// when set, else for an installed copy $XDG_CACHE_HOME/volume-haptics (or
/// ~/.cache/volume-haptics; empty without either), else the build tree's data/ folder
/// configured at build time. An installed copy never refers to the build machine's folders.
std::filesystem::path generatedDataDir();

/// The built-in scene: the paper's 256^3 block with a hole and a peg that fits it, simulated
/// device.
SceneSpec builtinBlockWithHoleScene();

/// A scene for a volume path (DICOM folder, NRRD, MetaImage) with the default tool and a
/// simulated device.
SceneSpec sceneForVolume(const std::filesystem::path& volume_path);

/// Prefix of SceneSpec::volume.path for a volume received over OpenIGTLink ("igtl:NAME", NAME
/// the IMAGE message's device name): it names no file; loadScene(spec, preloaded) takes the
/// voxels from memory.
inline constexpr const char* kIgtlVolumePrefix = "igtl:";

/// A scene for a volume that is already loaded (e.g. received over OpenIGTLink): volume path
/// "igtl:" + `volume.info.description`, the default tool and a simulated device, like
/// sceneForVolume(). Open it with loadScene(spec, volume).
SceneSpec sceneForLoadedVolume(const io::LoadedVolume& volume);

/// The surface the hand feels, one rule for a scene as loaded and for the live values: the felt
/// segments' smoothed indicator field at io::kSegmentSurfaceLevel when `segments` has some felt,
/// else `scan_field` at `scan_isovalue` (data units).
inline bool feltSegmentsIn(const std::shared_ptr<const SegmentSet>& segments) noexcept {
  return segments != nullptr && segments->feltField() != nullptr;
}
inline const std::shared_ptr<const haptics::ScalarVolume>& feltFieldOf(
    const std::shared_ptr<const SegmentSet>& segments, const std::shared_ptr<const haptics::ScalarVolume>& scan_field) noexcept {
  return feltSegmentsIn(segments) ? segments->feltField() : scan_field;
}
inline double feltIsovalueOf(const std::shared_ptr<const SegmentSet>& segments, double scan_isovalue) noexcept {
  return feltSegmentsIn(segments) ? io::kSegmentSurfaceLevel : scan_isovalue;
}

/// A scene with everything loaded: the volume (haptic field + VTK image), the tool (resampled
/// point shell, mass properties, display mesh), the isovalue and the initial pose. Immutable
/// once loaded: what changes while the program runs (the isovalue slider, the gains, the tool
/// picker, the felt segments) lives in LiveValues, whose one owner in the GUI is Session
/// (session.h). The fields below that a user can change are the values the scene was loaded
/// with (LiveValues::initial()); headless runs (runner.h, the benches) use them as they are.
struct LoadedScene {
  SceneSpec spec;
  io::LoadedVolume volume;                        ///< Field and image in W [m].
  std::shared_ptr<const haptics::ToolModel> tool; ///< Tool in its frame T [m], as loaded.
  double isovalue = 0.0;                          ///< Isovalue s in the data's units, as loaded.
  haptics::Pose X_WT_initial;                     ///< Initial proxy and device pose in W [m].
  int initial_points_inside = 0;  ///< Shell points inside F = s at X_WT_initial (0 normally).
  /// The scene's segments (spec.segmentation), or null. When some are felt, the hand feels
  /// their surface (hapticField()) and the isovalue only sets the scan's picture.
  std::shared_ptr<const SegmentSet> segments;

  /// True when segments are felt instead of the scan's isosurface.
  bool feltSegments() const noexcept { return feltSegmentsIn(segments); }
  /// The field the hand feels: the felt segments' smoothed indicator, else the scan's field.
  const std::shared_ptr<const haptics::ScalarVolume>& hapticField() const noexcept {
    return feltFieldOf(segments, volume.field);
  }
  /// The isovalue of hapticField(): io::kSegmentSurfaceLevel for felt segments, else isovalue.
  double hapticIsovalue() const noexcept { return feltIsovalueOf(segments, isovalue); }

  /// The spacing the tool's point shell was sampled at [m] (LiveValues::pointSpacing_m() of the
  /// loaded values); 0 without a tool or a field.
  double pointSpacing_m() const;

  /// A renderer for this scene as loaded (vh::runtime::makeRenderer() of LiveValues::initial())
  /// with the proxy at `X_WP` (X_WT_initial when absent).
  /// @throws std::invalid_argument as HapticRenderer's constructor.
  std::unique_ptr<haptics::HapticRenderer> makeRenderer(haptics::RendererOptions options = {},
                                                        const std::optional<haptics::Pose>& X_WP = {}) const;
  /// The scene's device (SimulatedDevice at X_WT_initial, ScriptedDevice stepping one servo
  /// period per read, or a registered hardware kind), or nullptr when the scene has no device
  /// section.
  /// @throws std::runtime_error for an unreadable trajectory (naming the file and line), a
  ///         hardware kind without a registered driver, or a device that cannot be opened.
  std::shared_ptr<Device> makeDevice(double servo_rate_Hz = 1000.0) const;
  /// The haptic threads for this scene as loaded: vh::runtime::makeHapticThread() of
  /// LiveValues::initial() (the headless runner's tests).
  /// @throws std::invalid_argument as HapticThread's and HapticRenderer's constructors.
  std::unique_ptr<HapticThread> makeHapticThread(std::shared_ptr<Device> device, double servo_rate_Hz = 1000.0,
                                                 const std::optional<haptics::Pose>& X_WP = {},
                                                 const HapticThreadOptions& options = {}) const;
};

/// What changes while the program runs over a loaded scene: the isovalue (the slider), the
/// coupling gains, the tool (the tool picker), the segments and which are felt (the Segments
/// panel), and what a drill removed (drill->cavity). In the GUI its one owner is
/// Session (session.h): the renderer, the recorder's metadata, the monitor, the OpenIGTLink
/// link and the panels read it there. Headless runs take LiveValues::initial() of their scene.
struct LiveValues {
  std::shared_ptr<const haptics::ScalarVolume> scan_field;  ///< The scan's field in W [m] (data units).
  double isovalue = 0.0;                          ///< The scan's isovalue s (data units; HU for CT).
  haptics::CouplingGains gains;                   ///< Virtual coupling gains [N/m], [N*m/rad].
  std::shared_ptr<const haptics::ToolModel> tool; ///< Tool in its frame T [m]; null: none.
  ToolSpec tool_spec;                             ///< How `tool` was made (mesh, scale, point spacing).
  haptics::Pose X_WT_initial;                     ///< Where the tool was placed, free, in W [m].
  std::shared_ptr<const SegmentSet> segments;     ///< The segments shown and felt; null: none.
  std::optional<SegmentationSpec> segmentation;   ///< What a scene file says of `segments`.
  /// Drilling (drilling.h): the burr, the hardness and the cavity the haptic threads were built
  /// on (drill->cavity; the threads' drill carves on from it); null: the tool only touches.
  /// Whether the burr spins is the haptic thread's (HapticThread::setDrilling()).
  std::optional<DrillSpec> drill;
  bool scan_in_HU = false;                        ///< The scan is CT in HU (drilling's hardness classes).
  TechniqueRules technique;                       ///< The technique rules the servo loop checks.
  /// Soft tissue (tissue_scene.h): the haptic threads feel it yield; absent: all rigid.
  std::optional<TissueSpec> tissue;

  /// The values `scene` was loaded with (its field, isovalue, spec.gains, tool, spec.tool,
  /// X_WT_initial, segments, spec.segmentation, spec.technique).
  static LiveValues initial(const LoadedScene& scene);

  /// True when segments are felt instead of the scan's isosurface.
  bool feltSegments() const noexcept { return feltSegmentsIn(segments); }
  /// The field the hand feels: the felt segments' smoothed indicator, else scan_field.
  const std::shared_ptr<const haptics::ScalarVolume>& hapticField() const noexcept {
    return feltFieldOf(segments, scan_field);
  }
  /// The isovalue of hapticField(): io::kSegmentSurfaceLevel for felt segments, else isovalue.
  double hapticIsovalue() const noexcept { return feltIsovalueOf(segments, isovalue); }
  /// The spacing the tool's point shell was sampled at [m]: toolPointSpacing_m() of tool_spec on
  /// the tool's mesh and hapticField() (derived, so it cannot disagree with the spec); 0 without
  /// a tool or a field.
  double pointSpacing_m() const;
};

/// The point spacing [m] of a tool whose spec gives none: about 1000 points on the mesh, not
/// below half the volume's smallest voxel. The one rule (loadScene(), the GUI's tool picker).
double automaticPointSpacing_m(const haptics::TriangleMesh& mesh_T, const haptics::ScalarVolume& volume);

/// The spacing [m] a tool spec asks for on `mesh_T` in `volume`: point_spacing_m when given;
/// sqrt(area / point_count) for a point count; else automaticPointSpacing_m().
double toolPointSpacing_m(const ToolSpec& spec, const haptics::TriangleMesh& mesh_T,
                          const haptics::ScalarVolume& volume);

/// Whether `path` names a volume or tool made in memory ("builtin:NAME": vh::datasets), not a
/// file.
bool isBuiltinPath(const std::string& path) noexcept;

/// Loads what a scene names: the volume (io::loadVolume, or vh::datasets for "builtin:NAME"),
/// the tool mesh (io::loadMesh scaled by scale_to_m, or a built-in tool) resampled into a point
/// shell (point_count, else point_spacing_m, else a spacing giving about 1000 points but not
/// below half a voxel), the isovalue (the spec's; else the built-in volume's; else 400 HU for CT data in HU
/// within its range; else midway
/// between the field's minimum and maximum) and the initial pose (the spec's; else
/// defaultInitialPose(): above the volume's centre, lowered to a clearance above the surface).
/// @throws io::LoadError for volume/mesh files that fail to load; std::runtime_error naming the
///         scene for unknown built-ins or an unusable tool.
LoadedScene loadScene(const SceneSpec& spec);
/// loadScene() with the volume read's progress (0..1, from the calling thread) and a cancel
/// flag (io::VolumeLoadOptions).
/// @throws io::LoadCancelled when `cancel` became true during the read; else as loadScene().
LoadedScene loadScene(const SceneSpec& spec, const std::function<void(double fraction)>& progress,
                      const std::atomic<bool>* cancel);
/// loadScene() with the volume already in memory (e.g. an IMAGE received over OpenIGTLink):
/// `preloaded` replaces the read of spec.volume.path; the isovalue, tool and initial pose follow
/// as for a file (400 HU for CT in HU, else midway; the spec's when set).
/// @throws std::invalid_argument when `preloaded` has no field; else as loadScene() (the tool).
LoadedScene loadScene(const SceneSpec& spec, io::LoadedVolume preloaded);
/// loadScene() with the volume and the segmentation already in memory (arrays from Python):
/// `segmentation` replaces the read of spec.segmentation->path (spec.segmentation gives the
/// felt, shown and critical choices), on the volume's grid.
/// @throws std::invalid_argument when spec.segmentation is absent or the label grid is not the
///         volume's; else as the overload above and SegmentSet::fromSpec().
LoadedScene loadScene(const SceneSpec& spec, io::LoadedVolume preloaded, io::LoadedSegmentation segmentation);

}  // namespace vh::runtime
