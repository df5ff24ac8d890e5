#pragma once
/// @file
/// Haptic guidance from an expert's recording (the force law and the path query are
/// haptics/path_guidance.h's): the expert's path read from a `.vhrec`, checked to be of the
/// session's scene, the gains kept within what the device renders, the "guidance" event, and a
/// simulated trainee's hand (CompliantHand) so that a headless run can show what the guidance
/// does to a scripted motion.
///
/// The path is the expert's **device** positions p_WD (TickRecord::p_WD_m, the tool origin the
/// hand held), not the proxy's: guidance acts on the trainee's device, the DTW of
/// `report --reference` compares device paths, and the device path carries how deep the expert
/// pressed into the surface (the proxy stays on it). Consecutive records are joined by a
/// segment except across a placement (kRecordFlagPlacement: a jump, not the hand's motion) or a
/// bad sample; records that moved less than 1 um are merged.
///
/// Where the force enters: HapticThread's coupling thread and the headless runner add the
/// guidance force to the coupling's (after its passivity controller: the guidance spring is
/// conservative, see path_guidance.h) before the stop ramp and the one safety layer
/// (ForceSafety: engage gate, fault hold, clamp to the device's force limit, ramp), so the
/// device never gets more than the safety layer allows, whatever the two add up to.
///
/// Recording: a "guidance" event {"expert_sha256", "expert_file" (its name), "expert_path" (its
/// absolute path, where a replay looks for it first), "stiffness_N_per_m" (applied
/// on this repetition), "requested_stiffness_N_per_m", "cap_N", "deadband_m", "fade",
/// "repetition"} when guidance starts; the headless run also writes "guidance_force" events
/// every kGuidanceEventTicks ticks {"F_W_N": [x, y, z] of the window's last tick, "peak_N": the
/// largest |F| over the window's ticks, "distance_m": the last tick's distance to the path}. The
/// 200-byte TickRecord is left as it is (its force is the renderer's, before the safety layer,
/// which is what a replay checks bit for bit); events carry the guidance without a format change.

#include <cstddef>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "vh/haptics/path_guidance.h"
#include "vh/haptics/pose.h"
#include "vh/runtime/device.h"
#include "vh/runtime/recording.h"
#include "vh/runtime/session_metrics.h"

namespace vh::runtime {

/// Ticks per "guidance_force" event of a headless run (10 ms at 1 kHz).
inline constexpr std::size_t kGuidanceEventTicks = 10;

/// The expert's device path from a recording, with the poses to show the expert's tool at a
/// point of it (the GUI's ghost). Immutable once built.
class ExpertPath {
 public:
  /// @param expert a recording with at least two usable records (not bad samples).
  /// @param file_sha256 the recording file's SHA-256 (for the "guidance" event; may be empty).
  /// @param file_name, file_path its name and its absolute path (for the event; may be empty).
  /// @throws std::invalid_argument when the recording has fewer than two usable records.
  ExpertPath(const Recording& expert, std::string file_sha256 = {}, std::string file_name = {},
             std::string file_path = {});

  const haptics::GuidancePath& path() const noexcept { return path_; }
  /// The recording's scene (sceneIdentity() of its metadata).
  const SceneIdentity& scene() const noexcept { return scene_; }
  const std::string& fileSha256() const noexcept { return file_sha256_; }
  const std::string& fileName() const noexcept { return file_name_; }
  const std::string& filePath() const noexcept { return file_path_; }
  /// The usable device positions, in record order (n x 3, W [m]): the path's vertices.
  const std::vector<Eigen::Vector3d>& points() const noexcept { return points_; }
  /// The expert's device pose at a point of the path (position on the segment, orientation
  /// slerped between its two records); the first record's pose for an empty PathPoint.
  haptics::Pose poseAt(const haptics::PathPoint& p) const noexcept;
  /// What was wrong with the expert's recording (its reader's warnings: damaged chunks, an
  /// unfinished end) and how much of its path is used, for the run, the window and the report
  /// to say; empty for a whole recording.
  const std::string& damage() const noexcept { return damage_; }
  /// devicePathSamples(expert, kDtwSamples): the path `report --reference` aligns with DTW.
  const std::vector<Eigen::Vector3d>& dtwSamples() const noexcept { return dtw_samples_; }
  static constexpr std::size_t kDtwSamples = 1000;

