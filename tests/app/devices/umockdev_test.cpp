// Integration tests of the hidapi and libusb backends against fake devices under umockdev (no
// hardware; the kernel here has no uhid or USB gadget support). Run under umockdev-wrapper
// (ctest does); without it every test skips with a message.
//
//   UmockdevSpaceMouse: a fake SpaceNavigator in sysfs (hidraw node with its `L: device=` link,
//     HID parent, USB device) whose ioctl handler answers HIDIOCGRDESCSIZE / HIDIOCGRDESC and
//     whose read handler hands out queued input reports (blocking reads: umockdev never signals
//     poll on it). Enumerated by hidapi and the DeviceCatalog, read through the transport and
//     the SpaceMouseDevice, unplugged.
//   UmockdevFalcon: a fake Novint Falcon (FTDI 0403:cb48) in sysfs whose usbdevfs ioctl handler
//     runs FakeFalcon (fakes.h) for every URB: enumerated and opened by libusb, the set-up
//     control transfers of the firmware upload checked, the I/O loop of FalconDevice, unplugged.
#include <linux/hidraw.h>
#include <linux/usbdevice_fs.h>
#include <sys/ioctl.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <deque>
#include <filesystem>
#include <fstream>
#include <functional>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>
#include <umockdev.h>

#include "fakes.h"
#include "vh/devices/device_catalog.h"
#include "vh/devices/falcon_device.h"
#include "vh/devices/spacemouse_device.h"
#include "vh/devices/transport.h"

namespace vh::devices {
namespace {

using namespace std::chrono_literals;

bool underUmockdev() {
  const char* preload = std::getenv("LD_PRELOAD");
  return preload != nullptr && std::strstr(preload, "libumockdev-preload") != nullptr;
}

#define VH_REQUIRE_UMOCKDEV()                                                                       \
  do {                                                                                              \
    if (!underUmockdev()) {                                                                         \
      GTEST_SKIP() << "not running under umockdev-wrapper (LD_PRELOAD of libumockdev-preload); "   \
                      "run: umockdev-wrapper " << ::testing::internal::GetArgvs()[0];               \
    }                                                                                               \
  } while (false)

bool waitFor(const std::function<bool()>& condition, std::chrono::milliseconds timeout = 30000ms) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  while (std::chrono::steady_clock::now() < deadline) {
    if (condition()) return true;
    std::this_thread::sleep_for(1ms);
  }
  return condition();
}

/// A umockdev testbed for one test.
class Testbed {
 public:
  Testbed() : testbed_(umockdev_testbed_new()) {}
  ~Testbed() { g_object_unref(testbed_); }
  Testbed(const Testbed&) = delete;
  Testbed& operator=(const Testbed&) = delete;
  UMockdevTestbed* get() const { return testbed_; }
  void attach(const char* devnode, UMockdevIoctlBase* handler) {
    GError* error = nullptr;
    ASSERT_TRUE(umockdev_testbed_attach_ioctl(testbed_, devnode, handler, &error))
        << (error != nullptr ? error->message : "attach failed");
  }
  void add(const std::string& description) {
    GError* error = nullptr;
    ASSERT_TRUE(umockdev_testbed_add_from_string(testbed_, description.c_str(), &error))
        << (error != nullptr ? error->message : "add failed");
  }
  void remove(const std::string& syspath) {
    const std::string full = "/sys" + syspath;
    umockdev_testbed_remove_device(testbed_, full.c_str());
  }

