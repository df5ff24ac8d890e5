// `volume-haptics bench bigscan` ("Big scans"): a 512 x 512 x 2000 int16 CT series
// (1 GiB of voxels) loads with progress and cancel, its peak memory against the voxel bytes,
// the min/max tree build time, and tick times on it next to the small phantom's.
//
// The series is generated once into the build tree from the shared Philips head phantom
// (512 x 512 x 140, 0.451 x 0.451 x 1 mm): resampled to 0.5 mm slices by linear interpolation
// between its slices (which leaves its trilinear field, hence its isosurface, unchanged up to
// rounding to whole stored values) and mirrored every 279 slices along the stack, so there is
// no step, with the phantom's own top at the top (+z of W) of the big scan. 0.5 mm is a
// realistic thin-slice body CT reconstruction; 2000 slices make a 1 m scan. The smallest voxel
// side stays the phantom's 0.451 mm, so the feature size, epsilon and the tool's point shell
// are the same on both volumes and the touch run compares like with like.
//
// The loads run in fresh child processes (this binary re-executed with the hidden
// `--child load|cancel`, started with posix_spawn so that none of the parent's memory is
// copied): their peak resident memory is sampled together with the DICOM worker they start.
#include <sys/resource.h>
#include <sys/wait.h>
#include <spawn.h>
#include <unistd.h>
#include <malloc.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <atomic>
#include <chrono>
#include <thread>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <functional>
#include <iostream>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include <Eigen/Geometry>
#include <vtkCallbackCommand.h>
#include <vtkDICOMCTGenerator.h>
#include <vtkDICOMMetaData.h>
#include <vtkDICOMValue.h>
#include <vtkDICOMWriter.h>
#include <vtkImageData.h>
#include <vtkIntArray.h>
#include <vtkObjectFactory.h>

#include "vh/bench/report.h"
#include "vh/haptics/haptic_renderer.h"
#include "vh/haptics/min_max_tree.h"
#include "vh/io/volume_loader.h"
#include "vh/runtime/scene.h"
#include "vh/runtime/trajectory.h"
#include "vh/runtime/realtime.h"

extern char** environ;

namespace vh::bench {

// Defined in table1.cpp: Table 1's scripted interaction (hover, circle, contact, press, slide,
// pry, wedge, hook, retract at `locations` spots), lasting ticks / 1 kHz.
runtime::Trajectory table1Trajectory(const haptics::ScalarVolume& volume, const haptics::PointShell& shell,
                                     double isovalue, const Eigen::Quaterniond& R0, int ticks, int locations,
                                     std::vector<std::string>* notes);

namespace fs = std::filesystem;

namespace {

constexpr int kFullSlices = 2000;
constexpr int kShortSlices = 64;
constexpr double kSliceSpacing_mm = 0.5;
constexpr double kIsovalue_HU = 400.0;  // bone, as table1's Bone scene
constexpr const char* kPhantom = "ct/philips-head-phantom-bone";
constexpr const char* kResultTag = "bigscan-result: ";
constexpr int kGeneratorVersion = 1;  // bump when the generated content changes

double seconds(std::chrono::steady_clock::time_point since) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - since).count();
}

/// A field of /proc/self/status in bytes (VmHWM, VmRSS: kB there), or -1.
double procStatusBytes(const char* key) {
  std::ifstream in("/proc/self/status");
  std::string line;
  const std::string prefix = std::string(key) + ":";
  while (std::getline(in, line)) {
    if (line.rfind(prefix, 0) == 0) return 1024.0 * std::atof(line.c_str() + prefix.size());
  }
  return -1.0;
}

/// Resident memory [bytes] of this process plus its child processes (a DICOM worker), from
/// /proc/self/status and /proc/PID/status of the pids in /proc/self/task/*/children.
double residentWithChildren() {
  double total = procStatusBytes("VmRSS");
  std::error_code ec;
  for (const auto& task : std::filesystem::directory_iterator("/proc/self/task", ec)) {
    std::ifstream children(task.path() / "children");
    int pid = 0;
    while (children >> pid) {
      std::ifstream status("/proc/" + std::to_string(pid) + "/status");
      std::string line;
      while (std::getline(status, line)) {
        if (line.rfind("VmRSS:", 0) == 0) total += 1024.0 * std::atof(line.c_str() + 6);
      }
    }
  }
  return total;
}

/// Samples residentWithChildren() every 5 ms on a thread of its own; peak() is the largest seen:
/// the memory the load held at one time, the loader's worker process included.
class ConcurrentPeak {
 public:
  ConcurrentPeak() : thread_([this] {
      while (!stop_.load()) {
        const double now = residentWithChildren();
        double old = peak_.load();
        while (now > old && !peak_.compare_exchange_weak(old, now)) {
        }
        std::this_thread::sleep_for(std::chrono::milliseconds(5));
      }
    }) {}
  ~ConcurrentPeak() { stopNow(); }
  double stopNow() {
    stop_ = true;
    if (thread_.joinable()) thread_.join();
    return peak_.load();
  }

 private:
  std::atomic<bool> stop_{false};
  std::atomic<double> peak_{0.0};
  std::thread thread_;
};

double gib(double bytes) { return bytes / (1024.0 * 1024.0 * 1024.0); }
double mib(double bytes) { return bytes / (1024.0 * 1024.0); }

// ---------------------------------------------------------------- generating the series

/// vtk-dicom's CT generator with the per-file geometry written explicitly (as the io test
/// fixtures do): position, orientation, slice location and instance number of each file.
class BigScanCTGenerator : public vtkDICOMCTGenerator {
 public:
  static BigScanCTGenerator* New();
  vtkTypeMacro(BigScanCTGenerator, vtkDICOMCTGenerator)
  std::function<bool(vtkDICOMMetaData*, vtkIntArray*)> patch;
  bool GenerateInstance(vtkInformation* info) override { return GenerateCTInstance(info) && patch(MetaData, SliceIndexArray); }
};
vtkStandardNewMacro(BigScanCTGenerator);

/// The generated series: where, its size, and whether this run wrote it.
struct SeriesInfo {
  fs::path dir;
  int nx = 0, ny = 0, nz = 0;
  double spacing_mm[3] = {0, 0, 0};
  bool generated = false;  ///< Written in this run (else reused).
  double generate_s = 0.0;
  double disk_bytes = 0.0;  ///< Bytes of the files.
};

constexpr const char* kMarker = "bigscan-series.json";

