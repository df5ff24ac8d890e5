// Session recordings in the GUI: recording from the window (records, events and
// metadata read back), replay (the recorded scene reloads, scrubbing the timeline puts the proxy
// actor at the recorded pose, one |F| sample per record), video and PNG export (GUI and command
// line), a recording whose dataset is missing (error naming it, the scene shown stays), and a
// full disk while recording (the status bar says so at once; the file keeps its ticks).
// Scenes: the built-in 64^3 sphere (no shared data needed), small windows (llvmpipe).
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include <csignal>

#include <sys/resource.h>
#include <sys/stat.h>

#include <QApplication>
#include <QLabel>
#include <QImage>
#include <QListWidget>
#include <QSignalSpy>
#include <QSlider>
#include <QTemporaryDir>
#include <QTest>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <vtkActor.h>
#include <vtkImageData.h>
#include <vtkMatrix4x4.h>
#include <vtkRenderer.h>

#include "file_size_limit.h"
#include "ui_test_util.h"
#include "vh/runtime/device.h"
#include "vh/runtime/recording.h"
#include "vh/runtime/replay.h"
#include "vh/runtime/session_metadata.h"
#include "vh/runtime/scene.h"
#include "vh/ui/main_window.h"
#include "vh/ui/devices/device_input.h"
#include "vh/ui/panels/histogram_slider.h"
#include "vh/ui/panels/isovalue_bar.h"
#include "vh/ui/tool_picker.h"
#include "vh/ui/export/media_export.h"
#include "vh/ui/replay/recorded_camera.h"
#include "vh/ui/replay/replay_controller.h"
#include "vh/ui/view/scene_view.h"
#include "vh/ui/replay/session_recorder.h"
#include "vh/ui/view/vtk_view.h"

namespace vh::ui {
namespace {

namespace fs = std::filesystem;
using test::waitFor;

runtime::SceneSpec sphereScene() {
  runtime::SceneSpec spec;
  spec.volume.path = "builtin:sphere";
  spec.tool.mesh = "builtin:probe";
  spec.device = runtime::DeviceSpec{};  // simulated
  return spec;
}

std::unique_ptr<MainWindow> smallWindow() {
  auto w = std::make_unique<MainWindow>();
  w->setInteractive(false);
  w->resize(520, 420);
  w->show();
  return w;
}

bool loadInto(MainWindow& w, const runtime::SceneSpec& spec) {
  QSignalSpy loaded(&w, &MainWindow::sceneLoaded);
  w.opener()->openScene(spec);
  return waitFor([&] { return loaded.count() > 0 && !w.opener()->loading(); }, 60000);
}

Eigen::Vector3d translationOf(vtkActor* actor) {
  vtkMatrix4x4* m = actor->GetUserMatrix();
  return Eigen::Vector3d(m->GetElement(0, 3), m->GetElement(1, 3), m->GetElement(2, 3));
}

Eigen::Quaterniond rotationOf(vtkActor* actor) {
  vtkMatrix4x4* m = actor->GetUserMatrix();
  Eigen::Matrix3d R;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) R(r, c) = m->GetElement(r, c);
  }
  return Eigen::Quaterniond(R);
}

std::string firstBytes(const fs::path& path, std::size_t n) {
  std::ifstream in(path, std::ios::binary);
  std::string s(n, '\0');
  in.read(s.data(), static_cast<std::streamsize>(n));
  s.resize(static_cast<std::size_t>(in.gcount()));
  return s;
}

/// One recording for the whole suite: the device pushed into the sphere (the proxy moves and a
/// force shows), a marker, an isovalue change from the slider.
class RecordedSession : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new QTemporaryDir();
    path_ = fs::path(dir_->path().toStdString()) / "session.vhrec";
    auto w = smallWindow();
    if (!loadInto(*w, sphereScene())) {
      setup_error_ = "the built-in sphere scene did not load: " + w->opener()->lastError().toStdString();
      return;
    }
    if (!w->session().hapticsRunning()) {
      setup_error_ = "the haptic thread did not start";
      return;
    }
    if (!w->recorder()->start(path_)) {
      setup_error_ = "recording did not start: " + w->recorder()->lastError().toStdString();
      return;
    }
    test::pump(250);
    if (!w->deviceInput()->touchSurface(0.004)) {
      setup_error_ = "touchSurface found no surface";
      return;
    }
    // The push reaches the solver and a force shows (ticks recorded meanwhile), however slow the
    // machine.
    runtime::HapticSnapshot latest;
    if (!waitFor([&] {
          return !w->deviceInput()->touchInProgress() && w->session().latestSnapshot(latest) &&
                 latest.force_W_N.norm() > 0.01;
        }, 30000)) {
      setup_error_ = "the tool never pressed on the sphere";
      return;
    }
    test::pump(500);
    marker_ok_ = w->recorder()->addMarker("nerve");
    // Haptics > Add Marker's key: "Marker 2" (not interactive, so no label dialog). Shortcuts
    // need the active window (Xvfb without a window manager: activate it by hand).
    w->activateWindow();
    key_window_active_ = QTest::qWaitForWindowActive(w.get(), 30000);
    QTest::keyClick(w->sceneView()->widget(), Qt::Key_M);
    rec_status_ = w->recorder()->statusText().toStdString();
    if (const char* shots = std::getenv("VH_UI_SHOTS_DIR"); shots != nullptr && *shots != '\0') {
      w->resize(1100, 760);
      test::pump(400);
      w->grab().toImage().save(QString::fromStdString((fs::path(shots) / "recording.png").string()), "PNG");
    }
    iso_before_ = w->session().isovalue();
    w->isovalueBar()->slider()->setValue(w->isovalueBar()->slider()->value() + 40);  // as a user's slider move
    iso_after_ = w->session().isovalue();
    haptics::CouplingGains gains = w->session().gains();
    gains.linear_N_per_m *= 0.8;
    w->session().setGains(gains);  // as from the haptics panel
    test::pump(500);
    // The new isovalue reached the solver (a recorded tick carries it) and more than 100 ticks were
    // recorded (the suite's tests read them back), however slow the machine.
    if (!waitFor([&] {
          return w->session().latestSnapshot(latest) && latest.isovalue == iso_after_ &&
                 w->recorder()->recordsWritten() > 150;
        }, 30000)) {
      setup_error_ = "the new isovalue never reached the solver, or fewer than 150 ticks were recorded";
      return;
    }
    // A tool swap records a "tool" event, then ends the recording (the haptic thread is rebuilt).
    const int other_tool = w->toolPicker()->currentIndex() == 0 ? 1 : 0;
    tool_label_ = w->toolPicker()->choices()[static_cast<std::size_t>(other_tool)].label;
    QSignalSpy tool_changed(w->toolPicker(), &ToolPicker::toolChanged);
    w->toolPicker()->select(other_tool);
    if (!waitFor([&] { return tool_changed.count() > 0; }, 60000)) {
      setup_error_ = "the tool swap did not finish";
      return;
    }
    recording_after_stop_ = w->recorder()->recording();
    w->session().stopHaptics();
  }
  static void TearDownTestSuite() {
    delete dir_;
    dir_ = nullptr;
  }
  void SetUp() override {
    if (!setup_error_.empty()) GTEST_FAIL() << setup_error_;
  }

  static inline QTemporaryDir* dir_ = nullptr;
  static inline fs::path path_;
  static inline std::string setup_error_;
  static inline bool marker_ok_ = false;
  static inline std::string rec_status_;
  static inline std::string tool_label_;
  static inline bool key_window_active_ = false;
  static inline bool recording_after_stop_ = true;
  static inline double iso_before_ = 0.0;
  static inline double iso_after_ = 0.0;
};

