// Drilling in a scene: the "drill" section, the hardness classes, a headless run that drills
// into the built-in sphere (never through what is not removed: crossings 0), and a record /
// replay round trip that rebuilds the drilled field bit for bit (SHA-256 of its voxels).
#include "vh/runtime/drilling.h"

#include <algorithm>
#include <atomic>
#include <fstream>
#include <iostream>
#include <iterator>
#include <map>
#include <optional>
#include <thread>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "drilling_scenes.h"
#include "runtime_test_support.h"
#include "vh/runtime/cohort_table.h"
#include "vh/runtime/default_isovalue.h"
#include "vh/runtime/haptic_thread.h"
#include "vh/runtime/placement.h"
#include "vh/runtime/recording.h"
#include "vh/runtime/replay.h"
#include "vh/runtime/session_metrics.h"
#include "vh/runtime/runner.h"
#include "vh/runtime/scene.h"
#include "vh/runtime/session.h"
#include "vh/runtime/session_metadata.h"
#include "vh/runtime/sha256.h"
#include "vh/runtime/snapshot_channel.h"

namespace vh::runtime {
namespace {

// The device at (x, y) [m], lowered from z_from to z_to [m] over the first t_down_s seconds,
// then held until 3 s.
Trajectory pressDown(double x, double y, double z_from, double t_down_s, double z_to) {
  return test::pressTrajectory(x, y, z_from, t_down_s, z_to, 3.0);
}

const char* kDrillScene = R"({
  "volume": {"path": "builtin:sphere"},
  "tool": {"mesh": "builtin:drill", "point_spacing_m": 0.001},
  "coupling": {"linear_N_per_m": 400},
  "drill": {"on": true, "burr_radius_m": 0.0025, "hardness": {"tissue": 2.0}}
})";

TEST(Drilling, SceneSectionIsParsedAndChecked) {
  const SceneSpec spec = parseScene(kDrillScene, "drill.json", ".");
  ASSERT_TRUE(spec.drill.has_value());
  EXPECT_TRUE(spec.drill->on);
  EXPECT_DOUBLE_EQ(spec.drill->burr_radius_m, 0.0025);
  EXPECT_DOUBLE_EQ(spec.drill->hardness_J_per_mm3.at("tissue"), 2.0);
  VH_EXPECT_THROW_WITH(parseScene(R"({"volume": {"path": "builtin:sphere"}, "drill": {"burr_radius_m": 0.02}})", "s.json", "."),
                       std::runtime_error, "s.json", "drill.burr_radius_m", "1 to 6 mm");
  VH_EXPECT_THROW_WITH(parseScene(R"({"volume": {"path": "builtin:sphere"}, "drill": {"speed": 3}})", "s.json", "."),
                       std::runtime_error, "unknown key 'speed'");
  VH_EXPECT_THROW_WITH(parseScene(R"({"volume": {"path": "builtin:sphere"}, "drill": {"hardness": {"bone": -1}}})", "s.json", "."),
                       std::runtime_error, "drill.hardness.bone", "> 0");
  EXPECT_FALSE(parseScene(R"({"volume": {"path": "builtin:sphere"}})", "s.json", ".").drill.has_value())
      << "a scene without the section starts no drilling";
}

// The built-in drill's burr: the ball at T's origin, found from the mesh alone.
TEST(Drilling, BurrOfTheBuiltinDrillIsItsBall) {
  const LoadedScene scene = loadScene(parseScene(kDrillScene, "drill.json", "."));
  DrillSpec spec;
  const Burr burr = burrOf(*scene.tool, spec);
  EXPECT_NEAR(burr.radius_m, 0.0025, 1e-12);
  EXPECT_LT(burr.center_T_m.norm(), 2e-4) << burr.center_T_m.transpose();
}

// HU classes: soft tissue, cancellous and cortical bone by the voxel's HU, a spec's hardness by
// name, and a name that is no material refused with the list.
TEST(Drilling, HardnessFollowsHounsfieldUnits) {
  haptics::VolumeGeometry g;
  g.dims = {3, 2, 2};
  const std::vector<std::int16_t> hu{-1000, 400, 1200, 0, 300, 900, -1000, 400, 1200, 0, 300, 900};
  const haptics::ScalarVolume ct = haptics::ScalarVolume::FromVoxels(g, hu);
  DrillSpec spec;
  spec.hardness_J_per_mm3["cortical bone"] = 3.5;
  const DrillMaterials m = makeDrillMaterials(ct, ct, true, nullptr, spec);
  ASSERT_EQ(m.materials.size(), 3u);
  const std::vector<std::uint8_t> expected{0, 1, 2, 0, 1, 2, 0, 1, 2, 0, 1, 2};
  EXPECT_EQ(m.voxel_material, expected);
  EXPECT_DOUBLE_EQ(m.materials[2].specific_energy_J_per_mm3, 3.5);
  EXPECT_DOUBLE_EQ(m.materials[1].specific_energy_J_per_mm3, kCancellousBone_J_per_mm3);
  EXPECT_GT(m.materials[2].specific_energy_J_per_mm3, m.materials[1].specific_energy_J_per_mm3);
  EXPECT_GT(m.materials[1].specific_energy_J_per_mm3, m.materials[0].specific_energy_J_per_mm3);
  spec.hardness_J_per_mm3["enamel"] = 9.0;
  VH_EXPECT_THROW_WITH(makeDrillMaterials(ct, ct, true, nullptr, spec), std::invalid_argument, "enamel",
                       "cortical bone");
}

// Press the drill 10 mm into the sphere's top for 3 s: it sinks as it cuts, the crossing check
// against the carved field finds nothing, and the replay of the recording (scene rebuilt from
// its metadata) cuts the same voxels: identical poses and forces, identical field checksum.
TEST(Drilling, HeadlessRunDrillsAndReplaysBitForBit) {
  const auto dir = test::scratchDir();
  const LoadedScene scene = loadScene(parseScene(kDrillScene, "drill.json", "."));
  const Trajectory press = pressDown(0.0, 0.0, 0.030, 1.0, 0.0125);
  RunOptions options;
  options.record = dir / "drill.vhrec";
  options.lag_reference = false;
  options.verify_step_voxels = 0.05;
  const RunReport report = runHeadless(scene, press, options);
  ASSERT_TRUE(report.drill.has_value());
  EXPECT_GT(report.drill->removed_mm3, 5.0);
  EXPECT_EQ(report.crossings, 0);
  EXPECT_LE(report.drill->removed_mm3, report.drill->eroded_mm3 + 1e-9);
  ASSERT_EQ(report.drill->materials.size(), 1u);
  EXPECT_EQ(report.drill->materials[0].name, "tissue");
  EXPECT_NE(report.toJson().find("\"removed_mm3\""), std::string::npos);

  const Recording recording = readRecording(options.record);
  const LoadedScene replayed_scene = loadScene(sceneFromSessionMetadata(recording.metadata_json));
  ASSERT_TRUE(replayed_scene.spec.drill.has_value()) << "the recording keeps the drill";
  const ReplayComparison replay = replayRecording(replayed_scene, recording);
  EXPECT_TRUE(replay.identical) << replay.mismatch << " at tick " << replay.first_mismatch_tick.value_or(0);
  ASSERT_NE(replay.drilled_field, nullptr);
  Sha256 sha;
  sha.update(replay.drilled_field->bytes().data(), replay.drilled_field->bytes().size());
  EXPECT_EQ(sha.hexDigest(), report.drill->drilled_field_sha256);
  // And it differs from the untouched field (the check can fail).
  Sha256 untouched;
  untouched.update(scene.hapticField()->bytes().data(), scene.hapticField()->bytes().size());
  EXPECT_NE(untouched.hexDigest(), report.drill->drilled_field_sha256);

  // The burr's reach takes voxels outside the felt surface too (air about the ball): the report
  // counts them apart. Oracle: the analytic ball (radius 20 mm about the origin, F = 1000 (R -
  // |p|) mm), each removed voxel's centre outside R - isovalue / 1000.
  const haptics::ScalarVolume& felt = *scene.hapticField();
  const haptics::ScalarVolume& carved = *replay.drilled_field;
  const Eigen::Matrix4d X_W_index = felt.geometry().indexToWorld();
  const auto& dims = felt.geometry().dims;
  std::uint64_t removed = 0, outside = 0;
  for (int k = 0; k < dims[2]; ++k)
    for (int j = 0; j < dims[1]; ++j)
      for (int i = 0; i < dims[0]; ++i) {
        const std::size_t index = static_cast<std::size_t>(i) + static_cast<std::size_t>(dims[0]) * (j + static_cast<std::size_t>(dims[1]) * k);
        if (carved.rawAt(index) != carved.lowestRaw() || felt.rawAt(index) == carved.lowestRaw()) continue;
        ++removed;
        const Eigen::Vector3d p_W = (X_W_index * Eigen::Vector4d(i, j, k, 1.0)).head<3>();
        if (p_W.norm() > 0.020 - scene.hapticIsovalue() / 1000.0) ++outside;
      }
  EXPECT_EQ(removed, report.drill->materials[0].voxels);
  EXPECT_GT(outside, 0u) << "the reach passed through the air above the ball";
  EXPECT_EQ(report.drill->materials[0].voxels_below_surface, outside);
  EXPECT_NEAR(report.drill->materials[0].below_surface_mm3, static_cast<double>(outside) * 1.0, 1e-9) << "1 mm voxels";
  EXPECT_NE(report.summary().find("below the felt surface"), std::string::npos) << report.summary();
}

