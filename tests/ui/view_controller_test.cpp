// ViewController: the Session shown in the SceneView, and the rendering mode of one scan not
// carried over to the next.
#include "vh/ui/view_controller.h"

#include <QVBoxLayout>
#include <QWidget>

#include <gtest/gtest.h>

#include "ui_test_util.h"
#include "vh/runtime/session.h"
#include "vh/ui/panels/display_panel.h"
#include "vh/ui/view/scene_actors.h"
#include "vh/ui/view/vtk_view.h"

namespace vh::ui {
namespace {

using test::sphereProbeScene;

struct Host {
  Host() {
    auto* layout = new QVBoxLayout(&widget);
    view = new SceneView(&widget);
    layout->addWidget(view->widget());
    panel = new DisplayPanel(&widget);
    layout->addWidget(panel);
    widget.resize(320, 400);
    widget.show();
  }
  ~Host() {
    controller.reset();
    session.clear();
  }
  QWidget widget;
  SceneView* view = nullptr;
  DisplayPanel* panel = nullptr;
  Preferences prefs;
  runtime::Session session;
  std::unique_ptr<ViewController> controller;
};

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

}  // namespace
}  // namespace vh::ui
