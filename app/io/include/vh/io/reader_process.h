#pragma once
/// @file
/// The DICOM worker process, so that no input crashes the application. loadVolume() reads
/// DICOM series in `volume-haptics-dicom-worker`, a small program built beside
/// `volume-haptics`, and takes the voxels back through a temporary file; a crash of vtk-dicom's
/// parser on a damaged file ends the worker, and the load fails with a LoadError that names the
/// file ("the DICOM reader crashed (SIGSEGV) on .../CT0042.dcm: a damaged file; nothing was
/// loaded"). What was open stays open; a recording in progress is untouched.

#include <filesystem>
#include <vector>

namespace vh::io {

/// The worker program: $VH_DICOM_WORKER if set, else the first of dicomWorkerCandidates() of
/// the running executable's folder that exists; empty when none exists.
std::filesystem::path dicomWorkerPath();

/// Where the worker is looked for, in order, for an executable in `exe_dir`: beside it (the
/// build tree's build/app/), then the installed layout relative to it (bin/ ->
/// libexec/volume-haptics/, so an unpacked or relocated package finds its own worker), then the
/// build tree's worker (tests whose executables live elsewhere in the build tree).
std::vector<std::filesystem::path> dicomWorkerCandidates(const std::filesystem::path& exe_dir);

/// The worker's main(): `load PATH OUT [--series S] [--phase N]` reads PATH in this process and
/// writes the voxels and geometry to OUT, printing "progress F" lines and "error MESSAGE" on a
/// LoadError (exit status 1); `list FOLDER OUT` writes listDicomSeries() as JSON, printing
/// "progress DONE TOTAL" lines; `mesh PATH OUT SCALE` reads a tool mesh (VTK's mesh readers
/// crash on some damaged files too) and writes its vertices and triangles; `probe PATH` parses each file of PATH alone, printing
/// "file NAME" before and "ok" after each (a crash names the file).
/// @return the process exit status.
int runDicomWorker(int argc, char** argv);

}  // namespace vh::io
