// Tests of vh/runtime/passivity_port.h: the passivity controller's state (observed energy,
// stiffness schedule) survives a gain change, the rendered stiffness does not step to the new
// gain while the hand presses, and it reaches the new gain in free space.
#include "vh/runtime/passivity_port.h"

#include <cmath>

#include <gtest/gtest.h>

namespace vh::runtime {
namespace {

constexpr double kT_s = 1e-3;

/// A wall at q = 0 along x: penetration q > 0 gives the spring's effort -k q on the hand.
Eigen::Vector3d wallEffort(double k_N_per_m, double q_m) { return {-k_N_per_m * std::max(q_m, 0.0), 0.0, 0.0}; }
double stored_J(double k_N_per_m, double q_m) { return 0.5 * k_N_per_m * q_m * q_m; }

/// Presses 2 mm into a 1000 N/m wall over 20 ticks and holds: the port absorbs k q^2 / 2.
void pressIn(PassivityPort& port, double k_N_per_m, double& q_m) {
  for (int i = 0; i < 20; ++i) {
    const double dq = 1e-4;
    q_m += dq;
    port.step(wallEffort(k_N_per_m, q_m), {dq, 0.0, 0.0}, kT_s, stored_J(k_N_per_m, q_m));
  }
  for (int i = 0; i < 10; ++i) port.step(wallEffort(k_N_per_m, q_m), Eigen::Vector3d::Zero(), kT_s, stored_J(k_N_per_m, q_m));
}

TEST(PassivityPort, AGainChangeKeepsTheEnergyStateAndTheRenderedStiffness) {
  const double k_old = 1000.0, k_new = 20000.0, rating = 1000.0;
  PassivityPort port;
  port.configure(k_old, rating);
  double q = 0.0;
  pressIn(port, k_old, q);
  // The observer holds the work the hand did on the spring through the one-tick-delayed command:
  // sum over the press of k q(k-2) dq = k dq^2 (1 + 2 + ... + 18) = 171 k dq^2.
  const double energy_before_J = port.controller().observedEnergy_J();
  ASSERT_NEAR(energy_before_J, 171.0 * k_old * 1e-8, 1e-12);

  port.setStiffness(k_new, rating);  // 20x, while pressing
  EXPECT_NEAR(port.renderedStiffness(), k_old, 1e-9) << "the rendered stiffness stepped";
  EXPECT_NEAR(port.transition(), k_old / k_new, 1e-15);
  // The next ticks at the new gain: the hand feels the old stiffness, the energy state is kept.
  for (int i = 0; i < 50; ++i) {
    const auto out = port.step(wallEffort(k_new, q), Eigen::Vector3d::Zero(), kT_s, stored_J(k_new, q));
    ASSERT_NEAR(out.effort_W.x(), -k_old * q, 1e-9) << "tick " << i << ": jumped to the new gain";
  }
  EXPECT_NEAR(port.controller().observedEnergy_J(), energy_before_J, 1e-12);
}

TEST(PassivityPort, TheNewGainIsReachedInFreeSpaceAtTheScheduleRecoveryRate) {
  const double k_old = 1000.0, k_new = 20000.0, rating = 1000.0;
  PassivityPort port;
  port.configure(k_old, rating);
  double q = 0.0;
  pressIn(port, k_old, q);
  port.setStiffness(k_new, rating);
  // Leaves the wall: free space (zero effort). h climbs at 1 / gain_recovery_s (0.5 s): from
  // 0.05 to 1 in about 0.475 s.
  const double recovery_s = haptics::PassivityOptions{}.gain_recovery_s;
  int ticks = 0;
  while (port.transition() < 1.0 && ticks < 2000) {
    port.step(Eigen::Vector3d::Zero(), {-1e-4, 0.0, 0.0}, kT_s, 0.0);
    ++ticks;
  }
  EXPECT_NEAR(ticks * kT_s, (1.0 - k_old / k_new) * recovery_s, 0.01);
  EXPECT_NEAR(port.renderedStiffness(), k_new, 1e-9);
  // Pressing again: the full new gain (with its schedule floored at the rating).
  const auto out = port.step(wallEffort(k_new, 1e-3), Eigen::Vector3d::Zero(), kT_s, stored_J(k_new, 1e-3));
  EXPECT_NEAR(out.effort_W.x(), -k_new * 1e-3, 1e-9);
}

TEST(PassivityPort, ASofterGainAppliesAtOnce) {
  PassivityPort port;
  port.configure(5000.0, 1000.0);
  double q = 0.0;
  pressIn(port, 5000.0, q);
  port.setStiffness(2000.0, 1000.0);
  EXPECT_EQ(port.transition(), 1.0);
  const auto out = port.step(wallEffort(2000.0, q), Eigen::Vector3d::Zero(), kT_s, stored_J(2000.0, q));
  EXPECT_NEAR(out.effort_W.x(), -2000.0 * q, 1e-9);
}

}  // namespace
}  // namespace vh::runtime