TEST_F(RecordedSession, WindowRecordingReadsBackWithEventsAndMetadata) {
  EXPECT_TRUE(marker_ok_);
  EXPECT_NE(rec_status_.find("REC"), std::string::npos) << rec_status_;
  EXPECT_FALSE(recording_after_stop_) << "a tool swap ends the recording";
  ASSERT_NE(iso_before_, iso_after_);
  const runtime::Recording rec = runtime::readRecording(path_);
  EXPECT_TRUE(rec.warnings.empty()) << rec.warnings.front();
  ASSERT_GT(rec.records.size(), 100u);
  for (std::size_t i = 1; i < rec.records.size(); ++i) {
    ASSERT_GE(rec.records[i].time_s, rec.records[i - 1].time_s);
  }
  bool marker = false, key_marker = false, isovalue = false, gains = false, tool = false;
  for (const runtime::RecordingEvent& e : rec.events) {
    const nlohmann::json detail = nlohmann::json::parse(e.detail_json);
    if (e.type == "marker" && detail.value("label", "") == "nerve") marker = true;
    if (e.type == "marker" && detail.value("label", "") == "Marker 2") key_marker = true;
    if (e.type == "isovalue") isovalue = true;
    if (e.type == "gains") gains = true;
    if (e.type == "tool" && detail.value("tool", "") == tool_label_) tool = true;
  }
  EXPECT_TRUE(marker) << "no marker event 'nerve' in " << rec.events.size() << " events";
  EXPECT_TRUE(key_marker) << "the M key added no marker (window active: " << key_window_active_ << ")";
  EXPECT_TRUE(isovalue) << "no isovalue event after the slider moved";
  EXPECT_TRUE(gains) << "no gains event after the gains changed";
  EXPECT_TRUE(tool) << "no tool event for " << tool_label_;
  // Records carry the new isovalue at the end.
  EXPECT_DOUBLE_EQ(rec.records.back().isovalue, iso_after_);
  const nlohmann::json meta = nlohmann::json::parse(rec.metadata_json);
  EXPECT_EQ(meta["scene"]["volume"]["path"], "builtin:sphere");
  EXPECT_TRUE(meta.contains("device"));
  // The device went into the sphere: some tick has contacts and a force.
  double max_force = 0.0;
  for (const runtime::TickRecord& r : rec.records) max_force = std::max(max_force, forceNormOf(r));
  EXPECT_GT(max_force, 0.01);
  // Started while the haptic threads ran (the scene had been felt for a while), the recording
  // still replays bit for bit: the recorder starts it on fresh threads from its initial pose.
  const runtime::ReplayComparison replay =
      runtime::replayRecording(runtime::loadScene(runtime::sceneFromSessionMetadata(rec.metadata_json)), rec);
  // The window's solver has the application's deadline on the clock; on a machine too busy to give
  // it its period it cuts a tick short, and the record says at which work: the replay (no clock)
  // stops there too, so it matches whatever the machine's load.
  EXPECT_TRUE(replay.identical) << runtime::replayDifference(replay, rec);
  EXPECT_TRUE(replay.identical) << replay.mismatch << " at tick " << replay.first_mismatch_tick.value_or(0) << " of "
                                << rec.records.size();
  EXPECT_GT(replay.forces_compared, 100u);
}

