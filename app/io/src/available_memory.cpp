// Available memory (vh/io/available_memory.h): /proc/meminfo's MemAvailable.
#include "vh/io/available_memory.h"

#include <cstdio>
#include <fstream>
#include <sstream>
#include <stdexcept>

namespace vh::io {

std::optional<std::uint64_t> availableMemoryBytes() {
  std::ifstream in("/proc/meminfo");
  std::string key;
  std::uint64_t value_kB = 0;
  std::string unit;
  std::string line;
  while (std::getline(in, line)) {
    std::istringstream fields(line);
    if (fields >> key >> value_kB >> unit && key == "MemAvailable:") return value_kB * 1024;
  }
  return std::nullopt;
}

std::string formatBytes(std::uint64_t bytes) {
  const char* units[] = {"bytes", "KiB", "MiB", "GiB", "TiB", "PiB", "EiB"};
  if (bytes < 1024) return std::to_string(bytes) + " bytes";
  double v = static_cast<double>(bytes);
  int u = 0;
  while (v >= 1024.0 && u < 6) {
    v /= 1024.0;
    ++u;
  }
  char text[32];
  std::snprintf(text, sizeof(text), v < 10.0 ? "%.1f %s" : "%.0f %s", v, units[u]);
  return text;
}

bool fitsInMemory(std::uint64_t bytes) {
  const std::optional<std::uint64_t> available = availableMemoryBytes();
  if (!available) return true;
  return bytes <= *available && *available - bytes >= kMemoryMargin_bytes;
}

void requireFitsInMemory(std::uint64_t bytes, const std::string& what) {
  if (fitsInMemory(bytes)) return;
  const std::uint64_t available = availableMemoryBytes().value_or(0);
  throw std::runtime_error(what + " declares " + formatBytes(bytes) + " but " + formatBytes(available) +
                           " of memory is available (" + formatBytes(kMemoryMargin_bytes) + " kept free)");
}

}  // namespace vh::io
