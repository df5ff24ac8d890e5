// Tests of the vendor back-ends loaded at run time (vendor_library.h, dhd_device.h,
// openhaptics_device.h) through the same path as the real SDKs: fake vendor libraries built by
// these tests (fake_vendors/fake_dhd.cpp, fake_hd.cpp) export the same C symbols, play back
// scripted poses and record every command; the drivers load them with dlopen by path. Cases per
// vendor: library missing, no device, calibration needed, a normal session (units, frames,
// force / torque where actuated, limits from the SDK), an error in mid-session (zero force at
// once, a message, the simulated device takes over), and the safety layer's clamp.
#include <dlfcn.h>

#include <chrono>
#include <cmath>
#include <numbers>
#include <stdexcept>
#include <thread>

#include <gtest/gtest.h>

#include "vh/devices/device_catalog.h"
#include "vh/devices/dhd_device.h"
#include "vh/devices/fallback_device.h"
#include "vh/devices/openhaptics_device.h"
#include "vh/devices/vendor_library.h"
#include "vh/runtime/device.h"

namespace vh::devices {
namespace {

using namespace std::chrono_literals;

/// The test-only controls of a fake library (the same instance the driver dlopens by path).
class FakeLibrary {
 public:
  explicit FakeLibrary(const char* path) : handle_(dlopen(path, RTLD_NOW | RTLD_LOCAL)) {
    if (handle_ == nullptr) throw std::runtime_error(std::string("cannot load the fake library ") + path);
  }
  template <typename Fn>
  Fn* fn(const char* name) const {
    auto* f = reinterpret_cast<Fn*>(dlsym(handle_, name));
    if (f == nullptr) throw std::runtime_error(std::string("fake library lacks ") + name);
    return f;
  }

 private:
  void* handle_;
};

/// Waits up to 30 s for `done` (generous for a loaded machine; returns as soon as it holds).
template <typename Pred>
bool waitFor(Pred done) {
  const auto deadline = std::chrono::steady_clock::now() + 30s;
  while (!done()) {
    if (std::chrono::steady_clock::now() > deadline) return false;
    std::this_thread::sleep_for(1ms);
  }
  return true;
}

// ---- Force Dimension -----------------------------------------------------------------------------

struct Dhd {
  FakeLibrary lib{VH_FAKE_DHD_PATH};
  void (*reset)(int, int, const char*, int, int, int, double, double) =
      lib.fn<void(int, int, const char*, int, int, int, double, double)>("fakedhd_reset");
  void (*setPoses)(const double*, int) = lib.fn<void(const double*, int)>("fakedhd_set_poses");
  void (*failAfter)(long) = lib.fn<void(long)>("fakedhd_fail_after");
  long (*reads)() = lib.fn<long()>("fakedhd_reads");
  int (*commandCount)() = lib.fn<int()>("fakedhd_command_count");
  int (*command)(int, double*) = lib.fn<int(int, double*)>("fakedhd_command");
  int (*forceEnabled)() = lib.fn<int()>("fakedhd_force_enabled");
  int (*isOpen)() = lib.fn<int()>("fakedhd_is_open");

