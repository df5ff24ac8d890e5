// Session metrics (vh/runtime/session_metrics.h) against analytic trajectories and force
// profiles, DTW against a second, recursive implementation, the reference check, damaged input
// and the cohort table.
#include "vh/runtime/cohort_table.h"
#include "vh/runtime/session_metrics.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <fstream>
#include <iostream>
#include <functional>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "runtime_test_support.h"

namespace vh::runtime {
namespace {

namespace fs = std::filesystem;
constexpr double kPi = 3.14159265358979323846;

/// A device on a circle of radius r [m] in the xy plane of W at angular speed w [rad/s],
/// sampled at `rate` [Hz] for `duration` [s] (records at t = i / rate, i = 0 .. n - 1).
Recording circleRecording(double r, double w, double rate, double duration) {
  Recording rec;
  rec.metadata_json = nlohmann::json{{"servo_rate_Hz", rate}}.dump();
  const auto n = static_cast<std::size_t>(std::llround(duration * rate)) + 1;
  for (std::size_t i = 0; i < n; ++i) {
    TickRecord t;
    t.time_s = static_cast<double>(i) / rate;
    t.tick = i;
    t.p_WD_m[0] = 0.01 + r * std::cos(w * t.time_s);
    t.p_WD_m[1] = -0.02 + r * std::sin(w * t.time_s);
    t.p_WD_m[2] = 0.03;
    for (int k = 0; k < 3; ++k) t.p_WP_m[k] = t.p_WD_m[k];
    rec.records.push_back(t);
  }
  return rec;
}

TEST(SessionMetrics, CircleAtKnownSpeedGivesPathSpeedAndJerkWithinOnePercent) {
  const double r = 0.05, w = kPi, rate = 1000.0, duration = 10.0;  // 0.5 Hz, 5 laps
  const SessionMetrics m = computeSessionMetrics(circleRecording(r, w, rate, duration));
  EXPECT_TRUE(m.notices.empty());
  EXPECT_DOUBLE_EQ(m.duration_s, duration);
  const double speed = r * w;
  EXPECT_NEAR(m.path_length_m, speed * duration, 0.01 * speed * duration);
  EXPECT_NEAR(m.mean_speed_m_per_s, speed, 0.01 * speed);
  EXPECT_NEAR(m.peak_speed_m_per_s, speed, 0.01 * speed);
  // |d^3p/dt^3| = r w^3 everywhere: ISJ = r^2 w^6 D, DJ = ISJ D^3 / (r w)^2 = (w D)^4.
  const double isj = r * r * std::pow(w, 6) * duration;
  EXPECT_NEAR(m.integrated_squared_jerk, isj, 0.01 * isj);
  const double dj = std::pow(w * duration, 4);
  EXPECT_NEAR(m.dimensionless_jerk, dj, 0.01 * dj);
  EXPECT_NEAR(m.log_dimensionless_jerk, -std::log(dj), 0.01);
  EXPECT_NEAR(m.proxy_path_length_m, m.path_length_m, 1e-12);
  std::cout << "relative errors: path length " << m.path_length_m / (speed * duration) - 1 << ", peak speed "
            << m.peak_speed_m_per_s / speed - 1 << ", ISJ " << m.integrated_squared_jerk / isj - 1 << ", DJ "
            << m.dimensionless_jerk / dj - 1 << std::endl;
  // A faster circle is jerkier in absolute terms but as smooth dimensionlessly per lap.
  const SessionMetrics fast = computeSessionMetrics(circleRecording(r, 2 * w, rate, duration));
  EXPECT_NEAR(fast.peak_speed_m_per_s, 2 * speed, 0.02 * speed);
  EXPECT_GT(fast.integrated_squared_jerk, 60 * m.integrated_squared_jerk);
}

TEST(SessionMetrics, ScriptedPressGivesExactForceStatistics) {
  // |F| = 0.002 i N for ticks i = 0 .. 1999 (a ramp to 3.998 N), then 1000 ticks of 0 N; in
  // contact whenever |F| > 0; direction (0.6, 0, 0.8).
  Recording rec;
  rec.metadata_json = R"({"servo_rate_Hz": 1000})";
  const std::size_t n = 3000;
  for (std::size_t i = 0; i < n; ++i) {
    TickRecord t;
    t.time_s = static_cast<double>(i) * 1e-3;
    t.tick = i;
    const double f = i < 2000 ? 0.002 * static_cast<double>(i) : 0.0;
    t.force_W_N[0] = 0.6 * f;
    t.force_W_N[2] = 0.8 * f;
    t.torque_W_Nm[1] = 0.01 * f;
    t.contacts = f > 0.0 ? 3u : 0u;
    t.tick_time_s = i == 1234 ? 4e-4 : 1e-4;
    if (i == 77 || i == 78) t.flags |= kRecordFlagDeadlineMiss;
    if (i >= 300 && i < 305) t.flags |= kRecordFlagDeadlineCut;
    rec.records.push_back(t);
  }
  MetricsOptions options;
  options.force_threshold_N = 2.0;
  const SessionMetrics m = computeSessionMetrics(rec, options);
  EXPECT_NEAR(m.max_force_N, 0.002 * 1999, 1e-12);
  EXPECT_NEAR(m.mean_force_N, 0.002 * (1999.0 * 2000.0 / 2.0) / 3000.0, 1e-12);
  EXPECT_NEAR(m.mean_contact_force_N, 0.002 * (1999.0 * 2000.0 / 2.0) / 1999.0, 1e-12);
  // Nearest rank ceil(0.95 * 3000) = 2850: 1001 zeros, then 0.002 i from i = 1: i = 2850 - 1001.
  EXPECT_NEAR(m.p95_force_N, 0.002 * (2850 - 1001), 1e-12);
  // |F| > 2 N for i = 1001 .. 1999: 999 ticks of 1 ms.
  EXPECT_NEAR(m.time_above_threshold_s, 0.999, 1e-12);
  EXPECT_NEAR(m.time_in_contact_s, 1.999, 1e-12);
  EXPECT_NEAR(m.max_torque_Nm, 0.01 * 0.002 * 1999, 1e-14);
  EXPECT_EQ(m.deadline_misses, 2u);
  EXPECT_EQ(m.deadline_cuts, 5u);
  EXPECT_DOUBLE_EQ(m.max_tick_s, 4e-4);
  // Another threshold, another time: |F| > 3 N for i = 1501 .. 1999.
  options.force_threshold_N = 3.0;
  EXPECT_NEAR(computeSessionMetrics(rec, options).time_above_threshold_s, 0.499, 1e-12);
  options.force_threshold_N = -1.0;
  VH_EXPECT_THROW_WITH(computeSessionMetrics(rec, options), std::invalid_argument, "threshold");
}

TEST(SessionMetrics, SegmentsAndCriticalRemovalsComeFromTheFlagsAndEvents) {
  Recording rec;
  rec.metadata_json = R"({"servo_rate_Hz": 1000, "scene": {"segmentation": {"segments": [
      {"name": "bone", "critical": false}, {"name": "facial nerve", "critical": true}]}}})";
  for (std::size_t i = 0; i < 1000; ++i) {
    TickRecord t;
    t.time_s = static_cast<double>(i) * 1e-3;
    t.tick = i;
    const int segment = i < 300 ? 0 : (i >= 500 && i < 650) || (i >= 800 && i < 850) ? 1 : -1;
    t.contacts = segment >= 0 ? 1u : 0u;
    t.flags = recordSegmentBits(segment) | (i >= 400 ? kRecordFlagDrillOn : 0u);
    t.force_W_N[2] = segment == 1 ? 1.5 : 0.5;
    rec.records.push_back(t);
  }
  rec.events.push_back({0.51, 510, "critical_removed", R"({"segment":"facial nerve","voxels":3,"mm3":0.375})"});
  rec.events.push_back({0.81, 810, "critical_removed", R"({"segment":"facial nerve","voxels":2,"mm3":0.25})"});
  rec.events.push_back({0.2, 200, "marker", R"({"label":"start"})"});
  const SessionMetrics m = computeSessionMetrics(rec);
  ASSERT_EQ(m.segments.size(), 2u);
  EXPECT_EQ(m.segments[0].name, "bone");
  EXPECT_NEAR(m.segments[0].time_in_contact_s, 0.3, 1e-12);
  EXPECT_EQ(m.segments[1].touches, 2u);
  EXPECT_NEAR(m.segments[1].time_in_contact_s, 0.2, 1e-12);
  EXPECT_DOUBLE_EQ(m.segments[1].peak_force_N, 1.5);
  EXPECT_EQ(m.segments[1].removed_voxels, 5u);
  EXPECT_DOUBLE_EQ(m.segments[1].removed_mm3, 0.625);
  EXPECT_NEAR(m.critical_contact_s, 0.2, 1e-12);
  EXPECT_EQ(m.critical_touches, 2u);
  EXPECT_EQ(m.critical_removed_voxels, 5u);
  EXPECT_NEAR(m.drill_on_s, 0.6, 1e-12);
  EXPECT_EQ(m.markers, 1u);
}

