// Numbers and events for people (vh/ui/export/report_format.h): the expected texts are written
// out by hand from the rules (significant digits, unit steps, en-dash ranges), never produced by
// the code under test.
#include "vh/ui/export/report_format.h"

#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include <gtest/gtest.h>

namespace vh::ui {
namespace {

using runtime::RecordingEvent;

TEST(ReportFormat, NumbersHaveThreeSignificantDigitsAndNoExponentToDecode) {
  EXPECT_EQ(formatNumber(130.3), "130");
  EXPECT_EQ(formatNumber(98.44), "98.4");
  EXPECT_EQ(formatNumber(0.012345), "0.0123");
  EXPECT_EQ(formatNumber(4.0), "4");
  EXPECT_EQ(formatNumber(12345.0), "12345");
  EXPECT_EQ(formatNumber(-2.5), "-2.5");
  EXPECT_EQ(formatNumber(0.0), "0");
  EXPECT_EQ(formatNumber(-0.0), "0");
  EXPECT_EQ(formatNumber(std::numeric_limits<double>::quiet_NaN()), "n/a");
  EXPECT_EQ(formatNumber(std::numeric_limits<double>::infinity()), "n/a");
  // Very large and very small: a power of ten in superscript, not "6.263e+12".
  EXPECT_EQ(formatNumber(6.263e12), "6.26 × 10¹²");
  EXPECT_EQ(formatNumber(6.392e-6), "6.39 × 10⁻⁶");
  EXPECT_EQ(formatNumber(9.9996e-4), "1 × 10⁻³") << "rounding carries into the exponent";
  EXPECT_EQ(formatNumber(3.14159, 5), "3.1416");
}

TEST(ReportFormat, QuantitiesTakeTheUnitThatReadsBest) {
  EXPECT_EQ(formatQuantity(6.392e-6, "s"), "6.39 µs");
  EXPECT_EQ(formatQuantity(0.0123, "s"), "12.3 ms");
  EXPECT_EQ(formatQuantity(0.00099999, "s"), "1 ms") << "the unit of the rounded value";
  EXPECT_EQ(formatQuantity(92.0, "s"), "92 s");
  EXPECT_EQ(formatQuantity(150.0, "s"), "2 min 30 s");
  EXPECT_EQ(formatQuantity(5000.0, "s"), "1 h 23 min");
  EXPECT_EQ(formatQuantity(0.25, "m"), "250 mm");
  EXPECT_EQ(formatQuantity(0.001, "m"), "1 mm");
  EXPECT_EQ(formatQuantity(2.5e-5, "m"), "25 µm");
  EXPECT_EQ(formatQuantity(1.75, "m"), "1.75 m");
  EXPECT_EQ(formatQuantity(6.713, "m/s"), "6.71 m/s");
  EXPECT_EQ(formatQuantity(0.05, "m/s"), "50 mm/s");
  EXPECT_EQ(formatQuantity(130.3, "N"), "130 N");
  EXPECT_EQ(formatQuantity(0.0125, "N*m"), "0.0125 N·m");
  EXPECT_EQ(formatQuantity(12.5, "mm^3"), "12.5 mm³");
  EXPECT_EQ(formatQuantity(3.0e5, "m^2/s^5"), "300000 m²/s⁵");
  EXPECT_EQ(formatQuantity(7.0, ""), "7");
  EXPECT_EQ(formatQuantity(std::nan(""), "N"), "n/a");
}

TEST(ReportFormat, RangesShareOneUnitAndAnEnDash) {
  // The report's top force band of a 130.3 N peak, once printed "98-1.3e+02".
  EXPECT_EQ(formatRange(0.75 * 130.3, 130.3, "N"), "98–130 N");
  EXPECT_EQ(formatRange(0.0, 0.25 * 130.3, "N", 2), "0–33 N");
  EXPECT_EQ(formatRange(0.0, 0.25 * 130.3, "N"), "0.0–32.6 N");
  EXPECT_EQ(formatRange(0.5, 1.25, "N"), "0.50–1.25 N");
  EXPECT_EQ(formatRange(0.0, 4.0, "N", 2), "0.0–4.0 N");
}

TEST(ReportFormat, ClockTimes) {
  EXPECT_EQ(formatClock(12.34), "0:12.3");
  EXPECT_EQ(formatClock(92.0), "1:32.0");
  EXPECT_EQ(formatClock(59.96), "1:00.0");
  EXPECT_EQ(formatClock(3725.0), "1:02:05.0");
  EXPECT_EQ(formatClock(-1.0), "n/a");
}

/// 300 isovalue changes from 250 to 400 HU (0.5 HU each, every 0.1 s from 1 s), a marker and a
/// tool change among them.
std::vector<RecordingEvent> isovalueSweep() {
  std::vector<RecordingEvent> events;
  for (int i = 0; i < 300; ++i) {
    const double from = 250.0 + 0.5 * i, to = from + 0.5;
    events.push_back({1.0 + 0.1 * i, static_cast<std::uint64_t>(1000 + 100 * i), "isovalue",
                      "{\"from\":" + std::to_string(from) + ",\"to\":" + std::to_string(to) + "}"});
  }
  events.push_back({2.05, 2050, "marker", R"({"label":"nerve"})"});
  events.push_back({3.05, 3050, "tool", R"({"tool":"drill","point_spacing_m":0.0015})"});
  return events;
}

TEST(ReportFormat, RepeatedEventsAreOneRowAndTheRestAreWords) {
  const std::vector<RecordingEvent> events = isovalueSweep();
  const std::vector<EventRow> rows = summariseEvents(events, "HU");
  ASSERT_EQ(rows.size(), 3u) << "300 isovalue changes in one row, the marker, the tool";
  // In time order: the isovalue run starts first (1 s), then the marker, then the tool.
  EXPECT_EQ(rows[0].type, "isovalue");
  EXPECT_EQ(rows[0].count, 300u);
  EXPECT_DOUBLE_EQ(rows[0].first_s, 1.0);
  EXPECT_DOUBLE_EQ(rows[0].last_s, 1.0 + 0.1 * 299);
  EXPECT_EQ(rows[0].text, "Isovalue changed 300 times, 250 → 400 HU");
  EXPECT_FALSE(rows[0].critical);
  EXPECT_EQ(rows[1].text, "Marker “nerve”");
  EXPECT_TRUE(rows[1].critical) << "markers are highlighted";
  EXPECT_EQ(rows[2].text, "Tool “drill” (points 1.5 mm apart)");
}

TEST(ReportFormat, FewEventsOfAKindAreListedOneByOneMarkersAlways) {
  std::vector<RecordingEvent> events;
  for (int i = 0; i < 5; ++i)
    events.push_back({1.0 * i, static_cast<std::uint64_t>(i), "segment",
                      i % 2 == 0 ? R"({"from":null,"to":"Liver"})" : R"({"from":"Liver","to":null})"});
  for (int i = 0; i < 8; ++i)
    events.push_back({10.0 + i, static_cast<std::uint64_t>(100 + i), "marker", "{\"label\":\"m" + std::to_string(i) + "\"}"});
  std::vector<EventRow> rows = summariseEvents(events, "HU", 5);
  ASSERT_EQ(rows.size(), 13u) << "5 segment changes (not more than 5) and 8 markers, one row each";
  EXPECT_EQ(rows[0].text, "Touched segment “Liver”");
  EXPECT_EQ(rows[1].text, "Left segment “Liver”");
  // A sixth segment change: the kind becomes one row naming what was touched.
  events.push_back({5.0, 5, "segment", R"({"from":null,"to":"Kidney"})"});
  rows = summariseEvents(events, "HU", 5);
  ASSERT_EQ(rows.size(), 9u);
  EXPECT_EQ(rows[0].text, "Touched segment changed 6 times (Liver, Kidney)");
  EXPECT_EQ(rows[0].count, 6u);
  EXPECT_DOUBLE_EQ(rows[0].last_s, 5.0);
}

TEST(ReportFormat, CriticalAndUnknownEvents) {
  std::vector<RecordingEvent> events;
  for (int i = 0; i < 7; ++i)
    events.push_back({0.5 * i, static_cast<std::uint64_t>(i), "critical_removed", R"({"segment":"Nerve","voxels":4,"mm3":0.5})"});
  events.push_back({9.0, 9000, "placement", R"({"kind":"touch","distance_m":0.012})"});
  const std::vector<EventRow> rows = summariseEvents(events, "");
  ASSERT_EQ(rows.size(), 2u);
  EXPECT_EQ(rows[0].text, "Critical segments drilled 7 times (Nerve), 3.5 mm³ in all");
  EXPECT_TRUE(rows[0].critical);
  EXPECT_EQ(rows[1].text, "Placement: distance 12 mm, kind touch") << "an unknown kind: its fields in words";
}

// Proximity and technique events read as sentences a teacher understands, and the alarm and the
// technique's advice are marked.
TEST(ReportFormat, ProximityAndTechniqueEventsInWords) {
  const std::vector<RecordingEvent> events = {
      {4.4, 4400, "proximity_warn", R"({"segment":"facial nerve","distance_mm":1.92})"},
      {5.3, 5300, "proximity_alarm", R"({"segment":"facial nerve","distance_mm":0.998})"},
      {6.0, 6000, "technique", R"({"rule":"force"})"},
      {6.7, 6700, "proximity_alarm_cleared", R"({"segment":"facial nerve","to":"warn","distance_mm":1.0})"},
      {7.2, 7200, "proximity_warn_cleared", R"({"segment":"facial nerve","to":"clear","distance_mm":2.14})"},
      {7.3, 7300, "technique", R"({"rule":"shaft"})"}};
  const std::vector<EventRow> rows = summariseEvents(events, "");
  ASSERT_EQ(rows.size(), 6u);
  EXPECT_EQ(rows[0].text, "Within the warning distance of “facial nerve”: 1.92 mm");
  EXPECT_FALSE(rows[0].critical);
  EXPECT_EQ(rows[1].text, "Within the alarm distance of “facial nerve”: 0.998 mm");
  EXPECT_TRUE(rows[1].critical);
  EXPECT_EQ(rows[2].text, "Technique: pressing too hard for too long: ease off and let the burr cut");
  EXPECT_TRUE(rows[2].critical);
  EXPECT_EQ(rows[3].text, "Out of the alarm distance of “facial nerve”: 1 mm");
  EXPECT_EQ(rows[4].text, "Clear of “facial nerve”: 2.14 mm");
  EXPECT_NE(rows[5].text.find("shaft"), std::string::npos) << rows[5].text;
}

}  // namespace
}  // namespace vh::ui
