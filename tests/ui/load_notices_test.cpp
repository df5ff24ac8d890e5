// What the loader corrected or chose, shown where the user looks (ui/load_notices.h): the status
// bar, the banner above the view, Help > Load Notes; progress and cancel of a scene load
// (ui/scene_loader.h); the time point of a 4-D series reaching the scene spec.
#include "vh/ui/panels/load_notices.h"

#include <atomic>
#include <chrono>
#include <filesystem>
#include <thread>

#include <QAction>
#include <QApplication>
#include <QLabel>
#include <QMenu>
#include <QMenuBar>
#include <QProgressBar>
#include <QPushButton>
#include <QSignalSpy>
#include <QSpinBox>
#include <QStatusBar>
#include <QTemporaryDir>
#include <QToolButton>
#include <QVBoxLayout>

#include <gtest/gtest.h>

#include "dicom_fixtures.h"
#include "ui_test_util.h"
#include "vh/io/dicom_series.h"
#include "vh/ui/main_window.h"
#include "vh/ui/view_controller.h"
#include "vh/ui/scene_loader.h"
#include "vh/ui/panels/series_chooser.h"

namespace vh::ui {
namespace {

namespace fs = std::filesystem;
using test::kHead;
using test::waitFor;

QString qs(const fs::path& p) { return QString::fromStdString(p.string()); }

/// The small CT head without CTHead50.dcm: the loader fills the gap and names the neighbours.
fs::path gappedHead(const QTemporaryDir& dir) {
  const fs::path out = fs::path(dir.path().toStdString()) / "ct-head-gap";
  fs::create_directories(out);
  for (const auto& entry : fs::directory_iterator(kHead)) {
    if (entry.path().filename() != "CTHead50.dcm") fs::copy_file(entry.path(), out / entry.path().filename());
  }
  return out;
}

QAction* menuAction(const MainWindow& window, const QString& text) {
  for (QAction* menu : window.menuBar()->actions()) {
    if (menu->menu() == nullptr) continue;
    for (QAction* a : menu->menu()->actions()) {
      if (a->text().remove('&') == text) return a;
    }
  }
  return nullptr;
}

TEST(LoadNotices, TheTiltOrAGapComesBeforeTheSeriesChoice) {
  EXPECT_EQ(primaryNotice({}), "");
  const std::string series = "loaded series 3 'Head' (93 files) of 2 series in the folder";
  const std::string tilt = "resampled from a gantry tilt of 18.5 deg";
  const std::string gap = "missing slices: a gap of 6.00 mm (about 3 slices) between X.dcm and Y.dcm";
  const std::string phases = "4-D series with 3 time points (phases or echoes): loaded time point 1";
  EXPECT_EQ(primaryNotice({series, phases, gap, tilt}), tilt);
  EXPECT_EQ(primaryNotice({series, gap}), gap);
  EXPECT_EQ(primaryNotice({series, phases}), phases);
  EXPECT_EQ(primaryNotice({"something new", series}), series);
  EXPECT_LT(noticeRank("dropped 2 duplicate slices: a.dcm"), noticeRank(series));
  // A PET's note on its values leads, not the scene's note on its tool's spacing (which says
  // "spacing" too); the tool's note comes after every note on the scan, unknown ones included.
  const std::string suv = "PET in SUV (body weight): weight 70 kg, injected dose 370 MBq";
  const std::string tool =
      "tool: at 1.50 mm point spacing a surface can come up to 1.35 mm inside the tool's mesh before it is felt";
  EXPECT_EQ(primaryNotice({tool, suv, series}), suv);
  EXPECT_EQ(primaryNotice({tool, "something new"}), "something new");
  EXPECT_EQ(primaryNotice({tool}), tool);
  EXPECT_LT(noticeRank(gap), noticeRank(suv));
}

TEST(LoadNotices, ManyNotesTakeOneLineUntilAskedAndABoundedListThen) {
  // A scan with 15 long notes (the two-part GE head CT had that many): the banner is one summary
  // line, the details a list of at most kMaxDetailLines lines, and the status bar names the count
  // and where to read them before the first note (a long line is cut at its end).
  QWidget host;
  auto* layout = new QVBoxLayout(&host);
  auto* panel = new LoadNoticePanel(&host);
  layout->addWidget(panel);
  layout->addStretch(1);
  host.resize(1000, 700);
  host.show();
  io::VolumeInfo info;
  std::vector<std::string> notes;
  for (int i = 0; i < 15; ++i) {
    notes.push_back("slices " + std::to_string(i) + " and " + std::to_string(i + 1) +
                    ": a change of slice thickness that the loader resampled to the finest spacing the "
                    "series supports, so that the volume is regular for the haptic rendering");
  }
  info.notices = notes;
  panel->setLoaded("ct-two-part - None", runtime::SceneSpec{}, info, {});
  QApplication::processEvents();
  const int line = panel->fontMetrics().lineSpacing();
  EXPECT_TRUE(panel->isVisible());
  EXPECT_FALSE(panel->detailsShown()) << "a new scan shows its summary line only";
  EXPECT_LE(panel->height(), 3 * line) << "collapsed: one line and margins";
  auto* summary = panel->findChild<QLabel*>("loadNoticeSummary");
  ASSERT_NE(summary, nullptr);
  EXPECT_TRUE(summary->text().contains("15 load notes")) << summary->text().toStdString();

  panel->setDetailsShown(true);
  QApplication::processEvents();
  EXPECT_TRUE(panel->detailsShown());
  EXPECT_LE(panel->height(), (LoadNoticePanel::kMaxDetailLines + 4) * line) << "the details list is bounded";
  EXPECT_LT(panel->height(), host.height() / 4) << "the view keeps most of the window";
  EXPECT_TRUE(panel->findChild<QLabel*>("loadNoticeText")->text().contains("slices 14 and 15"));

  const QString status = statusNote(notes);
  EXPECT_TRUE(status.startsWith("15 load notes (Help > Load Notes): ")) << status.toStdString();
  EXPECT_TRUE(status.contains("slices 0 and 1")) << status.toStdString();
}

TEST(LoadNotices, ASeriesDescribedAsNoneAddsNothingToTheTitle) {
  LoadedViewerScene loaded;
  loaded.scene = test::sphereProbeScene();
  loaded.scene.volume.info.format = "DICOM";
  loaded.title = "ct-missing-slice";
  for (const char* nothing : {"None", "NONE", "  ", ""}) {
    loaded.scene.volume.info.description = nothing;
    EXPECT_EQ(viewerSceneFor(loaded).title, "ct-missing-slice") << "description '" << nothing << "'";
  }
  loaded.scene.volume.info.description = "HEAD 5mm";
  EXPECT_EQ(viewerSceneFor(loaded).title, "ct-missing-slice - HEAD 5mm");
}

TEST(LoadNotices, ASeriesRetrievedIntoAFolderNamedByItsUidIsNamedByItsDescription) {
  // A PACS retrieve writes into a folder named by the Series Instance UID: the banner and the
  // window title name the series by its description instead.
  LoadedViewerScene loaded;
  loaded.scene = test::sphereProbeScene();
  loaded.scene.volume.info.format = "DICOM";
  loaded.title = "1.3.6.1.4.1.14519.5.2.1.7009.9004.160416029404301360186441590";
  loaded.scene.volume.info.description = "PET AC WB";
  EXPECT_EQ(viewerSceneFor(loaded).title, "PET AC WB");
  loaded.scene.volume.info.description = "None";  // nothing better than the UID
  EXPECT_EQ(viewerSceneFor(loaded).title, loaded.title);
}

TEST(LoadNotices, AGapIsNamedInTheStatusBarTheBannerAndHelpLoadNotes) {
  if (!fs::exists(kHead / "CTHead50.dcm")) GTEST_SKIP() << "dataset absent: " << kHead;
  QTemporaryDir dir;
  ASSERT_TRUE(dir.isValid());
  const fs::path gapped = gappedHead(dir);

  MainWindow window;
  window.setInteractive(false);
  window.setAutoStartHaptics(false);
  window.resize(1000, 700);
  window.show();
  LoadNoticePanel* panel = window.loadNotices();
  ASSERT_NE(panel, nullptr);
  EXPECT_FALSE(panel->isVisible()) << "nothing to say before a scan is open";

  QSignalSpy loaded(&window, &MainWindow::sceneLoaded);
  window.openPath(qs(gapped));
  ASSERT_TRUE(waitFor([&] { return loaded.count() > 0; }, 30000)) << window.opener()->lastError().toStdString();

  const QString status = window.statusBar()->currentMessage();
  EXPECT_TRUE(status.contains("missing slice")) << status.toStdString();
  EXPECT_TRUE(status.contains("CTHead49.dcm") && status.contains("CTHead51.dcm")) << status.toStdString();

  EXPECT_TRUE(panel->isVisible()) << "the banner shows itself";
  ASSERT_FALSE(panel->notices().isEmpty());
  const QString text = panel->findChild<QLabel*>("loadNoticeText")->text();
  EXPECT_TRUE(text.contains("CTHead49.dcm") && text.contains("CTHead51.dcm")) << text.toStdString();
  const QString summary = panel->findChild<QLabel*>("loadNoticeSummary")->text();
  EXPECT_TRUE(summary.contains("ct-head-gap")) << "titled with the scan: " << summary.toStdString();
  EXPECT_FALSE(panel->phaseSpinBox()->isVisible()) << "a 3-D series offers no time points";

  // The same series is what the scene names (and so a recording), by its UID.
  EXPECT_FALSE(window.session().loaded().spec.volume.series.empty());
  EXPECT_EQ(window.session().loaded().spec.volume.series, window.session().loaded().volume.info.series_uid);
  EXPECT_EQ(window.session().loaded().spec.volume.series, window.session().loaded().volume.info.series_uid);

  // Dismissed, then reopened from the Help menu.
  panel->findChild<QToolButton*>("loadNoticeClose")->click();
  EXPECT_FALSE(panel->isVisible());
  QAction* notes = menuAction(window, "Load Notes");
  ASSERT_NE(notes, nullptr) << "Help > Load Notes";
  notes->trigger();
  EXPECT_TRUE(panel->isVisible());
  EXPECT_TRUE(panel->findChild<QLabel*>("loadNoticeText")->text().contains("CTHead49.dcm"));
  window.close();
}

TEST(LoadNotices, CancellingAReadShowsItsProgressAndKeepsThePreviousScene) {
  if (!fs::exists(kHead)) GTEST_SKIP() << "dataset absent: " << kHead;
  MainWindow window;
  window.setInteractive(false);
  window.resize(1000, 700);
  window.show();
  QSignalSpy loaded(&window, &MainWindow::sceneLoaded);
  window.openPath(qs(kHead));
  ASSERT_TRUE(waitFor([&] { return loaded.count() > 0; }, 30000)) << window.opener()->lastError().toStdString();
  ASSERT_TRUE(waitFor([&] { return !window.opener()->loading(); }, 30000));
  ASSERT_TRUE(window.session().hapticsRunning());
  vtkVolume* shown = window.sceneView()->actors().volume();
  const std::string title = window.sceneTitle();
  ASSERT_TRUE(waitFor([&] { window.viewController()->refresh(); return window.viewController()->lastSnapshot().tick > 0; }, 30000));
  const auto ticks_before = window.viewController()->lastSnapshot().tick;

  // A read that reports a quarter done, then waits for the cancel as io::loadVolume does.
  std::atomic<bool> saw_cancel{false};
  window.loader()->setSceneLoadFunction(
      [&saw_cancel](const runtime::SceneSpec&, const std::function<void(double)>& progress,
                    const std::atomic<bool>* cancel) -> runtime::LoadedScene {
        progress(0.25);
        const auto end = std::chrono::steady_clock::now() + std::chrono::seconds(120);  // longer than the test's waits
        while (cancel != nullptr && !cancel->load() && std::chrono::steady_clock::now() < end) {
          std::this_thread::sleep_for(std::chrono::milliseconds(2));
        }
        saw_cancel = cancel != nullptr && cancel->load();
        throw io::LoadCancelled("big.nrrd: cancelled");
      });
  QSignalSpy failed(&window, &MainWindow::loadFailed);
  window.openPath(qs(kHead));
  auto* bar = window.findChild<QProgressBar*>("progressBar");
  ASSERT_NE(bar, nullptr);
  ASSERT_TRUE(waitFor([&] { return bar->isVisible() && bar->maximum() == 100 && bar->value() == 17; }, 30000))
      << "the read's fraction 0.25 shows as 17 % (0..70 % for the read); value " << bar->value();
  auto* cancel = window.findChild<QToolButton*>("progressCancel");
  ASSERT_NE(cancel, nullptr);
  EXPECT_TRUE(cancel->isVisible());
  cancel->click();
  EXPECT_FALSE(window.opener()->loading());
  EXPECT_TRUE(window.statusBar()->currentMessage().contains("cancelled", Qt::CaseInsensitive))
      << window.statusBar()->currentMessage().toStdString();
  window.loader()->waitForIdle();
  test::pump(200);
  EXPECT_TRUE(saw_cancel.load()) << "the read was told to stop";
  EXPECT_EQ(failed.count(), 0) << "a cancel is no error";
  EXPECT_EQ(loaded.count(), 1);
  EXPECT_EQ(window.sceneView()->actors().volume(), shown);
  EXPECT_EQ(window.sceneTitle(), title);
  EXPECT_TRUE(window.session().hapticsRunning()) << "the haptic thread runs on";
  EXPECT_TRUE(waitFor([&] { window.viewController()->refresh(); return window.viewController()->lastSnapshot().tick > ticks_before + 10; }, 30000))
      << "the haptic thread still ticks";
  EXPECT_FALSE(bar->isVisible());
  window.close();
}

TEST(LoadNotices, TheChosenTimePointReachesTheSceneSpec) {
  QTemporaryDir dir;
  ASSERT_TRUE(dir.isValid());
  const fs::path folder = fs::path(dir.path().toStdString()) / "cardiac";
  const io::test::SourceVolume ball = io::test::ballVolume({24, 24, 12}, {1.0, 1.0, 2.0}, {0.0, 0.0, 0.0},
                                                           {12.0, 12.0, 12.0}, 8.0);
  io::test::SeriesSpec spec;
  spec.time_points = 3;
  spec.series_description = "cardiac";
  const io::test::WrittenSeries written = io::test::writeSeries(folder, ball, spec);

  // The chooser offers the time points of the listed series and returns the 0-based choice.
  const std::vector<io::DicomSeriesInfo> listed = io::listDicomSeries(folder);
  ASSERT_EQ(listed.size(), 1u);
  EXPECT_EQ(estimatedTimePoints(listed.front()), 3);
  SeriesChooserDialog chooser(qs(folder), listed);
  EXPECT_TRUE(chooser.phaseSpinBox()->isEnabled());
  EXPECT_EQ(chooser.phaseSpinBox()->maximum(), 3);
  chooser.phaseSpinBox()->setValue(2);
  EXPECT_EQ(chooser.selectedPhase(), 1);

  MainWindow window;
  window.setInteractive(false);
  window.setAutoStartHaptics(false);
  window.resize(1000, 700);
  window.show();
  QSignalSpy loaded(&window, &MainWindow::sceneLoaded);
  window.opener()->openDicomSeries(listed.front(), chooser.selectedPhase());
  ASSERT_TRUE(waitFor([&] { return loaded.count() == 1; }, 30000)) << window.opener()->lastError().toStdString();
  EXPECT_EQ(window.session().loaded().spec.volume.phase, 1);
  EXPECT_EQ(window.session().loaded().spec.volume.series, written.series_uid);
  EXPECT_EQ(window.session().loaded().volume.info.phase, 1);
  EXPECT_EQ(window.session().loaded().volume.info.phase_count, 3);

  // The banner names the 4-D series and offers its other time points; the choice reloads.
  LoadNoticePanel* panel = window.loadNotices();
  ASSERT_TRUE(panel->isVisible());
  EXPECT_TRUE(panel->notices().join('\n').contains("3 time points")) << panel->notices().join('\n').toStdString();
  ASSERT_TRUE(panel->phaseSpinBox()->isVisible());
  EXPECT_EQ(panel->phaseSpinBox()->value(), 2) << "shown 1-based";
  EXPECT_EQ(panel->phaseSpinBox()->maximum(), 3);
  panel->phaseSpinBox()->setValue(3);
  panel->phaseLoadButton()->click();
  ASSERT_TRUE(waitFor([&] { return loaded.count() == 2; }, 30000)) << window.opener()->lastError().toStdString();
  EXPECT_EQ(window.session().loaded().spec.volume.phase, 2);
  EXPECT_EQ(window.session().loaded().volume.info.phase, 2);
  EXPECT_EQ(window.session().loaded().spec.volume.phase, 2) << "what a recording's metadata describes";
  EXPECT_EQ(window.session().loaded().spec.volume.series, written.series_uid);
  window.close();
}

}  // namespace
}  // namespace vh::ui
