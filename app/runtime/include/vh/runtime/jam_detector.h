#pragma once
/// @file
/// The jam detector: ticks in which the proxy is held in contact, far from a device that is
/// itself in free space, and cannot move towards it. A hand there is held at the device's
/// maximum force although nothing it touches resists (the device's own pose is free), so this is
/// a fault of the renderer, not a surface pressed on. Counted in the headless run report
/// (RunReport::jam_ticks) and flagged per tick in recordings (kRecordFlagJam), from which the
/// recording's writer derives "jam" / "jam_cleared" events.
///
/// A tick is a jam candidate when all of these hold (cheap tests first; the caller evaluates the
/// last one only on candidates, e.g. with countPointsInside() at the device pose):
///  - the proxy is in contact (contacts > 0): out of contact it always moves towards the device;
///  - the tool's centres of mass are more than kJamDistance_m apart: 10 mm is 10 N at the
///    default coupling stiffness (1000 N/m), above every desktop device's peak force (a Falcon's
///    9 N, a Touch's 3.3 N), so the hand is held at its maximum;
///  - the proxy's centre came less than kJamProgress_m closer to the device's in the tick: a free
///    proxy closes up to the contact travel limit (2 mm) per tick, one sliding along a wall
///    several micrometres;
///  - no shell point is inside the isosurface at the device pose (a device pressed into bone is
///    not a jam: there the proxy must stay).
/// A jam is a run of more than kJamTicks such ticks in a row: 50 ticks (50 ms at 1 kHz) is ten
/// times the few ticks the renderer's own recoveries take (the stuck contact's lift after two
/// blocked moves, the normal refinement within a tick), and shorter than a hand notices a hold.
/// Frames and units: W [m].

#include <cstdint>

#include <Eigen/Core>

#include "vh/haptics/pose.h"

namespace vh::runtime {

inline constexpr double kJamDistance_m = 0.010;
inline constexpr double kJamProgress_m = 1e-6;
inline constexpr int kJamTicks = 50;

/// Counts jams tick by tick (no allocation; any thread, one caller).
class JamDetector {
 public:
  /// Whether the tick from proxy pose X_WP_before to X_WP_after, with the device at X_WD and
  /// `contacts` contacts after it, is a candidate by the first three tests (the device's own
  /// freedom is the caller's, only then). p_TCm_m: the tool's centre of mass in T [m].
  static bool candidate(const haptics::Pose& X_WP_before, const haptics::Pose& X_WP_after, const haptics::Pose& X_WD,
                        const Eigen::Vector3d& p_TCm_m, int contacts) noexcept {
    if (contacts <= 0) return false;
    const Eigen::Vector3d c_D = X_WD * p_TCm_m;
    const double after_m = (c_D - X_WP_after * p_TCm_m).norm();
    const double before_m = (c_D - X_WP_before * p_TCm_m).norm();
    return after_m > kJamDistance_m && before_m - after_m < kJamProgress_m;
  }

  /// One tick: `stuck` when candidate() held and the device pose is free. @return whether this
  /// tick is part of a jam (the run of stuck ticks is longer than kJamTicks).
  bool update(bool stuck) noexcept {
    run_ = stuck ? run_ + 1 : 0;
    const bool jammed = run_ > kJamTicks;
    if (jammed) {
      ++jam_ticks_;
      if (run_ == kJamTicks + 1) ++jams_;
    }
    return jammed;
  }
  /// Ticks that were part of a jam so far.
  std::uint64_t jamTicks() const noexcept { return jam_ticks_; }
  /// Jams so far (runs of more than kJamTicks stuck ticks).
  std::uint64_t jams() const noexcept { return jams_; }
  /// Stuck ticks in a row up to the last update().
  int run() const noexcept { return run_; }

 private:
  int run_ = 0;
  std::uint64_t jam_ticks_ = 0;
  std::uint64_t jams_ = 0;
};

}  // namespace vh::runtime
