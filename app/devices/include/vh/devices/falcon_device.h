#pragma once
/// @file
/// The Novint Falcon as a runtime::Device (3-DOF position, 3-DOF force) over a UsbTransport:
/// firmware upload from a user-supplied file, the I/O loop on its own thread, forward
/// kinematics and force through the Jacobian (falcon_kinematics.h), hot-plug detection.
///
/// Threads: the constructor and reconnect() run on the caller's (GUI or loader) thread; one I/O
/// thread exchanges 16-byte packets with the device as fast as it answers (about 1 kHz); the
/// servo thread's read() / command() only touch lock-free triple buffers and atomics. The
/// thread, the connected flag, the connection counter and the problem text are IoThreadDevice's.
///
/// Samples are in the device base frame B (falcon_kinematics.h: x right, y up, z towards the
/// user, origin at the workspace centre): wrap the device in a runtime::MappedDevice (the
/// DeviceCatalog does) to use it in W.

#include <atomic>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "vh/devices/falcon_protocol.h"
#include "vh/devices/io_thread_device.h"
#include "vh/devices/transport.h"
#include "vh/runtime/device.h"

namespace vh::devices {

/// Timing of the firmware upload.
struct FalconUploadOptions {
  int boot_check_attempts = falcon::kBootCheckAttempts;  ///< Step 4 retries.
  unsigned timeout_ms = 100;                             ///< Per transfer [ms].
  int max_empty_reads = 20;  ///< Reads without data before an echo counts as missing.
};

/// Reads the user's Falcon firmware file (Novint's nvent_firmware.bin; never shipped here).
/// @throws std::runtime_error naming the file when it is missing, unreadable, empty or larger
///         than 64 KiB.
std::vector<std::uint8_t> readFalconFirmwareFile(const std::filesystem::path& path);

/// Uploads firmware into a Falcon's boot loader (devices.md steps 1-7: FTDI set-up, boot check
/// with retries, loader check, the image in blocks of at most 62 bytes with every byte's echo
/// compared, normal mode).
/// @throws std::runtime_error "Falcon firmware upload: STEP: problem" on the first failure.
void uploadFalconFirmware(UsbTransport& usb, std::span<const std::uint8_t> firmware,
                          const FalconUploadOptions& options = {});

/// Step 7 alone: latency 1 ms, baud divisor 2, purge (the mode the firmware talks in).
/// @throws std::runtime_error naming the control transfer that failed.
void setFalconNormalMode(UsbTransport& usb, unsigned timeout_ms = 1000);

/// True when the firmware answers: in normal mode, a zero-force command gets a valid status
/// packet back within `attempts` exchanges. Never throws.
bool falconFirmwareLoaded(UsbTransport& usb, int attempts = 10, unsigned timeout_ms = 20) noexcept;

/// The Falcon's ratings (devices.md): 8 N, no torque, 3000 N/m, workspace radius 0.04 m.
runtime::DeviceLimits falconLimits() noexcept;

/// How a FalconDevice opens and runs.
struct FalconOptions {
  /// The firmware file, uploaded when the Falcon does not run its firmware yet (after every
  /// power-up). Empty: such a Falcon fails to open with a message asking for it.
  std::filesystem::path firmware;
  FalconUploadOptions upload;
  /// Samples are valid (and forces sent) only once all three motors are homed: until then the
  /// LED is red and the Falcon is in homing mode (move the grip through its range).
  bool require_homing = true;
  unsigned io_timeout_ms = 50;        ///< Per bulk transfer in the I/O loop [ms].
  int max_consecutive_errors = 100;   ///< I/O errors in a row before the device counts as gone.
  double velocity_cutoff_Hz = 40.0;   ///< Low-pass of the finite-difference velocity [Hz].
  runtime::DeviceLimits limits = falconLimits();
};

/// A Novint Falcon.
class FalconDevice final : public IoThreadDevice {
 public:
  /// Opens `device` through `backend`, uploads the firmware when needed, starts the I/O thread.
  /// @throws std::runtime_error naming the device and the problem (cannot open, firmware
  ///         missing or rejected).
  FalconDevice(std::shared_ptr<UsbBackend> backend, UsbDeviceInfo device, FalconOptions options = {});
  ~FalconDevice() override;  ///< Sends zero force and stops the I/O thread.
  FalconDevice(const FalconDevice&) = delete;
  FalconDevice& operator=(const FalconDevice&) = delete;

  std::string name() const override { return "Novint Falcon"; }
  runtime::DeviceIdentity identity() const override;
  runtime::DeviceLimits limits() const noexcept override { return options_.limits; }
  runtime::SafetyPolicy safetyPolicy() const noexcept override { return runtime::SafetyPolicy::forHardware(); }
  runtime::DofMask sensedDof() const noexcept override { return runtime::kDofTranslation; }
  runtime::DofMask actuatedDof() const noexcept override { return runtime::kDofTranslation; }
  /// Re-finds the Falcon (same serial when known, else the first one), reopens it (uploading the
  /// firmware again when needed) and restarts the I/O thread.
  /// @throws std::runtime_error when it cannot be found or opened.
  void reconnect() override;
  /// Servo thread: the latest sample (X_BH in B, velocity, grip buttons). False while
  /// disconnected; `valid` false until homed.
  bool read(runtime::DeviceSample& sample) noexcept override;
  /// Servo thread: force [N] in B (torque ignored: not actuated).
  void command(const Eigen::Vector3d& force_B_N, const Eigen::Vector3d& torque_B_Nm) noexcept override;

  // problem() (IoThreadDevice): why the device is disconnected or not homed yet; empty when fine.
  /// Any thread: status packets received, I/O errors (counters since opening).
  std::uint64_t packetsReceived() const noexcept { return packets_.load(std::memory_order_relaxed); }
  std::uint64_t ioErrors() const noexcept { return io_errors_.load(std::memory_order_relaxed); }
  /// Any thread: all motors homed (from the latest status).
  bool homed() const noexcept { return homed_.load(std::memory_order_relaxed); }

 private:
  void openAndStart();
  /// Stops and joins the I/O thread, then drops the transport (closing the device).
  void stopIo() noexcept;
  void ioLoop() noexcept;

  std::shared_ptr<UsbBackend> backend_;
  UsbDeviceInfo info_;
  FalconOptions options_;
  std::vector<std::uint8_t> firmware_;  // read once, kept for reconnects
  std::unique_ptr<UsbTransport> transport_;  // I/O thread while it runs
  std::atomic<bool> homed_{false};
  std::atomic<std::uint64_t> packets_{0};
  std::atomic<std::uint64_t> io_errors_{0};
  runtime::TripleBuffer<runtime::DeviceSample> samples_;  // I/O thread -> servo thread
  runtime::TripleBuffer<Eigen::Vector3d> forces_;         // servo thread -> I/O thread
  runtime::DeviceSample servo_sample_;                    // servo thread only
};

}  // namespace vh::devices
