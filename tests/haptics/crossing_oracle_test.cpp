// "Never through": the proxy never carries a shell point through the isosurface, at
// any isovalue, however thin the feature. Evidence from independent oracles only:
//   - the exact segment test against dense sampling of the trilinear field along the segment;
//   - every tick of a scripted run checked by CrossingVerifier (each point's true arc sampled
//     every 1/1000 voxel, isInside() at each sample), in both detection modes;
//   - outcome checks from the geometry (no point of the tool ends beyond the wall's mid-surface).
// A control run with the earlier end-sample test shows that the oracle does catch tunnels.
#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <iostream>
#include <numbers>
#include <random>
#include <string>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include "test_tools.h"
#include "vh/haptics/crossing_verifier.h"
#include "vh/haptics/haptic_renderer.h"

namespace vh::haptics {
namespace {

constexpr double kOracleStepVoxels = 1e-3;  // the 1/1000 voxel

Pose at(double x, double y, double z, const Eigen::Quaterniond& R = Eigen::Quaterniond::Identity()) {
  Pose X;
  X.R_AB = R;
  X.p_AB_m = {x, y, z};
  return X;
}

datasets::GridSpec grid(int n, double spacing_m) {
  datasets::GridSpec g;
  g.dims = {n, n, n};
  g.spacing_m = Eigen::Vector3d::Constant(spacing_m);
  return g;
}

// ---- The exact segment test against dense sampling ------------------------------------------

TEST(SegmentEntry, AgreesWithDenseSamplingOnRandomFields) {
  // Random uint8 and float32 fields (every cell a different cubic along a line), random segments
  // of up to 6 voxels, some leaving the grid, random thresholds. Oracle: 20,000 samples of
  // isInside() along each segment.
  std::mt19937 rng(12);
  std::uniform_real_distribution<double> U(0.0, 1.0);
  datasets::GridSpec g = grid(10, 1e-3);
  g.origin_W_m = Eigen::Vector3d::Zero();
  const VolumeGeometry geometry{g.dims, g.spacing_m, g.origin_W_m, Eigen::Matrix3d::Identity()};
  std::vector<std::uint8_t> raw8(geometry.voxelCount());
  std::vector<float> rawf(geometry.voxelCount());
  for (auto& v : raw8) v = static_cast<std::uint8_t>(rng() % 256);
  for (auto& v : rawf) v = static_cast<float>(U(rng) * 2.0 - 1.0);
  const ScalarVolume volumes[2] = {ScalarVolume::FromVoxels(geometry, raw8),
                                   ScalarVolume::FromVoxels(geometry, rawf, -3.0, 7.0)};  // also a negative scale
  int hits = 0, hits_between_samples = 0;
  for (int trial = 0; trial < 3000; ++trial) {
    const ScalarVolume& vol = volumes[trial % 2];
    const double s = vol.minValue() + U(rng) * (vol.maxValue() - vol.minValue());
    const Eigen::Vector3d a(U(rng) * 10 - 0.5, U(rng) * 10 - 0.5, U(rng) * 10 - 0.5);
    const Eigen::Vector3d b = a + Eigen::Vector3d(U(rng) - 0.5, U(rng) - 0.5, U(rng) - 0.5).normalized() * (6.0 * U(rng));
    auto p_W = [&](double u) { return Eigen::Vector3d((a + u * (b - a)) * 1e-3); };
    const bool starts_inside = vol.isInside(p_W(0.0), s);
    if (starts_inside) continue;  // the leaving rule is tested below
    const SegmentEntry e = vol.firstEntryOnSegment(a, b, s, 1.0, 1e-9);
    constexpr int kSamples = 20000;
    double u_dense = 2.0;
    for (int i = 1; i <= kSamples; ++i) {
      if (vol.isInside(p_W(static_cast<double>(i) / kSamples), s)) {
        u_dense = static_cast<double>(i) / kSamples;
        break;
      }
    }
    if (u_dense <= 1.0) {
      ASSERT_TRUE(e.hit) << "trial " << trial << ": dense sampling enters at u = " << u_dense;
      ASSERT_LE(e.u_outside, u_dense) << "trial " << trial;
    }
    if (e.hit) {
      ++hits;
      if (u_dense > 1.0) ++hits_between_samples;
      // The bracket is real: inside at u_inside (to rounding), and no dense sample before u_outside.
      ASSERT_GT(vol.sample(p_W(e.u_inside)), s - 1e-9 * (1.0 + std::abs(s))) << "trial " << trial;
      ASSERT_LT(e.u_inside - e.u_outside, 1e-8);
      for (int i = 0; i <= kSamples && static_cast<double>(i) / kSamples < e.u_outside - 1e-12; ++i)
        ASSERT_FALSE(vol.isInside(p_W(static_cast<double>(i) / kSamples), s)) << "trial " << trial << " u " << i;
    }
  }
  EXPECT_GT(hits, 300);
  std::cout << hits << " entries found; " << hits_between_samples << " of them between 1/20000 samples\n";
}

TEST(SegmentEntry, ExcessMaxBoundsTheFieldAlongAFreeSegment) {
  // The clearance certificate of the edge test rests on excess_max: over a segment the walk
  // found free, F - s never exceeds it. Random uint8 and float32 fields (a negative scale too),
  // random segments of up to 6 voxels inside the grid, random thresholds. Oracle: the largest
  // of 20,000 trilinear samples along the segment. excess_max may exceed it only by what a
  // skipped cell's largest corner leaves above the trilinear field; where every cell is
  // examined it is the cubic's exact maximum, so on most segments it is within 1e-9.
  std::mt19937 rng(31);
  std::uniform_real_distribution<double> U(0.0, 1.0);
  const datasets::GridSpec g = grid(10, 1e-3);
  const VolumeGeometry geometry{g.dims, g.spacing_m, Eigen::Vector3d::Zero(), Eigen::Matrix3d::Identity()};
  std::vector<std::uint8_t> raw8(geometry.voxelCount());
  std::vector<float> rawf(geometry.voxelCount());
  for (auto& v : raw8) v = static_cast<std::uint8_t>(rng() % 256);
  for (auto& v : rawf) v = static_cast<float>(U(rng) * 2.0 - 1.0);
  const ScalarVolume volumes[2] = {ScalarVolume::FromVoxels(geometry, raw8),
                                   ScalarVolume::FromVoxels(geometry, rawf, -3.0, 7.0)};
  int free_segments = 0, tight = 0;
  for (int trial = 0; trial < 3000; ++trial) {
    const ScalarVolume& vol = volumes[trial % 2];
    // Thresholds in the field's upper part, so that most segments stay free.
    const double s = vol.minValue() + (0.6 + 0.4 * U(rng)) * (vol.maxValue() - vol.minValue());
    const Eigen::Vector3d a(U(rng) * 9, U(rng) * 9, U(rng) * 9);
    Eigen::Vector3d b = a + Eigen::Vector3d(U(rng) - 0.5, U(rng) - 0.5, U(rng) - 0.5).normalized() * (6.0 * U(rng));
    b = b.cwiseMax(Eigen::Vector3d::Zero()).cwiseMin(Eigen::Vector3d::Constant(9.0));
    if (vol.isInside(a * 1e-3, s)) continue;  // a start inside may leave: not free
    const SegmentEntry e = vol.firstEntryOnSegment(a, b, s, 1.0, 0.5);
    if (e.hit) continue;
    ++free_segments;
    double dense_max = -std::numeric_limits<double>::infinity();
    for (int i = 0; i <= 20000; ++i) dense_max = std::max(dense_max, vol.sample((a + i / 20000.0 * (b - a)) * 1e-3) - s);
    ASSERT_GE(e.excess_max, dense_max - 1e-9 * (1.0 + std::abs(s))) << "trial " << trial;
    ASSERT_LE(dense_max, 0.0) << "trial " << trial << ": a free segment with an inside sample";
    tight += e.excess_max - dense_max < 1e-9 * (1.0 + std::abs(s));
  }
  std::cout << free_segments << " free segments; excess_max exact on " << tight << " of them\n";
  EXPECT_GT(free_segments, 500);
  EXPECT_GT(tight, free_segments / 10);  // not merely any upper bound
}

TEST(SegmentEntry, FindsTheOneVoxelPlateAtNinetyNinePercentBetweenItsEnds) {
  const ScalarVolume vol = datasets::makeThinPlateVolume(grid(16, 1e-3));
  // Plate voxels at k = 8; at 99 % of 255 the trilinear plate is |k - 8| < 0.01 voxel thick.
  const Eigen::Vector3d a(3.3, 4.1, 7.3), b(3.9, 4.6, 8.6);
  ASSERT_FALSE(vol.isInside(vol.geometry().origin_W_m + a * 1e-3, 0.99 * 255));
  ASSERT_FALSE(vol.isInside(vol.geometry().origin_W_m + b * 1e-3, 0.99 * 255));
  const SegmentEntry e = vol.firstEntryOnSegment(a, b, 0.99 * 255, 1.0, 1e-12);
  ASSERT_TRUE(e.hit);
  const double k_in = a.z() + e.u_inside * (b.z() - a.z());
  EXPECT_NEAR(k_in, 8.0 - 0.01, 1e-9);
  // At the largest value itself nothing is inside (F > s is strict).
  EXPECT_FALSE(vol.firstEntryOnSegment(a, b, 255.0, 1.0, 1e-12).hit);
  EXPECT_TRUE(vol.firstEntryOnSegment(a, b, 254.999, 1.0, 1e-12).hit);
}

TEST(SegmentEntry, NonFiniteOrHugeSegmentsStopConservatively) {
  const ScalarVolume vol = datasets::makeThinPlateVolume(grid(16, 1e-3));
  const double nan = std::numeric_limits<double>::quiet_NaN();
  for (const Eigen::Vector3d& bad : {Eigen::Vector3d(nan, 1, 1), Eigen::Vector3d(1, std::numeric_limits<double>::infinity(), 1)}) {
    const SegmentEntry e = vol.firstEntryOnSegment({5, 5, 2}, bad, 127.5, 1.0, 1e-9);
    EXPECT_TRUE(e.hit);
    EXPECT_EQ(e.u_outside, 0.0);
  }
  // Far outside the grid on both ends but never crossing its box: no hit; a 1e9-voxel segment
  // through the grid still finds the plate (the box clip keeps the walk to the grid's cells).
  EXPECT_FALSE(vol.firstEntryOnSegment({-1e9, 5, 2}, {1e9, 5, 2}, 127.5, 1.0, 1e-9).hit);
  EXPECT_TRUE(vol.firstEntryOnSegment({5, 5, -1e9}, {5, 5, 1e9}, 127.5, 1.0, 1e-18).hit);
}

TEST(SegmentEntry, AStartInsideMayLeaveButNotGoDeeper) {
  const ScalarVolume vol = datasets::makeThinPlateVolume(grid(16, 1e-3));
  const double s = 127.5;  // plate |k - 8| < 0.5
  // Starting inside just below the plate's middle: moving down leaves; moving up goes deeper.
  EXPECT_FALSE(vol.firstEntryOnSegment({5, 5, 7.9}, {5, 5, 6.0}, s, 1.0, 1e-9).hit);
  const SegmentEntry deeper = vol.firstEntryOnSegment({5, 5, 7.9}, {5, 5, 9.5}, s, 1.0, 1e-9);
  ASSERT_TRUE(deeper.hit);
  EXPECT_EQ(deeper.u_outside, 0.0);
  // Leaving, then entering again elsewhere (a second plate needs a second volume: the same
  // plate re-entered after an exit along a path that turns is covered by the renderer tests).
}

// ---- Scripted runs, every tick checked by the oracle ----------------------------------------

struct RunOutcome {
  int ticks = 0;
  int crossing_ticks = 0;
  int first_crossing_tick = -1;
  std::int64_t oracle_samples = 0;
  int contacts_max = 0;
  Pose X_WP_final;
};

RunOutcome drive(const std::shared_ptr<const ScalarVolume>& vol, const std::shared_ptr<const ToolModel>& tool,
                 DetectionMode mode, SegmentTest test, double s, int ticks, const std::function<Pose(int)>& device,
                 const std::function<void(const Pose& X_WP, int tick)>& each_tick = {}) {
  RendererOptions o;
  o.detection_mode = mode;
  o.segment_test = test;
  // The tool starts clear of the surface: no point is embedded, so every point is held by it.
  for (const auto& p : tool->point_shell.points_T_m())
    EXPECT_FALSE(vol->isInside(device(0) * p, s)) << "the tool starts inside at isovalue " << s;
  HapticRenderer r(vol, tool, o, device(0), s);
  const CrossingVerifier oracle(*vol, tool->point_shell, kOracleStepVoxels);
  RunOutcome out;
  for (int i = 0; i < ticks; ++i) {
    const TickOutput t = r.tick(device(i), s);
    EXPECT_TRUE(t.X_WP.allFinite());
    const CrossingVerifier::Result c = oracle.check(r.lastMotion(), r.lastTimeOfContact(), s);
    out.oracle_samples += c.samples;
    if (c.crossing_points > 0) {
      if (out.crossing_ticks++ == 0) out.first_crossing_tick = i;
    }
    out.contacts_max = std::max(out.contacts_max, t.stats.contacts);
    if (each_tick) each_tick(t.X_WP, i);
    ++out.ticks;
  }
  out.X_WP_final = r.proxyPose();
  return out;
}

class NeverThrough : public ::testing::TestWithParam<DetectionMode> {};
INSTANTIATE_TEST_SUITE_P(Modes, NeverThrough, ::testing::Values(DetectionMode::kPaper, DetectionMode::kAccelerated),
                         [](const ::testing::TestParamInfo<DetectionMode>& p) { return std::string(toString(p.param)); });

const double kIsoFractions[] = {0.05, 0.25, 0.5, 0.75, 0.95, 0.99};
const double kSpeeds_mm[] = {0.01, 0.1, 1.0, 3.0, 6.0, 10.0};

std::shared_ptr<const ToolModel> ballTool() {  // builtin:sphere, a 10 mm ball
  static const auto tool = test::meshTool(datasets::makeBuiltinTool("sphere"), 1e-3);
  return tool;
}

// Drives the ball along `direction` from `start` (its surface `gap` from the wall) at `speed` per
// tick, past the wall by 5 mm; returns the run and checks each tick with the oracle.
RunOutcome pressThrough(const std::shared_ptr<const ScalarVolume>& vol, DetectionMode mode, SegmentTest test,
                        double s, const Eigen::Vector3d& start, const Eigen::Vector3d& direction, double travel_m,
                        double speed_m, const std::function<void(const Pose&, int)>& each_tick = {}) {
  const int ticks = std::min(600, static_cast<int>(std::ceil(travel_m / speed_m)) + 20);
  return drive(vol, ballTool(), mode, test, s, ticks, [&](int i) {
    const double d = std::min(travel_m, speed_m * i);
    return at(start.x() + d * direction.x(), start.y() + d * direction.y(), start.z() + d * direction.z());
  }, each_tick);
}

TEST_P(NeverThrough, BallOnTheOneVoxelPlateAtEveryIsovalueAndSpeed) {
  auto vol = std::make_shared<const ScalarVolume>(datasets::makeThinPlateVolume(grid(64, 1e-3)));
  const double z_plate = vol->geometry().origin_W_m.z() + 32e-3;
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> phase(0.0, 1e-3);
  int runs = 0;
  std::int64_t samples = 0;
  for (double fraction : kIsoFractions) {
    const double s = fraction * 255.0;
    for (double speed_mm : kSpeeds_mm) {
      // Start 1 to 2 mm above the plate's middle (a random phase against the grid and the
      // speed), drive 5 mm past it; the ball's radius is 5 mm.
      const double travel = std::max(0.5e-3, std::min(0.007, 400 * speed_mm * 1e-3));
      const Eigen::Vector3d start(phase(rng), phase(rng), z_plate + 0.005 + 1.0e-3 + phase(rng));
      const RunOutcome r = pressThrough(vol, GetParam(), SegmentTest::kExact, s, start, -Eigen::Vector3d::UnitZ(),
                                        travel + 0.005, speed_mm * 1e-3, [&](const Pose& X_WP, int tick) {
        for (const auto& p : ballTool()->point_shell.points_T_m())
          ASSERT_GT((X_WP * p).z(), z_plate) << "s " << s << " speed " << speed_mm << " mm tick " << tick;
      });
      EXPECT_EQ(r.crossing_ticks, 0) << "isovalue " << s << ", " << speed_mm << " mm per tick: first at tick "
                                     << r.first_crossing_tick;
      samples += r.oracle_samples;
      ++runs;
    }
  }
  std::cout << runs << " runs, " << samples << " oracle samples, 0 crossings expected\n";
}

// The shell and the tube are sampled on a grid that is not aligned with them: where no voxel
// centre lies near the mid-surface the wall's largest value is below 255, down to about half of
// it (two centres half a voxel either side). Above 50 % of the range the wall has holes, which
// the ball may pass through legitimately; there only the oracle decides (no point's path
// entered the wall), below it the wall is closed and the ball must also end on its own side.
bool wallIsClosed(double fraction) { return fraction < 0.5; }

TEST_P(NeverThrough, BallAgainstAThinShellFromOutsideAndInside) {
  auto vol = std::make_shared<const ScalarVolume>(datasets::makeThinShellVolume(grid(64, 1e-3), Eigen::Vector3d::Zero(), 0.020));
  std::mt19937 rng(2);
  std::uniform_real_distribution<double> phase(0.0, 1e-3);
  for (double fraction : kIsoFractions) {
    const double s = fraction * 255.0;
    for (double speed_mm : {0.01, 0.5, 3.0, 10.0}) {
      const double speed = speed_mm * 1e-3;
      // From outside, down onto the top of the shell (radius 20 mm), off centre.
      const Eigen::Vector3d out0(0.004 + phase(rng), phase(rng), 0.020 + 0.0052 + 0.002 + phase(rng));
      const RunOutcome a = pressThrough(vol, GetParam(), SegmentTest::kExact, s, out0, -Eigen::Vector3d::UnitZ(),
                                        0.010, speed, [&](const Pose& X_WP, int tick) {
        if (!wallIsClosed(fraction)) return;
        for (const auto& p : ballTool()->point_shell.points_T_m())
          ASSERT_GT((X_WP * p).norm(), 0.020) << "outside ball entered the shell at tick " << tick;
      });
      EXPECT_EQ(a.crossing_ticks, 0) << "outside, s " << s << ", " << speed_mm << " mm/tick";
      // From the centre, outward along a slanted direction.
      const Eigen::Vector3d dir = Eigen::Vector3d(1, 0.5, 0.3).normalized();
      const RunOutcome b = pressThrough(vol, GetParam(), SegmentTest::kExact, s, Eigen::Vector3d(phase(rng), 0, 0), dir,
                                        0.020, speed, [&](const Pose& X_WP, int tick) {
        if (!wallIsClosed(fraction)) return;
        for (const auto& p : ballTool()->point_shell.points_T_m())
          ASSERT_LT((X_WP * p).norm(), 0.020) << "inside ball left the shell at tick " << tick;
      });
      EXPECT_EQ(b.crossing_ticks, 0) << "inside, s " << s << ", " << speed_mm << " mm/tick";
    }
  }
}

TEST_P(NeverThrough, BallAgainstAThinWalledTubeWithAnisotropicVoxels) {
  // Voxels 0.5 x 0.5 x 1.5 mm: f = 0.25 mm; the tube (radius 15 mm, along z) is one smallest
  // voxel thick across its wall.
  datasets::GridSpec g;
  g.dims = {80, 80, 24};
  g.spacing_m = {0.5e-3, 0.5e-3, 1.5e-3};
  auto vol = std::make_shared<const ScalarVolume>(datasets::makeThinTubeVolume(g, 0.015));
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> phase(0.0, 0.5e-3);
  for (double fraction : kIsoFractions) {
    const double s = fraction * 255.0;
    for (double speed_mm : {0.01, 0.3, 3.0, 10.0}) {
      const double speed = speed_mm * 1e-3;
      const Eigen::Vector3d out0(0.015 + 0.005 + 0.002 + phase(rng), 0.003 + phase(rng), phase(rng));
      const RunOutcome a = pressThrough(vol, GetParam(), SegmentTest::kExact, s, out0, -Eigen::Vector3d::UnitX(),
                                        0.010, speed, [&](const Pose& X_WP, int tick) {
        if (!wallIsClosed(fraction)) return;
        for (const auto& p : ballTool()->point_shell.points_T_m()) {
          const Eigen::Vector3d q = X_WP * p;
          ASSERT_GT(std::hypot(q.x(), q.y()), 0.015) << "tick " << tick;
        }
      });
      EXPECT_EQ(a.crossing_ticks, 0) << "outside, s " << s << ", " << speed_mm << " mm/tick";
      const RunOutcome b = pressThrough(vol, GetParam(), SegmentTest::kExact, s, Eigen::Vector3d(phase(rng), 0, 0),
                                        Eigen::Vector3d(0.6, -0.8, 0.0), 0.016, speed, [&](const Pose& X_WP, int tick) {
        if (!wallIsClosed(fraction)) return;
        for (const auto& p : ballTool()->point_shell.points_T_m()) {
          const Eigen::Vector3d q = X_WP * p;
          ASSERT_LT(std::hypot(q.x(), q.y()), 0.015) << "tick " << tick;
        }
      });
      EXPECT_EQ(b.crossing_ticks, 0) << "inside, s " << s << ", " << speed_mm << " mm/tick";
    }
  }
}

TEST_P(NeverThrough, ThinToolSpinningFastAboutItsAxisOverAPlate) {
  // An L-shaped hook (a 1 mm shaft, a 4 mm foot) held tilted over the one-voxel plate, the foot
  // 0.4 mm above it; the device spins about the shaft by 1 to 3 rad per tick and presses down:
  // the foot sweeps arcs through the plate's plane unless the sweep stops it.
  auto vol = std::make_shared<const ScalarVolume>(datasets::makeThinPlateVolume(grid(64, 1e-3)));
  const double z_plate = vol->geometry().origin_W_m.z() + 32e-3;
  const TriangleMesh hook = datasets::concatenate(
      datasets::translated(datasets::makeBoxMesh({0.0005, 0.0005, 0.015}), {0, 0, 0.015}),
      datasets::translated(datasets::makeBoxMesh({0.002, 0.0005, 0.0005}), {0.0015, 0, 0.0005}));
  auto tool = test::meshTool(hook, 0.4e-3);
  for (double fraction : {0.5, 0.99}) {
    const double s = fraction * 255.0;
    for (double spin : {1.0, 3.0}) {
      const Eigen::Quaterniond tilt(Eigen::AngleAxisd(0.5, Eigen::Vector3d::UnitY()));
      const Eigen::Vector3d axis_W = tilt * Eigen::Vector3d::UnitZ();
      const RunOutcome r = drive(vol, tool, GetParam(), SegmentTest::kExact, s, 60, [&](int i) {
        const Eigen::Quaterniond R = Eigen::Quaterniond(Eigen::AngleAxisd(spin * i, axis_W)) * tilt;
        return at(0, 0, z_plate + 0.0027 - 0.00005 * i, R);
      }, [&](const Pose& X_WP, int tick) {
        for (const auto& p : tool->point_shell.points_T_m())
          ASSERT_GT((X_WP * p).z(), z_plate) << "s " << s << " spin " << spin << " tick " << tick;
      });
      EXPECT_EQ(r.crossing_ticks, 0) << "s " << s << ", spin " << spin << " rad per tick";
      EXPECT_GT(r.contacts_max, 0) << "the hook never touched the plate";
    }
  }
}

TEST_P(NeverThrough, BallSlidingAcrossConvexEdgesWhileTurning) {
  // The block with a hole (0.5 mm voxels): the ball pressed 1 mm onto the top face, slid across
  // the hole's rim and the block's outer edge and back, its orientation rocking +-0.3 rad.
  auto vol = std::make_shared<const ScalarVolume>(datasets::makeBlockWithHoleVolume(128));
  const double s = datasets::kBlockIsovalue;
  const double z_top = datasets::kBlockHalfHeight_m;
  for (double speed_mm : {0.2, 1.0, 2.5}) {
    const double speed = speed_mm * 1e-3;
    const int ticks = static_cast<int>(0.060 / speed);
    const RunOutcome r = drive(vol, ballTool(), GetParam(), SegmentTest::kExact, s, ticks, [&](int i) {
      // x from -30 mm to +30 mm and back (the block spans +-24 mm, the hole +-8 mm).
      const double u = std::min(1.0, 2.0 * i / ticks), w = std::max(0.0, 2.0 * i / ticks - 1.0);
      const double x = -0.030 + 0.060 * u - 0.060 * w;
      const Eigen::Quaterniond R(Eigen::AngleAxisd(0.3 * std::sin(0.2 * i), Eigen::Vector3d(0.3, 1, 0.2).normalized()));
      return at(x, 0.002, z_top + 0.005 - 0.001, R);
    });
    EXPECT_EQ(r.crossing_ticks, 0) << speed_mm << " mm per tick: first at tick " << r.first_crossing_tick;
    EXPECT_GT(r.contacts_max, 0);
  }
}

TEST_P(NeverThrough, RandomArcsOfARotatingPointThroughThinWalls) {
  // One point 30 mm from the centre of rotation, random translations up to 10 mm and rotations
  // up to 3 rad in one step, through the plate and the tube at random isovalues: the sweep's
  // stop must come before the oracle's first inside sample of the true arc, and, for straight
  // motions, within epsilon / 8 of travel (+ the oracle's step) of it.
  auto plate = std::make_shared<const ScalarVolume>(datasets::makeThinPlateVolume(grid(64, 1e-3)));
  auto tube = std::make_shared<const ScalarVolume>(datasets::makeThinTubeVolume(grid(64, 1e-3), 0.015));
  auto tool = test::pointTool(Eigen::Vector3d(0.0, 0.0, 0.0));
  tool->mass.p_TCm_m = Eigen::Vector3d(0.0, 0.0, 0.030);  // rotate about a centre 30 mm away
  std::mt19937 rng(4);
  std::uniform_real_distribution<double> U(-1.0, 1.0);
  int hits = 0;
  for (int trial = 0; trial < 800; ++trial) {
    const ScalarVolume& vol = trial % 2 == 0 ? *plate : *tube;
    const double s = (0.05 + 0.94 * (0.5 + 0.5 * U(rng))) * 255.0;
    CollisionDetector cd(vol, *tool, 0.0, 256, GetParam());
    const CrossingVerifier oracle(vol, tool->point_shell, kOracleStepVoxels);
    const bool rotate = trial % 3 != 0;
    const Pose X0 = at(0.012 * U(rng), 0.012 * U(rng), 0.012 * U(rng),
                       Eigen::Quaterniond(Eigen::AngleAxisd(3.0 * U(rng), Eigen::Vector3d(U(rng), U(rng), U(rng)).normalized())));
    if (vol.isInside(X0 * Eigen::Vector3d::Zero(), s)) continue;
    const Eigen::Vector3d v = 0.010 * Eigen::Vector3d(U(rng), U(rng), U(rng));
    const Eigen::Vector3d omega = rotate ? Eigen::Vector3d(3.0 * Eigen::Vector3d(U(rng), U(rng), U(rng)) / std::sqrt(3.0)) : Eigen::Vector3d::Zero();
    const RigidMotion motion = RigidMotion::FromVelocity(X0, tool->mass.p_TCm_m, v, omega);
    const SweepResult hit = cd.sweep(motion, s);
    const CrossingVerifier::Result c = oracle.check(motion, hit.t, s);
    ASSERT_EQ(c.crossing_points, 0) << "trial " << trial << ": stopped at t = " << hit.t << ", inside at t = " << c.first_t;
    // Where does the true arc first enter (over the whole step)?
    const CrossingVerifier::Result whole = oracle.check(motion, 1.0, s);
    if (whole.crossing_points > 0) {
      ++hits;
      ASSERT_GE(hit.hit_point, 0) << "trial " << trial;
      if (!rotate) {
        const double travel = motion.pathLengthBound(motion.radial_W(Eigen::Vector3d::Zero())) * (whole.first_t - hit.t);
        EXPECT_LE(travel, cd.epsilon_m() / 8.0 + 2.0 * oracle.step_m()) << "trial " << trial;
      }
    }
  }
  EXPECT_GT(hits, 100);
}

// ---- The oracle can fail: the end-sample test tunnels ------------------------------------------

TEST(NeverThroughControl, TheOracleCatchesTheEndSampleTunnel) {
  // The report: the 10 mm ball pressed onto the one-voxel plate at 250 of 255 sinks
  // through with the end-sample test. The oracle and the outcome check must both see it.
  auto vol = std::make_shared<const ScalarVolume>(datasets::makeThinPlateVolume(grid(64, 1e-3)));
  const double z_plate = vol->geometry().origin_W_m.z() + 32e-3;
  int tunnelled_runs = 0, flagged_runs = 0;
  for (double speed_mm : {0.3, 1.0, 3.0, 6.0}) {
    for (int phase = 0; phase < 4; ++phase) {
      const Eigen::Vector3d start(0.0, 0.0, z_plate + 0.0053 + 0.25e-3 * phase);
      bool through = false;
      const RunOutcome r = pressThrough(vol, DetectionMode::kAccelerated, SegmentTest::kEndSample, 250.0, start,
                                        -Eigen::Vector3d::UnitZ(), 0.0113, speed_mm * 1e-3, [&](const Pose& X_WP, int) {
        for (const auto& p : ballTool()->point_shell.points_T_m()) through |= (X_WP * p).z() < z_plate;
      });
      tunnelled_runs += through;
      flagged_runs += r.crossing_ticks > 0;
      if (through) {
        EXPECT_GT(r.crossing_ticks, 0) << "a tunnel the oracle did not report";
      }
    }
  }
  std::cout << "end-sample test: " << tunnelled_runs << " of 16 runs ended through the plate, "
            << flagged_runs << " flagged by the oracle\n";
  EXPECT_GT(tunnelled_runs, 0);
  EXPECT_GE(flagged_runs, tunnelled_runs);
}

// The oracle of the tool's surface between its points: a vertical edge whose two ends pass above
// and below the one-voxel plate (never through it) ends with the plate between them. The plate
// is at z = 0.5 mm, the ends at +-2 mm; the edge starts beside the volume (outside counts as
// outside) and moves sideways into it.
TEST(NeverThroughControl, TheEdgeOracleSeesAPlateBetweenTwoPointsThatNeverCrossedIt) {
  auto vol = std::make_shared<const ScalarVolume>(datasets::makeThinPlateVolume(grid(64, 1e-3)));
  const double z_plate = vol->geometry().origin_W_m.z() + 32e-3;
  const PointShell shell({Eigen::Vector3d(0, 0, 2e-3), Eigen::Vector3d(0, 0, -2e-3)});
  const ShellEdges edges = makeShellEdges(shell);
  ASSERT_EQ(edges.size(), 1u);
  const CrossingVerifier oracle(*vol, shell, 1e-2);
  const auto slide = [&](double x0, double x1) {
    return RigidMotion::FromVelocity(at(x0, 0, z_plate), Eigen::Vector3d::Zero(), Eigen::Vector3d(x1 - x0, 0, 0),
                                     Eigen::Vector3d::Zero());
  };
  // Into the volume: no point crossed, the edge did.
  const RigidMotion in = slide(-0.040, 0.0);
  EXPECT_EQ(oracle.check(in, 1.0, 250.0).crossing_points, 0);
  const CrossingVerifier::EdgeResult r = oracle.checkEdges(in, 1.0, 250.0, edges, 0.0);
  EXPECT_EQ(r.crossing_edges, 1);
  EXPECT_EQ(r.first_j, 0);
  EXPECT_EQ(r.first_k, 1);
  EXPECT_EQ(r.started_inside, 0);
  // Stopped half way, still outside the grid: free.
  EXPECT_EQ(oracle.checkEdges(in, 0.1, 250.0, edges, 0.0).crossing_edges, 0);
  // Through the volume and out the other side: free at the end, crossed on the way (only the
  // swept check sees it).
  const RigidMotion across = slide(-0.040, 0.040);
  EXPECT_EQ(oracle.checkEdges(across, 1.0, 250.0, edges, 0.0).crossing_edges, 0);
  EXPECT_EQ(oracle.checkEdges(across, 1.0, 250.0, edges, 0.0, 16).crossing_edges, 1);
  // Already across the plate where the move starts: not counted as a crossing.
  const CrossingVerifier::EdgeResult inside = oracle.checkEdges(slide(0.0, 0.005), 1.0, 250.0, edges, 0.0);
  EXPECT_EQ(inside.crossing_edges, 0);
  EXPECT_EQ(inside.started_inside, 1);
  // An edge of another shell is refused.
  EXPECT_THROW(oracle.checkEdges(in, 1.0, 250.0, makeShellEdges(PointShell({Eigen::Vector3d::Zero()})), 0.0),
               std::invalid_argument);
}

}  // namespace
}  // namespace vh::haptics
