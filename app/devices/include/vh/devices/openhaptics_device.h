#pragma once
/// @file
/// 3D Systems (SensAble) haptic devices (Touch, Touch X, Phantom Premium including the 6-DOF
/// Premium) as a runtime::Device, through the OpenHaptics HD API (libHD) loaded at run time with
/// dlopen: never a build dependency (vendor_library.h).
///
/// API facts used (OpenHaptics HD API, headers HD/hd.h and HD/hdDefines.h of OpenHaptics 3.x;
/// the enum values below are those of the public hdDefines.h, re-declared here, not copied):
///   - types: HHD, HDenum, HDerror = unsigned int; HDErrorInfo = {HDerror errorCode;
///     int internalErrorCode; HHD hHD}, returned by value by hdGetError(), which pops the
///     oldest error (HD_SUCCESS = 0 when none);
///   - hdInitDevice(HD_DEFAULT_DEVICE = NULL) -> HHD (HD_INVALID_HANDLE on error);
///   - HD_CURRENT_TRANSFORM: 16 doubles, a column-major 4 x 4 transform of the stylus in the
///     device frame, translation in millimetres; HD_CURRENT_BUTTONS: int bit mask;
///   - HD_CURRENT_FORCE: 3 doubles [N]; HD_CURRENT_TORQUE: 3 doubles [mN*m] (6-DOF output only);
///   - HD_NOMINAL_MAX_FORCE [N], HD_NOMINAL_MAX_STIFFNESS [N/mm], HD_NOMINAL_MAX_DAMPING
///     [N*s/mm], HD_NOMINAL_MAX_TORQUE_FORCE [mN*m], HD_NOMINAL_MAX_TORQUE_STIFFNESS
///     [mN*m/rad]; HD_INPUT_DOF / HD_OUTPUT_DOF: 3 or 6;
///   - forces are set only inside hdBeginFrame / hdEndFrame, which belong in a scheduler
///     callback (the servo loop the scheduler runs at about 1 kHz);
///   - hdCheckCalibration() -> HD_CALIBRATION_OK / _NEEDS_UPDATE / _NEEDS_MANUAL_INPUT;
///     hdUpdateCalibration(style) with a style from HD_CALIBRATION_STYLE.
///   - the device frame B (OpenHaptics programmer's guide): x to the user's right, y up,
///     z towards the user.
///
/// Threads (why the scheduler): OpenHaptics renders force only from its own servo thread (the
/// scheduler; hdStartScheduler) and reports errors there. The driver schedules one asynchronous
/// callback that, every servo tick inside one frame, reads the transform and buttons into a
/// triple buffer and sets the latest force / torque from another; our coupling thread's
/// read() / command() touch only those buffers and atomics (no lock, allocation, or blocking
/// on OpenHaptics). Calls outside the servo loop (calibration check) use
/// hdScheduleSynchronous. OpenHaptics has one scheduler per process: one OpenHapticsDevice at a
/// time.

#include <atomic>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "vh/devices/velocity_filter.h"
#include "vh/devices/vendor_library.h"
#include "vh/runtime/device.h"

