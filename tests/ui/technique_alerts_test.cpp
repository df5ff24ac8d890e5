// Technique feedback in the window (ui/technique_alerts.h): a rule that becomes active in a
// snapshot says what to change once and asks for the alert tone once; a rule that stays active
// says nothing more; one that ends and comes back is news again.
#include "vh/ui/technique_alerts.h"

#include <QSignalSpy>

#include <gtest/gtest.h>

#include "vh/runtime/technique.h"

namespace vh::ui {
namespace {

runtime::HapticSnapshot withRules(std::uint32_t technique) {
  runtime::HapticSnapshot s;
  s.technique = technique;
  return s;
}

TEST(TechniqueAlerts, EachRuleThatBecomesActiveIsSaidOnce) {
  TechniqueAlerts alerts;
  QSignalSpy messages(&alerts, &TechniqueAlerts::message);
  QSignalSpy tones(&alerts, &TechniqueAlerts::alertRequested);
  alerts.showSnapshot(withRules(0));
  EXPECT_EQ(messages.count(), 0);
  alerts.showSnapshot(withRules(runtime::kTechniqueForce));
  ASSERT_EQ(messages.count(), 1);
  EXPECT_EQ(messages.at(0).at(0).toString().toStdString(),
            "Technique: " + std::string(runtime::techniqueRuleAdvice(0, false)));
  EXPECT_EQ(tones.count(), 1);
  for (int i = 0; i < 50; ++i) alerts.showSnapshot(withRules(runtime::kTechniqueForce));
  EXPECT_EQ(messages.count(), 1) << "an active rule is said once";
  // The shaft joins the push: only the shaft is news.
  alerts.showSnapshot(withRules(runtime::kTechniqueForce | runtime::kTechniqueShaft));
  ASSERT_EQ(messages.count(), 2);
  EXPECT_NE(messages.at(1).at(0).toString().indexOf("shaft"), -1) << messages.at(1).at(0).toString().toStdString();
  EXPECT_EQ(tones.count(), 2);
  // Both end, then the push comes back: news again.
  alerts.showSnapshot(withRules(0));
  alerts.showSnapshot(withRules(runtime::kTechniqueForce));
  EXPECT_EQ(messages.count(), 3);
  EXPECT_EQ(alerts.alertsShown(), 3u);
  // Two rules at once: two messages, one tone.
  alerts.showSnapshot(withRules(0));
  alerts.showSnapshot(withRules(runtime::kTechniqueSpeed | runtime::kTechniqueShaft));
  EXPECT_EQ(messages.count(), 5);
  EXPECT_EQ(tones.count(), 4);
}

// The burr spinning while only the shaft touches (the burr cannot cut): said once, after the
// episode has lasted kShaftOnlyTicks solver ticks, with how to bring the burr to the surface; a
// passing touch is not said; the burr touching ends the episode. And the force rule's advice
// speaks of a burr only when there is a drill.
TEST(TechniqueAlerts, OnlyTheShaftTouchingIsSaidWithHowToBringTheBurr) {
  TechniqueAlerts alerts;
  QSignalSpy messages(&alerts, &TechniqueAlerts::message);
  const auto snapshot = [](std::uint64_t tick, bool burr_on, bool shaft_only) {
    runtime::HapticSnapshot s;
    s.solver_tick = tick;
    s.drill = true;
    s.burr_on = burr_on;
    s.shaft_only = shaft_only;
    s.contacts = 3;
    return s;
  };
  std::uint64_t tick = 1;
  for (int i = 0; i < 50; ++i, tick += 2) alerts.showSnapshot(snapshot(tick, true, true));  // 100 ticks: a passing touch
  alerts.showSnapshot(snapshot(tick++, true, false));                                     // the burr touches
  for (int i = 0; i < 90; ++i, tick += 2) alerts.showSnapshot(snapshot(tick, true, true));
  EXPECT_EQ(messages.count(), 0) << "180 ticks: not yet";
  for (int i = 0; i < 20; ++i, tick += 2) alerts.showSnapshot(snapshot(tick, true, true));
  ASSERT_EQ(messages.count(), 1);
  const QString said = messages.at(0).at(0).toString();
  EXPECT_NE(said.indexOf("only the shaft touches"), -1) << said.toStdString();
  EXPECT_NE(said.indexOf("Ctrl+T"), -1) << said.toStdString();
  for (int i = 0; i < 500; ++i, tick += 2) alerts.showSnapshot(snapshot(tick, true, true));
  EXPECT_EQ(messages.count(), 1) << "once per episode";
  alerts.showSnapshot(snapshot(tick++, false, true));  // the burr stops: the episode ends
  for (int i = 0; i < 150; ++i, tick += 2) alerts.showSnapshot(snapshot(tick, true, true));
  EXPECT_EQ(messages.count(), 2) << "a new episode is news";
  EXPECT_EQ(alerts.shaftOnlyShown(), 2u);
  runtime::HapticSnapshot probe = snapshot(tick++, false, false);
  probe.drill = false;
  probe.shaft_only = false;
  for (int i = 0; i < 300; ++i, ++probe.solver_tick) alerts.showSnapshot(probe);
  EXPECT_EQ(messages.count(), 2) << "no drill: nothing about a shaft";

  // The force rule with a probe: no burr in the advice; with a drill, the burr.
  alerts.showSnapshot(withRules(0));
  runtime::HapticSnapshot pressing = withRules(runtime::kTechniqueForce);
  alerts.showSnapshot(pressing);
  ASSERT_EQ(messages.count(), 3);
  EXPECT_EQ(messages.at(2).at(0).toString().indexOf("burr"), -1) << messages.at(2).at(0).toString().toStdString();
  alerts.showSnapshot(withRules(0));
  pressing.drill = true;
  alerts.showSnapshot(pressing);
  ASSERT_EQ(messages.count(), 4);
  EXPECT_NE(messages.at(3).at(0).toString().indexOf("burr"), -1) << messages.at(3).at(0).toString().toStdString();
}

}  // namespace
}  // namespace vh::ui