TEST_F(RecordedSession, ReplayLoadsTheSceneAndScrubbingMovesTheProxy) {
  const runtime::Recording rec = runtime::readRecording(path_);
  auto w = smallWindow();
  QSignalSpy started(w->replay(), &ReplayController::replayStarted);
  w->openPath(QString::fromStdString(path_.string()));  // as a dropped / command-line file
  ASSERT_TRUE(waitFor([&] { return started.count() > 0 && !w->opener()->loading(); }, 60000)) << w->opener()->lastError().toStdString();
  ASSERT_TRUE(w->replay()->active());
  EXPECT_FALSE(w->session().hapticsRunning());
  EXPECT_EQ(w->session().loaded().spec.volume.path, "builtin:sphere");
  // The |F| plot holds one sample per record; one marker in the list.
  EXPECT_EQ(w->replay()->timeline()->sampleCount(), rec.records.size());
  EXPECT_EQ(w->replay()->markerList()->count(), 2);

  ForceTimeline* timeline = w->replay()->timeline();
  timeline->resize(400, 100);
  // The record with the largest proxy displacement from the first one, then the first.
  std::size_t far = 0;
  double far_m = 0.0;
  for (std::size_t i = 0; i < rec.records.size(); ++i) {
    const double d = (proxyPoseOf(rec.records[i]).p_AB_m - proxyPoseOf(rec.records[0]).p_AB_m).norm();
    if (d > far_m) {
      far_m = d;
      far = i;
    }
  }
  ASSERT_GT(far_m, 1e-4) << "the proxy never moved in the recording";
  for (const double t : {rec.records[far].time_s, rec.records.front().time_s}) {
    const int x = static_cast<int>(std::lround(timeline->xAtTime(t)));
    QTest::mouseClick(timeline, Qt::LeftButton, {}, QPoint(x, timeline->height() / 2));
    const std::size_t i = w->replay()->currentIndex();
    EXPECT_EQ(i, recordIndexAt(rec.records, timeline->timeAtX(x)));
    const haptics::Pose X_WP = proxyPoseOf(rec.records[i]);
    EXPECT_LT((translationOf(w->sceneView()->actors().proxyActor()) - X_WP.p_AB_m).norm(), 1e-9);
    EXPECT_LT(rotationOf(w->sceneView()->actors().proxyActor()).angularDistance(X_WP.R_AB), 1e-6);
    EXPECT_LT((translationOf(w->sceneView()->actors().deviceActor()) - devicePoseOf(rec.records[i]).p_AB_m).norm(), 1e-9);
    EXPECT_DOUBLE_EQ(w->session().isovalue(), rec.records[i].isovalue);
  }
  // Jumping to the marker (the list holds the markers only, not placements or other events).
  const auto marker = std::find_if(rec.events.begin(), rec.events.end(), [](const auto& e) { return e.type == "marker"; });
  ASSERT_NE(marker, rec.events.end());
  w->replay()->markerList()->setCurrentRow(0);
  EXPECT_NEAR(w->replay()->time_s(), marker->time_s, 1e-9);

  // For a person to look at: VH_UI_SHOTS_DIR=DIR writes the window in replay at the deepest push.
  if (const char* shots = std::getenv("VH_UI_SHOTS_DIR"); shots != nullptr && *shots != '\0') {
    w->resize(1100, 760);
    test::pump(300);
    w->replay()->setTime(rec.records[far].time_s);
    w->sceneView()->renderStill(/*best_quality=*/true);
    test::pump(800);
    const QString out = QString::fromStdString((fs::path(shots) / "replay.png").string());
    EXPECT_TRUE(w->grab().toImage().save(out, "PNG")) << out.toStdString();
  }

  // A replay is watched for what it shows: however late its frames, none is coarser than
  // SceneView::kReplayImageSample_px between rays nor sampled at the nearest voxel (live, the
  // same lateness brings 8 px blocks).
  SceneActors& actors = w->sceneView()->actors();
  w->replay()->setTime(rec.records[far].time_s);
  ASSERT_TRUE(actors.interactive()) << "the tool moved: an interactive frame";
  for (int i = 0; i < 4; ++i) actors.adaptQuality(2000.0, 30.0);
  EXPECT_LE(actors.imageSampleDistance_px(), SceneView::kReplayImageSample_px);
  EXPECT_FALSE(actors.nearestSampling());
  EXPECT_FALSE(actors.surfaceMeshShown()) << "a replay shows the voxels as drilled, ray cast";

  // Close Replay: live haptics again on the same scene.
  w->replay()->closeReplay();
  EXPECT_FALSE(w->replay()->active());
  actors.setInteractive(true);
  for (int i = 0; i < 4; ++i) actors.adaptQuality(2000.0, 30.0);
  EXPECT_FALSE(!actors.surfaceMeshShown() && actors.imageSampleDistance_px() <= SceneView::kReplayImageSample_px)
      << "live frames keep to their time: rays further apart, or the surface mesh where the ray cast is too slow";
  EXPECT_TRUE(w->session().hapticsRunning());
  w->session().stopHaptics();
}

TEST_F(RecordedSession, VideoAndPngExport) {
  auto w = smallWindow();
  QSignalSpy started(w->replay(), &ReplayController::replayStarted);
  ASSERT_TRUE(w->replay()->openRecording(path_));
  ASSERT_TRUE(waitFor([&] { return started.count() > 0 && !w->opener()->loading(); }, 60000));
  const fs::path dir(dir_->path().toStdString());
  const double duration = w->replay()->timeline()->duration_s();
  const double fps = 4.0;
  int reported_total = 0;
  const int frames = w->replay()->exportVideo(dir / "gui.ogv", fps, 96, 64, [&](int, int total) {
    reported_total = total;
    return true;
  });
  EXPECT_EQ(frames, static_cast<int>(std::floor(duration * fps + 1e-9)) + 1);
  EXPECT_EQ(reported_total, frames);
  EXPECT_GT(fs::file_size(dir / "gui.ogv"), 100u);
  EXPECT_EQ(firstBytes(dir / "gui.ogv", 4), "OggS");

  w->replay()->exportPng(dir / "gui.png", 120, 90);
  const QImage png(QString::fromStdString((dir / "gui.png").string()));
  ASSERT_FALSE(png.isNull());
  EXPECT_EQ(png.size(), QSize(120, 90));
  EXPECT_EQ(firstBytes(dir / "gui.png", 8), std::string("\x89PNG\r\n\x1a\n", 8));
  int colours = 0;
  const QRgb first = png.pixel(0, 0);
  for (int y = 0; y < png.height() && colours == 0; ++y) {
    for (int x = 0; x < png.width(); ++x) {
      if (png.pixel(x, y) != first) {
        ++colours;
        break;
      }
    }
  }
  EXPECT_GT(colours, 0) << "the PNG is one colour";
  // Something besides the background gradient: the sphere or the tools.
  EXPECT_GT(test::brightFraction(png), 0.01);
  // The overlay is the export's choice: with it, the top left holds the time and forces on a
  // dark band; without it, that band is the plain picture; below it, both are the same picture.
  w->replay()->exportPng(dir / "with.png", 320, 240);
  w->replay()->exportPng(dir / "without.png", 320, 240, false);
  const QImage with(QString::fromStdString((dir / "with.png").string()));
  const QImage without(QString::fromStdString((dir / "without.png").string()));
  ASSERT_EQ(with.size(), without.size());
  const auto differing = [&](int y0, int y1) {
    int n = 0;
    for (int y = y0; y < y1; ++y)
      for (int x = 0; x < with.width(); ++x) n += with.pixel(x, y) != without.pixel(x, y);
    return static_cast<double>(n) / (with.width() * (y1 - y0));
  };
  EXPECT_GT(differing(0, 24), 0.05) << "no overlay drawn at the top";
  EXPECT_LT(differing(120, 240), 0.001) << "the pictures below the overlay differ";
  if (const char* shots = std::getenv("VH_UI_SHOTS_DIR"); shots != nullptr && *shots != '\0') {
    fs::copy_file(path_, fs::path(shots) / "session.vhrec", fs::copy_options::overwrite_existing);
    fs::copy_file(dir / "gui.png", fs::path(shots) / "replay-export.png", fs::copy_options::overwrite_existing);
    fs::copy_file(dir / "gui.ogv", fs::path(shots) / "replay-export.ogv", fs::copy_options::overwrite_existing);
  }
}

