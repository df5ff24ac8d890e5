#pragma once
/// @file
/// Frictionless unilateral contact of m tissue nodes against a rigid body, condensed onto those
/// nodes: with C (m x m) [m/N] the compliance of each node along its contact direction (from
/// StaticSolver::compliance) and delta (m) [m] how far each node must move along that direction
/// to clear the body (> 0 where the body's rest position overlaps the node), find the pushes
/// f (m) [N] with
///     f >= 0,   w = C f - delta >= 0,   f_i w_i = 0
/// (a linear complementarity problem: a node is pushed only where it touches, and nothing ends
/// inside the body). With C symmetric positive definite it is the convex quadratic programme
/// min 1/2 f^T C f - delta^T f over f >= 0, solved exactly by the Lawson-Hanson active-set method
/// (Lawson and Hanson 1974, "Solving Least Squares Problems", ch. 23), finite in exact arithmetic.
#include <Eigen/Core>

namespace vh::tissue {

struct ContactSolution {
  Eigen::VectorXd force_N;         ///< f (m) [N], >= 0.
  Eigen::VectorXd displacement_m;  ///< C f (m) [m], each node's move along its contact direction.
  int iterations = 0;              ///< Active-set changes made.
  bool converged = false;          ///< False only when the iteration cap was reached.
};

/// @param tolerance_m how far a node may stay inside the body (w_i >= -tolerance) at the answer.
/// @throws std::invalid_argument on a size mismatch, a non-square C or non-finite input.
ContactSolution solveFrictionlessContact(const Eigen::MatrixXd& compliance_m_per_N, const Eigen::VectorXd& delta_m,
                                         double tolerance_m = 1e-12);

}  // namespace vh::tissue
