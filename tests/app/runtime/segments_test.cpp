// Felt segments: a CT in which a nerve and a bone have the same intensity (no
// isovalue separates them) and a segmentation that names them. The hand feels the chosen
// segments' smoothed surface with the renderer's guarantees (no penetration, no crossing), each
// contact is named by its segment, a critical segment gives an event, and the export reports
// time in contact and peak force per segment.
#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <limits>
#include <fstream>
#include <string>

#include <nlohmann/json.hpp>

#include "runtime_test_support.h"
#include "vh/runtime/placement.h"
#include "vh/runtime/recording.h"
#include "vh/runtime/replay.h"
#include "vh/runtime/runner.h"
#include "vh/runtime/scene.h"
#include "vh/runtime/session.h"
#include "vh/runtime/session_metadata.h"
#include "vh/runtime/snapshot_channel.h"
#include "vh/runtime/trajectory.h"

namespace vh::runtime {
namespace {

namespace fs = std::filesystem;

constexpr int kN = 60;           // voxels per axis
constexpr double kH_mm = 0.5;    // voxel size
// The nerve: a ball of radius 6 mm at (15, 15, 19) mm; the bone: a slab z in [4, 9] mm.
bool inNerve(double x, double y, double z) {
  return (x - 15) * (x - 15) + (y - 15) * (y - 15) + (z - 19) * (z - 19) <= 36.0;
}
bool inBone(double x, double y, double z) { return x >= 3 && x <= 27 && y >= 3 && y <= 27 && z >= 4 && z <= 9; }

std::string nrrdHeader(const std::string& type, const std::string& extra) {
  return "NRRD0004\ntype: " + type + "\ndimension: 3\nspace: left-posterior-superior\nsizes: 60 60 60\n"
         "space directions: (0.5,0,0) (0,0.5,0) (0,0,0.5)\nkinds: domain domain domain\nendian: little\n"
         "encoding: raw\nspace origin: (0,0,0)\n" + extra + "\n";
}

/// Writes ct.nrrd (nerve and bone both 300, air 0: one intensity) and case.seg.nrrd.
fs::path writeCase() {
  const fs::path dir = test::scratchDir();
  std::string ct, labels;
  for (int k = 0; k < kN; ++k) {
    for (int j = 0; j < kN; ++j) {
      for (int i = 0; i < kN; ++i) {
        const double x = i * kH_mm, y = j * kH_mm, z = k * kH_mm;
        const int label = inNerve(x, y, z) ? 1 : inBone(x, y, z) ? 2 : 0;
        const std::int16_t hu = label != 0 ? 300 : 0;
        ct.append(reinterpret_cast<const char*>(&hu), 2);
        labels.push_back(static_cast<char>(label));
      }
    }
  }
  std::ofstream(dir / "ct.nrrd", std::ios::binary) << nrrdHeader("short", "") << ct;
  const std::string keys =
      "Segment0_Color:=1 0.9 0.2\nSegment0_ID:=Segment_1\nSegment0_LabelValue:=1\nSegment0_Layer:=0\n"
      "Segment0_Name:=facial nerve\nSegment1_Color:=0.9 0.9 0.8\nSegment1_ID:=Segment_2\n"
      "Segment1_LabelValue:=2\nSegment1_Layer:=0\nSegment1_Name:=bone\n";
  std::ofstream(dir / "case.seg.nrrd", std::ios::binary) << nrrdHeader("unsigned char", keys) << labels;
  return dir;
}

fs::path writeScene(const fs::path& dir, const std::string& felt, const std::string& critical) {
  return test::writeText(dir / ("scene-" + std::to_string(felt.size()) + ".json"),
                         R"({"volume": {"path": "ct.nrrd", "isovalue": 150},
                             "tool": {"mesh": "builtin:sphere", "scale_to_m": 0.4, "point_spacing_m": 0.0006},
                             "coupling": {"linear_N_per_m": 1000},
                             "segmentation": {"path": "case.seg.nrrd", "felt": )" + felt +
                             R"(, "critical": )" + critical + "}}");
}

/// Pushes the tool straight down (-z) from above the nerve's centre onto the felt surface, then
/// `push_depth_m` past it, and slides `slide_m`.
PushSlidePlan pushDownOverTheNerve(const LoadedScene& scene, double push_depth_m = 0.002, double slide_m = 0.002) {
  haptics::Pose start;
  start.p_AB_m = Eigen::Vector3d(0.015, 0.015, 0.029);
  PushSlideOptions push;
  push.start_clearance_m = 0.002;
  push.push_depth_m = push_depth_m;
  push.slide_m = slide_m;
  push.hold_s = 0.05;
  push.approach_time_s = 0.1;
  push.push_time_s = 0.3;
  push.slide_time_s = 0.3;
  push.retract_time_s = 0.1;
  return makePushSlideTrajectory(*scene.hapticField(), scene.tool->point_shell, scene.hapticIsovalue(), start, push);
}

Trajectory pushOverTheNerve(const LoadedScene& scene) { return pushDownOverTheNerve(scene).trajectory; }

/// The same push without its retraction (the last two keys: up, then held there): the device
/// stays pressed on the nerve after the slide (a ScriptedDevice holds its last pose), so the
/// contact a test polls for lasts however late a loaded machine lets it look.
Trajectory pushOverTheNerveAndHold(const LoadedScene& scene) {
  std::vector<TrajectorySample> keys = pushOverTheNerve(scene).samples();
  keys.resize(keys.size() - 2);
  return Trajectory(std::move(keys));
}

const SegmentContact& contactWith(const std::vector<SegmentContact>& contacts, const std::string& name) {
  for (const auto& c : contacts) {
    if (c.name == name) return c;
  }
  throw std::runtime_error("no segment " + name);
}

TEST(FeltSegments, TheNerveIsFeltNamedAndNeverEnteredWhileTheIsovalueOnlySetsThePicture) {
  const fs::path dir = writeCase();
  const LoadedScene scene = loadScene(loadSceneFile(writeScene(dir, R"(["facial nerve"])", R"(["facial nerve"])")));
  ASSERT_TRUE(scene.feltSegments());
  EXPECT_EQ(scene.isovalue, 150.0);  // the scan's picture
  EXPECT_EQ(scene.hapticIsovalue(), 0.5);
  ASSERT_EQ(scene.segments->size(), 2u);
  EXPECT_TRUE(scene.segments->isCritical(0));
  EXPECT_FALSE(scene.segments->isFelt(1));

  RunOptions options;
  options.record = dir / "nerve.vhrec";
  const RunReport r = runHeadless(scene, pushOverTheNerve(scene), options);
  std::cout << "[ segments ] " << r.summary() << "\n";
  // The renderer's guarantees hold on the felt surface.
  EXPECT_EQ(r.crossings, 0);
  EXPECT_LE(r.max_penetration_m, r.epsilon_m);
  EXPECT_EQ(r.nan_ticks, 0u);
  ASSERT_GT(r.ticks_in_contact, 100u);
  // The tool rests on the ball (radius 6 mm about z = 19 mm): its centre 2 mm above the top.
  ASSERT_EQ(r.segment_contacts.size(), 2u);
  const SegmentContact& nerve = contactWith(r.segment_contacts, "facial nerve");
  EXPECT_TRUE(nerve.critical);
  EXPECT_GT(nerve.ticks, r.ticks_in_contact * 9 / 10) << "contacts are named by their segment";
  EXPECT_NEAR(nerve.time_in_contact_s, static_cast<double>(nerve.ticks) / 1000.0, 1e-9);
  EXPECT_EQ(nerve.touches, 1u);
  EXPECT_NEAR(nerve.peak_force_N, r.max_force_N, 1e-12);
  EXPECT_GT(nerve.peak_force_N, 0.5);
  EXPECT_EQ(contactWith(r.segment_contacts, "bone").ticks, 0u);
  EXPECT_NE(r.summary().find("touched facial nerve (CRITICAL)"), std::string::npos);

  // The recording names the touched segment tick by tick, with a critical_contact event, and
  // its export gives the same time and peak force.
  const Recording rec = readRecording(options.record);
  int segment_events = 0, critical_events = 0;
  for (const RecordingEvent& e : rec.events) {
    const auto d = nlohmann::json::parse(e.detail_json);
    if (e.type == "segment") {
      ++segment_events;
      if (segment_events == 1) {
        EXPECT_TRUE(d.at("from").is_null());
        EXPECT_EQ(d.at("to"), "facial nerve");
      }
    }
    if (e.type == "critical_contact") {
      ++critical_events;
      EXPECT_EQ(d.at("segment"), "facial nerve");
      EXPECT_EQ(recordSegment(rec.records.at(e.tick - 1).flags), 0);
    }
  }
  EXPECT_EQ(segment_events, 2);  // on, then off when the tool retracts
  EXPECT_EQ(critical_events, 1);
  const auto exported = segmentContacts(rec);
  ASSERT_EQ(exported.size(), 2u);
  EXPECT_EQ(exported[0].ticks, nerve.ticks);
  EXPECT_DOUBLE_EQ(exported[0].peak_force_N, nerve.peak_force_N);
  writeRecordingJson(rec, dir / "nerve.json");
  std::ifstream json_in(dir / "nerve.json");
  const auto j = nlohmann::json::parse(json_in);
  EXPECT_EQ(j.at("segments").at(0).at("name"), "facial nerve");
  EXPECT_GT(j.at("segments").at(0).at("time_in_contact_s").get<double>(), 0.1);

  // The recording replays bit for bit: its metadata brings the segmentation back.
  const LoadedScene reloaded = loadScene(sceneFromSessionMetadata(rec.metadata_json));
  ASSERT_TRUE(reloaded.feltSegments());
  const ReplayComparison replay = replayRecording(reloaded, rec);
  EXPECT_TRUE(replay.identical) << replay.mismatch;
}

TEST(FeltSegments, WithOnlyTheBoneFeltTheToolPassesTheNerveAndRestsOnTheBone) {
  const fs::path dir = writeCase();
  const LoadedScene scene = loadScene(loadSceneFile(writeScene(dir, R"(["bone"])", "[]")));
  const PushSlidePlan plan = pushDownOverTheNerve(scene, 0.001, 0.0);
  // The first contact is on the slab's top (z = 9 mm): the tool's centre 2 mm above it, where the
  // nerve's voxels are (the nerve is not felt).
  EXPECT_NEAR(plan.X_WD_contact.p_AB_m.z(), 0.011, 0.0006);
  RunOptions options;
  options.lag_reference = false;
  const RunReport r = runHeadless(scene, plan.trajectory, options);
  EXPECT_EQ(r.crossings, 0);
  EXPECT_GT(contactWith(r.segment_contacts, "bone").ticks, 100u);
  EXPECT_EQ(contactWith(r.segment_contacts, "facial nerve").ticks, 0u);
  EXPECT_FALSE(contactWith(r.segment_contacts, "bone").critical);
}

TEST(FeltSegments, TheHapticThreadNamesTheSegmentAndKeepsItsSurfaceWhenTheIsovalueMoves) {
  const fs::path dir = writeCase();
  LoadedScene scene = loadScene(loadSceneFile(writeScene(dir, R"(["facial nerve", "bone"])", R"(["facial nerve"])")));
  const Trajectory trajectory = pushOverTheNerveAndHold(scene);
  Session session;
  // A second consumer (the OpenIGTLink link's channel) and the names it sends.
  auto monitor = std::make_shared<SnapshotChannel>();
  session.setMonitor(monitor);
  SegmentNameTable names;
  names.set(scene.segments.get());
  // A scripted device running the push; the session's isovalue moves the picture only.
  session.setScene(std::move(scene), std::make_shared<ScriptedDevice>(trajectory, 1e-3, "push"));
  session.startHaptics();
  session.setIsovalue(250.0);
  HapticSnapshot snap;
  const bool touched = test::waitUntil(
      [&] {
        return session.latestSnapshot(snap) && snap.contacts > 0 && snap.segment == 0;
      },
      std::chrono::milliseconds(60000));
  EXPECT_TRUE(touched) << "contacts " << snap.contacts << ", segment " << snap.segment;
  EXPECT_EQ(session.live().isovalue, 250.0);
  EXPECT_EQ(snap.isovalue, 0.5) << "the hand keeps the segments' surface";
  HapticSnapshot linked;
  EXPECT_TRUE(test::waitUntil([&] { return monitor->read(linked) && linked.contacts > 0 && linked.segment == 0; }));
  EXPECT_EQ(names.name(linked.segment), "facial nerve");
  EXPECT_EQ(names.name(-1), "");
  EXPECT_EQ(names.name(7), "");
  session.stopHaptics();
}

TEST(FeltSegments, AMonitorConnectedWhileSegmentsAreFeltKeepsTheSegmentsSurfaceInTheHand) {
  const fs::path dir = writeCase();
  LoadedScene scene = loadScene(loadSceneFile(writeScene(dir, R"(["facial nerve", "bone"])", R"(["facial nerve"])")));
  ASSERT_TRUE(scene.feltSegments());
  auto device = std::make_shared<SimulatedDevice>(scene.X_WT_initial);
  Session session;
  session.setScene(std::move(scene), device);
  session.startHaptics();
  session.setIsovalue(250.0);  // the scan's picture; the hand keeps the segments' level
  // The OpenIGTLink link connects: the threads are rebuilt with the monitor channel.
  auto monitor = std::make_shared<SnapshotChannel>();
  session.setMonitor(monitor);
  ASSERT_TRUE(session.hapticsRunning());
  EXPECT_EQ(session.hapticThread()->isovalue(), io::kSegmentSurfaceLevel);
  HapticSnapshot snap;
  ASSERT_TRUE(test::waitUntil([&] { return monitor->read(snap) && snap.solver_tick > 5; }));
  EXPECT_EQ(snap.isovalue, io::kSegmentSurfaceLevel) << "felt: the segments' surface, not the scan at 250";
  EXPECT_EQ(session.isovalue(), 250.0);
  session.stopHaptics();
}

TEST(FeltSegments, UnknownSegmentsAndBadSmoothingAreSceneErrors) {
  const fs::path dir = writeCase();
  VH_EXPECT_THROW_WITH(loadScene(loadSceneFile(writeScene(dir, R"(["tumour"])", "[]"))), std::runtime_error,
                       "segmentation.felt", "no segment \"tumour\"", "\"facial nerve\", \"bone\"");
  const fs::path bad = test::writeText(
      dir / "bad.json", R"({"volume": {"path": "ct.nrrd"}, "segmentation": {"path": "case.seg.nrrd", "smoothing_voxels": -1}})");
  VH_EXPECT_THROW_WITH(loadSceneFile(bad), std::runtime_error, "segmentation.smoothing_voxels");
  const fs::path typo = test::writeText(
      dir / "typo.json", R"({"volume": {"path": "ct.nrrd"}, "segmentation": {"path": "case.seg.nrrd", "feelt": []}})");
  VH_EXPECT_THROW_WITH(loadSceneFile(typo), std::runtime_error, "feelt");
  // Shown only: the scan stays felt.
  const fs::path shown = test::writeText(
      dir / "shown.json", R"({"volume": {"path": "ct.nrrd", "isovalue": 150}, "segmentation": {"path": "case.seg.nrrd"}})");
  const LoadedScene s = loadScene(loadSceneFile(shown));
  EXPECT_FALSE(s.feltSegments());
  EXPECT_EQ(s.hapticField(), s.volume.field);
  EXPECT_EQ(s.segments->shown().size(), 2u);
}

TEST(FeltSegments, TheSessionSwapsTheFeltSegmentsAndStartsTheProxyFreeOfTheNewSurface) {
  const fs::path dir = writeCase();
  // The scan felt first (isovalue 150: nerve and bone alike), segments only shown.
  const fs::path shown = test::writeText(dir / "shown.json", R"({"volume": {"path": "ct.nrrd", "isovalue": 150},
      "tool": {"mesh": "builtin:sphere", "scale_to_m": 0.4, "point_spacing_m": 0.0006},
      "segmentation": {"path": "case.seg.nrrd"}, "device": {"kind": "simulated"}})");
  LoadedScene scene = loadScene(loadSceneFile(shown));
  ASSERT_FALSE(scene.feltSegments());
  const io::LoadedSegmentation seg = scene.segments->segmentation();
  auto device = scene.makeDevice();
  Session session;
  session.setScene(std::move(scene), device);
  SessionChange heard{};
  session.addObserver([&](SessionChange what) { heard = what; });
  // Feel the nerve instead of the scan.
  SegmentationSpec spec = *session.live().segmentation;
  spec.felt = {"facial nerve"};
  session.setSegments(SegmentSet::fromSpec(seg, spec, "test"), spec);
  EXPECT_TRUE(has(heard, SessionChange::kSegments));
  ASSERT_TRUE(session.live().feltSegments());
  EXPECT_EQ(session.live().segmentation->felt, std::vector<std::string>{"facial nerve"});
  ASSERT_NE(session.hapticThread(), nullptr);
  // The proxy starts free of the nerve's surface.
  const haptics::Pose X_WP = session.proxyPose();
  EXPECT_EQ(countPointsInside(*session.live().hapticField(), session.live().tool->point_shell, X_WP, 0.5), 0);
  session.startHaptics();
  HapticSnapshot snap;
  ASSERT_TRUE(test::waitUntil([&] { return session.latestSnapshot(snap) && snap.solver_tick > 5; }));
  EXPECT_EQ(snap.isovalue, 0.5);
  // Back to the scan.
  session.setSegments(nullptr, std::nullopt);
  EXPECT_FALSE(session.live().feltSegments());
  EXPECT_FALSE(session.live().segmentation.has_value());
  session.stopHaptics();
}

}  // namespace
}  // namespace vh::runtime

