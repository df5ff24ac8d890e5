#include "vh/devices/falcon_protocol.h"

#include <algorithm>
#include <cstring>

namespace vh::devices::falcon {

bool isBootCheckReply(const std::uint8_t* data, std::size_t size) noexcept {
  if (data == nullptr || size < 2) return false;
  const std::size_t n = std::min(size, kBootCheckReply.size());
  return std::equal(data, data + n, kBootCheckReply.begin());
}

void encodeWord(std::int16_t value, std::uint8_t* out4) noexcept {
  const auto bits = static_cast<std::uint16_t>(value);
  for (int i = 0; i < 4; ++i) {
    out4[i] = static_cast<std::uint8_t>(((bits >> (4 * i)) & 0xF) + kNibbleOffset);
  }
}

bool decodeWord(const std::uint8_t* in4, std::int16_t& value) noexcept {
  std::uint16_t bits = 0;
  for (int i = 0; i < 4; ++i) {
    if (in4[i] < kNibbleOffset || in4[i] > kNibbleOffset + 0xF) return false;
    bits = static_cast<std::uint16_t>(bits | ((in4[i] - kNibbleOffset) << (4 * i)));
  }
  value = static_cast<std::int16_t>(bits);
  return true;
}

Packet encodeCommand(const Command& command) noexcept {
  Packet p{};
  p.fill(kNibbleOffset);
  p[0] = kPacketStart;
  for (std::size_t i = 0; i < 3; ++i) encodeWord(command.motor[i], &p[1 + 4 * i]);
  p[13] = static_cast<std::uint8_t>((command.flags & 0xF) + kNibbleOffset);
  p[14] = kNibbleOffset;
  p[15] = kPacketEnd;
  return p;
}

bool decodeStatus(const std::uint8_t* packet16, Status& status) noexcept {
  if (packet16 == nullptr || packet16[0] != kPacketStart || packet16[15] != kPacketEnd) return false;
  Status out;
  for (std::size_t i = 0; i < 3; ++i) {
    if (!decodeWord(&packet16[1 + 4 * i], out.encoder[i])) return false;
  }
  if (packet16[13] < kNibbleOffset) return false;
  const auto b = static_cast<std::uint8_t>(packet16[13] - kNibbleOffset);
  out.homed_mask = static_cast<std::uint8_t>((b >> 4) & 0x7);
  out.buttons = static_cast<std::uint8_t>(b & 0xF);
  status = out;
  return true;
}

Packet encodeStatus(const Status& status) noexcept {
  Packet p{};
  p.fill(kNibbleOffset);
  p[0] = kPacketStart;
  for (std::size_t i = 0; i < 3; ++i) encodeWord(status.encoder[i], &p[1 + 4 * i]);
  p[13] = static_cast<std::uint8_t>((((status.homed_mask & 0x7) << 4) | (status.buttons & 0xF)) + kNibbleOffset);
  p[15] = kPacketEnd;
  return p;
}

std::size_t stripFtdiStatus(const std::uint8_t* in, std::size_t size, std::uint8_t* out) noexcept {
  std::size_t written = 0;
  for (std::size_t start = 0; start < size; start += kUsbPacketBytes) {
    const std::size_t end = std::min(size, start + kUsbPacketBytes);
    if (end - start <= kFtdiStatusBytes) continue;
    const std::size_t n = end - start - kFtdiStatusBytes;
    std::memcpy(out + written, in + start + kFtdiStatusBytes, n);
    written += n;
  }
  return written;
}

void PacketParser::feed(const std::uint8_t* data, std::size_t size) noexcept {
  while (size > 0) {
    if (size_ == kCapacity) {
      // Full without a packet found: keep the newest half.
      const std::size_t drop = kCapacity / 2;
      std::memmove(buffer_.data(), buffer_.data() + drop, size_ - drop);
      size_ -= drop;
      discarded_ += drop;
    }
    const std::size_t n = std::min(size, kCapacity - size_);
    std::memcpy(buffer_.data() + size_, data, n);
    size_ += n;
    data += n;
    size -= n;
  }
}

bool PacketParser::next(Status& status) noexcept {
  std::size_t start = 0;
  bool found = false;
  while (start < size_) {
    if (buffer_[start] != kPacketStart) {
      ++start;
      ++discarded_;
      continue;
    }
    if (size_ - start < kPacketBytes) break;  // incomplete: wait for more bytes
    if (decodeStatus(&buffer_[start], status)) {
      start += kPacketBytes;
      found = true;
      break;
    }
    ++start;  // a '<' that does not start a valid packet
    ++discarded_;
  }
  std::memmove(buffer_.data(), buffer_.data() + start, size_ - start);
  size_ -= start;
  return found;
}

}  // namespace vh::devices::falcon
