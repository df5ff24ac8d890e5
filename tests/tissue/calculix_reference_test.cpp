// The tissue model's full static solve against an independent finite-element program: CalculiX
// (ccx, Debian's calculix-ccx), given the same lattice as 8-node bricks, the same materials,
// anchors and nodal loads. Where the two bricks are the same element (Poisson's ratio 0: only the
// shear part, 2 x 2 x 2 Gauss points in both), the displacements must agree to the digits ccx
// prints (7 significant), not merely within a discretisation error: a wrong sign, a swapped
// corner, a mis-assembled entry shows at once. With the gel's own near-incompressibility, ours
// (selective reduced integration) is held against CalculiX's incompatible-mode brick C3D8I.
//
// The case: a gel block (the "gel" preset) on a rigid base (its bottom nodes held), with a box of
// the stiffer "gel inclusion" preset inside, pressed by a square patch of nodal forces on its top,
// once over the inclusion and once beside it (two load cases, one ccx run): the force-indentation
// stiffness over the inclusion against beside it is the factor the reference gives.
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iostream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "vh/tissue/fem_model.h"
#include "vh/tissue/static_solver.h"

namespace vh::tissue {
namespace {

namespace fs = std::filesystem;

constexpr double kSpacing_m = 1e-3;
const Eigen::Vector3i kCells(14, 12, 7);
// The inclusion's cells: i 3..6, j 4..7, k 2..5 (4 x 4 x 4 mm, its top 1 mm under the surface).
bool inInclusion(int i, int j, int k) { return i >= 3 && i <= 6 && j >= 4 && j <= 7 && k >= 2 && k <= 5; }

HexLattice gelBlock() {
  LatticeGeometry g;
  g.origin_W_m = Eigen::Vector3d(0.002, -0.001, 0.0005);
  g.spacing_m = kSpacing_m;
  g.cells = kCells;
  std::vector<int> material(static_cast<std::size_t>(g.cellCount()));
  for (int k = 0; k < kCells.z(); ++k)
    for (int j = 0; j < kCells.y(); ++j)
      for (int i = 0; i < kCells.x(); ++i)
        material[static_cast<std::size_t>(i + kCells.x() * (j + kCells.y() * k))] = inInclusion(i, j, k) ? 1 : 0;
  return HexLattice(g, std::move(material));
}

/// Nodal forces: -total_N along z spread equally over the top nodes with i in [i0, i0 + 2] and
/// j in [j0, j0 + 2] (a 2 x 2 mm patch).
Eigen::VectorXd patchLoad(const HexLattice& L, int i0, int j0, double total_N) {
  Eigen::VectorXd f = Eigen::VectorXd::Zero(L.dofCount());
  for (int j = j0; j <= j0 + 2; ++j)
    for (int i = i0; i <= i0 + 2; ++i) f(3 * L.nodeAt(i, j, kCells.z()) + 2) = -total_N / 9.0;
  return f;
}

/// Runs ccx in `dir` on job.inp; @return the displacements of each load case (node count x 3
/// each, in node order), read from job.dat. Fails the test (and returns nothing) when ccx is
/// missing or its output cannot be read.
std::vector<Eigen::MatrixXd> runCalculix(const fs::path& dir, int nodes, int cases) {
  const std::string command = "cd '" + dir.string() + "' && ccx -i job > ccx.log 2>&1";
  const int rc = std::system(command.c_str());
  if (rc != 0) {
    ADD_FAILURE() << "ccx failed (rc " << rc << "; see " << (dir / "ccx.log").string()
                  << "): CalculiX is the independent reference of this test, Debian's calculix-ccx, which "
                     "packaging/setup.sh test installs";
    return {};
  }
  std::ifstream in(dir / "job.dat");
  std::vector<Eigen::MatrixXd> u;
  std::string line;
  while (std::getline(in, line)) {
    if (line.find("displacements") == std::string::npos) continue;
    Eigen::MatrixXd m = Eigen::MatrixXd::Constant(nodes, 3, std::nan(""));
    int read = 0;
    while (read < nodes && std::getline(in, line)) {
      std::istringstream row(line);
      int id = 0;
      double x = 0, y = 0, z = 0;
      if (!(row >> id >> x >> y >> z)) continue;  // the blank line after the heading
      if (id < 1 || id > nodes) break;
      m.row(id - 1) << x, y, z;
      ++read;
    }
    u.push_back(m);
  }
  EXPECT_EQ(static_cast<int>(u.size()), cases) << "load cases read from " << (dir / "job.dat").string();
  return u;
}

/// The gel block with `materials` (gel, inclusion), its base anchored, and the two patch loads.
struct GelBlockCase {
  std::vector<Material> materials;
  FemModel model;
  std::vector<int> anchored;
  std::array<Eigen::VectorXd, 2> loads;
  static constexpr double kForce_N = 0.05;

