// Tests of vh/devices/spacemouse_device.h against a fake HID device (fakes.h), no hardware:
// reports through the I/O thread into rate control on the servo side, buttons, the LED, no force,
// unplugging and reconnecting.
#include "vh/devices/spacemouse_device.h"

#include <chrono>
#include <functional>
#include <thread>

#include <gtest/gtest.h>

#include "fakes.h"

namespace vh::devices {
namespace {

using namespace std::chrono_literals;
using test::axisReport;
using test::FakeHidBackend;

bool waitFor(const std::function<bool()>& condition, std::chrono::milliseconds timeout = 30000ms) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  while (std::chrono::steady_clock::now() < deadline) {
    if (condition()) return true;
    std::this_thread::sleep_for(1ms);
  }
  return condition();
}

HidDeviceInfo navigator(const std::string& path = "/dev/hidraw7") {
  HidDeviceInfo info;
  info.path = path;
  info.vendor_id = 0x046D;
  info.product_id = 0xC626;
  info.manufacturer = "3Dconnexion";
  info.product = "SpaceNavigator";
  info.interface_number = 0;
  return info;
}

TEST(SpaceMouseDevice, DeflectionMovesTheHandleAtTheRateItSets) {
  auto backend = std::make_shared<FakeHidBackend>();
  auto hid = backend->add(navigator());
  SpaceMouseOptions options;
  options.rate.deadzone = 0.0;
  options.rate.max_speed_m_per_s = 0.1;
  options.rate.max_step_s = 10.0;  // exact integration whatever the test machine's load
  SpaceMouseDevice device(backend, navigator(), options);
  EXPECT_EQ(device.name(), "SpaceNavigator");
  EXPECT_EQ(device.actuatedDof(), runtime::kDofNone);
  EXPECT_EQ(device.sensedDof(), runtime::kDofAll);
  EXPECT_EQ(device.limits().max_force_N, 0.0);
  EXPECT_EQ(hid->written().at(0), (std::vector<std::uint8_t>{4, 15}));  // LED on

  runtime::DeviceSample s;
  ASSERT_TRUE(device.read(s));
  EXPECT_EQ(s.X_WD.p_AB_m, Eigen::Vector3d::Zero());
  hid->push(axisReport(1, 350, 0, 0));  // full deflection to the right
  hid->push(axisReport(3, 0x0002, 0, 0));  // a report of buttons: 3 bytes after the id... (3, 2, 0)
  ASSERT_TRUE(waitFor([&] { return device.reportsReceived() >= 2; }));
  ASSERT_TRUE(device.read(s));
  const double t0 = s.time_s;
  const double x0 = s.X_WD.p_AB_m.x();
  for (int i = 0; i < 100; ++i) {  // as the servo loop would
    std::this_thread::sleep_for(1ms);
    ASSERT_TRUE(device.read(s));
  }
  const double dt = s.time_s - t0;
  EXPECT_NEAR(s.X_WD.p_AB_m.x() - x0, 0.1 * dt, 1e-9);
  EXPECT_NEAR(s.v_WD_m_per_s.x(), 0.1, 1e-12);
  EXPECT_EQ(s.buttons, 2u);
  EXPECT_TRUE(s.valid);
  // Released: it stays where it went.
  hid->push(axisReport(1, 0, 0, 0));
  ASSERT_TRUE(waitFor([&] { return device.reportsReceived() >= 3; }));
  ASSERT_TRUE(device.read(s));
  const double x1 = s.X_WD.p_AB_m.x();
  std::this_thread::sleep_for(20ms);
  ASSERT_TRUE(device.read(s));
  EXPECT_EQ(s.X_WD.p_AB_m.x(), x1);
  EXPECT_EQ(s.v_WD_m_per_s, Eigen::Vector3d::Zero());
  device.recentre();
  ASSERT_TRUE(device.read(s));
  EXPECT_EQ(s.X_WD.p_AB_m, Eigen::Vector3d::Zero());
}

TEST(SpaceMouseDevice, CommandsAreRecordedButNothingIsSentToThePuck) {
  auto backend = std::make_shared<FakeHidBackend>();
  auto hid = backend->add(navigator());
  SpaceMouseDevice device(backend, navigator());
  device.command({1.0, 2.0, 3.0}, Eigen::Vector3d::Zero());
  runtime::DeviceCommand c;
  ASSERT_TRUE(device.lastCommand(c));
  EXPECT_EQ(c.force_W_N, Eigen::Vector3d(1.0, 2.0, 3.0));
  EXPECT_EQ(hid->written().size(), 1u);  // the LED report only
}

TEST(SpaceMouseDevice, UnpluggingIsReportedAndReconnectingKeepsThePose) {
  auto backend = std::make_shared<FakeHidBackend>();
  auto hid = backend->add(navigator());
  SpaceMouseOptions options;
  options.rate.deadzone = 0.0;
  SpaceMouseDevice device(backend, navigator(), options);
  hid->push(axisReport(1, 0, 0, -350));  // pushing the cap up... raw Z < 0 is up: +z of B
  ASSERT_TRUE(waitFor([&] { return device.reportsReceived() >= 1; }));
  runtime::DeviceSample s;
  ASSERT_TRUE(device.read(s));
  std::this_thread::sleep_for(30ms);
  ASSERT_TRUE(device.read(s));
  const double z = s.X_WD.p_AB_m.z();
  EXPECT_GT(z, 0.0);
  const std::uint32_t connection = s.connection;

  hid->unplug();
  ASSERT_TRUE(waitFor([&] { return !device.connected(); }));
  EXPECT_FALSE(device.read(s));
  EXPECT_NE(device.problem().find("unplugged"), std::string::npos);
  EXPECT_THROW(device.reconnect(), std::runtime_error);

  hid->plugIn();
  device.reconnect();
  ASSERT_TRUE(device.connected());
  ASSERT_TRUE(device.read(s));
  EXPECT_NE(s.connection, connection);
  EXPECT_GE(s.X_WD.p_AB_m.z(), z);  // the handle did not jump back
  EXPECT_EQ(device.problem(), "");
}

TEST(SpaceMouseDevice, RejectsDevicesThatAreNotASpaceMouse) {
  auto backend = std::make_shared<FakeHidBackend>();
  HidDeviceInfo other = navigator();
  other.product_id = 0x1234;
  EXPECT_THROW(SpaceMouseDevice(backend, other), std::invalid_argument);
  EXPECT_THROW(SpaceMouseDevice(backend, navigator("/dev/none")), std::runtime_error);
}

}  // namespace
}  // namespace vh::devices
