// SceneView on the built-in sphere (radius 20 mm, 64^3 voxels of 1 mm) with the probe tool.
// Oracles: the poses handed in (the proxy actor's matrix), the tool mesh's own vertices (the
// force arrow starts at the lowest one, found by brute force) and the volume's bounds (the
// clipping plane's position).
#include "vh/ui/view/scene_view.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <string>

#include <QVBoxLayout>
#include <QWidget>

#include <gtest/gtest.h>
#include <vtkActor.h>
#include <vtkActor2DCollection.h>
#include <vtkGPUVolumeRayCastMapper.h>
#include <vtkMatrix4x4.h>
#include <vtkPlane.h>
#include <vtkPlaneCollection.h>
#include <vtkRenderer.h>
#include <vtkTextActor.h>

#include "ui_test_util.h"
#include "vh/runtime/scene.h"
#include "vh/ui/export/media_export.h"
#include "vh/ui/view/vtk_view.h"

namespace vh::ui {
namespace {

using test::sphereProbeScene;

using haptics::Pose;


/// A small window holding a SceneView (the host owns the view and its widget).
struct ViewWindow {
  ViewWindow() {
    auto* layout = new QVBoxLayout(&host);
    layout->setContentsMargins(0, 0, 0, 0);
    view = new SceneView(&host);
    layout->addWidget(view->widget());
    host.resize(240, 180);
    host.show();
  }
  void load() { view->setScene(sceneActorsSpecFor(sphereProbeScene(), runtime::LiveValues::initial(sphereProbeScene())), sphereProbeScene().X_WT_initial, ViewLook{}); }

