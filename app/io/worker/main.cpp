// volume-haptics-dicom-worker: reads a DICOM series for volume-haptics in a process of its own,
// so that a parser crash on a damaged file cannot end the application (see vh/io/dicom_worker.h).
#include "vh/io/dicom_worker.h"

int main(int argc, char** argv) { return vh::io::runDicomWorker(argc, argv); }
