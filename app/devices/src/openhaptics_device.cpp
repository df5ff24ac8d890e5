#include "vh/devices/openhaptics_device.h"

#include "device_clock.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <stdexcept>

#include <Eigen/Geometry>

namespace vh::devices {

using detail::steadySeconds;

// ---- Library -------------------------------------------------------------------------------------

std::string HdApi::takeErrors(const char* call) const {
  std::string first;
  for (int i = 0; i < 64; ++i) {  // the error stack is finite; never loop forever on a broken library
    const hd::HDErrorInfo e = getError();
    if (e.errorCode == hd::kSuccess) break;
    if (!first.empty()) continue;
    const char* text = getErrorString != nullptr ? getErrorString(e.errorCode) : nullptr;
    char code[64];
    std::snprintf(code, sizeof code, " (HD error 0x%X, internal %d)", e.errorCode, e.internalErrorCode);
    first = std::string(call) + ": " + (text != nullptr && *text != '\0' ? text : "error") + code;
  }
  return first;
}

const std::vector<std::string>& defaultHdLibraries() {
  static const std::vector<std::string> names{"libHD.so.3.4.0", "libHD.so.3.4", "libHD.so.3", "libHD.so"};
  return names;
}

std::shared_ptr<const HdApi> loadHd(const std::vector<std::string>& candidates) {
  auto api = std::make_shared<HdApi>();
  api->library = VendorLibrary::open(candidates);
  const VendorLibrary& lib = *api->library;
  lib.bind(api->initDevice, "hdInitDevice");
  lib.bind(api->disableDevice, "hdDisableDevice");
  lib.bind(api->makeCurrentDevice, "hdMakeCurrentDevice");
  lib.bind(api->getError, "hdGetError");
  lib.bind(api->getErrorString, "hdGetErrorString");
  lib.bind(api->enable, "hdEnable");
  lib.bind(api->disable, "hdDisable");
  lib.bind(api->beginFrame, "hdBeginFrame");
  lib.bind(api->endFrame, "hdEndFrame");
  lib.bind(api->getDoublev, "hdGetDoublev");
  lib.bind(api->getIntegerv, "hdGetIntegerv");
  lib.bind(api->getString, "hdGetString");
  lib.bind(api->setDoublev, "hdSetDoublev");
  lib.bind(api->startScheduler, "hdStartScheduler");
  lib.bind(api->stopScheduler, "hdStopScheduler");
  lib.bind(api->scheduleAsynchronous, "hdScheduleAsynchronous");
  lib.bind(api->scheduleSynchronous, "hdScheduleSynchronous");
  lib.bind(api->unschedule, "hdUnschedule");
  lib.bind(api->checkCalibration, "hdCheckCalibration");
  lib.bind(api->updateCalibration, "hdUpdateCalibration");
  return api;
}

VendorStatus probeHd(const std::vector<std::string>& candidates, std::shared_ptr<const HdApi>& api) noexcept {
  return probeVendor(
      "openhaptics", "3D Systems OpenHaptics (HD)", api, [&] { return loadHd(candidates); },
      [](const HdApi&) { return std::string(); });
}

// ---- OpenHapticsDevice ---------------------------------------------------------------------------

void OpenHapticsDevice::transformToPose(const double m[16], Eigen::Vector3d& p_BH_m, Eigen::Quaterniond& R_BH) noexcept {
  // Column-major: element (row r, column c) at m[4 * c + r]; translation in column 3 [mm].
  Eigen::Matrix3d R;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) R(r, c) = m[4 * c + r];
  p_BH_m = Eigen::Vector3d(m[12], m[13], m[14]) * 1e-3;
  R_BH = Eigen::Quaterniond(R).normalized();
}

OpenHapticsDevice::OpenHapticsDevice(std::shared_ptr<const HdApi> api, OpenHapticsOptions options)
    : api_(std::move(api)), options_(std::move(options)) {
  if (!api_) throw std::runtime_error("OpenHaptics: the HD library is not installed");
  openAndStart();
}

OpenHapticsDevice::~OpenHapticsDevice() { shutdown(); }

