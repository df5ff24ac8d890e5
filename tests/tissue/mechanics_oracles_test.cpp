// The tissue model against mechanics, not against itself:
//   - Euler-Bernoulli: a slender cantilever's tip deflection P L^3 / (3 E I) and its first bending
//     frequency 1.8751^2 sqrt(E I / (rho A L^4));
//   - Hertz: a rigid sphere pressed into a block many times the contact's size,
//     F = 4/3 E / (1 - nu^2) sqrt(R) d^1.5, within 10 % for d <= 0.1 R and closer on a finer lattice;
//   - the modal model against the full static solve, error per number of modes.
// Each prints its figures (the table of docs/feeling.md).
#include <cmath>
#include <cstdio>
#include <vector>

#include <gtest/gtest.h>

#include "vh/tissue/contact_lcp.h"
#include "vh/tissue/fem_model.h"
#include "vh/tissue/modal_basis.h"
#include "vh/tissue/static_solver.h"

namespace vh::tissue {
namespace {

// ---- Cantilever -----------------------------------------------------------------------------

struct Cantilever {
  double length_m, side_m, spacing_m;
  Material material;
  FemModel model;
  std::vector<int> clamped;

  Cantilever(double length, double side, double h, Material m)
      : length_m(length), side_m(side), spacing_m(h), material(m),
        model(HexLattice::Box(Eigen::Vector3d::Zero(), h,
                              Eigen::Vector3i(static_cast<int>(std::lround(length / h)), static_cast<int>(std::lround(side / h)),
                                              static_cast<int>(std::lround(side / h)))),
              {m}) {
    for (int n = 0; n < model.lattice().nodeCount(); ++n)
      if (model.lattice().nodeGrid(n).x() == 0)
        for (int c = 0; c < 3; ++c) clamped.push_back(3 * n + c);
  }
  /// Tip load P [N] along -z spread over the tip face as a uniform traction (consistent weights).
  Eigen::VectorXd tipLoad(double P_N) const {
    const HexLattice& L = model.lattice();
    const Eigen::Vector3i cells = L.geometry().cells;
    Eigen::VectorXd f = Eigen::VectorXd::Zero(model.dofCount());
    const double per_cell = P_N / (cells.y() * cells.z());
    for (int n = 0; n < L.nodeCount(); ++n) {
      const Eigen::Vector3i g = L.nodeGrid(n);
      if (g.x() != cells.x()) continue;
      const double wy = (g.y() == 0 || g.y() == cells.y()) ? 0.5 : 1.0;
      const double wz = (g.z() == 0 || g.z() == cells.z()) ? 0.5 : 1.0;
      f(3 * n + 2) = -per_cell * wy * wz;
    }
    return f;
  }
  /// Mean u_z of the tip face [m].
  double tipDeflection(const Eigen::VectorXd& u) const {
    double sum = 0.0;
    int count = 0;
    for (int n = 0; n < model.lattice().nodeCount(); ++n)
      if (model.lattice().nodeGrid(n).x() == model.lattice().geometry().cells.x()) {
        sum += u(3 * n + 2);
        ++count;
      }
    return sum / count;
  }
  double secondMoment_m4() const { return std::pow(side_m, 4) / 12.0; }
};

TEST(TissueOracles, CantileverTipDeflectionWithinFivePercentOfEulerBernoulli) {
  std::printf("cantilever (L = 60 mm, 6 mm square, h = 1 mm, tip load 1 mN): tip deflection against P L^3 / (3 E I)\n");
  for (const double nu : {0.3, 0.45, 0.49}) {
    Material m = materialPreset("muscle");
    m.poisson_ratio = nu;
    const Cantilever bar(0.06, 0.006, 0.001, m);
    const double P = 1e-3;
    const Eigen::VectorXd u = StaticSolver(bar.model, bar.clamped).solve(bar.tipLoad(P));
    const double fem = -bar.tipDeflection(u);
    const double euler_bernoulli = P * std::pow(bar.length_m, 3) / (3.0 * m.youngs_modulus_Pa * bar.secondMoment_m4());
    const double error = fem / euler_bernoulli - 1.0;
    std::printf("  nu %.2f: FEM %.4f mm, Euler-Bernoulli %.4f mm, error %+.2f %%\n", nu, fem * 1e3, euler_bernoulli * 1e3,
                100.0 * error);
    EXPECT_LT(std::abs(error), 0.05) << "nu " << nu << ": FEM " << fem << " m against " << euler_bernoulli << " m";
  }
}

TEST(TissueOracles, CantileverFirstBendingFrequencyMatchesEulerBernoulli) {
  const Material m = materialPreset("muscle");
  const Cantilever bar(0.06, 0.006, 0.001, m);
  const StaticSolver solver(bar.model, bar.clamped);
  const ModalBasis modes(bar.model, solver, 4);
  const double area = bar.side_m * bar.side_m;
  const double beta1 = 1.875104068711961;
  const double omega1 = beta1 * beta1 * std::sqrt(m.youngs_modulus_Pa * bar.secondMoment_m4() /
                                                  (m.density_kg_per_m3 * area * std::pow(bar.length_m, 4)));
  // The square section bends alike about y and z: the two lowest modes share the frequency.
  const double fem0 = std::sqrt(modes.eigenvalues_per_s2()(0)), fem1 = std::sqrt(modes.eigenvalues_per_s2()(1));
  std::printf("cantilever first bending frequency: FEM %.3f and %.3f Hz, Euler-Bernoulli %.3f Hz\n", fem0 / (2 * M_PI),
              fem1 / (2 * M_PI), omega1 / (2 * M_PI));
  EXPECT_NEAR(fem0 / omega1, 1.0, 0.05);
  EXPECT_NEAR(fem1 / omega1, 1.0, 0.05);
  // Mass-normalised: Phi^T M Phi = I.
  const Eigen::MatrixXd gram = modes.modes().transpose() * bar.model.lumpedMass_kg().asDiagonal() * modes.modes();
  EXPECT_LT((gram - Eigen::MatrixXd::Identity(4, 4)).cwiseAbs().maxCoeff(), 1e-8);
}

// ---- Hertz ----------------------------------------------------------------------------------

struct HertzResult {
  double force_N = 0.0;        ///< Total force on the sphere (4 quarters).
  double hertz_N = 0.0;        ///< 4/3 E* sqrt(R) d^1.5.
  double max_overlap_m = 0.0;  ///< Deepest node inside the sphere after the solve (should be ~0).
  int contact_nodes = 0;
};

/// A quarter of a block (x, y in [0, W], z in [-D, 0]) under a rigid sphere of radius R centred
/// on the z axis, pressed d deep: symmetry planes x = 0 and y = 0 (normal displacement held),
/// the bottom held, the outer sides free. The lattice has R / h = cells_per_radius.
class HertzBlock {
 public:
  HertzBlock(double radius_m, int cells_per_radius, double block_in_radii, const Material& m)
      : R_(radius_m), h_(radius_m / cells_per_radius), material_(m),
        model_(HexLattice::Box(Eigen::Vector3d(0.0, 0.0, -block_in_radii * radius_m), h_,
                               Eigen::Vector3i::Constant(static_cast<int>(std::lround(block_in_radii * cells_per_radius)))),
               {m}),
        solver_(model_, fixedDofs()) {
    const HexLattice& L = model_.lattice();
    const int top = L.geometry().cells.z();
    for (int n = 0; n < L.nodeCount(); ++n) {
      const Eigen::Vector3d p = L.nodePosition_W(n);
      if (L.nodeGrid(n).z() == top && p.head<2>().norm() < 0.6 * R_) top_nodes_.push_back(n);
    }
    std::vector<int> dofs;
    for (const int n : top_nodes_) dofs.push_back(3 * n + 2);
    compliance_ = solver_.compliance(dofs);
  }

