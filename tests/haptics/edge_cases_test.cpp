// Edge cases a real scan and a real hand reach (oracles: the clean volume's own run, the
// analytic ball): an outlier voxel or a "no data" border must not change what the hand feels
// far from it; a probe pressed on a ball turns and slides at every point spacing.
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <functional>
#include <limits>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include "test_tools.h"
#include "vh/haptics/collision_detector.h"
#include "vh/haptics/crossing_verifier.h"
#include "vh/haptics/haptic_renderer.h"
#include "vh/haptics/penetration.h"

namespace vh::haptics {
namespace {

constexpr double kBallRadius_m = 0.010;
// A float ball as a scanner or a segmentation tool writes it: 64^3 voxels of 0.5 mm, F = the
// signed distance in mm (positive inside), isovalue 0.
std::vector<float> ballVoxels(VolumeGeometry& g) {
  g.dims = {64, 64, 64};
  g.spacing_m = Eigen::Vector3d::Constant(0.5e-3);
  g.origin_W_m = Eigen::Vector3d::Constant(-31.5 * 0.5e-3);
  std::vector<float> v(g.voxelCount());
  std::size_t i = 0;
  for (int z = 0; z < 64; ++z)
    for (int y = 0; y < 64; ++y)
      for (int x = 0; x < 64; ++x) {
        const Eigen::Vector3d p = g.origin_W_m + 0.5e-3 * Eigen::Vector3d(x, y, z);
        v[i++] = static_cast<float>(1e3 * (kBallRadius_m - p.norm()));
      }
  return v;
}

// One pose of a long-lived detector's edge test (`kept`, its certificates from the poses before)
// against two oracles: a detector built afresh at X (nothing kept) must give the same answer,
// and every edge that the dense samples (CrossingVerifier::checkEdges, 1/50 voxel) find
// entering over the move from `before` must be reported. `crosses`: kept's answer;
// `entering`: whether the dense samples found an edge entering; `fresh_work`: the fresh
// detector's work, added.
::testing::AssertionResult edgeTestAgreesWithOracles(CollisionDetector& kept, const ScalarVolume& volume,
                                                     const ToolModel& tool, const CrossingVerifier& oracle,
                                                     const Pose& before, const Pose& X, double isovalue, bool& crosses,
                                                     bool& entering, std::int64_t* fresh_work = nullptr) {
  crosses = kept.edgesCrossAt(X, isovalue);
  CollisionDetector fresh(volume, tool, 0.0);
  const bool fresh_crosses = fresh.edgesCrossAt(X, isovalue);
  if (fresh_work != nullptr) *fresh_work += fresh.work();
  if (crosses != fresh_crosses)
    return ::testing::AssertionFailure() << "kept says " << crosses << ", a fresh detector " << fresh_crosses;
  const CrossingVerifier::EdgeResult dense = oracle.checkEdges(RigidMotion::Between(before, X, tool.mass.p_TCm_m), 1.0,
                                                               isovalue, kept.shellEdges(), kept.epsilon_m());
  entering = dense.crossing_edges > 0;
  if (entering && !crosses)
    return ::testing::AssertionFailure() << "edge (" << dense.first_j << ", " << dense.first_k
                                         << ") enters the isosurface and was not reported";
  return ::testing::AssertionSuccess();
}

// The probe (2 mm ball tip at the origin of T, shaft along +z) with its tip `gap_m` above the
// ball's top (negative: pressed into it), turned by `angle` about the x axis through the tool's
// centre of mass over 500 ticks, then held 200 ticks. Returns the proxy's final rotation angle.
struct TurnResult {
  double proxy_angle_rad = 0.0;
  double max_torque_Nm = 0.0;
  int max_contacts = 0;
  double max_depth_m = 0.0;
};

TurnResult turnProbe(const std::shared_ptr<const ScalarVolume>& vol, double spacing_m, double gap_m, double angle,
                     bool about_tip = false, const Eigen::Vector3d& axis = Eigen::Vector3d::UnitX()) {
  const auto tool = test::meshTool(datasets::makeBuiltinTool("probe"), spacing_m);
  const Eigen::Vector3d cm_T = about_tip ? Eigen::Vector3d(0, 0, -0.002) : tool->mass.p_TCm_m;
  RendererOptions o;
  Pose X0;
  X0.p_AB_m = Eigen::Vector3d(0, 0, kBallRadius_m + 0.002 + 1e-3);
  HapticRenderer r(vol, tool, o, X0, 0.0);
  // The device: lowered from 1 mm above the ball to `gap_m` over 100 ticks, held 100 ticks,
  // then turned about Cm over 500 ticks and held 200.
  TurnResult result;
  Pose X_low = X0;
  X_low.p_AB_m.z() = kBallRadius_m + 0.002 + gap_m;
  const Eigen::Vector3d c_W = X_low * cm_T;
  for (int t = 0; t < 900; ++t) {
    const double u = t < 200 ? 0.0 : std::min(1.0, (t - 200) / 500.0);
    Pose X_WD;
    X_WD.R_AB = Eigen::Quaterniond(Eigen::AngleAxisd(angle * u, axis));
    X_WD.p_AB_m = c_W - X_WD.R_AB * cm_T;
    if (t < 100) X_WD.p_AB_m.z() += (1e-3 - gap_m) * (1.0 - t / 100.0);
    const TickOutput out = r.tick(X_WD, 0.0);
    result.max_torque_Nm = std::max(result.max_torque_Nm, out.torque_W_Nm.norm());
    result.max_contacts = std::max(result.max_contacts, out.stats.contacts);
    result.max_depth_m = std::max(result.max_depth_m, maxPenetration_m(*vol, tool->point_shell, out.X_WP, 0.0));
  }
  result.proxy_angle_rad = Eigen::AngleAxisd(r.proxyPose().R_AB).angle();
  return result;
}

TEST(EdgeCases, AnOutlierVoxelOrANoDataBorderLeavesTheRotationAsOnTheCleanVolume) {
  VolumeGeometry g;
  std::vector<float> v = ballVoxels(g);
  const auto clean = std::make_shared<const ScalarVolume>(ScalarVolume::FromVoxels(g, v));
  std::vector<float> w = v;
  w[w.size() - 1] = 1e30f;  // one far corner voxel
  const auto outlier = std::make_shared<const ScalarVolume>(ScalarVolume::FromVoxels(g, w));
  w = v;
  w[0] = 100.0f;  // the smallest freezing outlier
  const auto outlier100 = std::make_shared<const ScalarVolume>(ScalarVolume::FromVoxels(g, w));
  w = v;
  for (int z = 0; z < 64; ++z)
    for (int y = 0; y < 64; ++y)
      for (int x = 0; x < 64; ++x)
        if (x == 0 || y == 0 || z == 0 || x == 63 || y == 63 || z == 63) w[x + 64 * (y + 64 * z)] = -3e38f;
  const auto border = std::make_shared<const ScalarVolume>(ScalarVolume::FromVoxels(g, w));
  for (const double spacing : {0.5e-3, 1e-3}) {
    const TurnResult c = turnProbe(clean, spacing, 0.5e-3, 0.5);
    std::printf("hovering 0.5 mm, spacing %.1f mm: clean %.4f rad", spacing * 1e3, c.proxy_angle_rad);
    EXPECT_NEAR(c.proxy_angle_rad, 0.5, 0.005);
    EXPECT_EQ(c.max_contacts, 0);
    for (const auto& vol : {outlier, outlier100, border}) {
      const TurnResult d = turnProbe(vol, spacing, 0.5e-3, 0.5);
      std::printf(", %.4f rad (max torque %.3g N*m, contacts %d)", d.proxy_angle_rad, d.max_torque_Nm, d.max_contacts);
      EXPECT_NEAR(d.proxy_angle_rad, c.proxy_angle_rad, 0.01 * c.proxy_angle_rad);
      EXPECT_EQ(d.max_contacts, 0);
      EXPECT_LT(d.max_torque_Nm, 1e-6);
    }
    std::printf("\n");
  }
}

TEST(EdgeCases, AProbePressedOnABallTurnsAndSlidesAtEveryPointSpacing) {
  VolumeGeometry g;
  const auto vol = std::make_shared<const ScalarVolume>(ScalarVolume::FromVoxels(g, ballVoxels(g)));
  // The Haptics panel's range of spacings that give the probe a usable shell (0.1 mm is 200k
  // points); the renderer's epsilon is f / 8 = 31 um here.
  // Turned about the centre of mass (the tip slides over the ball), about the tip's lowest
  // point (the contact stays and rotates), and spun about the shaft.
  struct Turn {
    const char* name;
    bool about_tip;
    Eigen::Vector3d axis;
  };
  for (const Turn& turn : {Turn{"about Cm", false, Eigen::Vector3d::UnitX()}, Turn{"about the tip", true, Eigen::Vector3d::UnitX()},
                           Turn{"about the tip, oblique", true, Eigen::Vector3d(1, 1, 0).normalized()},
                           Turn{"spin", false, Eigen::Vector3d::UnitZ()}})
    for (const double spacing : {0.25e-3, 0.5e-3, 1e-3, 2e-3}) {
      // Spun about the shaft at 2 mm spacing the single contact creeps to a zero clearance
      // along the interpolant's bumps: without the lift after a stuck contact it stopped at
      // 0.43 of 0.5 rad.
      const TurnResult r = turnProbe(vol, spacing, -0.5e-3, 0.5, turn.about_tip, turn.axis);
      std::printf("pressed 0.5 mm, turned %s, spacing %.2f mm: proxy turned %.4f of 0.5 rad, %d contacts, depth %.2g m\n",
                  turn.name, spacing * 1e3, r.proxy_angle_rad, r.max_contacts, r.max_depth_m);
      EXPECT_GT(r.max_contacts, 0);
      // About the tip the held pose is tilted a little further than the device (the coupling's
      // energy is lower with Cm nearer the device's): 0.504-0.506 rad.
      EXPECT_NEAR(r.proxy_angle_rad, 0.5, turn.about_tip ? 0.01 : 0.002) << turn.name << ", spacing " << spacing;
      EXPECT_LT(r.max_depth_m, 0.5e-3 / 16);
    }
}

TEST(EdgeCases, TheCouplingTorqueGrowsPastPiWithoutReversing) {
  // Oracle: the device turned by theta about a fixed axis against a proxy held still: the
  // spring's torque is -k_ang (I_W / i) theta along the axis for every theta, past pi too.
  const auto tool = test::meshTool(datasets::makeBoxMesh({0.01, 0.01, 0.01}), 2e-3);  // I_W = i Id
  CouplingGains k;
  k.angular_Nm_per_rad = 0.5;
  VirtualCoupling coupling(k);
  const Eigen::Vector3d axis = Eigen::Vector3d(0.2, -0.3, 1.0).normalized();
  const Pose X_WP;
  for (int n = 0; n <= 400; ++n) {
    const double theta = 4.0 * n / 400.0;
    Pose X_WD;
    X_WD.R_AB = Eigen::Quaterniond(Eigen::AngleAxisd(theta, axis));
    X_WD.p_AB_m = tool->mass.p_TCm_m - X_WD.R_AB * tool->mass.p_TCm_m;  // turned about Cm
    const Wrench w = coupling.track(X_WP, X_WD, tool->mass);
    ASSERT_NEAR(w.torque_W_Nm.dot(axis), -k.angular_Nm_per_rad * theta, 1e-6) << "theta " << theta;
    ASSERT_LT(w.force_W_N.norm(), 1e-9);
  }
  // Back down from 4 rad to 0 the same way (the tracking follows both directions).
  for (int n = 400; n >= 0; --n) {
    const double theta = 4.0 * n / 400.0;
    Pose X_WD;
    X_WD.R_AB = Eigen::Quaterniond(Eigen::AngleAxisd(theta, axis));
    X_WD.p_AB_m = tool->mass.p_TCm_m - X_WD.R_AB * tool->mass.p_TCm_m;
    ASSERT_NEAR(coupling.track(X_WP, X_WD, tool->mass).torque_W_Nm.dot(axis), -k.angular_Nm_per_rad * theta, 1e-6);
  }
}

TEST(EdgeCases, APegHeldInItsHoleTwistedToFourRadiansNeverFlipsItsTorqueNorSnaps) {
  auto vol = std::make_shared<ScalarVolume>(datasets::makeBlockWithBlindHoleVolume(256, -0.004));
  PointShellOptions ps;
  ps.point_count = 1307;
  auto tool = std::make_shared<ToolModel>(makeToolModel(datasets::makeCylinderMesh(datasets::kPegRadius_m, 0.08, 64), ps));
  const double s = datasets::kBlockIsovalue;
  RendererOptions o;
  o.work_budget = 0;
  const Pose X_top = Pose::FromTranslation({0, 0, 0.02});
  HapticRenderer r(vol, tool, o, X_top, s);
  const Pose X_deep = Pose::FromTranslation({0, 0, -0.002});
  for (int t = 0; t < 1000; ++t) {
    Pose X = X_top;
    X.p_AB_m = X_top.p_AB_m + (X_deep.p_AB_m - X_top.p_AB_m) * std::min(1.0, t / 800.0);
    r.tick(X, s);
  }
  // Twisted about x (prying) through the device's centre of mass, 0 -> 4 rad over 2000 ticks.
  const Eigen::Vector3d c_W = X_deep * tool->mass.p_TCm_m;
  double worst_snap_rad = 0.0, largest_positive_torque = 0.0, torque_at_pi = 0.0, torque_at_end = 0.0;
  Eigen::Quaterniond last = r.proxyPose().R_AB;
  for (int t = 0; t <= 2000; ++t) {
    const double theta = 4.0 * t / 2000.0;
    Pose X_WD;
    X_WD.R_AB = Eigen::Quaterniond(Eigen::AngleAxisd(theta, Eigen::Vector3d::UnitX()));
    X_WD.p_AB_m = c_W - X_WD.R_AB * tool->mass.p_TCm_m;
    const TickOutput out = r.tick(X_WD, s);
    worst_snap_rad = std::max(worst_snap_rad, Eigen::AngleAxisd(out.X_WP.R_AB * last.conjugate()).angle());
    last = out.X_WP.R_AB;
    if (theta > 0.3) largest_positive_torque = std::max(largest_positive_torque, out.torque_W_Nm.x());
    if (std::abs(theta - std::numbers::pi) < 1e-3) torque_at_pi = out.torque_W_Nm.x();
    torque_at_end = out.torque_W_Nm.x();
    ASSERT_TRUE(out.torque_W_Nm.allFinite());
  }
  std::printf("twist to 4 rad: torque x at pi %.3f N*m, at 4 rad %.3f N*m, largest positive %.3g, largest proxy step %.4f rad\n",
              torque_at_pi, torque_at_end, largest_positive_torque, worst_snap_rad);
  EXPECT_LE(largest_positive_torque, 0.0);
  EXPECT_LT(torque_at_end, torque_at_pi);  // still growing past pi
  EXPECT_LT(worst_snap_rad, 0.01);
}

TEST(EdgeCases, LoweringTheIsovalueWhilePressingOnAThinPlateNeverLetsTheToolSinkOrPass) {
  // The one-voxel plate (255 in the slice k = 32 of 1 mm voxels, 0 elsewhere): at isovalue s its
  // solid is |z - z_k| < h (1 - s / 255) (the trilinear ramp, written here independently). A
  // 5 mm ball is pressed 2 mm onto it at s = 250 (a plate 0.04 mm thick) while the requested
  // isovalue drops to 10 (1.9 mm thick) over 200 ticks. Oracle: no shell point is ever inside
  // the plate at the isovalue the hand felt, nor below its mid-plane; lifted, the felt isovalue
  // reaches the requested one; pressed again, the ball rests on the thick plate.
  for (const DetectionMode mode : {DetectionMode::kPaper, DetectionMode::kAccelerated}) {
    auto vol = std::make_shared<const ScalarVolume>(datasets::makeThinPlateVolume(test::grid1mm()));
    const double z_k = vol->geometry().origin_W_m.z() + 32e-3, h = 1e-3;
    const auto tool = test::meshTool(datasets::makeBuiltinTool("sphere"), 1e-3);
    RendererOptions o;
    o.detection_mode = mode;
    o.work_budget = 0;
    const Pose above = Pose::FromTranslation({0.0003, 0.0002, z_k + 0.008});
    HapticRenderer r(vol, tool, o, above, 250.0);
    const Pose pressed = Pose::FromTranslation({0.0003, 0.0002, z_k + 0.005 - 0.002});
    double worst_depth_m = -1.0, lowest_felt = 250.0;
    const auto check = [&](const TickOutput& out, int tick) {
      const double half = h * (1.0 - out.stats.felt_isovalue / 255.0);
      for (const auto& p : tool->point_shell.points_T_m()) {
        const double z = (out.X_WP * p).z() - z_k;
        worst_depth_m = std::max(worst_depth_m, half - std::abs(z));
        ASSERT_GT(z, 0.0) << "tick " << tick << ": a point passed the plate's mid-plane";
      }
      lowest_felt = std::min(lowest_felt, out.stats.felt_isovalue);
    };
    int tick = 0;
    for (int t = 0; t < 300; ++t, ++tick) check(r.tick(t < 100 ? above : pressed, 250.0), tick);
    for (int t = 0; t <= 200; ++t, ++tick) check(r.tick(pressed, 250.0 - 240.0 * t / 200.0), tick);
    TickOutput out;
    for (int t = 0; t < 300; ++t, ++tick) check(out = r.tick(pressed, 10.0), tick);
    std::printf("%s: pressed while the isovalue dropped 250 -> 10: felt %.2f at the end, deepest point %.3g mm %s the felt plate\n",
                toString(mode), out.stats.felt_isovalue, std::abs(worst_depth_m) * 1e3, worst_depth_m > 0 ? "inside" : "outside");
    EXPECT_LE(worst_depth_m, 0.0);
    EXPECT_GT(out.stats.felt_isovalue, 200.0);  // the hand still presses on the thin plate
    // Lifted 8 mm: the felt isovalue follows the requested one; pressed again: the thick plate.
    for (int t = 0; t < 200; ++t, ++tick) check(out = r.tick(above, 10.0), tick);
    EXPECT_EQ(out.stats.felt_isovalue, 10.0);
    for (int t = 0; t < 400; ++t, ++tick) check(out = r.tick(pressed, 10.0), tick);
    EXPECT_LE(worst_depth_m, 0.0);
    const double ball_bottom = out.X_WP.p_AB_m.z() - 0.005 - z_k;
    EXPECT_NEAR(ball_bottom, h * (1.0 - 10.0 / 255.0), 0.1e-3);
    EXPECT_GT(out.force_W_N.z(), 0.5);
  }
}

TEST(EdgeCases, AnUprightProbeMovedEdgeOnIntoAThinPlateStopsAtItsEdge) {
  // The built-in one-voxel plate (slice k = 32 of 64^3 voxels of 1 mm, the grid's box ending at
  // x = 31.5 mm) at isovalue 250: 0.04 mm thick, far thinner than the probe's point spacing. The
  // upright probe (1 mm shaft radius) is moved sideways along -x from outside the grid into the
  // plate's edge, the plate crossing the shaft 20 mm above its tip at several heights between
  // shell points. Oracle (the plate's extent, written here): the shaft's axis stays outside the
  // plate by the shaft's radius (its 16-sided mesh: 0.98 mm), less epsilon and a margin.
  auto vol = std::make_shared<const ScalarVolume>(datasets::makeThinPlateVolume(test::grid1mm()));
  const double z_k = vol->geometry().origin_W_m.z() + 32e-3;
  const double edge_x = vol->geometry().origin_W_m.x() + 63e-3;
  int through_without = 0, through_with = 0, runs = 0;
  for (const double spacing : {1e-3, 2e-3}) {
    const auto tool = test::meshTool(datasets::makeBuiltinTool("probe"), spacing);
    for (int phase = 0; phase < 8; ++phase) {
      const double tip_z = z_k - 0.020 - phase * spacing / 8.0;
      double axis_x[2] = {0.0, 0.0};
      for (const int edge_test : {0, 1}) {
        RendererOptions o;
        o.edge_test = edge_test;
        HapticRenderer r(vol, tool, o, Pose::FromTranslation({edge_x + 0.008, 0.0003, tip_z}), 250.0);
        for (int t = 0; t < 400; ++t) {
          const double u = std::min(1.0, t / 300.0);
          r.tick(Pose::FromTranslation({edge_x + 0.008 - 0.030 * u, 0.0003, tip_z}), 250.0);
        }
        axis_x[edge_test] = r.proxyPose().p_AB_m.x();
      }
      ++runs;
      // Between the graph's edges a wall may reach in by an edge's sagitta on the shaft, at most
      // L^2 / (8 r) for edges of length L <= 1.8 x spacing (all of the radius at 2 mm spacing:
      // then only "never past the axis" is promised).
      const double r_shaft = 0.98e-3, L = 1.8 * spacing;
      const double limit = edge_x + r_shaft - std::min(r_shaft, L * L / (8.0 * r_shaft)) - 0.1e-3;
      through_without += axis_x[0] < edge_x - r_shaft;  // the plate cut through the whole shaft
      through_with += axis_x[1] < edge_x - r_shaft;
      EXPECT_GE(axis_x[1], limit) << "spacing " << spacing << ", phase " << phase;
      std::printf("spacing %.0f mm, phase %d: shaft axis %.3f mm from the plate's edge (without the edge test %.3f)\n",
                  spacing * 1e3, phase, (axis_x[1] - edge_x) * 1e3, (axis_x[0] - edge_x) * 1e3);
      EXPECT_LT(axis_x[1], edge_x + 1.5e-3) << "stopped too early";
    }
  }
  std::printf("probe edge-on into the plate at 250: through in %d of %d runs without the edge test, %d with it\n",
              through_without, runs, through_with);
  EXPECT_GT(through_without, 0);  // the case is real: the points alone let it through
}

TEST(EdgeCases, ASweptEdgeTestStopsAProbeAtAFinThatAMoveCouldCarryThroughItsShaft) {
  // A fin: the one-voxel plate of the test above (slice k = 32 of 64^3 voxels of 1 mm, 0.04 mm
  // thick at 250) cut to two voxel columns along x (i = 30, 31: about 1 mm long), so a move can
  // carry it into the probe's shaft between two rings of points and out again. The upright
  // probe is moved along -x across it in steps of 4 mm a tick (the free-space limit per tick),
  // from eight start offsets and at eight heights of the fin between rings. Oracle (the fin's
  // extent, written here): a proxy whose shaft axis ends past the fin's far side (x < 29 mm)
  // carried the fin through its shaft. Tested at the move's end only, the fin passes in some
  // runs (so the case is real); swept (the default), in none, and the shaft stops at the fin.
  VolumeGeometry g;
  g.dims = {64, 64, 64};
  g.spacing_m = Eigen::Vector3d::Constant(1e-3);
  g.origin_W_m = Eigen::Vector3d::Constant(-0.0315);  // centred, as test::grid1mm()
  std::vector<std::uint8_t> voxels(g.voxelCount(), 0);
  for (int j = 0; j < 64; ++j)
    for (int i = 30; i <= 31; ++i) voxels[static_cast<std::size_t>(i + 64 * (j + 64 * 32))] = 255;
  auto vol = std::make_shared<const ScalarVolume>(ScalarVolume::FromVoxels(g, voxels));
  const double z_k = g.origin_W_m.z() + 32e-3;
  const double fin_lo_x = g.origin_W_m.x() + 29e-3, fin_hi_x = g.origin_W_m.x() + 32e-3;
  const auto tool = test::meshTool(datasets::makeBuiltinTool("probe"), 1e-3);
  int through[2] = {0, 0}, runs = 0;
  for (int offset = 0; offset < 8; ++offset)
    for (int phase = 0; phase < 8; ++phase) {
      const double tip_z = z_k - 0.020 - phase / 8.0e3;
      const double start_x = fin_hi_x + 0.006 + offset * 0.5e-3;
      ++runs;
      for (const bool swept : {false, true}) {
        RendererOptions o;
        o.edge_test = 1;
        o.edge_test_swept = swept;
        HapticRenderer r(vol, tool, o, Pose::FromTranslation({start_x, 0.0003, tip_z}), 250.0);
        for (int t = 1; t <= 6; ++t) r.tick(Pose::FromTranslation({start_x - 0.004 * t, 0.0003, tip_z}), 250.0);
        const double axis_x = r.proxyPose().p_AB_m.x();
        through[swept] += axis_x < fin_lo_x;
        if (swept) {
          EXPECT_GE(axis_x, fin_hi_x - 1.1e-3) << "offset " << offset << ", phase " << phase << ": the shaft was not held";
        }
      }
    }
  std::printf("probe moved 4 mm a tick across a 1 mm fin: through in %d of %d runs tested at the move's end, %d swept\n",
              through[0], runs, through[1]);
  EXPECT_GT(through[0], 0) << "the case is real: a move carries the fin through the shaft";
  EXPECT_EQ(through[1], 0);
}

TEST(EdgeCases, TheEdgeTestSharesTheWorkBudgetAndStillGetsThrough) {
  // The upright probe moved edge-on into the one-voxel plate (as above, 1 mm spacing) and then
  // drawn back out, with the edge test under a work budget of a third of what its ticks take
  // unbudgeted (a quarter was less than one whole-graph test at the plate once the sweep's runs
  // along the plate were proven free by their direction). Oracles: the plate's extent (the shaft's axis stays kAxisClear_m outside its
  // edge at every tick), the tick's own work counter against the budget, the unbudgeted
  // run's stop at the plate (the budgeted proxy gets there too: a cut tick holds it where its
  // edges are proven free), and the device's pose once drawn back (the proxy follows it out:
  // cut ticks do not glue it to the wall).
  auto vol = std::make_shared<const ScalarVolume>(datasets::makeThinPlateVolume(test::grid1mm()));
  const double z_k = vol->geometry().origin_W_m.z() + 32e-3;
  const double edge_x = vol->geometry().origin_W_m.x() + 63e-3;
  const auto tool = test::meshTool(datasets::makeBuiltinTool("probe"), 1e-3);
  const double tip_z = z_k - 0.020 - 3e-3 / 8.0;
  // The shaft's radius (its 16-sided mesh: 0.98 mm) less 0.17 mm; the unbudgeted run stops with
  // its axis 0.91 mm outside the edge.
  constexpr double kAxisClear_m = 0.98e-3 - 0.0675e-3 - 0.1e-3;
  struct Run {
    double stop_x = 0.0, end_x = 0.0, device_x = 0.0;
    std::int64_t max_work = 0;
    int cut_ticks = 0;
  };
  const auto run = [&](std::int64_t budget) {
    RendererOptions o;
    o.edge_test = 1;
    o.work_budget = budget;
    // Steps of up to 4 mm in contact too, as the budget's case was built: the in-contact limit
    // halves the unbudgeted ticks' work, and with it the quarter budget, to less than one
    // whole-graph test at the plate.
    o.max_travel_in_contact_per_tick_m = 0.0;
    HapticRenderer r(vol, tool, o, Pose::FromTranslation({edge_x + 0.008, 0.0003, tip_z}), 250.0);
    Run result;
    for (int t = 0; t < 700; ++t) {
      // In to 22 mm past the edge over 300 ticks, held 100, out to the start over 200, held 100.
      const double u = t < 400 ? std::min(1.0, t / 300.0) : std::max(0.0, 1.0 - (t - 400) / 200.0);
      const Pose X_WD = Pose::FromTranslation({edge_x + 0.008 - 0.030 * u, 0.0003, tip_z});
      const TickOutput out = r.tick(X_WD, 250.0);
      result.max_work = std::max(result.max_work, out.stats.work);
      result.cut_ticks += out.stats.budget_cut;
      EXPECT_GE(out.X_WP.p_AB_m.x(), edge_x + kAxisClear_m) << "tick " << t;
      if (t == 399) result.stop_x = out.X_WP.p_AB_m.x();
      result.device_x = X_WD.p_AB_m.x();
    }
    result.end_x = r.proxyPose().p_AB_m.x();
    return result;
  };
  const Run free = run(0);
  const std::int64_t budget = free.max_work / 3;
  const Run budgeted = run(budget);
  std::printf("edge test unbudgeted: max work %lld a tick, stops %.3f mm from the edge; budget %lld: max work %lld, "
              "%d ticks cut, stops %.3f mm from the edge, %.3f mm from the device once drawn back\n",
              static_cast<long long>(free.max_work), 1e3 * (free.stop_x - edge_x), static_cast<long long>(budget),
              static_cast<long long>(budgeted.max_work), budgeted.cut_ticks, 1e3 * (budgeted.stop_x - edge_x),
              1e3 * std::abs(budgeted.end_x - budgeted.device_x));
  EXPECT_GT(budgeted.cut_ticks, 0) << "the budget never cut: the test does not exercise it";
  // One point's edges (at most 8 walks of a few cells) past the budget, and the sweep's own
  // overshoot of one queue step.
  EXPECT_LT(budgeted.max_work, budget + 400);
  EXPECT_NEAR(budgeted.stop_x, free.stop_x, 0.1e-3) << "the cut ticks kept the proxy from the wall";
  EXPECT_LT(std::abs(budgeted.end_x - budgeted.device_x), 0.1e-3) << "the proxy stuck to the wall";
  EXPECT_LT(std::abs(free.end_x - free.device_x), 0.1e-3);
}

// The edge test forked over several lanes (RendererOptions::solver_lanes) answers as on one:
// the crossing edge of the lowest-ranked part of the tree, once every part before it was
// walked, so the edge contacts, the stops and the proxy are those of one lane. Two runs that
// stop at edges: the upright probe moved edge-on into the one-voxel plate, and the 10 mm ball
// slid over the block's convex edges. Oracle: the one-lane run (the edge test's walk in the
// point-shell tree's order), tick by tick; unbudgeted, so that no lane's share is cut.
TEST(EdgeCases, TheEdgeTestOnSeveralLanesStopsWhereOneLaneStops) {
  struct Case {
    std::shared_ptr<const ScalarVolume> volume;
    std::shared_ptr<const ToolModel> tool;
    double isovalue;
    Pose start;
    std::function<Pose(int)> device;
    int ticks;
  };
  auto plate = std::make_shared<const ScalarVolume>(datasets::makeThinPlateVolume(test::grid1mm()));
  const double z_k = plate->geometry().origin_W_m.z() + 32e-3, edge_x = plate->geometry().origin_W_m.x() + 63e-3;
  const double tip_z = z_k - 0.020 - 3e-3 / 8.0;
  auto block = std::make_shared<const ScalarVolume>(datasets::makeBlockWithHoleVolume(128));
  const double z_top = datasets::kBlockHalfHeight_m;
  const std::vector<Case> cases = {
      {plate, test::meshTool(datasets::makeBuiltinTool("probe"), 1e-3), 250.0,
       Pose::FromTranslation({edge_x + 0.008, 0.0003, tip_z}),
       [=](int t) { return Pose::FromTranslation({edge_x + 0.008 - 0.030 * std::min(1.0, t / 300.0), 0.0003, tip_z}); },
       400},
      {block, test::meshTool(datasets::makeBuiltinTool("sphere"), 1e-3), datasets::kBlockIsovalue,
       Pose::FromTranslation({-0.030, 0.002, z_top + 0.006}),
       [=](int t) { return Pose::FromTranslation({-0.030 + 0.060 * std::min(1.0, t / 300.0), 0.002, z_top + 0.004}); },
       400}};
  for (std::size_t c = 0; c < cases.size(); ++c) {
    const Case& k = cases[c];
    RendererOptions one;
    one.edge_test = 1;
    one.work_budget = 0;
    one.solver_lanes = 1;
    HapticRenderer reference(k.volume, k.tool, one, k.start, k.isovalue);
    std::vector<Pose> path;
    std::vector<int> stops;
    int edge_stops = 0;
    for (int t = 0; t < k.ticks; ++t) {
      const TickOutput out = reference.tick(k.device(t), k.isovalue);
      path.push_back(out.X_WP);
      stops.push_back(out.stats.edge_stop);
      edge_stops += out.stats.edge_stop;
    }
    ASSERT_GT(edge_stops, 0) << "case " << c << ": no edge stopped the tool; the case does not test the edge test";
    for (const int lanes : {2, 3, 4}) {
      RendererOptions several = one;
      several.solver_lanes = lanes;
      HapticRenderer r(k.volume, k.tool, several, k.start, k.isovalue);
      for (int t = 0; t < k.ticks; ++t) {
        const TickOutput out = r.tick(k.device(t), k.isovalue);
        ASSERT_EQ(out.stats.edge_stop, stops[t] != 0) << "case " << c << ", " << lanes << " lanes, tick " << t;
        ASSERT_LT((out.X_WP.p_AB_m - path[t].p_AB_m).norm(), 1e-9) << "case " << c << ", " << lanes << " lanes, tick " << t;
        ASSERT_LT(out.X_WP.R_AB.angularDistance(path[t].R_AB), 1e-9) << "case " << c << ", " << lanes << " lanes, tick " << t;
      }
    }
    std::printf("case %zu: %d edge stops, the same on 2, 3 and 4 lanes\n", c, edge_stops);
  }
}

TEST(EdgeCases, ABallSlidOverABlocksConvexEdgesWithTheEdgeTestRidesOverThem) {
  // The block with a hole (0.5 mm voxels, +-24 mm wide, the hole +-8 mm): the 10 mm ball, its
  // device 1 mm below the top face, slid along +x from beside the block over its outer edge,
  // across the hole and off the far edge. Oracle: the geometry: past the far edge nothing holds
  // the ball, so the proxy ends where the device is; no point of the proxy is ever inside.
  auto vol = std::make_shared<const ScalarVolume>(datasets::makeBlockWithHoleVolume(128));
  const double s = datasets::kBlockIsovalue;
  const double z_top = datasets::kBlockHalfHeight_m;
  const auto tool = test::meshTool(datasets::makeBuiltinTool("sphere"), 1e-3);
  for (const double speed_mm : {0.2, 1.0}) {
    for (const int edge_test : {0, 1}) {
      SCOPED_TRACE(std::to_string(speed_mm) + " mm per tick, edge test " + std::to_string(edge_test));
      RendererOptions o;
      o.edge_test = edge_test;
      HapticRenderer r(vol, tool, o, Pose::FromTranslation({-0.030, 0.002, z_top + 0.006}), s);
      const int ticks = static_cast<int>(std::lround(60.0 / speed_mm));
      int max_contacts = 0, edge_stops = 0;
      double max_depth_m = 0.0;
      Pose X_WD;
      for (int t = 0; t < ticks + 200; ++t) {
        const double u = std::min(1.0, static_cast<double>(t) / ticks);
        X_WD = Pose::FromTranslation({-0.030 + 0.060 * u, 0.002, z_top + 0.004});
        const TickOutput out = r.tick(X_WD, s);
        max_contacts = std::max(max_contacts, out.stats.contacts);
        edge_stops += out.stats.edge_stop;
        max_depth_m = std::max(max_depth_m, maxPenetration_m(*vol, tool->point_shell, out.X_WP, s));
      }
      std::printf("ball over the block's edges at %.1f mm per tick, edge test %d: ends %.3f mm from the device, "
                  "%d edge stops, up to %d contacts, depth %.4f mm\n",
                  speed_mm, edge_test, 1e3 * (r.proxyPose().p_AB_m - X_WD.p_AB_m).norm(), edge_stops, max_contacts,
                  1e3 * max_depth_m);
      EXPECT_LT((r.proxyPose().p_AB_m - X_WD.p_AB_m).norm(), 0.5e-3) << "held on the way, at x = "
                                                                      << 1e3 * r.proxyPose().p_AB_m.x() << " mm";
      EXPECT_GT(max_contacts, 0);
      EXPECT_LE(max_depth_m, r.epsilon_m());
    }
  }
}

TEST(EdgeCases, EdgeClearanceCertificatesNeverHideACrossing) {
  // The edge test keeps, per shell point, the clearance its last walk proved for the point's
  // edges, and does not walk them again while the tool has moved them less than that. The
  // upright probe's 2 mm tip bobs through the surface (its lowest point from 0.35 mm into it to
  // 0.55 mm above, 100 poses a period) while wandering sideways (steps of 1 to 20 um, every
  // seventh up to 0.4 mm; every fifth pose turned up to 0.02 rad), over the one-voxel plate at
  // 250 and over the top of the float ball at 0. Oracles, at every pose: dense sampling of every
  // edge at the end of the move from the pose before (CrossingVerifier::checkEdges, 1/50 voxel):
  // an edge it finds entering must be reported; and a detector built afresh at that pose (no
  // certificates) must give the same answer. The certificates must also save work: the
  // long-lived detector's stays below the fresh ones'.
  VolumeGeometry ball_geometry;
  const std::vector<float> ball = ballVoxels(ball_geometry);
  auto plate = std::make_shared<const ScalarVolume>(datasets::makeThinPlateVolume(test::grid1mm()));
  const double plate_z = plate->geometry().origin_W_m.z() + 32e-3;
  const double plate_x = plate->geometry().origin_W_m.x() + 43e-3;  // 20 mm inside the grid
  struct Case {
    std::shared_ptr<const ScalarVolume> volume;
    double isovalue;
    Eigen::Vector3d surface_W_m;  // a point of the surface under the tip
  };
  const Case cases[] = {
      {plate, 250.0, {plate_x, 0.0, plate_z}},
      {std::make_shared<const ScalarVolume>(ScalarVolume::FromVoxels(ball_geometry, ball)), 0.0, {0.0, 0.0, kBallRadius_m}},
  };
  const auto tool = test::meshTool(datasets::makeBuiltinTool("probe"), 1e-3);
  constexpr double kTipRadius_m = 0.002;
  std::mt19937 rng(2027);
  std::uniform_real_distribution<double> U(-1.0, 1.0);
  int oracle_crossings = 0;
  for (const Case& c : cases) {
    CollisionDetector kept(*c.volume, *tool, 0.0);
    const CrossingVerifier oracle(*c.volume, tool->point_shell, 2e-2);
    int reported = 0, entered = 0, poses = 0;
    std::int64_t kept_work = 0, fresh_work = 0;
    Eigen::Vector2d sideways = Eigen::Vector2d::Zero();
    Pose X = Pose::FromTranslation(c.surface_W_m + Eigen::Vector3d(0, 0, kTipRadius_m + 0.55e-3));
    for (int step = 1; step <= 400; ++step, ++poses) {
      const Pose X_before = X;
      const double length_m = step % 7 == 0 ? 0.4e-3 * std::abs(U(rng)) : 2e-5 * std::abs(U(rng)) + 1e-6;
      sideways = (sideways + length_m * Eigen::Vector2d(U(rng), U(rng)).normalized()).cwiseMax(-2e-3).cwiseMin(2e-3);
      const double lowest_m = 0.1e-3 + 0.45e-3 * std::cos(2.0 * std::numbers::pi * step / 100.0);
      X.p_AB_m = c.surface_W_m + Eigen::Vector3d(sideways.x(), sideways.y(), kTipRadius_m + lowest_m);
      if (step % 5 == 0) {
        const Eigen::Quaterniond R =
            Eigen::Quaterniond(Eigen::AngleAxisd(0.02 * U(rng), Eigen::Vector3d(U(rng), U(rng), U(rng)).normalized())) *
            X.R_AB;
        if (Eigen::AngleAxisd(R).angle() < 0.1) X.R_AB = R.normalized();  // about upright
      }
      kept.resetSampleCount();
      bool crosses = false, entering = false;
      ASSERT_TRUE(edgeTestAgreesWithOracles(kept, *c.volume, *tool, oracle, X_before, X, c.isovalue, crosses, entering,
                                            &fresh_work))
          << "step " << step;
      kept_work += kept.work();
      entered += entering;
      reported += crosses;
    }
    oracle_crossings += entered;
    std::printf("isovalue %g: %d poses, %d with an edge crossing, %d entering (dense oracle); work %lld kept "
                "against %lld fresh (%.2fx)\n",
                c.isovalue, poses, reported, entered, static_cast<long long>(kept_work),
                static_cast<long long>(fresh_work), static_cast<double>(kept_work) / static_cast<double>(fresh_work));
    EXPECT_GT(reported, 40) << "the walk seldom met the surface between points";
    EXPECT_LT(static_cast<double>(kept_work), 0.8 * static_cast<double>(fresh_work)) << "no certificate was reused";
  }
  EXPECT_GT(oracle_crossings, 4);
}

TEST(EdgeCases, ABoxQueryCertificateHoldsForHalfAVoxelOfTravelOnly) {
  // Where the min-max tree proves the ball about a point's edges free (half a voxel larger than
  // they need), the edge test skips them until the point has moved half a voxel. A vertical
  // line of eight points 2 mm apart (one leaf of the point-shell tree) is held over the one-voxel plate (1.5 mm thick at 250) at
  // heights from 1 to 12 mm, then moved down in one move so that its lowest edge straddles the
  // plate, both its ends outside. Oracles: the dense samples of every edge
  // (CrossingVerifier::checkEdges) find it entering, and the detector that made its
  // certificates up there must report the crossing, as a fresh one does.
  auto plate = std::make_shared<const ScalarVolume>(datasets::makeThinPlateVolume(test::grid1mm()));
  const Eigen::Vector3d plate_W_m = plate->geometry().origin_W_m + Eigen::Vector3d(43e-3, 32e-3, 32e-3);
  std::vector<Eigen::Vector3d> points_T_m;
  for (int i = 0; i < 8; ++i) points_T_m.emplace_back(0.0, 0.0, 2e-3 * i);
  ToolModel line;
  line.point_shell = PointShell(points_T_m);
  const CrossingVerifier oracle(*plate, line.point_shell, 2e-2);
  // The lowest edge's middle on the plate's middle.
  const Pose down = Pose::FromTranslation(plate_W_m - Eigen::Vector3d(0.0, 0.0, 1e-3));
  ASSERT_FALSE(plate->isInside(down * points_T_m[0], 250.0));
  ASSERT_FALSE(plate->isInside(down * points_T_m[1], 250.0));
  int heights = 0;
  for (double lift_m = 1e-3; lift_m <= 12e-3 + 1e-9; lift_m += 0.2e-3, ++heights) {
    CollisionDetector kept(*plate, line, 0.0);
    const Pose up = Pose::FromTranslation(down.p_AB_m + Eigen::Vector3d(0.0, 0.0, lift_m));
    const bool crosses_up = kept.edgesCrossAt(up, 250.0);
    CollisionDetector fresh_up(*plate, line, 0.0);
    ASSERT_EQ(crosses_up, fresh_up.edgesCrossAt(up, 250.0)) << "lift " << 1e3 * lift_m << " mm";
    const CrossingVerifier::EdgeResult dense = oracle.checkEdges(RigidMotion::Between(up, down, line.mass.p_TCm_m), 1.0,
                                                                 250.0, kept.shellEdges(), kept.epsilon_m());
    ASSERT_GT(dense.crossing_edges, 0) << "the lowest edge straddles the plate";
    EXPECT_TRUE(kept.edgesCrossAt(down, 250.0)) << "lift " << 1e3 * lift_m << " mm: a certificate from up there hid "
                                                   "the crossing";
    CollisionDetector fresh(*plate, line, 0.0);
    EXPECT_TRUE(fresh.edgesCrossAt(down, 250.0));
  }
  EXPECT_EQ(heights, 56);
}

TEST(EdgeCases, AFieldThatRoseKeepsOnlyTheCertificatesWithMarginBeyondTheRise) {
  // The edge test's certificates when the field is rewritten and rises (deformable tissue):
  // told the most any voxel rose, a detector keeps the directional certificates whose margin
  // exceeds that rise and proves the others again. A line of eight points 4 mm apart along x
  // is held 1.5 mm over a plane (F = the signed distance in mm, isovalue 0; 1 mm voxels).
  // Oracle: the field sampled at the edge's middle and at its ends.
  datasets::GridSpec grid = test::grid1mm(48);
  std::vector<Eigen::Vector3d> points_T_m;
  for (int i = 0; i < 8; ++i) points_T_m.emplace_back(-14e-3 + 4e-3 * i, 0.0, 0.0);
  ToolModel line;
  line.point_shell = PointShell(points_T_m);
  const Pose X = Pose::FromTranslation({0.0, 0.0, 1.5e-3});
  const auto indexOf = [&](const ScalarVolume& v, const Eigen::Vector3d& p_W) {
    const Eigen::Vector3d g = v.gridCoordinates(p_W);
    return std::array<int, 3>{static_cast<int>(std::lround(g.x())), static_cast<int>(std::lround(g.y())),
                              static_cast<int>(std::lround(g.z()))};
  };
  // (a) The voxels about the middle of the edge between points 3 and 4 (x = -2 and 2 mm) rise
  // by 3: F there -1.5 + 3 > 0, the edge crosses, every point stays outside.
  {
    ScalarVolume plane = datasets::makePlaneVolume(grid, Eigen::Vector3d::UnitZ(), 0.0);
    CollisionDetector told(plane, line, 0.0), trusting(plane, line, 0.0);
    ASSERT_GT(told.shellEdges().size(), 0u);
    ASSERT_FALSE(told.edgesCrossAt(X, 0.0));
    ASSERT_FALSE(trusting.edgesCrossAt(X, 0.0));
    const std::array<int, 3> lo = indexOf(plane, X * Eigen::Vector3d(-0.5e-3, -0.5e-3, -1.0e-3));
    const std::array<int, 3> hi = indexOf(plane, X * Eigen::Vector3d(0.5e-3, 0.5e-3, 1.0e-3));
    for (int k = lo[2]; k <= hi[2]; ++k)
      for (int j = lo[1]; j <= hi[1]; ++j)
        for (int i = lo[0]; i <= hi[0]; ++i) {
          const std::size_t index = plane.geometry().indexOf(i, j, k);
          plane.writeRaw(index, plane.rawAt(index) + 3.0 / plane.valueScale());
        }
    plane.refreshRegion(lo, hi);
    ASSERT_GT(plane.sample(X * Eigen::Vector3d::Zero()), 0.0) << "the edge's middle is inside";
    for (const Eigen::Vector3d& p_T : points_T_m) ASSERT_LT(plane.sample(X * p_T), 0.0) << "every point outside";
    told.forgetFieldProofs(3.0);
    EXPECT_TRUE(told.edgesCrossAt(X, 0.0)) << "a certificate from before the rise hid the crossing";
    CollisionDetector fresh(plane, line, 0.0);
    EXPECT_TRUE(fresh.edgesCrossAt(X, 0.0));
    // The rise must not be understated: told 0, the old certificates hold and hide it.
    trusting.forgetFieldProofs(0.0);
    EXPECT_FALSE(trusting.edgesCrossAt(X, 0.0)) << "the certificates were not kept at all";
  }
  // (b) The whole field rises by 0.2 (F -1.3 at the line): no crossing, and the certificates,
  // with margins of about 1.5, hold: the told detector reads less than a fresh one.
  {
    ScalarVolume plane = datasets::makePlaneVolume(grid, Eigen::Vector3d::UnitZ(), 0.0);
    CollisionDetector told(plane, line, 0.0);
    ASSERT_FALSE(told.edgesCrossAt(X, 0.0));
    for (std::size_t index = 0; index < plane.geometry().voxelCount(); ++index)
      plane.writeRaw(index, plane.rawAt(index) + 0.2 / plane.valueScale());
    plane.refreshRegion({0, 0, 0}, {grid.dims[0] - 1, grid.dims[1] - 1, grid.dims[2] - 1});
    told.forgetFieldProofs(0.2);
    told.resetSampleCount();
    EXPECT_FALSE(told.edgesCrossAt(X, 0.0));
    const std::int64_t told_work = told.work();
    CollisionDetector fresh(plane, line, 0.0);
    fresh.resetSampleCount();
    EXPECT_FALSE(fresh.edgesCrossAt(X, 0.0));
    std::printf("after a rise of 0.2: the told detector's edge test %lld work, a fresh one's %lld\n",
                static_cast<long long>(told_work), static_cast<long long>(fresh.work()));
    EXPECT_LT(told_work, fresh.work()) << "no certificate was kept";
    // Told nothing (an unknown rise), it proves them all again.
    told.forgetFieldProofs();
    told.resetSampleCount();
    EXPECT_FALSE(told.edgesCrossAt(X, 0.0));
    EXPECT_GT(told.work(), told_work) << "certificates outlived an unknown rise";
  }
}

TEST(EdgeCases, AGlidingToolsEdgeTestAsksOnlyWhereTheSurfaceMayHaveMoved) {
  // The edge test lets a node of the point-shell tree through without a box query where its
  // last walk found a point near the surface below it. A 20 x 20 x 2 mm plate (0.7 mm point
  // spacing) glides 0.3 mm over a plane, 0.3 mm a test: after the first test, the nodes along
  // the plane are not asked again. Lifted 20 mm, the nodes let through find nothing near, and
  // the root is culled by its own query again. Oracle: a detector built afresh at each pose
  // (nothing kept) gives the same answer.
  const ScalarVolume plane = datasets::makePlaneVolume(test::grid1mm(), Eigen::Vector3d::UnitZ(), 0.0);
  const auto plate = test::meshTool(datasets::makeBoxMesh({0.01, 0.01, 0.001}), 0.7e-3);
  ASSERT_GT(plate->point_shell.size(), 1000u);
  CollisionDetector kept(plane, *plate, 0.0);
  std::vector<std::int64_t> queries;
  Pose X = Pose::FromTranslation({-0.006, 0.0, 0.001 + 0.0003});
  const auto test_at = [&](const Pose& next) {
    X = next;
    kept.resetSampleCount();
    const bool crosses = kept.edgesCrossAt(X, 0.0);
    queries.push_back(kept.boxQueryCount());
    CollisionDetector fresh(plane, *plate, 0.0);
    EXPECT_EQ(crosses, fresh.edgesCrossAt(X, 0.0)) << "test " << queries.size();
    EXPECT_FALSE(crosses) << "0.3 mm over the plane";
  };
  for (int i = 0; i < 30; ++i) test_at(Pose::FromTranslation(X.p_AB_m + Eigen::Vector3d(0.0003, 0.0, 0.0)));
  // Where every point's certificate still holds, only the root and the nodes that the walk
  // last found clear are asked; elsewhere the points whose certificates ran out ask their own.
  const std::int64_t first = queries.front();
  std::int64_t later_min = first, later_sum = 0;
  for (std::size_t i = 1; i < queries.size(); ++i) {
    later_min = std::min(later_min, queries[i]);
    later_sum += queries[i];
  }
  for (const std::int64_t q : queries) std::printf(" %lld", static_cast<long long>(q));
  std::printf("\nedge test gliding: box queries first %lld, later at least %lld, %lld in all\n",
              static_cast<long long>(first), static_cast<long long>(later_min), static_cast<long long>(later_sum));
  EXPECT_GT(first, 1000);
  EXPECT_LE(later_min, 10) << "the walk asked again about the nodes near the surface";
  EXPECT_LT(later_sum, 10 * first) << "the walk asked again about the nodes near the surface";
  for (int i = 0; i < 3; ++i) test_at(Pose::FromTranslation(X.p_AB_m + Eigen::Vector3d(0.0003, 0.0, i == 0 ? 0.02 : 0.0)));
  std::printf("lifted: box queries %lld, %lld, %lld\n", static_cast<long long>(queries[queries.size() - 3]),
              static_cast<long long>(queries[queries.size() - 2]), static_cast<long long>(queries.back()));
  EXPECT_LE(queries.back(), 2) << "the lifted plate was not culled at the root again";

  // Into a one-voxel wall (test::floorAndWallVolume(), i = 40, its isosurface 1 mm thick at
  // 128) that passes between the points of a 12 x 12 x 1 mm plate at 1.5 mm spacing, gliding 0.3 mm over the
  // floor in steps of 0.25 mm: the same answer as a fresh detector at every pose, and every
  // edge that the dense oracle (CrossingVerifier::checkEdges, 1/50 voxel) finds entering is
  // reported.
  const ScalarVolume wall = test::floorAndWallVolume();
  const auto coarse = test::meshTool(datasets::makeBoxMesh({0.006, 0.006, 0.0005}), 1.5e-3);
  CollisionDetector walled(wall, *coarse, 0.0);
  const CrossingVerifier oracle(wall, coarse->point_shell, 2e-2);
  int crossing = 0, entering = 0;
  Pose before = Pose::FromTranslation({20e-3, 12e-3, 20.5e-3 + 0.0005 + 0.0003});
  for (double x_m = 20e-3; x_m <= 50e-3 + 1e-9; x_m += 0.25e-3) {
    const Pose at = Pose::FromTranslation({x_m, 12e-3, 20.5e-3 + 0.0005 + 0.0003});
    bool crosses = false, entered = false;
    ASSERT_TRUE(edgeTestAgreesWithOracles(walled, wall, *coarse, oracle, before, at, 128.0, crosses, entered))
        << "x " << 1e3 * x_m << " mm";
    entering += entered;
    crossing += crosses;
    before = at;
  }
  std::printf("into the wall: %d poses with an edge crossing, %d entering (dense oracle)\n", crossing, entering);
  EXPECT_GE(entering, 4);
  ::testing::Test::RecordProperty("first_box_queries", static_cast<int>(first));
  ::testing::Test::RecordProperty("later_box_queries_total", static_cast<int>(later_sum));
}

TEST(EdgeCases, TheEdgeTestCountsWhatItDidWithEachPoint) {
  // CollisionDetector::edgeTestCounts(), against the plate's geometry: a 20 x 20 x 2 mm plate
  // (0.7 mm spacing) 0.3 mm over a plane. Its bottom face's points are 0.3 mm from the surface,
  // nearer than any of their edges reach, so no box query can clear them: a fresh detector
  // walks at least every bottom point that has edges, and holds none (it has no certificates).
  // At the same pose again their certificates hold and nothing is walked; lifted 20 mm, the
  // root's own box query clears everything and no point is reached.
  const ScalarVolume plane = datasets::makePlaneVolume(test::grid1mm(), Eigen::Vector3d::UnitZ(), 0.0);
  const auto plate = test::meshTool(datasets::makeBoxMesh({0.01, 0.01, 0.001}), 0.7e-3);
  const ShellEdges edges = makeShellEdges(plate->point_shell);
  std::int64_t bottom_with_edges = 0;
  for (std::size_t j = 0; j < plate->point_shell.size(); ++j)
    bottom_with_edges += plate->point_shell.points_T_m()[j].z() < -0.001 + 1e-6 && edges.offsets[j + 1] > edges.offsets[j];
  ASSERT_GT(bottom_with_edges, 100);
  const Pose X = Pose::FromTranslation({0.0, 0.0, 0.001 + 0.0003});
  CollisionDetector detector(plane, *plate, 0.0);
  detector.resetSampleCount();
  EXPECT_FALSE(detector.edgesCrossAt(X, 0.0));
  const EdgeTestCounts first = detector.edgeTestCounts();
  std::printf("fresh: held %lld, boxed %lld, walked %lld (%lld edges); bottom points with edges %lld, edges %zu\n",
              static_cast<long long>(first.points_held), static_cast<long long>(first.points_boxed),
              static_cast<long long>(first.points_walked), static_cast<long long>(first.edges_walked),
              static_cast<long long>(bottom_with_edges), edges.size());
  EXPECT_EQ(first.points_held, 0);
  EXPECT_GE(first.points_walked, bottom_with_edges);
  EXPECT_GE(first.edges_walked, first.points_walked);
  EXPECT_LE(first.edges_walked, static_cast<std::int64_t>(edges.size()));
  detector.resetSampleCount();
  EXPECT_FALSE(detector.edgesCrossAt(X, 0.0));
  const EdgeTestCounts again = detector.edgeTestCounts();
  EXPECT_EQ(again.points_walked, 0);
  EXPECT_EQ(again.edges_walked, 0);
  EXPECT_GE(again.points_held, bottom_with_edges);
  CollisionDetector lifted(plane, *plate, 0.0);
  EXPECT_FALSE(lifted.edgesCrossAt(Pose::FromTranslation({0.0, 0.0, 0.02}), 0.0));
  const EdgeTestCounts far = lifted.edgeTestCounts();
  EXPECT_EQ(far.points_held + far.points_boxed + far.points_walked + far.edges_walked, 0);
}

TEST(EdgeCases, ADirectionalCertificateExpiresBeforeItsEdgesLeaveTheBoxItKnows) {
  // The exact walk's directional certificate bounds F's rise by the range of F's derivatives
  // near the edges, so a move along a flat floor (dF/dx = 0 there) raises nothing it knows of;
  // the range says nothing two voxels on. A line of three points 3 mm apart along x, 0.2 mm
  // over a floor (a 1 mm uint8 grid, 255 up to k = 20, the surface at 20.5 at 128), slides
  // along x in steps of 0.25 mm into a one-voxel wall (i = 40, up to k = 30) that passes
  // between its points. Oracles: the dense samples of every edge (CrossingVerifier::checkEdges)
  // and a detector built afresh at each pose; the long-lived detector, which proved the edges
  // free far from the wall, must report the same crossings.
  const ScalarVolume floor_and_wall = test::floorAndWallVolume();
  ToolModel line;
  line.point_shell = PointShell({{0.0, 0.0, 0.0}, {3e-3, 0.0, 0.0}, {6e-3, 0.0, 0.0}});
  const CrossingVerifier oracle(floor_and_wall, line.point_shell, 2e-2);
  CollisionDetector kept(floor_and_wall, line, 0.0);
  int crossing = 0, entering = 0;
  std::int64_t kept_work = 0, fresh_work = 0;
  Pose before = Pose::FromTranslation(Eigen::Vector3d(6e-3, 12e-3, 20.7e-3));
  for (double x_m = 6e-3; x_m <= 45e-3 + 1e-9; x_m += 0.25e-3) {
    const Pose X = Pose::FromTranslation(Eigen::Vector3d(x_m, 12e-3, 20.7e-3));
    kept.resetSampleCount();
    bool crosses = false, entered = false;
    ASSERT_TRUE(edgeTestAgreesWithOracles(kept, floor_and_wall, line, oracle, before, X, 128.0, crosses, entered,
                                          &fresh_work))
        << "x " << 1e3 * x_m << " mm";
    kept_work += kept.work();
    entering += entered;
    crossing += crosses;
    before = X;
  }
  std::printf("%d poses with an edge crossing, %d entering (dense oracle); work %lld kept against %lld fresh\n",
              crossing, entering, static_cast<long long>(kept_work), static_cast<long long>(fresh_work));
  EXPECT_GE(crossing, 16) << "the wall never passed between the points";
  EXPECT_GE(entering, 1);
  EXPECT_LT(static_cast<double>(kept_work), 0.8 * static_cast<double>(fresh_work)) << "no certificate was reused";
}

TEST(EdgeCases, ANewIsovalueDropsTheDirectionalCertificates) {
  // Certificates hold for the isovalue they were proven at. A line of points 3 mm apart lies
  // across the top of the floor-and-wall volume's one-voxel wall (points at x = 38, 41, 44 mm,
  // 0.6 mm above the wall's top voxel, where F = 0.4 x 255 = 102 at x = 40): at 128 its edges
  // are walked (the ball about them holds the wall's top) and proven free with a margin; at
  // 100, not moved, the wall enters the first edge, its ends still outside, as a fresh
  // detector says.
  const ScalarVolume floor_and_wall = test::floorAndWallVolume();
  ToolModel line;
  line.point_shell = PointShell({{0.0, 0.0, 0.0}, {3e-3, 0.0, 0.0}, {6e-3, 0.0, 0.0}});
  const Pose X = Pose::FromTranslation(Eigen::Vector3d(38e-3, 12e-3, 30.6e-3));
  CollisionDetector kept(floor_and_wall, line, 0.0);
  kept.resetSampleCount();
  ASSERT_FALSE(kept.edgesCrossAt(X, 128.0));
  ASSERT_GT(kept.cellCount(), 0) << "the edges were not walked: no certificate of the walk's";
  ASSERT_FALSE(kept.edgesCrossAt(X, 128.0));
  ASSERT_TRUE(floor_and_wall.isInside(Eigen::Vector3d(40e-3, 12e-3, 30.6e-3), 100.0));  // the wall in the first edge
  ASSERT_FALSE(floor_and_wall.isInside(X.p_AB_m, 100.0));                               // its ends outside
  ASSERT_FALSE(floor_and_wall.isInside(Eigen::Vector3d(41e-3, 12e-3, 30.6e-3), 100.0));
  CollisionDetector fresh(floor_and_wall, line, 0.0);
  EXPECT_TRUE(fresh.edgesCrossAt(X, 100.0));
  EXPECT_TRUE(kept.edgesCrossAt(X, 100.0)) << "a certificate proven at 128 hid the wall at 100";
}

}  // namespace
}  // namespace vh::haptics
