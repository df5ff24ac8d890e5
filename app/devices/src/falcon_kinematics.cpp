#include "vh/devices/falcon_kinematics.h"

#include <algorithm>
#include <cmath>
#include <numbers>

#include <Eigen/LU>

namespace vh::devices::falcon {

namespace {

/// Degrees of motor angle per encoder count: (pi * 0.01425 / 1280) / (pi * 0.110 / 360).
constexpr double kDegPerCount = (0.01425 / 1280.0) * 360.0 / 0.110;
constexpr double kAngleOffsetDeg = 35.0;

/// One leg's state at a handle position: the leg frame coordinates and the angles.
struct Leg {
  double U = 0.0, v = 0.0, w = 0.0;  ///< u + c, v, w in the leg's frame [m].
  double theta = 0.0;                ///< Motor angle [rad].
  double theta3 = 0.0;               ///< Parallelogram angle [rad].
  double L = 0.0;                    ///< d + e + b sin(theta3) [m].
};

/// Leg i at p_K; false when out of reach.
bool solveLeg(const Eigen::Vector3d& p, int i, const Geometry& g, Leg& leg) noexcept {
  const double cphi = std::cos(g.phi_rad[static_cast<std::size_t>(i)]);
  const double sphi = std::sin(g.phi_rad[static_cast<std::size_t>(i)]);
  const double u = cphi * p.x() + sphi * p.y() - g.r;
  leg.v = -sphi * p.x() + cphi * p.y() - g.s;
  leg.w = p.z();
  leg.U = u + g.c;
  const double cos3 = (leg.v + g.f) / g.b;
  if (!(std::abs(cos3) <= 1.0)) return false;
  leg.theta3 = std::acos(cos3);
  leg.L = g.d + g.e + g.b * std::sin(leg.theta3);
  // The upper arm's tip (a cos t, a sin t) is at distance L from (U, w):
  // A cos t + B sin t = C, solved through the half angle tan(t/2) (the mechanism's branch).
  const double A = 2.0 * g.a * leg.U;
  const double B = 2.0 * g.a * leg.w;
  const double C = leg.U * leg.U + leg.w * leg.w + g.a * g.a - leg.L * leg.L;
  const double disc = A * A + B * B - C * C;
  if (!(disc >= 0.0)) return false;
  // t = (B - sqrt(disc)) / (C + A) = (C - A) / (B + sqrt(disc)): the form without cancellation.
  const double root = std::sqrt(disc);
  const double den = B >= 0.0 ? B + root : C + A;
  if (den == 0.0) return false;
  const double t = B >= 0.0 ? (C - A) / den : (B - root) / den;
  leg.theta = 2.0 * std::atan(t);
  return std::isfinite(leg.theta);
}

}  // namespace

double encoderToAngle_rad(std::int16_t encoder) noexcept {
  return (kDegPerCount * static_cast<double>(encoder) + kAngleOffsetDeg) * std::numbers::pi / 180.0;
}

std::int16_t angleToEncoder(double theta_rad) noexcept {
  const double counts = std::round((theta_rad * 180.0 / std::numbers::pi - kAngleOffsetDeg) / kDegPerCount);
  if (!std::isfinite(counts)) return 0;
  return static_cast<std::int16_t>(std::clamp(counts, -32768.0, 32767.0));
}

bool inverseKinematics(const Eigen::Vector3d& p_K_m, Eigen::Vector3d& theta_rad, const Geometry& g) noexcept {
  Eigen::Vector3d out;
  for (int i = 0; i < 3; ++i) {
    Leg leg;
    if (!solveLeg(p_K_m, i, g, leg)) return false;
    out[i] = leg.theta;
  }
  theta_rad = out;
  return true;
}

bool angleJacobian(const Eigen::Vector3d& p_K_m, Eigen::Matrix3d& dtheta_dp, const Geometry& g) noexcept {
  Eigen::Matrix3d out;
  for (int i = 0; i < 3; ++i) {
    Leg leg;
    if (!solveLeg(p_K_m, i, g, leg)) return false;
    // Implicit differentiation of phi = (U - a cos t)^2 + (w - a sin t)^2 - L(v)^2 = 0.
    const double ct = std::cos(leg.theta), st = std::sin(leg.theta);
    const double s3 = std::sin(leg.theta3), c3 = std::cos(leg.theta3);
    const double dphi_dt = 2.0 * g.a * (leg.U * st - leg.w * ct);
    if (!(std::abs(dphi_dt) > 1e-15) || !(s3 > 1e-12)) return false;
    const double dphi_du = 2.0 * (leg.U - g.a * ct);
    const double dphi_dv = 2.0 * leg.L * c3 / s3;  // dL/dv = -cos(theta3) / sin(theta3)
    const double dphi_dw = 2.0 * (leg.w - g.a * st);
    // (u, v, w) = R(-phi) (x, y) - (r, s), z.
    const double cphi = std::cos(g.phi_rad[static_cast<std::size_t>(i)]);
    const double sphi = std::sin(g.phi_rad[static_cast<std::size_t>(i)]);
    const double dtx = dphi_du * cphi - dphi_dv * sphi;
    const double dty = dphi_du * sphi + dphi_dv * cphi;
    out.row(i) = -Eigen::RowVector3d(dtx, dty, dphi_dw) / dphi_dt;
  }
  if (!out.allFinite()) return false;
  dtheta_dp = out;
  return true;
}

bool positionJacobian(const Eigen::Vector3d& p_K_m, Eigen::Matrix3d& J, const Geometry& g) noexcept {
  Eigen::Matrix3d A;
  if (!angleJacobian(p_K_m, A, g)) return false;
  const double det = A.determinant();
  if (!std::isfinite(det) || std::abs(det) < 1e-12) return false;
  J = A.inverse();
  return J.allFinite();
}

bool forwardKinematics(const Eigen::Vector3d& theta_rad, Eigen::Vector3d& p_K_m, const Eigen::Vector3d& start_K_m,
                       int max_iterations, double tolerance_rad, const Geometry& g) noexcept {
  if (!theta_rad.allFinite() || !start_K_m.allFinite()) return false;
  Eigen::Vector3d p = start_K_m;
  for (int k = 0; k <= max_iterations; ++k) {
    Eigen::Vector3d theta_p;
    Eigen::Matrix3d J;
    if (!inverseKinematics(p, theta_p, g) || !positionJacobian(p, J, g)) return false;
    const Eigen::Vector3d residual = theta_rad - theta_p;
    if (residual.cwiseAbs().maxCoeff() <= tolerance_rad) {
      p_K_m = p;
      return true;
    }
    if (k == max_iterations) break;
    p += J * residual;
  }
  return false;
}

bool jointTorques(const Eigen::Vector3d& p_K_m, const Eigen::Vector3d& force_K_N, Eigen::Vector3d& tau_Nm,
                  const Geometry& g) noexcept {
  Eigen::Matrix3d J;
  if (!force_K_N.allFinite() || !positionJacobian(p_K_m, J, g)) {
    tau_Nm.setZero();
    return false;
  }
  tau_Nm = J.transpose() * force_K_N;
  return true;
}

std::array<std::int16_t, 3> motorCommands(const Eigen::Vector3d& tau_Nm) noexcept {
  std::array<std::int16_t, 3> out{0, 0, 0};
  if (!tau_Nm.allFinite()) return out;
  Eigen::Vector3d tau = tau_Nm;
  const double max_tau = tau.cwiseAbs().maxCoeff();
  if (max_tau > kMaxJointTorque_Nm) tau *= kMaxJointTorque_Nm / max_tau;
  Eigen::Vector3d command = -kMotorCommandPerNm * tau;
  const double max_command = command.cwiseAbs().maxCoeff();
  if (max_command > 32767.0) command *= 32767.0 / max_command;
  for (int i = 0; i < 3; ++i) {
    out[static_cast<std::size_t>(i)] = static_cast<std::int16_t>(std::lround(std::clamp(command[i], -32767.0, 32767.0)));
  }
  return out;
}

}  // namespace vh::devices::falcon
