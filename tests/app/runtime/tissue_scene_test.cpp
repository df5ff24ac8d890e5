// Soft tissue in a scene: the "tissue" section, a headless run that presses a ball into the
// built-in gel (it yields: the force is the tissue's in series with the coupling, far below the
// coupling's alone on the same scan felt rigid; the crossing check against the deformed field
// finds nothing), and a record / replay round trip that deforms it tick for tick as the run did.
#include "vh/runtime/tissue_scene.h"

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <optional>

#include <gtest/gtest.h>

#include "runtime_test_support.h"
#include "vh/datasets/synthetic.h"
#include "vh/runtime/recording.h"
#include "vh/runtime/replay.h"
#include "vh/runtime/runner.h"
#include "vh/runtime/scene.h"
#include "vh/runtime/servo_factory.h"
#include "vh/runtime/session.h"
#include "vh/runtime/segments.h"
#include "vh/runtime/session_metadata.h"
#include "vh/tissue/deformable_scene.h"
#include "vh/tissue/hex_lattice.h"
#include "vh/io/segmentation.h"

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

// A label map on the gel's grid (`geo`): "slab", the block's voxels with x_lo < x < x_hi [m]
// above the bone plate and up to 1 mm over the gel's top (its blurred edge). `voxels`: how many
// voxels it labels.
io::LoadedSegmentation slabSegmentation(const haptics::VolumeGeometry& geo, double x_lo, double x_hi, int* voxels) {
  std::vector<float> labels(geo.voxelCount(), 0.0f);
  int count = 0;
  for (int k = 0; k < geo.dims[2]; ++k)
    for (int j = 0; j < geo.dims[1]; ++j)
      for (int i = 0; i < geo.dims[0]; ++i) {
        const Eigen::Vector3d p = geo.pointOf_W(Eigen::Vector3d(i, j, k));
        if (p.x() > x_lo && p.x() < x_hi && p.z() > datasets::kGelPlate_m + 1e-3 &&
            p.z() < datasets::kGelTop_m + 1e-3) {
          labels[geo.indexOf(i, j, k)] = 1.0f;
          ++count;
        }
      }
  if (voxels != nullptr) *voxels = count;
  const auto label_map = std::make_shared<const haptics::ScalarVolume>(haptics::ScalarVolume::FromVoxels(geo, labels));
  return io::segmentationFromLabels(label_map, "slab.nrrd", {{1, "slab"}});
}

