#include "vh/devices/spacemouse_device.h"

#include "device_clock.h"

#include <chrono>
#include <cstdio>
#include <stdexcept>

namespace vh::devices {

namespace {

using detail::steadySeconds;

std::string idText(std::uint16_t vendor_id, std::uint16_t product_id) {
  char text[16];
  std::snprintf(text, sizeof text, "%04x:%04x", vendor_id, product_id);
  return text;
}

}  // namespace

SpaceMouseDevice::SpaceMouseDevice(std::shared_ptr<HidBackend> backend, HidDeviceInfo device, SpaceMouseOptions options)
    : backend_(std::move(backend)),
      info_(std::move(device)),
      options_(std::move(options)),
      model_(spacemouse::findModel(info_.vendor_id, info_.product_id)),
      controller_(options_.rate),
      t0_s_(steadySeconds()) {
  if (!backend_) throw std::invalid_argument("SpaceMouseDevice: no HID backend");
  if (model_ == nullptr) {
    throw std::invalid_argument("SpaceMouseDevice: " + idText(info_.vendor_id, info_.product_id) +
                                " is not a known SpaceMouse model");
  }
  axes_ = options_.axis_map.value_or(model_->axes);
  controller_.reset();
  openAndStart();
}

SpaceMouseDevice::~SpaceMouseDevice() { stopIo(); }

runtime::DeviceIdentity SpaceMouseDevice::identity() const {
  return {model_->name, info_.manufacturer.empty() ? std::string("3Dconnexion") : info_.manufacturer, info_.serial,
          backend_->name() + " " + info_.path};
}

runtime::DeviceLimits SpaceMouseDevice::limits() const noexcept {
  runtime::DeviceLimits l;
  l.max_force_N = 0.0;
  l.max_torque_Nm = 0.0;
  l.workspace_radius_m = options_.rate.workspace_radius_m;
  // Rate control: the pose is integrated from the puck's deflection in steps of up to
  // max_step_s, so it cannot jump (a bad report is a bounded rate), and it stays inside the
  // workspace ball, which the plausibility test checks: no speed limit.
  l.max_speed_m_per_s = runtime::DeviceLimits::kUnbounded;
  l.max_angular_speed_rad_per_s = runtime::DeviceLimits::kUnbounded;
  return l;
}

void SpaceMouseDevice::openAndStart() {
  transport_ = backend_->open(info_.path);
  if (options_.led) {
    const auto led = spacemouse::ledReport(true);
    transport_->write(led.data(), led.size());  // best effort: not every model has the LED report
  }
  clearProblem();
  startIoThread([this] { ioLoop(); });
}

void SpaceMouseDevice::stopIo() noexcept {
  stopIoThread();
  if (transport_ && connected() && options_.led) {
    const auto led = spacemouse::ledReport(false);
    transport_->write(led.data(), led.size());
  }
  transport_.reset();
}

void SpaceMouseDevice::reconnect() {
  stopIo();
  markDisconnected();
  const std::vector<HidDeviceInfo> found = backend_->enumerate();
  for (const HidDeviceInfo& d : found) {
    if (d.vendor_id != info_.vendor_id || d.product_id != info_.product_id) continue;
    if (!info_.serial.empty() && d.serial != info_.serial) continue;
    info_ = d;
    openAndStart();
    return;
  }
  throw std::runtime_error(std::string(model_->name) + " (" + idText(info_.vendor_id, info_.product_id) +
                           "): not found (is it plugged in?)");
}

void SpaceMouseDevice::ioLoop() noexcept {
  HidTransport& hid = *transport_;
  spacemouse::State state;
  std::uint8_t report[64];
  while (!stopRequested()) {
    const int n = hid.read(report, sizeof report, options_.read_timeout_ms);
    if (n < 0) {
      const std::string why = hid.lastError();
      setProblem({"unplugged or failed: ", why});
      markDisconnected();
      break;
    }
    if (n == 0) continue;
    const unsigned changed = spacemouse::decodeReport(report, static_cast<std::size_t>(n), state);
    if (changed == 0) continue;
    reports_.fetch_add(1, std::memory_order_relaxed);
    if (changed & spacemouse::kChangedBattery) battery_.store(state.battery_percent, std::memory_order_relaxed);
    states_.writeSlot() = state;
    states_.publish();
  }
}

bool SpaceMouseDevice::read(runtime::DeviceSample& sample) noexcept {
  const double now_s = steadySeconds() - t0_s_;
  if (!connected()) {
    last_read_s_ = now_s;  // no motion is integrated over the gap
    return false;
  }
  states_.read(servo_state_);
  if (recentre_.exchange(false, std::memory_order_acq_rel)) controller_.reset();
  const double dt = last_read_s_ < 0.0 ? 0.0 : now_s - last_read_s_;
  last_read_s_ = now_s;
  controller_.step(spacemouse::deflection(servo_state_, axes_, options_.rate), dt);
  sample.time_s = now_s;
  sample.X_WD = controller_.pose();
  sample.v_WD_m_per_s = controller_.velocity_m_per_s();
  sample.w_WD_rad_per_s = controller_.angularVelocity_rad_per_s();
  sample.buttons = servo_state_.buttons;
  sample.connection = connection();
  sample.valid = true;
  return true;
}

void SpaceMouseDevice::command(const Eigen::Vector3d& force_B_N, const Eigen::Vector3d& torque_B_Nm) noexcept {
  commands_.record(force_B_N, torque_B_Nm);
}

}  // namespace vh::devices
