// Fuzz target: a C-FIND response identifier, as a PACS would send it, through what the PACS
// client makes of it (app/io/src/pacs_internal.h): the study record (STUDY level) and the
// series record (SERIES level), then the patients' tree (vh::io::pacsPatientsOf). The dataset is
// parsed by DCMTK (DcmDataset::loadFile, in the transfer syntax the mode byte picks), with no
// association: the DIMSE exchange itself is DCMTK's (DcmSCU), not the project's.
// Read from a file, not from a DcmInputBufferStream as dcmnet reads a received dataset: from a
// buffer stream DCMTK allocates each value's declared length before reading it (up to 4 GiB from
// a 150-byte input, each taking a second under ASan), so the fuzzer would spend its time in
// DCMTK's allocator; from a file it checks the length against the file first. That allocation is
// DCMTK's (docs/developing.md, "Fuzzing": open).
// Input: byte 0 picks the transfer syntax (bits 0-1: implicit VR little endian, explicit VR
// little endian, explicit VR big endian, deflated explicit VR little endian); the rest is the
// dataset, without preamble or meta header.
// Expected: records (empty fields for what is missing) or nothing when DCMTK refuses the bytes;
// no exception. Anything else is a finding. DCMTK 3.6.7 is not instrumented.
#include <cstddef>
#include <cstdint>
#include <vector>

#include <dcmtk/config/osconfig.h>  // DCMTK's configuration first
#include <dcmtk/dcmdata/dcdatset.h>
#include <dcmtk/dcmdata/dcxfer.h>
#include <dcmtk/oflog/oflog.h>

#include "fuzz_support.h"
#include "pacs_internal.h"

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  OFLog::configure(OFLogger::OFF_LOG_LEVEL);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 1) return 0;
  static const E_TransferSyntax kSyntax[] = {EXS_LittleEndianImplicit, EXS_LittleEndianExplicit, EXS_BigEndianExplicit,
                                             EXS_DeflatedLittleEndianExplicit};
  const E_TransferSyntax xfer = kSyntax[data[0] & 3];
  const auto path = vh::fuzz::freshDir("pacs_response") / "identifier";
  vh::fuzz::writeFile(path, data + 1, size - 1);
  DcmDataset dataset;
  const OFCondition read = dataset.loadFile(path.c_str(), xfer, EGL_noChange, DCM_MaxReadLength);
  if (read.bad()) return 0;  // dcmnet drops a response whose identifier does not parse
  std::vector<vh::io::PacsStudy> studies{vh::io::detail::studyFromResponse(&dataset)};
  const vh::io::PacsSeries series = vh::io::detail::seriesFromResponse(&dataset);
  (void)series;
  const std::vector<vh::io::PacsPatient> patients = vh::io::pacsPatientsOf(studies);
  (void)patients;
  return 0;
}
