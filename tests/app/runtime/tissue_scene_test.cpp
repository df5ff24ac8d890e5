// Soft tissue in a scene: the "tissue" section, a headless run that presses a ball into the
// built-in gel (it yields: the force is the tissue's in series with the coupling, far below the
// coupling's alone on the same scan felt rigid; the crossing check against the deformed field
// finds nothing), and a record / replay round trip that deforms it tick for tick as the run did.
#include "vh/runtime/tissue_scene.h"

#include <cstdio>
#include <filesystem>

#include <gtest/gtest.h>

#include "runtime_test_support.h"
#include "vh/datasets/synthetic.h"
#include "vh/runtime/recording.h"
#include "vh/runtime/replay.h"
#include "vh/runtime/runner.h"
#include "vh/runtime/scene.h"
#include "vh/runtime/servo_factory.h"
#include "vh/runtime/session_metadata.h"
#include "vh/tissue/deformable_scene.h"

namespace vh::runtime {
namespace {

const char* kGelScene = R"({
  "volume": {"path": "builtin:gel-with-inclusion", "isovalue": 50},
  "tool": {"mesh": "builtin:sphere", "point_spacing_m": 0.0005,
           "initial_pose": {"p_m": [-0.005, 0, 0.023], "q_wxyz": [1, 0, 0, 0]}},
  "coupling": {"linear_N_per_m": 200},
  "tissue": {"bands": [{"min": 10, "max": 150, "material": "gel"},
                       {"min": 150, "max": 300, "material": "gel inclusion"}],
             "rigid_above": 300, "cell_size_m": 0.002}
})";

// The device at (x, y) [m], lowered from z_from to z_to [m] over the first t_down_s seconds,
// then held until t_end_s.
Trajectory pressDown(double x, double y, double z_from, double t_down_s, double z_to, double t_end_s) {
  const auto at = [&](double t, double z) {
    TrajectorySample s;
    s.t_s = t;
    s.X_WD.p_AB_m = {x, y, z};
    return s;
  };
  return Trajectory({at(0.0, z_from), at(t_down_s, z_to), at(t_end_s, z_to)});
}

TEST(TissueScene, SectionIsParsedAndChecked) {
  const SceneSpec spec = parseScene(kGelScene, "gel.json", ".");
  ASSERT_TRUE(spec.tissue.has_value());
  ASSERT_EQ(spec.tissue->bands.size(), 2u);
  EXPECT_EQ(spec.tissue->bands[1].material, "gel inclusion");
  EXPECT_DOUBLE_EQ(spec.tissue->bands[0].min, 10.0);
  EXPECT_DOUBLE_EQ(*spec.tissue->rigid_above, 300.0);
  EXPECT_DOUBLE_EQ(spec.tissue->cell_size_m, 0.002);
  VH_EXPECT_THROW_WITH(
      parseScene(R"({"volume": {"path": "builtin:sphere"}, "tissue": {"bands": [{"min": 0, "max": 1, "material": "jelly"}]}})",
                 "s.json", "."),
      std::runtime_error, "s.json", "tissue.bands[0].material", "jelly", "liver");
  VH_EXPECT_THROW_WITH(
      parseScene(R"({"volume": {"path": "builtin:sphere"}, "tissue": {"bands": [{"min": 2, "max": 1, "material": "gel"}]}})",
                 "s.json", "."),
      std::runtime_error, "tissue.bands[0].max", "exceed");
  VH_EXPECT_THROW_WITH(parseScene(R"({"volume": {"path": "builtin:sphere"}, "drill": {},
                                      "tissue": {"bands": [{"min": 0, "max": 1, "material": "gel"}]}})",
                                  "s.json", "."),
                       std::runtime_error, "tissue", "drill");
  EXPECT_FALSE(parseScene(R"({"volume": {"path": "builtin:sphere"}})", "s.json", ".").tissue.has_value());
  // A scene without the section builds no tissue.
  const LoadedScene rigid = loadScene(parseScene(R"({"volume": {"path": "builtin:sphere"}})", "s.json", "."));
  EXPECT_EQ(makeServoRenderer(LiveValues::initial(rigid), {}, rigid.X_WT_initial, 1000.0).tissue, nullptr);
}

