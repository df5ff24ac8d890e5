// The tool's shadow on the felt surface (a depth cue). Oracle: the analytic ball (ray-sphere
// intersection in closed form) under a sampled ball field, and brute-force distances for the
// sample spread; in the window, the camera's own view up and the pixels of the frame.
#include "vh/ui/view/tool_shadow.h"

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <cmath>
#include <iostream>
#include <limits>
#include <optional>
#include <vector>

#include <QImage>
#include <QSignalSpy>

#include <gtest/gtest.h>
#include <vtkActor.h>
#include <vtkCamera.h>
#include <vtkMapper.h>
#include <vtkPolyData.h>
#include <vtkRenderer.h>

#include "phantom_window.h"
#include "ui_test_util.h"
#include "view_host.h"
#include "vh/datasets/synthetic.h"
#include "vh/runtime/drilling.h"
#include "vh/runtime/scene.h"
#include "vh/runtime/session.h"
#include "vh/ui/drill_controller.h"
#include "vh/ui/panels/display_panel.h"
#include "vh/ui/export/media_export.h"
#include "vh/ui/main_window.h"
#include "vh/ui/scene_opener.h"
#include "vh/ui/tool_picker.h"
#include "vh/ui/devices/device_input.h"
#include "vh/ui/view/scene_actors.h"
#include "vh/ui/view/scene_view.h"
#include "vh/ui/view/vtk_view.h"
#include "vh/ui/view_controller.h"

