// Tests of vh/devices/device_catalog.h and fallback_device.h with fake backends: enumeration of
// the supported devices only, labels, opening mapped devices, default workspace mappings, hot-plug
// events, the scene registry (registerDeviceKind / makeDevice) and error messages, the simulated
// stand-in while hardware is unplugged, and a servo path (read / command) without allocation.
#include "vh/devices/device_catalog.h"
#include "vh/devices/fallback_device.h"

#include <chrono>
#include <cmath>
#include <functional>
#include <numbers>
#include <thread>

#include <gtest/gtest.h>

#include "allocation_guard.h"
#include "fakes.h"
#include "vh/runtime/scene.h"

namespace vh::devices {
namespace {

using test::FakeHidBackend;
using test::FakeUsbBackend;

HidDeviceInfo hidInfo(std::string path, std::uint16_t vid, std::uint16_t pid, std::string serial = {}, int iface = 0) {
  HidDeviceInfo info;
  info.path = std::move(path);
  info.vendor_id = vid;
  info.product_id = pid;
  info.serial = std::move(serial);
  info.interface_number = iface;
  return info;
}

struct Rig {
  std::shared_ptr<FakeHidBackend> hid = std::make_shared<FakeHidBackend>();
  std::shared_ptr<FakeUsbBackend> usb = std::make_shared<FakeUsbBackend>();
  std::shared_ptr<DeviceCatalog> catalog = std::make_shared<DeviceCatalog>(hid, usb);
};

/// Polls `done` every 2 ms until it holds or 30 s pass (generous: a device's I/O thread may run
/// late on a loaded machine; a condition that holds returns at once). @return done().
bool pollUntil(const std::function<bool()>& done) {
  const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(30);
  while (!done() && std::chrono::steady_clock::now() < give_up) std::this_thread::sleep_for(std::chrono::milliseconds(2));
  return done();
}

TEST(DeviceCatalog, ListsOnlyTheSupportedDevices) {
  Rig rig;
  rig.hid->add(hidInfo("/dev/hidraw0", 0x046D, 0xC52B));           // a keyboard receiver
  rig.hid->add(hidInfo("/dev/hidraw1", 0x046D, 0xC626, "SN-1"));   // SpaceNavigator
  rig.hid->add(hidInfo("/dev/hidraw2", 0x256F, 0xC635, {}, 1));    // Compact, second interface
  rig.hid->add(hidInfo("/dev/hidraw3", 0x256F, 0xC635, {}, 0));    // Compact
  rig.usb->add(9, "FAL-9");
  const std::vector<FoundDevice> found = rig.catalog->enumerate();
  ASSERT_EQ(found.size(), 3u);
  EXPECT_EQ(found[0].kind, "spacemouse");
  EXPECT_EQ(found[0].model, "SpaceNavigator");
  EXPECT_EQ(found[0].label(), "SpaceNavigator (3Dconnexion, serial SN-1, /dev/hidraw1)");
  EXPECT_EQ(found[1].model, "SpaceMouse Compact");
  EXPECT_EQ(found[1].path, "/dev/hidraw3");
  EXPECT_EQ(found[2].kind, "falcon");
  EXPECT_EQ(found[2].label(), "Novint Falcon (Novint, serial FAL-9, usb:1:9)");
  EXPECT_TRUE(rig.catalog->problems().empty());
  EXPECT_EQ(rig.catalog->backends(), (std::vector<std::string>{"fake-hid", "fake-usb"}));
  EXPECT_EQ(rig.catalog->kinds(), (std::vector<std::string>{"spacemouse", "falcon"}));
}

TEST(DeviceCatalog, AFailingBackendIsReportedNotThrown) {
  Rig rig;
  rig.usb->add(2);
  rig.hid->setFailure("udev is broken");
  const auto found = rig.catalog->enumerate();
  ASSERT_EQ(found.size(), 1u);
  ASSERT_EQ(rig.catalog->problems().size(), 1u);
  EXPECT_EQ(rig.catalog->problems()[0], "fake-hid: udev is broken");
}

TEST(DeviceCatalog, OpensMappedDevicesCentredOnTheTool) {
  Rig rig;
  rig.hid->add(hidInfo("/dev/hidraw1", 0x046D, 0xC626));
  auto falcon = rig.usb->add(9);
  falcon->setFirmwareRunning(true);
  falcon->setHandle({0.0, 0.0, falcon::kWorkspaceCentreZ_m});
  const auto found = rig.catalog->enumerate();
  OpenOptions options;
  options.X_WT_initial.p_AB_m = {0.1, 0.2, 0.3};
  options.X_WT_initial.R_AB = Eigen::Quaterniond(Eigen::AngleAxisd(0.4, Eigen::Vector3d::UnitZ()));
  auto spacemouse = rig.catalog->open(found[0], options);
  runtime::DeviceSample s;
  ASSERT_TRUE(spacemouse->read(s));
  EXPECT_TRUE(s.X_WD.p_AB_m.isApprox(Eigen::Vector3d(0.1, 0.2, 0.3)));
  EXPECT_NEAR(s.X_WD.R_AB.angularDistance(options.X_WT_initial.R_AB), 0.0, 1e-12);
  EXPECT_EQ(spacemouse->actuatedDof(), runtime::kDofNone);

  auto mapped_falcon = rig.catalog->open(found[1], options);
  EXPECT_EQ(mapped_falcon->name(), "Novint Falcon");
  pollUntil([&] { return mapped_falcon->read(s) && s.valid; });
  ASSERT_TRUE(s.valid);
  EXPECT_LT((s.X_WD.p_AB_m - Eigen::Vector3d(0.1, 0.2, 0.3)).norm(), 2e-4);
  EXPECT_NEAR(s.X_WD.R_AB.angularDistance(options.X_WT_initial.R_AB), 0.0, 1e-12);
}

TEST(DefaultWorkspaceMapping, TheFalconsUpIsTheScenesUp) {
  haptics::Pose X_WT;
  X_WT.p_AB_m = {0.0, 0.0, 0.05};
  const runtime::WorkspaceMapping m = defaultWorkspaceMapping("falcon", X_WT);
  // Handle 1 cm up (B's y) and 1 cm towards the user (B's z).
  const haptics::Pose X_WD = m.toWorld(haptics::Pose::FromTranslation({0.0, 0.01, 0.01}));
  EXPECT_TRUE(X_WD.p_AB_m.isApprox(Eigen::Vector3d(0.0, -0.01, 0.06), 1e-12));
  EXPECT_NEAR(X_WD.R_AB.angularDistance(Eigen::Quaterniond::Identity()), 0.0, 1e-12);
  runtime::WorkspaceSpec spec;
  spec.scale = 3.0;
  spec.offset_W_m = Eigen::Vector3d(1.0, 1.0, 1.0);
  spec.R_WB = Eigen::Quaterniond::Identity();
  const runtime::WorkspaceMapping n = defaultWorkspaceMapping("spacemouse", X_WT, spec);
  EXPECT_TRUE(n.toWorld(haptics::Pose::FromTranslation({0.01, 0.0, 0.0})).p_AB_m.isApprox(Eigen::Vector3d(1.03, 1.0, 1.0)));
  EXPECT_THROW(defaultWorkspaceMapping("phantom", X_WT), std::invalid_argument);
}

TEST(DeviceCatalog, OpenFirstSelectsBySerialOrPathAndSaysWhatItFound) {
  Rig rig;
  rig.hid->add(hidInfo("/dev/hidraw1", 0x046D, 0xC626, "A"));
  rig.hid->add(hidInfo("/dev/hidraw2", 0x046D, 0xC62B, "B"));
  auto device = rig.catalog->openFirst("spacemouse", "B");
  EXPECT_EQ(device->name(), "SpaceMouse Pro");
  device = rig.catalog->openFirst("spacemouse", "/dev/hidraw1");
  EXPECT_EQ(device->name(), "SpaceNavigator");
  try {
    rig.catalog->openFirst("falcon", "");
    FAIL() << "no exception";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("no Novint Falcon found (found: SpaceNavigator"), std::string::npos) << e.what();
  }
}

TEST(HotplugMonitor, ReportsArrivalsAndDepartures) {
  Rig rig;
  auto hid = rig.hid->add(hidInfo("/dev/hidraw1", 0x046D, 0xC626, "A"));
  HotplugMonitor monitor(rig.catalog);
  monitor.pollOnce();
  auto events = monitor.takeEvents();
  ASSERT_EQ(events.size(), 1u);
  EXPECT_EQ(events[0].kind, HotplugEvent::Kind::kArrived);
  EXPECT_EQ(events[0].device.serial, "A");
  monitor.pollOnce();
  EXPECT_TRUE(monitor.takeEvents().empty());
  hid->unplug();
  auto falcon = rig.usb->add(3);
  monitor.pollOnce();
  events = monitor.takeEvents();
  ASSERT_EQ(events.size(), 2u);
  EXPECT_EQ(events[0].kind, HotplugEvent::Kind::kLeft);
  EXPECT_EQ(events[0].device.serial, "A");
  EXPECT_EQ(events[1].kind, HotplugEvent::Kind::kArrived);
  EXPECT_EQ(events[1].device.kind, "falcon");
  EXPECT_EQ(monitor.devices().size(), 1u);
  // The thread polls on its own.
  monitor.start();
  hid->plugIn();
  bool arrived = false;
  pollUntil([&] {
    for (const HotplugEvent& e : monitor.takeEvents()) arrived = arrived || (e.kind == HotplugEvent::Kind::kArrived && e.device.serial == "A");
    return arrived;
  });
  monitor.stop();
  EXPECT_TRUE(arrived);
  EXPECT_THROW(HotplugMonitor(nullptr), std::invalid_argument);
}

TEST(SceneRegistry, HardwareKindsNeedARegisteredDriver) {
  using runtime::DeviceSpec;
  // A kind nobody registered: the parser names it and the driver it needs.
  try {
    runtime::parseScene(R"({"volume": {"path": "builtin:plane"}, "device": {"kind": "falcon"}})", "s.json", {});
    if (!runtime::deviceKindAvailable("falcon")) FAIL() << "parsed an unregistered kind";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("device.kind: unknown device kind 'falcon' in this program"), std::string::npos)
        << e.what();
  }
  // Registered (here with a fake factory): parsed with its fields, made by makeDevice.
  Rig rig;
  rig.hid->add(hidInfo("/dev/hidraw1", 0x046D, 0xC626, "S1"));
  auto catalog = rig.catalog;
  runtime::registerDeviceKind("test-spacemouse", [catalog](const DeviceSpec& spec, const haptics::Pose& X_WT) {
    OpenOptions options;
    options.X_WT_initial = X_WT;
    options.workspace = spec.workspace;
    return std::shared_ptr<runtime::Device>(catalog->openFirst("spacemouse", spec.select, options));
  });
  EXPECT_TRUE(runtime::deviceKindAvailable("test-spacemouse"));
  const runtime::SceneSpec spec = runtime::parseScene(
      R"({"volume": {"path": "builtin:plane"},
          "device": {"kind": "test-spacemouse", "select": "S1",
                     "workspace": {"scale": 2, "offset_m": [0, 0, 0.01], "q_wxyz": [1, 0, 0, 0]}}})",
      "s.json", {});
  ASSERT_TRUE(spec.device.has_value());
  EXPECT_EQ(spec.device->select, "S1");
  EXPECT_EQ(spec.device->workspace.scale, 2.0);
  ASSERT_TRUE(spec.device->workspace.offset_W_m.has_value());
  EXPECT_EQ(*spec.device->workspace.offset_W_m, Eigen::Vector3d(0.0, 0.0, 0.01));
  const runtime::LoadedScene scene = runtime::loadScene(spec);
  auto device = scene.makeDevice();
  ASSERT_NE(device, nullptr);
  EXPECT_EQ(device->name(), "SpaceNavigator");
  runtime::DeviceSample s;
  ASSERT_TRUE(device->read(s));
  EXPECT_TRUE(s.X_WD.p_AB_m.isApprox(Eigen::Vector3d(0.0, 0.0, 0.01)));
  // Fields of other kinds are errors.
  EXPECT_THROW(runtime::parseScene(R"({"volume": {"path": "builtin:plane"},
                                       "device": {"kind": "simulated", "select": "x"}})", "s.json", {}),
               std::runtime_error);
  EXPECT_THROW(runtime::parseScene(R"({"volume": {"path": "builtin:plane"},
                                       "device": {"kind": "test-spacemouse", "workspace": {"scale": 0}}})", "s.json", {}),
               std::runtime_error);
  EXPECT_THROW(runtime::registerDeviceKind("simulated", [](const DeviceSpec&, const haptics::Pose&) {
                 return std::shared_ptr<runtime::Device>();
               }),
               std::invalid_argument);
}

