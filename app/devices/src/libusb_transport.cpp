// The libusb backend (libusb-1.0): built only when CMake found libusb.
#include <libusb.h>

#include <cstdio>
#include <stdexcept>

#include "vh/devices/transport.h"

namespace vh::devices {

namespace {

/// One libusb context shared by the backend and every transport it opened (kept alive by them).
class Context {
 public:
  Context() {
    const int r = libusb_init(&context_);
    if (r != 0) throw std::runtime_error(std::string("libusb: libusb_init failed: ") + libusb_error_name(r));
  }
  ~Context() { libusb_exit(context_); }
  Context(const Context&) = delete;
  Context& operator=(const Context&) = delete;
  libusb_context* get() const noexcept { return context_; }

 private:
  libusb_context* context_ = nullptr;
};

std::string describe(const UsbDeviceInfo& d) {
  char id[16];
  std::snprintf(id, sizeof id, "%04x:%04x", d.vendor_id, d.product_id);
  return std::string("USB device ") + id + " at " + d.path;
}

class LibusbTransport final : public UsbTransport {
 public:
  LibusbTransport(std::shared_ptr<Context> context, libusb_device_handle* handle)
      : context_(std::move(context)), handle_(handle) {}
  ~LibusbTransport() override {
    libusb_release_interface(handle_, 0);
    libusb_close(handle_);
  }
  int control(std::uint8_t request_type, std::uint8_t request, std::uint16_t value, std::uint16_t index,
              std::uint8_t* data, std::uint16_t length, unsigned timeout_ms) noexcept override {
    return libusb_control_transfer(handle_, request_type, request, value, index, data, length, timeout_ms);
  }
  int bulkWrite(std::uint8_t endpoint, const std::uint8_t* data, int length, unsigned timeout_ms) noexcept override {
    int transferred = 0;
    const int r = libusb_bulk_transfer(handle_, endpoint, const_cast<std::uint8_t*>(data), length, &transferred,
                                       timeout_ms);
    if (r == 0 || (r == LIBUSB_ERROR_TIMEOUT && transferred > 0)) return transferred;
    return r;
  }
  int bulkRead(std::uint8_t endpoint, std::uint8_t* data, int length, unsigned timeout_ms) noexcept override {
    int transferred = 0;
    const int r = libusb_bulk_transfer(handle_, endpoint, data, length, &transferred, timeout_ms);
    if (r == 0 || (r == LIBUSB_ERROR_TIMEOUT && transferred > 0)) return transferred;
    return r;
  }
  std::string errorName(int code) const override { return libusb_error_name(code); }

 private:
  std::shared_ptr<Context> context_;
  libusb_device_handle* handle_;
};

class LibusbBackend final : public UsbBackend {
 public:
  LibusbBackend() : context_(std::make_shared<Context>()) {}
  std::string name() const override { return "libusb"; }

  std::vector<UsbDeviceInfo> enumerate(std::uint16_t vendor_id, std::uint16_t product_id) override {
    libusb_device** list = nullptr;
    const ssize_t n = libusb_get_device_list(context_->get(), &list);
    if (n < 0) {
      throw std::runtime_error(std::string("libusb: cannot list USB devices: ") +
                               libusb_error_name(static_cast<int>(n)));
    }
    std::vector<UsbDeviceInfo> out;
    for (ssize_t i = 0; i < n; ++i) {
      libusb_device_descriptor desc{};
      if (libusb_get_device_descriptor(list[i], &desc) != 0) continue;
      if (desc.idVendor != vendor_id || desc.idProduct != product_id) continue;
      UsbDeviceInfo info;
      info.bus = libusb_get_bus_number(list[i]);
      info.address = libusb_get_device_address(list[i]);
      info.vendor_id = desc.idVendor;
      info.product_id = desc.idProduct;
      info.path = "usb:" + std::to_string(info.bus) + ":" + std::to_string(info.address);
      out.push_back(std::move(info));
    }
    libusb_free_device_list(list, 1);
    return out;
  }

  std::unique_ptr<UsbTransport> open(const UsbDeviceInfo& device) override {
    libusb_device** list = nullptr;
    const ssize_t n = libusb_get_device_list(context_->get(), &list);
    if (n < 0) {
      throw std::runtime_error(describe(device) + ": cannot list USB devices: " + libusb_error_name(static_cast<int>(n)));
    }
    libusb_device_handle* handle = nullptr;
    int r = LIBUSB_ERROR_NO_DEVICE;
    for (ssize_t i = 0; i < n; ++i) {
      if (libusb_get_bus_number(list[i]) == device.bus && libusb_get_device_address(list[i]) == device.address) {
        r = libusb_open(list[i], &handle);
        break;
      }
    }
    libusb_free_device_list(list, 1);
    if (r != 0 || handle == nullptr) {
      throw std::runtime_error(describe(device) + ": cannot open: " + libusb_error_name(r) +
                               (r == LIBUSB_ERROR_ACCESS ? " (the user needs access to the USB device node: a udev rule)"
                                                          : ""));
    }
    // The kernel's ftdi_sio driver binds the Falcon's FTDI chip: detach it while we hold it.
    libusb_set_auto_detach_kernel_driver(handle, 1);
    r = libusb_claim_interface(handle, 0);
    if (r != 0) {
      libusb_close(handle);
      throw std::runtime_error(describe(device) + ": cannot claim interface 0: " + libusb_error_name(r) +
                               (r == LIBUSB_ERROR_BUSY ? " (another program uses it)" : ""));
    }
    return std::make_unique<LibusbTransport>(context_, handle);
  }

 private:
  std::shared_ptr<Context> context_;
};

}  // namespace

std::shared_ptr<UsbBackend> makeLibusbBackend() { return std::make_shared<LibusbBackend>(); }

}  // namespace vh::devices
