// Guidance from an expert's recording in the window, checked as a person would: Haptics > Guide
// with Recording (HapticsController::guideWith()) refuses a recording of another scan naming both
// datasets' checksums and guides with one of the same scan (the haptic thread's guidance on);
// the expert's ghost then stands at the expert's pose at the nearest point of the expert's path to
// the device, in its colour where the camera projects it, and Stop Guidance hides it; a
// recording of the guided session replays with the ghost, and says in the status bar when the
// expert's recording is gone.
// Oracles: the expert's recorded device positions (the nearest point by brute force over
// consecutive records, the orientation of the record nearest to it), the checksums in the two
// recordings' own metadata, the camera's projection of the ghost's centre.
// Scenes: the built-in sphere and block (no shared data), small windows (llvmpipe).
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <iostream>
#include <filesystem>
#include <limits>
#include <memory>
#include <numbers>
#include <sstream>
#include <string>

#include <QImage>
#include <QSignalSpy>
#include <QTemporaryDir>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <vtkActor.h>
#include <vtkCamera.h>
#include <vtkImageData.h>
#include <vtkMatrix4x4.h>
#include <vtkRenderer.h>

#include "ui_test_util.h"
#include "vh/runtime/recording.h"
#include "vh/runtime/runner.h"
#include "vh/runtime/scene.h"
#include "vh/runtime/sha256.h"
#include "vh/runtime/trajectory.h"
#include "vh/ui/devices/device_input.h"
#include "vh/ui/export/media_export.h"
#include "vh/ui/haptics_controller.h"
#include "vh/ui/main_window.h"
#include "vh/ui/replay/replay_controller.h"
#include "vh/ui/replay/session_recorder.h"
#include "vh/ui/view/expert_ghost.h"
#include "vh/ui/view/scene_view.h"
#include "vh/ui/view/vtk_view.h"
#include "vh/ui/view_controller.h"

