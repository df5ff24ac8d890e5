#pragma once
/// @file
/// Rigid poses and 6-D motion vectors in SI units (m, rad).
///
/// Monogram notation: `X_WT` is the pose of frame T measured and expressed in frame W, so
/// `p_W = X_WT * p_T`. All poses are proper rigid transforms with a unit quaternion.

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace vh::haptics {

/// A 6-D motion vector: (translation [m], rotation vector [rad]) or its rates and forces.
using Vector6d = Eigen::Matrix<double, 6, 1>;

/// A rigid transform X_AB: rotation `R_AB` (unit quaternion) and translation `p_AB_m` [m].
struct Pose {
  Eigen::Quaterniond R_AB = Eigen::Quaterniond::Identity();  ///< Orientation of B in A.
  Eigen::Vector3d p_AB_m = Eigen::Vector3d::Zero();            ///< Origin of B in A [m].

  static Pose Identity() { return {}; }
  static Pose FromTranslation(const Eigen::Vector3d& p_m) { return {Eigen::Quaterniond::Identity(), p_m}; }

  /// p_A = X_AB * p_B.
  Eigen::Vector3d operator*(const Eigen::Vector3d& p_B) const { return R_AB * p_B + p_AB_m; }
  /// X_AC = X_AB * X_BC.
  Pose operator*(const Pose& X_BC) const { return {R_AB * X_BC.R_AB, R_AB * X_BC.p_AB_m + p_AB_m}; }
  /// X_BA.
  Pose inverse() const {
    const Eigen::Quaterniond R_BA = R_AB.conjugate();
    return {R_BA, -(R_BA * p_AB_m)};
  }
  /// True when every component is finite.
  bool allFinite() const { return R_AB.coeffs().allFinite() && p_AB_m.allFinite(); }
};

/// Rotation vector (axis * angle [rad], angle in [0, pi]) of a unit quaternion.
Eigen::Vector3d rotationVector(const Eigen::Quaterniond& q) noexcept;
/// The rotation vector of the same rotation as `theta_rad` (axis * angle, angle in [0, pi],
/// as rotationVector() gives it) that is nearest `reference_rad`: theta + 2 pi k * axis for the
/// integer k that makes it continuous with the reference (phase unwrapping, Itoh 1982, applied
/// to the angle about the rotation's axis). A relative rotation tracked tick by tick this way
/// grows past pi instead of jumping to the other side (the virtual coupling's torque then
/// never reverses while a twist keeps growing). With a zero reference, theta itself.
/// Near the identity (|theta| < 1e-6 rad) the axis is taken from the reference. When even the
/// nearest candidate is farther than max_step_rad from the reference (a jump no hand makes in
/// one servo tick: a glitch or a scripted jump, where "nearest" means nothing), theta itself,
/// the shortest rotation, is returned.
Eigen::Vector3d unwrapRotationVector(const Eigen::Vector3d& theta_rad, const Eigen::Vector3d& reference_rad,
                                     double max_step_rad = 0.25) noexcept;
/// Unit quaternion of a rotation vector (axis * angle [rad]); exact for tiny angles.
Eigen::Quaterniond quaternionFromRotationVector(const Eigen::Vector3d& theta_rad) noexcept;

/// Generalised 6-D displacement of the centre of mass from X_WA to X_WB, in W:
/// (c_B - c_A [m], rotation vector of R_WB R_WA^T [rad]), the centre at p_TCm_m in the tool
/// frame T of both poses. With rotation_reference_rad, the rotation vector is the one nearest it
/// (unwrapRotationVector(): may exceed pi). Used by the configuration solver (a_u = 2 dx, paper
/// section 2.4) and the virtual coupling (eq. 5).
Vector6d displacement_W(const Pose& X_WA, const Pose& X_WB, const Eigen::Vector3d& p_TCm_m,
                        const Eigen::Vector3d* rotation_reference_rad = nullptr) noexcept;

}  // namespace vh::haptics