/// True when `dir` holds a complete series of `nz` slices written by this generator version.
bool seriesComplete(const fs::path& dir, int nz, SeriesInfo& info) {
  std::ifstream in(dir / kMarker);
  if (!in) return false;
  nlohmann::json j;
  try {
    in >> j;
  } catch (const std::exception&) {
    return false;
  }
  if (j.value("version", 0) != kGeneratorVersion || j.value("nz", 0) != nz) return false;
  std::size_t files = 0;
  double bytes = 0.0;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(dir, ec)) {
    if (e.path().extension() == ".dcm") {
      ++files;
      bytes += static_cast<double>(e.file_size(ec));
    }
  }
  if (ec || files != static_cast<std::size_t>(nz)) return false;
  info.nx = j.value("nx", 0);
  info.ny = j.value("ny", 0);
  info.nz = nz;
  for (int a = 0; a < 3; ++a) info.spacing_mm[a] = j["spacing_mm"][static_cast<std::size_t>(a)].get<double>();
  info.disk_bytes = bytes;
  return true;
}

/// The phantom's fine slice (0 .. fine_last = 2 (n - 1); the even ones are its slices, the odd
/// ones midway between two) that big slice k shows: a triangle wave, so the stack is mirrored
/// without a step, with the phantom's top end at the big scan's top end (+z of W).
int fineSlice(int k, int nz, int fine_last, bool top_at_k_max) {
  const int x = top_at_k_max ? fine_last + (nz - 1 - k) : k;
  const int r = x % (2 * fine_last);
  return r <= fine_last ? r : 2 * fine_last - r;
}

/// Refuses to generate when the disk of `dir` has less than 3 times the voxel bytes of an
/// nx x ny x nz int16 series free (the files take the voxel bytes plus headers); removes `dir`
/// then. @throws std::runtime_error saying how much is free and needed.
void requireFreeSpace(const fs::path& dir, int nx, int ny, int nz) {
  std::error_code ec;
  const double voxel_bytes = 2.0 * nx * ny * static_cast<double>(nz);
  const double need = std::max(3.0 * voxel_bytes, 64.0 * 1024 * 1024);
  const fs::space_info space = fs::space(dir, ec);
  if (ec) throw std::runtime_error(dir.string() + ": cannot read the free disk space: " + ec.message());
  std::cout << "bench bigscan: " << format("%.1f", gib(static_cast<double>(space.available)))
            << " GiB free on the build tree's disk; the series needs " << format("%.2f", gib(voxel_bytes))
            << " GiB (refusing below " << format("%.1f", gib(need)) << " GiB)\n";
  if (static_cast<double>(space.available) < need) {
    fs::remove_all(dir, ec);
    throw std::runtime_error(format("only %.2f GiB free on the disk of %s; generating the %d-slice series needs "
                                    "at least %.2f GiB free: free some space or pass --series-dir on another disk",
                                    gib(static_cast<double>(space.available)), dir.string().c_str(), nz,
                                    gib(need)));
  }
}

/// The big scan's voxels in stored int16 (HU = slope * stored + intercept): nz slices of the
/// phantom `pf` dx x dy x dz [mm] apart, slice k showing fineSlice() (a phantom slice, or the
/// mean of two neighbours), its top at k = nz - 1 when top_at_k_max.
vtkSmartPointer<vtkImageData> resampledStack(const haptics::ScalarVolume& pf, int nz, double dx, double dy, double dz,
                                             bool top_at_k_max, double slope, double intercept) {
  const haptics::VolumeGeometry& pg = pf.geometry();
  const int nx = pg.dims[0], ny = pg.dims[1], pn = pg.dims[2];
  std::vector<float> hu(static_cast<std::size_t>(nx) * ny * pn);
  for (int k = 0; k < pn; ++k)
    for (int j = 0; j < ny; ++j)
      for (int i = 0; i < nx; ++i)
        hu[(static_cast<std::size_t>(k) * ny + j) * nx + i] = static_cast<float>(pf.voxel(i, j, k));
  const auto stored = [&](double v) {
    return static_cast<short>(std::clamp(std::round((v - intercept) / slope), -32768.0, 32767.0));
  };
  const int fine_last = 2 * (pn - 1);

  auto staging = vtkSmartPointer<vtkImageData>::New();
  staging->SetDimensions(nx, ny, nz);
  staging->SetSpacing(dx, dy, dz);
  staging->AllocateScalars(VTK_SHORT, 1);
  auto* dst = static_cast<short*>(staging->GetScalarPointer());
  const std::size_t plane = static_cast<std::size_t>(nx) * ny;
  for (int k = 0; k < nz; ++k) {
    const int f = fineSlice(k, nz, fine_last, top_at_k_max);
    const float* a = &hu[static_cast<std::size_t>(f / 2) * plane];
    const float* b = &hu[static_cast<std::size_t>(std::min(f / 2 + 1, pn - 1)) * plane];
    short* out = dst + static_cast<std::size_t>(k) * plane;
    if (f % 2 == 0) {
      for (std::size_t p = 0; p < plane; ++p) out[p] = stored(a[p]);
    } else {
      for (std::size_t p = 0; p < plane; ++p) out[p] = stored(0.5 * (static_cast<double>(a[p]) + b[p]));
    }
  }
  return staging;
}

/// Where the series lies in patient LPS [mm]: the phantom's row and column directions, its
/// stacking direction w, its first voxel o_mm, and dz between slices.
struct SeriesGeometry {
  Eigen::Vector3d row, col, w, o_mm;
  double dz = 0.0;
};

