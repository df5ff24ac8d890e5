#pragma once
/// @file
/// The plausibility test every device sample passes before any force is computed from it (the
/// coupling thread of HapticThread and the headless runner use this one implementation). An
/// encoder or USB glitch can report the handle a metre away for one sample; the renderer would
/// couple the proxy to it and command the full spring force for that tick. A sample is
/// implausible, and is neither rendered nor handed to the solver, when
///   * its pose is not finite, or its quaternion is off unit length by more than 1e-3;
///   * it lies outside the device's workspace: farther than kWorkspaceFactor times
///     DeviceLimits::workspace_radius_m from DeviceLimits::workspace_centre_m (drivers state
///     the ball inside the workspace, e.g. the largest ball in OpenHaptics' usable box, whose
///     corners can be 3 radii away: only positions no handle can take are rejected);
///   * it moved faster than the device can: farther from the last good sample than
///     DeviceLimits::max_speed_m_per_s (or turned more than max_angular_speed_rad_per_s) times
///     the time since that sample, plus kPositionSlack_m (kAngleSlack_rad).
/// Each sample is compared with the last GOOD sample and the time since it, so one glitch never
/// makes the next good sample look like a jump back. Two ways out of a lock-out:
///   * time: the allowed distance grows with the time since the last good sample, so after a
///     gap (missing samples, a reconnection) any jump the device could have made meanwhile
///     passes;
///   * re-seeding: kReseedSamples consecutive samples that are each plausible against the one
///     before them (a device that really is somewhere else, e.g. re-homed, or a pose the GUI
///     moved) are accepted: the last of them becomes the last good sample, and check() says
///     kReseeded so the caller re-arms the safety layer's engage gate as for a reconnection.
/// A new DeviceSample::connection also starts afresh (the next usable sample is good).
///
/// check() never allocates, blocks or throws.

#include <cstdint>

#include "vh/haptics/pose.h"
#include "vh/runtime/device.h"

namespace vh::runtime {

class SampleFilter {
 public:
  /// Allowed distance beyond speed x time, for encoder quantisation and jitter [m].
  static constexpr double kPositionSlack_m = 1e-3;
  /// Allowed rotation beyond angular speed x time [rad].
  static constexpr double kAngleSlack_rad = 0.01;
  /// Positions farther than this many workspace radii from the workspace centre are rejected.
  static constexpr double kWorkspaceFactor = 4.0;
  /// Consecutive mutually consistent samples that re-seed the filter (5 ms at 1 kHz).
  static constexpr int kReseedSamples = 5;

  enum class Verdict : std::uint8_t {
    kGood,        ///< Plausible: render it.
    kMissing,     ///< No usable sample (read() false or DeviceSample::valid false).
    kImplausible, ///< Rejected (non-finite, outside the workspace, too fast): do not render it.
    kReseeded,    ///< Accepted after kReseedSamples consistent samples away from the last good
                  ///< one: render it, and re-arm the engage gate (the hand may be anywhere).
  };

  /// Totals since construction.
  struct Stats {
    std::uint64_t implausible = 0;  ///< Samples rejected (all reasons below).
    std::uint64_t nonfinite = 0;    ///< ... with a non-finite pose or a quaternion off unit length.
    std::uint64_t outside = 0;      ///< ... outside the workspace.
    std::uint64_t too_fast = 0;     ///< ... faster than the device moves.
    std::uint64_t reseeds = 0;      ///< Times the filter re-seeded.
  };

  SampleFilter() = default;
  /// @param limits the device's (speed limits, workspace), in the frame of its samples.
  explicit SampleFilter(const DeviceLimits& limits) noexcept { setLimits(limits); }
  /// Cheap, allocation free (e.g. every tick after a workspace scale change).
  void setLimits(const DeviceLimits& limits) noexcept { limits_ = limits; }
  const DeviceLimits& limits() const noexcept { return limits_; }

  /// One servo tick.
  /// @param sample the device's sample (read only when `read_ok`).
  /// @param read_ok Device::read() returned true.
  /// @param dt_s time since the previous check() [s] (the tick interval; non-finite or < 0: 0).
  Verdict check(const DeviceSample& sample, bool read_ok, double dt_s) noexcept;

  /// The last good (or re-seeded) sample's pose; meaningful once haveGood().
  const haptics::Pose& lastGood() const noexcept { return good_; }
  bool haveGood() const noexcept { return have_good_; }
  const Stats& stats() const noexcept { return stats_; }

 private:
  /// Whether `X` could follow `from` after `elapsed_s`.
  bool reachable(const haptics::Pose& from, const haptics::Pose& X, double elapsed_s) const noexcept;

  DeviceLimits limits_;
  haptics::Pose good_;
  double since_good_s_ = 0.0;  // time since the last good sample [s]
  bool have_good_ = false;
  std::uint32_t connection_ = 0;
  bool have_connection_ = false;
  // The run of rejected samples that agree with each other (re-seeding).
  haptics::Pose candidate_;
  double since_candidate_s_ = 0.0;
  int candidate_run_ = 0;
  Stats stats_;
};

}  // namespace vh::runtime