// On a CT, the air the burr's reach takes (below -500 HU, charged at soft tissue's hardness) is
// reported as air, not as soft tissue. The scan: test::writeCtBallScene()'s; oracle: each removed
// voxel's value in the scan.
TEST(Drilling, AirTheBurrTakesOnACtIsReportedAsAir) {
  const auto dir = test::scratchDir();
  const auto scene_file = test::writeCtBallScene(dir);
  const LoadedScene scene = loadScene(loadSceneFile(scene_file));
  ASSERT_TRUE(inHounsfieldUnits(scene.volume));
  RunOptions options;
  options.record = dir / "air.vhrec";
  options.lag_reference = false;
  const RunReport report = runHeadless(scene, pressDown(0.0, 0.0, 0.030, 1.0, 0.0125), options);
  ASSERT_TRUE(report.drill.has_value());
  // The carved field: the recording replayed on its scene (its SHA-256 the run's).
  const Recording recording = readRecording(options.record);
  const ReplayComparison replay = replayRecording(loadScene(sceneFromSessionMetadata(recording.metadata_json)), recording);
  ASSERT_TRUE(replay.identical) << replay.mismatch << " at tick " << replay.first_mismatch_tick.value_or(0);
  ASSERT_NE(replay.drilled_field, nullptr);
  const haptics::ScalarVolume& field = *scene.volume.field;
  const haptics::ScalarVolume& carved = *replay.drilled_field;
  Sha256 sha;
  sha.update(carved.bytes().data(), carved.bytes().size());
  ASSERT_EQ(sha.hexDigest(), report.drill->drilled_field_sha256);
  std::uint64_t removed = 0, air = 0, soft = 0;
  for (std::size_t i = 0; i < field.geometry().voxelCount(); ++i) {
    if (carved.rawAt(i) != carved.lowestRaw() || field.rawAt(i) == carved.lowestRaw()) continue;
    ++removed;
    const double hu = field.valueScale() * field.rawAt(i) + field.valueOffset();
    air += hu < -500.0;
    soft += hu >= -500.0 && hu < kCancellousFrom_HU;
  }
  std::uint64_t reported = 0, reported_air = 0, reported_soft = 0;
  for (const DrillReport::Material& m : report.drill->materials) {
    reported += m.voxels;
    if (m.name == "air") reported_air += m.voxels;
    if (m.name == "soft tissue") reported_soft += m.voxels;
  }
  std::cout << report.summary() << "\n";
  EXPECT_GT(air, 0u) << "the reach passed through the air about the ball";
  EXPECT_EQ(reported, removed) << "every removed voxel is reported once";
  EXPECT_EQ(reported_air, air);
  EXPECT_EQ(reported_soft, soft) << "what is left as soft tissue lies between -500 HU and the bone classes";
  EXPECT_NE(report.summary().find(", air "), std::string::npos) << report.summary();
}

// Two sessions on `scene`, each recorded in `dir`: the first presses the drill onto the pole
// (first.vhrec, replayed: it must match) and leaves `cavity` (on the felt field's grid; null when
// nothing was carved, and then no second session); the second starts on that cavity and presses
// x_m [m] aside (second.vhrec, `record`), `run` its report.
struct SecondSession {
  std::shared_ptr<const DrilledCavity> cavity;
  RunReport run;
  std::filesystem::path record;
};
// `run --record path` of a press at (x_m, 0) from z_from_m down to z_to_m [m] over 1 s, held
// (no lag reference, no step check).
RunReport recordPress(const LoadedScene& scene, const std::filesystem::path& path, double x_m, double z_from_m,
                      double z_to_m) {
  RunOptions options;
  options.record = path;
  options.lag_reference = false;
  options.verify_step_voxels = 0.0;
  return runHeadless(scene, pressDown(x_m, 0.0, z_from_m, 1.0, z_to_m), options);
}

SecondSession drillBesideAFirstCavity(const LoadedScene& scene, const std::filesystem::path& dir, double x_m) {
  SecondSession out;
  (void)recordPress(scene, dir / "first.vhrec", 0.0, 0.030, 0.0125);
  const Recording first_rec = readRecording(dir / "first.vhrec");
  const ReplayComparison first = replayRecording(loadScene(sceneFromSessionMetadata(first_rec.metadata_json)), first_rec);
  EXPECT_TRUE(first.identical) << first.mismatch;
  if (first.drilled_field == nullptr) return out;
  out.cavity = std::make_shared<const DrilledCavity>(cavityOf(*first.drilled_field, *scene.hapticField()));
  LoadedScene drilled = scene;
  drilled.spec.drill->cavity = out.cavity;
  out.record = dir / "second.vhrec";
  out.run = recordPress(drilled, out.record, x_m, 0.030, 0.0125);
  return out;
}

// A recording that starts on a drilled field (a session that drilled, rebuilt its haptic threads
// and recorded on): its metadata carries the cavity, and the replay carves on from it to the very
// same field (SHA-256), which holds both cavities; replayed without the cavity, it is another.
TEST(Drilling, ARecordingThatStartsDrilledReplaysBitForBit) {
  const auto dir = test::scratchDir();
  const LoadedScene scene = loadScene(parseScene(kDrillScene, "drill.json", "."));
  // The second session starts from the first one's cavity and drills 4 mm aside.
  const SecondSession second = drillBesideAFirstCavity(scene, dir, 0.004);
  ASSERT_NE(second.cavity, nullptr);
  ASSERT_GT(second.cavity->voxels.size(), 20u);
  const std::shared_ptr<const DrilledCavity>& cavity = second.cavity;
  const RunReport& report = second.run;
  ASSERT_TRUE(report.drill.has_value());
  EXPECT_GT(report.drill->removed_mm3, 5.0) << "the second press cut too";
  const Recording rec = readRecording(second.record);
  const LoadedScene reloaded = loadScene(sceneFromSessionMetadata(rec.metadata_json));
  ASSERT_TRUE(reloaded.spec.drill.has_value());
  ASSERT_NE(reloaded.spec.drill->cavity, nullptr) << "the metadata carries the cavity";
  EXPECT_EQ(reloaded.spec.drill->cavity->voxels, cavity->voxels);
  const ReplayComparison replay = replayRecording(reloaded, rec);
  EXPECT_TRUE(replay.identical) << replay.mismatch << " at tick " << replay.first_mismatch_tick.value_or(0);
  ASSERT_NE(replay.drilled_field, nullptr);
  Sha256 sha;
  sha.update(replay.drilled_field->bytes().data(), replay.drilled_field->bytes().size());
  EXPECT_EQ(sha.hexDigest(), report.drill->drilled_field_sha256);
  const DrilledCavity both = cavityOf(*replay.drilled_field, *scene.hapticField());
  std::cout << "cavity at the start " << cavity->voxels.size() << " voxels, at the end " << both.voxels.size() << "\n";
  EXPECT_TRUE(std::includes(both.voxels.begin(), both.voxels.end(), cavity->voxels.begin(), cavity->voxels.end()));
  EXPECT_GT(both.voxels.size(), cavity->voxels.size());
  // The session's metrics by the rule every recording follows: the cavity it began with (the
  // metadata), what its records say the burr removed, and the two together, which is the cavity
  // the replay carved (the oracle: the replayed field against the scan, not the records).
  const SessionMetrics m = computeSessionMetrics(rec);
  EXPECT_EQ(m.cavity_at_start_voxels, cavity->voxels.size());
  EXPECT_EQ(m.removed_voxels, replay.removed_voxels.size());
  EXPECT_EQ(m.cavity_voxels, both.voxels.size());
  EXPECT_NEAR(m.removed_mm3, report.drill->removed_mm3, 1e-9 * report.drill->removed_mm3);
  const double voxel_mm3 = report.drill->removed_mm3 / static_cast<double>(m.removed_voxels);
  EXPECT_NEAR(m.cavity_mm3, static_cast<double>(both.voxels.size()) * voxel_mm3, 1e-9 * m.cavity_mm3);

  LoadedScene without = reloaded;  // the check can fail: the same records on the undrilled sphere
  without.spec.drill->cavity = nullptr;
  const ReplayComparison undrilled = replayRecording(without, rec);
  EXPECT_FALSE(undrilled.identical) << "the second press overlaps the first cavity: it feels different without it";
  std::cout << "replayed without the cavity: " << undrilled.mismatch << " differs at tick "
            << undrilled.first_mismatch_tick.value_or(0) << "\n";
}

