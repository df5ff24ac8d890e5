// Scenario tests of the paper's hard interactions (issue: prove the haptic core right). Every
// scenario drives a scripted device and checks on every tick:
//   - no proxy point deeper than epsilon inside the isosurface ((F - s) / |grad F|);
//   - no NaN or infinite value in the proxy pose, force or torque;
//   - force and torque equal the coupling, eq. 5, recomputed here independently;
//   - during a hold (device still), once settled, the proxy does not move (1e-9 m, 1e-9 rad).
#include <cmath>
#include <functional>
#include <numbers>
#include <string>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include "test_tools.h"
#include "vh/haptics/haptic_renderer.h"
#include "vh/haptics/penetration.h"

namespace vh::haptics {
namespace {

using datasets::GridSpec;

struct Phase {
  int ticks;                                   // duration
  std::function<Pose(double u)> device;        // device pose at u in [0, 1] over the phase
  bool hold = false;                           // device still: check rest after `settle` ticks
  int settle = 300;
};

struct Outcome {
  TickOutput last;
  int max_contacts = 0;
  double max_depth_m = 0.0;
  double max_force_N = 0.0;
};

// Independent eq. 5: F = -k_lin (c_D - c_P), tau = -(k_ang / i) I_W theta, i = trace(I) / 3.
void expectCoupling(const ToolModel& tool, const CouplingGains& k, const Pose& X_WP, const Pose& X_WD,
                    const TickOutput& out, int tick) {
  const Eigen::Vector3d c_P = X_WP * tool.mass.p_TCm_m, c_D = X_WD * tool.mass.p_TCm_m;
  const Eigen::Vector3d F = -k.linear_N_per_m * (c_D - c_P);
  const Eigen::AngleAxisd aa(X_WD.R_AB * X_WP.R_AB.conjugate());
  const Eigen::Vector3d theta = aa.angle() <= std::numbers::pi ? Eigen::Vector3d(aa.axis() * aa.angle())
                                                               : Eigen::Vector3d(-aa.axis() * (2 * std::numbers::pi - aa.angle()));
  const Eigen::Matrix3d R = X_WP.R_AB.toRotationMatrix();
  const Eigen::Matrix3d I_W = R * tool.mass.I_Cm_T_kgm2 * R.transpose();
  const Eigen::Vector3d tau = -(k.angular_Nm_per_rad / (tool.mass.I_Cm_T_kgm2.trace() / 3.0)) * I_W * theta;
  ASSERT_LT((out.force_W_N - F).norm(), 1e-9 * (1.0 + F.norm())) << "tick " << tick;
  ASSERT_LT((out.torque_W_Nm - tau).norm(), 1e-9 * (1.0 + tau.norm())) << "tick " << tick;
}

double depthOf(const ScalarVolume& vol, const ToolModel& tool, const Pose& X_WP, double s) {
  return maxPenetration_m(vol, tool.point_shell, X_WP, s);
}

Outcome runScenario(HapticRenderer& r, double s, const std::vector<Phase>& phases, const CouplingGains& gains) {
  Outcome o;
  int tick = 0;
  for (const Phase& ph : phases) {
    Pose previous = r.proxyPose();
    for (int i = 0; i < ph.ticks; ++i, ++tick) {
      const Pose X_WD = ph.device(ph.ticks > 1 ? static_cast<double>(i) / (ph.ticks - 1) : 1.0);
      const TickOutput out = r.tick(X_WD, s);
      EXPECT_TRUE(out.X_WP.allFinite() && out.force_W_N.allFinite() && out.torque_W_Nm.allFinite()) << "tick " << tick;
      const double depth = depthOf(r.volume(), r.tool(), out.X_WP, s);
      EXPECT_LE(depth, r.epsilon_m()) << "tick " << tick;
      expectCoupling(r.tool(), gains, out.X_WP, X_WD, out, tick);
      if (ph.hold && i > ph.settle) {
        EXPECT_LT((out.X_WP.p_AB_m - previous.p_AB_m).norm(), 1e-9) << "proxy moved during a hold, tick " << tick;
        EXPECT_LT(out.X_WP.R_AB.angularDistance(previous.R_AB), 1e-9) << "proxy turned during a hold, tick " << tick;
      }
      previous = out.X_WP;
      o.last = out;
      o.max_contacts = std::max(o.max_contacts, out.stats.contacts);
      o.max_depth_m = std::max(o.max_depth_m, depth);
      o.max_force_N = std::max(o.max_force_N, out.force_W_N.norm());
      if (::testing::Test::HasFatalFailure()) return o;
    }
  }
  return o;
}

std::function<Pose(double)> line(const Pose& a, const Pose& b) {
  return [a, b](double u) {
    Pose X;
    X.p_AB_m = a.p_AB_m + u * (b.p_AB_m - a.p_AB_m);
    X.R_AB = a.R_AB.slerp(u, b.R_AB);
    return X;
  };
}
std::function<Pose(double)> still(const Pose& a) { return [a](double) { return a; }; }

GridSpec grid(int n, double h_m) {
  GridSpec g;
  g.dims = {n, n, n};
  g.spacing_m = Eigen::Vector3d::Constant(h_m);
  return g;
}

Pose at(double x, double y, double z) { return Pose::FromTranslation({x, y, z}); }

// ---- Sliding --------------------------------------------------------------------------------

// Every test runs in both detection modes: the paper's path and the accelerated one.
class Scenario : public ::testing::TestWithParam<DetectionMode> {};
INSTANTIATE_TEST_SUITE_P(Modes, Scenario, ::testing::Values(DetectionMode::kPaper, DetectionMode::kAccelerated),
                         [](const ::testing::TestParamInfo<DetectionMode>& p) { return std::string(toString(p.param)); });

TEST_P(Scenario, SlidingOnAPlaneFollowsTheDeviceProjection) {
  auto vol = std::make_shared<ScalarVolume>(datasets::makePlaneVolume(grid(64, 1e-3), Eigen::Vector3d::UnitZ(), 0.0));
  const auto tool = test::meshTool(datasets::makeBoxMesh({0.005, 0.005, 0.002}), 1e-3);
  RendererOptions o;
  o.detection_mode = GetParam();
  HapticRenderer r(vol, tool, o, at(0, 0, 0.004), 0.0);
  // Press 2 mm in, then slide 15 mm diagonally, circle back, and hold.
  const Pose a = at(0, 0, 0.0), b = at(0.012, -0.009, 0.0);
  auto circle = [](double u) {
    const double t = 2 * std::numbers::pi * u;
    return at(0.012 - 0.006 + 0.006 * std::cos(t), -0.009 + 0.006 * std::sin(t), 0.0);
  };
  const Outcome out = runScenario(r, 0.0, {{100, line(at(0, 0, 0.004), a)}, {600, line(a, b)}, {1000, circle}, {600, still(b), true}}, o.gains);
  // Friction-free: the proxy sits on the plane right above the device, the force is normal.
  EXPECT_NEAR(r.proxyPose().p_AB_m.x(), 0.012, 1e-6);
  EXPECT_NEAR(r.proxyPose().p_AB_m.y(), -0.009, 1e-6);
  EXPECT_NEAR(r.proxyPose().p_AB_m.z(), 0.002, r.epsilon_m());
  EXPECT_LT(out.last.force_W_N.head<2>().norm(), 1e-6);
  EXPECT_GE(out.max_contacts, 3);
}

// ---- Pressing -------------------------------------------------------------------------------

TEST_P(Scenario, PressingIntoASphereGivesKTimesDepth) {
  auto vol = std::make_shared<ScalarVolume>(datasets::makeSphereVolume(grid(64, 1e-3), Eigen::Vector3d::Zero(), 0.02));
  const auto tool = test::pointTool();
  RendererOptions o;
  o.detection_mode = GetParam();
  o.epsilon_m = 0.02e-3;
  HapticRenderer r(vol, tool, o, at(0, 0, 0.026), 0.0);
  // First contact along -z, then the device goes exactly 5 mm further and holds.
  const Pose contact_start = at(0, 0, 0.026);
  runScenario(r, 0.0, {{200, line(contact_start, at(0, 0, 0.019))}}, o.gains);
  const double z_surface = r.proxyPose().p_AB_m.z();
  ASSERT_NEAR(z_surface, 0.02, 0.1e-3);  // the trilinear sphere's pole, within a tenth of a voxel
  const Pose pressed = at(0, 0, z_surface - 0.005);
  const Outcome out = runScenario(r, 0.0, {{50, line(at(0, 0, 0.019), pressed)}, {600, still(pressed), true}}, o.gains);
  const double expected = o.gains.linear_N_per_m * 0.005;
  EXPECT_NEAR(out.last.force_W_N.norm(), expected, 0.01 * expected);
  EXPECT_GT(out.last.force_W_N.z(), 0.0);
}

TEST_P(Scenario, PressingWorksForEveryVoxelTypeAndAnisotropicVoxels) {
  struct Case {
    VoxelType type;
    Eigen::Vector3d spacing_m;
  };
  const Case cases[] = {{VoxelType::kUInt8, Eigen::Vector3d::Constant(1e-3)},
                        {VoxelType::kInt16, Eigen::Vector3d::Constant(1e-3)},
                        {VoxelType::kUInt16, Eigen::Vector3d::Constant(1e-3)},
                        {VoxelType::kFloat32, Eigen::Vector3d::Constant(1e-3)},
                        {VoxelType::kFloat32, Eigen::Vector3d(0.1e-3, 0.1e-3, 3e-3)},
                        {VoxelType::kInt16, Eigen::Vector3d(0.1e-3, 0.1e-3, 3e-3)}};
  for (const Case& c : cases) {
    SCOPED_TRACE(std::string(voxelTypeName(c.type)) + " spacing " + std::to_string(c.spacing_m.x()) + " x " +
                 std::to_string(c.spacing_m.z()));
    GridSpec g;
    g.spacing_m = c.spacing_m;
    g.dims = {static_cast<int>(std::lround(0.012 / c.spacing_m.x())), static_cast<int>(std::lround(0.012 / c.spacing_m.y())),
              std::max(8, static_cast<int>(std::lround(0.03 / c.spacing_m.z())))};
    // A tilted plane: inside below n . p = 0 with n off the grid axes.
    const Eigen::Vector3d n = Eigen::Vector3d(0.2, -0.1, 1.0).normalized();
    auto vol = std::make_shared<ScalarVolume>(
        datasets::makeVolumeFromSignedDistance(g, [n](const Eigen::Vector3d& p) { return -n.dot(p); }, c.type));
    const auto tool = test::meshTool(datasets::makeSphereMesh(0.002, 3), 0.5e-3);
    RendererOptions o;
  o.detection_mode = GetParam();
    HapticRenderer r(vol, tool, o, at(0, 0, 0.006), 0.0);
    const Pose pressed = Pose::FromTranslation(n * (0.002 - 0.003));  // ball centre 3 mm past contact
    const Outcome out = runScenario(r, 0.0, {{300, line(at(0, 0, 0.006), pressed)}, {700, still(pressed), true}}, o.gains);
    // Resting on the plane: force along n, k times the 3 mm the device went past contact (within
    // the point shell's discretisation of the ball and the stand-off).
    EXPECT_GT(out.last.force_W_N.normalized().dot(n), 0.995);
    EXPECT_NEAR(out.last.force_W_N.norm(), o.gains.linear_N_per_m * 0.003, 0.05 * o.gains.linear_N_per_m * 0.003);
    EXPECT_GT(out.max_contacts, 0);
  }
}

// ---- Wedging ----------------------------------------------------------------------------------

TEST_P(Scenario, WedgingInAVGrooveAndACreviceSettlesWithoutChatter) {
  for (const double half_angle_deg : {45.0, 15.0}) {  // a V-groove and a narrow crevice
    SCOPED_TRACE("wall half-angle " + std::to_string(half_angle_deg));
    const double a = half_angle_deg * std::numbers::pi / 180.0;
    // Solid below both walls: z < |x| / tan(a) (walls meet at the origin along y).
    const Eigen::Vector3d n1(std::cos(a), 0, -std::sin(a)), n2(-std::cos(a), 0, -std::sin(a));
    auto vol = std::make_shared<ScalarVolume>(datasets::makeVolumeFromSignedDistance(
        grid(96, 0.5e-3), [n1, n2](const Eigen::Vector3d& p) { return std::max(n1.dot(p), n2.dot(p)); }));
    const auto tool = test::meshTool(datasets::makeSphereMesh(0.003, 3), 0.6e-3);
    RendererOptions o;
  o.detection_mode = GetParam();
    // Start clear of both walls (the V's half width at height z is z tan a), wedge 4 mm deeper
    // than where the ball meets both walls (centre height r / sin a).
    const Pose start = at(0.001, 0, 0.021);
    HapticRenderer r(vol, tool, o, start, 0.0);
    const Pose pressed = at(0.0005, 0, 0.003 / std::sin(a) - 0.004);
    const Outcome out = runScenario(r, 0.0, {{400, line(start, pressed)}, {1300, still(pressed), true}}, o.gains);
    EXPECT_GE(out.last.stats.contacts, 2);
    // Wedged between the walls: pushed up out of the groove, centred.
    EXPECT_GT(out.last.force_W_N.z(), 0.0);
    EXPECT_LT(std::abs(r.proxyPose().p_AB_m.x()), 0.2e-3);
  }
}

// ---- Prying -----------------------------------------------------------------------------------

TEST_P(Scenario, PryingALeverInASlotGivesAnOpposingTorque) {
  // A block (z < 0) with a slot 3 mm wide (|x| < 1.5 mm), 20 mm deep; a 2 x 6 x 40 mm bar in it.
  auto vol = std::make_shared<ScalarVolume>(datasets::makeVolumeFromSignedDistance(grid(96, 0.5e-3), [](const Eigen::Vector3d& p) {
    const double block = -p.z();
    const double outside_slot = std::max(std::abs(p.x()) - 0.0015, -0.02 - p.z());
    return std::min(block, outside_slot);
  }));
  const auto tool = test::meshTool(datasets::translated(datasets::makeBoxMesh({0.001, 0.003, 0.02}), {0, 0, 0.02}), 0.7e-3);
  RendererOptions o;
  o.detection_mode = GetParam();
  o.gains = {1000.0, 0.5};
  const Pose inserted = at(0, 0, -0.015);  // tip 15 mm down the slot
  HapticRenderer r(vol, tool, o, at(0, 0, 0.01), 0.0);
  runScenario(r, 0.0, {{300, line(at(0, 0, 0.01), inserted)}, {100, still(inserted)}}, o.gains);
  ASSERT_NEAR(r.proxyPose().p_AB_m.z(), -0.015, 1e-6);
  // Turn the device 0.3 rad about y, about the bar's tip: the slot lets the bar tilt ~0.05 rad.
  Pose turned;
  turned.R_AB = Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitY()));
  turned.p_AB_m = inserted.p_AB_m;  // the tip (tool origin) stays put
  const Outcome out = runScenario(r, 0.0, {{200, line(inserted, turned)}, {600, still(turned), true}}, o.gains);
  const double proxy_tilt = Eigen::AngleAxisd(r.proxyPose().R_AB).angle();
  EXPECT_LT(proxy_tilt, 0.1);   // held by the slot walls
  EXPECT_LT(out.last.torque_W_Nm.y(), 0.0);  // opposing the device's turn (+y)
  EXPECT_GT(std::abs(out.last.torque_W_Nm.y()), 0.5 * 0.5 * (0.3 - 0.1) * 0.5);  // a large share of k (dtheta)
  EXPECT_GE(out.max_contacts, 2);
}

