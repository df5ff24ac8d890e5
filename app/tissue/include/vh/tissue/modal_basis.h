#pragma once
/// @file
/// The reduced (modal) model of a tissue region: the r lowest vibration modes of
/// K phi = omega^2 M phi with the fixed dofs held (Barbic and James 2005, "Real-time subspace
/// integration for St. Venant-Kirchhoff deformable models", the linear case), computed with
/// Spectra's shift-invert Lanczos (SymEigsShiftSolver, shift 0) on M^-1/2 K M^-1/2 using the
/// static solver's factorisation. A static load f then gives u ~ Phi Omega^-2 Phi^T f.
#include <vector>

#include <Eigen/Core>

#include "vh/tissue/fem_model.h"
#include "vh/tissue/static_solver.h"

namespace vh::tissue {

class ModalBasis {
 public:
  /// @param solver the static solver of the same model and fixed dofs (its factor is reused).
  /// @param modes r (1 <= r < the number of free dofs).
  /// @throws std::invalid_argument on a bad mode count; std::runtime_error when the eigensolver
  ///         does not converge.
  ModalBasis(const FemModel& model, const StaticSolver& solver, int modes);

  /// Phi (dofCount x r), mass-normalised (Phi^T M Phi = I), zero on the fixed dofs, ordered by
  /// ascending frequency.
  const Eigen::MatrixXd& modes() const noexcept { return phi_; }
  /// omega^2 (r) [1/s^2], ascending.
  const Eigen::VectorXd& eigenvalues_per_s2() const noexcept { return omega2_; }
  int modeCount() const noexcept { return static_cast<int>(omega2_.size()); }

  /// The reduced static response Phi_r Omega_r^-2 Phi_r^T f (dofCount) [m] using the first r
  /// modes (r <= modeCount(); 0 or less: all).
  /// @throws std::invalid_argument on a size mismatch.
  Eigen::VectorXd staticResponse(const Eigen::VectorXd& f_N, int modes = 0) const;

 private:
  Eigen::MatrixXd phi_;
  Eigen::VectorXd omega2_;
};

}  // namespace vh::tissue
