// Drilling in the GUI, checked as a person would see it under Xvfb:
//  * the picture after a removal uploaded as a box (glTexSubImage3D) equals a fresh view of the
//    same drilled image uploaded whole (the independent path: VTK's own upload);
//  * Haptics > Drill on the built-in sphere: the burr pressed into it by the simulated device
//    removes voxels, the picture shows them removed within frames, and File > Export writes a
//    NRRD that VTK's own NRRD reader reads back voxel for voxel and a .seg.nrrd whose one segment
//    "drilled" holds exactly the removed voxels.
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <thread>

#include <QApplication>
#include <QCheckBox>
#include <QAudioDevice>
#include <QMainWindow>
#include <QMediaDevices>
#include <QSignalSpy>
#include <QStatusBar>
#include <QTableWidget>

#include <gtest/gtest.h>
#include <vtkDataArray.h>
#include <vtkImageData.h>
#include <vtkNrrdReader.h>
#include <vtkPointData.h>

#include "phantom_window.h"
#include "ui_test_util.h"
#include "view_host.h"
#include "drilling_scenes.h"
#include "vh/io/segmentation.h"
#include "vh/runtime/recording.h"
#include "vh/runtime/replay.h"
#include "vh/ui/replay/session_recorder.h"
#include "vh/runtime/scene.h"
#include "vh/runtime/session.h"
#include "vh/runtime/session_metadata.h"
#include "vh/runtime/session_metrics.h"
#include "vh/ui/drill_controller.h"
#include "vh/runtime/runner.h"
#include "vh/ui/main_window.h"
#include "vh/ui/panels/segments_panel.h"
#include "vh/ui/replay/replay_controller.h"
#include "vh/ui/tool_picker.h"
#include "vh/ui/export/media_export.h"
#include "vh/ui/view/scene_view.h"
#include "vh/ui/view/vtk_view.h"

namespace vh::ui {
namespace {
namespace fs = std::filesystem;

using ViewHost = test::SceneWindowHost;

fs::path outputDir() {
  const fs::path dir = fs::temp_directory_path() / "vh-ui-drilling";
  fs::create_directories(dir);
  return dir;
}

runtime::LoadedScene drillScene() {
  return runtime::loadScene(runtime::parseScene(
      R"({"volume": {"path": "builtin:sphere"}, "tool": {"mesh": "builtin:drill", "point_spacing_m": 0.001},
          "coupling": {"linear_N_per_m": 400}, "device": {"kind": "simulated"}})",
      "drill.json", "."));
}

// The voxels the picture shows removed: at the scan's lowest value in `shown` and not in the
// scan's own image `original`.
std::uint64_t removedInPicture(vtkImageData* shown, vtkImageData* original) {
  double range[2];
  original->GetScalarRange(range);
  vtkDataArray* shown_values = shown->GetPointData()->GetScalars();
  vtkDataArray* original_values = original->GetPointData()->GetScalars();
  std::uint64_t n = 0;
  for (vtkIdType i = 0; i < shown_values->GetNumberOfTuples(); ++i)
    n += shown_values->GetComponent(i, 0) == range[0] && original_values->GetComponent(i, 0) != range[0];
  return n;
}

// The picture and the hand of one session: a window's scene view, a Session on the drill scene
// (a simulated device) shown in it, and the drill controller between them.
struct DrillingSession {
  DrillingSession() : drill(session, *host.view) {
    runtime::LoadedScene scene = drillScene();
    tool = scene.tool;
    tool_spec = scene.spec.tool;
    spec = sceneActorsSpecFor(scene, runtime::LiveValues::initial(scene));
    auto device = scene.makeDevice();
    session.setScene(std::move(scene), device);
    host.view->setScene(spec, session.live().X_WT_initial, ViewLook{});
  }
  ViewHost host;
  runtime::Session session;
  DrillController drill;
  SceneActorsSpec spec;  ///< What the view shows of the scene, as first shown.
  std::shared_ptr<const haptics::ToolModel> tool;  ///< The scene's tool, as loaded.
  runtime::ToolSpec tool_spec;
};