  HertzResult press(double d_m) const {
    const HexLattice& L = model_.lattice();
    Eigen::VectorXd delta(static_cast<Eigen::Index>(top_nodes_.size()));
    for (std::size_t i = 0; i < top_nodes_.size(); ++i) {
      const double r = L.nodePosition_W(top_nodes_[i]).head<2>().norm();
      delta(static_cast<Eigen::Index>(i)) = d_m - (R_ - std::sqrt(R_ * R_ - r * r));
    }
    const ContactSolution s = solveFrictionlessContact(compliance_, delta, 1e-12 * R_);
    HertzResult out;
    out.force_N = 4.0 * s.force_N.sum();
    out.hertz_N = 4.0 / 3.0 * material_.contactModulus_Pa() * std::sqrt(R_) * std::pow(d_m, 1.5);
    out.contact_nodes = static_cast<int>((s.force_N.array() > 0.0).count());
    // Check on the full field, every top node (not only the candidates): none ends inside the
    // sphere in the linear theory's sense (the vertical gap at its rest radius, as Hertz's own).
    Eigen::VectorXd f = Eigen::VectorXd::Zero(model_.dofCount());
    for (std::size_t i = 0; i < top_nodes_.size(); ++i) f(3 * top_nodes_[i] + 2) = -s.force_N(static_cast<Eigen::Index>(i));
    const Eigen::VectorXd u = solver_.solve(f);
    const int top = L.geometry().cells.z();
    for (int n = 0; n < L.nodeCount(); ++n) {
      const double r = L.nodePosition_W(n).head<2>().norm();
      if (L.nodeGrid(n).z() != top || r >= R_) continue;
      const double needed = d_m - (R_ - std::sqrt(R_ * R_ - r * r));
      out.max_overlap_m = std::max(out.max_overlap_m, needed + u(3 * n + 2));
    }
    return out;
  }
  double spacing_m() const { return h_; }
  int nodeCount() const { return model_.lattice().nodeCount(); }