TEST(RegisterDeviceKinds, RegistersTheKindsOfThisBuild) {
  registerDeviceKinds();
  registerDeviceKinds();  // idempotent
  EXPECT_EQ(runtime::deviceKindAvailable("spacemouse"), VH_DEVICES_HAVE_HIDAPI != 0);
  EXPECT_EQ(runtime::deviceKindAvailable("falcon"), VH_DEVICES_HAVE_LIBUSB != 0);
}

}  // namespace
}  // namespace vh::devices

namespace vh::devices {
namespace {

TEST(ServoPath, ReadAndCommandOfTheMappedHardwareDevicesAllocateNothing) {
  Rig rig;
  auto hid = rig.hid->add(hidInfo("/dev/hidraw1", 0x046D, 0xC626));
  auto falcon = rig.usb->add(9);
  falcon->setFirmwareRunning(true);
  falcon->setHandle({0.0, 0.0, falcon::kWorkspaceCentreZ_m});
  const auto found = rig.catalog->enumerate();
  auto spacemouse = rig.catalog->open(found.at(0));
  auto mapped_falcon = rig.catalog->open(found.at(1));
  hid->push(test::axisReport(1, 100, 0, 0));
  runtime::DeviceSample s;
  pollUntil([&] { return mapped_falcon->read(s) && s.valid; });
  ASSERT_TRUE(s.valid);
  std::size_t allocations = 0;
  {
    vh::test::AllocationGuard guard;  // counts this thread's heap allocations
    for (int i = 0; i < 2000; ++i) {
      spacemouse->read(s);
      spacemouse->command(Eigen::Vector3d(1.0, 0.0, 0.0), Eigen::Vector3d::Zero());
      mapped_falcon->read(s);
      mapped_falcon->command(Eigen::Vector3d(0.0, 0.0, 1.0), Eigen::Vector3d::Zero());
      (void)mapped_falcon->limits();
      (void)mapped_falcon->connected();
    }
    allocations = guard.count();
  }
  EXPECT_EQ(allocations, 0u);
}

}  // namespace
}  // namespace vh::devices

