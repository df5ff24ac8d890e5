// Fuzz target: one RT Structure Set file through vh::io::loadDicomRtStruct in this process
// (DicomIsolation::kInProcess: DCMTK's DcmFileFormat and dcmrt's DRTStructureSetIOD, the
// project's reading of ROIs and contours, then the rasterisation of the closed contours on a
// scan). The application reads a structure set in the reader process, where a crash would end
// that process, not show here.
// Input: the whole file. The scan is a small one without DICOM UIDs (16 x 16 x 4 voxels of 1 mm
// from the origin, axes along LPS: the seeds' grid), matched by position.
// Expected: a segmentation or vh::io::LoadError. Anything else is a finding. DCMTK 3.6.7 is
// not instrumented: a memory error inside it shows as a SIGSEGV (or not at all).
#include <cstddef>
#include <cstdint>

#include "fuzz_support.h"
#include "vh/io/dicom_rtstruct.h"

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  vh::fuzz::quietVtk();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const vh::io::LoadedVolume scan = vh::fuzz::smallScan();
  const auto dir = vh::fuzz::freshDir("rtstruct");
  const auto path = dir / "rtstruct.dcm";
  vh::fuzz::writeFile(path, data, size);
  vh::io::VolumeLoadOptions options;
  options.dicom_isolation = vh::io::DicomIsolation::kInProcess;
  try {
    const vh::io::LoadedSegmentation s = vh::io::loadDicomRtStruct(path, &scan, options);
    (void)s;
  } catch (const vh::io::LoadError& e) {
    vh::fuzz::expected(e);
  }
  return 0;
}
