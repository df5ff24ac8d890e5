#pragma once
/// @file
/// Novint Falcon wire protocol (../shared/docs/devices.md, from libnifalcon's documented
/// behaviour): USB identity of its FTDI chip, the set-up control transfers, the 16-byte
/// command / status packets and the reassembly of status packets from the bulk-IN stream.
/// Pure encoders and decoders: no I/O, no allocation.

#include <array>
#include <cstddef>
#include <cstdint>

namespace vh::devices::falcon {

// ---- USB identity and endpoints ----------------------------------------------------------------

inline constexpr std::uint16_t kVendorId = 0x0403;   ///< FTDI.
inline constexpr std::uint16_t kProductId = 0xCB48;  ///< Novint Falcon.
inline constexpr std::uint8_t kEndpointOut = 0x02;   ///< Bulk OUT.
inline constexpr std::uint8_t kEndpointIn = 0x81;    ///< Bulk IN.
inline constexpr std::size_t kUsbPacketBytes = 64;   ///< Bulk IN read size; one USB packet.
inline constexpr std::size_t kFtdiStatusBytes = 2;   ///< Modem status bytes leading every IN packet.
inline constexpr std::uint8_t kControlRequestType = 0x40;  ///< Vendor, host to device.
inline constexpr std::size_t kFirmwareBlockBytes = 62;     ///< Largest firmware block per write.

// ---- Set-up control transfers (FTDI requests) ----------------------------------------------------

/// One FTDI control transfer: request type 0x40, `request`, `value`, index 0, no data.
struct ControlStep {
  std::uint8_t request;
  std::uint16_t value;
  const char* what;  ///< For messages.
};

/// FTDI request numbers.
inline constexpr std::uint8_t kRequestReset = 0;         ///< value 1: purge RX, 2: purge TX.
inline constexpr std::uint8_t kRequestModemControl = 1;  ///< RTS / DTR.
inline constexpr std::uint8_t kRequestFlowControl = 2;
inline constexpr std::uint8_t kRequestBaudRate = 3;      ///< value: baud divisor.
inline constexpr std::uint8_t kRequestLineProperty = 4;  ///< value 8: 8N1.
inline constexpr std::uint8_t kRequestLatencyTimer = 9;  ///< value: latency [ms].

/// Steps 1-3 before the firmware check: purge, 16 ms latency, 9600 baud, 8N1, no flow control,
/// RTS low, DTR low then high.
inline constexpr std::array<ControlStep, 9> kBootloaderSetup{{
    {kRequestReset, 1, "purge RX"},
    {kRequestReset, 2, "purge TX"},
    {kRequestLatencyTimer, 16, "latency timer 16 ms"},
    {kRequestBaudRate, 0x4138, "9600 baud"},
    {kRequestLineProperty, 8, "8N1"},
    {kRequestFlowControl, 0, "no flow control"},
    {kRequestModemControl, 0x0200, "RTS low"},
    {kRequestModemControl, 0x0100, "DTR low"},
    {kRequestModemControl, 0x0101, "DTR high"},
}};
/// Step 5, before the loader's echo check: DTR low, baud divisor 0x15.
inline constexpr std::array<ControlStep, 2> kLoaderSetup{{
    {kRequestModemControl, 0x0100, "DTR low"},
    {kRequestBaudRate, 0x0015, "baud divisor 0x15"},
}};
/// Step 7, after the upload (and when opening a Falcon that runs its firmware): 1 ms latency,
/// baud divisor 2, purge.
inline constexpr std::array<ControlStep, 4> kNormalModeSetup{{
    {kRequestLatencyTimer, 1, "latency timer 1 ms"},
    {kRequestBaudRate, 0x0002, "baud divisor 0x0002"},
    {kRequestReset, 1, "purge RX"},
    {kRequestReset, 2, "purge TX"},
}};

/// Step 4: sent to the boot loader ...
inline constexpr std::array<std::uint8_t, 3> kBootCheckRequest{0x0A, 0x43, 0x0D};
/// ... which answers this (on Linux only part of it may come back).
inline constexpr std::array<std::uint8_t, 4> kBootCheckReply{0x0A, 0x44, 0x2C, 0x0D};
/// Step 5: sent to the loader, echoed back.
inline constexpr std::uint8_t kLoaderCheckByte = 0x41;
/// Step 4 retries.
inline constexpr int kBootCheckAttempts = 100;

/// True when `data` (FTDI status bytes stripped) is an acceptable answer to kBootCheckRequest:
/// at least two bytes that match the start of kBootCheckReply.
bool isBootCheckReply(const std::uint8_t* data, std::size_t size) noexcept;

// ---- Packets -------------------------------------------------------------------------------------

inline constexpr std::size_t kPacketBytes = 16;  ///< '<' + 14 payload bytes + '>'.
inline constexpr std::uint8_t kPacketStart = 0x3C;  ///< '<'
inline constexpr std::uint8_t kPacketEnd = 0x3E;    ///< '>'
inline constexpr std::uint8_t kNibbleOffset = 0x41; ///< Every payload nibble is sent + 0x41.

using Packet = std::array<std::uint8_t, kPacketBytes>;

/// LEDs and homing flags of a command (outgoing byte 13).
inline constexpr std::uint8_t kLedGreen = 0x2;
inline constexpr std::uint8_t kLedBlue = 0x4;
inline constexpr std::uint8_t kLedRed = 0x8;
inline constexpr std::uint8_t kHomingMode = 0x1;

/// What the host sends every I/O cycle.
struct Command {
  std::array<std::int16_t, 3> motor{0, 0, 0};  ///< Motor commands (falcon::motorCommands()).
  std::uint8_t flags = 0;                      ///< kLed* | kHomingMode.
};

/// What the Falcon answers.
struct Status {
  std::array<std::int16_t, 3> encoder{0, 0, 0};  ///< Motor encoder counts.
  std::uint8_t homed_mask = 0;  ///< Bit i: motor i homed.
  std::uint8_t buttons = 0;     ///< Grip buttons (bit mask, 4 bits).
  bool allHomed() const noexcept { return (homed_mask & 0x7) == 0x7; }
};

/// A 16-bit word as 4 nibbles, least significant first, each + 0x41
/// (0x1234 -> 45 44 43 42).
void encodeWord(std::int16_t value, std::uint8_t* out4) noexcept;
/// The inverse of encodeWord(). @return false when a byte is not 0x41..0x50.
bool decodeWord(const std::uint8_t* in4, std::int16_t& value) noexcept;

/// The 16-byte command packet: '<', three motor words, flags + 0x41, 0x41, '>'.
/// Zero force with LEDs off is 3C, fourteen 41, 3E.
Packet encodeCommand(const Command& command) noexcept;
/// Decodes a 16-byte status packet. @return false for bad framing or nibbles (status untouched).
bool decodeStatus(const std::uint8_t* packet16, Status& status) noexcept;
/// Encodes a status packet as the Falcon would send it (for fakes and tests).
Packet encodeStatus(const Status& status) noexcept;

/// Copies the serial bytes of a bulk-IN transfer to `out`, dropping the 2 FTDI status bytes at
/// the start of every 64-byte USB packet. `out` must hold `size` bytes. @return bytes written.
std::size_t stripFtdiStatus(const std::uint8_t* in, std::size_t size, std::uint8_t* out) noexcept;

/// Reassembles status packets from the serial byte stream (bytes may arrive split or with junk
/// in between). Fixed storage, no allocation.
class PacketParser {
 public:
  /// Appends serial bytes (FTDI status already stripped).
  void feed(const std::uint8_t* data, std::size_t size) noexcept;
  /// The next complete, valid packet, oldest first. @return false when none is buffered.
  bool next(Status& status) noexcept;
  /// Drops everything buffered.
  void clear() noexcept { size_ = 0; }
  /// Bytes skipped because they could not start or complete a valid packet.
  std::uint64_t discardedBytes() const noexcept { return discarded_; }

 private:
  static constexpr std::size_t kCapacity = 4 * kUsbPacketBytes;
  std::array<std::uint8_t, kCapacity> buffer_{};
  std::size_t size_ = 0;
  std::uint64_t discarded_ = 0;
};

}  // namespace vh::devices::falcon