 private:
  UMockdevTestbed* testbed_;
};

// ---- A fake SpaceNavigator on hidraw --------------------------------------------------------------

/// HID report descriptor of a multi-axis controller (usage page 1, usage 8), enough for hidapi.
constexpr std::uint8_t kReportDescriptor[] = {0x05, 0x01, 0x09, 0x08, 0xA1, 0x01, 0xC0};

const char* kSpaceNavigatorSysfs =
    "P: /devices/pci0000:00/0000:00:14.0/usb1/1-3\n"
    "N: bus/usb/001/005\n"
    "E: SUBSYSTEM=usb\nE: DEVTYPE=usb_device\nE: BUSNUM=001\nE: DEVNUM=005\n"
    "A: idVendor=046d\\n\nA: idProduct=c626\\n\nA: manufacturer=3Dconnexion\\n\n"
    "A: product=SpaceNavigator\\n\nA: serial=FAKE-SN-42\\n\nA: busnum=1\\n\nA: devnum=5\\n\n"
    "A: bcdDevice=0435\\n\n"
    "\n"
    "P: /devices/pci0000:00/0000:00:14.0/usb1/1-3/1-3:1.0\n"
    "E: SUBSYSTEM=usb\nE: DEVTYPE=usb_interface\nE: INTERFACE=3/0/0\n"
    "A: bInterfaceNumber=00\\n\n"
    "\n"
    "P: /devices/pci0000:00/0000:00:14.0/usb1/1-3/1-3:1.0/0003:046D:C626.0007\n"
    "E: SUBSYSTEM=hid\nE: DRIVER=hid-generic\nE: HID_ID=0003:0000046D:0000C626\n"
    "E: HID_NAME=3Dconnexion SpaceNavigator\nE: HID_PHYS=usb-0000:00:14.0-3/input0\nE: HID_UNIQ=FAKE-SN-42\n"
    "H: report_descriptor=05010908A101C0\n"
    "\n"
    "P: /devices/pci0000:00/0000:00:14.0/usb1/1-3/1-3:1.0/0003:046D:C626.0007/hidraw/hidraw0\n"
    "N: hidraw0\n"
    "E: SUBSYSTEM=hidraw\nE: DEVNAME=/dev/hidraw0\nE: MAJOR=247\nE: MINOR=0\n"
    "L: device=../../../0003:046D:C626.0007\n";

/// The hidraw node's behaviour: report descriptor ioctls, queued input reports for (blocking)
/// reads, output reports recorded, unplugging. Handlers run on umockdev's thread.
class FakeHidraw {
 public:
  FakeHidraw() : handler_(umockdev_ioctl_base_new()) {
    g_signal_connect(handler_, "handle-ioctl", G_CALLBACK(&FakeHidraw::onIoctl), this);
    g_signal_connect(handler_, "handle-read", G_CALLBACK(&FakeHidraw::onRead), this);
    g_signal_connect(handler_, "handle-write", G_CALLBACK(&FakeHidraw::onWrite), this);
  }
  ~FakeHidraw() {
    unplug();
    g_object_unref(handler_);
  }
  UMockdevIoctlBase* handler() const { return handler_; }

  void push(std::vector<std::uint8_t> report) {
    std::lock_guard<std::mutex> l(m_);
    reports_.push_back(std::move(report));
    servePending();
  }
  /// Pending and later reads fail with ENODEV.
  void unplug() {
    std::lock_guard<std::mutex> l(m_);
    unplugged_ = true;
    servePending();
  }
  std::vector<std::vector<std::uint8_t>> written() {
    std::lock_guard<std::mutex> l(m_);
    return written_;
  }
  int descriptorRequests() {
    std::lock_guard<std::mutex> l(m_);
    return descriptor_requests_;
  }