/// Writes `staging` as one DICOM file per slice (CT0000.dcm ...) into `dir`, with each file's
/// position, orientation, slice location and instance number from `geo`; progress every 10 %.
/// Releases `staging` before it returns. @throws std::runtime_error (removing `dir`) on failure.
void writeDicomSeries(const fs::path& dir, vtkSmartPointer<vtkImageData> staging, const SeriesGeometry& geo,
                      double slope, double intercept) {
  int dims[3];
  staging->GetDimensions(dims);
  const int nx = dims[0], ny = dims[1], nz = dims[2];
  const Eigen::Vector3d &row = geo.row, &col = geo.col, &w = geo.w, &o_mm = geo.o_mm;
  const double dz = geo.dz;
  auto tags = vtkSmartPointer<vtkDICOMMetaData>::New();
  tags->Set(DC::Modality, "CT");
  tags->Set(DC::PatientName, "VolumeHaptics^BigScan");
  tags->Set(DC::PatientID, "VH-BIGSCAN");
  tags->Set(DC::Manufacturer, "VolumeHaptics bench bigscan");
  tags->Set(DC::SeriesNumber, 1);
  tags->Set(DC::ImageType, "DERIVED\\SECONDARY\\AXIAL");
  tags->Set(DC::BodyPartExamined, "HEAD");
  const Eigen::Vector3d normal = row.cross(col).normalized();
  auto generator = vtkSmartPointer<BigScanCTGenerator>::New();
  generator->patch = [&](vtkDICOMMetaData* meta, vtkIntArray* slice_index) {
    const double orientation[6] = {row.x(), row.y(), row.z(), col.x(), col.y(), col.z()};
    for (int i = 0; i < meta->GetNumberOfInstances(); ++i) {
      const int k = static_cast<int>(slice_index->GetComponent(i, 0));
      const Eigen::Vector3d p = o_mm + k * dz * w;
      meta->Set(i, DC::InstanceNumber, i + 1);
      meta->Set(i, DC::ImagePositionPatient, vtkDICOMValue(vtkDICOMVR::DS, p.data(), 3));
      meta->Set(i, DC::ImageOrientationPatient, vtkDICOMValue(vtkDICOMVR::DS, orientation, 6));
      meta->Set(i, DC::SliceLocation, p.dot(normal));
    }
    meta->Set(DC::SliceThickness, dz);
    return true;
  };
  // Progress every 10 % of the files.
  struct WriteProgress {
    double next = 0.1;
    std::chrono::steady_clock::time_point t0;
  } wp{0.1, std::chrono::steady_clock::now()};
  auto observer = vtkSmartPointer<vtkCallbackCommand>::New();
  observer->SetClientData(&wp);
  observer->SetCallback([](vtkObject*, unsigned long, void* client, void* call) {
    auto* p = static_cast<WriteProgress*>(client);
    const double f = call ? *static_cast<double*>(call) : 0.0;
    if (f + 1e-9 >= p->next) {
      std::cout << "bench bigscan: writing " << format("%3.0f", 100.0 * f) << " % ("
                << format("%.1f", seconds(p->t0)) << " s)" << std::endl;
      while (p->next <= f + 1e-9) p->next += 0.1;
    }
  });
  auto writer = vtkSmartPointer<vtkDICOMWriter>::New();
  writer->AddObserver(vtkCommand::ProgressEvent, observer);
  writer->SetInputData(staging);
  writer->SetGenerator(generator);
  writer->SetMetaData(tags);
  writer->SetSeriesDescription(format("bigscan %d x %d x %d (Philips head phantom, mirrored, 0.5 mm)", nx, ny, nz).c_str());
  writer->SetRescaleSlope(slope);
  writer->SetRescaleIntercept(intercept);
  writer->SetMemoryRowOrderToTopDown();  // staging row 0 is file row 0 (the phantom's row 0)
  writer->SetFileSliceOrderToSame();     // staging slice k is file k
  writer->SetFileDimensionality(2);
  writer->SetFilePrefix((dir / "CT").string().c_str());
  writer->SetFilePattern("%s%04d.dcm");
  std::cout << "bench bigscan: writing " << nz << " DICOM files of " << nx << " x " << ny << " int16 into "
            << dir.string() << " ..." << std::endl;
  writer->Write();
  if (writer->GetErrorCode() != 0) {
    std::error_code ec;
    fs::remove_all(dir, ec);
    throw std::runtime_error(dir.string() + ": vtkDICOMWriter failed (error code " +
                             std::to_string(writer->GetErrorCode()) + ")");
  }
}

/// The marker file that makes a series complete (seriesComplete()): the generator version, the
/// size and spacing [mm], the phantom it came from and the rescale of its stored values.
void writeSeriesMarker(const fs::path& dir, const fs::path& phantom_dir, int nx, int ny, int nz, double dx, double dy,
                       double dz, double slope, double intercept) {
  nlohmann::json marker;
  marker["version"] = kGeneratorVersion;
  marker["nx"] = nx;
  marker["ny"] = ny;
  marker["nz"] = nz;
  marker["spacing_mm"] = {dx, dy, dz};
  marker["source"] = phantom_dir.string();
  marker["rescale"] = {{"slope", slope}, {"intercept", intercept}};
  marker["date_utc"] = utcNow();
  writeText(dir / kMarker, marker.dump(2) + "\n");
}

/// Generates (or finds complete) the big series in `dir` from the phantom at `phantom_dir`.
/// @throws std::runtime_error when too little disk space is free or writing fails.
SeriesInfo generateSeries(const fs::path& dir, const fs::path& phantom_dir, int nz) {
  SeriesInfo info;
  info.dir = dir;
  if (seriesComplete(dir, nz, info)) {
    std::cout << "bench bigscan: reusing the complete series in " << dir.string() << " (" << nz << " files, "
              << format("%.2f", gib(info.disk_bytes)) << " GiB)\n";
    return info;
  }
  const auto t0 = std::chrono::steady_clock::now();
  std::error_code ec;
  fs::remove_all(dir, ec);  // an incomplete earlier attempt
  fs::create_directories(dir, ec);
  if (ec) throw std::runtime_error(dir.string() + ": cannot create the series folder: " + ec.message());

  std::cout << "bench bigscan: reading the phantom " << phantom_dir.string() << " ..." << std::endl;
  const io::LoadedVolume phantom = io::loadVolume(phantom_dir);
  const haptics::ScalarVolume& pf = *phantom.field;
  const haptics::VolumeGeometry& pg = pf.geometry();
  const int nx = pg.dims[0], ny = pg.dims[1];

  requireFreeSpace(dir, nx, ny, nz);

  // Stored int16 = HU + 1024 (rescale slope 1, intercept -1024), phantom slices in HU.
  const double slope = 1.0, intercept = -1024.0;
  // Geometry: the phantom's rows, columns and stacking direction; 0.5 mm between slices.
  const Eigen::Matrix3d& D = pg.direction_W;
  const Eigen::Vector3d row = D.col(0), col = D.col(1), w = D.col(2);
  const double dx = 1e3 * pg.spacing_m.x(), dy = 1e3 * pg.spacing_m.y(), dz = kSliceSpacing_mm;
  const Eigen::Vector3d o_mm = 1e3 * pg.origin_W_m;  // W is patient LPS [m]
  const bool top_at_k_max = w.z() > 0.0;
  writeDicomSeries(dir, resampledStack(pf, nz, dx, dy, dz, top_at_k_max, slope, intercept),
                   SeriesGeometry{row, col, w, o_mm, dz}, slope, intercept);
  writeSeriesMarker(dir, phantom_dir, nx, ny, nz, dx, dy, dz, slope, intercept);
  if (!seriesComplete(dir, nz, info)) throw std::runtime_error(dir.string() + ": the written series is incomplete");
  info.generated = true;
  info.generate_s = seconds(t0);
  std::cout << "bench bigscan: wrote " << nz << " files (" << format("%.2f", gib(info.disk_bytes)) << " GiB) in "
            << format("%.1f", info.generate_s) << " s\n";
  return info;
}

