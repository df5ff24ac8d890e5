// The opener hears that the scene it loaded is shown from the Session, not from the window: the
// scene's data goes one way (loader -> opener -> window -> Session), and the opener, observing the
// Session, puts what was opened into the recent files and keeps loading() true until the first
// frame after it (the volume's GPU upload). The oracle is what the user was told was opened:
// only a scene that came from the opener's own load, and that the Session took, is recent.

#include <filesystem>
#include <memory>

#include <QMainWindow>
#include <QStatusBar>

#include <gtest/gtest.h>

#include "ui_test_util.h"
#include "vh/runtime/session.h"
#include "vh/ui/panels/status_line.h"
#include "vh/ui/preferences.h"
#include "vh/ui/scene_loader.h"
#include "vh/ui/scene_opener.h"

namespace vh::ui {
namespace {

/// An opener with everything it needs but a window: the test plays the window (it gives the
/// opener's scenes to the Session, or refuses them) and the view (frameRendered()).
struct OpenerRig {
  QMainWindow window;
  runtime::Session session;
  Preferences prefs;
  StatusLine status{window.statusBar()};
  SceneLoader loader;
  SceneOpener opener{loader, session, prefs, status, window.statusBar(), &window};
  bool accept = true;  // what the "window" does with a loaded scene
  int shown = 0;

  OpenerRig() {
    opener.setInteractive(false);
    QObject::connect(&opener, &SceneOpener::sceneLoaded, &window, [this](const std::shared_ptr<ViewerScene>& v) {
      if (!accept) return;
      session.setScene(v->scene, nullptr);
      ++shown;
    });
  }

  /// What the loader reports when a load of `opened` finished.
  void finishLoad(const std::filesystem::path& opened) {
    auto loaded = std::make_shared<LoadedViewerScene>();
    loaded->scene = test::sphereProbeScene();
    loaded->opened = opened;
    loaded->title = opened.filename().string();
    emit loader.sceneLoaded(loaded);
  }
};

TEST(SceneOpener, TheSceneOfItsLoadIsRecentOnceTheSessionHoldsItAndLoadsUntilTheNextFrame) {
  OpenerRig rig;
  rig.opener.frameRendered(41);
  rig.finishLoad("/data/head-ct");
  ASSERT_EQ(rig.shown, 1);
  ASSERT_TRUE(rig.session.hasScene());
  ASSERT_EQ(rig.prefs.recent_files.size(), 1);
  EXPECT_TRUE(rig.prefs.recent_files.front().endsWith("head-ct")) << rig.prefs.recent_files.front().toStdString();
  EXPECT_TRUE(rig.opener.loading()) << "the volume's GPU upload: the frame after the scene";
  rig.opener.frameRendered(41);
  EXPECT_TRUE(rig.opener.loading()) << "frame 41 was drawn before the scene";
  rig.opener.frameRendered(42);
  EXPECT_FALSE(rig.opener.loading());
}

TEST(SceneOpener, AScenePutInTheSessionByAnotherPartIsNotItsToRemember) {
  OpenerRig rig;
  rig.session.setScene(test::sphereProbeScene(), nullptr);  // e.g. a volume received over the network
  EXPECT_TRUE(rig.prefs.recent_files.isEmpty());
  EXPECT_FALSE(rig.opener.loading());
}

TEST(SceneOpener, ALoadTheWindowRefusedLeavesNothingPendingForTheNextScene) {
  OpenerRig rig;
  rig.accept = false;
  rig.finishLoad("/data/refused");
  EXPECT_TRUE(rig.prefs.recent_files.isEmpty());
  rig.session.setScene(test::sphereProbeScene(), nullptr);  // a later scene from elsewhere
  EXPECT_TRUE(rig.prefs.recent_files.isEmpty()) << "the refused load's path must not be taken for it";
  EXPECT_FALSE(rig.opener.loading());
}

}  // namespace
}  // namespace vh::ui
