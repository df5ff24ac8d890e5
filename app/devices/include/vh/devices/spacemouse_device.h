#pragma once
/// @file
/// A 3Dconnexion SpaceMouse as a runtime::Device: 6-DOF input, no force. The puck's deflection
/// sets the velocity of a virtual handle pose (rate control, spacemouse_protocol.h), integrated
/// on the servo thread at every read.
///
/// Threads: one I/O thread reads HID reports (about 60 per second while the puck moves) and
/// hands the decoded state to the servo thread through a triple buffer; read() / command()
/// never block, allocate or throw. The thread, the connected flag, the connection counter and
/// the problem text are IoThreadDevice's.
///
/// Samples are in the device base frame B (spacemouse_protocol.h): wrap the device in a
/// runtime::MappedDevice (the DeviceCatalog does) to use it in W.

#include <atomic>
#include <memory>
#include <optional>
#include <string>

#include "vh/devices/io_thread_device.h"
#include "vh/devices/spacemouse_protocol.h"
#include "vh/devices/transport.h"
#include "vh/runtime/device.h"

namespace vh::devices {

/// How a SpaceMouseDevice reads and moves.
struct SpaceMouseOptions {
  spacemouse::RateControlOptions rate;
  /// Axis map from the HID axes into B; default: the model's (spacemouse::kDefaultAxisMap).
  std::optional<spacemouse::AxisMap> axis_map;
  /// I/O thread read timeout [ms]. < 0: plain blocking reads, for umockdev's emulated hidraw
  /// (which never signals poll); the I/O thread then stops only at the next report or when the
  /// device goes away.
  int read_timeout_ms = 100;
  bool led = true;  ///< Switch the puck's LED on while open.
};

/// A SpaceMouse (any model of spacemouse::knownModels()).
class SpaceMouseDevice final : public IoThreadDevice {
 public:
  /// Opens `device` through `backend` and starts the I/O thread; the handle starts at rest at
  /// B's origin.
  /// @throws std::runtime_error naming the device when it cannot be opened;
  ///         std::invalid_argument for a vendor / product id that is not a known model.
  SpaceMouseDevice(std::shared_ptr<HidBackend> backend, HidDeviceInfo device, SpaceMouseOptions options = {});
  ~SpaceMouseDevice() override;  ///< Stops the I/O thread (see SpaceMouseOptions::read_timeout_ms).
  SpaceMouseDevice(const SpaceMouseDevice&) = delete;
  SpaceMouseDevice& operator=(const SpaceMouseDevice&) = delete;

  std::string name() const override { return model_->name; }
  runtime::DeviceIdentity identity() const override;
  /// No force or torque; the workspace is the rate controller's ball.
  runtime::DeviceLimits limits() const noexcept override;
  runtime::DofMask sensedDof() const noexcept override { return runtime::kDofAll; }
  runtime::DofMask actuatedDof() const noexcept override { return runtime::kDofNone; }
  /// Re-finds the same model (same serial when known) and reopens it; the handle keeps its pose.
  /// @throws std::runtime_error when it cannot be found or opened.
  void reconnect() override;
  /// Servo thread: integrates the latest deflection since the previous read. False while
  /// disconnected.
  bool read(runtime::DeviceSample& sample) noexcept override;
  /// Servo thread: recorded only (the device has no motors).
  void command(const Eigen::Vector3d& force_B_N, const Eigen::Vector3d& torque_B_Nm) noexcept override;

  /// One consumer thread: the latest command sent. @return true when newer than the last call's.
  bool lastCommand(runtime::DeviceCommand& out) noexcept { return commands_.last(out); }
  /// Any thread: puts the handle back at B's origin with the identity orientation at the next read.
  void recentre() noexcept { recentre_.store(true, std::memory_order_release); }
  /// Any thread: reports decoded so far; battery percent (-1: not reported).
  std::uint64_t reportsReceived() const noexcept { return reports_.load(std::memory_order_relaxed); }
  int batteryPercent() const noexcept { return battery_.load(std::memory_order_relaxed); }
  // problem() (IoThreadDevice): why the device is disconnected; empty when fine.
  const spacemouse::Model& model() const noexcept { return *model_; }

 private:
  void openAndStart();
  /// Stops and joins the I/O thread, turns the LED off when still connected, drops the transport.
  void stopIo() noexcept;
  void ioLoop() noexcept;

  std::shared_ptr<HidBackend> backend_;
  HidDeviceInfo info_;
  SpaceMouseOptions options_;
  const spacemouse::Model* model_;
  spacemouse::AxisMap axes_;
  std::unique_ptr<HidTransport> transport_;  // I/O thread while it runs
  std::atomic<bool> recentre_{false};
  std::atomic<std::uint64_t> reports_{0};
  std::atomic<int> battery_{-1};
  runtime::TripleBuffer<spacemouse::State> states_;  // I/O thread -> servo thread
  runtime::CommandLog commands_;                     // servo thread -> one consumer
  // Servo thread only:
  spacemouse::State servo_state_;
  spacemouse::RateController controller_;
  double t0_s_ = 0.0;
  double last_read_s_ = -1.0;
};

}  // namespace vh::devices
