// "Never through" on real bone: the 10 mm ball (builtin:sphere) pushed onto the vault of the shared
// skull phantom at a high bone threshold (870 HU), from above at several places and speeds, in
// both detection modes. The issue's report: shell points were carried through the thin bone
// between ticks and the ball ended in the cranial cavity. Every tick is checked by the
// independent oracle (CrossingVerifier, each point's true arc sampled every 1/1000 voxel).
// Skipped with a message when the shared datasets are absent.
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <initializer_list>
#include <iostream>
#include <memory>

#include <gtest/gtest.h>

#include "runtime_test_support.h"
#include "vh/datasets/synthetic.h"
#include "vh/haptics/crossing_verifier.h"
#include "vh/haptics/haptic_renderer.h"
#include "vh/haptics/point_shell.h"
#include "vh/haptics/shell_fidelity.h"
#include "vh/haptics/tool_model.h"
#include "vh/runtime/placement.h"
#include "vh/runtime/scene.h"

namespace vh::runtime {
namespace {

namespace fs = std::filesystem;
using haptics::Pose;

class NeverThroughPhantom : public ::testing::TestWithParam<haptics::DetectionMode> {};
INSTANTIATE_TEST_SUITE_P(Modes, NeverThroughPhantom,
                         ::testing::Values(haptics::DetectionMode::kPaper, haptics::DetectionMode::kAccelerated),
                         [](const ::testing::TestParamInfo<haptics::DetectionMode>& p) {
                           return std::string(haptics::toString(p.param));
                         });

// Pushes the ball onto the vault at four places (those that meet bone) and three speeds;
// returns the ticks with a crossing over all runs.
int pushOntoTheVault(haptics::DetectionMode mode, haptics::SegmentTest test) {
  const SceneSpec spec = parseScene(
      R"({"volume": {"path": "ct/philips-head-phantom-bone", "isovalue": 870},
          "tool": {"mesh": "builtin:sphere", "point_spacing_m": 0.001}})",
      "vault.json", test::sourceDir());
  const LoadedScene scene = loadScene(spec);
  const auto& volume = scene.volume.field;
  const double s = scene.isovalue;
  const haptics::CrossingVerifier oracle(*volume, scene.tool->point_shell, 1e-3);
  const Pose above = poseAboveVolume(*volume, scene.tool->point_shell, Eigen::Quaterniond::Identity(), 0.005);
  int runs = 0, contacts = 0, total_crossings = 0;
  std::int64_t samples = 0;
  for (const Eigen::Vector2d& offset : {Eigen::Vector2d(0.0, 0.0), Eigen::Vector2d(0.02, 0.005),
                                       Eigen::Vector2d(-0.015, 0.02), Eigen::Vector2d(0.01, -0.03)}) {
    Pose start = above;
    start.p_AB_m.head<2>() += offset;
    const auto d = firstContactDistance(*volume, scene.tool->point_shell, start, -Eigen::Vector3d::UnitZ(), 0.3, s);
    if (!d) continue;
    start.p_AB_m.z() -= *d - 0.002;  // 2 mm above the vault
    for (const double speed_mm : {0.5, 2.0, 6.0}) {
      haptics::RendererOptions o;
      o.detection_mode = mode;
      o.segment_test = test;
      haptics::HapticRenderer r(volume, scene.tool, o, start, s);
      // Down 12 mm past the first contact (the vault is a few millimetres of bone), then held.
      const double travel = 0.014;
      const int ticks = static_cast<int>(travel / (speed_mm * 1e-3)) + 30;
      int crossing_ticks = 0, first = -1;
      for (int i = 0; i < ticks; ++i) {
        Pose X_WD = start;
        X_WD.p_AB_m.z() -= std::min(travel, speed_mm * 1e-3 * i);
        const auto out = r.tick(X_WD, s);
        contacts = std::max(contacts, out.stats.contacts);
        const auto c = oracle.check(r.lastMotion(), r.lastTimeOfContact(), s);
        samples += c.samples;
        if (c.crossing_points > 0 && crossing_ticks++ == 0) first = i;
      }
      if (test == haptics::SegmentTest::kExact) {
        EXPECT_EQ(crossing_ticks, 0) << "offset " << offset.transpose() << " m, " << speed_mm
                                     << " mm per tick: first crossing at tick " << first;
      }
      total_crossings += crossing_ticks;
      ++runs;
    }
  }
  EXPECT_GT(runs, 0) << "the ball met no bone at 870 HU";
  EXPECT_GT(contacts, 0);
  std::cout << toString(test) << ": " << runs << " approaches, " << samples << " oracle samples, up to " << contacts
            << " contacts, " << total_crossings << " ticks with a crossing\n";
  return total_crossings;
}

