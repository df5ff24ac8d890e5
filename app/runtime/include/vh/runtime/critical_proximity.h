#pragma once
/// @file
/// Warnings before harm: how near the tool is to each critical segment, per solver tick.
///
/// The distance is from the proxy's point shell (its points placed at X_WP) to the segment's
/// voxel centres, in metres, sampled from one haptics::DistanceField per critical segment
/// (built once with the SegmentSet, off the servo thread). It is within half a voxel diagonal of
/// the true distance from the shell's points to the voxel centres (distance_field.h); up to
/// kProximityRange_m around the segment, beyond which it is +infinity ("farther than the range").
/// Each critical segment has two thresholds: within warn_m the tick is a warning, within
/// alarm_m an alarm (alarm_m <= warn_m). The solver records the nearest critical segment and its
/// distance in every TickRecord; the recording's writer derives "proximity_warn" and
/// "proximity_alarm" events from them; the run report and session metrics give per segment the
/// time within each threshold and the closest approach.

#include <cstdint>
#include <limits>
#include <map>
#include <string>
#include <vector>

#include "vh/haptics/distance_field.h"
#include "vh/haptics/point_shell.h"
#include "vh/haptics/pose.h"

namespace vh::runtime {

class SegmentSet;  // segments.h

/// Distances are computed up to this far from a critical segment [m]; a warning threshold may
/// not exceed it.
inline constexpr double kProximityRange_m = 0.02;

/// The thresholds of one critical segment, in metres.
struct ProximityThresholds {
  double warn_m = 2e-3;   ///< Within this distance: a warning [m] (0 < alarm_m <= warn_m <= kProximityRange_m).
  double alarm_m = 1e-3;  ///< Within this distance: an alarm [m].
  bool operator==(const ProximityThresholds&) const = default;
};

/// Checks 0 < alarm_m <= warn_m <= kProximityRange_m, both finite.
/// @throws std::invalid_argument naming `what` (e.g. "segmentation.proximity") and the values in mm.
void validateProximityThresholds(const ProximityThresholds& t, const std::string& what);

/// The scene file's "segmentation": {"proximity": {...}}: the thresholds in mm for every
/// critical segment and, by name or ID, for some of them.
struct ProximitySpec {
  ProximityThresholds defaults;                              ///< In metres (the file says mm).
  std::map<std::string, ProximityThresholds> per_segment;    ///< Segment name or ID -> thresholds.
};

/// How near a distance is: clear, within warn_m, within alarm_m.
enum class ProximityLevel : std::uint8_t { kClear = 0, kWarn = 1, kAlarm = 2 };
/// The level of `distance_m` against `t` (NaN and +infinity: clear).
constexpr ProximityLevel proximityLevel(double distance_m, const ProximityThresholds& t) noexcept {
  return distance_m <= t.alarm_m ? ProximityLevel::kAlarm
                                 : distance_m <= t.warn_m ? ProximityLevel::kWarn : ProximityLevel::kClear;
}

/// The level of `distance_m` after `previous`, with hysteresis, for what a user is told (the
/// recording's proximity events, the window's warnings): a nearer level at once; a level is left
/// only once the distance is past its threshold by kProximityHysteresis of it (at least
/// kProximityHysteresisMin_m), so a tool that hovers at a threshold (the point shell's distance
/// moves by hundredths of a millimetre from tick to tick) gives one warning, not a flicker of
/// warn / clear pairs. The measures (time within, closest approach) keep proximityLevel().
inline constexpr double kProximityHysteresis = 0.1;
inline constexpr double kProximityHysteresisMin_m = 0.1e-3;
constexpr ProximityLevel proximityLevelAfter(ProximityLevel previous, double distance_m,
                                             const ProximityThresholds& t) noexcept {
  const ProximityLevel now = proximityLevel(distance_m, t);
  if (now >= previous) return now;
  const auto held = [&](double threshold_m) {
    const double margin_m = kProximityHysteresis * threshold_m > kProximityHysteresisMin_m
                                ? kProximityHysteresis * threshold_m
                                : kProximityHysteresisMin_m;
    return distance_m <= threshold_m + margin_m;
  };
  if (previous == ProximityLevel::kAlarm && held(t.alarm_m)) return ProximityLevel::kAlarm;
  if (held(t.warn_m)) return ProximityLevel::kWarn;
  return now;
}

/// The nearest critical segment on one tick.
struct CriticalDistance {
  int segment = -1;  ///< Index into the scene's segments, or -1: none within kProximityRange_m.
  double distance_m = std::numeric_limits<double>::infinity();  ///< Its distance [m]; +inf: none.
};

/// The per-tick evaluation for one tool and one SegmentSet (build it when either changes, off
/// the servo thread; evaluate() on the solver thread).
class CriticalProximity {
 public:
  /// @param segments its criticalFields(); @param shell the tool's point shell in T [m].
  CriticalProximity(const SegmentSet& segments, const haptics::PointShell& shell);
  /// The nearest critical segment to the shell at X_WP. No allocation, never throws.
  CriticalDistance evaluate(const haptics::Pose& X_WP) noexcept;
  /// Per critical segment (SegmentSet::critical() order), from the last evaluate() [m].
  std::span<const haptics::SegmentProximity> perSegment() const noexcept { return query_.results(); }
  /// Critical segments measured.
  std::size_t size() const noexcept { return segment_of_field_.size(); }

