// `volume-haptics bench memory`: the application's peak resident memory against its scan's voxel
// bytes, the reader process included (see memory_bench.h).
#include "vh/ui/bench/memory_bench.h"

#include <fcntl.h>
#include <spawn.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <fstream>
#include <iostream>
#include <map>
#include <memory>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include <CLI/CLI.hpp>

#include "vh/bench/report.h"
#include "vh/runtime/scene.h"

extern char** environ;

namespace vh::ui {
namespace {

namespace fs = std::filesystem;

constexpr int kGeneratedSlices = 275;  // bench render's abdomen-sized CT
constexpr double kTargetRatio = 2.5;   // peak / voxel bytes the application aims at
constexpr const char* kHeadlessResultTag = "bigscan-result: ";

double mib(double bytes) { return bytes / (1024.0 * 1024.0); }

/// VmRSS and VmHWM of process `pid` [bytes] from /proc/PID/status; 0 when it is gone.
struct Resident {
  double rss = 0.0, hwm = 0.0;
};
Resident residentOf(pid_t pid) {
  Resident r;
  std::ifstream in("/proc/" + std::to_string(pid) + "/status");
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind("VmRSS:", 0) == 0) r.rss = 1024.0 * std::atof(line.c_str() + 6);
    if (line.rfind("VmHWM:", 0) == 0) r.hwm = 1024.0 * std::atof(line.c_str() + 6);
  }
  return r;
}

/// The processes below `pid` (children, their children, ...), from /proc/PID/task/*/children.
std::vector<pid_t> descendantsOf(pid_t pid) {
  std::vector<pid_t> out, stack{pid};
  while (!stack.empty()) {
    const pid_t p = stack.back();
    stack.pop_back();
    std::error_code ec;
    for (const auto& task : fs::directory_iterator("/proc/" + std::to_string(p) + "/task", ec)) {
      std::ifstream children(task.path() / "children");
      pid_t c = 0;
      while (children >> c) {
        out.push_back(c);
        stack.push_back(c);
      }
    }
  }
  return out;
}

/// One measured run of the program.
struct Run {
  std::string name, what;
  std::vector<std::string> args;
  double own_peak = 0.0;         ///< The program's VmHWM (last sampled) [bytes].
  double ru_maxrss = 0.0;        ///< wait4's: the program's peak, or a waited child's if larger [bytes].
  double reader_peak = 0.0;      ///< The largest VmHWM sampled of a process below it [bytes].
  double concurrent_peak = 0.0;  ///< The largest sampled sum of VmRSS, the program and below [bytes].
  int readers = 0;               ///< Processes seen below it.
  double wall_s = 0.0;
  int exit_code = -1;
  std::string output;            ///< Its stdout and stderr.

  /// The memory the program and its readers held at one time, never below one's own peak.
  double peak() const { return std::max({own_peak, ru_maxrss, reader_peak, concurrent_peak}); }
};

