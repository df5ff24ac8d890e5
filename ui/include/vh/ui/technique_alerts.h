#pragma once
/// @file
/// Technique feedback in the window (runtime/technique.h): when a rule becomes active in a haptic
/// snapshot, the status bar says what to change and the alert tone sounds once. The haptic
/// thread evaluates the rules and records their events; this only shows what it decided.
///
/// Threads: GUI thread only.
#include <cstdint>
#include <optional>

#include <QObject>
#include <QString>

#include "vh/runtime/haptic_snapshot.h"

namespace vh::ui {

class TechniqueAlerts : public QObject {
  Q_OBJECT

 public:
  using QObject::QObject;

  /// One snapshot shown: a rule that was not active in the previous one gives message() and
  /// alertRequested() (once per episode: the monitor's hold and clear times keep it so).
  void showSnapshot(const runtime::HapticSnapshot& snapshot);
  /// Rules that became active since the window opened (all rules together).
  std::uint64_t alertsShown() const noexcept { return shown_; }
  /// Episodes of the burr spinning while only the shaft touched (HapticSnapshot::shaft_only)
  /// for at least kShaftOnlyTicks solver ticks, each said once (runtime::shaftOnlyAdvice()).
  std::uint64_t shaftOnlyShown() const noexcept { return shaft_only_shown_; }
  static constexpr std::uint64_t kShaftOnlyTicks = 200;

 signals:
  /// "Technique: moving fast near a critical structure: slow down", for the status bar (`ms`).
  void message(const QString& text, int ms);
  /// The alert tone (the window plays it when the segments panel's sound is on).
  void alertRequested();

 private:
  void showShaftOnly(const runtime::HapticSnapshot& snapshot);
  std::uint32_t active_ = 0;
  std::uint64_t shown_ = 0;
  std::optional<std::uint64_t> shaft_only_since_;  // solver tick the episode began on
  bool shaft_only_said_ = false;
  std::uint64_t shaft_only_shown_ = 0;
};

}  // namespace vh::ui