bool phantomPresent() { return fs::exists(test::sharedDatasets() / "ct" / "philips-head-phantom-bone"); }

TEST_P(NeverThroughPhantom, BallPushedOntoTheVaultAt870HUNeverEntersTheCranium) {
  if (!phantomPresent()) GTEST_SKIP() << "shared dataset absent: " << test::sharedDatasets() / "ct";
  EXPECT_EQ(pushOntoTheVault(GetParam(), haptics::SegmentTest::kExact), 0);
}

// The control: the earlier end-sample test carries points through the vault here, and the
// oracle reports it (so the check above can fail).
TEST(NeverThroughPhantomControl, TheEndSampleTestCrossesTheVault) {
  if (!phantomPresent()) GTEST_SKIP() << "shared dataset absent: " << test::sharedDatasets() / "ct";
  EXPECT_GT(pushOntoTheVault(haptics::DetectionMode::kAccelerated, haptics::SegmentTest::kEndSample), 0);
}


// The tool's surface, not its points: a dense sample of the tool mesh's own triangles (each
// cut into sub-triangles of about `spacing_m`, their corners kept), every sample moved epsilon
// into the tool along its triangle's normal (the surface may come within epsilon of the tool,
// as at its points). Independent of the renderer's point shell and of its neighbour graph.
haptics::PointShell denseSurface(const haptics::TriangleMesh& mesh, double spacing_m, double inset_m) {
  std::vector<Eigen::Vector3d> points;
  for (const auto& tri : mesh.triangles) {
    const Eigen::Vector3d& a = mesh.vertices_T_m[tri[0]];
    const Eigen::Vector3d& b = mesh.vertices_T_m[tri[1]];
    const Eigen::Vector3d& c = mesh.vertices_T_m[tri[2]];
    const Eigen::Vector3d n = (b - a).cross(c - a).normalized();
    const double longest = std::max({(b - a).norm(), (c - b).norm(), (a - c).norm()});
    const int m = std::max(1, static_cast<int>(std::ceil(longest / spacing_m)));
    for (int i = 0; i <= m; ++i)
      for (int j = 0; i + j <= m; ++j) {
        const double u = static_cast<double>(i) / m, v = static_cast<double>(j) / m;
        points.push_back(a + u * (b - a) + v * (c - a) - inset_m * n);
      }
  }
  return haptics::PointShell(std::move(points));
}

struct SurfaceRun {
  int approaches = 0, max_contacts = 0, edge_stops = 0;
  int point_crossing_ticks = 0;    // the renderer's own points (the guarantee per point)
  int surface_crossing_ticks = 0;  // a dense sample (inset by the reach-in depth) entered bone
  double reach_in_bound_m = 0.0;   // epsilon + a quarter of the point spacing [m]
  // Epsilon, the felt gap (the mesh's largest distance from the net of points and edges,
  // measured) and an eighth of the spacing: how far bone that must cross an edge to enter can
  // reach in between two poses the swept edge test checks.
  int bound_crossing_ticks = 0;
  double stated_bound_m = 0.0;
  int through = 0;                 // approaches whose ball centre ended beyond bone
};

