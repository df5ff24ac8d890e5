#include "vh/ui/panels/status_line.h"

#include <QHBoxLayout>
#include <QLabel>
#include <QProgressBar>
#include <QStatusBar>
#include <QToolButton>

namespace vh::ui {

void MissWindow::add(std::int64_t time_ns, std::uint64_t coupling_total, std::uint64_t solver_total) {
  if (!entries_.empty()) {
    const Entry& last = entries_.back();
    if (time_ns < last.time_ns || coupling_total < last.coupling || solver_total < last.solver) entries_.clear();
  }
  // The threads count from their start: the first snapshot's totals are misses since then.
  if (entries_.empty()) entries_.push_back({time_ns, 0, 0});
  entries_.push_back({time_ns, coupling_total, solver_total});
  // Keep one entry at or before the window's start as the baseline.
  const auto window_ns = static_cast<std::int64_t>(kWindow_s * 1e9);
  while (entries_.size() > 2 && entries_[1].time_ns <= time_ns - window_ns) entries_.pop_front();
}

std::uint64_t MissWindow::coupling() const noexcept {
  return entries_.empty() ? 0 : entries_.back().coupling - entries_.front().coupling;
}

std::uint64_t MissWindow::solver() const noexcept {
  return entries_.empty() ? 0 : entries_.back().solver - entries_.front().solver;
}

namespace {

/// Below this force [N] a tool without contacts is simply free: the spring's remainder as the
/// proxy settles on the device.
constexpr double kTrailingForce_N = 0.05;

/// The contact figure beside the force, never at odds with it. The force is the coupling's
/// spring to the proxy; the contacts are the solver's contact set, both from one snapshot. A
/// force without contacts is the proxy trailing the device (the solver moves it at most
/// max_travel_per_tick_m per tick, or finishes a sweep over several ticks), not a press, and
/// is said so instead of "contacts 0" beside a force.
QString contactText(int contacts, double force_N) {
  if (contacts > 0) return QString("contacts %1").arg(contacts);
  if (force_N < kTrailingForce_N) return "no contact";
  return "no contact (the proxy trails the device)";
}

}  // namespace

QString schedulingNote(bool realtime) {
  if (realtime) return {};
  return "  |  normal priority: a busy computer can delay the force (real-time: sudo adduser $USER volume-haptics, "
         "then log in again)";
}

QString hapticStatusText(const runtime::Session& session, const runtime::HapticSnapshot* snapshot,
                         const QString& replaying, const MissWindow* misses) {
  if (!session.hasScene()) return "No scan open";
  if (!replaying.isEmpty()) return "Replaying " + replaying + ": haptics stopped (Close Replay in the Replay dock to go live)";
  if (session.hapticThread() == nullptr) return "Haptics off: the scene has no device";
  if (!session.hapticsRunning()) return "Haptic thread stopped (Haptics > Run, Ctrl+H)";
  if (snapshot == nullptr) return "Haptic thread starting...";
  // Two threads (paper section 3.2): the coupling thread renders the force at the device's
  // rate, the solver thread moves the proxy (HapticRenderer::tick()) at its own.
  const runtime::HapticSnapshot& s = *snapshot;
  QString text =
      QString::fromUtf8("Coupling %1 Hz (jitter %2 \u00b5s, misses %3)  |  Solver %4 Hz (tick %5 / %6 \u00b5s "
                        "mean / max, misses %7)  |  %8  |  |F| %9 N  |  |\u03c4| %10 N\u00b7m")
          .arg(s.coupling.rate_Hz, 0, 'f', 0)
          .arg(s.coupling.jitter_us, 0, 'f', 0)
          .arg(misses != nullptr ? QString("%1/min").arg(misses->coupling())
                                 : QString::number(static_cast<qulonglong>(s.coupling.deadline_misses)))
          .arg(s.solver.rate_Hz, 0, 'f', 0)
          .arg(s.solver.mean_tick_us, 0, 'f', 1)
          .arg(s.solver.max_tick_us, 0, 'f', 1)
          .arg(misses != nullptr ? QString("%1/min").arg(misses->solver())
                                 : QString::number(static_cast<qulonglong>(s.solver.deadline_misses)))
          .arg(contactText(s.contacts, s.force_W_N.norm()))
          .arg(s.force_W_N.norm(), 0, 'f', 2)
          .arg(s.torque_W_Nm.norm(), 0, 'f', 4);
  // The structure touched.
  if (const auto& segments = session.live().segments; segments != nullptr && s.segment >= 0) {
    text += "  |  touching " + QString::fromStdString(segments->name(s.segment)) +
            (segments->isCritical(s.segment) ? " (CRITICAL)" : "");
  }
  if (s.skipped_samples > 0) {
    text += QString("  |  solver skipped %1 device samples").arg(static_cast<qulonglong>(s.skipped_samples));
  }
  return text + schedulingNote(session.hapticThread()->realtimeScheduling());
}

StatusLine::StatusLine(QStatusBar* bar) : QObject(bar) {
  label_ = new QLabel(bar);
  label_->setObjectName("hapticStatus");
  label_->setTextInteractionFlags(Qt::TextSelectableByMouse);
  label_->setToolTip(
      "Coupling: the thread that reads the device and sends the force (virtual coupling), at the "
      "device's rate; jitter is the largest deviation of its wake-up interval from the period over "
      "the last second.\nSolver: the thread that moves the proxy against the surface; tick is its "
      "computing time per tick over the last second.\nMisses: ticks that started more than one period "
      "late, over the last minute.\nContacts: the points where the tool's proxy touches the surface. "
      "|F|: the force on the hand, the spring between the proxy and the device; without contacts it "
      "is the proxy trailing a fast-moving device, not a press.");
  bar->addWidget(label_, 1);
  // A message (a load notice, "Loading cancelled") replaces the statistics while it lasts; the
  // status bar alone leaves both painted over each other once the label's text changes.
  connect(bar, &QStatusBar::messageChanged, label_, [this](const QString& message) { label_->setVisible(message.isEmpty()); });

  progress_box_ = new QWidget(bar);
  auto* layout = new QHBoxLayout(progress_box_);
  layout->setContentsMargins(0, 0, 0, 0);
  progress_label_ = new QLabel(progress_box_);
  progress_label_->setObjectName("progressLabel");
  progress_bar_ = new QProgressBar(progress_box_);
  progress_bar_->setObjectName("progressBar");
  progress_bar_->setFixedWidth(160);
  progress_bar_->setMaximumHeight(16);
  progress_cancel_ = new QToolButton(progress_box_);
  progress_cancel_->setObjectName("progressCancel");
  progress_cancel_->setText("Cancel");
  progress_cancel_->setToolTip("Stop loading; what is open stays (Esc)");
  layout->addWidget(progress_label_);
  layout->addWidget(progress_bar_);
  layout->addWidget(progress_cancel_);
  bar->addPermanentWidget(progress_box_);
  progress_box_->hide();
  connect(progress_cancel_, &QToolButton::clicked, this, &StatusLine::cancelRequested);
}

void StatusLine::showHaptics(const runtime::Session& session, const runtime::HapticSnapshot* snapshot,
                             const QString& replaying) {
  if (snapshot != nullptr && replaying.isEmpty()) {
    misses_.add(snapshot->time_ns, snapshot->coupling.deadline_misses, snapshot->solver.deadline_misses);
  } else {
    misses_.clear();
  }
  label_->setText(hapticStatusText(session, snapshot, replaying, misses_.empty() ? nullptr : &misses_));
}

QString StatusLine::text() const { return label_->text(); }

void StatusLine::showProgress(const QString& stage, int percent, bool cancellable) {
  progress_label_->setText(stage);
  if (percent < 0) {
    progress_bar_->setRange(0, 0);  // busy indicator
  } else {
    progress_bar_->setRange(0, 100);
    progress_bar_->setValue(percent);
  }
  progress_cancel_->setVisible(cancellable);
  progress_box_->show();
}

void StatusLine::hideProgress() { progress_box_->hide(); }

}  // namespace vh::ui
