#pragma once
/// @file
/// Novint Falcon kinematics (R. E. Stamper's model of the three-leg parallel mechanism, with the
/// geometry of ../shared/docs/devices.md): encoder counts to motor angles, inverse kinematics
/// (closed form per leg), forward kinematics (Newton-Raphson on the inverse), the Jacobian and
/// the motor torques for a handle force (tau = J^T F). Pure functions: no I/O, no allocation.
///
/// Frames:
///   K  the kinematic frame of the model [m]: x to the user's right, y up, z away from the
///      device's body towards the user; the workspace centre is at (0, 0, kWorkspaceCentreZ_m).
///   B  the device base frame used by FalconDevice: K shifted to the workspace centre,
///      p_B = p_K - (0, 0, kWorkspaceCentreZ_m).
/// Angles: theta [rad] is the angle of each leg's motor-driven upper arm (Stamper's theta1).

#include <array>
#include <cstdint>

#include <Eigen/Core>

namespace vh::devices::falcon {

/// Link lengths and offsets [m] and leg placement [rad] (Stamper's a..f, r, s, phi).
struct Geometry {
  double a = 0.060;     ///< Upper arm length [m].
  double b = 0.1025;    ///< Parallelogram length [m].
  double c = 0.01443;   ///< [m]
  double d = 0.01125;   ///< [m]
  double e = 0.01125;   ///< [m]
  double f = -0.025;    ///< [m]
  double r = 0.040;     ///< Leg offset in u [m].
  double s = -0.02309;  ///< Leg offset in v [m].
  /// Angles of the three legs about the z axis of K [rad]: 105, -15, -135 degrees.
  std::array<double, 3> phi_rad{1.8325957145940461, -0.26179938779914941, -2.3561944901923448};
};

/// The Falcon's geometry.
inline const Geometry kGeometry{};
/// Workspace centre along z of K [m].
inline constexpr double kWorkspaceCentreZ_m = 0.11;
/// Newton-Raphson start of forwardKinematics() without a better guess (z of K [m]).
inline constexpr double kForwardStartZ_m = 0.08;
/// Largest joint torque before the uniform scale-down of motorCommands() [N*m].
inline constexpr double kMaxJointTorque_Nm = 30.0;
/// Motor command per joint torque (command = -kMotorCommandPerNm * tau) [1/(N*m)].
inline constexpr double kMotorCommandPerNm = 10000.0;

/// Motor angle [rad] for an encoder count:
/// theta_deg = (pi * 0.01425 / 1280) * enc / (pi * 0.110 / 360) + 35.
double encoderToAngle_rad(std::int16_t encoder) noexcept;
/// The encoder count nearest to a motor angle [rad] (saturated to int16; for tests and fakes).
std::int16_t angleToEncoder(double theta_rad) noexcept;

/// Inverse kinematics: the three motor angles [rad] for the handle at p_K [m].
/// @return false (theta untouched) when p_K is out of the mechanism's reach.
bool inverseKinematics(const Eigen::Vector3d& p_K_m, Eigen::Vector3d& theta_rad,
                       const Geometry& g = kGeometry) noexcept;

/// d theta / d p at p_K (3 x 3, row i = gradient of leg i's angle) [rad/m].
/// @return false when p_K is out of reach or at a singular leg configuration.
bool angleJacobian(const Eigen::Vector3d& p_K_m, Eigen::Matrix3d& dtheta_dp,
                   const Geometry& g = kGeometry) noexcept;

/// Forward kinematics by Newton-Raphson on inverseKinematics(): p <- p + J (theta - IK(p)) with
/// J = (d theta / d p)^-1, from `start_K_m` (e.g. the previous solution), at most
/// `max_iterations` steps, until the angle residual is below `tolerance_rad`.
/// @return false (p_K untouched) when it does not converge or leaves the reach.
bool forwardKinematics(const Eigen::Vector3d& theta_rad, Eigen::Vector3d& p_K_m,
                       const Eigen::Vector3d& start_K_m = Eigen::Vector3d(0.0, 0.0, kForwardStartZ_m),
                       int max_iterations = 15, double tolerance_rad = 1e-10,
                       const Geometry& g = kGeometry) noexcept;

/// The position Jacobian J = d p / d theta at p_K [m/rad] (the inverse of angleJacobian()).
/// @return false when p_K is out of reach or singular.
bool positionJacobian(const Eigen::Vector3d& p_K_m, Eigen::Matrix3d& J, const Geometry& g = kGeometry) noexcept;

/// Joint torques [N*m] that produce the force F_K [N] on the handle at p_K: tau = J^T F.
/// @return false (tau zero) when p_K is out of reach or singular.
bool jointTorques(const Eigen::Vector3d& p_K_m, const Eigen::Vector3d& force_K_N, Eigen::Vector3d& tau_Nm,
                  const Geometry& g = kGeometry) noexcept;

/// Motor commands for joint torques: scaled down uniformly when max |tau| > kMaxJointTorque_Nm,
/// command = -kMotorCommandPerNm * tau, then scaled down uniformly to fit int16; a non-finite
/// torque gives zeros.
std::array<std::int16_t, 3> motorCommands(const Eigen::Vector3d& tau_Nm) noexcept;

}  // namespace vh::devices::falcon
