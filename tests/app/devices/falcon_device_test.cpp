// Tests of vh/devices/falcon_device.h against FakeFalcon (fakes.h), no hardware: the firmware
// upload's control transfers and echo checks, opening a Falcon that runs its firmware or needs
// it, the I/O loop (position by forward kinematics, force through the Jacobian into motor
// commands, homing, LEDs), a silent or unplugged device, reconnecting.
#include "vh/devices/falcon_device.h"

#include <chrono>
#include <filesystem>
#include <fstream>
#include <functional>
#include <thread>

#include <unistd.h>

#include <gtest/gtest.h>

#include "fakes.h"
#include "vh/devices/falcon_kinematics.h"

namespace vh::devices {
namespace {

using namespace std::chrono_literals;
using test::FakeFalcon;
using test::FakeUsbBackend;
using test::FakeUsbTransport;

bool waitFor(const std::function<bool()>& condition, std::chrono::milliseconds timeout = 30000ms) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  while (std::chrono::steady_clock::now() < deadline) {
    if (condition()) return true;
    std::this_thread::sleep_for(1ms);
  }
  return condition();
}

std::vector<std::uint8_t> fakeFirmware(std::size_t n) {
  std::vector<std::uint8_t> fw(n);
  for (std::size_t i = 0; i < n; ++i) fw[i] = static_cast<std::uint8_t>((i * 37 + 11) & 0xFF);
  return fw;
}

/// A firmware file in the temporary folder, unique to this process (tests of several build
/// trees may run at once), removed at the end of the test.
struct TempFile {
  TempFile(const std::vector<std::uint8_t>& bytes, const std::string& name)
      : path(std::filesystem::temp_directory_path() / (std::to_string(::getpid()) + "-" + name)) {
    std::ofstream out(path, std::ios::binary);
    out.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
  }
  ~TempFile() {
    std::error_code ec;
    std::filesystem::remove(path, ec);
  }
  TempFile(const TempFile&) = delete;
  TempFile& operator=(const TempFile&) = delete;
  std::filesystem::path path;
};

/// The control transfers the document prescribes for an upload with `boot_attempts` boot checks.
std::vector<FakeFalcon::Control> expectedUploadControls(int boot_attempts) {
  std::vector<FakeFalcon::Control> out;
  for (int i = 0; i < boot_attempts; ++i) {
    for (const auto& s : falcon::kBootloaderSetup) out.push_back({0x40, s.request, s.value, 0});
  }
  for (const auto& s : falcon::kLoaderSetup) out.push_back({0x40, s.request, s.value, 0});
  for (const auto& s : falcon::kNormalModeSetup) out.push_back({0x40, s.request, s.value, 0});
  return out;
}

TEST(FalconFirmware, UploadFollowsTheDocumentedSequenceAndEveryByteIsEchoed) {
  auto falcon = std::make_shared<FakeFalcon>();
  falcon->setBootCheckFailures(2);  // the boot loader answers on the third attempt
  falcon->setBootReplyBytes(3);     // only part of the reply comes back
  FakeUsbTransport usb(falcon);
  const auto firmware = fakeFirmware(1000);  // 16 full blocks of 62 bytes and one of 8
  uploadFalconFirmware(usb, firmware);
  EXPECT_EQ(falcon->uploaded(), firmware);
  EXPECT_EQ(falcon->bootChecks(), 3);
  EXPECT_EQ(falcon->controls(), expectedUploadControls(3));
  EXPECT_TRUE(falcon->running());
  EXPECT_TRUE(falconFirmwareLoaded(usb));
}

TEST(FalconFirmware, AWrongEchoStopsTheUploadNamingTheByte) {
  auto falcon = std::make_shared<FakeFalcon>();
  falcon->corruptEchoAt(100);
  FakeUsbTransport usb(falcon);
  try {
    uploadFalconFirmware(usb, fakeFirmware(300));
    FAIL() << "no exception";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("Falcon firmware upload: image: byte 100 echoed as 0x"), std::string::npos)
        << e.what();
  }
}

TEST(FalconFirmware, AFalconThatNeverAnswersTheBootCheckGivesUp) {
  auto falcon = std::make_shared<FakeFalcon>();
  falcon->setBootCheckFailures(1000);
  FakeUsbTransport usb(falcon);
  FalconUploadOptions options;
  options.boot_check_attempts = 5;
  try {
    uploadFalconFirmware(usb, fakeFirmware(10), options);
    FAIL() << "no exception";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("boot check: no answer to 0A 43 0D after 5 attempts"), std::string::npos)
        << e.what();
  }
  EXPECT_EQ(falcon->bootChecks(), 5);
}

