#pragma once
/// @file
/// What every benchmark's report is made of: statistics of tick times, the machine, the output
/// folder, the JSON and Markdown files, and PNG charts (VTK charts rendered off screen). Shared by
/// the benchmarks of vh::bench and those that need the window's rendering (the render benchmark in
/// ui/bench/). Not part of the servo loop: allocates, prints and throws freely.
#include <cstdint>
#include <filesystem>
#include <sstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "vh/bench/bench.h"
#include "vh/runtime/recording.h"

namespace vh::bench {

/// Summary of a sample of tick times [us] (or any values).
struct Stats {
  double mean = 0.0, p50 = 0.0, p99 = 0.0, p999 = 0.0, max = 0.0;
  std::size_t n = 0;
};
/// Mean, nearest-rank percentiles and maximum of `values` (copied; sorted inside).
Stats summarize(std::vector<double> values);

/// The CPU model from /proc/cpuinfo ("model name"), or "unknown".
std::string cpuModel();
/// Number of online CPUs.
unsigned cpuCount();
/// UTC time now, ISO 8601 ("2026-11-21T17:45:00Z").
using runtime::utcNow;
/// The start of every benchmark's JSON report: its name, the date, the machine (CPU model and
/// count), the build type and whether it is the short run.
nlohmann::ordered_json reportHeader(const std::string& benchmark, bool short_run);
/// The output folder for a benchmark (created). @throws std::runtime_error when it cannot be.
std::filesystem::path outputDir(const CommonOptions& options, const std::string& name);
/// Writes text to a file. @throws std::runtime_error naming the file.
void writeText(const std::filesystem::path& path, const std::string& text);
/// Appends the plots' links to the Markdown, writes NAME.json (json_text) and NAME.md into `out`
/// and prints the Markdown. @throws std::runtime_error naming a file that cannot be written.
void writeReportFiles(const std::filesystem::path& out, const std::string& name, const std::string& json_text,
                      std::ostringstream& md, const std::vector<std::string>& plots);
/// Stores `plots` in `report` (nlohmann::json or ordered_json), then writeReportFiles().
template <typename Json>
void writeReport(const std::filesystem::path& out, const std::string& name, Json& report, std::ostringstream& md,
                 const std::vector<std::string>& plots) {
  report["plots"] = plots;
  writeReportFiles(out, name, report.dump(2), md, plots);
}
/// A JSON number that is always finite (NaN / inf become null would break the tests' checks:
/// non-finite values are written as -1 and flagged by the caller).
double finiteOr(double v, double fallback = -1.0);
/// printf-style formatting into a std::string.
std::string format(const char* fmt, ...) __attribute__((format(printf, 1, 2)));

/// True when an X display is there for VTK's off-screen rendering (DISPLAY set).
bool displayAvailable();

/// One line series of a chart.
struct Series {
  std::string name;
  std::vector<double> x, y;
  bool points = false;  ///< Scatter (points) instead of a line.
};
/// Writes a line / scatter chart as PNG (VTK vtkChartXY rendered off screen).
/// @return false (with a message on stderr) when no display is available or rendering failed.
bool plotXY(const std::filesystem::path& png, const std::string& title, const std::string& x_label,
            const std::string& y_label, const std::vector<Series>& series, bool log_x = false, bool log_y = false,
            int width = 900, int height = 500);
/// Grouped bar chart: one group per category, one bar per series (series[i].y[category]).
bool plotBars(const std::filesystem::path& png, const std::string& title, const std::vector<std::string>& categories,
              const std::string& y_label, const std::vector<Series>& series, bool log_y = false, int width = 900,
              int height = 500);

}  // namespace vh::bench
