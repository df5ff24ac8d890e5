// The lanes of the accelerated sweep share its work evenly: after a sweep, the tool's upper
// nodes are dealt again by the work each cost (CollisionDetector::rebalanceLanes()), so the part
// of a tool that grazes a surface, where nearly all the work is, no longer falls to a few lanes.
// Oracle: TickStats' two work counts, all the lanes' work and the tick's critical path (the
// busiest lane per fork, what the budget and the clock wait for): work / (lanes x critical) is 1
// for a perfect share. A free move's work does not depend on timing (no lane's hit shortens
// another's search), so the figures are the same on any machine.
#include <cmath>
#include <iostream>

#include <gtest/gtest.h>

#include "test_tools.h"
#include "vh/haptics/haptic_renderer.h"

namespace vh::haptics {
namespace {

struct Balance {
  double first = 0.0;  // the first tick's share (the round-robin deal)
  double later = 0.0;  // the later ticks' share, summed over them
  int max_contacts = 0;
};

// A 40 x 40 x 4 mm plate (about 5,000 points) tilted about y, its low edge 0.3 mm above the
// plane z = -20 mm, slid along y 0.8 mm a tick without touching: the work lies along the low edge.
Balance grazingPlate(int lanes, double tilt_rad, int ticks) {
  auto volume = std::make_shared<ScalarVolume>(
      datasets::makePlaneVolume(test::grid1mm(96), Eigen::Vector3d::UnitZ(), -0.02));
  const auto tool = test::meshTool(datasets::makeBoxMesh({0.02, 0.02, 0.002}), 0.7e-3);
  RendererOptions o;
  o.detection_mode = DetectionMode::kAccelerated;
  o.solver_lanes = lanes;
  o.work_budget = 0;
  o.deadline_us = 0.0;
  Pose X_WD;
  X_WD.R_AB = Eigen::Quaterniond(Eigen::AngleAxisd(tilt_rad, Eigen::Vector3d::UnitY()));
  const double low_edge_z_m = -0.02 * std::sin(tilt_rad) - 0.002 * std::cos(tilt_rad);
  X_WD.p_AB_m = {0.0, -0.03, -0.02 + 0.0003 - low_edge_z_m};
  HapticRenderer r(volume, tool, o, X_WD, 0.0);
  EXPECT_EQ(r.solverLanes(), lanes);
  Balance b;
  double work = 0.0, critical = 0.0;
  for (int i = 0; i < ticks; ++i) {
    X_WD.p_AB_m.y() += 0.0008;
    const TickOutput out = r.tick(X_WD, 0.0);
    b.max_contacts = std::max(b.max_contacts, out.stats.contacts);
    const double w = static_cast<double>(out.stats.work), c = static_cast<double>(out.stats.critical_work);
    if (i == 0) {
      b.first = w / (lanes * c);
    } else {
      work += w;
      critical += c;
    }
  }
  b.later = work / (lanes * critical);
  return b;
}

TEST(LaneBalance, TheLanesShareAGrazingToolsWorkEvenlyAfterItsFirstSweep) {
  // Dealt round robin on every tick, the lanes' share stayed at 0.63 (4 lanes) and 0.47 (8).
  for (const int lanes : {4, 8}) {
    const Balance b = grazingPlate(lanes, 0.1, 60);
    std::cout << lanes << " lanes: share of the work " << b.first << " on the first tick (round robin), " << b.later
              << " on the next 59\n";
    EXPECT_EQ(b.max_contacts, 0) << "the plate must slide free";
    EXPECT_LT(b.first, 0.7) << "the first deal is round robin: the scene must unbalance it";
    EXPECT_GT(b.later, lanes == 4 ? 0.9 : 0.8) << lanes << " lanes";
  }
}

}  // namespace
}  // namespace vh::haptics