TEST(FalconFirmware, FirmwareFileErrorsNameTheFile) {
  EXPECT_THROW(readFalconFirmwareFile("/no/such/nvent_firmware.bin"), std::runtime_error);
  try {
    readFalconFirmwareFile("/no/such/nvent_firmware.bin");
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("/no/such/nvent_firmware.bin: Falcon firmware file not found"),
              std::string::npos);
  }
  const TempFile empty({}, "vh_empty_firmware.bin");
  EXPECT_THROW(readFalconFirmwareFile(empty.path), std::runtime_error);
  const TempFile ok(fakeFirmware(123), "vh_ok_firmware.bin");
  EXPECT_EQ(readFalconFirmwareFile(ok.path), fakeFirmware(123));
}

TEST(FalconDevice, OpensAFalconThatRunsItsFirmwareWithoutUploading) {
  auto backend = std::make_shared<FakeUsbBackend>();
  auto falcon = backend->add(3, "FALCON-1");
  falcon->setFirmwareRunning(true);
  falcon->setHandle({0.01, -0.005, 0.12});
  FalconDevice device(backend, backend->enumerate(falcon::kVendorId, falcon::kProductId).at(0));
  EXPECT_TRUE(falcon->uploaded().empty());
  EXPECT_EQ(device.identity().model, "Novint Falcon");
  EXPECT_EQ(device.identity().serial, "FALCON-1");
  EXPECT_EQ(device.actuatedDof(), runtime::kDofTranslation);
  EXPECT_EQ(device.sensedDof(), runtime::kDofTranslation);
  EXPECT_EQ(device.limits().max_force_N, 8.0);
  EXPECT_EQ(device.limits().max_linear_stiffness_N_per_m, 3000.0);
  EXPECT_EQ(device.limits().workspace_radius_m, 0.04);
  ASSERT_TRUE(waitFor([&] { return device.packetsReceived() > 20; }));
  runtime::DeviceSample s;
  ASSERT_TRUE(device.read(s));
  EXPECT_TRUE(s.valid);
  // Position from the encoders through forward kinematics, in B (origin at the workspace centre);
  // the encoders quantise the angles (about 0.6 mrad per count).
  EXPECT_LT((s.X_WD.p_AB_m - Eigen::Vector3d(0.01, -0.005, 0.01)).norm(), 2e-4) << s.X_WD.p_AB_m.transpose();
  EXPECT_TRUE(device.homed());
  EXPECT_EQ(falcon->lastCommand().flags, falcon::kLedGreen);
}

TEST(FalconDevice, UploadsTheFirmwareWhenNeededAndSaysSoWhenItHasNone) {
  auto backend = std::make_shared<FakeUsbBackend>();
  auto falcon = backend->add(4);
  const auto info = backend->enumerate(falcon::kVendorId, falcon::kProductId).at(0);
  try {
    FalconDevice device(backend, info);
    FAIL() << "opened without firmware";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("its firmware is not loaded"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("nvent_firmware.bin"), std::string::npos) << e.what();
  }
  const TempFile file(fakeFirmware(500), "vh_test_firmware.bin");
  FalconOptions options;
  options.firmware = file.path;
  FalconDevice device(backend, info, options);
  EXPECT_EQ(falcon->uploaded(), fakeFirmware(500));
  ASSERT_TRUE(waitFor([&] { return device.packetsReceived() > 5; }));
}

TEST(FalconDevice, ForceGoesThroughTheJacobianIntoMotorCommands) {
  auto backend = std::make_shared<FakeUsbBackend>();
  auto falcon = backend->add(5);
  falcon->setFirmwareRunning(true);
  const Eigen::Vector3d p_K(-0.01, 0.015, 0.105);
  falcon->setHandle(p_K);
  FalconDevice device(backend, backend->enumerate(falcon::kVendorId, falcon::kProductId).at(0));
  ASSERT_TRUE(waitFor([&] { return device.packetsReceived() > 20; }));
  runtime::DeviceSample s;
  ASSERT_TRUE(device.read(s));
  const Eigen::Vector3d F_B(0.0, 2.0, -1.0);
  device.command(F_B, Eigen::Vector3d(5.0, 5.0, 5.0));  // torque: not actuated, ignored
  // The command the device gets: motor = -10000 J^T F at the measured position.
  Eigen::Vector3d tau;
  ASSERT_TRUE(falcon::jointTorques(s.X_WD.p_AB_m + Eigen::Vector3d(0.0, 0.0, falcon::kWorkspaceCentreZ_m), F_B, tau));
  const auto expected = falcon::motorCommands(tau);
  ASSERT_TRUE(waitFor([&] { return falcon->lastCommand().motor == expected; }))
      << falcon->lastCommand().motor[0] << " " << falcon->lastCommand().motor[1] << " " << falcon->lastCommand().motor[2];
  EXPECT_NE(expected, (std::array<std::int16_t, 3>{0, 0, 0}));
  device.command(Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero());
  ASSERT_TRUE(waitFor([&] { return falcon->lastCommand().motor == std::array<std::int16_t, 3>{0, 0, 0}; }));
}

