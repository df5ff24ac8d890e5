// Session metadata for recordings: scene, dataset identity and SHA-256, tool, device, software.
// The layout and checksum rules are documented in vh/runtime/session_metadata.h.
#include "vh/runtime/session_metadata.h"

#include <algorithm>
#include <array>
#include <cctype>
#include <cstdint>
#include <ctime>
#include <fstream>
#include <map>
#include <mutex>
#include <stdexcept>

#include <nlohmann/json.hpp>

#include "vh/runtime/recording.h"
#include "vh/runtime/sha256.h"

#ifndef VH_SOFTWARE_VERSION
#define VH_SOFTWARE_VERSION "unknown"
#endif

namespace vh::runtime {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

std::string lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

std::string trim(const std::string& s) {
  const auto b = s.find_first_not_of(" \t\r\n");
  if (b == std::string::npos) return {};
  const auto e = s.find_last_not_of(" \t\r\n");
  return s.substr(b, e - b + 1);
}

/// The data files a detached header (.nhdr "data file:" / .mhd "ElementDataFile =") names,
/// relative to the header's folder, in order; empty when the data is attached (or LOCAL).
std::vector<std::string> detachedDataFiles(const fs::path& header, bool nrrd) {
  std::ifstream in(header);
  if (!in) throw std::runtime_error("dataset checksum: cannot read " + header.string());
  std::vector<std::string> files;
  std::string line;
  bool list = false;
  while (std::getline(in, line)) {
    if (list) {
      const std::string name = trim(line);
      if (!name.empty()) files.push_back(name);
      continue;
    }
    if (nrrd && trim(line).empty()) break;  // end of the NRRD header
    const std::string::size_type sep = line.find(nrrd ? ':' : '=');
    if (sep == std::string::npos) continue;
    const std::string key = lower(trim(line.substr(0, sep)));
    const std::string value = trim(line.substr(sep + 1));
    const bool is_data_key = nrrd ? (key == "data file" || key == "datafile") : (key == "elementdatafile");
    if (!is_data_key) continue;
    if (lower(value) == "local") break;
    if (lower(value.substr(0, 4)) == "list") {
      list = true;
      continue;
    }
    if (value.find('%') != std::string::npos || (!nrrd && value.find(' ') != std::string::npos)) {
      throw std::runtime_error("dataset checksum: " + header.string() +
                               ": data file patterns are not supported (\"" + value + "\")");
    }
    files.push_back(value);
    if (!nrrd) break;  // ElementDataFile is the header's last line
  }
  return files;
}

/// Cache key: path, total size and newest modification time of what the checksum covers.
struct CacheEntry {
  std::uintmax_t bytes = 0;
  fs::file_time_type newest = fs::file_time_type::min();
  DatasetChecksum checksum;
};

std::mutex g_cache_mutex;
std::map<std::string, CacheEntry>& cache() {
  static std::map<std::string, CacheEntry> entries;
  return entries;
}

std::string hashFileOrThrow(const fs::path& file) {
  if (!fs::is_regular_file(file)) throw std::runtime_error("dataset checksum: missing file " + file.string());
  std::string digest = sha256File(file);
  if (digest.empty()) throw std::runtime_error("dataset checksum: cannot read " + file.string());
  return digest;
}

DatasetChecksum computeChecksum(const fs::path& path, const std::vector<std::string>& files, const std::string& kind) {
  DatasetChecksum c;
  c.kind = kind;
  c.files = files;
  if (kind == "file") {
    c.sha256 = hashFileOrThrow(path);
    return c;
  }
  const fs::path base = fs::is_directory(path) ? path : path.parent_path();
  Sha256 listing;
  for (const std::string& f : files) listing.update(hashFileOrThrow(base / f) + "  " + f + "\n");
  c.sha256 = listing.hexDigest();
  return c;
}

json poseJson(const haptics::Pose& X) {
  const Eigen::Quaterniond& q = X.R_AB;
  return {{"p_m", {X.p_AB_m.x(), X.p_AB_m.y(), X.p_AB_m.z()}}, {"q_wxyz", {q.w(), q.x(), q.y(), q.z()}}};
}

}  // namespace

