// Segments in the view: drawn through the scan on request (the Segments panel's "Show segments
// through the scan"), and "go to segment" putting the tool on it. The scene is the built-in
// sphere (radius 20 mm about the origin, F = 20 mm - r, isovalue 0) with the probe (a 2 mm ball
// tip at the origin of T, the shaft along +z); the segments are voxelised balls on its grid
// (test::ballSegmentation). Oracles: the balls' analytic centres and radii, projected through
// the view's camera (a perspective projection written here, the inverse of rayThroughPixel());
// the probe's analytic tip; the haptic thread's placement count.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <iostream>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <QCheckBox>
#include <QImage>
#include <QMainWindow>
#include <QSignalSpy>
#include <QStatusBar>
#include <QTableWidget>

#include <gtest/gtest.h>
#include <vtkActor.h>
#include <vtkProperty.h>

#include "ui_test_util.h"
#include "vh/haptics/point_shell.h"
#include "vh/runtime/scene.h"
#include "vh/runtime/session.h"
#include "vh/ui/devices/device_input.h"
#include "vh/ui/panels/segments_panel.h"
#include "vh/ui/preferences.h"
#include "vh/ui/proximity_alerts.h"
#include "vh/ui/segments_controller.h"
#include "vh/ui/view/device_manipulation.h"
#include "vh/ui/view/scene_frames.h"
#include "vh/ui/view/scene_view.h"
#include "vh/ui/view/segment_surfaces.h"
#include "vh/ui/view/vtk_view.h"

namespace vh::ui {
namespace {

/// A ball segment: its analytic centre in W and radius [m], its colour.
struct Ball {
  Eigen::Vector3d centre_W_m;
  double radius_m;
  std::string name;
  std::array<double, 3> rgb;
};

/// A segmentation on the sphere scan's grid with one segment per ball, each in a layer of its
/// own (they may overlap).
io::LoadedSegmentation ballsSegmentation(const std::vector<Ball>& balls) {
  const haptics::ScalarVolume& scan = *test::sphereProbeScene().volume.field;
  io::LoadedSegmentation seg;
  seg.source = "in-memory";
  for (std::size_t b = 0; b < balls.size(); ++b) {
    io::LoadedSegmentation one = test::ballSegmentation(scan, balls[b].centre_W_m, balls[b].radius_m);
    io::SegmentInfo info = one.segments.front();
    info.id = "Segment_" + std::to_string(b + 1);
    info.name = balls[b].name;
    info.color_rgb = balls[b].rgb;
    info.layer = static_cast<int>(b);
    seg.segments.push_back(info);
    seg.layers.push_back(one.layers.front());
  }
  return seg;
}

/// The main window's segment wiring: the scene view, the simulated device's input, the
/// Segments dock and its controller over a Session on the sphere scene, and the preferences.
struct SegmentsHost {
  SegmentsHost() {
    view = new SceneView(&window);
    window.setCentralWidget(view->widget());
    window.resize(760, 420);
    window.show();
    input = new DeviceInput(session, *view);  // owned by the view
    controller = new SegmentsController(session, *view, &window, window.statusBar(), prefs, input);
    test::pump(200);  // the dock laid out: the view's size as it stays
    const runtime::LoadedScene& scene = test::sphereProbeScene();
    session.setScene(scene, std::make_shared<runtime::SimulatedDevice>(scene.X_WT_initial));
    view->setScene(sceneActorsSpecFor(scene, runtime::LiveValues::initial(scene)), scene.X_WT_initial, prefs);
    view->setMarkerVisible(false);  // its red faces are no segment
  }
  ~SegmentsHost() { session.clear(); }

  /// Shows `balls` as the session's segments: all shown, those at `felt` felt.
  void setSegments(const std::vector<Ball>& balls, const std::vector<int>& felt) {
    std::vector<int> shown;
    for (int s = 0; s < static_cast<int>(balls.size()); ++s) shown.push_back(s);
    runtime::SegmentationSpec spec;
    spec.path = "in-memory";
    session.setSegments(std::make_shared<const runtime::SegmentSet>(ballsSegmentation(balls), felt, shown,
                                                                    std::vector<int>{}, 1.0),
                        spec);
  }

