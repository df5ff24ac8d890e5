#pragma once
/// @file
/// The status line at the bottom of the main window: the haptic threads' statistics (or why
/// haptics are off), and the load progress with its Cancel button. Messages of the status bar
/// (load notices, "Loading cancelled") replace the statistics while they last.
/// GUI thread only.

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

/// The statistics text for `session` (its latest snapshot `snapshot`, null before the first),
/// or why there are none; `replaying` names the recording a replay shows (empty: live). With
/// segments, it names the one the tool touches ("touching facial nerve (CRITICAL)").
QString hapticStatusText(const runtime::Session& session, const runtime::HapticSnapshot* snapshot,
                         const QString& replaying);

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
};

}  // namespace vh::ui
