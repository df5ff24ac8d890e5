#pragma once
/// @file
/// Device trajectories: timed device poses X_WD (world frame W, metres) read from / written to
/// CSV, sampled at arbitrary times (linear interpolation of the position, slerp of the
/// rotation), and generated in code for scripted tests ("push into the surface and slide").
///
/// CSV format (one header line optional, '#' comment lines and blank lines ignored):
///   t_s,x_m,y_m,z_m,qw,qx,qy,qz[,isovalue]
/// t_s strictly increasing [s]; (x, y, z) = origin of the device frame D in W [m]; (qw..qz) the
/// rotation R_WD as a quaternion (normalised on load; it must not be zero); isovalue, optional,
/// the isovalue the headless run asks the renderer for at that key (data units; a blank field
/// or an 8-column row: the scene's). A header names either the 8 or the 9 columns, and then
/// every row has that many fields; without a header a row may have 8 or 9.

#include <cstddef>
#include <filesystem>
#include <iosfwd>
#include <limits>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "vh/haptics/point_shell.h"
#include "vh/haptics/pose.h"
#include "vh/haptics/scalar_volume.h"

namespace vh::runtime {

/// One key pose of a trajectory.
struct TrajectorySample {
  double t_s = 0.0;     ///< Time [s].
  haptics::Pose X_WD;   ///< Device pose in W [m], unit quaternion.
  /// Isovalue requested at this key (data units); NaN: none (the scene's).
  double isovalue = std::numeric_limits<double>::quiet_NaN();
};

/// A piecewise-linear (slerp for rotation) device trajectory; immutable once built.
class Trajectory {
 public:
  Trajectory() = default;
  /// @param samples (n >= 1) key poses with strictly increasing, finite times; quaternions are
  ///        normalised.
  /// @throws std::invalid_argument for no samples, non-increasing or non-finite times, a
  ///         non-finite pose, a zero quaternion or an infinite isovalue (NaN is "none") (the
  ///         message gives the sample's index).
  explicit Trajectory(std::vector<TrajectorySample> samples);

  bool empty() const noexcept { return samples_.empty(); }
  std::size_t size() const noexcept { return samples_.size(); }
  const std::vector<TrajectorySample>& samples() const noexcept { return samples_; }
  double startTime_s() const noexcept { return samples_.empty() ? 0.0 : samples_.front().t_s; }
  double endTime_s() const noexcept { return samples_.empty() ? 0.0 : samples_.back().t_s; }
  double duration_s() const noexcept { return endTime_s() - startTime_s(); }

  /// Pose at time t [s]: clamped to the first / last key pose outside [start, end]; identity
  /// for an empty trajectory. O(log n); allocation free.
  haptics::Pose poseAt(double t_s) const noexcept;
  /// Same, with a segment hint `cursor` (updated) that makes monotonic access O(1) amortised.
  haptics::Pose poseAt(double t_s, std::size_t& cursor) const noexcept;
  /// Whether any key requests an isovalue.
  bool hasIsovalues() const noexcept;
  /// Isovalue requested at time t [s] (data units): linear between the two keys around t, a
  /// key without one counting as `fallback` (the scene's); clamped to the first / last key
  /// outside [start, end]; `fallback` for an empty trajectory. O(log n); allocation free.
  double isovalueAt(double t_s, double fallback) const noexcept;

 private:
  haptics::Pose interpolate(std::size_t segment, double t_s) const noexcept;
  std::vector<TrajectorySample> samples_;
};

/// Parses trajectory CSV text; `source_name` (usually the file name) prefixes every error.
/// @throws std::runtime_error "SOURCE:LINE: problem" for a header that names other columns, a
///         wrong column count, a value that is not a number or not finite (naming the column),
///         a time that does not increase, a zero quaternion; "SOURCE: no samples" for an empty
///         file.
Trajectory parseTrajectoryCsv(std::istream& in, const std::string& source_name);

/// Reads a trajectory CSV file.
/// @throws std::runtime_error naming the file: missing/unreadable file, or as parseTrajectoryCsv.
Trajectory loadTrajectoryCsv(const std::filesystem::path& path);

/// Writes a trajectory as CSV with a header line (17 significant digits: lossless round trip);
/// the ninth column (isovalue, blank where a key has none) only when hasIsovalues().
/// @throws std::runtime_error naming the file when it cannot be written.
void writeTrajectoryCsv(const Trajectory& trajectory, const std::filesystem::path& path);

/// The scripted "push and slide" interaction used by the acceptance tests and `volume-haptics
/// make-trajectory`:
///   hold at the start (clearance outside the surface), approach to the surface, push
///   `push_depth_m` into it, slide `slide_m` tangentially (optionally rotating), hold, retract
///   back to the start height, hold.
struct PushSlideOptions {
  Eigen::Vector3d approach_dir_W = -Eigen::Vector3d::UnitZ();  ///< Direction of the push (unit).
  /// Slide direction; zero selects the W axis most perpendicular to the approach, made
  /// perpendicular to it.
  Eigen::Vector3d slide_dir_W = Eigen::Vector3d::Zero();
  double start_clearance_m = 0.015;  ///< Device start, this far before the first contact [m].
  double push_depth_m = 0.005;       ///< Device depth past the first contact [m].
  double slide_m = 0.02;             ///< Tangential slide [m].
  double slide_rotation_rad = 0.0;   ///< Rotation during the slide about approach x slide [rad].
  double hold_s = 0.2;               ///< Pause at the start, after the slide, and at the end [s].
  double approach_time_s = 0.5;      ///< Start to first contact [s].
  double push_time_s = 1.0;          ///< First contact to full depth [s].
  double slide_time_s = 2.0;         ///< Slide [s].
  double retract_time_s = 0.5;       ///< Back to the start height [s].
};

/// Where a push-and-slide trajectory meets the surface.
struct PushSlidePlan {
  Trajectory trajectory;            ///< Key poses (t from 0).
  haptics::Pose X_WD_contact;       ///< Pose of the first contact along the approach.
  double contact_distance_m = 0.0;  ///< Distance from X_WT_ray_start to X_WD_contact [m].
};

/// Casts the tool (point shell in its frame T) along `options.approach_dir_W` from
/// `X_WT_ray_start` (a free pose, e.g. poseAboveVolume()) to the first contact with F = s and
/// builds the push-and-slide trajectory around it (device frame D = tool frame T).
/// @throws std::runtime_error when the ray meets no surface within `max_distance_m` (0: the
///         volume's bounding-box diagonal plus the tool size), or the start pose is not free.
PushSlidePlan makePushSlideTrajectory(const haptics::ScalarVolume& volume,
                                      const haptics::PointShell& shell, double isovalue,
                                      const haptics::Pose& X_WT_ray_start,
                                      const PushSlideOptions& options = {},
                                      double max_distance_m = 0.0);

}  // namespace vh::runtime