TEST(DrillingView, BoxUploadShowsWhatAWholeUploadShows) {
  const runtime::LoadedScene scene = drillScene();
  const SceneActorsSpec spec = sceneActorsSpecFor(scene, runtime::LiveValues::initial(scene));
  ViewHost a;
  a.view->setScene(spec, scene.X_WT_initial, ViewLook{});
  a.view->setDeviceVisible(false);
  a.view->setStandardView(StandardView::kSuperior);  // looking down at the pole
  a.view->renderStill(true);
  const QImage before = a.view->widget()->grabFrame();
  // A cavity: the voxels within 8 mm of the sphere's top pole (0, 0, 20 mm).
  const auto& g = scene.volume.field->geometry();
  std::vector<std::uint64_t> cavity;
  for (int k = 0; k < g.dims[2]; ++k)
    for (int j = 0; j < g.dims[1]; ++j)
      for (int i = 0; i < g.dims[0]; ++i) {
        const Eigen::Vector3d p = g.origin_W_m + g.spacing_m.cwiseProduct(Eigen::Vector3d(i, j, k));
        if ((p - Eigen::Vector3d(0, 0, 0.020)).norm() < 0.008)
          cavity.push_back(static_cast<std::uint64_t>(i + g.dims[0] * (j + g.dims[1] * k)));
      }
  ASSERT_GT(cavity.size(), 100u);
  double range[2];
  spec.image->GetScalarRange(range);
  EXPECT_EQ(a.view->actors().removedValue(), range[0]) << "a removed voxel shows the scan's lowest value";
  a.view->actors().removeVoxels(cavity, range[0]);  // first call: the copy, uploaded whole
  a.view->renderStill(true);
  const QImage first_bite = a.view->widget()->grabFrame();
  const std::uint64_t partial_before = a.view->actors().partialUploads();
  std::vector<std::uint64_t> more;  // then a second bite, uploaded as a box
  for (const std::uint64_t index : cavity) more.push_back(index + 6);
  a.view->actors().removeVoxels(more, range[0]);
  a.view->renderStill(true);  // both views at the best still quality
  const QImage drilled = a.view->widget()->grabFrame();
  EXPECT_EQ(a.view->actors().partialUploads(), partial_before + 1) << "the second bite went up as a box";
  EXPECT_EQ(a.view->actors().fullUploads(), 0u);
  EXPECT_GT(test::differingFraction(before, drilled), 0.002) << "the cavity shows";
  const double second_bite = test::differingFraction(first_bite, drilled);
  std::printf("pixels changed by the second bite (box upload): %.4f\n", second_bite);
  EXPECT_GT(second_bite, 0.001) << "the box upload reached the texture";

  // The oracle: a fresh view of the drilled image, uploaded whole by VTK.
  SceneActorsSpec whole = spec;
  whole.image = vtkSmartPointer<vtkImageData>::New();
  whole.image->DeepCopy(a.view->actors().shownImage());
  ViewHost b;
  b.view->setScene(whole, scene.X_WT_initial, ViewLook{});
  b.view->setDeviceVisible(false);
  b.view->setStandardView(StandardView::kSuperior);
  b.view->renderStill(true);
  const QImage reference = b.view->widget()->grabFrame();
  ASSERT_EQ(reference.size(), drilled.size());
  const double off = test::differingFraction(reference, drilled);
  std::printf("pixels differing from the whole upload: %.4f\n", off);
  EXPECT_LT(off, 0.001);
}

TEST(DrillingView, DrillMenuCutsShowsAndExports) {
  DrillingSession s;
  ViewHost& host = s.host;
  runtime::Session& session = s.session;
  DrillController& drill = s.drill;
  const SceneActorsSpec& spec = s.spec;
  EXPECT_THROW(drill.exportDrilled(outputDir() / "none.nrrd", outputDir() / "none.seg.nrrd"), std::runtime_error)
      << "nothing drilled yet";

  drill.setDrilling(true);
  ASSERT_TRUE(session.drilling());
  ASSERT_NE(session.hapticThread(), nullptr);
  ASSERT_NE(session.hapticThread()->drill(), nullptr) << "the first Drill builds the drill";
  session.startHaptics();
  // Press the burr 8 mm into the sphere's top, straight down.
  haptics::Pose X_WD = session.live().X_WT_initial;
  X_WD.p_AB_m = Eigen::Vector3d(0, 0, 0.020 + 0.0025 - 0.008);
  session.simulatedDevice()->setPose(X_WD);
  ASSERT_TRUE(test::waitFor(
      [&] {
        drill.drain();
        return drill.removed_mm3() > 20.0;
      },
      30000 * test::kSanitizerSlowdown))
      << "removed " << drill.removed_mm3() << " mm^3";
  drill.setDrilling(false);
  EXPECT_FALSE(session.drilling());
  session.stopHaptics();
  drill.drain();

  const fs::path nrrd = outputDir() / "drilled.nrrd", seg = outputDir() / "drilled.seg.nrrd";
  fs::remove(nrrd);
  // File > Export Drilled Volume's path: the status bar says when it is done, naming both files.
  QSignalSpy said(&drill, &DrillController::message);
  EXPECT_EQ(drill.exportDrilledWithNotice(outputDir() / "drilled"), nrrd) << "the .nrrd extension is added";
  ASSERT_GE(said.count(), 2) << "a message before the write and one after";
  EXPECT_TRUE(said.first().at(0).toString().startsWith("Exporting")) << said.first().at(0).toString().toStdString();
  const QString done = said.last().at(0).toString();
  EXPECT_TRUE(done.contains(QString::fromStdString(nrrd.string()))) << done.toStdString();
  EXPECT_TRUE(done.contains("drilled.seg.nrrd")) << done.toStdString();
  EXPECT_TRUE(done.contains("exported")) << done.toStdString();
  EXPECT_GT(said.last().at(1).toInt(), 0) << "the notice goes away by itself";
  ASSERT_TRUE(fs::exists(nrrd) && fs::exists(seg));
  vtkNew<vtkNrrdReader> reader;
  reader->SetFileName(nrrd.string().c_str());
  reader->Update();
  vtkImageData* read = reader->GetOutput();
  vtkImageData* shown = host.view->actors().shownImage();
  int dr[3], ds[3];
  read->GetDimensions(dr);
  shown->GetDimensions(ds);
  ASSERT_EQ(std::vector<int>(dr, dr + 3), std::vector<int>(ds, ds + 3));
  vtkDataArray* rs = read->GetPointData()->GetScalars();
  vtkDataArray* ss = shown->GetPointData()->GetScalars();
  ASSERT_EQ(rs->GetNumberOfTuples(), ss->GetNumberOfTuples());
  std::int64_t differing = 0, at_min = 0;
  double range[2];
  spec.image->GetScalarRange(range);
  for (vtkIdType i = 0; i < rs->GetNumberOfTuples(); ++i) {
    differing += rs->GetComponent(i, 0) != ss->GetComponent(i, 0);
    at_min += ss->GetComponent(i, 0) == range[0] && spec.image->GetPointData()->GetScalars()->GetComponent(i, 0) != range[0];
  }
  EXPECT_EQ(differing, 0);
  EXPECT_EQ(static_cast<std::uint64_t>(at_min), drill.removedVoxels()) << "the picture shows every removed voxel";
  const io::LoadedSegmentation removed = io::loadSegmentation(seg);
  ASSERT_EQ(removed.segments.size(), 1u);
  EXPECT_EQ(removed.segments[0].name, "drilled");
  EXPECT_EQ(removed.segments[0].voxel_count, drill.removedVoxels());
}

