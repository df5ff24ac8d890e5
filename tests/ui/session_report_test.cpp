// The session report (vh/ui/export/session_report.h): its pictures are present, decode as PNGs
// of the stated size and are not blank; a damaged recording gives a report with a notice; a
// reference of another scene is refused. Runs on Qt's offscreen platform (no display).
#include "vh/ui/export/session_report.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <limits>
#include <cstring>
#include <fstream>
#include <set>
#include <string>
#include <vector>

#include <QApplication>
#include <QByteArray>
#include <QImage>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "drilling_scenes.h"
#include "vh/runtime/runner.h"
#include "vh/runtime/session_metrics.h"
#include "vh/runtime/trajectory.h"

namespace vh::ui {
namespace {

namespace fs = std::filesystem;
using runtime::Recording;
using runtime::TickRecord;

/// 6 s at 1 kHz: the device circles (radius 2 cm, 0.5 Hz) and presses on a surface in the
/// middle 2 s with a force rising to 4 N; a marker at 1 s.
Recording pressSession(const std::string& sha) {
  Recording rec;
  rec.metadata_json = nlohmann::json{{"servo_rate_Hz", 1000}, {"dataset", {{"sha256", sha}}},
                                     {"scene", {{"source", "press.json"}}}, {"note", "trainee <A>"}}
                          .dump();
  for (int i = 0; i < 6000; ++i) {
    TickRecord t;
    t.time_s = i * 1e-3;
    t.tick = static_cast<std::uint64_t>(i);
    t.p_WD_m[0] = 0.02 * std::cos(M_PI * t.time_s);
    t.p_WD_m[1] = 0.02 * std::sin(M_PI * t.time_s);
    t.p_WD_m[2] = 0.01 * t.time_s;
    for (int k = 0; k < 3; ++k) t.p_WP_m[k] = t.p_WD_m[k];
    const double f = i >= 2000 && i < 4000 ? 4.0 * (i - 2000) / 2000.0 : 0.0;
    t.force_W_N[2] = f;
    t.torque_W_Nm[0] = f > 0 ? 0.01 : 0.0;
    t.contacts = f > 0 ? 2u : 0u;
    t.tick_time_s = 5e-5;
    rec.records.push_back(t);
  }
  rec.events.push_back({1.0, 1000, "marker", R"({"label":"start"})"});
  return rec;
}

struct Image {
  QImage image;
  std::string alt;
};

/// Every inline PNG of the page, decoded (a plain search: std::regex recurses per character and
/// overflows the stack on a picture's base64).
std::vector<Image> inlineImages(const std::string& html) {
  std::vector<Image> out;
  const std::string alt_key = "alt=\"", src_key = "src=\"data:image/png;base64,";
  for (std::size_t at = html.find("<img "); at != std::string::npos; at = html.find("<img ", at + 1)) {
    const std::size_t alt = html.find(alt_key, at) + alt_key.size();
    const std::size_t src = html.find(src_key, at);
    if (src == std::string::npos) break;
    const std::size_t begin = src + src_key.size(), end = html.find('"', begin);
    Image im;
    im.alt = html.substr(alt, html.find('"', alt) - alt);
    im.image = QImage::fromData(QByteArray::fromBase64(QByteArray::fromStdString(html.substr(begin, end - begin))), "PNG");
    out.push_back(im);
  }
  return out;
}

/// The page without its inline pictures' data (base64 has letters, digits and '+').
std::string withoutPictures(const std::string& html) {
  std::string out;
  const std::string key = "src=\"data:";
  std::size_t from = 0;
  for (std::size_t at = html.find(key); at != std::string::npos; at = html.find(key, from)) {
    out += html.substr(from, at - from);
    from = html.find('"', at + key.size());
  }
  return out + html.substr(from);
}

/// Distinct colours of an image (a blank or single-colour picture has 1 or 2).
std::size_t colours(const QImage& image) {
  std::set<QRgb> seen;
  for (int y = 0; y < image.height(); y += 2)
    for (int x = 0; x < image.width(); x += 2) seen.insert(image.pixel(x, y));
  return seen.size();
}

TEST(SessionReport, PicturesArePresentDecodeAndAreNotBlank) {
  SessionReportOptions options;
  const std::string html = sessionReportHtml(pressSession("abc"), "press.vhrec", options);
  EXPECT_EQ(html.find("http://"), std::string::npos) << "no network";
  EXPECT_EQ(html.find("https://"), std::string::npos) << "no network";
  EXPECT_NE(html.find("trainee &lt;A&gt;"), std::string::npos) << "the label, escaped";
  const std::vector<Image> images = inlineImages(html);
  ASSERT_EQ(images.size(), 5u) << "force, speed, three contact projections";
  EXPECT_EQ(images[0].image.width(), options.chart_width);
  EXPECT_EQ(images[0].image.height(), options.chart_height);
  for (const Image& im : images) {
    ASSERT_FALSE(im.image.isNull()) << im.alt;
    EXPECT_GT(colours(im.image), 20u) << im.alt << ": a drawn chart has axes, text, lines";
  }
  // The force chart draws the force: the blue |F| line's pixels are there.
  int blue = 0;
  const QImage& force = images[0].image;
  for (int y = 0; y < force.height(); ++y)
    for (int x = 0; x < force.width(); ++x) {
      const QColor c(force.pixel(x, y));
      blue += c.blue() > 150 && c.red() < 80 && c.green() > 90 && c.green() < 150;
    }
  EXPECT_GT(blue, 200);
  // A recording whose metadata names no scene: the contact map without the surface, and why.
  EXPECT_NE(html.find("the scan could not be reloaded"), std::string::npos);
  // The metrics table: peak force 3.998 N and time in contact 1.999 s (1999 ticks), to 3 digits
  // with their units.
  EXPECT_NE(html.find("<td class=\"n\">4 N</td>"), std::string::npos);
  EXPECT_NE(html.find("<td class=\"n\">2 s</td>"), std::string::npos);
  // The jerk measures are in the appendix with what they mean, not among the teacher's figures.
  const std::size_t appendix = html.find("<h2>Appendix: smoothness");
  ASSERT_NE(appendix, std::string::npos);
  EXPECT_GT(html.find("<code>dimensionless_jerk</code>"), appendix);
  EXPECT_GT(html.find("<code>integrated_squared_jerk_m2_per_s5</code>"), appendix);
  EXPECT_LT(html.find("<code>max_force_N</code>"), appendix);
  EXPECT_NE(html.find("smaller dimensionless jerk"), std::string::npos);
  // No number in C's exponent notation ("6.392e-06", "1.3e+02") anywhere in the text.
  const std::string text = withoutPictures(html);
  for (std::size_t i = 1; i + 2 < text.size(); ++i)
    if ((text[i] == 'e' || text[i] == 'E') && std::isdigit(static_cast<unsigned char>(text[i - 1])) &&
        (text[i + 1] == '+' || text[i + 1] == '-') && std::isdigit(static_cast<unsigned char>(text[i + 2])))
      ADD_FAILURE() << "an exponent in: " << text.substr(i < 40 ? 0 : i - 40, 80);
}

/// The caption of the map whose title starts with `title` ("Contacts, Axial").
std::string captionOf(const std::string& html, const std::string& title) {
  const std::size_t at = html.find("alt=\"" + title);
  if (at == std::string::npos) return {};
  const std::size_t begin = html.find("<figcaption>", at), end = html.find("</figcaption>", at);
  return begin == std::string::npos ? std::string() : html.substr(begin + 12, end - begin - 12);
}

TEST(SessionReport, ContactMapsAreLabelledInThePatientFrameFromTheToolsSide) {
  // W is LPS (+x left, +y posterior, +z superior). pressSession pushes the hand up (+z) while in
  // contact: the tool was above the surface, so the axial view is seen from above the head.
  // Looking down on the top of the head with the nose (A) up, the patient's right is on the
  // viewer's right. The coronal and sagittal views have no force along their axis: the usual
  // radiological sides, from the front (the patient's right on the viewer's left) and from the
  // left (the face, A, on the left).
  Recording rec = pressSession("abc");
  std::string html = sessionReportHtml(rec, "press.vhrec");
  EXPECT_EQ(captionOf(html, "Contacts, Axial").rfind(
                "Axial, seen from above the head (superior, S): A at the top, P at the bottom, L on the left, R on the "
                "right", 0),
            0u)
      << captionOf(html, "Contacts, Axial");
  EXPECT_EQ(captionOf(html, "Contacts, Coronal").rfind(
                "Coronal, seen from the front (anterior, A): S at the top, I at the bottom, R on the left, L on the right",
                0),
            0u)
      << captionOf(html, "Contacts, Coronal");
  EXPECT_EQ(captionOf(html, "Contacts, Sagittal").rfind(
                "Sagittal, seen from the patient's left (L): S at the top, I at the bottom, A on the left, P on the right",
                0),
            0u)
      << captionOf(html, "Contacts, Sagittal");
  // Pushed down instead (the tool under the surface): seen from below the feet, mirrored left-right.
  for (TickRecord& t : rec.records) t.force_W_N[2] = -t.force_W_N[2];
  html = sessionReportHtml(rec, "press.vhrec");
  EXPECT_EQ(captionOf(html, "Contacts, Axial").rfind(
                "Axial, seen from below the feet (inferior, I): A at the top, P at the bottom, R on the left, L on the "
                "right",
                0),
            0u)
      << captionOf(html, "Contacts, Axial");
}

TEST(SessionReport, ContactMapsShowTheAnatomyAroundTheContactsNotAFewMillimetres) {
  // The contacts go round a circle of 20 mm radius: 40 mm across. Framed on at least 80 mm, they
  // cover about half of the map's width (a map zoomed onto them covers nearly all of it).
  SessionReportOptions options;
  const std::string html = sessionReportHtml(pressSession("abc"), "press.vhrec", options);
  const std::vector<Image> images = inlineImages(html);
  ASSERT_EQ(images.size(), 5u);
  const QImage& axial = images[2].image;
  ASSERT_NE(images[2].alt.find("Contacts, Axial"), std::string::npos) << images[2].alt;
  int left = axial.width(), right = -1;
  for (int y = 0; y < axial.height() * 3 / 4; ++y)  // above the legend
    for (int x = 0; x < axial.width(); ++x) {
      const QColor c(axial.pixel(x, y));
      const int spread = std::max({c.red(), c.green(), c.blue()}) - std::min({c.red(), c.green(), c.blue()});
      if (spread > 80) left = std::min(left, x), right = std::max(right, x);  // a force band's colour
    }
  ASSERT_GT(right, left) << "no contacts drawn";
  const double covered = static_cast<double>(right - left) / axial.width();
  EXPECT_GT(covered, 0.35);
  EXPECT_LT(covered, 0.6) << "40 mm of contacts in a field of 80 mm";
  EXPECT_NE(images[2].alt.find("Field 80 mm across, scale bar 20 mm"), std::string::npos) << images[2].alt;
}

TEST(SessionReport, RepeatedEventsAreSummarisedAndTheComparisonComesFirst) {
  Recording session = pressSession("abc");
  for (int i = 0; i < 300; ++i)
    session.events.push_back({1.5 + 0.01 * i, static_cast<std::uint64_t>(1500 + 10 * i), "isovalue",
                              "{\"from\":" + std::to_string(250 + 0.5 * i) + ",\"to\":" + std::to_string(250.5 + 0.5 * i) + "}"});
  Recording expert = pressSession("abc");
  const std::string html = sessionReportHtml(session, "s", {}, &expert, "expert.vhrec");
  const std::size_t events_at = html.find("<table class=\"events\">");
  ASSERT_NE(events_at, std::string::npos);
  const std::string events = html.substr(events_at, html.find("</table>", events_at) - events_at);
  std::size_t rows = 0;
  for (std::size_t at = events.find("<tr"); at != std::string::npos; at = events.find("<tr", at + 1)) ++rows;
  EXPECT_EQ(rows, 3u) << "the header, the marker, one row for 300 isovalue changes:\n" << events;
  EXPECT_NE(events.find("Isovalue changed 300 times, 250 → 400"), std::string::npos) << events;
  EXPECT_NE(events.find("first at 0:01.5, last at 0:04.5"), std::string::npos) << events;
  // The comparison with the expert before the charts and the tables.
  const std::size_t comparison = html.find("Against the reference expert.vhrec");
  ASSERT_NE(comparison, std::string::npos);
  EXPECT_LT(comparison, html.find("<h2>Force</h2>"));
  EXPECT_LT(comparison, events_at);
}

TEST(SessionReport, TruncatedRecordingGivesAReportWithANotice) {
  const fs::path dir = fs::path(VH_TEST_OUTPUT_DIR) / "session-report";
  fs::create_directories(dir);
  const fs::path path = dir / "cut.vhrec";
  {
    runtime::RecordingWriter writer(path, pressSession("abc").metadata_json);
    for (const TickRecord& t : pressSession("abc").records) writer.pushWaiting(t);
    writer.close();
  }
  fs::resize_file(path, fs::file_size(path) - 3000);
  const std::vector<std::string> notices = writeSessionReport(path, dir / "cut.html");
  ASSERT_FALSE(notices.empty());
  std::ifstream in(dir / "cut.html");
  const std::string html{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
  EXPECT_NE(html.find("Read with notices"), std::string::npos);
  EXPECT_NE(html.find("truncated"), std::string::npos);
  EXPECT_EQ(inlineImages(html).size(), 5u);
  // Not a recording at all: an error naming it, no report.
  std::ofstream(dir / "junk.vhrec") << "junk";
  EXPECT_THROW(writeSessionReport(dir / "junk.vhrec", dir / "junk.html"), std::runtime_error);
}

// Records that are all NaN, or random bits, with valid checksums (a solver that failed, a
// hostile file): before, the force chart's NaN axis range ended the program with SIGSEGV. Now a
// report whose pictures (the force and speed charts at least) decode.
TEST(SessionReport, RecordsOfNaNOrRandomBitsStillGiveAReport) {
  for (const bool random : {false, true}) {
    Recording rec = pressSession("abc");
    std::uint64_t state = 0x9E3779B97F4A7C15ull;
    const auto bits = [&] {
      state ^= state << 13, state ^= state >> 7, state ^= state << 17;  // xorshift64
      double d;
      std::memcpy(&d, &state, sizeof d);
      return d;
    };
    const double nan = std::numeric_limits<double>::quiet_NaN();
    for (TickRecord& t : rec.records) {
      t.time_s = random ? bits() : nan;
      for (int k = 0; k < 3; ++k) {
        t.p_WD_m[k] = random ? bits() : nan;
        t.p_WP_m[k] = random ? bits() : nan;
        t.force_W_N[k] = random ? bits() : nan;
        t.torque_W_Nm[k] = random ? bits() : nan;
      }
      t.tick_time_s = random ? bits() : nan;
    }
    const std::string html = sessionReportHtml(rec, random ? "random.vhrec" : "nan.vhrec");
    EXPECT_NE(html.find("<html"), std::string::npos);
    const auto images = inlineImages(html);
    EXPECT_GE(images.size(), 2u) << (random ? "random" : "NaN");  // the force and speed charts at least
    for (const auto& im : images) EXPECT_FALSE(im.image.isNull()) << im.alt;
  }
}

TEST(SessionReport, ReferenceOfTheSameSceneIsDrawnAnotherIsRefused) {
  const Recording session = pressSession("abc");
  Recording expert = pressSession("abc");
  for (TickRecord& t : expert.records) t.p_WD_m[2] += 0.001;  // 1 mm above, all along
  const std::string html = sessionReportHtml(session, "s", {}, &expert, "expert.vhrec");
  EXPECT_NE(html.find("Against the reference expert.vhrec"), std::string::npos);
  EXPECT_NE(html.find("<b>1 mm</b>"), std::string::npos) << "the DTW mean distance of a 1 mm offset";
  EXPECT_EQ(inlineImages(html).size(), 7u) << "two path projections more";
  const Recording other = pressSession("def");
  try {
    sessionReportHtml(session, "s", {}, &other, "other.vhrec");
    FAIL() << "another scene was not refused";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("another scene"), std::string::npos) << e.what();
  }
}

// A recording whose burr removed bone, soft tissue and the air above it on a CT: the page gives
// the removal per material from a replay of the recording on its reloaded scene (even with
// --no-anatomy), row for row what `run`'s report of the same session gave (whose classes
// tests/app/runtime's drilling test checks against each voxel's HU), and the rows sum to the
// records' count of removed voxels. A recording that drilled nothing has no such table.
TEST(SessionReport, DrilledAwayIsGivenPerMaterialFromAReplay) {
  const fs::path dir = fs::path(VH_TEST_OUTPUT_DIR) / "session-report-drilled";
  fs::remove_all(dir);
  fs::create_directories(dir);
  const runtime::LoadedScene scene = runtime::loadScene(runtime::loadSceneFile(test::writeCtBallScene(dir)));
  runtime::RunOptions run_options;
  run_options.record = dir / "drill.vhrec";
  run_options.lag_reference = false;
  run_options.verify_step_voxels = 0.0;
  const runtime::RunReport run = runtime::runHeadless(scene, test::pressTrajectory(0.0, 0.0, 0.030, 1.0, 0.0125, 2.0), run_options);
  ASSERT_TRUE(run.drill.has_value());
  const Recording rec = runtime::readRecording(run_options.record);
  SessionReportOptions options;
  options.anatomy = false;
  const std::string html = withoutPictures(sessionReportHtml(rec, "drill.vhrec", options));
  const std::size_t from = html.find("<h2>Drilled away, per material</h2>");
  ASSERT_NE(from, std::string::npos) << "no table per material";
  const std::string table = html.substr(from, html.find("</table>", from) - from);
  std::uint64_t voxels = 0;
  bool air = false;
  for (const runtime::DrillReport::Material& m : run.drill->materials) {
    if (m.voxels == 0) continue;
    voxels += m.voxels;
    air = air || m.name == "air";
    const std::size_t row = table.find("<td>" + m.name + "</td>");
    ASSERT_NE(row, std::string::npos) << m.name << " missing from\n" << table;
    EXPECT_NE(table.find("(" + std::to_string(m.voxels) + " voxels)", row), std::string::npos) << m.name << "\n" << table;
  }
  EXPECT_TRUE(air) << "the burr's reach took the air above the ball";
  EXPECT_EQ(voxels, runtime::computeSessionMetrics(rec).removed_voxels);
  EXPECT_NE(table.find("<th>all</th><td></td><td class=\"n\">"), std::string::npos);
  EXPECT_NE(table.find("(" + std::to_string(voxels) + " voxels)</td><td></td>"), std::string::npos) << table;

  // A session that drilled nothing: no table, whether its scene reloads or not (this one's does not).
  EXPECT_EQ(sessionReportHtml(pressSession("abc"), "s", options).find("per material"), std::string::npos);
  EXPECT_EQ(sessionReportHtml(pressSession("abc"), "s", {}).find("per material"), std::string::npos);
}

}  // namespace
}  // namespace vh::ui

int main(int argc, char** argv) {
  setenv("QT_QPA_PLATFORM", "offscreen", 1);
  QApplication app(argc, argv);
  ::testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