void OpenHapticsDevice::shutdown() noexcept {
  const HdApi& a = *api_;
  if (scheduler_running_) {
    a.stopScheduler();
    scheduler_running_ = false;
  }
  if (servo_scheduled_) {
    a.unschedule(servo_handle_);
    servo_scheduled_ = false;
  }
  if (hhd_ != hd::kInvalidHandle) {
    a.disableDevice(hhd_);
    hhd_ = hd::kInvalidHandle;
  }
  a.takeErrors("shutdown");
  connected_.store(false, std::memory_order_release);
}

namespace {

/// The current device's limits from its nominal properties: force, linear stiffness and damping
/// (per mm in OpenHaptics), with 6 output DOF (`output_dof`) torque and torsional stiffness (per
/// mN*m), the workspace ball inside the usable workspace box, and the speed limit of the
/// lightest 3D Systems mechanism across the box's longest side.
runtime::DeviceLimits readDeviceLimits(const HdApi& a, int output_dof) {
  double max_force_N = 0.0, max_stiffness_N_per_mm = 0.0, max_damping = 0.0;
  double workspace_mm[6] = {0, 0, 0, 0, 0, 0};
  a.getDoublev(hd::kNominalMaxForce, &max_force_N);
  a.getDoublev(hd::kNominalMaxStiffness, &max_stiffness_N_per_mm);
  a.getDoublev(hd::kNominalMaxDamping, &max_damping);
  a.getDoublev(hd::kUsableWorkspaceDimensions, workspace_mm);
  runtime::DeviceLimits limits{};
  limits.max_force_N = max_force_N > 0.0 ? max_force_N : 0.0;
  limits.max_linear_stiffness_N_per_m = max_stiffness_N_per_mm > 0.0 ? max_stiffness_N_per_mm * 1e3 : 0.0;
  if (max_damping > 0.0) limits.max_linear_damping_N_s_per_m = max_damping * 1e3;
  limits.max_torque_Nm = 0.0;
  limits.max_angular_stiffness_Nm_per_rad = 0.0;
  if (output_dof >= 6) {
    double torque_mNm = 0.0, torque_stiffness_mNm_per_rad = 0.0;
    a.getDoublev(hd::kNominalMaxTorqueForce, &torque_mNm);
    a.getDoublev(hd::kNominalMaxTorqueStiffness, &torque_stiffness_mNm_per_rad);
    limits.max_torque_Nm = torque_mNm > 0.0 ? torque_mNm * 1e-3 : 0.0;
    limits.max_angular_stiffness_Nm_per_rad = torque_stiffness_mNm_per_rad > 0.0 ? torque_stiffness_mNm_per_rad * 1e-3 : 0.0;
  }
  // The usable workspace box [mm]: minx, miny, minz, maxx, maxy, maxz; the ball inside it.
  double half_mm = 0.0;
  for (int i = 0; i < 3; ++i) {
    const double h = 0.5 * (workspace_mm[i + 3] - workspace_mm[i]);
    half_mm = i == 0 ? h : std::min(half_mm, h);
  }
  if (half_mm > 0.0) limits.workspace_radius_m = half_mm * 1e-3;
  double longest_half_mm = 0.0;
  for (int i = 0; i < 3; ++i) {
    limits.workspace_centre_m[i] = 0.5e-3 * (workspace_mm[i] + workspace_mm[i + 3]);
    longest_half_mm = std::max(longest_half_mm, 0.5 * (workspace_mm[i + 3] - workspace_mm[i]));
  }
  // Speed limit: the lightest 3D Systems mechanism, the Touch's 45 g apparent mass
  // (app/simulation device_catalog.cpp), across the box's longest side: e.g. Touch 3.3 N,
  // 160 mm: 6.8 m/s; Touch X 7.9 N: 9.5 m/s.
  limits.max_speed_m_per_s = runtime::handleMaxSpeed_m_per_s(limits.max_force_N, longest_half_mm * 1e-3, 0.045);
  return limits;
}

}  // namespace

