#pragma once
// In-memory fakes of the devices and transports (no hardware, no umockdev): a Falcon behind
// its FTDI chip (boot loader, loader echo, firmware packets), HID and USB backends. The Falcon
// fake is also what the umockdev test answers libusb with.
#include <algorithm>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <map>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "vh/devices/falcon_kinematics.h"
#include "vh/devices/falcon_protocol.h"
#include "vh/devices/transport.h"

namespace vh::devices::test {

/// A Novint Falcon as seen through its FTDI chip. Thread-safe (one mutex).
class FakeFalcon {
 public:
  struct Control {
    std::uint8_t request_type;
    std::uint8_t request;
    std::uint16_t value;
    std::uint16_t index;
    bool operator==(const Control&) const = default;
  };
  enum class Mode { kIdle, kBoot, kLoader, kNormal };

  // ---- Test set-up --------------------------------------------------------------------------
  /// The firmware runs already (as after an earlier upload in this power cycle).
  void setFirmwareRunning(bool running) {
    std::lock_guard<std::mutex> l(m_);
    running_ = running;
  }
  /// Boot checks answered with nothing before the first good answer.
  void setBootCheckFailures(int n) {
    std::lock_guard<std::mutex> l(m_);
    boot_failures_ = n;
  }
  /// Only this many bytes of the boot reply come back (Linux: part of it).
  void setBootReplyBytes(std::size_t n) {
    std::lock_guard<std::mutex> l(m_);
    boot_reply_bytes_ = n;
  }
  /// Corrupts the echo of firmware byte `index` (to test the comparison).
  void corruptEchoAt(std::size_t index) {
    std::lock_guard<std::mutex> l(m_);
    corrupt_at_ = index;
  }
  /// Puts the handle at p_K [m] (encoders from inverse kinematics), homing state and buttons.
  void setHandle(const Eigen::Vector3d& p_K_m, std::uint8_t homed_mask = 0x7, std::uint8_t buttons = 0) {
    Eigen::Vector3d theta;
    if (!falcon::inverseKinematics(p_K_m, theta)) throw std::invalid_argument("FakeFalcon: out of reach");
    std::lock_guard<std::mutex> l(m_);
    for (int i = 0; i < 3; ++i) status_.encoder[static_cast<std::size_t>(i)] = falcon::angleToEncoder(theta[i]);
    status_.homed_mask = homed_mask;
    status_.buttons = buttons;
  }
  /// Stops answering commands (a silent device) or resumes.
  void setSilent(bool silent) {
    std::lock_guard<std::mutex> l(m_);
    silent_ = silent;
    empty_reads_while_silent_ = 0;
  }
  /// Bulk-IN transfers that found nothing to send since setSilent(true) with nothing left
  /// queued: after two, the driver's I/O thread, which reads one transfer at a time, has dealt
  /// with every byte the fake sent before it fell silent.
  int emptyReadsWhileSilent() const {
    std::lock_guard<std::mutex> l(m_);
    return empty_reads_while_silent_;
  }
  void unplug() {
    std::lock_guard<std::mutex> l(m_);
    unplugged_ = true;
  }
  void plugIn() {  // a fresh power-up: the firmware is gone
    std::lock_guard<std::mutex> l(m_);
    unplugged_ = false;
    running_ = false;
    mode_ = Mode::kIdle;
    pending_.clear();
    uploaded_.clear();
  }

  // ---- What happened --------------------------------------------------------------------------
  std::vector<Control> controls() const {
    std::lock_guard<std::mutex> l(m_);
    return controls_;
  }
  std::vector<std::uint8_t> uploaded() const {
    std::lock_guard<std::mutex> l(m_);
    return uploaded_;
  }
  std::vector<falcon::Command> commands() const {
    std::lock_guard<std::mutex> l(m_);
    return commands_;
  }
  std::size_t commandCount() const {
    std::lock_guard<std::mutex> l(m_);
    return commands_.size();
  }
  falcon::Command lastCommand() const {
    std::lock_guard<std::mutex> l(m_);
    return commands_.empty() ? falcon::Command{} : commands_.back();
  }
  int bootChecks() const {
    std::lock_guard<std::mutex> l(m_);
    return boot_checks_;
  }
  bool running() const {
    std::lock_guard<std::mutex> l(m_);
    return running_;
  }
  bool unplugged() const {
    std::lock_guard<std::mutex> l(m_);
    return unplugged_;
  }

