// The numeric fields of the panels and dialogs never change a typed value silently: a number
// typed outside a box's range is not taken, the box keeps its value and says the range. Oracles:
// the ranges the fields are built with (0.1 to 20 mm for the point spacing, 1 to 65535 for a
// TCP port) and the values they held before the typing.
#include <QApplication>
#include <QDialogButtonBox>
#include <QLineEdit>
#include <QPushButton>
#include <QSignalSpy>
#include <QTest>

#include <gtest/gtest.h>

#include "ui_test_util.h"
#include "vh/ui/panels/haptics_panel.h"
#include "vh/ui/panels/load_notices.h"
#include "vh/ui/panels/pacs_dialog.h"
#include "vh/ui/panels/range_spin_box.h"
#include "vh/ui/panels/segments_panel.h"
#include "vh/ui/panels/series_chooser.h"

namespace vh::ui {
namespace {

/// Types `text` over the number in `box` (its prefix and suffix stay) and presses Enter.
void typeAndEnter(QAbstractSpinBox* box, const QString& text) {
  box->setFocus();
  box->selectAll();  // the number only
  QTest::keyClicks(box, text);
  QTest::keyClick(box, Qt::Key_Return);
}

TEST(RangeSpinBox, ThePointSpacingKeepsItsValueWhenTypedOutOfRangeAndTheStatusBarHearsIt) {
  HapticsPanel panel;
  panel.setPointShell(0.5e-3, 1234);  // 0.50 mm
  panel.show();
  RangeSpinBox* spacing = panel.spacingBox();
  ASSERT_DOUBLE_EQ(spacing->value(), 0.5);
  ASSERT_EQ(spacing->minimum(), 0.1);
  ASSERT_EQ(spacing->maximum(), 20.0);
  QSignalSpy said(spacing, &RangeSpinBox::outOfRange);
  QSignalSpy status(&panel, &HapticsPanel::message);
  QSignalSpy changed(spacing, &QDoubleSpinBox::valueChanged);

  typeAndEnter(spacing, "50");
  EXPECT_DOUBLE_EQ(spacing->value(), 0.5) << "50 mm is not taken (nor 20, nor 5)";
  EXPECT_EQ(changed.count(), 0);
  ASSERT_EQ(said.count(), 1);
  const QString message = said.first().at(0).toString();
  EXPECT_EQ(message, "50 is outside 0.10 to 20.00: the point spacing stays 0.50") << message.toStdString();
  ASSERT_EQ(status.count(), 1) << "the panel passes the message on to the status bar";
  EXPECT_EQ(status.first().at(0).toString(), message);

  typeAndEnter(spacing, "0.05");  // below the minimum too
  EXPECT_DOUBLE_EQ(spacing->value(), 0.5);
  EXPECT_EQ(said.count(), 2);

  typeAndEnter(spacing, "1.25");
  EXPECT_DOUBLE_EQ(spacing->value(), 1.25) << "a number in range is taken as typed";
  EXPECT_EQ(said.count(), 2);
  EXPECT_TRUE(spacing->lastRangeMessage().isEmpty());
}

TEST(RangeSpinBox, ThePacsPortKeepsItsValueAndTheDialogStaysOpenOnceToSayIt) {
  io::PacsServer server;
  server.host = "127.0.0.1";
  server.port = 11112;
  PacsSettingsDialog dialog(server);
  dialog.show();
  auto* port = dialog.findChild<RangeIntSpinBox*>("pacsPort");
  ASSERT_NE(port, nullptr) << "the port is a RangeIntSpinBox (a QSpinBox)";
  ASSERT_NE(qobject_cast<QSpinBox*>(port), nullptr);
  QSignalSpy said(port, &RangeIntSpinBox::outOfRange);
  QSignalSpy accepted(&dialog, &QDialog::accepted);
  QPushButton* ok = dialog.findChild<QDialogButtonBox*>()->button(QDialogButtonBox::Ok);
  ASSERT_NE(ok, nullptr);
  ASSERT_TRUE(ok->isDefault()) << "Enter in a field presses OK";

  // 70000 and Enter (which presses OK): the port stays, the dialog stays open with the message.
  typeAndEnter(port, "70000");
  EXPECT_EQ(port->value(), 11112);
  ASSERT_EQ(said.count(), 1);
  EXPECT_EQ(said.first().at(0).toString(), "70000 is outside 1 to 65535: the port stays 11112");
  EXPECT_EQ(accepted.count(), 0) << "OK right after the refusal is held back";
  EXPECT_TRUE(dialog.isVisible());
  EXPECT_EQ(dialog.server().port, 11112);

  // An in-range port is taken; OK closes the dialog with it.
  typeAndEnter(port, "4242");
  EXPECT_EQ(port->value(), 4242);
  EXPECT_EQ(said.count(), 1);
  EXPECT_EQ(accepted.count(), 1) << "Enter pressed OK, no refusal since the last try";
  EXPECT_FALSE(dialog.isVisible());
  EXPECT_EQ(dialog.server().port, 4242);
}

TEST(RangeSpinBox, EveryOtherNumericFieldSaysItsRange) {
  // The fields the brief named, each a RangeSpinBox or RangeIntSpinBox naming its value.
  SegmentsPanel segments;
  EXPECT_NE(qobject_cast<RangeSpinBox*>(segments.smoothingBox()), nullptr);
  HapticsPanel haptics;
  EXPECT_NE(qobject_cast<RangeSpinBox*>(haptics.linearStiffnessBox()), nullptr);
  EXPECT_NE(qobject_cast<RangeSpinBox*>(haptics.torsionalStiffnessBox()), nullptr);
  LoadNoticePanel notices;
  EXPECT_NE(qobject_cast<RangeIntSpinBox*>(notices.phaseSpinBox()), nullptr);
  SeriesChooserDialog chooser("/data", {});
  EXPECT_NE(qobject_cast<RangeIntSpinBox*>(chooser.phaseSpinBox()), nullptr);
  PacsSettingsDialog pacs(io::PacsServer{});
  EXPECT_NE(pacs.findChild<RangeIntSpinBox*>("pacsTimeout"), nullptr);

  // The torsional stiffness (0 to 50 N*m/rad, a suffix): 80 is not taken, 2.5 is.
  haptics.show();
  RangeSpinBox* torsional = haptics.torsionalStiffnessBox();
  torsional->setValue(1.0);
  QSignalSpy said(torsional, &RangeSpinBox::outOfRange);
  typeAndEnter(torsional, "80");
  EXPECT_DOUBLE_EQ(torsional->value(), 1.0);
  ASSERT_EQ(said.count(), 1);
  EXPECT_TRUE(said.first().at(0).toString().contains("the torsional stiffness stays 1.000"));
  typeAndEnter(torsional, "2.5");
  EXPECT_DOUBLE_EQ(torsional->value(), 2.5);
}

TEST(RangeSpinBox, AnIntegerBoxRefusesAFractionKeystrokeAsQSpinBoxDoes) {
  RangeIntSpinBox box("the time point");
  box.setRange(1, 12);
  box.setValue(3);
  box.show();
  QSignalSpy said(&box, &RangeIntSpinBox::outOfRange);
  typeAndEnter(&box, "5.5");  // the "." is refused: 55, outside 1 to 12
  EXPECT_EQ(box.value(), 3);
  ASSERT_EQ(said.count(), 1);
  EXPECT_EQ(said.first().at(0).toString(), "55 is outside 1 to 12: the time point stays 3");
  typeAndEnter(&box, "7");
  EXPECT_EQ(box.value(), 7);
}

}  // namespace
}  // namespace vh::ui
