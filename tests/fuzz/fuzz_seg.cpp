// Fuzz target: one DICOM SEG file through vh::io::loadDicomSegmentation in this process
// (DicomIsolation::kInProcess: DCMTK's DcmFileFormat and dcmseg, the project's checks of the
// dataset, segments and frames, then the placement of the frames on a grid). The application
// reads a SEG in the reader process, where a crash would end that process, not show here.
// Input: byte 0 is a mode; the rest is the file (the 128-byte preamble, "DICM", ...). Mode bit 0
// clear: the SEG on its own grid (no scan); set: on a small scan without DICOM UIDs (16 x 16 x 4
// voxels of 1 mm from the origin, axes along LPS: the seeds' grid), matched by position.
// Expected: a segmentation or vh::io::LoadError. Anything else is a finding. DCMTK 3.6.7 is
// not instrumented: a memory error inside it shows as a SIGSEGV (or not at all). Leaks inside
// dcmseg, dcmfg and dcmiod are not findings (LeakSanitizer suppressions below): DCMTK 3.6.7's
// DcmSegmentation keeps the segments and functional groups it read when a later step fails
// ("Invalid Pixel Data") and its destructor does not free them; the application reads a SEG in
// the reader process, which exits after each file.
#include <cstddef>
#include <cstdint>

#include "fuzz_support.h"
#include "vh/io/dicom_seg.h"

extern "C" const char* __lsan_default_suppressions() {
  return "leak:libdcmseg.so\nleak:libdcmfg.so\nleak:libdcmiod.so\n";
}

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  vh::fuzz::quietVtk();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 1) return 0;
  static const vh::io::LoadedVolume scan = vh::fuzz::smallScan();
  const auto dir = vh::fuzz::freshDir("seg");
  const auto path = dir / "seg.dcm";
  vh::fuzz::writeFile(path, data + 1, size - 1);
  vh::io::VolumeLoadOptions options;
  options.dicom_isolation = vh::io::DicomIsolation::kInProcess;
  try {
    const vh::io::LoadedSegmentation s =
        vh::io::loadDicomSegmentation(path, (data[0] & 1) != 0 ? &scan : nullptr, options);
    (void)s;
  } catch (const vh::io::LoadError& e) {
    vh::fuzz::expected(e);
  }
  return 0;
}
