// The technique rules (technique.h): each rule against a scripted tick sequence whose answer is
// known from the rule's definition (hold times, the clear time, the speed of a uniform motion),
// the shaft's contacts against their distance from the burr, and no allocation per tick.
#include "vh/runtime/technique.h"

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string>
#include <limits>
#include <vector>

#include <gtest/gtest.h>

#include "allocation_guard.h"
#include "vh/runtime/recording.h"
#include "vh/runtime/runner.h"
#include "vh/runtime/scene.h"
#include "vh/runtime/session_metadata.h"
#include "vh/runtime/session_metrics.h"

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

// A placement (Touch the Surface, Home: the tools put somewhere, not moved by the hand) near a
// critical segment: a 40 mm jump in one tick is 40 m/s as a difference, which fires the speed
// rule; flagged as placed it is no motion and the rule stays quiet while the hand stays still.
TEST(TechniqueRules, APlacementIsNotTheHandsSpeed) {
  for (const bool placed : {false, true}) {
    TechniqueMonitor m{TechniqueRules{}};
    bool fired = false;
    for (int i = 0; i < 300; ++i) {
      TechniqueSample s = at(i * kDt);
      s.p_W_m = Eigen::Vector3d(i < 100 ? 0.0 : 0.040, 0.01, -0.02);
      s.nearest_critical_m = 0.002;
      s.placed = placed && i == 100;
      fired = fired || (m.update(s) & kTechniqueSpeed) != 0;
    }
    EXPECT_EQ(fired, !placed) << (placed ? "flagged as a placement" : "the same jump as the hand's");
    if (placed) EXPECT_EQ(m.speed_m_per_s(), 0.0);
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

TEST(TechniqueScene, TheSectionSetsEveryRuleAndItsAbsenceKeepsTheDefaults) {
  const SceneSpec defaults = parseScene(R"({"volume": {"path": "builtin:plane"}})", "d.json", {});
  EXPECT_TRUE(defaults.technique.on);
  EXPECT_DOUBLE_EQ(defaults.technique.safe_force_N, TechniqueRules{}.safe_force_N);
  const SceneSpec set = parseScene(R"({"volume": {"path": "builtin:plane"},
      "technique": {"on": true, "safe_force_N": 2.0, "safe_force_by_material_N": {"facial nerve": 0.4},
                    "force_hold_s": 0.3, "near_critical_m": 0.002, "max_speed_near_critical_m_per_s": 0.005,
                    "shaft_margin_m": 0.001, "shaft_hold_s": 0.2, "clear_s": 1.0}})",
                                   "s.json", {});
  const TechniqueRules& r = set.technique;
  EXPECT_DOUBLE_EQ(r.safe_force_N, 2.0);
  EXPECT_DOUBLE_EQ(r.safeForceFor("Facial Nerve"), 0.4);
  EXPECT_DOUBLE_EQ(r.force_hold_s, 0.3);
  EXPECT_DOUBLE_EQ(r.near_critical_m, 0.002);
  EXPECT_DOUBLE_EQ(r.max_speed_near_critical_m_per_s, 0.005);
  EXPECT_DOUBLE_EQ(r.shaft_margin_m, 0.001);
  EXPECT_DOUBLE_EQ(r.shaft_hold_s, 0.2);
  EXPECT_DOUBLE_EQ(r.clear_s, 1.0);
  EXPECT_FALSE(parseScene(R"({"volume": {"path": "builtin:plane"}, "technique": {"on": false}})", "o.json", {})
                   .technique.on);
}

TEST(TechniqueScene, BadValuesAreRefusedNamingTheField) {
  const auto error = [](const std::string& technique) {
    try {
      parseScene(R"({"volume": {"path": "builtin:plane"}, "technique": )" + technique + "}", "t.json", {});
    } catch (const std::runtime_error& e) {
      return std::string(e.what());
    }
    return std::string("(taken)");
  };
  EXPECT_NE(error(R"({"safe_force_N": 0})").find("technique.safe_force_N"), std::string::npos);
  EXPECT_NE(error(R"({"safe_force_by_material_N": {"dura": -1}})").find("technique.safe_force_by_material_N.dura"),
            std::string::npos);
  EXPECT_NE(error(R"({"safe_force_by_material_N": 3})").find("expected an object"), std::string::npos);
  EXPECT_NE(error(R"({"force_hold_s": -0.1})").find("technique.force_hold_s"), std::string::npos);
  EXPECT_NE(error(R"({"max_speed_mm_per_s": 10})").find("unknown key 'max_speed_mm_per_s'"), std::string::npos);
}

