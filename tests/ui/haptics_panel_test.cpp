// Tests of vh/ui/haptics_panel.h: the passivity-control check box shows and edits
// CouplingGains::passivity_control the way the stiffness spin boxes do.
#include "vh/ui/panels/haptics_panel.h"

#include <QCheckBox>
#include <QDoubleSpinBox>
#include <vector>

#include <gtest/gtest.h>

namespace vh::ui {
namespace {

TEST(HapticsPanel, PassivityControlBoxEditsTheGains) {
  HapticsPanel panel;
  QCheckBox* box = panel.passivityControlBox();
  ASSERT_NE(box, nullptr);
  EXPECT_FALSE(box->isChecked());  // off by default
  EXPECT_TRUE(box->toolTip().contains("Hannaford and Ryu 2002"));
  EXPECT_FALSE(panel.gains().passivity_control);

  // Shown from the gains, without emitting (as the spin boxes).
  std::vector<haptics::CouplingGains> changed;
  QObject::connect(&panel, &HapticsPanel::gainsChanged,
                   [&changed](const haptics::CouplingGains& g) { changed.push_back(g); });
  panel.setGains({1500.0, 2.0, true});
  EXPECT_TRUE(box->isChecked());
  EXPECT_TRUE(changed.empty());
  EXPECT_TRUE(panel.gains().passivity_control);

  // The user's toggle emits the gains with the switch, the stiffnesses kept.
  box->setChecked(false);
  ASSERT_EQ(changed.size(), 1u);
  haptics::CouplingGains emitted = changed.back();
  changed.clear();
  EXPECT_FALSE(emitted.passivity_control);
  EXPECT_DOUBLE_EQ(emitted.linear_N_per_m, 1500.0);
  EXPECT_DOUBLE_EQ(emitted.angular_Nm_per_rad, 2.0);
  box->click();
  ASSERT_EQ(changed.size(), 1u);
  emitted = changed.back();
  changed.clear();
  EXPECT_TRUE(emitted.passivity_control);

  // A stiffness edit keeps the switch.
  panel.linearStiffnessBox()->setValue(3000.0);
  ASSERT_EQ(changed.size(), 1u);
  emitted = changed.back();
  changed.clear();
  EXPECT_TRUE(emitted.passivity_control);
  EXPECT_DOUBLE_EQ(emitted.linear_N_per_m, 3000.0);
}

}  // namespace
}  // namespace vh::ui