  std::shared_ptr<const DhdApi> api() const { return loadDhd({VH_FAKE_DHD_PATH}); }
  std::array<double, 6> lastCommand() const {
    std::array<double, 6> c{};
    command(commandCount() - 1, c.data());
    return c;
  }
};

TEST(DhdBackend, AMissingLibraryIsListedAsNotInstalled) {
  std::shared_ptr<const DhdApi> api;
  const VendorStatus status = probeDhd({"/nonexistent/libdhd.so.3"}, api);
  EXPECT_FALSE(status.installed);
  EXPECT_EQ(api, nullptr);
  EXPECT_EQ(status.kind, "forcedimension");
  EXPECT_NE(status.label().find("Force Dimension (DHD): not installed"), std::string::npos) << status.label();
  EXPECT_NE(status.detail.find("/nonexistent/libdhd.so.3"), std::string::npos) << status.detail;
  EXPECT_THROW(DhdDevice(nullptr), std::runtime_error);
}

TEST(DhdBackend, ALibraryWithoutTheApiIsNotInstalled) {
  try {
    loadDhd({VH_FAKE_HD_PATH});
    FAIL() << "loaded the OpenHaptics fake as DHD";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("lacks dhdGetDeviceCount"), std::string::npos) << e.what();
  }
}

TEST(DhdBackend, TheEnvironmentVariableReplacesTheDefaultNames) {
  ::setenv(kDhdLibraryEnv, VH_FAKE_DHD_PATH, 1);
  const auto candidates = vendorLibraryCandidates(kDhdLibraryEnv, defaultDhdLibraries());
  ::unsetenv(kDhdLibraryEnv);
  ASSERT_EQ(candidates.size(), 1u);
  EXPECT_EQ(candidates[0], VH_FAKE_DHD_PATH);
  EXPECT_EQ(vendorLibraryCandidates(kDhdLibraryEnv, defaultDhdLibraries()), defaultDhdLibraries());
  std::shared_ptr<const DhdApi> api;
  const VendorStatus status = probeDhd(candidates, api);
  EXPECT_TRUE(status.installed);
  EXPECT_EQ(status.detail, "SDK 3.14.0");
}

TEST(DhdDevice, NoDeviceIsAClearError) {
  Dhd fake;
  fake.reset(0, dhd::kDeviceSigma331, "sigma.7", 1, 1, 1, -1, -1);
  try {
    DhdDevice device(fake.api());
    FAIL() << "opened without a device";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("no Force Dimension device found"), std::string::npos) << e.what();
  }
}

TEST(DhdDevice, AnUncalibratedDeviceIsRefusedWithWhatToDo) {
  Dhd fake;
  fake.reset(1, dhd::kDeviceOmega331, "omega.7", 1, 0, /*calibrated=*/0, -1, -1);
  try {
    DhdDevice device(fake.api());
    FAIL() << "opened an uncalibrated device";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("omega.7 is not calibrated"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("autoinit"), std::string::npos) << e.what();
  }
  EXPECT_EQ(fake.isOpen(), 0);
  EXPECT_EQ(fake.forceEnabled(), 0);
}

TEST(DhdDevice, Sigma7SessionReportsPosesInMetresAndCommandsForceAndTorque) {
  Dhd fake;
  fake.reset(1, dhd::kDeviceSigma331, "sigma.7", 1, 1, 1, /*max force*/ 15.0, /*max torque*/ -1.0);
  const Eigen::Matrix3d R = Eigen::AngleAxisd(0.3, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  double pose[12] = {0.01, -0.02, 0.03};
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) pose[3 + 3 * i + j] = R(i, j);
  fake.setPoses(pose, 1);
  DhdDevice device(fake.api());
  EXPECT_EQ(device.name(), "sigma.7");
  EXPECT_EQ(device.identity().manufacturer, "Force Dimension");
  EXPECT_EQ(device.actuatedDof(), runtime::kDofAll);
  EXPECT_EQ(device.sensedDof(), runtime::kDofAll);
  EXPECT_DOUBLE_EQ(device.limits().max_force_N, 15.0);  // the SDK's software limit below the rating (20 N)
  EXPECT_DOUBLE_EQ(device.limits().max_torque_Nm, 0.4);
  EXPECT_DOUBLE_EQ(device.limits().max_linear_stiffness_N_per_m, 14500.0);
  EXPECT_EQ(fake.forceEnabled(), 1);

  runtime::DeviceSample sample;
  ASSERT_TRUE(waitFor([&] { return device.read(sample); }));
  EXPECT_NEAR((sample.X_WD.p_AB_m - Eigen::Vector3d(0.01, -0.02, 0.03)).norm(), 0.0, 1e-12);
  EXPECT_NEAR((sample.X_WD.R_AB.toRotationMatrix() - R).norm(), 0.0, 1e-12);
  EXPECT_TRUE(device.connected());

  device.command({1.0, -2.0, 3.0}, {0.1, -0.2, 0.3});
  ASSERT_TRUE(waitFor([&] { return fake.commandCount() > 0 && fake.lastCommand()[0] == 1.0; }));
  const auto c = fake.lastCommand();
  EXPECT_EQ(c, (std::array<double, 6>{1.0, -2.0, 3.0, 0.1, -0.2, 0.3}));  // N and N*m, as given
}

