// The stand-off lift (ConfigurationSolver::standoffTranslation): the translation that lifts the
// contacts closer than half the stand-off to the stand-off must not push the tool into any
// other contact it knows of. The oracle is each contact's half-space, n . d against its bound,
// checked with plain dot products; the contacts are those that held the drill in its cavity in
// the head phantom (normals and clearances printed by the servo at the jammed tick).
#include <array>
#include <span>

#include <gtest/gtest.h>

#include "vh/haptics/configuration_solver.h"

namespace vh::haptics {
namespace {

Contact contact(const Eigen::Vector3d& n, double clearance_m, bool edge) {
  Contact c;
  c.point_index = edge ? -1 : 23;
  c.n_W = n.normalized();
  c.clearance_m = clearance_m;
  if (edge) c.edge_T = Eigen::Vector3d::UnitX();
  return c;
}

constexpr double kStandoff_m = 0.5 * 0.0282e-3;  // half the phantom's epsilon, as after an edge stop

// n . d for each contact against what it allows: the stand-off for the near ones (clearance below
// half the stand-off), no more than half its clearance inwards for the others.
void expectLiftRespects(std::span<const Contact> contacts, const Eigen::Vector3d& d) {
  for (const Contact& c : contacts) {
    const double reach = c.n_W.dot(d);
    if (c.clearance_m < 0.5 * kStandoff_m) {
      EXPECT_GT(reach, 0.0) << "a near contact (clearance " << c.clearance_m << ") is lifted, not approached";
    } else {
      EXPECT_GE(reach, -0.5 * c.clearance_m - 1e-3 * kStandoff_m) << "a far contact is not pushed into";
    }
  }
}

TEST(StandoffLift, ClearsTheEdgeContactThatStoppedTheMoveWhenItIsPassedBeside) {
  // At the jammed tick: the pruned set held three contacts; the edge contact that stopped the
  // lift (the last one) had been dropped, as the device pulled away from it.
  const std::array<Contact, 4> all = {contact({-0.375, 0.841, 0.389}, 1.59e-5, true),
                                      contact({-0.143, -0.627, 0.766}, 1.94e-5, true),
                                      contact({-0.898, 0.098, 0.429}, 1.76e-6, false),
                                      contact({0.511, -0.466, 0.722}, 0.0, true)};
  const std::span<const Contact> pruned(all.data(), 3);
  const Eigen::Vector3d blind = ConfigurationSolver::standoffTranslation(pruned, kStandoff_m);
  EXPECT_LT(all[3].n_W.dot(blind), 0.0) << "without it, the lift heads into the dropped edge contact (the jam)";
  const Eigen::Vector3d d = ConfigurationSolver::standoffTranslation(pruned, kStandoff_m, &all[3]);
  ASSERT_GT(d.norm(), 0.0);
  EXPECT_LE(d.norm(), 2.0 * kStandoff_m * (1.0 + 1e-12)) << "capped";
  expectLiftRespects(all, d);
  // Both near contacts reach the full stand-off (the cap is not hit here).
  EXPECT_NEAR(all[2].n_W.dot(d), kStandoff_m - all[2].clearance_m, 1e-3 * kStandoff_m);
  EXPECT_GE(all[3].n_W.dot(d), kStandoff_m - 1e-3 * kStandoff_m);
}

TEST(StandoffLift, OneContactIsLiftedAlongItsNormal) {
  const Contact c = contact({0.0, 0.0, 1.0}, 0.0, false);
  const Eigen::Vector3d d = ConfigurationSolver::standoffTranslation(std::span<const Contact>(&c, 1), kStandoff_m);
  EXPECT_NEAR(d.z(), kStandoff_m, 1e-15);
  EXPECT_NEAR(d.head<2>().norm(), 0.0, 1e-15);
}

TEST(StandoffLift, NoLiftBetweenFacingContacts) {
  // A burr in a slot narrower than the stand-off allows: touching both walls, no translation
  // lifts one without pushing into the other.
  const std::array<Contact, 2> walls = {contact({1.0, 0.0, 0.0}, 0.0, false), contact({-1.0, 0.0, 0.0}, 0.0, true)};
  const Eigen::Vector3d d = ConfigurationSolver::standoffTranslation(walls, kStandoff_m);
  EXPECT_EQ(d, Eigen::Vector3d::Zero());
}

TEST(StandoffLift, ARestingProxyStaysStill) {
  const Contact c = contact({0.0, 0.0, 1.0}, 0.6 * kStandoff_m, false);
  EXPECT_EQ(ConfigurationSolver::standoffTranslation(std::span<const Contact>(&c, 1), kStandoff_m), Eigen::Vector3d::Zero())
      << "hysteresis: a contact at more than half the stand-off is not lifted";
}

}  // namespace
}  // namespace vh::haptics