TEST_F(RecordedSession, CommandLineMediaExport) {
  const fs::path dir(dir_->path().toStdString());
  MediaExportOptions options;
  options.video = dir / "cli.ogv";
  options.png = dir / "cli.png";
  options.png_time_s = 0.5;
  options.fps = 3.0;
  options.width = 80;
  options.height = 60;
  ASSERT_EQ(exportRecordingMedia(0, nullptr, path_, options), 0);
  EXPECT_EQ(firstBytes(options.video, 4), "OggS");
  const QImage png(QString::fromStdString(options.png.string()));
  ASSERT_FALSE(png.isNull());
  EXPECT_EQ(png.size(), QSize(80, 60));
  if (const char* shots = std::getenv("VH_UI_SHOTS_DIR"); shots != nullptr && *shots != '\0') {
    MediaExportOptions look;  // the command line's default frame, at the deepest push
    look.png = fs::path(shots) / "export-cli.png";
    look.png_time_s = 3.0;
    EXPECT_EQ(exportRecordingMedia(0, nullptr, path_, look), 0);
  }
  // A recording that does not exist: 1 and no output.
  options.video = dir / "none.ogv";
  options.png.clear();
  EXPECT_EQ(exportRecordingMedia(0, nullptr, dir / "missing.vhrec", options), 1);
  EXPECT_FALSE(fs::exists(options.video));
}

TEST_F(RecordedSession, MissingDatasetNamesItAndKeepsTheScene) {
  // The same recording, but its metadata names a dataset that is not there.
  const runtime::Recording rec = runtime::readRecording(path_);
  nlohmann::json meta = nlohmann::json::parse(rec.metadata_json);
  const fs::path dir(dir_->path().toStdString());
  const std::string missing = (dir / "ct-gone" / "head.nrrd").string();
  meta["scene"]["volume"]["path"] = missing;
  if (meta.contains("dataset")) meta["dataset"]["path"] = missing;
  const fs::path bad = dir / "missing-dataset.vhrec";
  {
    runtime::RecordingWriter writer(bad, meta.dump());
    for (std::size_t i = 0; i < 10 && i < rec.records.size(); ++i) writer.push(rec.records[i]);
    writer.close();
  }
  auto w = smallWindow();
  ASSERT_TRUE(loadInto(*w, sphereScene()));
  w->session().stopHaptics();
  const void* image_before = w->session().loaded().volume.image.get();
  QSignalSpy failed(w.get(), &MainWindow::loadFailed);
  EXPECT_FALSE(w->replay()->openRecording(bad));
  EXPECT_EQ(failed.count(), 1);
  EXPECT_NE(w->opener()->lastError().indexOf(QString::fromStdString(missing)), -1) << w->opener()->lastError().toStdString();
  EXPECT_FALSE(w->replay()->active());
  EXPECT_FALSE(w->replay()->pending());
  EXPECT_EQ(w->session().loaded().volume.image.get(), image_before);
}

// Record pressed while the tool already rests on the surface (the hand in contact): the
// recording still replays bit for bit, and from where the proxy was when it started, not from
// the scene's free placement (where Reset Device still goes). The threads that had run are
// rebuilt for the recording; before that, the replay began at the free pose and differed at
// its first tick.
TEST(RecordingInContact, ARecordingStartedOnTheSurfaceReplaysBitForBit) {
  QTemporaryDir dir;
  const fs::path path = fs::path(dir.path().toStdString()) / "in-contact.vhrec";
  auto w = smallWindow();
  ASSERT_TRUE(loadInto(*w, sphereScene()));
  ASSERT_TRUE(w->session().hapticsRunning());
  ASSERT_TRUE(w->deviceInput()->touchSurface(0.004));
  ASSERT_TRUE(waitFor([&] { return !w->deviceInput()->touchInProgress(); }, 30000));
  test::pump(300);
  runtime::HapticSnapshot before;
  ASSERT_TRUE(waitFor([&] { return w->session().latestSnapshot(before) && before.contacts > 0; }, 30000))
      << "the tool never rested on the sphere";
  const haptics::Pose free_pose = w->session().live().X_WT_initial;
  const auto t0 = std::chrono::steady_clock::now();
  ASSERT_TRUE(w->recorder()->start(path)) << w->recorder()->lastError().toStdString();
  std::cout << "Record pressed in contact: started in "
            << std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count()
            << " ms (the checksum, the haptic threads' restart)\n";
  EXPECT_TRUE(w->session().hapticsRunning());
  test::pump(600);
  // More than 200 ticks recorded, however slow the machine.
  ASSERT_TRUE(waitFor([&] { return w->recorder()->recordsWritten() > 250; }, 30000));
  w->recorder()->stop();
  w->session().stopHaptics();
  EXPECT_EQ(w->session().live().X_WT_initial.p_AB_m, free_pose.p_AB_m) << "Reset Device still goes to the free pose";

  const runtime::Recording rec = runtime::readRecording(path);
  ASSERT_GT(rec.records.size(), 200u);
  EXPECT_GT(rec.records.front().contacts, 0u) << "in contact from the first tick";
  const runtime::LoadedScene scene = runtime::loadScene(runtime::sceneFromSessionMetadata(rec.metadata_json));
  EXPECT_LT((scene.X_WT_initial.p_AB_m - before.X_WP.p_AB_m).norm(), 0.002) << "starts where the proxy was";
  const runtime::ReplayComparison replay = runtime::replayRecording(scene, rec);
  // The window's solver has the application's deadline on the clock; a tick it cut on a busy
  // machine is replayed where it stopped (the record's deadline_work).
  EXPECT_TRUE(replay.identical) << runtime::replayDifference(replay, rec);
  EXPECT_TRUE(replay.identical) << replay.mismatch << " at tick " << replay.first_mismatch_tick.value_or(0) << " of "
                                << rec.records.size();
  EXPECT_GT(replay.forces_compared, 200u);
}