DatasetChecksum datasetChecksum(const std::string& volume_path) {
  if (isBuiltinPath(volume_path)) {
    Sha256 sha;
    sha.update(volume_path);
    return {"builtin", sha.hexDigest(), {}};
  }
  const fs::path path(volume_path);
  if (!fs::exists(path)) throw std::runtime_error("dataset missing: " + volume_path);
  // What the checksum covers, with the cache key (sizes and times), before reading any byte.
  std::string kind;
  std::vector<std::string> files;
  if (fs::is_directory(path)) {
    kind = "dicom-folder";
    for (const auto& e : fs::recursive_directory_iterator(path))
      if (e.is_regular_file()) files.push_back(fs::relative(e.path(), path).generic_string());
    std::sort(files.begin(), files.end());
  } else {
    const std::string ext = lower(path.extension().string());
    if (ext == ".nhdr" || ext == ".mhd") {
      kind = ext == ".nhdr" ? "nrrd" : "metaimage";
      files.push_back(path.filename().string());
      for (const std::string& f : detachedDataFiles(path, ext == ".nhdr")) files.push_back(f);
    } else if (ext == ".hdr") {
      // A NIfTI (or Analyze) pair: the header and its voxel file beside it.
      kind = "nifti";
      files.push_back(path.filename().string());
      for (const char* img : {".img", ".img.gz"}) {
        const fs::path data = fs::path(path).replace_extension(img);
        if (fs::exists(data)) {
          files.push_back(data.filename().string());
          break;
        }
      }
    } else {
      kind = ext == ".nrrd" ? "nrrd" : ext == ".mha" ? "metaimage" : "file";
      files.push_back(path.filename().string());
    }
  }
  CacheEntry key;
  const fs::path base = fs::is_directory(path) ? path : path.parent_path();
  for (const std::string& f : files) {
    std::error_code ec;
    key.bytes += fs::file_size(base / f, ec);
    const fs::file_time_type t = fs::last_write_time(base / f, ec);
    if (!ec) key.newest = std::max(key.newest, t);
  }
  const std::string cache_key = fs::absolute(path).lexically_normal().string();
  {
    const std::lock_guard<std::mutex> lock(g_cache_mutex);
    const auto it = cache().find(cache_key);
    if (it != cache().end() && it->second.bytes == key.bytes && it->second.newest == key.newest &&
        it->second.checksum.files == files)
      return it->second.checksum;
  }
  // "file" kind hashes the bytes themselves (sha256sum); the others a listing of files.
  key.checksum = computeChecksum(path, files, (kind == "nrrd" || kind == "metaimage") && files.size() == 1 ? "file" : kind);
  key.checksum.kind = kind;
  const std::lock_guard<std::mutex> lock(g_cache_mutex);
  cache()[cache_key] = key;
  return key.checksum;
}

namespace {

/// A drilled cavity as {"dims", "origin_W_m", "spacing_m", "direction_W" (row by row), "runs":
/// [first, count, first, count, ...]}: runs of consecutive linear indices, ascending (a cavity's
/// voxels lie in rows along x, so a run holds several).
json cavityJson(const DrilledCavity& cavity) {
  const haptics::VolumeGeometry& g = cavity.grid;
  json j;
  j["dims"] = g.dims;
  j["origin_W_m"] = {g.origin_W_m.x(), g.origin_W_m.y(), g.origin_W_m.z()};
  j["spacing_m"] = {g.spacing_m.x(), g.spacing_m.y(), g.spacing_m.z()};
  json direction = json::array();
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) direction.push_back(g.direction_W(r, c));
  j["direction_W"] = direction;
  json runs = json::array();
  for (std::size_t i = 0; i < cavity.voxels.size();) {
    std::size_t n = 1;
    while (i + n < cavity.voxels.size() && cavity.voxels[i + n] == cavity.voxels[i] + n) ++n;
    runs.push_back(cavity.voxels[i]);
    runs.push_back(n);
    i += n;
  }
  j["runs"] = runs;
  return j;
}

