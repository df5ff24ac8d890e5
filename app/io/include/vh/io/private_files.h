#pragma once
/// @file
/// Files and folders only their owner can read, whatever the umask: recordings, exports,
/// reports, drilled volumes and the PACS cache carry patient data (docs/scans.md says which
/// carry identifiers), so they are created 0600 (files) and 0700 (folders), never 0644 / 0755.
///
/// Whole-file outputs (exports, reports, volumes) go through PrivateOutput: written to a
/// temporary file beside the target (same folder, so the final rename is atomic) and renamed
/// over the target only when complete; a failure (full disk, an exception while writing) removes
/// the temporary file and leaves the target as it was, never a partial file. Streams that must
/// keep what was written when the program dies (a recording) use openPrivateFile() instead.
///
/// In vh::io (not vh::runtime) because io's own writers (the PACS cache, the NRRD writer) use it
/// and runtime sits above io.

#include <filesystem>
#include <fstream>
#include <string>

namespace vh::io {

/// Permissions of patient files and folders.
inline constexpr std::filesystem::perms kPrivateFilePerms =
    std::filesystem::perms::owner_read | std::filesystem::perms::owner_write;  // 0600
inline constexpr std::filesystem::perms kPrivateDirPerms = std::filesystem::perms::owner_all;  // 0700

/// Creates `dir` and its missing parents with mode 0700 (folders that exist are left as they
/// are). @throws std::runtime_error naming the folder and the system's reason.
void createPrivateDirectories(const std::filesystem::path& dir);

/// Opens `path` for writing (created or truncated) with mode 0600, also when it existed with
/// wider permissions (fchmod). @return the descriptor (O_CLOEXEC), owned by the caller.
/// @throws std::runtime_error naming the file and the system's reason.
int openPrivateFile(const std::filesystem::path& path, bool append = false);

/// Creates `path` empty (or truncates it) with mode 0600, for a stream opened on it next (a
/// std::ofstream keeps the mode). @throws std::runtime_error as openPrivateFile().
void createPrivateFile(const std::filesystem::path& path);

/// Sets `path` to 0600 (for files a library created itself). @throws std::runtime_error.
void makePrivate(const std::filesystem::path& path);

/// A whole-file output written beside its target and renamed into place by commit().
class PrivateOutput {
 public:
  /// Creates the temporary file ".NAME.XXXXXX.EXT" (0600) in the target's folder; the folder
  /// must exist. @throws std::runtime_error naming the target when it cannot be created.
  explicit PrivateOutput(std::filesystem::path target);
  ~PrivateOutput();  ///< Removes the temporary file unless committed.
  PrivateOutput(const PrivateOutput&) = delete;
  PrivateOutput& operator=(const PrivateOutput&) = delete;

  /// A stream on the temporary file (binary; opened on first use). Not for use with tempPath().
  std::ofstream& stream();
  /// The temporary file's path (same extension as the target), for writers that open the file
  /// themselves (VTK writers, encoders); made 0600 again at commit().
  const std::filesystem::path& tempPath() const noexcept { return temp_; }
  const std::filesystem::path& target() const noexcept { return target_; }

  /// Flushes and closes the stream, checks it, makes the file 0600 and renames it over the
  /// target. @throws std::runtime_error "cannot write TARGET: <reason>" (the temporary file is
  /// removed, the target untouched).
  void commit();

 private:
  std::filesystem::path target_;
  std::filesystem::path temp_;
  std::ofstream stream_;
  bool committed_ = false;
};

}  // namespace vh::io