// ---- Hooking ----------------------------------------------------------------------------------

TEST_P(Scenario, HookCaughtUnderAShelfHoldsWhenPulled) {
  // A shelf 4 mm thick at 0 < z < 4 mm over x > 0 (an overhang); an L-shaped hook: a shaft along
  // +z and a foot along +x at its bottom, slid under the shelf and pulled straight up.
  auto vol = std::make_shared<ScalarVolume>(datasets::makeVolumeFromSignedDistance(grid(80, 0.5e-3), [](const Eigen::Vector3d& p) {
    return std::min({p.x(), p.z(), 0.004 - p.z()});
  }));
  const TriangleMesh hook = datasets::concatenate(
      datasets::translated(datasets::makeBoxMesh({0.001, 0.001, 0.012}), {-0.004, 0, 0.012}),
      datasets::translated(datasets::makeBoxMesh({0.004, 0.001, 0.001}), {-0.001, 0, 0.0}));
  const auto tool = test::meshTool(hook, 0.6e-3);
  RendererOptions o;
  o.detection_mode = GetParam();
  const Pose under = at(0.0, 0, -0.004);  // foot (z in [-1, 1] mm around origin) below the shelf
  HapticRenderer r(vol, tool, o, at(-0.01, 0, -0.004), 0.0);
  const Pose pulled = at(0.0, 0, 0.004);  // 8 mm up: the foot would end inside the shelf
  const Outcome out = runScenario(r, 0.0, {{300, line(at(-0.01, 0, -0.004), under)}, {300, line(under, pulled)}, {700, still(pulled), true}}, o.gains);
  // Caught: the foot's top (z = +1 mm in T) rests on the shelf's underside z = 0.
  EXPECT_NEAR(r.proxyPose().p_AB_m.z(), -0.001, 0.2e-3);
  EXPECT_LT(out.last.force_W_N.z(), -0.9 * o.gains.linear_N_per_m * 0.004);
  EXPECT_GT(out.last.stats.contacts, 0);
}

