#pragma once
/// @file
/// `volume-haptics bench render`: the frame rate of the main view (SceneView: the volume as
/// isosurface, composite and MIP, the proxy and device tools, a segment surface) in a window of
/// each size asked for, while the haptic threads (HapticThread, 1 kHz) run a scripted trajectory
/// that presses on the scan and circles; and the haptic threads' tick times with rendering on and
/// off, interleaved in the same run (each rendered row is followed by as long without rendering).
///
/// Frames are the interactive frames of a person at work: each moves the camera a quarter degree
/// and shows the haptic threads' latest snapshot (the tools move), so SceneView renders them at
/// its interactive quality; after each row one still frame (full quality) is timed too. A drilling
/// row spins the burr (its removal uploaded to the volume texture as the view does when drilling).
///
/// The scan: `volume` when given; else a 512 x 512 x 275 int16 CT (an abdomen's size) generated
/// once into the build tree from the shared Philips head phantom (bench::bigScanSeries()); the
/// short run uses the shared small CT head (64 x 64 x 93).
///
/// The isosurface's rows (still and drilling) come twice: first as the window draws them (its
/// moving frames a surface mesh where the ray cast would be coarser than 3 px between rays: a
/// software renderer), then with the moving frames ray cast whatever their cost (`moving_view`
/// "ray cast"), side by side in one run.
///
/// The soft tissue rows (`tissue_rows`, one per size): the built-in gel with an inclusion pressed
/// 3 mm by the gel-palpation scene's ball and circled, the deformation shown as the window shows
/// it: the frame rate, the deformed windows shown per second and the time to show one.
///
/// Writes render.json (rows: mode, moving_view, surface_mesh_frames, surface_mesh_triangles,
/// width, height, fps_mean, frame_ms_mean, frame_ms_p99, frame_ms_max, still_frame_ms, renderer; servo: the solver's tick time [us] and the coupling
/// thread's with rendering on and off) and render.md, and prints the table. Needs an X display
/// with OpenGL (e.g. xvfb-run -a -s "-screen 0 1920x1080x24"). Creates the QApplication when
/// there is none; GUI thread only.

#include <array>
#include <filesystem>
#include <functional>
#include <vector>

#include "vh/bench/bench.h"

namespace CLI {
class App;
}

namespace vh::ui {

struct RenderBenchOptions {
  bench::CommonOptions common;
  /// The scan to render (DICOM folder, NRRD, MetaImage); empty: the generated CT (see the file
  /// comment), or the small CT head in a short run.
  std::filesystem::path volume;
  /// Slices of the generated CT (512 x 512 x slices); 0: 275.
  int slices = 0;
  /// Where the generated CT is written and reused; empty: defaultOutputDir() / "render" /
  /// "ct-512x512xN".
  std::filesystem::path series_dir;
  /// Window sizes [px] (width, height) of the view.
  std::vector<std::array<int, 2>> sizes = {{1280, 720}, {1920, 1080}};
  /// Rendering time of each row [s], and as long without rendering after it; 0: 4 s (short 0.5 s).
  double row_seconds = 0.0;
  /// Also the drilling rows (isosurface, the burr spinning).
  bool drilling = true;
  /// Also the soft tissue rows (`tissue_rows`): the built-in gel of the gel-palpation scene pressed
  /// and circled by its ball, its haptic thread stepping the tissue, each deformed window it
  /// publishes shown by the view (SceneActors::showVoxelBox(), as the window's Tissue panel does).
  bool tissue = true;
};

/// Runs the benchmark (see the file comment). @return the output folder.
/// @throws std::runtime_error without a display, for a volume that cannot be loaded, a trajectory
///         that meets no surface, or an unwritable output folder.
std::filesystem::path runRenderBench(const RenderBenchOptions& options);

/// Adds `render` to the `bench` subcommand (bench::addBenchSubcommand()); after parsing,
/// `handler` runs it when it was chosen (0 on success; errors are printed).
void addRenderBenchSubcommand(CLI::App& bench, std::function<int()>& handler);

}  // namespace vh::ui
