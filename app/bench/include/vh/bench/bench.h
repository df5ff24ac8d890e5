#pragma once
/// @file
/// Benchmarks of the rendering core, run by `volume-haptics bench ...`:
///   table1     the paper's Table 1 (section 3.2): four scenes, scripted device trajectories,
///              tick times per detection mode (paper / accelerated) side by side with their ratio,
///              and the accelerated mode with the earlier end-sample segment test (the "before"
///              column) against the exact test; every tick's proxy motion checked
///              for crossings by haptics::CrossingVerifier outside the timed section;
///   accuracy   contact-position and normal error against tick time on volumes with exact
///              isosurfaces, swept over epsilon, segment_fraction and point-shell density;
///   stability  the coupling-stiffness sweep with the simulated device (vh::simulation) and a
///              table of extreme cases with their outcomes;
///   tissue     the whole tick with soft tissue against the rigid tick on the same scenes, and
///              the tissue's step per lattice size;
///   bigscan    a ~1 GB CT series: load time, peak memory, tree build, cancel, and
///              tick times against the small phantom's.
/// Each writes a JSON report, a Markdown report and PNG plots (VTK charts rendered off screen;
/// skipped with a message when no X display is available) into an output folder.
/// Not part of the servo loop: allocates, prints and throws freely.

#include <array>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "vh/haptics/haptic_renderer.h"
#include "vh/runtime/scene.h"
#include "vh/runtime/trajectory.h"

namespace CLI {
class App;
}

