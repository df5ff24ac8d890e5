#pragma once
/// @file
/// The tissue's motion under external nodal forces: M a + C v + K u = f, integrated by backward
/// (implicit) Euler with one prefactored matrix,
///     (M + dt C + dt^2 K) v_{k+1} = M v_k + dt (f_{k+1} - K u_k),   u_{k+1} = u_k + dt v_{k+1}.
/// Backward Euler is unconditionally stable (any dt, the stiffest preset included) and
/// dissipative: with f = 0 the energy 1/2 v^T M v + 1/2 u^T K u never grows (its change per step
/// is -dt v^T C v - 1/2 |dv|_M^2 - 1/2 dt^2 |v|_K^2 <= 0), which is the passivity the hand needs
/// from the tissue when it lets go.
#include <vector>

#include <Eigen/Core>
#include <Eigen/SparseCholesky>

#include "vh/tissue/fem_model.h"

namespace vh::tissue {

class ImplicitDynamics {
 public:
  /// @param fixed_dofs dofs held at zero displacement and velocity.
  /// @param time_step_s dt [s] (> 0, finite).
  /// @throws std::invalid_argument on a bad dof or time step; std::runtime_error when the
  ///         system matrix cannot be factored.
  ImplicitDynamics(const FemModel& model, const std::vector<int>& fixed_dofs, double time_step_s);

  /// One step under nodal forces f (dofCount) [N] (forces on fixed dofs are ignored).
  /// @throws std::invalid_argument on a size mismatch.
  void step(const Eigen::VectorXd& f_N);
  /// Back to rest (u = v = 0).
  void reset();

  const Eigen::VectorXd& displacement_m() const noexcept { return u_; }
  const Eigen::VectorXd& velocity_m_per_s() const noexcept { return v_; }
  double timeStep_s() const noexcept { return dt_; }
  /// 1/2 v^T M v + 1/2 u^T K u [J].
  double energy_J() const;

 private:
  const FemModel* model_;
  double dt_;
  std::vector<int> free_index_;
  std::vector<int> free_dofs_;
  Eigen::SimplicialLDLT<SparseMatrix, Eigen::Lower> ldlt_;
  Eigen::VectorXd u_, v_;
};

}  // namespace vh::tissue
