// IsovalueBar against runtime::Session on the built-in sphere (F = 20 mm - r in mm, 64^3 voxels
// of 1 mm). Oracles: the field's own minimum and maximum (the slider maps 0..1000 linearly onto
// them) and the values handed to the session.
#include "vh/ui/panels/isovalue_bar.h"
#include "vh/ui/panels/range_spin_box.h"

#include <cmath>
#include <memory>

#include <QDoubleSpinBox>
#include <QLabel>
#include <QLineEdit>
#include <QSignalSpy>
#include <QTest>

#include <gtest/gtest.h>

#include "ui_test_util.h"

#include "vh/runtime/scene.h"
#include "vh/runtime/session.h"
#include "vh/ui/panels/histogram_slider.h"

namespace vh::ui {
namespace {

using test::sphereProbeScene;


TEST(IsovalueBar, TheSliderSetsTheSessionsIsovalueLinearlyOverTheFieldsRange) {
  runtime::Session session;
  session.setScene(sphereProbeScene(), nullptr);
  IsovalueBar bar(session);
  const double min = sphereProbeScene().volume.field->minValue();
  const double max = sphereProbeScene().volume.field->maxValue();
  // F = 20 mm - r: about 20 at the centre, negative in the corners.
  ASSERT_GT(max, 19.0);
  ASSERT_LT(min, -20.0);
  EXPECT_EQ(bar.slider()->value(), static_cast<int>(std::lround(1000.0 * (0.0 - min) / (max - min))))
      << "the slider shows the scene's isovalue 0";
  for (const int p : {0, 250, 731, 1000}) {
    bar.slider()->setValue(p);
    EXPECT_NEAR(session.isovalue(), min + (max - min) * p / 1000.0, 1e-9) << "slider at " << p;
    EXPECT_EQ(bar.slider()->value(), p);
  }
}

TEST(IsovalueBar, TheSpinBoxFollowsTheSessionClampedToTheFieldsMaximum) {
  runtime::Session session;
  session.setScene(sphereProbeScene(), nullptr);
  IsovalueBar bar(session);
  const double max = sphereProbeScene().volume.field->maxValue();
  session.setIsovalue(1.5);
  EXPECT_NEAR(bar.spinBox()->value(), 1.5, 1e-9);
  session.setIsovalue(max + 7.0);
  EXPECT_DOUBLE_EQ(session.isovalue(), max);
  EXPECT_NEAR(bar.spinBox()->value(), max, 0.005) << "the spin box shows two decimals";
  EXPECT_EQ(bar.slider()->value(), 1000);

  // The spin box sends what is typed.
  bar.spinBox()->setValue(-3.25);
  EXPECT_NEAR(session.isovalue(), -3.25, 1e-9);
}

TEST(IsovalueBar, OneStepAddsOneSpinBoxStep) {
  runtime::Session session;
  session.setScene(sphereProbeScene(), nullptr);
  IsovalueBar bar(session);
  session.setIsovalue(2.0);
  const double step = bar.spinBox()->singleStep();
  ASSERT_GT(step, 0.0);
  bar.step(+1);
  EXPECT_NEAR(session.isovalue(), 2.0 + step, 1e-9);
  bar.step(-1);
  bar.step(-1);
  EXPECT_NEAR(session.isovalue(), 2.0 - step, 1e-9);
}

TEST(IsovalueBar, IsDisabledWithoutAScene) {
  runtime::Session session;
  IsovalueBar bar(session);
  EXPECT_FALSE(bar.slider()->isEnabled());
  EXPECT_FALSE(bar.spinBox()->isEnabled());
  session.setScene(sphereProbeScene(), nullptr);
  EXPECT_TRUE(bar.slider()->isEnabled());
  EXPECT_TRUE(bar.spinBox()->isEnabled());
  session.clear();
  EXPECT_FALSE(bar.slider()->isEnabled());
  EXPECT_FALSE(bar.spinBox()->isEnabled());
}

// The label names the unit of every modality, as the loader read it. The oracle: the units
// written into the scene's VolumeInfo by hand, one per modality and PET variant.
TEST(IsovalueBar, TheLabelNamesTheUnitOfEveryModality) {
  struct Case {
    std::string modality, value_unit, label, meaning_word;
  };
  const Case cases[] = {
      {"CT", "HU", "Isovalue [HU]", "Hounsfield"},
      {"PT", "SUVbw", "Isovalue [SUVbw]", "uptake"},
      {"PT", "Bq/ml", "Isovalue [Bq/ml]", "SUV needs"},
      {"PT", "", "Isovalue [a.u.]", "names no unit"},
      {"MR", "", "Isovalue [a.u.]", "scanner"},
      {"", "", "Isovalue [a.u.]", "names no unit"},
  };
  for (const Case& c : cases) {
    runtime::LoadedScene scene = sphereProbeScene();
    scene.volume.info.modality = c.modality;
    scene.volume.info.value_unit = c.value_unit;
    runtime::Session session;
    IsovalueBar bar(session);
    EXPECT_EQ(bar.label()->text().toStdString(), "Isovalue") << "no scene, no unit";
    session.setScene(scene, nullptr);
    EXPECT_EQ(bar.label()->text().toStdString(), c.label) << c.modality << " " << c.value_unit;
    EXPECT_NE(bar.label()->toolTip().toStdString().find(c.meaning_word), std::string::npos)
        << c.modality << ": " << bar.label()->toolTip().toStdString();
    session.clear();
    EXPECT_EQ(bar.label()->text().toStdString(), "Isovalue") << "the unit leaves with the scene";
  }
  // A new scene of another modality replaces the unit (no carry-over from the last scan).
  runtime::Session session;
  IsovalueBar bar(session);
  runtime::LoadedScene ct = sphereProbeScene();
  ct.volume.info.modality = "CT";
  ct.volume.info.value_unit = "HU";
  runtime::LoadedScene mr = sphereProbeScene();
  mr.volume.info.modality = "MR";
  mr.volume.info.value_unit.clear();
  session.setScene(ct, nullptr);
  session.setScene(mr, nullptr);
  EXPECT_EQ(bar.label()->text().toStdString(), "Isovalue [a.u.]");
}

TEST(RangeSpinBox, ATypedValueOutOfRangeIsNotTakenAndTheRangeIsSaid) {
  // The PET's SUV box: 0.00 to 3.41, at 0.23. Typing 30 must not become 3.00 (or 3.41) silently.
  RangeSpinBox box("the isovalue");
  box.setDecimals(2);
  box.setRange(0.0, 3.41);
  box.setValue(0.23);
  box.setKeyboardTracking(false);
  box.show();
  QSignalSpy said(&box, &RangeSpinBox::outOfRange);
  QSignalSpy changed(&box, &QDoubleSpinBox::valueChanged);
  QLineEdit* edit = box.findChild<QLineEdit*>();  // lineEdit() is protected
  ASSERT_NE(edit, nullptr);
  edit->selectAll();
  QTest::keyClicks(&box, "30");
  EXPECT_EQ(edit->text(), "30") << "the digits typed stay as typed until Enter";
  QTest::keyClick(&box, Qt::Key_Return);
  EXPECT_DOUBLE_EQ(box.value(), 0.23) << "an out-of-range number is not taken";
  EXPECT_EQ(changed.count(), 0);
  ASSERT_EQ(said.count(), 1);
  const QString message = said.first().at(0).toString();
  EXPECT_TRUE(message.contains("30") && message.contains("0.00 to 3.41") && message.contains("stays 0.23"))
      << message.toStdString();
  EXPECT_EQ(edit->text(), "0.23") << "the box shows the value it kept";
  // A number in range is taken as typed.
  edit->selectAll();
  QTest::keyClicks(&box, "2.5");
  QTest::keyClick(&box, Qt::Key_Return);
  EXPECT_DOUBLE_EQ(box.value(), 2.5);
  EXPECT_EQ(said.count(), 1);
  EXPECT_TRUE(box.lastRangeMessage().isEmpty());
}

TEST(IsovalueBar, TheSpinBoxSaysTheRangeOfAnOutOfRangeValue) {
  runtime::Session session;
  IsovalueBar bar(session);
  EXPECT_NE(qobject_cast<RangeSpinBox*>(bar.spinBox()), nullptr);
}

}  // namespace
}  // namespace vh::ui
