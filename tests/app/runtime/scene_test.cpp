// Tests of vh/runtime/scene.h: parsing scene files (good and every error), built-in scenes,
// loading a scene into a renderer, and the default placement of the tool.
#include "vh/runtime/scene.h"
#include "vh/runtime/tool_fidelity.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <cstdlib>
#include <limits>
#include <optional>
#include <stdexcept>
#include <string>
#include <thread>

#include <gtest/gtest.h>
#include <vtkImageData.h>  // the image LoadedScene shares for rendering

#include "runtime_test_support.h"
#include "vh/datasets/synthetic.h"
#include "vh/runtime/placement.h"
#include "vh/runtime/servo_factory.h"

namespace vh::runtime {
namespace {

namespace fs = std::filesystem;
using test::scratchDir;
using test::writeText;

TEST(SceneFile, ParsesEveryField) {
  const fs::path dir = scratchDir();
  writeText(dir / "data" / "tool.stl", "not read by the parser");
  writeText(dir / "traj.csv", "0,0,0,0,1,0,0,0\n");
  const fs::path scene = writeText(dir / "s.json", R"({
    // comments are allowed
    "description": "test scene",
    "volume": {"path": "builtin:sphere", "isovalue": -2.5},
    "tool": {"mesh": "data/tool.stl", "scale_to_m": 0.001, "point_count": 321,
             "initial_pose": {"p_m": [0.01, -0.02, 0.03], "q_wxyz": [0, 0, 0, 2]}},
    "coupling": {"linear_N_per_m": 2500, "angular_Nm_per_rad": 1.5},
    "device": {"kind": "scripted", "trajectory": "traj.csv"}
  })");
  const SceneSpec spec = loadSceneFile(scene);
  EXPECT_EQ(spec.source, fs::absolute(scene));
  EXPECT_EQ(spec.volume.path, "builtin:sphere");
  EXPECT_TRUE(spec.volume.isovalue_set);
  EXPECT_DOUBLE_EQ(spec.volume.isovalue, -2.5);
  EXPECT_EQ(fs::path(spec.tool.mesh), fs::absolute(dir / "data" / "tool.stl").lexically_normal());
  EXPECT_DOUBLE_EQ(spec.tool.scale_to_m, 0.001);
  EXPECT_EQ(spec.tool.point_count, 321u);
  EXPECT_DOUBLE_EQ(spec.tool.point_spacing_m, 0.0);
  EXPECT_TRUE(spec.tool.initial_pose_set);
  EXPECT_FALSE(spec.tool.initial_orientation_set);
  EXPECT_TRUE(spec.tool.X_WT_initial.p_AB_m.isApprox(Eigen::Vector3d(0.01, -0.02, 0.03)));
  EXPECT_NEAR(spec.tool.X_WT_initial.R_AB.z(), 1.0, 1e-15);  // normalised from (0, 0, 0, 2)
  EXPECT_DOUBLE_EQ(spec.gains.linear_N_per_m, 2500.0);
  EXPECT_DOUBLE_EQ(spec.gains.angular_Nm_per_rad, 1.5);
  ASSERT_TRUE(spec.device.has_value());
  EXPECT_EQ(spec.device->kind, "scripted");
  EXPECT_EQ(fs::path(spec.device->trajectory), fs::absolute(dir / "traj.csv").lexically_normal());
}

TEST(SceneFile, SeriesAndPhaseOfADicomFolder) {
  const fs::path dir = scratchDir();
  SceneSpec spec = loadSceneFile(writeText(dir / "a.json", R"({"volume": {"path": "builtin:plane", "series": "BONE", "phase": 2}})"));
  EXPECT_EQ(spec.volume.series, "BONE");
  EXPECT_EQ(spec.volume.phase, 2);
  spec = loadSceneFile(writeText(dir / "b.json", R"({"volume": {"path": "builtin:plane", "series": 3}})"));
  EXPECT_EQ(spec.volume.series, "3");
  EXPECT_EQ(spec.volume.phase, 0);
  EXPECT_THROW(loadSceneFile(writeText(dir / "c.json", R"({"volume": {"path": "builtin:plane", "phase": -1}})")),
               std::runtime_error);
  EXPECT_THROW(loadSceneFile(writeText(dir / "d.json", R"({"volume": {"path": "builtin:plane", "series": ""}})")),
               std::runtime_error);
}

TEST(SceneFile, DefaultsAndNoDeviceMeansNoHapticThread) {
  const fs::path dir = scratchDir();
  const SceneSpec spec = loadSceneFile(writeText(dir / "s.json", R"({"volume": {"path": "builtin:plane"}})"));
  EXPECT_FALSE(spec.volume.isovalue_set);
  EXPECT_EQ(spec.tool.mesh, "builtin:probe");
  EXPECT_FALSE(spec.tool.initial_pose_set);
  EXPECT_FALSE(spec.device.has_value());
  const haptics::CouplingGains defaults;
  EXPECT_EQ(spec.gains.linear_N_per_m, defaults.linear_N_per_m);
  // A scene starts only what it uses: no device section, no device (and so no haptic thread).
  const LoadedScene loaded = loadScene(spec);
  EXPECT_EQ(loaded.makeDevice(), nullptr);
  EXPECT_DOUBLE_EQ(loaded.isovalue, datasets::builtinIsovalue("plane"));
}

TEST(SceneFile, OrientationOnlyKeepsAutomaticPlacement) {
  const fs::path dir = scratchDir();
  const SceneSpec spec = loadSceneFile(writeText(dir / "s.json", R"({"volume": {"path": "builtin:sphere"},
      "tool": {"initial_pose": {"q_wxyz": [0.7071067811865476, 0.7071067811865476, 0, 0]}}})"));
  EXPECT_FALSE(spec.tool.initial_pose_set);
  EXPECT_TRUE(spec.tool.initial_orientation_set);
  const LoadedScene loaded = loadScene(spec);
  EXPECT_NEAR(loaded.X_WT_initial.R_AB.angularDistance(spec.tool.X_WT_initial.R_AB), 0.0, 1e-12);
  EXPECT_EQ(loaded.initial_points_inside, 0);
}

TEST(SceneFile, ResolvesRelativePathsAgainstTheSharedDatasets) {
  const fs::path drill = test::sharedDatasets() / "meshes" / "drill" / "drill.stl";
  if (!fs::exists(drill)) GTEST_SKIP() << "shared dataset absent: " << drill;
  const fs::path dir = scratchDir();
  const SceneSpec spec = loadSceneFile(writeText(dir / "s.json", R"({"volume": {"path": "builtin:plane"},
      "tool": {"mesh": "meshes/drill/drill.stl"}})"));
  EXPECT_TRUE(fs::equivalent(spec.tool.mesh, drill));
}

/// Writes `json` as a scene file and expects loadSceneFile to fail naming the file and `parts`.
template <typename... Parts>
void expectSceneError(const std::string& json, Parts... parts) {
  const fs::path dir = scratchDir();
  const fs::path file = writeText(dir / "bad.json", json);
  VH_EXPECT_THROW_WITH(loadSceneFile(file), std::runtime_error, file.string(), parts...);
}

TEST(SceneFile, OpenIgtlinkIsOffUnlessTheSceneAsks) {
  const fs::path dir = scratchDir();
  EXPECT_FALSE(loadSceneFile(writeText(dir / "off.json", R"({"volume": {"path": "builtin:plane"}})")).openigtlink);
  const SceneSpec defaults =
      loadSceneFile(writeText(dir / "d.json", R"({"volume": {"path": "builtin:plane"}, "openigtlink": {}})"));
  ASSERT_TRUE(defaults.openigtlink.has_value());
  EXPECT_EQ(defaults.openigtlink->port, 18944);
  EXPECT_DOUBLE_EQ(defaults.openigtlink->rate_Hz, 60.0);
  const SceneSpec set = loadSceneFile(
      writeText(dir / "s.json", R"({"volume": {"path": "builtin:plane"}, "openigtlink": {"port": 18945, "rate_Hz": 250}})"));
  ASSERT_TRUE(set.openigtlink.has_value());
  EXPECT_EQ(set.openigtlink->port, 18945);
  EXPECT_DOUBLE_EQ(set.openigtlink->rate_Hz, 250.0);
}

TEST(SceneFileErrors, OpenIgtlink) {
  expectSceneError(R"({"volume": {"path": "builtin:plane"}, "openigtlink": {"port": 0}})", "openigtlink.port",
                   "expected an integer port in 1..65535, found 0");
  expectSceneError(R"({"volume": {"path": "builtin:plane"}, "openigtlink": {"port": 18944.5}})", "openigtlink.port");
  expectSceneError(R"({"volume": {"path": "builtin:plane"}, "openigtlink": {"rate_Hz": -1}})", "openigtlink.rate_Hz",
                   "must be > 0");
  expectSceneError(R"({"volume": {"path": "builtin:plane"}, "openigtlink": {"rate": 60}})", "openigtlink",
                   "unknown key 'rate'");
  expectSceneError(R"({"volume": {"path": "builtin:plane"}, "openigtlink": 18944})", "openigtlink", "expected an object");
}

TEST(SceneLoad, PreloadedVolumeOpensLikeAFile) {
  SceneSpec builtin;
  builtin.volume.path = "builtin:sphere";
  const LoadedScene file = loadScene(builtin);
  io::LoadedVolume volume = file.volume;
  volume.info.description = "FromSlicer";
  volume.info.format = "OpenIGTLink";
  const SceneSpec spec = sceneForLoadedVolume(volume);
  EXPECT_EQ(spec.volume.path, "igtl:FromSlicer");
  EXPECT_EQ(spec.tool.mesh, "builtin:probe");
  ASSERT_TRUE(spec.device.has_value());
  const LoadedScene scene = loadScene(spec, volume);
  EXPECT_EQ(scene.volume.field, volume.field);
  ASSERT_NE(scene.tool, nullptr);
  EXPECT_EQ(scene.initial_points_inside, 0);
  EXPECT_DOUBLE_EQ(scene.isovalue, 0.5 * (volume.field->minValue() + volume.field->maxValue()));
  VH_EXPECT_THROW_WITH(loadScene(spec, io::LoadedVolume{}), std::invalid_argument, "no field");
}

TEST(SceneFileErrors, MissingFile) {
  VH_EXPECT_THROW_WITH(loadSceneFile("/no/such/scene.json"), std::runtime_error, "/no/such/scene.json",
                       "scene file not found");
}

TEST(SceneFileErrors, InvalidJson) {
  expectSceneError("{\n  \"volume\": {\"path\": \"builtin:plane\",,}\n}", "invalid JSON", "line 2");
}

TEST(SceneFileErrors, TopLevelNotAnObject) { expectSceneError("[1, 2]", "expected an object, found array"); }

TEST(SceneFileErrors, MissingVolume) { expectSceneError(R"({"tool": {}})", "volume: missing"); }

TEST(SceneFileErrors, MissingVolumePath) { expectSceneError(R"({"volume": {"isovalue": 3}})", "volume.path: missing"); }

TEST(SceneFile, PassivityControlIsOffUnlessTheSceneAsks) {
  const fs::path dir = scratchDir();
  EXPECT_FALSE(loadSceneFile(writeText(dir / "absent.json", R"({"volume": {"path": "builtin:plane"}})"))
                   .gains.passivity_control);
  const SceneSpec on = loadSceneFile(writeText(
      dir / "on.json", R"({"volume": {"path": "builtin:plane"}, "coupling": {"passivity_control": true}})"));
  EXPECT_TRUE(on.gains.passivity_control);
  EXPECT_EQ(on.gains.linear_N_per_m, haptics::CouplingGains{}.linear_N_per_m);
  EXPECT_FALSE(loadSceneFile(writeText(dir / "off.json", R"({"volume": {"path": "builtin:plane"},
      "coupling": {"linear_N_per_m": 2000, "passivity_control": false}})"))
                   .gains.passivity_control);
}

// The edge test is on unless the tool says "edge_test": false, and the setting reaches the
// renderer: the upright probe (2 mm point spacing) moved sideways into the edge of the built-in
// one-voxel plate at 250 goes through it with "edge_test": false and stops at the plate's edge by
// default (the plate's extent is the oracle: its edge at x = 31.5 mm, the probe's shaft radius
// 0.98 mm).
TEST(SceneFile, TheEdgeTestIsOnUnlessTheToolTurnsItOff) {
  const fs::path dir = scratchDir();
  const char* base = R"({"volume": {"path": "builtin:thin-plate", "isovalue": 250},
      "tool": {"mesh": "builtin:probe", "point_spacing_m": 0.002, "initial_pose": {"p_m": [0.0395, 0.0003, -0.0195]})";
  const SceneSpec off = loadSceneFile(writeText(dir / "off.json", std::string(base) + ", \"edge_test\": false}}"));
  const SceneSpec on = loadSceneFile(writeText(dir / "on.json", std::string(base) + "}}"));
  EXPECT_FALSE(off.tool.edge_test);
  ASSERT_TRUE(on.tool.edge_test);
  expectSceneError(R"({"volume": {"path": "builtin:plane"}, "tool": {"edge_test": 1}})",
                   "tool.edge_test: expected true or false, found 1");
  const double edge_x = 0.0315;
  double axis_x[2] = {0.0, 0.0};
  for (const bool edge_test : {false, true}) {
    const LoadedScene scene = loadScene(edge_test ? on : off);
    auto renderer = scene.makeRenderer(haptics::RendererOptions{});
    for (int t = 0; t < 400; ++t) {
      haptics::Pose X_WD = scene.X_WT_initial;
      X_WD.p_AB_m.x() -= 0.030 * std::min(1.0, t / 300.0);
      renderer->tick(X_WD, scene.isovalue);
    }
    axis_x[edge_test] = renderer->proxyPose().p_AB_m.x();
  }
  EXPECT_LT(axis_x[0], edge_x - 0.98e-3) << "without the edge test the plate passes between the points";
  EXPECT_GT(axis_x[1], edge_x - 0.98e-3) << "with it the shaft's axis stays outside the plate";
}

TEST(SceneFileErrors, PassivityControlMustBeABoolean) {
  // Stiffnesses past the stated maxima (a force of 1e300 N/m x 1 mm overflows |F| to inf).
  expectSceneError(R"({"volume": {"path": "builtin:plane"}, "coupling": {"linear_N_per_m": 1e300}})",
                   "coupling.linear_N_per_m: must be at most 100000 N/m, found 1e+300");
  expectSceneError(R"({"volume": {"path": "builtin:plane"}, "coupling": {"angular_Nm_per_rad": 51}})",
                   "coupling.angular_Nm_per_rad: must be at most 50");
  expectSceneError(R"({"volume": {"path": "builtin:plane"}, "coupling": {"passivity_control": 1}})",
                   "coupling.passivity_control: expected true or false, found 1");
  expectSceneError(R"({"volume": {"path": "builtin:plane"}, "coupling": {"passivity_control": "yes"}})",
                   "coupling.passivity_control: expected true or false");
}

TEST(SceneFileErrors, MistypedFields) {
  expectSceneError(R"({"volume": {"path": 12}})", "volume.path: expected a string, found number");
  expectSceneError(R"({"volume": {"path": "builtin:plane", "isovalue": "400"}})",
                   "volume.isovalue: expected a number, found string");
  expectSceneError(R"({"volume": {"path": "builtin:plane"}, "tool": {"scale_to_m": -1}})",
                   "tool.scale_to_m: must be > 0");
  expectSceneError(R"({"volume": {"path": "builtin:plane"}, "tool": {"point_count": 2.5}})",
                   "tool.point_count: expected a positive integer");
  expectSceneError(R"({"volume": {"path": "builtin:plane"}, "coupling": {"linear_N_per_m": 0}})",
                   "coupling.linear_N_per_m: must be > 0");
}

TEST(SceneFileErrors, UnknownKeyIsATypo) {
  expectSceneError(R"({"volume": {"path": "builtin:plane", "isoValue": 3}})", "volume", "unknown key 'isoValue'",
                   "path, isovalue");
  expectSceneError(R"({"volume": {"path": "builtin:plane"}, "devices": {}})", "unknown key 'devices'");
}

TEST(SceneFileErrors, BadPose) {
  expectSceneError(R"({"volume": {"path": "builtin:plane"}, "tool": {"initial_pose": {"p_m": [0, 0]}}})",
                   "tool.initial_pose.p_m: expected an array of 3 numbers");
  expectSceneError(R"({"volume": {"path": "builtin:plane"}, "tool": {"initial_pose": {"q_wxyz": [0, 0, 0, 0]}}})",
                   "tool.initial_pose.q_wxyz: zero quaternion");
  expectSceneError(R"({"volume": {"path": "builtin:plane"}, "tool": {"initial_pose": {}}})",
                   "tool.initial_pose: needs p_m and/or q_wxyz");
}

TEST(SceneFileErrors, SpacingAndCountTogether) {
  expectSceneError(R"({"volume": {"path": "builtin:plane"},
                       "tool": {"point_spacing_m": 0.001, "point_count": 100}})",
                   "give point_spacing_m or point_count, not both");
}