 private:
  static gboolean onIoctl(UMockdevIoctlBase*, UMockdevIoctlClient* client, FakeHidraw* self) {
    const unsigned long request = umockdev_ioctl_client_get_request(client);
    UMockdevIoctlData* arg = umockdev_ioctl_client_get_arg(client);
    if (request == HIDIOCGRDESCSIZE) {
      UMockdevIoctlData* d = umockdev_ioctl_data_resolve(arg, 0, sizeof(int), nullptr);
      *reinterpret_cast<int*>(d->data) = sizeof kReportDescriptor;
      umockdev_ioctl_client_complete(client, 0, 0);
      g_object_unref(d);
      std::lock_guard<std::mutex> l(self->m_);
      ++self->descriptor_requests_;
      return TRUE;
    }
    if (request == HIDIOCGRDESC) {
      UMockdevIoctlData* d = umockdev_ioctl_data_resolve(arg, 0, sizeof(hidraw_report_descriptor), nullptr);
      auto* desc = reinterpret_cast<hidraw_report_descriptor*>(d->data);
      desc->size = sizeof kReportDescriptor;
      std::memcpy(desc->value, kReportDescriptor, sizeof kReportDescriptor);
      umockdev_ioctl_client_complete(client, 0, 0);
      g_object_unref(d);
      std::lock_guard<std::mutex> l(self->m_);
      ++self->descriptor_requests_;
      return TRUE;
    }
    return FALSE;
  }
  static gboolean onRead(UMockdevIoctlBase*, UMockdevIoctlClient* client, FakeHidraw* self) {
    std::lock_guard<std::mutex> l(self->m_);
    self->pending_.push_back(UMOCKDEV_IOCTL_CLIENT(g_object_ref(client)));
    self->servePending();  // at once when a report is queued; else when one is pushed
    return TRUE;
  }
  static gboolean onWrite(UMockdevIoctlBase*, UMockdevIoctlClient* client, FakeHidraw* self) {
    UMockdevIoctlData* arg = umockdev_ioctl_client_get_arg(client);
    std::lock_guard<std::mutex> l(self->m_);
    if (self->unplugged_) {
      umockdev_ioctl_client_complete(client, -1, ENODEV);
      return TRUE;
    }
    self->written_.emplace_back(arg->data, arg->data + arg->data_len);
    umockdev_ioctl_client_complete(client, arg->data_len, 0);
    return TRUE;
  }
  void servePending() {  // with m_ held
    while (!pending_.empty() && (unplugged_ || !reports_.empty())) {
      UMockdevIoctlClient* client = pending_.front();
      pending_.pop_front();
      if (unplugged_) {
        umockdev_ioctl_client_complete(client, -1, ENODEV);
      } else {
        UMockdevIoctlData* arg = umockdev_ioctl_client_get_arg(client);
        const std::vector<std::uint8_t> r = std::move(reports_.front());
        reports_.pop_front();
        const std::size_t n = std::min<std::size_t>(r.size(), static_cast<std::size_t>(arg->data_len));
        std::memcpy(arg->data, r.data(), n);
        umockdev_ioctl_client_complete(client, static_cast<glong>(n), 0);
      }
      g_object_unref(client);
    }
  }