// A segment of a segmentation as the tissue: the left half of the gel block labelled "slab" (on
// the scan's grid), the right half left rigid. Oracles: the region is exactly the labelled voxels
// (counted from the label's box, not from the rule under test); a press on the left yields,
// the same press on the right is felt as the rigid scan; a segment given before a band takes its
// voxels with its own material (the stiffer "gel inclusion" over the slab, "gel" elsewhere), and
// it feels stiffer than the same slab of "gel". Errors name what is missing.
TEST(TissueScene, ASegmentIsTissueOfItsOwnMaterialAndTheRestStaysRigid) {
  const LoadedScene scene = loadScene(parseScene(kGelScene, "gel.json", "."));
  const haptics::ScalarVolume& field = *scene.volume.field;
  const haptics::VolumeGeometry& geo = field.geometry();
  int slab_voxels = 0;
  const io::LoadedSegmentation seg = slabSegmentation(geo, -1.0, 0.0, &slab_voxels);  // the left half
  auto segments = std::make_shared<const SegmentSet>(seg, std::vector<int>{}, std::vector<int>{0}, std::vector<int>{}, 1.0);

  TissueSpec only_slab;
  only_slab.segments = {{"SLAB", "gel"}};  // names are matched ignoring case
  only_slab.rigid_above = 300.0;
  const auto slab_scene = makeTissueScene(only_slab, scene.volume.field, 50.0, false, &seg);
  EXPECT_EQ(slab_scene->region().tissue_voxels, slab_voxels);

  // The press: 1.5 mm below the rest surface over 1,000 ticks, then held 300 ticks, on `spec`'s
  // tissue (none: the rigid scan, as makeServoRenderer() builds it): the force felt [N];
  // `k_tissue`: the tissue's stiffness there, its push over its indentation [N/m].
  const auto press = [&](const std::optional<TissueSpec>& spec, double x_m, double* k_tissue = nullptr) {
    LiveValues live = LiveValues::initial(scene);
    live.tissue = spec;
    live.segments = segments;
    const double R = 0.005, z0 = datasets::kGelTop_m + R + 0.5e-3, z1 = datasets::kGelTop_m + R - 1.5e-3;
    haptics::Pose X = haptics::Pose::FromTranslation(Eigen::Vector3d(x_m, 0.0, z0));
    DrillingRenderer r = makeServoRenderer(live, {}, X, 1000.0);
    EXPECT_EQ(r.tissue != nullptr, spec.has_value());
    double force_N = 0.0;
    for (int t = 0; t <= 1300; ++t) {
      X.p_AB_m.z() = z0 + (z1 - z0) * std::min(1.0, t / 1000.0);
      const tissue::DeformableStep step = r.tissue ? r.tissue->step(X, *r.renderer) : tissue::DeformableStep{};
      force_N = r.renderer->tick(X, 50.0).force_W_N.z();
      if (k_tissue != nullptr && step.indentation_m > 0.0)
        *k_tissue = step.contact.force_on_device_N.norm() / step.indentation_m;
    }
    return force_N;
  };
  const double left = press(only_slab, -0.006), right = press(only_slab, 0.006);
  const double rigid_left = press(std::nullopt, -0.006), rigid_right = press(std::nullopt, 0.006);
  // The slab in gel (a band), of its own material: "gel", then the 4x stiffer "gel inclusion".
  TissueSpec soft_slab, stiff_slab;
  soft_slab.segments = {{"slab", "gel"}};
  stiff_slab.segments = {{"slab", "gel inclusion"}};
  soft_slab.bands = stiff_slab.bands = {{10.0, 150.0, "gel"}};
  soft_slab.rigid_above = stiff_slab.rigid_above = 300.0;
  double soft_k = 0.0, stiff_k = 0.0;
  const double soft_F = press(soft_slab, -0.006, &soft_k), stiff_F = press(stiff_slab, -0.006, &stiff_k);
  std::printf("1.5 mm press on the slab of gel %.4f N (rigid %.4f N), beside it %.4f N (rigid %.4f N); the slab in "
              "gel: of gel %.4f N (tissue %.0f N/m), of gel inclusion %.4f N (tissue %.0f N/m)\n",
              left, rigid_left, right, rigid_right, soft_F, soft_k, stiff_F, stiff_k);
  EXPECT_GT(left, 0.01) << "the slab was not touched";
  EXPECT_LT(left, 0.6 * rigid_left) << "the slab did not yield";
  EXPECT_NEAR(right, rigid_right, 0.02 * rigid_right) << "beside the slab is not tissue: felt as the rigid scan";
  EXPECT_GT(stiff_F, soft_F);
  EXPECT_GT(stiff_k, 2.0 * soft_k) << "the segment's stiffer material (4x the gel's modulus) was not used";

  // The segment's material over the slab, the band's elsewhere (materials: segments first).
  const auto stiff_scene = makeTissueScene(stiff_slab, scene.volume.field, 50.0, false, &seg);
  const tissue::HexLattice& L = stiff_scene->region().model.lattice();
  const double h = L.geometry().spacing_m;
  int inside_slab = 0, wrong_inside = 0, outside_slab = 0, wrong_outside = 0;
  for (int e = 0; e < L.elementCount(); ++e) {
    // The cell's centre in W (the lattice is in G; the gel's grid is axis-aligned).
    const Eigen::Vector3d c_G = L.geometry().origin_W_m + h * (L.elementCell(e).cast<double>() + Eigen::Vector3d::Constant(0.5));
    const Eigen::Vector3d c_W = geo.origin_W_m + c_G;
    if (c_W.z() < datasets::kGelPlate_m + 1e-3 + h || c_W.z() > datasets::kGelTop_m - h) continue;  // mixed cells
    if (c_W.x() < -h) {
      ++inside_slab;
      wrong_inside += L.elementMaterial(e) != 0;
    } else if (c_W.x() > h && (c_W - datasets::kGelInclusionCentre_m).norm() > datasets::kGelInclusionRadius_m + h) {
      ++outside_slab;
      wrong_outside += L.elementMaterial(e) != 1;
    }
  }
  EXPECT_GT(inside_slab, 20);
  EXPECT_GT(outside_slab, 20);
  EXPECT_EQ(wrong_inside, 0);
  EXPECT_EQ(wrong_outside, 0);

  // Errors: segments without a segmentation, a segment it does not hold, a scene file's segments
  // without its "segmentation".
  VH_EXPECT_THROW_WITH(makeTissueScene(only_slab, scene.volume.field, 50.0, false, nullptr), std::invalid_argument,
                       "segmentation");
  TissueSpec unknown = only_slab;
  unknown.segments[0].segment = "liver";
  VH_EXPECT_THROW_WITH(makeTissueScene(unknown, scene.volume.field, 50.0, false, &seg), std::invalid_argument, "liver",
                       "slab");
  VH_EXPECT_THROW_WITH(
      parseScene(R"({"volume": {"path": "builtin:sphere"}, "tissue": {"segments": [{"segment": "a", "material": "gel"}]}})",
                 "s.json", "."),
      std::runtime_error, "s.json", "segmentation");
  VH_EXPECT_THROW_WITH(
      parseScene(R"({"volume": {"path": "builtin:sphere"}, "tissue": {"cell_size_m": 0.002}})", "s.json", "."),
      std::runtime_error, "bands", "segments");
}

