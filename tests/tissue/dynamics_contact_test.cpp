// Implicit dynamics (passivity: the tissue, let go, never gains energy and comes to rest within
// its damping) and the condensed frictionless contact solver against a brute-force reference
// (every active set tried).
#include <cmath>
#include <cstdio>
#include <random>
#include <vector>

#include <Eigen/Cholesky>

#include <gtest/gtest.h>

#include "vh/tissue/contact_lcp.h"
#include "vh/tissue/implicit_dynamics.h"
#include "vh/tissue/static_solver.h"

namespace vh::tissue {
namespace {

/// A liver slab 20 x 20 x 10 mm held at its bottom, h = 2 mm.
struct Slab {
  FemModel model{HexLattice::Box(Eigen::Vector3d(0.0, 0.0, -0.01), 0.002, Eigen::Vector3i(10, 10, 5)), {stiffest()}};
  std::vector<int> fixed = model.dofsOfNodes([](const Eigen::Vector3d& p) { return p.z() < -0.0099; });
  int centre_top = model.lattice().nodeAt(5, 5, 5);

  static Material stiffest() {
    // The stiffest preset (skin), so the step's stability is shown where it is hardest.
    Material m = materialPreset("skin");
    for (const Material& p : materialPresets())
      if (p.youngs_modulus_Pa > m.youngs_modulus_Pa) m = p;
    return m;
  }
};

TEST(TissueDynamics, ReleasedTissueNeverGainsEnergyAndComesToRestWithinItsDamping) {
  const Slab slab;
  ImplicitDynamics dynamics(slab.model, slab.fixed, 1e-3);  // the servo period
  Eigen::VectorXd push = Eigen::VectorXd::Zero(slab.model.dofCount());
  push(3 * slab.centre_top + 2) = -0.05;  // 50 mN down on the top centre
  // Held: settles onto the static answer.
  for (int k = 0; k < 1000; ++k) dynamics.step(push);
  const Eigen::VectorXd u_static = StaticSolver(slab.model, slab.fixed).solve(push);
  EXPECT_LT((dynamics.displacement_m() - u_static).norm(), 1e-3 * u_static.norm()) << "held, it did not settle";
  // Released: energy never grows, and falls to a millionth.
  const double e0 = dynamics.energy_J();
  ASSERT_GT(e0, 0.0);
  const Eigen::VectorXd zero = Eigen::VectorXd::Zero(slab.model.dofCount());
  double previous = e0;
  int steps_to_rest = -1;
  for (int k = 0; k < 5000 && (steps_to_rest < 0 || k < steps_to_rest + 500); ++k) {
    dynamics.step(zero);
    const double e = dynamics.energy_J();
    ASSERT_LE(e, previous * (1.0 + 1e-12)) << "energy grew at step " << k;
    previous = e;
    if (steps_to_rest < 0 && e < 1e-6 * e0) steps_to_rest = k + 1;
  }
  std::printf("released: energy %.3e J to a millionth in %d steps of 1 ms\n", e0, steps_to_rest);
  ASSERT_GT(steps_to_rest, 0) << "still moving after 5 s";
  // Without damping, backward Euler's own dissipation still makes it passive.
  Material m = slab.model.materials()[0];
  m.damping_stiffness_s = 0.0;
  m.damping_mass_per_s = 0.0;
  const FemModel no_damping(slab.model.lattice(), {m});
  ImplicitDynamics free(no_damping, slab.fixed, 1e-3);
  for (int k = 0; k < 50; ++k) free.step(push);
  double before = free.energy_J();
  for (int k = 0; k < 500; ++k) {
    free.step(zero);
    ASSERT_LE(free.energy_J(), before * (1.0 + 1e-12)) << "undamped energy grew at step " << k;
    before = free.energy_J();
  }
}

TEST(TissueDynamics, StableAtTheStiffestPresetForAnyTimeStep) {
  const Slab slab;
  for (const double dt : {1e-4, 1e-3, 1e-2, 0.1}) {
    ImplicitDynamics dynamics(slab.model, slab.fixed, dt);
    Eigen::VectorXd push = Eigen::VectorXd::Zero(slab.model.dofCount());
    push(3 * slab.centre_top + 2) = -0.05;
    for (int k = 0; k < 200; ++k) dynamics.step(push);
    EXPECT_TRUE(dynamics.displacement_m().allFinite()) << dt;
    EXPECT_LT(dynamics.displacement_m().cwiseAbs().maxCoeff(), 0.01) << "dt " << dt << ": the slab blew up";
  }
  EXPECT_THROW(ImplicitDynamics(slab.model, slab.fixed, 0.0), std::invalid_argument);
  EXPECT_THROW(ImplicitDynamics(slab.model, slab.fixed, std::nan("")), std::invalid_argument);
}

/// The reference: every subset as the set of pushed nodes, the first that satisfies all the
/// complementarity conditions (the solution is unique for C positive definite).
Eigen::VectorXd bruteForceContact(const Eigen::MatrixXd& C, const Eigen::VectorXd& delta) {
  const int m = static_cast<int>(delta.size());
  for (int mask = 0; mask < (1 << m); ++mask) {
    std::vector<int> idx;
    for (int i = 0; i < m; ++i)
      if (mask & (1 << i)) idx.push_back(i);
    Eigen::VectorXd f = Eigen::VectorXd::Zero(m);
    if (!idx.empty()) {
      const auto p = static_cast<Eigen::Index>(idx.size());
      Eigen::MatrixXd Cpp(p, p);
      Eigen::VectorXd dp(p);
      for (Eigen::Index a = 0; a < p; ++a) {
        dp(a) = delta(idx[static_cast<std::size_t>(a)]);
        for (Eigen::Index b = 0; b < p; ++b) Cpp(a, b) = C(idx[static_cast<std::size_t>(a)], idx[static_cast<std::size_t>(b)]);
      }
      const Eigen::VectorXd fp = Cpp.llt().solve(dp);
      for (Eigen::Index a = 0; a < p; ++a) f(idx[static_cast<std::size_t>(a)]) = fp(a);
    }
    const Eigen::VectorXd w = C * f - delta;
    if ((f.array() >= -1e-12).all() && (w.array() >= -1e-12).all()) return f;
  }
  return Eigen::VectorXd::Constant(m, std::nan(""));
}

TEST(TissueContact, ActiveSetSolverMatchesEveryActiveSetTried) {
  std::mt19937 rng(7);
  std::normal_distribution<double> normal(0.0, 1.0);
  for (int trial = 0; trial < 200; ++trial) {
    const int m = 1 + trial % 10;
    const Eigen::MatrixXd A = Eigen::MatrixXd::NullaryExpr(m, m, [&] { return normal(rng); });
    const Eigen::MatrixXd C = A * A.transpose() + 0.1 * Eigen::MatrixXd::Identity(m, m);
    const Eigen::VectorXd delta = Eigen::VectorXd::NullaryExpr(m, [&] { return normal(rng); });
    const ContactSolution s = solveFrictionlessContact(C, delta, 1e-13);
    const Eigen::VectorXd reference = bruteForceContact(C, delta);
    ASSERT_TRUE(s.converged) << "trial " << trial;
    EXPECT_LT((s.force_N - reference).cwiseAbs().maxCoeff(), 1e-9 * (1.0 + reference.cwiseAbs().maxCoeff())) << "trial " << trial;
    EXPECT_GE((s.displacement_m - delta).minCoeff(), -1e-10) << "a node left inside, trial " << trial;
  }
  EXPECT_THROW(solveFrictionlessContact(Eigen::MatrixXd::Identity(2, 2), Eigen::VectorXd::Zero(3)), std::invalid_argument);
  EXPECT_THROW(solveFrictionlessContact(Eigen::MatrixXd::Identity(1, 1), Eigen::VectorXd::Constant(1, std::nan(""))),
               std::invalid_argument);
}

}  // namespace
}  // namespace vh::tissue
