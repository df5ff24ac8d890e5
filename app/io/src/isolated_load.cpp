// DICOM loading in a worker process: vtk-dicom's parser has crashed (SIGSEGV in
// vtkDICOMParser::ReadMetaData) on damaged files; in a worker such a crash ends the worker, and
// the application names the file and keeps what it had open.
//
// Protocol: the application runs `volume-haptics-dicom-worker load PATH OUT [--series S]
// [--phase N]`; the worker reads with loadDicomRaw() and writes OUT (below), printing
// "progress F" lines on stdout, and "error MESSAGE" before exiting 1 on a LoadError. After a
// crash the application runs `... probe PATH`, which parses the files one by one, printing
// "file NAME" before each: the last name before the crash is the damaged file.
//
// OUT: "VHRAW1\n", the length of a JSON header as 8 bytes (little endian), the header
// (geometry, value scale and offset, VolumeInfo, the VTK scalar type), then the voxels.
#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <atomic>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iostream>
#include <sstream>

#include <nlohmann/json.hpp>
#include <vtkDICOMMetaData.h>
#include <vtkDICOMParser.h>
#include <vtkDataArray.h>
#include <vtkImageData.h>
#include <vtkPointData.h>
#include <vtkSmartPointer.h>

#include "loader_internal.h"
#include "vh/io/dicom_series.h"
#include "vh/io/dicom_worker.h"
#include "vtk_error_capture.h"

extern char** environ;

