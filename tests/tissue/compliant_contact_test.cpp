// Tissue cut from a scan (a gel block on a bone plate, with a stiffer inclusion), and the
// servo-rate contact against it checked with the full static solve, which the servo path never
// calls: after every tick of a sphere pressed into the gel, no sample point of the deformed
// surface is inside the sphere (0 crossings) and the touching ones sit on it.
#include <cmath>
#include <limits>
#include <array>
#include <cstdio>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include "allocation_guard.h"

#include "vh/tissue/compliant_contact.h"
#include "vh/tissue/deformed_field.h"
#include "vh/tissue/hex_element.h"
#include "vh/tissue/static_solver.h"
#include "vh/tissue/surface_compliance.h"
#include "vh/tissue/tissue_region.h"

namespace vh::tissue {
namespace {

// The scan: 40 x 40 x 30 voxels of 0.5 mm. Bone below z = 1 mm (k < 2), gel up to z = 12 mm
// (k < 24), air above; a sphere of radius 3 mm of inclusion centred at (6, 10, 8) mm.
constexpr double kVoxel = 0.5e-3;
constexpr int kTopVoxel = 23;  // last gel layer
const Eigen::Vector3d kInclusionCentre(6e-3, 10e-3, 8e-3);

RegionSpec gelSpec(double cell_m) {
  RegionSpec spec;
  spec.cell_size_m = cell_m;
  spec.material_of_voxel = [](int i, int j, int k) {
    if (k < 2 || k > kTopVoxel) return -1;
    const Eigen::Vector3d p = kVoxel * Eigen::Vector3d(i, j, k);
    return (p - kInclusionCentre).norm() < 3e-3 ? 1 : 0;
  };
  spec.is_rigid_voxel = [](int, int, int k) { return k < 2; };
  spec.hold_at_scan_border = false;
  return spec;
}

VoxelGrid gelGrid() {
  VoxelGrid g;
  g.dims = Eigen::Vector3i(40, 40, 30);
  g.spacing_m = Eigen::Vector3d::Constant(kVoxel);
  return g;
}

std::vector<Material> gelMaterials() { return {materialPreset("gel"), materialPreset("gel inclusion")}; }

TEST(TissueRegion, CutFromTheScanWithItsInclusionAndHeldOnTheBone) {
  const TissueRegion region = buildTissueRegion(gelGrid(), gelSpec(2e-3), gelMaterials());
  const HexLattice& L = region.model.lattice();
  EXPECT_EQ(region.tissue_voxels, 40 * 40 * 22);
  EXPECT_EQ(L.geometry().cells, Eigen::Vector3i(10, 10, 8));
  int inclusion_cells = 0;
  for (int e = 0; e < L.elementCount(); ++e) inclusion_cells += L.elementMaterial(e) == 1;
  EXPECT_GT(inclusion_cells, 0) << "the inclusion is lost";
  EXPECT_LT(inclusion_cells, 27);
  // Held: exactly the nodes of the cells that hold bone voxels (the lowest cell layer: voxels k = 2, 3 are gel in it).
  for (const int dof : region.fixed_dofs) EXPECT_LE(L.nodeGrid(dof / 3).z(), 1);
  EXPECT_FALSE(region.fixed_dofs.empty());
  // Without the bone and the border the region floats: refused with the reason.
  RegionSpec floating = gelSpec(2e-3);
  floating.is_rigid_voxel = nullptr;
  try {
    (void)buildTissueRegion(gelGrid(), floating, gelMaterials());
    FAIL() << "a floating region was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("float"), std::string::npos) << e.what();
  }
  EXPECT_THROW(buildTissueRegion(gelGrid(), gelSpec(0.2e-3), gelMaterials()), std::invalid_argument) << "cell below a voxel";
}

/// The top surface of the gel (z = top) and a sphere of radius R centred at (x, y, top + R - depth).
struct Press {
  const TissueRegion& region;
  const StaticSolver& solver;
  SurfaceCompliance compliance;
  CompliantContact contact;
  double top_m;

  Press(const TissueRegion& r, const StaticSolver& s)
      : region(r), solver(s), compliance(s, outerLayerNodes(r.model.lattice()), 2),
        contact(r.model.lattice(), compliance, 256), top_m(kVoxel * (kTopVoxel + 0.5)) {}