// The oracle's classes: each voxel of `voxels` classed by its own HU in the scan `ct` (air below
// -500, soft tissue below 250, cancellous bone below 800, cortical bone above).
std::map<std::string, std::uint64_t> byHuClass(const haptics::ScalarVolume& ct, const std::vector<std::uint64_t>& voxels) {
  std::map<std::string, std::uint64_t> classes;
  for (const std::uint64_t i : voxels) {
    const double hu = ct.valueScale() * ct.rawAt(i) + ct.valueOffset();
    ++classes[hu < kAirBelow_HU       ? "air"
              : hu < kCancellousFrom_HU ? "soft tissue"
              : hu < kCorticalFrom_HU   ? "cancellous bone"
                                        : "cortical bone"];
  }
  return classes;
}

// The voxels `carved` lacks against the scan `ct` (at its lowest value there, not in the scan),
// less those of `at_start` (a sorted cavity): what a session that began on `at_start` removed.
std::vector<std::uint64_t> removedAgainstScan(const haptics::ScalarVolume& carved, const haptics::ScalarVolume& ct,
                                              const std::vector<std::uint64_t>& at_start) {
  std::vector<std::uint64_t> removed;
  for (std::uint64_t i = 0; i < ct.geometry().voxelCount(); ++i)
    if (carved.rawAt(i) == carved.lowestRaw() && ct.rawAt(i) != carved.lowestRaw() &&
        !std::binary_search(at_start.begin(), at_start.end(), i))
      removed.push_back(i);
  return removed;
}

// What a recording removed, per material and as air, from its replay (the session report's
// table): on the CT ball, a first session drills the pole, a second, recorded, starts on that
// cavity and drills 6 mm aside. Oracle: the voxels the replayed field lacks against the scan,
// less the cavity the recording started with, each classed by its own HU in the scan (air
// below -500, soft tissue below 250, cancellous bone below 800, cortical bone above), and the
// records' count of removed voxels.
TEST(Drilling, AReplayGivesWhatItsRecordingRemovedPerMaterialAndAsAir) {
  const auto dir = test::scratchDir();
  const LoadedScene scene = loadScene(loadSceneFile(test::writeCtBallScene(dir)));
  ASSERT_TRUE(inHounsfieldUnits(scene.volume));
  const SecondSession second = drillBesideAFirstCavity(scene, dir, 0.006);
  ASSERT_NE(second.cavity, nullptr);
  ASSERT_GT(second.cavity->voxels.size(), 20u);
  const std::shared_ptr<const DrilledCavity>& cavity = second.cavity;
  const RunReport& run = second.run;
  ASSERT_TRUE(run.drill.has_value());
  const Recording rec = readRecording(second.record);
  const ReplayComparison replay = replayRecording(loadScene(sceneFromSessionMetadata(rec.metadata_json)), rec);
  ASSERT_TRUE(replay.identical) << replay.mismatch << " at tick " << replay.first_mismatch_tick.value_or(0);
  ASSERT_TRUE(replay.drill.has_value()) << "a replay with a drill gives what it removed";
  ASSERT_NE(replay.drilled_field, nullptr);

  const haptics::ScalarVolume& ct = *scene.volume.field;
  const std::vector<std::uint64_t> removed_voxels = removedAgainstScan(*replay.drilled_field, ct, cavity->voxels);
  const std::uint64_t removed = removed_voxels.size();
  std::map<std::string, std::uint64_t> expected = byHuClass(ct, removed_voxels);
  std::map<std::string, std::uint64_t> got;
  std::uint64_t reported = 0;
  for (const DrillReport::Material& m : replay.drill->materials) {
    if (m.voxels > 0) got[m.name] += m.voxels;
    reported += m.voxels;
    EXPECT_NEAR(m.removed_mm3, static_cast<double>(m.voxels) * 1.0, 1e-9) << m.name << ": 1 mm voxels";
  }
  std::cout << "the second session removed " << removed << " voxels:";
  for (const auto& [name, n] : expected) std::cout << " " << name << " " << n;
  std::cout << "\n";
  EXPECT_GT(expected["air"], 0u) << "the reach passed through the air above the ball";
  EXPECT_GT(expected["cortical bone"], 0u);
  EXPECT_EQ(got, expected);
  EXPECT_EQ(reported, removed) << "the cavity the recording began on is not counted";
  EXPECT_EQ(reported, computeSessionMetrics(rec).removed_voxels) << "the records' count";
  EXPECT_EQ(replay.drill->drilled_field_sha256, run.drill->drilled_field_sha256);
  // And `run`'s report of that session gives the same rows.
  ASSERT_EQ(run.drill->materials.size(), replay.drill->materials.size());
  for (std::size_t m = 0; m < run.drill->materials.size(); ++m) {
    EXPECT_EQ(run.drill->materials[m].name, replay.drill->materials[m].name);
    EXPECT_EQ(run.drill->materials[m].voxels, replay.drill->materials[m].voxels) << run.drill->materials[m].name;
    EXPECT_EQ(run.drill->materials[m].voxels_below_surface, replay.drill->materials[m].voxels_below_surface);
  }
}

// RFC 4180 rows (quoted fields with commas, doubled quotes and line breaks), for the cohort table.
std::vector<std::vector<std::string>> readCsvRows(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  std::vector<std::vector<std::string>> rows(1, std::vector<std::string>(1));
  bool quoted = false;
  for (std::size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    if (quoted) {
      if (c == '"' && i + 1 < text.size() && text[i + 1] == '"') rows.back().back() += text[++i];
      else if (c == '"') quoted = false;
      else rows.back().back() += c;
    } else if (c == '"') {
      quoted = true;
    } else if (c == ',') {
      rows.back().emplace_back();
    } else if (c == '\n') {
      rows.emplace_back(1);
    } else {
      rows.back().back() += c;
    }
  }
  if (rows.back().size() == 1 && rows.back()[0].empty()) rows.pop_back();
  return rows;
}

// The cohort table per material (`report DIR --table --per-material`), by the session report's
// rule, for every recording in the folder: on the CT ball a first session drills the pole, a
// second starts on its cavity and drills 6 mm aside, a third stays 20 mm above the ball.
// Oracle: each session's removed voxels classed by their own HU in the scan (the first: its
// cavity against the scan; the second: what its replayed field lacks against the scan, less
// that cavity); 1 mm voxels, so a count is its volume in mm^3. Without the option there are
// no such columns.
TEST(Drilling, TheCohortTableGivesEachRecordingsRemovalPerMaterial) {
  const auto dir = test::scratchDir();
  const LoadedScene scene = loadScene(loadSceneFile(test::writeCtBallScene(dir)));
  const SecondSession second = drillBesideAFirstCavity(scene, dir, 0.006);
  ASSERT_NE(second.cavity, nullptr);
  (void)recordPress(scene, dir / "above.vhrec", 0.0, 0.060, 0.050);
  const Recording second_rec = readRecording(second.record);
  const ReplayComparison replay =
      replayRecording(loadScene(sceneFromSessionMetadata(second_rec.metadata_json)), second_rec);
  ASSERT_NE(replay.drilled_field, nullptr);
  const haptics::ScalarVolume& ct = *scene.volume.field;
  std::map<std::string, std::map<std::string, std::uint64_t>> expected;
  expected["above.vhrec"] = {};
  expected["first.vhrec"] = byHuClass(ct, second.cavity->voxels);
  expected["second.vhrec"] = byHuClass(ct, removedAgainstScan(*replay.drilled_field, ct, second.cavity->voxels));
  EXPECT_GT(expected["first.vhrec"]["cortical bone"], 0u);
  EXPECT_GT(expected["second.vhrec"]["air"], 0u);

  CohortTableOptions options;
  options.drilled_per_material = true;
  ASSERT_EQ(writeCohortTable(dir, dir / "table.csv", options), 3u);
  const std::vector<std::vector<std::string>> rows = readCsvRows(dir / "table.csv");
  ASSERT_EQ(rows.size(), 4u);
  const std::vector<std::string>& header = rows[0];
  const auto column = [&](const std::string& key) {
    return static_cast<std::size_t>(std::find(header.begin(), header.end(), key) - header.begin());
  };
  std::vector<std::string> materials;
  for (const std::string& h : header)
    if (h.rfind("removed_mm3[", 0) == 0) materials.push_back(h.substr(12, h.size() - 13));
  std::cout << "material columns:";
  for (const std::string& m : materials) std::cout << " [" << m << "]";
  std::cout << "\n";
  for (const char* name : {"air", "soft tissue", "cancellous bone", "cortical bone"})
    EXPECT_NE(std::find(materials.begin(), materials.end(), name), materials.end()) << name;
  for (std::size_t r = 1; r < rows.size(); ++r) {
    const std::vector<std::string>& row = rows[r];
    ASSERT_EQ(row.size(), header.size()) << row[0];
    ASSERT_EQ(expected.count(row[0]), 1u) << row[0];
    std::map<std::string, std::uint64_t>& want = expected[row[0]];
    double sum_mm3 = 0.0;
    for (const std::string& m : materials) {
      const std::string& cell = row[column("removed_mm3[" + m + "]")];
      ASSERT_FALSE(cell.empty()) << row[0] << " " << m << ": " << row[column("notices")];
      EXPECT_DOUBLE_EQ(std::stod(cell), static_cast<double>(want[m])) << row[0] << " " << m;
      sum_mm3 += std::stod(cell);
    }
    EXPECT_NEAR(sum_mm3, std::stod(row[column("removed_mm3")]), 1e-6) << row[0] << ": the records' total";
    EXPECT_EQ(row[column("notices")].find("not known"), std::string::npos) << row[column("notices")];
    std::cout << row[0] << ": removed " << row[column("removed_mm3")] << " mm^3\n";
  }
  ASSERT_EQ(writeCohortTable(dir, dir / "plain.csv"), 3u);
  const std::vector<std::vector<std::string>> plain = readCsvRows(dir / "plain.csv");
  ASSERT_FALSE(plain.empty());
  for (const std::string& h : plain[0]) EXPECT_EQ(h.rfind("removed_mm3[", 0), std::string::npos) << h;
}

