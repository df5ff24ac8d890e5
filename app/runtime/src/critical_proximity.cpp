// Warnings before harm: distance from the tool to the critical segments (critical_proximity.h).
#include "vh/runtime/critical_proximity.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>

#include "vh/runtime/segments.h"

namespace vh::runtime {
namespace {

std::string mm(double m) {
  char text[32];
  std::snprintf(text, sizeof text, "%g mm", m * 1e3);
  return text;
}

}  // namespace

void validateProximityThresholds(const ProximityThresholds& t, const std::string& what) {
  if (!std::isfinite(t.warn_m) || !std::isfinite(t.alarm_m) || t.warn_m <= 0.0 || t.alarm_m <= 0.0) {
    throw std::invalid_argument(what + ": warn_mm and alarm_mm must be finite and > 0 (warn " + mm(t.warn_m) +
                                ", alarm " + mm(t.alarm_m) + ")");
  }
  if (t.alarm_m > t.warn_m) {
    throw std::invalid_argument(what + ": alarm_mm (" + mm(t.alarm_m) + ") must not exceed warn_mm (" +
                                mm(t.warn_m) + ")");
  }
  if (t.warn_m > kProximityRange_m) {
    throw std::invalid_argument(what + ": warn_mm (" + mm(t.warn_m) + ") beyond the measured range (" +
                                mm(kProximityRange_m) + ")");
  }
}

CriticalProximity::CriticalProximity(const SegmentSet& segments, const haptics::PointShell& shell)
    : query_(segments.criticalFields(), shell, kProximityRange_m), segment_of_field_(segments.critical()) {}

CriticalDistance CriticalProximity::evaluate(const haptics::Pose& X_WP) noexcept {
  const haptics::NearestProximity n = query_.evaluate(X_WP);
  if (n.field < 0) return {};
  return {segment_of_field_[static_cast<std::size_t>(n.field)], n.distance_m};
}

ProximityTally::ProximityTally(const std::vector<int>& segments, const std::vector<std::string>& names,
                               const std::vector<ProximityThresholds>& thresholds)
    : segment_(segments) {
  for (const int s : segments) {
    const auto i = static_cast<std::size_t>(s);
    SegmentProximityStats st;
    st.name = i < names.size() ? names[i] : std::string();
    st.thresholds = i < thresholds.size() ? thresholds[i] : ProximityThresholds{};
    stats_.push_back(st);
  }
  previous_.assign(stats_.size(), ProximityLevel::kClear);
  current_.assign(stats_.size(), ProximityLevel::kClear);
}

void ProximityTally::add(int segment, double distance_m, double time_s, double dt_s) noexcept {
  for (std::size_t k = 0; k < segment_.size(); ++k) {
    if (segment_[k] != segment) continue;
    SegmentProximityStats& st = stats_[k];
    const ProximityLevel level = proximityLevel(distance_m, st.thresholds);
    if (level != ProximityLevel::kClear) st.time_within_warn_s += dt_s;
    if (level == ProximityLevel::kAlarm) st.time_within_alarm_s += dt_s;
    if (level != ProximityLevel::kClear && previous_[k] == ProximityLevel::kClear) ++st.warnings;
    if (level == ProximityLevel::kAlarm && previous_[k] != ProximityLevel::kAlarm) ++st.alarms;
    if (distance_m < st.closest_m) {
      st.closest_m = distance_m;
      st.closest_time_s = time_s;
    }
    current_[k] = level;
  }
}

void ProximityTally::endTick() noexcept {
  previous_ = current_;  // same size: no allocation
  std::fill(current_.begin(), current_.end(), ProximityLevel::kClear);
}

void ProximityTally::markUnmeasured() noexcept {
  for (auto& st : stats_) {
    st.closest_m = std::numeric_limits<double>::quiet_NaN();
    st.closest_time_s = std::numeric_limits<double>::quiet_NaN();
  }
}

ProximityTally proximityTally(const SegmentSet& segments) {
  std::vector<std::string> names;
  for (int s = 0; s < static_cast<int>(segments.size()); ++s) names.push_back(segments.name(s));
  return ProximityTally(segments.critical(), names, segments.proximityThresholds());
}

std::string proximitySummary(const std::vector<SegmentProximityStats>& proximity) {
  std::string out;
  char line[320];
  for (const SegmentProximityStats& p : proximity) {
    out += "; near " + p.name + " (CRITICAL): ";
    if (std::isnan(p.closest_m)) {
      out += "not measured";
      continue;
    }
    if (!std::isfinite(p.closest_m)) {
      out += "not within " + mm(kProximityRange_m);
      continue;
    }
    std::snprintf(line, sizeof line, "closest %.3f mm at %.3f s, within %g mm %.3f s (%llu times), within %g mm %.3f s (%llu times)",
                  p.closest_m * 1e3, p.closest_time_s, p.thresholds.warn_m * 1e3, p.time_within_warn_s,
                  static_cast<unsigned long long>(p.warnings), p.thresholds.alarm_m * 1e3, p.time_within_alarm_s,
                  static_cast<unsigned long long>(p.alarms));
    out += line;
  }
  return out;
}

}  // namespace vh::runtime
