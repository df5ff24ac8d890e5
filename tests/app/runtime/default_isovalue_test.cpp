// The opening isovalue: bone for CT in HU, the triangle threshold for MR and PET, the middle of the
// range otherwise. Oracles: volumes of two value populations with a known gap (any threshold
// that separates them is right) and the analytic voxel count of a ball.
#include <cmath>
#include <filesystem>
#include <iostream>
#include <memory>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "vh/runtime/default_isovalue.h"
#include "vh/runtime/scene.h"

namespace vh::runtime {
namespace {

constexpr int kN = 48;
constexpr double kBallRadiusVoxels = 14.0;

bool inBall(int i, int j, int k) {
  const double c = 0.5 * (kN - 1);
  return std::hypot(i - c, j - c, k - c) <= kBallRadiusVoxels;
}

/// A "head" ball of values in [tissue_lo, tissue_hi] in a background of [0, noise] (uniform
/// random, fixed seed), as an MR or PET scan looks: most voxels background, no fixed scale.
std::shared_ptr<const haptics::ScalarVolume> ballInNoise(double noise, double tissue_lo, double tissue_hi) {
  haptics::VolumeGeometry g;
  g.dims = {kN, kN, kN};
  std::vector<float> v(g.voxelCount());
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> background(0.0, noise), tissue(tissue_lo, tissue_hi);
  std::size_t n = 0;
  for (int k = 0; k < kN; ++k)
    for (int j = 0; j < kN; ++j)
      for (int i = 0; i < kN; ++i) v[n++] = static_cast<float>(inBall(i, j, k) ? tissue(rng) : background(rng));
  return std::make_shared<const haptics::ScalarVolume>(haptics::ScalarVolume::FromVoxels(g, v));
}

std::size_t ballVoxels() {
  std::size_t n = 0;
  for (int k = 0; k < kN; ++k)
    for (int j = 0; j < kN; ++j)
      for (int i = 0; i < kN; ++i) n += inBall(i, j, k) ? 1 : 0;
  return n;
}

io::LoadedVolume volumeOf(std::shared_ptr<const haptics::ScalarVolume> field, const std::string& modality,
                          const std::string& unit) {
  io::LoadedVolume v;
  v.field = std::move(field);
  v.info.modality = modality;
  v.info.value_unit = unit;
  return v;
}

TEST(DefaultIsovalue, TriangleSplitsTheBackgroundFromTheBody) {
  // Background [0, 40], tissue [150, 250]: every threshold in the gap separates them exactly.
  const auto field = ballInNoise(40.0, 150.0, 250.0);
  const double t = triangleThreshold(*field);
  EXPECT_GT(t, 40.0);
  EXPECT_LE(t, 150.0 + (field->maxValue() - field->minValue()) / 256.0);
  // A small gap and a tissue population far smaller and broader than the background still split.
  const auto narrow = ballInNoise(100.0, 110.0, 1000.0);
  const double u = triangleThreshold(*narrow);
  EXPECT_GT(u, 100.0 - (narrow->maxValue() - narrow->minValue()) / 256.0);
  EXPECT_LT(u, 1000.0);
}

TEST(DefaultIsovalue, MrAndPetOpenAtTheBodyWhereTheMiddleOfTheRangeMissesIt) {
  // Tissue [150, 1200]: the middle of the range (about 600) leaves most of the ball out, as an
  // MPRAGE opened at its mid-range shows a speckle cloud; the triangle level keeps all of it.
  const auto field = ballInNoise(40.0, 150.0, 1200.0);
  std::size_t above_mid = 0, above_default = 0;
  const double mid = 0.5 * (field->minValue() + field->maxValue());
  for (const std::string modality : {"MR", "PT"}) {
    const double s = defaultIsovalue(volumeOf(field, modality, modality == "PT" ? "SUVbw" : ""));
    above_mid = above_default = 0;
    for (int k = 0; k < kN; ++k)
      for (int j = 0; j < kN; ++j)
        for (int i = 0; i < kN; ++i) {
          above_default += field->voxel(i, j, k) > s ? 1 : 0;
          above_mid += field->voxel(i, j, k) > mid ? 1 : 0;
        }
    EXPECT_EQ(above_default, ballVoxels()) << modality << " at " << s;
  }
  EXPECT_LT(above_mid, ballVoxels() * 7 / 10) << "the middle of the range should have missed part of the ball";
}

TEST(DefaultIsovalue, CtOpensAtBoneAndUnknownScansAtTheMiddle) {
  const auto field = ballInNoise(40.0, 150.0, 1200.0);
  EXPECT_EQ(defaultIsovalue(volumeOf(field, "CT", "HU")), 400.0);
  EXPECT_DOUBLE_EQ(defaultIsovalue(volumeOf(field, "", "")), 0.5 * (field->minValue() + field->maxValue()));
  // A CT whose values never reach 400 HU: no bone to show, the middle of its range.
  const auto soft = ballInNoise(40.0, 150.0, 300.0);
  EXPECT_DOUBLE_EQ(defaultIsovalue(volumeOf(soft, "CT", "HU")), 0.5 * (soft->minValue() + soft->maxValue()));
}

}  // namespace
}  // namespace vh::runtime

namespace vh::runtime {
namespace {

/// The shared MR head (T1, NRRD): the body is the part above the triangle level; the middle of
/// the range keeps a small part of it (the bright fat and vessels only).
TEST(DefaultIsovalue, TheSharedMrHeadOpensWithItsHeadWhole) {
  const std::filesystem::path path = sharedDatasetsDir() / "nrrd" / "mr-brain" / "brain1_image.nrrd";
  if (!std::filesystem::exists(path)) GTEST_SKIP() << path << " is absent (../shared/datasets)";
  io::LoadedVolume volume = io::loadVolume(path);
  volume.info.modality = "MR";
  const haptics::ScalarVolume& f = *volume.field;
  const double s = defaultIsovalue(volume);
  const double mid = 0.5 * (f.minValue() + f.maxValue());
  const auto& d = f.geometry().dims;
  double above = 0.0, above_mid = 0.0;
  for (int k = 0; k < d[2]; ++k)
    for (int j = 0; j < d[1]; ++j)
      for (int i = 0; i < d[0]; ++i) {
        above += f.voxel(i, j, k) > s ? 1.0 : 0.0;
        above_mid += f.voxel(i, j, k) > mid ? 1.0 : 0.0;
      }
  const double n = static_cast<double>(f.geometry().voxelCount());
  std::cout << "[ mr head ] range " << f.minValue() << ".." << f.maxValue() << ", default " << s << " keeps "
            << 100.0 * above / n << " % of the voxels, the middle " << mid << " keeps " << 100.0 * above_mid / n
            << " %" << std::endl;
  EXPECT_GT(above / n, 0.15);
  EXPECT_LT(above / n, 0.8);
  EXPECT_GT(above, 3.0 * above_mid);
}

}  // namespace
}  // namespace vh::runtime