// Press the 5 mm ball 1.5 mm into the gel beside the inclusion for 2.5 s: the gel gives (the
// force stays far below the 0.3 N the coupling alone would push with against the same scan felt
// rigid), nothing crosses the deformed field, and the replay deforms it tick for tick.
TEST(TissueScene, HeadlessRunFeelsTheGelYieldAndReplaysIt) {
  const auto dir = test::scratchDir();
  const LoadedScene scene = loadScene(parseScene(kGelScene, "gel.json", "."));
  const double top = datasets::kGelTop_m, R = 0.005;
  const Trajectory press = pressDown(-0.005, 0.0, top + R + 0.001, 1.0, top + R - 0.0015, 2.5);
  RunOptions options;
  options.record = dir / "gel.vhrec";
  options.lag_reference = false;
  options.verify_step_voxels = 0.05;
  const RunReport soft = runHeadless(scene, press, options);

  SceneSpec rigid_spec = scene.spec;
  rigid_spec.tissue.reset();
  RunOptions rigid_options = options;
  rigid_options.record.clear();
  const RunReport rigid = runHeadless(loadScene(rigid_spec), press, rigid_options);
  std::printf("gel pressed 1.5 mm with a 5 mm ball at 200 N/m: peak force %.4f N yielding, %.4f N rigid; "
              "crossings %lld, deepest %.3g m (epsilon %.3g m)\n",
              soft.max_force_N, rigid.max_force_N, static_cast<long long>(soft.crossings), soft.max_penetration_m,
              soft.epsilon_m);
  EXPECT_GT(rigid.max_force_N, 0.25);
  EXPECT_GT(soft.max_force_N, 0.01) << "the gel was not touched";
  EXPECT_LT(soft.max_force_N, 0.6 * rigid.max_force_N) << "the gel did not yield";
  EXPECT_EQ(soft.crossings, 0);
  EXPECT_LE(soft.max_penetration_m, soft.epsilon_m);
  // Force against indentation in the report: the gel gave most of the 1.5 mm press (the rest is
  // the coupling's stretch, force / k), and the force grows with the indentation.
  ASSERT_TRUE(soft.tissue.has_value());
  EXPECT_FALSE(rigid.tissue.has_value());
  std::printf("indentation %.3f mm, push %.4f N; force by indentation:", soft.tissue->max_indentation_m * 1e3,
              soft.tissue->max_push_N);
  for (const auto& [d, f] : soft.tissue->force_by_indentation) std::printf(" %.2f mm %.3f N;", d * 1e3, f);
  std::printf("\n");
  EXPECT_NEAR(soft.tissue->max_indentation_m + soft.max_force_N / 200.0, 1.5e-3, 0.3e-3);
  ASSERT_EQ(soft.tissue->force_by_indentation.size(), 10u);
  EXPECT_GT(soft.tissue->force_by_indentation.back().second, soft.tissue->force_by_indentation[4].second);
  EXPECT_NE(soft.toJson().find("\"force_by_indentation\""), std::string::npos);

  const Recording recording = readRecording(options.record);
  const LoadedScene replayed_scene = loadScene(sceneFromSessionMetadata(recording.metadata_json));
  ASSERT_TRUE(replayed_scene.spec.tissue.has_value()) << "the recording keeps the tissue";
  const ReplayComparison replay = replayRecording(replayed_scene, recording);
  EXPECT_TRUE(replay.identical) << replay.mismatch << " at tick " << replay.first_mismatch_tick.value_or(0);
  // Without the tissue the replay is another run (the check can fail).
  SceneSpec without = replayed_scene.spec;
  without.tissue.reset();
  EXPECT_FALSE(replayRecording(loadScene(without), recording).identical);
}

// The brain of the shared small CT head (64 x 64 x 93 voxels of 3.2 x 3.2 x 1.5 mm, the
// classic "headsq": brain about 900-1180, bone above 1300 in its units) as tissue on a 4 mm
// lattice: its whole surface is touchable, so the compliance table (9 S^2 floats) would not fit;
// the scene is refused before any solve, naming the size and what to change.
TEST(TissueScene, ARegionWhoseTableWouldNotFitIsRefusedWithItsSize) {
  const auto head = sharedDatasetsDir() / "ct" / "ct-head-small";
  if (!std::filesystem::exists(head)) GTEST_SKIP() << "shared dataset absent: " << head;
  SceneSpec spec = sceneForVolume(head);
  spec.volume.isovalue = 900.0;
  spec.volume.isovalue_set = true;
  const LoadedScene scene = loadScene(spec);
  TissueSpec brain;
  brain.bands = {{900.0, 1180.0, "brain grey matter"}};
  brain.rigid_above = 1300.0;
  brain.cell_size_m = 0.004;
  try {
    (void)makeTissueScene(brain, scene.volume.field, 900.0, false);
    FAIL() << "a table past the limit was built";
  } catch (const std::invalid_argument& e) {
    std::printf("CT head brain, 4 mm lattice: %s\n", e.what());
    const std::string what = e.what();
    EXPECT_NE(what.find("touchable nodes"), std::string::npos) << what;
    EXPECT_NE(what.find("GB"), std::string::npos) << what;
    EXPECT_NE(what.find("cell_size_m"), std::string::npos) << what;
  }
}

}  // namespace
}  // namespace vh::runtime
