// The fit check beside the window (tool_fit_checker.h).
#include "vh/ui/tool_fit_checker.h"

#include <sys/resource.h>
#include <unistd.h>

#include <exception>
#include <utility>

#include <QMetaObject>
#include <QPointer>

namespace vh::ui {

ToolFitChecker::ToolFitChecker(QObject* parent) : QObject(parent) {}

ToolFitChecker::~ToolFitChecker() { stop(); }

void ToolFitChecker::setOptions(const runtime::ToolFitOptions& options) {
  options_ = options;
  tool_ = nullptr;  // the next check runs whatever the tool
}

void ToolFitChecker::stop() {
  if (cancel_) cancel_->store(true);
  if (worker_.joinable()) worker_.join();
  busy_ = false;
}

void ToolFitChecker::check(const runtime::LiveValues& live) {
  const void* tool = live.tool.get();
  const void* field = live.hapticField().get();
  const bool edges = live.tool_spec.edge_test;
  if (tool == tool_ && field == field_ && edges == edges_ && (busy_ || last_)) return;
  stop();
  tool_ = tool;
  field_ = field;
  edges_ = edges;
  last_.reset();
  if (tool == nullptr || field == nullptr) return;
  const int generation = ++generation_;
  cancel_ = std::make_shared<std::atomic<bool>>(false);
  runtime::ToolFitOptions options = options_;
  options.cancel = cancel_.get();
  busy_ = true;
  emit started();
  QPointer<ToolFitChecker> self(this);
  worker_ = std::thread([self, live, options, generation, cancel = cancel_] {
    // Beside the window and the servo loop: the warm-up's solvers yield to both.
    (void)setpriority(PRIO_PROCESS, static_cast<id_t>(::gettid()), 10);
    std::optional<runtime::ToolFit> fit;
    QString why;
    try {
      fit = runtime::checkToolFit(live, options);
    } catch (const runtime::ToolFitCancelled&) {
      return;
    } catch (const std::exception& e) {
      why = QString::fromStdString(e.what());
    }
    if (cancel->load()) return;
    QMetaObject::invokeMethod(
        self.data(),
        [self, fit, why, generation] {
          if (self == nullptr || generation != self->generation_) return;
          self->busy_ = false;
          if (fit) {
            self->last_ = fit;
            emit self->checked(*fit);
          } else {
            emit self->failed(why);
          }
        },
        Qt::QueuedConnection);
  });
}

}  // namespace vh::ui
