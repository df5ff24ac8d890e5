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

/// Where Touch the Surface puts the tools (touchSurfacePose()).
struct SurfaceTouch {
  haptics::Pose X_WP;     ///< Free: the tool's shell just meets the isosurface [m, W].
  haptics::Pose X_WD;     ///< X_WP moved `depth_m` further along the approach [m, W].
  Eigen::Vector3d dir_W;  ///< The approach direction (unit, W).
};

/// Touch the Surface's approach, as a placement (proxy and device put there together): the tool
/// at orientation `R_WT`, its centre of mass (`p_TCm_m`, in T [m]) on the line along `dir_W`
/// through `aim_W` [m, W], starts outside the volume's bounding box (every corner's distance
/// from `aim_W` plus the tool's reach about its centre of mass plus a margin of 5% of the
/// volume's diagonal, at least 5 mm) and moves along `dir_W` until a shell point first meets
/// the isosurface F = `isovalue` (firstContactDistance(), to 5% of the feature size): X_WP.
/// Where that line meets nothing (a hole in the surface), parallel lines on rings around it
/// (5, 10, 20 and 30% of the volume's diagonal, 8 lines each) are tried in turn.
/// @param dir_W the approach direction (e.g. the camera's view direction); normalised here.
/// @param depth_m how far the device goes past the contact [m] (negative: 0).
/// @return nullopt when no line meets the surface, or `dir_W` is zero or not finite.
std::optional<SurfaceTouch> touchSurfacePose(const haptics::ScalarVolume& volume, const haptics::PointShell& shell,
                                             const Eigen::Vector3d& p_TCm_m, const Eigen::Quaterniond& R_WT,
                                             const Eigen::Vector3d& dir_W, const Eigen::Vector3d& aim_W,
                                             double isovalue, double depth_m);

/// Touch the Surface at a picked point: as touchSurfacePose(), on the one line along `dir_W`
/// through `through_W` [m, W] (e.g. the ray under the cursor: the eye and its direction), with
/// no neighbouring lines tried, so the tool lands where the user pointed or not at all.
/// @return nullopt when the line meets no surface, or `dir_W` is zero or not finite.
std::optional<SurfaceTouch> touchSurfacePoseOnLine(const haptics::ScalarVolume& volume,
                                                   const haptics::PointShell& shell, const Eigen::Vector3d& p_TCm_m,
                                                   const Eigen::Quaterniond& R_WT, const Eigen::Vector3d& dir_W,
                                                   const Eigen::Vector3d& through_W, double isovalue, double depth_m);

/// Touch the Surface tip first, for a tool with a working end (a drill's burr): the first point
/// where the line along `dir_W` through `through_W` [m, W] enters the isosurface F = `isovalue`
/// (ScalarVolume::firstEntryOnSegment(), from outside the volume's box), the tool turned by the
/// smallest rotation that points its axis (from its centre of mass `p_TCm_m` to `tip_T_m`, both
/// in T [m]) along the field's gradient there (into the surface, eq. 1; the approach `dir_W`
/// itself where the gradient is zero or faces back against it), then approached along that
/// axis through the point (touchSurfacePoseOnLine()): the tip leads, so it is what touches.
/// `R_WT` is the tool's orientation before the turn (its roll about the axis is kept).
/// @return nullopt when the line meets no surface, `dir_W` is zero or not finite, or the tip
///         lies at the centre of mass (no axis).
std::optional<SurfaceTouch> touchSurfaceTipFirst(const haptics::ScalarVolume& volume, const haptics::PointShell& shell,
                                                 const Eigen::Vector3d& p_TCm_m, const Eigen::Vector3d& tip_T_m,
                                                 const Eigen::Quaterniond& R_WT, const Eigen::Vector3d& dir_W,
                                                 const Eigen::Vector3d& through_W, double isovalue, double depth_m);

/// The centre of the axis-aligned box (in W [m]) around the centres of the voxels inside the
/// isosurface (value > `isovalue`): where Touch the Surface aims at felt segments, whose
/// surfaces may lie anywhere in the volume. One pass over the voxels.
/// @return nullopt when no voxel is inside.
std::optional<Eigen::Vector3d> insideBoxCentre_W(const haptics::ScalarVolume& volume, double isovalue);

}  // namespace vh::runtime
