// Scene files (scene.h): the JSON reader with its checks and messages, the data folders a
// scene's relative paths are looked for in, and the scenes made without a file.
#include "vh/runtime/scene.h"
#include "vh/tissue/material.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <initializer_list>
#include <map>
#include <mutex>
#include <optional>
#include <set>
#include <sstream>
#include <stdexcept>
#include <utility>
#include <thread>

#include <nlohmann/json.hpp>

#include "vh/datasets/synthetic.h"
#include "vh/runtime/default_isovalue.h"
#include "vh/runtime/placement.h"
#include "vh/runtime/tool_fidelity.h"

#ifndef VH_DEFAULT_SHARED_DATASETS_DIR
#define VH_DEFAULT_SHARED_DATASETS_DIR ""
#endif
#ifndef VH_DEFAULT_GENERATED_DATA_DIR
#define VH_DEFAULT_GENERATED_DATA_DIR ""
#endif

namespace vh::runtime {

namespace fs = std::filesystem;
using nlohmann::json;

bool isBuiltinPath(const std::string& path) noexcept { return path.rfind("builtin:", 0) == 0; }

namespace {

/// Reads fields of one JSON object, checking types and unknown keys; errors name the scene and
/// the dotted field path.
class ObjectReader {
 public:
  ObjectReader(const json& object, std::string path, const std::string& source)
      : object_(object), path_(std::move(path)), source_(source) {
    if (!object_.is_object()) fail(path_, "expected an object, found " + std::string(object_.type_name()));
  }

  [[noreturn]] void fail(const std::string& field, const std::string& problem) const {
    throw std::runtime_error(source_ + ": " + (field.empty() ? std::string() : field + ": ") + problem);
  }
  std::string fieldPath(const std::string& key) const { return path_.empty() ? key : path_ + "." + key; }
  /// The scene's name in errors (for a reader of a nested object, which must outlive none of it).
  const std::string& source() const noexcept { return source_; }

  /// Throws for a key not in `known`.
  void allowOnly(std::initializer_list<const char*> known) const {
    std::set<std::string> allowed;
    std::string list;
    for (const char* k : known) {
      allowed.insert(k);
      list += (list.empty() ? "" : ", ") + std::string(k);
    }
    for (auto it = object_.begin(); it != object_.end(); ++it) {
      if (!allowed.count(it.key())) {
        fail(path_.empty() ? std::string() : path_,
             "unknown key '" + it.key() + "' (expected one of: " + list + ")");
      }
    }
  }

  bool has(const char* key) const { return object_.contains(key); }
  /// The object's keys (sorted).
  std::vector<std::string> keys() const {
    std::vector<std::string> out;
    for (auto it = object_.begin(); it != object_.end(); ++it) out.push_back(it.key());
    return out;
  }
  const json& at(const char* key) const {
    if (!object_.contains(key)) fail(fieldPath(key), "missing");
    return object_.at(key);
  }