namespace vh::ui {
namespace {

namespace fs = std::filesystem;
using haptics::Pose;
using test::waitFor;

runtime::SceneSpec sphereScene() {
  runtime::SceneSpec spec;
  spec.volume.path = "builtin:sphere";
  spec.tool.mesh = "builtin:probe";
  spec.device = runtime::DeviceSpec{};  // simulated
  return spec;
}

/// The expert's pass: 24 mm along x over the scene's initial pose, the probe turning from 30
/// degrees about x to -30 degrees, recorded by a headless run (the device a position source).
void recordExpert(const runtime::SceneSpec& spec, const fs::path& file) {
  const runtime::LoadedScene scene = runtime::loadScene(spec);
  const Eigen::Vector3d p0 = scene.X_WT_initial.p_AB_m;
  const double a = std::numbers::pi / 6;
  std::vector<runtime::TrajectorySample> keys(2);
  keys[0].t_s = 0.0;
  keys[0].X_WD = {Eigen::Quaterniond(Eigen::AngleAxisd(a, Eigen::Vector3d::UnitX())), p0 + Eigen::Vector3d(-0.012, 0, 0.002)};
  keys[1].t_s = 0.6;
  keys[1].X_WD = {Eigen::Quaterniond(Eigen::AngleAxisd(-a, Eigen::Vector3d::UnitX())), p0 + Eigen::Vector3d(0.012, 0, 0.002)};
  runtime::RunOptions options;
  options.verify_step_voxels = 0.0;
  options.lag_reference = false;
  options.record = file;
  runtime::runHeadless(scene, runtime::Trajectory(std::move(keys)), options);
}

/// The oracle: the nearest point to p of the segments between consecutive records' device
/// positions (by brute force), and the orientation of the record nearest to that point.
Pose nearestExpertPose(const runtime::Recording& expert, const Eigen::Vector3d& p) {
  double best = std::numeric_limits<double>::infinity();
  Eigen::Vector3d nearest = Eigen::Vector3d::Zero();
  const auto at = [&](std::size_t i) { return Eigen::Vector3d(expert.records[i].p_WD_m[0], expert.records[i].p_WD_m[1], expert.records[i].p_WD_m[2]); };
  for (std::size_t i = 0; i + 1 < expert.records.size(); ++i) {
    const Eigen::Vector3d a = at(i), ab = at(i + 1) - a;
    const double s = ab.squaredNorm() > 0.0 ? std::clamp((p - a).dot(ab) / ab.squaredNorm(), 0.0, 1.0) : 0.0;
    const Eigen::Vector3d q = a + s * ab;
    if ((q - p).norm() < best) {
      best = (q - p).norm();
      nearest = q;
    }
  }
  std::size_t record = 0;
  for (std::size_t i = 0; i < expert.records.size(); ++i)
    if ((at(i) - nearest).norm() < (at(record) - nearest).norm()) record = i;
  const double* q = expert.records[record].q_WD;
  return {Eigen::Quaterniond(q[0], q[1], q[2], q[3]).normalized(), nearest};
}

Pose actorPose(vtkActor* actor) {
  vtkMatrix4x4* m = actor->GetUserMatrix();
  Eigen::Matrix3d R;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) R(r, c) = m->GetElement(r, c);
  return {Eigen::Quaterniond(R), Eigen::Vector3d(m->GetElement(0, 3), m->GetElement(1, 3), m->GetElement(2, 3))};
}

std::string datasetSha256(const fs::path& recording) {
  return nlohmann::json::parse(runtime::readRecording(recording).metadata_json)["dataset"]["sha256"].get<std::string>();
}

std::unique_ptr<MainWindow> sphereWindow() {
  auto w = std::make_unique<MainWindow>();
  w->setInteractive(false);
  w->resize(560, 440);
  w->show();
  QSignalSpy loaded(w.get(), &MainWindow::sceneLoaded);
  w->opener()->openScene(sphereScene());
  if (!waitFor([&] { return loaded.count() > 0 && !w->opener()->loading() && w->session().hapticsRunning(); }, 60000)) return nullptr;
  return w;
}

/// Ghost-green pixels (green well above red and blue) within `radius_px` of (x, y) of `image`.
int greenPixelsNear(const QImage& image, int x, int y, int radius_px) {
  const QImage rgb = image.convertToFormat(QImage::Format_RGB32);
  int n = 0;
  for (int j = std::max(0, y - radius_px); j < std::min(rgb.height(), y + radius_px + 1); ++j) {
    for (int i = std::max(0, x - radius_px); i < std::min(rgb.width(), x + radius_px + 1); ++i) {
      const QRgb c = rgb.pixel(i, j);
      if (qGreen(c) > qRed(c) + 25 && qGreen(c) > qBlue(c) + 25) ++n;
    }
  }
  return n;
}

/// The expert's recordings and the window for the whole suite.
class Guidance : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new QTemporaryDir();
    const fs::path dir(dir_->path().toStdString());
    expert_ = dir / "expert.vhrec";
    other_ = dir / "other-scan.vhrec";
    recordExpert(sphereScene(), expert_);
    recordExpert(runtime::builtinBlockWithHoleScene(), other_);
  }
  static void TearDownTestSuite() {
    delete dir_;
    dir_ = nullptr;
  }
  static inline QTemporaryDir* dir_ = nullptr;
  static inline fs::path expert_, other_;
};

TEST_F(Guidance, AnotherScansRecordingIsRefusedNamingBothChecksumsAndTheSameScansGuides) {
  auto w = sphereWindow();
  ASSERT_NE(w, nullptr) << "the built-in sphere did not load and run";
  const std::string ours = datasetSha256(expert_), theirs = datasetSha256(other_);
  ASSERT_NE(ours, theirs);
  QString error;
  EXPECT_FALSE(w->haptics()->guideWith(QString::fromStdString(other_.string()), &error));
  EXPECT_TRUE(error.contains(QString::fromStdString(ours.substr(0, 12)))) << error.toStdString();
  EXPECT_TRUE(error.contains(QString::fromStdString(theirs.substr(0, 12)))) << error.toStdString();
  EXPECT_EQ(w->session().hapticThread()->guidance(), nullptr);
  EXPECT_FALSE(w->sceneView()->ghost()->visible());

  ASSERT_TRUE(w->haptics()->guideWith(QString::fromStdString(expert_.string()), &error)) << error.toStdString();
  ASSERT_NE(w->session().hapticThread()->guidance(), nullptr);
  EXPECT_EQ(w->session().hapticThread()->guidance()->fileSha256(), runtime::sha256File(expert_));
  EXPECT_TRUE(waitFor([&] { const auto* s = w->viewController()->snapshot(); return s != nullptr && s->guidance_on; }, 30000))
      << "the coupling thread never reported guidance on";
  w->haptics()->stopGuidance();
  EXPECT_EQ(w->session().hapticThread()->guidance(), nullptr);
  w->session().stopHaptics();
}

