// Fuzz target: NRRD header and voxels through vh::io::loadVolume, and the same file as a segmentation (loadSegmentation).
// Input: a whole attached .nrrd file, or, when the input holds the line "#VHDATA#" (kSplit), a
// detached header (the bytes before it, written as in.nhdr) and its data file (the bytes after
// it, written as in.raw; the header names it with `data file: in.raw`).
// Expected: a volume or vh::io::LoadError. Anything else is a finding.
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "fuzz_support.h"
#include "vh/io/segmentation.h"
#include "vh/io/volume_loader.h"

namespace {
constexpr std::string_view kSplit = "\n#VHDATA#\n";
}

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  vh::fuzz::quietVtk();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const auto dir = vh::fuzz::freshDir("nrrd");
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  const std::size_t split = text.find(kSplit);
  std::filesystem::path path;
  if (split == std::string_view::npos) {
    path = dir / "in.nrrd";
    vh::fuzz::writeFile(path, data, size);
  } else {
    path = dir / "in.nhdr";
    vh::fuzz::writeFile(path, data, split + 1);  // the header keeps its last line end
    const std::size_t rest = split + kSplit.size();
    vh::fuzz::writeFile(dir / "in.raw", data + rest, size - rest);
  }
  try {
    const vh::io::LoadedVolume v = vh::io::loadVolume(path);
    (void)v;
  } catch (const vh::io::LoadError& e) {
    vh::fuzz::expected(e);
  }
  // The same file as a segmentation: the header's key/value pairs, the layers of a
  // 4-D layered .seg.nrrd, the labels.
  try {
    const vh::io::LoadedSegmentation s = vh::io::loadSegmentation(path);
    (void)s;
  } catch (const vh::io::LoadError& e) {
    vh::fuzz::expected(e);
  }
  return 0;
}
