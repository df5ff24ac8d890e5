// Fuzz target: a MetaImage .mha (header and attached voxels, ElementDataFile = LOCAL) through
// vh::io::loadVolume. Expected: a volume or vh::io::LoadError. Anything else is a finding.
#include <cstddef>
#include <cstdint>

#include "fuzz_support.h"
#include "vh/io/volume_loader.h"

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  vh::fuzz::quietVtk();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const auto path = vh::fuzz::freshDir("mha") / "in.mha";
  vh::fuzz::writeFile(path, data, size);
  try {
    const vh::io::LoadedVolume v = vh::io::loadVolume(path);
    (void)v;
  } catch (const vh::io::LoadError& e) {
    vh::fuzz::expected(e);
  }
  return 0;
}