// ---- Peg in hole ------------------------------------------------------------------------------

TEST_P(Scenario, LongPegGoesToTheBottomOfTheHoleAndJamsOnlyWhenPulledSideways) {
  auto vol = std::make_shared<ScalarVolume>(datasets::makeBlockWithBlindHoleVolume(256, -0.004));
  PointShellOptions ps;
  ps.point_count = 1307;  // the paper's Hole / Peg figure
  // The snug peg (radius kPegRadius_m), 80 mm long: 1307 points put about 50 on its flat end, the
  // paper's "up to 40" coplanar contacts regime (the 40 mm built-in peg puts about 100 there).
  auto tool = std::make_shared<ToolModel>(makeToolModel(datasets::makeCylinderMesh(datasets::kPegRadius_m, 0.08, 64), ps));
  const double s = datasets::kBlockIsovalue;
  RendererOptions o;
  o.detection_mode = GetParam();
  o.work_budget = 0;  // the contact count of whole ticks (a budget adds the rest on later ticks)
  HapticRenderer r(vol, tool, o, at(0, 0, 0.02), s);
  const Pose deep = at(0, 0, -0.008);  // 4 mm past the hole's floor at z = -4 mm
  const Outcome in = runScenario(r, s, {{1500, line(at(0, 0, 0.02), deep)}, {800, still(deep), true}}, o.gains);
  EXPECT_NEAR(r.proxyPose().p_AB_m.z(), -0.004, 0.1e-3);  // at the bottom: no jamming on the way
  EXPECT_GE(in.max_contacts, 30);
  EXPECT_LE(in.max_contacts, 60);
  RecordProperty("coplanar_contacts", in.max_contacts);
  std::cout << "peg at the bottom: " << in.max_contacts << " simultaneous contacts\n";
  // Pulled sideways and up: the walls hold it (the proxy stays in the hole, the force says so).
  const Pose sideways = at(0.004, 0, 0.0);
  const Outcome jam = runScenario(r, s, {{300, line(deep, sideways)}, {400, still(sideways), true}}, o.gains);
  EXPECT_LT(std::hypot(r.proxyPose().p_AB_m.x(), r.proxyPose().p_AB_m.y()), datasets::kHoleRadius_m - datasets::kPegRadius_m + 1e-4);
  // The long peg tilts in the hole, but its centre of mass cannot follow: it lags the device's
  // by more than 1 mm in x, and the force (= k times the lag, checked every tick) pulls back.
  EXPECT_LT(jam.last.force_W_N.x(), -o.gains.linear_N_per_m * 0.001);
}

