#pragma once
#include <memory>
/// @file
/// The Haptics dock and the Haptics menu: shows the Session (running, gains, tool and its point
/// shell, device and its limits) in the HapticsPanel whenever the session changes, and sends the
/// panel's and the menu's commands to the session, the tool picker and the device picker. While
/// a replay is shown the haptic thread waits: starting it is refused with a notice.
///
/// Whenever a scene or a tool is chosen, the fit check (runtime/tool_fit.h) runs beside the
/// window (ToolFitChecker); a tool this computer does not render on time is said in the panel
/// and the status bar, with the finest spacing that fits offered as a button.
///
/// Data flows one way: Session -> this -> HapticsPanel; panel and menu -> this -> Session.
/// GUI thread only.

#include <QObject>
#include <QString>

class QAction;
class QMenu;
class QMenuBar;
class QWidget;

namespace vh::runtime {
class ExpertPath;
class Session;
struct ToolFit;
}

namespace vh::ui {

class DeviceInput;
class DevicePicker;
class HapticsPanel;
class ReplayController;
class SessionRecorder;
class ToolFitChecker;
class ToolPicker;

class HapticsController : public QObject {
  Q_OBJECT

 public:
  /// Observes `session` from now on; every reference outlives this.
  HapticsController(runtime::Session& session, HapticsPanel& panel, ToolPicker& tools, DevicePicker& devices,
                    DeviceInput& input, SessionRecorder& recorder, ReplayController& replay, QObject* parent = nullptr);
  ~HapticsController() override;

  /// Starts the haptic threads; refused (a notice) while a replay is shown.
  void start();
  /// Adds the Haptics menu to `bar`: run, reset device, touch, record, marker (M anywhere in
  /// `window`), the device submenu. @return the menu (others add their actions to it).
  QMenu* addMenu(QMenuBar* bar, QWidget* window);
  /// Shows the session in the panel and the menu now.
  void refresh();
  /// Haptics > Guide with Recording...: guidance toward the expert's path in `file` (a
  /// recording of the same scan, runtime/guidance.h) from now on, kept over rebuilt haptic
  /// threads. @return false with a message when the file cannot be read or is of another scan.
  bool guideWith(const QString& file, QString* error = nullptr);
  /// Guidance off. A recording started while guidance is on holds its "guidance" event too
  /// (the expert's file and checksum: a replay shows the expert's ghost).
  void stopGuidance();
  /// The fit check of the session's tool (run whenever a scene or a tool is chosen).
  ToolFitChecker& fitChecker() noexcept { return *fit_checker_; }
  /// The expert's path guided along, or null.
  const std::shared_ptr<const runtime::ExpertPath>& guide() const noexcept { return guide_; }

 signals:
  /// A short text for the status bar.
  void message(const QString& text, int timeout_ms);
  /// Guidance started, stopped or went with the scan it was of (guide() tells which).
  void guidanceChanged();

 private:
  bool replaying() const;
  /// Reset Device: the simulated device to the scene's initial pose, the proxy to a legal pose
  /// near the device (Session::resetDevice()).
  void resetDevice();

  runtime::Session& session_;
  HapticsPanel& panel_;
  ToolPicker& tools_;
  DevicePicker& devices_;
  DeviceInput& input_;
  SessionRecorder& recorder_;
  ReplayController& replay_;
  QAction* run_action_ = nullptr;
  QAction* stop_guide_action_ = nullptr;
  int observer_ = 0;
  /// Guidance (Guide with Recording...): the path, applied to every haptic thread the session builds.
  std::shared_ptr<const runtime::ExpertPath> guide_;
  ToolFitChecker* fit_checker_;  ///< Owned as a child.
  /// The fit check's verdict, in the panel and (when late) the status bar.
  void showToolFit(const runtime::ToolFit& fit);
  void applyGuidance();
};

}  // namespace vh::ui
