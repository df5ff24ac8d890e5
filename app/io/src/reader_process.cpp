// The application's side of the reader process: finding the reader program, starting it with
// posix_spawn, its stdout line protocol under a watchdog, killing it, and the crash or stall
// of a reader turned into a LoadError (reader_process_internal.h).
#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <functional>

#include "loader_internal.h"
#include "reader_process_internal.h"
#include "vh/io/reader_process.h"

extern char** environ;

namespace vh::io {
namespace detail {

ReaderProcess::ReaderProcess(const std::vector<std::string>& args) {
  int fds[2];
  if (pipe2(fds, O_CLOEXEC) != 0) {
    throw LoadError(std::string("cannot start the reader process: ") + std::strerror(errno));
  }
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_adddup2(&actions, fds[1], STDOUT_FILENO);
  // A crashing reader's last words (glibc's "*** buffer overflow detected ***", VTK text that
  // escaped the capture) are not the user's console's: the crash itself is reported.
  posix_spawn_file_actions_addopen(&actions, STDERR_FILENO, "/dev/null", O_WRONLY, 0);
  std::vector<char*> argv;
  for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  const int rc = posix_spawn(&pid_, argv[0], &actions, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  close(fds[1]);
  out_ = fds[0];
  if (rc != 0) {
    close(out_);
    out_ = -1;
    pid_ = -1;
    throw LoadError(std::string("cannot start the reader process ") + args[0] + ": " + std::strerror(rc));
  }
}

ReaderProcess::~ReaderProcess() {
  if (pid_ > 0) {
    kill(pid_, SIGKILL);
    waitpid(pid_, nullptr, 0);
  }
  if (out_ >= 0) close(out_);
}

bool ReaderProcess::readLine(std::string& line, int timeout_ms) {
  line.clear();
  for (;;) {
    const auto nl = buffer_.find('\n');
    if (nl != std::string::npos) {
      line = buffer_.substr(0, nl);
      buffer_.erase(0, nl + 1);
      return true;
    }
    pollfd p{out_, POLLIN, 0};
    const int ready = poll(&p, 1, timeout_ms);
    if (ready == 0) return true;
    if (ready < 0) {
      if (errno == EINTR) continue;
      return false;
    }
    char chunk[4096];
    const ssize_t got = read(out_, chunk, sizeof(chunk));
    if (got < 0 && errno == EINTR) continue;
    if (got <= 0) {
      if (!buffer_.empty()) {
        line.swap(buffer_);
        return true;
      }
      return false;
    }
    buffer_.append(chunk, static_cast<std::size_t>(got));
  }
}

int ReaderProcess::wait() {
  int status = 0;
  while (waitpid(pid_, &status, 0) < 0 && errno == EINTR) {
  }
  pid_ = -1;
  return status;
}

void ReaderProcess::kill9() {
  if (pid_ > 0) {
    kill(pid_, SIGKILL);
    wait();
  }
}

void ReaderProcess::signal(int sig) {
  if (pid_ > 0) kill(pid_, sig);
}

std::string signalName(int sig) {
  const char* abbrev = sigabbrev_np(sig);
  return abbrev != nullptr ? std::string("SIG") + abbrev : "signal " + std::to_string(sig);
}

namespace {

std::atomic<int> g_output_counter{0};

}  // namespace

double stallLimitFor(const fs::path& file, double base_s) {
  if (!(base_s > 0.0)) return 0.0;
  std::error_code ec;
  const auto bytes = fs::is_regular_file(file, ec) ? fs::file_size(file, ec) : 0;
  return base_s + (ec ? 0.0 : static_cast<double>(bytes) / (8.0 * 1024 * 1024));
}

ReaderOutputFile::ReaderOutputFile(const char* kind) {
  std::error_code ec;
  path_ = fs::temp_directory_path(ec) /
          ("vh-" + std::string(kind) + "-" + std::to_string(getpid()) + "-" + std::to_string(g_output_counter++));
}

ReaderOutputFile::~ReaderOutputFile() {
  std::error_code ec;
  fs::remove(path_, ec);
}

namespace {

/// Runs the reader `args` to its end, `on_line` seeing each line it prints; killed when it prints
/// nothing for `stall_s` seconds (0: never). @return true when it crashed or stalled.
bool readerCrashesOrStalls(const std::vector<std::string>& args, double stall_s,
                           const std::function<void(const std::string&)>& on_line) {
  ReaderProcess run(args);
  std::string line;
  auto last_line = std::chrono::steady_clock::now();
  while (run.readLine(line, kReaderPollMs)) {
    if (line.empty()) {
      if (stall_s > 0.0 && secondsSince(last_line) > stall_s) {
        run.kill9();
        return true;
      }
      continue;
    }
    last_line = std::chrono::steady_clock::now();
    on_line(line);
  }
  return WIFSIGNALED(run.wait());
}

std::string culpritAfter(const fs::path& program, const fs::path& path, double stall_s, const std::string& after) {
  std::vector<std::string> args = {program.string(), "probe", path.string()};
  if (!after.empty()) args.insert(args.end(), {"--after", after});
  std::string last;
  const bool failed = readerCrashesOrStalls(args, stall_s, [&](const std::string& line) {
    if (line.rfind("file ", 0) == 0) last = line.substr(5);
    if (line == "ok") last.clear();
  });
  return failed ? last : std::string();
}

}  // namespace

std::vector<std::string> findCulpritFiles(const fs::path& program, const fs::path& path, double stall_s,
                                          std::size_t max_files) {
  std::vector<std::string> found;
  std::string after;
  while (found.size() < max_files) {
    const std::string culprit = culpritAfter(program, path, stall_s, after);
    // A probe that stops again on a file at or before the last one found is going nowhere.
    if (culprit.empty() || (!after.empty() && !(fs::path(after) < fs::path(culprit)))) break;
    found.push_back(culprit);
    after = culprit;
  }
  return found;
}

namespace {

/// A temporary folder of symbolic links to some files (each named NNNNN-<its name>, so that two
/// files of one name in different sub-folders stay apart), removed with it.
class LinkFolder {
 public:
  explicit LinkFolder(const std::vector<fs::path>& files) {
    std::error_code ec;
    path_ = fs::temp_directory_path(ec) /
            ("vh-dicom-bisect-" + std::to_string(getpid()) + "-" + std::to_string(g_output_counter++));
    fs::create_directory(path_, ec);
    if (ec) fail(path_, "cannot make a folder to find the damaged file in: " + ec.message());
    for (std::size_t i = 0; i < files.size(); ++i) {
      char index[32];
      std::snprintf(index, sizeof(index), "%05zu-", i);
      fs::create_symlink(fs::absolute(files[i], ec), path_ / (index + files[i].filename().string()), ec);
      if (ec) fail(path_, "cannot link " + files[i].string() + " to find the damaged file: " + ec.message());
    }
  }
  ~LinkFolder() {
    std::error_code ec;
    fs::remove_all(path_, ec);
  }
  LinkFolder(const LinkFolder&) = delete;
  LinkFolder& operator=(const LinkFolder&) = delete;
  const fs::path& path() const { return path_; }

 private:
  fs::path path_;
};

/// Whether the reader `program` crashes (or stops responding for `stall_s` s, 0: never) reading
/// the series made of `files` alone, as `load` with `extra_args` (the series, the time point).
bool seriesReadFails(const fs::path& program, const std::vector<fs::path>& files,
                     const std::vector<std::string>& extra_args, double stall_s) {
  const LinkFolder folder(files);
  const ReaderOutputFile out("dicom-bisect");
  std::vector<std::string> args = {program.string(), "load", folder.path().string(), out.path().string()};
  args.insert(args.end(), extra_args.begin(), extra_args.end());
  return readerCrashesOrStalls(args, stall_s, [](const std::string&) {});
}

}  // namespace

std::vector<fs::path> dicomFolderFiles(const fs::path& folder) {
  std::error_code ec;
  std::vector<fs::path> files;
  for (auto it = fs::recursive_directory_iterator(folder, ec); !ec && it != fs::recursive_directory_iterator();
       it.increment(ec)) {
    if (it.depth() >= kDicomScanDepth) it.disable_recursion_pending();
    if (it->is_regular_file(ec)) files.push_back(it->path());
  }
  std::sort(files.begin(), files.end());
  return files;
}

std::vector<std::string> findSeriesCulprits(const fs::path& program, const fs::path& folder,
                                            const std::vector<std::string>& extra_args, double stall_s,
                                            std::size_t max_tests) {
  const std::vector<fs::path> files = dicomFolderFiles(folder);
  if (files.size() < 2) return {};
  std::size_t tests = 0;
  const auto fails = [&](const std::vector<fs::path>& subset) {
    ++tests;
    return seriesReadFails(program, subset, extra_args, stall_s);
  };
  // Halve the files while one half alone still fails.
  std::vector<fs::path> s = files;
  while (s.size() > 1 && tests + 2 <= max_tests) {
    const auto middle = s.begin() + static_cast<std::ptrdiff_t>(s.size() / 2);
    std::vector<fs::path> a(s.begin(), middle), b(middle, s.end());
    if (fails(a)) {
      s = std::move(a);
    } else if (fails(b)) {
      s = std::move(b);
    } else {
      break;  // the failure needs files of both halves (a damaged slice beside good ones)
    }
  }
  if (s.size() == 1) return {s.front().string()};
  // Each file left, read beside one file from outside them: the damaged one fails with any
  // other, a good one beside a good one does not.
  const auto partner = std::find_if(files.begin(), files.end(),
                                    [&](const fs::path& f) { return std::find(s.begin(), s.end(), f) == s.end(); });
  if (partner == files.end() || s.size() + tests > max_tests) return {};
  std::vector<std::string> culprits;
  for (const fs::path& f : s) {
    if (fails({f, *partner})) culprits.push_back(f.string());
  }
  // Every one failing: the partner is as likely the damaged one; nothing is named.
  if (culprits.size() == s.size()) return {};
  return culprits;
}

bool runReaderToEnd(const std::vector<std::string>& args, const fs::path& named, double stall_s,
                    const std::function<void(const std::string&)>& on_line, const std::atomic<bool>* cancel,
                    const std::function<std::string(const std::string&)>& problem) {
  ReaderProcess run(args);
  std::string line, error;
  auto last_line = std::chrono::steady_clock::now();
  while (run.readLine(line, kReaderPollMs)) {
    if (cancel != nullptr && cancel->load(std::memory_order_relaxed)) {
      run.kill9();
      return false;
    }
    const auto now = std::chrono::steady_clock::now();
    if (line.empty()) {
      if (stall_s > 0.0 && std::chrono::duration<double>(now - last_line).count() > stall_s) {
        run.kill9();
        char seconds[32];
        std::snprintf(seconds, sizeof(seconds), "%.0f", stall_s);
        fail(named, problem(std::string("stopped responding (nothing for ") + seconds + " s)"));
      }
      continue;
    }
    last_line = now;
    if (line.rfind("error ", 0) == 0) error = line.substr(6);
    else if (on_line) on_line(line);
  }
  const int status = run.wait();
  if (WIFSIGNALED(status)) fail(named, problem("crashed (" + signalName(WTERMSIG(status)) + ")"));
  if (WEXITSTATUS(status) != 0) {
    if (!error.empty()) throw LoadError(error);
    fail(named, "the reader process " + args[0] + " failed (exit status " + std::to_string(WEXITSTATUS(status)) + ")");
  }
  return true;
}

}  // namespace detail

namespace fs = std::filesystem;

std::vector<fs::path> readerProcessCandidates(const fs::path& exe_dir) {
  std::vector<fs::path> candidates;
  if (!exe_dir.empty()) {
    candidates.push_back(exe_dir / detail::kReaderProgramName);
#ifdef VH_READER_PROCESS_INSTALL_RELATIVE_PATH
    candidates.push_back((exe_dir / VH_READER_PROCESS_INSTALL_RELATIVE_PATH).lexically_normal());
#endif
  }
#ifdef VH_READER_PROCESS_BUILD_PATH
  candidates.emplace_back(VH_READER_PROCESS_BUILD_PATH);
#endif
  return candidates;
}

fs::path readerProcessPath() {
  std::error_code ec;
  if (const char* env = std::getenv("VH_DICOM_WORKER"); env != nullptr && *env != '\0') {
    return fs::exists(env, ec) ? fs::path(env) : fs::path();
  }
  fs::path exe_dir = fs::read_symlink("/proc/self/exe", ec).parent_path();
  if (ec) exe_dir.clear();
  for (const fs::path& candidate : readerProcessCandidates(exe_dir)) {
    if (fs::exists(candidate, ec)) return candidate;
  }
  return {};
}

}  // namespace vh::io
