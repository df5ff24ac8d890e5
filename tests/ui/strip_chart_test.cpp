// The live strip chart (ui/strip_chart.h): samples kept over the window, batched redraws.
#include "vh/ui/panels/strip_chart.h"

#include <QChart>
#include <QChartView>
#include <QLegend>
#include <QLineSeries>
#include <QValueAxis>

#include <gtest/gtest.h>

namespace vh::ui {
namespace {

TEST(StripChart, KeepsTheLastWindowOfSamples) {
  StripChart chart(nullptr, 10.0);
  for (int i = 0; i <= 150; ++i) chart.addSample(0.1 * i, 0.01 * i, 50.0, 80.0, 3.0);  // 15 s at 10 Hz
  chart.flush();
  // Everything older than the window (and a second of margin) is gone: t in [4, 15].
  EXPECT_GE(chart.sampleCount(), 100);
  EXPECT_LE(chart.sampleCount(), 112);
  auto* series = qobject_cast<QLineSeries*>(chart.chartView()->chart()->series().front());
  ASSERT_NE(series, nullptr);
  EXPECT_NEAR(series->at(series->count() - 1).x(), 0.0, 1e-9) << "x: seconds before the newest sample";
  EXPECT_NEAR(series->at(0).x(), -11.0, 0.11);
  EXPECT_NEAR(series->at(series->count() - 1).y(), 1.5, 1e-9);
  const auto axes = chart.chartView()->chart()->axes(Qt::Vertical, series);
  ASSERT_FALSE(axes.isEmpty());
  const auto* force_axis = qobject_cast<QValueAxis*>(axes.front());
  ASSERT_NE(force_axis, nullptr);
  EXPECT_GE(force_axis->max(), 1.5) << "the force axis covers the largest force shown";
  // The solver's tick times and the coupling thread's jitter share the right axis [us], each a
  // series named in the legend.
  QStringList names;
  for (QAbstractSeries* s : chart.chartView()->chart()->series()) names << s->name();
  EXPECT_EQ(names.size(), 4);
  EXPECT_TRUE(names.filter("solver tick mean").size() == 1) << names.join(", ").toStdString();
  EXPECT_TRUE(names.filter("solver tick max").size() == 1);
  EXPECT_TRUE(names.filter("coupling jitter").size() == 1);
  EXPECT_TRUE(chart.chartView()->chart()->legend()->isVisible());
  auto* jitter = qobject_cast<QLineSeries*>(chart.chartView()->chart()->series().back());
  ASSERT_NE(jitter, nullptr);
  EXPECT_EQ(jitter->at(jitter->count() - 1).y(), 3.0);
  chart.addSample(15.1, std::nan(""), 1.0, 1.0, std::nan(""));  // a non-finite force is drawn as 0
  chart.flush();
  EXPECT_EQ(series->at(series->count() - 1).y(), 0.0);
  chart.clear();
  EXPECT_EQ(chart.sampleCount(), 0);
}

}  // namespace
}  // namespace vh::ui
