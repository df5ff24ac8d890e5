#pragma once
// Checks the readers make on what a header names before anything is opened or allocated: a
// detached data file stays beside its header, names a regular file (not a FIFO or device that
// would block or never end), and the declared voxels fit in memory.

#include <cstdint>
#include <filesystem>
#include <string>

namespace vh::io::detail {

/// Throws LoadError naming `header` unless `data_file` (absolute, or already joined to the
/// header's folder) lies in the header's folder or below it, once `..` and symbolic links are
/// resolved: a header cannot make the reader load /etc/shadow as voxels.
void requireBesideHeader(const std::filesystem::path& header, const std::filesystem::path& data_file);

/// Throws LoadError naming `named_by` unless `path` is a regular file (stat, which does not
/// open it: a FIFO would block the open, a device would never end).
void requireRegularFile(const std::filesystem::path& path, const std::filesystem::path& named_by);

/// Throws LoadError naming `path` when `bytes` of declared voxels do not fit the memory
/// available (io::fitsInMemory), with both sizes.
void requireDeclaredFits(const std::filesystem::path& path, std::uint64_t bytes);

}  // namespace vh::io::detail