  QWidget host;
  SceneView* view = nullptr;
};

Eigen::Vector3d translationOf(vtkActor* actor) {
  vtkMatrix4x4* m = actor->GetUserMatrix();
  return {m->GetElement(0, 3), m->GetElement(1, 3), m->GetElement(2, 3)};
}

/// The welcome text of an empty view (the renderer's text actor that says "Open a scan").
vtkTextActor* welcomeText(SceneView& view) {
  vtkActor2DCollection* actors = view.widget()->renderer()->GetActors2D();
  actors->InitTraversal();
  while (vtkActor2D* a = actors->GetNextActor2D()) {
    auto* text = vtkTextActor::SafeDownCast(a);
    if (text != nullptr && text->GetInput() != nullptr && std::string(text->GetInput()).starts_with("Open a scan")) {
      return text;
    }
  }
  return nullptr;
}

TEST(SceneView, AMovedProxyAsksForANewFrameAndTheSameFrameDoesNot) {
  ViewWindow w;
  w.load();
  ToolFrame frame;
  frame.X_WP.R_AB = Eigen::Quaterniond(Eigen::AngleAxisd(std::numbers::pi / 6, Eigen::Vector3d::UnitX()));
  frame.X_WP.p_AB_m = sphereProbeScene().X_WT_initial.p_AB_m + Eigen::Vector3d(0.003, -0.002, 0.001);
  frame.X_WD = frame.X_WP;
  EXPECT_TRUE(w.view->show(frame));
  EXPECT_FALSE(w.view->show(frame)) << "nothing moved: no new frame";

  // The proxy actor's user matrix is X_WP: rotation 30 degrees about x, the translation given.
  vtkMatrix4x4* m = w.view->actors().proxyActor()->GetUserMatrix();
  ASSERT_NE(m, nullptr);
  const double c = std::cos(std::numbers::pi / 6), s = std::sin(std::numbers::pi / 6);
  const double R[3][3] = {{1, 0, 0}, {0, c, -s}, {0, s, c}};
  for (int r = 0; r < 3; ++r) {
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(m->GetElement(r, k), R[r][k], 1e-12) << r << "," << k;
    EXPECT_NEAR(m->GetElement(r, 3), frame.X_WP.p_AB_m[r], 1e-12);
  }
  EXPECT_TRUE(w.view->shownProxyPose().p_AB_m.isApprox(frame.X_WP.p_AB_m, 1e-12));

  // Half a millimetre further: a new frame again.
  frame.X_WP.p_AB_m.z() += 0.0005;
  EXPECT_TRUE(w.view->show(frame));
  EXPECT_NEAR(translationOf(w.view->actors().proxyActor()).z(), frame.X_WP.p_AB_m.z(), 1e-12);
}

TEST(SceneView, TheForceArrowStartsAtTheToolsLowestVertexWhenPushedUp) {
  ViewWindow w;
  w.load();
  // The probe tilted 20 degrees about y, pushed up by 2 N.
  ToolFrame frame;
  frame.X_WP.R_AB = Eigen::Quaterniond(Eigen::AngleAxisd(20.0 * std::numbers::pi / 180.0, Eigen::Vector3d::UnitY()));
  frame.X_WP.p_AB_m = Eigen::Vector3d(0.001, 0.002, 0.021);
  frame.X_WD = frame.X_WP;
  frame.force_W_N = Eigen::Vector3d(0.0, 0.0, 2.0);
  ASSERT_TRUE(w.view->show(frame));

  double lowest_z = std::numeric_limits<double>::infinity();
  const auto& vertices_T = sphereProbeScene().tool->mesh_T.vertices_T_m;
  ASSERT_FALSE(vertices_T.empty());
  for (const Eigen::Vector3d& v : vertices_T) lowest_z = std::min(lowest_z, (frame.X_WP * v).z());
  vtkActor* arrow = w.view->actors().forceActor();
  ASSERT_TRUE(arrow->GetVisibility());
  const Eigen::Vector3d origin = translationOf(arrow);
  EXPECT_NEAR(origin.z(), lowest_z, 1e-9) << "the arrow starts at the lowest point of the tool";
  double nearest = std::numeric_limits<double>::infinity();
  for (const Eigen::Vector3d& v : vertices_T) nearest = std::min(nearest, (frame.X_WP * v - origin).norm());
  EXPECT_LT(nearest, 1e-9) << "the arrow starts at a vertex of the tool";
  // The tip (ball of 2 mm about T's origin) is the lowest part: well below the proxy's origin.
  EXPECT_NEAR(origin.z(), frame.X_WP.p_AB_m.z() - 0.002, 0.2e-3);

  // No force: the arrow is hidden.
  frame.force_W_N.setZero();
  ASSERT_TRUE(w.view->show(frame));
  EXPECT_FALSE(arrow->GetVisibility());
}

TEST(SceneView, TheClippingPlaneSitsAtTheFractionOfTheVolumesExtent) {
  ViewWindow w;
  w.load();
  double b[6];
  w.view->actors().volumeBounds_W(b);
  ASSERT_LT(b[4], b[5]);
  w.view->setClipping(true, ClipAxis::kZ, 0.25, false);
  vtkPlaneCollection* planes = w.view->actors().volumeMapper()->GetClippingPlanes();
  ASSERT_NE(planes, nullptr);
  ASSERT_EQ(planes->GetNumberOfItems(), 1);
  vtkPlane* plane = planes->GetItem(0);
  double o[3], n[3];
  plane->GetOrigin(o);
  plane->GetNormal(n);
  EXPECT_NEAR(o[2], b[4] + 0.25 * (b[5] - b[4]), 1e-12);
  EXPECT_NEAR(n[0], 0.0, 1e-12);
  EXPECT_NEAR(n[1], 0.0, 1e-12);
  EXPECT_NEAR(n[2], 1.0, 1e-12) << "the upper side is kept";
  // The sphere's volume is about 63 mm high and centred on the origin: the plane near -16 mm.
  EXPECT_NEAR(o[2], -0.016, 1.5e-3);

  w.view->setClipping(true, ClipAxis::kX, 0.75, true);
  planes = w.view->actors().volumeMapper()->GetClippingPlanes();
  ASSERT_EQ(planes->GetNumberOfItems(), 1);
  planes->GetItem(0)->GetOrigin(o);
  planes->GetItem(0)->GetNormal(n);
  EXPECT_NEAR(o[0], b[0] + 0.75 * (b[1] - b[0]), 1e-12);
  EXPECT_NEAR(n[0], -1.0, 1e-12) << "flipped: the lower side is kept";

  w.view->setClipping(false, ClipAxis::kX, 0.75, true);
  planes = w.view->actors().volumeMapper()->GetClippingPlanes();
  EXPECT_TRUE(planes == nullptr || planes->GetNumberOfItems() == 0);
}

TEST(SceneView, TheWelcomeTextGoesWithTheFirstScene) {
  ViewWindow w;
  vtkTextActor* welcome = welcomeText(*w.view);
  ASSERT_NE(welcome, nullptr);
  EXPECT_TRUE(welcome->GetVisibility());
  EXPECT_FALSE(w.view->hasScene());
  w.load();
  EXPECT_TRUE(w.view->hasScene());
  EXPECT_FALSE(welcome->GetVisibility());
  EXPECT_TRUE(test::waitFor([&] { return w.view->widget()->frameCount() > 0; }, 20000)) << "the view never rendered";
  w.view->clearScene();
  EXPECT_FALSE(w.view->hasScene());
  EXPECT_FALSE(welcome->GetVisibility()) << "once a scene was shown the welcome text stays hidden";
}

}  // namespace
}  // namespace vh::ui