/// @throws std::runtime_error for runs that are not ascending, or that leave the grid.
DrilledCavity cavityFromJson(const json& j) {
  DrilledCavity cavity;
  haptics::VolumeGeometry& g = cavity.grid;
  g.dims = j.at("dims").get<std::array<int, 3>>();
  const auto vector3 = [&j](const char* key) {
    const auto v = j.at(key).get<std::vector<double>>();
    if (v.size() != 3) throw std::runtime_error(std::string("scene.drill.cavity.") + key + ": expected 3 numbers");
    return Eigen::Vector3d(v[0], v[1], v[2]);
  };
  g.origin_W_m = vector3("origin_W_m");
  g.spacing_m = vector3("spacing_m");
  const auto direction = j.at("direction_W").get<std::vector<double>>();
  if (direction.size() != 9) throw std::runtime_error("scene.drill.cavity.direction_W: expected 9 numbers");
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) g.direction_W(r, c) = direction[static_cast<std::size_t>(3 * r + c)];
  const auto runs = j.at("runs").get<std::vector<std::uint64_t>>();
  if (runs.size() % 2 != 0) throw std::runtime_error("scene.drill.cavity.runs: expected pairs of first, count");
  const std::uint64_t voxels = g.voxelCount();
  for (std::size_t r = 0; r < runs.size(); r += 2) {
    const std::uint64_t first = runs[r], count = runs[r + 1];
    if ((!cavity.voxels.empty() && first <= cavity.voxels.back()) || count == 0 || first >= voxels ||
        count > voxels - first)
      throw std::runtime_error("scene.drill.cavity.runs: run " + std::to_string(r / 2) +
                               " is not ascending or leaves the grid of " + std::to_string(voxels) + " voxels");
    for (std::uint64_t i = 0; i < count; ++i) cavity.voxels.push_back(first + i);
  }
  return cavity;
}

/// The session's segmentation: the file, the felt, shown and critical choices by name (what a
/// scene file says), and every segment as loaded (the recording names the touched segment by its
/// index into "segments").
json segmentationJson(const SegmentSet& set, const SegmentationSpec& segmentation) {
  const auto names = [&set](const std::vector<int>& indices) {
    std::vector<std::string> out;
    for (const int s : indices) out.push_back(set.name(s));
    return out;
  };
  json seg;
  seg["path"] = segmentation.path;
  seg["felt"] = names(set.felt());
  seg["shown"] = names(set.shown());
  seg["critical"] = names(set.critical());
  seg["smoothing_voxels"] = set.smoothingVoxels();
  seg["segments"] = json::array();
  for (int s = 0; s < static_cast<int>(set.size()); ++s) {
    const io::SegmentInfo& segment = set.segment(s);
    seg["segments"].push_back({{"name", segment.name},
                               {"id", segment.id},
                               {"label_value", segment.label_value},
                               {"layer", segment.layer},
                               {"color_rgb", segment.color_rgb},
                               {"felt", set.isFelt(s)},
                               {"critical", set.isCritical(s)}});
    if (set.isCritical(s)) {  // its warning and alarm distances (critical_proximity.h)
      seg["segments"].back()["warn_mm"] = 1e3 * set.thresholds(s).warn_m;
      seg["segments"].back()["alarm_mm"] = 1e3 * set.thresholds(s).alarm_m;
    }
  }
  return seg;
}

/// The session's drill: what a replay needs to cut as the session did.
/// The technique rules the session ran with (the scene file's "technique" section, technique.h).
json techniqueJson(const TechniqueRules& r) {
  return {{"on", r.on},
          {"safe_force_N", r.safe_force_N},
          {"safe_force_by_material_N", r.safe_force_by_material_N},
          {"force_hold_s", r.force_hold_s},
          {"near_critical_m", r.near_critical_m},
          {"max_speed_near_critical_m_per_s", r.max_speed_near_critical_m_per_s},
          {"shaft_margin_m", r.shaft_margin_m},
          {"shaft_hold_s", r.shaft_hold_s},
          {"clear_s", r.clear_s}};
}

/// The rules of techniqueJson(); absent keys (metadata written before them) keep the defaults.
TechniqueRules techniqueFromJson(const json& t) {
  TechniqueRules r;
  r.on = t.value("on", r.on);
  r.safe_force_N = t.value("safe_force_N", r.safe_force_N);
  if (t.contains("safe_force_by_material_N"))
    r.safe_force_by_material_N = t.at("safe_force_by_material_N").get<std::map<std::string, double>>();
  r.force_hold_s = t.value("force_hold_s", r.force_hold_s);
  r.near_critical_m = t.value("near_critical_m", r.near_critical_m);
  r.max_speed_near_critical_m_per_s = t.value("max_speed_near_critical_m_per_s", r.max_speed_near_critical_m_per_s);
  r.shaft_margin_m = t.value("shaft_margin_m", r.shaft_margin_m);
  r.shaft_hold_s = t.value("shaft_hold_s", r.shaft_hold_s);
  r.clear_s = t.value("clear_s", r.clear_s);
  return r;
}