  std::string string(const char* key) const {
    const json& v = at(key);
    if (!v.is_string()) fail(fieldPath(key), "expected a string, found " + std::string(v.type_name()));
    const std::string s = v.get<std::string>();
    if (s.empty()) fail(fieldPath(key), "must not be empty");
    return s;
  }
  double number(const char* key) const {
    const json& v = at(key);
    if (!v.is_number()) fail(fieldPath(key), "expected a number, found " + std::string(v.type_name()));
    const double d = v.get<double>();
    if (!std::isfinite(d)) fail(fieldPath(key), "must be finite");
    return d;
  }
  double positive(const char* key) const {
    const double d = number(key);
    if (!(d > 0.0)) fail(fieldPath(key), "must be > 0, found " + json(d).dump());
    return d;
  }
  bool boolean(const char* key) const {
    const json& v = at(key);
    if (!v.is_boolean()) fail(fieldPath(key), "expected true or false, found " + v.dump());
    return v.get<bool>();
  }
  std::size_t count(const char* key) const {
    const json& v = at(key);
    if (!v.is_number_integer() || v.get<long long>() <= 0) {
      fail(fieldPath(key), "expected a positive integer, found " + v.dump());
    }
    return static_cast<std::size_t>(v.get<long long>());
  }
  /// A list of strings (absent: empty).
  std::vector<std::string> strings(const char* key) const {
    std::vector<std::string> out;
    if (!has(key)) return out;
    const json& v = at(key);
    if (!v.is_array()) fail(fieldPath(key), "expected a list of strings, found " + v.dump());
    for (const json& e : v) {
      if (!e.is_string()) fail(fieldPath(key), "expected a list of strings, found " + e.dump() + " in it");
      out.push_back(e.get<std::string>());
    }
    return out;
  }
  /// A string, or an integer given as a number (a DICOM series number).
  std::string stringOrInteger(const char* key) const {
    const json& v = at(key);
    if (v.is_number_integer()) return std::to_string(v.get<long long>());
    return string(key);
  }
  std::size_t index(const char* key) const {
    const json& v = at(key);
    if (!v.is_number_integer() || v.get<long long>() < 0 || v.get<long long>() > 1000000) {
      fail(fieldPath(key), "expected an integer >= 0, found " + v.dump());
    }
    return static_cast<std::size_t>(v.get<long long>());
  }
  template <int N>
  Eigen::Matrix<double, N, 1> vector(const char* key) const {
    const json& v = at(key);
    if (!v.is_array() || v.size() != static_cast<std::size_t>(N)) {
      fail(fieldPath(key), "expected an array of " + std::to_string(N) + " numbers, found " + v.dump());
    }
    Eigen::Matrix<double, N, 1> out;
    for (int i = 0; i < N; ++i) {
      const json& e = v[static_cast<std::size_t>(i)];
      if (!e.is_number() || !std::isfinite(e.get<double>())) {
        fail(fieldPath(key), "expected an array of " + std::to_string(N) + " numbers, found " + v.dump());
      }
      out[i] = e.get<double>();
    }
    return out;
  }
  ObjectReader object(const char* key) const { return ObjectReader(at(key), fieldPath(key), source_); }

