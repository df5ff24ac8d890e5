// DeviceInput on the built-in sphere (radius 20 mm about the origin, F = 20 mm - r, isovalue 0)
// with the probe above it and a simulated device. Oracles: the analytic sphere (how deep the
// tool's point shell goes after touchSurface()), the field's bounds (the wheel step) and the
// scene's initial pose (the Home key).
#include "vh/ui/devices/device_input.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <unistd.h>

#include <QCoreApplication>
#include <QTimer>
#include <QKeyEvent>
#include <QMouseEvent>
#include <QSignalSpy>
#include <QVBoxLayout>
#include <QWidget>

#include <gtest/gtest.h>

#include "ui_test_util.h"
#include <vtkActor.h>
#include <vtkCamera.h>
#include <vtkMatrix4x4.h>
#include <vtkRenderer.h>

#include "vh/haptics/point_shell.h"
#include "vh/runtime/drilling.h"
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
  explicit ViewAndDevice(const runtime::LoadedScene& scene = sphereProbeScene()) {
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
  // Along the view direction through the volume's centre (the origin), on the viewer's side:
  // the tool's centre of mass on that line within 0.05 mm; the orientation stays.
  const Eigen::Vector3d forward = s.view->camera().forward_W();
  const Eigen::Vector3d c_W = X_WD * s.session.live().tool->mass.p_TCm_m;
  EXPECT_LT((c_W - c_W.dot(forward) * forward).norm(), 0.05e-3) << "off the line of sight through the centre";
  EXPECT_LT(c_W.dot(forward), 0.0) << "on the far side of the sphere";
  EXPECT_LT(X_WD.R_AB.angularDistance(start.R_AB), 1e-12);
  // The view shows the device tool where it went.
  vtkMatrix4x4* m = s.view->actors().deviceActor()->GetUserMatrix();
  ASSERT_NE(m, nullptr);
  for (int r = 0; r < 3; ++r) EXPECT_NEAR(m->GetElement(r, 3), X_WD.p_AB_m[r], 1e-12);
}

// Touch the Surface with the built-in drill (no drill settings yet: the burr has not been
// switched on, the mesh says it is a drill), held upright while the view looks from the front:
// the drill is turned so that its axis runs along the line of sight into the sphere, and what
// sinks into it is the burr (the shell points deepest in the sphere lie on the burr's ball).
// Before, the drill came in side-on as held, its shaft on the sphere.
TEST(DeviceInput, TouchSurfaceWithADrillPutsTheBurrOnTheSurface) {
  const runtime::LoadedScene scene = runtime::loadScene(runtime::parseScene(
      R"({"volume": {"path": "builtin:sphere"}, "tool": {"mesh": "builtin:drill", "point_spacing_m": 0.001}})",
      "drill.json", "."));
  ViewAndDevice s(scene);
  ASSERT_FALSE(s.session.live().drill.has_value());
  const haptics::ToolModel& tool = *s.session.live().tool;
  const runtime::Burr burr = runtime::burrOf(tool, runtime::DrillSpec{});
  ASSERT_TRUE(s.input->touchSurface(0.002));
  const Pose X_WD = s.session.simulatedDevice()->pose();
  const Eigen::Vector3d forward = s.view->camera().forward_W();
  const Eigen::Vector3d axis_W = X_WD.R_AB * (burr.center_T_m - tool.mass.p_TCm_m).normalized();
  EXPECT_GT(axis_W.dot(forward), 0.99) << "the burr leads along the line of sight";
  int on_burr = 0, elsewhere = 0;
  for (const Eigen::Vector3d& p_T : tool.point_shell.points_T_m()) {
    if ((X_WD * p_T).norm() >= 0.020) continue;  // inside the sphere: what the device pressed in
    ++((p_T - burr.center_T_m).norm() <= burr.radius_m + 0.5e-3 ? on_burr : elsewhere);
  }
  EXPECT_GT(on_burr, 0);
  EXPECT_EQ(elsewhere, 0) << "only the burr is in the sphere";
}

/// Where the view's VTK camera draws `p_W`, in widget pixels with y down (the oracle: VTK's
/// projection, not the code under test).
Eigen::Vector2d pixelOf(SceneView& view, const Eigen::Vector3d& p_W) {
  vtkRenderer* renderer = view.widget()->renderer();
  const int* vtk_size = renderer->GetSize();
  const int size[2] = {vtk_size[0] > 0 ? vtk_size[0] : view.widget()->width(),
                       vtk_size[1] > 0 ? vtk_size[1] : view.widget()->height()};
  vtkMatrix4x4* m = renderer->GetActiveCamera()->GetCompositeProjectionTransformMatrix(
      static_cast<double>(size[0]) / size[1], -1.0, 1.0);
  const double in[4] = {p_W.x(), p_W.y(), p_W.z(), 1.0};
  double out[4];
  m->MultiplyPoint(in, out);
  return {(out[0] / out[3] + 1.0) * 0.5 * size[0], (1.0 - out[1] / out[3]) * 0.5 * size[1]};
}