namespace vh::ui {
namespace {

using haptics::Pose;
namespace fs = std::filesystem;

/// Distance t >= 0 along the unit `d` from `a` to the first point of the ball (c, R); none when
/// the ray misses it or starts inside.
std::optional<double> rayBall(const Eigen::Vector3d& a, const Eigen::Vector3d& d, const Eigen::Vector3d& c, double R) {
  const Eigen::Vector3d m = a - c;
  const double b = m.dot(d);
  const double q = m.squaredNorm() - R * R;
  if (q <= 0.0) return std::nullopt;
  const double disc = b * b - q;
  if (disc < 0.0 || b > 0.0) return std::nullopt;
  return -b - std::sqrt(disc);
}

// A grid of sample points above an off-grid ball, at a tilted pose, cast along a tilted "down":
// every sample whose ray meets the ball casts a shadow point where the closed form puts it
// (within 0.05 mm: trilinear distance field of 1 mm voxels, bracket of 1/20 voxel); rays that
// miss it by more than half a voxel cast nothing; the drop line is the shortest of them.
TEST(ToolShadow, FallsWhereTheRayMeetsTheAnalyticBallAndTheDropLineIsTheShortest) {
  datasets::GridSpec grid;  // 64^3 of 1 mm about the origin
  const Eigen::Vector3d c(0.7e-3, -1.3e-3, 0.4e-3);
  const double R = 0.020;
  const haptics::ScalarVolume field = datasets::makeSphereVolume(grid, c, R);
  Pose X_WP;
  X_WP.R_AB = Eigen::Quaterniond(Eigen::AngleAxisd(0.5, Eigen::Vector3d(1, 2, 0.5).normalized()));
  X_WP.p_AB_m = Eigen::Vector3d(2e-3, 1e-3, 26e-3);
  std::vector<Eigen::Vector3d> samples_T;
  for (int i = -6; i <= 6; ++i) {
    for (int j = -6; j <= 6; ++j) samples_T.emplace_back(i * 3.1e-3, j * 3.1e-3, 0.0);
  }
  const Eigen::Vector3d down_W = Eigen::Vector3d(0.2, -0.1, -1.0);  // not unit: normalised inside
  const Eigen::Vector3d d = down_W.normalized();
  const double reach = 0.08;

  int hits = 0;
  int misses = 0;
  double best = std::numeric_limits<double>::infinity();
  Eigen::Vector3d best_from = Eigen::Vector3d::Zero();
  for (const Eigen::Vector3d& p_T : samples_T) {
    const Eigen::Vector3d a = X_WP * p_T;
    const ToolShadow one = castToolShadow(field, 0.0, X_WP, std::span(&p_T, 1), down_W, reach);
    const std::optional<double> t = rayBall(a, d, c, R);
    // Distance of the ray's line from the centre: near R the ray grazes the ball (no oracle).
    const double miss = ((a - c) - (a - c).dot(d) * d).norm();
    if (std::abs(miss - R) < 0.5e-3) continue;
    if (t.has_value() && (a - c).norm() > R) {
      ASSERT_EQ(one.footprint_W_m.size(), 1u) << "no shadow under " << a.transpose();
      EXPECT_LT((one.footprint_W_m[0] - (a + *t * d)).norm(), 0.05e-3) << "at " << a.transpose();
      EXPECT_TRUE(one.has_gap);
      EXPECT_NEAR(one.gap_m, *t, 0.05e-3);
      ++hits;
      if (*t < best) {
        best = *t;
        best_from = a;
      }
    } else {
      EXPECT_TRUE(one.footprint_W_m.empty()) << "a shadow where the ray misses, from " << a.transpose();
      EXPECT_FALSE(one.has_gap);
      ++misses;
    }
  }
  EXPECT_GT(hits, 50);
  EXPECT_GT(misses, 10);

  const ToolShadow all = castToolShadow(field, 0.0, X_WP, samples_T, down_W, reach);
  ASSERT_TRUE(all.has_gap);
  EXPECT_NEAR(all.gap_m, best, 0.05e-3);
  EXPECT_LT((all.gap_from_W_m - best_from).norm(), 1e-12);
  EXPECT_NEAR((all.gap_to_W_m - all.gap_from_W_m).dot(d), all.gap_m, 1e-9);

  // Out of reach, a zero direction, a sample inside the ball: nothing.
  EXPECT_TRUE(castToolShadow(field, 0.0, X_WP, samples_T, down_W, 0.5 * best).footprint_W_m.empty());
  EXPECT_TRUE(castToolShadow(field, 0.0, X_WP, samples_T, Eigen::Vector3d::Zero(), reach).footprint_W_m.empty());
  const Eigen::Vector3d inside_T = X_WP.inverse() * c;
  EXPECT_TRUE(castToolShadow(field, 0.0, X_WP, std::span(&inside_T, 1), down_W, reach).footprint_W_m.empty());
}

// A pit drilled into the ball's top (voxels inside it within 5 mm of the vertical axis, down to
// 8 mm below the top) carved into a CarvedRegion in three batches (the second inside the box,
// the third beyond it): straight down from above the pit the shadow falls onto the pit's floor
// (within a voxel of 8 mm down; the uncarved field puts it on the top), and every shadow, along
// a tilted light too, is the one cast on a dense copy of the field with the same voxels set to
// its lowest value (the brute-force oracle), to 1e-9 m.
TEST(ToolShadow, FallsIntoADrilledPitAsOnACarvedCopyOfTheWholeField) {
  datasets::GridSpec grid;  // 64^3 of 1 mm about the origin
  const Eigen::Vector3d c(0.3e-3, -0.2e-3, 0.1e-3);
  const double R = 0.020, pit_r = 0.005, pit_depth = 0.008;
  auto field = std::make_shared<const haptics::ScalarVolume>(datasets::makeSphereVolume(grid, c, R));
  const auto& g = field->geometry();
  std::vector<std::uint64_t> pit;
  for (int k = 0; k < g.dims[2]; ++k)
    for (int j = 0; j < g.dims[1]; ++j)
      for (int i = 0; i < g.dims[0]; ++i) {
        const Eigen::Vector3d p = g.origin_W_m + g.spacing_m.cwiseProduct(Eigen::Vector3d(i, j, k));
        if (field->voxel(i, j, k) > 0.0 && std::hypot(p.x() - c.x(), p.y() - c.y()) < pit_r &&
            p.z() > c.z() + R - pit_depth)
          pit.push_back(static_cast<std::uint64_t>(i + g.dims[0] * (j + g.dims[1] * k)));
      }
  ASSERT_GT(pit.size(), 300u);
  // Batches: the pit's lower half (by index: z grows with it), then its upper half but for a
  // core around the axis halfway down (the box grows: copied again), then that core (inside the
  // box already: written in place).
  const auto inCore = [&](std::uint64_t index) {
    const int i = static_cast<int>(index % 64), j = static_cast<int>((index / 64) % 64), k = static_cast<int>(index / 4096);
    const Eigen::Vector3d p = g.origin_W_m + g.spacing_m.cwiseProduct(Eigen::Vector3d(i, j, k));
    return std::hypot(p.x() - c.x(), p.y() - c.y()) < 0.002 && std::abs(p.z() - (c.z() + R - 0.003)) < 0.0011;
  };
  std::vector<std::uint64_t> first, second, core;
  for (std::size_t n = 0; n < pit.size(); ++n) {
    if (n < pit.size() / 2) first.push_back(pit[n]);
    else if (inCore(pit[n])) core.push_back(pit[n]);
    else second.push_back(pit[n]);
  }
  ASSERT_GT(core.size(), 5u);
  pit = first;  // in the order carved, for the dense copy
  pit.insert(pit.end(), second.begin(), second.end());
  pit.insert(pit.end(), core.begin(), core.end());

  std::vector<Eigen::Vector3d> samples_T;
  for (int i = -4; i <= 4; ++i)
    for (int j = -4; j <= 4; ++j) samples_T.emplace_back(i * 1.1e-3, j * 1.1e-3, 0.0);
  Pose X_WP;
  X_WP.p_AB_m = c + Eigen::Vector3d(0.0, 0.0, R + 0.004);
  const Eigen::Vector3d down(0, 0, -1), tilted = Eigen::Vector3d(0.3, -0.2, -1.0).normalized();

  CarvedRegion carved;
  carved.reset(field, first);
  const auto checkAgainstDenseCopy = [&](std::size_t removed, const char* stage) {
    haptics::ScalarVolume dense = *field;
    for (std::size_t n = 0; n < removed; ++n) dense.writeRaw(pit[n], field->lowestRaw());
    dense.refreshRegion({0, 0, 0}, {g.dims[0] - 1, g.dims[1] - 1, g.dims[2] - 1});
    for (const Eigen::Vector3d& d : {down, tilted}) {
      const ToolShadow expected = castToolShadow(dense, 0.0, X_WP, samples_T, d, 0.06);
      const ToolShadow got = castToolShadow(*field, carved, 0.0, X_WP, samples_T, d, 0.06);
      ASSERT_EQ(got.footprint_W_m.size(), expected.footprint_W_m.size()) << stage;
      for (std::size_t n = 0; n < got.footprint_W_m.size(); ++n)
        EXPECT_LT((got.footprint_W_m[n] - expected.footprint_W_m[n]).norm(), 1e-9) << stage << ", sample " << n;
      EXPECT_NEAR(got.gap_m, expected.gap_m, 1e-9) << stage;
    }
  };
  checkAgainstDenseCopy(first.size(), "lower half");
  std::uint64_t version = carved.version();
  carved.remove(second);
  EXPECT_GT(carved.version(), version);
  checkAgainstDenseCopy(first.size() + second.size(), "upper half but its core");
  version = carved.version();
  carved.remove(core);
  EXPECT_GT(carved.version(), version);
  EXPECT_EQ(carved.removedCount(), pit.size());
  checkAgainstDenseCopy(pit.size(), "whole pit");

  // Straight down over the pit's middle: onto its floor, not the ball's top.
  const std::vector<Eigen::Vector3d> middle_T{Eigen::Vector3d::Zero()};
  const ToolShadow into = castToolShadow(*field, carved, 0.0, X_WP, middle_T, down, 0.06);
  const ToolShadow onto = castToolShadow(*field, 0.0, X_WP, middle_T, down, 0.06);
  ASSERT_EQ(into.footprint_W_m.size(), 1u);
  ASSERT_EQ(onto.footprint_W_m.size(), 1u);
  const double floor_z = c.z() + R - pit_depth;
  EXPECT_NEAR(into.footprint_W_m[0].z(), floor_z, 1.0e-3) << "the pit's floor";
  EXPECT_NEAR(onto.footprint_W_m[0].z(), c.z() + R, 0.1e-3) << "the top, uncarved";
  std::cout << "shadow straight down: on the uncut top at z = " << onto.footprint_W_m[0].z() * 1e3
            << " mm, into the pit at " << into.footprint_W_m[0].z() * 1e3 << " mm (floor " << floor_z * 1e3 << ")\n";

  // On another field (a rebuilt felt field), or cleared: the plain cast.
  const auto other = std::make_shared<const haptics::ScalarVolume>(*field);
  EXPECT_NEAR(castToolShadow(*other, carved, 0.0, X_WP, middle_T, down, 0.06).footprint_W_m[0].z(), c.z() + R, 0.1e-3);
  carved.clear();
  EXPECT_EQ(carved.box(), nullptr);
  EXPECT_NEAR(castToolShadow(*field, carved, 0.0, X_WP, middle_T, down, 0.06).footprint_W_m[0].z(), c.z() + R, 0.1e-3);
}

// Farthest-point sampling of a 100 mm segment: both ends, and every vertex within a quarter of
// the length of a sample when five are taken (the covering radius, by brute force).
TEST(ToolShadow, SamplesSpreadOverTheWholeTool) {
  std::vector<Eigen::Vector3d> v;
  for (int i = 0; i <= 1000; ++i) v.emplace_back(0.1e-3 * i, 0.0, 0.0);
  const std::vector<Eigen::Vector3d> s = shadowSamples(v, 5);
  ASSERT_EQ(s.size(), 5u);
  const auto has = [&](double x) {
    return std::any_of(s.begin(), s.end(), [&](const Eigen::Vector3d& p) { return std::abs(p.x() - x) < 1e-12; });
  };
  EXPECT_TRUE(has(0.0));
  EXPECT_TRUE(has(0.1));
  double cover = 0.0;
  for (const Eigen::Vector3d& p : v) {
    double nearest = std::numeric_limits<double>::infinity();
    for (const Eigen::Vector3d& q : s) nearest = std::min(nearest, (p - q).norm());
    cover = std::max(cover, nearest);
  }
  EXPECT_LE(cover, 0.025 + 1e-12);
  EXPECT_EQ(shadowSamples(v, 2000).size(), v.size());
  const std::vector<Eigen::Vector3d> same(10, Eigen::Vector3d(1, 2, 3));
  EXPECT_EQ(shadowSamples(same, 5).size(), 1u);
  EXPECT_TRUE(shadowSamples(v, 0).empty());
}


std::vector<Eigen::Vector3d> pointsOf(vtkActor* actor) {
  std::vector<Eigen::Vector3d> out;
  auto* poly = vtkPolyData::SafeDownCast(actor->GetMapper()->GetInput());
  if (poly == nullptr || poly->GetPoints() == nullptr) return out;
  for (vtkIdType i = 0; i < poly->GetNumberOfPoints(); ++i) {
    double p[3];
    poly->GetPoint(i, p);
    out.emplace_back(p[0], p[1], p[2]);
  }
  return out;
}

// The window while drilling: the drill sinks 4 mm into the built-in ball (radius 20 mm about the
// origin), the burr stops and the tool is drawn 2 mm back up, inside its pit. Its shadow falls
// on the pit's walls and floor, as on the field the haptic threads carved (the oracle: that
// field itself, read once the threads stopped): every point the view shows is one of the cast
// on it, and some lie below the uncut surface, where the field as loaded has bone.
TEST(ToolShadow, InTheWindowItFallsIntoTheDrilledPit) {
  MainWindow window;
  window.setInteractive(false);
  window.resize(640, 480);
  window.show();
  runtime::SceneSpec spec = runtime::parseScene(R"({"volume": {"path": "builtin:sphere"}, "tool": {"mesh": "builtin:drill",
      "point_spacing_m": 0.001}, "coupling": {"linear_N_per_m": 400}, "device": {"kind": "simulated"},
      "drill": {"on": true, "burr_radius_m": 0.0025, "hardness": {"tissue": 0.3}}})", "drill.json", ".");
  QSignalSpy loaded(&window, &MainWindow::sceneLoaded);
  window.opener()->openScene(spec);
  ASSERT_TRUE(test::waitFor([&] { return loaded.count() > 0 && !window.opener()->loading(); }, 60000));
  runtime::Session& session = window.session();
  session.startHaptics();
  ASSERT_TRUE(session.hapticsRunning());
  Pose press = session.proxyPose();
  press.p_AB_m = Eigen::Vector3d(0.0, 0.0, 0.0125);
  session.simulatedDevice()->setPose(press);
  ASSERT_TRUE(test::waitFor([&] { return session.proxyPose().p_AB_m.z() < 0.0185; }, 30000))
      << "the burr's centre at z = " << session.proxyPose().p_AB_m.z() * 1e3 << " mm";
  session.setDrilling(false);
  Pose up = session.proxyPose();
  up.p_AB_m.z() += 0.002;
  session.simulatedDevice()->setPose(up);
  ASSERT_TRUE(test::waitFor([&] { return (session.proxyPose().p_AB_m - up.p_AB_m).norm() < 1e-4; }, 30000));
  test::pump(200);
  session.stopHaptics();
  window.drillController()->drain();
  test::pump(200);
  // The threads' last snapshot shown (not only whichever the display timer reached last), and the
  // shadow cast for it on the carved field.
  window.viewController()->refresh();
  window.viewController()->updateShadow();