namespace vh::devices {

/// OpenHaptics HD API values (HD/hdDefines.h, OpenHaptics 3.x).
namespace hd {
using HHD = unsigned int;
using HDenum = unsigned int;
using HDerror = unsigned int;
using HDCallbackCode = unsigned int;
using HDSchedulerHandle = unsigned long;
struct HDErrorInfo {
  HDerror errorCode;
  int internalErrorCode;
  HHD hHD;
};
using HDSchedulerCallback = HDCallbackCode (*)(void* user_data);

inline constexpr HHD kInvalidHandle = 0xFFFFFFFFu;
inline constexpr HDerror kSuccess = 0x0000;
inline constexpr HDerror kInvalidOperation = 0x0102;
inline constexpr HDerror kDeviceFault = 0x0300;
inline constexpr HDerror kCommError = 0x0302;
inline constexpr HDenum kCurrentButtons = 0x2000;
inline constexpr HDenum kCurrentTransform = 0x2052;
inline constexpr HDenum kDeviceModelType = 0x2501;
inline constexpr HDenum kDeviceVendor = 0x2503;
inline constexpr HDenum kDeviceSerialNumber = 0x2504;
inline constexpr HDenum kUsableWorkspaceDimensions = 0x2551;
inline constexpr HDenum kInputDof = 0x2553;
inline constexpr HDenum kOutputDof = 0x2554;
inline constexpr HDenum kCalibrationStyle = 0x2555;
inline constexpr HDenum kNominalMaxStiffness = 0x2602;
inline constexpr HDenum kNominalMaxForce = 0x2603;
inline constexpr HDenum kNominalMaxDamping = 0x2609;
inline constexpr HDenum kNominalMaxTorqueStiffness = 0x2620;
inline constexpr HDenum kNominalMaxTorqueForce = 0x2622;
inline constexpr HDenum kCurrentForce = 0x2700;
inline constexpr HDenum kCurrentTorque = 0x2701;
inline constexpr HDenum kForceOutput = 0x4000;
inline constexpr HDenum kCalibrationOk = 0x5000;
inline constexpr HDenum kCalibrationNeedsUpdate = 0x5001;
inline constexpr HDenum kCalibrationNeedsManualInput = 0x5002;
inline constexpr HDenum kCalibrationEncoderReset = 1u << 0;
inline constexpr HDenum kCalibrationAuto = 1u << 1;
inline constexpr HDenum kCalibrationInkwell = 1u << 2;
inline constexpr HDCallbackCode kCallbackDone = 0;
inline constexpr HDCallbackCode kCallbackContinue = 1;
inline constexpr unsigned short kDefaultSchedulerPriority = 0xFFFF / 2;  ///< (USHRT_MAX + 0) / 2
}  // namespace hd

/// The HD functions the driver calls, bound with dlsym (C ABI; HDAPIENTRY is empty on Linux).
struct HdApi {
  std::shared_ptr<VendorLibrary> library;
  hd::HHD (*initDevice)(const char* config_name) = nullptr;
  void (*disableDevice)(hd::HHD) = nullptr;
  void (*makeCurrentDevice)(hd::HHD) = nullptr;
  hd::HDErrorInfo (*getError)() = nullptr;
  const char* (*getErrorString)(hd::HDerror) = nullptr;
  void (*enable)(hd::HDenum) = nullptr;
  void (*disable)(hd::HDenum) = nullptr;
  void (*beginFrame)(hd::HHD) = nullptr;
  void (*endFrame)(hd::HHD) = nullptr;
  void (*getDoublev)(hd::HDenum, double*) = nullptr;
  void (*getIntegerv)(hd::HDenum, int*) = nullptr;
  const char* (*getString)(hd::HDenum) = nullptr;
  void (*setDoublev)(hd::HDenum, const double*) = nullptr;
  void (*startScheduler)() = nullptr;
  void (*stopScheduler)() = nullptr;
  hd::HDSchedulerHandle (*scheduleAsynchronous)(hd::HDSchedulerCallback, void*, unsigned short priority) = nullptr;
  void (*scheduleSynchronous)(hd::HDSchedulerCallback, void*, unsigned short priority) = nullptr;
  void (*unschedule)(hd::HDSchedulerHandle) = nullptr;
  hd::HDenum (*checkCalibration)() = nullptr;
  void (*updateCalibration)(hd::HDenum style) = nullptr;

  /// Pops every pending error; @return the first ("CALL: text (HD error 0x302, internal N)"),
  /// or empty when none. Never allocates when there is no error.
  std::string takeErrors(const char* call) const;
};

/// The library names tried by default: libHD.so.3.4.0, libHD.so.3.4, libHD.so.3, libHD.so.
const std::vector<std::string>& defaultHdLibraries();
/// Environment variable naming the library to load instead (a path): VH_OPENHAPTICS_LIBRARY.
inline constexpr char kHdLibraryEnv[] = "VH_OPENHAPTICS_LIBRARY";

/// Loads libHD from `candidates` and binds every function.
/// @throws std::runtime_error "not installed (...)" when none loads or a function is missing.
std::shared_ptr<const HdApi> loadHd(const std::vector<std::string>& candidates);
/// loadHd() that never throws: the status for the picker and `api` (null when not installed).
VendorStatus probeHd(const std::vector<std::string>& candidates, std::shared_ptr<const HdApi>& api) noexcept;

/// How an OpenHapticsDevice opens.
struct OpenHapticsOptions {
  std::string device_name;  ///< hdInitDevice's configuration name; empty: HD_DEFAULT_DEVICE.
};

/// A 3D Systems device through a loaded OpenHaptics HD library.
class OpenHapticsDevice final : public runtime::Device {
 public:
  /// Initialises the device, reads its ratings, checks the calibration (an automatic update is
  /// applied; manual calibration is refused with a message), enables force output, starts the
  /// scheduler and the servo callback.
  /// @throws std::runtime_error for a null api, no device (hdInitDevice's error), a device
  ///         that needs manual calibration, or a scheduler error.
  OpenHapticsDevice(std::shared_ptr<const HdApi> api, OpenHapticsOptions options = {});
  ~OpenHapticsDevice() override;  ///< Stops the scheduler, disables the device.
  OpenHapticsDevice(const OpenHapticsDevice&) = delete;
  OpenHapticsDevice& operator=(const OpenHapticsDevice&) = delete;