TEST(SceneFileErrors, Devices) {
  expectSceneError(R"({"volume": {"path": "builtin:plane"}, "device": {"kind": "falcon"}})",
                   "device.kind: unknown device kind 'falcon'");
  expectSceneError(R"({"volume": {"path": "builtin:plane"}, "device": {"kind": "scripted"}})",
                   "device.trajectory: missing");
  expectSceneError(R"({"volume": {"path": "builtin:plane"}, "device": {"trajectory": "t.csv"}})",
                   "device.trajectory: only for kind \"scripted\"");
}

TEST(SceneFileErrors, DataFileNotFoundNamesWhereItLooked) {
  expectSceneError(R"({"volume": {"path": "no/such/volume.nrrd"}})", "volume.path: 'no/such/volume.nrrd' not found",
                   "looked in", test::sharedDatasets().lexically_normal().string());
  expectSceneError(R"({"volume": {"path": "/abs/volume.nrrd"}})", "volume.path: '/abs/volume.nrrd' not found");
}

TEST(SceneFileErrors, DataFileNotFoundSaysHowToPointAtTheDatasets) {
  // An installed copy without the datasets: the message names the folder looked in, that it is
  // absent, and the variable that points the program at the data, with where to get it.
  const char* before = std::getenv("VH_SHARED_DATASETS_DIR");
  const std::string saved = before != nullptr ? before : "";
  const fs::path missing = scratchDir() / "no-datasets-here";
  ::setenv("VH_SHARED_DATASETS_DIR", missing.c_str(), 1);
  expectSceneError(R"({"volume": {"path": "ct/philips-head-phantom-bone"}})",
                   "'ct/philips-head-phantom-bone' not found", missing.string() + " (absent)",
                   "VH_SHARED_DATASETS_DIR", "Help > About");
  EXPECT_NE(sharedDatasetsNote().find(missing.string() + " (absent)"), std::string::npos) << sharedDatasetsNote();
  if (before != nullptr) ::setenv("VH_SHARED_DATASETS_DIR", saved.c_str(), 1);
  else ::unsetenv("VH_SHARED_DATASETS_DIR");
}