// ---------------------------------------------------------------- child processes

/// Prints one progress line per 10 % of a load and keeps the (fraction, seconds) timeline.
struct ProgressPrinter {
  std::chrono::steady_clock::time_point t0 = std::chrono::steady_clock::now();
  double next = 0.1;
  nlohmann::json timeline = nlohmann::json::array();
  void operator()(double f, const char* what) {
    if (f + 1e-9 < next) return;
    const double t = seconds(t0);
    std::cout << "  " << what << ": " << format("%3.0f", 100.0 * f) << " % (" << format("%.2f", t) << " s)"
              << std::endl;
    timeline.push_back({f, t});
    while (next <= f + 1e-9) next += 0.1;
  }
};

haptics::MinMaxTree buildTree(const haptics::ScalarVolume& field) {
  const std::byte* b = field.bytes().data();
  const std::array<int, 3>& dims = field.geometry().dims;
  switch (field.voxelType()) {
    case haptics::VoxelType::kUInt8: return haptics::MinMaxTree::Build(reinterpret_cast<const std::uint8_t*>(b), dims);
    case haptics::VoxelType::kInt16: return haptics::MinMaxTree::Build(reinterpret_cast<const std::int16_t*>(b), dims);
    case haptics::VoxelType::kUInt16: return haptics::MinMaxTree::Build(reinterpret_cast<const std::uint16_t*>(b), dims);
    case haptics::VoxelType::kFloat32: return haptics::MinMaxTree::Build(reinterpret_cast<const float*>(b), dims);
  }
  return {};
}

int childLoad(const BigScanOptions& options) {
  nlohmann::json r;
  r["rss_before_bytes"] = procStatusBytes("VmRSS");
  ProgressPrinter printer;
  io::VolumeLoadOptions lo;
  lo.progress = [&](double f) { printer(f, "load"); };
  const auto t0 = std::chrono::steady_clock::now();
  ConcurrentPeak sampler;
  io::LoadedVolume v = io::loadVolume(options.series_dir, lo);
  r["load_s"] = seconds(t0);
  r["peak_concurrent_bytes"] = sampler.stopNow();
  r["peak_rss_bytes"] = procStatusBytes("VmHWM");
  r["rss_after_load_bytes"] = procStatusBytes("VmRSS");
  // Processes the loader itself started and waited for (a DICOM reading worker), if
  // any: their peak counts too (the sum of both peaks bounds the memory at any one time).
  rusage children{};
  getrusage(RUSAGE_CHILDREN, &children);
  r["loader_children_peak_rss_bytes"] = 1024.0 * static_cast<double>(children.ru_maxrss);
  const haptics::ScalarVolume& field = *v.field;
  const haptics::VolumeGeometry& g = field.geometry();
  r["dims"] = g.dims;
  r["spacing_m"] = {g.spacing_m.x(), g.spacing_m.y(), g.spacing_m.z()};
  r["voxel_type"] = haptics::voxelTypeName(field.voxelType());
  r["voxel_bytes"] = static_cast<double>(field.bytes().size());
  r["image_bytes"] = v.image ? static_cast<double>(v.image->GetActualMemorySize()) * 1024.0 : 0.0;
  // One copy of the voxels: the rendering image's scalars are the field's own buffer.
  r["image_shares_field"] = v.image != nullptr && v.image->GetScalarPointer() == static_cast<const void*>(field.bytes().data());
  r["value_range"] = {field.minValue(), field.maxValue()};
  r["notices"] = v.info.notices;
  r["progress"] = printer.timeline;
  // The min/max tree alone on the loaded voxels (the loader built one already, inside load_s).
  std::vector<double> tree_s;
  int levels = 0;
  for (int rep = 0; rep < 3; ++rep) {
    const auto t1 = std::chrono::steady_clock::now();
    const haptics::MinMaxTree tree = buildTree(field);
    tree_s.push_back(seconds(t1));
    levels = tree.levels();
  }
  std::sort(tree_s.begin(), tree_s.end());
  r["tree_build_s"] = tree_s;  // sorted, 3 repetitions
  r["tree_build_median_s"] = tree_s[1];
  r["tree_levels"] = levels;
  // The whole ScalarVolume construction (range, Lipschitz bound, tree) on a copy made beforehand
  // (after the peak above was read: the copy is not the loader's memory).
  {
    std::vector<std::byte> copy = field.bytes();
    const auto t1 = std::chrono::steady_clock::now();
    const haptics::ScalarVolume again =
        haptics::ScalarVolume::FromBytes(g, field.voxelType(), std::move(copy), field.valueScale(), field.valueOffset());
    r["scalar_volume_build_s"] = seconds(t1);
  }
  std::cout << kResultTag << r.dump() << std::endl;
  return 0;
}

int childCancel(const BigScanOptions& options) {
  nlohmann::json r;
  r["rss_before_bytes"] = procStatusBytes("VmRSS");
  std::atomic<bool> cancel{false};
  std::chrono::steady_clock::time_point t_flag{};
  double flag_fraction = -1.0;
  ProgressPrinter printer;
  io::VolumeLoadOptions lo;
  lo.cancel = &cancel;
  lo.progress = [&](double f) {
    printer(f, "load (to be cancelled)");
    if (!cancel.load(std::memory_order_relaxed) && f >= options.cancel_at) {
      flag_fraction = f;
      t_flag = std::chrono::steady_clock::now();
      cancel.store(true, std::memory_order_relaxed);
      std::cout << "  cancel flag set at " << format("%.1f", 100.0 * f) << " %" << std::endl;
    }
  };
  const auto t0 = std::chrono::steady_clock::now();
  bool cancelled = false;
  std::string message;
  try {
    const io::LoadedVolume v = io::loadVolume(options.series_dir, lo);
  } catch (const io::LoadCancelled& e) {
    cancelled = true;
    message = e.what();
  }
  const auto t_end = std::chrono::steady_clock::now();
  r["cancelled"] = cancelled;
  r["message"] = message;
  r["flag_fraction"] = flag_fraction;
  r["flag_after_s"] = flag_fraction >= 0.0 ? std::chrono::duration<double>(t_flag - t0).count() : -1.0;
  r["latency_ms"] = flag_fraction >= 0.0 ? 1e3 * std::chrono::duration<double>(t_end - t_flag).count() : -1.0;
  r["peak_rss_bytes"] = procStatusBytes("VmHWM");
  r["rss_after_bytes"] = procStatusBytes("VmRSS");
  rusage children{};
  getrusage(RUSAGE_CHILDREN, &children);  // the loader's worker process, if any
  r["loader_children_peak_rss_bytes"] = 1024.0 * static_cast<double>(children.ru_maxrss);
  malloc_trim(0);
  r["rss_after_trim_bytes"] = procStatusBytes("VmRSS");
  r["progress"] = printer.timeline;
  std::cout << kResultTag << r.dump() << std::endl;
  return 0;
}

