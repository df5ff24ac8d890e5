#pragma once
/// @file
/// `volume-haptics bench memory`: the peak resident memory of the application against the bytes
/// of the scan's voxels, with the reader process (the `volume-haptics-dicom-worker` that reads
/// the files) counted, in one report. Three runs, each a fresh process of the program started
/// by this one:
///  - `gui`: the window as a user opens it (`volume-haptics SCAN --touch --screenshot PNG`: the
///    series read in the reader process, the histogram, the volume uploaded to the ray caster,
///    the haptic threads running on the field, the tool brought onto the surface);
///  - `gui_baseline`: the same on a tiny scan (the shared 64 x 64 x 93 CT head, 0.7 MB of
///    voxels): what the program takes whatever it opens (libraries, Qt, the GL context);
///  - `headless_load`: io::loadVolume alone (`bench bigscan`'s load child), which also says
///    whether the rendering image shares the field's voxel buffer; its figures are the child's
///    own, taken when the load returns (VmHWM, its reader's ru_maxrss, their sum sampled).
/// Each window run's memory is sampled every 5 ms from /proc (the program and every process
/// below it once it runs its own executable; VmRSS summed, each one's VmHWM kept), and the
/// program's own peak is also the kernel's (wait4's ru_maxrss). Peak = the largest of the
/// sampled sum and each process's own peak.
///
/// The scan: `volume` when given; else the 512 x 512 x 275 int16 CT of `bench render`
/// (bench::bigScanSeries(), generated once into the build tree); a short run uses the shared
/// small CT head for both GUI runs. Needs an X display with OpenGL (xvfb-run).
///
/// Writes memory.json: `voxel_bytes`, `runs` (each: `name`, `command`, `peak_bytes`,
/// `own_peak_bytes`, `reader_peak_bytes`, `concurrent_peak_bytes`, `ru_maxrss_bytes`,
/// `wall_s`, `exit_code`), `gui_peak_over_voxels`, `gui_added_over_voxels` ((gui peak - baseline
/// peak) / voxel bytes), `headless_peak_over_voxels`, `image_shares_field`; and memory.md.

#include <filesystem>
#include <functional>

#include "vh/bench/bench.h"

namespace CLI {
class App;
}

namespace vh::ui {

struct MemoryBenchOptions {
  bench::CommonOptions common;
  /// The scan (DICOM folder, NRRD, MetaImage); empty: the generated CT (see the file comment),
  /// or the small CT head in a short run.
  std::filesystem::path volume;
  /// Slices of the generated CT (512 x 512 x slices); 0: 275.
  int slices = 0;
  /// Where the generated CT is written and reused; empty: bench render's,
  /// defaultOutputDir() / "render" / "ct-512x512xN".
  std::filesystem::path series_dir;
  /// The volume-haptics program to measure; empty: this process's own executable.
  std::filesystem::path program;
};

/// Runs the benchmark (see the file comment). @return the output folder.
/// @throws std::runtime_error without a display, when the program cannot be started, a run
///         fails, or the output folder cannot be written.
std::filesystem::path runMemoryBench(const MemoryBenchOptions& options);

/// Adds `memory` to the `bench` subcommand; after parsing, `handler` runs it when it was chosen.
void addMemoryBenchSubcommand(CLI::App& bench, std::function<int()>& handler);

}  // namespace vh::ui
