// `volume-haptics bench render`: the main view's frame rate while the haptic threads run, and
// the haptic threads' tick times with rendering on and off (see render_bench.h).
#include "vh/ui/bench/render_bench.h"

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <fstream>
#include <iostream>
#include <memory>
#include <numbers>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>

#include <CLI/CLI.hpp>
#include <QApplication>
#include <QVBoxLayout>
#include <QWidget>
#include <vtkCamera.h>
#include <vtkGenericOpenGLRenderWindow.h>
#include <vtkImageData.h>
#include <vtkRenderer.h>
#include <vtkTextureObject.h>

#include "vh/bench/report.h"
#include "vh/runtime/haptic_thread.h"
#include "vh/runtime/recording.h"
#include "vh/runtime/scene.h"
#include "vh/runtime/servo_factory.h"
#include "vh/runtime/trajectory.h"
#include "vh/tissue/deformable_scene.h"
#include "vh/ui/application.h"
#include "vh/ui/drill_controller.h"
#include "vh/ui/export/media_export.h"
#include "vh/ui/view/scene_view.h"
#include "vh/ui/view/tool_shadow.h"
#include "vh/ui/view/vtk_view.h"

namespace vh::ui {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

constexpr double kServoRate_Hz = 1000.0;
constexpr int kGeneratedSlices = 275;        // an abdomen CT's slice count
constexpr double kCameraStep_deg = 0.25;     // camera turn per frame: a slow drag
constexpr double kPressDepth_m = 0.003;      // the device this far past the first contact
constexpr double kCircleRadius_m = 0.004;    // the circle the device draws on the surface
constexpr double kCirclePeriod_s = 3.0;

double msSince(Clock::time_point t0) { return std::chrono::duration<double, std::milli>(Clock::now() - t0).count(); }

/// The mode's name as the report spells it: "isosurface", "composite", "mip".
std::string rowName(RenderMode mode) {
  std::string name = modeName(mode);
  for (char& c : name) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return name;
}

/// A shown (not felt) segment for the picture: a sphere of a fifth of the scan's smallest extent
/// at its centre, on a grid four times coarser than the scan's.
std::shared_ptr<const runtime::SegmentSet> sphereSegment(const haptics::ScalarVolume& scan) {
  constexpr int kStep = 4;
  const haptics::VolumeGeometry& g = scan.geometry();
  haptics::VolumeGeometry sg = g;
  for (int a = 0; a < 3; ++a) {
    sg.dims[static_cast<std::size_t>(a)] = std::max(2, (g.dims[static_cast<std::size_t>(a)] + kStep - 1) / kStep);
    sg.spacing_m[a] = g.spacing_m[a] * kStep;
  }
  const Eigen::Vector3d extent_m(g.spacing_m.x() * (g.dims[0] - 1), g.spacing_m.y() * (g.dims[1] - 1),
                                 g.spacing_m.z() * (g.dims[2] - 1));
  const double radius_m = 0.2 * extent_m.minCoeff();
  std::vector<std::uint8_t> labels(sg.voxelCount(), 0);
  std::size_t count = 0;
  for (int k = 0; k < sg.dims[2]; ++k)
    for (int j = 0; j < sg.dims[1]; ++j)
      for (int i = 0; i < sg.dims[0]; ++i) {
        const Eigen::Vector3d p(i * sg.spacing_m.x(), j * sg.spacing_m.y(), k * sg.spacing_m.z());
        if ((p - 0.5 * extent_m).norm() > radius_m) continue;
        labels[static_cast<std::size_t>(i) + static_cast<std::size_t>(sg.dims[0]) * (j + static_cast<std::size_t>(sg.dims[1]) * k)] = 1;
        ++count;
      }
  io::LoadedSegmentation seg;
  seg.source = "bench render: a sphere";
  io::SegmentInfo info;
  info.id = "Segment_1";
  info.name = "sphere";
  info.color_rgb = {0.85, 0.35, 0.3};
  info.voxel_count = count;
  seg.segments.push_back(info);
  seg.layers.push_back(std::make_shared<const haptics::ScalarVolume>(haptics::ScalarVolume::FromVoxels(sg, labels)));
  return std::make_shared<const runtime::SegmentSet>(std::move(seg), std::vector<int>{}, std::vector<int>{0},
                                                     std::vector<int>{}, 1.0);
}

/// The device's path: from the initial pose down to the first contact of the tool below it and
/// kPressDepth_m beyond, then circles of kCircleRadius_m on the surface until `duration_s`.
/// @throws std::runtime_error when the tool meets no surface below its initial pose.
runtime::Trajectory pressAndCircle(const runtime::LoadedScene& scene, double duration_s) {
  const runtime::PushSlidePlan plan = runtime::makePushSlideTrajectory(
      *scene.hapticField(), scene.tool->point_shell, scene.hapticIsovalue(), scene.X_WT_initial);
  std::vector<runtime::TrajectorySample> keys;
  keys.push_back({0.0, scene.X_WT_initial});
  for (double t = 1.0; t <= duration_s + 1.0; t += 0.02) {
    runtime::TrajectorySample s{t, plan.X_WD_contact};
    const double r = kCircleRadius_m * std::min(1.0, t - 1.0);
    const double phase = 2.0 * std::numbers::pi * (t - 1.0) / kCirclePeriod_s;
    s.X_WD.p_AB_m += Eigen::Vector3d(r * std::cos(phase) - r, r * std::sin(phase), -kPressDepth_m);
    keys.push_back(s);
  }
  return runtime::Trajectory(std::move(keys));
}

/// A stretch of the run: the haptic threads' solver ticks [begin, end), rendering or not, and the
/// coupling thread's largest one-second figures seen meanwhile.
struct Phase {
  bool rendering = false;
  std::uint64_t begin = 0, end = 0;
  double coupling_max_tick_us = 0.0;
  double coupling_jitter_us = 0.0;
  std::uint64_t misses_begin = 0, misses_end = 0;
};

/// The window, its view and the haptic threads feeding it.
/// Each frame of a row in parts [ms], in order: VTK's render and the blit as the CPU issues
/// them, the swap, the tool's shadow cast (with the cavity's carving while drilling); and the
/// image sample distance it was cast at [px].
struct FrameParts {
  std::vector<double> paint_ms, swap_ms, shadow_ms, image_sample_px;
  std::size_t surface_mesh_frames = 0;  // frames that drew the surface mesh, not the ray cast
  // Soft tissue: the deformed windows the frames took from the haptic thread and showed (as the
  // window's TissueController does), each one's showVoxelBox() [ms], the deepest indentation [m].
  std::size_t windows_shown = 0;
  std::vector<double> tissue_show_ms;
  double indentation_m = 0.0;
};

struct Bench {
  QWidget window;
  SceneView* view = nullptr;  // owned by the window
  runtime::HapticThread* thread = nullptr;
  const haptics::ScalarVolume* scan = nullptr;
  std::shared_ptr<const haptics::ScalarVolume> felt;  // the haptic field, which the tool's shadow falls on
  CarvedRegion carved;  // felt, carved by the drill (as the window's DrillController keeps it)
  double felt_isovalue = 0.0;
  tissue::DeformableScene* tissue = nullptr;  // the thread's soft tissue (null: none)
  tissue::DeformedWindow deformed;            // its last window taken
  std::vector<Eigen::Vector3d> shadow_samples_T_m;
  runtime::HapticSnapshot snapshot;
  std::vector<Phase> phases;
  std::vector<std::uint64_t> drained, picture;

