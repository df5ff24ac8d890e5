#pragma once
/// @file
/// The link's parsing of what a client sends (igtl_link.cpp), apart from its sockets: the
/// OpenIGTLink message header and an IMAGE message's body. Private to vh::igtl; apart so that the
/// fuzz target (tests/fuzz/fuzz_igtl.cpp) can feed it bytes that no client sent.
///
/// Wire format (OpenIGTLink protocol, all integers big-endian): a 58-byte header (version 2
/// bytes, type 12 and device name 20 characters, NUL-padded, time stamp 8, body size 8, CRC-64
/// of the body 8), then the body. Header version 2 (protocol 3) bodies start with a 12-byte
/// extended header and end with metadata.

#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "vh/io/volume_loader.h"

namespace vh::igtl::detail {

/// Bytes of an OpenIGTLink message header (IGTL_HEADER_SIZE).
inline constexpr std::size_t kHeaderSize = 58;

using HeaderBytes = std::array<unsigned char, kHeaderSize>;

/// A message header's fields as sent (strings unescaped, up to their first NUL).
struct MessageHeaderFields {
  std::uint16_t version = 0;   ///< Header version: 1, or 2 (protocol 3, extended header).
  std::string type;            ///< Message type ("IMAGE", "TRANSFORM", ...), at most 12 characters.
  std::string device_name;     ///< Device name, at most 20 characters.
  std::uint64_t timestamp = 0; ///< Seconds (high 32 bits) and fraction of a second (low 32 bits).
  std::uint64_t body_size = 0; ///< Bytes of the body that follows [bytes].
  std::uint64_t crc = 0;       ///< CRC-64 (ECMA-182) of the body.
};

/// The fields of a message header. Never throws but std::bad_alloc; checks nothing.
MessageHeaderFields parseMessageHeader(const HeaderBytes& header);

/// An IMAGE message (its header and whole body, `body` header.body_size bytes as the link
/// receives it) as a volume in W (patient LPS, metres): scalar, whole volumes, at least 2 voxels
/// along every axis, any scalar type and byte order, RAS or LPS, header version 1 or 2 (see
/// igtl_link.h). The volume's name is the device name, control bytes escaped.
/// @throws std::invalid_argument saying why the message is refused (CRC mismatch, sizes that
///         disagree, unknown version, scalar type or byte order, several components, a
///         sub-volume, a spacing outside kMinImageSpacing_mm..kMaxImageSpacing_mm, a zero,
///         non-finite or sheared axis); std::bad_alloc.
io::LoadedVolume decodeImageMessage(const HeaderBytes& header, const std::vector<unsigned char>& body);
/// The voxel spacings an IMAGE may give [mm]: 1 um (the scan readers' smallest voxel side) to
/// 10 m (no scan's voxel is larger); outside, decodeImageMessage() refuses it with the value.
inline constexpr double kMinImageSpacing_mm = 1e-3;
/// The slowest a message may arrive once begun, after LinkOptions::partial_timeout_s [bytes/s]:
/// a 150 MB CT over a slow network still arrives; a client sending a byte every few seconds
/// (each within the idle timeout) is cut off.
inline constexpr double kMinReceiveBytesPerSecond = 1e6;
inline constexpr double kMaxImageSpacing_mm = 1e4;

}  // namespace vh::igtl::detail
