// The DICOM network process. The public PACS operations of vh/io/pacs.h run in the reader program
// (`volume-haptics-dicom-worker pacs OP REQUEST OUT`, pacsProcessMain()), as the scan readers do:
// DCMTK parses a server's answer with recursion as deep as the answer's nesting and allocates a
// value's declared length before reading it, so a hostile or broken server could otherwise end
// the application (and a recording in progress, and the haptic threads) with one response. Here
// such an answer ends the network process, and the call throws a PacsError that says so.
//
// The settings and the query travel in a private request file (not on the command line, where
// `ps` would show a patient's name), the result in a private output file; both hold length-prefixed
// fields, so that DICOM text in any character set comes back byte for byte. The process prints
// "progress RECEIVED TOTAL FAILED NAME" after each file retrieved and "error MESSAGE" before
// exiting 1. The calling side keeps its own deadline over the whole process (the operation's
// timeout and a margin, restarted with each file retrieved): it covers what the operation's own
// watchdog cannot cut off, the host name's lookup.
#include <signal.h>
#include <sys/resource.h>
#include <sys/wait.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <optional>
#include <sstream>
#include <string>
#include <string_view>
#include <system_error>
#include <vector>

#include "loader_internal.h"
#include "pacs_internal.h"
#include "reader_process_internal.h"
#include "vh/io/available_memory.h"
#include "vh/io/private_files.h"
#include "vh/io/reader_process.h"

namespace vh::io {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

/// How long past an operation's own timeout the calling side waits before it stops the network
/// process [s]: the process's start, and room for the operation's own deadline to fire first
/// (its message says more).
constexpr double kProcessMarginS = 3.0;
/// How long past PacsRetrieveOptions::cancel_grace_s a cancelled retrieval's process may take
/// to end on its own (C-CANCEL, the association released, its files deleted) [s].
constexpr double kCancelMarginS = 2.0;
/// The network process's address space is bounded by the memory free, but never below this
/// (the program's libraries and threads alone reserve several hundred MiB of it) [bytes].
constexpr std::uint64_t kMinAddressSpace_bytes = std::uint64_t{2} << 30;

using detail::pacsError;
using detail::secondsSince;

// ---- the request and result files: fields, each "LENGTH\n" and its bytes ----

class FieldWriter {
 public:
  FieldWriter& add(std::string_view v) {
    bytes_ += std::to_string(v.size());
    bytes_ += '\n';
    bytes_.append(v);
    return *this;
  }
  FieldWriter& add(long long v) { return add(std::to_string(v)); }
  FieldWriter& add(double v) {
    char buf[64];
    std::snprintf(buf, sizeof buf, "%.17g", v);
    return add(std::string_view(buf));
  }
  /// Writes the fields to a new owner-only file `path`. @throws std::runtime_error on failure.
  void save(const fs::path& path) const {
    createPrivateFile(path);
    std::ofstream f(path, std::ios::binary | std::ios::trunc);
    f.write(bytes_.data(), static_cast<std::streamsize>(bytes_.size()));
    f.flush();
    if (!f) throw std::runtime_error("cannot write " + path.string());
  }

 private:
  std::string bytes_;
};

class FieldReader {
 public:
  /// The fields of `path`. @throws std::runtime_error when it cannot be read.
  explicit FieldReader(const fs::path& path) {
    std::ifstream f(path, std::ios::binary);
    if (!f) throw std::runtime_error("cannot read " + path.string());
    std::ostringstream all;
    all << f.rdbuf();
    bytes_ = std::move(all).str();
  }
  /// The next field. @throws std::runtime_error when the file ends or is malformed.
  std::string text() {
    const auto nl = bytes_.find('\n', at_);
    if (nl == std::string::npos || nl == at_ || nl - at_ > 12) throw malformed();
    std::size_t length = 0;
    for (std::size_t i = at_; i < nl; ++i) {
      if (bytes_[i] < '0' || bytes_[i] > '9') throw malformed();
      length = length * 10 + static_cast<std::size_t>(bytes_[i] - '0');
    }
    if (length > bytes_.size() - nl - 1) throw malformed();
    at_ = nl + 1 + length;
    return bytes_.substr(nl + 1, length);
  }
  long long integer() {
    const std::string t = text();
    try {
      std::size_t used = 0;
      const long long v = std::stoll(t, &used);
      if (used == t.size()) return v;
    } catch (const std::exception&) {
    }
    throw malformed();
  }
  int count(int most) {
    const long long v = integer();
    if (v < -1 || v > most) throw malformed();
    return static_cast<int>(v);
  }
  double real() {
    const std::string t = text();
    try {
      return std::stod(t);
    } catch (const std::exception&) {
      throw malformed();
    }
  }