TEST(SceneFiles, TheChosenDataFolderResolvesDatasetNamesUnlessTheEnvironmentNamesAnother) {
  // A folder holding one dataset under its shared name (a NRRD the test writes): found through
  // the chosen folder when VH_SHARED_DATASETS_DIR is unset, not when the variable names another.
  const char* before = std::getenv("VH_SHARED_DATASETS_DIR");
  const std::string saved = before != nullptr ? before : "";
  const fs::path dir = scratchDir();  // made afresh on each call: once
  const fs::path chosen = dir / "chosen-datasets";
  fs::create_directories(chosen / "nrrd");
  {
    std::ofstream f(chosen / "nrrd" / "tiny.nrrd", std::ios::binary);
    f << "NRRD0004\ntype: uint8\ndimension: 3\nsizes: 4 4 4\nspacings: 1 1 1\nencoding: raw\n\n"
      << std::string(64, '\x10');
  }
  ::unsetenv("VH_SHARED_DATASETS_DIR");
  setPreferredSharedDatasetsDir(chosen);
  EXPECT_EQ(sharedDatasetsDir(), chosen);
  EXPECT_FALSE(sharedDatasetsDirFromEnvironment());
  const SceneSpec spec =
      loadSceneFile(writeText(dir / "chosen.json", R"({"volume": {"path": "nrrd/tiny.nrrd"}})"));
  EXPECT_EQ(fs::path(spec.volume.path), chosen / "nrrd" / "tiny.nrrd");
  const fs::path other = dir / "env-datasets";
  ::setenv("VH_SHARED_DATASETS_DIR", other.c_str(), 1);
  EXPECT_EQ(sharedDatasetsDir(), other) << "the environment wins over the chosen folder";
  EXPECT_TRUE(sharedDatasetsDirFromEnvironment());
  VH_EXPECT_THROW_WITH(loadSceneFile(dir / "chosen.json"), std::runtime_error, "not found",
                       other.string() + " (absent)", "File > Data Folder");
  setPreferredSharedDatasetsDir({});
  if (before != nullptr) ::setenv("VH_SHARED_DATASETS_DIR", saved.c_str(), 1);
  else ::unsetenv("VH_SHARED_DATASETS_DIR");
}

