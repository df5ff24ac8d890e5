#pragma once
/// @file
/// Mouse -> simulated device pose mapping (pure geometry, no Qt or VTK), so the program is
/// usable without haptic hardware. All poses are X_WD: the device's tool frame D in the world
/// frame W [m]. Pixel deltas are in widget pixels with y pointing down (Qt's convention).

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "vh/haptics/pose.h"

namespace vh::ui {

/// What the mapping needs of the camera, in W.
struct ViewCamera {
  Eigen::Vector3d position_W_m = Eigen::Vector3d(0, 0, 1);   ///< Eye position [m].
  Eigen::Vector3d focal_point_W_m = Eigen::Vector3d::Zero(); ///< Look-at point [m].
  Eigen::Vector3d view_up_W = Eigen::Vector3d::UnitY();       ///< Approximate up direction.
  double view_angle_deg = 30.0;  ///< Vertical field of view (perspective) [deg].
  bool parallel = false;         ///< Parallel projection.
  double parallel_scale_m = 1.0; ///< Half the view height (parallel projection) [m].
  int viewport_height_px = 1;    ///< Height of the view [px].
  int viewport_width_px = 1;     ///< Width of the view [px].

  /// Unit direction of projection (from the eye towards the focal point).
  Eigen::Vector3d forward_W() const;
  /// Unit screen-right direction.
  Eigen::Vector3d right_W() const;
  /// Unit screen-up direction (orthogonal to forward).
  Eigen::Vector3d up_W() const;
  /// Size of one pixel [m] in the plane through p_W parallel to the screen.
  double metresPerPixelAt(const Eigen::Vector3d& p_W_m) const;
};

/// A line of sight in W: the points origin_W_m + t * dir_W, t >= 0.
struct ViewRay {
  Eigen::Vector3d origin_W_m;  ///< Where it starts [m]: the eye (perspective), or the pixel's point in the plane through the eye (parallel).
  Eigen::Vector3d dir_W;       ///< Unit direction, away from the viewer.
};

/// The line of sight through the view's pixel (x_px, y_px) (y down, Qt's convention; (0, 0) the
/// top-left corner, the pixel's centre at +0.5), what the viewer sees there: the inverse of the
/// camera's projection (vtkCamera's, with the aspect of viewport_width_px / viewport_height_px).
ViewRay rayThroughPixel(const ViewCamera& camera, double x_px, double y_px);

/// Moves the device in the view plane so that the point p_W_anchor (e.g. the tool's centre)
/// follows the cursor: (dx, dy) pixels, y down.
haptics::Pose dragInViewPlane(const haptics::Pose& X_WD, const ViewCamera& camera,
                              const Eigen::Vector3d& p_W_anchor_m, double dx_px, double dy_px);

/// Moves the device along the view direction by distance_m [m] (positive: away from the eye).
haptics::Pose moveAlongView(const haptics::Pose& X_WD, const ViewCamera& camera, double distance_m);

/// Trackball rotation of the device about its point p_D_centre (in D, e.g. the centre of mass):
/// dragging right turns the side facing the viewer to the right, dragging up turns it up.
/// @param rad_per_px rotation per pixel of drag [rad].
haptics::Pose rotateTrackball(const haptics::Pose& X_WD, const ViewCamera& camera,
                              const Eigen::Vector3d& p_D_centre_m, double dx_px, double dy_px,
                              double rad_per_px);

}  // namespace vh::ui