 private:
  static std::runtime_error malformed() { return std::runtime_error("a malformed field in the network process's file"); }
  std::string bytes_;
  std::size_t at_ = 0;
};

/// The most records a result may hold (more than any PACS lists for one query).
constexpr int kMostRecords = 10'000'000;

void addServer(FieldWriter& w, const PacsServer& s) {
  w.add(s.host).add(static_cast<long long>(s.port)).add(s.called_aet).add(s.calling_aet);
  w.add(static_cast<long long>(s.timeout_s)).add(static_cast<long long>(s.tls ? 1 : 0));
  w.add(s.ca_cert).add(s.client_cert).add(s.client_key);
}

PacsServer readServer(FieldReader& r) {
  PacsServer s;
  s.host = r.text();
  s.port = r.count(65535);
  s.called_aet = r.text();
  s.calling_aet = r.text();
  s.timeout_s = r.count(3600);
  s.tls = r.integer() != 0;
  s.ca_cert = r.text();
  s.client_cert = r.text();
  s.client_key = r.text();
  return s;
}

void addStudies(FieldWriter& w, const std::vector<PacsStudy>& studies) {
  w.add(static_cast<long long>(studies.size()));
  for (const PacsStudy& s : studies) {
    w.add(s.patient_name).add(s.patient_id).add(s.patient_birth_date).add(s.patient_sex).add(s.study_uid);
    w.add(s.study_date).add(s.study_time).add(s.description).add(s.accession_number).add(s.modalities);
    w.add(static_cast<long long>(s.series_count));
  }
}

std::vector<PacsStudy> readStudies(FieldReader& r) {
  std::vector<PacsStudy> studies(static_cast<std::size_t>(std::max(0, r.count(kMostRecords))));
  for (PacsStudy& s : studies) {
    s.patient_name = r.text();
    s.patient_id = r.text();
    s.patient_birth_date = r.text();
    s.patient_sex = r.text();
    s.study_uid = r.text();
    s.study_date = r.text();
    s.study_time = r.text();
    s.description = r.text();
    s.accession_number = r.text();
    s.modalities = r.text();
    s.series_count = r.count(kMostRecords);
  }
  return studies;
}

void addSeries(FieldWriter& w, const std::vector<PacsSeries>& series) {
  w.add(static_cast<long long>(series.size()));
  for (const PacsSeries& s : series) {
    w.add(s.study_uid).add(s.series_uid).add(s.modality).add(s.description);
    w.add(static_cast<long long>(s.number)).add(static_cast<long long>(s.instance_count));
  }
}

std::vector<PacsSeries> readSeries(FieldReader& r) {
  std::vector<PacsSeries> series(static_cast<std::size_t>(std::max(0, r.count(kMostRecords))));
  for (PacsSeries& s : series) {
    s.study_uid = r.text();
    s.series_uid = r.text();
    s.modality = r.text();
    s.description = r.text();
    s.number = static_cast<int>(std::clamp<long long>(r.integer(), -1, 2147483647));
    s.instance_count = r.count(kMostRecords);
  }
  return series;
}

// ---- the calling side ----

/// What a retrieval adds to running the network process: its progress and cancel, and the files
/// it reported, for deleting them when the process ends badly.
struct RetrieveWatch {
  const PacsRetrieveOptions* options = nullptr;
  fs::path folder;
  std::vector<fs::path> files;  ///< Reported so far, in order.
  PacsRetrieveProgress progress;
  bool stopped_after_cancel = false;  ///< The process did not end within the grace: killed.

