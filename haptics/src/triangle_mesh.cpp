#include "vh/haptics/triangle_mesh.h"

#include <cmath>
#include <limits>
#include <stdexcept>

#include <Eigen/Eigenvalues>

namespace vh::haptics {

double TriangleMesh::area_m2() const {
  double a = 0.0;
  for (const auto& t : triangles)
    a += 0.5 * (vertices_T_m[t[1]] - vertices_T_m[t[0]]).cross(vertices_T_m[t[2]] - vertices_T_m[t[0]]).norm();
  return a;
}

double TriangleMesh::signedVolume_m3() const {
  double v = 0.0;
  for (const auto& t : triangles)
    v += vertices_T_m[t[0]].dot(vertices_T_m[t[1]].cross(vertices_T_m[t[2]])) / 6.0;
  return v;
}

void TriangleMesh::scale(double factor) {
  for (auto& p : vertices_T_m) p *= factor;
}

Eigen::Vector3d TriangleMesh::boundsMin_T_m() const {
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
  for (const auto& p : vertices_T_m) lo = lo.cwiseMin(p);
  return lo;
}

Eigen::Vector3d TriangleMesh::boundsMax_T_m() const {
  Eigen::Vector3d hi = Eigen::Vector3d::Constant(-std::numeric_limits<double>::infinity());
  for (const auto& p : vertices_T_m) hi = hi.cwiseMax(p);
  return hi;
}

Eigen::Matrix<double, 6, 6> MassProperties::massMatrix_W(const Eigen::Matrix3d& R_WT) const {
  Eigen::Matrix<double, 6, 6> M = Eigen::Matrix<double, 6, 6>::Zero();
  M.topLeftCorner<3, 3>() = mass_kg * Eigen::Matrix3d::Identity();
  M.bottomRightCorner<3, 3>() = R_WT * I_Cm_T_kgm2 * R_WT.transpose();
  return M;
}

MassProperties massPropertiesFromMesh(const TriangleMesh& mesh, double density) {
  if (mesh.triangles.empty()) throw std::invalid_argument("massPropertiesFromMesh: the mesh has no triangles");
  if (!(density > 0.0)) throw std::invalid_argument("massPropertiesFromMesh: density must be > 0");
  for (const auto& t : mesh.triangles)
    for (int i : t)
      if (i < 0 || static_cast<std::size_t>(i) >= mesh.vertices_T_m.size())
        throw std::invalid_argument("massPropertiesFromMesh: triangle index out of range");
  const double area = mesh.area_m2();
  if (!(area > 0.0) || !std::isfinite(area)) throw std::invalid_argument("massPropertiesFromMesh: the mesh has zero area");
  const double diag = (mesh.boundsMax_T_m() - mesh.boundsMin_T_m()).norm();
  const double volume = mesh.signedVolume_m3();
  const bool solid = std::abs(volume) > 1e-3 * area * diag;
  const double sign = volume < 0.0 ? -1.0 : 1.0;

  // Zeroth, first and second moments: m, m c, C = integral of x x^T.
  double m = 0.0;
  Eigen::Vector3d first = Eigen::Vector3d::Zero();
  Eigen::Matrix3d second = Eigen::Matrix3d::Zero();
  for (const auto& t : mesh.triangles) {
    const Eigen::Vector3d& a = mesh.vertices_T_m[t[0]];
    const Eigen::Vector3d& b = mesh.vertices_T_m[t[1]];
    const Eigen::Vector3d& c = mesh.vertices_T_m[t[2]];
    const Eigen::Vector3d s = a + b + c;
    const Eigen::Matrix3d outer = a * a.transpose() + b * b.transpose() + c * c.transpose() + s * s.transpose();
    if (solid) {  // signed tetrahedron (0, a, b, c)
      const double v = sign * a.dot(b.cross(c)) / 6.0;
      m += v;
      first += v * s / 4.0;
      second += v / 20.0 * outer;
    } else {  // thin shell of 1 mm
      const double w = 0.5 * (b - a).cross(c - a).norm() * 1e-3;
      m += w;
      first += w * s / 3.0;
      second += w / 12.0 * outer;
    }
  }
  MassProperties props;
  props.mass_kg = density * m;
  props.p_TCm_m = first / m;
  const Eigen::Matrix3d C_cm = density * (second - m * props.p_TCm_m * props.p_TCm_m.transpose());
  props.I_Cm_T_kgm2 = C_cm.trace() * Eigen::Matrix3d::Identity() - C_cm;
  // A degenerate (e.g. perfectly straight, zero-radius) tool would give a singular inertia:
  // keep the mass matrix positive definite with a floor relative to the largest moment.
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(props.I_Cm_T_kgm2);
  const double floor = 1e-6 * std::max(eig.eigenvalues().maxCoeff(), props.mass_kg * 1e-8);
  if (eig.eigenvalues().minCoeff() < floor) {
    Eigen::Vector3d ev = eig.eigenvalues().cwiseMax(floor);
    props.I_Cm_T_kgm2 = eig.eigenvectors() * ev.asDiagonal() * eig.eigenvectors().transpose();
  }
  if (!props.p_TCm_m.allFinite() || !props.I_Cm_T_kgm2.allFinite() || !(props.mass_kg > 0.0))
    throw std::invalid_argument("massPropertiesFromMesh: degenerate mesh (non-finite mass properties)");
  return props;
}

}  // namespace vh::haptics
