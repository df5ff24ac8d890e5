// Fuzz target: NIfTI-1 / NIfTI-2 header and voxels through vh::io::loadVolume in this process
// (DicomIsolation::kInProcess: the project's header checks, then vtkNIFTIImageReader), and the
// same file as a label-map segmentation (loadSegmentation).
// Input: a whole .nii file; one starting with the gzip magic (1f 8b) is written as in.nii.gz;
// one holding the line "#VHDATA#" (kSplit) is a pair: the bytes before it in.hdr, after it in.img.
// Expected: a volume or vh::io::LoadError. Anything else is a finding.
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
  const auto dir = vh::fuzz::freshDir("nifti");
  const std::string_view bytes(reinterpret_cast<const char*>(data), size);
  const std::size_t split = bytes.find(kSplit);
  std::filesystem::path path;
  if (split != std::string_view::npos) {
    path = dir / "in.hdr";
    vh::fuzz::writeFile(path, data, split);
    const std::size_t rest = split + kSplit.size();
    vh::fuzz::writeFile(dir / "in.img", data + rest, size - rest);
  } else {
    const bool gzip = size >= 2 && data[0] == 0x1f && data[1] == 0x8b;
    path = dir / (gzip ? "in.nii.gz" : "in.nii");
    vh::fuzz::writeFile(path, data, size);
  }
  vh::io::VolumeLoadOptions options;
  options.dicom_isolation = vh::io::DicomIsolation::kInProcess;
  try {
    const vh::io::LoadedVolume v = vh::io::loadVolume(path, options);
    (void)v;
  } catch (const vh::io::LoadError& e) {
    vh::fuzz::expected(e);
  }
  try {
    const vh::io::LoadedSegmentation s = vh::io::loadSegmentation(path, options);
    (void)s;
  } catch (const vh::io::LoadError& e) {
    vh::fuzz::expected(e);
  }
  return 0;
}