  void poll(Phase& phase) {
    if (!thread->latestSnapshot(snapshot)) return;
    phase.coupling_max_tick_us = std::max(phase.coupling_max_tick_us, snapshot.coupling.max_tick_us);
    phase.coupling_jitter_us = std::max(phase.coupling_jitter_us, snapshot.coupling.jitter_us);
  }
  Phase begin(bool rendering) {
    Phase p;
    p.rendering = rendering;
    thread->latestSnapshot(snapshot);
    p.begin = snapshot.solver_tick;
    p.misses_begin = snapshot.coupling.deadline_misses + snapshot.solver.deadline_misses;
    return p;
  }
  void end(Phase& p) {
    thread->latestSnapshot(snapshot);
    p.end = snapshot.solver_tick;
    p.misses_end = snapshot.coupling.deadline_misses + snapshot.solver.deadline_misses;
    phases.push_back(p);
  }
  /// Moves the drill's removed voxels into the picture and into the shadow's carved field (as
  /// the window's DrillController does); the carving's time goes to `carve_ms`.
  std::uint64_t drain(double& carve_ms) {
    const auto& drill = thread->drill();
    if (drill == nullptr) return 0;
    std::uint64_t total = 0;
    for (;;) {
      const std::size_t n = drill->removal().drainRemoved(drained);
      if (n == 0) break;
      picture = pictureIndices(drill->removal().volume(), *scan, std::span<const std::uint64_t>(drained.data(), n));
      view->actors().removeVoxels(picture, view->actors().removedValue());
      const auto carve_t0 = Clock::now();
      carved.remove(std::span<const std::uint64_t>(drained.data(), n));
      carve_ms += msSince(carve_t0);
      total += n;
    }
    return total;
  }
  /// One frame as the window draws it while someone works: the camera turned a little, the
  /// latest haptic snapshot shown with the tool's shadow cast for it (as ViewController does),
  /// painted now. @return its wall time [ms]; its parts go to `parts`.
  double frame(Phase& phase, bool drilling, std::uint64_t& removed, FrameParts& parts) {
    const auto t0 = Clock::now();
    poll(phase);
    double carve_ms = 0.0;
    if (drilling) removed += drain(carve_ms);
    if (tissue != nullptr && tissue->takeDeformedWindow(deformed)) {
      const auto show_t0 = Clock::now();
      if (view->actors().showVoxelBox(deformed.lo, deformed.hi, std::span<const float>(deformed.values_F))) {
        ++parts.windows_shown;
        parts.indentation_m = std::max(parts.indentation_m, deformed.indentation_m);
      }
      parts.tissue_show_ms.push_back(msSince(show_t0));
    }
    view->widget()->renderer()->GetActiveCamera()->Azimuth(kCameraStep_deg);
    view->noteMotion();
    ToolFrame f;
    f.X_WP = snapshot.X_WP;
    f.X_WD = snapshot.X_WD;
    f.force_W_N = snapshot.force_W_N;
    f.contacts_W_m = std::span<const Eigen::Vector3d>(snapshot.contact_p_W_m.data(),
                                                      static_cast<std::size_t>(snapshot.contacts_shown));
    view->show(f);
    const auto shadow_t0 = Clock::now();
    const Eigen::Vector3d down_W = view->shadowDirection_W();
    view->showShadow(castToolShadow(*felt, carved, felt_isovalue, f.X_WP, shadow_samples_T_m, down_W), down_W);
    parts.shadow_ms.push_back(msSince(shadow_t0) + carve_ms);
    parts.image_sample_px.push_back(view->actors().imageSampleDistance_px());  // what this frame casts
    view->widget()->renderNow();
    if (view->actors().surfaceMeshShown()) ++parts.surface_mesh_frames;
    parts.paint_ms.push_back(view->widget()->lastFrameMs());
    parts.swap_ms.push_back(view->widget()->lastSwapMs());
    QCoreApplication::processEvents();
    return msSince(t0);
  }
  void idle(double seconds) {
    Phase p = begin(false);
    const auto t0 = Clock::now();
    while (msSince(t0) < 1e3 * seconds) {
      QCoreApplication::processEvents();
      poll(p);
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
    end(p);
  }
  void resizeView(int width, int height) {
    window.resize(width, height);
    const auto t0 = Clock::now();
    while ((view->widget()->width() != width || view->widget()->height() != height) && msSince(t0) < 2000.0)
      QCoreApplication::processEvents();
  }
};

/// The GL renderer, version and 3-D texture limit of the view's context (after its first frame).
struct GlInfo {
  std::string renderer = "unknown", version = "unknown";
  int max_3d_texture = -1;
};
GlInfo glInfo(VtkView& view) {
  GlInfo info;
  view.makeCurrent();
  vtkGenericOpenGLRenderWindow* window = view.renderWindow();
  const std::string caps = window->ReportCapabilities() != nullptr ? window->ReportCapabilities() : "";
  std::istringstream lines(caps);
  for (std::string line; std::getline(lines, line);) {
    const auto value = [&] {
      std::string v = line.substr(line.find(':') + 1);
      v.erase(0, v.find_first_not_of(" \t"));
      return v;
    };
    if (line.find("OpenGL renderer string") != std::string::npos) info.renderer = value();
    if (line.find("OpenGL version string") != std::string::npos) info.version = value();
  }
  info.max_3d_texture = vtkTextureObject::GetMaximumTextureSize3D(window);
  view.doneCurrent();
  return info;
}

/// The 1-minute load average (/proc/loadavg): how busy the machine was besides the benchmark;
/// -1 when unknown.
double loadAverage() {
  std::ifstream in("/proc/loadavg");
  double load = -1.0;
  return (in >> load) ? load : -1.0;
}

nlohmann::ordered_json statsJson(const bench::Stats& s) {
  return {{"n", s.n}, {"mean", s.mean}, {"p50", s.p50}, {"p99", s.p99}, {"p99_9", s.p999}, {"max", s.max}};
}

}  // namespace

namespace {

/// The scan to render: --volume, else (short) the shared small CT head, else the generated big
/// series (made once in --series-dir).
fs::path renderBenchScan(const RenderBenchOptions& o, bool short_run) {
  using namespace bench;
  fs::path volume = o.volume;
  if (volume.empty() && short_run) volume = runtime::sharedDatasetsDir() / "ct" / "ct-head-small";
  if (volume.empty()) {
    const int slices = o.slices > 0 ? o.slices : kGeneratedSlices;
    const fs::path dir = o.series_dir.empty() ? defaultOutputDir() / "render" / format("ct-512x512x%d", slices) : o.series_dir;
    volume = bigScanSeries(dir, slices);
  }
  return volume;
}

/// What a row draws: the render mode, the burr on or off, and what its moving frames draw.
struct RowKind {
  RenderMode mode = RenderMode::kIsosurface;
  bool drilling = false;
  MovingView moving = MovingView::kAuto;
  bool tissue = false;  // the gel's soft tissue pressed and deformed (the bench's tissue thread)
};

/// The row's name in the report: "isosurface", "composite", "mip", "drilling", "tissue".
std::string rowName(const RowKind& kind) {
  if (kind.tissue) return "tissue";
  return kind.drilling ? std::string("drilling") : rowName(kind.mode);
}

/// What a row's moving frames drew, for its table: "mesh" (the surface mesh in all of them),
/// "ray cast", or "mesh N/M" when only N of its M frames did.
std::string movingPicture(const nlohmann::ordered_json& row) {
  const auto mesh = row["surface_mesh_frames"].get<std::size_t>(), frames = row["frames"].get<std::size_t>();
  if (mesh == 0) return "ray cast";
  if (mesh == frames) return "mesh";
  return bench::format("mesh %zu/%zu", mesh, frames);
}

/// One row: the view at `size` in `kind`'s mode for `row_s` seconds of frames, then its still
/// frame and as long without rendering; its picture into `picture_dir` (empty: none).
/// `scan_voxel_m`: the scan's smallest spacing [m].
nlohmann::ordered_json renderRow(Bench& b, runtime::HapticThread& thread, const RowKind& kind,
                                 const std::array<int, 2>& size, const ViewLook& look, double row_s,
                                 const fs::path& picture_dir, const GlInfo& gl, double scan_voxel_m) {
  using namespace bench;
  const RenderMode mode = kind.mode;
  const bool drilling = kind.drilling;
  const bool ray_cast = kind.moving == MovingView::kRayCast;
  b.resizeView(size[0], size[1]);
  b.view->actors().setMovingView(kind.moving);
  b.view->setRenderMode(mode, look.preset);
  b.view->resetCamera();
  auto t0 = Clock::now();
  b.view->widget()->renderNow();  // a new mode compiles its shader
  const double first_ms = msSince(t0);
  if (drilling) {  // the burr switched on: the picture's copy for the cavity, uploaded once
    b.view->actors().prepareRemoval();
    b.view->widget()->renderNow();
  }
  thread.setDrilling(drilling);
  const std::uint64_t partial0 = b.view->actors().partialUploads(), full0 = b.view->actors().fullUploads();
  std::uint64_t removed = 0;
  std::vector<double> frames;
  FrameParts parts;
  const std::uint64_t paints0 = b.view->widget()->frameCount();
  Phase on = b.begin(true);
  t0 = Clock::now();
  while (msSince(t0) < 1e3 * row_s || frames.size() < 3) frames.push_back(b.frame(on, drilling, removed, parts));
  const double elapsed_s = 1e-3 * msSince(t0);
  b.end(on);
  thread.setDrilling(false);
  const double interactive_px = b.view->actors().imageSampleDistance_px();
  const double interactive_voxels = b.view->actors().sampleDistance_m() / scan_voxel_m;
  // What the eyes got meanwhile: one more frame at the row's last interactive sampling.
  std::string picture;
  if (!picture_dir.empty()) {
    picture = format("interactive-%s%s-%dx%d.png", rowName(kind).c_str(), ray_cast ? "-ray-cast" : "",
                     b.view->widget()->width(), b.view->widget()->height());
    if (!b.view->widget()->grabFrame().save(QString::fromStdString((picture_dir / picture).string()), "PNG"))
      picture.clear();
  }
  // The still frame when the hand rests, at the quality the view chooses for it.
  b.view->renderStill();
  const double still_sample_voxels = b.view->actors().sampleDistance_m() /
                                     scan_voxel_m;
  const double still_px = b.view->actors().imageSampleDistance_px();
  // Painted until the view has drawn a new frame (a repaint that draws nothing does not count).
  const std::uint64_t frames_before_still = b.view->widget()->frameCount();
  t0 = Clock::now();
  b.view->widget()->renderNow();
  while (b.view->widget()->frameCount() == frames_before_still && msSince(t0) < 30000.0) {
    QCoreApplication::processEvents(QEventLoop::AllEvents, 5);
  }
  const double still_ms = msSince(t0);
  b.idle(row_s);

  const Stats s = summarize(frames);
  nlohmann::ordered_json row;
  row["mode"] = rowName(kind);
  // What the moving frames were asked to draw ("auto": the view's own choice, as in the window;
  // "ray cast": the ray cast whatever its cost, the comparison row), and what they drew.
  row["moving_view"] = ray_cast ? "ray cast" : "auto";
  row["surface_mesh_frames"] = parts.surface_mesh_frames;
  row["surface_mesh_triangles"] = b.view->actors().surfaceMeshTriangles();
  row["surface_mesh_factor"] = b.view->actors().surfaceMeshFactor();
  row["width"] = b.view->widget()->width();
  row["height"] = b.view->widget()->height();
  row["frames"] = frames.size();
  row["fps_mean"] = static_cast<double>(frames.size()) / elapsed_s;
  row["frame_ms_mean"] = s.mean;
  row["frame_ms_p99"] = s.p99;
  row["frame_ms_max"] = s.max;
  row["frames_ms"] = frames;  // each frame in order: the first ones after the still frame and the mode change show
  // VtkView paints per frame: 1 when each frame is painted once (no queued repaint on top).
  row["paints_per_frame"] = static_cast<double>(b.view->widget()->frameCount() - paints0) / static_cast<double>(frames.size());
  // Each frame's parts: VTK's render and the blit as the CPU issues them (the GPU may still
  // be working), then the swap (where the driver waits for the GPU and the display).
  row["paint_ms_mean"] = summarize(parts.paint_ms).mean;
  row["swap_ms_mean"] = summarize(parts.swap_ms).mean;
  row["frames_paint_ms"] = parts.paint_ms;
  row["frames_swap_ms"] = parts.swap_ms;
  row["frames_image_sample_px"] = parts.image_sample_px;  // each frame's rays apart [px]
  const Stats shadow = summarize(parts.shadow_ms);  // the tool's shadow cast (inside frame_ms)
  row["shadow_ms_mean"] = shadow.mean;
  row["shadow_ms_max"] = shadow.max;
  row["first_frame_ms"] = first_ms;
  row["interactive_image_sample_px"] = interactive_px;  // the last interactive frame's
  row["interactive_sample_voxels"] = interactive_voxels;
  if (!picture.empty()) row["interactive_picture"] = picture;  // beside render.json
  row["still_frame_ms"] = still_ms;
  row["still_sample_voxels"] = still_sample_voxels;
  row["still_image_sample_px"] = still_px;
  if (drilling) {
    row["removed_voxels"] = removed;
    row["partial_uploads"] = b.view->actors().partialUploads() - partial0;
    row["full_uploads"] = b.view->actors().fullUploads() - full0;
  }
  if (kind.tissue) {
    const Stats show = summarize(parts.tissue_show_ms.empty() ? std::vector<double>{0.0} : parts.tissue_show_ms);
    row["deformed_windows_shown"] = parts.windows_shown;
    row["deformed_windows_per_s"] = static_cast<double>(parts.windows_shown) / elapsed_s;
    row["tissue_show_ms_mean"] = show.mean;  // showVoxelBox(): the window into the picture (inside frame_ms)
    row["tissue_show_ms_max"] = show.max;
    row["indentation_mm_max"] = 1e3 * parts.indentation_m;
  }
  row["coupling_max_tick_us"] = b.phases.back().coupling_max_tick_us;  // the coupling thread's, during the row
  row["contacts"] = b.snapshot.contacts;  // the haptic threads' last snapshot of the row
  row["force_N"] = b.snapshot.force_W_N.norm();
  row["renderer"] = gl.renderer;
  b.view->actors().setMovingView(MovingView::kAuto);
  std::cout << format("bench render: %-10s %-9s %4d x %4d  %6.1f fps  mean %6.1f  p99 %6.1f  max %6.1f ms"
                      "  (render %4.1f, swap %4.1f)  still %6.0f ms  (shadow %4.1f / %4.1f ms)",
                      row["mode"].get<std::string>().c_str(), movingPicture(row).c_str(), row["width"].get<int>(),
                      row["height"].get<int>(), row["fps_mean"].get<double>(), s.mean, s.p99, s.max, row["paint_ms_mean"].get<double>(),
                      row["swap_ms_mean"].get<double>(), still_ms, shadow.mean, shadow.max)
            << std::endl;
  return row;
}

/// The haptic threads' side of the run: the solver's tick times (from the recording), the
/// coupling's longest tick and jitter and the deadline misses, each with rendering on and off.
nlohmann::ordered_json servoJson(const runtime::Recording& recording, const std::vector<Phase>& phases,
                                 bool realtime_scheduling) {
  using namespace bench;
  std::vector<double> on_us, off_us;
  double coupling_on = 0.0, coupling_off = 0.0, jitter_on = 0.0, jitter_off = 0.0;
  std::uint64_t misses_on = 0, misses_off = 0;
  for (const runtime::TickRecord& r : recording.records) {
    for (const Phase& p : phases) {
      if (r.tick < p.begin || r.tick >= p.end) continue;
      (p.rendering ? on_us : off_us).push_back(1e6 * r.tick_time_s);
      break;
    }
  }
  for (const Phase& p : phases) {
    (p.rendering ? coupling_on : coupling_off) = std::max(p.rendering ? coupling_on : coupling_off, p.coupling_max_tick_us);
    (p.rendering ? jitter_on : jitter_off) = std::max(p.rendering ? jitter_on : jitter_off, p.coupling_jitter_us);
    (p.rendering ? misses_on : misses_off) += p.misses_end - p.misses_begin;
  }
  const Stats son = summarize(on_us), soff = summarize(off_us);
  nlohmann::ordered_json servo;
  servo["rate_Hz"] = kServoRate_Hz;
  servo["realtime_scheduling"] = realtime_scheduling;
  servo["solver_tick_us"] = {{"rendering_on", statsJson(son)}, {"rendering_off", statsJson(soff)}};
  servo["coupling_max_tick_us"] = {{"rendering_on", coupling_on}, {"rendering_off", coupling_off}};
  servo["coupling_jitter_us"] = {{"rendering_on", jitter_on}, {"rendering_off", jitter_off}};
  servo["deadline_misses"] = {{"rendering_on", misses_on}, {"rendering_off", misses_off}};
  servo["dropped_records"] = recording.dropped_records;
  return servo;
}

/// Shows `scene` in b's window at `size`, fed by `thread`, and waits for the view's first frame
/// (shaders, the volume's upload). @return the view's GL renderer.
/// @throws std::runtime_error when the view is never shown.
GlInfo openBench(Bench& b, runtime::HapticThread& thread, const runtime::LoadedScene& scene,
                 const runtime::LiveValues& live, const std::array<int, 2>& size, const ViewLook& look) {
  b.thread = &thread;
  b.scan = scene.volume.field.get();
  b.felt = scene.hapticField();
  b.carved.reset(b.felt);
  b.felt_isovalue = scene.hapticIsovalue();
  b.shadow_samples_T_m = toolShadowSamples(*scene.tool);
  b.drained.resize(1 << 16);
  b.window.setWindowTitle("VolumeHaptics: bench render");
  auto* layout = new QVBoxLayout(&b.window);
  layout->setContentsMargins(0, 0, 0, 0);
  b.view = new SceneView(&b.window);
  layout->addWidget(b.view->widget());
  b.view->setScene(sceneActorsSpecFor(scene, live), scene.X_WT_initial, look);
  b.view->setSegments(live.segments.get());
  b.resizeView(size[0], size[1]);
  b.window.show();
  for (const auto shown = Clock::now(); b.view->widget()->frameCount() == 0 && msSince(shown) < 10000.0;)
    QCoreApplication::processEvents(QEventLoop::AllEvents, 5);
  if (b.view->widget()->frameCount() == 0) throw std::runtime_error("bench render: the view was never shown");
  return glInfo(*b.view->widget());
}

/// The tissue rows: the gel-palpation scene's gel pressed 3 mm by its ball and circled, its
/// haptic thread stepping the soft tissue, the view showing each deformed window the thread
/// publishes as the window does (one row per size): into report's `tissue_rows`, the gel's size
/// into its `tissue_volume_dims`.
void tissueRows(const RenderBenchOptions& o, double row_s, const fs::path& picture_dir, nlohmann::ordered_json& report) {
  runtime::SceneSpec spec = bench::gelPalpationScene(0.002);
  spec.tool.X_WT_initial.p_AB_m = Eigen::Vector3d(0.0, 0.0, 0.024);  // the scene file's: above the gel, free
  const runtime::LoadedScene scene = runtime::loadScene(spec);
  const runtime::LiveValues live = runtime::LiveValues::initial(scene);
  const double planned_s = static_cast<double>(o.sizes.size()) * (2.0 * row_s + 10.0) + 30.0;
  auto device = std::make_shared<runtime::ScriptedDevice>(pressAndCircle(scene, planned_s), 1.0 / kServoRate_Hz,
                                                          "bench render, tissue");
  const std::unique_ptr<runtime::HapticThread> thread =
      runtime::makeHapticThread(live, device, kServoRate_Hz, scene.X_WT_initial);
  nlohmann::ordered_json rows = nlohmann::ordered_json::array();
  Bench b;
  ViewLook look;
  const GlInfo gl = openBench(b, *thread, scene, live, o.sizes.front(), look);
  b.tissue = thread->tissue().get();
  thread->start();
  b.idle(1.5);  // the ball reaches the gel and presses it
  for (const auto& size : o.sizes)
    rows.push_back(renderRow(b, *thread, RowKind{RenderMode::kIsosurface, false, MovingView::kAuto, true}, size, look,
                             row_s, picture_dir, gl, scene.volume.field->geometry().spacing_m.minCoeff()));
  thread->stop();
  report["tissue_rows"] = rows;
  report["tissue_volume_dims"] = scene.volume.field->geometry().dims;
}

/// render.json and render.md: the rows and the haptic threads' table.
void writeRenderReport(const fs::path& out, nlohmann::ordered_json& report, const haptics::VolumeGeometry& g,
                       const GlInfo& gl, double row_s, bool short_run) {
  using namespace bench;
  const nlohmann::ordered_json& rows = report["rows"];
  std::ostringstream md;
  md << "## Frame rate of the main view (`volume-haptics bench render" << (short_run ? " --short" : "") << "`)\n\n"
     << format("Scan %d x %d x %d, ", g.dims[0], g.dims[1], g.dims[2]) << "renderer " << gl.renderer << ", CPU "
     << report["cpu_model"].get<std::string>() << " (" << report["cpus"].get<unsigned>() << " CPUs, load average "
     << format("%.1f before, %.1f after", report["load_average_before"].get<double>(),
               report["load_average_after"].get<double>())
     << "); " << format("%.1f s per row, the haptic threads at 1 kHz throughout.\n\n", row_s)
     << "| mode | moving frames | window | fps | mean [ms] | p99 [ms] | max [ms] | render / swap mean [ms] | still frame [ms] | tool shadow mean / max [ms] |\n"
     << "|---|---|---|---|---|---|---|---|---|---|\n";
  for (const auto& r : rows) {
    std::string moving = movingPicture(r);
    if (r["surface_mesh_triangles"].get<std::size_t>() > 0 && r["surface_mesh_frames"].get<std::size_t>() > 0)
      moving += format(" (%zu k triangles, f %d)", r["surface_mesh_triangles"].get<std::size_t>() / 1000,
                       r["surface_mesh_factor"].get<int>());
    md << format("| %s | %s | %d x %d | %.1f | %.1f | %.1f | %.1f | %.1f / %.1f | %.0f | %.2f / %.2f |\n",
                 r["mode"].get<std::string>().c_str(), moving.c_str(), r["width"].get<int>(), r["height"].get<int>(),
                 r["fps_mean"].get<double>(), r["frame_ms_mean"].get<double>(), r["frame_ms_p99"].get<double>(),
                 r["frame_ms_max"].get<double>(), r["paint_ms_mean"].get<double>(), r["swap_ms_mean"].get<double>(),
                 r["still_frame_ms"].get<double>(), r["shadow_ms_mean"].get<double>(), r["shadow_ms_max"].get<double>());
  }
  const auto& st = report["servo"]["solver_tick_us"];
  md << "\n| haptic threads | solver p99 [us] | solver p99.9 [us] | solver max [us] | coupling max [us] | deadline misses |\n"
     << "|---|---|---|---|---|---|\n";
  for (const char* k : {"rendering_on", "rendering_off"})
    md << format("| %s | %.1f | %.1f | %.1f | %.1f | %llu |\n", k, st[k]["p99"].get<double>(),
                 st[k]["p99_9"].get<double>(), st[k]["max"].get<double>(),
                 report["servo"]["coupling_max_tick_us"][k].get<double>(),
                 static_cast<unsigned long long>(report["servo"]["deadline_misses"][k].get<std::uint64_t>()));
  if (report.contains("tissue_rows") && !report["tissue_rows"].empty()) {
    md << "\nSoft tissue: the gel-palpation scene's gel (" << report["tissue_volume_dims"].dump()
       << " voxels, 2 mm lattice cells) pressed and circled by its ball, each deformed window the haptic thread "
          "publishes shown as the window shows it.\n\n"
       << "| mode | moving frames | window | fps | mean [ms] | p99 [ms] | max [ms] | deformed windows shown per s | "
          "showing one, mean / max [ms] | deepest indentation [mm] | coupling max [us] |\n"
       << "|---|---|---|---|---|---|---|---|---|---|---|\n";
    for (const auto& r : report["tissue_rows"])
      md << format("| %s | %s | %d x %d | %.1f | %.1f | %.1f | %.1f | %.1f | %.2f / %.2f | %.2f | %.0f |\n",
                   r["mode"].get<std::string>().c_str(), movingPicture(r).c_str(), r["width"].get<int>(),
                   r["height"].get<int>(), r["fps_mean"].get<double>(), r["frame_ms_mean"].get<double>(),
                   r["frame_ms_p99"].get<double>(), r["frame_ms_max"].get<double>(),
                   r["deformed_windows_per_s"].get<double>(), r["tissue_show_ms_mean"].get<double>(),
                   r["tissue_show_ms_max"].get<double>(), r["indentation_mm_max"].get<double>(),
                   r["coupling_max_tick_us"].get<double>());
  }
  writeReport(out, "render", report, md, {});
}

}  // namespace

fs::path runRenderBench(const RenderBenchOptions& o) {
  using namespace bench;
  if (!displayAvailable())
    throw std::runtime_error("bench render draws in a window and needs an X display with OpenGL: run it under "
                             "xvfb-run -a -s \"-screen 0 1920x1080x24\"");
  if (o.sizes.empty()) throw std::runtime_error("bench render: no window size to render");
  const bool short_run = o.common.short_run;
  const fs::path out = outputDir(o.common, "render");
  const double row_s = o.row_seconds > 0.0 ? o.row_seconds : (short_run ? 0.5 : 4.0);

  // The scan.
  const fs::path volume = renderBenchScan(o, short_run);
  std::cout << "bench render: loading " << volume.string() << " ..." << std::endl;
  // The burr is spun up for the drilling rows only.
  const runtime::LoadedScene scene = runtime::loadScene(bench::drillingScene(volume, /*drill_on=*/false));
  runtime::LiveValues live = runtime::LiveValues::initial(scene);
  live.segments = sphereSegment(*scene.volume.field);

  // The rows, each followed by as long without rendering; the trajectory outlasts them all.
  // The isosurface's rows again with the moving frames ray cast whatever their cost: what the
  // view's automatic choice (a surface mesh on a software renderer) is measured against.
  std::vector<RowKind> kinds = {{RenderMode::kIsosurface}, {RenderMode::kComposite}, {RenderMode::kMip}};
  if (o.drilling) kinds.push_back({RenderMode::kIsosurface, true});
  kinds.push_back({RenderMode::kIsosurface, false, MovingView::kRayCast});
  if (o.drilling) kinds.push_back({RenderMode::kIsosurface, true, MovingView::kRayCast});
  const double planned_s = static_cast<double>(o.sizes.size() * kinds.size()) * (2.0 * row_s + 10.0) + 60.0;
  auto device = std::make_shared<runtime::ScriptedDevice>(pressAndCircle(scene, planned_s), 1.0 / kServoRate_Hz,
                                                          "bench render");
  const std::unique_ptr<runtime::HapticThread> thread =
      runtime::makeHapticThread(live, device, kServoRate_Hz, scene.X_WT_initial);
  const fs::path ticks_path = out / "render-ticks.vhrec";
  auto writer = std::make_unique<runtime::RecordingWriter>(ticks_path, "{}");
  thread->setRecorder(writer.get());

  std::unique_ptr<QApplication> app;
  static int argc = 1;
  static char name[] = "volume-haptics";
  static char* argv[] = {name, nullptr};
  if (QCoreApplication::instance() == nullptr) {
    setDefaultSurfaceFormat();
    app = std::make_unique<QApplication>(argc, argv);
  }

  nlohmann::ordered_json report = reportHeader("render", short_run);
  report["load_average_before"] = loadAverage();
  nlohmann::ordered_json rows = nlohmann::ordered_json::array();
  GlInfo gl;
  {
    Bench b;
    ViewLook look;
    gl = openBench(b, *thread, scene, live, o.sizes.front(), look);
    std::cout << "bench render: " << gl.renderer << " (OpenGL " << gl.version << ", 3-D textures up to "
              << gl.max_3d_texture << ")" << std::endl;

    thread->start();
    b.idle(1.5);  // the device reaches the surface
    b.phases.clear();
    for (const auto& size : o.sizes) {
      for (const RowKind& kind : kinds) {
        rows.push_back(renderRow(b, *thread, kind, size, look, row_s, o.common.plots ? out : fs::path(), gl,
                                 scene.volume.field->geometry().spacing_m.minCoeff()));
      }
    }
    thread->stop();
    b.view->actors().restoreVolume();
    thread->setRecorder(nullptr);
    writer->close();
    writer.reset();

    // The solver's tick times of each stretch, rendering on and off.
    const runtime::Recording recording = runtime::readRecording(ticks_path);
    std::error_code ec;
    fs::remove(ticks_path, ec);
    report["servo"] = servoJson(recording, b.phases, thread->realtimeScheduling());
  }

  const haptics::VolumeGeometry& g = scene.volume.field->geometry();
  report["volume"] = {{"path", volume.string()},
                      {"dims", g.dims},
                      {"spacing_mm", {1e3 * g.spacing_m.x(), 1e3 * g.spacing_m.y(), 1e3 * g.spacing_m.z()}},
                      {"isovalue", scene.isovalue}};
  report["load_average_after"] = loadAverage();
  report["renderer"] = gl.renderer;
  report["gl_version"] = gl.version;
  report["max_3d_texture"] = gl.max_3d_texture;
  report["row_seconds"] = row_s;
  report["rows"] = rows;
  if (o.tissue) {
    std::cout << "bench render: the soft tissue rows (the built-in gel) ..." << std::endl;
    tissueRows(o, row_s, o.common.plots ? out : fs::path(), report);
  }

  writeRenderReport(out, report, g, gl, row_s, short_run);
  return out;
}

void addRenderBenchSubcommand(CLI::App& bench, std::function<int()>& handler) {
  auto options = std::make_shared<RenderBenchOptions>();
  auto sizes = std::make_shared<std::vector<std::string>>();
  CLI::App* cmd = bench.add_subcommand(
      "render", "Frames per second of the main view (isosurface, composite, MIP, drilling; the tools and a segment "
                "surface) while the haptic threads run a scripted trajectory, and the haptic threads' tick times with "
                "rendering on and off; needs an X display (xvfb-run -a -s \"-screen 0 1920x1080x24\")");
  bench::addCommonOptions(*cmd, options->common);
  cmd->add_option("--volume", options->volume,
                  "The scan to render (default: a 512 x 512 x 275 CT generated from the shared head phantom; short: the "
                  "small CT head)");
  cmd->add_option("--slices", options->slices, "Slices of the generated CT (default 275)")->check(CLI::Range(2, 100000));
  cmd->add_option("--series-dir", options->series_dir,
                  "Where the generated CT is written and reused (default: " +
                      (bench::defaultOutputDir() / "render").string() + "/ct-512x512xN)");
  cmd->add_option("--sizes", *sizes, "Window sizes WxH, comma separated (default 1280x720,1920x1080)")->delimiter(',');
  cmd->add_option("--seconds", options->row_seconds, "Rendering time of each row [s], and as long without (default 4; short 0.5)")
      ->check(CLI::Range(0.05, 600.0));
  cmd->add_flag("!--no-drilling", options->drilling, "Skip the drilling rows");
  cmd->add_flag("!--no-tissue", options->tissue, "Skip the soft tissue rows (the built-in gel pressed and deformed)");
  cmd->callback([&handler, options, sizes] {
    if (!sizes->empty()) {
      options->sizes.clear();
      for (const std::string& s : *sizes) {
        int w = 0, h = 0;
        char x = 0;
        std::istringstream in(s);
        if (!(in >> w >> x >> h) || (x != 'x' && x != 'X') || w < 64 || h < 64 || w > 8192 || h > 8192)
          throw CLI::ValidationError("--sizes", "'" + s + "': expected WIDTHxHEIGHT, 64 to 8192 each, e.g. 1280x720");
        options->sizes.push_back({w, h});
      }
    }
    handler = [options] { return bench::runGuarded("render", [&] { runRenderBench(*options); }); };
  });
}

}  // namespace vh::ui
