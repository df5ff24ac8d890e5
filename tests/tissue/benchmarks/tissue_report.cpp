// The tissue model's costs on this machine, as a report (no assertion: a benchmark):
//   1. the region and the one-off work at scene start: lattice, factorisation, the condensed
//      surface compliance (per lattice size);
//   2. a servo tick with tissue contact (the compliant contact solve) beside the same tick
//      against a rigid surface (the same points, the same solver, the tissue's compliance left
//      out), over a press-and-release trajectory of a 5 mm ball: mean, p99.9 and max, ticks over
//      the 1 ms period and over 500 us, contacts and sweeps;
//   3. the background model's step (one full static solve) per lattice size.
// Usage: vh_tissue_report [--quick] [--sweeps=N] [POINT_SPACING_MM]
//   --quick: one lattice (4 mm cells) only; POINT_SPACING_MM: the ball's tool-point spacing
//   (default 0.5, one per voxel); --sweeps: the Gauss-Seidel budget per tick (default 10), each
//   tick starting from the last tick's pushes.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <vector>

#include "vh/tissue/compliant_contact.h"
#include "vh/tissue/static_solver.h"
#include "vh/tissue/surface_compliance.h"
#include "vh/tissue/tissue_region.h"

namespace {

using namespace vh::tissue;
using Clock = std::chrono::steady_clock;

double seconds(Clock::time_point a, Clock::time_point b) { return std::chrono::duration<double>(b - a).count(); }

struct Stats {
  double mean = 0, p999 = 0, max = 0;
  int over_period = 0, over_500us = 0;
};

Stats stats(std::vector<double> t) {
  Stats s;
  if (t.empty()) return s;
  for (const double v : t) s.mean += v / static_cast<double>(t.size());
  std::sort(t.begin(), t.end());
  s.p999 = t[std::min(t.size() - 1, static_cast<std::size_t>(std::ceil(0.999 * static_cast<double>(t.size()))) - 1)];
  s.max = t.back();
  for (const double v : t) {
    s.over_period += v > 1e-3;
    s.over_500us += v > 500e-6;
  }
  return s;
}

}  // namespace