  // ---- The wire (UsbTransport semantics) ------------------------------------------------------
  int control(std::uint8_t request_type, std::uint8_t request, std::uint16_t value, std::uint16_t index) {
    std::lock_guard<std::mutex> l(m_);
    if (unplugged_) return UsbTransport::kErrorNoDevice;
    controls_.push_back({request_type, request, value, index});
    if (request == falcon::kRequestReset && value == 1) pending_.clear();  // purge RX (host side)
    if (request == falcon::kRequestBaudRate) {
      if (value == 0x4138) mode_ = Mode::kBoot;
      if (value == 0x0015) {
        mode_ = Mode::kLoader;
        loader_checked_ = false;
      }
      if (value == 0x0002) {
        mode_ = Mode::kNormal;
        if (!uploaded_.empty()) running_ = true;  // the uploaded image starts
      }
    }
    if (request == falcon::kRequestBaudRate && value == 0x4138) boot_buffer_.clear();
    return 0;
  }
  int bulkOut(const std::uint8_t* data, int length) {
    std::lock_guard<std::mutex> l(m_);
    if (unplugged_) return UsbTransport::kErrorNoDevice;
    for (int i = 0; i < length; ++i) {
      const std::uint8_t b = data[i];
      switch (mode_) {
        case Mode::kBoot:
          boot_buffer_.push_back(b);
          if (boot_buffer_.size() >= 3 &&
              std::equal(boot_buffer_.end() - 3, boot_buffer_.end(), falcon::kBootCheckRequest.begin())) {
            ++boot_checks_;
            boot_buffer_.clear();
            if (boot_failures_ > 0) {
              --boot_failures_;
            } else {
              for (std::size_t k = 0; k < std::min(boot_reply_bytes_, falcon::kBootCheckReply.size()); ++k) {
                pending_.push_back(falcon::kBootCheckReply[k]);
              }
            }
          }
          break;
        case Mode::kLoader:
          if (!loader_checked_) {
            if (b == falcon::kLoaderCheckByte) loader_checked_ = true;
            pending_.push_back(b);
          } else {
            const std::uint8_t echo = uploaded_.size() == corrupt_at_ ? static_cast<std::uint8_t>(b ^ 0xFF) : b;
            uploaded_.push_back(b);
            pending_.push_back(echo);
          }
          break;
        case Mode::kNormal:
          if (!running_) break;  // the boot loader ignores packets at this rate
          packet_.push_back(b);
          if (packet_.size() == falcon::kPacketBytes) {
            falcon::Command c;
            if (packet_[0] == falcon::kPacketStart && packet_[15] == falcon::kPacketEnd) {
              for (std::size_t k = 0; k < 3; ++k) falcon::decodeWord(&packet_[1 + 4 * k], c.motor[k]);
              c.flags = static_cast<std::uint8_t>(packet_[13] - falcon::kNibbleOffset);
              commands_.push_back(c);
              if (!silent_) {
                const falcon::Packet s = falcon::encodeStatus(status_);
                pending_.insert(pending_.end(), s.begin(), s.end());
              }
            }
            packet_.clear();
          }
          break;
        case Mode::kIdle:
          break;
      }
    }
    return length;
  }
  /// One bulk-IN transfer: 2 FTDI status bytes, then at most 62 pending bytes.
  int bulkIn(std::uint8_t* data, int length) {
    std::lock_guard<std::mutex> l(m_);
    if (unplugged_) return UsbTransport::kErrorNoDevice;
    if (length < 2) return 0;
    data[0] = 0x31;
    data[1] = 0x60;
    const std::size_t n = std::min<std::size_t>(pending_.size(), std::min<std::size_t>(length - 2, 62));
    std::copy(pending_.begin(), pending_.begin() + static_cast<std::ptrdiff_t>(n), data + 2);
    pending_.erase(pending_.begin(), pending_.begin() + static_cast<std::ptrdiff_t>(n));
    if (silent_ && n == 0) ++empty_reads_while_silent_;
    return static_cast<int>(n + 2);
  }