namespace vh::bench {

/// Which detection paths a benchmark runs (haptics::DetectionMode; kBoth: paper and accelerated).
enum class ModeSelection { kPaper, kAccelerated, kBoth };

/// Options shared by every benchmark.
struct CommonOptions {
  /// Short version (about 1,000 ticks per run, reduced sweeps): for tests; seconds, not minutes.
  bool short_run = false;
  /// Output folder; empty: defaultOutputDir() / NAME.
  std::filesystem::path out_dir;
  /// Write PNG plots (needs an X display; skipped with a message when there is none).
  bool plots = true;
};

struct Table1Options {
  CommonOptions common;
  ModeSelection modes = ModeSelection::kBoth;
  /// When the accelerated mode runs: also run it with SegmentTest::kEndSample (the earlier test,
  /// the "before" column), interleaved with the others, and compare it with the exact test.
  bool before = false;
  /// When the accelerated mode runs: also run it as the application does (budget, deadline,
  /// lanes, the edge test between shell points: RendererOptions::edge_test, the
  /// "accelerated-edges" column), interleaved, and give its cost over the points-only
  /// accelerated mode. On by default: it is what the application renders.
  bool edge_test = true;
  /// The "edges" columns with the edge test swept along each move
  /// (RendererOptions::edge_test_swept), to measure what testing along the move costs.
  bool edge_test_swept = false;
  /// Crossing check of every tick's move (haptics::CrossingVerifier; table1 checks the moves
  /// after the run, so its reads of the volume do not evict the timed ticks' state from the
  /// caches): sampling step along each shell point's path [voxels]; 0: off (crossings -1).
  double verify_step_voxels = 0.01;
  /// Also crossing-check the unbudgeted reference runs (the full solves that measure the
  /// budget's lag). Off by default: no proxy the hand feels comes from them, and their checks
  /// took 40 % of a default run (the check itself 95 %: 35 min of 37 on the 2-core VM).
  bool verify_references = false;
  /// The accelerated mode's RendererOptions::work_budget (the application's default).
  /// > 0 also runs the accelerated mode without it ("accelerated-unbudgeted"), interleaved, and
  /// reports the budgeted proxy's lag behind it (how far apart: mm, rad, ticks), how much farther
  /// from the device it is (behind), the cut ticks and the "Never behind" table with the targets,
  /// and after the run the control: the unbudgeted mode again with one device sample in
  /// kHeldSampleEvery held, and how far that gets from it; 0 runs the accelerated mode
  /// unbudgeted only.
  std::int64_t work_budget = haptics::RendererOptions::kDefaultWorkBudget;
  /// The control's held samples: one device sample in this many is held (the previous sample
  /// repeated, as when a USB packet is lost).
  static constexpr int kHeldSampleEvery = 1000;
  /// Run only this scene ("Bunny", "Engine", "Hole", "Bone", case-insensitive); empty: all.
  std::string scene;
  /// Ticks per scene and mode; 0: 20,000 (short: 1,000).
  int ticks = 0;
  /// Also the large-tool runs (20,000 points on Bone and Engine); never in short runs.
  bool large_tools = true;
  /// Also the 50,000-point rows (on Bone and Engine, after the 20,000-point ones). Off by
  /// default: on a 2-core machine the Engine's alone took longer than the four scenes, and
  /// default table1 must finish within 30 minutes there; tool_rows "50000" runs them too.
  bool tools_50k = false;
  /// Run only the rows of this tool, one of kToolRows: "paper" (the paper's tool), "20000" or
  /// "50000" (the resampled large tools); empty: all (subject to large_tools).
  std::string tool_rows;
  /// The values of tool_rows, in table order (index 0: the paper's tool, 1 and 2: the large ones).
  static constexpr std::array<const char*, 3> kToolRows = {"paper", "20000", "50000"};
  /// The accelerated modes' RendererOptions::solver_lanes (cores of the sweep); 0: the
  /// application's for each tool (runtime::solverLanesFor(): runtime::defaultSolverLanes(), one
  /// lane for tools under runtime::kPointsForSeveralLanes points).
  int lanes = 0;
  /// The accelerated mode's RendererOptions::deadline_us (the budget's last line, on the
  /// clock); < 0: the application's (runtime::solverDeadline_us() at 1 kHz); 0: none.
  double deadline_us = -1.0;
  /// Busy threads run beside the benchmark (a loaded machine); the same columns are reported.
  int load = 0;
  /// Scaling: the accelerated mode without budget or deadline also on each of these lane counts
  /// ("accelerated-lanes-N"), interleaved with the others, with a scaling table.
  std::vector<int> lane_sweep;
};

/// `bench bigscan` ("Big scans"): a 512 x 512 x N int16 CT series (default N = 2000,
/// about 1 GB of voxels) generated once into the build tree from the shared Philips head
/// phantom, loaded by io::loadVolume in fresh child processes (load time, peak resident memory
/// against the voxel bytes, min/max tree build time; a load cancelled at 30 % progress), and
/// tick times on it side by side with the 140-slice phantom.
struct BigScanOptions {
  CommonOptions common;
  /// Slices of the generated scan; 0: 2000 (short: 64).
  int slices = 0;
  /// Ticks of the side-by-side touch run; 0: 20,000 (short: 1,000).
  int ticks = 0;
  /// Where the series is generated (and reused when complete); empty: defaultOutputDir() /
  /// "bigscan" / "series-512x512xN".
  std::filesystem::path series_dir;
  /// Progress fraction (0..1) at which the cancel run sets VolumeLoadOptions::cancel.
  double cancel_at = 0.3;
  /// Internal: "load" or "cancel" runs only that child part on `series_dir` and prints one
  /// "bigscan-result: {json}" line (the parent re-executes its own binary with it).
  std::string child;
};

/// The big-scan benchmark (see BigScanOptions). Skips with a message (and a report saying so)
/// when the shared phantom is absent. @return the output folder.
/// @throws std::runtime_error when fewer than 3 times the voxel bytes (3 GB for the full scan)
///         are free where the series is generated, or when a child process fails.
std::filesystem::path runBigScan(const BigScanOptions& options);

/// A 512 x 512 x `slices` int16 CT series (bench bigscan's: the shared Philips head phantom
/// resampled to 0.5 mm between slices, mirrored along the stack), written into `dir` once and
/// reused while complete. @return `dir`.
/// @throws std::runtime_error when the phantom is absent, fewer than 3 times the voxel bytes are
///         free in `dir`, or writing fails.
std::filesystem::path bigScanSeries(const std::filesystem::path& dir, int slices);

/// The child part named by options.child (see BigScanOptions::child). @return the exit code.
int runBigScanChild(const BigScanOptions& options);

/// The paper's Table 1 (see the file comment). Scenes whose data are absent are skipped with a
/// message (and listed as skipped in the report). @return the output folder.
/// @throws std::runtime_error for an unknown scene name or an unwritable output folder.
std::filesystem::path runTable1(const Table1Options& options);

/// The scene `name` of Table 1 (Bunny, Engine, Hole or Bone, case-insensitive) as runTable1()
/// loads it, its tool resampled to `point_count` points (0: the paper's count): its volume and
/// tool mesh found in the shared datasets (the CT bunny unpacked when needed).
/// @return the spec, or nullopt with `why` when its data are absent.
/// @throws std::runtime_error for an unknown scene name.
std::optional<runtime::SceneSpec> table1SceneSpec(const std::string& name, std::size_t point_count, std::string& why);

/// The scripted hand of a Table 1 scene (runTable1()): at `locations` spots over `volume` the
/// tool, at orientation R0, hovers and circles, touches the isosurface F = `isovalue`, presses,
/// slides, pries, wedges and hooks, in `ticks` ticks at 1 kHz. Spots whose ray meets no surface
/// add a line to `notes` (when not null).
runtime::Trajectory table1Trajectory(const haptics::ScalarVolume& volume, const haptics::PointShell& shell,
                                     double isovalue, const Eigen::Quaterniond& R0, int ticks, int locations,
                                     std::vector<std::string>* notes = nullptr);

/// Error against run time (see the file comment). @return the output folder.
std::filesystem::path runAccuracy(const CommonOptions& options);

/// Stiffness sweep and extreme cases (see the file comment). @return the output folder.
std::filesystem::path runStability(const CommonOptions& options);
/// `bench drilling`: the burr's removal against the swept capsule (three burr radii, two voxel
/// sizes: capsule_cases, each with error_voxel_layers) and the solver's thread CPU time per tick
/// on the CT head phantom, drilling against touching alone on the same trajectory in the same
/// run (p99_9_ratio, max_ratio); writes drilling.json and drilling.md.
std::filesystem::path runDrilling(const CommonOptions& options);
/// `bench tissue`: the whole tick with soft tissue against the rigid tick on the same scenes (the
/// gel with an inclusion; the shared small CT head's soft tissue when present), tick by tick
/// interleaved, and the tissue's step per lattice size; writes tissue.json and tissue.md into
/// the output folder (returned). @throws std::runtime_error when a report cannot be written.
std::filesystem::path runTissue(const CommonOptions& options);

/// The drilling benchmarks' scene on the CT at `volume`: bone (400 HU) felt, the built-in drill
/// (2.5 mm ball burr) sampled every 1 mm, its burr spinning from the start when `drill_on`.
runtime::SceneSpec drillingScene(const std::filesystem::path& volume, bool drill_on);

/// The gel-palpation scene (resources/scenes/gel-palpation.json) as the tissue benchmarks press
/// it: the built-in gel with an inclusion, a 5 mm ball every 0.5 mm starting 6 mm left of the
/// inclusion's axis, the tissue in two value bands on lattice cells of `cell_m` [m]; the
/// application's default coupling (1,000 N/m), the stiffest the hand gets.
runtime::SceneSpec gelPalpationScene(double cell_m);

/// Where the benchmarks write: $VH_BENCH_OUT_DIR when set; installed
/// (runtime::installedDataDir()), $XDG_DATA_HOME/volume-haptics/bench, else
/// ~/.local/share/volume-haptics/bench, else ./volume-haptics-bench; from the build tree,
/// its `BUILD/bench`.
std::filesystem::path defaultOutputDir();

/// Adds the options every benchmark takes to `cmd`: --short, --out DIR (the default named after
/// `cmd`), --no-plots.
void addCommonOptions(CLI::App& cmd, CommonOptions& common);
/// Runs `f`; an exception is printed as "volume-haptics bench NAME: error: ..." and returns 1.
/// @return the process exit code (0 when `f` returned).
int runGuarded(const char* name, const std::function<void()>& f);

/// Adds `bench` with the subcommands `table1`, `accuracy`, `stability` and `bigscan` to `app`. After
/// app.parse(), `handler` is set when a bench subcommand was chosen; calling it runs the
/// benchmark and returns the process exit code (0 on success; errors are printed).
/// @return the `bench` subcommand.
CLI::App* addBenchSubcommand(CLI::App& app, std::function<int()>& handler);

}  // namespace vh::bench