/// The recorded "segmentation" (segmentationJson()).
SegmentationSpec segmentationFromJson(const json& seg) {
  SegmentationSpec s;
  s.path = seg.at("path").get<std::string>();
  s.felt = seg.at("felt").get<std::vector<std::string>>();
  s.shown = seg.at("shown").get<std::vector<std::string>>();
  s.critical = seg.at("critical").get<std::vector<std::string>>();
  s.smoothing_voxels = seg.at("smoothing_voxels").get<double>();
  // Each critical segment's thresholds (absent in metadata written before them: defaults).
  for (const json& one : seg.value("segments", json::array())) {
    if (!one.value("critical", false) || !one.contains("warn_mm")) continue;
    s.proximity.per_segment[one.at("name").get<std::string>()] = {1e-3 * one.at("warn_mm").get<double>(),
                                                                   1e-3 * one.at("alarm_mm").get<double>()};
  }
  return s;
}

/// The recorded "drill" (drillJson()).
DrillSpec drillFromJson(const json& d) {
  DrillSpec drill;
  drill.on = d.value("on", false);
  drill.burr_radius_m = d.value("burr_radius_m", 0.0);
  if (d.contains("burr_center_T_m")) {
    const auto c = d.at("burr_center_T_m").get<std::vector<double>>();
    if (c.size() != 3) throw std::runtime_error("scene.drill.burr_center_T_m: expected [x, y, z]");
    drill.burr_center_T_m = Eigen::Vector3d(c[0], c[1], c[2]);
  }
  drill.burr_speed_rpm = d.value("burr_speed_rpm", drill.burr_speed_rpm);
  if (d.contains("hardness")) drill.hardness_J_per_mm3 = d.at("hardness").get<std::map<std::string, double>>();
  if (d.contains("cavity")) drill.cavity = std::make_shared<const DrilledCavity>(cavityFromJson(d.at("cavity")));
  return drill;
}

json drillJson(const DrillSpec& spec) {
  json drill;
  drill["on"] = spec.on;
  if (spec.burr_radius_m > 0.0) drill["burr_radius_m"] = spec.burr_radius_m;
  if (spec.burr_center_T_m) {
    const Eigen::Vector3d& c = *spec.burr_center_T_m;
    drill["burr_center_T_m"] = {c.x(), c.y(), c.z()};
  }
  drill["burr_speed_rpm"] = spec.burr_speed_rpm;
  drill["hardness"] = spec.hardness_J_per_mm3;
  if (spec.cavity != nullptr && !spec.cavity->voxels.empty())
    drill["cavity"] = cavityJson(*spec.cavity);
  return drill;
}

/// The soft tissue (tissue_scene.h), as the scene file gives it: what a replay needs to deform it
/// as the session did.
json tissueJson(const TissueSpec& spec) {
  json t;
  t["bands"] = json::array();
  for (const TissueBand& b : spec.bands) t["bands"].push_back({{"min", b.min}, {"max", b.max}, {"material", b.material}});
  if (spec.rigid_above) t["rigid_above"] = *spec.rigid_above;
  t["cell_size_m"] = spec.cell_size_m;
  t["touchable_layers"] = spec.touchable_layers;
  return t;
}

/// The recorded "tissue" (tissueJson()).
TissueSpec tissueFromJson(const json& t) {
  TissueSpec spec;
  for (const json& b : t.at("bands")) spec.bands.push_back({b.at("min").get<double>(), b.at("max").get<double>(), b.at("material").get<std::string>()});
  if (t.contains("rigid_above")) spec.rigid_above = t.at("rigid_above").get<double>();
  spec.cell_size_m = t.value("cell_size_m", spec.cell_size_m);
  spec.touchable_layers = t.value("touchable_layers", spec.touchable_layers);
  return spec;
}