// ---- Thin and fast ------------------------------------------------------------------------------

TEST_P(Scenario, TenCentimetreJumpWithAHalfTurnNeverCrossesAOneVoxelPlate) {
  auto vol = std::make_shared<ScalarVolume>(datasets::makeThinPlateVolume(grid(64, 1e-3)));
  const double s = datasets::builtinIsovalue("thin-plate");
  const double z_plate = vol->geometry().origin_W_m.z() + 32e-3;
  const auto tool = test::meshTool(datasets::makeBuiltinTool("probe"), 1e-3);
  RendererOptions o;
  o.detection_mode = GetParam();
  HapticRenderer r(vol, tool, o, at(0, 0, z_plate + 0.004), s);
  for (int i = 0; i < 40; ++i) {
    Pose X_WD = at(0.001 * (i % 3), 0, z_plate + (i % 2 == 0 ? -0.096 : 0.004));
    X_WD.R_AB = Eigen::Quaterniond(Eigen::AngleAxisd(i % 2 == 0 ? 3.1 : 0.0, Eigen::Vector3d::UnitX()));
    const TickOutput out = r.tick(X_WD, s);
    ASSERT_TRUE(out.X_WP.allFinite());
    for (const auto& p : tool->point_shell.points_T_m()) ASSERT_GT((out.X_WP * p).z(), z_plate) << "tick " << i;
  }
}

}  // namespace
}  // namespace vh::haptics