TEST(DeviceInput, CtrlShiftClickTouchesTheSurfaceUnderTheCursor) {
  ViewAndDevice s;
  const haptics::PointShell& shell = s.session.live().tool->point_shell;
  const Eigen::Vector3d p_TCm = s.session.live().tool->mass.p_TCm_m;
  QCoreApplication::processEvents();
  // A pixel off the view's centre whose line of sight passes 12 mm from the sphere's centre:
  // on the sphere (radius 20 mm), but not where the centre's line would land.
  const Eigen::Vector2d centre_px = pixelOf(*s.view, Eigen::Vector3d::Zero());
  const Eigen::Vector2d right_px = pixelOf(*s.view, 0.012 * s.view->camera().right_W());
  const QPointF click(right_px.x(), right_px.y());
  ASSERT_GT((right_px - centre_px).norm(), 5.0) << "the pick must differ from the centre's line";
  QMouseEvent press(QEvent::MouseButtonPress, click, s.view->widget()->mapToGlobal(click), Qt::LeftButton,
                    Qt::LeftButton, Qt::ControlModifier | Qt::ShiftModifier);
  EXPECT_TRUE(QCoreApplication::sendEvent(s.view->widget(), &press)) << "the view's filter takes the click";
  const Pose X_WD = s.session.simulatedDevice()->pose();
  const Eigen::Vector3d c_W = X_WD * p_TCm;
  // The tool's centre of mass on the line of sight of the clicked pixel, as VTK projects it.
  const Eigen::Vector2d seen = pixelOf(*s.view, c_W);
  EXPECT_NEAR(seen.x(), click.x(), 0.5);
  EXPECT_NEAR(seen.y(), click.y(), 0.5);
  // On the viewer's side, the proxy's pose (the device 3 mm back along the line of sight) just
  // touching the analytic sphere.
  const Eigen::Vector3d eye_W = s.view->camera().position_W_m;
  const Eigen::Vector3d dir_W = (c_W - eye_W).normalized();
  EXPECT_LT((c_W - eye_W).norm(), eye_W.norm()) << "behind the sphere's centre";
  const Pose X_WP{X_WD.R_AB, X_WD.p_AB_m - DeviceInput::kTouchDepth_m * dir_W};
  EXPECT_NEAR(deepestRadius_m(shell, X_WP), 0.020, 0.1e-3);

  // A click beside the sphere, in the view's corner: nothing to touch, nothing moves, a message.
  QSignalSpy messages(s.input, &DeviceInput::message);
  const QPointF corner(2.0, 2.0);
  QMouseEvent miss(QEvent::MouseButtonPress, corner, s.view->widget()->mapToGlobal(corner), Qt::LeftButton,
                   Qt::LeftButton, Qt::ControlModifier | Qt::ShiftModifier);
  QCoreApplication::sendEvent(s.view->widget(), &miss);
  EXPECT_EQ(messages.count(), 1);
  EXPECT_LT((s.session.simulatedDevice()->pose().p_AB_m - X_WD.p_AB_m).norm(), 1e-15);
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

/// A chest's shape with the body cut at the volume's top and bottom, as a chest CT is: a tube
/// of "rib" (1000) 20 mm thick, outer radius 120 mm, along z, with a "heart" ball (radius 40 mm)
/// at the centre, in 0 (air and soft tissue below the rib's level), 60 x 60 x 60 voxels of 5 mm,
/// LPS; isovalue 500. Lowered from above (the default initial pose), the tool falls into the
/// open tube onto the heart: inside the chest.
const runtime::LoadedScene& cutChestScene() {
  static const runtime::LoadedScene scene = [] {
    const std::filesystem::path file =
        std::filesystem::temp_directory_path() / ("vh_cut_chest_" + std::to_string(::getpid()) + ".nrrd");
    const int nx = 60, ny = 60, nz = 60;
    {
      std::ofstream out(file, std::ios::binary);
      out << "NRRD0004\ntype: int16\ndimension: 3\nspace: left-posterior-superior\nsizes: " << nx << " " << ny << " "
          << nz << "\nspace directions: (5,0,0) (0,5,0) (0,0,5)\nspace origin: (-147.5,-147.5,-147.5)\n"
          << "endian: little\nencoding: raw\n\n";
      std::vector<std::int16_t> voxels;
      for (int k = 0; k < nz; ++k) {
        for (int j = 0; j < ny; ++j) {
          for (int i = 0; i < nx; ++i) {
            const double x = -147.5 + 5.0 * i, y = -147.5 + 5.0 * j, r = std::hypot(x, y);
            const double z = -147.5 + 5.0 * k;
            voxels.push_back((r >= 100.0 && r <= 120.0) || std::hypot(r, z) <= 40.0 ? 1000 : 0);
          }
        }
      }
      out.write(reinterpret_cast<const char*>(voxels.data()), static_cast<std::streamsize>(voxels.size() * 2));
    }
    runtime::SceneSpec spec;
    spec.volume.path = file.string();
    spec.volume.isovalue = 500.0;
    spec.volume.isovalue_set = true;
    spec.tool.mesh = "builtin:probe";
    spec.device = runtime::DeviceSpec{};
    runtime::LoadedScene loaded = runtime::loadScene(spec);
    std::filesystem::remove(file);
    return loaded;
  }();
  return scene;
}

/// Whether the straight line from outside the volume's box to `p_W` (along `-dir_W`) stays below
/// `isovalue` in the field's samples every 0.25 mm, stopping 1 mm short of `p_W`: a point
/// reached from outside the body, not through it.
bool reachedFromOutside(const haptics::ScalarVolume& field, double isovalue, const Eigen::Vector3d& p_W,
                        const Eigen::Vector3d& dir_W) {
  const double far_m = (field.boundsMax_W_m() - field.boundsMin_W_m()).norm();
  for (double s = 1e-3; s < far_m; s += 0.25e-3) {
    if (field.sample(p_W - s * dir_W) > isovalue) return false;
  }
  return true;
}

// With the haptic threads running, the touch leads the tool from where it was placed (inside
// the cut chest, above the heart) out of the volume's box and onto the surface from outside: the
// proxy ends in contact, and the line from outside the box to each contact point along the
// approach crosses no surface (the independent oracle: the field sampled along that line).
TEST(DeviceInput, TouchSurfaceApproachesFromOutsideTheBodyNotFromInsideTheChest) {
  struct Case {
    std::string name;
    const runtime::LoadedScene* scene;
  };
  std::vector<Case> cases = {{"cut chest", &cutChestScene()}};
  std::optional<runtime::LoadedScene> head;
  if (std::filesystem::exists(test::kHead)) {
    runtime::SceneSpec spec;
    spec.volume.path = test::kHead.string();
    spec.tool.mesh = "builtin:probe";
    spec.device = runtime::DeviceSpec{};
    head = runtime::loadScene(spec);
    cases.push_back({"shared CT head (bone)", &*head});
  } else {
    std::cout << "[ SKIPPED part ] no shared CT head at " << test::kHead << "\n";
  }
  for (const Case& c : cases) {
    SCOPED_TRACE(c.name);
    const runtime::LoadedScene& scene = *c.scene;
    const haptics::ScalarVolume& field = *scene.volume.field;
    const double iso = runtime::LiveValues::initial(scene).hapticIsovalue();
    runtime::Session session;
    session.setScene(scene, std::make_shared<runtime::SimulatedDevice>(scene.X_WT_initial));
    QWidget host;
    auto* layout = new QVBoxLayout(&host);
    layout->setContentsMargins(0, 0, 0, 0);
    auto* view = new SceneView(&host);
    layout->addWidget(view->widget());
    view->setScene(sceneActorsSpecFor(scene, runtime::LiveValues::initial(scene)), scene.X_WT_initial, ViewLook{});
    auto* input = new DeviceInput(session, *view);
    host.resize(240, 180);
    host.show();
    session.startHaptics();
    ASSERT_TRUE(session.hapticsRunning());
    const Eigen::Vector3d forward = view->camera().forward_W();
    if (c.name == "cut chest") {
      // The oracle tells inside from outside here: the tool starts inside the chest, and the
      // line from there towards the viewer meets the ribs.
      const Eigen::Vector3d c_W = scene.X_WT_initial * session.live().tool->mass.p_TCm_m;
      ASSERT_LT(std::hypot(c_W.x(), c_W.y()), 0.1) << "the tool was placed outside the chest";
      ASSERT_FALSE(reachedFromOutside(field, iso, c_W, forward));
    }
    ASSERT_TRUE(input->touchSurface(0.003));
    // The proxy comes to rest in contact (the path takes well under 2 s at 1 kHz).
    runtime::HapticSnapshot snap;
    bool touching = false;
    test::waitFor([&] {
      touching = session.latestSnapshot(snap) && snap.contacts > 0 &&
                 (snap.X_WD.p_AB_m - session.simulatedDevice()->pose().p_AB_m).norm() < 1e-9 &&
                 !input->touchInProgress();
      return touching;
    }, 30000 * test::kSanitizerSlowdown);
    ASSERT_TRUE(touching) << "the tool never came to rest on the surface: contacts " << snap.contacts
                          << ", device " << (snap.X_WD.p_AB_m - session.simulatedDevice()->pose().p_AB_m).norm()
                          << " m from the placed pose, placement " << (input->touchInProgress() ? "pending" : "applied");
    ASSERT_GT(snap.contacts_shown, 0);
    for (int i = 0; i < snap.contacts_shown; ++i) {
      EXPECT_TRUE(reachedFromOutside(field, iso, snap.contact_p_W_m[i], forward))
          << "contact " << i << " at " << snap.contact_p_W_m[i].transpose() << " lies behind a surface";
    }
    session.stopHaptics();
  }
}

}  // namespace
}  // namespace vh::ui
