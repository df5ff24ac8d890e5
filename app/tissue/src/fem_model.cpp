#include "vh/tissue/fem_model.h"

#include <stdexcept>
#include <string>

#include "vh/tissue/hex_element.h"

namespace vh::tissue {

FemModel::FemModel(HexLattice lattice, std::vector<Material> materials)
    : lattice_(std::move(lattice)), materials_(std::move(materials)) {
  if (static_cast<int>(materials_.size()) <= lattice_.maxMaterial())
    throw std::invalid_argument("tissue model: the lattice uses material " + std::to_string(lattice_.maxMaterial()) +
                                " but only " + std::to_string(materials_.size()) + " materials were given");
  for (const Material& m : materials_) m.validate();
  const double h = lattice_.geometry().spacing_m;
  const int n = dofCount();
  std::vector<ElementMatrix> K_material(materials_.size());
  for (std::size_t m = 0; m < materials_.size(); ++m)
    K_material[m] = cubeStiffness(h, materials_[m].lambda_Pa(), materials_[m].mu_Pa());

  std::vector<Eigen::Triplet<double>> k_entries, c_entries;
  k_entries.reserve(static_cast<std::size_t>(lattice_.elementCount()) * 576);
  c_entries.reserve(static_cast<std::size_t>(lattice_.elementCount()) * 576);
  mass_ = Eigen::VectorXd::Zero(n);
  for (int e = 0; e < lattice_.elementCount(); ++e) {
    const Material& material = materials_[static_cast<std::size_t>(lattice_.elementMaterial(e))];
    const ElementMatrix& Ke = K_material[static_cast<std::size_t>(lattice_.elementMaterial(e))];
    const std::array<int, 8>& nodes = lattice_.elementNodes(e);
    const double corner_mass = material.density_kg_per_m3 * h * h * h / 8.0;
    for (int a = 0; a < 8; ++a) {
      for (int c = 0; c < 3; ++c) mass_(3 * nodes[static_cast<std::size_t>(a)] + c) += corner_mass;
      for (int b = 0; b < 8; ++b)
        for (int r = 0; r < 3; ++r)
          for (int c = 0; c < 3; ++c) {
            const int row = 3 * nodes[static_cast<std::size_t>(a)] + r;
            const int col = 3 * nodes[static_cast<std::size_t>(b)] + c;
            const double k = Ke(3 * a + r, 3 * b + c);
            k_entries.emplace_back(row, col, k);
            double cval = material.damping_stiffness_s * k;
            if (row == col) cval += material.damping_mass_per_s * corner_mass;
            c_entries.emplace_back(row, col, cval);
          }
    }
  }
  K_.resize(n, n);
  K_.setFromTriplets(k_entries.begin(), k_entries.end());
  C_.resize(n, n);
  C_.setFromTriplets(c_entries.begin(), c_entries.end());
}

FreeDofs freeDofs(int dof_count, const std::vector<int>& fixed, const char* who) {
  FreeDofs out;
  out.free_index.assign(static_cast<std::size_t>(dof_count), 0);
  for (const int dof : fixed) {
    if (dof < 0 || dof >= dof_count) throw std::invalid_argument(std::string(who) + ": fixed dof " + std::to_string(dof) + " out of range");
    out.free_index[static_cast<std::size_t>(dof)] = -1;
  }
  for (int dof = 0; dof < dof_count; ++dof) {
    if (out.free_index[static_cast<std::size_t>(dof)] < 0) continue;
    out.free_index[static_cast<std::size_t>(dof)] = static_cast<int>(out.free.size());
    out.free.push_back(dof);
  }
  return out;
}

double FemModel::strainEnergy_J(const Eigen::VectorXd& u_m) const { return 0.5 * u_m.dot(K_ * u_m); }

double FemModel::kineticEnergy_J(const Eigen::VectorXd& v_m_per_s) const {
  return 0.5 * (v_m_per_s.array().square() * mass_.array()).sum();
}

}  // namespace vh::tissue