  UMockdevIoctlBase* handler_;
  std::mutex m_;
  std::deque<std::vector<std::uint8_t>> reports_;
  std::deque<UMockdevIoctlClient*> pending_;
  std::vector<std::vector<std::uint8_t>> written_;
  int descriptor_requests_ = 0;
  bool unplugged_ = false;
};

TEST(UmockdevSpaceMouse, EnumeratedOpenedAndReadThroughHidapi) {
  VH_REQUIRE_UMOCKDEV();
  Testbed testbed;
  FakeHidraw hidraw;
  testbed.attach("/dev/hidraw0", hidraw.handler());
  testbed.add(kSpaceNavigatorSysfs);

  std::shared_ptr<HidBackend> hid = makeHidapiBackend();
  ASSERT_NE(hid, nullptr);
  const std::vector<HidDeviceInfo> all = hid->enumerate();
  ASSERT_EQ(all.size(), 1u);
  EXPECT_EQ(all[0].path, "/dev/hidraw0");
  EXPECT_EQ(all[0].vendor_id, 0x046D);
  EXPECT_EQ(all[0].product_id, 0xC626);
  EXPECT_EQ(all[0].manufacturer, "3Dconnexion");
  EXPECT_EQ(all[0].product, "SpaceNavigator");
  EXPECT_EQ(all[0].serial, "FAKE-SN-42");

  DeviceCatalog catalog(hid, nullptr);
  const std::vector<FoundDevice> found = catalog.enumerate();
  ASSERT_EQ(found.size(), 1u);
  EXPECT_EQ(found[0].label(), "SpaceNavigator (3Dconnexion, serial FAKE-SN-42, /dev/hidraw0)");

  // The transport: one report per blocking read, as sent.
  std::unique_ptr<HidTransport> transport = hid->open("/dev/hidraw0");
  EXPECT_GE(hidraw.descriptorRequests(), 1);  // hidapi checks the node answers HIDIOCGRDESCSIZE
  hidraw.push(test::axisReport(1, 120, -45, 300));
  hidraw.push(test::axisReport(2, -7, 0, 350));
  std::uint8_t buffer[64];
  spacemouse::State state;
  ASSERT_EQ(transport->read(buffer, sizeof buffer, -1), 7);
  EXPECT_EQ(spacemouse::decodeReport(buffer, 7, state), spacemouse::kChangedTranslation);
  ASSERT_EQ(transport->read(buffer, sizeof buffer, -1), 7);
  EXPECT_EQ(spacemouse::decodeReport(buffer, 7, state), spacemouse::kChangedRotation);
  EXPECT_EQ(state.raw, (std::array<std::int16_t, 6>{120, -45, 300, -7, 0, 350}));
  const auto led = spacemouse::ledReport(true);
  EXPECT_EQ(transport->write(led.data(), led.size()), 2);
  ASSERT_EQ(hidraw.written().size(), 1u);
  EXPECT_EQ(hidraw.written()[0], (std::vector<std::uint8_t>{4, 15}));
}

TEST(UmockdevSpaceMouse, TheDeviceMovesWithThePuckAndReportsUnplugging) {
  VH_REQUIRE_UMOCKDEV();
  Testbed testbed;
  FakeHidraw hidraw;
  testbed.attach("/dev/hidraw0", hidraw.handler());
  testbed.add(kSpaceNavigatorSysfs);
  auto catalog = std::make_shared<DeviceCatalog>(makeHidapiBackend(), nullptr);
  OpenOptions options;
  options.spacemouse.read_timeout_ms = -1;  // blocking reads: umockdev never signals poll
  options.spacemouse.rate.deadzone = 0.0;
  options.X_WT_initial.p_AB_m = {0.0, 0.0, 0.05};
  std::shared_ptr<runtime::MappedDevice> device = catalog->openFirst("spacemouse", "FAKE-SN-42", options);
  ASSERT_TRUE(waitFor([&] { return !hidraw.written().empty(); }));
  EXPECT_EQ(hidraw.written()[0], (std::vector<std::uint8_t>{4, 15}));  // LED on

  runtime::DeviceSample s;
  ASSERT_TRUE(device->read(s));
  EXPECT_TRUE(s.X_WD.p_AB_m.isApprox(Eigen::Vector3d(0.0, 0.0, 0.05)));
  hidraw.push(test::axisReport(1, 0, 0, -350));  // lift the cap: +z
  auto* raw = dynamic_cast<SpaceMouseDevice*>(device->raw().get());
  ASSERT_NE(raw, nullptr);
  ASSERT_TRUE(waitFor([&] { return raw->reportsReceived() >= 1; }));
  for (int i = 0; i < 50; ++i) {
    std::this_thread::sleep_for(1ms);
    ASSERT_TRUE(device->read(s));
  }
  EXPECT_GT(s.X_WD.p_AB_m.z(), 0.05);
  EXPECT_NEAR(s.v_WD_m_per_s.z(), options.spacemouse.rate.max_speed_m_per_s, 1e-12);

  // Unplugged: the blocked read fails, the device says so, read() has nothing.
  HotplugMonitor monitor(catalog);
  monitor.pollOnce();
  EXPECT_EQ(monitor.takeEvents().size(), 1u);
  hidraw.unplug();
  testbed.remove("/devices/pci0000:00/0000:00:14.0/usb1/1-3/1-3:1.0/0003:046D:C626.0007/hidraw/hidraw0");
  ASSERT_TRUE(waitFor([&] { return !device->connected(); }));
  EXPECT_FALSE(device->read(s));
  monitor.pollOnce();
  const auto events = monitor.takeEvents();
  ASSERT_EQ(events.size(), 1u);
  EXPECT_EQ(events[0].kind, HotplugEvent::Kind::kLeft);
  EXPECT_EQ(events[0].device.serial, "FAKE-SN-42");
}

// ---- A fake Novint Falcon on usbdevfs --------------------------------------------------------------

// Device descriptor: USB 1.1, class 0, max packet 8, 0403:cb48, bcdDevice 4.00, strings 1 2 3,
// one configuration; configuration with one vendor-specific interface, bulk IN 0x81 and OUT 0x02
// of 64 bytes.
const char* kFalconSysfs =
    "P: /devices/pci0000:00/0000:00:14.0/usb1/1-4\n"
    "N: bus/usb/001/006\n"
    "E: SUBSYSTEM=usb\nE: DRIVER=usb\nE: DEVTYPE=usb_device\nE: BUSNUM=001\nE: DEVNUM=006\n"
    "E: DEVNAME=/dev/bus/usb/001/006\n"
    "A: busnum=1\\n\nA: devnum=6\\n\nA: speed=12\\n\nA: bConfigurationValue=1\\n\n"
    "A: idVendor=0403\\n\nA: idProduct=cb48\\n\nA: manufacturer=FTDI\\n\nA: product=FALCON HAPTIC\\n\n"
    "H: descriptors=12011001000000080304" "48cb0004010203" "01"
    "090220000101008032"
    "0904000002ffffff02"
    "07058102400000"
    "07050202400000\n";

/// usbdevfs emulation: every URB goes to a FakeFalcon; URBs complete at once and are handed
/// back by REAPURB(NDELAY). Control transfers are recorded by the FakeFalcon.
class FakeUsbdevfs {
 public:
  explicit FakeUsbdevfs(std::shared_ptr<test::FakeFalcon> falcon)
      : falcon_(std::move(falcon)), handler_(umockdev_ioctl_base_new()) {
    g_signal_connect(handler_, "handle-ioctl", G_CALLBACK(&FakeUsbdevfs::onIoctl), this);
  }
  ~FakeUsbdevfs() {
    for (Done& d : done_) {
      g_object_unref(d.buffer);
      g_object_unref(d.urb);
    }
    g_object_unref(handler_);
  }
  UMockdevIoctlBase* handler() const { return handler_; }
  std::vector<std::string> unhandled() {
    std::lock_guard<std::mutex> l(m_);
    return unhandled_;
  }