/// Runs this binary again as `bench bigscan --child MODE --series-dir DIR` (posix_spawn: no copy
/// of this process's memory), echoes its output and returns its result line's JSON, with the
/// child's ru_maxrss from wait4 added. @throws std::runtime_error when it cannot start, fails or
/// prints no result.
nlohmann::json runChild(const std::string& mode, const BigScanOptions& options) {
  const std::string exe = fs::read_symlink("/proc/self/exe").string();
  std::vector<std::string> args{exe,     "bench",       "bigscan", "--child", mode, "--series-dir", options.series_dir.string(),
                                "--cancel-at", format("%.17g", options.cancel_at)};
  std::vector<char*> argv;
  for (std::string& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  int fds[2];
  if (::pipe(fds) != 0) throw std::runtime_error(std::string("pipe: ") + std::strerror(errno));
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_adddup2(&actions, fds[1], STDOUT_FILENO);
  posix_spawn_file_actions_addclose(&actions, fds[0]);
  posix_spawn_file_actions_addclose(&actions, fds[1]);
  pid_t pid = 0;
  std::cout.flush();
  const auto t0 = std::chrono::steady_clock::now();
  const int rc = posix_spawn(&pid, exe.c_str(), &actions, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  ::close(fds[1]);
  if (rc != 0) {
    ::close(fds[0]);
    throw std::runtime_error("cannot start " + exe + ": " + std::strerror(rc));
  }
  std::string pending, result;
  char buf[4096];
  for (;;) {
    const ssize_t n = ::read(fds[0], buf, sizeof buf);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) break;
    pending.append(buf, static_cast<std::size_t>(n));
    for (std::size_t nl; (nl = pending.find('\n')) != std::string::npos;) {
      const std::string line = pending.substr(0, nl);
      pending.erase(0, nl + 1);
      if (line.rfind(kResultTag, 0) == 0) result = line.substr(std::strlen(kResultTag));
      else std::cout << line << std::endl;
    }
  }
  ::close(fds[0]);
  int status = 0;
  rusage ru{};
  while (::wait4(pid, &status, 0, &ru) < 0 && errno == EINTR) {
  }
  if (!WIFEXITED(status) || WEXITSTATUS(status) != 0)
    throw std::runtime_error("the " + mode + " child failed (" +
                             (WIFEXITED(status) ? "exit code " + std::to_string(WEXITSTATUS(status))
                                                : "signal " + std::to_string(WTERMSIG(status))) +
                             ")");
  if (result.empty()) throw std::runtime_error("the " + mode + " child printed no result");
  nlohmann::json j = nlohmann::json::parse(result);
  j["ru_maxrss_bytes"] = 1024.0 * static_cast<double>(ru.ru_maxrss);
  j["child_wall_s"] = seconds(t0);
  return j;
}

// ---------------------------------------------------------------- ticks side by side

/// Table 1's Bone scene on `volume`: the CHAI3D drill (100 mm, burr down, 518 points) at 400 HU,
/// or the built-in probe when the drill mesh is absent.
runtime::SceneSpec touchScene(const fs::path& volume, std::string& tool_label) {
  runtime::SceneSpec spec;
  spec.volume.path = volume.string();
  spec.volume.isovalue = kIsovalue_HU;
  spec.volume.isovalue_set = true;
  const fs::path drill = runtime::sharedDatasetsDir() / "meshes/drill/drill.stl";
  if (fs::exists(drill)) {
    spec.tool.mesh = drill.string();
    spec.tool.scale_to_m = 0.00044;
    spec.tool.point_count = 518;
    spec.tool.X_WT_initial.R_AB = Eigen::Quaterniond(0.7071067811865476, 0.0, -0.7071067811865476, 0.0);
    spec.tool.initial_orientation_set = true;
    tool_label = "drill with ball burr (100 mm, 518 points)";
  } else {
    spec.tool.mesh = "builtin:probe";
    tool_label = "built-in probe (the drill mesh is absent)";
  }
  return spec;
}

struct TouchRun {
  std::unique_ptr<haptics::HapticRenderer> renderer;
  runtime::Trajectory trajectory;
  std::vector<double> wall_us, cpu_us;
  double contacts_sum = 0.0, tree_nodes_sum = 0.0, samples_sum = 0.0;
  std::int64_t in_contact = 0, nan_ticks = 0, budget_cuts = 0, over_1ms = 0;
  std::vector<std::string> notes;
};

nlohmann::ordered_json touchJson(const TouchRun& r, const runtime::LoadedScene& scene) {
  const Stats w = summarize(r.wall_us), c = summarize(r.cpu_us);
  const double n = std::max<double>(1.0, static_cast<double>(r.wall_us.size()));
  const haptics::VolumeGeometry& g = scene.volume.field->geometry();
  nlohmann::ordered_json j;
  j["volume"] = scene.spec.volume.path;
  j["dims"] = g.dims;
  j["spacing_m"] = {g.spacing_m.x(), g.spacing_m.y(), g.spacing_m.z()};
  j["voxel_bytes"] = static_cast<double>(scene.volume.field->bytes().size());
  j["tree_levels"] = scene.volume.field->minMaxTree().levels();
  j["epsilon_m"] = r.renderer->epsilon_m();
  j["points"] = scene.tool->point_shell.size();
  j["ticks"] = w.n;
  j["mean_us"] = w.mean;
  j["p50_us"] = w.p50;
  j["p99_us"] = w.p99;
  j["p99_9_us"] = w.p999;
  j["max_us"] = w.max;
  j["cpu_mean_us"] = c.mean;
  j["cpu_p99_9_us"] = c.p999;
  j["cpu_max_us"] = c.max;
  j["ticks_over_1ms"] = r.over_1ms;
  j["ticks_in_contact"] = r.in_contact;
  j["mean_contacts"] = r.contacts_sum / n;
  j["mean_tree_nodes"] = r.tree_nodes_sum / n;
  j["mean_volume_samples"] = r.samples_sum / n;
  j["budget_cuts"] = r.budget_cuts;
  j["nan_ticks"] = r.nan_ticks;
  j["trajectory_notes"] = r.notes;
  return j;
}

/// The same touch run on the small phantom and on the big scan, interleaved tick by tick
/// (alternating which goes first), each with its trajectory placed on its own volume.
nlohmann::ordered_json touchSideBySide(const fs::path& small_path, const fs::path& big_path, int ticks,
                                       int locations) {
  std::string tool_label;
  const runtime::SceneSpec small_spec = touchScene(small_path, tool_label);
  const runtime::SceneSpec big_spec = touchScene(big_path, tool_label);
  std::cout << "bench bigscan: loading the touch scenes (" << tool_label << ", " << kIsovalue_HU << " HU) ..."
            << std::endl;
  auto t0 = std::chrono::steady_clock::now();
  const runtime::LoadedScene small = runtime::loadScene(small_spec);
  const double small_load_s = seconds(t0);
  t0 = std::chrono::steady_clock::now();
  const runtime::LoadedScene big = runtime::loadScene(big_spec);
  const double big_load_s = seconds(t0);
  std::cout << "bench bigscan: scenes loaded (phantom " << format("%.1f", small_load_s) << " s, big scan "
            << format("%.1f", big_load_s) << " s); " << ticks << " ticks each, interleaved ..." << std::endl;

  std::vector<TouchRun> runs(2);
  const runtime::LoadedScene* scenes[2] = {&small, &big};
  for (std::size_t r = 0; r < 2; ++r) {
    const runtime::LoadedScene& s = *scenes[r];
    runs[r].trajectory = table1Trajectory(*s.volume.field, s.tool->point_shell, s.isovalue,
                                          s.spec.tool.X_WT_initial.R_AB, ticks, locations, &runs[r].notes);
    haptics::RendererOptions ro;  // the application's defaults (accelerated, work budget)
    ro.gains = s.spec.gains;
    runs[r].renderer = std::make_unique<haptics::HapticRenderer>(s.volume.field, s.tool, ro,
                                                                 runs[r].trajectory.samples().front().X_WD, s.isovalue);
    runs[r].wall_us.reserve(static_cast<std::size_t>(ticks));
    runs[r].cpu_us.reserve(static_cast<std::size_t>(ticks));
  }
  std::size_t cursor[2] = {0, 0};
  const auto t_run = std::chrono::steady_clock::now();
  for (int i = 0; i < ticks; ++i) {
    for (std::size_t q = 0; q < 2; ++q) {
      const std::size_t r = (i % 2 == 0) ? q : 1 - q;
      TouchRun& m = runs[r];
      const haptics::Pose X_WD = m.trajectory.poseAt(i * 1e-3, cursor[r]);
      const double c0 = runtime::threadCpuTime_us();
      const haptics::TickOutput out = m.renderer->tick(X_WD, scenes[r]->isovalue);
      m.cpu_us.push_back(runtime::threadCpuTime_us() - c0);
      m.wall_us.push_back(out.stats.exec_time_us);
      m.contacts_sum += out.stats.contacts;
      m.tree_nodes_sum += static_cast<double>(out.stats.tree_nodes);
      m.samples_sum += static_cast<double>(out.stats.volume_samples);
      m.in_contact += out.stats.contacts > 0;
      m.budget_cuts += out.stats.budget_cut;
      m.over_1ms += out.stats.exec_time_us > 1000.0;
      if (!(out.force_W_N.allFinite() && out.X_WP.allFinite())) ++m.nan_ticks;
    }
  }
  nlohmann::ordered_json j;
  j["tool"] = tool_label;
  j["isovalue_HU"] = kIsovalue_HU;
  j["ticks"] = ticks;
  j["spots"] = locations;
  j["detection_mode"] = "accelerated (application defaults, work budget)";
  j["run_s"] = seconds(t_run);
  j["load_s"] = {{"phantom", small_load_s}, {"bigscan", big_load_s}};
  j["phantom"] = touchJson(runs[0], small);
  j["bigscan"] = touchJson(runs[1], big);
  const auto ratio = [](double a, double b) { return b > 0.0 ? a / b : 0.0; };
  const auto& a = j["bigscan"];
  const auto& b = j["phantom"];
  j["ratio_bigscan_over_phantom"] = {{"mean", ratio(a["mean_us"], b["mean_us"])},
                                     {"p99_9", ratio(a["p99_9_us"], b["p99_9_us"])},
                                     {"max", ratio(a["max_us"], b["max_us"])},
                                     {"cpu_mean", ratio(a["cpu_mean_us"], b["cpu_mean_us"])},
                                     {"cpu_p99_9", ratio(a["cpu_p99_9_us"], b["cpu_p99_9_us"])},
                                     {"cpu_max", ratio(a["cpu_max_us"], b["cpu_max_us"])}};
  return j;
}

/// The generated series for the report: where, its size and spacing, its files and whether
/// this run wrote it; voxel_bytes: its int16 voxels' bytes.
nlohmann::ordered_json seriesJson(const SeriesInfo& series, double voxel_bytes) {
  return {{"dir", series.dir.string()},
          {"dims", {series.nx, series.ny, series.nz}},
          {"spacing_mm", {series.spacing_mm[0], series.spacing_mm[1], series.spacing_mm[2]}},
          {"voxel_type", "int16"},
          {"voxel_bytes", voxel_bytes},
          {"files", series.nz},
          {"disk_bytes", series.disk_bytes},
          {"generated_now", series.generated},
          {"generate_s", series.generate_s},
          {"source", std::string(kPhantom) + ", resampled to 0.5 mm slices, mirrored along the stack"}};
}

/// The load in a fresh process: its result with the peak memory against `voxel_bytes`.
nlohmann::json measureLoad(const BigScanOptions& o, const SeriesInfo& series, double voxel_bytes) {
  std::cout << "bench bigscan: loading " << series.nx << " x " << series.ny << " x " << series.nz
            << " in a fresh process (io::loadVolume) ..." << std::endl;
  nlohmann::json load = runChild("load", o);
  // The sum of the two processes' peaks bounds the memory from above (reported); the measure is
  // the sampled peak of both together (the application waits for its worker to end before it
  // takes the voxels, so the two peaks do not coincide), but never below this process's own.
  load["peak_sum_bytes"] = load["peak_rss_bytes"].get<double>() + load["loader_children_peak_rss_bytes"].get<double>();
  const double peak = std::max(load["peak_concurrent_bytes"].get<double>(), load["peak_rss_bytes"].get<double>());
  load["peak_total_bytes"] = peak;
  const double ratio = peak / voxel_bytes;
  load["peak_over_voxel_bytes"] = ratio;
  // The process's own resident memory before the load (libraries: Qt, VTK) is part of the peak;
  // on a small scan it dominates, so the growth during the load is reported as well.
  load["peak_above_start_over_voxel_bytes"] = (peak - load["rss_before_bytes"].get<double>()) / voxel_bytes;
  load["within_2_5x"] = ratio <= 2.5;
  return load;
}

/// A cancelled load in another fresh process: its result, with whether the memory was released
/// (grew by less than a tenth of `voxel_bytes`).
nlohmann::json measureCancel(const BigScanOptions& o, double voxel_bytes) {
  std::cout << "bench bigscan: loading again, cancelled at " << format("%.0f", 100.0 * o.cancel_at)
            << " % progress ..." << std::endl;
  nlohmann::json cancel = runChild("cancel", o);
  const double rss_before = cancel["rss_before_bytes"].get<double>();
  const double rss_after = cancel["rss_after_bytes"].get<double>();
  cancel["released"] = rss_after - rss_before < 0.1 * voxel_bytes;
  return cancel;
}

/// The paragraph on the scan and how it was measured, and the table of the load and the cancel.
void writeLoadTable(std::ostringstream& md, const nlohmann::ordered_json& report, const SeriesInfo& series,
                    double voxel_bytes) {
  const auto& ld = report["load"];
  const auto& cc = report["cancel"];
  const double peak = ld["peak_total_bytes"].get<double>();
  const double ratio = ld["peak_over_voxel_bytes"].get<double>();
  const double rss_before = cc["rss_before_bytes"].get<double>();
  const double rss_after = cc["rss_after_bytes"].get<double>();
  md << "Run " << report["date_utc"].get<std::string>() << " on " << report["cpu_model"].get<std::string>() << " ("
     << cpuCount() << " CPUs, " << report["build"].get<std::string>() << "). The scan: " << series.nx << " x "
     << series.ny << " x " << series.nz << " int16 CT, "
     << format("%.3f x %.3f x %.2f", series.spacing_mm[0], series.spacing_mm[1], series.spacing_mm[2]) << " mm, "
     << series.nz << " DICOM files (" << format("%.2f", gib(series.disk_bytes))
     << " GiB), generated from the Philips head phantom (0.5 mm slices interpolated between its 1 mm ones, mirrored "
        "along the stack, its top at the top); "
     << (series.generated ? format("written in %.1f s this run", series.generate_s) : std::string("reused"))
     << ". Loads in fresh child processes; peak memory: the child and the processes the loader started (its "
        "DICOM worker) together, sampled every 5 ms, and never below the child's own VmHWM (the loader waits "
        "for its worker to end before it takes the voxels, so their peaks do not coincide; the sum of the two is "
        "given as a bound). Tick times: "
        "the CPU-time columns are the ones to read on a shared machine (a preempted tick inflates the wall time).\n\n";
  md << "| what | value |\n|---|---|\n";
  md << "| voxel bytes | " << format("%.0f MiB", mib(voxel_bytes)) << " |\n";
  md << "| load time (io::loadVolume) | " << format("%.2f s", ld["load_s"].get<double>()) << " |\n";
  md << "| peak resident memory, this process and its DICOM worker together (sampled every 5 ms; at least VmHWM) | "
     << format("%.0f MiB", mib(peak)) << " |\n";
  md << "| peaks of each: the loading process (VmHWM) / the DICOM worker (ru_maxrss); their sum | "
     << format("%.0f / %.0f MiB; %.0f MiB", mib(ld["peak_rss_bytes"].get<double>()),
               mib(ld["loader_children_peak_rss_bytes"].get<double>()), mib(ld["peak_sum_bytes"].get<double>()))
     << " |\n";
  md << "| peak / voxel bytes (target <= 2.5) | " << format("%.2f", ratio) << (ratio <= 2.5 ? " (met)" : " (NOT MET)")
     << " |\n";
  md << "| peak minus the child's resident memory before the load (" << format("%.0f MiB", mib(ld["rss_before_bytes"].get<double>()))
     << ") / voxel bytes | " << format("%.2f", ld["peak_above_start_over_voxel_bytes"].get<double>()) << " |\n";
  {
    std::string timeline;
    for (const auto& p : ld["progress"]) {
      if (!timeline.empty()) timeline += ", ";
      timeline += format("%.0f %% at %.2f s", 100.0 * p[0].get<double>(), p[1].get<double>());
    }
    md << "| progress lines (then done at " << format("%.2f s", ld["load_s"].get<double>()) << ") | " << timeline
       << " |\n";
  }
  md << "| resident after the load | " << format("%.0f MiB", mib(ld["rss_after_load_bytes"].get<double>()))
     << " |\n";
  md << "| min/max tree build (MinMaxTree::Build, median of 3) | "
     << format("%.3f s", ld["tree_build_median_s"].get<double>()) << " (" << ld["tree_levels"].get<int>()
     << " levels) |\n";
  md << "| ScalarVolume construction (range, Lipschitz bound, tree) | "
     << format("%.3f s", ld["scalar_volume_build_s"].get<double>()) << " |\n";
  if (cc["cancelled"].get<bool>()) {
    md << "| cancel: flag set at | "
       << format("%.1f %% (%.2f s)", 100.0 * cc["flag_fraction"].get<double>(), cc["flag_after_s"].get<double>())
       << " |\n";
    md << "| cancel: LoadCancelled thrown after the flag | " << format("%.1f ms", cc["latency_ms"].get<double>())
       << " |\n";
  } else {
    md << "| cancel | NOT cancelled: the load finished |\n";
  }
  md << "| cancel: resident before / peak / after (after malloc_trim) | "
     << format("%.0f / %.0f / %.0f (%.0f) MiB", mib(rss_before), mib(cc["peak_rss_bytes"].get<double>()),
               mib(rss_after), mib(cc["rss_after_trim_bytes"].get<double>()))
     << (cc["released"].get<bool>() ? " (released)" : " (NOT released)") << " |\n";
  if (cc["loader_children_peak_rss_bytes"].get<double>() > 0.0)
    md << "| cancel: the loader's worker process's peak before it ended | "
       << format("%.0f MiB", mib(cc["loader_children_peak_rss_bytes"].get<double>())) << " |\n";
  md << "\n";
}

/// The touch run's table: tick times on the phantom and on the big scan, and their ratio.
void writeTouchTable(std::ostringstream& md, const nlohmann::ordered_json& touch, int ticks, int locations) {
  const auto& tp = touch["phantom"];
  const auto& tb = touch["bigscan"];
  const auto& tr = touch["ratio_bigscan_over_phantom"];
  md << "Tick times: the same touch run (table1's scripted interaction, " << locations << " spot"
     << (locations == 1 ? "" : "s") << ", " << ticks << " ticks at a simulated 1 kHz; "
     << touch["tool"].get<std::string>() << ", " << kIsovalue_HU
     << " HU; the application's renderer defaults) on the 140-slice phantom and on the big scan, interleaved tick by "
        "tick in one process; wall time is TickStats::exec_time_us, CPU time the thread's around tick().\n\n";
  md << "| volume | voxels | tree levels | mean [us] | p99.9 [us] | max [us] | CPU mean / p99.9 / max [us] | ticks in "
        "contact | contacts mean | tree nodes / tick |\n|---|---|---|---|---|---|---|---|---|---|\n";
  for (const auto* t : {&tp, &tb}) {
    const auto& d = (*t)["dims"];
    md << "| " << (t == &tp ? "phantom" : "bigscan") << " | " << d[0].get<int>() << " x " << d[1].get<int>() << " x "
       << d[2].get<int>() << " | " << (*t)["tree_levels"].get<int>() << " | "
       << format("%.1f", (*t)["mean_us"].get<double>()) << " | " << format("%.1f", (*t)["p99_9_us"].get<double>())
       << " | " << format("%.1f", (*t)["max_us"].get<double>()) << " | "
       << format("%.1f / %.1f / %.1f", (*t)["cpu_mean_us"].get<double>(), (*t)["cpu_p99_9_us"].get<double>(),
                 (*t)["cpu_max_us"].get<double>())
       << " | " << (*t)["ticks_in_contact"].get<std::int64_t>() << " | "
       << format("%.2f", (*t)["mean_contacts"].get<double>()) << " | "
       << format("%.1f", (*t)["mean_tree_nodes"].get<double>()) << " |\n";
  }
  md << "| **bigscan / phantom** | | | " << format("%.2fx", tr["mean"].get<double>()) << " | "
     << format("%.2fx", tr["p99_9"].get<double>()) << " | " << format("%.2fx", tr["max"].get<double>()) << " | "
     << format("%.2fx / %.2fx / %.2fx", tr["cpu_mean"].get<double>(), tr["cpu_p99_9"].get<double>(),
               tr["cpu_max"].get<double>())
     << " | | | |\n";
}

/// The one-line summary on stdout (the CLI test looks for "bench bigscan: load ... s, peak ... MiB").
void printSummary(const nlohmann::ordered_json& report) {
  const auto& ld = report["load"];
  const auto& cc = report["cancel"];
  const auto& tr = report["touch"]["ratio_bigscan_over_phantom"];
  const double peak = ld["peak_total_bytes"].get<double>();
  const double ratio = ld["peak_over_voxel_bytes"].get<double>();
  std::cout << "bench bigscan: load " << format("%.2f", ld["load_s"].get<double>()) << " s, peak "
            << format("%.0f", mib(peak)) << " MiB = " << format("%.2f", ratio) << "x the voxel bytes; tree "
            << format("%.3f", ld["tree_build_median_s"].get<double>()) << " s; cancel latency "
            << format("%.1f", cc["latency_ms"].get<double>()) << " ms; bigscan / phantom tick: mean "
            << format("%.2f", tr["mean"].get<double>()) << "x, p99.9 " << format("%.2f", tr["p99_9"].get<double>())
            << "x, max " << format("%.2f", tr["max"].get<double>()) << "x\n";
}

}  // namespace

