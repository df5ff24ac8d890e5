// Collision detection, the paper's path against the accelerated one, side by side in
// one run. Each benchmark iteration replays one scripted device trajectory through a fresh
// HapticRenderer and records every tick's time (the renderer's own exec_time_us), its trilinear
// samples and its min-max tree box queries. After Google Benchmark's table, a ratio table
// (paper / accelerated) is printed per scene, and the accelerated path's exact segment test
// against the earlier end-sample test (accelerated-end-sample).
//
// Scenes:
//   hole         the paper's Hole scene: 256^3 uint8 block (0.25 mm voxels) with a blind hole
//                and the snug peg (1307 points, 80 mm): press on the top face, slide over the
//                hole and drop in, descend to the bottom, wedge (pulled sideways and tilted), hold.
//   sphere-plane a sphere of radius 20 mm with 20,000 points on a plane (128^3, 0.5 mm,
//                float32): press 3 mm, slide 10 mm, circle of radius 10 mm, hold.
//   slider       sphere-plane with the isovalue moving on every tick (+-0.5 mm of surface).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <functional>
#include <map>
#include <memory>
#include <numbers>
#include <string>
#include <vector>

#include <benchmark/benchmark.h>

#include "vh/datasets/synthetic.h"
#include "vh/haptics/haptic_renderer.h"

namespace {

using vh::haptics::DetectionMode;
using vh::haptics::HapticRenderer;
using vh::haptics::Pose;
using vh::haptics::RendererOptions;
using vh::haptics::ScalarVolume;
using vh::haptics::SegmentTest;
using vh::haptics::ToolModel;

struct Scene {
  std::string name;
  std::shared_ptr<const ScalarVolume> volume;
  std::shared_ptr<const ToolModel> tool;
  double isovalue = 0.0;
  std::vector<Pose> device;       // one pose per tick
  std::vector<double> isovalues;  // per tick, when the slider moves (else `isovalue` throughout)
  double isovalueAt(std::size_t tick) const { return isovalues.empty() ? isovalue : isovalues[tick]; }
};

Pose at(double x, double y, double z, const Eigen::Quaterniond& q = Eigen::Quaterniond::Identity()) {
  Pose X;
  X.R_AB = q;
  X.p_AB_m = {x, y, z};
  return X;
}

// Appends `ticks` poses moving linearly (slerp for the rotation) from the last pose to `to`.
void moveTo(std::vector<Pose>& path, const Pose& to, int ticks) {
  const Pose from = path.back();
  for (int i = 1; i <= ticks; ++i) {
    const double u = static_cast<double>(i) / ticks;
    Pose X;
    X.p_AB_m = from.p_AB_m + u * (to.p_AB_m - from.p_AB_m);
    X.R_AB = from.R_AB.slerp(u, to.R_AB);
    path.push_back(X);
  }
}

const Scene& holeScene() {
  static const Scene scene = [] {
    Scene s;
    s.name = "hole";
    s.volume = std::make_shared<ScalarVolume>(vh::datasets::makeBlockWithBlindHoleVolume(256, -0.004));
    vh::haptics::PointShellOptions ps;
    ps.point_count = 1307;
    s.tool = std::make_shared<ToolModel>(
        vh::haptics::makeToolModel(vh::datasets::makeCylinderMesh(vh::datasets::kPegRadius_m, 0.08, 64), ps));
    s.isovalue = vh::datasets::kBlockIsovalue;
    s.device.push_back(at(0.015, 0.0, 0.02));
    moveTo(s.device, at(0.015, 0.0, 0.010), 400);   // press 2 mm into the top face (z = 12 mm)
    moveTo(s.device, at(0.0, 0.0, 0.010), 800);     // slide over the hole and drop in
    moveTo(s.device, at(0.0, 0.0, -0.008), 1200);   // descend, press 4 mm into the bottom
    const Eigen::Quaterniond tilt(Eigen::AngleAxisd(0.1, Eigen::Vector3d::UnitY()));
    moveTo(s.device, at(0.004, 0.0, 0.0, tilt), 600);  // wedge: pulled sideways and tilted
    moveTo(s.device, s.device.back(), 400);            // hold
    return s;
  }();
  return scene;
}

const Scene& spherePlaneScene() {
  static const Scene scene = [] {
    Scene s;
    s.name = "sphere-plane";
    vh::datasets::GridSpec g;
    g.dims = {128, 128, 128};
    g.spacing_m = Eigen::Vector3d::Constant(0.5e-3);
    s.volume = std::make_shared<ScalarVolume>(vh::datasets::makePlaneVolume(g, Eigen::Vector3d::UnitZ(), 0.0));
    vh::haptics::PointShellOptions ps;
    ps.point_count = 20000;
    s.tool = std::make_shared<ToolModel>(vh::haptics::makeToolModel(vh::datasets::makeSphereMesh(0.02, 4), ps));
    s.isovalue = 0.0;
    // The sphere's centre is its tool-frame origin: resting on the plane at z = 20 mm.
    s.device.push_back(at(0.0, 0.0, 0.023));
    moveTo(s.device, at(0.0, 0.0, 0.017), 500);     // press 3 mm
    moveTo(s.device, at(0.01, 0.0, 0.017), 600);    // slide 10 mm
    for (int i = 1; i <= 1200; ++i) {               // circle of radius 10 mm
      const double a = 2.0 * std::numbers::pi * i / 1200.0;
      s.device.push_back(at(0.01 * std::cos(a), 0.01 * std::sin(a), 0.017));
    }
    moveTo(s.device, s.device.back(), 400);         // hold
    return s;
  }();
  return scene;
}

// The sphere-plane run with the isovalue slider moving on every tick (+-0.5 mm of surface
// travel, F is in mm): each tick rescans the point shell for embedded points.
const Scene& sliderScene() {
  static const Scene scene = [] {
    Scene s = spherePlaneScene();
    s.name = "slider";
    for (std::size_t i = 0; i < s.device.size(); ++i)
      s.isovalues.push_back(0.5 * std::sin(2.0 * std::numbers::pi * static_cast<double>(i) / 500.0));
    return s;
  }();
  return scene;
}

// CPU time of the calling thread [us]: on this shared machine, wall time per tick carries the
// scheduler's preemptions (4 ms slices), which swamp a 100 us tick; CPU time does not.
double threadCpu_us() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return 1e6 * static_cast<double>(ts.tv_sec) + 1e-3 * static_cast<double>(ts.tv_nsec);
}