TEST(DhdDevice, Omega3SensesAndRendersTranslationOnly) {
  Dhd fake;
  fake.reset(1, dhd::kDeviceOmega3, "omega.3", /*wrist*/ 0, 0, 1, -1, -1);
  DhdDevice device(fake.api());
  EXPECT_EQ(device.sensedDof(), runtime::kDofTranslation);
  EXPECT_EQ(device.actuatedDof(), runtime::kDofTranslation);
  EXPECT_DOUBLE_EQ(device.limits().max_force_N, 12.0);
  EXPECT_DOUBLE_EQ(device.limits().max_torque_Nm, 0.0);
  device.command({0.5, 0.0, 0.0}, {0.1, 0.1, 0.1});
  ASSERT_TRUE(waitFor([&] { return fake.commandCount() > 0 && fake.lastCommand()[0] == 0.5; }));
  const auto c = fake.lastCommand();
  EXPECT_EQ(c[3], 0.0);
  EXPECT_EQ(c[4], 0.0);
  EXPECT_EQ(c[5], 0.0);
}

TEST(DhdDevice, AnErrorInMidSessionZeroesTheForceAndTheSimulatedDeviceTakesOver) {
  Dhd fake;
  fake.reset(1, dhd::kDeviceSigma331, "sigma.7", 1, 1, 1, -1, -1);
  auto device = std::make_shared<DhdDevice>(fake.api());
  auto simulated = std::make_shared<runtime::SimulatedDevice>(haptics::Pose{});
  FallbackDevice fallback(device, simulated);
  runtime::DeviceSample sample;
  ASSERT_TRUE(waitFor([&] { return device->read(sample); }));
  fallback.read(sample);
  EXPECT_FALSE(fallback.usingFallback());
  fallback.command({2.0, 0.0, 0.0}, {0.0, 0.0, 0.0});
  ASSERT_TRUE(waitFor([&] { return fake.commandCount() > 0 && fake.lastCommand()[0] == 2.0; }));

  fake.failAfter(fake.reads() + 5);
  ASSERT_TRUE(waitFor([&] { return !device->connected(); }));
  EXPECT_EQ(fake.lastCommand(), (std::array<double, 6>{}));  // zero force at once
  EXPECT_EQ(fake.forceEnabled(), 0);
  EXPECT_NE(device->problem().find("communication error"), std::string::npos) << device->problem();
  EXPECT_NE(device->problem().find("dhdGetPositionAndOrientationFrame"), std::string::npos) << device->problem();
  EXPECT_FALSE(device->read(sample));
  EXPECT_TRUE(fallback.read(sample));
  EXPECT_TRUE(fallback.usingFallback());
  const int before = fake.commandCount();
  fallback.command({5.0, 0.0, 0.0}, {0.0, 0.0, 0.0});  // goes to the simulated device
  runtime::DeviceCommand to_simulated;
  EXPECT_TRUE(simulated->lastCommand(to_simulated));
  EXPECT_DOUBLE_EQ(to_simulated.force_W_N.x(), 5.0);
  std::this_thread::sleep_for(5ms);
  EXPECT_EQ(fake.commandCount(), before);

  fake.failAfter(-1);
  device->reconnect();
  EXPECT_TRUE(device->connected());
  EXPECT_TRUE(device->problem().empty());
}