/// The scene as the session ran it: the volume as loaded, the tool, the coupling, the
/// segmentation, the drill and the tissue.
json sceneJson(const LoadedScene& scene, const LiveValues& live) {
  const SceneSpec& spec = scene.spec;
  json sc;
  sc["source"] = spec.source.string();
  sc["volume"] = {{"path", spec.volume.path}, {"isovalue", live.isovalue}};
  // The series as loaded, by its UID (the folder may hold others), and the time point.
  const std::string series = scene.volume.info.series_uid.empty() ? spec.volume.series : scene.volume.info.series_uid;
  if (!series.empty()) sc["volume"]["series"] = series;
  if (scene.volume.info.phase_count > 1 || spec.volume.phase != 0) sc["volume"]["phase"] = scene.volume.info.phase;
  sc["tool"] = {{"mesh", live.tool_spec.mesh},
                {"scale_to_m", live.tool_spec.scale_to_m},
                {"point_spacing_m", live.tool_spec.point_spacing_m},
                {"point_count", live.tool_spec.point_count},
                {"initial_pose", poseJson(live.X_WT_initial)}};
  // Always written: recordings made before the edge test was on by default lack the key and
  // were made without it (read as false below).
  sc["tool"]["edge_test"] = live.tool_spec.edge_test;
  sc["coupling"] = {{"linear_N_per_m", live.gains.linear_N_per_m},
                    {"angular_Nm_per_rad", live.gains.angular_Nm_per_rad},
                    {"passivity_control", live.gains.passivity_control}};
  if (live.segments != nullptr && live.segmentation) {
    sc["segmentation"] = segmentationJson(*live.segments, *live.segmentation);
  }
  if (live.drill) {  // what a replay needs to cut as the session did
    sc["drill"] = drillJson(*live.drill);
  }
  if (live.tissue) sc["tissue"] = tissueJson(*live.tissue);  // what a replay needs to deform it as the session did
  sc["technique"] = techniqueJson(live.technique);
  return sc;
}

/// The dataset: its path, checksum, grid, format and what the loader said of it.
json datasetJson(const LoadedScene& scene) {
  const SceneSpec& spec = scene.spec;
  // A volume given as an array (Python's load_scene) has no file: its voxels' SHA-256 stands in.
  DatasetChecksum checksum;
  if (spec.volume.path == kArrayVolumePath && scene.volume.field != nullptr) {
    Sha256 sha;
    sha.update(scene.volume.field->bytes().data(), scene.volume.field->bytes().size());
    checksum = {"array", sha.hexDigest(), {}};
  } else {
    checksum = datasetChecksum(spec.volume.path);
  }
  json ds;
  ds["path"] = spec.volume.path;
  ds["kind"] = checksum.kind;
  if (scene.volume.field) {
    const auto& g = scene.volume.field->geometry();
    ds["dims"] = g.dims;
    ds["spacing_m"] = {g.spacing_m.x(), g.spacing_m.y(), g.spacing_m.z()};
  }
  ds["format"] = scene.volume.info.format;
  ds["modality"] = scene.volume.info.modality;
  ds["value_unit"] = scene.volume.info.value_unit;
  ds["description"] = scene.volume.info.description;
  if (!scene.volume.info.series_uid.empty()) {
    ds["series_uid"] = scene.volume.info.series_uid;
    ds["series_number"] = scene.volume.info.series_number;
  }
  if (scene.volume.info.phase_count > 1) ds["phase"] = {scene.volume.info.phase, scene.volume.info.phase_count};
  // What the loader corrected or chose ("resampled from a gantry tilt of 18.5 deg", gaps...).
  ds["notices"] = scene.volume.info.notices;
  ds["sha256"] = checksum.sha256;
  ds["checksum_files"] = checksum.files;
  return ds;
}

}  // namespace

std::string makeSessionMetadata(const LoadedScene& scene, const LiveValues& live, const SessionInfo& info) {
  json j;
  j["format"] = "volume-haptics session";
  j["software"] = {{"name", "volume-haptics"}, {"version", VH_SOFTWARE_VERSION}};
  j["start_time_utc"] = utcNow();
  j["servo_rate_Hz"] = 1000.0;

  j["scene"] = sceneJson(scene, live);
  j["dataset"] = datasetJson(scene);
  if (live.drill && live.hapticField() != nullptr) {
    // The unit of every record's removed_voxels and of the cavity (session_metrics.h).
    const Eigen::Vector3d& h = live.hapticField()->geometry().spacing_m;
    j["drilling"] = {{"felt_voxel_volume_mm3", 1e9 * h.x() * h.y() * h.z()}};
  }

  json tool;
  tool["mesh"] = live.tool_spec.mesh;
  if (live.tool) {
    tool["point_count"] = live.tool->point_shell.size();
    tool["point_spacing_m"] = live.tool->point_shell.meanNearestNeighbourSpacing_m();
  }
  j["tool"] = tool;
  j["gains"] = j["scene"]["coupling"];
  j["device"] = {{"name", info.device_name}, {"kind", info.device_kind}};
  if (!info.note.empty()) j["note"] = info.note;
  return j.dump();
}

