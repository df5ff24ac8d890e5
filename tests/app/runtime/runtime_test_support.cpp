#include "runtime_test_support.h"

#include "vh/runtime/recording.h"

#include <cstring>
#include <fstream>
#include <thread>

namespace vh::test {

namespace fs = std::filesystem;

fs::path scratchDir() {
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  std::string name = info ? std::string(info->test_suite_name()) + "." + info->name() : "scratch";
  for (char& c : name) {
    if (c == '/') c = '_';
  }
  const fs::path dir = fs::path(VH_TEST_OUTPUT_DIR) / "scratch" / name;
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

fs::path writeText(const fs::path& path, const std::string& text) {
  fs::create_directories(path.parent_path());
  std::ofstream out(path, std::ios::binary);
  out << text;
  return path;
}

fs::path sharedDatasets() { return fs::path(VH_SHARED_DATASETS_DIR); }
fs::path generatedData() { return fs::path(VH_GENERATED_DATA_DIR); }
fs::path sourceDir() { return fs::path(VH_SOURCE_DIR); }

const runtime::LoadedScene& sphereBallScene() {
  static const runtime::LoadedScene scene = [] {
    runtime::SceneSpec spec;
    spec.volume.path = "builtin:sphere";
    spec.tool.mesh = "builtin:sphere";
    spec.tool.point_spacing_m = 0.0015;
    spec.gains.linear_N_per_m = 1000.0;
    spec.device = runtime::DeviceSpec{};
    return runtime::loadScene(spec);
  }();
  return scene;
}

bool waitUntil(const std::function<bool()>& condition, std::chrono::milliseconds timeout) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  while (std::chrono::steady_clock::now() < deadline) {
    if (condition()) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  return condition();
}

long lockedMemory_kB() {
  std::ifstream status("/proc/self/status");
  std::string line;
  while (std::getline(status, line))
    if (line.rfind("VmLck:", 0) == 0) return std::stol(line.substr(6));
  return -1;
}

namespace {
std::uint32_t u32At(const std::string& b, std::size_t at) {
  std::uint32_t v = 0;
  std::memcpy(&v, b.data() + at, 4);
  return v;
}
void putU32(std::string& b, std::size_t at, std::uint32_t v) { std::memcpy(b.data() + at, &v, 4); }
}  // namespace

namespace {
// The records cut to `bytes` (and, for version 4, its 4 reserved bytes 0).
std::string asOlderRecording(const std::string& current, std::uint32_t version, std::size_t bytes) {
  const std::size_t first = 24 + u32At(current, 16);
  std::string out = current.substr(0, first);
  putU32(out, 8, version);
  putU32(out, 12, static_cast<std::uint32_t>(bytes));
  for (std::size_t at = first; at + 4 <= current.size();) {
    const std::string tag = current.substr(at, 4);
    if (tag == "CHNK") {
      const std::uint32_t n = u32At(current, at + 4);
      std::string chunk = current.substr(at, 16);
      for (std::uint32_t k = 0; k < n; ++k) {
        std::string record = current.substr(at + 16 + k * sizeof(runtime::TickRecord), bytes);
        if (version == 4) putU32(record, bytes - 4, 0);  // reserved
        chunk += record;
      }
      chunk += std::string(4, '\0');
      putU32(chunk, chunk.size() - 4, runtime::crc32(chunk.data(), chunk.size() - 4));
      out += chunk;
      at += 16 + n * sizeof(runtime::TickRecord) + 4;
    } else if (tag == "EVNT") {
      const std::size_t size = 12 + u32At(current, at + 8) + 4;
      out += current.substr(at, size);
      at += size;
    } else {  // "ENDR", the last
      out += current.substr(at);
      break;
    }
  }
  return out;
}
}  // namespace

std::string asVersion3Recording(const std::string& current) {
  return asOlderRecording(current, 3, runtime::kTickRecordBytesV3);
}

std::string asVersion4Recording(const std::string& current) {
  return asOlderRecording(current, 4, runtime::kTickRecordBytesV4);
}

}  // namespace vh::test