/// The built-in drilling scene (the synthetic sphere, radius 20 mm, top at z = 20 mm; the
/// drill's 2.5 mm burr at T's origin), its sphere `hardness_J_per_mm3` hard, with `technique`.
SceneSpec drillingSphere(const std::string& technique, double hardness_J_per_mm3) {
  return parseScene(R"({"volume": {"path": "builtin:sphere", "isovalue": 0},
      "tool": {"mesh": "builtin:drill", "point_spacing_m": 0.001},
      "coupling": {"linear_N_per_m": 400, "angular_Nm_per_rad": 1.0},
      "drill": {"on": true, "burr_radius_m": 0.0025, "hardness": {"tissue": )" +
                        std::to_string(hardness_J_per_mm3) + R"(}},
      "technique": )" + technique + "}",
                    "sphere-drill.json", {});
}

/// Above the sphere until 0.5 s, pressed 12 mm below its top by 1 s, held until 3 s.
Trajectory pressIntoTheSphere() {
  std::vector<TrajectorySample> keys;
  for (const auto& [t, z] : {std::pair{0.0, 0.030}, {0.5, 0.030}, {1.0, 0.008}, {3.0, 0.008}}) {
    TrajectorySample k;
    k.t_s = t;
    k.X_WD = haptics::Pose::FromTranslation({0.0, 0.0, z});
    keys.push_back(k);
  }
  return Trajectory(keys);
}

// A headless drilling run: the hand pushes on bone too hard to cut fast, so |F| stays above the
// safe level. The recording's "technique" events must come exactly where the rule says, as
// recomputed here from the recorded forces (the first tick at which |F| has been above the level
// for force_hold_s), and the run report counts the same episodes; a level above every force the
// run reaches gives none.
TEST(TechniqueRun, APushAboveTheSafeLevelIsRecordedWhereTheRuleSaysAndCounted) {
  const std::filesystem::path dir = std::filesystem::path(VH_TEST_OUTPUT_DIR) / "technique-run";
  std::filesystem::create_directories(dir);
  const LoadedScene scene = loadScene(drillingSphere(R"({"safe_force_N": 2.0, "force_hold_s": 0.25})", 50.0));
  RunOptions options;
  options.verify_step_voxels = 0.0;
  options.lag_reference = false;
  options.record = dir / "push.vhrec";
  const RunReport report = runHeadless(scene, pressIntoTheSphere(), options);
  ASSERT_GT(report.max_force_N, 2.0) << "the push must exceed the level for the test to mean anything";
  const Recording rec = readRecording(options.record);
  // The oracle: the first record at which every record of the last 0.25 s had |F| > 2 N.
  double expected_s = -1.0, above_since = -1.0;
  for (const TickRecord& r : rec.records) {
    const double f = Eigen::Vector3d(r.force_W_N[0], r.force_W_N[1], r.force_W_N[2]).norm();
    if (f <= 2.0) {
      above_since = -1.0;
      continue;
    }
    if (above_since < 0.0) above_since = r.time_s;
    if (r.time_s - above_since >= 0.25 - 1e-9) {
      expected_s = r.time_s;
      break;
    }
  }
  ASSERT_GE(expected_s, 0.0) << "the run never pushed above 2 N for 0.25 s";
  std::vector<double> events_s;
  for (const RecordingEvent& e : rec.events) {
    if (e.type == "technique" && e.detail_json.find("\"force\"") != std::string::npos) events_s.push_back(e.time_s);
  }
  ASSERT_FALSE(events_s.empty()) << report.summary();
  std::printf("max |F| %.2f N; rule due at %.3f s, first force event at %.3f s; %zu force events\n", report.max_force_N,
              expected_s, events_s.front(), events_s.size());
  EXPECT_NEAR(events_s.front(), expected_s, 1.5e-3);
  EXPECT_EQ(report.technique_episodes[0], events_s.size());
  EXPECT_EQ(report.technique_episodes[2], 0u) << "the burr alone touched the sphere";
  EXPECT_NE(report.toJson().find("\"technique_episodes\""), std::string::npos);
  // The recording keeps the rules it ran with (a replay or a re-opened session uses them).
  const SceneSpec recorded = sceneFromSessionMetadata(rec.metadata_json);
  EXPECT_DOUBLE_EQ(recorded.technique.safe_force_N, 2.0);
  EXPECT_DOUBLE_EQ(recorded.technique.force_hold_s, 0.25);
  EXPECT_DOUBLE_EQ(recorded.technique.clear_s, TechniqueRules{}.clear_s);
  // The session's metrics (the report's and the cohort table's) count the same events.
  const SessionMetrics metrics = computeSessionMetrics(rec);
  EXPECT_EQ(metrics.technique_events[0], events_s.size());
  EXPECT_EQ(metrics.technique_events[1] + metrics.technique_events[2], 0u);

  const LoadedScene lenient = loadScene(drillingSphere(R"({"safe_force_N": 1000})", 50.0));
  options.record.clear();
  const RunReport calm = runHeadless(lenient, pressIntoTheSphere(), options);
  EXPECT_EQ(calm.technique_episodes[0], 0u);
}

}  // namespace
}  // namespace vh::runtime
