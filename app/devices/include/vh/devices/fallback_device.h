#pragma once
/// @file
/// Hot-plug fallback: a hardware device paired with a simulated stand-in. While the hardware is
/// connected its samples and commands pass through; when it disappears the simulated device
/// (mouse / keyboard, driven by the GUI) takes over, the hardware gets nothing and the safety
/// layer re-engages from zero (the sample's `connection` changes at every switch). After
/// Device::reconnect() the hardware takes over again at its next sample.
///
/// The GUI places the stand-in (SimulatedDevice::setPose(), e.g. at the last snapshot's X_WD)
/// when it sees usingFallback() turn true.

#include <atomic>
#include <memory>
#include <string>

#include "vh/runtime/device.h"

namespace vh::devices {

class FallbackDevice final : public runtime::Device {
 public:
  /// @throws std::invalid_argument for a null device.
  FallbackDevice(std::shared_ptr<runtime::Device> hardware, std::shared_ptr<runtime::SimulatedDevice> fallback);

  /// Any thread: true while the samples come from the simulated stand-in.
  bool usingFallback() const noexcept { return using_fallback_.load(std::memory_order_acquire); }
  const std::shared_ptr<runtime::Device>& hardware() const noexcept { return hardware_; }
  const std::shared_ptr<runtime::SimulatedDevice>& simulated() const noexcept { return fallback_; }

  std::string name() const override;
  runtime::DeviceIdentity identity() const override { return hardware_->identity(); }
  runtime::DeviceLimits limits() const noexcept override { return hardware_->limits(); }
  runtime::SafetyPolicy safetyPolicy() const noexcept override { return hardware_->safetyPolicy(); }
  runtime::DofMask sensedDof() const noexcept override { return hardware_->sensedDof(); }
  runtime::DofMask actuatedDof() const noexcept override { return hardware_->actuatedDof(); }
  /// The hardware's state (the stand-in is always there).
  bool connected() const noexcept override { return hardware_->connected(); }
  std::string problem() const override { return hardware_->problem(); }
  void reconnect() override { hardware_->reconnect(); }
  /// The stand-in while it stands in (usingFallback()), else null.
  runtime::SimulatedDevice* simulatedDevice() noexcept override { return usingFallback() ? fallback_.get() : nullptr; }
  /// Servo thread: the hardware's sample while connected, else the stand-in's (always true).
  bool read(runtime::DeviceSample& sample) noexcept override;
  /// Servo thread: to whichever device the last read came from.
  void command(const Eigen::Vector3d& force_W_N, const Eigen::Vector3d& torque_W_Nm) noexcept override;

 private:
  std::shared_ptr<runtime::Device> hardware_;
  std::shared_ptr<runtime::SimulatedDevice> fallback_;
  std::atomic<bool> using_fallback_{false};
  bool last_from_fallback_ = false;  // servo thread only
  std::uint32_t switches_ = 0;       // servo thread only
};

}  // namespace vh::devices