  const haptics::ScalarVolume& carved_field = session.hapticThread()->drill()->removal().volume();
  const double iso = session.live().hapticIsovalue();
  const Pose X_WP = window.sceneView()->shownProxyPose();
  const Eigen::Vector3d d = window.sceneView()->shadowDirection_W();
  const auto& samples = window.viewController()->shadowSamples_T_m();
  const ToolShadow expected = castToolShadow(carved_field, iso, X_WP, samples, d);
  const ToolShadow uncut = castToolShadow(*session.live().hapticField(), iso, X_WP, samples, d);
  const double lift_m = 0.5 * carved_field.geometry().minSpacing();
  const std::vector<Eigen::Vector3d> shown = pointsOf(window.sceneView()->actors().shadowActor());
  ASSERT_EQ(shown.size(), expected.footprint_W_m.size());
  int below_uncut = 0;
  for (const Eigen::Vector3d& p : shown) {
    const Eigen::Vector3d on_surface = p + lift_m * d;
    double nearest = std::numeric_limits<double>::infinity();
    for (const Eigen::Vector3d& q : expected.footprint_W_m) nearest = std::min(nearest, (q - on_surface).norm());
    EXPECT_LT(nearest, 1e-6) << "a shadow point off the carved field at " << on_surface.transpose();
    below_uncut += on_surface.norm() < 0.020 - 1e-3;
  }
  std::cout << shown.size() << " shadow points, " << below_uncut << " below the uncut surface; the uncut field puts "
            << uncut.footprint_W_m.size() << " on it; the pit " << window.drillController()->carved().removedCount()
            << " voxels\n";
  EXPECT_GE(below_uncut, 3) << "the shadow falls into the pit";
  if (const char* shots = std::getenv("VH_UI_SHOTS_DIR"); shots != nullptr && *shots != '\0') {
    window.sceneView()->focusOn(*session.live().tool, X_WP);
    window.sceneView()->renderStill(true);
    window.grab().save(QString::fromLocal8Bit(shots) + "/shadow-in-pit.png");
  }
  EXPECT_GT(window.drillController()->carved().removedCount(), 20u);
}

