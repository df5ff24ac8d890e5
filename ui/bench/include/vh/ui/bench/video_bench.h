#pragma once
/// @file
/// `volume-haptics bench video`: how fast `volume-haptics export --video` (and the replay panel's
/// export, the same path: exportFrameRenderer(), writeRecordingVideo()) writes a recording's
/// frames, with each frame's time split into showing the record on the props, drawing the window,
/// reading its pixels back and encoding them (Ogg/Theora).
///
/// The recording: `recording` when given; else one made here as `run --record` makes it: the
/// shared Philips head phantom (bone at 400 HU) with the built-in probe, a push-and-slide
/// trajectory onto the skull from above (runtime::makePushSlideTrajectory(), about 4.6 s),
/// replayed by the headless runner into `video-bench.vhrec` in the output folder; a short run
/// uses the shared small CT head instead.
///
/// Writes video.json (the renderer, frame size, fps, frames, frames_per_s, volume_renders, and per stage the
/// mean, p50, p99 and max [ms] of show, render, readback, encode and the whole frame) and
/// video.md, and prints the table. Needs an X display with OpenGL (xvfb-run -a -s "-screen 0
/// 1280x1024x24").

#include <filesystem>
#include <functional>

#include "vh/bench/bench.h"

namespace CLI {
class App;
}

namespace vh::ui {

struct VideoBenchOptions {
  bench::CommonOptions common;
  /// The recording to export; empty: one made on the head phantom (see the file comment).
  std::filesystem::path recording;
  int width = 640;    ///< Frame width [px].
  int height = 480;   ///< Frame height [px].
  double fps = 10.0;  ///< Frames per second of recording time.
  /// The frames to time; 0: the whole recording at `fps`.
  int frames = 0;
  /// Render every frame in full, the volume ray cast each time
  /// (RecordingFrameRenderer::setReuseVolume(false)): the export as it was before the volume's
  /// picture was kept, for a before and after.
  bool full_render = false;
};

/// Runs the benchmark (see the file comment). @return the output folder.
/// @throws std::runtime_error without a display, for a recording that cannot be read or whose
///         scene cannot be loaded, or an unwritable output folder.
std::filesystem::path runVideoBench(const VideoBenchOptions& options);

/// Adds `video` to the `bench` subcommand; after parsing, `handler` runs it when it was chosen.
void addVideoBenchSubcommand(CLI::App& bench, std::function<int()>& handler);

}  // namespace vh::ui