/// Top-down DTW by memoised recursion: the textbook definition, written apart from the
/// library's row-by-row table.
double recursiveDtw(const std::vector<Eigen::Vector3d>& a, const std::vector<Eigen::Vector3d>& b) {
  std::vector<double> memo(a.size() * b.size(), -1.0);
  std::function<double(std::size_t, std::size_t)> D = [&](std::size_t i, std::size_t j) -> double {
    double& slot = memo[i * b.size() + j];
    if (slot >= 0.0) return slot;
    double prev = 0.0;
    if (i > 0 && j > 0) prev = std::min({D(i - 1, j - 1), D(i - 1, j), D(i, j - 1)});
    else if (i > 0) prev = D(i - 1, 0);
    else if (j > 0) prev = D(0, j - 1);
    return slot = (a[i] - b[j]).norm() + prev;
  };
  return D(a.size() - 1, b.size() - 1);
}

std::vector<Eigen::Vector3d> onX(std::initializer_list<double> xs) {
  std::vector<Eigen::Vector3d> out;
  for (double x : xs) out.emplace_back(x, 0.0, 0.0);
  return out;
}

TEST(DynamicTimeWarping, HandComputedCases) {
  // One point against two: both pairs are on the path, |0 - 1| + |2 - 1|.
  DtwAlignment d = dynamicTimeWarping(onX({0, 2}), onX({1}));
  EXPECT_DOUBLE_EQ(d.total_distance_m, 2.0);
  EXPECT_DOUBLE_EQ(d.mean_distance_m, 1.0);
  ASSERT_EQ(d.path.size(), 2u);
  // A copy that waits at its start (shifted in time) aligns with distance 0.
  d = dynamicTimeWarping(onX({0, 1, 2, 3}), onX({0, 0, 0, 1, 2, 3}));
  EXPECT_DOUBLE_EQ(d.total_distance_m, 0.0);
  EXPECT_EQ(d.path.front(), std::make_pair(std::size_t{0}, std::size_t{0}));
  EXPECT_EQ(d.path.back(), std::make_pair(std::size_t{3}, std::size_t{5}));
  // 0 1 2 against 0 2 2: the best path pairs 1 with 0 or 2 once: total 1, over 3 or 4 pairs.
  d = dynamicTimeWarping(onX({0, 1, 2}), onX({0, 2, 2}));
  EXPECT_DOUBLE_EQ(d.total_distance_m, 1.0);
  VH_EXPECT_THROW_WITH(dynamicTimeWarping({}, onX({1})), std::invalid_argument, "non-empty");
}