 private:
  struct Done {
    UMockdevIoctlData* urb;     // resolved usbdevfs_urb
    UMockdevIoctlData* buffer;  // resolved data buffer
    int actual_length;
  };

  static gboolean onIoctl(UMockdevIoctlBase*, UMockdevIoctlClient* client, FakeUsbdevfs* self) {
    return self->handle(client) ? TRUE : FALSE;
  }

  bool handle(UMockdevIoctlClient* client) {
    const unsigned long request = umockdev_ioctl_client_get_request(client);
    UMockdevIoctlData* arg = umockdev_ioctl_client_get_arg(client);
    switch (request) {
      case USBDEVFS_GET_CAPABILITIES: {
        UMockdevIoctlData* d = umockdev_ioctl_data_resolve(arg, 0, sizeof(std::uint32_t), nullptr);
        *reinterpret_cast<std::uint32_t*>(d->data) =
            USBDEVFS_CAP_BULK_CONTINUATION | USBDEVFS_CAP_NO_PACKET_SIZE_LIM | USBDEVFS_CAP_REAP_AFTER_DISCONNECT;
        umockdev_ioctl_client_complete(client, 0, 0);
        g_object_unref(d);
        return true;
      }
      case USBDEVFS_CLAIMINTERFACE:
      case USBDEVFS_RELEASEINTERFACE:
      case USBDEVFS_SETINTERFACE:
      case USBDEVFS_CLEAR_HALT:
      case USBDEVFS_RESET:
      case USBDEVFS_RESETEP:
      case USBDEVFS_DISCONNECT_CLAIM:
        umockdev_ioctl_client_complete(client, 0, 0);
        return true;
      case USBDEVFS_GETDRIVER:
      case USBDEVFS_IOCTL:  // kernel driver queries / detach: none bound
        umockdev_ioctl_client_complete(client, -1, ENODATA);
        return true;
      case USBDEVFS_SUBMITURB:
        return submit(client, arg);
      case USBDEVFS_REAPURB:
      case USBDEVFS_REAPURBNDELAY:
        return reap(client, arg);
      case USBDEVFS_DISCARDURB:
        umockdev_ioctl_client_complete(client, -1, EINVAL);  // every URB completes at once
        return true;
      default: {
        std::lock_guard<std::mutex> l(m_);
        unhandled_.push_back(std::to_string(request));
        return false;
      }
    }
  }