TEST_F(Guidance, TheGhostStandsAtTheExpertsNearestPoseInItsColourAndGoesWithStopGuidance) {
  auto w = sphereWindow();
  ASSERT_NE(w, nullptr) << "the built-in sphere did not load and run";
  const runtime::Recording expert = runtime::readRecording(expert_);
  const Pose X_WD = Pose::FromTranslation(w->session().live().X_WT_initial.p_AB_m + Eigen::Vector3d(0.004, 0.006, 0.003));
  w->deviceInput()->setDevicePose(X_WD);
  ASSERT_TRUE(w->haptics()->guideWith(QString::fromStdString(expert_.string())));
  const auto device_there = [&] {
    const runtime::HapticSnapshot* s = w->viewController()->snapshot();
    return s != nullptr && s->guidance_on && s->guidance_segment >= 0 && (s->X_WD.p_AB_m - X_WD.p_AB_m).norm() < 1e-9;
  };
  ASSERT_TRUE(waitFor(device_there, 30000)) << "no snapshot of the device guided where it was put";
  test::pump(200);
  const ExpertGhost* ghost = w->sceneView()->ghost();
  ASSERT_NE(ghost, nullptr);
  ASSERT_TRUE(ghost->visible());
  EXPECT_TRUE(ghost->toolActor()->GetVisibility());
  EXPECT_TRUE(ghost->pathActor()->GetVisibility());
  const Pose oracle = nearestExpertPose(expert, X_WD.p_AB_m);
  const Pose shown = actorPose(ghost->toolActor());
  EXPECT_LT((shown.p_AB_m - oracle.p_AB_m).norm(), 1e-9) << shown.p_AB_m.transpose() << " vs " << oracle.p_AB_m.transpose();
  EXPECT_LT(shown.R_AB.angularDistance(oracle.R_AB), 2e-3);
  EXPECT_GT(shown.R_AB.angularDistance(X_WD.R_AB), 0.05) << "the expert's orientation, not the trainee's";

  // The ghost's colour where the camera projects its centre, and not once it is hidden.
  vtkRenderer* renderer = w->sceneView()->widget()->renderer();
  double bounds[6];
  ghost->toolActor()->GetBounds(bounds);
  renderer->SetWorldPoint(0.5 * (bounds[0] + bounds[1]), 0.5 * (bounds[2] + bounds[3]), 0.5 * (bounds[4] + bounds[5]), 1.0);
  renderer->WorldToDisplay();
  const double* d = renderer->GetDisplayPoint();
  w->sceneView()->renderStill(true);
  const QImage with = w->sceneView()->widget()->grabFrame();
  const int x = static_cast<int>(std::lround(d[0])), y = with.height() - 1 - static_cast<int>(std::lround(d[1]));
  ASSERT_TRUE(x >= 0 && y >= 0 && x < with.width() && y < with.height()) << x << ", " << y;
  const int green = greenPixelsNear(with, x, y, 12);
  // For a person to look at: VH_UI_SHOTS_DIR=DIR writes the view, closer and turned so that the
  // trainee's tool and the expert's ghost stand apart.
  if (const char* shots = std::getenv("VH_UI_SHOTS_DIR"); shots != nullptr && *shots != '\0') {
    w->resize(1000, 700);
    test::pump(300);
    w->viewController()->focusOnTool();
    renderer->GetActiveCamera()->Azimuth(-50.0);
    renderer->GetActiveCamera()->Elevation(15.0);
    renderer->GetActiveCamera()->Zoom(1.6);
    w->sceneView()->renderStill(true);
    test::pump(400);
    w->sceneView()->widget()->grabFrame().save(QString::fromStdString((fs::path(shots) / "guidance-ghost.png").string()), "PNG");
  }

  w->haptics()->stopGuidance();
  EXPECT_FALSE(ghost->visible());
  EXPECT_FALSE(ghost->toolActor()->GetVisibility());
  EXPECT_FALSE(ghost->pathActor()->GetVisibility());
  w->resize(560, 440);
  test::pump(300);
  w->sceneView()->renderStill(true);
  const QImage without = w->sceneView()->widget()->grabFrame();
  const int green_after = greenPixelsNear(without, x, y, 12);
  std::cout << "ghost-green pixels within 12 px of the ghost's projected centre: " << green << " shown, "
            << green_after << " after Stop Guidance\n";
  EXPECT_GT(green, 40) << "ghost-green pixels about its centre's projection (" << x << ", " << y << ")";
  EXPECT_LT(green_after, green / 10) << "after Stop Guidance";
  w->session().stopHaptics();
}

