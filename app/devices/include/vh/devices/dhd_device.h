#pragma once
/// @file
/// Force Dimension haptic devices (omega.3/6/7, delta.3/6, sigma.7, lambda.7, and the Novint
/// Falcon through the same SDK) as a runtime::Device, through the vendor's DHD library
/// (libdhd / libdrd of the Force Dimension SDK) loaded at run time with dlopen: never a build
/// dependency (vendor_library.h).
///
/// API facts used (Force Dimension SDK "DHD" C API, dhdc.h; documentation at
/// https://downloads.forcedimension.com/sdk/doc/fdsdk-3.14.0/dhd/index.html, prototypes as
/// declared by the public Python bindings forcedimension-core, which load the same library):
///   - every function takes the device as a trailing `char ID` (-1: the default device);
///   - int results are 0 (or DHD_TIMEGUARD = 1) on success and -1 on error; the error is then
///     dhdErrorGetLast() / dhdErrorGetLastStr() of the calling thread;
///   - positions in metres, orientation as a 3 x 3 rotation matrix (row i, column j at
///     matrix[i][j]) of the end-effector in the device frame; forces in N, torques in N*m;
///   - the device frame B: origin at the workspace centre, x towards the user, y to the
///     user's right, z up (Force Dimension user manuals).
/// libdrd (the robotic SDK) contains the DHD API as well and adds drdIsInitialized(), which
/// tells whether the device is calibrated: it is tried first; with libdhd alone the
/// calibration check is skipped (the SDK then reports an uncalibrated device through errors).
///
/// Threads: the constructor and reconnect() run on the caller's thread; one I/O thread reads
/// the pose and sends the latest force at about 1 kHz (DHD calls block on USB I/O and report
/// errors per thread); read() / command() touch only triple buffers and atomics. The thread,
/// the connected flag, the connection counter and the problem text are IoThreadDevice's.

#include <atomic>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "vh/devices/io_thread_device.h"
#include "vh/devices/vendor_library.h"
#include "vh/runtime/device.h"

namespace vh::devices {

/// The DHD functions the driver calls, bound with dlsym (C ABI, plain `cdecl` on Linux).
struct DhdApi {
  std::shared_ptr<VendorLibrary> library;
  int (*getDeviceCount)() = nullptr;
  int (*openID)(char index) = nullptr;                 ///< Device ID >= 0, or -1.
  int (*close)(char id) = nullptr;
  int (*getSystemType)(char id) = nullptr;             ///< DHD_DEVICE_* or -1.
  const char* (*getSystemName)(char id) = nullptr;     ///< e.g. "sigma.7"; null on error.
  bool (*hasWrist)(char id) = nullptr;                 ///< Senses rotation.
  bool (*hasActiveWrist)(char id) = nullptr;           ///< Actuates rotation (torque).
  int (*enableForce)(unsigned char on, char id) = nullptr;
  int (*getPosition)(double* px, double* py, double* pz, char id) = nullptr;  ///< [m]
  int (*getPositionAndOrientationFrame)(double* px, double* py, double* pz, double matrix[3][3], char id) = nullptr;
  unsigned int (*getButtonMask)(char id) = nullptr;    ///< Bit i: button i pressed.
  int (*setForceAndTorque)(double fx, double fy, double fz, double tx, double ty, double tz, char id) = nullptr;
  double (*getMaxForce)(char id) = nullptr;            ///< Software force limit [N]; < 0: none set.
  double (*getMaxTorque)(char id) = nullptr;           ///< Software torque limit [N*m]; < 0: none set.
  int (*errorGetLast)() = nullptr;                     ///< DHD_ERROR_* of the calling thread.
  const char* (*errorGetLastStr)() = nullptr;
  void (*getSdkVersion)(int* major, int* minor, int* release, int* revision) = nullptr;
  bool (*drdIsInitialized)(char id) = nullptr;         ///< Optional (libdrd only): calibrated.

