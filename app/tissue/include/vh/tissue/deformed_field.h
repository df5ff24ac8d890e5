#pragma once
/// @file
/// The scan's field as the deformed tissue carries it. The tissue maps each material point X
/// (frame G, rest) to x = X + u(X), u interpolated trilinearly from the lattice's nodal
/// displacements; a point p is inside the deformed isosurface F = s when F(X) >= s at the
/// material point X with X + u(X) = p. The scan's own voxels keep carrying the surface: only the
/// point is mapped back. This is the question the proxy's contact asks of deformed tissue.
#include <functional>

#include <Eigen/Core>

#include "vh/tissue/hex_lattice.h"

namespace vh::tissue {

class DeformedField {
 public:
  /// @param displacement_m the lattice's nodal displacements (3 per node) [m], frame G.
  /// @throws std::invalid_argument on a size mismatch or a non-finite displacement.
  DeformedField(const HexLattice& lattice, Eigen::VectorXd displacement_m);

  /// u(X) [m] at material point X (zero outside the lattice's cells).
  Eigen::Vector3d displacementAt(const Eigen::Vector3d& X_G_m) const noexcept;
  /// The deformation gradient I + grad u at X (3 x 3), grad u of the trilinear interpolant.
  Eigen::Matrix3d deformationGradient(const Eigen::Vector3d& X_G_m) const noexcept;

  struct Inverse {
    Eigen::Vector3d X_G_m = Eigen::Vector3d::Zero();  ///< Material point with X + u(X) = p.
    int iterations = 0;
    bool converged = false;  ///< |X + u(X) - p| <= tolerance.
  };
  /// The material point of spatial point p: Newton on X + u(X) = p from X = p, the cell's exact
  /// trilinear Jacobian each step (the map is invertible while the tissue is not turned inside
  /// out, det(I + grad u) > 0). Points outside the lattice are their own material point.
  Inverse materialPoint(const Eigen::Vector3d& p_G_m, double tolerance_m = 1e-12, int max_iterations = 20) const noexcept;

  /// F(X(p)) >= s, F given in the rest frame G (the scan's field). Unconverged points are judged
  /// at their best estimate.
  bool isInside(const Eigen::Vector3d& p_G_m, const std::function<double(const Eigen::Vector3d&)>& F, double isovalue) const;

 private:
  const HexLattice& lattice_;
  Eigen::VectorXd u_;
};

}  // namespace vh::tissue