TEST(SceneFileErrors, PackedDatasetGetsAHint) {
  const fs::path archive = test::sharedDatasets() / "classic" / "ct-bunny.tar.zst";
  if (!fs::exists(archive)) GTEST_SKIP() << "shared dataset absent: " << archive;
  const fs::path dir = scratchDir();
  const fs::path file = writeText(dir / "bad.json", R"({"volume": {"path": "classic/ct-bunny/no-such.nhdr"}})");
  VH_EXPECT_THROW_WITH(loadSceneFile(file), std::runtime_error, "not found", "ct-bunny.tar.zst", "unpack");
}

TEST(SceneLoading, UnknownBuiltinsNameTheScene) {
  SceneSpec spec;
  spec.source = "my-scene.json";
  spec.volume.path = "builtin:torus";
  VH_EXPECT_THROW_WITH(loadScene(spec), std::runtime_error, "my-scene.json", "torus");
  spec.volume.path = "builtin:plane";
  spec.tool.mesh = "builtin:hammer";
  VH_EXPECT_THROW_WITH(loadScene(spec), std::runtime_error, "my-scene.json", "hammer");
}

TEST(SceneLoading, BuiltinBlockWithHoleScene) {
  const SceneSpec spec = builtinBlockWithHoleScene();
  EXPECT_EQ(spec.volume.path, "builtin:block-with-hole");
  EXPECT_EQ(spec.tool.mesh, "builtin:peg");
  ASSERT_TRUE(spec.device.has_value());
  EXPECT_EQ(spec.device->kind, "simulated");
  const LoadedScene scene = loadScene(spec);
  EXPECT_EQ(scene.volume.field->geometry().dims, (std::array<int, 3>{256, 256, 256}));
  ASSERT_NE(scene.volume.image, nullptr);
  int image_dims[3];
  scene.volume.image->GetDimensions(image_dims);
  EXPECT_EQ(image_dims[0], 256);
  EXPECT_DOUBLE_EQ(scene.isovalue, datasets::kBlockIsovalue);
  EXPECT_EQ(scene.initial_points_inside, 0);
  EXPECT_TRUE(scene.volume.info.notices.empty())
      << "the program's own scene opens without a note on its own tool: " << scene.volume.info.notices.front();
  EXPECT_LE(feltGap(*scene.tool, spec.tool.edge_test).max_gap_m, haptics::kShellGapWarning_m);
  // The peg hangs over the hole: lowering it along -z, it passes through without touching.
  EXPECT_FALSE(firstContactDistance(*scene.volume.field, scene.tool->point_shell, scene.X_WT_initial,
                                    -Eigen::Vector3d::UnitZ(), 0.03, scene.isovalue)
                   .has_value());
  const auto device = scene.makeDevice();
  ASSERT_NE(device, nullptr);
  EXPECT_NE(dynamic_cast<SimulatedDevice*>(device.get()), nullptr);
  const auto renderer = scene.makeRenderer();
  EXPECT_TRUE(renderer->proxyPose().p_AB_m.isApprox(scene.X_WT_initial.p_AB_m));
}

