#include "vh/tissue/modal_basis.h"

#include <Spectra/SymEigsShiftSolver.h>

#include <algorithm>
#include <numeric>
#include <stdexcept>
#include <string>

namespace vh::tissue {
namespace {

/// y = (M^-1/2 K M^-1/2)^-1 x = M^1/2 K^-1 M^1/2 x over the free dofs, for Spectra's shift-invert
/// mode at shift 0.
class InverseMassScaledStiffness {
 public:
  using Scalar = double;
  InverseMassScaledStiffness(const StaticSolver& solver, std::vector<int> free_dofs, Eigen::VectorXd sqrt_mass)
      : solver_(solver), free_dofs_(std::move(free_dofs)), sqrt_mass_(std::move(sqrt_mass)),
        f_(Eigen::VectorXd::Zero(solver.dofCount())) {}
  Eigen::Index rows() const { return static_cast<Eigen::Index>(free_dofs_.size()); }
  Eigen::Index cols() const { return rows(); }
  void set_shift(double sigma) {
    if (sigma != 0.0) throw std::invalid_argument("modal basis: only the shift 0 is supported");
  }
  void perform_op(const double* x_in, double* y_out) const {
    for (std::size_t i = 0; i < free_dofs_.size(); ++i)
      f_(free_dofs_[i]) = sqrt_mass_(static_cast<Eigen::Index>(i)) * x_in[i];
    const Eigen::VectorXd u = solver_.solve(f_);
    for (std::size_t i = 0; i < free_dofs_.size(); ++i)
      y_out[i] = sqrt_mass_(static_cast<Eigen::Index>(i)) * u(free_dofs_[i]);
  }

 private:
  const StaticSolver& solver_;
  std::vector<int> free_dofs_;
  Eigen::VectorXd sqrt_mass_;
  mutable Eigen::VectorXd f_;
};

}  // namespace

ModalBasis::ModalBasis(const FemModel& model, const StaticSolver& solver, int modes) {
  std::vector<int> free_dofs;
  for (int dof = 0; dof < model.dofCount(); ++dof)
    if (!solver.isFixed(dof)) free_dofs.push_back(dof);
  const int n = static_cast<int>(free_dofs.size());
  if (modes < 1 || modes >= n)
    throw std::invalid_argument("modal basis: the mode count must lie in [1, " + std::to_string(n - 1) + "]");
  Eigen::VectorXd sqrt_mass(n);
  for (int i = 0; i < n; ++i) sqrt_mass(i) = std::sqrt(model.lumpedMass_kg()(free_dofs[static_cast<std::size_t>(i)]));
  InverseMassScaledStiffness op(solver, free_dofs, sqrt_mass);
  const int ncv = std::min(n, std::max(2 * modes + 1, modes + 20));
  Spectra::SymEigsShiftSolver<InverseMassScaledStiffness> eigs(op, modes, ncv, 0.0);
  eigs.init();
  eigs.compute(Spectra::SortRule::LargestMagn, 1000, 1e-10);
  if (eigs.info() != Spectra::CompInfo::Successful)
    throw std::runtime_error("modal basis: the eigensolver did not converge for " + std::to_string(modes) + " modes");
  const Eigen::VectorXd lambda = eigs.eigenvalues();
  const Eigen::MatrixXd x = eigs.eigenvectors();
  std::vector<int> order(static_cast<std::size_t>(modes));
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(), [&](int a, int b) { return lambda(a) < lambda(b); });
  phi_ = Eigen::MatrixXd::Zero(model.dofCount(), modes);
  omega2_.resize(modes);
  for (int k = 0; k < modes; ++k) {
    const int src = order[static_cast<std::size_t>(k)];
    omega2_(k) = lambda(src);
    for (int i = 0; i < n; ++i) phi_(free_dofs[static_cast<std::size_t>(i)], k) = x(i, src) / sqrt_mass(i);
  }
}

Eigen::VectorXd ModalBasis::staticResponse(const Eigen::VectorXd& f_N, int modes) const {
  if (f_N.size() != phi_.rows()) throw std::invalid_argument("modal basis: the force vector has the wrong size");
  const int r = (modes <= 0 || modes > modeCount()) ? modeCount() : modes;
  const Eigen::VectorXd q = (phi_.leftCols(r).transpose() * f_N).cwiseQuotient(omega2_.head(r));
  return phi_.leftCols(r) * q;
}

}  // namespace vh::tissue
