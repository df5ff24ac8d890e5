#include "vh/tissue/implicit_dynamics.h"

#include <cmath>
#include <stdexcept>
#include <string>

namespace vh::tissue {

ImplicitDynamics::ImplicitDynamics(const FemModel& model, const std::vector<int>& fixed_dofs, double time_step_s)
    : model_(&model), dt_(time_step_s) {
  if (!std::isfinite(time_step_s) || time_step_s <= 0.0)
    throw std::invalid_argument("tissue dynamics: the time step must be finite and > 0 s");
  FreeDofs dofs = freeDofs(model.dofCount(), fixed_dofs, "tissue dynamics");
  free_index_ = std::move(dofs.free_index);
  free_dofs_ = std::move(dofs.free);
  const SparseMatrix A_full = dt_ * model.damping_Ns_per_m() + (dt_ * dt_) * model.stiffness_N_per_m();
  std::vector<Eigen::Triplet<double>> entries;
  for (int col = 0; col < A_full.outerSize(); ++col) {
    const int c = free_index_[static_cast<std::size_t>(col)];
    if (c < 0) continue;
    entries.emplace_back(c, c, model.lumpedMass_kg()(col));
    for (SparseMatrix::InnerIterator it(A_full, col); it; ++it) {
      const int r = free_index_[static_cast<std::size_t>(it.row())];
      if (r >= c) entries.emplace_back(r, c, it.value());
    }
  }
  const auto m = static_cast<Eigen::Index>(free_dofs_.size());
  SparseMatrix A(m, m);
  A.setFromTriplets(entries.begin(), entries.end());
  ldlt_.compute(A);
  if (ldlt_.info() != Eigen::Success) throw std::runtime_error("tissue dynamics: the system matrix cannot be factored");
  reset();
}

void ImplicitDynamics::reset() {
  u_ = Eigen::VectorXd::Zero(model_->dofCount());
  v_ = Eigen::VectorXd::Zero(model_->dofCount());
}

void ImplicitDynamics::step(const Eigen::VectorXd& f_N) {
  if (f_N.size() != model_->dofCount()) throw std::invalid_argument("tissue dynamics: the force vector has the wrong size");
  const Eigen::VectorXd rhs_full =
      model_->lumpedMass_kg().cwiseProduct(v_) + dt_ * (f_N - model_->stiffness_N_per_m() * u_);
  Eigen::VectorXd rhs(static_cast<Eigen::Index>(free_dofs_.size()));
  for (std::size_t i = 0; i < free_dofs_.size(); ++i) rhs(static_cast<Eigen::Index>(i)) = rhs_full(free_dofs_[i]);
  const Eigen::VectorXd v_free = ldlt_.solve(rhs);
  v_.setZero();
  for (std::size_t i = 0; i < free_dofs_.size(); ++i) v_(free_dofs_[i]) = v_free(static_cast<Eigen::Index>(i));
  u_ += dt_ * v_;
}

double ImplicitDynamics::energy_J() const { return model_->kineticEnergy_J(v_) + model_->strainEnergy_J(u_); }

}  // namespace vh::tissue