TEST(DhdDevice, TheSafetyLayerClampsToTheDevicesMaxForce) {
  Dhd fake;
  fake.reset(1, dhd::kDeviceDelta3, "delta.3", 0, 0, 1, -1, -1);
  DhdDevice device(fake.api());
  runtime::ForceSafety safety(device.limits(), runtime::SafetyPolicy{}, device.actuatedDof());
  safety.enable();
  runtime::SafetyInput in;
  in.sample_ok = true;
  in.sample_time_s = 1.0;
  in.force_W_N = {0.0, 0.0, 100.0};
  in.torque_W_Nm = {1.0, 0.0, 0.0};
  Eigen::Vector3d f, tau;
  safety.step(in, f, tau);
  EXPECT_DOUBLE_EQ(f.norm(), 20.0);  // delta.3's rating
  EXPECT_EQ(tau, Eigen::Vector3d::Zero());
  device.command(f, tau);
  ASSERT_TRUE(waitFor([&] { return fake.commandCount() > 0 && fake.lastCommand()[2] == 20.0; }));
  haptics::CouplingGains gains;
  gains.linear_N_per_m = 1e6;
  EXPECT_DOUBLE_EQ(runtime::clampGains(gains, device.limits()).linear_N_per_m, 14500.0);
}

// ---- OpenHaptics ---------------------------------------------------------------------------------

struct Hd {
  FakeLibrary lib{VH_FAKE_HD_PATH};
  void (*reset)(int, int, int, unsigned, int, double, double, double, const char*) =
      lib.fn<void(int, int, int, unsigned, int, double, double, double, const char*)>("fakehd_reset");
  void (*setTransforms)(const double*, int) = lib.fn<void(const double*, int)>("fakehd_set_transforms");
  void (*failAtFrame)(long, unsigned) = lib.fn<void(long, unsigned)>("fakehd_fail_at_frame");
  long (*frames)() = lib.fn<long()>("fakehd_frames");
  int (*commandCount)() = lib.fn<int()>("fakehd_command_count");
  int (*command)(int, double*) = lib.fn<int(int, double*)>("fakehd_command");
  int (*forceOutput)() = lib.fn<int()>("fakehd_force_output");
  int (*schedulerRunning)() = lib.fn<int()>("fakehd_scheduler_running");
  int (*calibrationUpdates)() = lib.fn<int()>("fakehd_calibration_updates");
  int (*pendingErrors)() = lib.fn<int()>("fakehd_pending_errors");

  std::shared_ptr<const HdApi> api() const { return loadHd({VH_FAKE_HD_PATH}); }
  std::array<double, 6> lastCommand() const {
    std::array<double, 6> c{};
    command(commandCount() - 1, c.data());
    return c;
  }
  /// A Touch: 6-DOF input, 3-DOF output, 3.3 N, 1.26 N/mm.
  void touch(unsigned calibration = hd::kCalibrationOk, int style = static_cast<int>(hd::kCalibrationAuto)) const {
    reset(1, 6, 3, calibration, style, 3.3, 1.26, 0.0, "Touch");
  }
};

TEST(OpenHapticsBackend, AMissingLibraryIsListedAsNotInstalled) {
  std::shared_ptr<const HdApi> api;
  const VendorStatus status = probeHd({"/nonexistent/libHD.so"}, api);
  EXPECT_FALSE(status.installed);
  EXPECT_EQ(api, nullptr);
  EXPECT_EQ(status.kind, "openhaptics");
  EXPECT_NE(status.label().find("OpenHaptics (HD): not installed"), std::string::npos) << status.label();
  EXPECT_THROW(OpenHapticsDevice(nullptr), std::runtime_error);
  try {
    loadHd({VH_FAKE_DHD_PATH});
    FAIL() << "loaded the DHD fake as OpenHaptics";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("lacks hdInitDevice"), std::string::npos) << e.what();
  }
}

TEST(OpenHapticsDevice, NoDeviceIsAClearError) {
  Hd fake;
  fake.reset(0, 6, 3, hd::kCalibrationOk, 2, 3.3, 1.26, 0.0, "Touch");
  try {
    OpenHapticsDevice device(fake.api());
    FAIL() << "opened without a device";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("no OpenHaptics device found"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("Device fault"), std::string::npos) << e.what();
  }
  EXPECT_EQ(fake.schedulerRunning(), 0);
}