// The window: the probe held above the built-in ball (radius 20 mm about the origin) casts its
// shadow along the light that turns with the camera; the drop line is the closed form's shortest
// ray from the tool's samples; it follows the camera when the view turns and the tool when a
// frame shows it elsewhere; the frame shows dark shadow pixels that the same frame without the
// shadow does not; the toggle hides it.
TEST(ToolShadow, TheWindowCastsItAlongTheCamerasDownOntoTheFeltBall) {
  test::ViewControllerHost host;
  host.controller = std::make_unique<ViewController>(host.session, *host.view, *host.panel, host.prefs);
  host.session.setScene(test::sphereProbeScene(), nullptr);
  ASSERT_TRUE(test::waitFor([&] { return host.view->widget()->renderer()->GetSize()[1] > 0; }, 20000));
  ToolFrame frame;
  frame.X_WP = frame.X_WD = Pose::FromTranslation(Eigen::Vector3d(3e-3, -2e-3, 31e-3));
  host.view->show(frame);  // casts it (SceneView::toolFrameShown)

  const SceneActors& actors = host.view->actors();
  const auto checkAgainstTheBall = [&](const char* when) {
    SCOPED_TRACE(when);
    const Eigen::Vector3d d = host.view->shadowDirection_W();
    const ViewCamera cam = host.view->camera();
    EXPECT_LT((d - (-cam.up_W() + 0.5 * cam.right_W() + 0.5 * cam.forward_W()).normalized()).norm(), 1e-9);
    double best = std::numeric_limits<double>::infinity();
    for (const Eigen::Vector3d& p_T : host.controller->shadowSamples_T_m()) {
      const std::optional<double> t = rayBall(frame.X_WP * p_T, d, Eigen::Vector3d::Zero(), 0.020);
      if (t.has_value()) best = std::min(best, *t);
    }
    ASSERT_TRUE(std::isfinite(best)) << "the closed form sees no shadow: a bad test pose";
    ASSERT_TRUE(actors.gapLineActor()->GetVisibility());
    ASSERT_TRUE(actors.shadowActor()->GetVisibility());
    const std::vector<Eigen::Vector3d> line = pointsOf(actors.gapLineActor());
    ASSERT_EQ(line.size(), 2u);
    // The drop line's end is lifted half a voxel (0.5 mm) back along d off the surface.
    EXPECT_NEAR((line[1] - line[0]).dot(d), best - 0.5e-3, 0.1e-3);
    EXPECT_LT(((line[1] - line[0]) - (line[1] - line[0]).dot(d) * d).norm(), 1e-9);
    for (const Eigen::Vector3d& p : pointsOf(actors.shadowActor())) {
      EXPECT_NEAR((p + 0.5e-3 * d).norm(), 0.020, 0.1e-3) << "a shadow point off the ball";
    }
  };
  checkAgainstTheBall("the opening view");
  EXPECT_GT(pointsOf(actors.shadowActor()).size(), 10u);
  EXPECT_FALSE(host.controller->updateShadow()) << "cast again with nothing changed";

  host.view->renderStill(true);
  const QImage with = host.view->widget()->grabFrame().convertToFormat(QImage::Format_RGB32);
  host.controller->setToolShadowVisible(false);
  EXPECT_FALSE(host.prefs.tool_shadow);
  EXPECT_FALSE(actors.shadowActor()->GetVisibility());
  EXPECT_FALSE(actors.gapLineActor()->GetVisibility());
  host.view->renderStill(true);
  const QImage without = host.view->widget()->grabFrame().convertToFormat(QImage::Format_RGB32);
  ASSERT_EQ(with.size(), without.size());
  int darker = 0;
  for (int y = 0; y < with.height(); ++y) {
    const auto* a = reinterpret_cast<const QRgb*>(with.constScanLine(y));
    const auto* b = reinterpret_cast<const QRgb*>(without.constScanLine(y));
    for (int x = 0; x < with.width(); ++x) darker += qGray(b[x]) - qGray(a[x]) > 60 ? 1 : 0;
  }
  EXPECT_GT(darker, 10) << "the shadow is not seen on the surface";

  host.controller->setToolShadowVisible(true);
  host.view->setStandardView(StandardView::kLeft);
  EXPECT_TRUE(host.controller->updateShadow()) << "the camera turned: a new down";
  checkAgainstTheBall("the left view");

  // A replayed tick shows the tool elsewhere through the same SceneView::show(): the shadow follows.
  frame.X_WP = frame.X_WD = Pose::FromTranslation(Eigen::Vector3d(-6e-3, 4e-3, 27e-3));
  host.view->show(frame);
  checkAgainstTheBall("the tool moved");
}

