#pragma once
/// @file
/// The fit check (vh/runtime/tool_fit.h) of the session's tool, run beside the window whenever a
/// scene or a tool is chosen: on a thread of its own at a lower CPU priority (nice 10), the
/// result handed to the GUI thread. A check of a tool no longer chosen is cancelled within a
/// tick and its result dropped.

#include <atomic>
#include <memory>
#include <optional>
#include <thread>

#include <QObject>
#include <QString>

#include "vh/runtime/scene.h"
#include "vh/runtime/tool_fit.h"

namespace vh::ui {

class ToolFitChecker : public QObject {
  Q_OBJECT

 public:
  explicit ToolFitChecker(QObject* parent = nullptr);
  /// Cancels a check in progress and waits for its thread (within a tick of the solver).
  ~ToolFitChecker() override;
  ToolFitChecker(const ToolFitChecker&) = delete;
  ToolFitChecker& operator=(const ToolFitChecker&) = delete;

  /// How the checks run (e.g. a fixed cost of a work unit, for tests); from the next check on.
  void setOptions(const runtime::ToolFitOptions& options);
  /// Checks live's tool on live's felt surface, unless that tool with that edge test on that
  /// field was the one checked last or being checked; a check in progress of another is
  /// cancelled. Without a tool or a field, forgets the last result.
  void check(const runtime::LiveValues& live);
  /// The last result of the current tool; empty while it is being checked or without one.
  const std::optional<runtime::ToolFit>& last() const noexcept { return last_; }
  /// True while a check runs.
  bool busy() const noexcept { return busy_; }

 signals:
  /// A check started (the panel says "checking...").
  void started();
  /// A check of the current tool ended (on the GUI thread).
  void checked(const runtime::ToolFit& fit);
  /// A check failed (on the GUI thread): why.
  void failed(const QString& why);

 private:
  void stop();

  runtime::ToolFitOptions options_;
  std::thread worker_;
  std::shared_ptr<std::atomic<bool>> cancel_;
  int generation_ = 0;
  const void* tool_ = nullptr;
  const void* field_ = nullptr;
  bool edges_ = false;
  bool busy_ = false;
  std::optional<runtime::ToolFit> last_;
};

}  // namespace vh::ui