TEST(SceneLoading, SceneForVolume) {
  const SceneSpec spec = sceneForVolume("some/volume.nrrd");
  EXPECT_TRUE(fs::path(spec.volume.path).is_absolute());
  EXPECT_EQ(spec.tool.mesh, "builtin:probe");
  EXPECT_FALSE(spec.volume.isovalue_set);
  ASSERT_TRUE(spec.device.has_value());
  EXPECT_EQ(spec.device->kind, "simulated");
}

TEST(SceneLoading, PointShellFromSpacingOrCount) {
  SceneSpec spec;
  spec.volume.path = "builtin:sphere";
  spec.tool.mesh = "builtin:sphere";
  spec.tool.point_count = 250;
  EXPECT_EQ(loadScene(spec).tool->point_shell.size(), 250u);
  spec.tool.point_count = 0;
  spec.tool.point_spacing_m = 0.002;
  const LoadedScene scene = loadScene(spec);
  EXPECT_NEAR(scene.tool->point_shell.meanNearestNeighbourSpacing_m(), 0.002, 0.001);
  // Scaled built-in tool: a 5 mm sphere scaled by 2 is 10 mm in radius.
  spec.tool.scale_to_m = 2.0;
  const LoadedScene big = loadScene(spec);
  EXPECT_NEAR(big.tool->point_shell.points_T_m().front().norm(), 0.010, 5e-4);
}