// Touch the Surface with a drill held upright (burr down, shaft and handle up +z), approached
// from the side (+y) at the sphere's centre. Tip first (touchSurfaceTipFirst()) the drill is
// turned so that its axis points into the sphere along the normal where the line of sight meets
// it, only the burr touches, and pressed on along that axis with the burr on it cuts. Placed as
// held (touchSurfacePose()), the shaft meets the sphere first and the same press cuts nothing
// (so the checks can fail; the oracle for "what touches" is the sphere itself: the shell points
// inside it 0.3 mm further on, and where they lie on the tool).
TEST(Drilling, TouchTheSurfaceWithADrillPutsItsBurrOnTheSurface) {
  const LoadedScene scene = loadScene(parseScene(kDrillScene, "drill.json", "."));
  const haptics::ToolModel& tool = *scene.tool;
  const haptics::ScalarVolume& field = *scene.hapticField();
  const double s = scene.hapticIsovalue();
  const Burr burr = burrOf(tool, *scene.spec.drill);
  const Eigen::Quaterniond upright = Eigen::Quaterniond::Identity();
  const Eigen::Vector3d dir(0.0, 1.0, 0.0), aim(0.0, 0.0, 0.0);
  const std::optional<SurfaceTouch> tip =
      touchSurfaceTipFirst(field, tool.point_shell, tool.mass.p_TCm_m, burr.center_T_m, upright, dir, aim, s, 0.0);
  const std::optional<SurfaceTouch> held =
      touchSurfacePose(field, tool.point_shell, tool.mass.p_TCm_m, upright, dir, aim, s, 0.0);
  ASSERT_TRUE(tip.has_value());
  ASSERT_TRUE(held.has_value());
  struct Touching {
    int on_burr = 0, elsewhere = 0;
  };
  const auto touching = [&](const SurfaceTouch& t) {
    haptics::Pose X = t.X_WP;
    X.p_AB_m += 0.3e-3 * t.dir_W;
    Touching n;
    for (const Eigen::Vector3d& p_T : tool.point_shell.points_T_m())
      if (field.isInside(X * p_T, s)) ++((p_T - burr.center_T_m).norm() <= burr.radius_m + 0.5e-3 ? n.on_burr : n.elsewhere);
    return n;
  };
  EXPECT_EQ(countPointsInside(field, tool.point_shell, tip->X_WP, s), 0) << "placed free";
  const Touching by_tip = touching(*tip), as_held = touching(*held);
  EXPECT_GT(by_tip.on_burr, 0);
  EXPECT_EQ(by_tip.elsewhere, 0) << "tip first, only the burr touches";
  EXPECT_GT(as_held.elsewhere, 0) << "held upright from the side, the shaft meets the sphere first";
  // The drill's axis along the sphere's inward normal at the burr (the sphere is centred at 0).
  const Eigen::Vector3d burr_W = tip->X_WP * burr.center_T_m;
  const Eigen::Vector3d axis_W = tip->X_WP.R_AB * (burr.center_T_m - tool.mass.p_TCm_m).normalized();
  EXPECT_GT(axis_W.dot(-burr_W.normalized()), 0.99);
  EXPECT_NEAR(burr_W.norm(), 0.020 + burr.radius_m, 0.5e-3) << "the burr rests on the sphere";
  // Pressed 10 mm on along the approach over 0.5 s and held for 2.5 s, the burr spinning (as
  // HeadlessRunDrillsAndReplaysBitForBit presses from above).
  const auto removedByPress = [&](const SurfaceTouch& t) {
    const auto at = [&](double time_s, double along_m) {
      TrajectorySample sample;
      sample.t_s = time_s;
      sample.X_WD = t.X_WP;
      sample.X_WD.p_AB_m += along_m * t.dir_W;
      return sample;
    };
    RunOptions options;
    options.lag_reference = false;
    options.verify_step_voxels = 0.0;
    const RunReport report = runHeadless(scene, Trajectory({at(0.0, 0.0), at(0.5, 0.010), at(3.0, 0.010)}), options);
    return report.drill.has_value() ? report.drill->removed_mm3 : -1.0;
  };
  const double tip_mm3 = removedByPress(*tip), held_mm3 = removedByPress(*held);
  EXPECT_GT(tip_mm3, 1.0) << "the burr on the surface cuts";
  EXPECT_EQ(held_mm3, 0.0) << "the shaft on the surface cuts nothing";
  std::cout << "touched tip first: " << by_tip.on_burr << " points of the burr touch, " << by_tip.elsewhere
            << " elsewhere, pressed on it cut " << tip_mm3 << " mm^3; as held: " << as_held.on_burr << " on the burr, "
            << as_held.elsewhere << " elsewhere, cut " << held_mm3 << " mm^3\n";
}

// A cavity moved onto another grid (the felt field changed): the voxels of the finer grid whose
// nearest voxel of the cavity's grid was removed; the same grid gives the indices back.
TEST(Drilling, CavityMovesOntoAnotherGridByNearestVoxel) {
  DrilledCavity ball;
  ball.grid.dims = {20, 20, 20};
  ball.grid.spacing_m = Eigen::Vector3d::Constant(0.001);
  for (int k = 0; k < 20; ++k)
    for (int j = 0; j < 20; ++j)
      for (int i = 0; i < 20; ++i)
        if (Eigen::Vector3d(i - 10, j - 10, k - 10).norm() <= 5.0)
          ball.voxels.push_back(static_cast<std::uint64_t>(i + 20 * (j + 20 * k)));
  EXPECT_EQ(cavityVoxelsOn(ball, ball.grid), ball.voxels);
  haptics::VolumeGeometry fine;
  fine.dims = {50, 50, 50};
  fine.spacing_m = Eigen::Vector3d::Constant(0.0005);
  fine.origin_W_m = Eigen::Vector3d::Constant(-0.002);  // covers the ball's grid and more
  const std::vector<std::uint64_t> on_fine = cavityVoxelsOn(ball, fine);
  // Oracle: the same rule evaluated voxel by voxel over the whole fine grid.
  std::vector<std::uint64_t> expected;
  for (int k = 0; k < 50; ++k)
    for (int j = 0; j < 50; ++j)
      for (int i = 0; i < 50; ++i) {
        const Eigen::Vector3d p_mm = Eigen::Vector3d(-2.0 + 0.5 * i, -2.0 + 0.5 * j, -2.0 + 0.5 * k);
        const Eigen::Vector3d nearest(std::lround(p_mm.x()), std::lround(p_mm.y()), std::lround(p_mm.z()));
        if ((nearest.array() < 0).any() || (nearest.array() > 19).any()) continue;
        if ((nearest - Eigen::Vector3d::Constant(10)).norm() <= 5.0)
          expected.push_back(static_cast<std::uint64_t>(i + 50 * (j + 50 * k)));
      }
  EXPECT_EQ(on_fine, expected);
  // About eight fine voxels per coarse one (rounding ties at half-voxel centres aside).
  EXPECT_NEAR(static_cast<double>(on_fine.size()) / ball.voxels.size(), 8.0, 1.5);
}

// Hardness set in the session: kept until the burr's first start, then live on the drill (no
// rebuild: the haptic thread stays the same object).
TEST(Drilling, SessionHardnessReachesTheDrillWithoutARebuild) {
  Session session;
  LoadedScene scene = loadScene(parseScene(R"({"volume": {"path": "builtin:sphere"}, "tool": {"mesh": "builtin:drill",
      "point_spacing_m": 0.001}, "device": {"kind": "simulated"}})", "s.json", "."));
  auto device = scene.makeDevice();
  session.setScene(std::move(scene), device);
  EXPECT_THROW(session.setHardness("tissue", 0.0), std::invalid_argument);
  session.setHardness("tissue", 3.0);
  ASSERT_EQ(session.hapticThread()->drill(), nullptr) << "no drill before the burr starts";
  session.setDrilling(true);
  ASSERT_NE(session.hapticThread()->drill(), nullptr);
  EXPECT_DOUBLE_EQ(session.hapticThread()->drill()->removal().specificEnergy(0), 3.0);
  const HapticThread* thread = session.hapticThread();
  session.setHardness("tissue", 0.25);
  EXPECT_EQ(session.hapticThread(), thread) << "no rebuild";
  EXPECT_NEAR(session.hapticThread()->drill()->removal().specificEnergy(0), 0.25, 1e-12);
  EXPECT_DOUBLE_EQ(session.hardness().at("tissue"), 0.25);
  session.setDrilling(false);
  EXPECT_FALSE(session.drilling());
  EXPECT_EQ(session.hapticThread(), thread);
}