void OpenHapticsDevice::openAndStart() {
  const HdApi& a = *api_;
  a.takeErrors("before hdInitDevice");
  hhd_ = a.initDevice(options_.device_name.empty() ? nullptr : options_.device_name.c_str());
  std::string error = a.takeErrors("hdInitDevice");
  if (hhd_ == hd::kInvalidHandle || !error.empty()) {
    hhd_ = hd::kInvalidHandle;
    throw std::runtime_error("no OpenHaptics device found (" + (error.empty() ? std::string("hdInitDevice failed") : error) +
                             "): check the cable, the device's configuration (Touch Setup) and permissions");
  }
  try {
    a.makeCurrentDevice(hhd_);
    const char* model = a.getString(hd::kDeviceModelType);
    const char* vendor = a.getString(hd::kDeviceVendor);
    const char* serial = a.getString(hd::kDeviceSerialNumber);
    identity_.model = model != nullptr && *model != '\0' ? model : "OpenHaptics device";
    identity_.manufacturer = vendor != nullptr && *vendor != '\0' ? vendor : "3D Systems";
    identity_.serial = serial != nullptr ? serial : "";
    identity_.backend = "openhaptics (" + a.library->path() + ")";
    int input_dof = 3, output_dof = 3, calibration_style = 0;
    a.getIntegerv(hd::kInputDof, &input_dof);
    a.getIntegerv(hd::kOutputDof, &output_dof);
    a.getIntegerv(hd::kCalibrationStyle, &calibration_style);
    sensed_ = input_dof >= 6 ? runtime::kDofAll : runtime::kDofTranslation;
    actuated_ = output_dof >= 6 ? runtime::kDofAll : runtime::kDofTranslation;
    limits_ = readDeviceLimits(a, output_dof);
    error = a.takeErrors("reading the device's properties");
    if (!error.empty()) throw std::runtime_error("OpenHaptics: " + error);

    a.enable(hd::kForceOutput);
    a.startScheduler();
    error = a.takeErrors("hdStartScheduler");
    if (!error.empty()) throw std::runtime_error("OpenHaptics: " + error);
    scheduler_running_ = true;

    // Calibration, checked on the scheduler thread (hdCheckCalibration needs the servo loop).
    a.scheduleSynchronous(&OpenHapticsDevice::calibrationCallback, this, hd::kDefaultSchedulerPriority);
    if (calibration_ == hd::kCalibrationNeedsUpdate) {
      // Automatic styles (encoder reset, auto, inkwell with the stylus in it) update at once.
      const hd::HDenum style = (calibration_style & hd::kCalibrationAuto)       ? hd::kCalibrationAuto
                               : (calibration_style & hd::kCalibrationInkwell)   ? hd::kCalibrationInkwell
                                                                                 : hd::kCalibrationEncoderReset;
      a.updateCalibration(style);
      a.scheduleSynchronous(&OpenHapticsDevice::calibrationCallback, this, hd::kDefaultSchedulerPriority);
    }
    error = a.takeErrors("calibration");
    if (!error.empty()) throw std::runtime_error("OpenHaptics: " + error);
    if (calibration_ != hd::kCalibrationOk) {
      throw std::runtime_error(
          identity_.model + " needs calibration: " +
          ((calibration_style & hd::kCalibrationInkwell) ? std::string("put the stylus in its inkwell")
                                                        : std::string("move the arm through its whole workspace")) +
          " (or run the vendor's Touch Diagnostic / calibration tool), then pick the device again");
    }

    {
      const std::lock_guard<std::mutex> lock(problem_mutex_);
      problem_.clear();
    }
    wrenches_.writeSlot() = Wrench{};
    wrenches_.publish();
    scheduler_wrench_ = Wrench{};
    velocity_.reset();
    failed_.store(false, std::memory_order_release);
    connection_.fetch_add(1, std::memory_order_acq_rel);
    connected_.store(true, std::memory_order_release);
    servo_handle_ = a.scheduleAsynchronous(&OpenHapticsDevice::servoCallback, this, hd::kDefaultSchedulerPriority);
    error = a.takeErrors("hdScheduleAsynchronous");
    if (!error.empty()) throw std::runtime_error("OpenHaptics: " + error);
    servo_scheduled_ = true;
  } catch (...) {
    shutdown();
    throw;
  }
}

void OpenHapticsDevice::reconnect() {
  shutdown();
  openAndStart();
}

std::string OpenHapticsDevice::problem() const {
  const std::lock_guard<std::mutex> lock(problem_mutex_);
  return problem_;
}

hd::HDCallbackCode OpenHapticsDevice::calibrationCallback(void* self) noexcept {
  auto* device = static_cast<OpenHapticsDevice*>(self);
  device->calibration_ = device->api_->checkCalibration();
  return hd::kCallbackDone;
}