 private:
  std::vector<Eigen::Vector3d> dtw_samples_;
  haptics::GuidancePath path_;
  std::vector<Eigen::Vector3d> points_;
  std::vector<haptics::Pose> segment_from_, segment_to_;  ///< The records at each segment's ends.
  SceneIdentity scene_;
  std::string file_sha256_, file_name_, file_path_;
  std::string damage_;
};

/// Reads the expert's recording and checks that it was recorded on the session's scene
/// (requireSameScene(), as `report --reference` does).
/// @param session_metadata_json the session's metadata (makeSessionMetadata()).
/// @param files the window passes kVhrecOnly (readRecording()).
/// @throws std::runtime_error when the file cannot be read; std::invalid_argument naming both
///         datasets when the scene differs, or when the recording has too few records.
std::shared_ptr<const ExpertPath> loadExpertPath(const std::filesystem::path& file,
                                                 const std::string& session_metadata_json,
                                                 RecordingFiles files = RecordingFiles::kVhrecOrHdf5);

/// The guidance gains within what the device renders: the stiffness at most the device's
/// max_linear_stiffness_N_per_m, the cap at most its max_force_N.
haptics::GuidanceGains clampGuidance(const haptics::GuidanceGains& gains, const DeviceLimits& limits) noexcept;

/// The "guidance" event's detail (see the file comment) for `applied` gains (clampGuidance())
/// and the `requested` ones.
std::string guidanceEventJson(const ExpertPath& expert, const haptics::GuidanceGains& applied,
                              const haptics::GuidanceGains& requested);

/// A simulated trainee's hand for headless runs: the device follows the scripted trajectory as
/// the hand's *intended* motion, and the hand yields to the force the device commands as a
/// mass-spring-damper about it (translation only; orientation as intended):
///   m a = k (x_int - x) + b (v_int - v) + F,
/// integrated with the semi-implicit Euler method at one step per read(). The default
/// impedance is a relaxed grip [estimates within the ranges Tsuji, Morasso, Goto and Ito,
/// "Human hand impedance characteristics during maintained posture", Biol. Cybern. 72, 1995,
/// measured: m 0.5-3 kg, b 5-50 N s/m, k 50-800 N/m]. With guidance stiffness K alone, the hand
/// settles K / (k + K) of the way from its intended path toward the expert's.
struct HandImpedance {
  double mass_kg = 0.5;                ///< m [kg] (> 0).
  double damping_N_s_per_m = 20.0;     ///< b [N s/m] (>= 0).
  double stiffness_N_per_m = 300.0;    ///< k [N/m] (> 0).
};

/// A Device whose reads are `intended`'s moved by the hand model (HandImpedance) under the
/// commands it gets. read() and command() never allocate, block or throw.
class CompliantHand final : public Device {
 public:
  /// @param step_s the time one read() stands for [s] (the servo period; > 0).
  /// @throws std::invalid_argument for an impedance or step out of range.
  CompliantHand(Device& intended, const HandImpedance& hand, double step_s);
  std::string name() const override { return intended_.name() + " (compliant hand)"; }
  DeviceLimits limits() const noexcept override { return intended_.limits(); }
  SafetyPolicy safetyPolicy() const noexcept override { return intended_.safetyPolicy(); }
  DofMask actuatedDof() const noexcept override { return intended_.actuatedDof(); }
  bool read(DeviceSample& sample) noexcept override;
  void command(const Eigen::Vector3d& force_W_N, const Eigen::Vector3d& torque_W_Nm) noexcept override;

 private:
  Device& intended_;
  HandImpedance hand_;
  double step_s_;
  bool started_ = false;
  Eigen::Vector3d p_W_m_ = Eigen::Vector3d::Zero(), v_W_m_per_s_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d force_W_N_ = Eigen::Vector3d::Zero();  ///< The last command.
};

/// What guidance did in a headless run (RunReport::guidance).
struct GuidanceReport {
  std::string expert_sha256;        ///< The expert recording's SHA-256.
  /// ExpertPath::damage(): the expert's recording was damaged or unfinished and how much of it
  /// guided (in the JSON only when not empty).
  std::string expert_damage;
  double stiffness_N_per_m = 0.0;   ///< Applied on this repetition (K fade^r, clamped) [N/m].
  double cap_N = 0.0;               ///< The cap [N].
  int repetition = 0;
  double max_force_N = 0.0;         ///< Largest |guidance force| over the run (<= cap_N) [N].
  double mean_distance_m = 0.0;     ///< Mean distance of the device to the expert's path [m].
  double dtw_mean_m = 0.0;          ///< GuidanceTrack::dtwMean_m() [m].
  /// The trainee's hand model (CompliantHand) the run used; false: the device was a position
  /// source (guidance then cannot move it).
  bool compliant_hand = false;
  /// As a JSON object text (keys as the field names).
  std::string toJson() const;
  /// "guidance K 200 N/m (repetition 0), cap 1.5 N, max 0.8 N; mean distance to the expert 1.2 mm, DTW 1.5 mm".
  std::string summary() const;
};

/// Guidance over a headless run: the force each tick, its events and its figures.
class GuidanceTrack {
 public:
  GuidanceTrack(std::shared_ptr<const ExpertPath> expert, const haptics::GuidanceGains& applied);
  /// Tick i's guidance force [N, W] for the device at p_WD (zero when !sample_ok); writes a
  /// "guidance_force" event every kGuidanceEventTicks ticks into `recorder` (may be null).
  Eigen::Vector3d step(std::uint64_t i, double servo_rate_Hz, const Eigen::Vector3d& p_WD_m, bool sample_ok,
                       RecordingWriter* recorder);
  double maxForce_N() const noexcept { return max_force_N_; }
  double meanDistance_m() const noexcept { return ticks_ > 0 ? distance_sum_m_ / static_cast<double>(ticks_) : 0.0; }
  /// DTW (dynamicTimeWarping(), as `report --reference`) of the run's device path against the
  /// expert's, both thinned to ExpertPath::kDtwSamples points as devicePathSamples() thins
  /// them [mean distance along the warping path, m].
  double dtwMean_m() const;
  const haptics::GuidanceGains& gains() const noexcept { return gains_; }
  /// The figures so far.
  GuidanceReport report(bool compliant_hand) const;

 private:
  std::shared_ptr<const ExpertPath> expert_;
  haptics::GuidanceGains gains_;
  std::vector<Eigen::Vector3d> device_path_;
  double max_force_N_ = 0.0, window_peak_N_ = 0.0, distance_sum_m_ = 0.0;
  std::uint64_t ticks_ = 0;
};

/// The nearest-point distance of every point of `path` to the expert's path, averaged [m].
double meanDistanceToPath(const std::vector<Eigen::Vector3d>& path, const haptics::GuidancePath& expert);

}  // namespace vh::runtime