 private:
  mutable std::mutex m_;
  Mode mode_ = Mode::kIdle;
  bool running_ = false;
  bool unplugged_ = false;
  bool silent_ = false;
  int empty_reads_while_silent_ = 0;
  bool loader_checked_ = false;
  int boot_failures_ = 0;
  int boot_checks_ = 0;
  std::size_t boot_reply_bytes_ = 4;
  std::size_t corrupt_at_ = static_cast<std::size_t>(-1);
  std::vector<std::uint8_t> boot_buffer_;
  std::vector<std::uint8_t> packet_;
  std::deque<std::uint8_t> pending_;
  std::vector<Control> controls_;
  std::vector<std::uint8_t> uploaded_;
  std::vector<falcon::Command> commands_;
  falcon::Status status_{{0, 0, 0}, 0x7, 0};
};

/// UsbTransport over a FakeFalcon.
class FakeUsbTransport final : public UsbTransport {
 public:
  explicit FakeUsbTransport(std::shared_ptr<FakeFalcon> falcon) : falcon_(std::move(falcon)) {}
  int control(std::uint8_t request_type, std::uint8_t request, std::uint16_t value, std::uint16_t index, std::uint8_t*,
              std::uint16_t, unsigned) noexcept override {
    return falcon_->control(request_type, request, value, index);
  }
  int bulkWrite(std::uint8_t, const std::uint8_t* data, int length, unsigned) noexcept override {
    return falcon_->bulkOut(data, length);
  }
  int bulkRead(std::uint8_t, std::uint8_t* data, int length, unsigned) noexcept override {
    const int n = falcon_->bulkIn(data, length);
    if (n == 2) std::this_thread::sleep_for(std::chrono::microseconds(200));  // status only: like a 1 ms latency timer, shorter
    return n;
  }
  std::string errorName(int code) const override { return "fake USB error " + std::to_string(code); }

 private:
  std::shared_ptr<FakeFalcon> falcon_;
};

/// A USB backend with FakeFalcons plugged in.
class FakeUsbBackend final : public UsbBackend {
 public:
  std::shared_ptr<FakeFalcon> add(std::uint8_t address, std::string serial = {}) {
    auto f = std::make_shared<FakeFalcon>();
    std::lock_guard<std::mutex> l(m_);
    UsbDeviceInfo info;
    info.bus = 1;
    info.address = address;
    info.vendor_id = falcon::kVendorId;
    info.product_id = falcon::kProductId;
    info.serial = std::move(serial);
    info.path = "usb:1:" + std::to_string(address);
    devices_.push_back({info, f});
    return f;
  }
  std::string name() const override { return "fake-usb"; }
  std::vector<UsbDeviceInfo> enumerate(std::uint16_t vendor_id, std::uint16_t product_id) override {
    std::lock_guard<std::mutex> l(m_);
    std::vector<UsbDeviceInfo> out;
    for (const auto& [info, f] : devices_) {
      if (info.vendor_id == vendor_id && info.product_id == product_id && !f->unplugged()) out.push_back(info);
    }
    return out;
  }
  std::unique_ptr<UsbTransport> open(const UsbDeviceInfo& device) override {
    std::lock_guard<std::mutex> l(m_);
    for (const auto& [info, f] : devices_) {
      if (info.bus == device.bus && info.address == device.address && !f->unplugged()) {
        ++opens_;
        return std::make_unique<FakeUsbTransport>(f);
      }
    }
    throw std::runtime_error(device.path + ": no such fake device");
  }
  int opens() const {
    std::lock_guard<std::mutex> l(m_);
    return opens_;
  }