hd::HDCallbackCode OpenHapticsDevice::servoCallback(void* self) noexcept {
  return static_cast<OpenHapticsDevice*>(self)->servoTick();
}

void OpenHapticsDevice::fail(const std::string& text) noexcept {
  connected_.store(false, std::memory_order_release);
  failed_.store(true, std::memory_order_release);
  try {
    const std::lock_guard<std::mutex> lock(problem_mutex_);
    problem_ = identity_.model + ": " + text + "; forces off (pick the device again to reconnect)";
  } catch (...) {
  }
}

hd::HDCallbackCode OpenHapticsDevice::servoTick() noexcept {
  const HdApi& a = *api_;
  if (failed_.load(std::memory_order_acquire)) return hd::kCallbackDone;
  a.beginFrame(hhd_);
  double m[16];
  int buttons = 0;
  a.getDoublev(hd::kCurrentTransform, m);
  a.getIntegerv(hd::kCurrentButtons, &buttons);
  wrenches_.read(scheduler_wrench_);
  const double force[3] = {scheduler_wrench_.force_N.x(), scheduler_wrench_.force_N.y(), scheduler_wrench_.force_N.z()};
  a.setDoublev(hd::kCurrentForce, force);
  const bool torque = (actuated_ & runtime::kDofRotation) == runtime::kDofRotation;
  if (torque) {
    // HD_CURRENT_TORQUE is in mN*m.
    const double tau_mNm[3] = {scheduler_wrench_.torque_Nm.x() * 1e3, scheduler_wrench_.torque_Nm.y() * 1e3,
                               scheduler_wrench_.torque_Nm.z() * 1e3};
    a.setDoublev(hd::kCurrentTorque, tau_mNm);
  }
  a.endFrame(hhd_);
  const hd::HDErrorInfo e = a.getError();
  if (e.errorCode != hd::kSuccess) {
    // Zero force at once: one more frame with zero output (ignored when the device is gone),
    // force output off, then stop this callback.
    const double zero[3] = {0.0, 0.0, 0.0};
    a.beginFrame(hhd_);
    a.setDoublev(hd::kCurrentForce, zero);
    if (torque) a.setDoublev(hd::kCurrentTorque, zero);
    a.endFrame(hhd_);
    a.disable(hd::kForceOutput);
    const char* text = a.getErrorString(e.errorCode);
    char code[64];
    std::snprintf(code, sizeof code, " (HD error 0x%X, internal %d)", e.errorCode, e.internalErrorCode);
    fail(std::string("error in the servo loop: ") + (text != nullptr ? text : "error") + code);
    a.takeErrors("after the error");
    return hd::kCallbackDone;
  }
  const double t = steadySeconds();
  Eigen::Vector3d p_BH;
  Eigen::Quaterniond R_BH;
  transformToPose(m, p_BH, R_BH);
  velocity_.update(p_BH, t);
  runtime::DeviceSample& s = samples_.writeSlot();
  s.time_s = t;
  s.X_WD.p_AB_m = p_BH;
  s.X_WD.R_AB = R_BH;
  s.v_WD_m_per_s = velocity_.velocity();
  s.w_WD_rad_per_s.setZero();
  s.buttons = static_cast<unsigned>(buttons);
  s.connection = connection_.load(std::memory_order_relaxed);
  s.valid = p_BH.allFinite() && R_BH.coeffs().allFinite();
  samples_.publish();
  ticks_.fetch_add(1, std::memory_order_relaxed);
  return hd::kCallbackContinue;
}

bool OpenHapticsDevice::read(runtime::DeviceSample& sample) noexcept {
  samples_.read(servo_sample_);
  if (!connected()) return false;
  sample = servo_sample_;
  return sample.valid;
}

void OpenHapticsDevice::command(const Eigen::Vector3d& force_B_N, const Eigen::Vector3d& torque_B_Nm) noexcept {
  Wrench& w = wrenches_.writeSlot();
  w.force_N = force_B_N.allFinite() ? force_B_N : Eigen::Vector3d::Zero();
  w.torque_Nm = torque_B_Nm.allFinite() ? torque_B_Nm : Eigen::Vector3d::Zero();
  wrenches_.publish();
}

}  // namespace vh::devices