TEST(SceneLoading, DefaultPoseRestsAboveTheSurfaceAtAClearance) {
  SceneSpec spec;
  spec.volume.path = "builtin:sphere";  // radius 20 mm in a 64 mm cube of 1 mm voxels
  spec.tool.mesh = "builtin:probe";     // 2 mm ball tip at the origin, shaft along +z
  const LoadedScene scene = loadScene(spec);
  const auto& field = *scene.volume.field;
  EXPECT_EQ(scene.initial_points_inside, 0);
  EXPECT_NEAR(scene.isovalue, 0.0, 1e-12);
  // Over the centre in x, y; the clearance to the surface is 10% of 64 mm = 6.4 mm.
  EXPECT_NEAR(scene.X_WT_initial.p_AB_m.x(), 0.0, 1e-3);
  EXPECT_NEAR(scene.X_WT_initial.p_AB_m.y(), 0.0, 1e-3);
  const auto gap = firstContactDistance(field, scene.tool->point_shell, scene.X_WT_initial, -Eigen::Vector3d::UnitZ(),
                                        0.05, scene.isovalue);
  ASSERT_TRUE(gap.has_value());
  EXPECT_NEAR(*gap, 0.0064, field.featureSize_m());
}

TEST(SceneResources, ShippedScenesParse) {
  const fs::path dir = test::sourceDir() / "resources" / "scenes";
  const SceneSpec block = loadSceneFile(dir / "block-peg.json");
  EXPECT_EQ(block.volume.path, "builtin:block-with-hole");
  for (const char* name : {"phantom-drill.json", "bunny-probe.json"}) {
    try {
      const SceneSpec spec = loadSceneFile(dir / name);
      EXPECT_TRUE(spec.volume.isovalue_set) << name;
      EXPECT_TRUE(fs::exists(spec.volume.path)) << name;
    } catch (const std::runtime_error& e) {
      // Only a missing shared dataset is acceptable here.
      EXPECT_NE(std::string(e.what()).find("not found"), std::string::npos) << e.what();
    }
  }
}

}  // namespace
}  // namespace vh::runtime

