#pragma once
/// @file
/// The 8-node trilinear hexahedron on a cube of side h, linear isotropic elasticity.
///
/// Stiffness by selective reduced integration (Hughes 1980, "Generalization of selective
/// integration procedures to anisotropic and nonlinear media", IJNME 15:1413-1418): the shear
/// part 2 mu eps:eps with 2 x 2 x 2 Gauss points, the volumetric part lambda (tr eps)^2 with the
/// one point at the centre. Full integration of the volumetric part locks as nu -> 0.5 (soft
/// tissue is 0.45-0.49); the shear part, fully integrated, leaves no hourglass mode.
///
/// Corner a (0..7) is at local coordinates xi = (2 (a & 1) - 1, 2 ((a >> 1) & 1) - 1,
/// 2 ((a >> 2) & 1) - 1) in [-1, 1]^3; displacement dofs are ordered (u_x, u_y, u_z) per corner.
/// Strains in Voigt order (e_xx, e_yy, e_zz, g_xy, g_yz, g_zx), engineering shear strains.
#include <Eigen/Core>

namespace vh::tissue {

using ElementMatrix = Eigen::Matrix<double, 24, 24>;
using StrainDisplacement = Eigen::Matrix<double, 6, 24>;

/// Trilinear shape functions N_a(xi) of the 8 corners at local coordinates xi in [-1, 1]^3.
Eigen::Matrix<double, 8, 1> hexShapeFunctions(const Eigen::Vector3d& xi) noexcept;

/// Gradients dN_a/dx (3 x 8, column a) [1/m] of the shape functions at local coordinates xi of a
/// cube of side h [m], in the lattice's axes.
Eigen::Matrix<double, 3, 8> hexShapeGradients(const Eigen::Vector3d& xi, double spacing_m) noexcept;

/// Strain-displacement matrix B (6 x 24) at local coordinates xi of a cube of side h [m]:
/// eps = B u_e for the element's 24 corner displacements u_e [m].
StrainDisplacement cubeStrainDisplacement(const Eigen::Vector3d& xi, double spacing_m) noexcept;

/// Element stiffness K_e (24 x 24) [N/m] of a cube of side h [m] with Lame parameters lambda and
/// mu [Pa]: K_e = h (lambda K_lambda + mu K_mu), K_lambda and K_mu the unit-cube matrices of the
/// two parts above. Symmetric, positive semi-definite with exactly the 6 rigid-body modes in its
/// null space (for mu > 0).
ElementMatrix cubeStiffness(double spacing_m, double lambda_Pa, double mu_Pa) noexcept;

}  // namespace vh::tissue
