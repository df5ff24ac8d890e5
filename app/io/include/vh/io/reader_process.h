#pragma once
/// @file
/// The reader process, so that no input file crashes the application. loadVolume() (DICOM,
/// NRRD, MetaImage), listDicomSeries(), loadMesh() and loadDicomSegmentation() read in `volume-haptics-dicom-worker` (the
/// program's historical name: it reads every format), a small program built beside
/// `volume-haptics`, and take the result back through a temporary file. A crash of a reader on
/// a damaged file (vtk-dicom's parser, VTK's NRRD, MetaImage, OBJ and PLY readers) ends the
/// reader process, and the load fails with a LoadError that names the file ("the DICOM reader
/// crashed (SIGSEGV) on .../CT0042.dcm: a damaged file; nothing was loaded"). What was open
/// stays open; a recording in progress is untouched.

#include <filesystem>
#include <vector>

namespace vh::io {

/// The reader program: $VH_DICOM_WORKER if set (empty when that file does not exist), else the
/// first of readerProcessCandidates() of the running executable's folder that exists; empty
/// when none exists.
std::filesystem::path readerProcessPath();

/// Where the reader program is looked for, in order, for an executable in `exe_dir`: beside it
/// (the build tree's build/app/), then the installed layout relative to it (bin/ ->
/// libexec/volume-haptics/, so an unpacked or relocated package finds its own reader), then the
/// build tree's reader program (tests whose executables live elsewhere in the build tree).
/// An empty `exe_dir` gives the build tree's program only.
std::vector<std::filesystem::path> readerProcessCandidates(const std::filesystem::path& exe_dir);

/// The reader program's main(), one mode per call:
///  - `load PATH OUT [--series S] [--phase N]`: reads a DICOM file, folder or DICOMDIR in this
///    process and writes the voxels and geometry to OUT, printing "progress F" lines (F in 0..1);
///  - `volume FILE OUT [--layer N]`: reads a NRRD or MetaImage file (any loadVolume() input) and
///    writes the converted field to OUT;
///  - `list FOLDER OUT`: writes listDicomSeries() as JSON, printing "progress DONE TOTAL" lines;
///  - `mesh PATH OUT SCALE`: reads a tool mesh (VTK's mesh readers crash on some damaged files
///    too) and writes its vertices [m] and triangles;
///  - `seg FILE OUT`: reads a DICOM SEG with DCMTK (dicom_seg.h) and writes its segments and
///    each frame's plane and inside pixels;
///  - `probe PATH`: parses each DICOM file of PATH alone, printing "file NAME" before and "ok"
///    after each (a crash names the file);
///  - `pacs OP REQUEST OUT`: the DICOM network process, one PACS operation of vh/io/pacs.h
///    (echo, find-studies, find-series, find-series-by-uid, retrieve), so that a server's answer
///    that crashes DCMTK's parser ends this process, not the application.
/// A LoadError (any exception) prints "error MESSAGE" and exits with status 1.
/// @return the process exit status: 0 done, 1 a read error, 2 a usage error.
int readerProcessMain(int argc, char** argv);

}  // namespace vh::io
