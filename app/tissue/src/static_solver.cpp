#include "vh/tissue/static_solver.h"

#include <stdexcept>
#include <string>

namespace vh::tissue {
namespace {

/// K restricted to the free dofs (rows and columns), lower triangle.
SparseMatrix freePart(const SparseMatrix& K, const std::vector<int>& free_index, int free_count) {
  std::vector<Eigen::Triplet<double>> entries;
  entries.reserve(static_cast<std::size_t>(K.nonZeros()) / 2 + static_cast<std::size_t>(free_count));
  for (int col = 0; col < K.outerSize(); ++col) {
    const int c = free_index[static_cast<std::size_t>(col)];
    if (c < 0) continue;
    for (SparseMatrix::InnerIterator it(K, col); it; ++it) {
      const int r = free_index[static_cast<std::size_t>(it.row())];
      if (r >= c) entries.emplace_back(r, c, it.value());
    }
  }
  SparseMatrix out(free_count, free_count);
  out.setFromTriplets(entries.begin(), entries.end());
  return out;
}

}  // namespace

StaticSolver::StaticSolver(const FemModel& model, const std::vector<int>& fixed_dofs) {
  FreeDofs dofs = freeDofs(model.dofCount(), fixed_dofs, "static solve");
  free_index_ = std::move(dofs.free_index);
  free_dofs_ = std::move(dofs.free);
  if (free_dofs_.empty()) throw std::invalid_argument("static solve: every dof is fixed");
  ldlt_.compute(freePart(model.stiffness_N_per_m(), free_index_, static_cast<int>(free_dofs_.size())));
  if (ldlt_.info() != Eigen::Success || (ldlt_.vectorD().array() <= 0.0).any())
    throw std::runtime_error("static solve: the stiffness is singular; part of the tissue region is not anchored "
                             "(hold some of its nodes fixed)");
}

Eigen::VectorXd StaticSolver::solve(const Eigen::VectorXd& f_N) const {
  if (f_N.size() != dofCount()) throw std::invalid_argument("static solve: the force vector has the wrong size");
  Eigen::VectorXd f_free(static_cast<Eigen::Index>(free_dofs_.size()));
  for (std::size_t i = 0; i < free_dofs_.size(); ++i) f_free(static_cast<Eigen::Index>(i)) = f_N(free_dofs_[i]);
  const Eigen::VectorXd u_free = ldlt_.solve(f_free);
  Eigen::VectorXd u = Eigen::VectorXd::Zero(dofCount());
  for (std::size_t i = 0; i < free_dofs_.size(); ++i) u(free_dofs_[i]) = u_free(static_cast<Eigen::Index>(i));
  return u;
}

Eigen::VectorXd StaticSolver::unitResponse(int dof) const {
  if (dof < 0 || dof >= dofCount() || isFixed(dof))
    throw std::invalid_argument("static solve: dof " + std::to_string(dof) + " is fixed or out of range");
  Eigen::VectorXd f = Eigen::VectorXd::Zero(dofCount());
  f(dof) = 1.0;
  return solve(f);
}

Eigen::MatrixXd StaticSolver::compliance(const std::vector<int>& dofs) const {
  const auto m = static_cast<Eigen::Index>(dofs.size());
  Eigen::MatrixXd C(m, m);
  for (Eigen::Index b = 0; b < m; ++b) {
    const Eigen::VectorXd u = unitResponse(dofs[static_cast<std::size_t>(b)]);
    for (Eigen::Index a = 0; a < m; ++a) C(a, b) = u(dofs[static_cast<std::size_t>(a)]);
  }
  return 0.5 * (C + C.transpose());  // symmetric up to rounding
}

long StaticSolver::factorNonZeros() const { return static_cast<long>(ldlt_.matrixL().nestedExpression().nonZeros()); }

}  // namespace vh::tissue