struct Summary {
  double mean_us = 0.0, max_us = 0.0, p99_us = 0.0;      // thread CPU time per tick
  double wall_mean_us = 0.0, wall_median_us = 0.0;        // the renderer's exec_time_us
  double samples_per_tick = 0.0, box_queries_per_tick = 0.0, contacts_max = 0.0;
  Pose final_proxy;
};
std::map<std::string, Summary>& summaries() {
  static std::map<std::string, Summary> s;
  return s;
}

// The accelerated path with the earlier end-sample segment test: today's exact test against it.
std::string variantName(DetectionMode mode, SegmentTest test) {
  return std::string(vh::haptics::toString(mode)) + (test == SegmentTest::kEndSample ? "-end-sample" : "");
}

void runScene(benchmark::State& state, const Scene& scene, DetectionMode mode, SegmentTest test) {
  std::vector<double> tick_us, wall_us;
  tick_us.reserve(scene.device.size());
  wall_us.reserve(scene.device.size());
  Summary sum;
  for (auto _ : state) {
    state.PauseTiming();
    RendererOptions o;
    o.detection_mode = mode;
    o.segment_test = test;
    HapticRenderer r(scene.volume, scene.tool, o, scene.device.front(), scene.isovalueAt(0));
    tick_us.clear();
    wall_us.clear();
    double samples = 0.0, boxes = 0.0;
    int contacts_max = 0;
    state.ResumeTiming();
    for (std::size_t i = 0; i < scene.device.size(); ++i) {
      const Pose& X_WD = scene.device[i];
      const double cpu0 = threadCpu_us();
      const auto out = r.tick(X_WD, scene.isovalueAt(i));
      tick_us.push_back(threadCpu_us() - cpu0);
      wall_us.push_back(out.stats.exec_time_us);
      samples += static_cast<double>(out.stats.volume_samples);
      boxes += static_cast<double>(out.stats.box_queries);
      contacts_max = std::max(contacts_max, out.stats.contacts);
      if (std::getenv("VH_BENCH_TRACE") && tick_us.back() > 300.0)
        std::fprintf(stderr, "%s tick %zu: %.0f us cpu, %.0f wall, %lld samples, %lld boxes, %d contacts, t %.3g\n",
                     vh::haptics::toString(mode), tick_us.size() - 1, tick_us.back(), out.stats.exec_time_us,
                     static_cast<long long>(out.stats.volume_samples), static_cast<long long>(out.stats.box_queries),
                     out.stats.contacts, out.stats.time_of_contact);
    }
    state.PauseTiming();
    const double n = static_cast<double>(tick_us.size());
    double total = 0.0;
    for (double t : tick_us) total += t;
    std::vector<double> sorted = tick_us;
    std::sort(sorted.begin(), sorted.end());
    sum.mean_us = total / n;
    sum.max_us = sorted.back();
    sum.p99_us = sorted[static_cast<std::size_t>(0.99 * (n - 1))];
    std::sort(wall_us.begin(), wall_us.end());
    double wall_total = 0.0;
    for (double t : wall_us) wall_total += t;
    sum.wall_mean_us = wall_total / n;
    sum.wall_median_us = wall_us[wall_us.size() / 2];
    sum.samples_per_tick = samples / n;
    sum.box_queries_per_tick = boxes / n;
    sum.contacts_max = contacts_max;
    sum.final_proxy = r.proxyPose();
    state.ResumeTiming();
  }
  state.counters["wall_mean_tick_us"] = sum.wall_mean_us;
  state.counters["wall_median_tick_us"] = sum.wall_median_us;
  state.counters["mean_tick_us"] = sum.mean_us;
  state.counters["p99_tick_us"] = sum.p99_us;
  state.counters["max_tick_us"] = sum.max_us;
  state.counters["samples_per_tick"] = sum.samples_per_tick;
  state.counters["box_queries_per_tick"] = sum.box_queries_per_tick;
  state.counters["max_contacts"] = sum.contacts_max;
  summaries()[scene.name + "/" + variantName(mode, test)] = sum;
}