// A recording made in the window holds the view's camera (at its start and after each move),
// and its exported frames are seen from the camera the user had at their time: from the default
// view at the start, from above after View > Superior; before, every export used the default
// camera, the drill site hard to see.
TEST(RecordingCamera, ExportedFramesAreSeenFromTheCameraTheUserHad) {
  QTemporaryDir dir;
  const fs::path path = fs::path(dir.path().toStdString()) / "camera.vhrec";
  auto w = smallWindow();
  ASSERT_TRUE(loadInto(*w, sphereScene()));
  ASSERT_TRUE(w->recorder()->start(path)) << w->recorder()->lastError().toStdString();
  const ViewCamera at_start = w->sceneView()->camera();
  ASSERT_TRUE(waitFor([&] { return w->recorder()->recordsWritten() > 300; }, 30000));
  w->sceneView()->setStandardView(StandardView::kSuperior);
  const ViewCamera from_above = w->sceneView()->camera();
  ASSERT_LT(at_start.forward_W().dot(from_above.forward_W()), 0.9) << "the view turned";
  const std::uint64_t written = w->recorder()->recordsWritten();
  ASSERT_TRUE(waitFor([&] { return w->recorder()->recordsWritten() > written + 600; }, 30000));
  w->recorder()->stop();
  w->session().stopHaptics();

  const runtime::Recording rec = runtime::readRecording(path);
  const std::vector<RecordedCamera> cameras = recordedCameras(rec);
  ASSERT_GE(cameras.size(), 2u);
  EXPECT_TRUE(sameView(cameras.front().camera, at_start)) << "the camera as the recording started";
  EXPECT_TRUE(sameView(cameras.back().camera, from_above)) << "and after the move";
  EXPECT_LT(cameras.back().time_s, rec.records.back().time_s);

  runtime::SceneSpec spec = runtime::sceneFromSessionMetadata(rec.metadata_json);
  spec.device.reset();
  const runtime::LoadedScene scene = runtime::loadScene(spec);
  MediaExportOptions options;
  options.width = 160;
  options.height = 120;
  const std::unique_ptr<RecordingFrameRenderer> frames = exportFrameRenderer(scene, rec, options, nullptr);
  frames->show(rec.records.front());
  EXPECT_GT(frames->camera().forward_W().dot(at_start.forward_W()), 1.0 - 1e-9);
  frames->show(rec.records.back());
  EXPECT_GT(frames->camera().forward_W().dot(from_above.forward_W()), 1.0 - 1e-9);
  EXPECT_LT((frames->camera().position_W_m - from_above.position_W_m).norm(), 1e-9);
  // A recording without camera events (a headless run's): the default camera stays.
  runtime::Recording without = rec;
  without.events.clear();
  const std::unique_ptr<RecordingFrameRenderer> plain = exportFrameRenderer(scene, without, options, nullptr);
  const ViewCamera default_view = plain->camera();
  plain->show(without.records.back());
  EXPECT_TRUE(sameView(plain->camera(), default_view));
}

TEST(ReplayForceArrow, StartsAtTheToolsExtremePointAgainstTheForce) {
  // A vertical probe: vertices from its tip (z = 0) to its end (z = 0.06 m) in T.
  const std::vector<Eigen::Vector3d> vertices_T = {{0, 0, 0.03}, {0.001, 0, 0.06}, {0, 0, 0}, {0, 0.001, 0.01}};
  haptics::Pose X_WP;
  X_WP.p_AB_m = Eigen::Vector3d(0.1, 0.2, 0.3);
  // Pushed up (+z): the tip; pushed down: the far end.
  EXPECT_LT((forceOrigin_W(X_WP, Eigen::Vector3d(0, 0, 2.0), vertices_T) - Eigen::Vector3d(0.1, 0.2, 0.3)).norm(), 1e-12);
  EXPECT_LT((forceOrigin_W(X_WP, Eigen::Vector3d(0, 0, -2.0), vertices_T) - Eigen::Vector3d(0.101, 0.2, 0.36)).norm(), 1e-12);
  // Turned upside down (180 degrees about x): pushed down (-z in W) is the tip again.
  X_WP.R_AB = Eigen::Quaterniond(Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitX()));
  EXPECT_LT((forceOrigin_W(X_WP, Eigen::Vector3d(0, 0, -2.0), vertices_T) - X_WP.p_AB_m).norm(), 1e-12);
  // No force: the proxy's origin.
  X_WP.p_AB_m = Eigen::Vector3d(0.5, 0, 0);
  EXPECT_EQ(forceOrigin_W(X_WP, Eigen::Vector3d::Zero(), vertices_T), X_WP.p_AB_m);
}

