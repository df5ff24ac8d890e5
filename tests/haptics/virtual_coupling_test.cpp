#include "vh/haptics/virtual_coupling.h"

#include <gtest/gtest.h>

#include "vh/datasets/synthetic.h"
#include "vh/haptics/configuration_solver.h"

namespace vh::haptics {
namespace {

TEST(VirtualCoupling, ForceIsMinusKTimesTheCentreOfMassOffset) {
  const MassProperties mass = massPropertiesFromMesh(datasets::makeBuiltinTool("drill"));
  const VirtualCoupling vc({2000.0, 1.5});
  Pose X_WP = Pose::FromTranslation({0.01, 0.02, 0.03});
  X_WP.R_AB = Eigen::Quaterniond(Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 1, 0).normalized()));
  Pose X_WD = X_WP;
  X_WD.p_AB_m += Eigen::Vector3d(0.001, -0.002, 0.0005);
  const Wrench w = vc.compute(X_WP, X_WD, mass);
  EXPECT_LT((w.force_W_N - (-2000.0 * Eigen::Vector3d(0.001, -0.002, 0.0005))).norm(), 1e-9);
  EXPECT_LT(w.torque_W_Nm.norm(), 1e-12);  // pure translation: no torque
  // Coincident: nothing.
  EXPECT_LT(vc.compute(X_WP, X_WP, mass).force_W_N.norm(), 1e-15);
}

TEST(VirtualCoupling, MatchesEquation5RecomputedIndependently) {
  const MassProperties mass = massPropertiesFromMesh(datasets::makeBuiltinTool("drill"));
  const CouplingGains gains{1500.0, 0.8};
  const VirtualCoupling vc(gains);
  Pose X_WP;
  X_WP.R_AB = Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitY()));
  Pose X_WD = X_WP;
  X_WD.R_AB = Eigen::Quaterniond(Eigen::AngleAxisd(0.05, Eigen::Vector3d(0.2, 1, 0.3).normalized())) * X_WP.R_AB;
  X_WD.p_AB_m = Eigen::Vector3d(0.002, 0.0, -0.001);
  const Wrench w = vc.compute(X_WP, X_WD, mass);
  // F = -K M a'_u with a'_u = 2 dx', K = diag(k_lin / 2m, k_ang / 2i).
  const Vector6d a_u = 2.0 * displacement_W(X_WP, X_WD, mass.p_TCm_m);
  const Matrix6d M = mass.massMatrix_W(X_WP.R_AB.toRotationMatrix());
  const double i_mean = mass.I_Cm_T_kgm2.trace() / 3;
  Vector6d K;
  K << Eigen::Vector3d::Constant(gains.linear_N_per_m / (2 * mass.mass_kg)),
      Eigen::Vector3d::Constant(gains.angular_Nm_per_rad / (2 * i_mean));
  const Vector6d F = -(K.asDiagonal() * (M * a_u));
  EXPECT_LT((w.force_W_N - F.head<3>()).norm(), 1e-12 * (1 + F.norm()));
  EXPECT_LT((w.torque_W_Nm - F.tail<3>()).norm(), 1e-12 * (1 + F.norm()));
  // The torque opposes the rotation from proxy to device.
  EXPECT_LT(w.torque_W_Nm.dot(a_u.tail<3>()), 0.0);
}

}  // namespace
}  // namespace vh::haptics
