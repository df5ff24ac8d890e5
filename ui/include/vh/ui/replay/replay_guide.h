#pragma once
/// @file
/// The expert's ghost in a replay: a recording made with guidance holds a "guidance" event
/// (runtime/guidance.h) naming the expert's recording by its absolute path ("expert_path"), its
/// name ("expert_file") and its SHA-256 ("expert_sha256"), not its path itself. The replay shows
/// the expert's ghost when that file is found and is the same file: first at the recorded path,
/// else under its name beside the replayed recording (the two moved together), and only when
/// its SHA-256 is the one recorded. Otherwise there is no ghost and a notice says why (not
/// found, or changed since). No Qt or VTK.
///
/// The ghost of a record is the expert's pose at the nearest point of the expert's path to the
/// record's device position (ExpertPath::poseAt()), as the live guidance computed it; it is
/// shown for the records after a "guidance" event of that expert and before the next
/// "guidance" event (another expert's, or {"off": true}).

#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "vh/haptics/pose.h"
#include "vh/runtime/guidance.h"
#include "vh/runtime/recording.h"

namespace vh::ui {

class ReplayGuide {
 public:
  ReplayGuide() = default;
  /// Reads the "guidance" events of `recording` (read from `recording_file`) and looks for the
  /// expert's recording as the file comment says. Never throws: a file that cannot be read is
  /// told in notice().
  ReplayGuide(const runtime::Recording& recording, const std::filesystem::path& recording_file);

  /// The expert's path (null: no ghost in this replay).
  const std::shared_ptr<const runtime::ExpertPath>& expert() const noexcept { return expert_; }
  /// Why there is no ghost though the recording was guided ("" when there is one, or when the
  /// recording was not guided).
  const std::string& notice() const noexcept { return notice_; }
  /// Whether the recording was guided at some time.
  bool guided() const noexcept { return !switches_.empty(); }
  /// Whether the expert's ghost is shown at recording time `t_s` [s].
  bool onAt(double t_s) const noexcept;
  /// The expert's pose at the nearest point of its path to p_WD (the record's device) [m, W].
  haptics::Pose ghostPose(const Eigen::Vector3d& p_WD_m) const noexcept;

 private:
  struct Switch {
    double time_s = 0.0;
    std::string expert_sha256;  // empty: guidance off from then on
  };
  std::vector<Switch> switches_;
  std::shared_ptr<const runtime::ExpertPath> expert_;
  std::string notice_;
  /// Loads the expert that the first guided switch names, or says why not.
  void findExpert(const std::string& sha256, const std::string& recorded_path, const std::string& name,
                  const std::filesystem::path& recording_file);
};

}  // namespace vh::ui