SceneSpec sceneFromSessionMetadata(const std::string& metadata_json) {
  json j;
  try {
    j = json::parse(metadata_json);
  } catch (const json::exception& e) {
    throw std::runtime_error(std::string("session metadata is not JSON: ") + e.what());
  }
  if (!j.is_object() || !j.contains("scene"))
    throw std::runtime_error("session metadata has no \"scene\" (not recorded by makeSessionMetadata())");
  SceneSpec spec;
  try {
    const json& sc = j.at("scene");
    spec.source = sc.value("source", std::string());
    spec.volume.path = sc.at("volume").at("path").get<std::string>();
    spec.volume.isovalue = sc.at("volume").at("isovalue").get<double>();
    spec.volume.isovalue_set = true;
    spec.volume.series = sc.at("volume").value("series", std::string());
    spec.volume.phase = sc.at("volume").value("phase", 0);
    const json& tool = sc.at("tool");
    spec.tool.mesh = tool.at("mesh").get<std::string>();
    spec.tool.scale_to_m = tool.at("scale_to_m").get<double>();
    spec.tool.point_spacing_m = tool.at("point_spacing_m").get<double>();
    spec.tool.point_count = tool.at("point_count").get<std::size_t>();
    spec.tool.edge_test = tool.value("edge_test", false);
    const json& pose = tool.at("initial_pose");
    const auto p = pose.at("p_m").get<std::vector<double>>();
    const auto q = pose.at("q_wxyz").get<std::vector<double>>();
    if (p.size() != 3 || q.size() != 4) throw std::runtime_error("scene.tool.initial_pose: bad p_m / q_wxyz");
    spec.tool.X_WT_initial.p_AB_m = {p[0], p[1], p[2]};
    spec.tool.X_WT_initial.R_AB = Eigen::Quaterniond(q[0], q[1], q[2], q[3]);  // as stored: bit for bit
    spec.tool.initial_pose_set = true;
    spec.gains.linear_N_per_m = sc.at("coupling").at("linear_N_per_m").get<double>();
    spec.gains.angular_Nm_per_rad = sc.at("coupling").at("angular_Nm_per_rad").get<double>();
    // Absent in metadata written before the switch existed: off.
    spec.gains.passivity_control = sc.at("coupling").value("passivity_control", false);
    if (sc.contains("segmentation")) spec.segmentation = segmentationFromJson(sc.at("segmentation"));
    if (sc.contains("drill")) spec.drill = drillFromJson(sc.at("drill"));
    if (sc.contains("tissue")) spec.tissue = tissueFromJson(sc.at("tissue"));
    if (sc.contains("technique")) spec.technique = techniqueFromJson(sc.at("technique"));
  } catch (const json::exception& e) {
    throw std::runtime_error(std::string("session metadata: bad \"scene\": ") + e.what());
  }
  // The dataset must be the recorded one.
  const std::string recorded = j.contains("dataset") ? j["dataset"].value("sha256", std::string()) : std::string();
  const std::string& volume = spec.volume.path;
  if (!isBuiltinPath(volume) && !fs::exists(volume))
    throw std::runtime_error("the recorded dataset is missing: " + volume + " (recorded SHA-256 " + recorded + ")");
  if (!isBuiltinPath(spec.tool.mesh) && !fs::exists(spec.tool.mesh))
    throw std::runtime_error("the recorded tool mesh is missing: " + spec.tool.mesh);
  if (!recorded.empty()) {
    const DatasetChecksum now = datasetChecksum(volume);
    if (now.sha256 != recorded) {
      throw std::runtime_error("the dataset " + volume + " (" + now.kind + ") differs from the recorded one: SHA-256 " +
                               now.sha256 + " now, " + recorded + " when recorded");
    }
  }
  return spec;
}

LoadedScene loadRecordedScene(const std::string& metadata_json) {
  SceneSpec spec = sceneFromSessionMetadata(metadata_json);
  spec.device.reset();
  spec.openigtlink.reset();
  return loadScene(spec);
}

}  // namespace vh::runtime
