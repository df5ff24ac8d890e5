// Both detection modes give the same answers. The accelerated path skips only runs of
// segments that the min-max tree proves free of inside points and samples the rest exactly as
// the paper's path does, so its first time of contact is the same double; the contact set is
// the same set. The one documented difference: when two points reach the surface at exactly the
// same time, each path reports the one its queue meets first (the accelerated path prefers the
// lower index among those it has popped); each path adds its own hit point to the contact set
// unconditionally, so the two sets can then differ in those two points only.
#include <algorithm>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "test_tools.h"
#include "vh/haptics/collision_detector.h"
#include "vh/haptics/haptic_renderer.h"

namespace vh::haptics {
namespace {

std::vector<int> contactPoints(const CollisionDetector& cd) {
  std::vector<int> points;
  for (const Contact& c : cd.contacts()) points.push_back(c.point_index);
  std::sort(points.begin(), points.end());
  return points;
}

// Random motions of a tool around a surface, with a random isovalue on every motion (the same
// detectors throughout: nothing may depend on the previous isovalue).
// `lanes`: the accelerated sweep on that many cores (CollisionDetector::setLanes()).
void checkEquivalentOnRandomMotions(const ScalarVolume& vol, const ToolModel& tool, double s_lo, double s_hi,
                                    double reach_m, std::uint32_t seed, int lanes = 1) {
  CollisionDetector paper(vol, tool, 0.0, 256, DetectionMode::kPaper);
  CollisionDetector fast(vol, tool, 0.0, 256, DetectionMode::kAccelerated);
  fast.setLanes(lanes);
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0), s_dist(s_lo, s_hi);
  int hits = 0, tie_breaks = 0;
  std::int64_t samples_paper = 0, samples_fast = 0;
  for (int n = 0; n < 400; ++n) {
    const double s = s_dist(rng);
    Pose X0, X1;
    X0.p_AB_m = reach_m * Eigen::Vector3d(u(rng), u(rng), u(rng));
    X0.R_AB = Eigen::Quaterniond(u(rng), u(rng), u(rng), u(rng)).normalized();
    // Short (servo-tick) and long (jump) motions, with and without rotation.
    const double step = (n % 4 == 0) ? reach_m : 0.05 * reach_m;
    X1.p_AB_m = X0.p_AB_m + step * Eigen::Vector3d(u(rng), u(rng), u(rng));
    X1.R_AB = (n % 2 == 0) ? X0.R_AB
                           : Eigen::Quaterniond(Eigen::AngleAxisd(0.5 * u(rng), Eigen::Vector3d(u(rng), u(rng), u(rng)).normalized())) * X0.R_AB;
    const RigidMotion motion = RigidMotion::Between(X0, X1, tool.mass.p_TCm_m);
    paper.clearContacts();
    fast.clearContacts();
    ASSERT_EQ(fast.updateEmbedded(X0, s), paper.updateEmbedded(X0, s)) << "motion " << n;
    paper.resetSampleCount();
    fast.resetSampleCount();
    const SweepResult rp = paper.sweep(motion, s);
    const SweepResult rf = fast.sweep(motion, s);
    samples_paper += paper.sampleCount();
    samples_fast += fast.sampleCount();
    ASSERT_EQ(rf.t, rp.t) << "motion " << n;  // bit for bit: the same samples, the same bisection
    ASSERT_EQ(rf.hit_point < 0, rp.hit_point < 0) << "motion " << n;
    if (rp.hit_point < 0) continue;
    ++hits;
    if (rf.hit_point != rp.hit_point) ++tie_breaks;  // equal times (asserted above): a tie
    else EXPECT_EQ(rf.t_inside, rp.t_inside) << "motion " << n;  // a tied point's bracket is its own
    paper.addContactsAt(motion, rp, s);
    fast.addContactsAt(motion, rf, s);
    std::vector<int> set_paper = contactPoints(paper), set_fast = contactPoints(fast);
    if (rf.hit_point != rp.hit_point) {
      // Each path adds its own hit point unconditionally; the other tied point joins only when
      // its epsilon look-ahead is inside. Compare the rest.
      for (std::vector<int>* set : {&set_paper, &set_fast})
        std::erase_if(*set, [&](int j) { return j == rp.hit_point || j == rf.hit_point; });
    }
    EXPECT_EQ(set_fast, set_paper) << "motion " << n << ", hit points " << rp.hit_point << " / " << rf.hit_point;
  }
  EXPECT_GT(hits, 40) << "the random motions must exercise contacts";
  ::testing::Test::RecordProperty("hits", hits);
  ::testing::Test::RecordProperty("tie_breaks", tie_breaks);
  std::cout << lanes << " lane(s): " << hits << " contacts, " << tie_breaks << " tie breaks; sweep samples paper " << samples_paper
            << ", accelerated " << samples_fast << "\n";
}

TEST(DetectionEquivalence, SphereVolumeWithARotatingBoxTool) {
  const ScalarVolume vol = datasets::makeSphereVolume(test::grid1mm(), Eigen::Vector3d::Zero(), 0.015);
  const auto tool = test::meshTool(datasets::makeBoxMesh({0.004, 0.003, 0.002}), 1e-3);
  checkEquivalentOnRandomMotions(vol, *tool, -3.0, 3.0, 0.02, 11);
}

TEST(DetectionEquivalence, HoleBlockWithThePeg) {
  const ScalarVolume vol = datasets::makeBlockWithBlindHoleVolume(128, -0.004);
  PointShellOptions ps;
  ps.point_count = 400;
  const ToolModel tool = makeToolModel(datasets::makeCylinderMesh(datasets::kPegRadius_m, 0.02, 32), ps);
  checkEquivalentOnRandomMotions(vol, tool, 60.0, 200.0, 0.02, 12);
}

TEST(DetectionEquivalence, OneVoxelPlateUInt8) {
  datasets::GridSpec g = test::grid1mm(48);
  const ScalarVolume vol = datasets::makeThinPlateVolume(g);
  const auto tool = test::meshTool(datasets::makeSphereMesh(0.004, 2), 1e-3);
  checkEquivalentOnRandomMotions(vol, *tool, 20.0, 230.0, 0.015, 13);
}

// Several lanes (the sweep on several cores): the same first time of contact, bit for bit, as
// the paper's path; the lanes share the point-shell tree round robin on the first sweep and by
// each node's work after it, so every lane count from 2 to 5, and every motion, deals the points
// differently.
TEST(DetectionEquivalence, LanesGiveThePapersResult) {
  const ScalarVolume sphere = datasets::makeSphereVolume(test::grid1mm(), Eigen::Vector3d::Zero(), 0.015);
  const auto box = test::meshTool(datasets::makeBoxMesh({0.004, 0.003, 0.002}), 0.5e-3);
  const ScalarVolume block = datasets::makeBlockWithBlindHoleVolume(128, -0.004);
  PointShellOptions ps;
  ps.point_count = 400;
  const ToolModel peg = makeToolModel(datasets::makeCylinderMesh(datasets::kPegRadius_m, 0.02, 32), ps);
  for (int lanes = 2; lanes <= 5; ++lanes) {
    checkEquivalentOnRandomMotions(sphere, *box, -3.0, 3.0, 0.02, 21 + lanes, lanes);
    checkEquivalentOnRandomMotions(block, peg, 60.0, 200.0, 0.02, 31 + lanes, lanes);
  }
}

// Whole runs: the scripted peg descent gives the same proxy path in both modes (the contact
// order can differ only after a tie break, so the poses are compared to 1e-9 m, not bit for bit).
// Also with the accelerated sweep on 3 lanes (RendererOptions::solver_lanes).
class RendererRuns : public ::testing::TestWithParam<int> {};
INSTANTIATE_TEST_SUITE_P(Lanes, RendererRuns, ::testing::Values(1, 3));
TEST_P(RendererRuns, AgreeTickByTick) {
  auto vol = std::make_shared<ScalarVolume>(datasets::makeBlockWithBlindHoleVolume(128, -0.004));
  PointShellOptions ps;
  ps.point_count = 600;
  auto tool = std::make_shared<ToolModel>(makeToolModel(datasets::makeCylinderMesh(datasets::kPegRadius_m, 0.04, 32), ps));
  RendererOptions op, of;
  op.detection_mode = DetectionMode::kPaper;
  of.detection_mode = DetectionMode::kAccelerated;
  op.work_budget = of.work_budget = 0;  // the paths, not the budget (a cut tick moves less far)
  of.stuck_standoff_fraction = 0.0;     // nor the lift after a stuck contact (not in the paper)
  of.solver_lanes = GetParam();
  const Pose start = Pose::FromTranslation({0.012, 0.0, 0.016});
  HapticRenderer rp(vol, tool, op, start, datasets::kBlockIsovalue);
  HapticRenderer rf(vol, tool, of, start, datasets::kBlockIsovalue);
  std::int64_t samples_paper = 0, samples_fast = 0;
  double max_difference_m = 0.0;
  for (int i = 0; i <= 1500; ++i) {
    const double u = i / 1500.0;
    // Press on the top face, slide over the hole, descend; the isovalue steps at the end.
    Pose X_WD = start;
    X_WD.p_AB_m = u < 0.5 ? Eigen::Vector3d(0.012 * (1.0 - 2.0 * u), 0.0, 0.010)
                          : Eigen::Vector3d(0.0, 0.0, 0.010 - 0.036 * (u - 0.5));
    const double s = i < 1400 ? datasets::kBlockIsovalue : 100.0;
    const TickOutput a = rp.tick(X_WD, s), b = rf.tick(X_WD, s);
    samples_paper += a.stats.volume_samples;
    samples_fast += b.stats.volume_samples;
    max_difference_m = std::max(max_difference_m, (a.X_WP.p_AB_m - b.X_WP.p_AB_m).norm());
    ASSERT_LT((a.X_WP.p_AB_m - b.X_WP.p_AB_m).norm(), 1e-9) << "tick " << i;
    ASSERT_LT(a.X_WP.R_AB.angularDistance(b.X_WP.R_AB), 1e-9) << "tick " << i;
    ASSERT_EQ(a.stats.contacts, b.stats.contacts) << "tick " << i;
  }
  EXPECT_LT(samples_fast, samples_paper);  // the point of the accelerated path
  std::cout << "samples paper " << samples_paper << ", accelerated " << samples_fast << ", max pose difference "
            << max_difference_m << " m\n";
}

}  // namespace
}  // namespace vh::haptics