// The cavity outlives rebuilds of the haptic threads in the picture as in the hand: after a tool,
// a device and a segments change the picture still shows every voxel the solver's field lacks
// (the oracle: the scan's voxels at the image's minimum in the picture, against the voxels of the
// solver's field that differ from the scan), without a whole upload; drilling on adds to it.
TEST(DrillingView, TheCavityStaysInThePictureOverRebuilds) {
  DrillingSession s;
  ViewHost& host = s.host;
  runtime::Session& session = s.session;
  DrillController& drill = s.drill;
  const SceneActorsSpec& spec = s.spec;
  const auto tool = s.tool;
  const runtime::ToolSpec tool_spec = s.tool_spec;
  const haptics::Pose X_free = session.live().X_WT_initial;
  const auto pictureRemoved = [&] {
    return removedInPicture(host.view->actors().shownImage(), spec.image);
  };
  const auto solverRemoved = [&] {  // the renderer's own field against the scan
    return runtime::cavityOf(session.hapticThread()->drill()->removal().volume(), *session.live().scan_field).voxels.size();
  };
  const auto press = [&](double x_m, double mm3) {
    session.startHaptics();
    haptics::Pose X_WD = X_free;
    X_WD.p_AB_m = Eigen::Vector3d(x_m, 0, 0.020 + 0.0025 - 0.008);
    session.simulatedDevice()->setPose(X_WD);
    const double before = drill.removed_mm3();
    EXPECT_TRUE(test::waitFor(
        [&] {
          drill.drain();
          return drill.removed_mm3() > before + mm3;
        },
        30000 * test::kSanitizerSlowdown));
    session.stopHaptics();
    drill.drain();
  };
  drill.setDrilling(true);
  ASSERT_TRUE(session.drilling());
  press(0.0, 10.0);
  const std::uint64_t drilled = solverRemoved();
  ASSERT_GT(drilled, 10u);
  EXPECT_EQ(pictureRemoved(), drilled);
  const std::uint64_t whole_uploads = host.view->actors().fullUploads();

  const auto expectKept = [&](const char* after) {
    drill.drain();  // the controller's timer does it every 20 ms
    EXPECT_EQ(solverRemoved(), drilled) << "the hand keeps the cavity after " << after;
    EXPECT_EQ(pictureRemoved(), drilled) << "the picture keeps the cavity after " << after;
    EXPECT_EQ(drill.removedVoxels(), drilled) << after;
  };
  session.setTool(tool, tool_spec, X_free);
  expectKept("a tool change");
  session.setDevice(std::make_shared<runtime::SimulatedDevice>(X_free));
  expectKept("a device change");
  auto set = std::make_shared<const runtime::SegmentSet>(
      test::ballSegmentation(*session.live().scan_field, Eigen::Vector3d(0, 0, 0.015), 0.006), std::vector<int>{},
      std::vector<int>{0}, std::vector<int>{0}, 1.0);
  runtime::SegmentationSpec seg_spec;
  seg_spec.path = "in-memory";
  session.setSegments(set, seg_spec);
  expectKept("a segments change");
  EXPECT_EQ(host.view->actors().fullUploads(), whole_uploads) << "no whole upload for a cavity already shown";

  press(0.004, 5.0);  // drilling on after the rebuilds adds to the same cavity
  const std::uint64_t more = solverRemoved();
  std::printf("cavity: %llu voxels, %llu after drilling on past three rebuilds\n",
              static_cast<unsigned long long>(drilled), static_cast<unsigned long long>(more));
  EXPECT_GT(more, drilled);
  EXPECT_EQ(pictureRemoved(), more);
  EXPECT_EQ(drill.removedVoxels(), more);
}