namespace vh::io {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;

constexpr char kMagic[] = "VHRAW1\n";
constexpr char kWorkerName[] = "volume-haptics-dicom-worker";

json toJson(const Eigen::Vector3d& v) { return {v.x(), v.y(), v.z()}; }
Eigen::Vector3d vec(const json& j) { return {j.at(0).get<double>(), j.at(1).get<double>(), j.at(2).get<double>()}; }

/// The worker's output files: kMagic, the JSON header's length (8 bytes) and the header; the
/// voxels follow.
void writeHeader(std::ofstream& f, const json& h) {
  const std::string header = h.dump(-1, ' ', false, json::error_handler_t::replace);
  const std::uint64_t n = header.size();
  f.write(kMagic, sizeof(kMagic) - 1);
  f.write(reinterpret_cast<const char*>(&n), sizeof(n));
  f.write(header.data(), static_cast<std::streamsize>(header.size()));
}

/// Reads what writeHeader() wrote (a LoadError naming `source` when it cannot).
json readHeader(std::ifstream& f, const fs::path& source) {
  char magic[sizeof(kMagic) - 1];
  std::uint64_t n = 0;
  f.read(magic, sizeof(magic));
  f.read(reinterpret_cast<char*>(&n), sizeof(n));
  if (!f || std::memcmp(magic, kMagic, sizeof(magic)) != 0 || n > (1u << 26)) {
    detail::fail(source, "the reader worker's output is unreadable");
  }
  std::string header(n, '\0');
  f.read(header.data(), static_cast<std::streamsize>(n));
  try {
    return json::parse(header);
  } catch (const json::exception& e) {
    detail::fail(source, std::string("the reader worker's output is unreadable: ") + e.what());
  }
}

json infoToJson(const VolumeInfo& i) {
  return {{"format", i.format},           {"modality", i.modality},         {"value_unit", i.value_unit},
          {"description", i.description}, {"patient_name", i.patient_name}, {"series_uid", i.series_uid},
          {"series_number", i.series_number}, {"phase", i.phase},           {"phase_count", i.phase_count},
          {"notices", i.notices}};
}

VolumeInfo infoFromJson(const json& i) {
  VolumeInfo info;
  info.format = i.at("format").get<std::string>();
  info.modality = i.at("modality").get<std::string>();
  info.value_unit = i.at("value_unit").get<std::string>();
  info.description = i.at("description").get<std::string>();
  info.patient_name = i.at("patient_name").get<std::string>();
  info.series_uid = i.at("series_uid").get<std::string>();
  info.series_number = i.at("series_number").get<int>();
  info.phase = i.at("phase").get<int>();
  info.phase_count = i.at("phase_count").get<int>();
  info.notices = i.at("notices").get<std::vector<std::string>>();
  return info;
}

/// A loaded field (NRRD, MetaImage read in the worker): header as in writeRaw, then its bytes.
void writeField(const haptics::ScalarVolume& field, const VolumeInfo& info, const fs::path& out) {
  const auto& g = field.geometry();
  json h;
  h["dims"] = g.dims;
  h["voxel_type"] = static_cast<int>(field.voxelType());
  h["spacing_m"] = toJson(g.spacing_m);
  h["origin_W_m"] = toJson(g.origin_W_m);
  h["direction_W"] = {toJson(g.direction_W.col(0)), toJson(g.direction_W.col(1)), toJson(g.direction_W.col(2))};
  h["value_scale"] = field.valueScale();
  h["value_offset"] = field.valueOffset();
  h["info"] = infoToJson(info);
  std::ofstream f(out, std::ios::binary);
  writeHeader(f, h);
  f.write(reinterpret_cast<const char*>(field.bytes().data()), static_cast<std::streamsize>(field.bytes().size()));
  if (!f) throw LoadError(out.string() + ": cannot write the loaded volume (disk full?)");
}

LoadedVolume readField(const fs::path& in, const fs::path& source) {
  std::ifstream f(in, std::ios::binary);
  const json h = readHeader(f, source);
  LoadedVolume out;
  try {
    haptics::VolumeGeometry g;
    g.dims = h.at("dims").get<std::array<int, 3>>();
    g.spacing_m = vec(h.at("spacing_m"));
    g.origin_W_m = vec(h.at("origin_W_m"));
    for (int c = 0; c < 3; ++c) g.direction_W.col(c) = vec(h.at("direction_W").at(c));
    const auto type = static_cast<haptics::VoxelType>(h.at("voxel_type").get<int>());
    std::vector<std::byte> bytes(g.voxelCount() * haptics::voxelTypeSize(type));
    f.read(reinterpret_cast<char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
    if (static_cast<std::size_t>(f.gcount()) != bytes.size()) detail::fail(source, "the reader worker's output is cut short");
    auto field = std::make_shared<haptics::ScalarVolume>(haptics::ScalarVolume::FromBytes(
        g, type, std::move(bytes), h.at("value_scale").get<double>(), h.at("value_offset").get<double>()));
    out.image = imageFromField(*field);
    out.field = std::move(field);
    out.info = infoFromJson(h.at("info"));
    out.info.source = source;
  } catch (const json::exception& e) {
    detail::fail(source, std::string("the reader worker's output is unreadable: ") + e.what());
  } catch (const std::invalid_argument& e) {
    detail::fail(source, std::string("the reader worker's output is invalid: ") + e.what());
  }
  return out;
}

void writeRaw(const detail::RawVolume& raw, const fs::path& out) {
  int dims[3];
  raw.image->GetDimensions(dims);
  vtkDataArray* scalars = raw.image->GetPointData()->GetScalars();
  if (scalars == nullptr) throw LoadError(out.string() + ": the reader produced no voxels");
  json h;
  h["dims"] = {dims[0], dims[1], dims[2]};
  h["components"] = scalars->GetNumberOfComponents();
  h["vtk_type"] = scalars->GetDataType();
  h["spacing_m"] = toJson(raw.geometry.spacing_m);
  h["origin_W_m"] = toJson(raw.geometry.origin_W_m);
  h["direction_W"] = {toJson(raw.geometry.direction_W.col(0)), toJson(raw.geometry.direction_W.col(1)),
                      toJson(raw.geometry.direction_W.col(2))};
  h["value_scale"] = raw.value_scale;
  h["value_offset"] = raw.value_offset;
  h["info"] = infoToJson(raw.info);
  std::ofstream f(out, std::ios::binary);
  writeHeader(f, h);
  const auto bytes = static_cast<std::streamsize>(scalars->GetNumberOfValues()) * scalars->GetDataTypeSize();
  f.write(static_cast<const char*>(scalars->GetVoidPointer(0)), bytes);
  if (!f) throw LoadError(out.string() + ": cannot write the loaded volume (disk full?)");
}

detail::RawVolume readRaw(const fs::path& in, const fs::path& source) {
  std::ifstream f(in, std::ios::binary);
  const json h = readHeader(f, source);
  detail::RawVolume raw;
  try {
    const auto dims = h.at("dims").get<std::array<int, 3>>();
    raw.image = vtkSmartPointer<vtkImageData>::New();
    raw.image->SetDimensions(dims[0], dims[1], dims[2]);
    raw.image->AllocateScalars(h.at("vtk_type").get<int>(), h.at("components").get<int>());
    vtkDataArray* scalars = raw.image->GetPointData()->GetScalars();
    const auto bytes = static_cast<std::streamsize>(scalars->GetNumberOfValues()) * scalars->GetDataTypeSize();
    f.read(static_cast<char*>(scalars->GetVoidPointer(0)), bytes);
    if (f.gcount() != bytes) detail::fail(source, "the DICOM worker's output is cut short");
    raw.geometry.spacing_m = vec(h.at("spacing_m"));
    raw.geometry.origin_W_m = vec(h.at("origin_W_m"));
    for (int c = 0; c < 3; ++c) raw.geometry.direction_W.col(c) = vec(h.at("direction_W").at(c));
    raw.value_scale = h.at("value_scale").get<double>();
    raw.value_offset = h.at("value_offset").get<double>();
    raw.info = infoFromJson(h.at("info"));
  } catch (const json::exception& e) {
    detail::fail(source, std::string("the DICOM worker's output is unreadable: ") + e.what());
  }
  return raw;
}

json seriesToJson(const DicomSeriesInfo& i) {
  std::vector<std::string> files;
  for (const auto& f : i.files) files.push_back(f.string());
  return {{"folder", i.folder.string()},
          {"index", i.index},
          {"patient_name", i.patient_name},
          {"patient_id", i.patient_id},
          {"study_description", i.study_description},
          {"study_date", i.study_date},
          {"series_description", i.series_description},
          {"series_uid", i.series_uid},
          {"series_number", i.series_number},
          {"modality", i.modality},
          {"file_count", i.file_count},
          {"slice_count", i.slice_count},
          {"rows", i.rows},
          {"columns", i.columns},
          {"spacing_mm", toJson(i.spacing_mm)},
          {"files", files}};
}

DicomSeriesInfo seriesFromJson(const json& j) {
  DicomSeriesInfo i;
  i.folder = j.at("folder").get<std::string>();
  i.index = j.at("index").get<int>();
  i.patient_name = j.at("patient_name").get<std::string>();
  i.patient_id = j.at("patient_id").get<std::string>();
  i.study_description = j.at("study_description").get<std::string>();
  i.study_date = j.at("study_date").get<std::string>();
  i.series_description = j.at("series_description").get<std::string>();
  i.series_uid = j.at("series_uid").get<std::string>();
  i.series_number = j.at("series_number").get<int>();
  i.modality = j.at("modality").get<std::string>();
  i.file_count = j.at("file_count").get<int>();
  i.slice_count = j.at("slice_count").get<int>();
  i.rows = j.at("rows").get<int>();
  i.columns = j.at("columns").get<int>();
  i.spacing_mm = vec(j.at("spacing_mm"));
  for (const auto& f : j.at("files")) i.files.emplace_back(f.get<std::string>());
  return i;
}

/// A running worker with its stdout.
class Worker {
 public:
  explicit Worker(const std::vector<std::string>& args) {
    int fds[2];
    if (pipe2(fds, O_CLOEXEC) != 0) throw LoadError(std::string("cannot start the DICOM worker: ") + std::strerror(errno));
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
      throw LoadError(std::string("cannot start the DICOM worker ") + args[0] + ": " + std::strerror(rc));
    }
  }
  ~Worker() {
    if (pid_ > 0) {
      kill(pid_, SIGKILL);
      waitpid(pid_, nullptr, 0);
    }
    if (out_ >= 0) close(out_);
  }
  Worker(const Worker&) = delete;
  Worker& operator=(const Worker&) = delete;

  /// Next line of stdout; false at the end. Waits at most `timeout_ms` (then `line` is empty
  /// and true is returned).
  bool readLine(std::string& line, int timeout_ms) {
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
  /// Waits for the end; the wait status.
  int wait() {
    int status = 0;
    while (waitpid(pid_, &status, 0) < 0 && errno == EINTR) {
    }
    pid_ = -1;
    return status;
  }
  void kill9() {
    if (pid_ > 0) {
      kill(pid_, SIGKILL);
      wait();
    }
  }

 private:
  pid_t pid_ = -1;
  int out_ = -1;
  std::string buffer_;
};

std::string signalName(int sig) {
  const char* abbrev = sigabbrev_np(sig);
  return abbrev != nullptr ? std::string("SIG") + abbrev : "signal " + std::to_string(sig);
}

/// Seconds the watchdog allows a single-file reader that reports no progress: `base_s` plus
/// 1 s per 8 MiB of `file`; 0 (no watchdog) stays 0.
double stallLimitFor(const fs::path& file, double base_s) {
  if (!(base_s > 0.0)) return 0.0;
  std::error_code ec;
  const auto bytes = fs::is_regular_file(file, ec) ? fs::file_size(file, ec) : 0;
  return base_s + (ec ? 0.0 : static_cast<double>(bytes) / (8.0 * 1024 * 1024));
}

/// Waits at most this long per poll of the worker's stdout [ms].
constexpr int kPollMs = 50;
/// The watchdog's default for readers without VolumeLoadOptions (meshes) [s].
constexpr double kDefaultStallS = 60.0;

/// After a crash or a stall: the file the worker's probe crashes or stops on, or "". The probe
/// has its own watchdog (`stall_s`, 0 = none): a file it stays on that long is the culprit.
std::string findCulpritFile(const fs::path& worker, const fs::path& path, double stall_s) {
  Worker probe({worker.string(), "probe", path.string()});
  std::string line, last;
  auto last_line = std::chrono::steady_clock::now();
  while (probe.readLine(line, kPollMs)) {
    if (line.empty()) {
      if (stall_s > 0.0 && std::chrono::duration<double>(std::chrono::steady_clock::now() - last_line).count() > stall_s) {
        probe.kill9();
        return last;
      }
      continue;
    }
    last_line = std::chrono::steady_clock::now();
    if (line.rfind("file ", 0) == 0) last = line.substr(5);
    if (line == "ok") last.clear();
  }
  const int status = probe.wait();
  return WIFSIGNALED(status) ? last : std::string();
}

std::atomic<int> g_out_counter{0};

/// A temporary file for a worker's output, removed again when it goes out of scope.
class WorkerOutput {
 public:
  explicit WorkerOutput(const char* kind) {
    std::error_code ec;
    path_ = fs::temp_directory_path(ec) /
            ("vh-" + std::string(kind) + "-" + std::to_string(getpid()) + "-" + std::to_string(g_out_counter++));
  }
  ~WorkerOutput() {
    std::error_code ec;
    fs::remove(path_, ec);
  }
  WorkerOutput(const WorkerOutput&) = delete;
  WorkerOutput& operator=(const WorkerOutput&) = delete;
  const fs::path& path() const { return path_; }

 private:
  fs::path path_;
};

/// Runs the worker to its end. `on_line` sees each line it prints but its "error MESSAGE";
/// `cancel` set kills it at once (returns false). A crash throws the LoadError that
/// `problem("crashed (SIGSEGV)")` describes (naming `named`); so does a stall, when the worker
/// prints nothing for `stall_s` seconds (0 = no watchdog): it is killed and `problem` gets
/// "stopped responding (nothing for N s)". A failure throws the worker's error message, else one
/// naming `named` and the exit status.
bool runWorker(const std::vector<std::string>& args, const fs::path& named, double stall_s,
               const std::function<void(const std::string&)>& on_line, const std::atomic<bool>* cancel,
               const std::function<std::string(const std::string&)>& problem) {
  Worker run(args);
  std::string line, error;
  auto last_line = std::chrono::steady_clock::now();
  while (run.readLine(line, kPollMs)) {
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
        detail::fail(named, problem(std::string("stopped responding (nothing for ") + seconds + " s)"));
      }
      continue;
    }
    last_line = now;
    if (line.rfind("error ", 0) == 0) error = line.substr(6);
    else if (on_line) on_line(line);
  }
  const int status = run.wait();
  if (WIFSIGNALED(status)) detail::fail(named, problem("crashed (" + signalName(WTERMSIG(status)) + ")"));
  if (WEXITSTATUS(status) != 0) {
    if (!error.empty()) throw LoadError(error);
    detail::fail(named, "the worker " + args[0] + " failed (exit status " + std::to_string(WEXITSTATUS(status)) + ")");
  }
  return true;
}

}  // namespace

