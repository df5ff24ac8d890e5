// The reference a sphere pressed into tissue is checked against (tests and the tissue reports):
// the exact frictionless contact on the region's lattice from the full static solve, which the
// servo path never uses.
#pragma once

#include <cmath>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "vh/tissue/contact_lcp.h"
#include "vh/tissue/hex_element.h"
#include "vh/tissue/static_solver.h"
#include "vh/tissue/tissue_region.h"

namespace vh::tissue {

/// The exact frictionless contact of a rigid sphere (radius R, lowest point d below the rest
/// top surface z = top_m, frame G, at (x, y)) with the lattice, from the full static solve: the rest surface sampled
/// every 0.25 mm within 0.9 R, each sample's vertical compliance interpolated from the corner
/// nodes' (StaticSolver::compliance), the LCP solved by Lawson-Hanson. Returns the total force [N].
inline double sphereContactForce_N(const TissueRegion& region, const StaticSolver& solver, double R, double d,
                                   const Eigen::Vector2d& xy, double top_m) {
  const HexLattice& L = region.model.lattice();
  std::vector<Eigen::Vector3d> samples;
  for (double dx = -0.9 * R; dx <= 0.9 * R; dx += 0.25e-3)
    for (double dy = -0.9 * R; dy <= 0.9 * R; dy += 0.25e-3)
      if (dx * dx + dy * dy <= 0.81 * R * R) samples.emplace_back(xy.x() + dx, xy.y() + dy, top_m);
  // The corner nodes' z dofs (free ones) and each sample's weights on them.
  std::vector<int> dofs, slot(static_cast<std::size_t>(L.dofCount()), -1);
  std::vector<std::vector<std::pair<int, double>>> weights(samples.size());
  for (std::size_t s = 0; s < samples.size(); ++s) {
    const HexLattice::Location at = L.locate(samples[s]);
    if (at.element < 0) continue;
    const Eigen::Matrix<double, 8, 1> N = hexShapeFunctions(at.xi);
    for (int a = 0; a < 8; ++a) {
      const int dof = 3 * L.elementNodes(at.element)[static_cast<std::size_t>(a)] + 2;
      if (N(a) == 0.0 || solver.isFixed(dof)) continue;
      if (slot[static_cast<std::size_t>(dof)] < 0) {
        slot[static_cast<std::size_t>(dof)] = static_cast<int>(dofs.size());
        dofs.push_back(dof);
      }
      weights[s].emplace_back(slot[static_cast<std::size_t>(dof)], N(a));
    }
  }
  const Eigen::MatrixXd Cn = solver.compliance(dofs);
  const auto m = static_cast<Eigen::Index>(samples.size());
  Eigen::MatrixXd P = Eigen::MatrixXd::Zero(m, static_cast<Eigen::Index>(dofs.size()));
  Eigen::VectorXd delta(m);
  for (Eigen::Index s = 0; s < m; ++s) {
    for (const auto& [col, w] : weights[static_cast<std::size_t>(s)]) P(s, col) = w;
    const double r2 = (samples[static_cast<std::size_t>(s)].head<2>() - xy).squaredNorm();
    delta(s) = d - (R - std::sqrt(R * R - r2));  // how far the sample must go down to clear the sphere
  }
  const Eigen::MatrixXd C = P * Cn * P.transpose() + 1e-15 * Eigen::MatrixXd::Identity(m, m);
  const ContactSolution sol = solveFrictionlessContact(C, delta, 1e-12);
  return sol.force_N.sum();
}

}  // namespace vh::tissue
