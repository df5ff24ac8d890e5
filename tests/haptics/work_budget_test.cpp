// A tick whose collision-detection work is bounded by construction. The check
// counts work (samples, cells, box queries: CollisionDetector::work()), never wall-clock time.
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <iostream>
#include <string>
#include <vector>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include "test_tools.h"
#include "vh/haptics/crossing_verifier.h"
#include "vh/haptics/haptic_renderer.h"
#include "vh/haptics/penetration.h"

namespace vh::haptics {
namespace {

class WorkBudget : public ::testing::TestWithParam<DetectionMode> {};
INSTANTIATE_TEST_SUITE_P(Modes, WorkBudget, ::testing::Values(DetectionMode::kPaper, DetectionMode::kAccelerated),
                         [](const ::testing::TestParamInfo<DetectionMode>& p) { return std::string(toString(p.param)); });

struct BudgetRun {
  std::int64_t max_work = 0, cuts = 0, deadline_cuts = 0, crossings = 0;
  int longest_cut_run = 0;  // most consecutive ticks the budget cut (one resumed sweep)
  int settle_ticks = 0;     // held ticks after the script until a tick was not cut
  double max_depth_m = 0.0;
  Pose final;
};

// A 5000-point ball over the one-voxel plate: the device teleports from 10 mm above the plate
// to 40 mm below it with a half turn and back, then presses and holds; the unbudgeted ticks of
// the jumps walk thousands of segments.
// `deadline_us` and `lanes`: RendererOptions::deadline_us and solver_lanes. With `settle`, the
// pressed pose is then held while the ticks only resume a cut sweep (cut, and no new sweep
// started: TickStats::sweeps 0), at most 20,000 ticks: it ends at the first tick that is not cut
// or that starts a new move, which it does only once the pending sweep has finished. How many
// ticks a deadline needs for that depends on the machine's load, what it ends with does not; a
// held tick's own cost (pruning and solving up to 64 contacts) may exceed a short deadline on a
// slow or loaded machine, so "not cut" alone would not be reached there.
BudgetRun teleports(DetectionMode mode, std::int64_t budget, double deadline_us = 0.0, int lanes = 1,
                    bool settle = false) {
  auto vol = std::make_shared<const ScalarVolume>(datasets::makeThinPlateVolume(test::grid1mm()));
  const double s = 200.0;  // 0.43 mm thick
  const double z_plate = vol->geometry().origin_W_m.z() + 32e-3;
  PointShellOptions ps;
  ps.point_count = 5000;
  static const auto tool = std::make_shared<const ToolModel>(makeToolModel(datasets::makeSphereMesh(0.010, 4), ps));
  RendererOptions o;
  o.detection_mode = mode;
  o.work_budget = budget;
  o.deadline_us = deadline_us;
  o.solver_lanes = lanes;
  Pose above;
  above.p_AB_m = {0.0, 0.0, z_plate + 0.011};
  HapticRenderer r(vol, tool, o, above, s);
  const CrossingVerifier oracle(*vol, tool->point_shell, 1e-2);
  BudgetRun run;
  int cut_run = 0;
  bool resuming = false;  // the last tick was cut and only resumed a cut sweep
  for (int i = 0; i < 400 || (settle && resuming && run.settle_ticks < 20000); ++i) {
    if (i >= 400) ++run.settle_ticks;
    Pose X_WD = above;
    if (i < 40 && i % 4 == 1) {  // a jump through the plate with a half turn
      X_WD.p_AB_m.z() = z_plate - 0.040;
      X_WD.R_AB = Eigen::Quaterniond(Eigen::AngleAxisd(3.0, Eigen::Vector3d::UnitX()));
    } else if (i >= 40) {  // pressed 3 mm into the plate and held
      X_WD.p_AB_m.z() = z_plate + 0.010 - 0.003;
    }
    const TickOutput out = r.tick(X_WD, s);
    resuming = out.stats.budget_cut && out.stats.sweeps == 0;
    if (std::getenv("VH_BUDGET_TRACE"))
      std::cout << i << " work " << out.stats.work << " cut " << out.stats.budget_cut << " t " << out.stats.time_of_contact
                << " z " << (out.X_WP.p_AB_m.z() - z_plate) * 1e3 << " contacts " << out.stats.contacts << "\n";
    run.max_work = std::max(run.max_work, out.stats.work);
    run.cuts += out.stats.budget_cut;
    run.deadline_cuts += out.stats.deadline_cut;
    if (out.stats.deadline_cut) EXPECT_TRUE(out.stats.budget_cut);
    cut_run = out.stats.budget_cut ? cut_run + 1 : 0;
    run.longest_cut_run = std::max(run.longest_cut_run, cut_run);
    run.max_depth_m = std::max(run.max_depth_m, maxPenetration_m(*vol, tool->point_shell, out.X_WP, s));
    run.crossings += oracle.check(r.lastMotion(), r.lastTimeOfContact(), s).crossing_points > 0;
  }
  run.final = r.proxyPose();
  return run;
}

TEST_P(WorkBudget, NoTickExceedsItsWorkAndTheProxyStillNeverPenetrates) {
  const BudgetRun free_run = teleports(GetParam(), 0);
  constexpr std::int64_t kBudget = 4000;
  // The unbudgeted jumps cost many times the budget (the test bites).
  ASSERT_GT(free_run.max_work, 5 * kBudget);
  const BudgetRun budgeted = teleports(GetParam(), kBudget);
  // Over the budget by at most the pruning of a full contact set (64 contacts, about 8 units
  // each, done before the sweep) and one queue step. The paper's path sets up every point's path
  // before its queue starts (a unit each), so its floor is the point count.
  const std::int64_t floor = GetParam() == DetectionMode::kPaper ? std::max<std::int64_t>(kBudget, 5000) : kBudget;
  EXPECT_LE(budgeted.max_work, floor + 64 * 12 + 200);
  EXPECT_GT(budgeted.cuts, 0);
  EXPECT_EQ(budgeted.crossings, 0);
  EXPECT_EQ(free_run.crossings, 0);
  const double epsilon_m = 0.125 * 0.5e-3;  // f / 8 of the 1 mm grid
  EXPECT_LE(budgeted.max_depth_m, epsilon_m);
  // The rest of the motion was done in later ticks: both end resting on the plate, in the same
  // place. Not in the paper's path: without culling, every sweep samples every point's first
  // segment (5000 here), so a budget below the point count stalls the proxy (safe, documented).
  if (GetParam() == DetectionMode::kAccelerated) {
    // Their contact histories differ (the budgeted proxy arrives later), so to within half a
    // voxel.
    EXPECT_LT((budgeted.final.p_AB_m - free_run.final.p_AB_m).norm(), 0.5e-3);
    // A cut sweep is resumed, never restarted, so every one finishes (the detector's test
    // AResumedSweepGivesTheUncutResult checks that it ends with the uncut result): no run of
    // cut ticks is long. The longest here is one sweep of about 19 budgets.
    EXPECT_LE(budgeted.longest_cut_run, 40);
  }
  std::cout << "work per tick: unbudgeted max " << free_run.max_work << ", budgeted max " << budgeted.max_work
            << " (budget " << kBudget << "), " << budgeted.cuts << " ticks cut, longest run of cut ticks "
            << budgeted.longest_cut_run << "\n";
}

// The deadline on the clock through the renderer (RendererOptions::deadline_us), on 2 lanes and
// without a work budget: a deadline far shorter than the jumps' sweeps cuts ticks and says so
// (TickStats::deadline_cut), the proxy never crosses the plate nor sinks past epsilon, and the
// cut sweeps resume until it rests where the unlimited run rests. Which ticks the clock cuts
// depends on the machine's speed and load; every check below holds whichever they are (the
// jumps' sweeps, tens of thousands of work units, take far longer than 20 us on any machine).
TEST(DeadlineOnTheClock, CutsTicksAndTheProxyNeverCrossesAndCatchesUp) {
  const BudgetRun free_run = teleports(DetectionMode::kAccelerated, 0);
  const BudgetRun late = teleports(DetectionMode::kAccelerated, 0, 20.0, 2, true);
  EXPECT_GT(late.deadline_cuts, 0);
  EXPECT_EQ(late.deadline_cuts, late.cuts) << "no work budget: every cut is the clock's";
  EXPECT_EQ(late.crossings, 0);
  EXPECT_LE(late.max_depth_m, 0.125 * 0.5e-3);
  EXPECT_LT(late.settle_ticks, 20000) << "a cut sweep never finished";  // resumed ticks only
  EXPECT_LT((late.final.p_AB_m - free_run.final.p_AB_m).norm(), 0.5e-3);
  EXPECT_EQ(free_run.deadline_cuts, 0);
  std::cout << "deadline 20 us on 2 lanes: " << late.deadline_cuts << " ticks cut by the clock, longest run "
            << late.longest_cut_run << ", " << late.settle_ticks << " ticks held after the script until one was not cut, final proxy "
            << 1e3 * (late.final.p_AB_m - free_run.final.p_AB_m).norm() << " mm from the unlimited run's\n";
}

// A tick the clock cut, repeated without a clock (a replay's case): given the live tick's
// TickStats::deadline_work, HapticRenderer::cutNextTickAtWork() stops the same work, so every
// tick after it repeats the live one bit for bit; without it the repeat does the whole tick and
// parts from the live run at the first cut (so the comparison can fail). The live run's cuts
// depend on the machine; the equality holds whichever ticks they are.
TEST(DeadlineOnTheClock, ATickTheClockCutRepeatsBitForBitFromItsWork) {
  struct Case {
    DetectionMode mode;
    int edge_test;
  };
  for (const Case c : {Case{DetectionMode::kAccelerated, 0}, Case{DetectionMode::kPaper, 0},
                       Case{DetectionMode::kAccelerated, 1}}) {
    const DetectionMode mode = c.mode;
    const std::string name = std::string(toString(mode)) + (c.edge_test != 0 ? " with the edge test" : "");
    SCOPED_TRACE(name);
    auto vol = std::make_shared<const ScalarVolume>(datasets::makeThinPlateVolume(test::grid1mm()));
    const double s = 200.0;
    const double z_plate = vol->geometry().origin_W_m.z() + 32e-3;
    PointShellOptions ps;
    ps.point_count = 3000;
    const auto tool = std::make_shared<const ToolModel>(makeToolModel(datasets::makeSphereMesh(0.010, 4), ps));
    RendererOptions o;
    o.detection_mode = mode;
    o.edge_test = c.edge_test;
    Pose above;
    above.p_AB_m = {0.0, 0.0, z_plate + 0.011};
    std::vector<Pose> script;
    for (int i = 0; i < 200; ++i) {
      Pose X_WD = above;
      if (i < 40 && i % 4 == 1) {  // jumps through the plate with a half turn: long sweeps
        X_WD.p_AB_m.z() = z_plate - 0.040;
        X_WD.R_AB = Eigen::Quaterniond(Eigen::AngleAxisd(3.0, Eigen::Vector3d::UnitX()));
      } else if (i >= 40) {
        X_WD.p_AB_m.z() = z_plate + 0.010 - 0.003 + 1e-4 * std::sin(0.1 * i);
      }
      script.push_back(X_WD);
    }
    RendererOptions live_options = o;
    live_options.deadline_us = 20.0;
    HapticRenderer live(vol, tool, live_options, above, s);
    std::vector<TickOutput> ticks;
    int cuts = 0;
    for (const Pose& X_WD : script) {
      ticks.push_back(live.tick(X_WD, s));
      if (ticks.back().stats.deadline_cut) {
        ++cuts;
        EXPECT_GT(ticks.back().stats.deadline_work, 0);
      } else {
        EXPECT_EQ(ticks.back().stats.deadline_work, 0);
      }
    }
    ASSERT_GT(cuts, 0) << "a 20 us deadline cuts the jumps' sweeps on any machine";
    const auto repeat = [&](bool with_work, std::size_t& first_difference) {
      HapticRenderer r(vol, tool, o, above, s);
      first_difference = script.size();
      for (std::size_t i = 0; i < script.size(); ++i) {
        if (with_work) r.cutNextTickAtWork(ticks[i].stats.deadline_work);
        const TickOutput out = r.tick(script[i], s);
        const bool same = out.X_WP.p_AB_m == ticks[i].X_WP.p_AB_m && out.X_WP.R_AB.coeffs() == ticks[i].X_WP.R_AB.coeffs() &&
                          out.force_W_N == ticks[i].force_W_N && out.torque_W_Nm == ticks[i].torque_W_Nm &&
                          out.stats.budget_cut == ticks[i].stats.budget_cut;
        if (!same) {
          first_difference = i;
          return;
        }
      }
    };
    std::size_t with_work = 0, without = 0;
    repeat(true, with_work);
    repeat(false, without);
    EXPECT_EQ(with_work, script.size()) << "the repeat parted from the live run at tick " << with_work;
    EXPECT_LT(without, script.size()) << "without the cut's work the repeat does whole ticks";
    std::cout << name << ": " << cuts << " of " << script.size()
              << " ticks cut by the clock; repeated from their work: identical; without it: parts at tick " << without
              << "\n";
  }
}

}  // namespace
}  // namespace vh::haptics