void printRatios() {
  std::printf("\nDetection modes side by side (per tick; thread CPU time except wall_median; ratio = paper / "
              "accelerated)\n");
  std::printf("%-13s %-12s %10s %10s %10s %12s %12s %12s %9s\n", "scene", "mode", "mean_us", "p99_us", "max_us",
              "wall_median", "samples", "box_queries", "contacts");
  for (const std::string scene : {"hole", "sphere-plane", "slider"}) {
    const auto p = summaries().find(scene + "/paper"), a = summaries().find(scene + "/accelerated");
    for (const auto& it : {p, a}) {
      if (it == summaries().end()) continue;
      const Summary& s = it->second;
      std::printf("%-13s %-12s %10.1f %10.1f %10.1f %12.1f %12.0f %12.0f %9.0f\n", scene.c_str(),
                  it->first.substr(scene.size() + 1).c_str(), s.mean_us, s.p99_us, s.max_us, s.wall_median_us,
                  s.samples_per_tick,
                  s.box_queries_per_tick, s.contacts_max);
    }
    if (p == summaries().end() || a == summaries().end()) continue;
    const Summary &sp = p->second, &sa = a->second;
    std::printf("%-13s %-12s %10.2f %10.2f %10.2f %12.2f %12.2f   final proxy pose difference %.3g m\n",
                scene.c_str(), "ratio", sp.mean_us / sa.mean_us, sp.p99_us / sa.p99_us, sp.max_us / sa.max_us,
                sp.wall_median_us / sa.wall_median_us,
                sp.samples_per_tick / std::max(1e-9, sa.samples_per_tick),
                (sp.final_proxy.p_AB_m - sa.final_proxy.p_AB_m).norm());
    // The exact segment test against the earlier end sample, both accelerated.
    const auto e = summaries().find(scene + "/accelerated-end-sample");
    if (e == summaries().end()) continue;
    const Summary& se = e->second;
    std::printf("%-13s %-12s %10.1f %10.1f %10.1f %12.1f %12.0f %12.0f %9.0f\n", scene.c_str(), "acc-end-smp",
                se.mean_us, se.p99_us, se.max_us, se.wall_median_us, se.samples_per_tick, se.box_queries_per_tick,
                se.contacts_max);
    std::printf("%-13s %-12s %10.2f %10.2f %10.2f %12.2f   (exact / end-sample, accelerated)\n", scene.c_str(), "ratio",
                sa.mean_us / se.mean_us, sa.p99_us / se.p99_us, sa.max_us / se.max_us,
                sa.wall_median_us / se.wall_median_us);
  }
}

}  // namespace

int main(int argc, char** argv) {
  const std::pair<DetectionMode, SegmentTest> variants[] = {{DetectionMode::kPaper, SegmentTest::kExact},
                                                             {DetectionMode::kAccelerated, SegmentTest::kExact},
                                                             {DetectionMode::kAccelerated, SegmentTest::kEndSample}};
  for (const Scene* scene : {&holeScene(), &spherePlaneScene(), &sliderScene()})
    for (const auto& [mode, test] : variants)
      benchmark::RegisterBenchmark((scene->name + "/" + variantName(mode, test)).c_str(),
                                   [scene, mode = mode, test = test](benchmark::State& st) { runScene(st, *scene, mode, test); })
          ->Unit(benchmark::kMillisecond)
          ->Iterations(3);
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  printRatios();
  return 0;
}