// The 5 mm ball (a 2.5 mm radius sphere mesh, 1 mm point spacing) pushed onto the skull's vault
// at 870 HU from 16 directions (two cones about the superior axis, eight azimuths each), at
// `steps_m` per tick for 12 mm past the first contact, then held. Each run starts 2 mm before the
// vault meets the tool's surface. Every tick is checked by the point oracle (the shell's own
// points) and by a dense oracle of the tool's surface: 0.15 mm samples of the tool mesh's
// triangles, inset by epsilon plus a quarter of the point spacing (the edge test's sub-step),
// their paths sampled every 1/100 voxel. After each run, whether the ball's centre went through
// bone (its straight path from start to end, sampled every 0.05 mm).
SurfaceRun pushBallFrom16Directions(int edge_test, std::initializer_list<double> steps_m) {
  const SceneSpec spec = parseScene(R"({"volume": {"path": "ct/philips-head-phantom-bone", "isovalue": 870}})",
                                    "vault16.json", test::sourceDir());
  const LoadedScene scene = loadScene(spec);
  const auto& volume = scene.volume.field;
  const double s = scene.isovalue;
  constexpr double kRadius_m = 0.0025;
  haptics::PointShellOptions shell_options;
  shell_options.spacing_m = 1e-3;
  const auto tool = std::make_shared<const haptics::ToolModel>(
      haptics::makeToolModel(datasets::makeSphereMesh(kRadius_m, 4), shell_options));
  const auto& g = volume->geometry();
  const Eigen::Vector3d centre_W =
      g.origin_W_m + g.direction_W * (0.5 * g.spacing_m.cwiseProduct(Eigen::Vector3d(g.dims[0] - 1, g.dims[1] - 1, g.dims[2] - 1)));
  haptics::RendererOptions o;
  o.detection_mode = haptics::DetectionMode::kAccelerated;
  o.edge_test = edge_test;
  o.edge_test_swept = edge_test != 0;  // along each move as well as at its end
  const double epsilon_m = haptics::HapticRenderer(volume, tool, o, haptics::Pose{}, s).epsilon_m();
  SurfaceRun run;
  run.reach_in_bound_m = epsilon_m + 0.25 * shell_options.spacing_m;
  const haptics::PointShell near = denseSurface(tool->mesh_T, 1.5e-4, epsilon_m);
  const haptics::PointShell core = denseSurface(tool->mesh_T, 1.5e-4, run.reach_in_bound_m);
  const double felt_gap_m =
      haptics::measureShellFidelity(tool->mesh_T, tool->point_shell, haptics::makeShellEdges(tool->point_shell), 0.05e-3)
          .max_gap_m;
  run.stated_bound_m = epsilon_m + felt_gap_m + shell_options.spacing_m / 8.0;
  const haptics::PointShell bound_core = denseSurface(tool->mesh_T, 1.5e-4, run.stated_bound_m);
  const haptics::CrossingVerifier bound_oracle(*volume, bound_core, 1e-2);
  const haptics::CrossingVerifier points_oracle(*volume, tool->point_shell, 1e-2);
  const haptics::CrossingVerifier surface_oracle(*volume, core, 1e-2);
  for (const double tilt : {0.35, 0.7})
    for (int k = 0; k < 8; ++k)
      for (const double step_m : steps_m) {
        const double azimuth = (k + 0.5 * (tilt > 0.5)) * M_PI / 4.0;
        const Eigen::Vector3d out(std::sin(tilt) * std::cos(azimuth), std::sin(tilt) * std::sin(azimuth), std::cos(tilt));
        haptics::Pose start;
        start.p_AB_m = centre_W + 0.2 * out;
        // 2 mm before the vault meets the tool's surface (its dense samples; its points alone
        // would place bone between them).
        const auto d = firstContactDistance(*volume, near, start, -out, 0.4, s);
        if (!d) continue;
        start.p_AB_m -= (*d - 0.002) * out;
        haptics::HapticRenderer r(volume, tool, o, start, s);
        ++run.approaches;
        const double travel_m = 0.014;
        for (int i = 0; i < static_cast<int>(travel_m / step_m) + 30; ++i) {
          haptics::Pose X_WD = start;
          X_WD.p_AB_m -= std::min(travel_m, step_m * i) * out;
          const auto result = r.tick(X_WD, s);
          run.max_contacts = std::max(run.max_contacts, result.stats.contacts);
          run.edge_stops += result.stats.edge_stop;
          run.point_crossing_ticks += points_oracle.check(r.lastMotion(), r.lastTimeOfContact(), s).crossing_points > 0;
          const auto c = surface_oracle.check(r.lastMotion(), r.lastTimeOfContact(), s);
          if (c.crossing_points > 0 || c.started_inside > 0) ++run.surface_crossing_ticks;
          const auto b = bound_oracle.check(r.lastMotion(), r.lastTimeOfContact(), s);
          if (b.crossing_points > 0 || b.started_inside > 0) ++run.bound_crossing_ticks;
        }
        // Through the vault: the straight path of the ball's centre from start to end meets bone.
        const Eigen::Vector3d from = start.p_AB_m, to = r.proxyPose().p_AB_m;
        const int n = static_cast<int>(std::ceil((to - from).norm() / 5e-5)) + 1;
        for (int i = 0; i <= n; ++i)
          if (volume->isInside(from + (to - from) * (static_cast<double>(i) / n), s)) {
            ++run.through;
            break;
          }
      }
  std::cout << "edge test " << edge_test << ": " << run.approaches << " approaches, up to " << run.max_contacts
            << " contacts, " << run.edge_stops << " edge stops; ticks with a crossing: points " << run.point_crossing_ticks
            << ", surface (" << core.size() << " samples inset by " << run.reach_in_bound_m * 1e3 << " mm) "
            << run.surface_crossing_ticks << ", inset by the stated bound (" << run.stated_bound_m * 1e3 << " mm) "
            << run.bound_crossing_ticks << "; " << run.through << " through the vault\n";
  return run;
}