// A critical segment cut in the last moments before the haptic threads are rebuilt (removals the
// picture's 20 ms drain had not reached) is still an alert after the rebuild, with every voxel.
TEST(DrillingView, CriticalRemovalJustBeforeARebuildIsStillTold) {
  DrillingSession s;
  runtime::Session& session = s.session;
  DrillController& drill = s.drill;
  const auto tool = s.tool;
  const runtime::ToolSpec tool_spec = s.tool_spec;
  auto set = std::make_shared<const runtime::SegmentSet>(  // a critical nodule under the pole
      test::ballSegmentation(*session.live().scan_field, Eigen::Vector3d(0, 0, 0.019), 0.004), std::vector<int>{},
      std::vector<int>{0}, std::vector<int>{0}, 1.0);
  runtime::SegmentationSpec seg_spec;
  seg_spec.path = "in-memory";
  session.setSegments(set, seg_spec);
  drill.setDrilling(true);
  ASSERT_NE(session.hapticThread()->drill(), nullptr);
  const runtime::Drill& first = *session.hapticThread()->drill();
  int nodule = -1;
  for (std::size_t m = 0; m < first.removal().materials().size(); ++m)
    if (first.removal().materials()[m].critical) nodule = static_cast<int>(m);
  ASSERT_GE(nodule, 0);
  drill.drain();  // the controller's timer met this drill (every 20 ms)
  session.startHaptics();
  haptics::Pose X_WD = session.live().X_WT_initial;
  X_WD.p_AB_m = Eigen::Vector3d(0, 0, 0.020 + 0.0025 - 0.006);
  session.simulatedDevice()->setPose(X_WD);
  // No events processed meanwhile: the drain timer never runs, as in the last 20 ms before a rebuild.
  const auto t0 = std::chrono::steady_clock::now();
  while (first.removal().removedVoxels(nodule) == 0 &&
         std::chrono::steady_clock::now() - t0 < std::chrono::seconds(30 * test::kSanitizerSlowdown))
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  session.stopHaptics();
  const std::uint64_t cut = first.removal().removedVoxels(nodule);
  ASSERT_GT(cut, 0u) << "the burr reached the nodule";
  QSignalSpy messages(&drill, &DrillController::message);
  session.setTool(tool, tool_spec, session.live().X_WT_initial);
  drill.drain();
  QString alert;
  for (const auto& m : messages)
    if (m.front().toString().startsWith("CRITICAL")) alert = m.front().toString();
  EXPECT_TRUE(alert.contains(QString("removed %1 voxels").arg(cut))) << alert.toStdString();
}

// The Segments panel's Hardness column: an edit to a number > 0 reaches the session as that
// segment's hardness (shown back in the cell); anything else is refused and reverted.
TEST(DrillingView, SegmentsPanelSetsTheHardness) {
  const runtime::LoadedScene& scene = test::sphereProbeScene();
  runtime::Session session;
  session.setScene(scene, scene.makeDevice());
  auto set = std::make_shared<const runtime::SegmentSet>(
      test::ballSegmentation(*scene.volume.field, Eigen::Vector3d(0, 0, 0.015), 0.006), std::vector<int>{},
      std::vector<int>{0}, std::vector<int>{0}, 1.0);
  runtime::SegmentationSpec spec;
  spec.path = "in-memory";
  session.setSegments(set, spec);
  SegmentsPanel panel;
  panel.showSegments(session.live().segments.get());
  QObject::connect(&panel, &SegmentsPanel::hardnessChanged, [&](int segment, double e) {
    session.setHardness(session.live().segments->name(segment), e);
    panel.showHardness(session.hardness());
  });
  QTableWidgetItem* cell = panel.table()->item(0, SegmentsPanel::kHardness);
  ASSERT_NE(cell, nullptr);
  EXPECT_TRUE(cell->flags() & Qt::ItemIsEditable);
  EXPECT_FALSE(panel.table()->item(0, SegmentsPanel::kName)->flags() & Qt::ItemIsEditable);
  cell->setText("1.5");
  EXPECT_DOUBLE_EQ(session.hardness().at("nodule"), 1.5);
  EXPECT_EQ(cell->text(), "1.5");
  cell->setText("soft");
  EXPECT_EQ(cell->text(), "1.5") << "refused and reverted";
  EXPECT_DOUBLE_EQ(session.hardness().at("nodule"), 1.5);
  cell->setText("-2");
  EXPECT_DOUBLE_EQ(session.hardness().at("nodule"), 1.5);
}

// A drilled session replayed in the window: the drilling is replayed on a thread of its own (the
// dock is up before it is done), then the cavity grows with the replay's time, all of it at the
// end (every voxel the run removed), none at the start (scrubbing back restores the scan).
// A headless run on the sphere with the drill on, the burr pressed into it for a second,
// recorded in `dir`: the recording and the voxels the live run removed (its own count).
struct DrilledRun {
  fs::path recording;
  std::uint64_t removed = 0;
};
DrilledRun recordDrilledRun(const fs::path& dir) {
  fs::create_directories(dir);
  const fs::path scene_path = dir / "drill.json";
  std::ofstream(scene_path) << R"({"volume": {"path": "builtin:sphere"}, "tool": {"mesh": "builtin:drill", "point_spacing_m": 0.001},
      "coupling": {"linear_N_per_m": 400}, "device": {"kind": "simulated"}, "drill": {"on": true}})";
  const runtime::LoadedScene scene = runtime::loadScene(runtime::loadSceneFile(scene_path));
  runtime::RunOptions options;
  options.record = dir / "drill.vhrec";
  options.lag_reference = false;
  options.verify_step_voxels = 0.0;
  const runtime::RunReport report = runtime::runHeadless(scene, vh::test::pressTrajectory(0.0, 0.0, 0.030, 0.5, 0.0125, 1.5), options);
  DrilledRun run;
  run.recording = options.record;
  if (report.drill.has_value())
    for (const auto& m : report.drill->materials) run.removed += m.voxels;
  return run;
}