std::vector<fs::path> dicomWorkerCandidates(const fs::path& exe_dir) {
  std::vector<fs::path> candidates;
  if (!exe_dir.empty()) {
    candidates.push_back(exe_dir / kWorkerName);
#ifdef VH_DICOM_WORKER_INSTALL_RELATIVE_PATH
    candidates.push_back((exe_dir / VH_DICOM_WORKER_INSTALL_RELATIVE_PATH).lexically_normal());
#endif
  }
#ifdef VH_DICOM_WORKER_BUILD_PATH
  candidates.emplace_back(VH_DICOM_WORKER_BUILD_PATH);
#endif
  return candidates;
}

fs::path dicomWorkerPath() {
  std::error_code ec;
  if (const char* env = std::getenv("VH_DICOM_WORKER"); env != nullptr && *env != '\0') {
    return fs::exists(env, ec) ? fs::path(env) : fs::path();
  }
  fs::path exe_dir = fs::read_symlink("/proc/self/exe", ec).parent_path();
  if (ec) exe_dir.clear();
  for (const fs::path& candidate : dicomWorkerCandidates(exe_dir)) {
    if (fs::exists(candidate, ec)) return candidate;
  }
  return {};
}

haptics::TriangleMesh loadMesh(const fs::path& path, double scale_to_m) {
  const fs::path worker = dicomWorkerPath();
  if (worker.empty() || !(scale_to_m > 0.0) || !std::isfinite(scale_to_m)) {
    return detail::loadMeshInProcess(path, scale_to_m);  // also names a bad scale
  }
  std::error_code ec;
  const WorkerOutput out("mesh");
  std::ostringstream scale;
  scale.precision(17);
  scale << scale_to_m;
  runWorker({worker.string(), "mesh", fs::absolute(path, ec).string(), out.path().string(), scale.str()}, path,
            stallLimitFor(path, kDefaultStallS), {}, nullptr, [](const std::string& what) {
              return "the mesh reader " + what + ": a damaged file; nothing was loaded";
            });
  std::ifstream in(out.path(), std::ios::binary);
  std::uint64_t nv = 0, nt = 0;
  in.read(reinterpret_cast<char*>(&nv), sizeof(nv));
  in.read(reinterpret_cast<char*>(&nt), sizeof(nt));
  if (!in || nv > (1ull << 31) || nt > (1ull << 31)) detail::fail(path, "the mesh worker's output is unreadable");
  haptics::TriangleMesh mesh;
  mesh.vertices_T_m.resize(nv);
  mesh.triangles.resize(nt);
  for (auto& v : mesh.vertices_T_m) in.read(reinterpret_cast<char*>(v.data()), 3 * sizeof(double));
  for (auto& t : mesh.triangles) in.read(reinterpret_cast<char*>(t.data()), 3 * sizeof(int));
  if (!in) detail::fail(path, "the mesh worker's output is cut short");
  for (const auto& t : mesh.triangles) {
    for (int v : t) {
      if (v < 0 || static_cast<std::uint64_t>(v) >= nv) detail::fail(path, "the mesh worker's output is inconsistent");
    }
  }
  return mesh;
}

