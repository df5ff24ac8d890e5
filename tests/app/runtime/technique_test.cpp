// The technique rules (technique.h): each rule against a scripted tick sequence whose answer is
// known from the rule's definition (hold times, the clear time, the speed of a uniform motion),
// the shaft's contacts against their distance from the burr, and no allocation per tick.
#include "vh/runtime/technique.h"

#include <cmath>
#include <limits>
#include <vector>

#include <gtest/gtest.h>

#include "allocation_guard.h"

namespace vh::runtime {
namespace {

constexpr double kDt = 0.001;

TechniqueSample at(double t_s) {
  TechniqueSample s;
  s.time_s = t_s;
  return s;
}

/// Runs `ticks` ticks from t0 with `make(t)` and returns the first time the rule's bit was on
/// (NaN if never).
template <class Make>
double firstActive(TechniqueMonitor& m, std::uint32_t bit, double t0, int ticks, Make make) {
  double first = std::numeric_limits<double>::quiet_NaN();
  for (int i = 0; i < ticks; ++i) {
    const double t = t0 + i * kDt;
    if ((m.update(make(t)) & bit) && std::isnan(first)) first = t;
  }
  return first;
}

TEST(TechniqueRules, ForceRuleWaitsForItsHoldTimeAndGivesOneEpisodePerPush) {
  TechniqueRules rules;  // 3 N, 0.5 s hold, 0.5 s clear
  TechniqueMonitor m(rules);
  auto push = [](double force_N) {
    return [force_N](double t) {
      TechniqueSample s = at(t);
      s.force_N = force_N;
      return s;
    };
  };
  // 0.4 s above the level: shorter than the hold, never active.
  EXPECT_TRUE(std::isnan(firstActive(m, kTechniqueForce, 0.0, 400, push(4.0))));
  EXPECT_TRUE(std::isnan(firstActive(m, kTechniqueForce, 0.4, 100, push(1.0))));
  // 1 s above: active once the push has lasted 0.5 s.
  const double on = firstActive(m, kTechniqueForce, 0.5, 1000, push(4.0));
  EXPECT_NEAR(on, 1.0, 1.5 * kDt);
  EXPECT_EQ(m.episodes(0), 1u);
  // A 0.3 s dip (shorter than clear_s) and back: the same episode.
  firstActive(m, kTechniqueForce, 1.5, 300, push(1.0));
  EXPECT_TRUE(m.active() & kTechniqueForce);
  firstActive(m, kTechniqueForce, 1.8, 700, push(4.0));
  EXPECT_EQ(m.episodes(0), 1u);
  // 0.6 s below: the rule ends; a new long push is a second episode.
  firstActive(m, kTechniqueForce, 2.5, 600, push(1.0));
  EXPECT_FALSE(m.active() & kTechniqueForce);
  firstActive(m, kTechniqueForce, 3.1, 600, push(4.0));
  EXPECT_EQ(m.episodes(0), 2u);
  // Exactly at the level is not above it.
  TechniqueMonitor level(rules);
  EXPECT_TRUE(std::isnan(firstActive(level, kTechniqueForce, 0.0, 1000, push(3.0))));
}

TEST(TechniqueRules, SafeLevelPerMaterialIgnoresCaseAndFallsBackToTheDefault) {
  TechniqueRules rules;
  rules.safe_force_N = 2.5;
  rules.safe_force_by_material_N = {{"Facial Nerve", 0.5}, {"cortical bone", 4.0}};
  EXPECT_DOUBLE_EQ(rules.safeForceFor("facial nerve"), 0.5);
  EXPECT_DOUBLE_EQ(rules.safeForceFor("CORTICAL BONE"), 4.0);
  EXPECT_DOUBLE_EQ(rules.safeForceFor("cancellous bone"), 2.5);
  EXPECT_DOUBLE_EQ(rules.safeForceFor(""), 2.5);
}

/// A tool moving along x at speed v [m/s], `distance_m` from its nearest critical segment.
auto moving(double v_m_per_s, double distance_m) {
  return [=](double t) {
    TechniqueSample s = at(t);
    s.p_W_m = Eigen::Vector3d(v_m_per_s * t, 0.01, -0.02);
    s.nearest_critical_m = distance_m;
    return s;
  };
}

TEST(TechniqueRules, SpeedRuleOnlyNearACriticalSegmentAndOnlyAboveTheLimit) {
  TechniqueRules rules;  // 10 mm/s within 3 mm
  {
    TechniqueMonitor m(rules);
    const double on = firstActive(m, kTechniqueSpeed, 0.0, 500, moving(0.02, 0.002));
    ASSERT_FALSE(std::isnan(on));
    // The filtered speed crosses 10 mm/s when 1 - exp(-t / 20 ms) = 1/2: t = 20 ms ln 2.
    EXPECT_NEAR(on, 0.02 * std::log(2.0), 2 * kDt);
    // It converges to the true speed.
    EXPECT_NEAR(m.speed_m_per_s(), 0.02, 0.02 * 1e-3);
  }
  {
    TechniqueMonitor slow(rules);
    EXPECT_TRUE(std::isnan(firstActive(slow, kTechniqueSpeed, 0.0, 1000, moving(0.005, 0.002))));
    TechniqueMonitor far(rules);
    EXPECT_TRUE(std::isnan(firstActive(far, kTechniqueSpeed, 0.0, 1000, moving(0.02, 0.005))));
    TechniqueMonitor none(rules);  // no critical segment: +inf
    EXPECT_TRUE(std::isnan(
        firstActive(none, kTechniqueSpeed, 0.0, 1000, moving(0.05, std::numeric_limits<double>::infinity()))));
  }
}

TEST(TechniqueRules, ShaftContactsAreThoseOutsideTheBurrByTheMargin) {
  const Eigen::Vector3d c_T(0, 0, 0.001);
  std::vector<haptics::Contact> contacts(4);
  contacts[0].p_T_m = c_T + Eigen::Vector3d(0.0025, 0, 0);         // on the burr's sphere
  contacts[1].p_T_m = c_T + Eigen::Vector3d(0, 0.0029, 0);         // 0.4 mm outside: within the margin
  contacts[2].p_T_m = c_T + Eigen::Vector3d(0, 0, 0.0031);         // 0.6 mm outside: the shaft
  contacts[3].p_T_m = c_T + Eigen::Vector3d(0.004, 0.004, 0.004);  // far up the shaft
  EXPECT_EQ(shaftContacts(contacts, c_T, 0.0025, 0.0005), 2);
  EXPECT_EQ(shaftContacts(contacts, c_T, 0.0025, 0.0), 3);
  EXPECT_EQ(shaftContacts({}, c_T, 0.0025, 0.0005), 0);
}

TEST(TechniqueRules, ShaftRuleNeedsTheBurrSpinningForItsHoldTime) {
  TechniqueRules rules;  // 0.1 s hold
  auto shaft = [](bool burr_on) {
    return [burr_on](double t) {
      TechniqueSample s = at(t);
      s.burr_on = burr_on;
      s.shaft_contacts = 2;
      return s;
    };
  };
  TechniqueMonitor off(rules);
  EXPECT_TRUE(std::isnan(firstActive(off, kTechniqueShaft, 0.0, 1000, shaft(false))));
  TechniqueMonitor on(rules);
  EXPECT_NEAR(firstActive(on, kTechniqueShaft, 0.0, 1000, shaft(true)), 0.1, 1.5 * kDt);
}

TEST(TechniqueRules, OffMeansNoRuleAndBadSettingsAreRefusedNamingTheField) {
  TechniqueRules rules;
  rules.on = false;
  TechniqueMonitor m(rules);
  TechniqueSample s = at(0.0);
  s.force_N = 100.0;
  s.burr_on = true;
  s.shaft_contacts = 5;
  for (int i = 0; i < 2000; ++i) {
    s.time_s = i * kDt;
    EXPECT_EQ(m.update(s), 0u);
  }
  TechniqueRules bad;
  bad.safe_force_N = -1.0;
  EXPECT_THROW(bad.validate(), std::invalid_argument);
  bad = {};
  bad.max_speed_near_critical_m_per_s = std::nan("");
  try {
    bad.validate();
    FAIL() << "a NaN speed limit was taken";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("max_speed_near_critical_m_per_s"), std::string::npos) << e.what();
  }
  bad = {};
  bad.safe_force_by_material_N["dura"] = 0.0;
  EXPECT_THROW(bad.validate(), std::invalid_argument);
  EXPECT_NO_THROW(TechniqueRules{}.validate());
}

TEST(TechniqueRules, AnUpdateNeitherAllocatesNorTakesANaNPose) {
  TechniqueMonitor m;
  TechniqueSample s = at(0.0);
  s.force_N = 5.0;
  vh::test::AllocationGuard guard;
  for (int i = 0; i < 2000; ++i) {
    s.time_s = i * kDt;
    s.p_W_m = i == 700 ? Eigen::Vector3d::Constant(std::nan("")) : Eigen::Vector3d(0.001 * s.time_s, 0, 0);
    m.update(s);
  }
  EXPECT_EQ(guard.count(), 0u);
  EXPECT_TRUE(std::isfinite(m.speed_m_per_s()));
  EXPECT_NEAR(m.speed_m_per_s(), 0.001, 1e-6);
  EXPECT_TRUE(m.active() & kTechniqueForce);
}

}  // namespace
}  // namespace vh::runtime