namespace vh::runtime {
namespace {

TEST(SceneLoading, CtWithoutAnIsovalueOpensAtBone) {
  const fs::path head = test::sharedDatasets() / "ct" / "ct-head-small";
  if (!fs::exists(head)) GTEST_SKIP() << "shared dataset absent: " << head;
  const LoadedScene scene = loadScene(sceneForVolume(head));
  ASSERT_EQ(scene.volume.info.value_unit, "HU");
  EXPECT_DOUBLE_EQ(scene.isovalue, 400.0);
  // An explicit isovalue wins.
  SceneSpec spec = sceneForVolume(head);
  spec.volume.isovalue = -300.0;
  spec.volume.isovalue_set = true;
  EXPECT_DOUBLE_EQ(loadScene(spec).isovalue, -300.0);
}

}  // namespace
}  // namespace vh::runtime

namespace vh::runtime {
namespace {

/// Sets an environment variable for one scope and restores it after.
class ScopedEnv {
 public:
  ScopedEnv(const char* name, const char* value) : name_(name) {
    if (const char* old = std::getenv(name)) old_ = old;
    ::setenv(name, value, 1);
  }
  ~ScopedEnv() {
    if (old_) {
      ::setenv(name_, old_->c_str(), 1);
    } else {
      ::unsetenv(name_);
    }
  }
  ScopedEnv(const ScopedEnv&) = delete;
  ScopedEnv& operator=(const ScopedEnv&) = delete;

