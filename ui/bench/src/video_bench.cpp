// `volume-haptics bench video`: the frame rate of `export --video`, with each frame split into
// show, render, read-back and encode (see video_bench.h).
#include "vh/ui/bench/video_bench.h"

#include <algorithm>
#include <chrono>
#include <fstream>
#include <iostream>
#include <memory>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <vtkRenderWindow.h>

#include "vh/bench/report.h"
#include "vh/runtime/placement.h"
#include "vh/runtime/recording.h"
#include "vh/runtime/runner.h"
#include "vh/runtime/scene.h"
#include "vh/runtime/session_metadata.h"
#include "vh/runtime/trajectory.h"
#include "vh/ui/export/media_export.h"

namespace vh::ui {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

constexpr const char* kPhantom = "ct/philips-head-phantom-bone";
constexpr double kPhantomIsovalue_HU = 400.0;  // the skull's surface

/// A recording as `run --record` makes one (see video_bench.h): the head phantom (short: the
/// small CT head) and the built-in probe, pushed onto the skull from above and slid along it.
fs::path makeRecording(const fs::path& out, bool short_run) {
  const fs::path volume = runtime::sharedDatasetsDir() / (short_run ? "ct/ct-head-small" : kPhantom);
  if (!fs::exists(volume))
    throw std::runtime_error("bench video: " + volume.string() +
                             " is absent: give a recording with --recording (volume-haptics run --record)");
  runtime::SceneSpec spec = runtime::sceneForVolume(volume);
  if (!short_run) {
    spec.volume.isovalue = kPhantomIsovalue_HU;
    spec.volume.isovalue_set = true;
  }
  const runtime::LoadedScene scene = runtime::loadScene(spec);
  const haptics::Pose start = runtime::poseAboveVolume(*scene.hapticField(), scene.tool->point_shell,
                                                       scene.X_WT_initial.R_AB, 0.01);
  const runtime::PushSlidePlan plan = runtime::makePushSlideTrajectory(
      *scene.hapticField(), scene.tool->point_shell, scene.hapticIsovalue(), start, runtime::PushSlideOptions{});
  runtime::RunOptions run;
  run.record = out / "video-bench.vhrec";
  run.verify_step_voxels = 0.0;
  run.check_penetration = false;
  run.lag_reference = false;
  run.record_note = "bench video";
  runtime::runHeadless(scene, plan.trajectory, run);
  return run.record;
}

/// The 1-minute load average (/proc/loadavg): how busy the machine was; -1 when unknown.
double loadAverage() {
  std::ifstream in("/proc/loadavg");
  double load = -1.0;
  return (in >> load) ? load : -1.0;
}

nlohmann::ordered_json statsJson(const bench::Stats& s) {
  return {{"mean", s.mean}, {"p50", s.p50}, {"p99", s.p99}, {"max", s.max}};
}

}  // namespace