namespace vh::runtime {
namespace {

/// The simulated device, watched: the smallest force magnitude commanded while armed.
class ForceWatchDevice final : public Device {
 public:
  explicit ForceWatchDevice(const haptics::Pose& X_WD) : inner_(std::make_shared<SimulatedDevice>(X_WD)) {}
  std::string name() const override { return "watched " + inner_->name(); }
  SimulatedDevice* simulatedDevice() noexcept override { return inner_.get(); }
  bool read(DeviceSample& sample) noexcept override { return inner_->read(sample); }
  void command(const Eigen::Vector3d& force_W_N, const Eigen::Vector3d& torque_W_Nm) noexcept override {
    if (armed_.load()) {
      const double f = force_W_N.norm();
      double seen = min_force_N_.load();
      while (f < seen && !min_force_N_.compare_exchange_weak(seen, f)) {
      }
      commands_.fetch_add(1);
    }
    inner_->command(force_W_N, torque_W_Nm);
  }
  void arm() {
    min_force_N_.store(std::numeric_limits<double>::infinity());
    commands_.store(0);
    armed_.store(true);
  }
  void disarm() { armed_.store(false); }
  double minForce_N() const { return min_force_N_.load(); }
  std::uint64_t commands() const { return commands_.load(); }

 private:
  std::shared_ptr<SimulatedDevice> inner_;
  std::atomic<bool> armed_{false};
  std::atomic<double> min_force_N_{std::numeric_limits<double>::infinity()};
  std::atomic<std::uint64_t> commands_{0};
};

// A segmentation opened to be seen, or other segments made critical, leaves the felt surface as
// it is: the running threads take the new segments between two ticks and the hand pressing on
// the surface never loses it (a restart ramps the force to zero and commands zero: the wall
// vanishes for the ramp and the rebuild). Oracle: every force the device was commanded over the
// change, against the pressing force before it; the restart is shown to drop it to 0.
TEST(FeltSegments, SegmentChoicesThatKeepTheFeltSurfaceNeverLetTheForceGo) {
  const fs::path dir = writeCase();
  const fs::path seen = test::writeText(dir / "seen.json", R"({"volume": {"path": "ct.nrrd", "isovalue": 150},
      "tool": {"mesh": "builtin:sphere", "scale_to_m": 0.4, "point_spacing_m": 0.0006},
      "segmentation": {"path": "case.seg.nrrd", "felt": [], "critical": []}})");
  LoadedScene scene = loadScene(loadSceneFile(seen));
  const io::LoadedSegmentation seg = scene.segments->segmentation();
  // Pressed 1 mm into the nerve's top (felt as the scan's surface at 150).
  const PushSlidePlan plan = pushDownOverTheNerve(scene);
  haptics::Pose pressed = plan.X_WD_contact;
  pressed.p_AB_m.z() -= 0.001;
  auto device = std::make_shared<ForceWatchDevice>(pressed);
  Session session;
  session.setScene(std::move(scene), device);
  session.startHaptics();
  HapticSnapshot snap;
  ASSERT_TRUE(test::waitUntil([&] { return session.latestSnapshot(snap) && snap.tick > 200 && snap.contacts > 0; }));
  const double pressing_N = snap.force_W_N.norm();
  ASSERT_GT(pressing_N, 0.5) << "the device is pressed 1 mm into the surface";

