#pragma once
/// @file
/// The rigid motion of the proxy over one unit time step (paper section 2.3, eq. 2):
///   p(t) = c0 + v t + R(omega t) r0,   t in [0, 1],
/// where c0 is the initial centre of rotation (the tool's centre of mass), v the linear
/// velocity [m per step], omega the angular velocity [rad per step] (rotation vector), and r0
/// the point's radial vector from c0 in W. The orientation follows R(t) = R(omega t) R0.

#include <cmath>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "vh/haptics/pose.h"

namespace vh::haptics {

class RigidMotion {
 public:
  RigidMotion() = default;
  /// Motion taking the tool from X_WT0 to X_WT1 in a unit step, rotating about the centre of
  /// mass p_TCm (in T). The rotation is the shortest one (angle <= pi).
  static RigidMotion Between(const Pose& X_WT0, const Pose& X_WT1, const Eigen::Vector3d& p_TCm_m) noexcept;
  /// Motion from X_WT0 with linear displacement v_W [m] and rotation vector omega_W [rad].
  static RigidMotion FromVelocity(const Pose& X_WT0, const Eigen::Vector3d& p_TCm_m,
                                  const Eigen::Vector3d& v_W_m, const Eigen::Vector3d& omega_W_rad) noexcept;

  const Eigen::Vector3d& c0_W_m() const noexcept { return c0_; }
  const Eigen::Vector3d& v_W_m() const noexcept { return v_; }
  const Eigen::Vector3d& omega_W_rad() const noexcept { return omega_; }

  /// Radial vector r0 (in W) of a tool point p_T at t = 0.
  Eigen::Vector3d radial_W(const Eigen::Vector3d& p_T_m) const noexcept { return R0_ * (p_T_m - p_TCm_); }
  /// Eq. 2: position at time t of the point with radial vector r0_W.
  Eigen::Vector3d pointAt(const Eigen::Vector3d& r0_W, double t) const noexcept {
    // The step's ends, which most sweeps sample for most points, reuse the cosine and sine
    // computed with the motion (the same doubles).
    double c, s;
    if (t == 1.0) {
      c = cos_end_;
      s = sin_end_;
    } else if (t == 0.0) {
      c = cos_start_;
      s = sin_start_;
    } else {
      const double angle = angle_ * t;
      c = std::cos(angle);
      s = std::sin(angle);
    }
    // Rodrigues' formula about the unit axis k.
    const Eigen::Vector3d rotated = r0_W * c + axis_.cross(r0_W) * s + axis_ * (axis_.dot(r0_W) * (1.0 - c));
    return c0_ + v_ * t + rotated;
  }
  /// Pose of the tool frame at time t.
  Pose poseAt(double t) const noexcept;
  /// The same arc over [t0, t1], re-timed to [0, 1]: starts at poseAt(t0), moves by
  /// (t1 - t0) v and (t1 - t0) omega (the axis and the centre's line are the same).
  RigidMotion part(double t0, double t1) const noexcept {
    return FromVelocity(poseAt(t0), p_TCm_, v_ * (t1 - t0), omega_ * (t1 - t0));
  }
  /// Path-length bound of a point over the unit step [m]: |v| + |omega x r0| (the point's speed
  /// is |v + omega x r(t)| and |omega x r(t)| = |omega| rho stays constant, rho its distance from
  /// the axis). Tighter than the paper's |v| + |omega| |r0| for points near the rotation axis
  /// (a thin tool spinning about its shaft).
  double pathLengthBound(const Eigen::Vector3d& r0_W) const noexcept { return speed_ + angle_ * radiusAboutAxis(r0_W); }
  /// Translation over the unit step, |v| [m].
  double speed_m() const noexcept { return speed_; }
  /// Rotation angle over the unit step, |omega| [rad].
  double angle_rad() const noexcept { return angle_; }
  /// Distance of the point with radial vector r0_W from the rotation axis through c0 [m]
  /// (0 without rotation): the radius of the circle its rotation part moves on.
  double radiusAboutAxis(const Eigen::Vector3d& r0_W) const noexcept {
    return angle_ > 0.0 ? (r0_W - axis_ * axis_.dot(r0_W)).norm() : 0.0;
  }
  /// True when the motion neither translates nor rotates.
  bool isStill() const noexcept { return speed_ == 0.0 && angle_ == 0.0; }

 private:
  Eigen::Vector3d c0_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d v_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d omega_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d axis_ = Eigen::Vector3d::UnitX();  // unit rotation axis
  double angle_ = 0.0;                               // |omega|
  // cos and sin of angle_ * 0 and angle_ * 1 (pointAt() at the step's ends).
  double cos_start_ = 1.0, sin_start_ = 0.0, cos_end_ = 1.0, sin_end_ = 0.0;
  double speed_ = 0.0;                               // |v|
  Eigen::Quaterniond R0_ = Eigen::Quaterniond::Identity();
  Eigen::Vector3d p_TCm_ = Eigen::Vector3d::Zero();
};

}  // namespace vh::haptics
