#pragma once
/// @file
/// The status line at the bottom of the main window: the haptic threads' statistics (or why
/// haptics are off), and the load progress with its Cancel button. Messages of the status bar
/// (load notices, "Loading cancelled") replace the statistics while they last.
/// GUI thread only.

#include <cstdint>
#include <deque>

#include <QObject>
#include <QString>

#include "vh/runtime/haptic_thread.h"
#include "vh/runtime/session.h"

class QLabel;
class QProgressBar;
class QStatusBar;
class QToolButton;
class QWidget;

namespace vh::ui {

/// Deadline misses of the two haptic threads over the last minute, from the totals of successive
/// snapshots (the threads count from their start, so on a busy machine a total only grows and
/// says nothing of now). Until a minute has passed since the first snapshot, the misses since the
/// threads started. Totals or time that go back (new threads) start it afresh.
class MissWindow {
 public:
  static constexpr double kWindow_s = 60.0;

  /// The totals of a snapshot taken at `time_ns` (steady clock [ns]).
  void add(std::int64_t time_ns, std::uint64_t coupling_total, std::uint64_t solver_total);
  void clear() { entries_.clear(); }
  bool empty() const noexcept { return entries_.empty(); }
  /// Misses within the window.
  std::uint64_t coupling() const noexcept;
  std::uint64_t solver() const noexcept;

 private:
  struct Entry {
    std::int64_t time_ns;
    std::uint64_t coupling, solver;
  };
  std::deque<Entry> entries_;  // oldest first; the first is the window's baseline
};

/// What the status line adds when the haptic threads run without real-time scheduling
/// (HapticThread::realtimeScheduling() false: SCHED_OTHER, so any busy program, a load or the
/// window's own drawing can delay a force update by milliseconds): that, and how to get it
/// (packaging/95-volume-haptics-realtime.conf). Empty when `realtime`.
QString schedulingNote(bool realtime);

/// The statistics text for `session` (its latest snapshot `snapshot`, null before the first),
/// or why there are none; `replaying` names the recording a replay shows (empty: live). With
/// segments, it names the one the tool touches ("touching facial nerve (CRITICAL)"). Deadline
/// misses per minute from `misses` when given (StatusLine), else the snapshot's totals; then
/// schedulingNote() of the running threads.
QString hapticStatusText(const runtime::Session& session, const runtime::HapticSnapshot* snapshot,
                         const QString& replaying, const MissWindow* misses = nullptr);

class StatusLine : public QObject {
  Q_OBJECT

 public:
  /// Adds its label and progress box to `bar`.
  explicit StatusLine(QStatusBar* bar);

  /// Shows hapticStatusText().
  void showHaptics(const runtime::Session& session, const runtime::HapticSnapshot* snapshot, const QString& replaying);
  QString text() const;
  /// `percent` in [0, 100], or -1 for a busy indicator.
  void showProgress(const QString& stage, int percent, bool cancellable);
  void hideProgress();

 signals:
  void cancelRequested();

 private:
  QLabel* label_ = nullptr;
  QWidget* progress_box_ = nullptr;
  QLabel* progress_label_ = nullptr;
  QProgressBar* progress_bar_ = nullptr;
  QToolButton* progress_cancel_ = nullptr;
  MissWindow misses_;
};

}  // namespace vh::ui
