// The edge test between the points (haptics/README.md, "Between the points"): a forked test's
// job, the clearance certificates kept across ticks, the last crossing edge. Private to the
// collision detector (collision_detector_impl.h; the test is in edge_test.cpp, its
// certificates in edge_certificates.cpp).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "vh/haptics/pose.h"

namespace vh::haptics::detail {

// The pose and isovalue of the forked edge test; the lowest root rank a lane found crossing.
struct EdgeJob {
  Pose X_WP;
  double isovalue = 0.0;
};
// Temporal coherence of the edge test (haptics/README.md, "Between the points"): per point j,
// the clearances proven for all of j's edges at the last two poses they were found free at,
// by the exact walk or by the box query around them. Until the tool has moved j's edges that
// far, they cannot meet the isosurface (the field only ever decreases under drilling), and
// neither is done again.
struct EdgeClearance {
  Eigen::Vector3d p_W_m = Eigen::Vector3d::Zero();               // point j at that pose, in W [m]
  Eigen::Quaterniond R_WT = Eigen::Quaterniond::Identity();      // the tool's orientation there
  double clearance_m = -1.0;                                     // <= 0: nothing proven
  // The lever the tool's turn since then acts on: j's edge reach plus epsilon for the exact
  // walk's certificate (its clearance is from the edges themselves); 0 for a box query's (its
  // clearance is the margin of a ball about point j that holds j's edges however it turns).
  double arm_m = 0.0;
  // The exact walk's directional certificate: F - s <= -margin on all of j's edges there, and
  // F's derivative per grid step along each grid axis within [step_lo, step_hi] over the
  // cells their box reaches, reach_lo below it and reach_hi above it along each grid axis (at
  // least kCertificateReachSteps: the whole step bricks read, ScalarVolume::gridStepRange());
  // margin <= 0: none. A tool sliding along a wall moves its edges along the wall, where F
  // hardly changes, and away from it, where F falls: a bound that knows the move's direction
  // keeps them proven for many ticks where the distance (clearance_m) lasts about one.
  // Floats rounded outward (the ranges) and inward (the reaches): 144 bytes a certificate.
  double margin = -1.0;
  Eigen::Vector3f step_lo = Eigen::Vector3f::Zero(), step_hi = Eigen::Vector3f::Zero();
  Eigen::Vector3f reach_lo = Eigen::Vector3f::Zero(), reach_hi = Eigen::Vector3f::Zero();  // grid steps
  // The field's rise when it was proven (CollisionDetector::Impl::field_rise_): a field that
  // rose since by r keeps the directional certificate with margin - r (F - s <= -margin + r
  // there now, and the derivative ranges still bound the old field's part of the rise along
  // the move), and ends the distance ones (their clearance assumed the old field's Lipschitz
  // bound on all of F).
  double rise_at_proof = 0.0;
};
// The last edge edgesCrossAt() found crossing: its ends and the pose it was tested at.
struct EdgeHit {
  int j = -1, k = -1;
  Pose X_WP;
};

}  // namespace vh::haptics::detail
