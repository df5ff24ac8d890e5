// volume-haptics-dicom-worker: the reader process of volume-haptics. It reads scans (DICOM,
// NRRD, MetaImage) and tool meshes in a process of its own, so that a reader crash on a damaged
// file cannot end the application (see vh/io/reader_process.h).
#include "vh/io/reader_process.h"

int main(int argc, char** argv) { return vh::io::readerProcessMain(argc, argv); }