TEST(DynamicTimeWarping, MatchesTheRecursiveDefinitionOnRandomCases) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-0.05, 0.05);
  std::uniform_int_distribution<int> len(1, 14);
  for (int c = 0; c < 200; ++c) {
    std::vector<Eigen::Vector3d> a(static_cast<std::size_t>(len(rng))), b(static_cast<std::size_t>(len(rng)));
    for (auto& p : a) p = {u(rng), u(rng), u(rng)};
    for (auto& p : b) p = {u(rng), u(rng), u(rng)};
    const DtwAlignment d = dynamicTimeWarping(a, b);
    ASSERT_NEAR(d.total_distance_m, recursiveDtw(a, b), 1e-12) << "case " << c;
    // The path is monotone, connected, and its distances add up to the total.
    double sum = 0.0;
    for (std::size_t k = 0; k < d.path.size(); ++k) {
      sum += (a[d.path[k].first] - b[d.path[k].second]).norm();
      if (k == 0) continue;
      const std::size_t di = d.path[k].first - d.path[k - 1].first, dj = d.path[k].second - d.path[k - 1].second;
      ASSERT_TRUE(di <= 1 && dj <= 1 && di + dj >= 1) << "case " << c << " step " << k;
    }
    EXPECT_NEAR(sum, d.total_distance_m, 1e-12);
    EXPECT_NEAR(dynamicTimeWarping(b, a).total_distance_m, d.total_distance_m, 1e-12);
  }
}