std::vector<DicomSeriesInfo> listDicomSeries(const fs::path& folder, const std::function<void(int, int)>& progress,
                                             const std::atomic<bool>* cancel) {
  const fs::path worker = dicomWorkerPath();
  if (worker.empty()) return detail::listDicomSeriesInProcess(folder, progress, cancel);
  std::error_code ec;
  const WorkerOutput out("dicom-list");
  const auto on_line = [&](const std::string& line) {
    int done = 0, total = 0;
    if (progress && std::sscanf(line.c_str(), "progress %d %d", &done, &total) == 2) progress(done, total);
  };
  const bool finished = runWorker({worker.string(), "list", fs::absolute(folder, ec).string(), out.path().string()},
                                  folder, kDefaultStallS, on_line, cancel, [&](const std::string& what) {
                                    const std::string file = findCulpritFile(worker, folder, kDefaultStallS);
                                    return "the DICOM reader " + what +
                                           (file.empty() ? std::string(" listing the folder") : " on " + file) +
                                           ": a damaged file";
                                  });
  if (!finished) return {};
  std::vector<DicomSeriesInfo> series;
  try {
    std::ifstream in(out.path());
    for (const auto& j : json::parse(in)) series.push_back(seriesFromJson(j));
  } catch (const json::exception& e) {
    detail::fail(folder, std::string("the DICOM worker's series list is unreadable: ") + e.what());
  }
  return series;
}