TEST(ReplayIsovalue, TicksOfFeltSegmentsLeaveThePicturesIsovalueAlone) {
  // A tick records the isovalue the hand felt: the scan's, or the segments' level (0.5) when
  // segments are felt. Only the scan's may move the picture.
  const runtime::LoadedScene& scene = test::sphereProbeScene();
  runtime::TickRecord record;
  record.isovalue = io::kSegmentSurfaceLevel;
  record.p_WP_m[2] = record.p_WD_m[2] = 0.05;

  runtime::LiveValues scan = runtime::LiveValues::initial(scene);
  scan.isovalue = 3.0;
  const SceneActorsSpec scan_spec = sceneActorsSpecFor(scene, scan);
  EXPECT_TRUE(scan_spec.isovalue_from_records);
  RecordingFrameRenderer scan_frames(scan_spec, 64, 64, ViewLook{});
  EXPECT_EQ(scan_frames.isovalue(), 3.0);
  scan_frames.show(record);
  EXPECT_EQ(scan_frames.isovalue(), io::kSegmentSurfaceLevel) << "the scan's isovalue changed while recording";

  runtime::LiveValues felt = scan;
  felt.segments = std::make_shared<const runtime::SegmentSet>(
      test::ballSegmentation(*scene.volume.field, Eigen::Vector3d::Zero(), 0.010), std::vector<int>{0},
      std::vector<int>{0}, std::vector<int>{}, 1.0);
  ASSERT_TRUE(felt.feltSegments());
  const SceneActorsSpec felt_spec = sceneActorsSpecFor(scene, felt);
  EXPECT_FALSE(felt_spec.isovalue_from_records);
  RecordingFrameRenderer felt_frames(felt_spec, 64, 64, ViewLook{});
  felt_frames.show(record);
  EXPECT_EQ(felt_frames.isovalue(), 3.0) << "the segments' level must not become the scan's isovalue";
}

// The overlay of exported frames: the time, |F| and |torque| of the record shown, a marker's label
// and a critical segment drilled for two seconds after their events, and none of it when off.
TEST(ExportOverlay, ShowsTheRecordsFiguresAndTheEventsOfTheLastTwoSeconds) {
  const runtime::LoadedScene& scene = test::sphereProbeScene();
  runtime::Recording recording;
  for (int i = 0; i <= 400; ++i) {
    runtime::TickRecord r;
    r.time_s = 0.01 * i;
    r.tick = static_cast<std::uint64_t>(i);
    r.p_WP_m[2] = r.p_WD_m[2] = 0.05;
    r.force_W_N[0] = 3.0, r.force_W_N[1] = 4.0;  // |F| = 5 N
    r.torque_W_Nm[2] = -0.012;
    recording.records.push_back(r);
  }
  recording.events.push_back({0.5, 50, "marker", R"({"label":"nerve close"})"});
  recording.events.push_back({0.6, 60, "critical_removed", R"({"segment":"facial nerve","voxels":3,"mm3":0.1})"});
  const SceneActorsSpec spec = sceneActorsSpecFor(scene, runtime::LiveValues::initial(scene));
  RecordingFrameRenderer with(spec, 320, 240, ViewLook{});
  with.setOverlay(&recording);
  with.show(recording.records[55]);
  EXPECT_NE(with.overlayText().find("t = 0.55 s"), std::string::npos) << with.overlayText();
  EXPECT_NE(with.overlayText().find("|F| = 5.00 N"), std::string::npos) << with.overlayText();
  EXPECT_NE(with.overlayText().find("|torque| = 0.012 N*m"), std::string::npos) << with.overlayText();
  EXPECT_NE(with.overlayText().find("marker: nerve close"), std::string::npos) << with.overlayText();
  EXPECT_EQ(with.overlayAlert(), "") << "the critical event comes at 0.6 s";
  with.show(recording.records[70]);
  EXPECT_EQ(with.overlayAlert(), "CRITICAL: facial nerve drilled");
  with.show(recording.records[300]);
  EXPECT_EQ(with.overlayText().find("marker"), std::string::npos) << "2.4 s after the marker: " << with.overlayText();
  EXPECT_EQ(with.overlayAlert(), "");
  // Drawn: the frame differs from the same frame without the overlay where the text is.
  with.show(recording.records[70]);
  RecordingFrameRenderer without(spec, 320, 240, ViewLook{});
  without.show(recording.records[70]);
  EXPECT_EQ(without.overlayText(), "");
  vtkImageData* a = with.render();
  vtkImageData* b = without.render();
  const auto* pa = static_cast<const unsigned char*>(a->GetScalarPointer());
  const auto* pb = static_cast<const unsigned char*>(b->GetScalarPointer());
  std::size_t differing = 0;
  for (vtkIdType i = 0; i < a->GetNumberOfPoints() * 3; ++i) differing += std::abs(pa[i] - pb[i]) > 40 ? 1 : 0;
  EXPECT_GT(differing, 300u) << "the overlay's text and alert are not in the picture";
}

// A frame's RGB bytes (bottom row first).
std::vector<unsigned char> framePixels(vtkImageData* image) {
  const auto* p = static_cast<const unsigned char*>(image->GetScalarPointer());
  return std::vector<unsigned char>(p, p + image->GetNumberOfPoints() * 3);
}

// Pixels of two frames of one size whose colour differs by more than 24 in any channel.
std::size_t differingPixels(const std::vector<unsigned char>& a, const std::vector<unsigned char>& b) {
  std::size_t n = 0;
  for (std::size_t i = 0; i < a.size(); i += 3)
    n += std::abs(a[i] - b[i]) > 24 || std::abs(a[i + 1] - b[i + 1]) > 24 || std::abs(a[i + 2] - b[i + 2]) > 24;
  return n;
}

