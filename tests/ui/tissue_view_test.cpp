// Soft tissue in the GUI, checked as a person would see it under Xvfb, on the built-in gel with a
// stiffer inclusion (the scene file resources/scenes/gel-palpation.json) and a simulated device:
//  * pressed, the picture shows the tissue as the hand feels it: the view's image equals, voxel
//    for voxel, the field the haptic thread's renderer felt last (read from the renderer's own
//    volume once the threads have stopped: not the path the picture took), the rendered frame
//    differs from the one at rest, and the Tissue dock gives the indentation;
//  * released, the picture is the scan again, voxel for voxel;
//  * a scene without tissue starts none of it (no dock shown, nothing drained);
//  * on a tissue scene the isovalue is applied where the slider is released, and the tissue is
//    rebuilt on the new surface: the hand's isovalue and the eyes' stay one.
#include <cmath>
#include <filesystem>
#include <memory>

#include <QApplication>
#include <QDockWidget>
#include <QMainWindow>

#include <gtest/gtest.h>
#include <vtkDataArray.h>
#include <vtkImageData.h>
#include <vtkPointData.h>

#include "ui_test_util.h"
#include "view_host.h"
#include "vh/datasets/synthetic.h"
#include "vh/haptics/haptic_renderer.h"
#include "vh/runtime/haptic_thread.h"
#include "vh/runtime/scene.h"
#include "vh/runtime/session.h"
#include "vh/ui/tissue_controller.h"
#include "vh/ui/view/scene_actors.h"
#include "vh/ui/view/scene_frames.h"
#include "vh/ui/view/scene_view.h"
#include "vh/ui/view/vtk_view.h"