  std::string name() const override { return identity_.model; }
  runtime::DeviceIdentity identity() const override { return identity_; }
  /// From the SDK: HD_NOMINAL_MAX_FORCE, HD_NOMINAL_MAX_STIFFNESS (N/mm -> N/m), torque ratings
  /// (mN*m -> N*m) for 6-DOF output; workspace radius from HD_USABLE_WORKSPACE_DIMENSIONS.
  runtime::DeviceLimits limits() const noexcept override { return limits_; }
  runtime::SafetyPolicy safetyPolicy() const noexcept override { return runtime::SafetyPolicy::forHardware(); }
  runtime::DofMask sensedDof() const noexcept override { return sensed_; }
  /// Translation; rotation too with HD_OUTPUT_DOF 6 (Premium 6-DOF).
  runtime::DofMask actuatedDof() const noexcept override { return actuated_; }
  bool connected() const noexcept override { return connected_.load(std::memory_order_acquire); }
  std::string problem() const override;
  /// Shuts the device down and initialises it again. @throws std::runtime_error as the constructor.
  void reconnect() override;
  /// Servo thread: the latest sample (X_BH in B [m]); false after an error.
  bool read(runtime::DeviceSample& sample) noexcept override;
  /// Servo thread: force [N] and torque [N*m] in B (torque sent only with 6-DOF output).
  void command(const Eigen::Vector3d& force_B_N, const Eigen::Vector3d& torque_B_Nm) noexcept override;

  /// Any thread: servo callbacks run since opening.
  std::uint64_t ticks() const noexcept { return ticks_.load(std::memory_order_relaxed); }

  /// X_BH [m] from an HD_CURRENT_TRANSFORM (column-major 4 x 4, millimetres). Pure.
  static void transformToPose(const double m[16], Eigen::Vector3d& p_BH_m, Eigen::Quaterniond& R_BH) noexcept;

 private:
  struct Wrench {
    Eigen::Vector3d force_N = Eigen::Vector3d::Zero();
    Eigen::Vector3d torque_Nm = Eigen::Vector3d::Zero();
  };
  static hd::HDCallbackCode servoCallback(void* self) noexcept;
  static hd::HDCallbackCode calibrationCallback(void* self) noexcept;
  hd::HDCallbackCode servoTick() noexcept;
  void openAndStart();
  void shutdown() noexcept;
  void fail(const std::string& text) noexcept;

  std::shared_ptr<const HdApi> api_;
  OpenHapticsOptions options_;
  hd::HHD hhd_ = hd::kInvalidHandle;
  bool scheduler_running_ = false;
  hd::HDSchedulerHandle servo_handle_ = 0;
  bool servo_scheduled_ = false;
  runtime::DeviceIdentity identity_;
  runtime::DeviceLimits limits_;
  runtime::DofMask sensed_ = runtime::kDofAll;
  runtime::DofMask actuated_ = runtime::kDofTranslation;
  hd::HDenum calibration_ = hd::kCalibrationOk;  // written by calibrationCallback
  std::atomic<bool> connected_{false};
  std::atomic<bool> failed_{false};             // servo callback: stop at the next tick
  std::atomic<std::uint32_t> connection_{0};
  std::atomic<std::uint64_t> ticks_{0};
  runtime::TripleBuffer<runtime::DeviceSample> samples_;  // scheduler thread -> servo thread
  runtime::TripleBuffer<Wrench> wrenches_;                // servo thread -> scheduler thread
  Wrench scheduler_wrench_;                               // scheduler thread only
  static constexpr double kVelocityCutoff_Hz = 40.0;     // low-pass of the velocity [Hz]
  VelocityFilter velocity_{kVelocityCutoff_Hz};          // scheduler thread only
  runtime::DeviceSample servo_sample_;                    // servo thread only
  mutable std::mutex problem_mutex_;
  std::string problem_;
};

}  // namespace vh::devices
