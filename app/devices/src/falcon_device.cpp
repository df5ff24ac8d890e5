#include "vh/devices/falcon_device.h"

#include "device_clock.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <fstream>
#include <iterator>
#include <sstream>
#include <stdexcept>

#include "vh/devices/falcon_kinematics.h"
#include "vh/devices/velocity_filter.h"

namespace vh::devices {

namespace {

using falcon::ControlStep;

constexpr std::size_t kMaxFirmwareBytes = 64 * 1024;

using detail::steadySeconds;

std::string hex(std::uint8_t b) {
  static constexpr char kDigits[] = "0123456789ABCDEF";
  return std::string{kDigits[b >> 4], kDigits[b & 0xF]};
}

[[noreturn]] void uploadFailure(const std::string& step, const std::string& problem) {
  throw std::runtime_error("Falcon firmware upload: " + step + ": " + problem);
}

template <std::size_t N>
void runControlSteps(UsbTransport& usb, const std::array<ControlStep, N>& steps, unsigned timeout_ms,
                     const char* phase) {
  for (const ControlStep& s : steps) {
    const int r = usb.control(falcon::kControlRequestType, s.request, s.value, 0, nullptr, 0, timeout_ms);
    if (r < 0) {
      throw std::runtime_error(std::string("Falcon ") + phase + ": control transfer '" + s.what +
                               "' failed: " + usb.errorName(r));
    }
  }
}

/// Writes all of `data` to the bulk OUT endpoint. @return false on error or timeout.
bool writeAll(UsbTransport& usb, const std::uint8_t* data, std::size_t size, unsigned timeout_ms, int& error) {
  std::size_t sent = 0;
  int stalls = 0;
  while (sent < size) {
    const int r = usb.bulkWrite(falcon::kEndpointOut, data + sent, static_cast<int>(size - sent), timeout_ms);
    if (r < 0) {
      error = r;
      return false;
    }
    if (r == 0 && ++stalls > 3) {
      error = UsbTransport::kErrorTimeout;
      return false;
    }
    sent += static_cast<std::size_t>(r);
  }
  return true;
}

/// Reads serial bytes (FTDI status stripped) until `want` bytes arrived or `max_empty_reads`
/// reads in a row brought none. @return bytes read into out (<= want); -error on an I/O error.
int readSerial(UsbTransport& usb, std::uint8_t* out, std::size_t want, unsigned timeout_ms, int max_empty_reads) {
  std::uint8_t raw[falcon::kUsbPacketBytes];
  std::uint8_t data[falcon::kUsbPacketBytes];
  std::size_t got = 0;
  int empty = 0;
  while (got < want && empty < max_empty_reads) {
    const int r = usb.bulkRead(falcon::kEndpointIn, raw, static_cast<int>(sizeof raw), timeout_ms);
    if (r == UsbTransport::kErrorTimeout) {
      ++empty;
      continue;
    }
    if (r < 0) return r;
    const std::size_t n = falcon::stripFtdiStatus(raw, static_cast<std::size_t>(r), data);
    if (n == 0) {
      ++empty;
      continue;
    }
    empty = 0;
    const std::size_t take = std::min(n, want - got);
    std::copy(data, data + take, out + got);
    got += take;
  }
  return static_cast<int>(got);
}

}  // namespace

// ---- Firmware ------------------------------------------------------------------------------------

std::vector<std::uint8_t> readFalconFirmwareFile(const std::filesystem::path& path) {
  std::error_code ec;
  if (path.empty()) throw std::runtime_error("Falcon firmware: no file given");
  if (!std::filesystem::is_regular_file(path, ec)) {
    throw std::runtime_error(path.string() + ": Falcon firmware file not found");
  }
  const auto size = std::filesystem::file_size(path, ec);
  if (ec) throw std::runtime_error(path.string() + ": cannot read the Falcon firmware file: " + ec.message());
  if (size == 0) throw std::runtime_error(path.string() + ": the Falcon firmware file is empty");
  if (size > kMaxFirmwareBytes) {
    throw std::runtime_error(path.string() + ": " + std::to_string(size) +
                             " bytes is too large for Falcon firmware (at most 65536)");
  }
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error(path.string() + ": cannot open the Falcon firmware file");
  std::vector<std::uint8_t> bytes(static_cast<std::size_t>(size));
  in.read(reinterpret_cast<char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
  if (in.gcount() != static_cast<std::streamsize>(bytes.size())) {
    throw std::runtime_error(path.string() + ": short read of the Falcon firmware file");
  }
  return bytes;
}

void setFalconNormalMode(UsbTransport& usb, unsigned timeout_ms) {
  runControlSteps(usb, falcon::kNormalModeSetup, timeout_ms, "normal mode");
}

void uploadFalconFirmware(UsbTransport& usb, std::span<const std::uint8_t> firmware, const FalconUploadOptions& o) {
  if (firmware.empty()) uploadFailure("image", "the firmware is empty");
  int error = 0;
  // Steps 1-4: FTDI set-up for the boot loader, then its check, retried.
  bool booted = false;
  for (int attempt = 0; attempt < o.boot_check_attempts && !booted; ++attempt) {
    try {
      runControlSteps(usb, falcon::kBootloaderSetup, o.timeout_ms, "boot loader set-up");
    } catch (const std::runtime_error& e) {
      uploadFailure("set-up", e.what());
    }
    if (!writeAll(usb, falcon::kBootCheckRequest.data(), falcon::kBootCheckRequest.size(), o.timeout_ms, error)) {
      if (error == UsbTransport::kErrorNoDevice) uploadFailure("boot check", "the device is gone");
      continue;
    }
    std::uint8_t reply[falcon::kBootCheckReply.size()] = {};
    const int n = readSerial(usb, reply, sizeof reply, o.timeout_ms, 2);
    if (n == UsbTransport::kErrorNoDevice) uploadFailure("boot check", "the device is gone");
    booted = n > 0 && falcon::isBootCheckReply(reply, static_cast<std::size_t>(n));
  }
  if (!booted) {
    uploadFailure("boot check", "no answer to 0A 43 0D after " + std::to_string(o.boot_check_attempts) +
                                    " attempts (is the Falcon powered?)");
  }
  // Step 5: the loader: DTR low, baud divisor 0x15, 'A' echoed.
  try {
    runControlSteps(usb, falcon::kLoaderSetup, o.timeout_ms, "loader set-up");
  } catch (const std::runtime_error& e) {
    uploadFailure("loader set-up", e.what());
  }
  const std::uint8_t check = falcon::kLoaderCheckByte;
  if (!writeAll(usb, &check, 1, o.timeout_ms, error)) uploadFailure("loader check", "cannot send 0x41: " + usb.errorName(error));
  std::uint8_t echo = 0;
  const int e = readSerial(usb, &echo, 1, o.timeout_ms, o.max_empty_reads);
  if (e != 1 || echo != check) {
    uploadFailure("loader check", e == 1 ? "0x41 echoed as 0x" + hex(echo) : std::string("0x41 was not echoed"));
  }
  // Step 6: the image in blocks of at most 62 bytes, every byte echoed.
  std::uint8_t block_echo[falcon::kFirmwareBlockBytes];
  for (std::size_t offset = 0; offset < firmware.size(); offset += falcon::kFirmwareBlockBytes) {
    const std::size_t n = std::min(falcon::kFirmwareBlockBytes, firmware.size() - offset);
    if (!writeAll(usb, firmware.data() + offset, n, o.timeout_ms, error)) {
      uploadFailure("image", "write at byte " + std::to_string(offset) + " failed: " + usb.errorName(error));
    }
    const int got = readSerial(usb, block_echo, n, o.timeout_ms, o.max_empty_reads);
    if (got < 0) uploadFailure("image", "echo read at byte " + std::to_string(offset) + " failed: " + usb.errorName(got));
    for (std::size_t i = 0; i < n; ++i) {
      if (i >= static_cast<std::size_t>(got)) {
        uploadFailure("image", "byte " + std::to_string(offset + i) + " of " + std::to_string(firmware.size()) +
                                   " was not echoed");
      }
      if (block_echo[i] != firmware[offset + i]) {
        uploadFailure("image", "byte " + std::to_string(offset + i) + " echoed as 0x" + hex(block_echo[i]) +
                                   ", expected 0x" + hex(firmware[offset + i]));
      }
    }
  }
  // Step 7: normal mode.
  try {
    setFalconNormalMode(usb, o.timeout_ms);
  } catch (const std::runtime_error& ex) {
    uploadFailure("normal mode", ex.what());
  }
}

bool falconFirmwareLoaded(UsbTransport& usb, int attempts, unsigned timeout_ms) noexcept {
  const falcon::Packet zero = falcon::encodeCommand({});
  falcon::PacketParser parser;
  std::uint8_t raw[falcon::kUsbPacketBytes];
  std::uint8_t data[falcon::kUsbPacketBytes];
  for (int i = 0; i < attempts; ++i) {
    const int w = usb.bulkWrite(falcon::kEndpointOut, zero.data(), static_cast<int>(zero.size()), timeout_ms);
    if (w == UsbTransport::kErrorNoDevice) return false;
    for (int k = 0; k < 3; ++k) {
      const int r = usb.bulkRead(falcon::kEndpointIn, raw, static_cast<int>(sizeof raw), timeout_ms);
      if (r == UsbTransport::kErrorNoDevice) return false;
      if (r <= 0) continue;
      const std::size_t n = falcon::stripFtdiStatus(raw, static_cast<std::size_t>(r), data);
      // A byte-for-byte echo of the command is a loader echoing, not the firmware answering.
      if (n >= zero.size() && std::equal(zero.begin(), zero.end(), data)) continue;
      parser.feed(data, n);
      falcon::Status status;
      if (parser.next(status)) return true;
    }
  }
  return false;
}

runtime::DeviceLimits falconLimits() noexcept {
  runtime::DeviceLimits l;
  l.max_force_N = 8.0;
  l.max_torque_Nm = 0.0;
  l.max_linear_stiffness_N_per_m = 3000.0;
  l.max_angular_stiffness_Nm_per_rad = 0.0;
  l.workspace_radius_m = 0.04;
  // 8 N on the catalogue's 0.15 kg moving mass (app/simulation device_catalog.cpp): 4.9 m/s.
  l.max_speed_m_per_s = runtime::handleMaxSpeed_m_per_s(l.max_force_N, l.workspace_radius_m, 0.15);
  return l;
}

// ---- FalconDevice ------------------------------------------------------------------------------

FalconDevice::FalconDevice(std::shared_ptr<UsbBackend> backend, UsbDeviceInfo device, FalconOptions options)
    : backend_(std::move(backend)), info_(std::move(device)), options_(std::move(options)) {
  if (!backend_) throw std::invalid_argument("FalconDevice: no USB backend");
  forces_.writeSlot().setZero();
  forces_.publish();
  openAndStart();
}

FalconDevice::~FalconDevice() { stopIo(); }

runtime::DeviceIdentity FalconDevice::identity() const {
  return {"Novint Falcon", "Novint", info_.serial, backend_->name() + " " + info_.path};
}

void FalconDevice::openAndStart() {
  const std::string where = "Novint Falcon at " + info_.path;
  std::unique_ptr<UsbTransport> usb = backend_->open(info_);
  bool loaded = false;
  try {
    setFalconNormalMode(*usb);
    loaded = falconFirmwareLoaded(*usb);
  } catch (const std::runtime_error& e) {
    throw std::runtime_error(where + ": " + e.what());
  }
  if (!loaded) {
    if (options_.firmware.empty()) {
      throw std::runtime_error(where + ": its firmware is not loaded (needed after every power-up): give the path of "
                               "Novint's firmware file (nvent_firmware.bin from the Novint driver; VolumeHaptics "
                               "does not ship it), e.g. \"firmware\" in the scene's device section");
    }
    if (firmware_.empty()) firmware_ = readFalconFirmwareFile(options_.firmware);
    try {
      uploadFalconFirmware(*usb, firmware_, options_.upload);
    } catch (const std::runtime_error& e) {
      throw std::runtime_error(where + ": " + e.what());
    }
    if (!falconFirmwareLoaded(*usb)) {
      throw std::runtime_error(where + ": the firmware from " + options_.firmware.string() +
                               " was uploaded but does not answer (is it the Falcon's firmware?)");
    }
  }
  transport_ = std::move(usb);
  setProblem(options_.require_homing ? "not homed yet: move the grip through its whole range" : "");
  startIoThread([this] { ioLoop(); });
}

void FalconDevice::stopIo() noexcept {
  stopIoThread();
  transport_.reset();
}

void FalconDevice::reconnect() {
  stopIo();
  markDisconnected();
  std::vector<UsbDeviceInfo> found = backend_->enumerate(falcon::kVendorId, falcon::kProductId);
  const auto same = std::find_if(found.begin(), found.end(), [&](const UsbDeviceInfo& d) {
    return !info_.serial.empty() ? d.serial == info_.serial : true;
  });
  if (same == found.end()) {
    throw std::runtime_error("Novint Falcon" + (info_.serial.empty() ? std::string() : " " + info_.serial) +
                             ": not found (is it plugged in?)");
  }
  info_ = *same;
  openAndStart();
}

bool FalconDevice::read(runtime::DeviceSample& sample) noexcept {
  samples_.read(servo_sample_);
  if (!connected()) return false;
  // Nothing measured since (re)connecting yet: no stale sample of the previous connection.
  if (servo_sample_.connection != connection()) return false;
  sample = servo_sample_;
  return true;
}

void FalconDevice::command(const Eigen::Vector3d& force_B_N, const Eigen::Vector3d&) noexcept {
  Eigen::Vector3d& slot = forces_.writeSlot();
  slot = force_B_N.allFinite() ? force_B_N : Eigen::Vector3d::Zero();
  forces_.publish();
}

namespace {

/// The round's command: with a usable position (`usable`), the force at the grip through the
/// Jacobian at `p_K` as motor commands (none where the Jacobian is singular); the LEDs red and
/// homing mode while the grip must still be homed (`homing`), else green.
falcon::Command falconCommand(const Eigen::Vector3d& p_K, const Eigen::Vector3d& force_B_N, bool usable,
                              bool homing) noexcept {
  falcon::Command cmd;
  if (usable) {
    Eigen::Vector3d tau;
    if (falcon::jointTorques(p_K, force_B_N, tau)) cmd.motor = falcon::motorCommands(tau);
  }
  cmd.flags = homing ? (falcon::kLedRed | falcon::kHomingMode) : falcon::kLedGreen;
  return cmd;
}

/// The grip's position by forward kinematics of the status' encoders, warm-started at the last
/// solution `p_K` (`have_position`), else from the default start; a failed warm start is tried
/// again from the default start. @return whether it solved (into `p_new`).
bool gripPosition(const falcon::Status& status, bool have_position, const Eigen::Vector3d& p_K,
                  Eigen::Vector3d& p_new) noexcept {
  const Eigen::Vector3d theta(falcon::encoderToAngle_rad(status.encoder[0]),
                              falcon::encoderToAngle_rad(status.encoder[1]),
                              falcon::encoderToAngle_rad(status.encoder[2]));
  return falcon::forwardKinematics(theta, p_new, have_position ? p_K : Eigen::Vector3d(0.0, 0.0, falcon::kForwardStartZ_m)) ||
         (have_position && falcon::forwardKinematics(theta, p_new));
}

/// A status round's device sample: taken at `time_s`, the grip at `p_K` (the workspace centre
/// the origin) moving at `v_m_per_s`, the status' buttons.
void fillSample(runtime::DeviceSample& s, double time_s, const Eigen::Vector3d& p_K, const Eigen::Vector3d& v_m_per_s,
                const falcon::Status& status, std::uint32_t connection, bool valid) noexcept {
  s.time_s = time_s;
  s.X_WD = haptics::Pose::FromTranslation(p_K - Eigen::Vector3d(0.0, 0.0, falcon::kWorkspaceCentreZ_m));
  s.v_WD_m_per_s = v_m_per_s;
  s.w_WD_rad_per_s.setZero();
  s.buttons = status.buttons;
  s.connection = connection;
  s.valid = valid;
}

/// Leaves the motors off: a zero command, and its reply drained.
void commandMotorsOff(UsbTransport& usb, unsigned timeout_ms) noexcept {
  const falcon::Packet zero = falcon::encodeCommand({});
  usb.bulkWrite(falcon::kEndpointOut, zero.data(), static_cast<int>(zero.size()), timeout_ms);
  std::uint8_t drain[falcon::kUsbPacketBytes];
  usb.bulkRead(falcon::kEndpointIn, drain, static_cast<int>(sizeof drain), timeout_ms);
}

}  // namespace

void FalconDevice::ioLoop() noexcept {
  UsbTransport& usb = *transport_;
  falcon::PacketParser parser;
  falcon::Status status;
  bool have_status = false;
  bool have_position = false;
  Eigen::Vector3d p_K(0.0, 0.0, falcon::kWorkspaceCentreZ_m);
  VelocityFilter velocity(options_.velocity_cutoff_Hz);
  double last_time_s = 0.0;
  const double t0_s = steadySeconds();
  const std::uint32_t this_connection = connection();
  int consecutive_errors = 0;
  bool was_homed = false;
  std::uint8_t raw[falcon::kUsbPacketBytes];
  std::uint8_t data[falcon::kUsbPacketBytes];

  auto disconnect = [&](const std::string& why) {
    markDisconnected();
    setProblem(why);
  };

  while (!stopRequested()) {
    // Command: force through the Jacobian at the latest position, LEDs / homing.
    Eigen::Vector3d force_B_N = Eigen::Vector3d::Zero();
    forces_.read(force_B_N);
    const bool homed = have_status && status.allHomed();
    const bool usable = have_position && (homed || !options_.require_homing);
    const falcon::Packet packet = falcon::encodeCommand(falconCommand(p_K, force_B_N, usable, options_.require_homing && !homed));

    const int w = usb.bulkWrite(falcon::kEndpointOut, packet.data(), static_cast<int>(packet.size()), options_.io_timeout_ms);
    const int r = w < 0 ? w : usb.bulkRead(falcon::kEndpointIn, raw, static_cast<int>(sizeof raw), options_.io_timeout_ms);
    if (w == UsbTransport::kErrorNoDevice || r == UsbTransport::kErrorNoDevice) {
      disconnect("unplugged (USB: no device)");
      break;
    }
    if (w < 0 || (r < 0 && r != UsbTransport::kErrorTimeout)) {
      io_errors_.fetch_add(1, std::memory_order_relaxed);
      if (++consecutive_errors > options_.max_consecutive_errors) {
        disconnect("USB errors: " + usb.errorName(w < 0 ? w : r));
        break;
      }
      continue;
    }
    consecutive_errors = 0;
    if (r <= 0) continue;  // nothing this round: the sample's time stays (the safety layer watches it)

    parser.feed(data, falcon::stripFtdiStatus(raw, static_cast<std::size_t>(r), data));
    bool fresh = false;
    while (parser.next(status)) {
      fresh = true;
      have_status = true;
      packets_.fetch_add(1, std::memory_order_relaxed);
    }
    if (!fresh) continue;

    // Position by forward kinematics, warm-started at the last solution.
    Eigen::Vector3d p_new;
    const bool solved = gripPosition(status, have_position, p_K, p_new);
    const double now_s = steadySeconds() - t0_s;
    if (solved) {
      velocity.update(p_new, now_s);
      p_K = p_new;
      have_position = true;
      last_time_s = now_s;
    }
    const bool homed_now = status.allHomed();
    homed_.store(homed_now, std::memory_order_relaxed);
    if (homed_now != was_homed) {
      setProblem(homed_now || !options_.require_homing ? "" : "not homed yet: move the grip through its whole range");
      was_homed = homed_now;
    }
    fillSample(samples_.writeSlot(), last_time_s, p_K, velocity.velocity(), status, this_connection,
               have_position && (homed_now || !options_.require_homing));
    samples_.publish();
  }
  // Leave the motors off when the device is still there.
  if (connected()) commandMotorsOff(usb, options_.io_timeout_ms);
}

}  // namespace vh::devices
