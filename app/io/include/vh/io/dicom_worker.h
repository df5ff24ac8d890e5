#pragma once
/// @file
/// The DICOM worker process (issue 15: no input crashes the application). loadVolume() reads
/// DICOM series in `volume-haptics-dicom-worker`, a small program built beside
/// `volume-haptics`, and takes the voxels back through a temporary file; a crash of vtk-dicom's
/// parser on a damaged file ends the worker, and the load fails with a LoadError that names the
/// file ("the DICOM reader crashed (SIGSEGV) on .../CT0042.dcm: a damaged file; nothing was
/// loaded"). What was open stays open; a recording in progress is untouched.

#include <filesystem>

namespace vh::io {

/// The worker program: $VH_DICOM_WORKER if set, else `volume-haptics-dicom-worker` beside the
/// running executable, else the build tree's or the installed one; empty when none exists.
std::filesystem::path dicomWorkerPath();

/// The worker's main(): `load PATH OUT [--series S] [--phase N]` reads PATH in this process and
/// writes the voxels and geometry to OUT, printing "progress F" lines and "error MESSAGE" on a
/// LoadError (exit status 1); `list FOLDER OUT` writes listDicomSeries() as JSON, printing
/// "progress DONE TOTAL" lines; `mesh PATH OUT SCALE` reads a tool mesh (VTK's mesh readers
/// crash on some damaged files too) and writes its vertices and triangles; `probe PATH` parses each file of PATH alone, printing
/// "file NAME" before and "ok" after each (a crash names the file).
/// @return the process exit status.
int runDicomWorker(int argc, char** argv);

}  // namespace vh::io