// A bone slab (1200 HU, z 4 to 9 mm) with a "nerve" segment inside it (z 6 to 7 mm), critical,
// each segment with the scene's hardness: drilling down through the bone reaches the nerve; its voxels
// are counted apart in the report and every removal of them is a critical_removed event.
// The run's per-tick burr states (RunOptions::on_drill_tick) against its report: one a tick, in
// order, the burr on throughout; the removal rates sum to the eroded volume; a force and a
// hardness (between the softest and the hardest material) exactly on the ticks that cut, the
// hardest alone on some; critical ticks on some.
void expectDrillTicksAgree(const std::vector<DrillTick>& ticks, const RunReport& report, double softest,
                           double hardest) {
  ASSERT_EQ(ticks.size(), report.ticks);
  double eroded_mm3 = 0.0;
  int cutting = 0, hardest_only = 0, softer = 0, critical = 0;
  for (std::size_t i = 0; i < ticks.size(); ++i) {
    const DrillTick& d = ticks[i];
    EXPECT_EQ(d.tick, i + 1);
    EXPECT_TRUE(d.burr_on);
    eroded_mm3 += d.removal_rate_mm3_per_s / report.servo_rate_Hz;
    EXPECT_EQ(d.force_N > 0.0, d.specific_energy_J_per_mm3 > 0.0) << "tick " << d.tick;
    if (d.specific_energy_J_per_mm3 > 0.0) {
      ++cutting;
      EXPECT_GE(d.specific_energy_J_per_mm3, softest - 1e-12);
      EXPECT_LE(d.specific_energy_J_per_mm3, hardest + 1e-12);
      hardest_only += std::abs(d.specific_energy_J_per_mm3 - hardest) < 1e-12;
      softer += d.specific_energy_J_per_mm3 < hardest - 1e-3;
    }
    critical += d.critical;
  }
  std::cout << "drill ticks: " << cutting << " cutting (" << hardest_only << " all of the hardest, " << softer
            << " softer), " << critical << " critical; eroded " << eroded_mm3 << " mm^3 (report "
            << report.drill->eroded_mm3 << ")\n";
  EXPECT_NEAR(eroded_mm3, report.drill->eroded_mm3, 1e-6 * report.drill->eroded_mm3);
  EXPECT_GT(hardest_only, 0);
  EXPECT_GT(softer, 0);
  EXPECT_GT(critical, 0);
}

// Without a "drill" section the run reports no burr at all.
TEST(Drilling, NoDrillTicksWithoutADrill) {
  const LoadedScene scene = loadScene(parseScene(
      R"({"volume": {"path": "builtin:sphere"}, "tool": {"mesh": "builtin:drill", "point_spacing_m": 0.001}})",
      "touch.json", "."));
  RunOptions options;
  options.lag_reference = false;
  options.verify_step_voxels = 0.0;
  int calls = 0;
  options.on_drill_tick = [&](const DrillTick&) { ++calls; };
  const RunReport report = runHeadless(scene, pressDown(0.0, 0.0, 0.030, 0.5, 0.019), options);
  EXPECT_GT(report.ticks_in_contact, 0u);
  EXPECT_EQ(calls, 0);
}

TEST(Drilling, CriticalSegmentRemovalIsReportedAndRecorded) {
  const auto dir = test::scratchDir();
  constexpr int kN = 60;  // 0.5 mm voxels
  std::string ct, labels;
  for (int k = 0; k < kN; ++k)
    for (int j = 0; j < kN; ++j)
      for (int i = 0; i < kN; ++i) {
        const double x = i * 0.5, y = j * 0.5, z = k * 0.5;
        const bool bone = x >= 3 && x <= 27 && y >= 3 && y <= 27 && z >= 4 && z <= 9;
        const bool nerve = bone && z >= 6 && z <= 7;
        const std::int16_t hu = bone ? 1200 : -1000;
        ct.append(reinterpret_cast<const char*>(&hu), 2);
        labels.push_back(static_cast<char>(nerve ? 1 : bone ? 2 : 0));
      }
  const auto header = [](const std::string& type, const std::string& extra) {
    return "NRRD0004\ntype: " + type + "\ndimension: 3\nspace: left-posterior-superior\nsizes: 60 60 60\n"
           "space directions: (0.5,0,0) (0,0.5,0) (0,0,0.5)\nkinds: domain domain domain\nendian: little\n"
           "encoding: raw\nspace origin: (0,0,0)\n" + extra + "\n";
  };
  std::ofstream(dir / "ct.nrrd", std::ios::binary) << header("short", "") << ct;
  std::ofstream(dir / "case.seg.nrrd", std::ios::binary)
      << header("unsigned char",
                "Segment0_ID:=Segment_1\nSegment0_LabelValue:=1\nSegment0_Layer:=0\nSegment0_Name:=nerve\n"
                "Segment1_ID:=Segment_2\nSegment1_LabelValue:=2\nSegment1_Layer:=0\nSegment1_Name:=bone\n")
      << labels;
  const auto scene_path = test::writeText(dir / "drill.json", R"({
    "volume": {"path": "ct.nrrd", "isovalue": 400},
    "tool": {"mesh": "builtin:drill", "point_spacing_m": 0.0008},
    "coupling": {"linear_N_per_m": 1000},
    "segmentation": {"path": "case.seg.nrrd", "critical": ["nerve"]},
    "drill": {"on": true, "hardness": {"nerve": 0.5, "bone": 2.5}}
  })");
  const LoadedScene scene = loadScene(loadSceneFile(scene_path));
  const Trajectory press = pressDown(0.015, 0.015, 0.016, 0.5, 0.002);
  RunOptions options;
  options.record = dir / "drill.vhrec";
  options.lag_reference = false;
  options.verify_step_voxels = 0.05;
  std::vector<DrillTick> drill_ticks;  // what the burr's sound follows (run --audio)
  options.on_drill_tick = [&](const DrillTick& d) { drill_ticks.push_back(d); };
  const RunReport report = runHeadless(scene, press, options);
  ASSERT_TRUE(report.drill.has_value());
  EXPECT_EQ(report.crossings, 0);
  expectDrillTicksAgree(drill_ticks, report, 0.5, 2.5);
  const DrillReport::Material* nerve = nullptr;
  const DrillReport::Material* bone = nullptr;
  for (const auto& m : report.drill->materials) {
    if (m.name == "nerve") nerve = &m;
    if (m.name == "bone") bone = &m;
  }
  ASSERT_NE(nerve, nullptr);
  ASSERT_NE(bone, nullptr);
  EXPECT_TRUE(nerve->critical);
  EXPECT_EQ(nerve->segment, "nerve");
  EXPECT_DOUBLE_EQ(nerve->specific_energy_J_per_mm3, 0.5);
  EXPECT_DOUBLE_EQ(bone->specific_energy_J_per_mm3, 2.5);
  EXPECT_GT(bone->voxels, 0u);
  EXPECT_GT(nerve->voxels, 0u) << "the burr went through the bone into the nerve";
  const Recording recording = readRecording(options.record);
  std::uint64_t recorded = 0;
  for (const auto& e : recording.events)
    if (e.type == "critical_removed") {
      EXPECT_NE(e.detail_json.find("\"segment\":\"nerve\""), std::string::npos) << e.detail_json;
      recorded += static_cast<std::uint64_t>(nlohmann::json::parse(e.detail_json).at("voxels").get<int>());
    }
  EXPECT_EQ(recorded, nerve->voxels) << "every removed nerve voxel is in an event";
}


// Voxels within 9 mm of the sphere's top pole (0, 0, 20 mm) whose value lies below `level`: open
// space, felt as nothing. Drilling a field adds to it; the oracle of what the solver feels.
int openVoxelsAtThePole(const haptics::ScalarVolume& field, double level) {
  const auto& g = field.geometry();
  int open = 0;
  for (int k = 0; k < g.dims[2]; ++k)
    for (int j = 0; j < g.dims[1]; ++j)
      for (int i = 0; i < g.dims[0]; ++i) {
        const Eigen::Vector3d p = g.origin_W_m + g.direction_W * g.spacing_m.cwiseProduct(Eigen::Vector3d(i, j, k));
        if ((p - Eigen::Vector3d(0, 0, 0.020)).norm() < 0.009 && field.voxel(i, j, k) < level) ++open;
      }
  return open;
}

