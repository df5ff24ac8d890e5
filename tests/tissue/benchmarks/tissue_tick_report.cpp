// The whole servo tick with tissue, as the hand gets it, beside the rigid tick on the same scene
// (a report: printed, never asserted; figures move 30-60 % between runs on a shared machine, so
// the two are interleaved tick by tick and compared in one run):
//   - the scene: a gel block with a stiffer inclusion (the built-in test case: gel 10 kPa, the
//     inclusion 40 kPa, the scan's values 100 and 200, its top blurred over 2 mm), on a bone
//     plate, cut by the scan's sides; a ball of radius 4 mm (the tool's point shell every 0.4 mm)
//     on the application's coupling (1,000 N/m), solver options as the application runs them
//     (edge test on, the 900 us deadline, the work budget);
//   - the trajectory: down 2 mm into the gel beside the inclusion, across over it and back up;
//   - per tick: the tissue's step (DeformableScene::step: gather, solve, write) plus the
//     renderer's tick, against the renderer's tick on the rigid scan (the same device samples):
//     mean, p99.9, max, ticks over 500 us and over the 1 ms period, ticks the deadline cut, the
//     proxy behind the device; the step's parts;
//   - 0 crossings of either felt field by a dense check of every tick's motion;
//   - force against indentation over the inclusion and beside it, with the full solve's exact
//     contact on the same lattice (sphere_contact_reference.h) for the factor.
// Usage: vh_tissue_tick_report [--cell-mm=H] [--window-margin-mm=M] [--lanes=N] [--quick]
//   M: DeformableSceneOptions::window_margin_m (default 0: its default)
//   N: the resampling's lanes (DeformableScene::setLanes(); default 1: one core)
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <vector>

#include "sphere_contact_reference.h"
#include "vh/datasets/synthetic.h"
#include "vh/haptics/crossing_verifier.h"
#include "vh/haptics/haptic_renderer.h"
#include "vh/haptics/tool_model.h"
#include "vh/tissue/deformable_scene.h"

namespace {

using namespace vh;
using namespace vh::tissue;
using Clock = std::chrono::steady_clock;

// The scan: 60 x 60 x 80 voxels of 0.5 mm (30 x 30 x 40 mm). Bone below k = 2, gel up to the top
// at z = 35.75 mm (blurred over 2 mm), air above; the inclusion a ball of radius 4 mm, its centre
// 6 mm below the top at (20, 15) mm.
constexpr int kNx = 60, kNy = 60, kNz = 80;
constexpr double kVoxel = 0.5e-3;
constexpr double kTop_m = 35.75e-3;
constexpr double kIsovalue = 50.0;
const Eigen::Vector3d kInclusion(20e-3, 15e-3, kTop_m - 6e-3);
constexpr double kInclusionR = 4e-3;

double gelValue(int i, int j, int k) {
  const Eigen::Vector3d p = kVoxel * Eigen::Vector3d(i, j, k);
  const double base = std::clamp(50.0 + 50.0 * (kTop_m - p.z()) / 1e-3, 0.0, 100.0);
  return (p - kInclusion).norm() < kInclusionR ? 200.0 : base;
}

std::shared_ptr<const haptics::ScalarVolume> scan() {
  haptics::VolumeGeometry geo;
  geo.dims = {kNx, kNy, kNz};
  geo.spacing_m = Eigen::Vector3d::Constant(kVoxel);
  std::vector<float> v(geo.voxelCount());
  for (int k = 0; k < kNz; ++k)
    for (int j = 0; j < kNy; ++j)
      for (int i = 0; i < kNx; ++i) v[geo.indexOf(i, j, k)] = static_cast<float>(gelValue(i, j, k));
  return std::make_shared<const haptics::ScalarVolume>(haptics::ScalarVolume::FromVoxels(geo, v));
}

TissueRegion region(double cell_m) {
  VoxelGrid grid;
  grid.dims = Eigen::Vector3i(kNx, kNy, kNz);
  grid.spacing_m = Eigen::Vector3d::Constant(kVoxel);
  RegionSpec spec;
  spec.cell_size_m = cell_m;
  // A value band per material, as a CT's soft tissue is cut: the inclusion above 150, the gel
  // from 10 (its blurred top included) to 150.
  spec.material_of_voxel = [](int i, int j, int k) {
    if (k < 2) return -1;
    const double v = gelValue(i, j, k);
    return v > 150.0 ? 1 : v > 10.0 ? 0 : -1;
  };
  spec.is_rigid_voxel = [](int, int, int k) { return k < 2; };
  spec.hold_at_scan_border = true;
  return buildTissueRegion(grid, spec, {materialPreset("gel"), materialPreset("gel inclusion")});
}

struct Stats {
  double mean = 0, p999 = 0, max = 0;
  int over_500us = 0, over_period = 0;
};
Stats stats(std::vector<double> t_us) {
  Stats s;
  if (t_us.empty()) return s;
  for (const double v : t_us) s.mean += v / static_cast<double>(t_us.size());
  std::sort(t_us.begin(), t_us.end());
  s.p999 = t_us[std::min(t_us.size() - 1, static_cast<std::size_t>(std::ceil(0.999 * static_cast<double>(t_us.size()))) - 1)];
  s.max = t_us.back();
  for (const double v : t_us) s.over_500us += v > 500.0, s.over_period += v > 1000.0;
  return s;
}
double since_us(Clock::time_point a) { return std::chrono::duration<double, std::micro>(Clock::now() - a).count(); }

}  // namespace

