#pragma once
/// @file
/// Benchmarks of the rendering core (issue 7), run by `volume-haptics bench ...`:
///   table1     the paper's Table 1 (section 3.2): four scenes, scripted device trajectories,
///              tick times per detection mode (paper / accelerated) side by side with their ratio,
///              and the accelerated mode with issue 8's end-sample segment test (the "before"
///              column of issue 12) against the exact test; every tick's proxy motion checked
///              for crossings by haptics::CrossingVerifier outside the timed section;
///   accuracy   contact-position and normal error against tick time on volumes with exact
///              isosurfaces, swept over epsilon, segment_fraction and point-shell density;
///   stability  the coupling-stiffness sweep with the simulated device (vh::simulation) and a
///              table of extreme cases with their outcomes.
/// Each writes a JSON report, a Markdown report and PNG plots (VTK charts rendered off screen;
/// skipped with a message when no X display is available) into an output folder.
/// Not part of the servo loop: allocates, prints and throws freely.

#include <filesystem>
#include <functional>
#include <string>

#include "vh/haptics/haptic_renderer.h"

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
  /// When the accelerated mode runs: also run it with SegmentTest::kEndSample (issue 8's test, the
  /// "before" column of issue 12), interleaved with the others, and compare it with the exact test.
  bool before = false;
  /// Crossing check after every tick (haptics::CrossingVerifier, outside the timed section):
  /// sampling step along each shell point's path [voxels]; 0: off (crossings reported as -1).
  double verify_step_voxels = 0.01;
  /// Issue 13: the accelerated mode's RendererOptions::work_budget (the application's default).
  /// > 0 also runs the accelerated mode without it ("accelerated-unbudgeted"), interleaved, and
  /// reports the budgeted proxy's lag behind it (mm, rad, ticks), the cut ticks and the "Never
  /// late" table with the targets; 0 runs the accelerated mode unbudgeted only.
  std::int64_t work_budget = haptics::RendererOptions::kDefaultWorkBudget;
  /// Run only this scene ("Bunny", "Engine", "Hole", "Bone", case-insensitive); empty: all.
  std::string scene;
  /// Ticks per scene and mode; 0: 20,000 (short: 1,000).
  int ticks = 0;
  /// Also the issue-8 large-tool runs (~20,000 points on Bone and Engine); never in short runs.
  bool large_tools = true;
};

/// The paper's Table 1 (see the file comment). Scenes whose data are absent are skipped with a
/// message (and listed as skipped in the report). @return the output folder.
/// @throws std::runtime_error for an unknown scene name or an unwritable output folder.
std::filesystem::path runTable1(const Table1Options& options);

/// Error against run time (see the file comment). @return the output folder.
std::filesystem::path runAccuracy(const CommonOptions& options);

/// Stiffness sweep and extreme cases (see the file comment). @return the output folder.
std::filesystem::path runStability(const CommonOptions& options);

/// The build tree's benchmark folder (`BUILD/bench`), or $VH_BENCH_OUT_DIR when set.
std::filesystem::path defaultOutputDir();

/// Adds `bench` with the subcommands `table1`, `accuracy` and `stability` to `app`. After
/// app.parse(), `handler` is set when a bench subcommand was chosen; calling it runs the
/// benchmark and returns the process exit code (0 on success; errors are printed).
/// @return the `bench` subcommand.
CLI::App* addBenchSubcommand(CLI::App& app, std::function<int()>& handler);

}  // namespace vh::bench
