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

/// Whether `target` names the standard output ("-", /dev/stdout, /dev/fd/1): PrivateOutput
/// writes such a target to std::cout, so a command printing its own summary sends that to
/// std::cerr instead.
bool namesStandardOutput(const std::filesystem::path& target);

/// A whole-file output written beside its target and renamed into place by commit().
///
/// Only a regular file (or a name not yet taken) is ever replaced. The target "-" and the
/// standard streams' names (/dev/stdout, /dev/stderr, /dev/fd/1, /dev/fd/2) write to the stream
/// itself; another existing target that is not a regular file (a FIFO, a character device such
/// as /dev/null) is written in place, as any program writing to it would (a failed write, such
/// as /dev/full's, is still an error); a symbolic link is refused (never followed: a link in a
/// shared folder could point a recording at any file the user may write), as is a folder.
class PrivateOutput {
 public:
  /// Creates the temporary file ".NAME.XXXXXX.EXT" (0600) in the target's folder; the folder
  /// must exist. A stream or another non-regular target: nothing is created, writes go to it.
  /// @throws std::runtime_error naming the target when it cannot be created, or when it is a
  ///         symbolic link or a folder (the message says so; nothing is touched).
  explicit PrivateOutput(std::filesystem::path target);
  ~PrivateOutput();  ///< Removes the temporary file unless committed.
  PrivateOutput(const PrivateOutput&) = delete;
  PrivateOutput& operator=(const PrivateOutput&) = delete;

  /// A stream on the temporary file (binary; opened on first use), or the standard output or
  /// error themselves for those targets (std::cout, std::cerr: written where the program's own
  /// messages go, at the same offset). Not for use with tempPath().
  std::ostream& stream();
  /// The temporary file's path (same extension as the target), for writers that open the file
  /// themselves (VTK writers, encoders); made 0600 again at commit().
  const std::filesystem::path& tempPath() const noexcept { return temp_; }
  const std::filesystem::path& target() const noexcept { return target_; }
  /// Whether writes go straight to the target (a stream or another non-regular file: tempPath()
  /// is then the target itself, /dev/stdout or /dev/stderr for the standard streams, opened
  /// anew by whoever writes to it by path; nothing is renamed).
  bool inPlace() const noexcept { return in_place_; }

  /// Flushes and closes the stream, checks it, makes the file 0600 and renames it over the
  /// target (in place: flushes and checks only). @throws std::runtime_error "cannot write TARGET:
  /// <reason>" (the temporary file is removed, the target untouched).
  void commit();

 private:
  std::filesystem::path target_;
  std::filesystem::path temp_;
  std::ofstream stream_;
  std::ostream* standard_ = nullptr;  // std::cout or std::cerr for those targets, else null
  bool committed_ = false;
  bool in_place_ = false;
};

}  // namespace vh::io