// With the edge test (here swept along each move) the ball never goes through the vault.
// Its surface is still reached by small pieces of bone during a move: bone that pierces a face of
// the net of points and edges, touching none of them, is not seen by the edge test however
// often it is tested (haptics/README.md, "Between the points"); the counts are printed, not
// asserted (at 0.278 mm inset 14 ticks swept, 52 at the move's end only; at epsilon, the felt
// gap and an eighth of the spacing, 4, all on free moves).
TEST(NeverThroughPhantomSurface, WithTheEdgeTestTheFiveMillimetreBallNeverGoesThroughTheVault) {
  if (!phantomPresent()) GTEST_SKIP() << "shared dataset absent: " << test::sharedDatasets() / "ct";
  const SurfaceRun run = pushBallFrom16Directions(1, {0.5e-3, 4e-3});
  EXPECT_GE(run.approaches, 24) << "most directions meet the vault";
  EXPECT_GT(run.max_contacts, 0);
  EXPECT_EQ(run.point_crossing_ticks, 0);
  EXPECT_EQ(run.through, 0);
}

// The control, the case as first reported: without the edge test no point's own path crosses,
// yet bone passes between the points, and the dense oracle sees it (so it can fail).
TEST(NeverThroughPhantomSurface, ControlWithoutTheEdgeTestBonePassesBetweenThePoints) {
  if (!phantomPresent()) GTEST_SKIP() << "shared dataset absent: " << test::sharedDatasets() / "ct";
  const SurfaceRun run = pushBallFrom16Directions(0, {4e-3});
  EXPECT_GE(run.approaches, 12) << "most directions meet the vault";
  EXPECT_EQ(run.point_crossing_ticks, 0);
  EXPECT_GT(run.surface_crossing_ticks, 0);
}

}  // namespace
}  // namespace vh::runtime
