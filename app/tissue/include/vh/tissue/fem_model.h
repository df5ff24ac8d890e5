#pragma once
/// @file
/// The assembled linear finite-element model of a tissue region: stiffness K, lumped mass M and
/// Rayleigh damping C over the lattice's 3 n degrees of freedom (node n's x, y, z displacement
/// are dofs 3n, 3n + 1, 3n + 2, in W, metres). A constant model: built once, read by the solvers.
#include <vector>

#include <Eigen/Core>
#include <Eigen/SparseCore>

#include "vh/tissue/hex_lattice.h"
#include "vh/tissue/material.h"

namespace vh::tissue {

/// Sparse matrices in column-major storage, both triangles stored.
using SparseMatrix = Eigen::SparseMatrix<double>;

/// The dofs left free when `fixed` are held: free_index[dof] is a dof's place among the free ones
/// (-1 when held), free[k] the k-th free dof.
struct FreeDofs {
  std::vector<int> free_index;
  std::vector<int> free;
};
/// @throws std::invalid_argument naming `who` on a held dof out of [0, dof_count).
FreeDofs freeDofs(int dof_count, const std::vector<int>& fixed, const char* who);

class FemModel {
 public:
  /// @param materials one per material index the lattice uses (at least lattice.maxMaterial() + 1).
  /// @throws std::invalid_argument when a material is missing or fails Material::validate().
  FemModel(HexLattice lattice, std::vector<Material> materials);

  const HexLattice& lattice() const noexcept { return lattice_; }
  const std::vector<Material>& materials() const noexcept { return materials_; }
  int dofCount() const noexcept { return lattice_.dofCount(); }

  /// K (dofCount x dofCount) [N/m]: sum of the elements' cubeStiffness().
  const SparseMatrix& stiffness_N_per_m() const noexcept { return K_; }
  /// Diagonal of the lumped M (dofCount) [kg]: each element's mass rho h^3 split over its 8 corners.
  const Eigen::VectorXd& lumpedMass_kg() const noexcept { return mass_; }
  /// C = sum over elements of (alpha_e M_e + beta_e K_e) (dofCount x dofCount) [N*s/m].
  const SparseMatrix& damping_Ns_per_m() const noexcept { return C_; }

  /// Strain energy 1/2 u^T K u [J] of displacements u (dofCount) [m].
  double strainEnergy_J(const Eigen::VectorXd& u_m) const;
  /// Kinetic energy 1/2 v^T M v [J] of velocities v (dofCount) [m/s].
  double kineticEnergy_J(const Eigen::VectorXd& v_m_per_s) const;

  /// Dofs of the nodes selected by `pick(position_W)` (all three components each), ascending.
  template <typename Pick>
  std::vector<int> dofsOfNodes(Pick pick) const {
    std::vector<int> dofs;
    for (int n = 0; n < lattice_.nodeCount(); ++n)
      if (pick(lattice_.nodePosition_W(n)))
        for (int c = 0; c < 3; ++c) dofs.push_back(3 * n + c);
    return dofs;
  }

 private:
  HexLattice lattice_;
  std::vector<Material> materials_;
  SparseMatrix K_;
  SparseMatrix C_;
  Eigen::VectorXd mass_;
};

}  // namespace vh::tissue