/// Starts `run.args` (stdout and stderr into `log`), samples its memory every 5 ms until it
/// ends, and fills `run`. @throws std::runtime_error when it cannot be started.
void measure(Run& run, const fs::path& log) {
  std::vector<char*> argv;
  for (std::string& a : run.args) argv.push_back(a.data());
  argv.push_back(nullptr);
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  posix_spawn_file_actions_adddup2(&actions, STDOUT_FILENO, STDERR_FILENO);
  pid_t pid = 0;
  std::cout.flush();
  const auto t0 = std::chrono::steady_clock::now();
  const int rc = posix_spawn(&pid, run.args[0].c_str(), &actions, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  if (rc != 0) throw std::runtime_error("cannot start " + run.args[0] + ": " + std::strerror(rc));
  std::map<pid_t, double> reader_hwm;
  int status = 0;
  rusage ru{};
  for (;;) {
    const Resident own = residentOf(pid);
    run.own_peak = std::max(run.own_peak, own.hwm);
    double sum = own.rss;
    for (const pid_t c : descendantsOf(pid)) {
      // Between posix_spawn's clone and its exec a child still shares the program's memory
      // (CLONE_VM): its /proc figures are the program's until it runs the reader's executable.
      std::error_code ec;
      if (fs::read_symlink("/proc/" + std::to_string(c) + "/exe", ec) == fs::path(run.args[0])) continue;
      const Resident r = residentOf(c);
      sum += r.rss;
      reader_hwm[c] = std::max(reader_hwm[c], r.hwm);
    }
    run.concurrent_peak = std::max(run.concurrent_peak, sum);
    const pid_t done = ::wait4(pid, &status, WNOHANG, &ru);
    if (done == pid) break;
    if (done < 0 && errno != EINTR) throw std::runtime_error("waiting for " + run.args[0] + ": " + std::strerror(errno));
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  run.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  run.ru_maxrss = 1024.0 * static_cast<double>(ru.ru_maxrss);
  run.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  run.readers = static_cast<int>(reader_hwm.size());
  for (const auto& [p, hwm] : reader_hwm) run.reader_peak = std::max(run.reader_peak, hwm);
  std::ifstream in(log);
  std::ostringstream text;
  text << in.rdbuf();
  run.output = text.str();
}

nlohmann::ordered_json runJson(const Run& r, double voxel_bytes) {
  nlohmann::ordered_json j;
  j["name"] = r.name;
  j["what"] = r.what;
  std::string command;
  for (const std::string& a : r.args) command += (command.empty() ? "" : " ") + a;
  j["command"] = command;
  j["peak_bytes"] = r.peak();
  j["peak_over_voxels"] = voxel_bytes > 0.0 ? r.peak() / voxel_bytes : -1.0;
  j["own_peak_bytes"] = r.own_peak;
  j["ru_maxrss_bytes"] = r.ru_maxrss;
  j["reader_peak_bytes"] = r.reader_peak;
  j["concurrent_peak_bytes"] = r.concurrent_peak;
  j["reader_processes"] = r.readers;
  j["wall_s"] = r.wall_s;
  j["exit_code"] = r.exit_code;
  return j;
}

}  // namespace

fs::path runMemoryBench(const MemoryBenchOptions& o) {
  using namespace bench;
  if (!displayAvailable())
    throw std::runtime_error("bench memory opens the program's window and needs an X display with OpenGL: run it under "
                             "xvfb-run -a -s \"-screen 0 1920x1080x24\"");
  const bool short_run = o.common.short_run;
  const fs::path out = outputDir(o.common, "memory");
  std::error_code ec;
  const fs::path program = fs::weakly_canonical(o.program.empty() ? fs::read_symlink("/proc/self/exe", ec) : o.program, ec);
  if (program.empty() || !fs::exists(program, ec)) throw std::runtime_error("bench memory: no program to measure");

  const fs::path small_ct = runtime::sharedDatasetsDir() / "ct" / "ct-head-small";
  fs::path volume = o.volume;
  if (volume.empty() && short_run) volume = small_ct;
  if (volume.empty()) {
    const int slices = o.slices > 0 ? o.slices : kGeneratedSlices;
    const fs::path dir =
        o.series_dir.empty() ? defaultOutputDir() / "render" / format("ct-512x512x%d", slices) : o.series_dir;
    volume = bigScanSeries(dir, slices);
  }
  if (!fs::exists(volume, ec)) throw std::runtime_error("bench memory: " + volume.string() + " does not exist");

  std::vector<Run> runs(3);
  runs[0].name = "headless_load";
  runs[0].what = "io::loadVolume alone (bench bigscan's load child), with its reader process: the child's VmHWM "
                 "when the load returns, its reader's ru_maxrss, their sum sampled every 5 ms during the load";
  runs[0].args = {program.string(), "bench", "bigscan", "--child", "load", "--series-dir", volume.string()};
  runs[1].name = "gui";
  runs[1].what = "the window: the scan read in the reader process, drawn by the ray caster, felt by the haptic threads, "
                 "the tool brought onto its surface, a screenshot";
  runs[1].args = {program.string(), volume.string(), "--touch", "--screenshot", (out / "memory-gui.png").string()};
  runs[2].name = "gui_baseline";
  runs[2].what = "the same window on the 64 x 64 x 93 CT head (0.7 MB of voxels): the program's own footprint";
  runs[2].args = {program.string(), small_ct.string(), "--touch", "--screenshot", (out / "memory-baseline.png").string()};
  const bool baseline = fs::exists(small_ct, ec);
  if (!baseline) runs.pop_back();

  nlohmann::json headless;
  for (Run& r : runs) {
    std::cout << "bench memory: " << r.name << " ..." << std::endl;
    measure(r, out / ("memory-" + r.name + ".log"));
    if (r.exit_code != 0)
      throw std::runtime_error("bench memory: the " + r.name + " run failed (exit code " + std::to_string(r.exit_code) +
                               "); its output is in " + (out / ("memory-" + r.name + ".log")).string());
    if (r.name == "headless_load") {
      const auto at = r.output.find(kHeadlessResultTag);
      if (at == std::string::npos) throw std::runtime_error("bench memory: the headless load printed no result");
      const auto end = r.output.find('\n', at);
      headless = nlohmann::json::parse(r.output.substr(at + std::strlen(kHeadlessResultTag), end - at - std::strlen(kHeadlessResultTag)));
      // The load's own figures, measured inside the child (it goes on to time min/max tree
      // builds on a copy of the voxels for bench bigscan, which is not the loader's memory).
      r.own_peak = headless.at("peak_rss_bytes").get<double>();
      r.reader_peak = headless.at("loader_children_peak_rss_bytes").get<double>();
      r.concurrent_peak = headless.at("peak_concurrent_bytes").get<double>();
      r.ru_maxrss = 0.0;
    }
    std::cout << format("bench memory: %-13s peak %6.0f MiB (own %6.0f, reader %6.0f, together %6.0f) in %.1f s",
                        r.name.c_str(), mib(r.peak()), mib(std::max(r.own_peak, r.ru_maxrss)), mib(r.reader_peak),
                        mib(r.concurrent_peak), r.wall_s)
              << std::endl;
  }
  const double voxel_bytes = headless.at("voxel_bytes").get<double>();
  const Run& headless_run = runs[0];
  const Run& gui = runs[1];

  nlohmann::ordered_json report = reportHeader("memory", short_run);
  report["volume"] = {{"path", volume.string()},
                      {"dims", headless.at("dims")},
                      {"voxel_type", headless.at("voxel_type")}};
  report["voxel_bytes"] = voxel_bytes;
  report["image_shares_field"] = headless.value("image_shares_field", false);
  report["target_ratio"] = kTargetRatio;
  nlohmann::ordered_json rows = nlohmann::ordered_json::array();
  for (const Run& r : runs) rows.push_back(runJson(r, voxel_bytes));
  report["runs"] = rows;
  report["headless_peak_over_voxels"] = headless_run.peak() / voxel_bytes;
  report["gui_peak_over_voxels"] = gui.peak() / voxel_bytes;
  report["gui_added_over_voxels"] = baseline ? (gui.peak() - runs[2].peak()) / voxel_bytes : -1.0;

  const auto dims = headless.at("dims").get<std::vector<int>>();
  std::ostringstream md;
  md << "## Peak memory against the voxels (`volume-haptics bench memory" << (short_run ? " --short" : "") << "`)\n\n"
     << format("Scan %d x %d x %d %s, %.1f MiB of voxels (%s); ", dims.at(0), dims.at(1), dims.at(2),
               headless.at("voxel_type").get<std::string>().c_str(), mib(voxel_bytes), volume.string().c_str())
     << "CPU " << report["cpu_model"].get<std::string>() << " (" << report["cpus"].get<unsigned>() << " CPUs). "
     << "Each run is a fresh process of the program; peak: the largest of the program's and its reader process's "
        "resident memory summed (sampled every 5 ms) and each one's own peak (VmHWM, wait4's ru_maxrss). The rendering "
        "image "
     << (report["image_shares_field"].get<bool>() ? "shares the field's voxel buffer (one copy)." : "holds its own copy of the voxels.")
     << "\n\n| run | peak [MiB] | peak / voxels | program's own peak [MiB] | reader process's peak [MiB] | together, sampled [MiB] |\n"
     << "|---|---|---|---|---|---|\n";
  for (const Run& r : runs)
    md << format("| %s | %.0f | %.2f | %.0f | %.0f | %.0f |\n", r.name.c_str(), mib(r.peak()), r.peak() / voxel_bytes,
                 mib(std::max(r.own_peak, r.ru_maxrss)), mib(r.reader_peak), mib(r.concurrent_peak));
  md << format("\nGUI peak / voxel bytes: **%.2f**", report["gui_peak_over_voxels"].get<double>());
  if (baseline)
    md << format("; what the scan adds to the program's own footprint (GUI peak - baseline peak) / voxel bytes: **%.2f** "
                 "(target <= %.1f: %s)",
                 report["gui_added_over_voxels"].get<double>(), kTargetRatio,
                 report["gui_added_over_voxels"].get<double>() <= kTargetRatio ? "met" : "NOT MET");
  md << format("; headless load: %.2f.\n", report["headless_peak_over_voxels"].get<double>());
  writeReport(out, "memory", report, md, {});
  return out;
}

void addMemoryBenchSubcommand(CLI::App& bench, std::function<int()>& handler) {
  auto options = std::make_shared<MemoryBenchOptions>();
  CLI::App* cmd = bench.add_subcommand(
      "memory", "Peak resident memory of the program against its scan's voxel bytes, the reader process included: the "
                "window on the scan, the window on a tiny scan (its own footprint) and the headless load; needs an X "
                "display (xvfb-run -a -s \"-screen 0 1920x1080x24\")");
  bench::addCommonOptions(*cmd, options->common);
  cmd->add_option("--volume", options->volume,
                  "The scan (default: bench render's 512 x 512 x 275 CT, generated from the shared head phantom; short: "
                  "the small CT head)");
  cmd->add_option("--slices", options->slices, "Slices of the generated CT (default 275)")->check(CLI::Range(2, 100000));
  cmd->add_option("--series-dir", options->series_dir,
                  "Where the generated CT is written and reused (default: " +
                      (bench::defaultOutputDir() / "render").string() + "/ct-512x512xN, bench render's)");
  cmd->add_option("--program", options->program,
                  "The volume-haptics executable to measure (default: this one), e.g. another build for a before and "
                  "after")
      ->check(CLI::ExistingFile);
  cmd->callback([&handler, options] {
    handler = [options] { return bench::runGuarded("memory", [&] { runMemoryBench(*options); }); };
  });
}

}  // namespace vh::ui