TEST(ReferenceComparison, RefusesAnotherSceneAndAlignsAShiftedCopy) {
  Recording a = circleRecording(0.05, kPi, 1000.0, 2.0);
  a.metadata_json = R"({"servo_rate_Hz": 1000, "dataset": {"sha256": "aaaa1111"}})";
  // The same circle, started 0.5 s later (the device waits at its start).
  Recording b = circleRecording(0.05, kPi, 1000.0, 2.0);
  b.metadata_json = a.metadata_json;
  std::vector<TickRecord> wait(500, b.records.front());
  b.records.insert(b.records.begin(), wait.begin(), wait.end());
  for (std::size_t i = 0; i < b.records.size(); ++i) b.records[i].time_s = static_cast<double>(i) * 1e-3;
  const SessionMetrics ma = computeSessionMetrics(a), mb = computeSessionMetrics(b);
  const ReferenceComparison c = compareWithReference(a, ma, b, mb, a.records.size() + b.records.size());
  EXPECT_NEAR(c.alignment.mean_distance_m, 0.0, 1e-12);
  ASSERT_EQ(c.session.size(), c.reference.size());
  EXPECT_EQ(c.session[0].key, "duration_s");
  EXPECT_NEAR(c.reference[0].value - c.session[0].value, 0.5, 1e-9);
  // Thinned to 200 points each, the alignment is still close (within a thinned step, 2 cm / 200).
  EXPECT_LT(compareWithReference(a, ma, b, mb, 200).alignment.mean_distance_m, 0.005);

  Recording other = b;
  other.metadata_json = R"({"servo_rate_Hz": 1000, "dataset": {"sha256": "bbbb2222"}})";
  VH_EXPECT_THROW_WITH(compareWithReference(a, ma, other, computeSessionMetrics(other)), std::invalid_argument,
                       "another scene", "bbbb2222", "aaaa1111");
}

/// Writes a circle recording with RecordingWriter; returns its path.
fs::path writeCircle(const fs::path& path, double seconds, const std::string& label) {
  fs::create_directories(path.parent_path());
  RecordingWriterOptions opt;
  opt.ring_capacity = 1u << 15;
  RecordingWriter writer(path, nlohmann::json{{"note", label}, {"dataset", {{"sha256", "cafe"}}}}.dump(), opt);
  for (const TickRecord& t : circleRecording(0.05, kPi, 1000.0, seconds).records) writer.pushWaiting(t);
  writer.close();
  return path;
}

TEST(SessionMetrics, TruncatedOrEmptyRecordingGivesMetricsWithANotice) {
  const fs::path dir = test::scratchDir();
  const fs::path path = writeCircle(dir / "cut.vhrec", 3.0, "cut");
  const auto size = fs::file_size(path);
  fs::resize_file(path, size - 5000);  // a kill -9 during the last chunk's write
  const Recording rec = readRecording(path);
  const SessionMetrics m = computeSessionMetrics(rec);
  ASSERT_FALSE(m.notices.empty());
  EXPECT_NE(m.notices[0].find("truncated"), std::string::npos) << m.notices[0];
  EXPECT_GT(m.records, 2000u);
  EXPECT_NEAR(m.mean_speed_m_per_s, 0.05 * kPi, 0.01 * 0.05 * kPi);

  // Only the header survived: zeros and a notice, no division by zero.
  std::ifstream in(path, std::ios::binary);
  std::string head(24, '\0');
  in.read(head.data(), 24);
  std::uint32_t meta_len = 0;
  std::memcpy(&meta_len, head.data() + 16, 4);
  fs::resize_file(path, 24 + meta_len);
  const SessionMetrics empty = computeSessionMetrics(readRecording(path));
  EXPECT_EQ(empty.records, 0u);
  EXPECT_EQ(empty.mean_force_N, 0.0);
  bool said = false;
  for (const std::string& n : empty.notices) said = said || n.find("holds no ticks") != std::string::npos;
  EXPECT_TRUE(said);
}