  QImage still() {
    view->renderStill(true);
    test::pump(100);
    // Best quality again for the frame grabbed: a still frame drawn meanwhile that took longer
    // than SceneActors' kStillSlowMs (3 s, a busy machine) steps the next still frames down.
    view->renderStill(true);
    return view->widget()->grabFrame();
  }

  Preferences prefs;
  runtime::Session session;
  QMainWindow window;  // owns the view, the input and the controller
  SceneView* view = nullptr;
  DeviceInput* input = nullptr;
  SegmentsController* controller = nullptr;
};

/// Where the perspective `camera` draws `p_W` [px, y down, (0, 0) the top-left corner]: the
/// inverse of rayThroughPixel().
Eigen::Vector2d project(const ViewCamera& camera, const Eigen::Vector3d& p_W) {
  const Eigen::Vector3d d = p_W - camera.position_W_m;
  const double z = d.dot(camera.forward_W());
  const double t = std::tan(0.5 * camera.view_angle_deg * std::acos(-1.0) / 180.0);
  const double u = d.dot(camera.right_W()) / (z * t), v = d.dot(camera.up_W()) / (z * t);
  const double h = camera.viewport_height_px, w = camera.viewport_width_px;
  return {0.5 * (u * h + w), 0.5 * (h - v * h)};
}

/// The radius [px] of the disk a ball of `radius_m` about `centre_W` fills in `camera`'s
/// picture when its centre is on the line of sight through the view's centre: the cone's
/// half-angle asin(r / d) on the view's plane.
double diskRadius_px(const ViewCamera& camera, const Eigen::Vector3d& centre_W, double radius_m) {
  const double d = (centre_W - camera.position_W_m).norm();
  const double t = std::tan(0.5 * camera.view_angle_deg * std::acos(-1.0) / 180.0);
  return 0.5 * camera.viewport_height_px * std::tan(std::asin(radius_m / d)) / t;
}

/// Whether `pixel` shows `rgb` (0..1): the same chromaticity (each channel's share of the sum
/// within 0.08, whatever the shading) and not dark.
bool showsColour(QRgb pixel, const std::vector<double>& rgb) {
  const double r = qRed(pixel), g = qGreen(pixel), b = qBlue(pixel), sum = r + g + b;
  const double ref = rgb[0] + rgb[1] + rgb[2];
  if (sum < 90.0 || ref <= 0.0) return false;
  return std::abs(r / sum - rgb[0] / ref) < 0.08 && std::abs(g / sum - rgb[1] / ref) < 0.08 &&
         std::abs(b / sum - rgb[2] / ref) < 0.08;
}

/// Pixels of `image` showing `rgb` within `inner_px` of `centre_px`, their share of the pixels
/// there, and the pixels showing it farther than `outer_px`.
struct DiskCount {
  double inside_share = 0.0;
  int outside = 0;
};
DiskCount countColour(const QImage& image, const std::vector<double>& rgb, const Eigen::Vector2d& centre_px,
                      double inner_px, double outer_px) {
  int inside = 0, inside_on = 0;
  DiskCount c;
  for (int y = 0; y < image.height(); ++y) {
    for (int x = 0; x < image.width(); ++x) {
      const double r = (Eigen::Vector2d(x + 0.5, y + 0.5) - centre_px).norm();
      const bool on = showsColour(image.pixel(x, y), rgb);
      if (r <= inner_px) {
        ++inside;
        inside_on += on;
      } else if (r > outer_px) {
        c.outside += on;
      }
    }
  }
  c.inside_share = inside > 0 ? static_cast<double>(inside_on) / inside : 0.0;
  return c;
}

TEST(SegmentsThroughScan, ABallInsideTheScanShowsItsDiskOnlyWhenAskedInThePanel) {
  SegmentsHost host;
  // A ball 6 mm in radius wholly inside the sphere (its farthest point 13.2 mm from the centre).
  const Ball ball{Eigen::Vector3d(0.006, 0.0, 0.004), 0.006, "nodule", {0.9, 0.3, 0.2}};
  host.setSegments({ball}, {});
  const SegmentSurfaces* surfaces = host.view->segmentSurfaces();
  ASSERT_NE(surfaces, nullptr);
  ASSERT_EQ(surfaces->shownSegments(), std::vector<int>{0});
  const std::vector<double> rgb = surfaces->colour(0);
  ASSERT_EQ(rgb.size(), 3u);
  // Only the scan and the segment in the picture.
  host.view->actors().proxyActor()->SetVisibility(false);
  host.view->setDeviceVisible(false);
  ASSERT_TRUE(host.view->frameSegment(0));
  const QImage off_image = host.still();
  // The camera as it drew that picture (the view's size included).
  const ViewCamera camera = host.view->camera();
  ASSERT_EQ(camera.viewport_width_px, off_image.width());
  ASSERT_EQ(camera.viewport_height_px, off_image.height());
  const Eigen::Vector2d centre_px = project(camera, ball.centre_W_m);
  const double radius_px = diskRadius_px(camera, ball.centre_W_m, ball.radius_m);
  ASSERT_GT(radius_px, 20.0) << "the framed ball is large enough to count";
  const double inner_px = 0.8 * radius_px, outer_px = 1.2 * radius_px + 2.0;

  // Off (the default): the scan's surface hides the ball.
  QCheckBox* box = host.controller->panel()->throughScanBox();
  ASSERT_NE(box, nullptr);
  EXPECT_FALSE(box->isChecked());
  EXPECT_FALSE(host.prefs.segments_through_scan);
  EXPECT_FALSE(box->toolTip().isEmpty());
  const DiskCount off = countColour(off_image, rgb, centre_px, inner_px, outer_px);
  std::cout << "[ through scan ] off: " << off.inside_share * 100.0 << " % of the disk, " << off.outside
            << " px outside\n";
  EXPECT_LT(off.inside_share, 0.01) << "the segment shows through the scan's surface";
  EXPECT_EQ(off.outside, 0);

  // On, ticked in the panel: the preference, the view, and the ball's disk where the camera
  // projects it.
  box->click();
  EXPECT_TRUE(host.prefs.segments_through_scan);
  EXPECT_TRUE(host.view->segmentsThroughScan());
  const DiskCount on = countColour(host.still(), rgb, centre_px, inner_px, outer_px);
  std::cout << "[ through scan ] on: " << on.inside_share * 100.0 << " % of the disk (radius " << radius_px
            << " px), " << on.outside << " px outside " << outer_px << " px\n";
  EXPECT_GT(on.inside_share, 0.95);
  EXPECT_LT(on.outside, 10);

  // Off again: hidden again.
  box->click();
  EXPECT_FALSE(host.prefs.segments_through_scan);
  EXPECT_LT(countColour(host.still(), rgb, centre_px, inner_px, outer_px).inside_share, 0.01);
}

TEST(SegmentsThroughScan, TheNearerSegmentHidesTheFartherOne) {
  SegmentsHost host;
  host.prefs.segments_through_scan = true;  // as remembered from an earlier session
  host.view->setScene(sceneActorsSpecFor(test::sphereProbeScene(), host.session.live()),
                      host.session.live().X_WT_initial, host.prefs);
  host.view->setMarkerVisible(false);
  // Seen from the front (anterior: the camera at -y): the red ball 14 mm nearer than the blue
  // one and 6 mm to the side; their disks overlap between their centres.
  const Ball near{Eigen::Vector3d(0.003, -0.007, 0.0), 0.005, "near", {0.9, 0.3, 0.2}};
  const Ball far{Eigen::Vector3d(-0.003, 0.007, 0.0), 0.005, "far", {0.2, 0.45, 1.0}};
  host.setSegments({near, far}, {});
  EXPECT_TRUE(host.view->segmentsThroughScan());
  host.view->actors().proxyActor()->SetVisibility(false);
  host.view->setDeviceVisible(false);
  host.view->setStandardView(StandardView::kAnterior);
  const QImage image = host.still();
  const ViewCamera camera = host.view->camera();
  ASSERT_GT(camera.forward_W().y(), 0.99);
  ASSERT_EQ(camera.viewport_width_px, image.width());
  const Eigen::Vector2d a = project(camera, near.centre_W_m), b = project(camera, far.centre_W_m);
  const std::vector<double> red = host.view->segmentSurfaces()->colour(0);
  const std::vector<double> blue = host.view->segmentSurfaces()->colour(1);
  const auto at = [&](const Eigen::Vector2d& p) { return image.pixel(static_cast<int>(p.x()), static_cast<int>(p.y())); };
  ASSERT_GT((a - b).norm(), 5.0);
  EXPECT_TRUE(showsColour(at(a), red)) << "the near ball's centre";
  EXPECT_TRUE(showsColour(at(0.5 * (a + b)), red)) << "where both disks lie, the near ball";
  EXPECT_TRUE(showsColour(at(b + 0.6 * (b - a).normalized() * diskRadius_px(camera, far.centre_W_m, far.radius_m)), blue))
      << "the far ball beyond the near one's disk";
}

/// The proxy's pose once the haptic threads have applied the last placement and the proxy
/// touches (null after 30 s).
std::optional<haptics::Pose> restingProxy(SegmentsHost& host) {
  runtime::HapticSnapshot snap;
  const bool rested = test::waitFor(
      [&] { return !host.input->touchInProgress() && host.session.latestSnapshot(snap) && snap.contacts > 0; },
      30000 * test::kSanitizerSlowdown);
  if (!rested) return std::nullopt;
  test::pump(300);  // the hand's steady push: the proxy settles
  host.session.latestSnapshot(snap);
  return snap.X_WP;
}

TEST(SegmentsGoTo, GoToSegmentPutsTheToolOnItAlongTheLineOfSightThroughItsCentre) {
  SegmentsHost host;
  // The felt "nodule" off the sphere's centre; "vessel" shown only, where the vertical line
  // through its centre passes 18 mm from the nodule's.
  const Ball nodule{Eigen::Vector3d(0.008, 0.002, 0.004), 0.006, "nodule", {0.9, 0.3, 0.2}};
  const Ball vessel{Eigen::Vector3d(-0.009, -0.004, 0.0), 0.005, "vessel", {0.2, 0.45, 1.0}};
  host.setSegments({nodule, vessel}, {0});
  ASSERT_TRUE(host.session.live().feltSegments());
  // Looking down the probe's shaft (tip down at the scene's pose): the tip on the line of sight.
  const haptics::Pose start = host.session.simulatedDevice()->pose();
  ASSERT_GT((start.R_AB * Eigen::Vector3d::UnitZ()).z(), 0.999) << "the probe's shaft is vertical";
  host.view->setStandardView(StandardView::kSuperior);

  // Haptics off: framed, the tool stays, and the status bar says why.
  EXPECT_EQ(host.controller->goToSegment(0), SegmentsController::GoTo::kFramedOnly);
  EXPECT_TRUE(host.window.statusBar()->currentMessage().contains("stays")) << host.window.statusBar()->currentMessage().toStdString();
  EXPECT_LT((host.session.simulatedDevice()->pose().p_AB_m - start.p_AB_m).norm(), 1e-15);

  host.session.startHaptics();
  ASSERT_TRUE(host.session.hapticsRunning());
  const runtime::HapticThread* thread = host.session.hapticThread();
  const std::uint64_t placements = thread->placementsApplied();
  // The vessel is not felt and its line of sight meets no felt surface: framed, nothing moves.
  EXPECT_EQ(host.controller->goToSegment(1), SegmentsController::GoTo::kNoSurface);
  EXPECT_TRUE(host.window.statusBar()->currentMessage().contains("no felt surface"));
  EXPECT_LT((host.session.simulatedDevice()->pose().p_AB_m - start.p_AB_m).norm(), 1e-15);

  // The nodule, through the panel's double-click: the tool rests on it.
  const double tip_before_m = (start.p_AB_m - nodule.centre_W_m).norm();
  ASSERT_GT(tip_before_m, 0.02) << "the probe starts far from the nodule";
  emit host.controller->panel()->table()->cellDoubleClicked(0, SegmentsPanel::kName);
  EXPECT_TRUE(host.window.statusBar()->currentMessage().contains("rests")) << host.window.statusBar()->currentMessage().toStdString();
  const std::optional<haptics::Pose> X_WP = restingProxy(host);
  ASSERT_TRUE(X_WP.has_value()) << "the tool never came to rest";
  EXPECT_EQ(thread->placementsApplied(), placements + 1) << "one placement, not the hand's motion";

  // Tolerance from the tool and the grid: the probe's shell samples its 2 mm tip every
  // `spacing`, and the felt surface of a voxelised ball lies within half a voxel (1 mm) of it.
  const haptics::PointShell& shell = host.session.live().tool->point_shell;
  const double spacing_m = shell.meanNearestNeighbourSpacing_m();
  const double tolerance_m = spacing_m + 0.5e-3;
  const ViewCamera camera = host.view->camera();
  const Eigen::Vector3d f = camera.forward_W();
  // The tip's centre (T's origin) on the line of sight through the nodule's centre, the tip
  // ball (2 mm) on the nodule's surface on the viewer's side.
  const Eigen::Vector3d tip_W = X_WP->p_AB_m;
  const Eigen::Vector3d off_W = tip_W - nodule.centre_W_m;
  const double lateral_m = (off_W - off_W.dot(f) * f).norm();
  double nearest_m = std::numeric_limits<double>::infinity();
  for (const Eigen::Vector3d& p_T : shell.points_T_m()) nearest_m = std::min(nearest_m, ((*X_WP) * p_T - nodule.centre_W_m).norm());
  std::cout << "[ go to segment ] tip " << lateral_m * 1e3 << " mm off the line; nearest shell point "
            << nearest_m * 1e3 << " mm from the nodule's centre (radius 6 mm); tolerance " << tolerance_m * 1e3
            << " mm (shell spacing " << spacing_m * 1e3 << " mm)\n";
  EXPECT_LT(lateral_m, tolerance_m);
  EXPECT_LT(off_W.dot(f), 0.0) << "on the viewer's side";
  EXPECT_NEAR(nearest_m, nodule.radius_m, tolerance_m);
  EXPECT_NEAR(off_W.norm(), nodule.radius_m + 0.002, tolerance_m);
  host.session.stopHaptics();
}

}  // namespace
}  // namespace vh::ui

