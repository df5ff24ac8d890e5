#pragma once
/// @file
/// Triangle meshes of tools in their own frame T, and rigid-body mass properties from geometry.

#include <array>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace vh::haptics {

/// A triangle mesh in the tool frame T [m].
struct TriangleMesh {
  std::vector<Eigen::Vector3d> vertices_T_m;  ///< Vertex positions (n x 3) in T [m].
  std::vector<std::array<int, 3>> triangles;  ///< Vertex indices (m x 3), counter-clockwise outward.

  bool empty() const noexcept { return triangles.empty(); }
  /// Total surface area [m^2].
  double area_m2() const;
  /// Signed enclosed volume [m^3] (positive for a closed, outward-oriented mesh).
  double signedVolume_m3() const;
  /// Applies p <- scale * p to every vertex.
  void scale(double factor);
  /// Bounding box corners in T [m].
  Eigen::Vector3d boundsMin_T_m() const;
  Eigen::Vector3d boundsMax_T_m() const;
};

/// Rigid-body mass properties, expressed in the tool frame T.
struct MassProperties {
  double mass_kg = 1.0;                                       ///< Mass [kg].
  Eigen::Vector3d p_TCm_m = Eigen::Vector3d::Zero();         ///< Centre of mass in T [m].
  Eigen::Matrix3d I_Cm_T_kgm2 = Eigen::Matrix3d::Identity(); ///< Inertia about Cm, axes of T [kg m^2].

  /// 6 x 6 mass matrix about the centre of mass for a tool at orientation R_WT, in W:
  /// diag(m I3, R_WT I_Cm_T R_WT^T) (section 2.4, eq. 3).
  Eigen::Matrix<double, 6, 6> massMatrix_W(const Eigen::Matrix3d& R_WT) const;
};

/// Mass properties of a tool from its geometry at uniform density [kg/m^3].
/// A closed mesh (|signed volume| > 1e-3 * area * bounding-box diagonal) is treated as a solid
/// (divergence theorem over signed tetrahedra); an open one as a thin shell of the same density
/// times 1 mm thickness.
/// @throws std::invalid_argument for an empty or degenerate mesh (zero area).
MassProperties massPropertiesFromMesh(const TriangleMesh& mesh, double density_kg_per_m3 = 7800.0);

}  // namespace vh::haptics
