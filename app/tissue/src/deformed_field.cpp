#include "vh/tissue/deformed_field.h"

#include <Eigen/LU>

#include <stdexcept>

#include "vh/tissue/hex_element.h"

namespace vh::tissue {

DeformedField::DeformedField(const HexLattice& lattice, Eigen::VectorXd displacement_m)
    : lattice_(lattice), u_(std::move(displacement_m)) {
  if (u_.size() != lattice.dofCount()) throw std::invalid_argument("deformed field: one displacement per dof is needed");
  if (!u_.allFinite()) throw std::invalid_argument("deformed field: a displacement is not finite");
}

Eigen::Vector3d DeformedField::displacementAt(const Eigen::Vector3d& X) const noexcept {
  const HexLattice::Location at = lattice_.locate(X);
  if (at.element < 0) return Eigen::Vector3d::Zero();
  const Eigen::Matrix<double, 8, 1> N = hexShapeFunctions(at.xi);
  Eigen::Vector3d out = Eigen::Vector3d::Zero();
  for (int a = 0; a < 8; ++a) out += N(a) * u_.segment<3>(3 * lattice_.elementNodes(at.element)[static_cast<std::size_t>(a)]);
  return out;
}

Eigen::Matrix3d DeformedField::deformationGradient(const Eigen::Vector3d& X) const noexcept {
  Eigen::Matrix3d F = Eigen::Matrix3d::Identity();
  const HexLattice::Location at = lattice_.locate(X);
  if (at.element < 0) return F;
  const Eigen::Matrix<double, 3, 8> dN = hexShapeGradients(at.xi, lattice_.geometry().spacing_m);
  for (int a = 0; a < 8; ++a)
    F += u_.segment<3>(3 * lattice_.elementNodes(at.element)[static_cast<std::size_t>(a)]) * dN.col(a).transpose();
  return F;
}

DeformedField::Inverse DeformedField::materialPoint(const Eigen::Vector3d& p, double tolerance_m, int max_iterations) const noexcept {
  Inverse out;
  out.X_G_m = p;
  if (!p.allFinite()) return out;
  for (int it = 0; it < max_iterations; ++it) {
    const Eigen::Vector3d residual = out.X_G_m + displacementAt(out.X_G_m) - p;
    out.iterations = it;
    if (residual.norm() <= tolerance_m) {
      out.converged = true;
      return out;
    }
    const Eigen::Matrix3d F = deformationGradient(out.X_G_m);
    const double det = F.determinant();
    const Eigen::Vector3d step = (det > 1e-12) ? Eigen::Vector3d(F.inverse() * residual) : residual;  // fixed point when F is degenerate
    out.X_G_m -= step;
  }
  out.iterations = max_iterations;
  out.converged = (out.X_G_m + displacementAt(out.X_G_m) - p).norm() <= tolerance_m;
  return out;
}

bool DeformedField::isInside(const Eigen::Vector3d& p, const std::function<double(const Eigen::Vector3d&)>& F,
                             double isovalue) const {
  return F(materialPoint(p).X_G_m) >= isovalue;
}

}  // namespace vh::tissue
