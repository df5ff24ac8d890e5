#include "vh/haptics/collision_detector.h"

#include <iostream>
#include <random>
#include <string>

#include <chrono>

#include <gtest/gtest.h>

#include "test_tools.h"

namespace vh::haptics {
namespace {

// Brute-force reference: sample every point's arc at 1/100 of the feature size and return the
// first sample time at which any point is inside (1 when none).
double bruteForceFirstContact(const ScalarVolume& vol, const ToolModel& tool, const RigidMotion& motion, double s) {
  const double f = vol.featureSize_m();
  double first = 1.0;
  for (const auto& p_T : tool.point_shell.points_T_m()) {
    const Eigen::Vector3d r0 = motion.radial_W(p_T);
    const int steps = std::max(1, static_cast<int>(std::ceil(motion.pathLengthBound(r0) / (f / 100))));
    for (int i = 1; i <= steps; ++i) {
      const double t = static_cast<double>(i) / steps;
      if (t >= first) break;
      if (vol.isInside(motion.pointAt(r0, t), s)) {
        first = t;
        break;
      }
    }
  }
  return first;
}

// Every test runs in both detection modes: the paper's path and the accelerated one.
class CollisionDetectorModes : public ::testing::TestWithParam<DetectionMode> {};
INSTANTIATE_TEST_SUITE_P(Modes, CollisionDetectorModes, ::testing::Values(DetectionMode::kPaper, DetectionMode::kAccelerated),
                         [](const ::testing::TestParamInfo<DetectionMode>& p) { return std::string(toString(p.param)); });

TEST_P(CollisionDetectorModes, PointDrivenIntoAPlaneStopsWithinEpsilon) {
  const ScalarVolume vol = datasets::makePlaneVolume(test::grid1mm(), Eigen::Vector3d::UnitZ(), 0.0);
  const auto tool = test::pointTool();
  CollisionDetector cd(vol, *tool, 0.0, 256, GetParam());
  const Pose X0 = Pose::FromTranslation({0.001, 0.002, 0.010});
  const Pose X1 = Pose::FromTranslation({0.003, 0.002, -0.010});
  const RigidMotion motion = RigidMotion::Between(X0, X1, tool->mass.p_TCm_m);
  const SweepResult r = cd.sweep(motion, 0.0);
  ASSERT_EQ(r.hit_point, 0);
  const Eigen::Vector3d p = motion.poseAt(r.t) * Eigen::Vector3d::Zero();
  EXPECT_GE(p.z(), 0.0);                                        // outside
  EXPECT_LE(p.z() * std::hypot(20.0, 2.0) / 20.0, cd.epsilon_m());  // within epsilon of travel
  // Contact set with the normal of the plane.
  cd.addContactsAt(motion, r, 0.0);
  ASSERT_EQ(cd.contacts().size(), 1u);
  EXPECT_LT((cd.contacts()[0].n_W - Eigen::Vector3d::UnitZ()).norm(), 1e-9);
}

TEST_P(CollisionDetectorModes, PointDrivenIntoASphereStopsWithinEpsilon) {
  datasets::GridSpec g = test::grid1mm();
  const ScalarVolume vol = datasets::makeSphereVolume(g, Eigen::Vector3d::Zero(), 0.015);
  const auto tool = test::pointTool();
  CollisionDetector cd(vol, *tool, 0.0, 256, GetParam());
  std::mt19937 rng(4);
  std::normal_distribution<double> nd;
  for (int n = 0; n < 50; ++n) {
    const Eigen::Vector3d dir = Eigen::Vector3d(nd(rng), nd(rng), nd(rng)).normalized();
    const RigidMotion motion = RigidMotion::Between(Pose::FromTranslation(0.025 * dir), Pose::FromTranslation(0.005 * dir),
                                                    tool->mass.p_TCm_m);
    const SweepResult r = cd.sweep(motion, 0.0);
    ASSERT_EQ(r.hit_point, 0);
    const Eigen::Vector3d p = motion.poseAt(r.t).p_AB_m;
    EXPECT_LE(vol.sample(p), 0.0);
    // Distance to the (interpolated) surface along the path: travel to the inside <= epsilon.
    const double t_ref = bruteForceFirstContact(vol, *tool, motion, 0.0);
    EXPECT_LE(r.t, t_ref);
    EXPECT_LE((t_ref - r.t) * 0.020, cd.epsilon_m() + vol.featureSize_m() / 100);
  }
}

TEST_P(CollisionDetectorModes, NeverLaterThanTheBruteForceReferenceForRotatingTools) {
  const ScalarVolume vol = datasets::makeSphereVolume(test::grid1mm(), Eigen::Vector3d::Zero(), 0.012);
  const auto tool = test::meshTool(datasets::makeBuiltinTool("probe"), 2e-3);
  CollisionDetector cd(vol, *tool, 0.0, 256, GetParam());
  std::mt19937 rng(9);
  std::normal_distribution<double> nd;
  int hits = 0;
  for (int n = 0; n < 60; ++n) {
    Pose X0, X1;
    X0.p_AB_m = Eigen::Vector3d(0, 0, 0.016) + 0.002 * Eigen::Vector3d(nd(rng), nd(rng), nd(rng));
    X0.R_AB = Eigen::Quaterniond(Eigen::AngleAxisd(0.3 * nd(rng), Eigen::Vector3d::UnitX()));
    X1.p_AB_m = X0.p_AB_m + Eigen::Vector3d(0.004 * nd(rng), 0.004 * nd(rng), -0.006);
    X1.R_AB = Eigen::Quaterniond(Eigen::AngleAxisd(0.5 * nd(rng), Eigen::Vector3d(nd(rng), nd(rng), nd(rng)).normalized())) * X0.R_AB;
    // Start outside: skip poses where any point already is inside.
    bool clear = true;
    for (const auto& p : tool->point_shell.points_T_m()) clear &= !vol.isInside(X0 * p, 0.0);
    if (!clear) continue;
    const RigidMotion motion = RigidMotion::Between(X0, X1, tool->mass.p_TCm_m);
    const SweepResult r = cd.sweep(motion, 0.0);
    const double t_ref = bruteForceFirstContact(vol, *tool, motion, 0.0);
    EXPECT_LE(r.t, t_ref + 1e-12) << "missed contact, case " << n;
    if (r.hit_point >= 0) {
      ++hits;
      const double travel = motion.pathLengthBound(motion.radial_W(tool->point_shell.points_T_m()[r.hit_point]));
      EXPECT_GE(r.t * travel + cd.epsilon_m() + vol.featureSize_m() / 100, t_ref * travel) << "too early, case " << n;
    }
  }
  EXPECT_GT(hits, 10);
}

TEST_P(CollisionDetectorModes, OneVoxelPlateIsNotTunnelledThrough) {
  const ScalarVolume vol = datasets::makeThinPlateVolume(test::grid1mm());
  const double s = datasets::builtinIsovalue("thin-plate");
  const auto tool = test::meshTool(datasets::makeBuiltinTool("sphere"), 1.5e-3);
  CollisionDetector cd(vol, *tool, 0.0, 256, GetParam());
  const double z_plate = vol.geometry().origin_W_m.z() + 32 * 1e-3;
  // A 10 cm jump with a half turn, straight through the plate, in one step.
  Pose X0 = Pose::FromTranslation({0.0, 0.0, z_plate + 0.02});
  Pose X1 = Pose::FromTranslation({0.0, 0.0, z_plate - 0.08});
  X1.R_AB = Eigen::Quaterniond(Eigen::AngleAxisd(3.1, Eigen::Vector3d::UnitY()));
  const RigidMotion motion = RigidMotion::Between(X0, X1, tool->mass.p_TCm_m);
  const SweepResult r = cd.sweep(motion, s);
  ASSERT_GE(r.hit_point, 0);
  const Pose X = motion.poseAt(r.t);
  for (const auto& p : tool->point_shell.points_T_m()) {
    EXPECT_FALSE(vol.isInside(X * p, s));
    EXPECT_GT((X * p).z(), z_plate);  // still on the near side of the plate
  }
}

TEST_P(CollisionDetectorModes, PruningKeepsOnlyContactsThatBlockTheMotion) {
  const ScalarVolume vol = datasets::makePlaneVolume(test::grid1mm(), Eigen::Vector3d::UnitZ(), 0.0);
  const auto tool = test::pointTool();
  CollisionDetector cd(vol, *tool, 0.0, 256, GetParam());
  const RigidMotion motion = RigidMotion::Between(Pose::FromTranslation({0, 0, 0.005}), Pose::FromTranslation({0, 0, -0.005}),
                                                  tool->mass.p_TCm_m);
  const SweepResult r = cd.sweep(motion, 0.0);
  cd.addContactsAt(motion, r, 0.0);
  const Pose X_WP = motion.poseAt(r.t);
  ASSERT_EQ(cd.contacts().size(), 1u);
  cd.pruneContacts(X_WP, Pose::FromTranslation({0.001, 0, -0.003}), 0.0);  // still pushing in
  EXPECT_EQ(cd.contacts().size(), 1u);
  cd.pruneContacts(X_WP, Pose::FromTranslation({0.001, 0, 0.003}), 0.0);   // pulling away
  EXPECT_EQ(cd.contacts().size(), 0u);
}

// Accelerated path: a point whose whole path (here 8 segments) lies in bricks that cannot hold
// an inside point is culled by one box query on its path's ball, with no sample and no run
// tests (a run-by-run walk takes 4 more: runs of 1, 2, 4 and 1 segments). Slides at many
// heights above a plane: none may hit, and at some heights the point-shell tree's root (its
// ball is epsilon larger) passes and the point's own whole-path test culls it: 2 queries.
TEST(CollisionDetector, AcceleratedCullsAWholeFreePathWithOneQuery) {
  const ScalarVolume vol = datasets::makePlaneVolume(test::grid1mm(), Eigen::Vector3d::UnitZ(), 0.0);
  const auto tool = test::pointTool();
  CollisionDetector cd(vol, *tool, 0.0, 256, DetectionMode::kAccelerated);
  const double length_m = 8.0 * vol.featureSize_m();
  int culled_by_point_test = 0, more_queries = 0;
  for (int i = 0; i < 400; ++i) {
    const double height_m = 0.0002 + 0.000025 * i;  // 0.2 to 10.2 mm
    const Pose X0 = Pose::FromTranslation({-0.5 * length_m, 0.001, height_m});
    const Pose X1 = Pose::FromTranslation({0.5 * length_m, 0.001, height_m});
    const RigidMotion motion = RigidMotion::Between(X0, X1, tool->mass.p_TCm_m);
    cd.resetSampleCount();
    const SweepResult r = cd.sweep(motion, 0.0);
    ASSERT_LT(r.hit_point, 0) << "height " << height_m;  // parallel to the plane, above it
    if (cd.sampleCount() == 0 && cd.boxQueryCount() == 2) ++culled_by_point_test;
    if (cd.sampleCount() == 0 && cd.boxQueryCount() > 2) ++more_queries;
  }
  EXPECT_GT(culled_by_point_test, 0) << "no height exercised the point's own whole-path test";
  ::testing::Test::RecordProperty("culled_by_point_test", culled_by_point_test);
  ::testing::Test::RecordProperty("sample_free_with_run_tests", more_queries);
}

// A point gliding 0.3 mm over a flat floor (1 mm uint8 grid, 255 up to k = 20, the isosurface
// at 128 at k = 20.5) in 1 mm moves, into a one-voxel wall (i = 40, up to k = 30). The ball about
// each move holds the floor; F at the move's start plus the most F can rise along the move's
// direction (the floor's dF/dx is 0) proves the glide free without walking a cell (up to 29 mm,
// where the ranges it reads, per 8-voxel brick, do not reach the wall's steps), and the
// same bound cannot hide the wall: the sweep stops where the trilinear field reaches 128 at
// that height (x* = 39 + (128 - 76.5) / 178.5 mm: F = 0.3 x 255 at i = 39, 255 at i = 40),
// within epsilon before it and never past it, in both modes.
TEST_P(CollisionDetectorModes, AGlideAlongAFloorIsProvenFreeByItsDirectionAndStopsAtTheWall) {
  const ScalarVolume vol = test::floorAndWallVolume();
  const auto tool = test::pointTool();
  CollisionDetector cd(vol, *tool, 0.0, 256, GetParam());
  const double wall_x_m = 39e-3 + (128.0 - 76.5) / 178.5 * 1e-3;
  Pose X = Pose::FromTranslation({10e-3, 12e-3, 20.7e-3});
  std::int64_t glide_cells = 0;
  bool stopped = false;
  for (int tick = 0; tick < 40 && !stopped; ++tick) {
    const Pose next = Pose::FromTranslation(X.p_AB_m + Eigen::Vector3d(1e-3, 0.0, 0.0));
    const RigidMotion motion = RigidMotion::Between(X, next, tool->mass.p_TCm_m);
    cd.resetSampleCount();
    const SweepResult r = cd.sweep(motion, 128.0);
    if (r.hit_point < 0) {
      if (next.p_AB_m.x() < 29.5e-3) glide_cells += cd.cellCount();  // 8-cell bricks clear of the wall's
      X = next;
      continue;
    }
    stopped = true;
    const Eigen::Vector3d p = motion.poseAt(r.t).p_AB_m;
    EXPECT_FALSE(vol.isInside(p, 128.0));
    EXPECT_LE(p.x(), wall_x_m + 1e-12);
    EXPECT_GE(p.x(), wall_x_m - cd.epsilon_m()) << "stopped " << 1e3 * (wall_x_m - p.x()) << " mm before the wall";
  }
  EXPECT_TRUE(stopped) << "went through the wall";
  if (GetParam() == DetectionMode::kAccelerated) EXPECT_EQ(glide_cells, 0) << "the glide walked cells";
  // The same glide in one 35 mm move, by a detector that has walked nothing yet (no point near
  // the surface): only the bounds of its runs stand between it and the wall.
  CollisionDetector fresh(vol, *tool, 0.0, 256, GetParam());
  const RigidMotion long_move = RigidMotion::Between(Pose::FromTranslation({10e-3, 12e-3, 20.7e-3}),
                                                     Pose::FromTranslation({45e-3, 12e-3, 20.7e-3}), tool->mass.p_TCm_m);
  const SweepResult r = fresh.sweep(long_move, 128.0);
  ASSERT_EQ(r.hit_point, 0) << "went through the wall in one move";
  const Eigen::Vector3d p = long_move.poseAt(r.t).p_AB_m;
  EXPECT_LE(p.x(), wall_x_m + 1e-12);
  EXPECT_GE(p.x(), wall_x_m - fresh.epsilon_m());
}

// Temporal coherence of the point-shell tree's walk: a 20 x 20 x 2 mm plate (about 1,200 points)
// gliding 0.3 mm over a plane, 0.3 mm a sweep. Its bottom face lies within a brick of the
// surface, so every upper node's ball holds it: the first sweep asks the min-max tree about each
// of them; later sweeps let the nodes found near the surface through unasked and prove the
// face's points free along their direction. What they still ask is about the points of the
// plate's sides and top, within the plane's 4 mm brick, each about its own path (526 against
// 1,509 on the first sweep, 979 when every node is asked). Lifted 20 mm, the plate is asked
// about again and culled at the root by the third sweep up there. Every sweep gives the paper
// path's answer (no hit, the same double), the oracle for what a skipped question must never
// change. Fails with the walk asking every node, or with near nodes never asked again.
TEST(CollisionDetector, AGlidingToolsWalkAsksOnlyWhereTheSurfaceMayHaveMoved) {
  const ScalarVolume vol = datasets::makePlaneVolume(test::grid1mm(), Eigen::Vector3d::UnitZ(), 0.0);
  const auto tool = test::meshTool(datasets::makeBoxMesh({0.01, 0.01, 0.001}), 0.7e-3);
  ASSERT_GT(tool->point_shell.size(), 1000u);
  CollisionDetector paper(vol, *tool, 0.0, 256, DetectionMode::kPaper);
  CollisionDetector fast(vol, *tool, 0.0, 256, DetectionMode::kAccelerated);
  Pose X = Pose::FromTranslation({-0.006, 0.0, 0.001 + 0.0003});
  std::vector<std::int64_t> queries;
  const auto move = [&](const Eigen::Vector3d& d_m) {
    const Pose next = Pose::FromTranslation(X.p_AB_m + d_m);
    const RigidMotion motion = RigidMotion::Between(X, next, tool->mass.p_TCm_m);
    fast.resetSampleCount();
    const SweepResult rp = paper.sweep(motion, 0.0), rf = fast.sweep(motion, 0.0);
    EXPECT_EQ(rf.hit_point, rp.hit_point);
    EXPECT_EQ(rf.t, rp.t);
    queries.push_back(fast.boxQueryCount());
    X = next;
  };
  for (int i = 0; i < 30; ++i) move({0.0003, 0.0, 0.0});
  const std::int64_t first = queries.front();
  std::int64_t later_max = 0;
  for (std::size_t i = 2; i < queries.size(); ++i) later_max = std::max(later_max, queries[i]);
  std::cout << "glide: box queries first sweep " << first << ", later sweeps at most " << later_max << ":";
  for (const std::int64_t q : queries) std::cout << " " << q;
  std::cout << "\n";
  EXPECT_GT(first, 100);
  EXPECT_LT(later_max * 5, first * 2) << "the walk asked again about the nodes near the surface";
  move({0.0, 0.0, 0.02});  // lifted: the nodes near the plane are let through once more
  move({0.0003, 0.0, 0.0});
  move({0.0003, 0.0, 0.0});
  std::cout << "lifted: box queries " << queries[queries.size() - 3] << ", " << queries[queries.size() - 2] << ", "
            << queries.back() << "\n";
  EXPECT_LE(queries.back(), 2) << "the lifted plate was not culled at the root again";
  ::testing::Test::RecordProperty("first_sweep_box_queries", static_cast<int>(first));
  ::testing::Test::RecordProperty("later_sweeps_box_queries_max", static_cast<int>(later_max));
}

// A plate of points gliding 0.3 mm over a floor into a one-voxel wall (test::floorAndWallVolume()),
// 0.5 mm a sweep: near the floor its points are proven free along their direction with F's steps
// read once per point-shell leaf, over the leaf's ball. Those steps are looser than a point's
// own, never wrong: every sweep gives the paper path's first time of contact (the same double),
// and the plate stops before the wall, within epsilon, never in it.
TEST(CollisionDetector, ALeafsStepsProveAGlideFreeAndStillStopAtTheWall) {
  const ScalarVolume vol = test::floorAndWallVolume();
  const auto tool = test::meshTool(datasets::makeBoxMesh({0.003, 0.003, 0.0005}), 0.5e-3);
  ASSERT_GT(tool->point_shell.size(), 100u);
  CollisionDetector paper(vol, *tool, 0.0, 256, DetectionMode::kPaper);
  CollisionDetector fast(vol, *tool, 0.0, 256, DetectionMode::kAccelerated);
  const double floor_z_m = 20.5e-3;
  Pose X = Pose::FromTranslation({8e-3, 12e-3, floor_z_m + 0.0005 + 0.00005});
  bool stopped = false;
  std::int64_t glide_cells = 0;
  for (int tick = 0; tick < 80 && !stopped; ++tick) {
    const Pose next = Pose::FromTranslation(X.p_AB_m + Eigen::Vector3d(0.5e-3, 0.0, 0.0));
    const RigidMotion motion = RigidMotion::Between(X, next, tool->mass.p_TCm_m);
    fast.resetSampleCount();
    const SweepResult rp = paper.sweep(motion, 128.0), rf = fast.sweep(motion, 128.0);
    ASSERT_EQ(rf.t, rp.t) << "tick " << tick;
    if (rp.hit_point < 0) {
      if (tick >= 2 && next.p_AB_m.x() + 0.003 < 28.5e-3) glide_cells += fast.cellCount();  // bricks clear of the wall's
      X = next;
      continue;
    }
    stopped = true;
    // The plate's leading face (x + 3 mm) stops before the wall's isosurface, which lies at
    // x = 39.38 mm at the bottom face's height (F = 51 on the floor there) and 39.50 mm above
    // z = 21 mm, and no point of the plate is inside.
    const double front_x_m = motion.poseAt(rf.t).p_AB_m.x() + 0.003;
    EXPECT_LT(front_x_m, 39.51e-3);
    EXPECT_GT(front_x_m, 39.37e-3 - 1e-3) << "stopped more than a step before the wall";
    for (const Eigen::Vector3d& p_T : tool->point_shell.points_T_m())
      EXPECT_FALSE(vol.isInside(motion.poseAt(rf.t) * p_T, 128.0));
  }
  EXPECT_TRUE(stopped) << "went through the wall";
  EXPECT_EQ(glide_cells, 0) << "the glide over the floor walked cells";
}

// A tool resting on a plane and pushed into it is blocked at t = 0 by its own contacts: the
// accelerated sweep tests the contact points first and stops there, without walking the
// point-shell tree (no box query); the time of contact and the contact set added afterwards
// are the paper path's.
TEST(CollisionDetector, AcceleratedStopsAtABlockingContactWithoutWalkingTheTree) {
  const ScalarVolume vol = datasets::makePlaneVolume(test::grid1mm(), Eigen::Vector3d::UnitZ(), 0.0);
  const auto tool = test::meshTool(datasets::makeBoxMesh({0.004, 0.004, 0.002}), 1e-3);
  // epsilon f / 4: the resting pose after the drop is then within the bisection tolerance of the
  // plane, so the second push is blocked at exactly t = 0 (the case under test).
  const double eps = 0.25 * vol.featureSize_m();
  CollisionDetector paper(vol, *tool, eps, 256, DetectionMode::kPaper);
  CollisionDetector fast(vol, *tool, eps, 256, DetectionMode::kAccelerated);
  // Drop the box onto the plane (z = 0 is the surface; inside below), then push it further.
  const Pose X_start = Pose::FromTranslation({0.0005, 0.0003, 0.004});
  const Pose X_low = Pose::FromTranslation({0.0005, 0.0003, -0.002});
  const RigidMotion drop = RigidMotion::Between(X_start, X_low, tool->mass.p_TCm_m);
  const SweepResult hp = paper.sweep(drop, 0.0), hf = fast.sweep(drop, 0.0);
  ASSERT_GE(hp.hit_point, 0);
  ASSERT_EQ(hf.t, hp.t);
  paper.addContactsAt(drop, hp, 0.0);
  fast.addContactsAt(drop, hf, 0.0);
  ASSERT_GT(fast.contacts().size(), 1u);
  // At the bracket's outside end itself (the sweep stops a little before it, kStopClearanceFraction).
  const Pose X_rest = drop.poseAt(hf.t + CollisionDetector::kStopClearanceFraction * eps / 0.006);
  paper.refreshPositions(X_rest);
  fast.refreshPositions(X_rest);
  // Pushed down again from the resting pose: blocked at once.
  const RigidMotion push = RigidMotion::Between(X_rest, X_low, tool->mass.p_TCm_m);
  paper.resetSampleCount();
  fast.resetSampleCount();
  const SweepResult rp = paper.sweep(push, 0.0), rf = fast.sweep(push, 0.0);
  ASSERT_EQ(rp.t, 0.0);
  EXPECT_EQ(rf.t, rp.t);
  // On a tie at t = 0 the two paths may name different points (documented), whose brackets
  // differ (a point already inside and going deeper has t_inside = 0).
  if (rf.hit_point == rp.hit_point) {
    EXPECT_EQ(rf.t_inside, rp.t_inside);
  }
  EXPECT_EQ(fast.boxQueryCount(), 0) << "the tree was walked although a contact blocks at t = 0";
  // The points added at t = 0 (collected by addContactsAt itself) are the paper's.
  paper.clearContacts();
  fast.clearContacts();
  paper.addContactsAt(push, rp, 0.0);
  fast.addContactsAt(push, rf, 0.0);
  std::vector<int> a, b;
  for (const Contact& c : paper.contacts()) a.push_back(c.point_index);
  for (const Contact& c : fast.contacts()) b.push_back(c.point_index);
  // Each path adds its own hit point first; on a tie at t = 0 these may differ (documented).
  std::erase(a, rp.hit_point);
  std::erase(a, rf.hit_point);
  std::erase(b, rp.hit_point);
  std::erase(b, rf.hit_point);
  std::sort(a.begin(), a.end());
  std::sort(b.begin(), b.end());
  EXPECT_EQ(a, b);
  EXPECT_FALSE(a.empty());
}

// A sweep the work budget cuts is resumed on later calls where it stopped. Done, it
// gives the uncut sweep's result bit for bit (time, bracket, point) and so keeps its contract
// with the brute-force reference; the times reported while cut are proven free (never after
// the first contact) and never decrease; resuming costs little more work than one uncut sweep.
// With several lanes (the sweep on several cores), each lane is cut and resumed on its own; the
// same first time of contact (on a tie between lanes the point may differ).
class ResumedSweep : public ::testing::TestWithParam<int> {};
INSTANTIATE_TEST_SUITE_P(Lanes, ResumedSweep, ::testing::Values(1, 3));

TEST_P(ResumedSweep, GivesTheUncutResult) {
  const int lanes = GetParam();
  const ScalarVolume vol = datasets::makeSphereVolume(test::grid1mm(), Eigen::Vector3d::Zero(), 0.012);
  const auto tool = test::meshTool(datasets::makeSphereMesh(0.006, 3), 0.5e-3);
  CollisionDetector uncut(vol, *tool, 0.0, 256, DetectionMode::kAccelerated);
  CollisionDetector cut(vol, *tool, 0.0, 256, DetectionMode::kAccelerated);
  cut.setLanes(lanes);
  std::mt19937 rng(31);
  std::normal_distribution<double> nd;
  int compared = 0, hits = 0, resumed = 0;
  std::int64_t uncut_work = 0, cut_work = 0;
  for (int n = 0; n < 80; ++n) {
    Pose X0, X1;
    X0.p_AB_m = Eigen::Vector3d(0, 0, 0.020) + 0.002 * Eigen::Vector3d(nd(rng), nd(rng), nd(rng));
    X1.p_AB_m = X0.p_AB_m + Eigen::Vector3d(0.004 * nd(rng), 0.004 * nd(rng), -0.006);
    X1.R_AB = Eigen::Quaterniond(Eigen::AngleAxisd(0.5 * nd(rng), Eigen::Vector3d(nd(rng), nd(rng), nd(rng)).normalized()));
    bool clear = true;
    for (const auto& p : tool->point_shell.points_T_m()) clear &= !vol.isInside(X0 * p, 0.0);
    if (!clear) continue;
    const RigidMotion motion = RigidMotion::Between(X0, X1, tool->mass.p_TCm_m);
    uncut.resetSampleCount();
    const SweepResult reference = uncut.sweep(motion, 0.0);
    uncut_work += uncut.work();
    const std::int64_t budget = 50 + n * 7;
    cut.setWorkBudget(budget);
    cut.resetSampleCount();
    SweepResult r = cut.sweep(motion, 0.0);
    cut_work += cut.work();
    double last_t = 0.0;
    int calls = 1;
    while (r.budget_cut) {
      ASSERT_TRUE(cut.sweepPending());
      EXPECT_GE(r.t, last_t) << "case " << n;
      EXPECT_LE(r.t, reference.t) << "a cut time after the first contact, case " << n;
      last_t = r.t;
      cut.resetSampleCount();
      r = cut.resumeSweep();
      cut_work += cut.work();
      ASSERT_LT(++calls, 100000) << "the resumed sweep does not finish, case " << n;
    }
    EXPECT_FALSE(cut.sweepPending());
    resumed += calls > 1;
    EXPECT_EQ(r.t, reference.t) << "case " << n;
    if (lanes == 1) {
      EXPECT_EQ(r.t_inside, reference.t_inside) << "case " << n;
      EXPECT_EQ(r.hit_point, reference.hit_point) << "case " << n;
    }
    EXPECT_LE(r.t, bruteForceFirstContact(vol, *tool, motion, 0.0) + 1e-12) << "case " << n;
    ++compared;
    hits += r.hit_point >= 0;
  }
  std::cout << lanes << " lane(s): " << compared << " sweeps (" << hits << " hits, " << resumed << " resumed): work uncut " << uncut_work
            << ", cut and resumed " << cut_work << "\n";
  EXPECT_GT(compared, 40);
  EXPECT_GT(hits, 10);
  EXPECT_GT(resumed, 30);
  EXPECT_LT(static_cast<double>(cut_work), 1.25 * static_cast<double>(uncut_work));
}

// The deadline on the clock, the work budget's last line: a sweep whose deadline has passed
// stops at once as at an exhausted budget (proven free up to where it stops, never after the
// first contact of the uncut sweep or the brute-force reference), and, resumed with the
// deadline lifted, gives the uncut result.
TEST(CollisionDetector, APassedDeadlineCutsTheSweepLikeTheBudget) {
  const ScalarVolume vol = datasets::makeSphereVolume(test::grid1mm(), Eigen::Vector3d::Zero(), 0.012);
  const auto tool = test::meshTool(datasets::makeSphereMesh(0.006, 3), 0.5e-3);
  for (int lanes : {1, 2}) {
    CollisionDetector uncut(vol, *tool, 0.0, 256, DetectionMode::kAccelerated);
    CollisionDetector late(vol, *tool, 0.0, 256, DetectionMode::kAccelerated);
    late.setLanes(lanes);
    Pose X0, X1;
    X0.p_AB_m = Eigen::Vector3d(0.001, 0.0, 0.020);
    X1.p_AB_m = Eigen::Vector3d(0.002, 0.001, 0.012);
    const RigidMotion motion = RigidMotion::Between(X0, X1, tool->mass.p_TCm_m);
    const SweepResult reference = uncut.sweep(motion, 0.0);
    ASSERT_GE(reference.hit_point, 0);
    late.resetSampleCount();
    late.setDeadline(std::chrono::steady_clock::now() - std::chrono::milliseconds(1));
    SweepResult r = late.sweep(motion, 0.0);
    EXPECT_TRUE(r.budget_cut) << lanes << " lanes";
    EXPECT_TRUE(late.deadlineReached());
    EXPECT_LE(r.t, reference.t);
    EXPECT_LE(r.t, bruteForceFirstContact(vol, *tool, motion, 0.0) + 1e-12);
    EXPECT_LT(late.work(), 2 * CollisionDetector::kClockCheckWork) << "stops within a chunk of work";
    late.clearDeadline();
    late.resetSampleCount();
    EXPECT_FALSE(late.deadlineReached());
    r = late.resumeSweep();
    EXPECT_FALSE(r.budget_cut);
    EXPECT_EQ(r.t, reference.t) << lanes << " lanes";
  }
}

TEST(CollisionDetector, DefaultEpsilonIsAnEighthOfTheFeatureSize) {
  // Chosen by `volume-haptics bench accuracy` (top README, "Error against run time").
  const ScalarVolume vol = datasets::makePlaneVolume(test::grid1mm(16), Eigen::Vector3d::UnitZ(), 0.0);
  const auto tool = test::pointTool();
  for (const DetectionMode mode : {DetectionMode::kPaper, DetectionMode::kAccelerated}) {
    const CollisionDetector cd(vol, *tool, 0.0, 256, mode);
    EXPECT_DOUBLE_EQ(cd.epsilon_m(), vol.featureSize_m() / 8.0) << toString(mode);
    EXPECT_DOUBLE_EQ(CollisionDetector(vol, *tool, 0.1e-3, 256, mode).epsilon_m(), 0.1e-3) << toString(mode);
  }
}

TEST(CollisionDetector, RejectsEpsilonNotBelowTheFeatureSize) {
  const ScalarVolume vol = datasets::makePlaneVolume(test::grid1mm(16), Eigen::Vector3d::UnitZ(), 0.0);
  const auto tool = test::pointTool();
  EXPECT_THROW(CollisionDetector(vol, *tool, 0.6e-3), std::invalid_argument);
  EXPECT_NO_THROW(CollisionDetector(vol, *tool, 0.4e-3));
}

}  // namespace
}  // namespace vh::haptics