namespace vh::ui {
namespace {

// The two sound boxes are remembered: ticking them sets the preferences, and a window opened
// with those preferences shows them ticked (the burr's sound then starts with the window).
TEST(SegmentsSounds, TheSoundBoxesAreRememberedInThePreferences) {
  SegmentsHost host;
  const auto box = [](SegmentsController& c, const QString& text) {
    for (QCheckBox* b : c.panel()->findChildren<QCheckBox*>())
      if (b->text() == text) return b;
    return static_cast<QCheckBox*>(nullptr);
  };
  QCheckBox* burr = box(*host.controller, "Burr sound");
  QCheckBox* alert = box(*host.controller, "Alert sounds (critical segment near or touched, technique)");
  ASSERT_NE(burr, nullptr);
  ASSERT_NE(alert, nullptr);
  EXPECT_FALSE(host.prefs.burr_sound);
  EXPECT_FALSE(host.prefs.alert_sound);
  burr->click();
  alert->click();
  EXPECT_TRUE(host.prefs.burr_sound);
  EXPECT_TRUE(host.prefs.alert_sound);

  QMainWindow other;
  SceneView* view = new SceneView(&other);
  other.setCentralWidget(view->widget());
  Preferences remembered = host.prefs;
  runtime::Session session;
  SegmentsController reopened(session, *view, &other, other.statusBar(), remembered, nullptr);
  EXPECT_TRUE(reopened.panel()->burrSound());
  EXPECT_TRUE(reopened.panel()->alertSound());
  box(reopened, "Burr sound")->click();
  EXPECT_FALSE(remembered.burr_sound);
  EXPECT_TRUE(host.prefs.burr_sound) << "each window writes its own preferences";
}

}  // namespace
}  // namespace vh::ui