// The Segments panel's "Burr sound" in the window: off at first; ticked on a machine without an
// audio output, the window says once that the sound is off and carries on.
TEST(DrillingView, BurrSoundWithoutAnAudioOutputIsSaidOnceAndTheWindowCarriesOn) {
  MainWindow window;
  window.setInteractive(false);
  window.resize(640, 480);
  window.show();
  QCheckBox* burr_sound = nullptr;
  for (QCheckBox* box : window.findChildren<QCheckBox*>())
    if (box->text() == "Burr sound") burr_sound = box;
  ASSERT_NE(burr_sound, nullptr);
  EXPECT_FALSE(burr_sound->isChecked());
  if (!QMediaDevices::audioOutputs().isEmpty()) GTEST_SKIP() << "this machine has an audio output";
  burr_sound->setChecked(true);
  const QString said = window.statusBar()->currentMessage();
  EXPECT_TRUE(said.startsWith("Sound off: no audio output")) << said.toStdString();
  window.statusBar()->clearMessage();
  burr_sound->setChecked(false);
  burr_sound->setChecked(true);
  EXPECT_EQ(window.statusBar()->currentMessage(), "") << "said once";
  QApplication::processEvents();
  EXPECT_TRUE(window.isVisible());
}

TEST(DrillingView, ReplayShowsTheCavityAtItsTime) {
  const DrilledRun run = recordDrilledRun(outputDir() / "replay");
  const std::uint64_t removed = run.removed;
  ASSERT_GT(removed, 10u);

  MainWindow window;
  window.setInteractive(false);
  window.resize(640, 480);
  window.show();
  QSignalSpy started(window.replay(), &ReplayController::replayStarted);
  QSignalSpy replayed(window.replay(), &ReplayController::drillingReplayed);
  bool pending_when_shown = false;  // the drilling replays off the GUI thread: the dock shows first
  QObject::connect(window.replay(), &ReplayController::replayStarted,
                   [&] { pending_when_shown = window.replay()->drillingPending(); });
  ASSERT_TRUE(window.replay()->openRecording(run.recording));
  ASSERT_TRUE(test::waitFor([&] { return started.count() > 0 && !window.opener()->loading(); }, 60000));
  EXPECT_TRUE(pending_when_shown) << "the replay dock came up before the drilling was replayed";
  ASSERT_TRUE(test::waitFor([&] { return replayed.count() > 0; }, 60000));
  EXPECT_TRUE(replayed.front().front().toBool());
  EXPECT_FALSE(window.replay()->drillingPending());
  const auto removedShown = [&] {
    return removedInPicture(window.sceneView()->actors().shownImage(), window.session().loaded().volume.image.get());
  };
  const double end = window.replay()->recording().records.back().time_s;
  window.replay()->setTime(end);
  EXPECT_EQ(removedShown(), removed) << "every voxel the run removed, removed in the picture";
  // The shadow's field follows (the built-in sphere's felt grid is the picture's).
  EXPECT_EQ(window.replay()->carved().removedCount(), removed) << "the shadow falls into the whole cavity";
  window.replay()->setTime(0.0);
  EXPECT_EQ(removedShown(), 0u) << "scrubbed back to the start: the undrilled scan";
  EXPECT_EQ(window.replay()->carved().removedCount(), 0u);
  window.replay()->setTime(0.5 * end);
  const std::uint64_t middle = removedShown();
  EXPECT_GT(middle, 0u);
  EXPECT_LT(middle, removed);
  EXPECT_EQ(window.replay()->carved().removedCount(), middle);
}