fs::path bigScanSeries(const fs::path& dir, int slices) {
  if (slices < 2) throw std::runtime_error("a CT series needs at least 2 slices");
  const fs::path phantom = runtime::sharedDatasetsDir() / kPhantom;
  if (!fs::exists(phantom)) throw std::runtime_error(phantom.string() + " is absent: the CT series is made from it");
  return generateSeries(dir, phantom, slices).dir;
}

int runBigScanChild(const BigScanOptions& options) {
  try {
    if (options.child == "load") return childLoad(options);
    if (options.child == "cancel") return childCancel(options);
    std::cerr << "volume-haptics bench bigscan: error: unknown --child '" << options.child << "'\n";
  } catch (const std::exception& e) {
    std::cerr << "volume-haptics bench bigscan --child " << options.child << ": error: " << e.what() << std::endl;
  }
  return 1;
}

fs::path runBigScan(const BigScanOptions& options) {
  const fs::path out = outputDir(options.common, "bigscan");
  const bool short_run = options.common.short_run;
  const int nz = options.slices > 0 ? options.slices : (short_run ? kShortSlices : kFullSlices);
  const int ticks = options.ticks > 0 ? options.ticks : (short_run ? 1000 : 20000);
  const int locations = short_run ? 1 : 4;
  if (nz < 2) throw std::runtime_error("--slices must be >= 2");
  if (!(options.cancel_at > 0.0 && options.cancel_at < 1.0)) throw std::runtime_error("--cancel-at must be in (0, 1)");
  BigScanOptions o = options;
  if (o.series_dir.empty()) o.series_dir = defaultOutputDir() / "bigscan" / format("series-512x512x%d", nz);

  nlohmann::ordered_json report = reportHeader("bigscan", short_run);
  std::ostringstream md;
  md << "## Big scans (`volume-haptics bench bigscan" << (short_run ? " --short" : "") << "`)\n\n";

  const fs::path phantom = runtime::sharedDatasetsDir() / kPhantom;
  if (!fs::exists(phantom)) {
    const std::string why = phantom.string() + " is absent: the big series is generated from it";
    std::cout << "bench bigscan: skipped: " << why << "\n";
    report["status"] = "skipped";
    report["reason"] = why;
    md << "Skipped: " << why << ".\n";
    writeReport(out, "bigscan", report, md, {});
    return out;
  }
  report["status"] = "ran";

  // 1. The series.
  const SeriesInfo series = generateSeries(o.series_dir, phantom, nz);
  const double voxel_bytes = 2.0 * series.nx * series.ny * static_cast<double>(series.nz);
  report["series"] = seriesJson(series, voxel_bytes);

  // 2. The load in a fresh process.
  report["load"] = measureLoad(o, series, voxel_bytes);

  // 3. A cancelled load in another fresh process.
  report["cancel"] = measureCancel(o, voxel_bytes);

  // 4. Ticks side by side with the 140-slice phantom.
  report["touch"] = touchSideBySide(phantom, series.dir, ticks, locations);

  // Markdown.
  writeLoadTable(md, report, series, voxel_bytes);
  writeTouchTable(md, report["touch"], ticks, locations);
  writeReport(out, "bigscan", report, md, {});
  printSummary(report);
  return out;
}

}  // namespace vh::bench
