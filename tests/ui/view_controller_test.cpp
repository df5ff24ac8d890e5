// ViewController: the Session shown in the SceneView, and the rendering mode of one scan not
// carried over to the next.
#include "vh/ui/view_controller.h"

#include <algorithm>
#include <limits>
#include <memory>

#include <QImage>
#include <QScreen>

#include <gtest/gtest.h>
#include <vtkGenericOpenGLRenderWindow.h>
#include <vtkRenderer.h>

#include "ui_test_util.h"
#include "view_host.h"
#include "vh/runtime/device.h"
#include "vh/runtime/session.h"
#include "vh/ui/panels/display_panel.h"
#include "vh/ui/view/scene_actors.h"
#include "vh/ui/view/scene_view.h"
#include "vh/ui/view/vtk_view.h"

namespace vh::ui {
namespace {

using test::sphereProbeScene;

using Host = test::ViewControllerHost;

TEST(ViewController, ANewScanOpensInTheModeTheWindowOpenedWithNotTheLastOnesMode) {
  Host host;
  host.prefs.mode = RenderMode::kIsosurface;
  host.controller = std::make_unique<ViewController>(host.session, *host.view, *host.panel, host.prefs);
  host.session.setScene(sphereProbeScene(), nullptr);
  ASSERT_TRUE(host.view->hasScene());
  EXPECT_EQ(host.view->actors().renderMode(), RenderMode::kIsosurface);

  host.controller->setRenderMode(RenderMode::kMip);  // chosen for this scan
  EXPECT_EQ(host.view->actors().renderMode(), RenderMode::kMip);
  EXPECT_EQ(host.prefs.mode, RenderMode::kMip);

  host.session.setScene(sphereProbeScene(), nullptr);  // the next file, or a replay's scene
  EXPECT_EQ(host.view->actors().renderMode(), RenderMode::kIsosurface);
  EXPECT_EQ(host.prefs.mode, RenderMode::kIsosurface);
  EXPECT_EQ(host.panel->renderMode(), RenderMode::kIsosurface);
}

TEST(ViewController, AModeChosenBeforeAnyScanIsWhatEveryScanOpensWith) {
  Host host;
  host.controller = std::make_unique<ViewController>(host.session, *host.view, *host.panel, host.prefs);
  host.controller->setRenderMode(RenderMode::kComposite);  // --render-mode composite
  host.session.setScene(sphereProbeScene(), nullptr);
  EXPECT_EQ(host.view->actors().renderMode(), RenderMode::kComposite);
  host.controller->setRenderMode(RenderMode::kMip);
  host.session.setScene(sphereProbeScene(), nullptr);
  EXPECT_EQ(host.view->actors().renderMode(), RenderMode::kComposite);
}

TEST(ViewController, TheViewFollowsTheSessionsIsovalue) {
  Host host;
  host.controller = std::make_unique<ViewController>(host.session, *host.view, *host.panel, host.prefs);
  host.session.setScene(sphereProbeScene(), nullptr);
  const double s = 0.5 * (host.session.isovalue() + host.session.loaded().volume.field->maxValue());
  host.session.setIsovalue(s);
  EXPECT_DOUBLE_EQ(host.view->actors().isovalue(), host.session.isovalue());
}

// Stereo: side by side draws the scene twice, one eye in each half (the sphere, in the middle of the
// mono frame, then sits in the middle of each half and not in the middle of the view); the
// anaglyph frame is another picture of the same scene; the camera (what is felt) stays put.
TEST(ViewController, StereoModesDrawTwoEyesOfTheSameCamera) {
  Host host;
  host.controller = std::make_unique<ViewController>(host.session, *host.view, *host.panel, host.prefs);
  host.session.setScene(sphereProbeScene(), nullptr);
  ASSERT_TRUE(test::waitFor([&] { return host.view->widget()->renderer()->GetSize()[1] > 0; }, 20000));
  // Bright pixels in the columns [x0, x1) below the hint lines (the top 40 %).
  const auto brightIn = [](const QImage& image, int x0, int x1) {
    const QImage rgb = image.convertToFormat(QImage::Format_RGB32);
    std::size_t n = 0;
    for (int y = static_cast<int>(0.4 * rgb.height()); y < rgb.height(); ++y) {
      const auto* p = reinterpret_cast<const QRgb*>(rgb.constScanLine(y));
      for (int x = std::max(0, x0); x < std::min(rgb.width(), x1); ++x) n += qGray(p[x]) > 100 ? 1 : 0;
    }
    return n;
  };
  host.view->renderStill(true);
  const QImage mono = host.view->widget()->grabFrame();
  const int w = mono.width();
  ASSERT_GT(brightIn(mono, w / 2 - 3, w / 2 + 3), 0u) << "the sphere is not in the middle of the mono frame";
  const ViewCamera camera = host.view->camera();

  host.controller->setStereo(ViewController::Stereo::kSideBySide);
  EXPECT_EQ(host.controller->stereo(), ViewController::Stereo::kSideBySide);
  const QImage side = host.view->widget()->grabFrame();
  EXPECT_GT(brightIn(side, w / 4 - 3, w / 4 + 3), 0u) << "no left eye";
  EXPECT_GT(brightIn(side, 3 * w / 4 - 3, 3 * w / 4 + 3), 0u) << "no right eye";
  EXPECT_EQ(brightIn(side, w / 2 - 1, w / 2 + 1), 0u) << "one picture across the view, not two";

  host.controller->setStereo(ViewController::Stereo::kAnaglyph);
  EXPECT_EQ(host.view->widget()->renderWindow()->GetStereoType(), VTK_STEREO_ANAGLYPH);
  // The sphere's pixels (about 2 % of the view) change: red for one eye, cyan for the other.
  EXPECT_GT(test::differingFraction(host.view->widget()->grabFrame(), mono), 0.001);
  EXPECT_EQ(host.view->camera().position_W_m, camera.position_W_m) << "stereo moved the camera";

  host.controller->setStereo(ViewController::Stereo::kOff);
  EXPECT_EQ(host.view->widget()->renderWindow()->GetStereoRender(), 0);
  EXPECT_LT(test::differingFraction(host.view->widget()->grabFrame(), mono), 0.01);
  if (host.view->widget()->renderWindow()->GetStereoCapableWindow() == 0) {
    host.controller->setStereo(ViewController::Stereo::kQuadBuffer);
    EXPECT_EQ(host.controller->stereo(), ViewController::Stereo::kOff) << "quad buffer without a stereo context";
  }
}

// The tool is shown at the screen's rate (one new pose per refresh), not at a fixed 30 Hz that
// no display runs at: the period follows QScreen::refreshRate(), rounded down, within 240 to
// 30 Hz, 60 Hz where the screen reports none.
TEST(ViewController, TheHapticSnapshotIsShownOncePerRefreshOfTheScreen) {
  EXPECT_EQ(displayPeriodMsFor(60.0), 16);
  EXPECT_EQ(displayPeriodMsFor(59.94), 16);
  EXPECT_EQ(displayPeriodMsFor(75.0), 13);
  EXPECT_EQ(displayPeriodMsFor(144.0), 6);
  EXPECT_EQ(displayPeriodMsFor(240.0), 4);
  EXPECT_EQ(displayPeriodMsFor(1000.0), 4);
  EXPECT_EQ(displayPeriodMsFor(24.0), 33);
  EXPECT_EQ(displayPeriodMsFor(0.0), 16);
  EXPECT_EQ(displayPeriodMsFor(-5.0), 16);
  EXPECT_EQ(displayPeriodMsFor(std::numeric_limits<double>::quiet_NaN()), 16);
  EXPECT_EQ(displayPeriodMsFor(std::numeric_limits<double>::infinity()), 16);

  Host host;
  host.controller = std::make_unique<ViewController>(host.session, *host.view, *host.panel, host.prefs);
  const runtime::LoadedScene& scene = sphereProbeScene();
  host.session.setScene(scene, std::make_shared<runtime::SimulatedDevice>(scene.X_WT_initial));
  host.session.startHaptics();
  ASSERT_TRUE(host.session.hapticsRunning());
  const QScreen* screen = host.view->widget()->screen();
  ASSERT_NE(screen, nullptr);
  EXPECT_EQ(host.controller->displayPeriodMs(), displayPeriodMsFor(screen->refreshRate()))
      << "screen refresh " << screen->refreshRate() << " Hz";
  EXPECT_LE(host.controller->displayPeriodMs(), 16) << "Xvfb reports 60 Hz: the tool at 30 Hz again";
  host.session.stopHaptics();
}

}  // namespace
}  // namespace vh::ui