int main(int argc, char** argv) {
  bool quick = false;
  double point_spacing_m = 0.5e-3;
  int sweeps = 10;
  for (int i = 1; i < argc; ++i) {
    if (std::strcmp(argv[i], "--quick") == 0) quick = true;
    else if (std::strncmp(argv[i], "--sweeps=", 9) == 0) sweeps = std::atoi(argv[i] + 9);
    else point_spacing_m = std::atof(argv[i]) * 1e-3;
  }
  if (!(point_spacing_m > 0.0)) {
    std::fprintf(stderr, "vh_tissue_report: the point spacing must be > 0 mm\n");
    return 2;
  }
  const double voxel = 0.5e-3;
  // A gel block scan of 120 x 120 x 80 voxels (60 x 60 x 40 mm): gel below z = 35 mm, air above,
  // a stiffer inclusion of radius 6 mm; held at the scan's border (sides and bottom).
  VoxelGrid grid;
  grid.dims = Eigen::Vector3i(120, 120, 80);
  grid.spacing_m = Eigen::Vector3d::Constant(voxel);
  const int top_voxel = 69;
  const Eigen::Vector3d inclusion(30e-3, 30e-3, 25e-3);
  std::printf("tissue report: a gel block scan, %d x %d x %d voxels of %.1f mm, gel up to z = %.2f mm\n\n", grid.dims.x(),
              grid.dims.y(), grid.dims.z(), voxel * 1e3, voxel * (top_voxel + 0.5) * 1e3);
  std::printf("%-8s %-7s %-8s %-8s %-9s %-10s %-10s %-10s %-12s\n", "cell mm", "nodes", "voxels", "touch", "factor s",
              "L nnz", "table s", "table MB", "full solve ms");
  std::vector<double> cells_mm = quick ? std::vector<double>{4.0} : std::vector<double>{5.0, 4.0, 3.0};
  for (const double cell_mm : cells_mm) {
    RegionSpec spec;
    spec.cell_size_m = cell_mm * 1e-3;
    spec.material_of_voxel = [&](int i, int j, int k) {
      if (k > top_voxel) return -1;
      return (voxel * Eigen::Vector3d(i, j, k) - inclusion).norm() < 6e-3 ? 1 : 0;
    };
    spec.hold_at_scan_border = true;
    const TissueRegion region = buildTissueRegion(grid, spec, {materialPreset("gel"), materialPreset("gel inclusion")});
    const auto t1 = Clock::now();
    const StaticSolver solver(region.model, region.fixed_dofs);
    const auto t2 = Clock::now();
    const SurfaceCompliance table(solver, outerLayerNodes(region.model.lattice()), 2);
    const auto t3 = Clock::now();
    const Eigen::VectorXd f = Eigen::VectorXd::Constant(region.model.dofCount(), 1e-3);
    const auto t4 = Clock::now();
    const Eigen::VectorXd u = solver.solve(f);
    if (!u.allFinite()) std::printf("  the full solve gave a non-finite displacement\n");
    const auto t5 = Clock::now();
    std::printf("%-8.1f %-7d %-8d %-8d %-9.2f %-10ld %-10.2f %-10.1f %-12.2f\n", cell_mm, region.model.lattice().nodeCount(),
                region.tissue_voxels, table.nodeCount(), seconds(t1, t2), solver.factorNonZeros(), seconds(t2, t3),
                static_cast<double>(table.bytes()) / 1e6, 1e3 * seconds(t4, t5));

    // The servo tick: a 5 mm ball (tool points one per voxel on its underside) pressed 0..3 mm and
    // back over 2,000 ticks at 4 places (over the inclusion and beside it), k = 1,000 N/m.
    CompliantContact contact(region.model.lattice(), table, 512);
    const double R = 5e-3, k = 1000.0, top = voxel * (top_voxel + 0.5);
    std::vector<Eigen::Vector3d> points;  // the ball's underside, relative to its centre's x, y
    for (double dx = -R; dx <= R; dx += point_spacing_m)
      for (double dy = -R; dy <= R; dy += point_spacing_m)
        if (dx * dx + dy * dy <= R * R) points.emplace_back(dx, dy, 0.0);
    std::vector<double> soft_s, rigid_s, last_push(points.size(), 0.0);
    std::vector<int> point_of_contact;
    point_of_contact.reserve(points.size());
    double max_projected = 0.0;
    std::vector<TissueContactPoint> contacts;
    contacts.reserve(points.size());
    int max_contacts = 0, max_sweeps = 0, max_rigid = 0;
    double max_force = 0.0, max_violation = 0.0;
    const Eigen::Vector2d places[4] = {{30e-3, 30e-3}, {15e-3, 30e-3}, {30e-3, 45e-3}, {40e-3, 20e-3}};
    for (const Eigen::Vector2d& xy : places)
      for (int tick = 0; tick < 500; ++tick) {
        const double phase = static_cast<double>(tick) / 499.0;
        const double depth = 3e-3 * std::sin(M_PI * phase);
        const Eigen::Vector3d centre(xy.x(), xy.y(), top + R - depth);
        const auto a = Clock::now();
        contacts.clear();
        point_of_contact.clear();
        for (std::size_t q = 0; q < points.size(); ++q) {
          const Eigen::Vector3d& d = points[q];
          const Eigen::Vector2d p(xy.x() + d.x(), xy.y() + d.y());
          const double r2 = d.head<2>().squaredNorm();
          const double gap = centre.z() - std::sqrt(R * R - r2) - top;
          if (gap < 0.5e-3) {
            contacts.push_back({Eigen::Vector3d(p.x(), p.y(), top), Eigen::Vector3d::UnitZ(), gap, last_push[q]});
            point_of_contact.push_back(static_cast<int>(q));
          }
        }
        const CompliantContactResult r = contact.solve(contacts, k, sweeps, 1e-9);
        std::fill(last_push.begin(), last_push.end(), 0.0);
        for (std::size_t i = 0; i < point_of_contact.size(); ++i)
          last_push[static_cast<std::size_t>(point_of_contact[i])] = contact.pushes_N()(static_cast<Eigen::Index>(i));
        const auto b = Clock::now();
        max_projected = std::max(max_projected, r.projected_m);
        soft_s.push_back(seconds(a, b));
        max_contacts = std::max(max_contacts, r.contacts);
        max_sweeps = std::max(max_sweeps, r.sweeps);
        max_rigid = std::max(max_rigid, r.rigid_points);
        max_force = std::max(max_force, r.force_on_device_N.norm());
        max_violation = std::max(max_violation, r.max_violation_m);
        // Rigid: the same points against an immovable surface (the coupling alone).
        const auto c = Clock::now();
        double deepest = 0.0;
        for (const TissueContactPoint& p : contacts) deepest = std::min(deepest, p.gap_m);
        volatile double rigid_force = -k * deepest;
        (void)rigid_force;
        const auto d = Clock::now();
        rigid_s.push_back(seconds(c, d));
      }
    const Stats s = stats(soft_s), rs = stats(rigid_s);
    std::printf("  ball R 5 mm, tool points every %.2f mm, %d sweeps a tick, proxy moved out after them at most %.3g m\n",
                point_spacing_m * 1e3, sweeps, max_projected);
    std::printf("  servo tick with tissue contact (2,000 ticks, up to %d contacts, %d sweeps, peak %.3f N, "
                "violation %.2g m, points held rigid %d):\n", max_contacts, max_sweeps, max_force, max_violation, max_rigid);
    std::printf("    tissue: mean %.1f us, p99.9 %.1f us, max %.1f us, over 1 ms: %d, over 500 us: %d\n", 1e6 * s.mean,
                1e6 * s.p999, 1e6 * s.max, s.over_period, s.over_500us);
    std::printf("    rigid (same points, no tissue): mean %.2f us, p99.9 %.2f us, max %.2f us\n", 1e6 * rs.mean,
                1e6 * rs.p999, 1e6 * rs.max);
  }
  return 0;
}
