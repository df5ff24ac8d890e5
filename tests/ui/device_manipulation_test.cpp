// Mouse -> device mapping: pure geometry with exact answers.
#include "vh/ui/view/device_manipulation.h"

#include <cmath>
#include <numbers>

#include <gtest/gtest.h>

#include <vtkCamera.h>
#include <vtkMatrix4x4.h>
#include <vtkNew.h>

#include "vh/ui/view/scene_actors.h"

namespace vh::ui {
namespace {

// Camera on +z looking at the origin, y up, 1000 px high, 90 degree field of view: at depth d
// one pixel is 2 d tan(45 deg) / 1000 = d / 500 metres.
ViewCamera testCamera() {
  ViewCamera c;
  c.position_W_m = Eigen::Vector3d(0, 0, 1.0);
  c.focal_point_W_m = Eigen::Vector3d::Zero();
  c.view_up_W = Eigen::Vector3d(0, 1, 0.2);  // not orthogonal: must be orthogonalised
  c.view_angle_deg = 90.0;
  c.viewport_height_px = 1000;
  return c;
}

TEST(ViewCamera, FrameIsOrthonormalAndRightHanded) {
  const ViewCamera c = testCamera();
  EXPECT_TRUE(c.forward_W().isApprox(Eigen::Vector3d(0, 0, -1)));
  EXPECT_TRUE(c.right_W().isApprox(Eigen::Vector3d(1, 0, 0)));
  EXPECT_TRUE(c.up_W().isApprox(Eigen::Vector3d(0, 1, 0)));
}

TEST(ViewCamera, MetresPerPixelScalesWithDepth) {
  const ViewCamera c = testCamera();
  EXPECT_NEAR(c.metresPerPixelAt(Eigen::Vector3d(0, 0, 0)), 1.0 / 500.0, 1e-12);
  EXPECT_NEAR(c.metresPerPixelAt(Eigen::Vector3d(0.3, 0, -1.0)), 2.0 / 500.0, 1e-12);
  ViewCamera p = c;
  p.parallel = true;
  p.parallel_scale_m = 0.25;  // view 0.5 m high
  EXPECT_NEAR(p.metresPerPixelAt(Eigen::Vector3d(0, 0, -5)), 0.5 / 1000.0, 1e-12);
}

TEST(DeviceManipulation, DragFollowsTheCursorAtTheAnchorDepth) {
  const ViewCamera c = testCamera();
  haptics::Pose X_WD;
  X_WD.p_AB_m = Eigen::Vector3d(0.1, 0.0, 0.0);
  // 50 px right and 100 px down (Qt's y points down) at depth 1 m: +0.1 m x, -0.2 m y.
  const haptics::Pose moved = dragInViewPlane(X_WD, c, X_WD.p_AB_m, 50.0, 100.0);
  EXPECT_TRUE(moved.p_AB_m.isApprox(Eigen::Vector3d(0.2, -0.2, 0.0)));
  EXPECT_TRUE(moved.R_AB.isApprox(X_WD.R_AB));
}

TEST(DeviceManipulation, MoveAlongViewGoesAwayFromTheEye) {
  const haptics::Pose moved = moveAlongView(haptics::Pose::Identity(), testCamera(), 0.01);
  EXPECT_TRUE(moved.p_AB_m.isApprox(Eigen::Vector3d(0, 0, -0.01)));
}

TEST(DeviceManipulation, TrackballKeepsTheCentreAndTurnsTheFrontRight) {
  const ViewCamera c = testCamera();
  haptics::Pose X_WD;
  X_WD.p_AB_m = Eigen::Vector3d(0.05, 0.02, -0.1);
  const Eigen::Vector3d p_D_centre(0.0, 0.0, 0.03);
  const Eigen::Vector3d c_before = X_WD * p_D_centre;
  // 100 px right at pi/200 rad per px: a quarter turn about screen-up.
  const haptics::Pose turned = rotateTrackball(X_WD, c, p_D_centre, 100.0, 0.0,
                                               std::numbers::pi / 200.0);
  EXPECT_TRUE((turned * p_D_centre).isApprox(c_before, 1e-12));
  // The device's +z (towards the viewer) now points to screen-right.
  EXPECT_TRUE((turned.R_AB * Eigen::Vector3d::UnitZ()).isApprox(Eigen::Vector3d::UnitX(), 1e-12));
  EXPECT_NEAR(turned.R_AB.norm(), 1.0, 1e-12);
  // Dragging up (negative dy) turns the front up.
  const haptics::Pose up = rotateTrackball(haptics::Pose::Identity(), c, Eigen::Vector3d::Zero(),
                                           0.0, -100.0, std::numbers::pi / 200.0);
  EXPECT_TRUE((up.R_AB * Eigen::Vector3d::UnitZ()).isApprox(Eigen::Vector3d::UnitY(), 1e-12));
}

/// Where VTK's camera draws `p_W` in a `w` x `h` view, in pixels with y down (the oracle for
/// rayThroughPixel(): vtkCamera's own projection matrix, not our geometry).
Eigen::Vector2d vtkPixelOf(vtkCamera* camera, const Eigen::Vector3d& p_W, int w, int h) {
  vtkMatrix4x4* m = camera->GetCompositeProjectionTransformMatrix(static_cast<double>(w) / h, -1.0, 1.0);
  const double in[4] = {p_W.x(), p_W.y(), p_W.z(), 1.0};
  double out[4];
  m->MultiplyPoint(in, out);
  const double x_ndc = out[0] / out[3], y_ndc = out[1] / out[3];
  return {(x_ndc + 1.0) * 0.5 * w, (1.0 - y_ndc) * 0.5 * h};
}

TEST(ViewRay, EveryPointOfThePixelsRayProjectsOntoThatPixelAsVtksCameraSeesIt) {
  const int w = 640, h = 360;  // wider than high: the aspect matters
  for (const bool parallel : {false, true}) {
    SCOPED_TRACE(parallel ? "parallel" : "perspective");
    vtkNew<vtkCamera> camera;
    camera->SetPosition(0.3, -0.4, 0.5);
    camera->SetFocalPoint(0.01, 0.02, -0.03);
    camera->SetViewUp(0.1, 0.2, 1.0);
    camera->OrthogonalizeViewUp();
    camera->SetViewAngle(35.0);
    camera->SetParallelProjection(parallel);
    camera->SetParallelScale(0.12);
    const ViewCamera c = viewCameraOf(camera, h, w);  // as the view reads its camera
    for (const Eigen::Vector2d px : {Eigen::Vector2d(320, 180), Eigen::Vector2d(10.5, 20.25), Eigen::Vector2d(600, 350)}) {
      const ViewRay ray = rayThroughPixel(c, px.x(), px.y());
      EXPECT_NEAR(ray.dir_W.norm(), 1.0, 1e-12);
      EXPECT_GT(ray.dir_W.dot(c.forward_W()), 0.0) << "away from the viewer";
      for (const double t : {0.2, 0.7, 1.5}) {
        const Eigen::Vector2d seen = vtkPixelOf(camera, ray.origin_W_m + t * ray.dir_W, w, h);
        EXPECT_NEAR(seen.x(), px.x(), 1e-6) << "t " << t;
        EXPECT_NEAR(seen.y(), px.y(), 1e-6) << "t " << t;
      }
    }
  }
}

}  // namespace
}  // namespace vh::ui