 private:
  std::vector<int> fixedDofs() const {
    std::vector<int> fixed;
    const HexLattice& L = model_.lattice();
    for (int n = 0; n < L.nodeCount(); ++n) {
      const Eigen::Vector3i g = L.nodeGrid(n);
      if (g.z() == 0) fixed.insert(fixed.end(), {3 * n, 3 * n + 1, 3 * n + 2});
      if (g.x() == 0) fixed.push_back(3 * n);
      if (g.y() == 0) fixed.push_back(3 * n + 1);
    }
    return fixed;
  }
  double R_, h_;
  Material material_;
  FemModel model_;
  StaticSolver solver_;
  std::vector<int> top_nodes_;
  Eigen::MatrixXd compliance_;
};

TEST(TissueOracles, HertzSphereIndentationWithinTenPercentAndCloserOnAFinerLattice) {
  const Material m = materialPreset("liver");
  const double R = 0.01;
  std::printf("Hertz: rigid sphere R = 10 mm into a liver block 3 R deep and wide (a quarter by symmetry)\n");
  std::printf("  R/h  nodes   d/R   FEM [mN]  Hertz [mN]  error    contact nodes  overlap [um]\n");
  std::vector<double> worst_error;
  for (const int cells_per_radius : {4, 5, 6}) {
    const HertzBlock block(R, cells_per_radius, 3.0, m);
    double worst = 0.0;
    for (const double d_over_R : {0.04, 0.07, 0.1}) {
      const HertzResult r = block.press(d_over_R * R);
      const double error = r.force_N / r.hertz_N - 1.0;
      worst = std::max(worst, std::abs(error));
      std::printf("  %3d  %6d  %.2f  %8.3f  %9.3f  %+6.2f %%  %4d  %12.4f\n", cells_per_radius, block.nodeCount(), d_over_R,
                  1e3 * r.force_N, 1e3 * r.hertz_N, 100.0 * error, r.contact_nodes, 1e6 * r.max_overlap_m);
      EXPECT_LT(r.max_overlap_m, 1e-9) << "a node ended inside the sphere";
    }
    worst_error.push_back(worst);
  }
  EXPECT_LT(worst_error.back(), 0.10) << "finest lattice";
  EXPECT_LT(worst_error.back(), worst_error.front()) << "the finer lattice is not closer to Hertz";
}

// ---- Modal model against the full solve ----------------------------------------------------

TEST(TissueOracles, ModalStaticResponseConvergesToTheFullSolveAsModesAreAdded) {
  const Cantilever bar(0.03, 0.006, 0.0015, materialPreset("liver"));
  const StaticSolver solver(bar.model, bar.clamped);
  const int modes = 60;
  const ModalBasis basis(bar.model, solver, modes);
  // A point load on the tip's top edge (not only the smooth bending mode).
  Eigen::VectorXd f = Eigen::VectorXd::Zero(bar.model.dofCount());
  const HexLattice& L = bar.model.lattice();
  const int tip = L.nodeAt(L.geometry().cells.x(), L.geometry().cells.y() / 2, L.geometry().cells.z());
  ASSERT_GE(tip, 0);
  f(3 * tip + 2) = -1e-3;
  f(3 * tip + 1) = 4e-4;
  const Eigen::VectorXd full = solver.solve(f);
  std::printf("modal static response against the full LDL^T solve (point load at the tip, %d dofs)\n", bar.model.dofCount());
  // The energy norm |e|_K = sqrt(e^T K e): the truncation error in it can only fall as modes are
  // added (the modes are K-orthogonal), whatever the load.
  const auto energyNorm = [&](const Eigen::VectorXd& e) { return std::sqrt(e.dot(bar.model.stiffness_N_per_m() * e)); };
  std::printf("  modes  error (energy norm)  error (2-norm)  error at the loaded node\n");
  double previous = 1e300, last_2norm = 1e300;
  for (const int r : {1, 5, 10, 20, 40, 60}) {
    const Eigen::VectorXd reduced = basis.staticResponse(f, r);
    const double error = energyNorm(reduced - full) / energyNorm(full);
    last_2norm = (reduced - full).norm() / full.norm();
    const double local = (reduced.segment<3>(3 * tip) - full.segment<3>(3 * tip)).norm() / full.segment<3>(3 * tip).norm();
    std::printf("  %5d  %19.4f  %14.4f  %23.4f\n", r, error, last_2norm, local);
    EXPECT_LE(error, previous + 1e-12) << r << " modes: adding modes made it worse";
    previous = error;
  }
  EXPECT_LT(last_2norm, 0.05) << "60 modes still far from the full solve";
}

}  // namespace
}  // namespace vh::tissue
