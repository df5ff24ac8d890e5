// Drilling in a scene: the "drill" section, the hardness classes, a headless run that drills
// into the built-in sphere (never through what is not removed: crossings 0), and a record /
// replay round trip that rebuilds the drilled field bit for bit (SHA-256 of its voxels).
#include "vh/runtime/drilling.h"

#include <gtest/gtest.h>

#include "runtime_test_support.h"
#include "vh/runtime/recording.h"
#include "vh/runtime/replay.h"
#include "vh/runtime/runner.h"
#include "vh/runtime/scene.h"
#include "vh/runtime/session_metadata.h"
#include "vh/runtime/sha256.h"

namespace vh::runtime {
namespace {

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
  const auto at = [](double t, double z) {
    TrajectorySample s;
    s.t_s = t;
    s.X_WD.p_AB_m = {0.0, 0.0, z};
    return s;
  };
  const Trajectory press({at(0.0, 0.030), at(1.0, 0.0125), at(3.0, 0.0125)});
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
}

}  // namespace
}  // namespace vh::runtime
