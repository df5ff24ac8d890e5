#include "vh/devices/device_catalog.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <stdexcept>

#include "vh/devices/falcon_protocol.h"
#include "vh/devices/spacemouse_protocol.h"

namespace vh::devices {

#if !VH_DEVICES_HAVE_HIDAPI
std::shared_ptr<HidBackend> makeHidapiBackend() { return nullptr; }
#endif
#if !VH_DEVICES_HAVE_LIBUSB
std::shared_ptr<UsbBackend> makeLibusbBackend() { return nullptr; }
#endif

namespace {

std::string idText(std::uint16_t vendor_id, std::uint16_t product_id) {
  char text[16];
  std::snprintf(text, sizeof text, "%04x:%04x", vendor_id, product_id);
  return text;
}

/// The libusb backend, or null when it fails to initialise (reported by the catalog).
std::shared_ptr<UsbBackend> tryLibusb(std::string& problem) {
  try {
    return makeLibusbBackend();
  } catch (const std::exception& e) {
    problem = e.what();
    return nullptr;
  }
}

void loadVendors(const VendorLibraries& vendors, std::shared_ptr<const DhdApi>& dhd, std::shared_ptr<const HdApi>& hd,
                 std::vector<VendorStatus>& status) {
  status.push_back(probeDhd(vendors.dhd, dhd));
  status.push_back(probeHd(vendors.openhaptics, hd));
}

const VendorStatus* findStatus(const std::vector<VendorStatus>& status, const std::string& kind) {
  for (const VendorStatus& s : status)
    if (s.kind == kind) return &s;
  return nullptr;
}

}  // namespace

VendorLibraries VendorLibraries::fromEnvironment() {
  VendorLibraries v;
  v.dhd = vendorLibraryCandidates(kDhdLibraryEnv, defaultDhdLibraries());
  v.openhaptics = vendorLibraryCandidates(kHdLibraryEnv, defaultHdLibraries());
  return v;
}

// ---- FoundDevice ---------------------------------------------------------------------------------

std::string FoundDevice::label() const {
  std::string text = model.empty() ? kind : model;
  text += " (";
  if (!manufacturer.empty()) text += manufacturer + ", ";
  if (!serial.empty()) text += "serial " + serial + ", ";
  text += path.empty() ? idText(vendor_id, product_id) : path;
  text += ")";
  return text;
}

bool FoundDevice::sameDeviceAs(const FoundDevice& other) const noexcept {
  if (kind != other.kind || vendor_id != other.vendor_id || product_id != other.product_id) return false;
  if (!serial.empty() && !other.serial.empty()) return serial == other.serial;
  return path == other.path;
}

// ---- Mapping -------------------------------------------------------------------------------------

runtime::WorkspaceMapping defaultWorkspaceMapping(const std::string& kind, const haptics::Pose& X_WT_initial,
                                                  const runtime::WorkspaceSpec& spec) {
  Eigen::Quaterniond R_WB_default;
  if (kind == "falcon" || kind == "openhaptics") {
    R_WB_default = Eigen::Quaterniond(Eigen::AngleAxisd(0.5 * std::numbers::pi, Eigen::Vector3d::UnitX()));
  } else if (kind == "spacemouse") {
    R_WB_default = Eigen::Quaterniond::Identity();
  } else if (kind == "forcedimension") {
    R_WB_default = Eigen::Quaterniond(Eigen::AngleAxisd(-0.5 * std::numbers::pi, Eigen::Vector3d::UnitZ()));
  } else {
    throw std::invalid_argument("no workspace mapping for device kind '" + kind + "'");
  }
  runtime::WorkspaceMapping m;
  m.scale = spec.scale;
  m.X_WB.R_AB = spec.R_WB.value_or(R_WB_default).normalized();
  m.X_WB.p_AB_m = spec.offset_W_m.value_or(X_WT_initial.p_AB_m);
  m.R_HD = (m.X_WB.R_AB.conjugate() * X_WT_initial.R_AB).normalized();
  m.validate();
  return m;
}

// ---- DeviceCatalog -------------------------------------------------------------------------------

DeviceCatalog::DeviceCatalog() : hid_(makeHidapiBackend()) {
  std::string problem;
  usb_ = tryLibusb(problem);
  if (!problem.empty()) problems_.push_back(problem);
  loadVendors(VendorLibraries::fromEnvironment(), dhd_, hd_, vendor_status_);
}

DeviceCatalog::DeviceCatalog(std::shared_ptr<HidBackend> hid, std::shared_ptr<UsbBackend> usb,
                             const VendorLibraries& vendors)
    : hid_(std::move(hid)), usb_(std::move(usb)) {
  loadVendors(vendors, dhd_, hd_, vendor_status_);
}

std::vector<std::string> DeviceCatalog::backends() const {
  std::vector<std::string> out;
  if (hid_) out.push_back(hid_->name());
  if (usb_) out.push_back(usb_->name());
  return out;
}

std::vector<std::string> DeviceCatalog::kinds() const {
  std::vector<std::string> out;
  if (hid_) out.emplace_back("spacemouse");
  if (usb_) out.emplace_back("falcon");
  if (dhd_) out.emplace_back("forcedimension");
  if (hd_) out.emplace_back("openhaptics");
  return out;
}

std::vector<FoundDevice> DeviceCatalog::enumerate() {
  std::vector<FoundDevice> out;
  std::vector<std::string> problems;
  if (hid_) {
    try {
      for (const HidDeviceInfo& d : hid_->enumerate()) {
        const spacemouse::Model* model = spacemouse::findModel(d.vendor_id, d.product_id);
        if (model == nullptr) continue;
        // A receiver or a multi-interface model may list several hidraw nodes: keep the first
        // interface (the one with the axes), or the only one.
        if (d.interface_number > 0) continue;
        FoundDevice f;
        f.kind = "spacemouse";
        f.model = model->name;
        f.manufacturer = d.manufacturer.empty() ? std::string("3Dconnexion") : d.manufacturer;
        f.serial = d.serial;
        f.path = d.path;
        f.vendor_id = d.vendor_id;
        f.product_id = d.product_id;
        f.backend = hid_->name();
        out.push_back(std::move(f));
      }
    } catch (const std::exception& e) {
      problems.push_back(hid_->name() + ": " + e.what());
    }
  }
  if (usb_) {
    try {
      for (const UsbDeviceInfo& d : usb_->enumerate(falcon::kVendorId, falcon::kProductId)) {
        FoundDevice f;
        f.kind = "falcon";
        f.model = "Novint Falcon";
        f.manufacturer = "Novint";
        f.serial = d.serial;
        f.path = d.path;
        f.vendor_id = d.vendor_id;
        f.product_id = d.product_id;
        f.backend = usb_->name();
        out.push_back(std::move(f));
      }
    } catch (const std::exception& e) {
      problems.push_back(usb_->name() + ": " + e.what());
    }
  }
  if (dhd_) {
    const std::lock_guard<std::mutex> lock(mutex_);
    if (dhd_open_.expired()) {  // never call the SDK while a device of it runs its I/O thread
      dhd_found_.clear();
      const int count = dhd_->getDeviceCount();
      if (count < 0) problems.push_back("dhd: " + dhd_->lastError("dhdGetDeviceCount"));
      for (int i = 0; i < count; ++i) {
        FoundDevice f;
        f.kind = "forcedimension";
        f.model = "Force Dimension device";
        f.manufacturer = "Force Dimension";
        f.path = "dhd:" + std::to_string(i);
        f.backend = "dhd";
        dhd_found_.push_back(std::move(f));
      }
    }
    out.insert(out.end(), dhd_found_.begin(), dhd_found_.end());
  }
  if (hd_) {
    // OpenHaptics has no enumeration without opening: its configured default device.
    FoundDevice f;
    f.kind = "openhaptics";
    f.model = "OpenHaptics device";
    f.manufacturer = "3D Systems";
    f.path = "hd:default";
    f.backend = "openhaptics";
    out.push_back(std::move(f));
  }
  const std::lock_guard<std::mutex> lock(mutex_);
  problems_ = std::move(problems);
  return out;
}

std::vector<std::string> DeviceCatalog::problems() const {
  const std::lock_guard<std::mutex> lock(mutex_);
  return problems_;
}

std::shared_ptr<runtime::MappedDevice> DeviceCatalog::open(const FoundDevice& device, const OpenOptions& options) {
  const runtime::WorkspaceMapping mapping = defaultWorkspaceMapping(device.kind, options.X_WT_initial, options.workspace);
  std::shared_ptr<runtime::Device> raw;
  if (device.kind == "spacemouse") {
    if (!hid_) throw std::runtime_error(device.label() + ": this program has no HID backend (hidapi)");
    HidDeviceInfo info;
    info.path = device.path;
    info.vendor_id = device.vendor_id;
    info.product_id = device.product_id;
    info.manufacturer = device.manufacturer;
    info.serial = device.serial;
    raw = std::make_shared<SpaceMouseDevice>(hid_, info, options.spacemouse);
  } else if (device.kind == "falcon") {
    if (!usb_) throw std::runtime_error(device.label() + ": this program has no USB backend (libusb)");
    UsbDeviceInfo info;
    info.path = device.path;
    info.vendor_id = device.vendor_id;
    info.product_id = device.product_id;
    info.serial = device.serial;
    // "usb:BUS:ADDRESS"
    unsigned bus = 0, address = 0;
    if (std::sscanf(device.path.c_str(), "usb:%u:%u", &bus, &address) != 2) {
      throw std::runtime_error(device.label() + ": not a USB path (expected usb:BUS:ADDRESS)");
    }
    info.bus = static_cast<std::uint8_t>(bus);
    info.address = static_cast<std::uint8_t>(address);
    FalconOptions falcon_options = options.falcon;
    if (!options.falcon_firmware.empty()) falcon_options.firmware = options.falcon_firmware;
    raw = std::make_shared<FalconDevice>(usb_, info, falcon_options);
  } else if (device.kind == "forcedimension") {
    if (!dhd_) throw std::runtime_error(findStatus(vendor_status_, "forcedimension")->label() + "; set " + kDhdLibraryEnv + " to the SDK's libdhd.so or libdrd.so");
    DhdOptions dhd_options = options.dhd;
    int index = 0;
    if (std::sscanf(device.path.c_str(), "dhd:%d", &index) == 1) dhd_options.index = index;
    auto dhd = std::make_shared<DhdDevice>(dhd_, dhd_options);
    {
      const std::lock_guard<std::mutex> lock(mutex_);
      dhd_open_ = dhd;
    }
    raw = std::move(dhd);
  } else if (device.kind == "openhaptics") {
    if (!hd_) throw std::runtime_error(findStatus(vendor_status_, "openhaptics")->label() + "; set " + kHdLibraryEnv + " to OpenHaptics' libHD.so");
    raw = std::make_shared<OpenHapticsDevice>(hd_, options.openhaptics);
  } else {
    throw std::runtime_error("unknown device kind '" + device.kind + "'");
  }
  return std::make_shared<runtime::MappedDevice>(std::move(raw), mapping);
}

std::shared_ptr<runtime::MappedDevice> DeviceCatalog::openFirst(const std::string& kind, const std::string& select,
                                                                const OpenOptions& options) {
  const std::vector<FoundDevice> found = enumerate();
  std::string seen;
  for (const FoundDevice& d : found) {
    seen += (seen.empty() ? "" : "; ") + d.label();
    if (d.kind != kind) continue;
    if (!select.empty() && d.serial != select && d.path != select) continue;
    return open(d, options);
  }
  if (const VendorStatus* vendor = findStatus(vendor_status_, kind); vendor != nullptr && !vendor->installed) {
    throw std::runtime_error(vendor->label() + "; set " +
                             (kind == "forcedimension" ? std::string(kDhdLibraryEnv) : std::string(kHdLibraryEnv)) +
                             " to the SDK's library");
  }
  std::string problems;
  for (const std::string& p : this->problems()) problems += "; " + p;
  const std::string what = kind == "falcon" ? "Novint Falcon" : kind == "spacemouse" ? "SpaceMouse" : kind;
  throw std::runtime_error("no " + what + (select.empty() ? std::string() : " matching '" + select + "'") +
                           " found (found: " + (seen.empty() ? std::string("nothing") : seen) + ")" + problems);
}

// ---- HotplugMonitor ------------------------------------------------------------------------------

HotplugMonitor::HotplugMonitor(std::shared_ptr<DeviceCatalog> catalog, std::chrono::milliseconds period)
    : catalog_(std::move(catalog)), period_(period) {
  if (!catalog_) throw std::invalid_argument("HotplugMonitor: no catalog");
}

HotplugMonitor::~HotplugMonitor() { stop(); }

void HotplugMonitor::start() {
  const std::lock_guard<std::mutex> lock(mutex_);
  if (thread_.joinable()) return;
  stop_ = false;
  thread_ = std::thread([this] {
    std::unique_lock<std::mutex> guard(mutex_);
    while (!stop_) {
      guard.unlock();
      pollOnce();
      guard.lock();
      wake_.wait_for(guard, period_, [this] { return stop_; });
    }
  });
}

void HotplugMonitor::stop() {
  {
    const std::lock_guard<std::mutex> lock(mutex_);
    stop_ = true;
  }
  wake_.notify_all();
  if (thread_.joinable()) thread_.join();
}

void HotplugMonitor::pollOnce() {
  std::vector<FoundDevice> now = catalog_->enumerate();
  const std::lock_guard<std::mutex> lock(mutex_);
  for (const FoundDevice& before : present_) {
    const bool still = std::any_of(now.begin(), now.end(), [&](const FoundDevice& d) { return d.sameDeviceAs(before); });
    if (!still) events_.push_back({HotplugEvent::Kind::kLeft, before});
  }
  for (const FoundDevice& d : now) {
    const bool known = std::any_of(present_.begin(), present_.end(), [&](const FoundDevice& b) { return b.sameDeviceAs(d); });
    if (!known) events_.push_back({HotplugEvent::Kind::kArrived, d});
  }
  present_ = std::move(now);
}

std::vector<HotplugEvent> HotplugMonitor::takeEvents() {
  const std::lock_guard<std::mutex> lock(mutex_);
  std::vector<HotplugEvent> out;
  out.swap(events_);
  return out;
}

std::vector<FoundDevice> HotplugMonitor::devices() const {
  const std::lock_guard<std::mutex> lock(mutex_);
  return present_;
}

// ---- Registration --------------------------------------------------------------------------------

void registerDeviceKinds() {
  static std::once_flag once;
  std::call_once(once, [] {
    auto catalog = std::make_shared<DeviceCatalog>();
    const auto factory = [catalog](const runtime::DeviceSpec& spec,
                                   const haptics::Pose& X_WT_initial) -> std::shared_ptr<runtime::Device> {
      OpenOptions options;
      options.X_WT_initial = X_WT_initial;
      options.workspace = spec.workspace;
      options.falcon_firmware = spec.firmware;
      return catalog->openFirst(spec.kind, spec.select, options);
    };
    for (const std::string& kind : catalog->kinds()) runtime::registerDeviceKind(kind, factory);
    // Vendor SDKs: always (a scene naming one opens it, or fails saying it is not installed).
    for (const VendorStatus& vendor : catalog->vendorStatus()) runtime::registerDeviceKind(vendor.kind, factory);
  });
}

}  // namespace vh::devices
