// `volume-haptics bench drilling`: the burr's removal against an analytic oracle (the capsule a
// straight pass sweeps through a uniform block), and the solver's cost of drilling on the CT head
// phantom: one scripted press-and-circle trajectory rendered twice, tick by tick interleaved,
// by a renderer that only touches and by one that drills (the same solver plus Drill::step()),
// thread CPU time and wall time per tick side by side.

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <iostream>
#include <numbers>
#include <sstream>

#include <nlohmann/json.hpp>

#include "vh/bench/report.h"
#include "vh/bench/bench.h"
#include "vh/haptics/material_removal.h"
#include "vh/runtime/drilling.h"
#include "vh/runtime/scene.h"
#include "vh/runtime/servo_factory.h"
#include "vh/runtime/realtime.h"

namespace vh::bench {
namespace fs = std::filesystem;

namespace {

constexpr const char* kPhantom = "ct/philips-head-phantom-bone";
constexpr double kIsovalue_HU = 400.0;

double wallTime_us() { return 1e-3 * static_cast<double>(runtime::monotonicNs()); }

/// One capsule case: a burr of radius r passed straight through a uniform block of voxels h; the
/// removed volume against pi r^2 L + 4/3 pi r^3, the error in voxel layers (capsule area x h).
nlohmann::ordered_json capsuleCase(double h, double r) {
  const int n = static_cast<int>(std::ceil(0.040 / h)) | 1;
  haptics::VolumeGeometry g;
  g.dims = {n, n, n};
  g.spacing_m = Eigen::Vector3d::Constant(h);
  g.origin_W_m = Eigen::Vector3d::Constant(-0.5 * (n - 1) * h);
  std::vector<std::uint8_t> v(g.voxelCount(), 0);  // a block of 200 in air (0), two voxels in from the border
  for (int k = 2; k < n - 2; ++k)
    for (int j = 2; j < n - 2; ++j)
      for (int i = 2; i < n - 2; ++i) v[static_cast<std::size_t>(i + n * (j + n * k))] = 200;
  auto volume = std::make_shared<haptics::ScalarVolume>(haptics::ScalarVolume::FromVoxels(g, v));
  haptics::MaterialRemoval removal(volume, {}, {{"block", 1.0, false}});
  const Eigen::Vector3d a(-0.008, 0.001, -0.0005), b(0.008, -0.002, 0.0015);
  const double L = (b - a).norm();
  const int steps = static_cast<int>(std::ceil(L / (0.1 * h)));
  // Whether the burr's sphere meets the block (F > 100), as a contact set on it would say: 400
  // points spread on it (a Fibonacci sphere).
  const auto touches = [&](const Eigen::Vector3d& c) {
    constexpr int kN = 400;
    for (int i = 0; i < kN; ++i) {
      const double z = 1.0 - 2.0 * (i + 0.5) / kN, rho = std::sqrt(1.0 - z * z);
      const double phi = i * std::numbers::pi * (3.0 - std::sqrt(5.0));
      if (volume->isInside(c + r * Eigen::Vector3d(rho * std::cos(phi), rho * std::sin(phi), z), 100.0)) return true;
    }
    return false;
  };
  for (int t = 0; t <= steps; ++t) {  // a force so large that each tick clears the burr
    const Eigen::Vector3d c = a + (b - a) * (static_cast<double>(t) / steps);
    removal.cut(c, r, 1e9, 1e-3, 100.0, touches(c));
  }
  const double removed_mm3 = static_cast<double>(removal.removedVoxels()) * removal.voxelVolume_mm3();
  const double capsule_mm3 = 1e9 * (std::numbers::pi * r * r * L + 4.0 / 3.0 * std::numbers::pi * r * r * r);
  const double layer_mm3 = 1e9 * (2.0 * std::numbers::pi * r * L + 4.0 * std::numbers::pi * r * r) * h;
  nlohmann::ordered_json j;
  j["voxel_m"] = h;
  j["burr_radius_m"] = r;
  j["path_length_m"] = L;
  j["removed_mm3"] = removed_mm3;
  j["analytic_mm3"] = capsule_mm3;
  j["error_voxel_layers"] = std::abs(removed_mm3 - capsule_mm3) / layer_mm3;
  return j;
}

/// From X_WT0, down (-z in W) to `depth_m` below in 2 s, then a circle (radius 3 mm, 4 s a turn) at that depth.
haptics::Pose trajectoryAt(const haptics::Pose& X_WT0, double depth_m, double t_s) {
  haptics::Pose X = X_WT0;
  const double press = std::min(t_s / 2.0, 1.0) * depth_m;
  const double phase = std::max(0.0, t_s - 2.0) * 2.0 * std::numbers::pi / 4.0;
  const double radius = std::min(std::max(0.0, t_s - 2.0), 1.0) * 0.003;
  X.p_AB_m += Eigen::Vector3d(radius * std::cos(phase) - radius, radius * std::sin(phase), -press);
  return X;
}

}  // namespace

runtime::SceneSpec drillingScene(const fs::path& volume, bool drill_on) {
  runtime::SceneSpec spec = runtime::sceneForVolume(volume);
  spec.volume.isovalue = kIsovalue_HU;
  spec.volume.isovalue_set = true;
  spec.tool.mesh = "builtin:drill";
  spec.tool.point_spacing_m = 0.001;
  spec.drill = runtime::DrillSpec{};
  spec.drill->on = drill_on;
  return spec;
}

fs::path runDrilling(const CommonOptions& options) {
  const bool short_run = options.short_run;
  const fs::path out = outputDir(options, "drilling");
  nlohmann::ordered_json report = reportHeader("drilling", short_run);
  std::ostringstream md;
  md << "# Drilling\n\n## The removal against the swept capsule\n\n"
     << "| voxel [mm] | burr radius [mm] | removed [mm^3] | capsule [mm^3] | error [voxel layers] |\n|---|---|---|---|---|\n";
  report["capsule_cases"] = nlohmann::ordered_json::array();
  for (const double h : {0.5e-3, 1.0e-3})
    for (const double r : {1.5e-3, 3.0e-3, 5.0e-3}) {
      const auto c = capsuleCase(h, r);
      md << format("| %.1f | %.1f | %.1f | %.1f | %.3f |\n", h * 1e3, r * 1e3, c["removed_mm3"].get<double>(),
                   c["analytic_mm3"].get<double>(), c["error_voxel_layers"].get<double>());
      report["capsule_cases"].push_back(c);
    }

  const fs::path phantom = runtime::sharedDatasetsDir() / kPhantom;
  if (!fs::exists(phantom)) {
    std::cout << "bench drilling: " << phantom.string() << " is absent: the timing part is skipped\n";
    report["timing_skipped"] = "the CT head phantom is absent: " + phantom.string();
    writeReport(out, "drilling", report, md, {});
    return out;
  }
  const runtime::LoadedScene scene = runtime::loadScene(drillingScene(phantom, /*drill_on=*/true));
  const runtime::LiveValues live = runtime::LiveValues::initial(scene);
  haptics::RendererOptions ro;
  ro.gains = scene.spec.gains;
  // The same solver twice: touching alone, and drilling (its own carved copy of the field).
  auto touching = runtime::makeRenderer(live, ro, scene.X_WT_initial);
  const double prepare_begin = wallTime_us();
  runtime::DrillingRenderer drilling = runtime::makeServoRenderer(live, ro, scene.X_WT_initial, 1000.0);
  const double prepare_s = (wallTime_us() - prepare_begin) * 1e-6;
  // Where the burr meets the skull straight below the initial pose: the press goes 4 mm beyond.
  const runtime::Burr burr = drilling.drill->burr();
  const Eigen::Vector3d bottom = scene.X_WT_initial * burr.center_T_m - Eigen::Vector3d(0, 0, burr.radius_m);
  double contact_m = 0.0;
  while (contact_m < 0.15 && !scene.volume.field->isInside(bottom - Eigen::Vector3d(0, 0, contact_m), scene.isovalue))
    contact_m += 1e-4;
  const double depth_m = contact_m + 0.004;
  const int ticks = short_run ? 3000 : 60000;
  std::vector<double> cpu_touch, cpu_drill, wall_touch, wall_drill, cut_cpu;
  cpu_touch.reserve(ticks), cpu_drill.reserve(ticks), wall_touch.reserve(ticks), wall_drill.reserve(ticks);
  std::int64_t contact_ticks = 0;
  for (int i = 0; i < ticks; ++i) {
    const haptics::Pose X_WD = trajectoryAt(scene.X_WT_initial, depth_m, i * 1e-3);
    double c0 = runtime::threadCpuTime_us(), w0 = wallTime_us();
    (void)touching->tick(X_WD, scene.isovalue);
    cpu_touch.push_back(runtime::threadCpuTime_us() - c0);
    wall_touch.push_back(wallTime_us() - w0);
    c0 = runtime::threadCpuTime_us(), w0 = wallTime_us();
    const haptics::TickOutput o = drilling.renderer->tick(X_WD, scene.isovalue);
    const double c1 = runtime::threadCpuTime_us();
    (void)drilling.drill->step(*drilling.renderer, o);
    const double c2 = runtime::threadCpuTime_us();
    cpu_drill.push_back(c2 - c0);
    wall_drill.push_back(wallTime_us() - w0);
    cut_cpu.push_back(c2 - c1);
    if (o.stats.contacts > 0) ++contact_ticks;
  }
  const Stats ct = summarize(cpu_touch), cd = summarize(cpu_drill), wt = summarize(wall_touch),
              wd = summarize(wall_drill), cc = summarize(cut_cpu);
  const auto stats = [](const Stats& s) {
    return nlohmann::ordered_json{{"mean_us", s.mean}, {"p99_us", s.p99}, {"p99_9_us", s.p999}, {"max_us", s.max}};
  };
  report["scene"] = {{"volume", kPhantom},
                     {"isovalue_HU", kIsovalue_HU},
                     {"tool", "built-in drill, 2.5 mm burr, 1 mm point spacing"},
                     {"ticks", ticks},
                     {"trajectory", "press to 4 mm beyond the skull below the initial pose in 2 s, then circle 3 mm at that depth"},
                     {"contact_below_initial_m", contact_m},
                     {"prepare_s", prepare_s}};
  report["touching_cpu"] = stats(ct);
  report["drilling_cpu"] = stats(cd);
  report["touching_wall"] = stats(wt);
  report["drilling_wall"] = stats(wd);
  report["cut_cpu"] = stats(cc);
  report["p99_9_ratio"] = cd.p999 / std::max(ct.p999, 1e-9);
  report["max_ratio"] = cd.max / std::max(ct.max, 1e-9);
  report["wall_p99_9_ratio"] = wd.p999 / std::max(wt.p999, 1e-9);
  report["wall_max_ratio"] = wd.max / std::max(wt.max, 1e-9);
  report["contact_ticks"] = contact_ticks;
  report["removed_mm3"] = drilling.drill->removed_mm3();
  report["removed_voxels"] = drilling.drill->removal().removedVoxels();
  md << "\n## The solver's cost of drilling (CT head phantom, " << ticks << " ticks at 1 kHz, interleaved)\n\n"
     << "| per tick [us] | mean | p99 | p99.9 | max |\n|---|---|---|---|---|\n"
     << format("| touching, thread CPU | %.1f | %.1f | %.1f | %.1f |\n", ct.mean, ct.p99, ct.p999, ct.max)
     << format("| drilling, thread CPU | %.1f | %.1f | %.1f | %.1f |\n", cd.mean, cd.p99, cd.p999, cd.max)
     << format("| of which the cut | %.1f | %.1f | %.1f | %.1f |\n", cc.mean, cc.p99, cc.p999, cc.max)
     << format("| touching, wall | %.1f | %.1f | %.1f | %.1f |\n", wt.mean, wt.p99, wt.p999, wt.max)
     << format("| drilling, wall | %.1f | %.1f | %.1f | %.1f |\n", wd.mean, wd.p99, wd.p999, wd.max)
     << format("\nDrilling over touching (thread CPU): p99.9 %.2fx, max %.2fx (target <= 1.2x); removed %.1f mm^3 "
               "in %lld contact ticks; materials and the carved copy prepared in %.2f s.\n",
               report["p99_9_ratio"].get<double>(), report["max_ratio"].get<double>(), drilling.drill->removed_mm3(),
               static_cast<long long>(contact_ticks), prepare_s);
  writeReport(out, "drilling", report, md, {});
  return out;
}

}  // namespace vh::bench
