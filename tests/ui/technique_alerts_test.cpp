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
            "Technique: " + std::string(runtime::techniqueRuleAdvice(0)));
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

}  // namespace
}  // namespace vh::ui