namespace vh::devices {
namespace {

TEST(FallbackDevice, TheSimulatedDeviceStandsInWhileTheHardwareIsUnplugged) {
  Rig rig;
  auto hid = rig.hid->add(hidInfo("/dev/hidraw1", 0x046D, 0xC626, "S"));
  OpenOptions options;
  options.X_WT_initial.p_AB_m = {0.0, 0.0, 0.1};
  auto hardware = rig.catalog->open(rig.catalog->enumerate().at(0), options);
  auto simulated = std::make_shared<runtime::SimulatedDevice>(haptics::Pose::FromTranslation({0.5, 0.0, 0.0}));
  FallbackDevice device(hardware, simulated);
  EXPECT_EQ(device.actuatedDof(), runtime::kDofNone);  // the hardware's
  runtime::DeviceSample s;
  ASSERT_TRUE(device.read(s));
  EXPECT_FALSE(device.usingFallback());
  EXPECT_TRUE(s.X_WD.p_AB_m.isApprox(Eigen::Vector3d(0.0, 0.0, 0.1)));
  const std::uint32_t first = s.connection;

  hid->unplug();
  pollUntil([&] { return !device.connected(); });
  ASSERT_FALSE(device.connected());
  ASSERT_TRUE(device.read(s));
  EXPECT_TRUE(device.usingFallback());
  EXPECT_TRUE(s.X_WD.p_AB_m.isApprox(Eigen::Vector3d(0.5, 0.0, 0.0)));
  EXPECT_NE(s.connection, first);  // the safety layer re-engages from zero
  EXPECT_NE(device.name().find("disconnected"), std::string::npos);
  device.command({1.0, 0.0, 0.0}, Eigen::Vector3d::Zero());
  runtime::DeviceCommand c;
  ASSERT_TRUE(simulated->lastCommand(c));
  EXPECT_EQ(c.force_W_N, Eigen::Vector3d(1.0, 0.0, 0.0));
  const std::uint32_t second = s.connection;

  hid->plugIn();
  device.reconnect();
  ASSERT_TRUE(device.read(s));
  EXPECT_FALSE(device.usingFallback());
  EXPECT_NE(s.connection, second);
  EXPECT_THROW(FallbackDevice(nullptr, simulated), std::invalid_argument);
}

}  // namespace
}  // namespace vh::devices
