#include "vh/ui/replay/replay_guide.h"

#include <system_error>

#include <nlohmann/json.hpp>

#include "vh/runtime/sha256.h"

namespace vh::ui {

namespace fs = std::filesystem;

ReplayGuide::ReplayGuide(const runtime::Recording& recording, const fs::path& recording_file) {
  std::string recorded_path, name;
  for (const runtime::RecordingEvent& e : recording.events) {
    if (e.type != "guidance") continue;
    const nlohmann::json d = nlohmann::json::parse(e.detail_json, nullptr, /*allow_exceptions=*/false);
    if (!d.is_object()) continue;
    Switch s;
    s.time_s = e.time_s;
    s.expert_sha256 = d.value("off", false) ? std::string() : d.value("expert_sha256", std::string());
    if (!s.expert_sha256.empty() && switches_.empty()) {
      recorded_path = d.value("expert_path", std::string());
      name = d.value("expert_file", std::string());
    }
    if (!s.expert_sha256.empty() && name.empty()) name = d.value("expert_file", std::string());
    switches_.push_back(std::move(s));
  }
  for (const Switch& s : switches_) {
    if (s.expert_sha256.empty()) continue;
    findExpert(s.expert_sha256, recorded_path, name, recording_file);
    break;
  }
}

void ReplayGuide::findExpert(const std::string& sha256, const std::string& recorded_path, const std::string& name,
                             const fs::path& recording_file) {
  std::vector<fs::path> candidates;
  if (!recorded_path.empty()) candidates.emplace_back(recorded_path);
  if (!name.empty()) candidates.push_back(recording_file.parent_path() / fs::path(name).filename());
  const std::string shown = name.empty() ? std::string("the expert's recording") : "the expert's recording " + name;
  std::string changed;
  for (const fs::path& file : candidates) {
    std::error_code ec;
    if (!fs::is_regular_file(file, ec)) continue;
    try {
      const std::string found = runtime::sha256File(file);
      if (found != sha256) {
        changed = file.string() + " has SHA-256 " + found.substr(0, 12) + ", not the recorded " + sha256.substr(0, 12);
        continue;
      }
      expert_ = std::make_shared<const runtime::ExpertPath>(runtime::readRecording(file, runtime::RecordingFiles::kVhrecOnly), found,
                                                            file.filename().string(), file.string());
      return;
    } catch (const std::exception& e) {
      changed = file.string() + ": " + e.what();
    }
  }
  notice_ = "No expert's ghost in this replay: " + shown + " (SHA-256 " + sha256.substr(0, 12) + ") is not available" +
            (changed.empty() ? std::string(" (not at its recorded path nor beside this recording)") : " (" + changed + ")");
}

bool ReplayGuide::onAt(double t_s) const noexcept {
  if (expert_ == nullptr) return false;
  const Switch* last = nullptr;
  for (const Switch& s : switches_) {
    if (s.time_s > t_s) break;
    last = &s;
  }
  return last != nullptr && last->expert_sha256 == expert_->fileSha256();
}

haptics::Pose ReplayGuide::ghostPose(const Eigen::Vector3d& p_WD_m) const noexcept {
  if (expert_ == nullptr) return {};
  return expert_->poseAt(expert_->path().nearest(p_WD_m));
}

}  // namespace vh::ui
