#include "vh/devices/dhd_device.h"

#include "device_clock.h"

#include <chrono>
#include <cmath>
#include <stdexcept>

#include <Eigen/Geometry>

#include "vh/devices/velocity_filter.h"

namespace vh::devices {

namespace {

using detail::steadySeconds;

/// `moving_mass_kg`: the handle's moving mass, for the speed limit (handleMaxSpeed_m_per_s();
/// app/simulation device_catalog.cpp's figures).
runtime::DeviceLimits limitsOf(double force_N, double torque_Nm, double stiffness_N_per_m, double radius_m,
                               double moving_mass_kg) noexcept {
  runtime::DeviceLimits l;
  l.max_force_N = force_N;
  l.max_torque_Nm = torque_Nm;
  l.max_linear_stiffness_N_per_m = stiffness_N_per_m;
  // Rotational stiffness is not published; a conservative value for the wrists.
  l.max_angular_stiffness_Nm_per_rad = torque_Nm > 0.0 ? 1.0 : 0.0;
  l.workspace_radius_m = radius_m;
  l.max_speed_m_per_s = runtime::handleMaxSpeed_m_per_s(force_N, radius_m, moving_mass_kg);
  return l;
}

}  // namespace

// ---- Library -------------------------------------------------------------------------------------

std::string DhdApi::sdkVersion() const {
  if (getSdkVersion == nullptr) return {};
  int major = 0, minor = 0, release = 0, revision = 0;
  getSdkVersion(&major, &minor, &release, &revision);
  return "SDK " + std::to_string(major) + "." + std::to_string(minor) + "." + std::to_string(release);
}

std::string DhdApi::lastError(const char* call) const {
  const char* text = errorGetLastStr != nullptr ? errorGetLastStr() : nullptr;
  const int code = errorGetLast != nullptr ? errorGetLast() : -1;
  return std::string(call) + ": " + (text != nullptr && *text != '\0' ? text : "error") + " (DHD error " +
         std::to_string(code) + ")";
}

const std::vector<std::string>& defaultDhdLibraries() {
  static const std::vector<std::string> names{"libdrd.so.3", "libdrd.so", "libdhd.so.3", "libdhd.so"};
  return names;
}

std::shared_ptr<const DhdApi> loadDhd(const std::vector<std::string>& candidates) {
  auto api = std::make_shared<DhdApi>();
  api->library = VendorLibrary::open(candidates);
  const VendorLibrary& lib = *api->library;
  lib.bind(api->getDeviceCount, "dhdGetDeviceCount");
  lib.bind(api->openID, "dhdOpenID");
  lib.bind(api->close, "dhdClose");
  lib.bind(api->getSystemType, "dhdGetSystemType");
  lib.bind(api->getSystemName, "dhdGetSystemName");
  lib.bind(api->hasWrist, "dhdHasWrist");
  lib.bind(api->hasActiveWrist, "dhdHasActiveWrist");
  lib.bind(api->enableForce, "dhdEnableForce");
  lib.bind(api->getPosition, "dhdGetPosition");
  lib.bind(api->getPositionAndOrientationFrame, "dhdGetPositionAndOrientationFrame");
  lib.bind(api->getButtonMask, "dhdGetButtonMask");
  lib.bind(api->setForceAndTorque, "dhdSetForceAndTorque");
  lib.bind(api->getMaxForce, "dhdGetMaxForce");
  lib.bind(api->getMaxTorque, "dhdGetMaxTorque");
  lib.bind(api->errorGetLast, "dhdErrorGetLast");
  lib.bind(api->errorGetLastStr, "dhdErrorGetLastStr");
  lib.bind(api->getSdkVersion, "dhdGetSDKVersion");
  lib.bindOptional(api->drdIsInitialized, "drdIsInitialized");
  return api;
}

VendorStatus probeDhd(const std::vector<std::string>& candidates, std::shared_ptr<const DhdApi>& api) noexcept {
  return probeVendor(
      "forcedimension", "Force Dimension (DHD)", api, [&] { return loadDhd(candidates); },
      [](const DhdApi& loaded) { return loaded.sdkVersion(); });
}

runtime::DeviceLimits dhdPublishedLimits(int system_type) noexcept {
  switch (system_type) {
    case dhd::kDeviceOmega3:
    case dhd::kDeviceOmega33:
    case dhd::kDeviceOmega33Left:
    case dhd::kDeviceOmega331:
    case dhd::kDeviceOmega331Left:
      return limitsOf(12.0, 0.0, 14500.0, 0.055, 0.2);   // omega.x: 12 N, 14.5 N/mm, 160 x 110 mm; 5.6 m/s
    case dhd::kDeviceDelta3:
      return limitsOf(20.0, 0.0, 14500.0, 0.13, 0.5);    // delta.3: 20 N, 14.5 N/mm, 400 x 260 mm; 6.6 m/s
    case dhd::kDeviceSigma331:
    case dhd::kDeviceSigma331Left:
      return limitsOf(20.0, 0.4, 14500.0, 0.065, 0.5);   // sigma.7: 20 N, 0.4 N*m, 190 x 130 mm; 5.2 m/s
    case dhd::kDeviceFalcon:
      return limitsOf(8.0, 0.0, 3000.0, 0.04, 0.15);      // as falconLimits() (devices.md); 4.9 m/s
    default:
      return limitsOf(8.0, 0.1, 2000.0, 0.05, 0.2);      // unknown: conservative; 4.8 m/s
  }
}

// ---- DhdDevice -----------------------------------------------------------------------------------

DhdDevice::DhdDevice(std::shared_ptr<const DhdApi> api, DhdOptions options) : api_(std::move(api)), options_(options) {
  if (!api_) throw std::runtime_error("Force Dimension: the DHD library is not installed");
  openAndStart();
}

DhdDevice::~DhdDevice() {
  stopIoThread();
  closeDevice();
}

void DhdDevice::closeDevice() noexcept {
  if (!open_) return;
  api_->setForceAndTorque(0, 0, 0, 0, 0, 0, id_);
  api_->enableForce(0, id_);
  api_->close(id_);
  open_ = false;
}

void DhdDevice::openAndStart() {
  const DhdApi& a = *api_;
  const int count = a.getDeviceCount();
  if (count < 0) throw std::runtime_error("Force Dimension: " + a.lastError("dhdGetDeviceCount"));
  if (count == 0) {
    throw std::runtime_error("no Force Dimension device found (dhdGetDeviceCount: 0): check the USB cable, the power "
                             "switch and the udev permissions");
  }
  if (options_.index < 0 || options_.index >= count) {
    throw std::runtime_error("Force Dimension: no device #" + std::to_string(options_.index) + " (" +
                             std::to_string(count) + " found)");
  }
  const int id = a.openID(static_cast<char>(options_.index));
  if (id < 0) throw std::runtime_error("Force Dimension: " + a.lastError("dhdOpenID"));
  id_ = static_cast<char>(id);
  open_ = true;
  try {
    system_type_ = a.getSystemType(id_);
    const char* system_name = a.getSystemName(id_);
    identity_.model = system_name != nullptr && *system_name != '\0' ? system_name : "Force Dimension device";
    identity_.manufacturer = "Force Dimension";
    identity_.serial.clear();
    identity_.backend = "dhd (" + a.library->path() + ")";
    if (a.drdIsInitialized != nullptr && !a.drdIsInitialized(id_)) {
      throw std::runtime_error(identity_.model +
                               " is not calibrated: run the Force Dimension calibration (the SDK's 'autoinit' "
                               "tool, or move the device through its calibration routine as its manual says), "
                               "then pick it again");
    }
    has_wrist_ = a.hasWrist(id_);
    const bool active_wrist = a.hasActiveWrist(id_);
    sensed_ = runtime::kDofTranslation | (has_wrist_ ? runtime::kDofRotation : runtime::kDofNone);
    actuated_ = runtime::kDofTranslation | (active_wrist ? runtime::kDofRotation : runtime::kDofNone);
    limits_ = dhdPublishedLimits(system_type_);
    if (!active_wrist) {
      limits_.max_torque_Nm = 0.0;
      limits_.max_angular_stiffness_Nm_per_rad = 0.0;
    }
    const double sdk_force = a.getMaxForce(id_);
    if (sdk_force > 0.0 && std::isfinite(sdk_force)) limits_.max_force_N = std::min(limits_.max_force_N, sdk_force);
    const double sdk_torque = a.getMaxTorque(id_);
    if (sdk_torque > 0.0 && std::isfinite(sdk_torque)) limits_.max_torque_Nm = std::min(limits_.max_torque_Nm, sdk_torque);
    if (a.enableForce(1, id_) < 0) throw std::runtime_error("Force Dimension: " + a.lastError("dhdEnableForce"));
    if (a.setForceAndTorque(0, 0, 0, 0, 0, 0, id_) < 0) {
      throw std::runtime_error("Force Dimension: " + a.lastError("dhdSetForceAndTorque"));
    }
  } catch (...) {
    closeDevice();
    throw;
  }
  clearProblem();
  wrenches_.writeSlot() = Wrench{};
  wrenches_.publish();
  startIoThread([this] { ioLoop(); });
}

void DhdDevice::reconnect() {
  stopIoThread();
  closeDevice();
  markDisconnected();
  openAndStart();
}

void DhdDevice::fail(const std::string& text) noexcept {
  // Zero force at once (the device may not answer any more), forces off, then report.
  api_->setForceAndTorque(0, 0, 0, 0, 0, 0, id_);
  api_->enableForce(0, id_);
  markDisconnected();
  setProblem({identity_.model, ": ", text, "; forces off (pick the device again to reconnect)"});
}

void DhdDevice::ioLoop() noexcept {
  const DhdApi& a = *api_;
  const std::uint32_t this_connection = connection();
  const auto period = std::chrono::duration_cast<std::chrono::steady_clock::duration>(
      std::chrono::duration<double>(options_.io_period_s));
  auto next = std::chrono::steady_clock::now();
  VelocityFilter velocity(options_.velocity_cutoff_Hz);
  Wrench wrench;
  while (!stopRequested()) {
    double px = 0.0, py = 0.0, pz = 0.0;
    double m[3][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
    const int r = has_wrist_ ? a.getPositionAndOrientationFrame(&px, &py, &pz, m, id_) : a.getPosition(&px, &py, &pz, id_);
    if (r < 0) {
      fail(a.lastError(has_wrist_ ? "dhdGetPositionAndOrientationFrame" : "dhdGetPosition"));
      return;
    }
    const double t = steadySeconds();
    const Eigen::Vector3d p_BH(px, py, pz);
    Eigen::Matrix3d R;
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) R(i, j) = m[i][j];
    velocity.update(p_BH, t);
    runtime::DeviceSample& s = samples_.writeSlot();
    s.time_s = t;
    s.X_WD.p_AB_m = p_BH;
    s.X_WD.R_AB = Eigen::Quaterniond(R).normalized();
    s.v_WD_m_per_s = velocity.velocity();
    s.w_WD_rad_per_s.setZero();
    s.buttons = a.getButtonMask(id_);
    s.connection = this_connection;
    s.valid = p_BH.allFinite() && s.X_WD.R_AB.coeffs().allFinite();
    samples_.publish();

    wrenches_.read(wrench);
    const bool torque = (actuated_ & runtime::kDofRotation) == runtime::kDofRotation;
    const Eigen::Vector3d tau = torque ? wrench.torque_Nm : Eigen::Vector3d::Zero();
    if (a.setForceAndTorque(wrench.force_N.x(), wrench.force_N.y(), wrench.force_N.z(), tau.x(), tau.y(), tau.z(),
                            id_) < 0) {
      fail(a.lastError("dhdSetForceAndTorque"));
      return;
    }
    cycles_.fetch_add(1, std::memory_order_relaxed);
    next += period;
    const auto now = std::chrono::steady_clock::now();
    if (next < now) next = now;
    std::this_thread::sleep_until(next);
  }
}

bool DhdDevice::read(runtime::DeviceSample& sample) noexcept {
  samples_.read(servo_sample_);
  if (!connected()) return false;
  sample = servo_sample_;
  return sample.valid;
}

void DhdDevice::command(const Eigen::Vector3d& force_B_N, const Eigen::Vector3d& torque_B_Nm) noexcept {
  Wrench& w = wrenches_.writeSlot();
  w.force_N = force_B_N.allFinite() ? force_B_N : Eigen::Vector3d::Zero();
  w.torque_Nm = torque_B_Nm.allFinite() ? torque_B_Nm : Eigen::Vector3d::Zero();
  wrenches_.publish();
}

}  // namespace vh::devices