  void deleteFiles() const {
    std::error_code ec;
    for (const fs::path& f : files) fs::remove(f, ec);
  }
};

/// "progress RECEIVED TOTAL FAILED NAME": the progress, NAME the file's name in the folder.
bool parseProgress(const std::string& line, RetrieveWatch& watch) {
  std::istringstream in(line.substr(9));
  int received = 0, total = -1, failed = 0;
  if (!(in >> received >> total >> failed)) return false;
  std::string name;
  in.get();  // the space
  std::getline(in, name);
  if (name.empty() || name.find('/') != std::string::npos || name == "." || name == "..") return false;
  const fs::path file = watch.folder / name;
  if (std::find(watch.files.begin(), watch.files.end(), file) == watch.files.end()) watch.files.push_back(file);
  watch.progress = {received, total, failed, file};
  return true;
}

/// Runs operation `op` with `request` in the network process `program` to its end, under the
/// deadline `server.timeout_s` plus a margin (restarted with each file a retrieval reports).
/// `what` names the operation in messages ("C-FIND"). @return the result file's fields; empty
/// when a cancelled retrieval was stopped (watch->stopped_after_cancel).
/// @throws PacsError: the operation's own error, a crash, the deadline, or no process.
std::optional<FieldReader> runNetworkProcess(const fs::path& program, const PacsServer& server, const std::string& op,
                                             const FieldWriter& request, const std::string& what,
                                             RetrieveWatch* watch) {
  const detail::ReaderOutputFile request_file("pacs-request");
  const detail::ReaderOutputFile result_file("pacs-result");
  try {
    request.save(request_file.path());
  } catch (const std::runtime_error& e) {
    throw pacsError(server, std::string("cannot hand the request to the DICOM network process: ") + e.what());
  }
  std::optional<detail::ReaderProcess> process;
  try {
    process.emplace(std::vector<std::string>{program.string(), "pacs", op, request_file.path().string(),
                                             result_file.path().string()});
  } catch (const std::exception& e) {
    throw pacsError(server, std::string("cannot start the DICOM network process: ") + e.what());
  }
  const double limit_s = server.timeout_s + kProcessMarginS;
  const std::atomic<bool>* cancel = watch != nullptr && watch->options != nullptr ? watch->options->cancel : nullptr;
  const double grace_s = watch != nullptr && watch->options != nullptr ? watch->options->cancel_grace_s : 0.0;
  auto last_line = Clock::now();
  std::optional<Clock::time_point> cancel_sent;
  std::string line, error;
  while (process->readLine(line, detail::kReaderPollMs)) {
    if (cancel != nullptr && !cancel_sent && cancel->load()) {
      process->signal(SIGUSR1);
      cancel_sent = Clock::now();
    }
    if (cancel_sent && secondsSince(*cancel_sent) > grace_s + kCancelMarginS) {
      process->kill9();
      watch->stopped_after_cancel = true;
      return std::nullopt;
    }
    if (line.empty()) {
      if (secondsSince(last_line) > limit_s) {
        process->kill9();
        if (watch != nullptr) watch->deleteFiles();
        throw pacsError(server, what + " did not finish within the timeout of " + std::to_string(server.timeout_s) +
                               " s, so the DICOM network process was stopped: does the host name '" + server.host +
                               "' resolve quickly, and is the server or the network very slow?");
      }
      continue;
    }
    last_line = Clock::now();
    if (line.rfind("error ", 0) == 0) {
      error = line.substr(6);
    } else if (watch != nullptr && line.rfind("progress ", 0) == 0 && parseProgress(line, *watch)) {
      if (watch->options->progress) watch->options->progress(watch->progress);
    }
  }
  const int status = process->wait();
  if (WIFSIGNALED(status)) {
    if (watch != nullptr) watch->deleteFiles();
    const int sig = WTERMSIG(status);
    throw pacsError(server, "the DICOM network process " +
                           (sig == SIGKILL ? std::string("was killed (SIGKILL: out of memory?)")
                                           : "crashed (" + detail::signalName(sig) + ")") +
                           " on the server's answer to " + what +
                           ": a malformed or hostile response (e.g. nested too deep); nothing was loaded or changed");
  }
  if (WEXITSTATUS(status) != 0) {
    if (watch != nullptr) watch->deleteFiles();
    if (!error.empty()) throw PacsError(error);
    throw pacsError(server, "the DICOM network process " + program.string() + " failed during " + what + " (exit status " +
                           std::to_string(WEXITSTATUS(status)) + ")");
  }
  try {
    return FieldReader(result_file.path());
  } catch (const std::runtime_error& e) {
    throw pacsError(server, std::string("the DICOM network process gave no result for ") + what + ": " + e.what());
  }
}

/// A result's fields, read; a malformed one becomes a PacsError.
template <typename Read>
auto readResult(const PacsServer& server, Read&& read) {
  try {
    return read();
  } catch (const std::runtime_error& e) {
    throw pacsError(server, std::string("the DICOM network process's result cannot be read: ") + e.what());
  }
}

// ---- the network process's side ----

std::atomic<bool> g_cancel{false};

extern "C" void onCancelSignal(int) { g_cancel.store(true); }

/// SIGUSR1 sets g_cancel; system calls it interrupts resume (SA_RESTART).
void installCancelHandler() {
  struct sigaction action = {};
  action.sa_handler = onCancelSignal;
  sigemptyset(&action.sa_mask);
  action.sa_flags = SA_RESTART;
  sigaction(SIGUSR1, &action, nullptr);
}

/// The address space bounded by the memory free (at least kMinAddressSpace_bytes): a value
/// length that asks for more fails its allocation here (DCMTK reports the memory exhausted)
/// instead of taking the computer's memory from the application beside it.
void boundAddressSpace() {
  const std::optional<std::uint64_t> free_bytes = availableMemoryBytes();
  if (!free_bytes) return;
  const rlim_t limit = static_cast<rlim_t>(std::max(*free_bytes, kMinAddressSpace_bytes));
  rlimit current{};
  if (getrlimit(RLIMIT_AS, &current) != 0) return;
  if (current.rlim_max != RLIM_INFINITY && current.rlim_max < limit) return;
  const rlimit bounded{limit, current.rlim_max};
  setrlimit(RLIMIT_AS, &bounded);
}

/// Runs operation `op` of the request `in`; its result into `out`.
/// @return false for an unknown operation.
bool runOperation(const std::string& op, FieldReader& in, FieldWriter& out) {
  const PacsServer server = readServer(in);
  if (op == "echo") {
    detail::pacsEchoInProcess(server);
  } else if (op == "find-studies") {
    PacsStudyQuery query;
    query.patient_name = in.text();
    query.patient_id = in.text();
    query.study_date = in.text();
    addStudies(out, detail::pacsFindStudiesInProcess(server, query));
  } else if (op == "find-series") {
    const std::string study_uid = in.text();
    const std::string modality = in.text();
    addSeries(out, detail::pacsFindSeriesInProcess(server, study_uid, modality));
  } else if (op == "find-series-by-uid") {
    addSeries(out, {detail::pacsFindSeriesByUidInProcess(server, in.text())});
  } else if (op == "retrieve") {
    const std::string study_uid = in.text();
    const std::string series_uid = in.text();
    const fs::path folder = in.text();
    PacsRetrieveOptions options;
    options.expected_instances = in.count(kMostRecords);
    options.cancel_grace_s = in.real();
    options.cancel = &g_cancel;
    options.progress = [](const PacsRetrieveProgress& p) {
      std::cout << "progress " << p.received << ' ' << p.total << ' ' << p.failed << ' '
                << p.last_file.filename().string() << std::endl;
    };
    const PacsRetrieveResult r = detail::pacsRetrieveSeriesInProcess(server, study_uid, series_uid, folder, options);
    out.add(static_cast<long long>(r.files.size()));
    for (const fs::path& f : r.files) out.add(f.string());
    out.add(static_cast<long long>(r.failed)).add(static_cast<long long>(r.cancelled ? 1 : 0));
    out.add(static_cast<long long>(r.cancel_acknowledged ? 1 : 0)).add(r.seconds);
  } else {
    return false;
  }
  return true;
}

}  // namespace