// A ball segment "cap" about (0, 0, 17 mm), radius 8 mm, on the scan's grid.
std::shared_ptr<const SegmentSet> capSegment(const haptics::ScalarVolume& scan, bool felt) {
  const auto& g = scan.geometry();
  std::vector<std::uint8_t> labels(g.voxelCount(), 0);
  std::size_t n = 0, inside = 0;
  for (int k = 0; k < g.dims[2]; ++k)
    for (int j = 0; j < g.dims[1]; ++j)
      for (int i = 0; i < g.dims[0]; ++i, ++n) {
        const Eigen::Vector3d p = g.origin_W_m + g.direction_W * g.spacing_m.cwiseProduct(Eigen::Vector3d(i, j, k));
        if ((p - Eigen::Vector3d(0, 0, 0.017)).norm() <= 0.008) labels[n] = 1, ++inside;
      }
  io::LoadedSegmentation seg;
  seg.source = "in-memory";
  io::SegmentInfo info;
  info.id = "Segment_1";
  info.name = "cap";
  info.label_value = 1;
  info.voxel_count = inside;
  seg.segments.push_back(info);
  seg.layers.push_back(std::make_shared<const haptics::ScalarVolume>(haptics::ScalarVolume::FromVoxels(g, labels)));
  return std::make_shared<const SegmentSet>(std::move(seg), felt ? std::vector<int>{0} : std::vector<int>{},
                                            std::vector<int>{0}, std::vector<int>{}, 1.0);
}

// The cavity belongs to the session, not to one renderer: drilled into the sphere, it stays in
// the field the solver reads after every rebuild of the haptic threads (a tool, a device, shown
// segments, a monitor; felt segments carve the segments' field there and give it back), counted
// by the oracle (open voxels at the pole beyond the scan's); and the hand feels it: with the burr
// off, the proxy sinks into the cavity again as deep as it drilled.
TEST(Drilling, TheCavityOutlivesRebuildsOfTheHapticThreads) {
  Session session;
  LoadedScene scene = loadScene(parseScene(R"({"volume": {"path": "builtin:sphere"}, "tool": {"mesh": "builtin:drill",
      "point_spacing_m": 0.001}, "coupling": {"linear_N_per_m": 400}, "device": {"kind": "simulated"},
      "drill": {"on": true, "burr_radius_m": 0.0025, "hardness": {"tissue": 0.3}}})", "s.json", "."));
  const auto tool = scene.tool;
  const ToolSpec tool_spec = scene.spec.tool;
  const haptics::Pose X_free = scene.X_WT_initial;
  auto device = scene.makeDevice();
  session.setScene(std::move(scene), device);
  const haptics::ScalarVolume& scan = *session.live().scan_field;
  const double iso = session.live().hapticIsovalue();
  const int open_in_scan = openVoxelsAtThePole(scan, iso);
  const auto solverField = [&]() -> const haptics::ScalarVolume& {
    return session.hapticThread()->drill()->removal().volume();  // the renderer's own field
  };
  haptics::Pose press = X_free;
  press.p_AB_m = Eigen::Vector3d(0.0, 0.0, 0.0125);  // the burr's centre 7.5 mm into the sphere
  session.startHaptics();
  session.simulatedDevice()->setPose(press);
  // Until the burr's centre is 3.5 mm below where the undrilled pole stops it.
  ASSERT_TRUE(test::waitUntil([&] { return session.proxyPose().p_AB_m.z() < 0.019; }, std::chrono::milliseconds(90000)))
      << "the burr's centre at z = " << session.proxyPose().p_AB_m.z() * 1e3 << " mm, "
      << session.hapticThread()->drill()->removal().removedVoxels() << " voxels removed";
  session.stopHaptics();
  const double drilled_to_m = session.proxyPose().p_AB_m.z();
  const int drilled = openVoxelsAtThePole(solverField(), iso) - open_in_scan;
  std::cout << "drilled " << drilled << " voxels of the sphere; the burr's centre sank to z = " << drilled_to_m * 1e3
            << " mm (20 + 2.5 mm on the undrilled surface)\n";
  ASSERT_GT(drilled, 20);
  EXPECT_NE(session.live().drill->cavity, nullptr) << "stopping keeps the cavity in the live values";
  const haptics::ScalarVolume drilled_scan = solverField();  // a copy, for the felt segments below

  const auto expectCavity = [&](const char* after) {
    ASSERT_NE(session.hapticThread(), nullptr) << after;
    ASSERT_NE(session.hapticThread()->drill(), nullptr) << after;
    EXPECT_EQ(openVoxelsAtThePole(solverField(), iso) - open_in_scan, drilled) << "after " << after;
    EXPECT_EQ(session.hapticThread()->drill()->removal().removedVoxels(), 0u) << "nothing cut since, " << after;
  };
  session.setTool(tool, tool_spec, X_free);
  expectCavity("a tool change");
  session.setDevice(std::make_shared<SimulatedDevice>(X_free));
  expectCavity("a device change");
  SegmentationSpec seg_spec;
  seg_spec.path = "in-memory";
  session.setSegments(capSegment(scan, false), seg_spec);
  expectCavity("shown segments");
  session.setMonitor(std::make_shared<SnapshotChannel>());
  expectCavity("a monitor");

  // Felt segments: the hand feels the cap's smoothed indicator (on its own, padded grid); the
  // cavity moves onto that grid: every voxel drilled from the scan deep inside the cap (indicator
  // 1) is open in the field the solver reads now.
  auto felt = capSegment(scan, true);
  session.setSegments(felt, seg_spec);
  ASSERT_NE(session.hapticThread()->drill(), nullptr);
  const haptics::ScalarVolume& cap = *felt->feltField();
  const haptics::ScalarVolume& carved_cap = solverField();
  ASSERT_NE(carved_cap.geometry().dims, scan.geometry().dims) << "the test needs the other grid";
  int checked = 0, open_there = 0;
  const auto& g = scan.geometry();
  for (int k = 0; k < g.dims[2]; ++k)
    for (int j = 0; j < g.dims[1]; ++j)
      for (int i = 0; i < g.dims[0]; ++i) {
        if (!(scan.voxel(i, j, k) >= iso && drilled_scan.voxel(i, j, k) < iso)) continue;  // not drilled
        const Eigen::Vector3d q =
            cap.gridCoordinates(g.origin_W_m + g.direction_W * g.spacing_m.cwiseProduct(Eigen::Vector3d(i, j, k)));
        const int a = static_cast<int>(std::lround(q.x())), b = static_cast<int>(std::lround(q.y())),
                  c = static_cast<int>(std::lround(q.z()));
        if (cap.voxel(a, b, c) < 0.99) continue;  // outside the cap or near its edge
        ++checked;
        open_there += carved_cap.voxel(a, b, c) < io::kSegmentSurfaceLevel;
      }
  std::cout << "felt cap: " << open_there << " of the " << checked << " drilled voxels deep in it are open there\n";
  EXPECT_GT(checked, 10);
  EXPECT_EQ(open_there, checked) << "the cavity is carved into the felt segment";
  session.setSegments(nullptr, std::nullopt);
  expectCavity("the segments felt and dropped again");

  // The hand: burr off, the device pressed where it drilled: the proxy goes back down into the
  // cavity (on the undrilled sphere it would stop 2.5 mm above the pole, z = 22.5 mm).
  session.setDrilling(false);
  session.startHaptics();
  session.simulatedDevice()->setPose(press);
  EXPECT_TRUE(test::waitUntil([&] { return session.proxyPose().p_AB_m.z() < drilled_to_m + 0.0005; },
                              std::chrono::milliseconds(30000)))
      << "the proxy stays at z = " << session.proxyPose().p_AB_m.z() * 1e3 << " mm";
  session.stopHaptics();
  EXPECT_EQ(session.hapticThread()->drill()->removal().removedVoxels(), 0u) << "the burr was off";
}

