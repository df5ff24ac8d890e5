#pragma once
/// @file
/// Finding, opening and watching hardware devices: what a GUI device picker and the scene
/// factory use.
///
///   DeviceCatalog catalog;                          // the backends this build has
///   for (const FoundDevice& d : catalog.enumerate()) list.add(d.label());
///   std::shared_ptr<runtime::MappedDevice> device = catalog.open(found[i], options);
///   HotplugMonitor monitor(catalogPtr); monitor.start();   // then takeEvents() from a GUI timer
///
/// Devices come out mapped into the scene (runtime::MappedDevice over the driver, the workspace
/// centred on the tool's initial pose); the GUI adjusts the mapping with setMapping().

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "vh/devices/dhd_device.h"
#include "vh/devices/falcon_device.h"
#include "vh/devices/openhaptics_device.h"
#include "vh/devices/spacemouse_device.h"
#include "vh/devices/transport.h"
#include "vh/haptics/pose.h"
#include "vh/runtime/device.h"
#include "vh/runtime/scene.h"

namespace vh::devices {

/// A supported device present now.
struct FoundDevice {
  std::string kind;          ///< "spacemouse" | "falcon" | "forcedimension" | "openhaptics" (scene kinds).
  std::string model;         ///< e.g. "SpaceNavigator", "Novint Falcon".
  std::string manufacturer;  ///< Empty when unknown.
  std::string serial;        ///< Empty when unknown.
  std::string path;          ///< Backend address: "/dev/hidraw3", "usb:1:7", "dhd:0", "hd:default".
  std::uint16_t vendor_id = 0;
  std::uint16_t product_id = 0;
  std::string backend;       ///< "hidapi" | "libusb" | "dhd" | "openhaptics".

  /// One line for a list, e.g. "SpaceNavigator (3Dconnexion, /dev/hidraw3)".
  std::string label() const;
  /// The same physical device: same kind and ids, and the same serial (the same path when
  /// either has no serial).
  bool sameDeviceAs(const FoundDevice& other) const noexcept;
  bool operator==(const FoundDevice& other) const = default;
};

/// How DeviceCatalog::open() makes a device.
struct OpenOptions {
  /// The tool's initial pose in W [m]: the default mapping puts the workspace centre at its
  /// position and keeps its orientation when the handle is at rest.
  haptics::Pose X_WT_initial;
  runtime::WorkspaceSpec workspace;       ///< Scale, offset, rotation; unset fields: the defaults.
  std::filesystem::path falcon_firmware;  ///< A Falcon's firmware file (overrides falcon.firmware).
  SpaceMouseOptions spacemouse;
  FalconOptions falcon;
  DhdOptions dhd;                  ///< Force Dimension (the index comes from FoundDevice::path).
  OpenHapticsOptions openhaptics;
};

/// Where the catalog looks for the vendor SDK libraries (dlopen candidates, vendor_library.h).
/// An empty list: that back-end is not tried (listed as not installed).
struct VendorLibraries {
  std::vector<std::string> dhd;          ///< Force Dimension DHD / DRD.
  std::vector<std::string> openhaptics;  ///< OpenHaptics libHD.
  /// VH_DHD_LIBRARY / VH_OPENHAPTICS_LIBRARY when set, else the default library names.
  static VendorLibraries fromEnvironment();
};

/// The workspace mapping of a device kind: scale `spec.scale`; offset `spec.offset_W_m`, else
/// the tool's initial position; rotation `spec.R_WB`, else the kind's axes into W (z up):
/// "falcon" B y up -> W +z, B z towards the user -> W -y (a +90 degree turn about x);
/// "spacemouse" B = W axes; "openhaptics" as "falcon" (B y up, z towards the user);
/// "forcedimension" B x towards the user, y right, z up -> a -90 degree turn about z (B y -> W +x,
/// B x -> W -y). R_HD keeps the tool's initial orientation at rest.
/// @throws std::invalid_argument for an unknown kind or an invalid mapping.
runtime::WorkspaceMapping defaultWorkspaceMapping(const std::string& kind, const haptics::Pose& X_WT_initial,
                                                  const runtime::WorkspaceSpec& spec = {});

/// Finds and opens the supported devices through HID and USB backends.
class DeviceCatalog {
 public:
  /// The backends this build has (hidapi, libusb; either may be missing) and the vendor SDKs
  /// installed on this machine (VendorLibraries::fromEnvironment(); loaded with dlopen).
  DeviceCatalog();
  /// Given backends (e.g. fakes in tests); either may be null. Vendor SDKs from `vendors`
  /// (none by default).
  DeviceCatalog(std::shared_ptr<HidBackend> hid, std::shared_ptr<UsbBackend> usb, const VendorLibraries& vendors = {});