// Exported frames show the cavity as it was at their time, as `volume-haptics export` renders
// them (the scene reloaded from the recording's metadata, no window): at the end every voxel the
// live run removed is removed in the picture (the oracle: the run's own count, not the replay),
// at the start none, half way some; and the command itself writes the PNG.
TEST(DrillingView, ExportedFramesShowTheCavityAtTheirTime) {
  const fs::path dir = outputDir() / "export";
  const DrilledRun run = recordDrilledRun(dir);
  ASSERT_GT(run.removed, 10u);
  const runtime::Recording recording = runtime::readRecording(run.recording);
  runtime::SceneSpec spec = runtime::sceneFromSessionMetadata(recording.metadata_json);
  spec.device.reset();
  const runtime::LoadedScene scene = runtime::loadScene(spec);
  RecordingFrameRenderer frames(sceneActorsSpecFor(scene, runtime::LiveValues::initial(scene)), 320, 240);
  frames.setDrilling(drillingTimeline(scene, recording));
  frames.setShadow(scene.hapticField(), scene.hapticIsovalue(), toolShadowSamples(*scene.tool));
  const auto removedAt = [&](double t_s) {
    writeRecordingPng(frames, recording, t_s, dir / "frame.png");
    return removedInPicture(frames.actors().shownImage(), scene.volume.image.get());
  };
  const double end = recording.records.back().time_s;
  EXPECT_EQ(removedAt(end), run.removed) << "every voxel the run removed, removed in the exported frame";
  // The shadow falls on the field the replay carved (the runtime's replay: the oracle), as far
  // as the frame's time: the built-in sphere's felt grid is the picture's.
  const runtime::ReplayComparison replayed = runtime::replayRecording(scene, recording);
  ASSERT_NE(replayed.drilled_field, nullptr);
  const std::uint64_t felt_removed = runtime::cavityOf(*replayed.drilled_field, *scene.hapticField()).voxels.size();
  EXPECT_EQ(frames.shadowCarved().removedCount(), felt_removed);
  ASSERT_NE(frames.shadowCarved().box(), nullptr);
  for (const std::uint64_t index : replayed.removed_voxels) {
    const auto& g = scene.hapticField()->geometry();
    const int i = static_cast<int>(index % static_cast<std::uint64_t>(g.dims[0]));
    const int j = static_cast<int>((index / static_cast<std::uint64_t>(g.dims[0])) % static_cast<std::uint64_t>(g.dims[1]));
    const int k = static_cast<int>(index / (static_cast<std::uint64_t>(g.dims[0]) * static_cast<std::uint64_t>(g.dims[1])));
    const Eigen::Vector3d p = g.origin_W_m + g.direction_W * g.spacing_m.cwiseProduct(Eigen::Vector3d(i, j, k));
    ASSERT_NEAR(frames.shadowCarved().box()->sample(p), replayed.drilled_field->sample(p), 1e-9)
        << "removed voxel " << index;  // the box's grid coordinates round differently
  }
  EXPECT_EQ(removedAt(0.0), 0u) << "the first frame: the undrilled scan";
  EXPECT_EQ(frames.shadowCarved().removedCount(), 0u) << "and the shadow on it";
  const std::uint64_t middle = removedAt(0.5 * end);
  EXPECT_GT(middle, 0u);
  EXPECT_LT(middle, run.removed);
  EXPECT_EQ(frames.cavityVoxelsShown(), middle);
  EXPECT_EQ(frames.shadowCarved().removedCount(), middle);

  MediaExportOptions options;
  options.png = dir / "end.png";
  options.png_time_s = end;
  options.width = 160;
  options.height = 120;
  EXPECT_EQ(exportRecordingMedia(0, nullptr, run.recording, options), 0);
  EXPECT_GT(fs::file_size(options.png), 0u);
}

// A recording that started on a drilled sphere (its metadata carries the cavity) replays from it:
// the picture shows the cavity at the start, the cavity plus what the run removed at the end
// (the oracle: the replayed field's cavity, from the runtime), and Close Replay leaves the
// cavity the live drill starts from, in the hand and in the picture.
TEST(DrillingView, ReplayStartsFromTheRecordedCavity) {
  const fs::path dir = outputDir() / "replay-cavity";
  fs::create_directories(dir);
  const fs::path scene_path = dir / "drill.json";
  std::ofstream(scene_path) << R"({"volume": {"path": "builtin:sphere"}, "tool": {"mesh": "builtin:drill", "point_spacing_m": 0.001},
      "coupling": {"linear_N_per_m": 400}, "device": {"kind": "simulated"}, "drill": {"on": true}})";
  runtime::LoadedScene scene = runtime::loadScene(runtime::loadSceneFile(scene_path));
  const auto at = [](double t, double x, double z) {
    runtime::TrajectorySample s;
    s.t_s = t;
    s.X_WD.p_AB_m = {x, 0.0, z};
    return s;
  };
  runtime::RunOptions options;
  options.record = dir / "first.vhrec";
  options.lag_reference = false;
  options.verify_step_voxels = 0.0;
  const runtime::Trajectory first_press({at(0.0, 0.0, 0.030), at(0.5, 0.0, 0.0125), at(1.5, 0.0, 0.0125)});
  (void)runtime::runHeadless(scene, first_press, options);
  const runtime::Recording first = runtime::readRecording(options.record);
  const runtime::ReplayComparison carved =
      runtime::replayRecording(runtime::loadScene(runtime::sceneFromSessionMetadata(first.metadata_json)), first);
  auto cavity = std::make_shared<const runtime::DrilledCavity>(runtime::cavityOf(*carved.drilled_field, *scene.hapticField()));
  ASSERT_GT(cavity->voxels.size(), 10u);
  scene.spec.drill->cavity = cavity;
  options.record = dir / "second.vhrec";
  (void)runtime::runHeadless(scene, runtime::Trajectory({at(0.0, 0.004, 0.030), at(0.5, 0.004, 0.0125), at(1.5, 0.004, 0.0125)}),
                             options);
  const runtime::Recording second = runtime::readRecording(options.record);
  const runtime::ReplayComparison both_replayed =
      runtime::replayRecording(runtime::loadScene(runtime::sceneFromSessionMetadata(second.metadata_json)), second);
  const std::uint64_t both = runtime::cavityOf(*both_replayed.drilled_field, *scene.hapticField()).voxels.size();
  ASSERT_GT(both, cavity->voxels.size());

  MainWindow window;
  window.setInteractive(false);
  window.resize(640, 480);
  window.show();
  QSignalSpy started(window.replay(), &ReplayController::replayStarted);
  QSignalSpy replayed(window.replay(), &ReplayController::drillingReplayed);
  ASSERT_TRUE(window.replay()->openRecording(options.record));
  ASSERT_TRUE(test::waitFor([&] { return started.count() > 0 && replayed.count() > 0 && !window.opener()->loading(); }, 60000));
  const auto removedShown = [&] {
    return removedInPicture(window.sceneView()->actors().shownImage(), window.session().loaded().volume.image.get());
  };
  window.replay()->setTime(0.0);
  EXPECT_EQ(removedShown(), cavity->voxels.size()) << "the cavity the recording started from";
  window.replay()->setTime(window.replay()->recording().records.back().time_s);
  EXPECT_EQ(removedShown(), both) << "and what the run removed after it";
  window.replay()->closeReplay();
  test::pump(100);
  window.session().stopHaptics();
  window.drillController()->drain();  // what its 20 ms timer does, once the threads are still
  ASSERT_NE(window.session().hapticThread(), nullptr);
  const auto& live = window.session().hapticThread()->drill();
  ASSERT_NE(live, nullptr);
  const std::uint64_t felt =
      runtime::cavityOf(live->removal().volume(), *window.session().live().scan_field).voxels.size();
  EXPECT_EQ(felt, cavity->voxels.size()) << "live again: the drill starts from the recording's cavity";
  EXPECT_EQ(removedShown(), felt) << "and the picture shows what the hand feels";
}

