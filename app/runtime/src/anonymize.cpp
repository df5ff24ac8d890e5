// `--anonymize`: patient identifiers out of a recording's metadata and warnings (see
// vh/runtime/anonymize.h for the fields and the DICOM PS3.15 Annex E actions).
#include "vh/runtime/anonymize.h"

#include <algorithm>

#include <nlohmann/json.hpp>

#include "vh/runtime/sha256.h"

namespace vh::runtime {
namespace {

using nlohmann::json;

/// `path` and each of its file and folder names.
void addPathParts(const std::string& path, std::vector<std::string>& out) {
  if (path.empty()) return;
  out.push_back(path);
  for (const auto& part : std::filesystem::path(path)) {
    const std::string name = part.string();
    if (name != "/" && name != "." && name != "..") out.push_back(name);
  }
}

bool isUid(const std::string& text) {
  return !text.empty() && text.size() <= 64 &&
         std::all_of(text.begin(), text.end(), [](char c) { return (c >= '0' && c <= '9') || c == '.'; });
}

/// Replaces the string at `object[key]` (when there is one) by "ANONYMIZED"; notes the path parts.
void replacePath(json& object, const char* key, const std::string& name, json& replaced, std::vector<std::string>& ids) {
  if (!object.is_object() || !object.contains(key) || !object[key].is_string()) return;
  addPathParts(object[key].get<std::string>(), ids);
  object[key] = kAnonymized;
  replaced.push_back(name);
}

/// Removes `object[key]` (when there is one); notes a string value.
void removeField(json& object, const char* key, const std::string& name, json& removed, std::vector<std::string>& ids) {
  if (!object.is_object() || !object.contains(key)) return;
  if (object[key].is_string()) ids.push_back(object[key].get<std::string>());
  object.erase(key);
  removed.push_back(name);
}

/// Replaces a UID (or a series chosen by another text) at `object[key]`.
void replaceUid(json& object, const char* key, const std::string& name, json& replaced, std::vector<std::string>& ids) {
  if (!object.is_object() || !object.contains(key) || !object[key].is_string()) return;
  const std::string value = object[key].get<std::string>();
  ids.push_back(value);
  object[key] = isUid(value) ? anonymizedUid(value) : std::string(kAnonymized);
  replaced.push_back(name);
}

}  // namespace

std::vector<std::string> pathIdentifiers(const std::filesystem::path& path) {
  std::vector<std::string> ids;
  if (path.empty()) return ids;
  addPathParts(path.string(), ids);
  std::error_code error;
  const std::filesystem::path absolute = std::filesystem::absolute(path, error);
  if (!error) addPathParts(absolute.string(), ids);
  return ids;
}

std::string anonymizedUid(const std::string& uid) {
  Sha256 sha;
  sha.update(uid);
  const std::string hex = sha.hexDigest().substr(0, 32);
  // The 128-bit number in base 16 digits (most significant first), divided by 10 until 0.
  std::vector<unsigned> value;
  for (const char c : hex) value.push_back(static_cast<unsigned>(c <= '9' ? c - '0' : c - 'a' + 10));
  std::string digits;
  while (std::any_of(value.begin(), value.end(), [](unsigned d) { return d != 0; })) {
    unsigned remainder = 0;
    for (unsigned& d : value) {
      const unsigned current = remainder * 16 + d;
      d = current / 10;
      remainder = current % 10;
    }
    digits.insert(digits.begin(), static_cast<char>('0' + remainder));
  }
  return "2.25." + (digits.empty() ? std::string("0") : digits);
}

std::string anonymizeSessionMetadata(const std::string& metadata_json, std::vector<std::string>* identifiers) {
  json meta = json::parse(metadata_json, nullptr, false);
  if (!meta.is_object()) meta = json::object();
  std::vector<std::string> ids;
  json removed = json::array();
  json replaced = json::array();
  removeField(meta, "start_time_utc", "start_time_utc", removed, ids);
  if (meta.contains("scene") && meta["scene"].is_object()) {
    json& scene = meta["scene"];
    replacePath(scene, "source", "scene.source", replaced, ids);
    if (scene.contains("volume")) {
      replacePath(scene["volume"], "path", "scene.volume.path", replaced, ids);
      replaceUid(scene["volume"], "series", "scene.volume.series", replaced, ids);
    }
    if (scene.contains("segmentation")) replacePath(scene["segmentation"], "path", "scene.segmentation.path", replaced, ids);
  }
  if (meta.contains("dataset") && meta["dataset"].is_object()) {
    json& dataset = meta["dataset"];
    replacePath(dataset, "path", "dataset.path", replaced, ids);
    removeField(dataset, "description", "dataset.description", removed, ids);
    replaceUid(dataset, "series_uid", "dataset.series_uid", replaced, ids);
    if (dataset.contains("checksum_files") && dataset["checksum_files"].is_array()) {
      for (const json& f : dataset["checksum_files"])
        if (f.is_string()) addPathParts(f.get<std::string>(), ids);
    }
    removeField(dataset, "checksum_files", "dataset.checksum_files", removed, ids);
    if (dataset.contains("notices") && dataset["notices"].is_array()) {
      for (json& n : dataset["notices"])
        if (n.is_string()) n = scrubText(n.get<std::string>(), ids);
    }
  }
  meta["anonymized"] = {{"profile", "DICOM PS3.15 Annex E Basic Application Level Confidentiality Profile, for the "
                                    "fields a recording keeps"},
                        {"removed", removed},
                        {"replaced", replaced}};
  if (identifiers != nullptr) identifiers->insert(identifiers->end(), ids.begin(), ids.end());
  return meta.dump();
}

std::string scrubText(std::string text, const std::vector<std::string>& identifiers) {
  std::vector<std::string> sorted = identifiers;
  std::sort(sorted.begin(), sorted.end(), [](const std::string& a, const std::string& b) { return a.size() > b.size(); });
  const std::string replacement = kAnonymized;
  for (const std::string& id : sorted) {
    if (id.size() < 3) continue;
    for (std::size_t at = text.find(id); at != std::string::npos; at = text.find(id, at + replacement.size()))
      text.replace(at, id.size(), replacement);
  }
  return text;
}

std::vector<std::string> anonymizeRecording(Recording& recording, const std::filesystem::path& recording_path) {
  std::vector<std::string> ids;
  recording.metadata_json = anonymizeSessionMetadata(recording.metadata_json, &ids);
  const std::vector<std::string> path_ids = pathIdentifiers(recording_path);
  ids.insert(ids.end(), path_ids.begin(), path_ids.end());
  for (std::string& w : recording.warnings) w = scrubText(w, ids);
  return ids;
}

void anonymizeRunReport(RunReport& report, std::vector<std::string> identifiers) {
  for (const std::string* path : {&report.scene, &report.volume, &report.trajectory}) {
    if (path->empty() || *path == "builtin" || path->rfind("builtin:", 0) == 0) continue;
    const std::vector<std::string> ids = pathIdentifiers(*path);
    identifiers.insert(identifiers.end(), ids.begin(), ids.end());
  }
  for (std::string* path : {&report.scene, &report.volume, &report.trajectory})
    if (!path->empty() && *path != "builtin" && path->rfind("builtin:", 0) != 0) *path = kAnonymized;
  for (std::string& notice : report.volume_notices) notice = scrubText(notice, identifiers);
}

}  // namespace vh::runtime