TEST_F(Guidance, AGuidedSessionReplaysWithTheGhostAndSaysSoWhenTheExpertIsGone) {
  const fs::path session = fs::path(dir_->path().toStdString()) / "guided.vhrec";
  {
    auto w = sphereWindow();
    ASSERT_NE(w, nullptr) << "the built-in sphere did not load and run";
    w->deviceInput()->setDevicePose(Pose::FromTranslation(w->session().live().X_WT_initial.p_AB_m + Eigen::Vector3d(0.003, 0.004, 0.0)));
    ASSERT_TRUE(w->haptics()->guideWith(QString::fromStdString(expert_.string())));  // before the recording
    ASSERT_TRUE(w->recorder()->start(session)) << w->recorder()->lastError().toStdString();
    test::pump(400);
    ASSERT_TRUE(waitFor([&] { return w->recorder()->recordsWritten() > 0; }, 30000)) << "no tick recorded";
    w->recorder()->stop();
    w->session().stopHaptics();
  }
  const runtime::Recording rec = runtime::readRecording(session);
  const auto event = std::find_if(rec.events.begin(), rec.events.end(), [](const auto& e) { return e.type == "guidance"; });
  ASSERT_NE(event, rec.events.end()) << "a recording started with guidance on holds its guidance event";
  const nlohmann::json detail = nlohmann::json::parse(event->detail_json);
  EXPECT_EQ(detail.value("expert_sha256", ""), runtime::sha256File(expert_));
  EXPECT_EQ(fs::path(detail.value("expert_path", "")), fs::absolute(expert_).lexically_normal());

  auto w = std::make_unique<MainWindow>();
  w->setInteractive(false);
  w->resize(560, 440);
  w->show();
  QSignalSpy started(w->replay(), &ReplayController::replayStarted);
  ASSERT_TRUE(w->replay()->openRecording(session));
  ASSERT_TRUE(waitFor([&] { return started.count() > 0 && !w->opener()->loading(); }, 60000));
  const runtime::Recording expert = runtime::readRecording(expert_);
  w->replay()->setTime(rec.records.back().time_s);
  const runtime::TickRecord& r = rec.records[w->replay()->currentIndex()];
  const Eigen::Vector3d p_WD(r.p_WD_m[0], r.p_WD_m[1], r.p_WD_m[2]);
  ASSERT_TRUE(w->sceneView()->ghost()->visible());
  EXPECT_LT((actorPose(w->sceneView()->ghost()->toolActor()).p_AB_m - nearestExpertPose(expert, p_WD).p_AB_m).norm(), 1e-9);
  w->replay()->closeReplay();
  EXPECT_FALSE(w->sceneView()->ghost()->visible()) << "live again, without guidance";
  w->session().stopHaptics();

  // The expert's recording gone: no ghost, and the status bar says why.
  fs::rename(expert_, expert_.string() + ".moved");
  QSignalSpy notices(w->replay(), &ReplayController::noticeRequested);
  ASSERT_TRUE(w->replay()->openRecording(session));
  ASSERT_TRUE(waitFor([&] { return started.count() > 1 && !w->opener()->loading(); }, 60000));
  fs::rename(expert_.string() + ".moved", expert_);
  w->replay()->setTime(rec.records.back().time_s);
  EXPECT_FALSE(w->sceneView()->ghost()->visible());
  bool said = false;
  for (const QList<QVariant>& n : notices) said = said || n.at(0).toString().contains("not available");
  EXPECT_TRUE(said) << "no notice that the expert's recording is not available";
  EXPECT_TRUE(w->recorder()->statusText().contains("not available")) << w->recorder()->statusText().toStdString();
}

