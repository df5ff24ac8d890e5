// Drilling in a scene: the "drill" section, the hardness classes, a headless run that drills
// into the built-in sphere (never through what is not removed: crossings 0), and a record /
// replay round trip that rebuilds the drilled field bit for bit (SHA-256 of its voxels).
#include "vh/runtime/drilling.h"

#include <algorithm>
#include <atomic>
#include <fstream>
#include <iostream>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "runtime_test_support.h"
#include "vh/runtime/haptic_thread.h"
#include "vh/runtime/recording.h"
#include "vh/runtime/replay.h"
#include "vh/runtime/runner.h"
#include "vh/runtime/scene.h"
#include "vh/runtime/session.h"
#include "vh/runtime/session_metadata.h"
#include "vh/runtime/sha256.h"

namespace vh::runtime {
namespace {

// The device at (x, y) [m], lowered from z_from to z_to [m] over the first t_down_s seconds,
// then held until 3 s.
Trajectory pressDown(double x, double y, double z_from, double t_down_s, double z_to) {
  const auto at = [&](double t, double z) {
    TrajectorySample s;
    s.t_s = t;
    s.X_WD.p_AB_m = {x, y, z};
    return s;
  };
  return Trajectory({at(0.0, z_from), at(t_down_s, z_to), at(3.0, z_to)});
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
  const RunReport report = runHeadless(scene, press, options);
  ASSERT_TRUE(report.drill.has_value());
  EXPECT_EQ(report.crossings, 0);
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
TEST(Drilling, TheDevicesFirstButtonSpinsTheBurrWhileHeld) {
  std::uint64_t removed[2] = {0, 0};
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
    EXPECT_TRUE(test::waitUntil([&] { return device->reads() >= 1500; }, std::chrono::milliseconds(20000)));
    session.stopHaptics();
    removed[press] = session.hapticThread()->drill()->removal().removedVoxels();
    EXPECT_FALSE(session.drilling()) << "the button does not switch the drill on for good";
  }
  std::cout << "removed voxels: button not pressed " << removed[0] << ", held " << removed[1] << "\n";
  EXPECT_EQ(removed[0], 0u);
  EXPECT_GT(removed[1], 0u);
}

}  // namespace
}  // namespace vh::runtime