// Exported frames reuse the volume's ray-cast picture and depth, and lay the tools over it where
// they are nearer: the frames must be the ones a full render gives (VTK's ray caster stopping at
// the tools' depth), with the probe above the sphere, pushed into it (the device's lines inside
// hidden), and behind it from the camera (partly hidden by the sphere), while the volume is ray
// cast once for all of them.
TEST(ExportFrames, ReusingTheVolumesPictureGivesTheFullRendersFrames) {
  const runtime::LoadedScene& scene = test::sphereProbeScene();
  const haptics::ScalarVolume& field = *scene.hapticField();
  const double iso = scene.hapticIsovalue();
  const Eigen::Vector3d centre = 0.5 * (field.boundsMin_W_m() + field.boundsMax_W_m());
  // The sphere's radius along +y (towards the back: the camera looks from the front).
  double radius = 0.0;
  while (field.isInside(centre + Eigen::Vector3d(0, radius + 1e-4, 0), iso)) radius += 1e-4;
  ASSERT_GT(radius, 0.005);
  const auto record = [](const Eigen::Vector3d& p_WP, const Eigen::Vector3d& p_WD, double force_z_N) {
    runtime::TickRecord r;
    for (int a = 0; a < 3; ++a) r.p_WP_m[a] = p_WP[a], r.p_WD_m[a] = p_WD[a];
    r.force_W_N[2] = force_z_N;
    r.isovalue = std::numeric_limits<double>::quiet_NaN();
    return r;
  };
  const Eigen::Vector3d top = scene.X_WT_initial.p_AB_m;  // free, just above the surface
  const std::vector<runtime::TickRecord> records = {
      record(top + Eigen::Vector3d(0, 0, 0.01), top + Eigen::Vector3d(0, 0, 0.01), 0.0),  // above
      record(top, top - Eigen::Vector3d(0, 0, 0.008), 4.0),                             // pressed: device inside
      record(centre + Eigen::Vector3d(0, radius + 0.004, 0), centre + Eigen::Vector3d(0, radius + 0.004, 0), 0.0),  // behind
  };
  const SceneActorsSpec spec = sceneActorsSpecFor(scene, runtime::LiveValues::initial(scene));
  RecordingFrameRenderer kept(spec, 320, 240, ViewLook{});
  RecordingFrameRenderer full(spec, 320, 240, ViewLook{});
  full.setReuseVolume(false);
  kept.show(records[0]);
  kept.resetCamera();
  full.copyCamera(kept.renderer()->GetActiveCamera());
  RecordingFrameRenderer empty(spec, 320, 240, ViewLook{});  // the sphere without the tools
  empty.copyCamera(kept.renderer()->GetActiveCamera());
  empty.actors().proxyActor()->SetVisibility(false);
  empty.actors().deviceActor()->SetVisibility(false);
  empty.setReuseVolume(false);
  empty.show(records[0]);
  const std::vector<unsigned char> sphere_alone = framePixels(empty.render());
  const std::size_t frame_pixels = sphere_alone.size() / 3;
  for (std::size_t k = 0; k < records.size(); ++k) {
    kept.show(records[k]);
    full.show(records[k]);
    const std::vector<unsigned char> a = framePixels(kept.render()), b = framePixels(full.render());
    EXPECT_LT(differingPixels(a, b), frame_pixels / 200) << "record " << k << ": the frame differs from a full render's";
    if (k < 2) {
      EXPECT_GT(differingPixels(b, sphere_alone), 100u) << "record " << k << ": the probe is not in the picture";
    }
  }
  EXPECT_EQ(kept.volumeRenders(), 2u) << "the volume is ray cast once (picture and depth) for every frame";
  EXPECT_EQ(full.volumeRenders(), records.size());
}

// While the burr drills, the kept picture is ray cast again only where the cavity lies on the
// screen. Oracle: a full render of each frame, its cavity carved the same. On the sphere a
// cavity grows on the side the camera looks at, over four records (balls of 3 to 7.5 voxels); the frames must be the full
// renders' and show it growing, while the pixels ray cast for it are a small part of the four
// full frames that re-casting the kept picture whole would cost. Then the probe is pushed into
// the cavity: it must be hidden where the surface is nearer, as in the full render.
TEST(ExportFrames, AGrowingCavityIsCastAgainOnlyWhereItLies) {
  const runtime::LoadedScene& scene = test::sphereProbeScene();
  const SceneActorsSpec spec = sceneActorsSpecFor(scene, runtime::LiveValues::initial(scene));
  int dims[3];
  spec.image->GetDimensions(dims);
  // The sphere's front (-y, anterior: the default camera looks from there) on the centre column.
  const int ic = dims[0] / 2, kc = dims[2] / 2;
  const auto at = [&](int i, int j, int k) { return spec.image->GetScalarComponentAsDouble(i, j, k, 0); };
  int js = 0;
  while (js < dims[1] && at(ic, js, kc) < spec.isovalue) ++js;
  ASSERT_LT(js, dims[1] / 2) << "no surface in front of the centre";
  DrillingTimeline timeline;
  timeline.picture.after_record.push_back(0);  // record 0: nothing removed yet
  std::vector<bool> taken(static_cast<std::size_t>(dims[0]) * dims[1] * dims[2], false);
  for (int step = 1; step <= 4; ++step) {  // balls of 3 to 7.5 voxels about a voxel inside the surface
    const double r = 1.5 + 1.5 * step;
    for (int k = kc - 8; k <= kc + 8; ++k)
      for (int j = js - 7; j <= js + 9; ++j)
        for (int i = ic - 8; i <= ic + 8; ++i) {
          if (j < 0 || (i - ic) * (i - ic) + (j - js - 1) * (j - js - 1) + (k - kc) * (k - kc) > r * r) continue;
          const auto v = static_cast<std::uint64_t>(i) + static_cast<std::uint64_t>(dims[0]) * (j + static_cast<std::uint64_t>(dims[1]) * k);
          if (taken[v]) continue;
          taken[v] = true;
          timeline.picture.voxels.push_back(v);
        }
    timeline.picture.after_record.push_back(timeline.picture.voxels.size());
  }
  runtime::TickRecord away;  // the probe 10 cm above: not in the picture's way
  const Eigen::Vector3d p = scene.X_WT_initial.p_AB_m + Eigen::Vector3d(0, 0, 0.1);
  for (int a = 0; a < 3; ++a) away.p_WP_m[a] = away.p_WD_m[a] = p[a];
  away.isovalue = std::numeric_limits<double>::quiet_NaN();
  RecordingFrameRenderer kept(spec, 320, 240, ViewLook{});
  RecordingFrameRenderer full(spec, 320, 240, ViewLook{});
  full.setReuseVolume(false);
  kept.setDrilling(timeline);
  full.setDrilling(timeline);
  kept.show(away);
  kept.resetCamera();
  full.copyCamera(kept.renderer()->GetActiveCamera());
  std::vector<unsigned char> before;
  std::uint64_t cast_for_the_first = 0;
  const std::uint64_t frame_pixels = 320u * 240u;
  for (std::size_t record = 0; record < timeline.picture.after_record.size(); ++record) {
    kept.showCavityAt(record);
    full.showCavityAt(record);
    kept.show(away);
    full.show(away);
    const std::vector<unsigned char> a = framePixels(kept.render()), b = framePixels(full.render());
    std::cout << "record " << record << ": " << differingPixels(a, b) << " pixels differ from the full render, "
              << (before.empty() ? 0 : differingPixels(a, before)) << " from the frame before\n";
    // The pixels cast again are shaded as the full render shades them; those not cast again
    // still show what they showed, which the cavity did not change.
    EXPECT_LE(differingPixels(a, b), 4u) << "record " << record << ": the frame differs from a full render's";
    if (record == 0) {
      cast_for_the_first = kept.volumePixelsCast();
    } else {
      EXPECT_GT(differingPixels(a, before), 20u) << "record " << record << ": the cavity did not grow in the picture";
    }
    before = a;
  }
  const std::uint64_t cast_for_the_cavity = kept.volumePixelsCast() - cast_for_the_first;
  // The probe's lowest point pushed through the cavity, 2.5 voxels into its back wall: which of
  // the tool is drawn now rests on the depth cast for the cavity's pixels (the kept picture is
  // not cast again), and its tip is hidden.
  double origin[3], spacing[3];
  spec.image->GetOrigin(origin);
  spec.image->GetSpacing(spacing);
  const Eigen::Vector3d o(origin[0], origin[1], origin[2]);
  const Eigen::Vector3d centre_image = o + Eigen::Vector3d(ic * spacing[0], (js + 11) * spacing[1], kc * spacing[2]);
  const Eigen::Vector3d centre_W = o + spec.direction_W * (centre_image - o);
  Eigen::Vector3d tip_T = spec.tool_mesh_T.vertices_T_m.front();
  for (const Eigen::Vector3d& v : spec.tool_mesh_T.vertices_T_m)
    if (v.z() < tip_T.z()) tip_T = v;
  runtime::TickRecord in_cavity = away;
  for (int a = 0; a < 3; ++a) in_cavity.p_WP_m[a] = in_cavity.p_WD_m[a] = centre_W[a] - tip_T[a];
  const std::uint64_t renders = kept.volumeRenders();
  kept.show(in_cavity);
  full.show(in_cavity);
  const std::vector<unsigned char> a = framePixels(kept.render()), b = framePixels(full.render());
  std::cout << "the probe in the cavity: " << differingPixels(a, b) << " pixels differ from the full render, "
            << differingPixels(a, before) << " from the frame without it\n";
  EXPECT_EQ(kept.volumeRenders(), renders) << "the kept picture serves";
  EXPECT_GT(differingPixels(a, before), 100u) << "the probe is in the picture";
  EXPECT_LE(differingPixels(a, b), 8u) << "the probe is hidden where the cavity's surface is nearer, as in a full render";
  std::cout << "the cavity's four steps cast " << cast_for_the_cavity << " pixels; the kept picture whole, "
            << 2 * 4 * frame_pixels << "\n";
  EXPECT_EQ(cast_for_the_first, 2 * frame_pixels) << "the first frame keeps the whole picture (colour and depth)";
  EXPECT_GT(cast_for_the_cavity, 0u);
  EXPECT_LT(cast_for_the_cavity, 2 * 4 * frame_pixels / 8) << "the cavity is cast again where it lies only";
}

