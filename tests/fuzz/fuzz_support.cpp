#include "fuzz_support.h"

#include <cstdio>
#include <cstdlib>
#include <stdexcept>
#include <system_error>

#include <unistd.h>

#if VH_FUZZ_WITH_VTK
#include <memory>
#include <vector>

#include <vtkLogger.h>

#include "vh/haptics/scalar_volume.h"
#endif

namespace vh::fuzz {
namespace fs = std::filesystem;

namespace {

struct TempDir {
  fs::path path;
  TempDir() {
    std::error_code ec;
    fs::path base = "/dev/shm";
    if (!fs::is_directory(base, ec)) {
      const char* tmp = std::getenv("TMPDIR");
      base = tmp != nullptr && *tmp != '\0' ? fs::path(tmp) : fs::path("/tmp");
    }
    path = base / ("vh-fuzz-" + std::to_string(::getpid()));
    fs::remove_all(path, ec);
    fs::create_directories(path);
  }
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(path, ec);
  }
};

}  // namespace

const fs::path& tempDir() {
  static const TempDir dir;
  return dir.path;
}

fs::path freshDir(const std::string& name) {
  const fs::path dir = tempDir() / name;
  std::error_code ec;
  if (fs::is_directory(dir, ec)) {
    for (const auto& entry : fs::directory_iterator(dir)) fs::remove_all(entry.path(), ec);
  } else {
    fs::create_directories(dir);
  }
  return dir;
}

void writeFile(const fs::path& path, const std::uint8_t* data, std::size_t size) {
  std::FILE* f = std::fopen(path.c_str(), "wb");
  if (f == nullptr) throw std::runtime_error("fuzz: cannot create " + path.string());
  const bool ok = (size == 0 || std::fwrite(data, 1, size, f) == size);
  if (std::fclose(f) != 0 || !ok) throw std::runtime_error("fuzz: cannot write " + path.string());
}

void expected(const std::exception& e) {
  static const bool verbose = std::getenv("VH_FUZZ_VERBOSE") != nullptr;
  if (verbose) std::fprintf(stderr, "fuzz: rejected: %s\n", e.what());
}

void quietVtk() {
#if VH_FUZZ_WITH_VTK
  vtkLogger::SetStderrVerbosity(vtkLogger::VERBOSITY_OFF);
#endif
}

#if VH_FUZZ_WITH_VTK
vh::io::LoadedVolume smallScan() {
  haptics::VolumeGeometry g;
  g.dims = {16, 16, 4};
  g.spacing_m = Eigen::Vector3d(1e-3, 1e-3, 1e-3);
  const std::vector<std::int16_t> voxels(g.voxelCount(), 0);
  auto field = std::make_shared<const haptics::ScalarVolume>(haptics::ScalarVolume::FromVoxels(g, voxels));
  vh::io::LoadedVolume scan;
  scan.image = vh::io::imageFromField(field);
  scan.field = std::move(field);
  scan.info.source = "fuzz-scan";
  return scan;
}
#endif

}  // namespace vh::fuzz
