// The rendering algorithm on deformable tissue: the 6-DOF renderer (configuration solver,
// collision detector, edge test: unchanged) feels the gel of a scan through the volume that
// DeformableScene rewrites tick by tick. Checked against what the servo path never uses:
//   - the force felt at each depth against the exact frictionless contact of a rigid sphere with
//     the same lattice (the full static solve's compliance at the rest surface, Lawson-Hanson),
//     and against Hertz (printed: a lattice this coarse is Hertz's within its own error, see
//     mechanics_oracles_test.cpp);
//   - the tissue's shape under the pushes from the full static solve: the deformed surface
//     touches the proxy's sphere and holds it out;
//   - on every tick: no proxy point inside the felt field, 0 crossings by a dense check of the
//     tick's motion (CrossingVerifier), and, released, the field back to the scan's voxels;
//   - sliding: no edge of the tool's surface between its points inside the felt field (checked
//     along every edge);
//   - the written field, voxel for voxel, against an independent solve of each material point;
//   - what the view is given (takeDeformedWindow()): the felt field, voxel for voxel over the whole
//     scan, whenever the field has settled under a held tool, and the rest state once released.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <stdexcept>
#include <vector>

#include <gtest/gtest.h>

#include "allocation_guard.h"
#include "vh/datasets/synthetic.h"
#include "vh/haptics/crossing_verifier.h"
#include "vh/haptics/haptic_renderer.h"
#include "vh/haptics/point_shell.h"
#include "vh/haptics/tool_model.h"
#include "vh/haptics/worker_pool.h"
#include "vh/tissue/deformable_scene.h"
#include "vh/tissue/deformed_field.h"
#include "sphere_contact_reference.h"