namespace detail {

LoadedVolume loadFileIsolated(const fs::path& path, const VolumeLoadOptions& options,
                              const std::function<LoadedVolume()>& in_process) {
  const fs::path worker = options.dicom_isolation == DicomIsolation::kInProcess ? fs::path() : dicomWorkerPath();
  if (worker.empty()) {
    if (options.dicom_isolation == DicomIsolation::kWorker) {
      fail(path, std::string("the reader worker program (") + kWorkerName + ") was not found");
    }
    return in_process();
  }
  std::error_code ec;
  const WorkerOutput out("volume");
  std::vector<std::string> args = {worker.string(), "volume", fs::absolute(path, ec).string(), out.path().string()};
  if (options.nrrd_layer != 0) args.insert(args.end(), {"--layer", std::to_string(options.nrrd_layer)});
  const bool finished = runWorker(args,
                                  path, stallLimitFor(path, options.worker_stall_timeout_s), {}, options.cancel,
                                  [](const std::string& what) {
                                    return "the volume reader " + what + ": a damaged file; nothing was loaded";
                                  });
  if (!finished) throw LoadCancelled(path.string() + ": loading cancelled");
  return readField(out.path(), path);
}

LoadedVolume loadDicom(const fs::path& path, const VolumeLoadOptions& options) {
  const fs::path worker = options.dicom_isolation == DicomIsolation::kInProcess ? fs::path() : dicomWorkerPath();
  if (worker.empty()) {
    if (options.dicom_isolation == DicomIsolation::kWorker) {
      fail(path, std::string("the DICOM worker program (") + kWorkerName + ") was not found");
    }
    RawVolume raw = loadDicomRaw(path, options);
    if (options.dicom_isolation == DicomIsolation::kAuto) {
      raw.info.notices.push_back(std::string("read in this process: the DICOM worker (") + kWorkerName +
                                 ") was not found, so a damaged file could end the program");
    }
    return finishVolume(std::move(raw), path);
  }
  std::error_code ec;
  const WorkerOutput out("dicom");
  std::vector<std::string> args = {worker.string(), "load", fs::absolute(path, ec).string(), out.path().string()};
  if (!options.dicom_series.empty()) args.insert(args.end(), {"--series", options.dicom_series});
  if (options.dicom_phase != 0) args.insert(args.end(), {"--phase", std::to_string(options.dicom_phase)});
  const auto on_line = [&](const std::string& line) {
    if (line.rfind("progress ", 0) == 0 && options.progress) options.progress(0.9 * std::strtod(line.c_str() + 9, nullptr));
  };
  const double stall_s = stallLimitFor(path, options.worker_stall_timeout_s);
  const bool finished = runWorker(args, path, stall_s, on_line, options.cancel, [&](const std::string& what) {
    const std::string file = findCulpritFile(worker, path, stall_s);
    return "the DICOM reader " + what +
           (file.empty() ? std::string(" reading the series") : " on " + file) + ": a damaged file; nothing was loaded";
  });
  if (!finished) throw LoadCancelled(path.string() + ": loading cancelled");
  RawVolume raw = readRaw(out.path(), path);
  if (options.progress) options.progress(0.95);
  return finishVolume(std::move(raw), path);
}

}  // namespace detail