  explicit GelBlockCase(std::vector<Material> m) : materials(m), model(gelBlock(), std::move(m)) {
    const HexLattice& L = model.lattice();
    for (int n = 0; n < L.nodeCount(); ++n)
      if (L.nodeGrid(n).z() == 0)
        for (int c = 0; c < 3; ++c) anchored.push_back(3 * n + c);
    // Over the inclusion's centre (nodes i 4..6, j 5..7), and as far beside it along x.
    loads = {patchLoad(L, 4, 5, kForce_N), patchLoad(L, 10, 5, kForce_N)};
  }

  /// The same problem for ccx, in SI units, as CalculiX element `type` (C3D8, C3D8I), solved in
  /// `dir`: nodes 1.. in our order, the bricks' corners in CalculiX's order (the bottom face
  /// counter-clockwise seen from above, then the top face). @return each load case's displacements.
  std::vector<Eigen::MatrixXd> calculix(const fs::path& dir, const std::string& type) const {
    const HexLattice& L = model.lattice();
    fs::remove_all(dir);
    fs::create_directories(dir);
    {
      std::ofstream inp(dir / "job.inp");
      inp.precision(17);
      inp << "*NODE, NSET=NALL\n";
      for (int n = 0; n < L.nodeCount(); ++n) {
        const Eigen::Vector3d p = L.nodePosition_W(n);
        inp << n + 1 << ", " << p.x() << ", " << p.y() << ", " << p.z() << "\n";
      }
      for (int m = 0; m < 2; ++m) {
        inp << "*ELEMENT, TYPE=" << type << ", ELSET=E" << m << "\n";
        for (int e = 0; e < L.elementCount(); ++e) {
          if (L.elementMaterial(e) != m) continue;
          const std::array<int, 8>& c = L.elementNodes(e);  // corner a at (a & 1, a >> 1 & 1, a >> 2 & 1)
          inp << e + 1;
          for (const int a : {0, 1, 3, 2, 4, 5, 7, 6}) inp << ", " << c[static_cast<std::size_t>(a)] + 1;
          inp << "\n";
        }
      }
      for (int m = 0; m < 2; ++m)
        inp << "*MATERIAL, NAME=M" << m << "\n*ELASTIC\n"
            << materials[static_cast<std::size_t>(m)].youngs_modulus_Pa << ", "
            << materials[static_cast<std::size_t>(m)].poisson_ratio << "\n*SOLID SECTION, ELSET=E" << m
            << ", MATERIAL=M" << m << "\n";
      inp << "*NSET, NSET=BASE\n";
      for (int n = 0; n < L.nodeCount(); ++n)
        if (L.nodeGrid(n).z() == 0) inp << n + 1 << "\n";
      inp << "*BOUNDARY\nBASE, 1, 3\n";
      for (const Eigen::VectorXd& f : loads) {
        inp << "*STEP\n*STATIC\n*CLOAD, OP=NEW\n";
        for (int dof = 0; dof < f.size(); ++dof)
          if (f(dof) != 0.0) inp << dof / 3 + 1 << ", " << dof % 3 + 1 << ", " << f(dof) << "\n";
        inp << "*NODE PRINT, NSET=NALL\nU\n*END STEP\n";
      }
    }
    return runCalculix(dir, L.nodeCount(), 2);
  }