TEST(OpenHapticsDevice, ManualCalibrationIsRefusedWithWhatToDo) {
  Hd fake;
  fake.touch(hd::kCalibrationNeedsManualInput, static_cast<int>(hd::kCalibrationInkwell));
  try {
    OpenHapticsDevice device(fake.api());
    FAIL() << "opened a device that needs manual calibration";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("Touch needs calibration: put the stylus in its inkwell"), std::string::npos)
        << e.what();
  }
  EXPECT_EQ(fake.schedulerRunning(), 0);
  EXPECT_EQ(fake.forceOutput(), 0);
}

TEST(OpenHapticsDevice, AnAutomaticCalibrationUpdateIsApplied) {
  Hd fake;
  fake.touch(hd::kCalibrationNeedsUpdate, static_cast<int>(hd::kCalibrationAuto));
  OpenHapticsDevice device(fake.api());
  EXPECT_EQ(fake.calibrationUpdates(), 1);
  EXPECT_TRUE(device.connected());
}

TEST(OpenHapticsDevice, TransformsInMillimetresColumnMajorBecomeMetres) {
  // Independent reference: a known rotation and translation written element by element.
  const Eigen::Matrix3d R = Eigen::AngleAxisd(-0.7, Eigen::Vector3d(0.2, -1.0, 0.4).normalized()).toRotationMatrix();
  const Eigen::Vector3d p_mm(12.5, -40.0, 7.25);
  double m[16] = {};
  for (int row = 0; row < 3; ++row)
    for (int col = 0; col < 3; ++col) m[col * 4 + row] = R(row, col);
  m[12] = p_mm.x();
  m[13] = p_mm.y();
  m[14] = p_mm.z();
  m[15] = 1.0;
  Eigen::Vector3d p;
  Eigen::Quaterniond q;
  OpenHapticsDevice::transformToPose(m, p, q);
  EXPECT_NEAR((p - Eigen::Vector3d(0.0125, -0.040, 0.00725)).norm(), 0.0, 1e-15);
  EXPECT_NEAR((q.toRotationMatrix() - R).norm(), 0.0, 1e-12);
}

TEST(OpenHapticsDevice, TouchSessionReadsPosesAndCommandsForceOnly) {
  Hd fake;
  fake.touch();
  const Eigen::Matrix3d R = Eigen::AngleAxisd(0.5, Eigen::Vector3d::UnitY()).toRotationMatrix();
  double m[16] = {};
  for (int row = 0; row < 3; ++row)
    for (int col = 0; col < 3; ++col) m[col * 4 + row] = R(row, col);
  m[12] = 10.0;
  m[13] = 20.0;
  m[14] = -30.0;
  m[15] = 1.0;
  fake.setTransforms(m, 1);
  OpenHapticsDevice device(fake.api());
  EXPECT_EQ(device.name(), "Touch");
  EXPECT_EQ(device.identity().serial, "FAKE-0001");
  EXPECT_EQ(device.sensedDof(), runtime::kDofAll);
  EXPECT_EQ(device.actuatedDof(), runtime::kDofTranslation);
  EXPECT_DOUBLE_EQ(device.limits().max_force_N, 3.3);                      // HD_NOMINAL_MAX_FORCE
  EXPECT_DOUBLE_EQ(device.limits().max_linear_stiffness_N_per_m, 1260.0);  // 1.26 N/mm
  EXPECT_DOUBLE_EQ(device.limits().max_torque_Nm, 0.0);
  EXPECT_DOUBLE_EQ(device.limits().workspace_radius_m, 0.035);
  EXPECT_EQ(fake.schedulerRunning(), 1);
  EXPECT_EQ(fake.forceOutput(), 1);

  runtime::DeviceSample sample;
  ASSERT_TRUE(waitFor([&] { return device.read(sample); }));
  EXPECT_NEAR((sample.X_WD.p_AB_m - Eigen::Vector3d(0.010, 0.020, -0.030)).norm(), 0.0, 1e-15);
  EXPECT_NEAR((sample.X_WD.R_AB.toRotationMatrix() - R).norm(), 0.0, 1e-12);

  device.command({0.5, -1.0, 1.5}, {0.1, 0.1, 0.1});
  ASSERT_TRUE(waitFor([&] { return fake.commandCount() > 0 && fake.lastCommand()[0] == 0.5; }));
  EXPECT_EQ(fake.lastCommand(), (std::array<double, 6>{0.5, -1.0, 1.5, 0.0, 0.0, 0.0}));
  EXPECT_EQ(fake.pendingErrors(), 0);  // every force was set inside a frame
}