 private:
  const json& object_;
  std::string path_;
  const std::string& source_;
};

/// A hint for a relative path that lies inside an archive of the shared folder
/// ("classic/ct-bunny/bunny.nhdr" -> "classic/ct-bunny.tar.zst"), or empty.
std::string archiveHint(const fs::path& relative) {
  std::error_code ec;
  fs::path prefix;
  for (const fs::path& part : relative) {
    prefix /= part;
    for (const char* ext : {".tar.zst", ".tar.gz", ".tar.xz", ".zip"}) {
      const fs::path archive = sharedDatasetsDir() / (prefix.string() + ext);
      if (fs::is_regular_file(archive, ec)) {
        return "; it is packed in " + archive.string() + ": unpack it into " +
               (generatedDataDir() / prefix.parent_path()).lexically_normal().string() +
               " (cmake -E tar xf), or run the runtime tests, which do";
      }
    }
  }
  return {};
}

/// Resolves a data path: absolute as is; relative against the scene's folder, the shared
/// datasets folder, then the generated data folder. Built-ins are returned unchanged.
std::string resolveDataPath(const ObjectReader& reader, const char* key, const std::string& value,
                            const fs::path& base_dir) {
  if (isBuiltinPath(value)) return value;
  std::error_code ec;
  const fs::path p(value);
  if (p.is_absolute()) {
    if (!fs::exists(p, ec)) reader.fail(reader.fieldPath(key), "'" + value + "' not found");
    return p.lexically_normal().string();
  }
  std::vector<fs::path> candidates;
  if (!base_dir.empty()) candidates.push_back(base_dir / p);
  const fs::path shared = sharedDatasetsDir();
  if (!shared.empty()) candidates.push_back(shared / p);
  const fs::path generated = generatedDataDir();
  if (!generated.empty()) candidates.push_back(generated / p);
  std::string looked;
  for (const fs::path& c : candidates) {
    if (fs::exists(c, ec)) return fs::absolute(c, ec).lexically_normal().string();
    looked += (looked.empty() ? "" : " and ") + c.lexically_normal().string();
  }
  const std::string hint = archiveHint(p);
  reader.fail(reader.fieldPath(key), "'" + value + "' not found (looked in " + looked + ")" +
                                         (hint.empty() ? ". " + sharedDatasetsNote() : hint));
}

}  // namespace


fs::path installedDataDir() {
#ifdef VH_INSTALL_DATA_RELATIVE_PATH
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  if (ec) return {};
  const fs::path data = (exe.parent_path() / VH_INSTALL_DATA_RELATIVE_PATH).lexically_normal();
  if (fs::is_directory(data, ec)) return data;
#endif
  return {};
}

namespace {

std::mutex& preferredDatasetsMutex() {
  static std::mutex m;
  return m;
}

fs::path& preferredDatasetsDir() {  // guarded by preferredDatasetsMutex()
  static fs::path dir;
  return dir;
}

}  // namespace

void setPreferredSharedDatasetsDir(const fs::path& dir) {
  const std::lock_guard lock(preferredDatasetsMutex());
  preferredDatasetsDir() = dir;
}

bool sharedDatasetsDirFromEnvironment() {
  const char* env = std::getenv("VH_SHARED_DATASETS_DIR");
  return env != nullptr && *env != '\0';
}

fs::path sharedDatasetsDir() {
  if (sharedDatasetsDirFromEnvironment()) return fs::path(std::getenv("VH_SHARED_DATASETS_DIR"));
  {
    const std::lock_guard lock(preferredDatasetsMutex());
    if (!preferredDatasetsDir().empty()) return preferredDatasetsDir();
  }
  if (const fs::path installed = installedDataDir(); !installed.empty()) return installed / "datasets";
  return fs::path(VH_DEFAULT_SHARED_DATASETS_DIR).lexically_normal();
}

std::string sharedDatasetsNote() {
  std::error_code ec;
  const fs::path dir = sharedDatasetsDir();
  const bool present = !dir.empty() && fs::is_directory(dir, ec);
  return "The shared datasets (scans and tool meshes) are looked for in " + dir.string() +
         (present ? "" : " (absent)") +
         ". They are not shipped with the program: download them from the public sources that Help > About "
         "(and datasets/manifest.json in the source) lists, into one folder keeping their paths (ct/, nrrd/, "
         "classic/, meshes/), and choose that folder with File > Data Folder in the window, or set "
         "VH_SHARED_DATASETS_DIR to it (which wins over the window's choice).";
}

fs::path generatedDataDir() {
  if (const char* env = std::getenv("VH_GENERATED_DATA_DIR"); env != nullptr && *env != '\0') {
    return fs::path(env);
  }
  if (!installedDataDir().empty()) {
    // An installed copy never writes beside itself: the user's cache (XDG base directories).
    if (const char* cache = std::getenv("XDG_CACHE_HOME"); cache != nullptr && *cache == '/') {
      return fs::path(cache) / "volume-haptics";
    }
    if (const char* home = std::getenv("HOME"); home != nullptr && *home == '/') {
      return fs::path(home) / ".cache/volume-haptics";
    }
    return {};
  }
  return fs::path(VH_DEFAULT_GENERATED_DATA_DIR).lexically_normal();
}

namespace {

/// The "volume" section (required) into `v` (which holds the defaults).
void readVolume(const ObjectReader& volume, const fs::path& base_dir, VolumeSpec& v) {
  volume.allowOnly({"path", "isovalue", "series", "phase"});
  v.path = resolveDataPath(volume, "path", volume.string("path"), base_dir);
  if (volume.has("isovalue")) {
    v.isovalue = volume.number("isovalue");
    v.isovalue_set = true;
  }
  if (volume.has("series")) v.series = volume.stringOrInteger("series");
  if (volume.has("phase")) v.phase = static_cast<int>(volume.index("phase"));
}

/// The "tool" section into `t` (which holds the defaults).
void readTool(const ObjectReader& tool, const fs::path& base_dir, ToolSpec& t) {
  tool.allowOnly({"mesh", "scale_to_m", "point_spacing_m", "point_count", "initial_pose", "edge_test"});
  if (tool.has("edge_test")) t.edge_test = tool.boolean("edge_test");
  if (tool.has("mesh")) t.mesh = resolveDataPath(tool, "mesh", tool.string("mesh"), base_dir);
  if (tool.has("scale_to_m")) t.scale_to_m = tool.positive("scale_to_m");
  if (tool.has("point_spacing_m") && tool.has("point_count")) {
    tool.fail("tool", "give point_spacing_m or point_count, not both");
  }
  if (tool.has("point_spacing_m")) t.point_spacing_m = tool.positive("point_spacing_m");
  if (tool.has("point_count")) t.point_count = tool.count("point_count");
  if (tool.has("initial_pose")) {
    const ObjectReader pose = tool.object("initial_pose");
    pose.allowOnly({"p_m", "q_wxyz"});
    if (!pose.has("p_m") && !pose.has("q_wxyz")) pose.fail(tool.fieldPath("initial_pose"), "needs p_m and/or q_wxyz");
    if (pose.has("q_wxyz")) {
      const Eigen::Vector4d q = pose.vector<4>("q_wxyz");
      if (!(q.norm() > 1e-9)) pose.fail(pose.fieldPath("q_wxyz"), "zero quaternion");
      t.X_WT_initial.R_AB = Eigen::Quaterniond(q[0], q[1], q[2], q[3]).normalized();
    }
    if (pose.has("p_m")) {
      t.X_WT_initial.p_AB_m = pose.vector<3>("p_m");
      t.initial_pose_set = true;
    } else {
      t.initial_orientation_set = true;
    }
  }
}

/// The "coupling" section into `gains` (which holds the defaults).
void readCoupling(const ObjectReader& coupling, haptics::CouplingGains& gains) {
  coupling.allowOnly({"linear_N_per_m", "angular_Nm_per_rad", "passivity_control"});
  const auto stiffness = [&](const char* key, double max, const char* unit) {
    const double k = coupling.positive(key);
    if (k > max) {
      char text[120];
      std::snprintf(text, sizeof text, "must be at most %g %s, found %g", max, unit, k);
      coupling.fail(coupling.fieldPath(key), text);
    }
    return k;
  };
  if (coupling.has("linear_N_per_m")) gains.linear_N_per_m = stiffness("linear_N_per_m", kMaxLinearStiffness_N_per_m, "N/m");
  if (coupling.has("angular_Nm_per_rad")) {
    gains.angular_Nm_per_rad = stiffness("angular_Nm_per_rad", kMaxAngularStiffness_Nm_per_rad, "N*m/rad");
  }
  if (coupling.has("passivity_control")) gains.passivity_control = coupling.boolean("passivity_control");
}

/// Throws unless `kind` is one this program can make: the built-in ones and the registered
/// drivers.
void checkDeviceKind(const ObjectReader& device, const std::string& kind, bool hardware) {
  if (hardware && !deviceKindAvailable(kind)) {
    const bool known_driver = kind == "spacemouse" || kind == "falcon";  // built-time libraries
    device.fail(device.fieldPath("kind"),
                "unknown device kind '" + kind + "'" +
                    (known_driver ? std::string(" in this program (its driver registers with "
                                                "vh::devices::registerDeviceKinds() when built with ") +
                                        (kind == "falcon" ? "libusb" : "hidapi") + ")"
                                  : std::string(" (expected \"simulated\", \"scripted\", \"spacemouse\", \"falcon\", "
                                                "\"forcedimension\" or \"openhaptics\")")));
  }
}

/// The hardware device's "workspace" section into `w`.
void readWorkspace(const ObjectReader& ws, WorkspaceSpec& w) {
  ws.allowOnly({"scale", "offset_m", "q_wxyz"});
  if (ws.has("scale")) w.scale = ws.positive("scale");
  if (ws.has("offset_m")) w.offset_W_m = ws.vector<3>("offset_m");
  if (ws.has("q_wxyz")) {
    const Eigen::Vector4d q = ws.vector<4>("q_wxyz");
    if (!(q.norm() > 1e-9)) ws.fail(ws.fieldPath("q_wxyz"), "zero quaternion");
    w.R_WB = Eigen::Quaterniond(q[0], q[1], q[2], q[3]).normalized();
  }
}

/// The "device" section.
DeviceSpec readDevice(const ObjectReader& device, const fs::path& base_dir) {
  device.allowOnly({"kind", "trajectory", "firmware", "select", "workspace"});
  DeviceSpec d;
  if (device.has("kind")) d.kind = device.string("kind");
  const bool hardware = d.kind != "simulated" && d.kind != "scripted";
  checkDeviceKind(device, d.kind, hardware);
  if (d.kind == "scripted") {
    if (!device.has("trajectory")) device.fail(device.fieldPath("trajectory"), "missing (needed by kind \"scripted\")");
    d.trajectory = resolveDataPath(device, "trajectory", device.string("trajectory"), base_dir);
  } else if (device.has("trajectory")) {
    device.fail(device.fieldPath("trajectory"), "only for kind \"scripted\"");
  }
  if (device.has("firmware")) {
    if (d.kind != "falcon") device.fail(device.fieldPath("firmware"), "only for kind \"falcon\"");
    d.firmware = resolveDataPath(device, "firmware", device.string("firmware"), base_dir);
  }
  if (device.has("select")) {
    if (!hardware) device.fail(device.fieldPath("select"), "only for hardware kinds (e.g. \"spacemouse\", \"falcon\")");
    d.select = device.string("select");
  }
  if (device.has("workspace")) {
    if (!hardware) device.fail(device.fieldPath("workspace"), "only for hardware kinds (e.g. \"spacemouse\", \"falcon\")");
    readWorkspace(device.object("workspace"), d.workspace);
  }
  return d;
}

/// Thresholds in mm (warn_mm, alarm_mm; each absent: `defaults`) of one object, checked.
ProximityThresholds readThresholds(const ObjectReader& o, const ProximityThresholds& defaults, const std::string& what) {
  ProximityThresholds t = defaults;
  if (o.has("warn_mm")) t.warn_m = 1e-3 * o.positive("warn_mm");
  if (o.has("alarm_mm")) t.alarm_m = 1e-3 * o.positive("alarm_mm");
  // A warning distance alone below the inherited alarm distance pulls the alarm down with it.
  if (o.has("warn_mm") && !o.has("alarm_mm")) t.alarm_m = std::min(t.alarm_m, t.warn_m);
  try {
    validateProximityThresholds(t, what);
  } catch (const std::invalid_argument& e) {
    o.fail("", e.what());
  }
  return t;
}

/// The "segmentation" section's "proximity": default thresholds and per segment ones.
ProximitySpec readProximity(const ObjectReader& p) {
  p.allowOnly({"warn_mm", "alarm_mm", "per_segment"});
  ProximitySpec spec;
  spec.defaults = readThresholds(p, ProximityThresholds{}, "segmentation.proximity");
  if (p.has("per_segment")) {
    const ObjectReader per = p.object("per_segment");
    for (const std::string& name : per.keys()) {
      const ObjectReader one = per.object(name.c_str());
      one.allowOnly({"warn_mm", "alarm_mm"});
      spec.per_segment[name] = readThresholds(one, spec.defaults, "segmentation.proximity.per_segment." + name);
    }
  }
  return spec;
}

/// The "segmentation" section.
SegmentationSpec readSegmentation(const ObjectReader& seg, const fs::path& base_dir) {
  seg.allowOnly({"path", "felt", "shown", "critical", "smoothing_voxels", "proximity"});
  SegmentationSpec s;
  s.path = resolveDataPath(seg, "path", seg.string("path"), base_dir);
  s.felt = seg.strings("felt");
  if (seg.has("shown")) s.shown = seg.strings("shown");
  s.critical = seg.strings("critical");
  if (seg.has("smoothing_voxels")) {
    s.smoothing_voxels = seg.number("smoothing_voxels");
    if (!(s.smoothing_voxels >= 0.0 && s.smoothing_voxels <= 10.0)) {
      seg.fail(seg.fieldPath("smoothing_voxels"), "expected a number of voxels in [0, 10]");
    }
  }
  if (seg.has("proximity")) s.proximity = readProximity(seg.object("proximity"));
  return s;
}

/// The "openigtlink" section.
OpenIgtlinkSpec readOpenIgtlink(const ObjectReader& igtl) {
  igtl.allowOnly({"port", "rate_Hz"});
  OpenIgtlinkSpec o;
  if (igtl.has("port")) {
    const json& v = igtl.at("port");
    if (!v.is_number_integer() || v.get<long long>() < 1 || v.get<long long>() > 65535) {
      igtl.fail(igtl.fieldPath("port"), "expected an integer port in 1..65535, found " + v.dump());
    }
    o.port = static_cast<int>(v.get<long long>());
  }
  if (igtl.has("rate_Hz")) o.rate_Hz = igtl.positive("rate_Hz");
  return o;
}

/// The "drill" section.
DrillSpec readDrill(const ObjectReader& drill) {
  drill.allowOnly({"on", "burr_radius_m", "burr_center_T_m", "burr_speed_rpm", "hardness"});
  DrillSpec d;
  if (drill.has("on")) d.on = drill.boolean("on");
  if (drill.has("burr_radius_m")) {
    d.burr_radius_m = drill.number("burr_radius_m");
    if (!(d.burr_radius_m >= 0.001 && d.burr_radius_m <= 0.006))
      drill.fail(drill.fieldPath("burr_radius_m"), "expected 0.001 to 0.006 (1 to 6 mm), found " + json(d.burr_radius_m).dump());
  }
  if (drill.has("burr_center_T_m")) {
    const json& v = drill.at("burr_center_T_m");
    if (!v.is_array() || v.size() != 3 || !v[0].is_number() || !v[1].is_number() || !v[2].is_number())
      drill.fail(drill.fieldPath("burr_center_T_m"), "expected [x, y, z] in metres, found " + v.dump());
    d.burr_center_T_m = Eigen::Vector3d(v[0].get<double>(), v[1].get<double>(), v[2].get<double>());
  }
  if (drill.has("burr_speed_rpm")) d.burr_speed_rpm = drill.positive("burr_speed_rpm");
  if (drill.has("hardness")) {
    const ObjectReader h(drill.at("hardness"), drill.fieldPath("hardness"), "");
    for (auto it = drill.at("hardness").begin(); it != drill.at("hardness").end(); ++it) {
      if (!it.value().is_number() || !(it.value().get<double>() > 0.0))
        drill.fail(drill.fieldPath("hardness") + "." + it.key(), "expected a specific energy > 0 [J/mm^3], found " + it.value().dump());
      d.hardness_J_per_mm3[it.key()] = it.value().get<double>();
    }
  }
  return d;
}

/// The "tissue" section (tissue_scene.h): value bands and segments with their materials.
TissueSpec readTissue(const ObjectReader& t) {
  t.allowOnly({"bands", "segments", "rigid_above", "cell_size_m", "touchable_layers"});
  TissueSpec spec;
  // A preset's name; an unknown one refused with the presets' list (tissue::materialPreset()).
  const auto material = [](const ObjectReader& entry) {
    const std::string name = entry.string("material");
    try {
      (void)tissue::materialPreset(name);
    } catch (const std::invalid_argument& e) {
      entry.fail(entry.fieldPath("material"), e.what());
    }
    return name;
  };
  const auto list = [&t](const char* key, const char* shape) -> const json& {
    const json& entries = t.at(key);
    if (!entries.is_array() || entries.empty())
      t.fail(t.fieldPath(key), std::string("expected a list of ") + shape + ", found " + entries.dump());
    return entries;
  };
  if (!t.has("bands") && !t.has("segments"))
    t.fail(t.fieldPath("bands"), "expected \"bands\" (value bands) or \"segments\" (segments of the scene's segmentation)");
  if (t.has("bands")) {
    const json& bands = list("bands", "{\"min\", \"max\", \"material\"}");
    for (std::size_t b = 0; b < bands.size(); ++b) {
      const ObjectReader band(bands[b], t.fieldPath("bands") + "[" + std::to_string(b) + "]", t.source());
      band.allowOnly({"min", "max", "material"});
      TissueBand out;
      out.min = band.number("min");
      out.max = band.number("max");
      if (!(out.max > out.min)) band.fail(band.fieldPath("max"), "must exceed min");
      out.material = material(band);
      spec.bands.push_back(out);
    }
  }
  if (t.has("segments")) {
    const json& segments = list("segments", "{\"segment\", \"material\"}");
    for (std::size_t s = 0; s < segments.size(); ++s) {
      const ObjectReader entry(segments[s], t.fieldPath("segments") + "[" + std::to_string(s) + "]", t.source());
      entry.allowOnly({"segment", "material"});
      TissueSegment out;
      out.segment = entry.string("segment");
      out.material = material(entry);
      spec.segments.push_back(out);
    }
  }
  if (t.has("rigid_above")) spec.rigid_above = t.number("rigid_above");
  if (t.has("cell_size_m")) {
    spec.cell_size_m = t.number("cell_size_m");
    if (!(spec.cell_size_m >= 0.0005 && spec.cell_size_m <= 0.02))
      t.fail(t.fieldPath("cell_size_m"), "expected 0.0005 to 0.02 (0.5 to 20 mm), found " + json(spec.cell_size_m).dump());
  }
  if (t.has("touchable_layers")) {
    const std::size_t layers = t.count("touchable_layers");
    if (layers > 4) t.fail(t.fieldPath("touchable_layers"), "expected 1 to 4, found " + std::to_string(layers));
    spec.touchable_layers = static_cast<int>(layers);
  }
  return spec;
}

/// The "technique" section (technique.h): the rules' levels and times.
TechniqueRules readTechnique(const ObjectReader& t) {
  t.allowOnly({"on", "safe_force_N", "safe_force_by_material_N", "force_hold_s", "near_critical_m",
               "max_speed_near_critical_m_per_s", "shaft_margin_m", "shaft_hold_s", "clear_s"});
  TechniqueRules r;
  if (t.has("on")) r.on = t.boolean("on");
  if (t.has("safe_force_by_material_N")) {
    const json& levels = t.at("safe_force_by_material_N");
    if (!levels.is_object()) t.fail(t.fieldPath("safe_force_by_material_N"), "expected an object of name: force [N]");
    for (auto it = levels.begin(); it != levels.end(); ++it) {
      if (!it.value().is_number())
        t.fail(t.fieldPath("safe_force_by_material_N") + "." + it.key(), "expected a force > 0 [N], found " + it.value().dump());
      r.safe_force_by_material_N[it.key()] = it.value().get<double>();
    }
  }
  for (const auto& [key, value] : {std::pair<const char*, double*>{"safe_force_N", &r.safe_force_N},
                                   {"force_hold_s", &r.force_hold_s},
                                   {"near_critical_m", &r.near_critical_m},
                                   {"max_speed_near_critical_m_per_s", &r.max_speed_near_critical_m_per_s},
                                   {"shaft_margin_m", &r.shaft_margin_m},
                                   {"shaft_hold_s", &r.shaft_hold_s},
                                   {"clear_s", &r.clear_s}}) {
    if (t.has(key)) *value = t.number(key);
  }
  // The rules' own bounds (one place: TechniqueRules::validate()), named by field.
  try {
    r.validate();
  } catch (const std::invalid_argument& e) {
    t.fail("", e.what());
  }
  return r;
}

}  // namespace

SceneSpec parseScene(const std::string& json_text, const std::string& source, const fs::path& base_dir) {
  json root;
  try {
    root = json::parse(json_text, nullptr, /*allow_exceptions=*/true, /*ignore_comments=*/true);
  } catch (const json::exception& e) {  // parse_error, and out_of_range for a number that overflows
    // e.what() is "[json.exception.parse_error.101] parse error at line 3, column 5: ...".
    std::string what = e.what();
    const auto pos = what.find("] ");
    throw std::runtime_error(source + ": invalid JSON: " + (pos == std::string::npos ? what : what.substr(pos + 2)));
  }
  const ObjectReader top(root, "", source);
  top.allowOnly({"description", "volume", "tool", "coupling", "device", "segmentation", "openigtlink", "drill",
                 "technique", "tissue"});

  SceneSpec spec;
  spec.source = source;
  readVolume(top.object("volume"), base_dir, spec.volume);
  if (top.has("tool")) readTool(top.object("tool"), base_dir, spec.tool);
  if (top.has("coupling")) readCoupling(top.object("coupling"), spec.gains);
  if (top.has("device")) spec.device = readDevice(top.object("device"), base_dir);
  if (top.has("segmentation")) spec.segmentation = readSegmentation(top.object("segmentation"), base_dir);
  if (top.has("openigtlink")) spec.openigtlink = readOpenIgtlink(top.object("openigtlink"));
  if (top.has("drill")) spec.drill = readDrill(top.object("drill"));
  if (top.has("technique")) spec.technique = readTechnique(top.object("technique"));
  if (top.has("tissue")) {
    spec.tissue = readTissue(top.object("tissue"));
    if (spec.drill) top.fail("tissue", "not with \"drill\": cutting soft tissue is not supported yet");
    if (spec.segmentation && !spec.segmentation->felt.empty())
      top.fail("tissue", "not with felt segments: the tissue's surface is the scan's isosurface");
    if (!spec.tissue->segments.empty() && !spec.segmentation)
      top.fail("tissue", "its \"segments\" need the scene's \"segmentation\" (the file they are read from)");
  }
  return spec;
}

SceneSpec loadSceneFile(const fs::path& path) {
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) throw std::runtime_error(path.string() + ": scene file not found");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error(path.string() + ": cannot open the scene file");
  std::ostringstream text;
  text << in.rdbuf();
  SceneSpec spec = parseScene(text.str(), path.string(), fs::absolute(path, ec).parent_path());
  spec.source = fs::absolute(path, ec);
  return spec;
}