namespace vh::ui {
namespace {

// Warnings before harm in the window: a snapshot's nearest critical distance against the
// segment's own thresholds (3 mm / 1.5 mm here, not the defaults) gives the level the view
// colours the tool with, a status line naming the structure and the distance, and a cue whose
// rate follows proximityCueRate_Hz(); leaving the warning distance stops the cue.
TEST(ProximityAlerts, TheSegmentsThresholdsColourTheToolNameTheDistanceAndPaceTheCue) {
  SegmentsHost host;
  const Ball nerve{Eigen::Vector3d(0.0, 0.0, 0.0), 0.004, "facial nerve", {0.9, 0.8, 0.2}};
  const auto plain = std::make_shared<const runtime::SegmentSet>(ballsSegmentation({nerve}), std::vector<int>{},
                                                                 std::vector<int>{0}, std::vector<int>{0}, 1.0);
  const auto set = plain->withThresholds({runtime::ProximityThresholds{3e-3, 1.5e-3}});
  ProximityAlerts alerts;
  QSignalSpy levels(&alerts, &ProximityAlerts::levelChanged);
  QSignalSpy messages(&alerts, &ProximityAlerts::message);
  QSignalSpy cues(&alerts, &ProximityAlerts::cueChanged);
  QObject::connect(&alerts, &ProximityAlerts::levelChanged, host.view,
                   [&](runtime::ProximityLevel level) { host.view->setToolProximity(static_cast<int>(level)); });
  const auto at = [&](double distance_m) {
    runtime::HapticSnapshot s;
    s.critical_segment = 0;
    s.critical_distance_m = distance_m;
    alerts.showSnapshot(s, set.get());
  };
  const auto toolColour = [&] {
    double rgb[3];
    host.view->actors().proxyActor()->GetProperty()->GetColor(rgb);
    return Eigen::Vector3d(rgb[0], rgb[1], rgb[2]);
  };
  const Eigen::Vector3d steel = toolColour();
  at(0.005);
  EXPECT_EQ(levels.count(), 0);
  EXPECT_EQ(messages.count(), 0);
  at(0.0025);  // inside 3 mm, outside 1.5 mm: a warning (the default 2 mm would not warn)
  ASSERT_EQ(levels.count(), 1);
  EXPECT_EQ(alerts.level(), runtime::ProximityLevel::kWarn);
  ASSERT_EQ(messages.count(), 1);
  EXPECT_EQ(messages.at(0).at(0).toString().toStdString(), "facial nerve 2.5 mm (warning within 3.0 mm)");
  ASSERT_EQ(cues.count(), 1);
  EXPECT_TRUE(cues.at(0).at(0).toBool());
  EXPECT_NEAR(cues.at(0).at(1).toDouble(), 2.0 + 8.0 * (1.0 - 2.5 / 3.0), 1e-9);
  const Eigen::Vector3d amber = toolColour();
  EXPECT_GT((amber - steel).norm(), 0.3) << "the warned tool looks different";
  at(0.001);
  EXPECT_EQ(alerts.level(), runtime::ProximityLevel::kAlarm);
  EXPECT_NE(alerts.text().find("ALARM within 1.5 mm"), std::string::npos) << alerts.text();
  EXPECT_GT(cues.last().at(1).toDouble(), cues.at(0).at(1).toDouble()) << "nearer: faster";
  const Eigen::Vector3d red = toolColour();
  EXPECT_GT(red.x(), red.y() + 0.5);
  EXPECT_GT((red - amber).norm(), 0.3);
  at(std::numeric_limits<double>::infinity());  // out of range
  EXPECT_EQ(alerts.level(), runtime::ProximityLevel::kClear);
  EXPECT_FALSE(cues.last().at(0).toBool()) << "the cue stops";
  EXPECT_LT((toolColour() - steel).norm(), 1e-12) << "back to the tool's own colour";
  // A tool colour chosen while warned waits for the warning to end.
  at(0.001);
  host.view->actors().setToolColour(0.1, 0.2, 0.3);
  EXPECT_LT((toolColour() - red).norm(), 1e-12);
  at(std::numeric_limits<double>::infinity());
  EXPECT_LT((toolColour() - Eigen::Vector3d(0.1, 0.2, 0.3)).norm(), 1e-12);
  // Without segments (or another scene's index), nothing is warned.
  runtime::HapticSnapshot stale;
  stale.critical_segment = 3;
  stale.critical_distance_m = 0.0;
  alerts.showSnapshot(stale, set.get());
  alerts.showSnapshot(stale, nullptr);
  EXPECT_EQ(alerts.level(), runtime::ProximityLevel::kClear);
  EXPECT_LT(proximityCueRate_Hz(0.0019, 0.002), proximityCueRate_Hz(0.0001, 0.002));
  EXPECT_DOUBLE_EQ(proximityCueRate_Hz(0.0, 0.002), 10.0);
  EXPECT_DOUBLE_EQ(proximityCueRate_Hz(0.002, 0.002), 2.0);
}

}  // namespace
}  // namespace vh::ui