 private:
  const char* name_;
  std::optional<std::string> old_;
};

TEST(SolverLanes, TheMachineLessTwoCoresAtMostEightAndTheEnvironmentOverridesValidCounts) {
  // Oracle: the rule as documented, from std::thread::hardware_concurrency() itself.
  const int machine = std::clamp(static_cast<int>(std::thread::hardware_concurrency()) - 2, 1, 8);
  {
    ScopedEnv unset("VH_SOLVER_LANES", "");
    ::unsetenv("VH_SOLVER_LANES");
    EXPECT_EQ(defaultSolverLanes(), machine);
  }
  {
    ScopedEnv three("VH_SOLVER_LANES", "3");
    EXPECT_EQ(defaultSolverLanes(), 3);
  }
  {
    ScopedEnv most("VH_SOLVER_LANES", "64");
    EXPECT_EQ(defaultSolverLanes(), 64);
  }
  // Anything that is not a whole count in 1..64 is ignored (the machine's rule applies).
  for (const char* bad : {"0", "-2", "65", "abc", "3x", "", "2.5"}) {
    ScopedEnv env("VH_SOLVER_LANES", bad);
    EXPECT_EQ(defaultSolverLanes(), machine) << "VH_SOLVER_LANES=\"" << bad << "\"";
  }
}

TEST(SolverLanes, AToolUnderEightHundredPointsRunsOnOneLaneUnlessTheEnvironmentSaysOtherwise) {
  // Oracle: the documented rule, on both sides of the threshold, on an 8-lane machine (whatever
  // this one has) and from this machine's own count.
  for (const std::size_t points : {std::size_t{0}, std::size_t{518}, kPointsForSeveralLanes - 1})
    EXPECT_EQ(solverLanesFor(points, 8), 1) << points << " points";
  for (const std::size_t points : {kPointsForSeveralLanes, std::size_t{1307}, std::size_t{20000}})
    EXPECT_EQ(solverLanesFor(points, 8), 8) << points << " points";
  EXPECT_EQ(solverLanesFor(20000, 0), 1) << "never fewer than one lane";
  const int machine = std::clamp(static_cast<int>(std::thread::hardware_concurrency()) - 2, 1, 8);
  {
    ScopedEnv unset("VH_SOLVER_LANES", "");
    ::unsetenv("VH_SOLVER_LANES");
    for (const std::size_t points : {std::size_t{0}, std::size_t{1}, std::size_t{518}, kPointsForSeveralLanes - 1})
      EXPECT_EQ(solverLanesFor(points), 1) << points << " points";
    for (const std::size_t points : {kPointsForSeveralLanes, std::size_t{2126}, std::size_t{20000}})
      EXPECT_EQ(solverLanesFor(points), machine) << points << " points";
  }
  {
    ScopedEnv three("VH_SOLVER_LANES", "3");
    EXPECT_EQ(solverLanesFor(518), 3) << "the environment applies to every tool";
    EXPECT_EQ(solverLanesFor(20000), 3);
  }
  {
    ScopedEnv bad("VH_SOLVER_LANES", "0");
    EXPECT_EQ(solverLanesFor(518), 1) << "an invalid count is ignored";
    EXPECT_EQ(solverLanesFor(20000), machine);
  }
}

TEST(SolverLanes, TheDeadlineIsNinetyPercentOfTheServoPeriod) {
  EXPECT_DOUBLE_EQ(solverDeadline_us(1000.0), 900.0);
  EXPECT_DOUBLE_EQ(solverDeadline_us(4000.0), 225.0);
  for (const double bad : {0.0, -1000.0, std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::infinity()}) {
    EXPECT_EQ(solverDeadline_us(bad), 0.0) << bad;  // no deadline rather than a wrong one
  }
}

}  // namespace
}  // namespace vh::runtime
