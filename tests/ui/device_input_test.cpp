// DeviceInput on the built-in sphere (radius 20 mm about the origin, F = 20 mm - r, isovalue 0)
// with the probe above it and a simulated device. Oracles: the analytic sphere (how deep the
// tool's point shell goes after touchSurface()), the field's bounds (the wheel step) and the
// scene's initial pose (the Home key).
#include "vh/ui/devices/device_input.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>

#include <QCoreApplication>
#include <QKeyEvent>
#include <QVBoxLayout>
#include <QWidget>

#include <gtest/gtest.h>

#include "ui_test_util.h"
#include <vtkActor.h>
#include <vtkMatrix4x4.h>

#include "vh/haptics/point_shell.h"
#include "vh/runtime/scene.h"
#include "vh/runtime/session.h"
#include "vh/ui/export/media_export.h"
#include "vh/ui/view/scene_view.h"
#include "vh/ui/view/vtk_view.h"

namespace vh::ui {
namespace {

using test::sphereProbeScene;

using haptics::Pose;


/// The shell point nearest the sphere's centre when the tool is at `X_WT`: its distance [m].
double deepestRadius_m(const haptics::PointShell& shell, const Pose& X_WT) {
  double r = std::numeric_limits<double>::infinity();
  for (const Eigen::Vector3d& p_T : shell.points_T_m()) r = std::min(r, (X_WT * p_T).norm());
  return r;
}

/// A session with a simulated device at the initial pose, shown in a small view.
struct ViewAndDevice {
  ViewAndDevice() {
    const runtime::LoadedScene& scene = sphereProbeScene();
    session.setScene(scene, std::make_shared<runtime::SimulatedDevice>(scene.X_WT_initial));
    auto* layout = new QVBoxLayout(&host);
    layout->setContentsMargins(0, 0, 0, 0);
    view = new SceneView(&host);
    layout->addWidget(view->widget());
    view->setScene(sceneActorsSpecFor(scene, runtime::LiveValues::initial(scene)), scene.X_WT_initial, ViewLook{});
    input = new DeviceInput(session, *view);  // owned by the view
    host.resize(240, 180);
    host.show();
  }

  runtime::Session session;
  QWidget host;
  SceneView* view = nullptr;
  DeviceInput* input = nullptr;
};

TEST(DeviceInput, TouchSurfaceSinksTheToolTheDepthAskedIntoTheSphere) {
  ViewAndDevice s;
  const haptics::PointShell& shell = s.session.live().tool->point_shell;
  ASSERT_FALSE(shell.empty());
  const Pose start = s.session.simulatedDevice()->pose();
  ASSERT_GT(deepestRadius_m(shell, start), 0.020) << "the probe starts clear of the sphere";

  ASSERT_TRUE(s.input->touchSurface(0.002));
  const Pose X_WD = s.session.simulatedDevice()->pose();
  EXPECT_NEAR(deepestRadius_m(shell, X_WD), 0.020 - 0.002, 0.3e-3);
  // Down towards the volume's centre, which lies below the tool (x and y within 0.05 mm); the
  // orientation stays.
  EXPECT_NEAR(X_WD.p_AB_m.x(), start.p_AB_m.x(), 0.05e-3);
  EXPECT_NEAR(X_WD.p_AB_m.y(), start.p_AB_m.y(), 0.05e-3);
  EXPECT_LT(X_WD.p_AB_m.z(), start.p_AB_m.z() - 1e-3);
  EXPECT_LT(X_WD.R_AB.angularDistance(start.R_AB), 1e-12);
  // The view shows the device tool where it went.
  vtkMatrix4x4* m = s.view->actors().deviceActor()->GetUserMatrix();
  ASSERT_NE(m, nullptr);
  for (int r = 0; r < 3; ++r) EXPECT_NEAR(m->GetElement(r, 3), X_WD.p_AB_m[r], 1e-12);
}

TEST(DeviceInput, TheWheelStepIsA200thOfTheVolumesDiagonal) {
  ViewAndDevice s;
  const auto& field = *sphereProbeScene().volume.field;
  const double diagonal_m = (field.boundsMax_W_m() - field.boundsMin_W_m()).norm();
  EXPECT_NEAR(s.input->wheelStep_m(), std::clamp(diagonal_m / 200.0, 0.5e-3, 5e-3), 1e-15);
  // 64^3 voxels of 1 mm: a diagonal of about 110 mm, a step of about 0.55 mm.
  EXPECT_NEAR(s.input->wheelStep_m(), 0.55e-3, 0.01e-3);
}

TEST(DeviceInput, HomeBringsTheDeviceBackToTheInitialPose) {
  ViewAndDevice s;
  ASSERT_TRUE(s.input->touchSurface(0.001));
  const Pose& X_WT = sphereProbeScene().X_WT_initial;
  ASSERT_GT((s.session.simulatedDevice()->pose().p_AB_m - X_WT.p_AB_m).norm(), 1e-3);
  QKeyEvent home(QEvent::KeyPress, Qt::Key_Home, Qt::NoModifier);
  EXPECT_TRUE(QCoreApplication::sendEvent(s.view->widget(), &home)) << "the view's filter takes the key";
  EXPECT_LT((s.session.simulatedDevice()->pose().p_AB_m - X_WT.p_AB_m).norm(), 1e-12);
  EXPECT_LT(s.session.simulatedDevice()->pose().R_AB.angularDistance(X_WT.R_AB), 1e-12);
}

TEST(DeviceInput, WithoutASimulatedDeviceNothingMoves) {
  ViewAndDevice s;
  s.session.setDevice(nullptr);
  EXPECT_FALSE(s.input->touchSurface(0.002));
  QKeyEvent home(QEvent::KeyPress, Qt::Key_Home, Qt::NoModifier);
  QCoreApplication::sendEvent(s.view->widget(), &home);  // nothing to move; must not crash
  EXPECT_EQ(s.session.device(), nullptr);
}

}  // namespace
}  // namespace vh::ui
