#pragma once
/// @file
/// The configuration solver (paper section 2.4): the unconstrained acceleration towards the
/// device (a_u = 2 dx), the contact constraints (eq. 4), Gauss' principle of least constraint
/// (eq. 3) by cone projection, and the target configuration x_t = x_i + a_c / 2.

#include <array>
#include <span>
#include <vector>

#include <Eigen/Core>

#include "vh/haptics/collision_detector.h"
#include "vh/haptics/cone_projection.h"
#include "vh/haptics/pose.h"
#include "vh/haptics/tool_model.h"
#include "vh/haptics/virtual_coupling.h"

namespace vh::haptics {

/// Constraint row of eq. 4 for a contact at p_W with normal n_W on a body rotating about c_W:
/// (n^T, ((p - c) x n)^T).
Vector6d constraintRow(const Eigen::Vector3d& p_W_m, const Eigen::Vector3d& n_W,
                       const Eigen::Vector3d& c_W_m) noexcept;

class ConfigurationSolver {
 public:
  explicit ConfigurationSolver(std::size_t max_contacts = 256);

  /// The metric of Gauss' principle (eq. 3). Without gains: the tool's mass matrix M (the
  /// paper). With gains: the coupling's own metric K M = diag(k_lin I3, (k_ang / i) I_W), i =
  /// trace(I) / 3, which is the paper's M up to a factor when k_ang = k_lin i / m (the paper's
  /// scalar k). With separate gains, projecting in M let the proxy move against the coupling
  /// and inject energy (a ball rolled 0.09 rad and doubled the coupling energy in one step);
  /// a projection in the coupling's metric never raises the coupling energy of a step.
  /// k_ang is floored at 1e-3 k_lin i / m so that the metric stays positive definite.
  void setGains(const CouplingGains& gains) noexcept { gains_ = gains; has_gains_ = true; }

  /// Step 1 + 3: constrained motion for the proxy at X_WP pulled towards X_WD under the
  /// contacts. Returns the motion from X_WP to the target x_t = x_i + a_c / 2, plus the
  /// contact stand-off translation (see standoffTranslation()) when standoff_m > 0.
  /// rotation_reference_rad: the relative rotation proxy -> device tracked by the coupling
  /// (VirtualCoupling::trackedRotation_W()), so that a twist past pi keeps its direction.
  RigidMotion constrainedMotion(const Pose& X_WP, const Pose& X_WD, const MassProperties& mass,
                                std::span<const Contact> contacts, double standoff_m = 0.0,
                                const Eigen::Vector3d* rotation_reference_rad = nullptr) noexcept;

  /// Translation [m, W] that lifts every contact closer than standoff_m / 2 to a clearance of
  /// standoff_m along its normal while moving no other contact into the surface by more than
  /// half its clearance (projections onto those half-spaces, in turn, until none is short by
  /// more than 0.1 % of standoff_m, at most 32 sweeps; the hysteresis keeps a proxy at rest
  /// still), capped at 2 standoff_m. Zero when no such translation was found: a lift that would
  /// push the tool into one of its contacts is never returned. `also` (may be null): one more
  /// contact, e.g. the edge contact that stopped the last move and that the pruning dropped.
  /// A position-level correction in the spirit of Baumgarte stabilisation: the
  /// bisection of section 2.3 leaves contacts anywhere in [0, epsilon) from the surface, and at
  /// zero clearance any second-order inward drift of a tangent step (curvature, rotation,
  /// gradient error) ends inside and stops the proxy for the whole tick.
  static Eigen::Vector3d standoffTranslation(std::span<const Contact> contacts, double standoff_m,
                                             const Contact* also = nullptr) noexcept;

  /// Last projection's details (for statistics and tests).
  const ConeProjection& lastProjection() const noexcept { return last_; }
  /// Last unconstrained acceleration a_u = 2 dx (W).
  const Vector6d& lastUnconstrained() const noexcept { return a_u_; }

 private:
  CouplingGains gains_;
  bool has_gains_ = false;
  ConeProjector projector_;
  std::vector<Vector6d> rows_;
  ConeProjection last_;
  Vector6d a_u_ = Vector6d::Zero();
  // Point-shell indices of the last projection's active set: the next projection starts from
  // the rows of the same points (a warm start).
  std::array<int, 6> active_points_{};
  int active_point_count_ = 0;
};

}  // namespace vh::haptics
