#include "vh/runtime/placement.h"

#include "vh/haptics/penetration.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

namespace vh::runtime {

using haptics::Pose;

int countPointsInside(const haptics::ScalarVolume& volume, const haptics::PointShell& shell,
                      const Pose& X_WT, double isovalue) noexcept {
  int count = 0;
  for (const Eigen::Vector3d& p_T : shell.points_T_m()) {
    if (volume.isInside(X_WT * p_T, isovalue)) ++count;
  }
  return count;
}

namespace {

bool anyInside(const haptics::ScalarVolume& volume, const haptics::PointShell& shell, const Pose& X_WT,
               double isovalue) noexcept {
  for (const Eigen::Vector3d& p_T : shell.points_T_m()) {
    if (volume.isInside(X_WT * p_T, isovalue)) return true;
  }
  return false;
}

Pose translatedBy(const Pose& X_WT, const Eigen::Vector3d& d_W_m) {
  return {X_WT.R_AB, X_WT.p_AB_m + d_W_m};
}

}  // namespace

std::optional<double> firstContactDistance(const haptics::ScalarVolume& volume,
                                           const haptics::PointShell& shell, const Pose& X_WT_start,
                                           const Eigen::Vector3d& dir_W, double max_distance_m,
                                           double isovalue, double tolerance_m) {
  const Eigen::Vector3d d = dir_W.normalized();
  const double f = volume.featureSize_m();
  const double tolerance = tolerance_m > 0.0 ? tolerance_m : f / 8.0;
  if (anyInside(volume, shell, X_WT_start, isovalue)) return 0.0;
  // Pure translation: every point moves exactly the step, at most f (section 2.3).
  const double step = f;
  double free_s = 0.0;
  double hit_s = -1.0;
  for (double s = step;; s += step) {
    const double s_clamped = std::min(s, max_distance_m);
    if (anyInside(volume, shell, translatedBy(X_WT_start, s_clamped * d), isovalue)) {
      hit_s = s_clamped;
      break;
    }
    free_s = s_clamped;
    if (s_clamped >= max_distance_m) break;
  }
  if (hit_s < 0.0) return std::nullopt;
  while (hit_s - free_s > tolerance) {
    const double mid = 0.5 * (free_s + hit_s);
    if (anyInside(volume, shell, translatedBy(X_WT_start, mid * d), isovalue)) {
      hit_s = mid;
    } else {
      free_s = mid;
    }
  }
  return free_s;
}

Pose poseAboveVolume(const haptics::ScalarVolume& volume, const haptics::PointShell& shell,
                     const Eigen::Quaterniond& R_WT, double clearance_m) {
  const Eigen::Vector3d lo = volume.boundsMin_W_m(), hi = volume.boundsMax_W_m();
  const Eigen::Quaterniond R = R_WT.normalized();
  // Lowest points of the rotated tool; centre the band of points near the bottom over the box.
  double z_min = std::numeric_limits<double>::infinity(), z_max = -z_min;
  for (const Eigen::Vector3d& p_T : shell.points_T_m()) {
    const double z = (R * p_T).z();
    z_min = std::min(z_min, z);
    z_max = std::max(z_max, z);
  }
  Eigen::Vector3d bottom_centre = Eigen::Vector3d::Zero();
  if (!shell.empty()) {
    const double band = 0.01 * (z_max - z_min) + 1e-9;  // points within 1% of the height
    int n = 0;
    for (const Eigen::Vector3d& p_T : shell.points_T_m()) {
      const Eigen::Vector3d p = R * p_T;
      if (p.z() <= z_min + band) {
        bottom_centre += p;
        ++n;
      }
    }
    bottom_centre /= std::max(n, 1);
  } else {
    z_min = 0.0;
  }
  const Eigen::Vector3d centre = 0.5 * (lo + hi);
  Pose X_WT;
  X_WT.R_AB = R;
  X_WT.p_AB_m = Eigen::Vector3d(centre.x() - bottom_centre.x(), centre.y() - bottom_centre.y(),
                                hi.z() + clearance_m - z_min);
  return X_WT;
}

Pose defaultInitialPose(const haptics::ScalarVolume& volume, const haptics::PointShell& shell,
                        const Eigen::Quaterniond& R_WT, double isovalue) {
  const double f = volume.featureSize_m();
  const Pose above = poseAboveVolume(volume, shell, R_WT, 2.0 * f);
  const Eigen::Vector3d extent = volume.boundsMax_W_m() - volume.boundsMin_W_m();
  double tool_height = 0.0;
  if (!shell.empty()) {
    double z_lo = std::numeric_limits<double>::infinity(), z_hi = -z_lo;
    for (const Eigen::Vector3d& p_T : shell.points_T_m()) {
      const double z = (above.R_AB * p_T).z();
      z_lo = std::min(z_lo, z);
      z_hi = std::max(z_hi, z);
    }
    tool_height = z_hi - z_lo;
  }
  const double max_distance = extent.z() + tool_height + 4.0 * f;
  const auto contact = firstContactDistance(volume, shell, above, -Eigen::Vector3d::UnitZ(),
                                            max_distance, isovalue);
  if (!contact) return above;
  const double back_off = std::clamp(0.1 * extent.maxCoeff(), 2.0 * f, 0.01);
  return translatedBy(above, -std::max(0.0, *contact - back_off) * Eigen::Vector3d::UnitZ());
}

Pose legalPoseNear(const haptics::ScalarVolume& volume, const haptics::PointShell& shell, const Pose& X_WT,
                   double isovalue, const std::optional<Pose>& fallback) {
  if (!anyInside(volume, shell, X_WT, isovalue)) return X_WT;
  if (fallback && !anyInside(volume, shell, *fallback, isovalue)) return *fallback;
  return defaultInitialPose(volume, shell, X_WT.R_AB, isovalue);
}

namespace {

/// The geometry shared by the approach lines: where a line's approach starts and how far it may go.
struct Approach {
  Eigen::Vector3d dir;   // unit, W
  Eigen::Quaterniond R;  // the tool's orientation, normalised
  double outside_m;      // start this far before the aim: no shell point in the box from there
  double max_travel_m;   // then go at most this far
};

std::optional<Approach> approachFor(const haptics::ScalarVolume& volume, const haptics::PointShell& shell,
                                    const Eigen::Vector3d& p_TCm_m, const Eigen::Quaterniond& R_WT,
                                    const Eigen::Vector3d& dir_W, const Eigen::Vector3d& aim_W) {
  if (!dir_W.allFinite() || dir_W.norm() < 1e-9 || !aim_W.allFinite() || shell.empty()) return std::nullopt;
  const Eigen::Vector3d lo = volume.boundsMin_W_m(), hi = volume.boundsMax_W_m();
  // The tool's reach about its centre of mass [m]; the box's farthest corner from the aim [m].
  double reach_m = 0.0;
  for (const Eigen::Vector3d& p_T : shell.points_T_m()) reach_m = std::max(reach_m, (p_T - p_TCm_m).norm());
  double corner_m = 0.0;
  for (int c = 0; c < 8; ++c) {
    const Eigen::Vector3d corner((c & 1) ? hi.x() : lo.x(), (c & 2) ? hi.y() : lo.y(), (c & 4) ? hi.z() : lo.z());
    corner_m = std::max(corner_m, (corner - aim_W).norm());
  }
  const double margin_m = std::max(0.005, 0.05 * (hi - lo).norm());
  const double outside_m = corner_m + reach_m + margin_m;
  return Approach{dir_W.normalized(), R_WT.normalized(), outside_m, outside_m + corner_m + reach_m};
}

/// The approach along the line along a.dir through `through_W` (the tool's centre of mass on it).
std::optional<SurfaceTouch> touchAlong(const haptics::ScalarVolume& volume, const haptics::PointShell& shell,
                                       const Eigen::Vector3d& p_TCm_m, const Approach& a,
                                       const Eigen::Vector3d& through_W, double isovalue, double depth_m) {
  const Pose from{a.R, through_W - a.outside_m * a.dir - a.R * p_TCm_m};
  const std::optional<double> free_m =
      firstContactDistance(volume, shell, from, a.dir, a.max_travel_m, isovalue, 0.05 * volume.featureSize_m());
  if (!free_m) return std::nullopt;
  SurfaceTouch touch;
  touch.X_WP = translatedBy(from, *free_m * a.dir);
  touch.X_WD = translatedBy(touch.X_WP, std::max(0.0, depth_m) * a.dir);
  touch.dir_W = a.dir;
  return touch;
}

}  // namespace

std::optional<SurfaceTouch> touchSurfacePose(const haptics::ScalarVolume& volume, const haptics::PointShell& shell,
                                             const Eigen::Vector3d& p_TCm_m, const Eigen::Quaterniond& R_WT,
                                             const Eigen::Vector3d& dir_W, const Eigen::Vector3d& aim_W,
                                             double isovalue, double depth_m) {
  const std::optional<Approach> a = approachFor(volume, shell, p_TCm_m, R_WT, dir_W, aim_W);
  if (!a) return std::nullopt;
  const double diagonal_m = (volume.boundsMax_W_m() - volume.boundsMin_W_m()).norm();
  const Eigen::Vector3d e1 = a->dir.unitOrthogonal();
  const Eigen::Vector3d e2 = a->dir.cross(e1);
  for (const double ring : {0.0, 0.05, 0.1, 0.2, 0.3}) {
    const int n = ring == 0.0 ? 1 : 8;
    for (int k = 0; k < n; ++k) {
      const double angle = 2.0 * std::numbers::pi * k / n;
      const Eigen::Vector3d through_W = aim_W + ring * diagonal_m * (std::cos(angle) * e1 + std::sin(angle) * e2);
      if (auto touch = touchAlong(volume, shell, p_TCm_m, *a, through_W, isovalue, depth_m)) return touch;
    }
  }
  return std::nullopt;
}

std::optional<SurfaceTouch> touchSurfacePoseOnLine(const haptics::ScalarVolume& volume,
                                                   const haptics::PointShell& shell, const Eigen::Vector3d& p_TCm_m,
                                                   const Eigen::Quaterniond& R_WT, const Eigen::Vector3d& dir_W,
                                                   const Eigen::Vector3d& through_W, double isovalue, double depth_m) {
  const std::optional<Approach> a = approachFor(volume, shell, p_TCm_m, R_WT, dir_W, through_W);
  if (!a) return std::nullopt;
  return touchAlong(volume, shell, p_TCm_m, *a, through_W, isovalue, depth_m);
}

std::optional<SurfaceTouch> touchSurfaceTipFirst(const haptics::ScalarVolume& volume, const haptics::PointShell& shell,
                                                 const Eigen::Vector3d& p_TCm_m, const Eigen::Vector3d& tip_T_m,
                                                 const Eigen::Quaterniond& R_WT, const Eigen::Vector3d& dir_W,
                                                 const Eigen::Vector3d& through_W, double isovalue, double depth_m) {
  if (!dir_W.allFinite() || dir_W.norm() < 1e-9 || !through_W.allFinite()) return std::nullopt;
  const Eigen::Vector3d axis_T = tip_T_m - p_TCm_m;
  if (!axis_T.allFinite() || axis_T.norm() < 1e-9) return std::nullopt;
  const Eigen::Vector3d dir = dir_W.normalized();
  // The line from outside the box, past its far side: where it first enters the surface.
  const Eigen::Vector3d lo = volume.boundsMin_W_m(), hi = volume.boundsMax_W_m();
  double reach_m = 0.0;
  for (int c = 0; c < 8; ++c) {
    const Eigen::Vector3d corner((c & 1) ? hi.x() : lo.x(), (c & 2) ? hi.y() : lo.y(), (c & 4) ? hi.z() : lo.z());
    reach_m = std::max(reach_m, (corner - through_W).norm());
  }
  const Eigen::Vector3d a_W = through_W - (reach_m + 1e-3) * dir, b_W = through_W + (reach_m + 1e-3) * dir;
  const haptics::SegmentEntry entry =
      volume.firstEntryOnSegment(volume.gridCoordinates(a_W), volume.gridCoordinates(b_W), isovalue, 1.0, 1e-9);
  if (!entry.hit) return std::nullopt;
  const Eigen::Vector3d surface_W = a_W + entry.u_inside * (b_W - a_W);
  // Into the surface: F grows inwards (inside is F > s), so along the gradient.
  const Eigen::Vector3d g_W = volume.gradient(surface_W);
  Eigen::Vector3d in_W = dir;
  if (g_W.allFinite() && g_W.norm() > 0.0 && g_W.normalized().dot(dir) > 0.0) in_W = g_W.normalized();
  const Eigen::Quaterniond R = (Eigen::Quaterniond::FromTwoVectors(R_WT.normalized() * axis_T.normalized(), in_W) *
                                R_WT.normalized()).normalized();
  return touchSurfacePoseOnLine(volume, shell, p_TCm_m, R, in_W, surface_W, isovalue, depth_m);
}

std::optional<Eigen::Vector3d> insideBoxCentre_W(const haptics::ScalarVolume& volume, double isovalue) {
  const haptics::VolumeGeometry& g = volume.geometry();
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
  Eigen::Vector3d hi = -lo;
  bool any = false;
  for (int k = 0; k < g.dims[2]; ++k) {
    for (int j = 0; j < g.dims[1]; ++j) {
      for (int i = 0; i < g.dims[0]; ++i) {
        if (!(volume.voxel(i, j, k) > isovalue)) continue;
        const Eigen::Vector3d p_W = g.pointOf_W(Eigen::Vector3d(i, j, k));
        lo = lo.cwiseMin(p_W);
        hi = hi.cwiseMax(p_W);
        any = true;
      }
    }
  }
  if (!any) return std::nullopt;
  return Eigen::Vector3d(0.5 * (lo + hi));
}

}  // namespace vh::runtime