  /// Sample points of the rest top surface within `radius` of (x, y), every `step`.
  std::vector<Eigen::Vector3d> surfaceSamples(const Eigen::Vector2d& xy, double radius, double step) const {
    std::vector<Eigen::Vector3d> out;
    for (double dx = -radius; dx <= radius; dx += step)
      for (double dy = -radius; dy <= radius; dy += step)
        if (dx * dx + dy * dy <= radius * radius) out.emplace_back(xy.x() + dx, xy.y() + dy, top_m);
    return out;
  }
  static double sphereBottom(const Eigen::Vector3d& centre, double R, const Eigen::Vector2d& xy) {
    const double r2 = (xy - centre.head<2>()).squaredNorm();
    return r2 >= R * R ? 1e9 : centre.z() - std::sqrt(R * R - r2);
  }
};

/// u(X) on the full solve's field, interpolated in X's cell.
Eigen::Vector3d displacementAt(const HexLattice& L, const Eigen::VectorXd& u, const Eigen::Vector3d& X) {
  return DeformedField(L, u).displacementAt(X);
}

TEST(TissueCompliantContact, ASpherePressedTickByTickNeverCrossesTheDeformedSurfaceByTheFullSolve) {
  const TissueRegion region = buildTissueRegion(gelGrid(), gelSpec(2e-3), gelMaterials());
  const StaticSolver solver(region.model, region.fixed_dofs);
  Press press(region, solver);
  const HexLattice& L = region.model.lattice();
  const double R = 3e-3, k = 200.0;  // a 3 mm ball on a 200 N/m coupling
  const Eigen::Vector2d xy(13e-3, 12e-3);  // beside the inclusion
  // The tool's points: the ball's underside over 1.5 R, one per voxel (those within 0.5 mm of the
  // rest surface are the contact candidates); between them, 4 per voxel side, the surface's sag
  // into the ball is printed (the edge test's business for the rigid surface), not asserted.
  const std::vector<Eigen::Vector3d> tool_points = press.surfaceSamples(xy, 1.5 * R, kVoxel);
  const std::vector<Eigen::Vector3d> between = press.surfaceSamples(xy, R, 0.25 * kVoxel);
  double worst_crossing = 0.0, worst_active_gap = 0.0, previous_force = 0.0, worst_sag = 0.0;
  for (int tick = 1; tick <= 20; ++tick) {
    const double depth = 0.1e-3 * tick;  // the device goes 2 mm below the rest surface in 20 ticks
    const Eigen::Vector3d device(xy.x(), xy.y(), press.top_m + R - depth);
    std::vector<TissueContactPoint> contacts;
    for (const Eigen::Vector3d& X : tool_points) {
      const double gap = Press::sphereBottom(device, R, X.head<2>()) - X.z();
      if (gap < 0.5e-3) contacts.push_back({X, Eigen::Vector3d::UnitZ(), gap});
    }
    ASSERT_LE(contacts.size(), static_cast<std::size_t>(press.contact.capacity()));
    const CompliantContactResult r = press.contact.solve(contacts, k, 2000, 1e-12);
    ASSERT_EQ(r.rigid_points, 0);
    // The independent check: the full solve of the same forces, every dense sample of the deformed surface.
    const Eigen::VectorXd u = solver.solve(press.contact.nodalForces_N(contacts));
    const Eigen::Vector3d proxy = device + r.proxy_offset_m;
    for (const Eigen::Vector3d& X : between)
      worst_sag = std::min(worst_sag, Press::sphereBottom(proxy, R, X.head<2>()) - (X.z() + displacementAt(L, u, X).z()));
    for (const Eigen::Vector3d& X : tool_points) {
      // Small-strain contact, as Hertz's: the surface point keeps its rest x, y (its sideways
      // motion, second order in the slope, is not followed).
      const double below = Press::sphereBottom(proxy, R, X.head<2>()) - (X.z() + displacementAt(L, u, X).z());  // < 0: inside the ball
      worst_crossing = std::min(worst_crossing, below);
    }
    for (std::size_t i = 0; i < contacts.size(); ++i)
      if (press.contact.pushes_N()(static_cast<Eigen::Index>(i)) > 0.0) {
        const Eigen::Vector3d& X = contacts[i].X_G_m;
        worst_active_gap = std::max(worst_active_gap, Press::sphereBottom(proxy, R, X.head<2>()) - (X.z() + displacementAt(L, u, X).z()));
      }
    EXPECT_GE(r.force_on_device_N.z(), previous_force) << "tick " << tick << ": pressing deeper felt softer";
    previous_force = r.force_on_device_N.z();
    // Converged: many points share a cell's 8 nodes, so A is only semi-definite and the pushes
    // need not be unique, but the gaps after are; projected Gauss-Seidel reaches them.
    EXPECT_LT(r.max_violation_m, 1e-12) << "tick " << tick << " after " << r.sweeps << " sweeps";
  }
  std::printf("sphere R 3 mm, coupling 200 N/m, 2 mm into the gel: force %.4f N, deepest crossing %.3g m, "
              "largest gap of a pushed point %.3g m, deepest sag between the tool's points %.3g m\n", previous_force,
              worst_crossing, worst_active_gap, worst_sag);
  EXPECT_GT(previous_force, 0.0);
  EXPECT_GE(worst_crossing, -1e-8) << "the deformed surface went into the ball";
  EXPECT_LT(worst_active_gap, 1e-8) << "a pushed point does not touch the ball";
}

// The servo path allocates nothing and never throws or returns a non-finite force, whatever it is
// given: a stiff coupling, a device 10 cm inside, zero or non-finite normals, more contacts than
// its capacity, points off the lattice.
TEST(TissueCompliantContact, NoAllocationAndFiniteAnswersOnStiffAndExtremeInput) {
  const TissueRegion region = buildTissueRegion(gelGrid(), gelSpec(2e-3), gelMaterials());
  const StaticSolver solver(region.model, region.fixed_dofs);
  Press press(region, solver);
  const Eigen::Vector2d xy(13e-3, 12e-3);
  std::vector<TissueContactPoint> deep, odd, many, off;
  for (const Eigen::Vector3d& X : press.surfaceSamples(xy, 3e-3, kVoxel)) {
    deep.push_back({X, Eigen::Vector3d::UnitZ(), -0.1, 0.0});
    odd.push_back({X, Eigen::Vector3d::Zero(), -1e-3, 0.0});
  }
  for (const Eigen::Vector3d& X : press.surfaceSamples(xy, 6e-3, 0.25 * kVoxel)) many.push_back({X, Eigen::Vector3d::UnitZ(), -1e-3, 0.0});
  ASSERT_GT(many.size(), static_cast<std::size_t>(press.contact.capacity()));
  off.push_back({Eigen::Vector3d(1.0, 1.0, 1.0), Eigen::Vector3d::UnitZ(), -1e-3, 0.0});
  std::vector<TissueContactPoint> bad = deep;
  bad[0].gap_m = std::nan("");
  std::vector<TissueContactPoint> infinite_guess = deep;
  infinite_guess[1].push_guess_N = std::numeric_limits<double>::infinity();

  struct Case {
    const char* what;
    const std::vector<TissueContactPoint>* contacts;
    double k;
  };
  const Case cases[] = {{"a 10 cm push on a 1e6 N/m coupling", &deep, 1e6},   {"zero normals", &odd, 1e3},
                        {"more contacts than the capacity", &many, 1e3},       {"a point off the lattice", &off, 1e3},
                        {"a NaN gap", &bad, 1e3},                               {"an infinite guess", &infinite_guess, 1e3},
                        {"a zero coupling", &deep, 0.0},                        {"a NaN coupling", &deep, std::nan("")}};
  for (const Case& c : cases) {
    CompliantContactResult r;
    {
      const test::AllocationGuard guard;
      r = press.contact.solve(*c.contacts, c.k, 50, 1e-9);
      EXPECT_EQ(guard.count(), 0u) << c.what;
    }
    EXPECT_TRUE(r.force_on_device_N.allFinite()) << c.what;
    EXPECT_TRUE(r.proxy_offset_m.allFinite()) << c.what;
    EXPECT_LE(r.contacts, press.contact.capacity()) << c.what;
  }
  // The stiff push: the tissue cannot give 10 cm, so the proxy stays out and the force is what
  // the coupling's stretch says, at most k times the push.
  const CompliantContactResult stiff = press.contact.solve(deep, 1e6, 200, 1e-9);
  EXPECT_GT(stiff.force_on_device_N.z(), 0.0);
  EXPECT_LE(stiff.force_on_device_N.z(), 1e6 * 0.1 * (1.0 + 1e-9));
  // Off the lattice: rigid, said.
  EXPECT_EQ(press.contact.solve(off, 1e3).rigid_points, 1);
}

// The inclusion is felt: the force-indentation curve of the ball is steeper over the inclusion
// than beside it, by the factor the full static solve of the same lattice gives (there, the
// tissue's compliance at the tool's points is built from full solves, one per point, not from the
// condensed table, and the contact problem is solved to convergence).
TEST(TissueCompliantContact, TheInclusionIsFeltSteeperByTheFactorOfTheFullSolve) {
  const TissueRegion region = buildTissueRegion(gelGrid(), gelSpec(2e-3), gelMaterials());
  const StaticSolver solver(region.model, region.fixed_dofs);
  Press press(region, solver);
  const HexLattice& L = region.model.lattice();
  const double R = 2e-3, k = 1e4, depth = 0.6e-3;
  const auto slope = [&](const Eigen::Vector2d& xy, bool full) {
    // Force at two depths; the slope between them [N/m].
    double force[2] = {0.0, 0.0};
    for (int level = 0; level < 2; ++level) {
      const double d = depth * (level + 1) / 2.0;
      const Eigen::Vector3d device(xy.x(), xy.y(), press.top_m + R - d);
      std::vector<TissueContactPoint> contacts;
      for (const Eigen::Vector3d& X : press.surfaceSamples(xy, R, kVoxel)) {
        const double gap = Press::sphereBottom(device, R, X.head<2>()) - X.z();
        if (gap < 0.3e-3) contacts.push_back({X, Eigen::Vector3d::UnitZ(), gap});
      }
      if (!full) {
        force[level] = press.contact.solve(contacts, k, 5000, 1e-13).force_on_device_N.z();
        continue;
      }
      // Reference: A from full solves of each point's unit push.
      const auto m = static_cast<Eigen::Index>(contacts.size());
      Eigen::MatrixXd response(region.model.dofCount(), m);
      std::vector<std::array<std::pair<int, double>, 8>> weights(contacts.size());
      for (Eigen::Index i = 0; i < m; ++i) {
        const HexLattice::Location at = L.locate(contacts[static_cast<std::size_t>(i)].X_G_m);
        const Eigen::Matrix<double, 8, 1> N = hexShapeFunctions(at.xi);
        Eigen::VectorXd f = Eigen::VectorXd::Zero(region.model.dofCount());
        for (int a = 0; a < 8; ++a) {
          const int node = L.elementNodes(at.element)[static_cast<std::size_t>(a)];
          weights[static_cast<std::size_t>(i)][static_cast<std::size_t>(a)] = {node, N(a)};
          f(3 * node + 2) = N(a);
        }
        response.col(i) = solver.solve(f);
      }
      Eigen::MatrixXd A(m, m);
      for (Eigen::Index i = 0; i < m; ++i)
        for (Eigen::Index j = 0; j < m; ++j) {
          double w = 0.0;
          for (const auto& [node, N] : weights[static_cast<std::size_t>(i)]) w += N * response(3 * node + 2, j);
          A(i, j) = w + 1.0 / k;
        }
      A = 0.5 * (A + A.transpose());
      Eigen::VectorXd lambda = Eigen::VectorXd::Zero(m);
      for (int sweep = 0; sweep < 20000; ++sweep)
        for (Eigen::Index i = 0; i < m; ++i)
          lambda(i) = std::max(0.0, lambda(i) - (A.row(i).dot(lambda) + contacts[static_cast<std::size_t>(i)].gap_m) / A(i, i));
      force[level] = lambda.sum();
    }
    return (force[1] - force[0]) / (0.5 * depth);
  };
  const Eigen::Vector2d over(kInclusionCentre.x(), kInclusionCentre.y()), beside(14e-3, 14e-3);
  const double fast_over = slope(over, false), fast_beside = slope(beside, false);
  const double full_over = slope(over, true), full_beside = slope(beside, true);
  std::printf("indentation slope with a 2 mm ball: over the inclusion %.2f N/m, beside it %.2f N/m (x%.3f); full "
              "solve %.2f and %.2f N/m (x%.3f)\n", fast_over, fast_beside, fast_over / fast_beside, full_over, full_beside,
              full_over / full_beside);
  EXPECT_GT(fast_over / fast_beside, 1.05) << "the inclusion is not felt";
  EXPECT_NEAR(fast_over / fast_beside, full_over / full_beside, 0.01 * full_over / full_beside);
}

}  // namespace
}  // namespace vh::tissue
