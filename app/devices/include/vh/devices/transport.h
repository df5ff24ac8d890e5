#pragma once
/// @file
/// Small transport interfaces between the device drivers and the USB libraries: HID reports
/// (hidapi, hidapi_transport.h) and USB control / bulk transfers (libusb, libusb_transport.h).
/// The drivers (SpaceMouseDevice, FalconDevice) only see these, so they are tested with
/// in-memory fakes; the library backends are tested under umockdev.

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace vh::devices {

// ---- HID ---------------------------------------------------------------------------------------

/// A HID device found by enumeration.
struct HidDeviceInfo {
  std::string path;           ///< Opaque to callers (hidapi: "/dev/hidrawN").
  std::uint16_t vendor_id = 0;
  std::uint16_t product_id = 0;
  std::string manufacturer;   ///< Empty when unknown.
  std::string product;        ///< Empty when unknown.
  std::string serial;         ///< Empty when unknown.
  int interface_number = -1;  ///< USB interface, -1 when unknown.
};

/// An open HID device, used by one thread at a time (the driver's I/O thread).
class HidTransport {
 public:
  virtual ~HidTransport() = default;
  /// Reads one input report (report id first) into `data`; `timeout_ms` < 0 waits until one
  /// arrives. @return its size (> 0), 0 on timeout, -1 on error (e.g. the device was unplugged;
  /// lastError() says why).
  virtual int read(std::uint8_t* data, std::size_t size, int timeout_ms) noexcept = 0;
  /// Writes one output report (report id first). @return bytes written, -1 on error.
  virtual int write(const std::uint8_t* data, std::size_t size) noexcept = 0;
  /// The last error, for messages.
  virtual std::string lastError() const = 0;
};

/// Enumerates and opens HID devices.
class HidBackend {
 public:
  virtual ~HidBackend() = default;
  virtual std::string name() const = 0;  ///< e.g. "hidapi".
  /// Every HID device present (all vendors). @throws std::runtime_error when the library fails.
  virtual std::vector<HidDeviceInfo> enumerate() = 0;
  /// @throws std::runtime_error naming the path and why it cannot be opened (e.g. permissions).
  virtual std::unique_ptr<HidTransport> open(const std::string& path) = 0;
};

// ---- USB ---------------------------------------------------------------------------------------

/// A USB device found by enumeration.
struct UsbDeviceInfo {
  std::string path;           ///< "usb:BUS:ADDRESS" (decimal).
  std::uint8_t bus = 0;
  std::uint8_t address = 0;
  std::uint16_t vendor_id = 0;
  std::uint16_t product_id = 0;
  std::string serial;         ///< Empty when unknown or unreadable.
};

/// An open USB device (interface 0 claimed), used by one thread at a time.
class UsbTransport {
 public:
  /// Error codes (the values of libusb's).
  static constexpr int kErrorIo = -1;
  static constexpr int kErrorNoDevice = -4;
  static constexpr int kErrorTimeout = -7;

  virtual ~UsbTransport() = default;
  /// A control transfer. @return bytes transferred (>= 0) or a negative error code.
  virtual int control(std::uint8_t request_type, std::uint8_t request, std::uint16_t value, std::uint16_t index,
                      std::uint8_t* data, std::uint16_t length, unsigned timeout_ms) noexcept = 0;
  /// A bulk OUT transfer. @return bytes transferred (>= 0; may be short on timeout) or a
  /// negative error code (kErrorTimeout when nothing went out in time).
  virtual int bulkWrite(std::uint8_t endpoint, const std::uint8_t* data, int length, unsigned timeout_ms) noexcept = 0;
  /// A bulk IN transfer. @return bytes received (>= 0) or a negative error code
  /// (kErrorTimeout when nothing came in time).
  virtual int bulkRead(std::uint8_t endpoint, std::uint8_t* data, int length, unsigned timeout_ms) noexcept = 0;
  /// Text for an error code.
  virtual std::string errorName(int code) const = 0;
};

/// Enumerates and opens USB devices.
class UsbBackend {
 public:
  virtual ~UsbBackend() = default;
  virtual std::string name() const = 0;  ///< e.g. "libusb".
  /// Devices with this vendor / product id. @throws std::runtime_error when the library fails.
  virtual std::vector<UsbDeviceInfo> enumerate(std::uint16_t vendor_id, std::uint16_t product_id) = 0;
  /// Opens the device and claims interface 0.
  /// @throws std::runtime_error naming the device and why (permissions, busy, gone).
  virtual std::unique_ptr<UsbTransport> open(const UsbDeviceInfo& device) = 0;
};

/// The hidapi backend, or nullptr when this build has no hidapi.
std::shared_ptr<HidBackend> makeHidapiBackend();
/// The libusb backend, or nullptr when this build has no libusb.
std::shared_ptr<UsbBackend> makeLibusbBackend();

}  // namespace vh::devices
