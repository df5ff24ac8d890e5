#include "vh/ui/devices/device_picker.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <iostream>

#include <QAction>
#include <QActionGroup>
#include <QFileDialog>
#include <QFileInfo>
#include <QMenu>
#include <QMessageBox>
#include <QSettings>
#include <QSignalBlocker>
#include <QTimer>

#include "vh/devices/device_catalog.h"
#include "vh/devices/fallback_device.h"

namespace vh::ui {
namespace {

constexpr char kFalconFirmwareKey[] = "devices/falcon_firmware";
constexpr int kHotplugPeriodMs = 1000;
const QString kSimulatedChoice = "Simulated device (mouse/keyboard)";

QString q(const std::string& s) { return QString::fromStdString(s); }

/// "12 N", "unbounded".
QString limitValue(double v, const char* unit, int decimals = 1) {
  if (!std::isfinite(v)) return "unbounded";
  return QString::fromUtf8("%1 %2").arg(v, 0, 'f', decimals).arg(QString::fromUtf8(unit));
}

}  // namespace

QString deviceLimitsText(const runtime::Device& device) {
  const runtime::DeviceLimits l = device.limits();
  if (!std::isfinite(l.max_force_N) && !std::isfinite(l.workspace_radius_m)) {
    return "No force or workspace limits (no hardware).";
  }
  QStringList lines;
  lines << QString::fromUtf8("max force %1, torque %2")
               .arg(limitValue(l.max_force_N, "N"), limitValue(l.max_torque_Nm, "N\u00b7m", 2));
  lines << QString::fromUtf8("max stiffness %1, %2")
               .arg(limitValue(l.max_linear_stiffness_N_per_m, "N/m", 0),
                    limitValue(l.max_angular_stiffness_Nm_per_rad, "N\u00b7m/rad", 2));
  lines << QString("workspace radius %1")
               .arg(std::isfinite(l.workspace_radius_m) ? QString("%1 mm").arg(l.workspace_radius_m * 1e3, 0, 'f', 0)
                                                        : QString("unbounded"));
  return lines.join("\n");
}

DevicePicker::DevicePicker(runtime::Session& session, QWidget* dialog_parent)
    : QObject(dialog_parent), session_(session), dialog_parent_(dialog_parent) {
  try {
    catalog_ = std::make_shared<devices::DeviceCatalog>();
  } catch (const std::exception& e) {  // no backend at all: only the simulated device
    std::cerr << "volume-haptics: no device backends: " << e.what() << std::endl;
  }
  actions_ = new QActionGroup(this);
  actions_->setExclusive(true);
  connect(actions_, &QActionGroup::triggered, this, [this](QAction* action) {
    if (!choose(action->data().toInt())) sync();
  });
  rescan();
  if (catalog_ != nullptr) {
    hotplug_ = std::make_unique<devices::HotplugMonitor>(catalog_, std::chrono::milliseconds(kHotplugPeriodMs));
    hotplug_->start();
    hotplug_timer_ = new QTimer(this);
    hotplug_timer_->setInterval(kHotplugPeriodMs);
    connect(hotplug_timer_, &QTimer::timeout, this, &DevicePicker::pollHotplug);
    hotplug_timer_->start();
  }
}

DevicePicker::~DevicePicker() { hotplug_.reset(); }

void DevicePicker::setMenu(QMenu* menu) {
  menu_ = menu;
  showChoices();
}

void DevicePicker::rescan() {
  std::vector<devices::FoundDevice> found;
  problems_.clear();
  if (catalog_ != nullptr) {
    found = catalog_->enumerate();  // never throws
    problems_ = catalog_->problems();
  }
  // The device in use stays listed (and selected) even when it did not answer this time.
  int picked_index = -1;
  if (picked_ != nullptr && picked_ == session_.sharedDevice() && choice_ > 0 &&
      choice_ <= static_cast<int>(found_.size())) {
    const devices::FoundDevice in_use = found_[static_cast<std::size_t>(choice_ - 1)];
    auto it = std::find_if(found.begin(), found.end(), [&](const devices::FoundDevice& d) { return d.sameDeviceAs(in_use); });
    if (it == found.end()) it = found.insert(found.end(), in_use);
    picked_index = static_cast<int>(it - found.begin()) + 1;
  }
  picked_index_ = picked_index;
  found_ = std::move(found);
  if (!problems_.empty()) emit message("Listing devices: " + q(problems_.front()), 6000);
  showChoices();
}

QStringList DevicePicker::choices() const {
  QStringList labels{kSimulatedChoice};
  for (const devices::FoundDevice& d : found_) labels << q(d.label());
  return labels;
}

QStringList DevicePicker::notInstalled() const {
  QStringList out;
  if (catalog_ == nullptr) return out;
  for (const devices::VendorStatus& v : catalog_->vendorStatus()) {
    if (!v.installed) out << q(v.title + ": not installed");
  }
  return out;
}

void DevicePicker::showChoices() {
  QString problems;
  for (const std::string& p : problems_) problems += (problems.isEmpty() ? "" : "\n") + q(p);
  const QStringList labels = choices();
  if (menu_ != nullptr) {
    menu_->clear();
    for (QAction* a : actions_->actions()) actions_->removeAction(a);
    for (int i = 0; i < labels.size(); ++i) {
      QAction* action = menu_->addAction(labels[i]);
      action->setCheckable(true);
      action->setData(i);
      actions_->addAction(action);
    }
    if (catalog_ != nullptr) {
      for (const devices::VendorStatus& v : catalog_->vendorStatus()) {
        if (v.installed) continue;
        QAction* missing = menu_->addAction(q(v.title + ": not installed"));
        missing->setEnabled(false);
        missing->setToolTip(q(v.detail));
      }
    }
    if (labels.size() == 1) {
      QAction* none = menu_->addAction(problems.isEmpty() ? "No haptic device found" : "No haptic device found (see tooltip)");
      none->setEnabled(false);
    }
    menu_->addSeparator();
    QAction* rescan_action = menu_->addAction("&Rescan Devices", this, &DevicePicker::rescan);
    rescan_action->setToolTip(problems.isEmpty() ? "List the connected devices again" : problems);
    menu_->setToolTipsVisible(true);
  }
  emit choicesChanged(labels, -1, problems);
  sync();
}

void DevicePicker::sync() {
  int choice = -1;
  runtime::Device* device = session_.device();
  if (device != nullptr) {
    if (picked_ != nullptr && device == picked_.get()) {
      choice = picked_index_;
    } else if (dynamic_cast<runtime::SimulatedDevice*>(device) != nullptr) {
      choice = 0;
    }
  }
  if (picked_ != nullptr && device != picked_.get()) limits_text_.clear();
  choice_ = choice;
  for (QAction* a : actions_->actions()) {
    const QSignalBlocker block(a);
    a->setChecked(a->data().toInt() == choice);
  }
  emit choiceChanged(choice);
}

bool DevicePicker::choose(int index) {
  last_error_.clear();
  if (index < 0 || index > static_cast<int>(found_.size())) return false;
  const haptics::Pose X_WP = session_.proxyPose();
  if (index == 0) {
    if (dynamic_cast<runtime::SimulatedDevice*>(session_.device()) == nullptr) {
      picked_.reset();
      limits_text_.clear();
      session_.setDevice(std::make_shared<runtime::SimulatedDevice>(X_WP));
    }
    sync();
    return true;
  }
  const devices::FoundDevice found = found_[static_cast<std::size_t>(index - 1)];
  if (picked_ != nullptr && session_.device() == picked_.get() && picked_index_ == index) return true;
  devices::OpenOptions options;
  options.X_WT_initial = session_.live().X_WT_initial;
  if (found.kind == "falcon") {
    QSettings settings;
    QString firmware = settings.value(kFalconFirmwareKey).toString();
    if ((firmware.isEmpty() || !QFileInfo::exists(firmware)) && interactive_) {
      firmware = QFileDialog::getOpenFileName(dialog_parent_, "Novint Falcon firmware", firmware,
                                              "Falcon firmware (*.bin *.rbf);;All files (*)");
      if (firmware.isEmpty()) {
        sync();
        return false;  // cancelled
      }
      settings.setValue(kFalconFirmwareKey, firmware);
    }
    if (!firmware.isEmpty()) options.falcon_firmware = firmware.toStdString();
  }
  std::shared_ptr<runtime::Device> device;
  QString limits;
  try {
    std::shared_ptr<runtime::MappedDevice> hardware = catalog_->open(found, options);
    limits = deviceLimitsText(*hardware);
    device = std::make_shared<devices::FallbackDevice>(hardware, std::make_shared<runtime::SimulatedDevice>(X_WP));
  } catch (const std::exception& e) {
    last_error_ = q(e.what());
    if (interactive_) {
      QMessageBox::warning(dialog_parent_, "VolumeHaptics", "Could not open " + q(found.label()) + ":\n" + last_error_);
    } else {
      std::cerr << "volume-haptics: could not open " << found.label() << ": " << e.what() << std::endl;
    }
    sync();
    return false;
  }
  picked_ = device;
  picked_index_ = index;
  limits_text_ = limits;
  session_.setDevice(device);
  sync();
  emit message("Using " + q(found.label()), 4000);
  return true;
}

void DevicePicker::pollHotplug() {
  if (hotplug_ == nullptr) return;
  const std::vector<devices::HotplugEvent> events = hotplug_->takeEvents();
  if (events.empty()) return;
  bool changed = false;
  QString text;
  for (const devices::HotplugEvent& event : events) {
    const bool listed = std::any_of(found_.begin(), found_.end(),
                                    [&](const devices::FoundDevice& d) { return d.sameDeviceAs(event.device); });
    if (event.kind == devices::HotplugEvent::Kind::kArrived) {
      if (listed) continue;  // already listed (e.g. the monitor's first poll)
      text = "Device connected: " + q(event.device.label());
      const bool in_use_and_lost = picked_ != nullptr && session_.device() == picked_.get() && !picked_->connected() &&
                                   picked_index_ > 0 &&
                                   found_[static_cast<std::size_t>(picked_index_ - 1)].sameDeviceAs(event.device);
      if (in_use_and_lost) text += " (pick it again in Haptics > Device to reconnect)";
    } else {
      text = "Device removed: " + q(event.device.label());
      if (auto* fallback = dynamic_cast<devices::FallbackDevice*>(session_.device())) {
        // The stand-in takes over where the hardware left the tool.
        runtime::HapticSnapshot snapshot;
        if (session_.latestSnapshot(snapshot)) fallback->simulated()->setPose(snapshot.X_WD);
      }
    }
    changed = true;
  }
  if (!changed) return;
  emit message(text, 6000);
  rescan();
}

}  // namespace vh::ui
