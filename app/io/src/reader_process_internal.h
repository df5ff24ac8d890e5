#pragma once
/// @file
/// The application's side of the reader process (vh/io/reader_process.h): starting the reader
/// program, reading its stdout line protocol under a watchdog, killing it, and turning a crash
/// or a stall into a LoadError. Private to vh::io.
///
/// Line protocol (the reader's stdout, one message a line): "progress ..." while it reads,
/// "error MESSAGE" before exiting 1 on a LoadError; in `probe` mode "file NAME" before and "ok"
/// after each file parsed.

#include <sys/types.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <exception>
#include <iostream>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

namespace vh::io::detail {

namespace fs = std::filesystem;

/// File name of the reader program (historical: it reads every format, not only DICOM).
inline constexpr char kReaderProgramName[] = "volume-haptics-dicom-worker";
/// The watchdog for readers run without VolumeLoadOptions (meshes, series listing) [s].
inline constexpr double kDefaultStallS = 60.0;

/// Waits at most this long per poll of a reader's stdout [ms].
inline constexpr int kReaderPollMs = 50;

/// A running reader program (posix_spawn) with its stdout in a pipe and its stderr into
/// /dev/null; killed (SIGKILL) and reaped when destroyed.
class ReaderProcess {
 public:
  /// Starts `args[0]` with `args`.
  /// @throws LoadError when the pipe or the process cannot be made.
  explicit ReaderProcess(const std::vector<std::string>& args);
  ~ReaderProcess();
  ReaderProcess(const ReaderProcess&) = delete;
  ReaderProcess& operator=(const ReaderProcess&) = delete;

  /// The next line of its stdout; false at the end. Waits at most `timeout_ms` [ms] (then
  /// `line` is empty and true is returned).
  bool readLine(std::string& line, int timeout_ms);
  /// Waits for the end; the wait status (waitpid()'s).
  int wait();
  /// Kills it (SIGKILL) and waits for the end.
  void kill9();
  /// Sends it `sig` (e.g. SIGUSR1: a request to stop), while it runs.
  void signal(int sig);

 private:
  pid_t pid_ = -1;
  int out_ = -1;
  std::string buffer_;
};

/// In the reader program: runs `read`; an exception becomes the protocol's "error MESSAGE" line
/// (on one line) and exit status 1, else 0.
template <typename Read>
int reportingErrors(Read&& read) {
  try {
    read();
  } catch (const std::exception& e) {
    std::string message = e.what();
    std::replace(message.begin(), message.end(), '\n', ' ');
    std::cout << "error " << message << std::endl;
    return 1;
  }
  return 0;
}

/// Seconds from `t` to now (steady clock).
inline double secondsSince(std::chrono::steady_clock::time_point t) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
}

/// "SIGSEGV" for SIGSEGV; "signal N" for one without a name.
std::string signalName(int sig);

/// Seconds the watchdog allows a single-file reader that reports no progress: `base_s` plus
/// 1 s per 8 MiB of `file`; 0 (no watchdog) stays 0.
double stallLimitFor(const fs::path& file, double base_s);

/// A temporary file for the reader's output (in the temporary folder, named after `kind`, this
/// process's id and a counter), removed again when it goes out of scope.
class ReaderOutputFile {
 public:
  explicit ReaderOutputFile(const char* kind);
  ~ReaderOutputFile();
  ReaderOutputFile(const ReaderOutputFile&) = delete;
  ReaderOutputFile& operator=(const ReaderOutputFile&) = delete;
  const fs::path& path() const { return path_; }

 private:
  fs::path path_;
};

/// Runs the reader program to its end; `args[0]` is the program. `on_line` sees each line it
/// prints but its "error MESSAGE"; `cancel` set kills it at once (returns false). A crash throws
/// the LoadError that `problem("crashed (SIGSEGV)")` describes (naming `named`); so does a
/// stall, when the reader prints nothing for `stall_s` seconds (0 = no watchdog): it is killed
/// and `problem` gets "stopped responding (nothing for N s)". A failure throws the reader's
/// error message, else one naming `named` and the exit status.
/// @return true when the reader finished, false when cancelled.
/// @throws LoadError as above, or when the program cannot be started.
bool runReaderToEnd(const std::vector<std::string>& args, const fs::path& named, double stall_s,
                    const std::function<void(const std::string&)>& on_line, const std::atomic<bool>* cancel,
                    const std::function<std::string(const std::string&)>& problem);

/// After a crash or a stall: every file that stops the reader `program`'s DICOM probe of
/// `path` (it crashes or stops on it; the probe has its own watchdog, `stall_s`, 0 = none: a
/// file it stays on that long is a culprit). The probe runs again past each culprit
/// (`probe PATH --after FILE`, the files in sorted order) until it reaches the end, at most
/// `max_files` culprits. Sorted; empty when the probe stops on none.
/// @throws LoadError when the program cannot be started.
std::vector<std::string> findCulpritFiles(const fs::path& program, const fs::path& path, double stall_s,
                                          std::size_t max_files = 64);

/// The regular files under `folder` as a DICOM series read scans them (sub-folders to
/// kDicomScanDepth), sorted: what the reader's probe parses one by one.
std::vector<fs::path> dicomFolderFiles(const fs::path& folder);

/// After a series read crashed or stalled and the probe named no file (each file parses alone;
/// the crash needs the series read, a damaged slice among good ones): the files under `folder`
/// halved while one half alone still makes the reader `program` fail (`load` of a folder of
/// links to them, with `extra_args`: the series, the time point), then each file left read
/// beside one file from outside them. At most `max_tests` reads.
/// @return the files that make the read fail (original paths, sorted); empty when none is
///         found within the reads allowed.
/// @throws LoadError when the program cannot be started or the links cannot be made.
std::vector<std::string> findSeriesCulprits(const fs::path& program, const fs::path& folder,
                                            const std::vector<std::string>& extra_args, double stall_s,
                                            std::size_t max_tests = 32);

}  // namespace vh::io::detail