  bool submit(UMockdevIoctlClient* client, UMockdevIoctlData* arg) {
    UMockdevIoctlData* u = umockdev_ioctl_data_resolve(arg, 0, sizeof(usbdevfs_urb), nullptr);
    auto* urb = reinterpret_cast<usbdevfs_urb*>(u->data);
    UMockdevIoctlData* b =
        umockdev_ioctl_data_resolve(u, G_STRUCT_OFFSET(usbdevfs_urb, buffer), static_cast<gsize>(urb->buffer_length), nullptr);
    int result = 0;
    if (urb->type == USBDEVFS_URB_TYPE_CONTROL && urb->buffer_length >= 8) {
      const std::uint8_t* setup = b->data;
      result = falcon_->control(setup[0], setup[1], static_cast<std::uint16_t>(setup[2] | (setup[3] << 8)),
                                static_cast<std::uint16_t>(setup[4] | (setup[5] << 8)));
      if (result > 0) result = 0;
    } else if (urb->type == USBDEVFS_URB_TYPE_BULK && (urb->endpoint & 0x80) != 0) {
      result = falcon_->bulkIn(b->data, urb->buffer_length);
    } else if (urb->type == USBDEVFS_URB_TYPE_BULK) {
      result = falcon_->bulkOut(b->data, urb->buffer_length);
    } else {
      result = UsbTransport::kErrorIo;
    }
    if (result == UsbTransport::kErrorNoDevice || result < 0) {
      umockdev_ioctl_client_complete(client, -1, result == UsbTransport::kErrorNoDevice ? ENODEV : EIO);
      g_object_unref(b);
      g_object_unref(u);
      return true;
    }
    {
      std::lock_guard<std::mutex> l(m_);
      done_.push_back({u, b, result});
    }
    umockdev_ioctl_client_complete(client, 0, 0);
    return true;
  }

  bool reap(UMockdevIoctlClient* client, UMockdevIoctlData* arg) {
    Done d{};
    {
      std::lock_guard<std::mutex> l(m_);
      if (done_.empty()) {
        umockdev_ioctl_client_complete(client, -1, EAGAIN);
        return true;
      }
      d = done_.front();
      done_.pop_front();
    }
    auto* urb = reinterpret_cast<usbdevfs_urb*>(d.urb->data);
    urb->status = 0;
    urb->actual_length = d.actual_length;
    UMockdevIoctlData* slot = umockdev_ioctl_data_resolve(arg, 0, sizeof(void*), nullptr);
    umockdev_ioctl_data_set_ptr(slot, 0, d.urb);
    umockdev_ioctl_client_complete(client, 0, 0);
    g_object_unref(slot);
    g_object_unref(d.buffer);
    g_object_unref(d.urb);
    return true;
  }