int runDicomWorker(int argc, char** argv) {
  const std::string usage =
      "usage: volume-haptics-dicom-worker load PATH OUT [--series S] [--phase N] | volume FILE OUT | list FOLDER OUT | mesh PATH OUT "
      "SCALE | probe PATH";
  if (argc < 3) {
    std::cerr << usage << std::endl;
    return 2;
  }
  const std::string mode = argv[1];
  const fs::path path = argv[2];
  if (mode == "probe") {
    // Each file's header and pixels on its own; the name first, so a crash names it.
    std::error_code ec;
    std::vector<fs::path> files;
    if (fs::is_directory(path, ec)) {
      for (auto it = fs::recursive_directory_iterator(path, ec); !ec && it != fs::recursive_directory_iterator();
           it.increment(ec)) {
        if (it.depth() >= detail::kDicomScanDepth) it.disable_recursion_pending();
        if (it->is_regular_file(ec)) files.push_back(it->path());
      }
    } else {
      files.push_back(path);
    }
    std::sort(files.begin(), files.end());
    for (const auto& f : files) {
      std::cout << "file " << f.string() << std::endl;
      detail::VtkErrorCapture capture;
      auto meta = vtkSmartPointer<vtkDICOMMetaData>::New();
      auto parser = vtkSmartPointer<vtkDICOMParser>::New();
      capture.watch(parser);
      parser->SetMetaData(meta);
      parser->SetFileName(f.string().c_str());
      parser->Update();
      std::cout << "ok" << std::endl;
    }
    return 0;
  }
  if (mode == "volume" && argc >= 4) {
    try {
      VolumeLoadOptions in_process;
      in_process.dicom_isolation = DicomIsolation::kInProcess;
      for (int a = 4; a + 1 < argc; ++a) {
        if (std::string(argv[a]) == "--layer") in_process.nrrd_layer = std::atoi(argv[a + 1]);
      }
      const LoadedVolume v = loadVolume(path, in_process);
      writeField(*v.field, v.info, argv[3]);
    } catch (const std::exception& e) {
      std::string message = e.what();
      std::replace(message.begin(), message.end(), '\n', ' ');
      std::cout << "error " << message << std::endl;
      return 1;
    }
    return 0;
  }
  if (mode == "mesh" && argc >= 5) {
    try {
      const haptics::TriangleMesh mesh = detail::loadMeshInProcess(path, std::strtod(argv[4], nullptr));
      std::ofstream f(argv[3], std::ios::binary);
      const std::uint64_t nv = mesh.vertices_T_m.size(), nt = mesh.triangles.size();
      f.write(reinterpret_cast<const char*>(&nv), sizeof(nv));
      f.write(reinterpret_cast<const char*>(&nt), sizeof(nt));
      for (const auto& v : mesh.vertices_T_m) f.write(reinterpret_cast<const char*>(v.data()), 3 * sizeof(double));
      for (const auto& t : mesh.triangles) f.write(reinterpret_cast<const char*>(t.data()), 3 * sizeof(int));
      if (!f) throw LoadError(path.string() + ": cannot hand the mesh back (disk full?)");
    } catch (const std::exception& e) {
      std::string message = e.what();
      std::replace(message.begin(), message.end(), '\n', ' ');
      std::cout << "error " << message << std::endl;
      return 1;
    }
    return 0;
  }
  if (mode == "list" && argc >= 4) {
    try {
      const auto series = detail::listDicomSeriesInProcess(path, [](int done, int total) {
        std::cout << "progress " << done << " " << total << std::endl;
      }, nullptr);
      json list = json::array();
      for (const auto& i : series) list.push_back(seriesToJson(i));
      std::ofstream(argv[3]) << list.dump(-1, ' ', false, json::error_handler_t::replace);
    } catch (const std::exception& e) {
      std::string message = e.what();
      std::replace(message.begin(), message.end(), '\n', ' ');
      std::cout << "error " << message << std::endl;
      return 1;
    }
    return 0;
  }
  if (mode != "load" || argc < 4) {
    std::cerr << usage << std::endl;
    return 2;
  }
  VolumeLoadOptions options;
  options.dicom_isolation = DicomIsolation::kInProcess;
  for (int i = 4; i + 1 < argc; i += 2) {
    const std::string key = argv[i];
    if (key == "--series") options.dicom_series = argv[i + 1];
    else if (key == "--phase") options.dicom_phase = std::atoi(argv[i + 1]);
  }
  double last = -1.0;
  options.progress = [&](double f) {
    if (f - last >= 0.01 || f >= 1.0) {
      last = f;
      std::cout << "progress " << f << std::endl;
    }
  };
  try {
    detail::RawVolume raw = detail::loadDicomRaw(path, options);
    writeRaw(raw, argv[3]);
  } catch (const std::exception& e) {
    std::string message = e.what();
    std::replace(message.begin(), message.end(), '\n', ' ');
    std::cout << "error " << message << std::endl;
    return 1;
  }
  return 0;
}

}  // namespace vh::io
