#include "vh/tissue/hex_element.h"

#include <cmath>

namespace vh::tissue {
namespace {

Eigen::Vector3d cornerSigns(int a) noexcept {
  return {2.0 * (a & 1) - 1.0, 2.0 * ((a >> 1) & 1) - 1.0, 2.0 * ((a >> 2) & 1) - 1.0};
}

struct UnitCubeMatrices {
  ElementMatrix K_lambda = ElementMatrix::Zero();  ///< Volumetric part, one-point rule.
  ElementMatrix K_mu = ElementMatrix::Zero();      ///< Shear part, 2 x 2 x 2 rule.
};

UnitCubeMatrices buildUnitCube() {
  UnitCubeMatrices m;
  const double detJ = 0.125;  // (h / 2)^3 with h = 1
  Eigen::Matrix<double, 6, 1> d_mu;
  d_mu << 2.0, 2.0, 2.0, 1.0, 1.0, 1.0;
  const double g = 1.0 / std::sqrt(3.0);
  for (int q = 0; q < 8; ++q) {
    const Eigen::Vector3d xi = g * cornerSigns(q);
    const StrainDisplacement B = cubeStrainDisplacement(xi, 1.0);
    m.K_mu.noalias() += B.transpose() * d_mu.asDiagonal() * B * detJ;  // weight 1 per point
  }
  const StrainDisplacement B0 = cubeStrainDisplacement(Eigen::Vector3d::Zero(), 1.0);
  const Eigen::Matrix<double, 1, 24> divergence = B0.topRows<3>().colwise().sum();
  m.K_lambda.noalias() = divergence.transpose() * divergence * (8.0 * detJ);  // weight 8
  return m;
}

}  // namespace

Eigen::Matrix<double, 8, 1> hexShapeFunctions(const Eigen::Vector3d& xi) noexcept {
  Eigen::Matrix<double, 8, 1> N;
  for (int a = 0; a < 8; ++a) {
    const Eigen::Vector3d s = cornerSigns(a);
    N(a) = 0.125 * (1.0 + s.x() * xi.x()) * (1.0 + s.y() * xi.y()) * (1.0 + s.z() * xi.z());
  }
  return N;
}

Eigen::Matrix<double, 3, 8> hexShapeGradients(const Eigen::Vector3d& xi, double spacing_m) noexcept {
  Eigen::Matrix<double, 3, 8> dN;
  const double scale = 2.0 / spacing_m * 0.125;  // d xi / d x times the shape functions' 1/8
  for (int a = 0; a < 8; ++a) {
    const Eigen::Vector3d s = cornerSigns(a);
    dN(0, a) = scale * s.x() * (1.0 + s.y() * xi.y()) * (1.0 + s.z() * xi.z());
    dN(1, a) = scale * s.y() * (1.0 + s.x() * xi.x()) * (1.0 + s.z() * xi.z());
    dN(2, a) = scale * s.z() * (1.0 + s.x() * xi.x()) * (1.0 + s.y() * xi.y());
  }
  return dN;
}

StrainDisplacement cubeStrainDisplacement(const Eigen::Vector3d& xi, double spacing_m) noexcept {
  StrainDisplacement B = StrainDisplacement::Zero();
  const Eigen::Matrix<double, 3, 8> dN = hexShapeGradients(xi, spacing_m);
  for (int a = 0; a < 8; ++a) {
    const double nx = dN(0, a), ny = dN(1, a), nz = dN(2, a);
    const int c = 3 * a;
    B(0, c) = nx;
    B(1, c + 1) = ny;
    B(2, c + 2) = nz;
    B(3, c) = ny;
    B(3, c + 1) = nx;
    B(4, c + 1) = nz;
    B(4, c + 2) = ny;
    B(5, c) = nz;
    B(5, c + 2) = nx;
  }
  return B;
}

ElementMatrix cubeStiffness(double spacing_m, double lambda_Pa, double mu_Pa) noexcept {
  static const UnitCubeMatrices unit = buildUnitCube();
  return spacing_m * (lambda_Pa * unit.K_lambda + mu_Pa * unit.K_mu);
}

}  // namespace vh::tissue
