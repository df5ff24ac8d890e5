// The `volume-haptics bench` subcommands (CLI11).
#include <cstdlib>
#include <iostream>
#include <string>

#include <CLI/CLI.hpp>

#include "vh/bench/report.h"
#include "vh/runtime/scene.h"
#include "vh/runtime/servo_factory.h"

namespace vh::bench {

std::filesystem::path defaultOutputDir() {
  if (const char* env = std::getenv("VH_BENCH_OUT_DIR"); env != nullptr && *env != '\0') return env;
  // Installed, the build machine's folders mean nothing here: the user's data folder (XDG Base
  // Directory), else the current folder.
  if (!runtime::installedDataDir().empty()) {
    if (const char* xdg = std::getenv("XDG_DATA_HOME"); xdg != nullptr && *xdg == '/') {
      return std::filesystem::path(xdg) / "volume-haptics" / "bench";
    }
    if (const char* home = std::getenv("HOME"); home != nullptr && *home == '/') {
      return std::filesystem::path(home) / ".local" / "share" / "volume-haptics" / "bench";
    }
    return std::filesystem::current_path() / "volume-haptics-bench";
  }
  return VH_BENCH_DEFAULT_OUT_DIR;
}

void addCommonOptions(CLI::App& cmd, CommonOptions& common) {
  cmd.add_flag("--short", common.short_run, "Short version (about 1,000 ticks per run; for tests)");
  cmd.add_option("--out", common.out_dir, "Output folder (default: " + (defaultOutputDir() / cmd.get_name()).string() + ")");
  cmd.add_flag("!--no-plots", common.plots, "Do not write PNG plots");
}

int runGuarded(const char* name, const std::function<void()>& f) {
  try {
    f();
    return EXIT_SUCCESS;
  } catch (const std::exception& e) {
    std::cerr << "volume-haptics bench " << name << ": error: " << e.what() << std::endl;
    return 1;
  }
}


namespace {

/// "bench table1": the paper's Table 1 and its options.
void addTable1Subcommand(CLI::App& bench, std::function<int()>& handler) {
  auto table1 = std::make_shared<Table1Options>();
  auto mode = std::make_shared<std::string>("both");
  auto before = std::make_shared<bool>(false);
  CLI::App* t1 = bench.add_subcommand("table1", "The paper's Table 1: four scenes, tick times in both detection "
                                                 "modes side by side, the accelerated mode before and after the "
                                                 "exact segment test, plus the large-tool runs");
  addCommonOptions(*t1, table1->common);
  t1->add_option("--mode", *mode,
                 "Detection path(s): paper, accelerated, both (paper and accelerated) or all (both, plus the "
                 "accelerated mode with the end-sample segment test: the 'before' column)")
      ->capture_default_str()
      ->check(CLI::IsMember({"paper", "accelerated", "both", "all"}));
  t1->add_flag("--before", *before,
               "Add the 'before' column (accelerated mode, end-sample segment test) to --mode accelerated or both");
  t1->add_flag("--edge-test,!--no-edge-test", table1->edge_test,
               "The 'edges' column (on by default): the accelerated mode as the application runs it, with the edge "
               "test between shell points (the tool's surface between its points), and its cost over the points-only "
               "accelerated mode; --no-edge-test leaves it out");
  t1->add_flag("--edge-test-swept", table1->edge_test_swept,
               "The 'edges' columns with the edge test swept along each move, not only at its end (to measure "
               "what the swept test costs)");
  t1->add_option("--work-budget", table1->work_budget,
                 "The accelerated mode's work budget per tick (units of one trilinear sample's cost); "
                 "> 0 also runs it unbudgeted and reports the lag (how far apart the two proxies are) and behind "
                 "(how much farther from the device the budgeted one is), beside the control: the full solve again "
                 "with one device sample in " + std::to_string(Table1Options::kHeldSampleEvery) +
                     " held, and how far it gets from itself; 0: unbudgeted only")
      ->capture_default_str()
      ->check(CLI::NonNegativeNumber);
  t1->add_option("--verify-step", table1->verify_step_voxels,
                 "Crossing check of every tick's move, after the run (its reads of the volume do not share the timed ticks' caches): path sampling step [voxels]; 0: off")
      ->capture_default_str()
      ->check(CLI::NonNegativeNumber);
  t1->add_flag("--verify-references", table1->verify_references,
               "Also crossing-check the unbudgeted reference runs (the full solves that measure the work budget's "
               "lag; left out by default: no proxy the hand feels comes from them)");
  t1->add_option("--scene", table1->scene, "Only this scene: Bunny, Engine, Hole or Bone");
  t1->add_option("--ticks", table1->ticks, "Ticks per scene and mode (default 20000; short 1000); the 20,000- and 50,000-point tools run the first quarter of them (at least 1,000), the same hand at the same speed")
      ->check(CLI::PositiveNumber);
  t1->add_flag("!--no-large-tools", table1->large_tools, "Skip the 20,000- and 50,000-point tool runs");
  t1->add_flag("--50k-tools", table1->tools_50k,
               "Also the 50,000-point tool rows on Bone and Engine (left out by default, so that the default run "
               "finishes within 30 minutes on a 2-core machine; --tool-rows 50000 runs them alone)");
  t1->add_option("--tool-rows", table1->tool_rows,
                 "Only the rows of this tool: paper (the paper's tool), 20000 or 50000 (the large tools on Bone and Engine)")
      ->check(CLI::IsMember(std::vector<std::string>(Table1Options::kToolRows.begin(), Table1Options::kToolRows.end())));
  t1->add_option("--lanes", table1->lanes,
                 "Cores the accelerated modes' sweep runs on (RendererOptions::solver_lanes); 0: the application's "
                 "default (hardware threads less two, 1 to 8; one lane for tools under " +
                     std::to_string(runtime::kPointsForSeveralLanes) + " points)")
      ->capture_default_str()
      ->check(CLI::Range(0, 64));
  t1->add_option("--deadline-us", table1->deadline_us,
                 "The accelerated mode's deadline per tick on the clock [us] (the work budget's last line); "
                 "-1: the application's (900 us at 1 kHz); 0: none")
      ->capture_default_str()
      ->check(CLI::Range(-1.0, 1e6));
  t1->add_option("--load", table1->load, "Busy threads run beside the benchmark (a loaded machine)")
      ->capture_default_str()
      ->check(CLI::Range(0, 256));
  t1->add_option("--lanes-sweep", table1->lane_sweep,
                 "Scaling: also run the accelerated mode without budget or deadline on each of these lane counts "
                 "(e.g. 1,2,4,8,16), interleaved, with a scaling table")
      ->delimiter(',')
      ->check(CLI::Range(1, 64));
  t1->callback([&handler, table1, mode, before] {
    table1->modes = *mode == "paper"         ? ModeSelection::kPaper
                    : *mode == "accelerated" ? ModeSelection::kAccelerated
                                             : ModeSelection::kBoth;
    table1->before = *mode == "all" || *before;
    if (*mode == "paper" && *before)
      throw CLI::ValidationError("--before", "compares the accelerated mode's segment tests: use --mode accelerated, "
                                             "both or all");
    handler = [table1] { return runGuarded("table1", [&] { runTable1(*table1); }); };
  });
}

/// "bench accuracy", "bench stability", "bench drilling" and "bench tissue" (the common options only).
void addAccuracyStabilityDrilling(CLI::App& bench, std::function<int()>& handler) {
  auto accuracy = std::make_shared<CommonOptions>();
  CLI::App* acc = bench.add_subcommand("accuracy", "Contact-position and normal error against tick time on exact "
                                                    "isosurfaces; Pareto front and recommended defaults");
  addCommonOptions(*acc, *accuracy);
  acc->callback([&handler, accuracy] {
    handler = [accuracy] { return runGuarded("accuracy", [&] { runAccuracy(*accuracy); }); };
  });

  auto stability = std::make_shared<CommonOptions>();
  CLI::App* stab = bench.add_subcommand("stability", "Coupling-stiffness sweep with the simulated device, and "
                                                      "extreme cases with their outcomes");
  addCommonOptions(*stab, *stability);
  stab->callback([&handler, stability] {
    handler = [stability] { return runGuarded("stability", [&] { runStability(*stability); }); };
  });
  auto drilling = std::make_shared<CommonOptions>();
  CLI::App* drill = bench.add_subcommand("drilling", "Drilling: the removal against the swept capsule, and the "
                                                      "solver's tick times drilling against touching alone on the "
                                                      "CT head phantom");
  addCommonOptions(*drill, *drilling);
  drill->callback([&handler, drilling] {
    handler = [drilling] { return runGuarded("drilling", [&] { runDrilling(*drilling); }); };
  });
  auto tissue = std::make_shared<CommonOptions>();
  CLI::App* soft = bench.add_subcommand("tissue", "Soft tissue: the whole tick with tissue against the rigid tick "
                                                   "on the gel with an inclusion and the CT head's soft tissue, "
                                                   "interleaved, and the tissue's step per lattice size");
  addCommonOptions(*soft, *tissue);
  soft->callback([&handler, tissue] {
    handler = [tissue] { return runGuarded("tissue", [&] { runTissue(*tissue); }); };
  });
}

/// "bench bigscan": a generated big CT series, its load, memory and tick times.
void addBigScanSubcommand(CLI::App& bench, std::function<int()>& handler) {
  auto bigscan = std::make_shared<BigScanOptions>();
  CLI::App* big = bench.add_subcommand("bigscan", "Big scans: a 512 x 512 x 2000 int16 CT series "
                                                   "generated into the output folder, its load time, peak memory, "
                                                   "min/max tree build, a cancelled load, and tick times against "
                                                   "the 140-slice phantom's");
  addCommonOptions(*big, bigscan->common);
  big->add_option("--slices", bigscan->slices, "Slices of the generated scan (default 2000; short 64)")
      ->check(CLI::Range(2, 100000));
  big->add_option("--ticks", bigscan->ticks, "Ticks of the touch run on each volume (default 20000; short 1000)")
      ->check(CLI::PositiveNumber);
  big->add_option("--series-dir", bigscan->series_dir,
                  "Where the series is generated and reused (default: " +
                      (defaultOutputDir() / "bigscan").string() + "/series-512x512xN)");
  big->add_option("--cancel-at", bigscan->cancel_at, "Progress fraction at which the cancel run cancels")
      ->capture_default_str()
      ->check(CLI::Range(0.01, 0.99));
  // The child processes the benchmark starts (this binary re-executed): not for people.
  big->add_option("--child", bigscan->child, "internal")->group("");
  big->callback([&handler, bigscan] {
    if (!bigscan->child.empty()) {
      handler = [bigscan] { return runBigScanChild(*bigscan); };
      return;
    }
    handler = [bigscan] { return runGuarded("bigscan", [&] { runBigScan(*bigscan); }); };
  });
}

}  // namespace

CLI::App* addBenchSubcommand(CLI::App& app, std::function<int()>& handler) {
  CLI::App* bench = app.add_subcommand(
      "bench", "Benchmarks of the rendering core: the paper's Table 1, error against run time, stiff and "
               "extreme cases, big scans; "
               "reports (JSON, Markdown, PNG) go into --out, by default $VH_BENCH_OUT_DIR/NAME, else for an installed "
               "copy $XDG_DATA_HOME/volume-haptics/bench/NAME (~/.local/share/...), from a build tree BUILD/bench/NAME "
               "(each benchmark's --help names the folder)");
  bench->require_subcommand(1);

  addTable1Subcommand(*bench, handler);
  addAccuracyStabilityDrilling(*bench, handler);
  addBigScanSubcommand(*bench, handler);
  return bench;
}

}  // namespace vh::bench