namespace vh::tissue {
namespace {

// The scan: 48 x 48 x 32 voxels of 0.5 mm, float. Bone below k = 2 (rigid), gel for k = 2..25,
// air above; the gel's top blurred over 2 mm as a scan's partial volume blurs it (100 deep in the
// gel, 0 in the air, linear between). Isovalue 50: the top surface lies at z = 12.75 mm.
constexpr double kVoxel = 0.5e-3;
constexpr int kTopVoxel = 25;
constexpr double kIsovalue = 50.0;
constexpr double kTop_m = (kTopVoxel + 0.5) * kVoxel;

std::shared_ptr<const haptics::ScalarVolume> gelScan() {
  haptics::VolumeGeometry geo;
  geo.dims = {48, 48, 32};
  geo.spacing_m = Eigen::Vector3d::Constant(kVoxel);
  std::vector<float> v(geo.voxelCount(), 0.0f);
  for (int k = 0; k < 32; ++k) {
    const double value = std::clamp(50.0 + 50.0 * (kTop_m - k * kVoxel) / 1e-3, 0.0, 100.0);
    for (int j = 0; j < 48; ++j)
      for (int i = 0; i < 48; ++i) v[geo.indexOf(i, j, k)] = static_cast<float>(value);
  }
  return std::make_shared<const haptics::ScalarVolume>(haptics::ScalarVolume::FromVoxels(geo, v));
}

TissueRegion gelRegion(double cell_m) {
  VoxelGrid grid;
  grid.dims = Eigen::Vector3i(48, 48, 32);
  grid.spacing_m = Eigen::Vector3d::Constant(kVoxel);
  RegionSpec spec;
  spec.cell_size_m = cell_m;
  spec.material_of_voxel = [](int, int, int k) { return k >= 2 && k <= kTopVoxel + 2 ? 0 : -1; };
  spec.is_rigid_voxel = [](int, int, int k) { return k < 2; };
  spec.hold_at_scan_border = true;  // the block is cut by the scan's sides
  return buildTissueRegion(grid, spec, {materialPreset("gel")});
}

std::shared_ptr<const haptics::ToolModel> sphereTool(double radius_m) {
  haptics::PointShellOptions shell;
  shell.spacing_m = 0.4e-3;
  return std::make_shared<const haptics::ToolModel>(
      haptics::makeToolModel(datasets::makeSphereMesh(radius_m, 4), shell, 1000.0));
}

struct PressRecord {
  double depth_m = 0.0;   // the proxy sphere's lowest point below the rest surface
  double force_N = 0.0;   // what the hand feels (+z up)
  double push_N = 0.0;    // the tissue's pushes summed (what the tissue is pushed with)
};

// A 4 mm ball 0.3 mm above the gel's top at (12, 12.2) mm on a 200 N/m coupling (the edge test
// on): the deformable scene (1.5 mm lattice), the renderer on its felt volume and the dense
// crossing check on it.
struct GelPress {
  static constexpr double kRadius_m = 4e-3;
  static DeformableSceneOptions sceneOptions() {
    DeformableSceneOptions o;
    o.compliance_threads = 2;
    return o;
  }
  static haptics::RendererOptions rendererOptions() {
    haptics::RendererOptions o;
    o.edge_test = 1;
    o.gains.linear_N_per_m = 200.0;
    o.gains.angular_Nm_per_rad = 0.05;
    return o;
  }
  std::shared_ptr<const haptics::ScalarVolume> scan = gelScan();
  DeformableScene scene{scan, gelRegion(1.5e-3), kIsovalue, sceneOptions()};
  std::shared_ptr<const haptics::ToolModel> tool = sphereTool(kRadius_m);
  haptics::RendererOptions ro = rendererOptions();
  haptics::Pose X_WD = haptics::Pose::FromTranslation(Eigen::Vector3d(12e-3, 12.2e-3, kTop_m + kRadius_m + 0.3e-3));
  haptics::HapticRenderer renderer{scene.feltVolume(), tool, ro, X_WD, kIsovalue};
  haptics::CrossingVerifier verifier{*scene.feltVolume(), tool->point_shell, 1e-2};
};

TEST(TissueDeformableScene, TheSolverFeelsTheGelYieldByTheFullSolveAndNeverEntersIt) {
  GelPress g;
  const double R = GelPress::kRadius_m;
  const auto& scan = g.scan;
  DeformableScene& scene = g.scene;
  const auto& tool = g.tool;
  const haptics::RendererOptions& ro = g.ro;
  const Eigen::Vector2d xy(12e-3, 12.2e-3);
  haptics::Pose& X_WD = g.X_WD;
  haptics::HapticRenderer& renderer = g.renderer;
  const haptics::CrossingVerifier& verifier = g.verifier;

  // Down 2 um a tick to 0.75 mm below the surface, held at five depths on the way (400 ticks
  // each, the last 100 averaged), then up and away.
  std::vector<PressRecord> records;
  int ticks = 0, crossings = 0, inside_after = 0, clipped = 0, held_back = 0;
  std::vector<double> step_us;
  step_us.reserve(4000);
  DeformableStep parts;  // summed
  std::size_t step_allocations = 0;
  double worst_inside = -1e300;
  const auto tick = [&](const haptics::Pose& X) {
    DeformableStep s;
    {
      const test::AllocationGuard guard;  // the servo path never allocates
      s = scene.step(X, renderer);
      step_allocations += guard.count();
    }
    step_us.push_back(s.step_us);
    if (s.step_us > 3000 && std::getenv("VH_DEBUG_TISSUE"))
      std::printf("slow step %d: %.0f us: gather %.0f solve %.0f displace %.0f resample %.0f write %.0f, window %d, written %d\n",
                  ticks, s.step_us, s.gather_us, s.solve_us, s.displace_us, s.resample_us, s.write_us, s.window_voxels,
                  s.voxels_written);
    parts.gather_us += s.gather_us;
    parts.solve_us += s.solve_us;
    parts.displace_us += s.displace_us;
    parts.resample_us += s.resample_us;
    parts.write_us += s.write_us;
    parts.window_voxels = std::max(parts.window_voxels, s.window_voxels);
    clipped += s.window_clipped;
    held_back += s.felt_fraction < 1.0;
    const haptics::TickOutput out = renderer.tick(X, kIsovalue);
    ++ticks;
    const haptics::CrossingVerifier::Result c =
        verifier.check(renderer.lastMotion(), renderer.lastTimeOfContact(), kIsovalue);
    crossings += c.crossing_points;
    for (const Eigen::Vector3d& p_T : tool->point_shell.points_T_m()) {
      const double F = scene.feltVolume()->sample(out.X_WP * p_T);
      worst_inside = std::max(worst_inside, F - kIsovalue);
      inside_after += F > kIsovalue;
    }
    return std::make_pair(out, s);
  };
  // The view's picture of the tissue against the felt field, every voxel: the window's values
  // inside its box, the scan's at rest outside it.
  DeformedWindow shown;
  const auto viewMismatches = [&]() {
    const haptics::VolumeGeometry& g = scan->geometry();
    std::size_t bad = 0, at = 0;
    for (int k = 0; k < g.dims[2]; ++k)
      for (int j = 0; j < g.dims[1]; ++j)
        for (int i = 0; i < g.dims[0]; ++i) {
          const bool in = !shown.empty() && i >= shown.lo[0] && i <= shown.hi[0] && j >= shown.lo[1] &&
                          j <= shown.hi[1] && k >= shown.lo[2] && k <= shown.hi[2];
          double view = scan->rawAt(g.indexOf(i, j, k));
          if (in) {
            at = static_cast<std::size_t>((i - shown.lo[0]) + (shown.hi[0] - shown.lo[0] + 1) *
                                                               ((j - shown.lo[1]) + (shown.hi[1] - shown.lo[1] + 1) * (k - shown.lo[2])));
            view = at < shown.values_F.size() ? shown.values_F[at] : std::nan("");
          }
          bad += !(std::abs(view - scene.feltVolume()->rawAt(g.indexOf(i, j, k))) <= 1e-4);
        }
    return bad;
  };
  int settled_holds = 0;
  const std::vector<double> holds{0.15e-3, 0.3e-3, 0.45e-3, 0.6e-3, 0.75e-3};
  double z = X_WD.p_AB_m.z();
  for (const double hold : holds) {
    const double target = kTop_m + R - hold;
    while (z > target) {
      z = std::max(target, z - 2e-6);
      X_WD.p_AB_m.z() = z;
      tick(X_WD);
    }
    PressRecord r;
    for (int t = 0; t < 400; ++t) {
      const auto [out, s] = tick(X_WD);
      if (t == 399 && s.voxels_written == 0) {  // settled: the step published the field as it is
        ++settled_holds;
        ASSERT_TRUE(scene.takeDeformedWindow(shown)) << "nothing published for the view at hold " << hold;
        EXPECT_FALSE(shown.empty()) << "the view is told the tissue is at rest under the tool";
        EXPECT_EQ(viewMismatches(), 0u) << "the view's picture differs from the felt field at hold " << hold;
      }
      if (t < 300) continue;
      r.depth_m += (kTop_m - (out.X_WP.p_AB_m.z() - R)) / 100.0;
      r.force_N += out.force_W_N.z() / 100.0;
      r.push_N += s.contact.force_on_device_N.z() / 100.0;
    }
    records.push_back(r);
  }
  // The tissue's shape under the last pushes, by the full static solve: the deformed top surface
  // under the sphere's centre sits where the proxy's lowest point is.
  const StaticSolver solver(scene.region().model, scene.region().fixed_dofs);
  const Eigen::VectorXd u = solver.solve(scene.contact().nodalForces_N(scene.lastContacts()));
  const DeformedField deformed(scene.region().model.lattice(), u);
  const double surface_z = kTop_m + deformed.displacementAt(Eigen::Vector3d(xy.x(), xy.y(), kTop_m)).z();
  const double proxy_bottom = renderer.proxyPose().p_AB_m.z() - R;

  std::printf("gel (E 10 kPa, nu 0.45), 1.5 mm lattice (%d nodes, %d touchable), sphere R = 4 mm (%zu points), "
              "coupling 200 N/m\n", scene.region().model.lattice().nodeCount(), scene.compliance().nodeCount(),
              tool->point_shell.size());
  std::printf("  depth [mm]  felt [mN]  tissue pushed [mN]  full-solve contact [mN]  Hertz [mN]  felt/full\n");
  const double k_eps = ro.gains.linear_N_per_m * renderer.epsilon_m();
  std::printf("  (the coupling times the collision tolerance, k epsilon = %.3f mN)\n", 1e3 * k_eps);
  for (const PressRecord& r : records) {
    const double reference = sphereContactForce_N(scene.region(), solver, R, r.depth_m, xy, kTop_m);
    const double hertz = 4.0 / 3.0 * materialPreset("gel").contactModulus_Pa() * std::sqrt(R) * std::pow(r.depth_m, 1.5);
    std::printf("  %9.3f  %9.3f  %18.3f  %23.3f  %10.3f  %9.3f\n", 1e3 * r.depth_m, 1e3 * r.force_N, 1e3 * r.push_N,
                1e3 * reference, 1e3 * hertz, r.force_N / reference);
    // The servo path's model (the compliance table, its Gauss-Seidel, the tool's points) against
    // the full solve's exact contact.
    EXPECT_NEAR(r.push_N, reference, 0.15 * reference);
    // Equal and opposite: what the hand feels is what the tissue is pushed with, up to the
    // proxy's hover within the collision tolerance epsilon (paper section 2.3: a contact within
    // epsilon of the surface holds the proxy there), k epsilon at most.
    EXPECT_NEAR(r.force_N, r.push_N, k_eps + 0.05 * r.push_N);
    EXPECT_NEAR(r.force_N, reference, k_eps + 0.15 * reference);
  }
  std::printf("  full solve's surface under the centre %.4f mm, proxy's lowest point %.4f mm; %d ticks, %d crossings, "
              "deepest proxy point F - s = %.3g, %d ticks held back, %d windows clipped\n",
              1e3 * surface_z, 1e3 * proxy_bottom, ticks, crossings, worst_inside, held_back, clipped);
  std::sort(step_us.begin(), step_us.end());
  double mean_us = 0.0;
  for (const double t : step_us) mean_us += t / static_cast<double>(step_us.size());
  std::printf("  tissue step (gather, solve, write the window; printed, not asserted): mean %.0f us, p99.9 %.0f us, max %.0f us\n",
              mean_us, step_us[step_us.size() * 999 / 1000], step_us.back());
  const double n = static_cast<double>(step_us.size());
  std::printf("  its parts, mean: gather %.0f, solve %.0f, displace %.0f, resample %.0f, write %.0f us; largest window %d voxels\n",
              parts.gather_us / n, parts.solve_us / n, parts.displace_us / n, parts.resample_us / n, parts.write_us / n,
              parts.window_voxels);
  // The depth grows with the push and the tissue yields: softer than the coupling alone.
  for (std::size_t i = 1; i < records.size(); ++i) {
    EXPECT_GT(records[i].depth_m, records[i - 1].depth_m);
    EXPECT_GT(records[i].force_N, records[i - 1].force_N);
  }
  EXPECT_GT(records.back().depth_m, 0.5e-3) << "the gel did not yield";
  EXPECT_NEAR(surface_z, proxy_bottom, 0.1e-3) << "the tissue does not hold the tool where the full solve puts it";
  EXPECT_EQ(crossings, 0);
  EXPECT_EQ(inside_after, 0);
  EXPECT_EQ(step_allocations, 0u) << "the tissue's step allocated on the servo path";

  // A NaN device pose (a device fault): nothing is solved or written, the proxy stays.
  {
    haptics::Pose bad = X_WD;
    bad.p_AB_m.x() = std::nan("");
    const DeformableStep s = scene.step(bad, renderer);
    EXPECT_EQ(s.contact.contacts, 0);
    EXPECT_EQ(s.voxels_written, 0);
  }

  // Released: up and away; the field goes back to the scan's voxels exactly.
  for (int t = 0; t < 600; ++t) {
    z += 4e-6;
    X_WD.p_AB_m.z() = z;
    tick(X_WD);
  }
  EXPECT_EQ(crossings, 0);
  EXPECT_EQ(inside_after, 0);
  std::size_t differing = 0;
  for (std::size_t v = 0; v < scan->geometry().voxelCount(); ++v)
    differing += scene.feltVolume()->rawAt(v) != scan->rawAt(v);
  EXPECT_EQ(differing, 0u) << "released, the gel did not spring back";
  // The view follows: the tissue at rest, nothing left drawn deformed.
  EXPECT_GE(settled_holds, 3) << "the field did not settle under a held tool";
  ASSERT_TRUE(scene.takeDeformedWindow(shown));
  EXPECT_TRUE(shown.empty());
  EXPECT_EQ(viewMismatches(), 0u);
  EXPECT_FALSE(scene.takeDeformedWindow(shown)) << "a second take without a new step";
}

// The field the step wrote, against the material points an independent solve gives: the ball
// held 0.6 mm in, the nodal displacements from the full static solve of the last pushes (not the
// compliance table), each voxel centre's material point by Newton to 1e-9 m (DeformedField, not
// the step's chord iteration), F sampled there. Every voxel the step moved holds that value to a
// tenth of the step's stopping tolerance (a thousandth of a voxel: 0.025 of F's 25 per voxel
// here; the chord steps contract by a tenth or better, plain fixed-point steps under this push
// stopped 0.004 away), and in each column of the window the surface F = s lies where that field
// puts it. (Voxels deeper than the band keep the scan's value: they may differ from the oracle
// without moving the surface.)
TEST(TissueDeformableScene, TheWrittenFieldIsTheScanAtItsMaterialPoints) {
  GelPress g;
  DeformableScene& scene = g.scene;
  haptics::Pose& X_WD = g.X_WD;
  DeformableStep last;
  while (X_WD.p_AB_m.z() > kTop_m + GelPress::kRadius_m - 0.6e-3) {
    X_WD.p_AB_m.z() -= 5e-6;
    scene.step(X_WD, g.renderer);
    g.renderer.tick(X_WD, kIsovalue);
  }
  for (int t = 0; t < 300; ++t) {
    last = scene.step(X_WD, g.renderer);
    g.renderer.tick(X_WD, kIsovalue);
  }
  ASSERT_EQ(last.felt_fraction, 1.0) << "the last step was held back: its field is not the pushes' alone";
  DeformedWindow shown;
  ASSERT_TRUE(scene.takeDeformedWindow(shown));
  ASSERT_FALSE(shown.empty());
  const StaticSolver solver(scene.region().model, scene.region().fixed_dofs);
  const DeformedField deformed(scene.region().model.lattice(), solver.solve(scene.contact().nodalForces_N(scene.lastContacts())));
  const haptics::ScalarVolume& scan = *g.scan;
  const haptics::ScalarVolume& felt = *scene.feltVolume();
  // The surface's height in a column of values (k from lo[2] up): the first crossing of s from
  // the top down, linear between voxel centres [voxels]; -1 when there is none.
  const auto crossing = [&](const std::vector<double>& column) {
    for (int k = static_cast<int>(column.size()) - 1; k > 0; --k)
      if (column[k] < kIsovalue && column[k - 1] >= kIsovalue)
        return shown.lo[2] + k - 1 + (column[k - 1] - kIsovalue) / (column[k - 1] - column[k]);
    return -1.0;
  };
  double worst_moved = 0.0, largest_change = 0.0, worst_surface = 0.0, deepest = 1e9;
  std::size_t moved = 0, columns = 0, unconverged = 0;
  for (int j = shown.lo[1]; j <= shown.hi[1]; ++j)
    for (int i = shown.lo[0]; i <= shown.hi[0]; ++i) {
      std::vector<double> written_column, expected_column;
      for (int k = shown.lo[2]; k <= shown.hi[2]; ++k) {
        const DeformedField::Inverse X = deformed.materialPoint(kVoxel * Eigen::Vector3d(i, j, k), 1e-9, 50);
        // No material point: above the lattice's top face pushed down (u is zero beyond it), air.
        unconverged += !X.converged;
        const double expected = X.converged ? scan.sampleGrid(X.X_G_m / kVoxel) : scan.voxel(i, j, k);
        const double written = felt.voxel(i, j, k);
        written_column.push_back(written);
        expected_column.push_back(expected);
        if (written == scan.voxel(i, j, k)) continue;
        ++moved;
        worst_moved = std::max(worst_moved, std::abs(written - expected));
        largest_change = std::max(largest_change, std::abs(written - scan.voxel(i, j, k)));
      }
      const double at_written = crossing(written_column), at_expected = crossing(expected_column);
      ASSERT_EQ(at_written < 0.0, at_expected < 0.0) << "column " << i << ", " << j;
      if (at_written < 0.0) continue;
      ++columns;
      worst_surface = std::max(worst_surface, std::abs(at_written - at_expected));
      deepest = std::min(deepest, at_written);
    }
  std::printf("held 0.6 mm in: %zu voxels moved (by up to %.1f of F), at most %.4f of F from the independent "
              "material point; the surface in %zu columns within %.2e voxels of it (deepest at %.2f voxels, rest "
              "%.2f); %zu voxels in the air above the lattice have no material point\n",
              moved, largest_change, worst_moved, columns, worst_surface, deepest, kTop_m / kVoxel, unconverged);
  EXPECT_GT(moved, 100u) << "the gel was not deformed";
  EXPECT_LT(deepest, kTop_m / kVoxel - 0.5) << "the surface was not pushed half a voxel in";
  EXPECT_GT(columns, 100u);
  EXPECT_LT(worst_moved, 0.0025);
  EXPECT_LT(worst_surface, 2e-3);
}

// The edge test on deformed tissue: pressed 0.8 mm and slid 3 mm, the tool's surface between its
// points never enters the felt field (each tick's move checked edge by edge by
// CrossingVerifier::checkEdges, sampled along every edge; the renderer's own edge test walks
// cells and trusts certificates), nor does any of its points.
TEST(TissueDeformableScene, TheToolsSurfaceBetweenItsPointsNeverEntersTheSlidTissue) {
  GelPress g;
  const haptics::ShellEdges edges = haptics::makeShellEdges(g.tool->point_shell);
  haptics::Pose& X_WD = g.X_WD;
  int crossing_edges = 0, crossing_points = 0, changed_ticks = 0, edge_stops = 0;
  const auto tick = [&] {
    const DeformableStep s = g.scene.step(X_WD, g.renderer);
    const haptics::TickOutput out = g.renderer.tick(X_WD, kIsovalue);
    crossing_points += g.verifier.check(g.renderer.lastMotion(), g.renderer.lastTimeOfContact(), kIsovalue).crossing_points;
    crossing_edges += g.verifier
                          .checkEdges(g.renderer.lastMotion(), g.renderer.lastTimeOfContact(), kIsovalue, edges,
                                      g.renderer.epsilon_m())
                          .crossing_edges;
    changed_ticks += s.voxels_written > 0;
    edge_stops += out.stats.edge_stop;
  };
  while (X_WD.p_AB_m.z() > kTop_m + GelPress::kRadius_m - 0.8e-3) {  // 0.8 mm in, 5 um a tick
    X_WD.p_AB_m.z() -= 5e-6;
    tick();
  }
  const double depth_m = kTop_m - (g.renderer.proxyPose().p_AB_m.z() - GelPress::kRadius_m);
  for (int t = 0; t < 600; ++t) {  // 3 mm across, 5 um a tick
    X_WD.p_AB_m.x() += 5e-6;
    tick();
  }
  std::printf("pressed 0.8 mm (the proxy %.3f mm in) and slid 3 mm: %d ticks rewrote the field, %d moves stopped by "
              "the edge test; %d crossing edges, %d crossing points\n",
              1e3 * depth_m, changed_ticks, edge_stops, crossing_edges, crossing_points);
  EXPECT_GT(depth_m, 0.3e-3) << "the ball did not sink into the gel";
  EXPECT_GT(changed_ticks, 500);
  EXPECT_EQ(crossing_edges, 0);
  EXPECT_EQ(crossing_points, 0);
}

// The step on several lanes (the tool's points and the window's rows dealt to the solver's pool)
// gathers the contacts and writes the field that one lane does, bit for bit, tick after tick of
// a press and a slide: each point and row is done as on one lane, the contacts taken in the
// tool's order. The lanes are checked when set.
TEST(TissueDeformableScene, AStepOnSeveralLanesGathersAndWritesWhatOneLaneDoes) {
  GelPress one, three;
  three.scene.setLanes(3);
  EXPECT_EQ(three.scene.lanes(), 3);
  EXPECT_THROW(one.scene.setLanes(0), std::invalid_argument);
  EXPECT_THROW(one.scene.setLanes(haptics::WorkerPool::kMaxLanes + 1), std::invalid_argument);
  EXPECT_EQ(one.scene.lanes(), 1);
  int ticks = 0, rewritten = 0, differing_fields = 0, differing_forces = 0, differing_contacts = 0, most_contacts = 0;
  const auto tick = [&](const Eigen::Vector3d& dp_W) {
    for (GelPress* g : {&one, &three}) g->X_WD.p_AB_m += dp_W;
    const DeformableStep s1 = one.scene.step(one.X_WD, one.renderer);
    const DeformableStep s3 = three.scene.step(three.X_WD, three.renderer);
    const haptics::TickOutput o1 = one.renderer.tick(one.X_WD, kIsovalue);
    const haptics::TickOutput o3 = three.renderer.tick(three.X_WD, kIsovalue);
    ++ticks;
    rewritten += s1.voxels_written > 0;
    differing_fields += one.scene.feltVolume()->bytes() != three.scene.feltVolume()->bytes() ||
                        s1.voxels_written != s3.voxels_written;
    const auto c1 = one.scene.lastContacts(), c3 = three.scene.lastContacts();
    bool same_contacts = c1.size() == c3.size() && s1.tool_points_near == s3.tool_points_near;
    for (std::size_t q = 0; same_contacts && q < c1.size(); ++q)
      same_contacts = c1[q].X_G_m == c3[q].X_G_m && c1[q].n_G == c3[q].n_G && c1[q].gap_m == c3[q].gap_m &&
                      c1[q].push_guess_N == c3[q].push_guess_N;
    differing_contacts += !same_contacts;
    most_contacts = std::max(most_contacts, static_cast<int>(c1.size()));
    differing_forces += o1.force_W_N != o3.force_W_N;
  };
  for (int t = 0; t < 180; ++t) tick(Eigen::Vector3d(0.0, 0.0, -5e-6));  // 0.9 mm down
  for (int t = 0; t < 200; ++t) tick(Eigen::Vector3d(5e-6, 2e-6, 0.0));  // 1 mm across
  std::printf("%d ticks, %d rewrote the field, up to %d contacts; contacts differing %d, fields %d, forces %d\n", ticks,
              rewritten, most_contacts, differing_contacts, differing_fields, differing_forces);
  EXPECT_GT(rewritten, 200) << "the ball hardly deformed the gel: nothing was compared";
  EXPECT_GT(most_contacts, 20);
  EXPECT_EQ(differing_contacts, 0);
  EXPECT_EQ(differing_fields, 0);
  EXPECT_EQ(differing_forces, 0);
}

// The tool pressed in and drawn back part of the way in one jump, then held: the tissue springs
// back onto the proxy that waits where the device was. The proxy being massless, the surface
// carries it (it is never swallowed, never left inside the tissue); at rest the hand feels what
// the tissue is pushed with, not nothing (a surface held back by a proxy that has no reason to
// move would leave the tissue deformed and the hand at zero force: that was the failure).
TEST(TissueDeformableScene, SpringingBackTheTissueCarriesTheHeldProxy) {
  GelPress g;
  const double R = GelPress::kRadius_m;
  DeformableScene& scene = g.scene;
  haptics::Pose& X_WD = g.X_WD;
  int crossings = 0, inside = 0, carried = 0;
  DeformableStep last;
  haptics::TickOutput out;
  const auto tick = [&] {
    last = scene.step(X_WD, g.renderer);
    carried += last.proxy_carried_m > 0.0;
    out = g.renderer.tick(X_WD, kIsovalue);
    crossings += g.verifier.check(g.renderer.lastMotion(), g.renderer.lastTimeOfContact(), kIsovalue).crossing_points;
    for (const Eigen::Vector3d& p_T : g.tool->point_shell.points_T_m())
      inside += scene.feltVolume()->sample(out.X_WP * p_T) > kIsovalue;
  };
  while (X_WD.p_AB_m.z() > kTop_m + R - 1.0e-3) {  // 1 mm in, 5 um a tick
    X_WD.p_AB_m.z() -= 5e-6;
    tick();
  }
  for (int t = 0; t < 300; ++t) tick();
  X_WD.p_AB_m.z() += 0.6e-3;  // drawn back 0.6 mm at once, then held
  for (int t = 0; t < 1500; ++t) tick();
  const double push = last.contact.force_on_device_N.z();
  const double k_eps = g.ro.gains.linear_N_per_m * g.renderer.epsilon_m();
  std::printf("held 0.4 mm in after drawing back: felt %.2f mN, the tissue pushed %.2f mN, %d steps carried the proxy, "
              "%d crossings, %d points inside\n", 1e3 * out.force_W_N.z(), 1e3 * push, carried, crossings, inside);
  EXPECT_GT(push, 1e-3) << "the tissue is still pushed";
  EXPECT_NEAR(out.force_W_N.z(), push, k_eps + 0.1 * push) << "at rest the hand feels what the tissue is pushed with";
  EXPECT_GT(carried, 0) << "the springing-back surface never met the proxy";
  EXPECT_EQ(crossings, 0);
  EXPECT_EQ(inside, 0);
}

}  // namespace
}  // namespace vh::tissue