// A recording started in the middle of drilling, with the proxy pressed into its own cavity,
// replays bit for bit (proxy, force, torque, contacts on every tick, and the drilled field's
// bytes): the session rebuilds the haptic threads fresh where the proxy stopped, with the cavity
// so far, before the recorder's first tick, as SessionRecorder does. The oracle that this can
// fail: the same records replayed from the scene's own free pose, where threads that kept their
// state would have started for the replay, differ.
TEST(Drilling, ARecordingStartedWhileDrillingReplaysBitForBit) {
  const auto dir = test::scratchDir();
  Session session;
  LoadedScene scene = loadScene(parseScene(R"({"volume": {"path": "builtin:sphere"}, "tool": {"mesh": "builtin:drill",
      "point_spacing_m": 0.001}, "coupling": {"linear_N_per_m": 400}, "device": {"kind": "simulated"},
      "drill": {"on": true, "burr_radius_m": 0.0025, "hardness": {"tissue": 0.3}}})", "s.json", "."));
  const haptics::Pose X_free = scene.X_WT_initial;
  auto device = scene.makeDevice();
  session.setScene(std::move(scene), device);
  haptics::Pose press = X_free;
  press.p_AB_m = Eigen::Vector3d(0.0, 0.0, 0.0125);
  session.startHaptics();
  session.simulatedDevice()->setPose(press);
  // Drilling and pressed: the burr's centre 1 mm below where the undrilled pole stops it.
  ASSERT_TRUE(test::waitUntil([&] { return session.proxyPose().p_AB_m.z() < 0.0215; }, std::chrono::milliseconds(90000)))
      << "the burr's centre at z = " << session.proxyPose().p_AB_m.z() * 1e3 << " mm";

  const std::shared_ptr<Drill> old_drill = session.hapticThread()->drill();
  const std::optional<haptics::Pose> X_start = session.prepareRecording();
  ASSERT_TRUE(X_start.has_value());
  EXPECT_FALSE(session.hapticsRunning()) << "left stopped for the recorder";
  EXPECT_TRUE(session.lastRestart().prepared_while_feeling) << "the new drill was built with the force on";
  std::cout << "restart: " << session.lastRestart().while_feeling_ms << " ms preparing with the force on (the burr held for "
            << session.lastRestart().cutting_held_ms << " ms, then " << session.lastRestart().voxels_cut_while_preparing
            << " voxels cut), "
            << session.lastRestart().without_force_ms << " ms without force\n";
  // Whether the burr cut while the new drill was prepared (what the field check below then also
  // covers) depends on how the solver thread was scheduled during those milliseconds: reported,
  // not required. MaterialRemoval's own test covers the cuts since the mark.
  if (session.lastRestart().voxels_cut_while_preparing == 0)
    std::cout << "nothing was cut while the new drill was prepared: the catch-up path did not run this time\n";
  ASSERT_NE(session.hapticThread()->drill(), nullptr);
  ASSERT_NE(session.hapticThread()->drill(), old_drill);
  const auto old_bytes = old_drill->removal().volume().bytes();
  const auto new_bytes = session.hapticThread()->drill()->removal().volume().bytes();
  ASSERT_EQ(old_bytes.size(), new_bytes.size());
  EXPECT_TRUE(std::equal(old_bytes.begin(), old_bytes.end(), new_bytes.begin()))
      << "the new drill starts from the field the old threads ended with";
  EXPECT_LT(X_start->p_AB_m.z(), 0.0215) << "rebuilt where the proxy stopped, in its cavity";
  ASSERT_NE(session.live().drill->cavity, nullptr) << "the cavity so far is kept for the new threads";
  const std::size_t cavity_at_start = session.live().drill->cavity->voxels.size();
  LiveValues live = session.live();
  live.X_WT_initial = *X_start;
  SessionInfo info;
  info.device_kind = "simulated";
  HapticThread* thread = session.hapticThread();
  ASSERT_NE(thread, nullptr);
  RecordingWriterOptions writer_options;
  writer_options.servo_rate_Hz = thread->solverRate_Hz();
  const auto path = dir / "mid-run.vhrec";
  auto writer = std::make_unique<RecordingWriter>(path, makeSessionMetadata(session.loaded(), live, info), writer_options);
  thread->setRecorder(writer.get());
  session.startHaptics();
  // Keep pressing, then draw the burr 2 mm aside through the bone.
  const std::uint64_t removed_before = thread->drill()->removal().removedVoxels();
  haptics::Pose aside = press;
  aside.p_AB_m.x() = 0.002;
  // 300 solver ticks (recorded ticks) pressing, then 300 more after the cut: counted, so the
  // recording holds more than 300 ticks however slowly a loaded machine runs the threads.
  const auto waitSolverTicks = [&](std::uint64_t n) {
    HapticSnapshot s;
    thread->latestSnapshot(s);
    const std::uint64_t from = s.solver_tick;
    return test::waitUntil([&] { return thread->latestSnapshot(s) && s.solver_tick >= from + n; });
  };
  ASSERT_TRUE(waitSolverTicks(300));
  session.simulatedDevice()->setPose(aside);
  ASSERT_TRUE(test::waitUntil([&] { return thread->drill()->removal().removedVoxels() > removed_before + 20; },
                              std::chrono::milliseconds(90000)));
  ASSERT_TRUE(waitSolverTicks(300));
  session.stopHaptics();
  thread->setRecorder(nullptr);
  writer->close();
  const haptics::ScalarVolume& live_field = thread->drill()->removal().volume();

  const Recording rec = readRecording(path);
  ASSERT_GT(rec.records.size(), 300u);
  const LoadedScene reloaded = loadScene(sceneFromSessionMetadata(rec.metadata_json));
  ASSERT_TRUE(reloaded.spec.drill.has_value());
  ASSERT_NE(reloaded.spec.drill->cavity, nullptr) << "the metadata carries the cavity drilled before the recording";
  EXPECT_EQ(reloaded.spec.drill->cavity->voxels.size(), cavity_at_start);
  EXPECT_EQ(reloaded.X_WT_initial.p_AB_m, X_start->p_AB_m);
  const ReplayComparison replay = replayRecording(reloaded, rec);
  // The session's solver runs with its deadline on the clock (solverDeadline_us()): a loaded
  // machine can cut a tick short, and the record says at which work; the replay (no clock) stops
  // there too, so it is identical whatever the machine's load.
  const auto deadline_cuts = std::count_if(rec.records.begin(), rec.records.end(), [](const TickRecord& r) {
    return (r.flags & kRecordFlagDeadlineCut) != 0;
  });
  EXPECT_TRUE(replay.identical) << replayDifference(replay, rec);
  std::cout << deadline_cuts << " recorded ticks were cut by the solver's deadline; the replay "
            << (replay.identical ? "is identical" : replayDifference(replay, rec)) << "\n";
  EXPECT_GT(replay.ticks_replayed, 300u);
  ASSERT_NE(replay.drilled_field, nullptr);
  ASSERT_EQ(replay.drilled_field->bytes().size(), live_field.bytes().size());
  if (replay.identical) {
    EXPECT_TRUE(std::equal(live_field.bytes().begin(), live_field.bytes().end(), replay.drilled_field->bytes().begin()))
        << "the replay carves the field the live drill carved, byte for byte";
  }
  const std::size_t at_end = cavityOf(live_field, *session.live().hapticField()).voxels.size();
  std::cout << "recording of " << rec.records.size() << " ticks started with " << cavity_at_start
            << " voxels drilled, ended with " << at_end << "; the proxy started at z = " << X_start->p_AB_m.z() * 1e3
            << " mm\n";
  EXPECT_GT(at_end, cavity_at_start);
  // The haptic thread's recording (the window's writer) says what the burr removed as `run`'s
  // does: the cavity it began with, the records' removed voxels and the two together, which is
  // the cavity the live drill left (the oracle: its field against the scan).
  const SessionMetrics m = computeSessionMetrics(rec);
  EXPECT_EQ(m.cavity_at_start_voxels, cavity_at_start);
  EXPECT_GT(m.removed_voxels, 20u);
  EXPECT_EQ(m.cavity_voxels, at_end);
  const double voxel_mm3 = thread->drill()->removal().voxelVolume_mm3();
  EXPECT_NEAR(m.removed_mm3, static_cast<double>(m.removed_voxels) * voxel_mm3, 1e-9 * m.removed_mm3);
  EXPECT_NEAR(m.cavity_at_start_mm3, static_cast<double>(cavity_at_start) * voxel_mm3, 1e-9 * m.cavity_at_start_mm3);

  LoadedScene from_free = reloaded;  // the check can fail: the replay from the scene's free pose
  from_free.X_WT_initial = X_free;
  const ReplayComparison elsewhere = replayRecording(from_free, rec);
  EXPECT_FALSE(elsewhere.identical);
  std::cout << "replayed from the scene's free pose: " << elsewhere.mismatch << " differs at tick "
            << elsewhere.first_mismatch_tick.value_or(0) << "\n";
}

// Holding the cut (what a recording started while drilling does while it builds the new drill):
// with the burr on and pressed into the sphere, no voxel is removed and the drill's field stays
// byte for byte the same for 300 ms, while the force still pushes back; released, the burr cuts
// again (so the drill was cutting all along and the hold is what stopped it).
TEST(Drilling, HoldingTheCutKeepsTheFieldWhileTheForceGoesOn) {
  Session session;
  LoadedScene scene = loadScene(parseScene(R"({"volume": {"path": "builtin:sphere"}, "tool": {"mesh": "builtin:drill",
      "point_spacing_m": 0.001}, "coupling": {"linear_N_per_m": 400}, "device": {"kind": "simulated"},
      "drill": {"on": true, "burr_radius_m": 0.0025, "hardness": {"tissue": 0.3}}})", "s.json", "."));
  auto device = scene.makeDevice();
  session.setScene(std::move(scene), device);
  HapticThread* thread = session.hapticThread();
  ASSERT_NE(thread, nullptr);
  const haptics::MaterialRemoval& removal = thread->drill()->removal();
  haptics::Pose press = session.proxyPose();
  press.p_AB_m = Eigen::Vector3d(0.0, 0.0, 0.0125);
  session.startHaptics();
  session.simulatedDevice()->setPose(press);
  ASSERT_TRUE(test::waitUntil([&] { return removal.removedVoxels() > 20; }, std::chrono::milliseconds(90000)))
      << "the burr cuts";

  // A generous timeout: the hold waits for the solver's next tick, which a loaded machine may
  // delay past the default 100 ms.
  ASSERT_TRUE(thread->holdCutting(30000.0));
  EXPECT_TRUE(thread->cuttingHeld());
  const std::uint64_t held_at = removal.removedVoxels();
  const std::vector<std::byte> field_at = removal.volume().bytes();
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  HapticSnapshot snapshot;
  ASSERT_TRUE(session.latestSnapshot(snapshot));
  EXPECT_GT(snapshot.force_W_N.norm(), 0.5) << "the bone still pushes back on the hand";
  EXPECT_TRUE(thread->drilling()) << "the burr is still switched on";
  EXPECT_EQ(removal.removedVoxels(), held_at) << "no voxel removed while held";
  EXPECT_TRUE(std::equal(field_at.begin(), field_at.end(), removal.volume().bytes().begin()))
      << "the field is not written while held";

  thread->releaseCutting();
  EXPECT_TRUE(test::waitUntil([&] { return removal.removedVoxels() > held_at + 5; }, std::chrono::milliseconds(90000)))
      << "released, the burr cuts again";
  session.stopHaptics();
}