// The surgeon's case on the Philips head phantom (512 x 512 x 140, 400 HU): the built-in drill
// pressed into the skull from above with the burr spinning cuts a cavity that the ray-cast view
// shows while it grows. Prints the frames per second the view kept while drilling (no threshold:
// speed targets live in the benchmarks); writes drilled-cavity.png when VH_UI_SHOTS_DIR is set.
TEST(DrillingView, CavityInTheHeadPhantomGrowsInTheView) {
  if (!fs::exists(test::kHeadPhantom)) GTEST_SKIP() << test::kHeadPhantom.string() << " is absent";
  MainWindow window;
  ASSERT_TRUE(test::openPhantomWithDrill(window));
  runtime::Session& session = window.session();
  window.drillController()->setDrilling(true);
  ASSERT_TRUE(session.drilling());
  session.startHaptics();
  ASSERT_TRUE(session.hapticsRunning());
  // Straight down from the free pose to 6 mm past where the burr meets the skull.
  const haptics::Pose start = session.proxyPose();
  const runtime::Burr burr = session.hapticThread()->drill()->burr();
  const Eigen::Vector3d bottom = start * burr.center_T_m - Eigen::Vector3d(0, 0, burr.radius_m);
  double contact_m = 0.0;
  while (contact_m < 0.15 && !session.live().scan_field->isInside(bottom - Eigen::Vector3d(0, 0, contact_m), 400.0))
    contact_m += 1e-4;
  ASSERT_LT(contact_m, 0.15) << "no skull below the drill";
  haptics::Pose press = start;
  press.p_AB_m.z() -= contact_m + 0.006;
  window.sceneView()->focusOn(*session.live().tool, press);
  session.simulatedDevice()->setPose(press);
  const std::uint64_t frames_before = window.sceneView()->widget()->frameCount();
  const auto t0 = std::chrono::steady_clock::now();
  test::pump(1500);
  // Widen the cavity: a circle of 4 mm radius at that depth, as a surgeon saucerises the bone.
  for (int step = 1; step <= 24; ++step) {
    const double phase = step * 2.0 * 3.14159265358979 / 24.0;
    haptics::Pose around = press;
    around.p_AB_m += Eigen::Vector3d(0.004 * std::cos(phase) - 0.004, 0.004 * std::sin(phase), 0.0);
    session.simulatedDevice()->setPose(around);
    test::pump(100);
  }
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const double fps = static_cast<double>(window.sceneView()->widget()->frameCount() - frames_before) / seconds;
  // How much the burr cut in those seconds depends on how many ticks the machine ran: the burr
  // stays pressed in at the circle's end until it has cut into the skull and the view has shown
  // the cut.
  EXPECT_TRUE(test::waitFor(
      [&] {
        window.drillController()->drain();
        return window.drillController()->removed_mm3() > 1.0 && window.sceneView()->actors().partialUploads() > 0;
      },
      60000));
  const double removed = window.drillController()->removed_mm3();
  std::printf("head phantom: drilled %.1f mm^3 in %.1f s; the view kept %.1f frames per second meanwhile "
              "(%llu box uploads, %llu whole)\n",
              removed, seconds, fps, static_cast<unsigned long long>(window.sceneView()->actors().partialUploads()),
              static_cast<unsigned long long>(window.sceneView()->actors().fullUploads()));
  EXPECT_GT(removed, 1.0) << "the burr cut into the skull";
  EXPECT_GT(window.sceneView()->actors().partialUploads(), 0u);
  // Record pressed while drilling: the haptic threads restart where the proxy is, with the
  // cavity (what the hand meets as a pause; printed, no threshold).
  const fs::path record_dir = outputDir() / "phantom-record";
  fs::create_directories(record_dir);
  const auto r0 = std::chrono::steady_clock::now();
  ASSERT_TRUE(window.recorder()->start(record_dir / "mid-drilling.vhrec")) << window.recorder()->lastError().toStdString();
  const double restart_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - r0).count();
  EXPECT_TRUE(session.hapticsRunning());
  test::pump(300);
  // On in the recording, out from the cavity's centre by 0.5 mm and down by 0.25 mm at a time
  // (every 300 recorded ticks) into the bone around it until the burr has cut again, then 500
  // ticks more: the burr cuts while it records, however far the cavity already reached and
  // however many ticks a loaded machine gives it.
  const auto recordTicks = [&](std::uint64_t n) {
    const std::uint64_t from = window.recorder()->recordsWritten();
    return test::waitFor([&] { return window.recorder()->recordsWritten() >= from + n; }, 60000);
  };
  window.drillController()->drain();
  const double removed_before_mm3 = window.drillController()->removed_mm3();
  haptics::Pose deeper = press;
  bool cut_again = false;
  deeper.p_AB_m.x() -= 0.004;  // the circle's centre
  for (int step = 1; step <= 20 && !cut_again; ++step) {
    deeper.p_AB_m += Eigen::Vector3d(0.0005, 0.0, -0.00025);
    session.simulatedDevice()->setPose(deeper);
    ASSERT_TRUE(recordTicks(300));
    window.drillController()->drain();
    cut_again = window.drillController()->removed_mm3() > removed_before_mm3;
  }
  ASSERT_TRUE(cut_again) << "the burr pressed 10 mm out and 5 mm down cut nothing";
  ASSERT_TRUE(recordTicks(500));
  window.recorder()->stop();
  const runtime::Session::RestartTiming& restart = session.lastRestart();
  std::printf("head phantom: Record pressed while drilling started in %.0f ms (the checksum, the haptic threads' "
              "restart): %.0f ms preparing the new drill with the force on (the burr held from cutting for the "
              "first %.0f ms, then %zu voxels cut), %.0f ms from the old threads' stop to the new threads built\n",
              restart_ms, restart.while_feeling_ms, restart.cutting_held_ms, restart.voxels_cut_while_preparing,
              restart.without_force_ms);
  EXPECT_TRUE(restart.prepared_while_feeling) << "the new drill was built before the force let go";
  // What the window recorded: the cavity it began on, what the burr removed during it and the
  // two together, by the one rule every recording follows (the records and the metadata), equal
  // to what its replay carved (the oracle: the replayed field against the scan); and the replay
  // matches the recording tick for tick, the ticks the clock cut on this busy machine included.
  {
    const runtime::Recording rec = runtime::readRecording(record_dir / "mid-drilling.vhrec");
    const runtime::SessionMetrics m = runtime::computeSessionMetrics(rec);
    const runtime::LoadedScene replayed_scene = runtime::loadScene(runtime::sceneFromSessionMetadata(rec.metadata_json));
    const runtime::ReplayComparison replay = runtime::replayRecording(replayed_scene, rec);
    EXPECT_TRUE(replay.identical) << replay.mismatch << " at tick " << replay.first_mismatch_tick.value_or(0);
    ASSERT_NE(replay.drilled_field, nullptr);
    const std::uint64_t cavity_end = runtime::cavityOf(*replay.drilled_field, *replayed_scene.hapticField()).voxels.size();
    EXPECT_GT(m.cavity_at_start_voxels, 0u) << "recorded on a drilled skull";
    EXPECT_GT(m.removed_voxels, 0u) << "the burr cut while recording";
    EXPECT_EQ(m.removed_voxels, replay.removed_voxels.size());
    EXPECT_EQ(m.cavity_voxels, cavity_end);
    EXPECT_GT(m.removed_mm3, 0.0);
    EXPECT_NEAR(m.cavity_mm3, m.cavity_at_start_mm3 + m.removed_mm3, 1e-9 * m.cavity_mm3);
    std::uint64_t cut_ticks = 0;
    for (const runtime::TickRecord& r : rec.records) cut_ticks += (r.flags & runtime::kRecordFlagDeadlineCut) != 0;
    std::printf("head phantom: recorded in the window %zu ticks (%llu cut by the deadline), cavity %llu voxels at the "
                "start, %llu removed (%.2f mm^3), %llu at the end; the replay %s\n",
                rec.records.size(), static_cast<unsigned long long>(cut_ticks),
                static_cast<unsigned long long>(m.cavity_at_start_voxels), static_cast<unsigned long long>(m.removed_voxels),
                m.removed_mm3, static_cast<unsigned long long>(cavity_end), replay.identical ? "is identical" : "differs");
  }
  // Lift the drill out and look down into the cavity.
  haptics::Pose lifted = start;
  lifted.p_AB_m += Eigen::Vector3d(0.05, 0.0, 0.03);  // up and aside, out of the line of sight
  session.simulatedDevice()->setPose(lifted);
  test::pump(800);
  window.sceneView()->setStandardView(StandardView::kSuperior);
  window.sceneView()->focusOn(*session.live().tool, press);
  test::pump(300);
  if (const char* dir = std::getenv("VH_UI_SHOTS_DIR")) {
    window.sceneView()->renderStill(true);
    window.grab().save(QString::fromLocal8Bit(dir) + "/drilled-cavity.png");
  }
  session.stopHaptics();
}

}  // namespace
}  // namespace vh::ui
