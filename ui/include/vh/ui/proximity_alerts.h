#pragma once
/// @file
/// Warnings before harm in the window: the nearest critical segment's distance from each haptic
/// snapshot (measured on the haptic thread: runtime/critical_proximity.h) against that segment's
/// thresholds (SegmentSet::thresholds(): by default a warning within 2 mm, an alarm within
/// 1 mm). The view colours the tool (amber: warning, red: alarm), the status bar names the
/// structure and the distance, and a cue beeps faster as the distance falls.
///
/// Threads: GUI thread only. Data flows one way: snapshot -> this -> view, status bar, sound.
#include <string>

#include <QObject>
#include <QString>

#include "vh/runtime/critical_proximity.h"
#include "vh/runtime/haptic_snapshot.h"

namespace vh::runtime {
class SegmentSet;
}

namespace vh::ui {

/// The cue's beep rate at `distance_m` from a structure warned at `warn_m` [Hz]: 2 Hz at the
/// warning distance rising linearly to 10 Hz at contact (a parking sensor's scale: the rate, not
/// the pitch, carries the distance, so it stays audible over the burr).
double proximityCueRate_Hz(double distance_m, double warn_m) noexcept;

class ProximityAlerts : public QObject {
  Q_OBJECT

 public:
  using QObject::QObject;

  /// One snapshot shown, with the segments the session has now (null: none, all clear).
  void showSnapshot(const runtime::HapticSnapshot& snapshot, const runtime::SegmentSet* segments);
  runtime::ProximityLevel level() const noexcept { return level_; }
  /// "facial nerve 1.4 mm (warning within 2.0 mm)"; empty when clear.
  const std::string& text() const noexcept { return text_; }

 signals:
  /// The level changed: the view colours the tool.
  void levelChanged(vh::runtime::ProximityLevel level);
  /// The status bar's line while warned (every snapshot whose tenth of a millimetre changed).
  void message(const QString& text, int ms);
  /// The cue: on at `rate_Hz` while warned, off when clear.
  void cueChanged(bool on, double rate_Hz);

 private:
  runtime::ProximityLevel level_ = runtime::ProximityLevel::kClear;
  int segment_ = -1;  // the critical segment level_ is of
  std::string text_;
  double cue_rate_Hz_ = 0.0;
};

}  // namespace vh::ui