  /// The patch's stiffness [N/m]: the load over the patch's mean indentation under it.
  double patchStiffness_N_per_m(std::size_t c, const std::function<double(int)>& displacement) const {
    double indentation = 0.0;
    for (int dof = 0; dof < loads[c].size(); ++dof)
      if (loads[c](dof) != 0.0) indentation += -displacement(dof) / 9.0;
    return kForce_N / indentation;
  }
};

Material withoutVolumetricStiffness(Material m) {
  m.poisson_ratio = 0.0;  // lambda = 0
  return m;
}

const fs::path kOutputDir = fs::path(VH_TISSUE_TEST_OUTPUT_DIR) / "tissue-calculix";

TEST(TissueOracles, TheFullStaticSolveMatchesCalculixToItsPrintedDigitsWhereTheBrickIsTheSame) {
  // With Poisson's ratio 0 (lambda = 0) the element's volumetric part, which ours integrates at
  // one point (hex_element.h) and CalculiX's C3D8 at eight, vanishes: what is left, the shear
  // part, both integrate at 2 x 2 x 2 Gauss points, so the two solutions are the same field. Any
  // difference beyond ccx's 7 printed digits is a fault in the assembly, the corners, the loads,
  // the anchors or the solve.
  const GelBlockCase gel({withoutVolumetricStiffness(materialPreset("gel")),
                          withoutVolumetricStiffness(materialPreset("gel inclusion"))});
  const StaticSolver solver(gel.model, gel.anchored);
  const std::vector<Eigen::MatrixXd> reference = gel.calculix(kOutputDir / "nu0-C3D8", "C3D8");
  ASSERT_EQ(reference.size(), 2u);
  const HexLattice& L = gel.model.lattice();
  for (std::size_t c = 0; c < 2; ++c) {
    const Eigen::VectorXd u = solver.solve(gel.loads[c]);
    const Eigen::MatrixXd& ref = reference[c];
    ASSERT_TRUE(ref.allFinite()) << "case " << c << ": a node missing from job.dat";
    double worst = 0.0;
    for (int n = 0; n < L.nodeCount(); ++n)
      worst = std::max(worst, (Eigen::Vector3d(u.segment<3>(3 * n)) - Eigen::Vector3d(ref.row(n).transpose())).norm());
    const double largest = ref.rowwise().norm().maxCoeff();
    std::printf("nu 0, %s: largest displacement %.6e m (ccx), worst node difference %.3e m (%.2e of it)\n",
                c == 0 ? "over the inclusion" : "beside it", largest, worst, worst / largest);
    EXPECT_GT(largest, 1e-5) << "the load did nothing";
    EXPECT_LT(worst, 1e-5 * largest) << "case " << c;
  }
}

TEST(TissueOracles, TheGelsInclusionStiffensThePatchAsCalculixsIncompatibleModeBrickSays) {
  // The gel presets themselves (nearly incompressible). Ours integrates the volumetric part at
  // one point to keep it from locking; CalculiX's C3D8I (incompatible modes, another cure for the
  // same locking) is the reference: the patch's stiffness within 5 %, the inclusion's stiffening
  // factor within 3 %. CalculiX's fully integrated C3D8 locks: ours must come out softer than it.
  const GelBlockCase gel({materialPreset("gel"), materialPreset("gel inclusion")});
  const StaticSolver solver(gel.model, gel.anchored);
  const std::vector<Eigen::MatrixXd> incompatible = gel.calculix(kOutputDir / "gel-C3D8I", "C3D8I");
  const std::vector<Eigen::MatrixXd> locking = gel.calculix(kOutputDir / "gel-C3D8", "C3D8");
  ASSERT_EQ(incompatible.size(), 2u);
  ASSERT_EQ(locking.size(), 2u);
  std::array<double, 2> ours{}, theirs{};
  for (std::size_t c = 0; c < 2; ++c) {
    const Eigen::VectorXd u = solver.solve(gel.loads[c]);
    ours[c] = gel.patchStiffness_N_per_m(c, [&](int dof) { return u(dof); });
    theirs[c] = gel.patchStiffness_N_per_m(c, [&](int dof) { return incompatible[c](dof / 3, dof % 3); });
    const double locked = gel.patchStiffness_N_per_m(c, [&](int dof) { return locking[c](dof / 3, dof % 3); });
    std::printf("gel, %s: patch stiffness %.3f N/m here, %.3f by ccx C3D8I, %.3f by ccx C3D8 (full integration)\n",
                c == 0 ? "over the inclusion" : "beside it", ours[c], theirs[c], locked);
    EXPECT_NEAR(ours[c], theirs[c], 0.05 * theirs[c]) << "case " << c;
    EXPECT_LT(ours[c], locked) << "case " << c << ": no softer than the locking brick";
  }
  const double factor = ours[0] / ours[1], reference_factor = theirs[0] / theirs[1];
  std::printf("the patch over the inclusion is %.3f times as stiff as beside it (ccx C3D8I: %.3f)\n", factor,
              reference_factor);
  EXPECT_NEAR(factor, reference_factor, 0.03 * reference_factor);
  EXPECT_GT(factor, 1.2) << "the inclusion, 4 x 4 x 4 mm and 1 mm under the patch, is not felt";
}

}  // namespace
}  // namespace vh::tissue
