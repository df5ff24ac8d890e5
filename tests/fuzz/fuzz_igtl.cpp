// Fuzz target: an OpenIGTLink message as a client sends it, through the link's parsing
// (app/igtl/src/igtl_message.h): the 58-byte header (parseMessageHeader), then the body as an
// IMAGE (decodeImageMessage: header version 1 or 2, the extended header, libOpenIGTLink's
// unpacking and CRC check, the image header's checks, the byte swap, the conversion to a
// volume). The sockets around it are not fuzzed.
// Input: byte 0 is a mode, then the 58-byte header (zeros where the input is shorter), then the
// body. Mode bit 0 set: the header's body size is set to the body's, as the link guarantees
// (it reads exactly that many bytes before parsing; a body of another size is not parsed); bit 1
// set: the header's CRC-64 is recomputed over the body (what both header versions check), so
// the fuzzer reaches the image header instead of stopping at a checksum mismatch.
// Expected: a volume or std::invalid_argument (the reason the link gives when it rejects the
// message). Anything else is a finding. libOpenIGTLink 1.11 is not instrumented.
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <stdexcept>
#include <vector>

#include <igtl_util.h>

#include "fuzz_support.h"
#include "igtl_message.h"

namespace {

void putBigEndian(unsigned char* p, std::uint64_t v) {
  for (int i = 7; i >= 0; --i) {
    p[i] = static_cast<unsigned char>(v & 0xff);
    v >>= 8;
  }
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  vh::fuzz::quietVtk();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using vh::igtl::detail::kHeaderSize;
  if (size < 1) return 0;
  const std::uint8_t mode = data[0];
  vh::igtl::detail::HeaderBytes header{};
  const std::size_t in_header = std::min(size - 1, kHeaderSize);
  std::memcpy(header.data(), data + 1, in_header);
  std::vector<unsigned char> body(data + 1 + in_header, data + size);
  if ((mode & 1) != 0) putBigEndian(header.data() + 42, body.size());
  if ((mode & 2) != 0) putBigEndian(header.data() + 50, crc64(body.data(), body.size(), 0ULL));
  const vh::igtl::detail::MessageHeaderFields fields = vh::igtl::detail::parseMessageHeader(header);
  if (fields.body_size != body.size()) return 0;  // the link never parses such a body
  try {
    const vh::io::LoadedVolume v = vh::igtl::detail::decodeImageMessage(header, body);
    (void)v;
  } catch (const std::invalid_argument& e) {
    vh::fuzz::expected(e);
  }
  return 0;
}