TEST(OpenHapticsDevice, Premium6DofGetsTorqueInMilliNewtonMetres) {
  Hd fake;
  fake.reset(1, 6, 6, hd::kCalibrationOk, 1, 8.5, 3.5, 515.0, "PHANTOM Premium 1.5 6DOF");
  OpenHapticsDevice device(fake.api());
  EXPECT_EQ(device.actuatedDof(), runtime::kDofAll);
  EXPECT_DOUBLE_EQ(device.limits().max_torque_Nm, 0.515);
  EXPECT_DOUBLE_EQ(device.limits().max_angular_stiffness_Nm_per_rad, 0.05);
  device.command({1.0, 0.0, 0.0}, {0.1, -0.05, 0.2});
  ASSERT_TRUE(waitFor([&] { return fake.commandCount() > 0 && fake.lastCommand()[0] == 1.0; }));
  const auto c = fake.lastCommand();
  EXPECT_NEAR(c[3], 100.0, 1e-12);
  EXPECT_NEAR(c[4], -50.0, 1e-12);
  EXPECT_NEAR(c[5], 200.0, 1e-12);
}

TEST(OpenHapticsDevice, AnErrorInMidSessionZeroesTheForceAndTheSimulatedDeviceTakesOver) {
  Hd fake;
  fake.touch();
  auto device = std::make_shared<OpenHapticsDevice>(fake.api());
  auto simulated = std::make_shared<runtime::SimulatedDevice>(haptics::Pose{});
  FallbackDevice fallback(device, simulated);
  runtime::DeviceSample sample;
  ASSERT_TRUE(waitFor([&] { return device->read(sample); }));
  fallback.read(sample);
  fallback.command({2.0, 0.0, 0.0}, {0.0, 0.0, 0.0});
  ASSERT_TRUE(waitFor([&] { return fake.commandCount() > 0 && fake.lastCommand()[0] == 2.0; }));

  fake.failAtFrame(fake.frames() + 10, hd::kCommError);
  ASSERT_TRUE(waitFor([&] { return !device->connected(); }));
  ASSERT_TRUE(waitFor([&] { return fake.forceOutput() == 0; }));
  EXPECT_EQ(fake.lastCommand(), (std::array<double, 6>{}));  // a zero-force frame right after the error
  EXPECT_NE(device->problem().find("Communication error"), std::string::npos) << device->problem();
  EXPECT_FALSE(device->read(sample));
  EXPECT_TRUE(fallback.read(sample));
  EXPECT_TRUE(fallback.usingFallback());
  const long frames = fake.frames();
  std::this_thread::sleep_for(10ms);
  EXPECT_EQ(fake.frames(), frames);  // the servo callback stopped

  device->reconnect();
  EXPECT_TRUE(device->connected());
  EXPECT_TRUE(device->problem().empty());
}

