// Pictures of the dialogs and panels for a person to look at (not a check): written only when
// VH_UI_SHOTS_DIR names a folder, e.g.
//   VH_UI_SHOTS_DIR=/tmp/shots xvfb-run -a tests/ui/vh_ui_tests --gtest_filter='UiScreenshots.*'
#include <cstdlib>
#include <filesystem>

#include <QApplication>
#include <QDockWidget>
#include <QMessageBox>
#include <QTabBar>
#include <QTemporaryDir>

#include <gtest/gtest.h>

#include "ui_test_util.h"
#include "vh/io/dicom_series.h"
#include "vh/ui/main_window.h"
#include "vh/ui/view_controller.h"
#include "vh/ui/panels/series_chooser.h"
#include "vh/ui/view/vtk_view.h"

namespace vh::ui {
namespace {

namespace fs = std::filesystem;

TEST(UiScreenshots, DialogsAndPanels) {
  const char* dir = std::getenv("VH_UI_SHOTS_DIR");
  if (dir == nullptr || !fs::exists(test::kHead)) GTEST_SKIP() << "set VH_UI_SHOTS_DIR to write pictures";
  const QString out = QString::fromLocal8Bit(dir);
  MainWindow window;
  window.setInteractive(false);
  window.resize(1280, 860);
  window.show();
  window.grab().save(out + "/empty-window.png");
  window.openPath(QString::fromStdString(test::kHead.string()));
  ASSERT_TRUE(test::waitFor([&] { return window.hasScene() && !window.opener()->loading(); }, 30000));
  test::pump(1500);
  window.findChild<QDockWidget*>("displayDock")->raise();
  window.viewController()->setRenderMode(RenderMode::kComposite);
  window.viewController()->setPreset(VolumePreset::kSoftTissue);
  window.viewController()->setClipping(true, ClipAxis::kY, 0.5);
  window.sceneView()->setStandardView(StandardView::kLeft);
  test::pump(500);
  window.sceneView()->renderStill(true);
  window.grab().save(out + "/display-panel-soft-tissue-clipped.png");

  // The series chooser over a folder holding two series.
  QTemporaryDir tmp;
  const fs::path root = tmp.path().toStdString();
  fs::create_directories(root / "head");
  for (const auto& e : fs::directory_iterator(test::kHead)) fs::copy_file(e.path(), root / "head" / e.path().filename());
  const fs::path phantom = test::kSharedData / "ct/philips-head-phantom-bone";
  if (fs::exists(phantom)) {
    fs::create_directories(root / "phantom");
    for (const char* name : {"I10", "I20", "I30"}) fs::copy_file(phantom / name, root / "phantom" / name);
  }
  SeriesChooserDialog chooser(tmp.path(), io::listDicomSeries(root), &window);
  chooser.show();
  test::pump(200);
  chooser.grab().save(out + "/series-chooser.png");

  // The error dialog of a failed load (the scene stays).
  window.setInteractive(true);
  window.openPath(tmp.filePath("missing.nrrd"));
  auto* box = window.findChild<QMessageBox*>("errorBox");
  ASSERT_NE(box, nullptr);
  test::pump(200);
  box->grab().save(out + "/error-dialog.png");
  box->close();
  window.close();
}

}  // namespace
}  // namespace vh::ui
