#include "vh/ui/proximity_alerts.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "vh/runtime/segments.h"

namespace vh::ui {

double proximityCueRate_Hz(double distance_m, double warn_m) noexcept {
  if (!(warn_m > 0.0) || !std::isfinite(distance_m)) return 2.0;
  const double closeness = std::clamp(1.0 - distance_m / warn_m, 0.0, 1.0);
  return 2.0 + 8.0 * closeness;
}

void ProximityAlerts::showSnapshot(const runtime::HapticSnapshot& snapshot, const runtime::SegmentSet* segments) {
  const int s = snapshot.critical_segment;
  const bool known = segments != nullptr && s >= 0 && static_cast<std::size_t>(s) < segments->size();
  const runtime::ProximityThresholds t = known ? segments->thresholds(s) : runtime::ProximityThresholds{};
  // With hysteresis on the same segment: a tool hovering at a threshold is warned once.
  const runtime::ProximityLevel after = s == segment_ ? level_ : runtime::ProximityLevel::kClear;
  const runtime::ProximityLevel level =
      known ? runtime::proximityLevelAfter(after, snapshot.critical_distance_m, t) : runtime::ProximityLevel::kClear;
  segment_ = s;
  if (level != level_) {
    level_ = level;
    emit levelChanged(level);
  }
  if (level == runtime::ProximityLevel::kClear) {
    if (!text_.empty()) {
      text_.clear();
      cue_rate_Hz_ = 0.0;
      emit cueChanged(false, 0.0);
    }
    return;
  }
  const bool alarm = level == runtime::ProximityLevel::kAlarm;
  char line[64];
  std::snprintf(line, sizeof line, " %.1f mm (%s within %.1f mm)", snapshot.critical_distance_m * 1e3,
                alarm ? "ALARM" : "warning", (alarm ? t.alarm_m : t.warn_m) * 1e3);
  const std::string text = segments->name(s) + line;
  if (text != text_) {
    text_ = text;
    emit message(QString::fromStdString(text), 1000);
  }
  const double rate = proximityCueRate_Hz(snapshot.critical_distance_m, t.warn_m);
  if (std::abs(rate - cue_rate_Hz_) > 0.25) {
    cue_rate_Hz_ = rate;
    emit cueChanged(true, rate);
  }
}

}  // namespace vh::ui
