#pragma once
/// @file
/// The full static solve K u = f of a tissue model with some dofs held at zero (anchored to bone
/// or to the region's cut), by a sparse LDL^T factorisation made once (Eigen's SimplicialLDLT,
/// approximate minimum degree ordering). The reference every faster model is measured against,
/// and the source of the contact compliance the hand feels (ContactCompliance).
#include <vector>

#include <Eigen/Core>
#include <Eigen/SparseCholesky>

#include "vh/tissue/fem_model.h"

namespace vh::tissue {

class StaticSolver {
 public:
  /// @param fixed_dofs the dofs held at zero displacement (any order, duplicates allowed).
  /// @throws std::invalid_argument on a dof out of range.
  /// @throws std::runtime_error when the free part of K is singular (a part of the region that
  ///         nothing anchors: it could float away rigidly).
  StaticSolver(const FemModel& model, const std::vector<int>& fixed_dofs);

  int dofCount() const noexcept { return static_cast<int>(free_index_.size()); }
  bool isFixed(int dof) const { return free_index_[static_cast<std::size_t>(dof)] < 0; }

  /// Displacements u (dofCount) [m] under nodal forces f (dofCount) [N]; u = 0 on the fixed dofs
  /// (their forces are reactions, ignored here).
  /// @throws std::invalid_argument on a size mismatch.
  Eigen::VectorXd solve(const Eigen::VectorXd& f_N) const;

  /// Compliance matrix (m x m) [m/N] of the given dofs: entry (a, b) is the displacement of
  /// dofs[a] under a unit force on dofs[b], all other forces zero. Symmetric positive definite
  /// when no dof repeats and none is fixed.
  /// @throws std::invalid_argument on a fixed or out-of-range dof.
  Eigen::MatrixXd compliance(const std::vector<int>& dofs) const;

  /// The full displacement field (dofCount) [m] under a unit force on `dof`: a column of K^-1.
  /// @throws std::invalid_argument on a fixed or out-of-range dof.
  Eigen::VectorXd unitResponse(int dof) const;

  /// Nonzeros of the factor L (its memory is about 12 bytes each).
  long factorNonZeros() const;

 private:
  std::vector<int> free_index_;  ///< Per dof: its index among the free dofs, or -1 when fixed.
  std::vector<int> free_dofs_;   ///< The free dofs in order.
  Eigen::SimplicialLDLT<SparseMatrix, Eigen::Lower> ldlt_;
};

}  // namespace vh::tissue
