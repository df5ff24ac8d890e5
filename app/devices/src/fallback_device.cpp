#include "vh/devices/fallback_device.h"

#include <stdexcept>

namespace vh::devices {

FallbackDevice::FallbackDevice(std::shared_ptr<runtime::Device> hardware, std::shared_ptr<runtime::SimulatedDevice> fallback)
    : hardware_(std::move(hardware)), fallback_(std::move(fallback)) {
  if (!hardware_ || !fallback_) throw std::invalid_argument("FallbackDevice: no device");
}

std::string FallbackDevice::name() const {
  return usingFallback() ? hardware_->name() + " (disconnected: simulated device)" : hardware_->name();
}

bool FallbackDevice::read(runtime::DeviceSample& sample) noexcept {
  bool from_fallback = false;
  if (!(hardware_->connected() && hardware_->read(sample))) {
    fallback_->read(sample);
    from_fallback = true;
  }
  if (from_fallback != last_from_fallback_) {
    ++switches_;
    last_from_fallback_ = from_fallback;
    using_fallback_.store(from_fallback, std::memory_order_release);
  }
  sample.connection += switches_;  // both only grow: any switch or reconnection changes the sum
  return true;
}

void FallbackDevice::command(const Eigen::Vector3d& force_W_N, const Eigen::Vector3d& torque_W_Nm) noexcept {
  if (last_from_fallback_) {
    fallback_->command(force_W_N, torque_W_Nm);
  } else {
    hardware_->command(force_W_N, torque_W_Nm);
  }
}

}  // namespace vh::devices