SceneSpec builtinBlockWithHoleScene() {
  SceneSpec spec;
  spec.volume.path = "builtin:block-with-hole";
  spec.volume.isovalue = datasets::kBlockIsovalue;
  spec.volume.isovalue_set = true;
  spec.tool.mesh = "builtin:peg";
  // Sampled finely enough for its rims (felt within 1 mm of the mesh, haptics::kShellGapWarning_m;
  // the automatic spacing, 1.5 mm for ~1000 points, leaves 1.35 mm and would open the program's
  // own scene with a warning about its own tool).
  spec.tool.point_spacing_m = 0.0009;
  // The peg (tip at the origin of T, shaft along +z) 5 mm over the hole in the block's top face.
  spec.tool.X_WT_initial = haptics::Pose::FromTranslation({0.0, 0.0, datasets::kBlockHalfHeight_m + 0.005});
  spec.tool.initial_pose_set = true;
  spec.device = DeviceSpec{};
  return spec;
}

SceneSpec sceneForVolume(const fs::path& volume_path) {
  SceneSpec spec;
  std::error_code ec;
  spec.volume.path = fs::absolute(volume_path, ec).lexically_normal().string();
  spec.tool.mesh = "builtin:probe";
  spec.device = DeviceSpec{};
  return spec;
}

SceneSpec sceneForLoadedVolume(const io::LoadedVolume& volume) {
  SceneSpec spec;
  spec.volume.path = std::string(kIgtlVolumePrefix) + volume.info.description;
  spec.tool.mesh = "builtin:probe";
  spec.device = DeviceSpec{};
  return spec;
}

}  // namespace vh::runtime
