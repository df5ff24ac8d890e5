#pragma once
/// @file
/// The device picker (Haptics > Device and the Haptics dock's Device group): lists the
/// simulated device and the hardware devices found (devices::DeviceCatalog), watches them come
/// and go (devices::HotplugMonitor, polled from a GUI timer), opens the one picked mapped around
/// the scene's initial tool pose, wrapped in a devices::FallbackDevice, and hands it to
/// runtime::Session::setDevice(). It keeps which entry is in use; the device itself is the
/// session's. GUI thread only.

#include <memory>
#include <string>
#include <vector>

#include <QObject>
#include <QString>
#include <QStringList>

#include "vh/runtime/device.h"
#include "vh/runtime/session.h"

class QActionGroup;
class QMenu;
class QTimer;
class QWidget;

namespace vh::devices {
class DeviceCatalog;
class HotplugMonitor;
struct FoundDevice;
}  // namespace vh::devices

namespace vh::ui {

/// A device's limits as text for the haptics panel ("max force 8.5 N, torque ..."), or a line
/// saying it has none (no hardware).
QString deviceLimitsText(const runtime::Device& device);

class DevicePicker : public QObject {
  Q_OBJECT

 public:
  /// Lists the devices at once and starts the hot-plug monitor; `dialog_parent` parents the
  /// Falcon firmware file dialog and error boxes. `session` must outlive the picker.
  DevicePicker(runtime::Session& session, QWidget* dialog_parent);
  ~DevicePicker() override;  ///< Joins the hot-plug monitor's thread.

  /// Fills `menu` with the entries (and Rescan) from now on.
  void setMenu(QMenu* menu);
  /// The Haptics > Device submenu given to setMenu() (null before).
  QMenu* menu() const noexcept { return menu_; }
  /// Dialogs (firmware file, open errors) when true; else messages go to stderr only.
  void setInteractive(bool interactive) { interactive_ = interactive; }

  /// Lists the devices again (never throws): entry 0 the simulated device, then the devices found.
  void rescan();
  /// "Simulated device (mouse/keyboard)", then FoundDevice::label()s.
  QStringList choices() const;
  /// The vendor back-ends whose SDK is not installed, e.g. "Force Dimension (DHD): not
  /// installed"; the menu lists them disabled (their reason in the tooltip).
  QStringList notInstalled() const;
  /// The entry in use; -1 when the device is none of them (e.g. named by the scene file).
  int currentChoice() const noexcept { return choice_; }
  /// Switches to entry `index` (0: a SimulatedDevice at the proxy's pose). On failure the
  /// current device stays and lastError() says why. @return true when the device was switched.
  bool choose(int index);
  QString lastError() const { return last_error_; }
  /// The limits of the hardware device in use (empty for other devices).
  QString limitsText() const { return limits_text_; }
  /// Re-reads which entry is in use (after the session's device changed elsewhere).
  void sync();

 signals:
  /// The entries changed: their labels, the entry in use, and the listing's problems.
  void choicesChanged(const QStringList& labels, int current, const QString& problems);
  /// The entry in use changed (-1: none of them).
  void choiceChanged(int current);
  /// A line for the status bar ("Using ...", "Device removed: ...").
  void message(const QString& text, int ms);

 private:
  void showChoices();
  void pollHotplug();

  runtime::Session& session_;
  QWidget* dialog_parent_;
  bool interactive_ = true;
  std::shared_ptr<devices::DeviceCatalog> catalog_;
  std::unique_ptr<devices::HotplugMonitor> hotplug_;
  std::vector<devices::FoundDevice> found_;
  std::vector<std::string> problems_;
  std::shared_ptr<runtime::Device> picked_;  // the hardware device the picker opened
  int picked_index_ = -1;                    // its entry
  int choice_ = -1;
  QString last_error_;
  QString limits_text_;
  QMenu* menu_ = nullptr;
  QActionGroup* actions_ = nullptr;
  QTimer* hotplug_timer_ = nullptr;
};

}  // namespace vh::ui