 private:
  mutable std::mutex m_;
  std::vector<std::pair<UsbDeviceInfo, std::shared_ptr<FakeFalcon>>> devices_;
  int opens_ = 0;
};

/// A HID device: a queue of input reports, the output reports written.
class FakeHidDevice {
 public:
  void push(std::vector<std::uint8_t> report) {
    {
      std::lock_guard<std::mutex> l(m_);
      reports_.push_back(std::move(report));
    }
    cv_.notify_all();
  }
  void unplug() {
    {
      std::lock_guard<std::mutex> l(m_);
      unplugged_ = true;
    }
    cv_.notify_all();
  }
  void plugIn() {
    std::lock_guard<std::mutex> l(m_);
    unplugged_ = false;
  }
  bool unplugged() const {
    std::lock_guard<std::mutex> l(m_);
    return unplugged_;
  }
  std::vector<std::vector<std::uint8_t>> written() const {
    std::lock_guard<std::mutex> l(m_);
    return written_;
  }
  std::size_t queued() const {
    std::lock_guard<std::mutex> l(m_);
    return reports_.size();
  }
  int read(std::uint8_t* data, std::size_t size, int timeout_ms) {
    std::unique_lock<std::mutex> l(m_);
    const auto ready = [&] { return unplugged_ || !reports_.empty(); };
    if (timeout_ms < 0) cv_.wait(l, ready);
    else if (!cv_.wait_for(l, std::chrono::milliseconds(timeout_ms), ready)) return 0;
    if (unplugged_) return -1;
    const std::vector<std::uint8_t> r = std::move(reports_.front());
    reports_.pop_front();
    const std::size_t n = std::min(size, r.size());
    std::copy(r.begin(), r.begin() + static_cast<std::ptrdiff_t>(n), data);
    return static_cast<int>(n);
  }
  int write(const std::uint8_t* data, std::size_t size) {
    std::lock_guard<std::mutex> l(m_);
    if (unplugged_) return -1;
    written_.emplace_back(data, data + size);
    return static_cast<int>(size);
  }

 private:
  mutable std::mutex m_;
  std::condition_variable cv_;
  std::deque<std::vector<std::uint8_t>> reports_;
  std::vector<std::vector<std::uint8_t>> written_;
  bool unplugged_ = false;
};

class FakeHidTransport final : public HidTransport {
 public:
  explicit FakeHidTransport(std::shared_ptr<FakeHidDevice> d) : d_(std::move(d)) {}
  int read(std::uint8_t* data, std::size_t size, int timeout_ms) noexcept override { return d_->read(data, size, timeout_ms); }
  int write(const std::uint8_t* data, std::size_t size) noexcept override { return d_->write(data, size); }
  std::string lastError() const override { return "fake HID device gone"; }

 private:
  std::shared_ptr<FakeHidDevice> d_;
};

class FakeHidBackend final : public HidBackend {
 public:
  std::shared_ptr<FakeHidDevice> add(HidDeviceInfo info) {
    auto d = std::make_shared<FakeHidDevice>();
    std::lock_guard<std::mutex> l(m_);
    devices_.push_back({std::move(info), d});
    return d;
  }
  void setFailure(std::string what) {
    std::lock_guard<std::mutex> l(m_);
    failure_ = std::move(what);
  }
  std::string name() const override { return "fake-hid"; }
  std::vector<HidDeviceInfo> enumerate() override {
    std::lock_guard<std::mutex> l(m_);
    if (!failure_.empty()) throw std::runtime_error(failure_);
    std::vector<HidDeviceInfo> out;
    for (const auto& [info, d] : devices_) {
      if (!d->unplugged()) out.push_back(info);
    }
    return out;
  }
  std::unique_ptr<HidTransport> open(const std::string& path) override {
    std::lock_guard<std::mutex> l(m_);
    for (const auto& [info, d] : devices_) {
      if (info.path == path && !d->unplugged()) return std::make_unique<FakeHidTransport>(d);
    }
    throw std::runtime_error(path + ": no such fake HID device");
  }

 private:
  std::mutex m_;
  std::vector<std::pair<HidDeviceInfo, std::shared_ptr<FakeHidDevice>>> devices_;
  std::string failure_;
};

/// A SpaceMouse report: id 1 (translation) or 2 (rotation) with three int16 LE.
inline std::vector<std::uint8_t> axisReport(std::uint8_t id, std::int16_t a, std::int16_t b, std::int16_t c) {
  auto lo = [](std::int16_t v) { return static_cast<std::uint8_t>(static_cast<std::uint16_t>(v) & 0xFF); };
  auto hi = [](std::int16_t v) { return static_cast<std::uint8_t>(static_cast<std::uint16_t>(v) >> 8); };
  return {id, lo(a), hi(a), lo(b), hi(b), lo(c), hi(c)};
}

}  // namespace vh::devices::test
