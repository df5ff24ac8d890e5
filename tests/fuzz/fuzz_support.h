#pragma once
/// @file
/// What the fuzz targets share: a private temporary folder for readers that need a path, and
/// a quiet VTK. Not part of any library; linked into each target.

#include <cstddef>
#include <cstdint>
#include <exception>
#include <filesystem>
#include <string>

#if VH_FUZZ_WITH_VTK
#include "vh/io/volume_loader.h"
#endif

namespace vh::fuzz {

/// This process's own temporary folder: /dev/shm/vh-fuzz-PID (in memory) when /dev/shm is
/// there, else $TMPDIR (or /tmp)/vh-fuzz-PID. Created on first use, removed at exit.
const std::filesystem::path& tempDir();

/// An empty sub-folder `name` of tempDir() (emptied when it exists), so each input sees only
/// the files it wrote (a reader that scans a folder, or follows a name in a header, must not
/// find a previous input's files: the runs stay deterministic).
std::filesystem::path freshDir(const std::string& name);

/// Writes `size` bytes to `path` (replacing the file). @throws std::runtime_error when it cannot.
void writeFile(const std::filesystem::path& path, const std::uint8_t* data, std::size_t size);

/// An input was rejected as the reader documents (`e` is its exception): prints e.what() to
/// stderr when the environment variable VH_FUZZ_VERBOSE is set (to see what a seed or a crash
/// input does), else nothing.
void expected(const std::exception& e);

/// Keeps VTK's logger off stderr (the readers' own errors are captured by vh::io and thrown as
/// LoadError; what VTK logs besides is noise at thousands of runs per second).
void quietVtk();

#if VH_FUZZ_WITH_VTK
/// The scan the segmentation targets place a SEG or RT Structure Set on: 16 x 16 x 4 int16
/// voxels (all 0) of 1 mm, voxel (0, 0, 0) at the origin, axes along L, P, S, without DICOM UIDs
/// (so matched by position only), the grid of the seeds make_corpus.py writes.
vh::io::LoadedVolume smallScan();
#endif

}  // namespace vh::fuzz
