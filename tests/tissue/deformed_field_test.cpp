// The deformed field against closed forms: an affine displacement u(X) = A X + b (which the
// trilinear lattice carries exactly) is inverted to X = (I + A)^-1 (p - b); a sphere F = R - |X - c|
// under it becomes the ellipsoid |(I + A)^-1 (p - b) - c| = R.
#include "vh/tissue/deformed_field.h"

#include <cmath>
#include <random>

#include <Eigen/LU>

#include <gtest/gtest.h>

namespace vh::tissue {
namespace {

TEST(DeformedField, AnAffineDisplacementIsInvertedExactlyAndCarriesASphereToItsEllipsoid) {
  const HexLattice L = HexLattice::Box(Eigen::Vector3d(-0.01, -0.01, -0.01), 2e-3, Eigen::Vector3i(10, 10, 10));
  Eigen::Matrix3d A;
  A << -0.08, 0.02, 0.01, 0.03, 0.05, -0.02, 0.0, 0.04, -0.1;
  const Eigen::Vector3d b(2e-4, -1e-4, 3e-4);
  Eigen::VectorXd u(L.dofCount());
  for (int n = 0; n < L.nodeCount(); ++n) u.segment<3>(3 * n) = A * L.nodePosition_W(n) + b;
  const DeformedField field(L, u);
  const Eigen::Matrix3d inverse = (Eigen::Matrix3d::Identity() + A).inverse();
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> coord(-0.007, 0.007);
  const Eigen::Vector3d c(1e-3, -5e-4, 0.0);
  const double R = 4e-3;
  const auto sphere = [&](const Eigen::Vector3d& X) { return R - (X - c).norm(); };
  int disagreements = 0;
  for (int trial = 0; trial < 2000; ++trial) {
    const Eigen::Vector3d p(coord(rng), coord(rng), coord(rng));
    const DeformedField::Inverse X = field.materialPoint(p);
    ASSERT_TRUE(X.converged) << trial;
    const Eigen::Vector3d exact = inverse * (p - b);
    EXPECT_LT((X.X_G_m - exact).norm(), 1e-11) << trial;
    EXPECT_LE(X.iterations, 4) << "Newton on an affine map takes one step (a cell change may add one)";
    const bool inside = field.isInside(p, sphere, 0.0);
    const bool in_ellipsoid = (exact - c).norm() <= R;
    if (std::abs((exact - c).norm() - R) > 1e-9) disagreements += inside != in_ellipsoid;
  }
  EXPECT_EQ(disagreements, 0);
  // The deformation gradient is I + A everywhere.
  EXPECT_LT((field.deformationGradient(Eigen::Vector3d(0.003, -0.002, 0.001)) - (Eigen::Matrix3d::Identity() + A)).norm(), 1e-12);
  EXPECT_THROW(DeformedField(L, Eigen::VectorXd::Zero(3)), std::invalid_argument);
  Eigen::VectorXd bad = u;
  bad(5) = std::nan("");
  EXPECT_THROW(DeformedField(L, bad), std::invalid_argument);
}

}  // namespace
}  // namespace vh::tissue
