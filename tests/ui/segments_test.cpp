// Segments in the GUI: the Segments panel, the controller that applies its choices to
// the session, and the segment surfaces. Oracles: the test's own ball (its analytic radius and
// centre in W, from the geometry the test wrote), the session's segments after each command,
// and for a DICOM SEG opened in the window the label map it was written from with DCMTK
// (dicom_seg_fixtures.h), compared voxel for voxel; for a replayed session in which segments
// were felt, the scan's isovalue the scene was written with.
#include "vh/ui/panels/segments_panel.h"

#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <memory>
#include <sstream>
#include <string>

#include <unistd.h>

#include <QApplication>
#include <QCheckBox>
#include <QFileDialog>
#include <QLabel>
#include <QMainWindow>
#include <QPushButton>
#include <QSignalSpy>
#include <QStatusBar>
#include <QTableWidget>
#include <QTemporaryDir>
#include <QTimer>

#include <gtest/gtest.h>
#include <vtkActor.h>
#include <vtkCamera.h>
#include <vtkMapper.h>
#include <vtkPropCollection.h>
#include <vtkProperty.h>
#include <vtkMatrix4x4.h>
#include <vtkRenderer.h>
#include <vtkPolyData.h>

#include "dicom_seg_fixtures.h"
#include "ui_test_util.h"
#include "vh/io/nrrd_writer.h"
#include "vh/io/segmentation.h"
#include "vh/runtime/recording.h"
#include "vh/runtime/scene.h"
#include "vh/runtime/session.h"
#include "vh/runtime/session_metadata.h"
#include "vh/ui/view/scene_view.h"
#include "vh/ui/view/segment_surfaces.h"
#include "vh/ui/segments_controller.h"
#include "vh/ui/export/media_export.h"
#include "vh/ui/main_window.h"
#include "vh/ui/preferences.h"
#include "vh/ui/replay/replay_controller.h"
#include "vh/ui/scene_opener.h"
#include "vh/ui/view/vtk_view.h"

