// The hidapi backend (hidapi-hidraw): built only when CMake found hidapi.
#include <hidapi.h>

#include <cwchar>
#include <mutex>
#include <stdexcept>

#include "vh/devices/transport.h"

namespace vh::devices {

namespace {

/// UTF-8 of a wide string from hidapi (null: empty).
std::string narrow(const wchar_t* w) {
  std::string out;
  if (w == nullptr) return out;
  for (; *w != L'\0'; ++w) {
    auto c = static_cast<std::uint32_t>(*w);
    if (c < 0x80) {
      out += static_cast<char>(c);
    } else if (c < 0x800) {
      out += static_cast<char>(0xC0 | (c >> 6));
      out += static_cast<char>(0x80 | (c & 0x3F));
    } else if (c < 0x10000) {
      out += static_cast<char>(0xE0 | (c >> 12));
      out += static_cast<char>(0x80 | ((c >> 6) & 0x3F));
      out += static_cast<char>(0x80 | (c & 0x3F));
    } else {
      out += static_cast<char>(0xF0 | (c >> 18));
      out += static_cast<char>(0x80 | ((c >> 12) & 0x3F));
      out += static_cast<char>(0x80 | ((c >> 6) & 0x3F));
      out += static_cast<char>(0x80 | (c & 0x3F));
    }
  }
  return out;
}

/// hidapi's enumerate / open / init are not thread-safe: one lock for them.
std::mutex& hidapiMutex() {
  static std::mutex mutex;
  return mutex;
}

void ensureInit() {
  static bool done = false;
  if (done) return;
  if (hid_init() != 0) throw std::runtime_error("hidapi: hid_init failed: " + narrow(hid_error(nullptr)));
  done = true;
}

class HidapiTransport final : public HidTransport {
 public:
  HidapiTransport(hid_device* device, std::string path) : device_(device), path_(std::move(path)) {}
  ~HidapiTransport() override {
    const std::lock_guard<std::mutex> lock(hidapiMutex());
    hid_close(device_);
  }
  int read(std::uint8_t* data, std::size_t size, int timeout_ms) noexcept override {
    // timeout < 0: a plain blocking read (no poll(); umockdev's emulated hidraw never signals
    // poll, see ../shared/docs/devices.md).
    const int n = timeout_ms < 0 ? hid_read(device_, data, size) : hid_read_timeout(device_, data, size, timeout_ms);
    return n < 0 ? -1 : n;
  }
  int write(const std::uint8_t* data, std::size_t size) noexcept override {
    const int n = hid_write(device_, data, size);
    return n < 0 ? -1 : n;
  }
  std::string lastError() const override {
    const std::string e = narrow(hid_error(device_));
    return path_ + ": " + (e.empty() ? std::string("unknown hidapi error") : e);
  }

 private:
  hid_device* device_;
  std::string path_;
};

class HidapiBackend final : public HidBackend {
 public:
  std::string name() const override { return "hidapi"; }
  std::vector<HidDeviceInfo> enumerate() override {
    const std::lock_guard<std::mutex> lock(hidapiMutex());
    ensureInit();
    std::vector<HidDeviceInfo> out;
    hid_device_info* list = hid_enumerate(0, 0);
    for (const hid_device_info* d = list; d != nullptr; d = d->next) {
      HidDeviceInfo info;
      info.path = d->path != nullptr ? d->path : "";
      info.vendor_id = d->vendor_id;
      info.product_id = d->product_id;
      info.manufacturer = narrow(d->manufacturer_string);
      info.product = narrow(d->product_string);
      info.serial = narrow(d->serial_number);
      info.interface_number = d->interface_number;
      out.push_back(std::move(info));
    }
    hid_free_enumeration(list);
    return out;
  }
  std::unique_ptr<HidTransport> open(const std::string& path) override {
    const std::lock_guard<std::mutex> lock(hidapiMutex());
    ensureInit();
    hid_device* device = hid_open_path(path.c_str());
    if (device == nullptr) {
      const std::string e = narrow(hid_error(nullptr));
      throw std::runtime_error(path + ": cannot open the HID device" + (e.empty() ? std::string() : ": " + e) +
                               " (on Linux the user needs read/write access to the hidraw node: a udev rule)");
    }
    return std::make_unique<HidapiTransport>(device, path);
  }
};

}  // namespace

std::shared_ptr<HidBackend> makeHidapiBackend() { return std::make_shared<HidapiBackend>(); }

}  // namespace vh::devices
