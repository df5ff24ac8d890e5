// Loading what a scene names (scene.h): the volume, the segmentation, the tool and its pose;
// the device kinds. Scene files are read in scene_file.cpp, the servo built in servo_factory.cpp.
#include "vh/runtime/scene.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <map>
#include <mutex>
#include <optional>
#include <stdexcept>

#include "vh/datasets/synthetic.h"
#include "vh/runtime/default_isovalue.h"
#include "vh/runtime/placement.h"
#include "vh/runtime/tool_fidelity.h"

namespace vh::runtime {

namespace fs = std::filesystem;

namespace {

std::string builtinName(const std::string& path) { return path.substr(std::string_view("builtin:").size()); }

/// Factories of the registered hardware device kinds (registerDeviceKind()).
std::map<std::string, DeviceFactory>& deviceFactories() {
  static std::map<std::string, DeviceFactory> factories;
  return factories;
}
std::mutex& deviceFactoriesMutex() {
  static std::mutex mutex;
  return mutex;
}

}  // namespace

// ---- Loading -------------------------------------------------------------------------------

namespace {

/// The part of loading after the volume: the spec's isovalue, the segmentation, the tool, the
/// initial pose. `cancel` as loadScene()'s (the segmentation's read).
/// `preloaded`: the segmentation in memory instead of spec.segmentation->path's file.
void loadToolAndPose(LoadedScene& scene, const std::string& where, const std::atomic<bool>* cancel = nullptr,
                     std::optional<io::LoadedSegmentation> preloaded = std::nullopt);

}  // namespace

namespace {

/// loadScene() of `preloaded` (and `segmentation` when given) instead of the spec's files.
LoadedScene loadPreloaded(const SceneSpec& spec, io::LoadedVolume preloaded,
                          std::optional<io::LoadedSegmentation> segmentation) {
  const std::string where = spec.source.empty() ? std::string("scene") : spec.source.string();
  LoadedScene scene;
  scene.spec = spec;
  scene.volume = std::move(preloaded);
  if (scene.volume.image == nullptr) scene.volume.image = io::imageFromField(scene.volume.field);
  scene.isovalue = defaultIsovalue(scene.volume);
  loadToolAndPose(scene, where, nullptr, std::move(segmentation));
  return scene;
}

}  // namespace

LoadedScene loadScene(const SceneSpec& spec, io::LoadedVolume preloaded) {
  if (preloaded.field == nullptr) throw std::invalid_argument("loadScene: the preloaded volume has no field");
  return loadPreloaded(spec, std::move(preloaded), std::nullopt);
}

LoadedScene loadScene(const SceneSpec& spec, io::LoadedVolume preloaded, io::LoadedSegmentation segmentation) {
  if (!spec.segmentation) throw std::invalid_argument("loadScene: a preloaded segmentation needs the scene's segmentation section");
  if (preloaded.field == nullptr || segmentation.layers.empty() || segmentation.layers.front() == nullptr ||
      !segmentation.layers.front()->geometry().sameGridAs(preloaded.field->geometry()))
    throw std::invalid_argument("loadScene: the label volume is not on the volume's grid (same shape and affine)");
  return loadPreloaded(spec, std::move(preloaded), std::move(segmentation));
}

LoadedScene loadScene(const SceneSpec& spec) { return loadScene(spec, {}, nullptr); }

LoadedScene loadScene(const SceneSpec& spec, const std::function<void(double)>& progress,
                      const std::atomic<bool>* cancel) {
  const std::string where = spec.source.empty() ? std::string("scene") : spec.source.string();
  LoadedScene scene;
  scene.spec = spec;

  // Volume.
  if (isBuiltinPath(spec.volume.path)) {
    const std::string name = builtinName(spec.volume.path);
    try {
      auto field = std::make_shared<const haptics::ScalarVolume>(datasets::makeBuiltinVolume(name));
      scene.volume.image = io::imageFromField(field);
      scene.volume.field = std::move(field);
      scene.isovalue = datasets::builtinIsovalue(name);
    } catch (const std::invalid_argument& e) {
      throw std::runtime_error(where + ": volume: " + e.what());
    }
    scene.volume.info.source = spec.volume.path;
    scene.volume.info.format = "synthetic";
    scene.volume.info.description = name;
  } else {
    io::VolumeLoadOptions options;
    options.dicom_series = spec.volume.series;
    options.dicom_phase = spec.volume.phase;
    options.progress = progress;
    options.cancel = cancel;
    scene.volume = io::loadVolume(spec.volume.path, options);
    scene.isovalue = defaultIsovalue(scene.volume);
  }
  loadToolAndPose(scene, where, cancel);
  return scene;
}

namespace {

void loadToolAndPose(LoadedScene& scene, const std::string& where, const std::atomic<bool>* cancel,
                     std::optional<io::LoadedSegmentation> preloaded) {
  const SceneSpec& spec = scene.spec;
  if (spec.volume.isovalue_set) scene.isovalue = spec.volume.isovalue;
  if (spec.segmentation && preloaded) {
    scene.segments = SegmentSet::fromSpec(std::move(*preloaded), *spec.segmentation, where);
  } else if (spec.segmentation) {
    io::VolumeLoadOptions options;
    options.cancel = cancel;
    // On the scan: a DICOM SEG is placed on the scan's voxels and checked against its series.
    scene.segments = SegmentSet::fromSpec(io::loadSegmentation(spec.segmentation->path, scene.volume, options),
                                          *spec.segmentation, where);
  }
  const haptics::ScalarVolume& field = *scene.hapticField();

  // Tool.
  haptics::TriangleMesh mesh;
  if (isBuiltinPath(spec.tool.mesh)) {
    try {
      mesh = datasets::makeBuiltinTool(builtinName(spec.tool.mesh));
    } catch (const std::invalid_argument& e) {
      throw std::runtime_error(where + ": tool: " + e.what());
    }
    if (spec.tool.scale_to_m != 1.0) mesh.scale(spec.tool.scale_to_m);
  } else {
    mesh = io::loadMesh(spec.tool.mesh, spec.tool.scale_to_m);
  }
  haptics::PointShellOptions shell_options;
  if (spec.tool.point_count > 0) {
    shell_options.point_count = spec.tool.point_count;
  } else if (spec.tool.point_spacing_m > 0.0) {
    shell_options.spacing_m = spec.tool.point_spacing_m;
  } else {
    shell_options.spacing_m = automaticPointSpacing_m(mesh, field);
  }
  try {
    scene.tool = std::make_shared<const haptics::ToolModel>(haptics::makeToolModel(std::move(mesh), shell_options));
  } catch (const std::invalid_argument& e) {
    throw std::runtime_error(where + ": tool '" + spec.tool.mesh + "': " + e.what());
  }
  // A spacing too coarse for the tool's features (a 1 mm shaft at 2 mm) is said at once.
  const std::string gap_notice = feltGapNotice(feltGap(*scene.tool, spec.tool.edge_test),
                                               toolPointSpacing_m(spec.tool, scene.tool->mesh_T, field));
  if (!gap_notice.empty()) scene.volume.info.notices.push_back(gap_notice);

  // Initial pose.
  if (spec.tool.initial_pose_set) {
    scene.X_WT_initial = spec.tool.X_WT_initial;
  } else {
    const Eigen::Quaterniond R_WT =
        spec.tool.initial_orientation_set ? spec.tool.X_WT_initial.R_AB : Eigen::Quaterniond::Identity();
    scene.X_WT_initial = defaultInitialPose(field, scene.tool->point_shell, R_WT, scene.hapticIsovalue());
  }
  scene.initial_points_inside =
      countPointsInside(field, scene.tool->point_shell, scene.X_WT_initial, scene.hapticIsovalue());
}

}  // namespace

double automaticPointSpacing_m(const haptics::TriangleMesh& mesh_T, const haptics::ScalarVolume& volume) {
  return std::max(std::sqrt(mesh_T.area_m2() / 1000.0), 0.5 * volume.geometry().minSpacing());
}

double toolPointSpacing_m(const ToolSpec& spec, const haptics::TriangleMesh& mesh_T,
                          const haptics::ScalarVolume& volume) {
  if (spec.point_count > 0) return std::sqrt(mesh_T.area_m2() / static_cast<double>(spec.point_count));
  if (spec.point_spacing_m > 0.0) return spec.point_spacing_m;
  return automaticPointSpacing_m(mesh_T, volume);
}

LiveValues LiveValues::initial(const LoadedScene& scene) {
  LiveValues live;
  live.scan_field = scene.volume.field;
  live.isovalue = scene.isovalue;
  live.gains = scene.spec.gains;
  live.tool = scene.tool;
  live.tool_spec = scene.spec.tool;
  live.X_WT_initial = scene.X_WT_initial;
  live.segments = scene.segments;
  live.segmentation = scene.spec.segmentation;
  live.drill = scene.spec.drill;
  live.tissue = scene.spec.tissue;
  live.scan_in_HU = inHounsfieldUnits(scene.volume);
  live.technique = scene.spec.technique;
  return live;
}

double LiveValues::pointSpacing_m() const {
  if (tool == nullptr || hapticField() == nullptr) return 0.0;
  return toolPointSpacing_m(tool_spec, tool->mesh_T, *hapticField());
}

double LoadedScene::pointSpacing_m() const { return LiveValues::initial(*this).pointSpacing_m(); }

std::shared_ptr<Device> LoadedScene::makeDevice(double servo_rate_Hz) const {
  if (!spec.device) return nullptr;
  if (spec.device->kind == "scripted") {
    return std::make_shared<ScriptedDevice>(loadTrajectoryCsv(spec.device->trajectory), 1.0 / servo_rate_Hz,
                                            fs::path(spec.device->trajectory).filename().string());
  }
  if (spec.device->kind == "simulated") return std::make_shared<SimulatedDevice>(X_WT_initial);
  DeviceFactory factory;
  {
    const std::lock_guard<std::mutex> lock(deviceFactoriesMutex());
    const auto it = deviceFactories().find(spec.device->kind);
    if (it != deviceFactories().end()) factory = it->second;
  }
  const std::string where = spec.source.empty() ? std::string("scene") : spec.source.string();
  if (!factory) {
    throw std::runtime_error(where + ": device kind '" + spec.device->kind +
                             "' has no driver in this program (vh::devices::registerDeviceKinds() registers "
                             "\"spacemouse\" when hidapi was found and \"falcon\" when libusb was found)");
  }
  std::shared_ptr<Device> device = factory(*spec.device, X_WT_initial);
  if (!device) throw std::runtime_error(where + ": device kind '" + spec.device->kind + "': no device made");
  return device;
}

void registerDeviceKind(const std::string& kind, DeviceFactory factory) {
  if (kind.empty() || kind == "simulated" || kind == "scripted") {
    throw std::invalid_argument("registerDeviceKind: '" + kind + "' cannot be registered");
  }
  if (!factory) throw std::invalid_argument("registerDeviceKind: no factory for '" + kind + "'");
  const std::lock_guard<std::mutex> lock(deviceFactoriesMutex());
  deviceFactories()[kind] = std::move(factory);
}

bool deviceKindAvailable(const std::string& kind) {
  if (kind == "simulated" || kind == "scripted") return true;
  const std::lock_guard<std::mutex> lock(deviceFactoriesMutex());
  return deviceFactories().count(kind) > 0;
}

}  // namespace vh::runtime
