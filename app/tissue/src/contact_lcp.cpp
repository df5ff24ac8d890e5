#include "vh/tissue/contact_lcp.h"

#include <Eigen/Cholesky>

#include <stdexcept>
#include <vector>

namespace vh::tissue {
namespace {

/// z_P = C_PP^-1 delta_P, zero elsewhere.
Eigen::VectorXd solvePassive(const Eigen::MatrixXd& C, const Eigen::VectorXd& delta, const std::vector<bool>& passive) {
  std::vector<Eigen::Index> idx;
  for (Eigen::Index i = 0; i < delta.size(); ++i)
    if (passive[static_cast<std::size_t>(i)]) idx.push_back(i);
  const auto p = static_cast<Eigen::Index>(idx.size());
  Eigen::MatrixXd Cpp(p, p);
  Eigen::VectorXd dp(p);
  for (Eigen::Index a = 0; a < p; ++a) {
    dp(a) = delta(idx[static_cast<std::size_t>(a)]);
    for (Eigen::Index b = 0; b < p; ++b) Cpp(a, b) = C(idx[static_cast<std::size_t>(a)], idx[static_cast<std::size_t>(b)]);
  }
  const Eigen::VectorXd zp = Cpp.ldlt().solve(dp);
  Eigen::VectorXd z = Eigen::VectorXd::Zero(delta.size());
  for (Eigen::Index a = 0; a < p; ++a) z(idx[static_cast<std::size_t>(a)]) = zp(a);
  return z;
}

}  // namespace

ContactSolution solveFrictionlessContact(const Eigen::MatrixXd& C, const Eigen::VectorXd& delta, double tolerance_m) {
  const Eigen::Index m = delta.size();
  if (C.rows() != m || C.cols() != m) throw std::invalid_argument("contact: the compliance must be m x m for m nodes");
  if (!C.allFinite() || !delta.allFinite()) throw std::invalid_argument("contact: non-finite compliance or overlap");
  ContactSolution s;
  s.force_N = Eigen::VectorXd::Zero(m);
  std::vector<bool> passive(static_cast<std::size_t>(m), false);
  const int max_iterations = static_cast<int>(3 * m + 10);
  while (s.iterations < max_iterations) {
    // The gradient of 1/2 f^T C f - delta^T f is w = C f - delta; a node off the passive set
    // with w_i < 0 is still inside the body: push it.
    const Eigen::VectorXd w = C * s.force_N - delta;
    Eigen::Index j = -1;
    double most = -tolerance_m;
    for (Eigen::Index i = 0; i < m; ++i)
      if (!passive[static_cast<std::size_t>(i)] && w(i) < most) {
        most = w(i);
        j = i;
      }
    if (j < 0) {
      s.converged = true;
      break;
    }
    passive[static_cast<std::size_t>(j)] = true;
    ++s.iterations;
    // Inner loop: keep the passive set's forces positive.
    for (;;) {
      const Eigen::VectorXd z = solvePassive(C, delta, passive);
      bool feasible = true;
      for (Eigen::Index i = 0; i < m; ++i)
        if (passive[static_cast<std::size_t>(i)] && z(i) <= 0.0) feasible = false;
      if (feasible) {
        s.force_N = z;
        break;
      }
      double alpha = 1.0;
      for (Eigen::Index i = 0; i < m; ++i)
        if (passive[static_cast<std::size_t>(i)] && z(i) <= 0.0) {
          const double denom = s.force_N(i) - z(i);
          if (denom > 0.0) alpha = std::min(alpha, s.force_N(i) / denom);
        }
      s.force_N += alpha * (z - s.force_N);
      for (Eigen::Index i = 0; i < m; ++i)
        if (passive[static_cast<std::size_t>(i)] && s.force_N(i) <= 1e-15 * (1.0 + s.force_N.cwiseAbs().maxCoeff())) {
          passive[static_cast<std::size_t>(i)] = false;
          s.force_N(i) = 0.0;
        }
      ++s.iterations;
      if (s.iterations >= max_iterations) break;
    }
  }
  s.force_N = s.force_N.cwiseMax(0.0);
  s.displacement_m = C * s.force_N;
  return s;
}

}  // namespace vh::tissue