TEST(OpenHapticsDevice, TheSafetyLayerClampsToTheSdksMaxForce) {
  Hd fake;
  fake.touch();
  OpenHapticsDevice device(fake.api());
  runtime::ForceSafety safety(device.limits(), runtime::SafetyPolicy{}, device.actuatedDof());
  safety.enable();
  runtime::SafetyInput in;
  in.sample_ok = true;
  in.sample_time_s = 1.0;
  in.force_W_N = {30.0, 40.0, 0.0};
  Eigen::Vector3d f, tau;
  safety.step(in, f, tau);
  EXPECT_NEAR(f.norm(), 3.3, 1e-12);
  EXPECT_NEAR(f.x() / f.y(), 0.75, 1e-12);  // direction kept
  device.command(f, tau);
  ASSERT_TRUE(waitFor([&] { return fake.commandCount() > 0 && std::abs(fake.lastCommand()[0] - f.x()) < 1e-12; }));
  const auto c = fake.lastCommand();
  EXPECT_LE(std::hypot(c[0], c[1], c[2]), 3.3 + 1e-12);
}

// ---- Catalog ------------------------------------------------------------------------------------

TEST(VendorCatalog, WithoutTheSdksTheBackEndsAreListedAsNotInstalled) {
  VendorLibraries none;
  none.dhd = {"/nonexistent/libdhd.so"};
  none.openhaptics = {"/nonexistent/libHD.so"};
  DeviceCatalog catalog(nullptr, nullptr, none);
  const std::vector<VendorStatus> status = catalog.vendorStatus();
  ASSERT_EQ(status.size(), 2u);
  EXPECT_EQ(status[0].kind, "forcedimension");
  EXPECT_FALSE(status[0].installed);
  EXPECT_EQ(status[1].kind, "openhaptics");
  EXPECT_FALSE(status[1].installed);
  EXPECT_TRUE(catalog.kinds().empty());
  EXPECT_TRUE(catalog.enumerate().empty());
  try {
    catalog.openFirst("openhaptics", "");
    FAIL() << "opened an OpenHaptics device without the SDK";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("not installed"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find(kHdLibraryEnv), std::string::npos) << e.what();
  }
}

TEST(VendorCatalog, ListsAndOpensVendorDevicesMappedIntoTheScene) {
  Dhd dhd_fake;
  dhd_fake.reset(2, dhd::kDeviceSigma331, "sigma.7", 1, 1, 1, -1, -1);
  Hd hd_fake;
  hd_fake.touch();
  VendorLibraries fakes;
  fakes.dhd = {VH_FAKE_DHD_PATH};
  fakes.openhaptics = {VH_FAKE_HD_PATH};
  DeviceCatalog catalog(nullptr, nullptr, fakes);
  EXPECT_EQ(catalog.kinds(), (std::vector<std::string>{"forcedimension", "openhaptics"}));
  const std::vector<FoundDevice> found = catalog.enumerate();
  ASSERT_EQ(found.size(), 3u);
  EXPECT_EQ(found[0].path, "dhd:0");
  EXPECT_EQ(found[1].path, "dhd:1");
  EXPECT_EQ(found[2].path, "hd:default");
  OpenOptions options;
  options.X_WT_initial.p_AB_m = {0.1, 0.0, 0.0};
  auto sigma = catalog.open(found[1], options);
  EXPECT_EQ(sigma->name(), "sigma.7");
  EXPECT_DOUBLE_EQ(sigma->limits().max_force_N, 20.0);
  // While it runs, listing does not call the SDK and keeps the devices found before.
  EXPECT_EQ(catalog.enumerate().size(), 3u);
  auto touch = catalog.open(found[2], options);
  EXPECT_DOUBLE_EQ(touch->limits().max_force_N, 3.3);
  EXPECT_DOUBLE_EQ(touch->limits().max_linear_stiffness_N_per_m, 1260.0);
  // DHD B: x towards the user, y right, z up; B y maps to W +x.
  runtime::DeviceSample sample;
  double pose[12] = {0.0, 0.01, 0.0, 1, 0, 0, 0, 1, 0, 0, 0, 1};
  dhd_fake.setPoses(pose, 1);
  ASSERT_TRUE(waitFor([&] { return sigma->read(sample) && sample.X_WD.p_AB_m.x() > 0.105; }));
  EXPECT_NEAR((sample.X_WD.p_AB_m - Eigen::Vector3d(0.11, 0.0, 0.0)).norm(), 0.0, 1e-12);
}

}  // namespace
}  // namespace vh::devices