// Ghost-green pixels (green well above red and blue) of a frame (RGB, vtkImageData).
int greenPixels(vtkImageData* frame) {
  const auto* p = static_cast<const unsigned char*>(frame->GetScalarPointer());
  int n = 0;
  for (vtkIdType i = 0; i < frame->GetNumberOfPoints(); ++i, p += 3) n += (p[1] > p[0] + 25 && p[1] > p[2] + 25) ? 1 : 0;
  return n;
}

// `export` draws the expert's ghost in a guided session's frames, as its replay shows it: a
// headless trainee pass guided by the expert, exported (exportFrameRenderer()), stands the ghost
// at the expert's nearest pose to each record's device (oracle: nearestExpertPose(), by brute
// force) and puts ghost-green pixels in the frame. The expert's own recording (not guided)
// exports without a ghost; the guided one whose expert is gone too, and the log says why.
TEST_F(Guidance, AnExportOfAGuidedSessionDrawsTheExpertsGhost) {
  const fs::path dir(dir_->path().toStdString());
  const fs::path session = dir / "guided-headless.vhrec";
  const runtime::LoadedScene scene = runtime::loadScene(sphereScene());
  {
    const Eigen::Vector3d p0 = scene.X_WT_initial.p_AB_m;
    std::vector<runtime::TrajectorySample> keys(2);
    keys[0].t_s = 0.0;
    keys[0].X_WD = Pose::FromTranslation(p0 + Eigen::Vector3d(-0.010, 0.003, 0.004));
    keys[1].t_s = 0.5;
    keys[1].X_WD = Pose::FromTranslation(p0 + Eigen::Vector3d(0.010, 0.003, 0.004));
    runtime::RunOptions options;
    options.verify_step_voxels = 0.0;
    options.lag_reference = false;
    options.record = session;
    options.guide = std::make_shared<const runtime::ExpertPath>(runtime::readRecording(expert_), runtime::sha256File(expert_),
                                                                expert_.filename().string(), fs::absolute(expert_).string());
    runtime::runHeadless(scene, runtime::Trajectory(std::move(keys)), options);
  }
  const runtime::Recording rec = runtime::readRecording(session);
  const runtime::Recording expert = runtime::readRecording(expert_);
  MediaExportOptions options;
  options.width = 320;
  options.height = 240;
  std::ostringstream log;
  const auto frames = exportFrameRenderer(scene, rec, options, &log, session);
  ASSERT_NE(frames->ghost(), nullptr) << log.str();
  EXPECT_NE(log.str().find("the expert's ghost of expert.vhrec"), std::string::npos) << log.str();
  const runtime::TickRecord& r = rec.records[rec.records.size() / 2];
  frames->show(r);
  ASSERT_TRUE(frames->ghost()->visible());
  const Eigen::Vector3d p_WD(r.p_WD_m[0], r.p_WD_m[1], r.p_WD_m[2]);
  const Pose oracle = nearestExpertPose(expert, p_WD);
  EXPECT_LT((frames->ghost()->pose().p_AB_m - oracle.p_AB_m).norm(), 1e-9);
  EXPECT_LT((actorPose(frames->ghost()->toolActor()).p_AB_m - oracle.p_AB_m).norm(), 1e-9);
  const int green = greenPixels(frames->render());
  std::cout << "ghost-green pixels in the guided frame: " << green << "\n";
  EXPECT_GT(green, 50) << "the ghost is not in the exported frame";

  // Not guided: the expert's own recording.
  const auto plain = exportFrameRenderer(scene, expert, options, nullptr, expert_);
  EXPECT_EQ(plain->ghost(), nullptr);
  plain->show(expert.records[expert.records.size() / 2]);
  EXPECT_LT(greenPixels(plain->render()), 5);
  // Guided, but the expert's recording gone: no ghost, and why.
  fs::rename(expert_, expert_.string() + ".moved");
  std::ostringstream gone_log;
  const auto gone = exportFrameRenderer(scene, rec, options, &gone_log, session);
  fs::rename(expert_.string() + ".moved", expert_);
  EXPECT_EQ(gone->ghost(), nullptr);
  EXPECT_NE(gone_log.str().find("is not available"), std::string::npos) << gone_log.str();
}

}  // namespace
}  // namespace vh::ui