  std::shared_ptr<test::FakeFalcon> falcon_;
  UMockdevIoctlBase* handler_;
  std::mutex m_;
  std::deque<Done> done_;
  std::vector<std::string> unhandled_;
};

std::vector<std::uint8_t> fakeFirmware(std::size_t n) {
  std::vector<std::uint8_t> fw(n);
  for (std::size_t i = 0; i < n; ++i) fw[i] = static_cast<std::uint8_t>((i * 53 + 7) & 0xFF);
  return fw;
}

TEST(UmockdevFalcon, EnumeratedThroughLibusbAndItsSetUpControlTransfersChecked) {
  VH_REQUIRE_UMOCKDEV();
  Testbed testbed;
  auto falcon = std::make_shared<test::FakeFalcon>();
  FakeUsbdevfs usbfs(falcon);
  testbed.attach("/dev/bus/usb/001/006", usbfs.handler());
  testbed.add(kFalconSysfs);

  std::shared_ptr<UsbBackend> usb = makeLibusbBackend();
  ASSERT_NE(usb, nullptr);
  const std::vector<UsbDeviceInfo> found = usb->enumerate(falcon::kVendorId, falcon::kProductId);
  ASSERT_EQ(found.size(), 1u);
  EXPECT_EQ(found[0].path, "usb:1:6");
  EXPECT_EQ(found[0].bus, 1);
  EXPECT_EQ(found[0].address, 6);
  EXPECT_TRUE(usb->enumerate(0x046D, 0xC626).empty());

  std::unique_ptr<UsbTransport> transport = usb->open(found[0]);
  const std::vector<std::uint8_t> firmware = fakeFirmware(700);
  uploadFalconFirmware(*transport, firmware);
  EXPECT_EQ(falcon->uploaded(), firmware);  // every block went out and every echo came back

  // Every control transfer, as the device saw it: vendor request type 0x40, index 0, in the
  // document's order (one boot check attempt).
  std::vector<test::FakeFalcon::Control> expected;
  for (const auto& s : falcon::kBootloaderSetup) expected.push_back({0x40, s.request, s.value, 0});
  for (const auto& s : falcon::kLoaderSetup) expected.push_back({0x40, s.request, s.value, 0});
  for (const auto& s : falcon::kNormalModeSetup) expected.push_back({0x40, s.request, s.value, 0});
  EXPECT_EQ(falcon->controls(), expected);
  EXPECT_EQ(falcon->bootChecks(), 1);
  EXPECT_TRUE(falconFirmwareLoaded(*transport));
  EXPECT_TRUE(usbfs.unhandled().empty());
}

TEST(UmockdevFalcon, TheDeviceRunsItsIoLoopThroughLibusbAndReportsUnplugging) {
  VH_REQUIRE_UMOCKDEV();
  Testbed testbed;
  auto falcon = std::make_shared<test::FakeFalcon>();
  const Eigen::Vector3d p_K(0.005, 0.01, 0.115);
  falcon->setHandle(p_K);
  FakeUsbdevfs usbfs(falcon);
  testbed.attach("/dev/bus/usb/001/006", usbfs.handler());
  testbed.add(kFalconSysfs);

  const auto firmware_path =
      std::filesystem::temp_directory_path() / (std::to_string(::getpid()) + "-vh_umockdev_falcon_firmware.bin");
  {
    const auto fw = fakeFirmware(300);
    std::ofstream out(firmware_path, std::ios::binary);
    out.write(reinterpret_cast<const char*>(fw.data()), static_cast<std::streamsize>(fw.size()));
  }
  struct Remove {
    std::filesystem::path path;
    ~Remove() {
      std::error_code ec;
      std::filesystem::remove(path, ec);
    }
  } remove_firmware{firmware_path};
  auto catalog = std::make_shared<DeviceCatalog>(nullptr, makeLibusbBackend());
  const std::vector<FoundDevice> found = catalog->enumerate();
  ASSERT_EQ(found.size(), 1u);
  EXPECT_EQ(found[0].label(), "Novint Falcon (Novint, usb:1:6)");
  OpenOptions options;
  options.falcon_firmware = firmware_path;
  std::shared_ptr<runtime::MappedDevice> device = catalog->open(found[0], options);
  EXPECT_EQ(falcon->uploaded().size(), 300u);

  runtime::DeviceSample s;
  ASSERT_TRUE(waitFor([&] { return device->read(s) && s.valid; }));
  // Identity mapping of the offset (tool at the origin): X_WD = R_WB * (p_K - centre).
  const Eigen::Vector3d p_B = p_K - Eigen::Vector3d(0.0, 0.0, falcon::kWorkspaceCentreZ_m);
  EXPECT_LT((s.X_WD.p_AB_m - device->mapping().toWorld(haptics::Pose::FromTranslation(p_B)).p_AB_m).norm(), 2e-4);
  // A force up in W reaches the motors.
  device->command({0.0, 0.0, 3.0}, Eigen::Vector3d::Zero());
  ASSERT_TRUE(waitFor([&] { return falcon->lastCommand().motor != std::array<std::int16_t, 3>{0, 0, 0}; }));
  EXPECT_EQ(falcon->lastCommand().flags, falcon::kLedGreen);

  falcon->unplug();
  ASSERT_TRUE(waitFor([&] { return !device->connected(); }));
  EXPECT_FALSE(device->read(s));
  EXPECT_NE(device->problem().find("unplugged"), std::string::npos) << device->problem();
  EXPECT_TRUE(usbfs.unhandled().empty());
}

}  // namespace
}  // namespace vh::devices