namespace vh::ui {
namespace {

namespace fs = std::filesystem;

// The test's case: 28 x 28 x 16 voxels of 1 x 1 x 2 mm, axes (-x, -y, +z) as 3D Slicer writes
// LPS, origin (40, 30, -10) mm. Segment 1 "nerve": a ball of radius 8 mm about grid (13, 14, 8);
// segment 2 "bone": the slab k in [1, 3]. The CT has both at 300 (one intensity).
constexpr int kNx = 28, kNy = 28, kNz = 16;
const Eigen::Vector3d kSpacing_mm(1.0, 1.0, 2.0);
const Eigen::Vector3d kOrigin_mm(40.0, 30.0, -10.0);
const Eigen::Matrix3d kDirection = Eigen::Vector3d(-1.0, -1.0, 1.0).asDiagonal();
const Eigen::Vector3d kBallGrid(13.0, 14.0, 8.0);
constexpr double kBallRadius_mm = 8.0;

Eigen::Vector3d toW_mm(const Eigen::Vector3d& ijk) { return kOrigin_mm + kDirection * kSpacing_mm.cwiseProduct(ijk); }

int labelAt(int i, int j, int k) {
  if ((toW_mm(Eigen::Vector3d(i, j, k)) - toW_mm(kBallGrid)).norm() <= kBallRadius_mm) return 1;
  return k >= 1 && k <= 3 ? 2 : 0;
}

std::string header(const std::string& type, const std::string& extra) {
  std::ostringstream h;
  h << "NRRD0004\ntype: " << type << "\ndimension: 3\nspace: left-posterior-superior\nsizes: " << kNx << " " << kNy
    << " " << kNz << "\nspace directions: (-1,0,0) (0,-1,0) (0,0,2)\nkinds: domain domain domain\nendian: little\n"
    << "encoding: raw\nspace origin: (40,30,-10)\n" << extra << "\n";
  return h.str();
}

/// Writes ct.nrrd and case.seg.nrrd into a fresh folder.
fs::path writeCase(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() / ("vh_ui_segments_" + name + "_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  std::string ct, labels;
  for (int k = 0; k < kNz; ++k) {
    for (int j = 0; j < kNy; ++j) {
      for (int i = 0; i < kNx; ++i) {
        const int label = labelAt(i, j, k);
        const std::int16_t hu = label != 0 ? 300 : 0;
        ct.append(reinterpret_cast<const char*>(&hu), 2);
        labels.push_back(static_cast<char>(label));
      }
    }
  }
  std::ofstream(dir / "ct.nrrd", std::ios::binary) << header("short", "") << ct;
  const std::string keys =
      "Segment0_Color:=1 0.8 0.1\nSegment0_ID:=Segment_1\nSegment0_LabelValue:=1\nSegment0_Layer:=0\n"
      "Segment0_Name:=nerve\nSegment1_Color:=0.9 0.9 0.85\nSegment1_ID:=Segment_2\nSegment1_LabelValue:=2\n"
      "Segment1_Layer:=0\nSegment1_Name:=bone\n";
  std::ofstream(dir / "case.seg.nrrd", std::ios::binary) << header("unsigned char", keys) << labels;
  return dir;
}

runtime::LoadedScene loadCase(const fs::path& dir, bool with_segmentation) {
  runtime::SceneSpec spec;
  spec.volume.path = (dir / "ct.nrrd").string();
  spec.volume.isovalue = 150.0;
  spec.volume.isovalue_set = true;
  spec.tool.mesh = "builtin:sphere";
  spec.tool.scale_to_m = 0.3;
  spec.device = runtime::DeviceSpec{};
  if (with_segmentation) {
    spec.segmentation = runtime::SegmentationSpec{};
    spec.segmentation->path = (dir / "case.seg.nrrd").string();
    spec.segmentation->felt = {"nerve"};
    spec.segmentation->critical = {"nerve"};
  }
  return runtime::loadScene(spec);
}

TEST(SegmentsPanel, ShowsTheSegmentsAndEmitsTheChoicesTicked) {
  const fs::path dir = writeCase("panel");
  const runtime::LoadedScene scene = loadCase(dir, true);
  SegmentsPanel panel;
  panel.showSegments(scene.segments.get());
  QTableWidget* table = panel.table();
  ASSERT_EQ(table->rowCount(), 2);
  EXPECT_EQ(table->item(0, SegmentsPanel::kName)->text(), "nerve");
  EXPECT_EQ(table->item(1, SegmentsPanel::kName)->text(), "bone");
  EXPECT_EQ(table->item(0, SegmentsPanel::kFelt)->checkState(), Qt::Checked);
  EXPECT_EQ(table->item(1, SegmentsPanel::kFelt)->checkState(), Qt::Unchecked);
  EXPECT_EQ(table->item(0, SegmentsPanel::kCritical)->checkState(), Qt::Checked);
  EXPECT_EQ(table->item(1, SegmentsPanel::kShown)->checkState(), Qt::Checked);  // "shown" absent: all

  QSignalSpy spy(&panel, &SegmentsPanel::choicesChanged);
  table->item(1, SegmentsPanel::kFelt)->setCheckState(Qt::Checked);
  ASSERT_EQ(spy.count(), 1);
  const auto chosen = spy.takeFirst().at(0).value<SegmentChoices>();
  EXPECT_EQ(chosen.felt, (std::vector<int>{0, 1}));
  EXPECT_EQ(chosen.critical, (std::vector<int>{0}));

  panel.setTouched(0);
  EXPECT_TRUE(table->item(0, SegmentsPanel::kName)->font().bold());
  auto labels = panel.findChildren<QLabel*>();
  const bool says = std::any_of(labels.begin(), labels.end(),
                                [](QLabel* l) { return l->text() == "Touching: nerve (CRITICAL)"; });
  EXPECT_TRUE(says);
  panel.showSegments(nullptr);
  EXPECT_EQ(table->rowCount(), 0);
  EXPECT_EQ(spy.count(), 0) << "showing does not emit";
  fs::remove_all(dir);
}

// A critical segment's warning and alarm distances in the panel: shown in mm from the set, an
// edit within 0 < alarm <= warn <= 20 mm is taken into the choices (in metres), anything else is
// put back without a signal.
TEST(SegmentsPanel, TheWarningAndAlarmDistancesAreEditedWithinTheirRange) {
  const fs::path dir = writeCase("thresholds");
  const runtime::LoadedScene scene = loadCase(dir, true);
  SegmentsPanel panel;
  panel.showSegments(scene.segments.get());
  QTableWidget* table = panel.table();
  EXPECT_EQ(table->item(0, SegmentsPanel::kWarn)->text(), "2");
  EXPECT_EQ(table->item(0, SegmentsPanel::kAlarm)->text(), "1");
  QSignalSpy spy(&panel, &SegmentsPanel::choicesChanged);
  table->item(0, SegmentsPanel::kWarn)->setText("3.5");
  ASSERT_EQ(spy.count(), 1);
  const auto chosen = spy.takeFirst().at(0).value<SegmentChoices>();
  ASSERT_EQ(chosen.thresholds.size(), 2u);
  EXPECT_DOUBLE_EQ(chosen.thresholds[0].warn_m, 3.5e-3);
  EXPECT_DOUBLE_EQ(chosen.thresholds[0].alarm_m, 1e-3);
  for (const char* refused : {"25", "0", "-1", "abc"}) {
    table->item(0, SegmentsPanel::kWarn)->setText(refused);
    EXPECT_EQ(table->item(0, SegmentsPanel::kWarn)->text(), "3.5") << refused << " is put back";
  }
  table->item(0, SegmentsPanel::kAlarm)->setText("4");  // above the warning distance
  EXPECT_EQ(table->item(0, SegmentsPanel::kAlarm)->text(), "1");
  EXPECT_EQ(spy.count(), 0) << "nothing refused is emitted";
  fs::remove_all(dir);
}

/// A main window stand-in: the scene view as the central widget, the session, the controller.
struct Host {
  Host() {
    view = new SceneView(&window);
    window.setCentralWidget(view->widget());
    window.resize(480, 360);
    window.show();
    controller = new SegmentsController(session, *view, &window, window.statusBar(), prefs);
  }
  Preferences prefs;
  runtime::Session session;
  QMainWindow window;
  SceneView* view = nullptr;
  SegmentsController* controller = nullptr;
};

TEST(SegmentsController, OpensASegmentationAppliesChoicesAndAlertsOnACriticalTouch) {
  const fs::path dir = writeCase("controller");
  Host host;
  runtime::LoadedScene scene = loadCase(dir, false);
  auto device = scene.makeDevice();
  const SceneActorsSpec spec = sceneActorsSpecFor(scene, runtime::LiveValues::initial(scene));
  host.session.setScene(std::move(scene), device);
  host.view->setScene(spec, host.session.live().X_WT_initial, ViewLook{});

  QSignalSpy errors(host.controller, &SegmentsController::errorReported);
  ASSERT_TRUE(host.controller->open(dir / "case.seg.nrrd"));
  ASSERT_NE(host.session.live().segments, nullptr);
  EXPECT_FALSE(host.session.live().feltSegments()) << "opening shows; nothing is felt until ticked";
  EXPECT_EQ(host.controller->panel()->table()->rowCount(), 2);
  ASSERT_NE(host.view->segmentSurfaces(), nullptr);
  EXPECT_EQ(host.view->segmentSurfaces()->shownSegments(), (std::vector<int>{0, 1}));

  // Feel and guard the nerve; show only it.
  ASSERT_FALSE(host.prefs.segments_through_scan);
  SegmentChoices choices;
  choices.felt = {0};
  choices.shown = {0};
  choices.critical = {0};
  ASSERT_TRUE(host.controller->apply(choices));
  ASSERT_TRUE(host.session.live().feltSegments());
  // Felt from now on, the nerve (inside the scan's surface) and the tool are drawn through the
  // scan, once; unticked again, they stay behind it while the nerve stays felt.
  EXPECT_TRUE(host.prefs.segments_through_scan);
  EXPECT_TRUE(host.view->segmentLayer()->GetDraw()) << "the segments' layer is drawn over the scan";
  host.controller->setThroughScan(false);
  ASSERT_TRUE(host.controller->apply(choices));
  EXPECT_FALSE(host.prefs.segments_through_scan) << "the user's choice is kept while the nerve stays felt";
  EXPECT_EQ(host.session.live().segmentation->felt, std::vector<std::string>{"nerve"});
  EXPECT_EQ(host.session.live().segmentation->critical, std::vector<std::string>{"nerve"});
  EXPECT_EQ(host.view->segmentSurfaces()->shownSegments(), std::vector<int>{0});
  ASSERT_NE(host.session.hapticThread(), nullptr) << "the threads are rebuilt on the nerve's surface";
  // The panel's distances reach the session's segments and the scene's spec (the nerve's own).
  choices.thresholds = {runtime::ProximityThresholds{4e-3, 2e-3}, runtime::ProximityThresholds{}};
  ASSERT_TRUE(host.controller->apply(choices));
  EXPECT_DOUBLE_EQ(host.session.live().segments->thresholds(0).warn_m, 4e-3);
  EXPECT_DOUBLE_EQ(host.session.live().segments->thresholds(0).alarm_m, 2e-3);
  ASSERT_EQ(host.session.live().segmentation->proximity.per_segment.count("nerve"), 1u);
  EXPECT_EQ(host.session.live().segmentation->proximity.per_segment.size(), 1u);

  // A snapshot touching the nerve: the alert; leaving it: none. The beep (the window's alert
  // tone) only with the panel's sound ticked.
  QSignalSpy beeps(host.controller, &SegmentsController::alertSoundRequested);
  runtime::HapticSnapshot touching;
  touching.contacts = 2;
  touching.segment = 0;
  host.controller->showSnapshot(touching);
  EXPECT_NE(host.view->alertText().find("nerve"), std::string::npos) << host.view->alertText();
  EXPECT_EQ(host.controller->criticalAlerts(), 1);
  host.controller->showSnapshot(touching);  // still touching: no second alert
  EXPECT_EQ(host.controller->criticalAlerts(), 1);
  host.controller->showSnapshot(runtime::HapticSnapshot{});
  EXPECT_EQ(host.view->alertText(), "");
  EXPECT_EQ(beeps.count(), 0) << "sound not ticked";
  QCheckBox* sound = nullptr;
  QCheckBox* burr_sound = nullptr;
  for (QCheckBox* box : host.controller->panel()->findChildren<QCheckBox*>()) {
    if (box->text() == "Alert sounds (critical segment near or touched, technique)") sound = box;
    if (box->text() == "Burr sound") burr_sound = box;
  }
  ASSERT_NE(sound, nullptr);
  ASSERT_NE(burr_sound, nullptr);
  sound->setChecked(true);
  host.controller->showSnapshot(touching);
  EXPECT_EQ(beeps.count(), 1);
  QSignalSpy burr_toggled(host.controller->panel(), &SegmentsPanel::burrSoundToggled);
  EXPECT_FALSE(host.controller->panel()->burrSound()) << "the burr is silent until asked";
  burr_sound->setChecked(true);
  EXPECT_TRUE(host.controller->panel()->burrSound());
  EXPECT_EQ(burr_toggled.count(), 1);

  // A damaged file is reported and the segments stay.
  std::ofstream(dir / "bad.seg.nrrd") << "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 4 4\n\n";
  EXPECT_FALSE(host.controller->open(dir / "bad.seg.nrrd"));
  EXPECT_EQ(errors.count(), 1);
  EXPECT_TRUE(host.session.live().feltSegments());
  host.session.clear();
  fs::remove_all(dir);
}

// A session in which segments were felt records on every tick the level the hand felt (the
// segments' surface level, 0.5), not the scan's isovalue. Replayed in the window, the scan must
// stay at the scene's isovalue (150 here) while the Replay dock moves through the ticks.
// The panel's "Open Segmentation..." button opens the same file dialog as File > Open
// Segmentation (it was connected to nothing: four clicks did nothing); cancelled, nothing opens.
// Opening a segmentation reads it and builds its surfaces on a worker thread: the window goes on
// drawing (its timers and repaints run during the open; input waits until it is done) and the
// haptic threads go on with the force (a segmentation opened to be seen keeps the felt surface),
// where the GUI thread used to be held for the whole load (about 10 s on the head phantom).
// Oracle: a timer due at once fires before open() returns, and the threads are the same,
// running ones, their tick count going on.
TEST(SegmentsController, OpeningASegmentationLeavesTheWindowDrawingAndTheForceOn) {
  if (!fs::exists(test::kHead)) GTEST_SKIP() << test::kHead << " is absent (the shared datasets, ../shared/datasets)";
  Host host;
  runtime::LoadedScene scene = runtime::loadScene(runtime::sceneForVolume(test::kHead));
  auto device = scene.makeDevice();
  const SceneActorsSpec spec = sceneActorsSpecFor(scene, runtime::LiveValues::initial(scene));
  host.session.setScene(std::move(scene), device);
  host.view->setScene(spec, host.session.live().X_WT_initial, ViewLook{});
  host.session.startHaptics();
  ASSERT_TRUE(host.session.hapticsRunning());
  runtime::HapticSnapshot snap;
  ASSERT_TRUE(test::waitFor([&] { return host.session.latestSnapshot(snap) && snap.tick > 500; }, 30000));

  // Two labels from the scan itself: its brightest voxels (bone) in the middle third.
  const haptics::ScalarVolume& f = *host.session.loaded().volume.field;
  const haptics::VolumeGeometry& g = f.geometry();
  std::vector<std::uint8_t> labels(g.voxelCount(), 0);
  const double bone = f.minValue() + 0.7 * (f.maxValue() - f.minValue());
  for (int k = g.dims[2] / 3; k < 2 * g.dims[2] / 3; ++k)
    for (int j = 0; j < g.dims[1]; ++j)
      for (int i = 0; i < g.dims[0]; ++i)
        if (f.voxel(i, j, k) > bone)
          labels[static_cast<std::size_t>(i) + static_cast<std::size_t>(g.dims[0]) * (j + static_cast<std::size_t>(g.dims[1]) * k)] =
              i < g.dims[0] / 2 ? 1 : 2;
  io::NrrdVolume label_map;
  label_map.dims = g.dims;
  label_map.spacing_m = g.spacing_m;
  label_map.origin_W_m = g.origin_W_m;
  label_map.direction_W = g.direction_W;
  label_map.type = "uchar";
  label_map.voxels = labels.data();
  QTemporaryDir dir;
  const fs::path path = fs::path(dir.path().toStdString()) / "bone-halves.nrrd";
  io::writeNrrd(path, label_map);

  const runtime::HapticThread* threads = host.session.hapticThread();
  bool opening = true;
  int timer_fired_during_open = 0;
  QTimer::singleShot(0, host.controller, [&] { timer_fired_during_open += opening ? 1 : 0; });
  host.session.latestSnapshot(snap);
  const std::uint64_t tick_before = snap.tick;
  ASSERT_TRUE(host.controller->open(path));
  opening = false;
  EXPECT_EQ(timer_fired_during_open, 1) << "the window's event loop ran while the segmentation loaded";
  ASSERT_NE(host.session.live().segments, nullptr);
  EXPECT_EQ(host.view->segmentSurfaces()->shownSegments(), (std::vector<int>{0, 1})) << "the surfaces built off the GUI thread are drawn";
  EXPECT_EQ(host.session.hapticThread(), threads);
  EXPECT_TRUE(host.session.hapticsRunning());
  host.session.latestSnapshot(snap);
  EXPECT_GE(snap.tick, tick_before) << "the same threads' count goes on (a restart counts from 0 again)";
  host.session.stopHaptics();
}

TEST(SegmentsController, ThePanelsOpenButtonAsksForTheFile) {
  Host host;
  QPushButton* button = nullptr;
  for (QPushButton* b : host.controller->panel()->findChildren<QPushButton*>())
    if (b->text() == "Open Segmentation...") button = b;
  ASSERT_NE(button, nullptr);
  QString title;
  QTimer closer;
  QObject::connect(&closer, &QTimer::timeout, [&] {
    if (auto* dialog = qobject_cast<QFileDialog*>(QApplication::activeModalWidget())) {
      title = dialog->windowTitle();
      dialog->reject();
    }
  });
  closer.start(50);
  QTimer::singleShot(0, button, &QPushButton::click);
  ASSERT_TRUE(test::waitFor([&] { return !title.isEmpty(); }, 30000)) << "no file dialog came up";
  EXPECT_NE(title.indexOf("segmentation"), -1) << title.toStdString();
  EXPECT_EQ(host.session.hasScene(), false);
}

TEST(SegmentsReplay, TheReplayDockKeepsTheScansIsovalueWhenSegmentsWereFelt) {
  const fs::path dir = writeCase("replay");
  const fs::path path = dir / "felt.vhrec";
  {
    const runtime::LoadedScene scene = loadCase(dir, true);
    ASSERT_TRUE(scene.feltSegments());
    runtime::RecordingWriter writer(path, runtime::makeSessionMetadata(scene, {"Scripted device", "scripted", ""}));
    for (std::uint64_t i = 0; i < 100; ++i) {
      runtime::TickRecord r;
      r.tick = i + 1;
      r.time_s = 1e-3 * static_cast<double>(i);
      r.isovalue = io::kSegmentSurfaceLevel;  // what a tick on felt segments records
      r.p_WD_m[2] = r.p_WP_m[2] = 0.05;
      ASSERT_TRUE(writer.push(r));
    }
    writer.close();
  }
  auto w = std::make_unique<MainWindow>();
  w->setInteractive(false);
  w->resize(520, 420);
  w->show();
  QSignalSpy started(w->replay(), &ReplayController::replayStarted);
  w->openPath(QString::fromStdString(path.string()));
  ASSERT_TRUE(test::waitFor([&] { return started.count() > 0 && !w->opener()->loading(); }, 60000))
      << w->opener()->lastError().toStdString();
  ASSERT_TRUE(w->replay()->active());
  ASSERT_TRUE(w->session().live().feltSegments()) << "the recording's scene feels the nerve";
  EXPECT_EQ(w->session().isovalue(), 150.0);
  for (const double t_s : {0.0, 0.05, 0.099}) {
    w->replay()->setTime(t_s);
    EXPECT_EQ(w->session().isovalue(), 150.0) << "t " << t_s;
    EXPECT_EQ(w->sceneView()->actors().isovalue(), 150.0)
        << "t " << t_s << ": the picture shows the scan at the segments' level, not at the scene's isovalue";
  }
  w.reset();
  fs::remove_all(dir);
}

// Exported pictures show the segments the replay showed (they were left out): the exporter's
// frames draw the recording scene's shown segments with SegmentSurfaces, as the main view, and
// emphasise the one each record touched. Oracle: the surfaces drawn are the shown segments, the
// touched one is drawn brighter while it is touched.
TEST(SegmentsExport, ExportedFramesShowTheShownSegmentsAndTheTouchedOne) {
  const fs::path dir = writeCase("export");
  const fs::path path = dir / "shown.vhrec";
  const runtime::LoadedScene scene = loadCase(dir, true);  // the nerve felt and critical, both shown
  ASSERT_NE(scene.segments, nullptr);
  {
    runtime::RecordingWriter writer(path, runtime::makeSessionMetadata(scene, {"Scripted device", "scripted", ""}));
    for (std::uint64_t i = 0; i < 20; ++i) {
      runtime::TickRecord r;
      r.tick = i + 1;
      r.time_s = 1e-3 * static_cast<double>(i);
      r.isovalue = io::kSegmentSurfaceLevel;
      r.p_WD_m[2] = r.p_WP_m[2] = 0.05;
      r.flags = runtime::recordSegmentBits(i < 10 ? -1 : 0);  // the nerve touched from record 10 on
      ASSERT_TRUE(writer.push(r));
    }
    writer.close();
  }
  const runtime::Recording recording = runtime::readRecording(path);
  MediaExportOptions options;
  options.width = 160;
  options.height = 120;
  const auto frames = exportFrameRenderer(scene, recording, options, nullptr);
  ASSERT_NE(frames->segmentSurfaces(), nullptr) << "the recording's scene has segments: the frames draw them";
  EXPECT_EQ(frames->segmentSurfaces()->shownSegments(), scene.segments->shown());
  vtkActor* nerve = nullptr;
  vtkPropCollection* props = frames->renderer()->GetViewProps();
  props->InitTraversal();
  while (vtkProp* p = props->GetNextProp()) {
    auto* a = vtkActor::SafeDownCast(p);
    if (a != nullptr && a->GetMapper() != nullptr && a->GetMapper()->GetInput() == frames->segmentSurfaces()->surface(0)) nerve = a;
  }
  ASSERT_NE(nerve, nullptr) << "the nerve's surface is in the exported frames' scene";
  const auto brightness = [&] {
    const double* c = nerve->GetProperty()->GetColor();
    return c[0] + c[1] + c[2];
  };
  frames->show(recording.records[5]);
  const double untouched = brightness();
  frames->show(recording.records[15]);
  EXPECT_GT(brightness(), untouched + 0.1) << "the touched nerve is drawn brighter";
  frames->show(recording.records[5]);
  EXPECT_DOUBLE_EQ(brightness(), untouched);
  fs::remove_all(dir);
}

TEST(SegmentSurfaces, TheNervesSurfaceIsTheBallInTheSceneFrame) {
  const fs::path dir = writeCase("surfaces");
  const runtime::LoadedScene scene = loadCase(dir, true);
  Host host;
  host.view->setSegments(scene.segments.get());
  const SegmentSurfaces* surfaces = host.view->segmentSurfaces();
  ASSERT_NE(surfaces, nullptr);
  vtkPolyData* nerve = surfaces->surface(0);
  ASSERT_NE(nerve, nullptr);
  ASSERT_GT(nerve->GetNumberOfPoints(), 100);
  // The actor applies the direction about the origin: p_W = o + D (p - o) (as the volume's).
  const Eigen::Vector3d o_m = scene.segments->feltField()->geometry().origin_W_m;
  const Eigen::Vector3d c_m = toW_mm(kBallGrid) * 1e-3;
  double max_error_mm = 0.0, mean_error_mm = 0.0;
  for (vtkIdType p = 0; p < nerve->GetNumberOfPoints(); ++p) {
    double x[3];
    nerve->GetPoint(p, x);
    const Eigen::Vector3d p_W = o_m + kDirection * (Eigen::Vector3d(x[0], x[1], x[2]) - o_m);
    const double e = std::abs((p_W - c_m).norm() * 1e3 - kBallRadius_mm);
    max_error_mm = std::max(max_error_mm, e);
    mean_error_mm += e / static_cast<double>(nerve->GetNumberOfPoints());
  }
  std::cout << "[ surfaces ] nerve surface vs the 8 mm ball: mean " << mean_error_mm << " mm, max " << max_error_mm
            << " mm (voxels 1 x 1 x 2 mm)\n";
  EXPECT_LT(mean_error_mm, 0.6);
  EXPECT_LT(max_error_mm, 1.5);
  fs::remove_all(dir);
}


TEST(SegmentColours, TheDifferenceIsCie1976AndColoursCloseToTheSurfaceAreReplaced) {
  // CIE 1976 oracles: black and white differ by L* 100 alone; sRGB red is L*a*b* (53.24, 80.09,
  // 67.20) (the IEC 61966-2-1 / CIE reference values).
  EXPECT_NEAR(colourDifference_Lab({0.0, 0.0, 0.0}, {1.0, 1.0, 1.0}), 100.0, 1e-3);
  EXPECT_NEAR(colourDifference_Lab({0.2, 0.4, 0.6}, {0.2, 0.4, 0.6}), 0.0, 1e-12);
  EXPECT_NEAR(colourDifference_Lab({1.0, 0.0, 0.0}, {0.0, 0.0, 0.0}), std::sqrt(53.24 * 53.24 + 80.09 * 80.09 + 67.20 * 67.20),
              0.05);
  const Rgb surface = {237.0 / 255.0, 222.0 / 255.0, 189.0 / 255.0};  // the default bone beige
  const Rgb beige = {0.93, 0.86, 0.72};                              // a SEG's "Secondary"
  ASSERT_LT(colourDifference_Lab(beige, surface), kMinSegmentContrast_Lab);
  const Rgb first = distinctSegmentColour(beige, surface, {});
  EXPECT_GE(colourDifference_Lab(first, surface), kMinSegmentContrast_Lab);
  const Rgb second = distinctSegmentColour(beige, surface, {first});
  EXPECT_GE(colourDifference_Lab(second, first), kMinSegmentContrast_Lab) << "two hidden segments get two colours";
  const Rgb red = {0.9, 0.3, 0.2};
  EXPECT_EQ(distinctSegmentColour(red, surface, {}), red) << "a colour that stands out is kept";
}

TEST(SegmentSurfaces, ASegmentInTheSurfacesColourIsDrawnApartSaidAndFramedOnRequest) {
  Host host;
  runtime::LoadedScene scene = test::sphereProbeScene();
  const SceneActorsSpec spec = sceneActorsSpecFor(scene, runtime::LiveValues::initial(scene));
  auto device = scene.makeDevice();
  host.session.setScene(scene, device);
  host.view->setScene(spec, host.session.live().X_WT_initial, ViewLook{});
  io::LoadedSegmentation seg =
      test::ballSegmentation(*scene.volume.field, Eigen::Vector3d(0.014, 0.0, 0.014), 0.008);
  const QColor beige = ViewLook{}.surface;
  seg.segments[0].color_rgb = {beige.redF(), beige.greenF(), beige.blueF()};  // the scan surface's own
  const auto set = std::make_shared<const runtime::SegmentSet>(seg, std::vector<int>{}, std::vector<int>{0},
                                                               std::vector<int>{}, 1.0);
  runtime::SegmentationSpec seg_spec;
  seg_spec.path = "in-memory";
  host.session.setSegments(set, seg_spec);  // the controller shows them and says what it did
  const SegmentSurfaces* surfaces = host.view->segmentSurfaces();
  ASSERT_NE(surfaces, nullptr);
  EXPECT_EQ(surfaces->recoloured(), std::vector<int>{0});
  const std::vector<double> c = surfaces->colour(0);
  ASSERT_EQ(c.size(), 3u);
  EXPECT_GE(colourDifference_Lab({c[0], c[1], c[2]}, {beige.redF(), beige.greenF(), beige.blueF()}),
            kMinSegmentContrast_Lab);
  const QString said = host.window.statusBar()->currentMessage();
  EXPECT_TRUE(said.contains("nodule") && said.contains("too close")) << said.toStdString();

  // Go to segment: the camera keeps its direction and looks at the segment's centre, closer.
  vtkCamera* camera = host.view->widget()->renderer()->GetActiveCamera();
  double dop_before[3], dop_after[3], focal[3];
  camera->GetDirectionOfProjection(dop_before);
  const double distance_before = camera->GetDistance();
  double b[6];
  ASSERT_TRUE(surfaces->bounds_W(0, b));
  ASSERT_TRUE(host.view->frameSegment(0));
  camera->GetDirectionOfProjection(dop_after);
  camera->GetFocalPoint(focal);
  for (int i = 0; i < 3; ++i) {
    EXPECT_NEAR(dop_after[i], dop_before[i], 1e-9);
    EXPECT_NEAR(focal[i], 0.5 * (b[2 * i] + b[2 * i + 1]), 1e-9);
  }
  EXPECT_LT(camera->GetDistance(), distance_before) << "framed closer than the whole volume";
  EXPECT_FALSE(host.view->frameSegment(3)) << "no such segment shown";
  host.session.clear();
}

// ---- a DICOM SEG opened in the main window --------------------------------------------------

QString qs(const fs::path& p) { return QString::fromStdString(p.string()); }

/// A main window, not interactive (errors to lastError(), no dialogs), haptics not started.
struct SegWindow {
  SegWindow() {
    window.setInteractive(false);
    window.setAutoStartHaptics(false);
    window.resize(1000, 700);
    window.show();
  }
  /// Opens the DICOM folder `ct` and waits until its scene is shown and rendered.
  ::testing::AssertionResult openScan(const fs::path& ct) {
    QSignalSpy loaded(&window, &MainWindow::sceneLoaded);
    window.openPath(qs(ct));
    if (!test::waitFor([&] { return loaded.count() > 0; }, 30000))
      return ::testing::AssertionFailure() << "the scan did not load: " << window.opener()->lastError().toStdString();
    if (!test::waitFor([&] { return !window.opener()->loading(); }, 30000))
      return ::testing::AssertionFailure() << "the scan was never rendered";
    return ::testing::AssertionSuccess();
  }
  MainWindow window;
};

/// The segments' names in the Segments panel, top to bottom.
std::vector<std::string> panelNames(const MainWindow& window) {
  std::vector<std::string> names;
  QTableWidget* table = window.segments()->panel()->table();
  for (int row = 0; row < table->rowCount(); ++row)
    names.push_back(table->item(row, SegmentsPanel::kName)->text().toStdString());
  return names;
}

TEST(Segments, ADicomSegOpensOnTheScanShownVoxelForVoxel) {
  QTemporaryDir dir;
  ASSERT_TRUE(dir.isValid());
  const fs::path root(dir.path().toStdString());
  const io::test::CtSeries ct = io::test::syntheticCt(root / "ct");
  ASSERT_EQ(ct.slices.size(), 12u);
  // Two named segments that overlap (the two balls): two layers of the SEG's one grid.
  const io::test::LabelMap m =
      io::test::firstSegments(io::test::shapes(ct.columns, ct.rows, static_cast<int>(ct.slices.size())), 2);
  ASSERT_EQ(m.names, (std::vector<std::string>{"ball A", "ball B"}));
  std::size_t both = 0;
  for (std::size_t n = 0; n < m.inside[0].size(); ++n) both += m.inside[0][n] != 0 && m.inside[1][n] != 0;
  ASSERT_GT(both, 0u) << "the segments overlap";
  const fs::path seg_path = root / "ct-seg.dcm";
  ASSERT_NO_FATAL_FAILURE(io::test::writeSeg(seg_path, ct, m, io::test::SegSpec{}));

  SegWindow w;
  ASSERT_TRUE(w.openScan(root / "ct"));
  ASSERT_TRUE(w.window.session().hasScene());
  EXPECT_EQ(w.window.session().loaded().volume.info.series_uid, ct.series_uid);
  EXPECT_EQ(w.window.session().live().segments, nullptr);
  EXPECT_TRUE(panelNames(w.window).empty());

  w.window.openPath(qs(seg_path));  // the segments are opened on the scan at once
  EXPECT_TRUE(w.window.opener()->lastError().isEmpty()) << w.window.opener()->lastError().toStdString();
  EXPECT_FALSE(w.window.opener()->loading()) << "a segmentation is no new scene";
  const auto& segments = w.window.session().live().segments;
  ASSERT_NE(segments, nullptr);
  ASSERT_EQ(segments->size(), 2u);
  EXPECT_EQ(segments->segment(0).name, "ball A");
  EXPECT_EQ(segments->segment(1).name, "ball B");
  EXPECT_TRUE(segments->segmentation().from_dicom_seg);
  EXPECT_NE(segments->segment(0).layer, segments->segment(1).layer) << "overlapping segments share no layer";
  ASSERT_TRUE(w.window.session().live().segmentation.has_value());
  EXPECT_EQ(fs::path(w.window.session().live().segmentation->path), fs::absolute(seg_path).lexically_normal());
  EXPECT_EQ(panelNames(w.window), (std::vector<std::string>{"ball A", "ball B"}));
  ASSERT_NE(w.window.sceneView()->segmentSurfaces(), nullptr);
  EXPECT_EQ(w.window.sceneView()->segmentSurfaces()->shownSegments(), (std::vector<int>{0, 1}));

  // Every voxel of each segment is the label map's, on the scan the window shows.
  const io::LoadedVolume& scan = w.window.session().loaded().volume;
  for (std::size_t s = 0; s < 2; ++s) EXPECT_EQ(segments->segment(static_cast<int>(s)).voxel_count, m.count(s));
  EXPECT_EQ(io::test::mismatches(segments->segmentation(), scan, ct, m), 0u);
  // The comparison sees one voxel of ball B changed in the label map after the SEG was written.
  io::test::LabelMap changed = m;
  const std::size_t n = changed.at(ct.columns / 2, ct.rows / 2, static_cast<int>(ct.slices.size()) / 2);
  changed.inside[1][n] = changed.inside[1][n] != 0 ? 0 : 1;
  EXPECT_EQ(io::test::mismatches(segments->segmentation(), scan, ct, changed), 1u);
  w.window.close();
}

TEST(Segments, ADicomSegWithoutAScanSaysToOpenThatScanFirst) {
  QTemporaryDir dir;
  ASSERT_TRUE(dir.isValid());
  const fs::path root(dir.path().toStdString());
  const io::test::CtSeries ct = io::test::syntheticCt(root / "ct");
  const io::test::LabelMap m =
      io::test::firstSegments(io::test::shapes(ct.columns, ct.rows, static_cast<int>(ct.slices.size())), 2);
  const fs::path seg_path = root / "ct-seg.dcm";
  ASSERT_NO_FATAL_FAILURE(io::test::writeSeg(seg_path, ct, m, io::test::SegSpec{}));

  SegWindow w;
  QSignalSpy failed(&w.window, &MainWindow::loadFailed);
  QSignalSpy loaded(&w.window, &MainWindow::sceneLoaded);
  w.window.openPath(qs(seg_path));
  const std::string error = w.window.opener()->lastError().toStdString();
  EXPECT_NE(error.find("open that scan first"), std::string::npos) << error;
  EXPECT_NE(error.find("ct-seg.dcm"), std::string::npos) << error;
  EXPECT_EQ(failed.count(), 1);
  test::pump(300);  // nothing is loading in the background either
  EXPECT_FALSE(w.window.opener()->loading());
  EXPECT_EQ(loaded.count(), 0);
  EXPECT_FALSE(w.window.hasScene());
  EXPECT_FALSE(w.window.session().hasScene());
  EXPECT_TRUE(panelNames(w.window).empty());
  w.window.close();
}

TEST(Segments, ADicomSegOfAnotherSeriesIsRefusedAndTheScanStays) {
  QTemporaryDir dir;
  ASSERT_TRUE(dir.isValid());
  const fs::path root(dir.path().toStdString());
  const io::test::CtSeries ct = io::test::syntheticCt(root / "ct");
  const io::test::LabelMap m =
      io::test::firstSegments(io::test::shapes(ct.columns, ct.rows, static_cast<int>(ct.slices.size())), 2);
  io::test::SegSpec other;
  other.referenced_series = "1.2.826.0.1.3680043.8.498.77";
  const fs::path seg_path = root / "other-series-seg.dcm";
  ASSERT_NO_FATAL_FAILURE(io::test::writeSeg(seg_path, ct, m, other));

  SegWindow w;
  ASSERT_TRUE(w.openScan(root / "ct"));
  const runtime::Session& session = w.window.session();
  const auto field = session.loaded().volume.field;
  const std::string title = w.window.sceneTitle();
  ASSERT_NE(field, nullptr);
  EXPECT_TRUE(w.window.opener()->lastError().isEmpty());

  QSignalSpy loaded(&w.window, &MainWindow::sceneLoaded);
  w.window.openPath(qs(seg_path));
  const std::string error = w.window.opener()->lastError().toStdString();
  EXPECT_NE(error.find("other-series-seg.dcm"), std::string::npos) << error;
  EXPECT_NE(error.find("another series"), std::string::npos) << error;
  EXPECT_NE(error.find("1.2.826.0.1.3680043.8.498.77"), std::string::npos) << error;
  test::pump(300);
  EXPECT_EQ(loaded.count(), 0);
  EXPECT_FALSE(w.window.opener()->loading());
  // The scan shown is the one it was, and it still has no segments.
  ASSERT_TRUE(session.hasScene());
  EXPECT_EQ(session.loaded().volume.field, field);
  EXPECT_EQ(session.loaded().volume.info.series_uid, ct.series_uid);
  EXPECT_EQ(w.window.sceneTitle(), title);
  EXPECT_EQ(session.live().segments, nullptr);
  EXPECT_FALSE(session.live().segmentation.has_value());
  EXPECT_TRUE(panelNames(w.window).empty());
  w.window.close();
}

}  // namespace
}  // namespace vh::ui
