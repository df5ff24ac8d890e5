#include "vh/haptics/configuration_solver.h"

#include <algorithm>

namespace vh::haptics {

Vector6d constraintRow(const Eigen::Vector3d& p_W_m, const Eigen::Vector3d& n_W, const Eigen::Vector3d& c_W_m) noexcept {
  Vector6d row;
  row.head<3>() = n_W;
  row.tail<3>() = (p_W_m - c_W_m).cross(n_W);
  return row;
}

ConfigurationSolver::ConfigurationSolver(std::size_t max_contacts) : projector_(max_contacts), rows_(max_contacts) {}

Eigen::Vector3d ConfigurationSolver::standoffTranslation(std::span<const Contact> contacts, double standoff_m,
                                                         const Contact* also) noexcept {
  Eigen::Vector3d d = Eigen::Vector3d::Zero();
  if (!(standoff_m > 0.0)) return d;
  // Hysteresis: only contacts closer than half the stand-off are lifted (to the full stand-off),
  // so a proxy at rest stays at rest (the clearance is measured to epsilon / 16 only).
  bool any = also != nullptr && also->clearance_m < 0.5 * standoff_m;
  for (const Contact& c : contacts) any |= c.clearance_m < 0.5 * standoff_m;
  if (!any) return d;
  // The least n . d each contact allows: the stand-off for the near ones; for the others, no
  // more than half their clearance towards the surface. Each returns how far d falls short.
  const auto bound = [standoff_m](const Contact& c) {
    return c.clearance_m < 0.5 * standoff_m ? standoff_m - c.clearance_m : -0.5 * c.clearance_m;
  };
  const auto project = [&](const Contact& c) {
    const double deficit = bound(c) - c.n_W.dot(d);
    if (deficit > 0.0) d += deficit * c.n_W;
    return deficit;
  };
  const double tolerance = 1e-3 * standoff_m;
  for (int sweep = 0; sweep < 32; ++sweep) {
    double worst = also != nullptr ? project(*also) : 0.0;
    for (const Contact& c : contacts) worst = std::max(worst, project(c));
    if (worst <= tolerance) break;
  }
  const double cap = 2.0 * standoff_m;
  const double norm = d.norm();
  if (norm > cap) d *= cap / norm;  // a shorter lift: still towards every near contact's outside
  // Verified: no contact is approached past its bound's sign (contacts facing each other across
  // a gap narrower than the stand-off have no such lift).
  const auto intrudes = [&](const Contact& c) { return c.n_W.dot(d) < std::min(0.0, bound(c)) - tolerance; };
  bool bad = !d.allFinite() || (also != nullptr && intrudes(*also));
  for (const Contact& c : contacts) bad = bad || intrudes(c);
  return bad ? Eigen::Vector3d::Zero() : d;
}

RigidMotion ConfigurationSolver::constrainedMotion(const Pose& X_WP, const Pose& X_WD, const MassProperties& mass,
                                                   std::span<const Contact> contacts, double standoff_m,
                                                   const Eigen::Vector3d* rotation_reference_rad) noexcept {
  // Step 1: a_u = 2 dx takes the proxy to the device in a unit step (section 2.4).
  a_u_ = 2.0 * displacement_W(X_WP, X_WD, mass.p_TCm_m, rotation_reference_rad);
  // The projection is invariant to a scale of the metric; normalising keeps the numbers O(1).
  Matrix6d M = mass.massMatrix_W(X_WP.R_AB.toRotationMatrix()) / mass.mass_kg;
  if (has_gains_ && gains_.linear_N_per_m > 0.0) {
    // Coupling metric K M / k_lin = diag(I3, (k_ang / (k_lin i)) I_W) (see setGains()).
    const double i_mean = mass.I_Cm_T_kgm2.trace() / 3.0;
    const double k_ang = std::max(gains_.angular_Nm_per_rad, 1e-3 * gains_.linear_N_per_m * i_mean / mass.mass_kg);
    M.bottomRightCorner<3, 3>() *= (k_ang / (gains_.linear_N_per_m * i_mean)) * mass.mass_kg;
  }
  const Eigen::Vector3d c_W = X_WP * mass.p_TCm_m;
  const std::size_t m = std::min(contacts.size(), rows_.size());
  for (std::size_t i = 0; i < m; ++i) rows_[i] = constraintRow(contacts[i].p_W_m, contacts[i].n_W, c_W);
  // Step 3: Gauss' principle (eq. 3) under the contact constraints (eq. 4).
  // Warm start from the last tick's active set (the same points, where still in contact).
  std::array<int, 6> warm{};
  int warm_count = 0;
  for (int a = 0; a < active_point_count_; ++a)
    for (std::size_t i = 0; i < m; ++i)
      if (contacts[i].point_index >= 0 && contacts[i].point_index == active_points_[static_cast<std::size_t>(a)]) {
        warm[static_cast<std::size_t>(warm_count++)] = static_cast<int>(i);
        break;
      }
  last_ = projector_.project(M, a_u_, std::span<const Vector6d>(rows_.data(), m), {},
                             std::span<const int>(warm.data(), static_cast<std::size_t>(warm_count)));
  active_point_count_ = last_.active;
  for (int a = 0; a < last_.active; ++a)
    active_points_[static_cast<std::size_t>(a)] =
        contacts[static_cast<std::size_t>(last_.active_rows[static_cast<std::size_t>(a)])].point_index;
  const Vector6d& a_c = last_.a_c;
  // x_t = x_i + a_c / 2: the motion over the unit step (eq. 2).
  const Eigen::Vector3d lift = standoffTranslation(std::span<const Contact>(contacts.data(), m), standoff_m);
  return RigidMotion::FromVelocity(X_WP, mass.p_TCm_m, 0.5 * a_c.head<3>() + lift, 0.5 * a_c.tail<3>());
}

}  // namespace vh::haptics