// The report's speed over time: a circle at 0.05 m x pi rad/s = 0.157 m/s, with a 0.1 m jump
// half way. Flagged as a placement, the jump is no motion: the line breaks there, its time is
// marked, and the largest speed is the circle's; unflagged, the same jump reads as about 5 m/s
// (0.1 m over the 20 ms of the central difference), the spike a teacher saw.
TEST(SessionMetrics, TheSpeedSeriesBreaksAtAPlacementInsteadOfSpiking) {
  for (const bool flagged : {true, false}) {
    Recording rec = circleRecording(0.05, kPi, 1000.0, 2.0);
    for (std::size_t i = 1000; i < rec.records.size(); ++i) rec.records[i].p_WD_m[2] += 0.1;
    if (flagged) rec.records[1000].flags |= kRecordFlagPlacement;
    const DeviceSpeedSeries series = deviceSpeedSeries(rec, 1000.0, 0.01, 1);
    const double circle = 0.05 * kPi;
    if (flagged) {
      EXPECT_NEAR(series.max_m_per_s, circle, 0.01 * circle);
      ASSERT_EQ(series.placements_s.size(), 1u);
      EXPECT_DOUBLE_EQ(series.placements_s[0], 1.0);
      ASSERT_EQ(series.pieces.size(), 2u) << "the line breaks at the placement";
      EXPECT_LT(series.pieces[0].back().first, 1.0);
      EXPECT_GE(series.pieces[1].front().first, 1.0);
      EXPECT_NEAR(computeSessionMetrics(rec).peak_speed_m_per_s, series.max_m_per_s, 0.01 * circle)
          << "the chart and the metrics agree";
    } else {
      EXPECT_GT(series.max_m_per_s, 4.0);
      EXPECT_EQ(series.pieces.size(), 1u);
    }
  }
}

TEST(CohortTable, LabelFallsBackToTheFileNameAndRemovedVolumeIsAColumn) {
  const fs::path dir = test::scratchDir() / "cohort-label";
  writeCircle(dir / "trainee-07.vhrec", 1.0, "");  // no user, no note
  {  // a drilling session's recording: 125 voxels of 0.1 mm^3 removed over its ticks, on a
     // cavity of 7 + 3 voxels it began with
    RecordingWriterOptions opt;
    opt.ring_capacity = 1u << 15;
    const nlohmann::json meta = {
        {"note", "expert"},
        {"drilling", {{"felt_voxel_volume_mm3", 0.1}}},
        {"scene", {{"drill", {{"cavity", {{"spacing_m", {1e-3, 1e-3, 1e-3}}, {"runs", {10, 7, 40, 3}}}}}}}}};
    RecordingWriter writer(dir / "drilled.vhrec", meta.dump(), opt);
    int i = 0;
    for (TickRecord t : circleRecording(0.05, kPi, 1000.0, 0.5).records) {
      t.removed_voxels = i++ < 125 ? 1u : 0u;
      writer.pushWaiting(t);
    }
    // An event such as `run` wrote until format version 4: not counted beside the records.
    writer.addEvent({0.499, 500, "drilled", R"({"voxels": 999, "mm3": 99.9})"});
    writer.close();
  }
  const SessionMetrics m = computeSessionMetrics(readRecording(dir / "drilled.vhrec"));
  EXPECT_EQ(m.removed_voxels, 125u);
  EXPECT_DOUBLE_EQ(m.removed_mm3, 12.5);
  EXPECT_EQ(m.cavity_at_start_voxels, 10u);
  EXPECT_DOUBLE_EQ(m.cavity_at_start_mm3, 1.0);
  EXPECT_EQ(m.cavity_voxels, 135u);
  EXPECT_DOUBLE_EQ(m.cavity_mm3, 13.5);
  {  // the same file as format version 4 (no removed voxels in its records): the event counts
    std::ifstream in(dir / "drilled.vhrec", std::ios::binary);
    const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    test::writeText(dir / "old" / "drilled-v4.vhrec", test::asVersion4Recording(bytes));
    const SessionMetrics old = computeSessionMetrics(readRecording(dir / "old" / "drilled-v4.vhrec"));
    EXPECT_EQ(old.removed_voxels, 999u);
    EXPECT_DOUBLE_EQ(old.removed_mm3, 99.9);
    EXPECT_EQ(old.cavity_at_start_voxels, 10u);
  }
  fs::remove_all(dir / "old");
  ASSERT_EQ(writeCohortTable(dir, dir / "table.csv"), 2u);
  std::ifstream in(dir / "table.csv");
  std::vector<std::vector<std::string>> rows;
  for (std::string line; std::getline(in, line);) {
    std::vector<std::string> cells(1);
    for (char c : line) {  // no quoted fields in these rows
      if (c == ',') cells.emplace_back();
      else cells.back() += c;
    }
    rows.push_back(cells);
  }
  ASSERT_EQ(rows.size(), 3u);
  const auto column = [&](const std::string& key) {
    return static_cast<std::size_t>(std::find(rows[0].begin(), rows[0].end(), key) - rows[0].begin());
  };
  ASSERT_LT(column("removed_mm3"), rows[0].size()) << "no removed_mm3 column";
  EXPECT_EQ(rows[1][0], "drilled.vhrec");
  EXPECT_EQ(rows[1][column("label")], "expert") << "the note";
  EXPECT_DOUBLE_EQ(std::stod(rows[1][column("removed_mm3")]), 12.5);
  EXPECT_EQ(rows[2][0], "trainee-07.vhrec");
  EXPECT_EQ(rows[2][column("label")], "trainee-07") << "no user or note: the file name";
  EXPECT_DOUBLE_EQ(std::stod(rows[2][column("removed_mm3")]), 0.0);
  // Per material: the drilled one's scene cannot be reloaded (its metadata has none), which its
  // notices say; no recording gives materials, so no column is added.
  CohortTableOptions per_material;
  per_material.drilled_per_material = true;
  ASSERT_EQ(writeCohortTable(dir, dir / "per-material.csv", per_material), 2u);
  std::ifstream in2(dir / "per-material.csv");
  std::vector<std::string> lines;
  for (std::string line; std::getline(in2, line);) lines.push_back(line);
  ASSERT_EQ(lines.size(), 3u);
  EXPECT_EQ(lines[0].find("removed_mm3["), std::string::npos) << lines[0];
  EXPECT_NE(lines[1].find("removal per material not known: the scene could not be reloaded (session metadata: bad"),
            std::string::npos)
      << lines[1];
  EXPECT_EQ(lines[2].find("not known"), std::string::npos) << "drilled nothing: " << lines[2];
}