fs::path runVideoBench(const VideoBenchOptions& o) {
  using namespace bench;
  if (!displayAvailable())
    throw std::runtime_error("bench video renders off screen and needs an X display with OpenGL: run it under "
                             "xvfb-run -a -s \"-screen 0 1280x1024x24\"");
  const fs::path out = outputDir(o.common, "video");
  fs::path recording_path = o.recording;
  if (recording_path.empty()) {
    std::cout << "bench video: recording a push and slide on the "
              << (o.common.short_run ? "small CT head" : "head phantom") << " ..." << std::endl;
    recording_path = makeRecording(out, o.common.short_run);
  }
  const runtime::Recording recording = runtime::readRecording(recording_path);
  if (recording.records.empty()) throw std::runtime_error(recording_path.string() + ": the recording has no records");
  runtime::SceneSpec spec = runtime::sceneFromSessionMetadata(recording.metadata_json);
  spec.device.reset();
  const Clock::time_point load_begin = Clock::now();
  const runtime::LoadedScene scene = runtime::loadScene(spec);
  const double load_s = std::chrono::duration<double>(Clock::now() - load_begin).count();

  // As `export --video` does: the same options' defaults (overlay, shadow, isosurface).
  MediaExportOptions options;
  options.width = o.width;
  options.height = o.height;
  options.fps = o.fps;
  const Clock::time_point setup_begin = Clock::now();
  const std::unique_ptr<RecordingFrameRenderer> frames = exportFrameRenderer(scene, recording, options, &std::cout, recording_path);
  frames->setReuseVolume(!o.full_render);
  const double setup_s = std::chrono::duration<double>(Clock::now() - setup_begin).count();
  const double first_s = recording.records.front().time_s;
  const double end_s = o.frames > 0 ? std::min(recording.records.back().time_s, first_s + (o.frames - 1) / o.fps) : -1.0;

  std::vector<VideoFrameTimes> times;
  const Clock::time_point video_begin = Clock::now();
  const int written = writeRecordingVideo(*frames, recording, out / "video-bench.ogv", o.fps, first_s, end_s, {}, &times);
  const double video_s = std::chrono::duration<double>(Clock::now() - video_begin).count();
  if (written == 0 || times.empty()) throw std::runtime_error("bench video: no frame was written");

  std::vector<double> show, render, readback, encode, total;
  for (const VideoFrameTimes& t : times) {
    show.push_back(t.show_ms), render.push_back(t.render_ms), readback.push_back(t.readback_ms);
    encode.push_back(t.encode_ms), total.push_back(t.show_ms + t.render_ms + t.readback_ms + t.encode_ms);
  }
  // The first frame separately: it compiles the shaders and uploads the volume.
  const double first_frame_ms = total.front();
  const auto steady = [](std::vector<double> v) {
    if (v.size() > 1) v.erase(v.begin());
    return summarize(std::move(v));
  };
  const Stats s_show = steady(show), s_render = steady(render), s_read = steady(readback), s_encode = steady(encode),
              s_total = steady(total);
  const double fps = s_total.mean > 0 ? 1000.0 / s_total.mean : 0.0;

  std::string gl_renderer;
  {
    const char* caps = frames->renderWindow()->ReportCapabilities();
    std::istringstream lines(caps != nullptr ? caps : "");
    for (std::string line; std::getline(lines, line);)
      if (line.find("OpenGL renderer string") != std::string::npos) gl_renderer = line.substr(line.find(':') + 2);
  }

  nlohmann::ordered_json report = reportHeader("video", o.common.short_run);
  report["recording"] = recording_path.string();
  report["load_average"] = loadAverage();
  report["renderer"] = gl_renderer;
  report["width"] = frames->width();
  report["height"] = frames->height();
  report["fps_of_recording_time"] = o.fps;
  report["frames"] = written;
  report["full_render"] = o.full_render;
  report["volume_renders"] = frames->volumeRenders();
  report["scene_load_s"] = load_s;
  report["setup_s"] = setup_s;
  report["first_frame_ms"] = first_frame_ms;
  report["video_wall_s"] = video_s;
  report["frames_per_s"] = fps;
  report["frames_per_s_wall"] = video_s > 0 ? written / video_s : 0.0;
  report["target_frames_per_s"] = 10.0;
  report["frame_ms"] = {{"show", statsJson(s_show)},
                        {"render", statsJson(s_render)},
                        {"readback", statsJson(s_read)},
                        {"encode", statsJson(s_encode)},
                        {"total", statsJson(s_total)}};
  std::ostringstream md;
  md << "## Video export (`volume-haptics bench video" << (o.common.short_run ? " --short" : "") << "`)\n\n"
     << format("%d frames of %s at %d x %d (%.0f fps of recording time), %s, OpenGL renderer %s, CPU %s (%u CPUs, "
               "load average %.1f). Scene loaded in %.1f s, frame renderer set up in %.2f s, first frame %.0f ms "
               "(shaders, volume upload%s); the volume ray cast %llu times in all; the frames after the first:\n\n",
               written, recording_path.filename().string().c_str(), frames->width(), frames->height(), o.fps,
               o.full_render ? "every frame a full render (--full-render)" : "the volume's picture kept",
               gl_renderer.c_str(), report["cpu_model"].get<std::string>().c_str(), report["cpus"].get<unsigned>(),
               loadAverage(), load_s, setup_s, first_frame_ms, o.full_render ? "" : ", the volume's picture and depth",
               static_cast<unsigned long long>(frames->volumeRenders()))
     << "| stage | mean [ms] | p50 [ms] | p99 [ms] | max [ms] |\n|---|---|---|---|---|\n";
  const std::pair<const char*, const Stats*> rows[] = {{"show (poses, shadow, overlay)", &s_show},
                                                        {"render (to completion)", &s_render},
                                                        {"read-back", &s_read},
                                                        {"encode (Theora)", &s_encode},
                                                        {"frame", &s_total}};
  for (const auto& [name, st] : rows)
    md << format("| %s | %.1f | %.1f | %.1f | %.1f |\n", name, st->mean, st->p50, st->p99, st->max);
  md << format("\n**%.1f frames per second** (target at least 10 at 640 x 480: %s); %.1f with the first frame, over "
               "the whole export's wall time.\n",
               fps, fps >= 10.0 ? "met" : "NOT MET", report["frames_per_s_wall"].get<double>());
  writeReport(out, "video", report, md, {});
  return out;
}

void addVideoBenchSubcommand(CLI::App& bench, std::function<int()>& handler) {
  auto options = std::make_shared<VideoBenchOptions>();
  CLI::App* cmd = bench.add_subcommand(
      "video", "Frames per second of `export --video`, each frame split into show, render, read-back and encode, on a "
               "recording (default: one made on the head phantom); needs an X display (xvfb-run -a -s \"-screen 0 "
               "1280x1024x24\")");
  bench::addCommonOptions(*cmd, options->common);
  cmd->add_option("--recording", options->recording, "The recording (.vhrec) to export (default: one made here)")
      ->check(CLI::ExistingFile);
  cmd->add_option("--width", options->width, "Frame width [px] (default 640)")->check(CLI::Range(16, 8192));
  cmd->add_option("--height", options->height, "Frame height [px] (default 480)")->check(CLI::Range(16, 8192));
  cmd->add_option("--fps", options->fps, "Frames per second of recording time (default 10)")->check(CLI::Range(1.0, 120.0));
  cmd->add_option("--frames", options->frames, "Frames to time (default: the whole recording)")->check(CLI::Range(1, 1000000));
  cmd->add_flag("--full-render", options->full_render,
                "Render every frame in full, the volume ray cast each time: the export before its volume picture was "
                "kept (for a before and after)");
  cmd->callback([&handler, options] {
    handler = [options] { return bench::runGuarded("video", [&] { runVideoBench(*options); }); };
  });
}

}  // namespace vh::ui