namespace detail {

int pacsProcessMain(int argc, char** argv) {
  constexpr char kUsage[] =
      "usage: volume-haptics-dicom-worker pacs echo|find-studies|find-series|find-series-by-uid|retrieve REQUEST OUT";
  if (argc < 5) {
    std::cerr << kUsage << std::endl;
    return 2;
  }
  boundAddressSpace();
  installCancelHandler();
  const std::string op = argv[2];
  bool known = true;
  const int status = reportingErrors([&] {
    FieldReader in{fs::path(argv[3])};
    FieldWriter out;
    known = runOperation(op, in, out);
    if (known) out.save(argv[4]);
  });
  if (!known) {
    std::cerr << kUsage << std::endl;
    return 2;
  }
  return status;
}

}  // namespace detail

namespace {

/// What every public call starts with: `server`'s settings checked (@throws PacsError), the
/// DICOM network process's program, and a request naming the server. An empty program: no reader
/// program beside this one (a test binary), the caller runs the operation in this process.
struct NetworkRequest {
  fs::path program;
  FieldWriter fields;
};
NetworkRequest networkRequest(const PacsServer& server) {
  detail::checkPacsServer(server);
  NetworkRequest r;
  r.program = readerProcessPath();
  if (!r.program.empty()) addServer(r.fields, server);
  return r;
}

}  // namespace