namespace vh::ui {
namespace {
namespace fs = std::filesystem;

using ViewHost = test::SceneWindowHost;

runtime::LoadedScene gelScene() {
  const fs::path file = fs::path(VH_SOURCE_DIR) / "resources" / "scenes" / "gel-palpation.json";
  return runtime::loadScene(runtime::loadSceneFile(file));
}

// A window's scene view, a Session on `scene` (its simulated device) shown in it, and the tissue
// controller between them.
struct TissueSession {
  explicit TissueSession(runtime::LoadedScene scene) : tissue(session, *host.view, &host.window) {
    spec = sceneActorsSpecFor(scene, runtime::LiveValues::initial(scene));
    auto device = scene.makeDevice();
    session.setScene(std::move(scene), device);
    host.view->setScene(spec, session.live().X_WT_initial, ViewLook{});
  }
  ViewHost host;
  runtime::Session session;
  TissueController tissue;
  SceneActorsSpec spec;
};

// Voxels where the view's image and `field` (the felt values) differ by more than the image's
// rounding (the gel is float: none).
std::size_t pictureMismatches(vtkImageData* shown, const haptics::ScalarVolume& field) {
  vtkDataArray* values = shown->GetPointData()->GetScalars();
  const auto n = static_cast<std::size_t>(values->GetNumberOfTuples());
  if (n != field.geometry().voxelCount()) return n + 1;
  std::size_t bad = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const double felt = field.valueScale() * field.rawAt(i) + field.valueOffset();
    bad += !(std::abs(values->GetComponent(static_cast<vtkIdType>(i), 0) - felt) <= 1e-3);
  }
  return bad;
}

std::size_t differingPixels(const QImage& a, const QImage& b) {
  if (a.size() != b.size()) return static_cast<std::size_t>(a.width()) * static_cast<std::size_t>(a.height());
  std::size_t n = 0;
  for (int y = 0; y < a.height(); ++y)
    for (int x = 0; x < a.width(); ++x) n += a.pixel(x, y) != b.pixel(x, y);
  return n;
}

TEST(TissueView, PressedThePictureShowsWhatTheHandFeelsReleasedTheScan) {
  TissueSession s(gelScene());
  runtime::Session& session = s.session;
  ASSERT_TRUE(session.live().tissue.has_value());
  ASSERT_NE(session.hapticThread(), nullptr);
  ASSERT_NE(session.hapticThread()->tissue(), nullptr) << "a tissue scene builds its deformable scene";
  EXPECT_FALSE(s.tissue.dock()->isHidden()) << "the Tissue dock shows for a tissue scene";
  s.host.view->setDeviceVisible(false);
  s.host.view->setStandardView(StandardView::kAnterior);  // the gel's top edge-on: a dent shows in profile
  s.host.view->renderStill(true);
  const QImage at_rest = s.host.view->widget()->grabFrame();

  // Press the 5 mm ball 2 mm into the gel beside the inclusion, and hold it there.
  session.startHaptics();
  haptics::Pose X_WD = session.live().X_WT_initial;
  const double radius_m = 0.0025;  // builtin:sphere in gel-palpation.json: 5 mm across
  X_WD.p_AB_m = Eigen::Vector3d(-0.005, 0.0, datasets::kGelTop_m + radius_m - 0.002);
  session.simulatedDevice()->setPose(X_WD);
  ASSERT_TRUE(test::waitFor(
      [&] {
        s.tissue.drain();
        return s.tissue.shown().indentation_m > 0.3e-3;
      },
      30000 * test::kSanitizerSlowdown))
      << "indentation " << s.tissue.shown().indentation_m * 1e3 << " mm";
  // Held still, the field settles: nothing new published for a while.
  int quiet = 0;
  ASSERT_TRUE(test::waitFor(
      [&] {
        const std::uint64_t before = s.tissue.shown().step;
        s.tissue.drain();
        quiet = s.tissue.shown().step == before ? quiet + 1 : 0;
        return quiet >= 20;
      },
      30000 * test::kSanitizerSlowdown));
  s.host.view->renderStill(true);
  const QImage pressed = s.host.view->widget()->grabFrame();
  session.stopHaptics();
  s.tissue.drain();
  const runtime::HapticThread* thread = session.hapticThread();
  ASSERT_NE(thread, nullptr);
  const haptics::ScalarVolume& felt = thread->renderer().volume();
  EXPECT_EQ(&felt, thread->tissue()->feltVolume().get()) << "the renderer feels the tissue's volume";
  EXPECT_EQ(pictureMismatches(s.host.view->actors().shownImage(), felt), 0u)
      << "the picture differs from the field the hand felt";
  EXPECT_GT(s.host.view->actors().partialUploads() + s.host.view->actors().fullUploads(), 0u);
  const std::size_t changed = differingPixels(at_rest, pressed);
  std::printf("gel pressed 2 mm: indentation %.2f mm, tissue pushed %.3f N; %zu of %d pixels changed\n",
              s.tissue.shown().indentation_m * 1e3, s.tissue.shown().push_N, changed,
              at_rest.width() * at_rest.height());
  EXPECT_GT(changed, 50u) << "the dent is not seen";

  // Released: up and away; the picture is the scan again.
  session.startHaptics();
  X_WD.p_AB_m.z() += 0.010;
  session.simulatedDevice()->setPose(X_WD);
  ASSERT_TRUE(test::waitFor(
      [&] {
        s.tissue.drain();
        return s.tissue.shown().empty() && s.tissue.windowsShown() > 0;
      },
      30000 * test::kSanitizerSlowdown));
  session.stopHaptics();
  EXPECT_EQ(pictureMismatches(s.host.view->actors().shownImage(), *session.live().scan_field), 0u)
      << "released, the picture is not the scan";
}

// Haptic threads rebuilt on the same scene and surface (a recording starting restarts them where
// the proxy is) keep the tissue built for it: its compliance table took 36 s on the CT head's
// soft tissue. It starts again at rest: the felt field the scan's, voxel for voxel.
TEST(TissueView, RebuiltThreadsKeepTheTissueAndStartItAtRest) {
  TissueSession s(gelScene());
  runtime::Session& session = s.session;
  const tissue::DeformableScene* built = session.hapticThread()->tissue().get();
  ASSERT_NE(built, nullptr);
  session.startHaptics();
  haptics::Pose X_WD = session.live().X_WT_initial;
  X_WD.p_AB_m = Eigen::Vector3d(-0.005, 0.0, datasets::kGelTop_m + 0.0025 - 0.002);
  session.simulatedDevice()->setPose(X_WD);
  ASSERT_TRUE(test::waitFor(
      [&] {
        s.tissue.drain();
        return s.tissue.shown().indentation_m > 0.3e-3;
      },
      30000 * test::kSanitizerSlowdown));
  ASSERT_TRUE(session.prepareRecording().has_value());  // the threads rebuilt where the proxy is
  ASSERT_NE(session.hapticThread(), nullptr);
  EXPECT_EQ(session.hapticThread()->tissue().get(), built) << "the tissue was built again";
  session.stopHaptics();
  std::size_t differing = 0;
  const haptics::ScalarVolume& felt = *session.hapticThread()->tissue()->feltVolume();
  const haptics::ScalarVolume& scan = *session.live().scan_field;
  for (std::size_t v = 0; v < scan.geometry().voxelCount(); ++v) differing += felt.rawAt(v) != scan.rawAt(v);
  EXPECT_EQ(differing, 0u) << "the kept tissue did not start at rest";
}

TEST(TissueView, ARigidSceneStartsNoneOfIt) {
  TissueSession s(runtime::loadScene(runtime::parseScene(
      R"({"volume": {"path": "builtin:sphere"}, "device": {"kind": "simulated"}})", "rigid.json", ".")));
  EXPECT_TRUE(s.tissue.dock()->isHidden());
  ASSERT_NE(s.session.hapticThread(), nullptr);
  EXPECT_EQ(s.session.hapticThread()->tissue(), nullptr);
  s.tissue.drain();
  EXPECT_EQ(s.tissue.windowsShown(), 0u);
  EXPECT_TRUE(s.tissue.shown().empty());
}

TEST(TissueView, TheIsovalueIsOneForTheTissueAndTheHand) {
  TissueSession s(gelScene());
  runtime::Session& session = s.session;
  // Held, so that a rebuilt one cannot take its address.
  const std::shared_ptr<tissue::DeformableScene> before = session.hapticThread()->tissue();
  ASSERT_NE(before, nullptr);
  EXPECT_DOUBLE_EQ(before->isovalue(), session.isovalue());
  session.setIsovalue(60.0);
  ASSERT_NE(session.hapticThread(), nullptr);
  const std::shared_ptr<tissue::DeformableScene> after = session.hapticThread()->tissue();
  ASSERT_NE(after, nullptr);
  EXPECT_NE(after, before) << "the tissue was not rebuilt on the new surface";
  EXPECT_DOUBLE_EQ(after->isovalue(), 60.0);
  EXPECT_DOUBLE_EQ(session.isovalue(), 60.0);
  EXPECT_DOUBLE_EQ(session.hapticThread()->renderer().feltIsovalue(), 60.0);
}

}  // namespace
}  // namespace vh::ui