TEST(FalconDevice, NoForceAndInvalidSamplesUntilHomed) {
  auto backend = std::make_shared<FakeUsbBackend>();
  auto falcon = backend->add(6);
  falcon->setFirmwareRunning(true);
  falcon->setHandle({0.0, 0.0, 0.11}, /*homed_mask=*/0x3);
  FalconDevice device(backend, backend->enumerate(falcon::kVendorId, falcon::kProductId).at(0));
  ASSERT_TRUE(waitFor([&] { return device.packetsReceived() > 10; }));
  device.command({0.0, 0.0, 5.0}, Eigen::Vector3d::Zero());
  std::this_thread::sleep_for(20ms);
  runtime::DeviceSample s;
  ASSERT_TRUE(device.read(s));
  EXPECT_FALSE(s.valid);
  EXPECT_FALSE(device.homed());
  EXPECT_EQ(falcon->lastCommand().flags, falcon::kLedRed | falcon::kHomingMode);
  EXPECT_EQ(falcon->lastCommand().motor, (std::array<std::int16_t, 3>{0, 0, 0}));
  EXPECT_NE(device.problem().find("not homed"), std::string::npos);
  falcon->setHandle({0.0, 0.0, 0.11}, 0x7);
  ASSERT_TRUE(waitFor([&] { return device.homed() && device.read(s) && s.valid; }));
  EXPECT_EQ(device.problem(), "");
}

TEST(FalconDevice, ASilentFalconKeepsItsLastSampleTimeSoTheSafetyLayerZeroesIt) {
  auto backend = std::make_shared<FakeUsbBackend>();
  auto falcon = backend->add(7);
  falcon->setFirmwareRunning(true);
  falcon->setHandle({0.0, 0.0, 0.11});
  FalconDevice device(backend, backend->enumerate(falcon::kVendorId, falcon::kProductId).at(0));
  ASSERT_TRUE(waitFor([&] { return device.packetsReceived() > 10; }));
  falcon->setSilent(true);
  // Counted, not timed: once the I/O thread found the fake's queue empty twice, every status the
  // fake sent before falling silent has been read, so no new measurement can follow.
  ASSERT_TRUE(waitFor([&] { return falcon->emptyReadsWhileSilent() >= 2; }));
  runtime::DeviceSample a, b;
  ASSERT_TRUE(device.read(a));
  std::this_thread::sleep_for(30ms);
  ASSERT_TRUE(device.read(b));
  EXPECT_EQ(a.time_s, b.time_s);  // no new measurement: ForceSafety's silent_s trips
  EXPECT_TRUE(device.connected());
}

TEST(FalconDevice, UnpluggingIsReportedAndReconnectingUploadsTheFirmwareAgain) {
  auto backend = std::make_shared<FakeUsbBackend>();
  auto falcon = backend->add(8, "F-8");
  const TempFile file(fakeFirmware(200), "vh_test_firmware2.bin");
  FalconOptions options;
  options.firmware = file.path;
  FalconDevice device(backend, backend->enumerate(falcon::kVendorId, falcon::kProductId).at(0), options);
  ASSERT_TRUE(waitFor([&] { return device.packetsReceived() > 5; }));
  runtime::DeviceSample s;
  ASSERT_TRUE(device.read(s));
  const std::uint32_t connection = s.connection;

  falcon->unplug();
  ASSERT_TRUE(waitFor([&] { return !device.connected(); }));
  EXPECT_FALSE(device.read(s));
  EXPECT_NE(device.problem().find("unplugged"), std::string::npos) << device.problem();
  EXPECT_THROW(device.reconnect(), std::runtime_error);  // still unplugged

  falcon->plugIn();  // powered up again: no firmware
  device.reconnect();
  EXPECT_TRUE(device.connected());
  ASSERT_TRUE(waitFor([&] { return device.read(s) && s.valid; }));
  EXPECT_NE(s.connection, connection);  // the safety layer re-engages through its gate
  EXPECT_EQ(falcon->uploaded(), fakeFirmware(200));
}

}  // namespace
}  // namespace vh::devices