 private:
  haptics::ProximityQuery query_;
  std::vector<int> segment_of_field_;
};

/// Nearness to one critical segment over a session: what the run report and the session
/// metrics give per critical segment.
struct SegmentProximityStats {
  std::string name;                    ///< Segment name.
  ProximityThresholds thresholds;      ///< Its warning and alarm distances [m].
  double time_within_warn_s = 0.0;     ///< Ticks within warn_m (alarm ticks included) * period [s].
  double time_within_alarm_s = 0.0;    ///< Ticks within alarm_m * period [s].
  std::uint64_t warnings = 0;          ///< Entries within warn_m.
  std::uint64_t alarms = 0;            ///< Entries within alarm_m.
  /// The closest approach [m] (+infinity: never within kProximityRange_m; NaN: not measured,
  /// e.g. a recording of format version 1 to 3) and its time [s] (NaN when none).
  double closest_m = std::numeric_limits<double>::infinity();
  double closest_time_s = std::numeric_limits<double>::quiet_NaN();
};

/// Adds up SegmentProximityStats tick by tick (the runner's loop, a recording's records).
class ProximityTally {
 public:
  /// @param segments indices into the scene's segments of the critical ones; @param names,
  /// thresholds one entry per scene segment.
  ProximityTally(const std::vector<int>& segments, const std::vector<std::string>& names,
                 const std::vector<ProximityThresholds>& thresholds);
  /// Segment `segment` (an index into the scene's segments; others are ignored) at `distance_m`
  /// on the tick at `time_s` lasting `dt_s`. Call once per tick for each segment measured; a
  /// segment not given on a tick counts as clear then. No allocation.
  void add(int segment, double distance_m, double time_s, double dt_s) noexcept;
  /// Ends a tick: segments not given on it are clear (their next entry counts again).
  void endTick() noexcept;
  /// Marks the whole session as not measured (closest_m NaN): an old recording.
  void markUnmeasured() noexcept;
  const std::vector<SegmentProximityStats>& segments() const noexcept { return stats_; }

 private:
  std::vector<int> segment_;               // per stats entry: the scene's segment index
  std::vector<SegmentProximityStats> stats_;
  std::vector<ProximityLevel> previous_, current_;
};

/// The tally of `segments`' critical segments with their names and thresholds.
ProximityTally proximityTally(const SegmentSet& segments);

/// The report's text per critical segment, each part starting "; near NAME (CRITICAL): closest
/// 1.23 mm at 2.345 s, within 2 mm 0.512 s (1 time), within 1 mm 0 s" ("not within 20 mm" when
/// it never came near; "not measured" for NaN); empty for none.
std::string proximitySummary(const std::vector<SegmentProximityStats>& proximity);

}  // namespace vh::runtime