// Stalls the solver inside its tick while `stall` is set (HapticThreadOptions::solver_tick_hook).
struct SolverStall {
  std::atomic<bool> stall{false};
  std::atomic<bool> stalled{false};  // a tick is inside the stall now
  static void hook(void* context) {
    auto* self = static_cast<SolverStall*>(context);
    while (self->stall.load(std::memory_order_acquire)) {
      self->stalled.store(true, std::memory_order_release);
      std::this_thread::sleep_for(std::chrono::microseconds(200));
    }
    self->stalled.store(false, std::memory_order_release);
  }
};

// The hold's way out: a solver that does not finish a tick (stalled inside one that may still be
// cutting) cannot promise that nothing cuts, so holdCutting() gives up after its timeout, holds
// nothing (cuttingHeld() false) and says so; once the solver goes on, the burr cuts again (the
// caller builds after the stop instead, as Session::prepareRecording() does). After stop(),
// nothing can cut and the hold succeeds at once.
TEST(Drilling, AStalledSolverMakesTheHoldTimeOutAndHoldNothing) {
  LoadedScene scene = loadScene(parseScene(R"({"volume": {"path": "builtin:sphere"}, "tool": {"mesh": "builtin:drill",
      "point_spacing_m": 0.001}, "coupling": {"linear_N_per_m": 400}, "device": {"kind": "simulated"},
      "drill": {"on": true, "burr_radius_m": 0.0025, "hardness": {"tissue": 0.3}}})", "s.json", "."));
  auto device = scene.makeDevice();
  auto* simulated = dynamic_cast<SimulatedDevice*>(device.get());
  ASSERT_NE(simulated, nullptr);
  SolverStall stall;
  HapticThreadOptions options;
  options.solver_tick_hook = &SolverStall::hook;
  options.solver_tick_hook_context = &stall;
  std::unique_ptr<HapticThread> thread = scene.makeHapticThread(device, 1000.0, std::nullopt, options);
  ASSERT_NE(thread->drill(), nullptr);
  const haptics::MaterialRemoval& removal = thread->drill()->removal();
  haptics::Pose press = scene.X_WT_initial;
  press.p_AB_m = Eigen::Vector3d(0.0, 0.0, 0.0125);
  simulated->setPose(press);
  thread->start();
  ASSERT_TRUE(test::waitUntil([&] { return removal.removedVoxels() > 20; }, std::chrono::milliseconds(90000)))
      << "the burr cuts";

  stall.stall.store(true, std::memory_order_release);
  ASSERT_TRUE(test::waitUntil([&] { return stall.stalled.load(std::memory_order_acquire); }));
  const auto t0 = std::chrono::steady_clock::now();
  EXPECT_FALSE(thread->holdCutting(50.0)) << "a stalled solver cannot be held";
  const double waited_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  EXPECT_GE(waited_ms, 50.0) << "it waited its timeout";
  EXPECT_LT(waited_ms, 30000.0) << "it gave up rather than waiting on (late only by a loaded machine's wake-up)";
  EXPECT_FALSE(thread->cuttingHeld()) << "a failed hold holds nothing";
  std::cout << "the hold gave up after " << waited_ms << " ms (timeout 50 ms)\n";

  const std::uint64_t after_timeout = removal.removedVoxels();
  stall.stall.store(false, std::memory_order_release);
  EXPECT_TRUE(test::waitUntil([&] { return removal.removedVoxels() > after_timeout + 5; },
                              std::chrono::milliseconds(90000)))
      << "the solver going on, the burr cuts again: nothing was left held";
  thread->stop();
  EXPECT_TRUE(thread->holdCutting(50.0)) << "stopped threads cut nothing";
  EXPECT_TRUE(thread->cuttingHeld());
  thread->releaseCutting();
}

// A device lowered onto the sphere's top over its first 500 reads and held there, its first
// button held from read 300 on when `press_button`.
class ButtonDevice final : public Device {
 public:
  explicit ButtonDevice(bool press_button) : press_button_(press_button) {}
  std::string name() const override { return "button"; }
  bool read(DeviceSample& sample) noexcept override {
    const int i = reads_.load(std::memory_order_relaxed);
    reads_.store(i + 1, std::memory_order_release);
    const double a = std::clamp(i / 500.0, 0.0, 1.0);
    sample.X_WD = haptics::Pose::FromTranslation({0.0, 0.0, 0.030 - a * (0.030 - 0.0125)});
    sample.time_s = 1e-3 * i;
    sample.buttons = press_button_ && i >= 300 ? HapticThread::kDrillButton : 0u;
    sample.valid = true;
    return true;
  }
  void command(const Eigen::Vector3d&, const Eigen::Vector3d&) noexcept override {}
  int reads() const { return reads_.load(std::memory_order_acquire); }

 private:
  bool press_button_;
  std::atomic<int> reads_{0};
};

// The device's first button spins the burr while held, as a foot pedal: with the drill prepared
// but switched off, pressing on the sphere removes nothing; holding the button removes voxels.
// The GUI's snapshots say so too (what the burr's sound follows): the burr on, cutting with a
// force at the scene's hardness, the eroded volume growing to the drill's.
TEST(Drilling, TheDevicesFirstButtonSpinsTheBurrWhileHeld) {
  std::uint64_t removed[2] = {0, 0};
  bool seen_on[2] = {false, false}, seen_cut[2] = {false, false};
  double seen_eroded_mm3[2] = {0.0, 0.0};
  for (const bool press : {false, true}) {
    Session session;
    LoadedScene scene = loadScene(parseScene(R"({"volume": {"path": "builtin:sphere"}, "tool": {"mesh": "builtin:drill",
        "point_spacing_m": 0.001}, "coupling": {"linear_N_per_m": 400},
        "drill": {"on": false, "burr_radius_m": 0.0025, "hardness": {"tissue": 2.0}}})", "s.json", "."));
    auto device = std::make_shared<ButtonDevice>(press);
    session.setScene(std::move(scene), device);
    ASSERT_NE(session.hapticThread()->drill(), nullptr) << "the scene's drill is prepared, switched off";
    EXPECT_FALSE(session.drilling());
    session.startHaptics();
    HapticSnapshot snap;
    const auto watch = [&] {
      if (session.hapticThread()->latestSnapshot(snap)) {
        seen_on[press] = seen_on[press] || snap.burr_on;
        if (snap.burr_force_N > 0.0) {
          seen_cut[press] = true;
          EXPECT_DOUBLE_EQ(snap.burr_specific_energy_J_per_mm3, 2.0);
        }
        EXPECT_GE(snap.burr_eroded_mm3, seen_eroded_mm3[press]) << "it only grows";
        seen_eroded_mm3[press] = snap.burr_eroded_mm3;
      }
      return device->reads() >= 1500;
    };
    EXPECT_TRUE(test::waitUntil(watch, std::chrono::milliseconds(60000)));
    session.stopHaptics();
    removed[press] = session.hapticThread()->drill()->removal().removedVoxels();
    EXPECT_FALSE(session.drilling()) << "the button does not switch the drill on for good";
  }
  std::cout << "removed voxels: button not pressed " << removed[0] << ", held " << removed[1]
            << "; snapshots: eroded " << seen_eroded_mm3[1] << " mm^3\n";
  EXPECT_EQ(removed[0], 0u);
  EXPECT_GT(removed[1], 0u);
  EXPECT_FALSE(seen_on[0]);
  EXPECT_FALSE(seen_cut[0]);
  EXPECT_EQ(seen_eroded_mm3[0], 0.0);
  EXPECT_TRUE(seen_on[1]);
  EXPECT_TRUE(seen_cut[1]);
  EXPECT_GT(seen_eroded_mm3[1], 0.0);
}

}  // namespace
}  // namespace vh::runtime
