#include "vh/bench/report.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <fstream>
#include <iostream>
#include <sstream>
#include <stdexcept>
#include <thread>

#include "vh/runtime/runner.h"

namespace vh::bench {

namespace fs = std::filesystem;

Stats summarize(std::vector<double> values) {
  Stats s;
  s.n = values.size();
  if (values.empty()) return s;
  std::sort(values.begin(), values.end());
  double sum = 0.0;
  for (double v : values) sum += v;
  s.mean = sum / static_cast<double>(values.size());
  s.p50 = runtime::nearestRankPercentile(values, 0.50);
  s.p99 = runtime::nearestRankPercentile(values, 0.99);
  s.p999 = runtime::nearestRankPercentile(values, 0.999);
  s.max = values.back();
  return s;
}

std::string cpuModel() {
  std::ifstream in("/proc/cpuinfo");
  std::string line, model, mhz;
  const auto value = [](const std::string& l) {
    std::string v = l.substr(l.find(':') + 1);
    v.erase(0, v.find_first_not_of(" \t"));
    return v;
  };
  while (std::getline(in, line)) {
    if (model.empty() && line.rfind("model name", 0) == 0 && line.find(':') != std::string::npos) model = value(line);
    if (mhz.empty() && line.rfind("cpu MHz", 0) == 0 && line.find(':') != std::string::npos) mhz = value(line);
  }
  if (model.empty()) return "unknown";
  // A model name without its clock (e.g. a virtual "Intel(R) Xeon(R) Processor"): add the MHz.
  if (model.find("Hz") == std::string::npos && !mhz.empty()) model += ", " + mhz.substr(0, mhz.find('.')) + " MHz";
  return model;
}

unsigned cpuCount() { return std::max(1u, std::thread::hardware_concurrency()); }

fs::path outputDir(const CommonOptions& options, const std::string& name) {
  const fs::path dir = options.out_dir.empty() ? defaultOutputDir() / name : options.out_dir;
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec || !fs::is_directory(dir)) throw std::runtime_error(dir.string() + ": cannot create the output folder");
  return dir;
}

void writeText(const fs::path& path, const std::string& text) {
  std::ofstream out(path);
  if (!out) throw std::runtime_error(path.string() + ": cannot write");
  out << text;
  out.flush();
  if (!out) throw std::runtime_error(path.string() + ": write failed");
}

void writeReportFiles(const fs::path& out, const std::string& name, const std::string& json_text, std::ostringstream& md,
                      const std::vector<std::string>& plots) {
  if (!plots.empty()) {
    md << "\nPlots:";
    for (const auto& p : plots) md << " [" << p << "](" << p << ")";
    md << "\n";
  }
  writeText(out / (name + ".json"), json_text + "\n");
  writeText(out / (name + ".md"), md.str());
  std::cout << md.str() << "\nbench " << name << ": wrote " << (out / (name + ".json")).string() << ", " << name
            << ".md and " << plots.size() << " plots\n";
}

double finiteOr(double v, double fallback) { return std::isfinite(v) ? v : fallback; }

std::string format(const char* fmt, ...) {
  char buf[1024];
  va_list args;
  va_start(args, fmt);
  std::vsnprintf(buf, sizeof buf, fmt, args);
  va_end(args);
  return buf;
}

bool displayAvailable() {
  const char* d = std::getenv("DISPLAY");
  return d != nullptr && *d != '\0';
}

nlohmann::ordered_json reportHeader(const std::string& benchmark, bool short_run) {
  nlohmann::ordered_json report;
  report["benchmark"] = benchmark;
  report["date_utc"] = utcNow();
  report["cpu_model"] = cpuModel();
  report["cpus"] = cpuCount();
#ifdef NDEBUG
  report["build"] = "release (NDEBUG)";
#else
  report["build"] = "debug (assertions on)";
#endif
  report["short"] = short_run;
  return report;
}

}  // namespace vh::bench