  /// "SDK 3.14.0" from dhdGetSDKVersion().
  std::string sdkVersion() const;
  /// "dhdOpenID: <dhdErrorGetLastStr()> (DHD error N)" for the calling thread's last error.
  std::string lastError(const char* call) const;
};

/// The library names tried by default: libdrd.so.3, libdrd.so, libdhd.so.3, libdhd.so.
const std::vector<std::string>& defaultDhdLibraries();
/// Environment variable naming the library to load instead (a path): VH_DHD_LIBRARY.
inline constexpr char kDhdLibraryEnv[] = "VH_DHD_LIBRARY";

/// Loads the DHD library from `candidates` and binds every function.
/// @throws std::runtime_error "not installed (...)" when no candidate loads or one lacks a
///         required function.
std::shared_ptr<const DhdApi> loadDhd(const std::vector<std::string>& candidates);
/// loadDhd() that never throws: the status for the picker and `api` (null when not installed).
VendorStatus probeDhd(const std::vector<std::string>& candidates, std::shared_ptr<const DhdApi>& api) noexcept;

/// DHD_DEVICE_* system types (dhdc.h) this driver knows.
namespace dhd {
inline constexpr int kDeviceOmega3 = 33;
inline constexpr int kDeviceOmega33 = 34;       ///< omega.6
inline constexpr int kDeviceOmega331 = 35;      ///< omega.7
inline constexpr int kDeviceOmega33Left = 36;
inline constexpr int kDeviceOmega331Left = 37;
inline constexpr int kDeviceFalcon = 60;
inline constexpr int kDeviceDelta3 = 63;
inline constexpr int kDeviceSigma331 = 104;     ///< sigma.7
inline constexpr int kDeviceSigma331Left = 105;
}  // namespace dhd

/// Published ratings of a Force Dimension system type (force, torque, stiffness, workspace),
/// used where the SDK has no call for them (it has none for stiffness; dhdGetMaxForce() is a
/// software limit, applied on top when set). Unknown types get conservative ratings
/// (8 N, 0.1 N*m, 2000 N/m, 0.05 m). Sources in app/devices/README.md.
runtime::DeviceLimits dhdPublishedLimits(int system_type) noexcept;

/// How a DhdDevice opens and runs.
struct DhdOptions {
  int index = 0;                       ///< Which device (0: the first; dhdOpenID's index).
  double io_period_s = 0.001;          ///< I/O loop period [s] (the device may be slower).
  double velocity_cutoff_Hz = 40.0;    ///< Low-pass of the finite-difference velocity [Hz].
};

/// A Force Dimension device through a loaded DHD library.
class DhdDevice final : public IoThreadDevice {
 public:
  /// Opens device `options.index`, checks its calibration, enables forces and starts the I/O
  /// thread.
  /// @throws std::runtime_error for a null api, no device ("no Force Dimension device found"),
  ///         a failing dhdOpenID (with the SDK's message) or an uncalibrated device (the message
  ///         says what to do).
  DhdDevice(std::shared_ptr<const DhdApi> api, DhdOptions options = {});
  ~DhdDevice() override;  ///< Sends zero force, disables forces, closes the device.
  DhdDevice(const DhdDevice&) = delete;
  DhdDevice& operator=(const DhdDevice&) = delete;

  std::string name() const override { return identity_.model; }
  runtime::DeviceIdentity identity() const override { return identity_; }
  runtime::DeviceLimits limits() const noexcept override { return limits_; }
  runtime::SafetyPolicy safetyPolicy() const noexcept override { return runtime::SafetyPolicy::forHardware(); }
  /// Translation, plus rotation with a wrist (omega.6/7, sigma.7, lambda.7).
  runtime::DofMask sensedDof() const noexcept override { return sensed_; }
  /// Translation, plus rotation with an active wrist (sigma.7); never torque otherwise.
  runtime::DofMask actuatedDof() const noexcept override { return actuated_; }
  /// Closes and reopens the device (after an error).
  /// @throws std::runtime_error as the constructor.
  void reconnect() override;
  /// Servo thread: the latest sample (X_BH in B [m], velocity, buttons); false after an error.
  bool read(runtime::DeviceSample& sample) noexcept override;
  /// Servo thread: force [N] and torque [N*m] in B (torque dropped without an active wrist).
  void command(const Eigen::Vector3d& force_B_N, const Eigen::Vector3d& torque_B_Nm) noexcept override;

  /// The DHD system type (DHD_DEVICE_*).
  int systemType() const noexcept { return system_type_; }
  /// Any thread: I/O cycles completed since opening.
  std::uint64_t cycles() const noexcept { return cycles_.load(std::memory_order_relaxed); }

 private:
  struct Wrench {
    Eigen::Vector3d force_N = Eigen::Vector3d::Zero();
    Eigen::Vector3d torque_Nm = Eigen::Vector3d::Zero();
  };
  void openAndStart();
  void closeDevice() noexcept;
  void ioLoop() noexcept;
  void fail(const std::string& text) noexcept;

  std::shared_ptr<const DhdApi> api_;
  DhdOptions options_;
  char id_ = -1;
  bool open_ = false;
  int system_type_ = -1;
  runtime::DeviceIdentity identity_;
  runtime::DeviceLimits limits_;
  runtime::DofMask sensed_ = runtime::kDofTranslation;
  runtime::DofMask actuated_ = runtime::kDofTranslation;
  bool has_wrist_ = false;
  std::atomic<std::uint64_t> cycles_{0};
  runtime::TripleBuffer<runtime::DeviceSample> samples_;  // I/O thread -> servo thread
  runtime::TripleBuffer<Wrench> wrenches_;                // servo thread -> I/O thread
  runtime::DeviceSample servo_sample_;                    // servo thread only
};

}  // namespace vh::devices
