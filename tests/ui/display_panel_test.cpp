// DisplayPanel: the user's choices become signals, the window's setters show values without
// emitting, and the clipping widgets read back what was set.
#include "vh/ui/panels/display_panel.h"

#include <vector>

#include <QComboBox>
#include <QSignalSpy>

#include <gtest/gtest.h>

namespace vh::ui {
namespace {

TEST(DisplayPanel, ChoosingARenderModeEmitsIt) {
  DisplayPanel panel;
  auto* box = panel.findChild<QComboBox*>("renderMode");
  ASSERT_NE(box, nullptr);
  const int composite = box->findData(static_cast<int>(RenderMode::kComposite));
  ASSERT_GE(composite, 0);
  ASSERT_NE(box->currentIndex(), composite);
  std::vector<RenderMode> chosen;
  QObject::connect(&panel, &DisplayPanel::renderModeChosen, [&](RenderMode mode) { chosen.push_back(mode); });
  box->setCurrentIndex(composite);
  ASSERT_EQ(chosen.size(), 1u);
  EXPECT_EQ(chosen.front(), RenderMode::kComposite);
}

TEST(DisplayPanel, SettersShowWithoutEmitting) {
  DisplayPanel panel;
  auto* box = panel.findChild<QComboBox*>("renderMode");
  ASSERT_NE(box, nullptr);
  int chosen = 0;
  QObject::connect(&panel, &DisplayPanel::renderModeChosen, [&](RenderMode) { ++chosen; });
  QSignalSpy clipping(&panel, &DisplayPanel::clippingChanged);
  panel.setRenderMode(RenderMode::kMip);
  EXPECT_EQ(box->currentData().toInt(), static_cast<int>(RenderMode::kMip));
  panel.setClipping(true, ClipAxis::kY, 0.25, true);
  EXPECT_EQ(chosen, 0);
  EXPECT_EQ(clipping.count(), 0);
}

TEST(DisplayPanel, ClippingReadsBackWhatWasSet) {
  DisplayPanel panel;
  panel.setClipping(true, ClipAxis::kY, 0.25, true);
  EXPECT_TRUE(panel.clippingEnabled());
  EXPECT_EQ(panel.clipAxis(), ClipAxis::kY);
  EXPECT_DOUBLE_EQ(panel.clipFraction(), 0.25);
  EXPECT_TRUE(panel.clipFlipped());

  panel.setClipping(false, ClipAxis::kZ, 1.7, false);  // clamped to the far end
  EXPECT_FALSE(panel.clippingEnabled());
  EXPECT_EQ(panel.clipAxis(), ClipAxis::kZ);
  EXPECT_DOUBLE_EQ(panel.clipFraction(), 1.0);
  EXPECT_FALSE(panel.clipFlipped());
}

}  // namespace
}  // namespace vh::ui
