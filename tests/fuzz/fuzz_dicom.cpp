// Fuzz target: one DICOM file through the project's DICOM loading (vh::io::loadVolume on a file
// alone in its folder: vtkDICOMDirectory's scan and vtkDICOMParser, the slice checks, the
// vtkDICOMReader read, regularisation and conversion), in this process
// (DicomIsolation::kInProcess: the application reads DICOM in a worker process, where a crash
// would end the worker, not show here).
// Expected: a volume or vh::io::LoadError. Anything else is a finding. vtk-dicom 0.8.14 is not
// instrumented: a memory error inside it shows as a SIGSEGV (or not at all), not as an ASan
// report.
#include <cstddef>
#include <cstdint>

#include "fuzz_support.h"
#include "vh/io/volume_loader.h"

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  vh::fuzz::quietVtk();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const auto dir = vh::fuzz::freshDir("dicom");
  const auto path = dir / "IM0001.dcm";
  vh::fuzz::writeFile(path, data, size);
  try {
    vh::io::VolumeLoadOptions options;
    options.dicom_isolation = vh::io::DicomIsolation::kInProcess;
    const vh::io::LoadedVolume v = vh::io::loadVolume(path, options);
    (void)v;
  } catch (const vh::io::LoadError& e) {
    vh::fuzz::expected(e);
  }
  return 0;
}
