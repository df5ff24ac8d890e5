// Warnings before harm: the tool's distance to a critical segment per tick (critical_proximity.h).
// A CT of air (nothing felt: the proxy follows the device) with a critical ball in its label
// map; the tool approaches the ball along a grid axis and leaves. The reported distances, times
// within the thresholds and closest approach are checked against the analytic distance from the
// shell's points to the ball; the recording carries the same figures and derives the events.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <string>

#include <nlohmann/json.hpp>

#include "runtime_test_support.h"
#include "vh/runtime/drilling.h"
#include "vh/runtime/recording.h"
#include "vh/runtime/runner.h"
#include "vh/runtime/scene.h"
#include "vh/runtime/session_metrics.h"
#include "vh/runtime/trajectory.h"

namespace vh::runtime {
namespace {

namespace fs = std::filesystem;

constexpr int kN = 80;            // voxels per axis
constexpr double kH_m = 0.25e-3;  // voxel size
const Eigen::Vector3d kBall_W_m(0.005, 0.010, 0.010);  // on a voxel centre
constexpr double kBallRadius_m = 2.0e-3;               // 8 voxels

std::string nrrdHeader(const std::string& type, const std::string& extra) {
  return "NRRD0004\ntype: " + type + "\ndimension: 3\nspace: left-posterior-superior\nsizes: 80 80 80\n"
         "space directions: (0.25,0,0) (0,0.25,0) (0,0,0.25)\nkinds: domain domain domain\nendian: little\n"
         "encoding: raw\nspace origin: (0,0,0)\n" + extra + "\n";
}

/// ct.nrrd (air), case.seg.nrrd (the ball, label 1 "facial nerve") and a scene naming it critical.
fs::path writeCase(const std::string& proximity) {
  const fs::path dir = test::scratchDir();
  std::string ct(static_cast<std::size_t>(kN * kN * kN) * 2, '\0'), labels;
  for (int k = 0; k < kN; ++k)
    for (int j = 0; j < kN; ++j)
      for (int i = 0; i < kN; ++i)
        labels.push_back((Eigen::Vector3d(i, j, k) * kH_m - kBall_W_m).norm() <= kBallRadius_m + 1e-12 ? 1 : 0);
  std::ofstream(dir / "ct.nrrd", std::ios::binary) << nrrdHeader("short", "") << ct;
  const std::string keys = "Segment0_Color:=1 0.9 0.2\nSegment0_ID:=Segment_1\nSegment0_LabelValue:=1\n"
                           "Segment0_Layer:=0\nSegment0_Name:=facial nerve\n";
  std::ofstream(dir / "case.seg.nrrd", std::ios::binary) << nrrdHeader("unsigned char", keys) << labels;
  test::writeText(dir / "scene.json", R"({"volume": {"path": "ct.nrrd", "isovalue": 150},
      "tool": {"mesh": "builtin:sphere", "scale_to_m": 0.1, "point_spacing_m": 0.0005},
      "coupling": {"linear_N_per_m": 1000},
      "segmentation": {"path": "case.seg.nrrd", "critical": ["facial nerve"])" + proximity + "}}");
  return dir;
}

/// The analytic distance from the shell at X_WP to the ball [m] (points inside: 0).
double analyticDistance(const haptics::PointShell& shell, const haptics::Pose& X_WP) {
  double best = std::numeric_limits<double>::infinity();
  for (const auto& p_T : shell.points_T_m())
    best = std::min(best, std::max(0.0, (X_WP * p_T - kBall_W_m).norm() - kBallRadius_m));
  return best;
}

/// Along +x towards the ball from 8 mm to 0.4 mm of analytic clearance in 0.8 s, held 0.1 s,
/// back in 0.8 s (the tool's centre on the line through the ball's centre).
Trajectory approach(const haptics::PointShell& shell) {
  double reach = 0.0;  // the shell's extent along -x from its origin
  for (const auto& p : shell.points_T_m()) reach = std::max(reach, -p.x());
  const auto at = [&](double t, double clearance_m) {
    TrajectorySample s;
    s.t_s = t;
    s.X_WD.p_AB_m = kBall_W_m + Eigen::Vector3d(kBallRadius_m + reach + clearance_m, 0, 0);
    return s;
  };
  return Trajectory({at(0.0, 8e-3), at(0.8, 0.4e-3), at(0.9, 0.4e-3), at(1.7, 8e-3)});
}

TEST(CriticalProximity, HeadlessApproachMatchesTheAnalyticDistance) {
  const fs::path dir = writeCase(R"(, "proximity": {"warn_mm": 3, "alarm_mm": 1.5})");
  const LoadedScene scene = loadScene(loadSceneFile(dir / "scene.json"));
  const Trajectory trajectory = approach(scene.tool->point_shell);
  RunOptions options;
  options.record = dir / "approach.vhrec";
  options.lag_reference = false;
  const RunReport r = runHeadless(scene, trajectory, options);
  std::cout << "[ proximity ] " << r.summary() << "\n";
  ASSERT_EQ(r.proximity.size(), 1u);
  const SegmentProximityStats& p = r.proximity.front();
  EXPECT_EQ(p.name, "facial nerve");
  EXPECT_EQ(p.thresholds, (ProximityThresholds{3e-3, 1.5e-3}));

  // The analytic distance per tick (the proxy follows the device: nothing is felt).
  const Recording rec = readRecording(dir / "approach.vhrec");
  ASSERT_EQ(rec.version, kRecordingFormatVersion);
  ASSERT_EQ(rec.records.size(), r.ticks);
  const double dt = 1e-3;
  // Stated bound: sampling (half the voxel diagonal) plus the ball's voxel centres against the
  // ball (half a voxel diagonal too).
  const double bound = std::sqrt(3.0) * kH_m;
  double closest = std::numeric_limits<double>::infinity(), worst = 0.0;
  int warn_ticks = 0, alarm_ticks = 0;
  for (const TickRecord& t : rec.records) {
    haptics::Pose X_WP;
    X_WP.p_AB_m = {t.p_WP_m[0], t.p_WP_m[1], t.p_WP_m[2]};
    X_WP.R_AB = Eigen::Quaterniond(t.q_WP[0], t.q_WP[1], t.q_WP[2], t.q_WP[3]);
    const double d = analyticDistance(scene.tool->point_shell, X_WP);
    closest = std::min(closest, d);
    warn_ticks += d <= 3e-3 ? 1 : 0;
    alarm_ticks += d <= 1.5e-3 ? 1 : 0;
    if (d < kProximityRange_m - 1e-3) {
      ASSERT_EQ(t.critical_segment, 0) << "tick " << t.tick;
      worst = std::max(worst, std::abs(t.critical_distance_m - d));
    }
  }
  std::cout << "[ proximity ] worst |reported - analytic| " << worst * 1e3 << " mm (bound " << bound * 1e3
            << " mm); closest analytic " << closest * 1e3 << " mm, reported " << p.closest_m * 1e3 << " mm\n";
  EXPECT_LE(worst, bound);
  EXPECT_NEAR(p.closest_m, closest, bound);
  EXPECT_NEAR(p.closest_time_s, 0.85, 0.051);  // during the hold
  // Times within each threshold: as the analytic distance says, within two ticks per crossing.
  EXPECT_NEAR(p.time_within_warn_s, warn_ticks * dt, 4 * dt);
  EXPECT_NEAR(p.time_within_alarm_s, alarm_ticks * dt, 4 * dt);
  EXPECT_GT(alarm_ticks, 100);
  EXPECT_EQ(p.warnings, 1u);
  EXPECT_EQ(p.alarms, 1u);

  // The report's JSON, the recording's events and the session metrics say the same.
  const auto j = nlohmann::json::parse(r.toJson());
  ASSERT_EQ(j.at("proximity").size(), 1u);
  EXPECT_DOUBLE_EQ(j["proximity"][0]["closest_mm"].get<double>(), p.closest_m * 1e3);
  EXPECT_DOUBLE_EQ(j["proximity"][0]["time_within_warn_s"].get<double>(), p.time_within_warn_s);
  std::vector<std::string> types;
  for (const auto& e : rec.events)
    if (e.type.rfind("proximity", 0) == 0) types.push_back(e.type);
  EXPECT_EQ(types, (std::vector<std::string>{"proximity_warn", "proximity_alarm", "proximity_alarm_cleared",
                                             "proximity_warn_cleared"}));
  for (const auto& e : rec.events) {
    if (e.type != "proximity_alarm") continue;
    const auto d = nlohmann::json::parse(e.detail_json);
    EXPECT_EQ(d.at("segment"), "facial nerve");
    EXPECT_LE(d.at("distance_mm").get<double>(), 1.5);
  }
  const SessionMetrics m = computeSessionMetrics(rec);
  ASSERT_EQ(m.proximity.size(), 1u);
  EXPECT_EQ(m.proximity[0].closest_m, p.closest_m);
  EXPECT_NEAR(m.proximity[0].time_within_warn_s, p.time_within_warn_s, 1e-9);
  EXPECT_NEAR(m.proximity[0].time_within_alarm_s, p.time_within_alarm_s, 1e-9);

  // The same recording as format version 3 still reads: no distances, "not measured".
  std::ifstream in(dir / "approach.vhrec", std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  test::writeText(dir / "v3.vhrec", test::asVersion3Recording(bytes));
  const Recording old = readRecording(dir / "v3.vhrec");
  EXPECT_EQ(old.version, 3u);
  ASSERT_EQ(old.records.size(), rec.records.size());
  EXPECT_EQ(old.records[5].p_WP_m[0], rec.records[5].p_WP_m[0]);
  EXPECT_TRUE(std::isnan(old.records[5].critical_distance_m));
  const auto old_proximity = segmentProximity(old, dt);
  ASSERT_EQ(old_proximity.size(), 1u);
  EXPECT_TRUE(std::isnan(old_proximity[0].closest_m));
}

// A tool hovering at the warning distance (2 mm, the point shell's distance moving by +-0.03 mm
// from tick to tick, as contact jitter does), then at the alarm's (1 mm), then between them, then
// away, gives one warning, one alarm, one end of each,
// not a warn / clear pair every other tick (the flicker a teacher saw: 4 pairs within 15 ms); the
// alarm likewise. Without the hysteresis (proximityLevel() tick by tick) the same distances
// change level 150 times (the check can fail).
TEST(CriticalProximity, AToolHoveringAtAThresholdIsWarnedOnce) {
  const fs::path dir = test::scratchDir();
  const nlohmann::json meta = {
      {"scene", {{"segmentation", {{"segments", {{{"name", "facial nerve"}, {"critical", true}, {"warn_mm", 2.0}, {"alarm_mm", 1.0}}}}}}}}};
  std::vector<double> distances_m;
  for (int i = 0; i < 300; ++i) distances_m.push_back(2.0e-3 + ((i % 2) != 0 ? 0.03e-3 : -0.03e-3));  // at warn
  for (int i = 0; i < 300; ++i) distances_m.push_back(1.0e-3 + ((i % 2) != 0 ? 0.03e-3 : -0.03e-3));  // at alarm
  for (int i = 0; i < 300; ++i) distances_m.push_back(1.5e-3 + ((i % 2) != 0 ? 0.03e-3 : -0.03e-3));  // out of the alarm
  for (int i = 0; i < 100; ++i) distances_m.push_back(5.0e-3);                                          // away
  {
    RecordingWriter writer(dir / "hover.vhrec", meta.dump());
    for (std::size_t i = 0; i < distances_m.size(); ++i) {
      TickRecord r;
      r.tick = i + 1;
      r.time_s = 1e-3 * static_cast<double>(i);
      r.critical_segment = 0;
      r.critical_distance_m = distances_m[i];
      writer.pushWaiting(r);
    }
    writer.close();
  }
  const Recording rec = readRecording(dir / "hover.vhrec");
  std::vector<std::string> types;
  for (const auto& e : rec.events)
    if (e.type.rfind("proximity", 0) == 0) types.push_back(e.type);
  EXPECT_EQ(types, (std::vector<std::string>{"proximity_warn", "proximity_alarm", "proximity_alarm_cleared",
                                             "proximity_warn_cleared"}));
  int raw_changes = 0;
  ProximityLevel previous = ProximityLevel::kClear;
  for (const double d : distances_m) {
    const ProximityLevel now = proximityLevel(d, ProximityThresholds{2e-3, 1e-3});
    raw_changes += now != previous;
    previous = now;
  }
  EXPECT_GT(raw_changes, 100);
  // The hysteresis leaves a level 0.2 mm past the warning distance (10 %), 0.1 mm past the alarm's.
  EXPECT_EQ(proximityLevelAfter(ProximityLevel::kWarn, 2.19e-3, {2e-3, 1e-3}), ProximityLevel::kWarn);
  EXPECT_EQ(proximityLevelAfter(ProximityLevel::kWarn, 2.21e-3, {2e-3, 1e-3}), ProximityLevel::kClear);
  EXPECT_EQ(proximityLevelAfter(ProximityLevel::kAlarm, 1.09e-3, {2e-3, 1e-3}), ProximityLevel::kAlarm);
  EXPECT_EQ(proximityLevelAfter(ProximityLevel::kAlarm, 1.11e-3, {2e-3, 1e-3}), ProximityLevel::kWarn);
  EXPECT_EQ(proximityLevelAfter(ProximityLevel::kClear, 1.99e-3, {2e-3, 1e-3}), ProximityLevel::kWarn) << "nearer: at once";
}

TEST(CriticalProximity, SceneFileThresholdsAndTheirErrors) {
  const fs::path dir = writeCase(R"(, "proximity": {"warn_mm": 2.5, "per_segment": {"Facial Nerve": {"alarm_mm": 0.5}}})");
  const LoadedScene scene = loadScene(loadSceneFile(dir / "scene.json"));
  ASSERT_TRUE(scene.segments);
  EXPECT_EQ(scene.segments->thresholds(0), (ProximityThresholds{2.5e-3, 0.5e-3}));
  ASSERT_EQ(scene.segments->criticalFields().size(), 1u);
  // Defaults: 2 mm / 1 mm.
  const fs::path plain = writeCase("");
  EXPECT_EQ(loadScene(loadSceneFile(plain / "scene.json")).segments->thresholds(0), (ProximityThresholds{2e-3, 1e-3}));
  // The GUI's route: the same set with other thresholds, sharing the distance fields.
  const auto changed = scene.segments->withThresholds({ProximityThresholds{4e-3, 2e-3}});
  EXPECT_EQ(changed->thresholds(0).warn_m, 4e-3);
  EXPECT_EQ(changed->criticalFields().front(), scene.segments->criticalFields().front());
  EXPECT_THROW((void)scene.segments->withThresholds({ProximityThresholds{1e-3, 2e-3}}), std::invalid_argument);

  const auto error = [&](const std::string& proximity) {
    const fs::path d = writeCase(proximity);
    try {
      (void)loadScene(loadSceneFile(d / "scene.json"));
    } catch (const std::exception& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  const auto has = [](const std::string& text, const std::string& part) {
    return text.find(part) != std::string::npos;
  };
  std::string e = error(R"(, "proximity": {"warn_mm": 1, "alarm_mm": 2})");
  EXPECT_TRUE(has(e, "segmentation.proximity: alarm_mm (2 mm) must not exceed warn_mm (1 mm)")) << e;
  e = error(R"(, "proximity": {"warn_mm": -1})");
  EXPECT_TRUE(has(e, "segmentation.proximity.warn_mm: must be > 0")) << e;
  e = error(R"(, "proximity": {"warn_mm": 50})");
  EXPECT_TRUE(has(e, "beyond the measured range (20 mm)")) << e;
  e = error(R"(, "proximity": {"warm_mm": 3})");
  EXPECT_TRUE(has(e, "unknown key 'warm_mm'")) << e;
  e = error(R"(, "proximity": {"per_segment": {"vagus": {"warn_mm": 3}}})");
  EXPECT_TRUE(has(e, "no segment \"vagus\"")) << e;
  e = error(R"(, "proximity": {"per_segment": {"facial nerve": {"warn_mm": 3, "alarm_mm": 4}}})");
  EXPECT_TRUE(has(e, "segmentation.proximity.per_segment.facial nerve: alarm_mm (4 mm) must not exceed")) << e;
}

// The head phantom, drilled near a critical "facial nerve": a tube (radius 1 mm, along y) in a
// label map of its own 0.3 mm grid, 1.5 mm below the skull's surface and beside the burr's
// path. The burr drills 2 mm down into the bone, then 3 mm sideways towards the tube, and back.
// Writes phantom-nerve.json and phantom-nerve.csv (for `volume-haptics run`) into the test's
// folder; the run reports the time within each threshold and the closest approach.
TEST(CriticalProximity, HeadPhantomDrillingNearANerve) {
  const fs::path phantom = test::sharedDatasets() / "ct" / "philips-head-phantom-bone";
  if (!fs::exists(phantom)) GTEST_SKIP() << phantom << " is absent";
  const fs::path dir = test::scratchDir();
  const std::string base = R"({"volume": {"path": ")" + phantom.string() + R"(", "isovalue": 400},
      "tool": {"mesh": "builtin:drill", "point_spacing_m": 0.001}, "drill": {"on": true})";
  test::writeText(dir / "plain.json", base + "}");
  const LoadedScene plain = loadScene(loadSceneFile(dir / "plain.json"));
  const Burr burr = burrOf(*plain.tool, DrillSpec{});
  const haptics::Pose X0 = plain.X_WT_initial;
  const Eigen::Vector3d bottom = X0 * burr.center_T_m - Eigen::Vector3d(0, 0, burr.radius_m);
  double contact_m = 0.0;
  while (contact_m < 0.15 && !plain.volume.field->isInside(bottom - Eigen::Vector3d(0, 0, contact_m), plain.isovalue))
    contact_m += 1e-4;
  ASSERT_LT(contact_m, 0.15) << "no bone below the drill";
  // The nerve's axis: 2 mm below the surface, 4 mm of clearance beside the burr's centre line.
  const Eigen::Vector3d axis = X0 * burr.center_T_m + Eigen::Vector3d(burr.radius_m + 1e-3 + 4e-3, 0, -contact_m - 2e-3);
  constexpr int n = 60;
  const double h = 0.3e-3;
  const Eigen::Vector3d origin = axis - Eigen::Vector3d::Constant(0.5 * (n - 1) * h);
  std::string labels;
  for (int k = 0; k < n; ++k)
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i) {
        const Eigen::Vector3d p = origin + h * Eigen::Vector3d(i, j, k);
        labels.push_back(std::hypot(p.x() - axis.x(), p.z() - axis.z()) <= 1e-3 ? 1 : 0);
      }
  char header[512];
  std::snprintf(header, sizeof header,
                "NRRD0004\ntype: unsigned char\ndimension: 3\nspace: left-posterior-superior\nsizes: 60 60 60\n"
                "space directions: (0.3,0,0) (0,0.3,0) (0,0,0.3)\nkinds: domain domain domain\nendian: little\n"
                "encoding: raw\nspace origin: (%.9g,%.9g,%.9g)\n",
                origin.x() * 1e3, origin.y() * 1e3, origin.z() * 1e3);
  std::ofstream(dir / "nerve.seg.nrrd", std::ios::binary)
      << header << "Segment0_Color:=1 0.9 0.2\nSegment0_ID:=Segment_1\nSegment0_LabelValue:=1\nSegment0_Layer:=0\n"
      << "Segment0_Name:=facial nerve\n\n" << labels;
  test::writeText(dir / "phantom-nerve.json",
                  base + R"(, "segmentation": {"path": ")" + (dir / "nerve.seg.nrrd").string() +
                      R"(", "critical": ["facial nerve"], "proximity": {"warn_mm": 2, "alarm_mm": 1}}})");
  const auto key = [&](double t, double down_m, double side_m) {
    TrajectorySample s;
    s.t_s = t;
    s.X_WD = X0;
    s.X_WD.p_AB_m += Eigen::Vector3d(side_m, 0, -down_m);
    return s;
  };
  const double d = contact_m + 2e-3;
  const Trajectory trajectory({key(0, 0, 0), key(2, d, 0), key(4, d, 3e-3), key(5, d, 3e-3), key(7, d, 0)});
  writeTrajectoryCsv(trajectory, dir / "phantom-nerve.csv");

  const LoadedScene scene = loadScene(loadSceneFile(dir / "phantom-nerve.json"));
  RunOptions options;
  options.lag_reference = false;
  const RunReport r = runHeadless(scene, trajectory, options);
  std::cout << "[ phantom ] files in " << dir << "\n[ phantom ] " << r.summary() << "\n";
  ASSERT_EQ(r.proximity.size(), 1u);
  const SegmentProximityStats& p = r.proximity.front();
  EXPECT_TRUE(std::isfinite(p.closest_m));
  EXPECT_LT(p.closest_m, 4e-3);   // it came nearer than it started
  EXPECT_GT(p.time_within_warn_s, 0.0);
  EXPECT_GE(p.time_within_warn_s, p.time_within_alarm_s);
}

}  // namespace
}  // namespace vh::runtime