  // The nerve made critical: the same felt surface.
  SegmentationSpec spec = *session.live().segmentation;
  spec.critical = {"facial nerve"};
  device->arm();
  session.setSegments(SegmentSet::fromSpec(seg, spec, "test"), spec);
  ASSERT_TRUE(test::waitUntil([&] { return session.latestSnapshot(snap) && snap.critical_segment == 0; }))
      << "the running threads measure the nerve, critical now";
  const std::uint64_t after = device->commands();
  ASSERT_TRUE(test::waitUntil([&] { return device->commands() > after + 50; }));
  device->disarm();
  EXPECT_TRUE(session.hapticsRunning());
  EXPECT_EQ(session.live().segmentation->critical, std::vector<std::string>{"facial nerve"});
  EXPECT_GT(device->minForce_N(), 0.5 * pressing_N) << "the force held over the change (pressing " << pressing_N << " N)";
  EXPECT_LT(snap.critical_distance_m, 0.001) << "pressed on the nerve (within two voxels)";

  // Felt segments instead of the scan: a new surface, the threads rebuilt (the force ramped to 0).
  spec.felt = {"facial nerve"};
  device->arm();
  session.setSegments(SegmentSet::fromSpec(seg, spec, "test"), spec);
  device->disarm();
  EXPECT_EQ(device->minForce_N(), 0.0) << "the restart ramps the force to zero";
  session.stopHaptics();
}

}  // namespace
}  // namespace vh::runtime