void pacsEcho(const PacsServer& server) {
  NetworkRequest request = networkRequest(server);
  if (request.program.empty()) return detail::pacsEchoInProcess(server);
  runNetworkProcess(request.program, server, "echo", request.fields, "C-ECHO", nullptr);
}

std::vector<PacsStudy> pacsFindStudies(const PacsServer& server, const PacsStudyQuery& query) {
  NetworkRequest request = networkRequest(server);
  if (request.program.empty()) return detail::pacsFindStudiesInProcess(server, query);
  request.fields.add(query.patient_name).add(query.patient_id).add(query.study_date);
  std::optional<FieldReader> result =
      runNetworkProcess(request.program, server, "find-studies", request.fields, "C-FIND", nullptr);
  return readResult(server, [&] { return readStudies(*result); });
}

std::vector<PacsSeries> pacsFindSeries(const PacsServer& server, const std::string& study_uid,
                                       const std::string& modality) {
  NetworkRequest request = networkRequest(server);
  if (request.program.empty()) return detail::pacsFindSeriesInProcess(server, study_uid, modality);
  request.fields.add(study_uid).add(modality);
  std::optional<FieldReader> result =
      runNetworkProcess(request.program, server, "find-series", request.fields, "C-FIND", nullptr);
  return readResult(server, [&] { return readSeries(*result); });
}

PacsSeries pacsFindSeriesByUid(const PacsServer& server, const std::string& series_uid) {
  NetworkRequest request = networkRequest(server);
  if (request.program.empty()) return detail::pacsFindSeriesByUidInProcess(server, series_uid);
  request.fields.add(series_uid);
  std::optional<FieldReader> result =
      runNetworkProcess(request.program, server, "find-series-by-uid", request.fields, "C-FIND", nullptr);
  const std::vector<PacsSeries> series = readResult(server, [&] { return readSeries(*result); });
  if (series.size() != 1) throw pacsError(server, "the DICOM network process's result holds no series");
  return series.front();
}

PacsRetrieveResult pacsRetrieveSeries(const PacsServer& server, const std::string& study_uid,
                                      const std::string& series_uid, const fs::path& out_dir,
                                      const PacsRetrieveOptions& options) {
  NetworkRequest request = networkRequest(server);
  if (request.program.empty()) return detail::pacsRetrieveSeriesInProcess(server, study_uid, series_uid, out_dir, options);
  const auto t0 = Clock::now();
  std::string study = detail::pacsTrim(study_uid);
  const std::string series = detail::pacsTrim(series_uid);
  if (series.empty()) throw pacsError(server, "no Series Instance UID given");
  int expected = options.expected_instances;
  if (study.empty() || expected < 0) {  // the lookup in a process of its own, under its own deadline
    const PacsSeries found = pacsFindSeriesByUid(server, series);
    if (study.empty()) study = found.study_uid;
    if (expected < 0) expected = found.instance_count;
  }
  request.fields.add(study).add(series).add(out_dir.string()).add(static_cast<long long>(expected)).add(options.cancel_grace_s);
  RetrieveWatch watch;
  watch.options = &options;
  watch.folder = out_dir;
  const std::string what = "C-GET of series " + series;
  std::optional<FieldReader> fields = runNetworkProcess(request.program, server, "retrieve", request.fields, what, &watch);
  PacsRetrieveResult result;
  result.folder = out_dir;
  if (!fields) {  // cancelled, and the process did not end within the grace: stopped
    watch.deleteFiles();
    result.cancelled = true;
    result.failed = watch.progress.failed;
    result.seconds = secondsSince(t0);
    return result;
  }
  readResult(server, [&] {
    const int n = fields->count(kMostRecords);
    for (int i = 0; i < n; ++i) result.files.emplace_back(fields->text());
    result.failed = fields->count(kMostRecords);
    result.cancelled = fields->integer() != 0;
    result.cancel_acknowledged = fields->integer() != 0;
    return 0;
  });
  result.seconds = secondsSince(t0);
  return result;
}

}  // namespace vh::io