using vh::test::FileSizeLimit;

TEST(RecordingWriteFailure, AFullDiskEndsTheRecordingAndTheStatusBarSaysWhy) {
  QTemporaryDir dir;
  const fs::path path = fs::path(dir.path().toStdString()) / "full.vhrec";
  auto w = smallWindow();
  ASSERT_TRUE(loadInto(*w, sphereScene())) << w->opener()->lastError().toStdString();
  ASSERT_TRUE(w->session().hapticsRunning());
  ASSERT_TRUE(w->recorder()->start(path)) << w->recorder()->lastError().toStdString();
  ASSERT_TRUE(waitFor([&] { return w->recorder()->recordsWritten() > 0; }, 30000));
  auto* label = w->findChild<QLabel*>("recordingStatus");
  ASSERT_NE(label, nullptr);
  EXPECT_TRUE(label->text().contains("REC")) << label->text().toStdString();
  // Room for about half a second more (a tick is 200 bytes, the servo runs at about 1 kHz): the
  // disk fills within a second on an idle machine, and the status bar says so (waited for up to
  // 30 s: a busy machine ticks and writes more slowly).
  const rlim_t limit = static_cast<rlim_t>(fs::file_size(path)) + 100000;
  QString status;
  {
    const FileSizeLimit full(limit);
    const bool said = waitFor([&] { return label->text().startsWith("REC stopped"); }, 30000);
    status = label->text();
    ASSERT_TRUE(said) << "status bar: " << status.toStdString();
    EXPECT_FALSE(w->recorder()->recording());
  }
  EXPECT_TRUE(status.startsWith(QString::fromUtf8("REC stopped: file size limit reached (File too large) \u2014 ")))
      << status.toStdString();
  EXPECT_TRUE(label->isVisible());
  // The file (stat) stayed under the limit and reads back whole: every tick it kept, in order,
  // as many as the status bar says, no truncated chunk.
  struct stat st{};
  ASSERT_EQ(::stat(path.c_str(), &st), 0);
  EXPECT_LE(static_cast<rlim_t>(st.st_size), limit);
  const runtime::Recording rec = runtime::readRecording(path);
  ASSERT_GT(rec.records.size(), 0u);
  for (std::size_t i = 1; i < rec.records.size(); ++i) ASSERT_EQ(rec.records[i].tick, rec.records[0].tick + i);
  EXPECT_TRUE(status.contains(QString::fromUtf8("\u2014 %1 ticks kept").arg(rec.records.size()))) << status.toStdString();
  for (const std::string& warning : rec.warnings) EXPECT_EQ(warning.find("truncated"), std::string::npos) << warning;
  ASSERT_FALSE(rec.warnings.empty());
  EXPECT_TRUE(rec.warnings.back().find("file size limit reached") != std::string::npos ||
              rec.warnings.back().find("unfinished recording") != std::string::npos)
      << rec.warnings.back();
  // The next recording clears the message.
  ASSERT_TRUE(w->recorder()->start(fs::path(dir.path().toStdString()) / "next.vhrec"));
  EXPECT_TRUE(label->text().startsWith(QString::fromUtf8("\u25cf REC"))) << label->text().toStdString();
  w->recorder()->stop();
}

}  // namespace
}  // namespace vh::ui
