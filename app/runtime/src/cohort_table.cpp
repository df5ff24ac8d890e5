// The cohort table (cohort_table.h).

#include "vh/runtime/cohort_table.h"

#include <algorithm>
#include <exception>
#include <map>
#include <memory>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "vh/io/private_files.h"
#include "vh/runtime/anonymize.h"
#include "vh/runtime/drill_report.h"
#include "vh/runtime/recording.h"
#include "vh/runtime/session_metadata.h"

namespace vh::runtime {
namespace {

/// RFC 4180 field: quoted when it holds a comma, quote or line break; inner quotes doubled.
std::string csvField(const std::string& s) {
  if (s.find_first_of(",\"\r\n") == std::string::npos) return s;
  std::string out = "\"";
  for (char c : s) {
    if (c == '"') out += '"';
    out += c;
  }
  return out + '"';
}

std::string joined(const std::vector<std::string>& parts, const char* separator) {
  std::string out;
  for (const std::string& p : parts) out += (out.empty() ? "" : separator) + p;
  return out;
}

std::string number(double v) {
  std::ostringstream s;
  s.precision(9);
  s << v;
  return s.str();
}

/// The scene a recording was made on (loadRecordedScene()), kept for the next recordings of the
/// same scene (a cohort's sessions are mostly on one scan).
class RecordedScenes {
 public:
  /// `metadata` is the recording's metadata_json, parsed (its scene and dataset are the key).
  /// @throws std::runtime_error as loadRecordedScene().
  const LoadedScene& of(const Recording& recording, const nlohmann::json& metadata) {
    std::string key;
    if (metadata.is_object() && metadata.contains("scene"))
      key = metadata["scene"].dump() + (metadata.contains("dataset") ? metadata["dataset"].dump() : std::string());
    if (!scene_ || key.empty() || key != key_) {
      scene_.reset();
      key_.clear();
      scene_ = std::make_unique<LoadedScene>(loadRecordedScene(recording.metadata_json));
      key_ = key;
    }
    return *scene_;
  }

 private:
  std::unique_ptr<LoadedScene> scene_;
  std::string key_;
};

/// One row, written once every row's materials are known.
struct Row {
  std::string cells;  ///< From the file column to the last metric, without a trailing comma.
  bool read = false;
  std::vector<std::string> notices;
  std::optional<DrillReport> drilled;  ///< The removal per material when known.
  bool removed_nothing = false;        ///< The burr removed nothing (each material 0).
};

}  // namespace

std::size_t writeCohortTable(const std::filesystem::path& dir, const std::filesystem::path& csv,
                             const CohortTableOptions& options,
                             const std::function<void(std::size_t, std::size_t)>& progress) {
  const std::vector<std::filesystem::path> files = findRecordings(dir);
  io::PrivateOutput file(csv);  // 0600 (labels and scene names), renamed into place when whole
  const std::vector<MetricValue> columns = metricValues(SessionMetrics{});
  std::vector<Row> rows(files.size());
  std::vector<std::string> materials;  // in the order first met
  RecordedScenes scenes;
  for (std::size_t i = 0; i < files.size(); ++i) {
    Row& row = rows[i];
    const std::string anonymous = std::string(kAnonymized) + " " + std::to_string(i + 1);
    row.cells = csvField(options.anonymize ? anonymous : std::filesystem::relative(files[i], dir).generic_string());
    try {
      Recording recording = readRecording(files[i]);
      std::optional<RecordingDrillReport> drilled;
      if (options.drilled_per_material) {
        // Recordings of format 5 on say in their records whether the burr removed anything;
        // older ones written in the window do not (no "drilled" event): those with a drill are
        // replayed.
        const nlohmann::json meta = nlohmann::json::parse(recording.metadata_json, nullptr, false);
        const bool has_drill = meta.is_object() && meta.contains("scene") && meta["scene"].is_object() &&
                               meta["scene"].contains("drill");
        if (!drilledDuring(recording) && (!has_drill || recording.version >= 5)) {
          row.removed_nothing = true;
        } else {
          try {
            drilled = drillReportOfRecording(scenes.of(recording, meta), recording);
          } catch (const std::exception& e) {
            drilled = RecordingDrillReport{std::nullopt, std::string("the scene could not be reloaded (") + e.what() + ")"};
          }
        }
      }
      std::vector<std::string> ids;
      if (options.anonymize) ids = anonymizeRecording(recording, files[i]);
      const SessionMetrics m = computeSessionMetrics(recording, options.metrics);
      const std::string label = options.anonymize && m.label.empty() ? anonymous : cohortLabel(m, files[i]);
      row.cells += ',' + csvField(m.scene) + ',' + m.dataset_sha256 + ',' + csvField(label) + ',' +
                   csvField(m.start_time_utc);
      for (const MetricValue& v : metricValues(m)) row.cells += ',' + number(v.value);
      row.read = true;
      row.notices = m.notices;
      if (drilled && drilled->report) {
        row.drilled = drilled->report;
        for (const DrillReport::Material& mat : row.drilled->materials)
          if (std::find(materials.begin(), materials.end(), mat.name) == materials.end()) materials.push_back(mat.name);
      } else if (drilled) {
        row.notices.push_back("removal per material not known: " + scrubText(drilled->why, ids));
      }
    } catch (const std::runtime_error& e) {
      row.cells += ",,,,";
      for (std::size_t c = 0; c < columns.size(); ++c) row.cells += ',';
      const std::vector<std::string> ids = options.anonymize ? pathIdentifiers(files[i]) : std::vector<std::string>{};
      row.notices = {scrubText(std::string("not read: ") + e.what(), ids)};
    }
    if (progress) progress(i + 1, files.size());
  }

  std::ostream& out = file.stream();
  out << "file,scene,dataset_sha256,label,start_time_utc";
  for (const MetricValue& v : columns) out << ',' << v.key;
  for (const std::string& name : materials) out << ',' << csvField("removed_mm3[" + name + "]");
  out << ",notices\n";
  for (const Row& row : rows) {
    out << row.cells;
    for (const std::string& name : materials) {
      out << ',';
      if (row.read && row.removed_nothing) {
        out << '0';
      } else if (row.drilled) {
        std::optional<double> mm3;  // a material may have rows of several classes: their sum
        for (const DrillReport::Material& mat : row.drilled->materials)
          if (mat.name == name) mm3 = mm3.value_or(0.0) + mat.removed_mm3;
        if (mm3) out << number(*mm3);
      }
    }
    out << ',' << csvField(joined(row.notices, "; ")) << '\n';
  }
  file.commit();
  return files.size();
}

}  // namespace vh::runtime