TEST(CohortTable, OneRowPerRecordingInTheTreeWithProgress) {
  const fs::path dir = test::scratchDir() / "cohort";
  writeCircle(dir / "a.vhrec", 1.0, "trainee, A");
  writeCircle(dir / "group" / "b.vhrec", 2.0, "trainee B");
  test::writeText(dir / "group" / "broken.vhrec", "not a recording");
  test::writeText(dir / "notes.txt", "ignored");
  std::vector<std::size_t> seen;
  const std::size_t rows = writeCohortTable(dir, dir / "table.csv", {}, [&](std::size_t done, std::size_t total) {
    EXPECT_EQ(total, 3u);
    seen.push_back(done);
  });
  EXPECT_EQ(rows, 3u);
  EXPECT_EQ(seen, (std::vector<std::size_t>{1, 2, 3}));
  std::ifstream in(dir / "table.csv");
  std::vector<std::string> lines;
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  ASSERT_EQ(lines.size(), 4u);
  EXPECT_EQ(lines[0].rfind("file,scene,dataset_sha256,label,start_time_utc,duration_s,", 0), 0u) << lines[0];
  EXPECT_EQ(lines[1].rfind("a.vhrec,,cafe,\"trainee, A\",", 0), 0u) << lines[1];
  EXPECT_EQ(lines[2].rfind("group/b.vhrec,", 0), 0u) << lines[2];
  EXPECT_NE(lines[2].find(",2,"), std::string::npos) << "duration 2 s: " << lines[2];
  EXPECT_EQ(lines[3].rfind("group/broken.vhrec,", 0), 0u) << lines[3];
  EXPECT_NE(lines[3].find("not read:"), std::string::npos) << lines[3];
  // Every row has the header's column count (the broken one's metrics empty).
  const auto columns = [](const std::string& s) {
    std::size_t n = 1;
    bool quoted = false;
    for (char c : s) {
      if (c == '"') quoted = !quoted;
      else if (c == ',' && !quoted) ++n;
    }
    return n;
  };
  for (const std::string& l : lines) EXPECT_EQ(columns(l), columns(lines[0])) << l;
  VH_EXPECT_THROW_WITH(writeCohortTable(dir / "none", dir / "x.csv"), std::runtime_error, "not a folder");
}

}  // namespace
}  // namespace vh::runtime
