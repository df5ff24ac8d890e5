#pragma once
/// @file
/// Static queries of a tool's point shell against a volume's isosurface F = s, outside the servo
/// loop: placing a tool (initial poses, first contact along a ray) and measuring penetration
/// (the headless runner's check). Inside means F(p) > s within the grid (paper section 2.2).

#include <optional>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "vh/haptics/penetration.h"
#include "vh/haptics/point_shell.h"
#include "vh/haptics/pose.h"
#include "vh/haptics/scalar_volume.h"

namespace vh::runtime {

/// Number of shell points (in T) inside the isosurface when the tool is at X_WT.
int countPointsInside(const haptics::ScalarVolume& volume, const haptics::PointShell& shell,
                      const haptics::Pose& X_WT, double isovalue) noexcept;

/// (The penetration measure itself is haptics::maxPenetration_m, vh/haptics/penetration.h.)

/// Distance [m] the tool can translate from X_WT_start along unit `dir_W` before a shell point
/// first enters the isosurface, to within `tolerance_m` (the returned distance is on the free
/// side). Every point moves at most the volume's feature size f between tests, so no surface
/// is skipped (section 2.3). @return nullopt when nothing is met within max_distance_m.
/// The start pose should be free (a point already inside is reported as contact at 0).
std::optional<double> firstContactDistance(const haptics::ScalarVolume& volume,
                                           const haptics::PointShell& shell,
                                           const haptics::Pose& X_WT_start,
                                           const Eigen::Vector3d& dir_W, double max_distance_m,
                                           double isovalue, double tolerance_m = 0.0);

/// A pose with orientation R_WT whose lowest shell point lies `clearance_m` above the top
/// (+z of W) of the volume's bounding box, over the box's centre in x and y: always free.
haptics::Pose poseAboveVolume(const haptics::ScalarVolume& volume,
                              const haptics::PointShell& shell, const Eigen::Quaterniond& R_WT,
                              double clearance_m);

/// The default initial pose of a scene's tool (orientation R_WT): lowered from
/// poseAboveVolume() along -z onto the isosurface over the volume's centre, then backed off
/// by a clearance of 10% of the volume's extent clamped to [2 f, 10 mm]; the pose above the
/// volume when the ray meets nothing. Always free.
haptics::Pose defaultInitialPose(const haptics::ScalarVolume& volume,
                                 const haptics::PointShell& shell, const Eigen::Quaterniond& R_WT,
                                 double isovalue);

/// A pose for the tool near X_WT that no shell point is inside: X_WT itself when it is free,
/// else `fallback` when given and free, else defaultInitialPose() with X_WT's orientation (above
/// the volume). Where Reset Device and a restart of the haptic threads put the proxy, rather than
/// where it may have been held.
haptics::Pose legalPoseNear(const haptics::ScalarVolume& volume, const haptics::PointShell& shell,
                            const haptics::Pose& X_WT, double isovalue,
                            const std::optional<haptics::Pose>& fallback = std::nullopt);

}  // namespace vh::runtime