int main(int argc, char** argv) {
  double cell_m = 2e-3, window_margin_m = 0.0;
  int lanes = 1;
  bool quick = false;
  for (int i = 1; i < argc; ++i) {
    if (std::strncmp(argv[i], "--cell-mm=", 10) == 0) cell_m = std::atof(argv[i] + 10) * 1e-3;
    else if (std::strcmp(argv[i], "--quick") == 0) quick = true;
    else if (std::strncmp(argv[i], "--window-margin-mm=", 19) == 0) window_margin_m = std::atof(argv[i] + 19) * 1e-3;
    else if (std::strncmp(argv[i], "--lanes=", 8) == 0) lanes = std::atoi(argv[i] + 8);
  }
  const double R = 4e-3;
  const auto t0 = Clock::now();
  const std::shared_ptr<const haptics::ScalarVolume> field = scan();
  TissueRegion tissue = region(cell_m);
  const int voxels = tissue.tissue_voxels;
  const int nodes = tissue.model.lattice().nodeCount();
  const auto t1 = Clock::now();
  DeformableSceneOptions options;
  options.compliance_threads = 2;
  options.window_margin_m = window_margin_m;
  DeformableScene scene(field, std::move(tissue), kIsovalue, options);
  scene.setLanes(lanes);
  const double start_s = std::chrono::duration<double>(Clock::now() - t1).count();
  std::printf("gel block with an inclusion (%d tissue voxels), lattice %.1f mm: %d nodes, %d touchable; region %.2f s, "
              "scene start (factor, table %.0f MB, depth field) %.2f s; resampling on %d lane(s)\n",
              voxels, cell_m * 1e3, nodes, scene.compliance().nodeCount(),
              std::chrono::duration<double>(t1 - t0).count(), scene.compliance().bytes() / 1e6, start_s,
              scene.lanes());

  haptics::PointShellOptions shell;
  shell.spacing_m = 0.4e-3;
  const auto tool = std::make_shared<const haptics::ToolModel>(
      haptics::makeToolModel(datasets::makeSphereMesh(R, 4), shell, 1000.0));
  haptics::RendererOptions ro;  // as the application runs it
  ro.edge_test = 1;
  ro.deadline_us = 900.0;
  const Eigen::Vector3d start(10e-3, 15e-3, kTop_m + R + 0.5e-3);
  haptics::Pose X_WD = haptics::Pose::FromTranslation(start);
  haptics::HapticRenderer soft(scene.feltVolume(), tool, ro, X_WD, kIsovalue);
  haptics::HapticRenderer rigid(field, tool, ro, X_WD, kIsovalue);
  const haptics::CrossingVerifier soft_check(*scene.feltVolume(), tool->point_shell, 1e-2);
  const haptics::CrossingVerifier rigid_check(*field, tool->point_shell, 1e-2);

  // Down 2.5 mm (to 2 mm below the surface) in 1.5 s, held 0.5 s, across 10 mm (over the
  // inclusion) in 2 s, held, up and away in 1 s.
  std::vector<Eigen::Vector3d> path;
  const double scale = quick ? 0.25 : 1.0;
  const auto segment = [&](const Eigen::Vector3d& a, const Eigen::Vector3d& b, int ticks) {
    for (int t = 1; t <= ticks; ++t) path.push_back(a + (b - a) * (static_cast<double>(t) / ticks));
  };
  const Eigen::Vector3d down = start - Eigen::Vector3d(0, 0, 2.5e-3), across = down + Eigen::Vector3d(10e-3, 0, 0);
  segment(start, down, static_cast<int>(1500 * scale));
  segment(down, down, static_cast<int>(500 * scale));
  segment(down, across, static_cast<int>(2000 * scale));
  segment(across, across, static_cast<int>(500 * scale));
  segment(across, across + Eigen::Vector3d(0, 0, 3e-3), static_cast<int>(1000 * scale));

  std::vector<double> soft_us, rigid_us, step_us, after_us;
  DeformableStep parts;
  int soft_cut = 0, rigid_cut = 0, soft_cross = 0, rigid_cross = 0, held_back = 0, clipped = 0;
  double soft_behind = 0, rigid_behind = 0, peak_soft_N = 0, peak_rigid_N = 0, peak_u = 0;
  for (const Eigen::Vector3d& p : path) {
    X_WD.p_AB_m = p;
    auto a = Clock::now();
    const DeformableStep s = scene.step(X_WD, soft);
    const haptics::TickOutput so = soft.tick(X_WD, kIsovalue);
    soft_us.push_back(since_us(a));
    a = Clock::now();
    const haptics::TickOutput ro_out = rigid.tick(X_WD, kIsovalue);
    rigid_us.push_back(since_us(a));
    step_us.push_back(s.step_us);
    after_us.push_back(soft_us.back() - s.step_us);
    parts.gather_us += s.gather_us, parts.solve_us += s.solve_us, parts.displace_us += s.displace_us;
    parts.resample_us += s.resample_us, parts.write_us += s.write_us;
    parts.window_voxels = std::max(parts.window_voxels, s.window_voxels);
    held_back += s.felt_fraction < 1.0, clipped += s.window_clipped;
    peak_u = std::max(peak_u, s.max_displacement_m);
    soft_cut += so.stats.deadline_cut, rigid_cut += ro_out.stats.deadline_cut;
    soft_behind = std::max(soft_behind, (so.X_WP.p_AB_m - p).norm() - so.force_W_N.norm() / ro.gains.linear_N_per_m);
    rigid_behind = std::max(rigid_behind, (ro_out.X_WP.p_AB_m - p).norm() - ro_out.force_W_N.norm() / ro.gains.linear_N_per_m);
    peak_soft_N = std::max(peak_soft_N, so.force_W_N.norm());
    peak_rigid_N = std::max(peak_rigid_N, ro_out.force_W_N.norm());
    // Outside the timed part: every point's path sampled every 1/100 voxel against each field.
    soft_cross += soft_check.check(soft.lastMotion(), soft.lastTimeOfContact(), kIsovalue).crossing_points;
    rigid_cross += rigid_check.check(rigid.lastMotion(), rigid.lastTimeOfContact(), kIsovalue).crossing_points;
  }
  const Stats ss = stats(soft_us), rs = stats(rigid_us), st = stats(step_us), at = stats(after_us);
  const double n = static_cast<double>(path.size());
  std::printf("\nwhole tick, %zu ticks interleaved (ball R 4 mm, %zu points, coupling %.0f N/m, edge test on, deadline "
              "900 us)\n", path.size(), tool->point_shell.size(), ro.gains.linear_N_per_m);
  std::printf("| tick [us] | mean | p99.9 | max | > 500 us | > 1 ms | cut by the deadline | peak force [N] | crossings |\n");
  std::printf("|---|---|---|---|---|---|---|---|---|\n");
  std::printf("| tissue (step + tick) | %.0f | %.0f | %.0f | %d | %d | %d | %.3f | %d |\n", ss.mean, ss.p999, ss.max,
              ss.over_500us, ss.over_period, soft_cut, peak_soft_N, soft_cross);
  std::printf("| of which the step | %.0f | %.0f | %.0f | %d | %d | | | |\n", st.mean, st.p999, st.max, st.over_500us,
              st.over_period);
  std::printf("| of which the renderer's tick | %.0f | %.0f | %.0f | %d | %d | | | |\n", at.mean, at.p999, at.max,
              at.over_500us, at.over_period);
  std::printf("| rigid (tick) | %.0f | %.0f | %.0f | %d | %d | %d | %.3f | %d |\n", rs.mean, rs.p999, rs.max,
              rs.over_500us, rs.over_period, rigid_cut, peak_rigid_N, rigid_cross);
  std::printf("tissue over rigid: mean %.1fx, p99.9 %.1fx, max %.1fx\n", ss.mean / rs.mean, ss.p999 / rs.p999,
              ss.max / rs.max);
  std::printf("the step's parts, mean [us]: gather %.0f, solve %.0f, displace %.0f, resample %.0f, write %.0f; largest "
              "window %d voxels; %d ticks held back (a proxy point would have been swallowed), %d windows clipped; "
              "largest nodal displacement %.2f mm\n",
              parts.gather_us / n, parts.solve_us / n, parts.displace_us / n, parts.resample_us / n, parts.write_us / n,
              parts.window_voxels, held_back, clipped, peak_u * 1e3);
  std::printf("proxy behind the device beyond the coupling's stretch: tissue %.3f mm, rigid %.3f mm (max)\n",
              soft_behind * 1e3, rigid_behind * 1e3);

  // Force against indentation, over the inclusion and beside it (quasi-static presses).
  const StaticSolver solver(scene.region().model, scene.region().fixed_dofs);
  std::printf("\nforce against indentation (held 300 ticks a depth, the last 100 averaged):\n");
  std::printf("| where | depth [mm] | felt [mN] | full solve, exact contact [mN] |\n|---|---|---|---|\n");
  for (const double x : {kInclusion.x(), 8e-3}) {
    DeformableScene press_scene(field, region(cell_m), kIsovalue, options);
    const Eigen::Vector2d xy(x, kInclusion.y());
    haptics::Pose X = haptics::Pose::FromTranslation(Eigen::Vector3d(xy.x(), xy.y(), kTop_m + R + 0.3e-3));
    haptics::HapticRenderer r(press_scene.feltVolume(), tool, ro, X, kIsovalue);
    for (const double depth : {0.5e-3, 1.0e-3, 1.5e-3}) {
      const double target = kTop_m + R - depth;
      while (X.p_AB_m.z() > target) {
        X.p_AB_m.z() = std::max(target, X.p_AB_m.z() - 2e-6);
        press_scene.step(X, r);
        r.tick(X, kIsovalue);
      }
      double felt = 0, proxy_depth = 0;
      for (int t = 0; t < 300; ++t) {
        press_scene.step(X, r);
        const haptics::TickOutput o = r.tick(X, kIsovalue);
        if (t < 200) continue;
        felt += o.force_W_N.z() / 100.0;
        proxy_depth += (kTop_m - (o.X_WP.p_AB_m.z() - R)) / 100.0;
      }
      const double reference = sphereContactForce_N(press_scene.region(), solver, R, proxy_depth, xy, kTop_m);
      std::printf("| %s | %.3f | %.2f | %.2f |\n", x == kInclusion.x() ? "over the inclusion" : "beside it",
                  proxy_depth * 1e3, felt * 1e3, reference * 1e3);
    }
  }
  return 0;
}