// Exported frames: the same shadow as the view, cast along the export camera's light at each
// record's isovalue, for each record shown; the look's tool_shadow switch hides it. Oracle: the
// closed-form ray-ball intersection from the tool's samples.
TEST(ToolShadow, ExportedFramesCastItAlongTheirCamerasLight) {
  const runtime::LoadedScene& scene = test::sphereProbeScene();
  const runtime::LiveValues live = runtime::LiveValues::initial(scene);
  const std::vector<Eigen::Vector3d> samples = toolShadowSamples(*scene.tool);
  ASSERT_FALSE(samples.empty());
  const auto recordAt = [](const Eigen::Vector3d& p_m) {
    runtime::TickRecord r;
    for (int a = 0; a < 3; ++a) r.p_WP_m[a] = r.p_WD_m[a] = p_m[a];
    r.isovalue = 0.0;
    return r;
  };
  for (const bool on : {true, false}) {
    SCOPED_TRACE(on ? "shadow on" : "shadow off");
    ViewLook look;
    look.tool_shadow = on;
    RecordingFrameRenderer frames(sceneActorsSpecFor(scene, live), 160, 120, look);
    frames.setShadow(live.hapticField(), live.hapticIsovalue(), samples);
    for (const Eigen::Vector3d& p : {Eigen::Vector3d(3e-3, -2e-3, 31e-3), Eigen::Vector3d(-6e-3, 4e-3, 27e-3)}) {
      frames.show(recordAt(p));
      // The light of the export camera, from its own vectors.
      vtkCamera* cam = frames.renderer()->GetActiveCamera();
      double pos[3], focal[3], up[3];
      cam->GetPosition(pos);
      cam->GetFocalPoint(focal);
      cam->GetViewUp(up);
      const Eigen::Vector3d forward = (Eigen::Vector3d(focal[0], focal[1], focal[2]) - Eigen::Vector3d(pos[0], pos[1], pos[2])).normalized();
      const Eigen::Vector3d right = forward.cross(Eigen::Vector3d(up[0], up[1], up[2])).normalized();
      const Eigen::Vector3d up_ortho = right.cross(forward);
      const Eigen::Vector3d d = (-up_ortho + 0.5 * right + 0.5 * forward).normalized();
      double best = std::numeric_limits<double>::infinity();
      for (const Eigen::Vector3d& p_T : samples) {
        const std::optional<double> t = rayBall(p + p_T, d, Eigen::Vector3d::Zero(), 0.020);
        if (t.has_value()) best = std::min(best, *t);
      }
      ASSERT_TRUE(std::isfinite(best)) << "the closed form sees no shadow: a bad test pose";
      EXPECT_EQ(static_cast<bool>(frames.actors().shadowActor()->GetVisibility()), on);
      EXPECT_EQ(static_cast<bool>(frames.actors().gapLineActor()->GetVisibility()), on);
      const std::vector<Eigen::Vector3d> line = pointsOf(frames.actors().gapLineActor());
      ASSERT_EQ(line.size(), 2u);
      EXPECT_NEAR((line[1] - line[0]).dot(d), best - 0.5e-3, 0.1e-3);
      EXPECT_GT(pointsOf(frames.actors().shadowActor()).size(), 10u);
    }
  }
}

