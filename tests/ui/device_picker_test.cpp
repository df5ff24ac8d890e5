// DevicePicker and deviceLimitsText() on the built-in sphere without hardware: entry 0 is the
// simulated device, which the picker puts into the session at the proxy's pose; a device's
// limits read as text.
#include "vh/ui/devices/device_picker.h"

#include <cstdlib>
#include <memory>

#include <QSignalSpy>

#include <gtest/gtest.h>

#include "ui_test_util.h"

#include "vh/runtime/scene.h"
#include "vh/runtime/session.h"
#include "vh/runtime/trajectory.h"

namespace vh::ui {
namespace {

using test::sphereProbeScene;


TEST(DevicePicker, EntryZeroPutsASimulatedDeviceAtTheProxysPose) {
  runtime::Session session;
  session.setScene(sphereProbeScene(), nullptr);
  DevicePicker picker(session, nullptr);
  picker.setInteractive(false);
  const QStringList choices = picker.choices();
  ASSERT_FALSE(choices.isEmpty());
  EXPECT_EQ(choices.front(), "Simulated device (mouse/keyboard)");
  EXPECT_EQ(picker.currentChoice(), -1) << "the session has no device yet";

  QSignalSpy changed(&picker, &DevicePicker::choiceChanged);
  ASSERT_TRUE(picker.choose(0));
  runtime::SimulatedDevice* device = session.simulatedDevice();
  ASSERT_NE(device, nullptr);
  // Without a snapshot the proxy is at the scene's initial pose.
  const haptics::Pose& X_WT = sphereProbeScene().X_WT_initial;
  EXPECT_LT((device->pose().p_AB_m - X_WT.p_AB_m).norm(), 1e-12);
  EXPECT_LT(device->pose().R_AB.angularDistance(X_WT.R_AB), 1e-12);
  EXPECT_EQ(picker.currentChoice(), 0);
  ASSERT_GE(changed.count(), 1);
  EXPECT_EQ(changed.last().at(0).toInt(), 0);
  EXPECT_NE(session.hapticThread(), nullptr) << "the session built haptic threads for the device";

  // Entry 0 again keeps the simulated device.
  ASSERT_TRUE(picker.choose(0));
  EXPECT_EQ(session.simulatedDevice(), device);
}

TEST(DevicePicker, ListsVendorBackEndsWithoutTheirSdkAsNotInstalled) {
  // The variables are set before any thread starts and unset only after the picker (and its
  // hotplug thread, whose udev and libusb calls read the environment) is gone: setenv and
  // unsetenv beside a thread that reads the environment is a data race that can crash.
  ::setenv("VH_DHD_LIBRARY", "/nonexistent/libdhd.so", 1);
  ::setenv("VH_OPENHAPTICS_LIBRARY", "/nonexistent/libHD.so", 1);
  {
    runtime::Session session;
    session.setScene(sphereProbeScene(), nullptr);
    DevicePicker picker(session, nullptr);
    picker.setInteractive(false);
    const QStringList missing = picker.notInstalled();
    EXPECT_TRUE(missing.contains("Force Dimension (DHD): not installed")) << missing.join("; ").toStdString();
    EXPECT_TRUE(missing.contains("3D Systems OpenHaptics (HD): not installed")) << missing.join("; ").toStdString();
    for (const QString& choice : picker.choices()) EXPECT_FALSE(choice.contains("not installed"));  // not pickable
    EXPECT_TRUE(picker.choose(0));  // the app runs on with the simulated device
  }
  ::unsetenv("VH_DHD_LIBRARY");
  ::unsetenv("VH_OPENHAPTICS_LIBRARY");
}

TEST(DevicePicker, AnEntryOutOfRangeKeepsTheDevice) {
  runtime::Session session;
  session.setScene(sphereProbeScene(), nullptr);
  DevicePicker picker(session, nullptr);
  picker.setInteractive(false);
  ASSERT_TRUE(picker.choose(0));
  runtime::Device* device = session.device();
  const int past_the_end = static_cast<int>(picker.choices().size()) + 4;  // 5 without hardware
  EXPECT_FALSE(picker.choose(past_the_end));
  EXPECT_FALSE(picker.choose(-1));
  EXPECT_EQ(session.device(), device);
  EXPECT_EQ(picker.currentChoice(), 0);
}

TEST(DevicePicker, ADevicesLimitsReadAsText) {
  const runtime::SimulatedDevice simulated(haptics::Pose::Identity());
  EXPECT_TRUE(deviceLimitsText(simulated).contains("No force or workspace limits")) << deviceLimitsText(simulated).toStdString();

  runtime::ScriptedDevice scripted(runtime::Trajectory({runtime::TrajectorySample{0.0, haptics::Pose::Identity()}}));
  runtime::DeviceLimits limits;
  limits.max_force_N = 8.5;
  limits.max_torque_Nm = 0.25;
  limits.workspace_radius_m = 0.05;
  scripted.setLimits(limits);
  const QString text = deviceLimitsText(scripted);
  EXPECT_TRUE(text.contains("8.5 N")) << text.toStdString();
  EXPECT_TRUE(text.contains("0.25 N")) << text.toStdString();
  EXPECT_TRUE(text.contains("50 mm")) << text.toStdString();
  EXPECT_FALSE(text.contains("No force")) << text.toStdString();
}

}  // namespace
}  // namespace vh::ui