  /// The vendor back-ends ("forcedimension", "openhaptics"), installed or not, for the picker.
  std::vector<VendorStatus> vendorStatus() const { return vendor_status_; }

  /// Names of the backends in use, e.g. {"hidapi", "libusb"}.
  std::vector<std::string> backends() const;
  /// Device kinds this catalog can find: "spacemouse" with a HID backend, "falcon" with USB,
  /// "forcedimension" / "openhaptics" with their SDK installed.
  std::vector<std::string> kinds() const;
  /// Every supported device present now (any thread; may take some milliseconds). Never
  /// throws: a failing backend is skipped and its error kept in problems().
  std::vector<FoundDevice> enumerate();
  /// Errors of the last enumerate() (empty when every backend answered).
  std::vector<std::string> problems() const;
  /// Opens a device found by enumerate(), mapped into W.
  /// @throws std::runtime_error naming the device and the problem (permissions, firmware...).
  std::shared_ptr<runtime::MappedDevice> open(const FoundDevice& device, const OpenOptions& options = {});
  /// Opens the first device of `kind` whose serial or path equals `select` (empty: any).
  /// @throws std::runtime_error when none is found (listing what was found) or as open().
  std::shared_ptr<runtime::MappedDevice> openFirst(const std::string& kind, const std::string& select,
                                                   const OpenOptions& options = {});

 private:
  std::shared_ptr<HidBackend> hid_;
  std::shared_ptr<UsbBackend> usb_;
  std::shared_ptr<const DhdApi> dhd_;
  std::shared_ptr<const HdApi> hd_;
  std::vector<VendorStatus> vendor_status_;
  mutable std::mutex mutex_;
  std::vector<std::string> problems_;
  // The DHD device this catalog opened: while it lives, enumerate() does not call the SDK from
  // the monitor's thread and lists the devices found before (dhd_found_).
  std::weak_ptr<DhdDevice> dhd_open_;
  std::vector<FoundDevice> dhd_found_;
};

/// A device arriving or leaving.
struct HotplugEvent {
  enum class Kind { kArrived, kLeft };
  Kind kind = Kind::kArrived;
  FoundDevice device;
};

/// Watches a catalog for devices arriving and leaving by polling enumerate() on its own thread.
/// A device in use that disappears also reports itself (Device::connected() false, problem()
/// says why; the haptic thread then gets no samples and commands zero force, or a FallbackDevice
/// hands over to its simulated stand-in); when it arrives again (a kArrived event with
/// FoundDevice::sameDeviceAs()), the GUI offers to reconnect (Device::reconnect()).
class HotplugMonitor {
 public:
  /// @throws std::invalid_argument for a null catalog.
  explicit HotplugMonitor(std::shared_ptr<DeviceCatalog> catalog,
                          std::chrono::milliseconds period = std::chrono::milliseconds(500));
  ~HotplugMonitor();  ///< Stops the thread.
  HotplugMonitor(const HotplugMonitor&) = delete;
  HotplugMonitor& operator=(const HotplugMonitor&) = delete;

  /// Starts polling (the first poll runs at once). Idempotent.
  void start();
  /// Stops polling and joins the thread. Idempotent.
  void stop();
  /// Enumerates now on the caller's thread and queues the differences to the previous poll
  /// (the first poll reports every device present as arrived).
  void pollOnce();
  /// Any thread: the events since the last call, oldest first.
  std::vector<HotplugEvent> takeEvents();
  /// Any thread: the devices present at the last poll.
  std::vector<FoundDevice> devices() const;

 private:
  std::shared_ptr<DeviceCatalog> catalog_;
  std::chrono::milliseconds period_;
  mutable std::mutex mutex_;
  std::condition_variable wake_;
  std::vector<FoundDevice> present_;
  std::vector<HotplugEvent> events_;
  bool stop_ = false;
  std::thread thread_;
};

/// Registers the hardware kinds of this build with vh::runtime::registerDeviceKind() ("spacemouse"
/// when hidapi was built, "falcon" when libusb was; "forcedimension" and "openhaptics" always:
/// without their SDK opening one fails with a "not installed" message), so that scene files can
/// name them; their
/// devices come from one process-wide DeviceCatalog. Idempotent and thread-safe; call once at
/// start-up (before parsing scene files).
void registerDeviceKinds();

}  // namespace vh::devices