// The clinician's case on the Philips head phantom (512 x 512 x 140, 400 HU): the built-in drill
// held 8 mm above the skull casts its shadow on the bone. Oracle: dense sampling of the felt field
// along the drop line (every 0.05 mm): outside up to the shadow point, inside 0.2 mm past it.
// Writes tool-shadow.png (the README's picture) when VH_UI_SHOTS_DIR is set.
TEST(ToolShadow, TheDrillHeldAboveTheSkullShadowsTheBone) {
  if (!fs::exists(test::kHeadPhantom)) GTEST_SKIP() << test::kHeadPhantom.string() << " is absent";
  MainWindow window;
  ASSERT_TRUE(test::openPhantomWithDrill(window));
  runtime::Session& session = window.session();
  session.startHaptics();
  ASSERT_TRUE(session.hapticsRunning());
  // Down from the free pose to 8 mm above where the burr's lowest point meets the skull.
  const haptics::ScalarVolume& field = *session.live().hapticField();
  const haptics::Pose start = session.proxyPose();
  // The burr (a 2.5 mm ball about the tool's origin) at its lowest point.
  const Eigen::Vector3d tip = start.p_AB_m - Eigen::Vector3d(0.0, 0.0, 0.0025);
  double contact_m = 0.0;
  while (contact_m < 0.15 && !field.isInside(tip - Eigen::Vector3d(0, 0, contact_m), 400.0)) contact_m += 1e-4;
  ASSERT_LT(contact_m, 0.15) << "no skull below the drill";
  haptics::Pose hover = start;
  hover.p_AB_m.z() -= contact_m - 0.008;
  window.sceneView()->focusOn(*session.live().tool, hover);
  session.simulatedDevice()->setPose(hover);
  ASSERT_TRUE(test::waitFor([&] { return (session.proxyPose().p_AB_m - hover.p_AB_m).norm() < 1e-4; }, 20000));
  test::pump(300);
  window.viewController()->refresh();

  const SceneActors& actors = window.sceneView()->actors();
  ASSERT_TRUE(actors.gapLineActor()->GetVisibility()) << "no shadow under a drill 8 mm above the skull";
  const std::vector<Eigen::Vector3d> line = pointsOf(actors.gapLineActor());
  ASSERT_EQ(line.size(), 2u);
  const Eigen::Vector3d d = window.sceneView()->shadowDirection_W();
  const double spacing = field.geometry().minSpacing();
  const Eigen::Vector3d hit = line[1] + 0.5 * spacing * d;  // the drawn end is lifted half a voxel
  const double length = (hit - line[0]).norm();
  EXPECT_GT(length, 0.005) << "the drill is 8 mm above the bone";
  for (double t = 0.0; t < length - 0.05e-3; t += 0.05e-3) {
    ASSERT_FALSE(field.isInside(line[0] + t * d, 400.0)) << "the drop line enters bone " << 1e3 * t << " mm along";
  }
  EXPECT_TRUE(field.isInside(hit + 0.2e-3 * d, 400.0) || field.isInside(hit + 0.4e-3 * d, 400.0))
      << "no bone just past the shadow point";
  if (const char* dir = std::getenv("VH_UI_SHOTS_DIR")) {
    window.sceneView()->renderStill(true);
    window.grab().save(QString::fromLocal8Bit(dir) + "/tool-shadow.png");
  }
  session.stopHaptics();
}

}  // namespace
}  // namespace vh::ui
