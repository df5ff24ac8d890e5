// Fuzz target: a `.vhrec` recording through vh::runtime::readRecording, then its metadata
// through vh::runtime::sceneFromSessionMetadata (what File > Open Recording does before the
// replay).
// Input: byte 0 is a mode; the rest is the file. Mode bit 0 set: before writing the file, every
// CRC-32 (metadata, record chunks, event chunks, end marker) whose extent fits in the file is
// recomputed, so the fuzzer reaches the chunk contents instead of stopping at a checksum
// mismatch; clear: the bytes are written as they are (damaged checksums are fuzzed too).
// Expected: a Recording (with warnings for damaged chunks or a damaged tail) or
// std::runtime_error. Anything else is a finding.
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <stdexcept>
#include <vector>

#include "fuzz_support.h"
#include "vh/runtime/recording.h"
#include "vh/runtime/session_metadata.h"

namespace {

// The layout of recording.h's format (versions 1 to 3).
constexpr std::size_t kFileHeaderBytes = 24;  // magic[8] version record_size meta_size meta_crc
constexpr std::size_t kChunkHeaderBytes = 16;  // "CHNK" count dropped(u64), records, crc
constexpr std::size_t kEventHeaderBytes = 12;  // "EVNT" count payload_bytes, payload, crc
constexpr std::size_t kEndBodyBytes = 24;      // "ENDR" status records(u64) dropped(u64), crc

std::uint32_t getU32(const std::uint8_t* p) {
  return std::uint32_t{p[0]} | std::uint32_t{p[1]} << 8 | std::uint32_t{p[2]} << 16 | std::uint32_t{p[3]} << 24;
}
void putU32(std::uint8_t* p, std::uint32_t v) {
  for (int i = 0; i < 4; ++i) p[i] = static_cast<std::uint8_t>(v >> (8 * i));
}

/// Recomputes the CRCs of the header and of each chunk while their extents fit.
void fixChecksums(std::vector<std::uint8_t>& f) {
  const std::size_t size = f.size();
  if (size < kFileHeaderBytes) return;
  const std::size_t meta = getU32(f.data() + 16);
  if (meta > size - kFileHeaderBytes) return;
  putU32(f.data() + 20, vh::runtime::crc32(f.data() + kFileHeaderBytes, meta));
  const std::size_t record_bytes = sizeof(vh::runtime::TickRecord);
  std::size_t at = kFileHeaderBytes + meta;
  while (at < size) {
    std::uint8_t* c = f.data() + at;
    const std::size_t left = size - at;
    std::size_t body = 0;
    if (left >= kEventHeaderBytes && std::memcmp(c, "EVNT", 4) == 0) {
      body = kEventHeaderBytes + std::size_t{getU32(c + 8)};
    } else if (left >= kEndBodyBytes && std::memcmp(c, "ENDR", 4) == 0) {
      body = kEndBodyBytes;
    } else if (left >= kChunkHeaderBytes && std::memcmp(c, "CHNK", 4) == 0) {
      body = kChunkHeaderBytes + std::size_t{getU32(c + 4)} * record_bytes;
    } else {
      return;
    }
    if (body + 4 > left) return;
    putU32(c + body, vh::runtime::crc32(c, body));
    at += body + 4;
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  std::vector<std::uint8_t> file(data + 1, data + size);
  if ((data[0] & 1) != 0) fixChecksums(file);
  const auto path = vh::fuzz::freshDir("vhrec") / "in.vhrec";
  vh::fuzz::writeFile(path, file.data(), file.size());
  try {
    const vh::runtime::Recording rec = vh::runtime::readRecording(path);
    try {
      const vh::runtime::SceneSpec spec = vh::runtime::sceneFromSessionMetadata(rec.metadata_json);
      (void)spec;
    } catch (const std::runtime_error& e) {
      vh::fuzz::expected(e);
    }
  } catch (const std::runtime_error& e) {
    vh::fuzz::expected(e);
  }
  return 0;
}
