#include "vh/ui/haptics_controller.h"
#include "vh/runtime/placement.h"

#include <QAction>
#include <QFileDialog>
#include <QMessageBox>
#include <QMenu>
#include <QMenuBar>
#include <QSignalBlocker>
#include <QWidget>

#include "vh/runtime/guidance.h"
#include "vh/runtime/tool_fit.h"
#include "vh/runtime/session.h"
#include "vh/runtime/session_metadata.h"
#include "vh/ui/devices/device_input.h"
#include "vh/ui/devices/device_picker.h"
#include "vh/ui/panels/haptics_panel.h"
#include "vh/ui/replay/replay_controller.h"
#include "vh/ui/replay/session_recorder.h"
#include "vh/ui/tool_fit_checker.h"
#include "vh/ui/tool_picker.h"

namespace vh::ui {

HapticsController::HapticsController(runtime::Session& session, HapticsPanel& panel, ToolPicker& tools,
                                     DevicePicker& devices, DeviceInput& input, SessionRecorder& recorder,
                                     ReplayController& replay, QObject* parent)
    : QObject(parent), session_(session), panel_(panel), tools_(tools), devices_(devices), input_(input),
      recorder_(recorder), replay_(replay), fit_checker_(new ToolFitChecker(this)) {
  connect(fit_checker_, &ToolFitChecker::started, this, [this] { panel_.showToolFit("checking...", false); });
  connect(fit_checker_, &ToolFitChecker::checked, this, &HapticsController::showToolFit);
  connect(fit_checker_, &ToolFitChecker::failed, this,
          [this](const QString& why) { panel_.showToolFit("not checked: " + why, false); });
  observer_ = session_.addObserver([this](runtime::SessionChange what) {
    if (runtime::has(what, runtime::SessionChange::kScene) || runtime::has(what, runtime::SessionChange::kTool) ||
        runtime::has(what, runtime::SessionChange::kSegments)) {
      if (session_.hasScene()) {
        fit_checker_->check(session_.live());
      } else {
        fit_checker_->check({});
        panel_.showToolFit("-", false);
      }
    }
    if (runtime::has(what, runtime::SessionChange::kDevice)) devices_.sync();
    const bool dropped = runtime::has(what, runtime::SessionChange::kScene) && guide_ != nullptr;
    if (dropped) guide_.reset();  // the expert's path was of the last scan
    applyGuidance();  // a rebuilt haptic thread keeps the guidance
    refresh();
    if (dropped) emit guidanceChanged();
  });
  // A recording started now runs on fresh threads that were given the guidance before the
  // recorder: set it again so that the recording holds its "guidance" event.
  connect(&recorder_, &SessionRecorder::recordingChanged, this, [this](bool recording) {
    runtime::HapticThread* thread = session_.hapticThread();
    if (recording && thread != nullptr && guide_ != nullptr) thread->setGuidance(guide_, haptics::GuidanceGains{});
  });
  connect(&panel_, &HapticsPanel::startStopRequested, this, [this](bool run) { run ? start() : session_.stopHaptics(); });
  connect(&panel_, &HapticsPanel::toolRequested, &tools_, &ToolPicker::select);
  connect(&panel_, &HapticsPanel::gainsChanged, this, [this](const haptics::CouplingGains& g) { session_.setGains(g); });
  connect(&panel_, &HapticsPanel::edgeTestRequested, this, [this](bool on) {
    if (session_.hasScene()) session_.setEdgeTest(on);
  });
  connect(&panel_, &HapticsPanel::resetDeviceRequested, this, [this] { resetDevice(); });
  connect(&panel_, &HapticsPanel::rescanRequested, &devices_, &DevicePicker::rescan);
  connect(&panel_, &HapticsPanel::message, this, &HapticsController::message);
  connect(&panel_, &HapticsPanel::deviceChoiceRequested, &devices_, &DevicePicker::choose);
  connect(&devices_, &DevicePicker::choicesChanged, &panel_, &HapticsPanel::setDeviceChoices);
  connect(&devices_, &DevicePicker::choiceChanged, &panel_, &HapticsPanel::setDeviceChoice);
  connect(&tools_, &ToolPicker::buildStarted, this, [this](const QString& label, double spacing_m) {
    recorder_.noteTool(label, spacing_m);
    panel_.setBuilding(true);
  });
  connect(&tools_, &ToolPicker::choicesChanged, this, [this] { refresh(); });
  connect(&tools_, &ToolPicker::buildEnded, this, [this] {
    panel_.setBuilding(false);
    refresh();
  });
  const auto replay_changed = [this] {
    recorder_.setReplayActive(replay_.active());
    refresh();
  };
  connect(&replay_, &ReplayController::replayStarted, this, replay_changed);
  connect(&replay_, &ReplayController::replayClosed, this, replay_changed);
}

HapticsController::~HapticsController() { session_.removeObserver(observer_); }

void HapticsController::showToolFit(const runtime::ToolFit& fit) {
  const QString summary = QString::fromStdString(fit.summary());
  if (fit.fits()) {
    panel_.showToolFit(QString("on time (worst tick %1 % of the deadline)").arg(100.0 * fit.deadlineShare(fit.asked), 0, 'f', 0),
                       false);
    return;
  }
  const QString late = QString("late: %1 in %2 ticks cut, %3 mm behind")
                           .arg(fit.asked.cut_ticks)
                           .arg(fit.asked.ticks)
                           .arg(fit.asked.behind_max_m * 1e3, 0, 'f', 2);
  if (fit.suggested) {
    panel_.showToolFit(late + QString("; at %1 mm: felt within %2 mm, on time")
                                  .arg(fit.suggested->spacing_m * 1e3, 0, 'f', 2)
                                  .arg(fit.suggested->felt_gap_m * 1e3, 0, 'f', 2),
                       true, fit.suggested->spacing_m, fit.suggested->points);
  } else {
    panel_.showToolFit(late + "; no coarser spacing tried is on time", true);
  }
  emit message("This computer renders the tool late: " + summary + ". The Haptics panel offers the spacing.", 15000);
}

bool HapticsController::replaying() const { return replay_.active(); }

void HapticsController::resetDevice() {
  if (!session_.hasScene()) return;
  const runtime::LiveValues& live = session_.live();
  if (session_.simulatedDevice() != nullptr && live.tool != nullptr && live.hapticField() != nullptr) {
    // A placement (proxy and device together, recorded as such, no spring stretched over the
    // jump): the device at the initial pose, the proxy at a legal pose near it (drilling only
    // lowers the field, so a pose free on the scan is free on the drilled copy).
    input_.place(runtime::legalPoseNear(*live.hapticField(), live.tool->point_shell, live.X_WT_initial,
                                        live.hapticIsovalue()),
                 live.X_WT_initial);
    return;
  }
  input_.setDevicePose(live.X_WT_initial);  // the picture's device
  session_.resetDevice();                   // and the proxy at a legal pose near it
}

void HapticsController::start() {
  if (replaying()) {
    recorder_.showNotice("A recording is replayed: Close Replay first", 4000);
    return;
  }
  session_.startHaptics();
}

void HapticsController::refresh() {
  panel_.showSession(session_, tools_.choices(), tools_.currentIndex(), devices_.limitsText(), replaying());
  if (run_action_ != nullptr) {
    const QSignalBlocker block(run_action_);
    run_action_->setEnabled(session_.hapticThread() != nullptr && !replaying());
    run_action_->setChecked(session_.hapticsRunning());
  }
}

QMenu* HapticsController::addMenu(QMenuBar* bar, QWidget* window) {
  QMenu* menu = bar->addMenu("&Haptics");
  run_action_ = menu->addAction("&Run Haptic Thread", this, [this](bool on) { on ? start() : session_.stopHaptics(); });
  run_action_->setCheckable(true);
  run_action_->setShortcut(QKeySequence("Ctrl+H"));
  menu->addAction("Reset &Device", this, [this] { resetDevice(); })->setShortcut(QKeySequence("Ctrl+Home"));
  QAction* touch = menu->addAction("&Touch the Surface", this, [this] {
    if (!input_.touchSurface(DeviceInput::kTouchDepth_m)) emit message("No simulated device, or no surface along the view through the volume's centre", 4000);
  });
  touch->setShortcut(QKeySequence("Ctrl+T"));
  touch->setToolTip("Puts the tool on the felt surface (the felt segments, else the scan) along the view direction, resting with the device 3 mm in: a placement, not the hand's motion");
  menu->addAction("&Guide with Recording...", this, [this, window] {
    const QString file = QFileDialog::getOpenFileName(window, "Guide with an expert's recording", QString(),
                                                      "Recordings (*.vhrec)");
    QString error;
    if (!file.isEmpty() && !guideWith(file, &error)) QMessageBox::warning(window, "Guide with Recording", error);
  });
  stop_guide_action_ = menu->addAction("Stop G&uidance", this, [this] { stopGuidance(); });
  stop_guide_action_->setEnabled(false);
  menu->addSeparator();
  menu->addAction(recorder_.recordAction());
  menu->addAction(recorder_.markerAction());
  window->addAction(recorder_.markerAction());  // M works wherever the focus is in the window
  menu->addSeparator();
  devices_.setMenu(menu->addMenu("De&vice"));
  refresh();
  return menu;
}

bool HapticsController::guideWith(const QString& file, QString* error) {
  try {
    if (!session_.hasScene()) throw std::invalid_argument("open a scan first");
    // The same scan as the recording's (its dataset SHA-256), as report --reference checks.
    const std::string metadata = runtime::makeSessionMetadata(session_.loaded(), session_.live(), {});
    guide_ = runtime::loadExpertPath(file.toStdString(), metadata, runtime::RecordingFiles::kVhrecOnly);
  } catch (const std::exception& e) {
    if (error != nullptr) *error = QString("%1: %2").arg(file, QString::fromStdString(e.what()));
    return false;
  }
  applyGuidance();
  emit guidanceChanged();
  if (!guide_->damage().empty()) {  // guided along part of the path: never without a word
    emit message(QString("Guided along part of %1: %2")
                     .arg(QString::fromStdString(guide_->fileName()), QString::fromStdString(guide_->damage())),
                 15000);
  } else {
    emit message(QString("Guided along %1 (%2 segments)").arg(QString::fromStdString(guide_->fileName())).arg(guide_->path().size()), 4000);
  }
  return true;
}

void HapticsController::stopGuidance() {
  guide_.reset();
  if (runtime::HapticThread* thread = session_.hapticThread()) thread->setGuidance(nullptr, haptics::GuidanceGains{});
  if (stop_guide_action_ != nullptr) stop_guide_action_->setEnabled(false);
  emit guidanceChanged();
}

void HapticsController::applyGuidance() {
  runtime::HapticThread* thread = session_.hapticThread();
  if (thread != nullptr && guide_ != nullptr && thread->guidance() != guide_) thread->setGuidance(guide_, haptics::GuidanceGains{});
  if (stop_guide_action_ != nullptr) stop_guide_action_->setEnabled(guide_ != nullptr);
}

}  // namespace vh::ui