// A session whose tissue is a segment: new segments rebuild the tissue on them (the haptic
// thread's region is the new slab's voxels, counted from its box), and segments that cannot
// carry it (closed) are refused with the old ones kept and the threads running on them.
TEST(TissueScene, TheSessionRebuildsTissueOfSegmentsOnNewSegmentsAndKeepsTheOldWhenItCannot) {
  LoadedScene scene = loadScene(parseScene(kGelScene, "gel.json", "."));
  const haptics::VolumeGeometry geo = scene.volume.field->geometry();
  int left_voxels = 0, right_voxels = 0;
  const io::LoadedSegmentation left = slabSegmentation(geo, -1.0, 0.0, &left_voxels);
  const io::LoadedSegmentation right = slabSegmentation(geo, 0.003, 1.0, &right_voxels);
  ASSERT_NE(left_voxels, right_voxels) << "the halves must differ for the check to tell them apart";
  SegmentationSpec seg_spec;
  seg_spec.path = "slab.nrrd";
  scene.spec.segmentation = seg_spec;
  scene.spec.tissue->bands.clear();
  scene.spec.tissue->segments = {{"slab", "gel"}};
  scene.segments = std::make_shared<const SegmentSet>(left, std::vector<int>{}, std::vector<int>{0}, std::vector<int>{}, 1.0);
  auto device = std::make_shared<SimulatedDevice>(scene.X_WT_initial);
  Session session;
  session.setScene(std::move(scene), device);
  ASSERT_NE(session.hapticThread(), nullptr);
  ASSERT_NE(session.hapticThread()->tissue(), nullptr);
  EXPECT_EQ(session.hapticThread()->tissue()->region().tissue_voxels, left_voxels);

  session.setSegments(std::make_shared<const SegmentSet>(right, std::vector<int>{}, std::vector<int>{0},
                                                         std::vector<int>{}, 1.0),
                      seg_spec);
  ASSERT_NE(session.hapticThread(), nullptr);
  ASSERT_NE(session.hapticThread()->tissue(), nullptr);
  EXPECT_EQ(session.hapticThread()->tissue()->region().tissue_voxels, right_voxels) << "the tissue was not rebuilt";

  const SegmentSet* kept = session.live().segments.get();
  VH_EXPECT_THROW_WITH(session.setSegments(nullptr, std::nullopt), std::invalid_argument, "segmentation");
  EXPECT_EQ(session.live().segments.get(), kept);
  EXPECT_TRUE(session.live().segmentation.has_value());
  ASSERT_NE(session.hapticThread(), nullptr);
  ASSERT_NE(session.hapticThread()->tissue(), nullptr);
  EXPECT_EQ(session.hapticThread()->tissue()->region().tissue_voxels, right_voxels);
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
