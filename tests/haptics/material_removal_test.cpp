#include "vh/haptics/material_removal.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "allocation_guard.h"
#include "test_tools.h"
#include "vh/haptics/haptic_renderer.h"

namespace vh::haptics {
namespace {

// A uniform block: uint8 200 inside [2, n - 3]^3, 0 outside; isovalue 100.
std::shared_ptr<ScalarVolume> uniformBlock(int n, double spacing_m) {
  VolumeGeometry g;
  g.dims = {n, n, n};
  g.spacing_m = Eigen::Vector3d::Constant(spacing_m);
  g.origin_W_m = Eigen::Vector3d::Constant(-0.5 * (n - 1) * spacing_m);
  std::vector<std::uint8_t> v(g.voxelCount(), 0);
  for (int k = 2; k < n - 2; ++k)
    for (int j = 2; j < n - 2; ++j)
      for (int i = 2; i < n - 2; ++i) v[static_cast<std::size_t>(i + n * (j + n * k))] = 200;
  return std::make_shared<ScalarVolume>(ScalarVolume::FromVoxels(g, v));
}

// Whether the burr's sphere meets the felt solid (F > 100): 400 points spread on it (a
// Fibonacci sphere), as a contact set on the burr would say.
bool touches(const ScalarVolume& v, const Eigen::Vector3d& c, double r) {
  constexpr int kN = 400;
  for (int i = 0; i < kN; ++i) {
    const double z = 1.0 - 2.0 * (i + 0.5) / kN, rho = std::sqrt(1.0 - z * z);
    const double phi = i * std::numbers::pi * (3.0 - std::sqrt(5.0));
    if (v.isInside(c + r * Eigen::Vector3d(rho * std::cos(phi), rho * std::sin(phi), z), 100.0)) return true;
  }
  return false;
}

std::vector<CuttingMaterial> oneMaterial(double energy_J_per_mm3 = 1.0) {
  return {CuttingMaterial{"bone", energy_J_per_mm3, false}};
}

// The incremental refresh of the min-max tree and the local Lipschitz bounds equals a rebuild
// from scratch (the oracle) after scattered writes, on every node and every brick.
// Every node's range of `t1` equals `t2`'s (a tree refreshed in place against one rebuilt).
void expectSameRanges(const MinMaxTree& t1, const MinMaxTree& t2, const std::string& what) {
  ASSERT_EQ(t1.levels(), t2.levels()) << what;
  for (int level = 0; level < t1.levels(); ++level) {
    const auto n = t1.nodes(level);
    for (int c = 0; c < n[2]; ++c)
      for (int b = 0; b < n[1]; ++b)
        for (int a = 0; a < n[0]; ++a) {
          float lo1, hi1, lo2, hi2;
          t1.node(level, a, b, c, lo1, hi1);
          t2.node(level, a, b, c, lo2, hi2);
          ASSERT_EQ(lo1, lo2) << what << " level " << level;
          ASSERT_EQ(hi1, hi2) << what << " level " << level;
        }
  }
}

TEST(MaterialRemoval, RefreshedTreeEqualsARebuild) {
  std::mt19937 rng(7);
  for (const VoxelType type : {VoxelType::kUInt8, VoxelType::kInt16, VoxelType::kFloat32}) {
    VolumeGeometry g;
    g.dims = {23, 18, 29};
    g.spacing_m = {0.5e-3, 0.7e-3, 1.1e-3};
    std::vector<std::byte> bytes(g.voxelCount() * voxelTypeSize(type));
    for (auto& b : bytes) b = static_cast<std::byte>(rng() % 64);  // small values: float bytes stay finite
    ScalarVolume carved = ScalarVolume::FromBytes(g, type, bytes);
    std::uniform_int_distribution<int> x(0, g.dims[0] - 1), y(0, g.dims[1] - 1), z(0, g.dims[2] - 1);
    for (int round = 0; round < 20; ++round) {
      const std::array<int, 3> a{x(rng), y(rng), z(rng)};
      std::array<int, 3> lo = a, hi = a;
      for (int w = 0; w < 5; ++w) {
        const std::array<int, 3> p{std::min(a[0] + w, g.dims[0] - 1), std::min(a[1] + w / 2, g.dims[1] - 1), a[2]};
        const std::size_t idx = static_cast<std::size_t>(p[0] + g.dims[0] * (p[1] + g.dims[1] * p[2]));
        carved.writeRaw(idx, carved.lowestRaw());
        for (int ax = 0; ax < 3; ++ax) {
          lo[ax] = std::min(lo[ax], p[ax]);
          hi[ax] = std::max(hi[ax], p[ax]);
        }
      }
      carved.refreshRegion(lo, hi);
    }
    const ScalarVolume rebuilt = ScalarVolume::FromBytes(g, type, carved.bytes());
    const MinMaxTree &t1 = carved.minMaxTree(), &t2 = rebuilt.minMaxTree();
    expectSameRanges(t1, t2, voxelTypeName(type));
    const auto n0 = t1.nodes(0);
    for (int c = 0; c < n0[2]; ++c)
      for (int b = 0; b < n0[1]; ++b)
        for (int a = 0; a < n0[0]; ++a) {
          const int i = 4 * a, j = 4 * b, k = 4 * c;
          ASSERT_EQ(t1.brickLipschitz(i, j, k), t2.brickLipschitz(i, j, k)) << voxelTypeName(type);
        }
    // Box queries on upper levels read the propagated bounds.
    float rmin1, rmax1, rmin2, rmax2, l1, l2;
    t1.rawRange({0, 0, 0}, {22, 17, 28}, rmin1, rmax1, nullptr, &l1);
    t2.rawRange({0, 0, 0}, {22, 17, 28}, rmin2, rmax2, nullptr, &l2);
    EXPECT_EQ(rmin1, rmin2);
    EXPECT_EQ(rmax1, rmax2);
    EXPECT_EQ(l1, l2);
  }
}

// The oracle: a burr moved along a straight line through a uniform block removes the capsule
// it sweeps, pi r^2 L + 4/3 pi r^3, within one voxel layer (the capsule's area times a voxel
// side), at three burr radii and two voxel sizes.
TEST(MaterialRemoval, StraightPassRemovesTheSweptCapsule) {
  for (const double h : {0.5e-3, 1.0e-3}) {
    for (const double r : {1.5e-3, 3.0e-3, 5.0e-3}) {
      const int n = static_cast<int>(std::ceil(0.040 / h)) | 1;
      auto volume = uniformBlock(n, h);
      MaterialRemoval drill(volume, {}, oneMaterial());
      const Eigen::Vector3d a(-0.008, 0.001, -0.0005), b(0.008, -0.002, 0.0015);
      const double L = (b - a).norm();
      const int steps = static_cast<int>(std::ceil(L / (0.1 * h)));
      for (int t = 0; t <= steps; ++t) {  // a force so large that each tick clears the whole reach
        const Eigen::Vector3d c = a + (b - a) * (static_cast<double>(t) / steps);
        drill.cut(c, r, 1e9, 1e-3, 100.0, touches(*volume, c, r));
      }
      const double removed_m3 = static_cast<double>(drill.removedVoxels()) * h * h * h;
      const double capsule_m3 = std::numbers::pi * r * r * L + 4.0 / 3.0 * std::numbers::pi * r * r * r;
      const double layer_m3 = (2.0 * std::numbers::pi * r * L + 4.0 * std::numbers::pi * r * r) * h;
      const double error_layers = std::abs(removed_m3 - capsule_m3) / layer_m3;
      std::printf("capsule h %.1f mm r %.1f mm: removed %.2f mm^3, analytic %.2f mm^3, error %.3f voxel layers\n", h * 1e3,
                  r * 1e3, removed_m3 * 1e9, capsule_m3 * 1e9, error_layers);
      EXPECT_LE(error_layers, 1.0) << "h " << h << " r " << r << ": removed " << removed_m3 * 1e9 << " mm^3, capsule "
                                   << capsule_m3 * 1e9 << " mm^3";
      // And the shape: inside the capsule less a voxel everything is gone, outside it plus a
      // voxel nothing is (distance to the segment, the independent description).
      const auto& g = volume->geometry();
      int wrong = 0;
      for (int k = 0; k < n; ++k)
        for (int j = 0; j < n; ++j)
          for (int i = 0; i < n; ++i) {
            const Eigen::Vector3d p = g.origin_W_m + h * Eigen::Vector3d(i, j, k);
            const double u = std::clamp((p - a).dot(b - a) / (L * L), 0.0, 1.0);
            const double d = (p - (a + u * (b - a))).norm();
            const bool gone = volume->voxel(i, j, k) == 0.0;
            const bool was = i >= 2 && j >= 2 && k >= 2 && i < n - 2 && j < n - 2 && k < n - 2;
            if (was && d < r - h && !gone) ++wrong;
            if (was && d > r + h && gone) ++wrong;
          }
      EXPECT_EQ(wrong, 0) << "h " << h << " r " << r;
    }
  }
}

// Energy is conserved: the removed volume never exceeds the delivered energy over the specific
// energy, and a material ten times harder removes about a tenth as much.
TEST(MaterialRemoval, RemovalFollowsForceOverHardness) {
  const auto removedAfter = [](double energy_J_per_mm3, double force_N) {
    auto volume = uniformBlock(41, 0.5e-3);
    MaterialRemoval drill(volume, {}, oneMaterial(energy_J_per_mm3));
    double energy = 0.0;
    Eigen::Vector3d c(0, 0, 0.0095);  // above the block's top face (z = 8.5 mm + burr radius 1 mm)
    for (int t = 0; t < 2000; ++t) {
      energy += drill.cut(c, 1e-3, force_N, 1e-3, 100.0, true).energy_J;
      c.z() -= 2e-6;  // slow feed: the burr is energy-limited, not geometry-limited
    }
    const double removed_mm3 = drill.erodedVolume_mm3();
    EXPECT_LE(static_cast<double>(drill.removedVoxels()) * drill.voxelVolume_mm3(), removed_mm3);
    EXPECT_LE(removed_mm3 * energy_J_per_mm3, energy * 1.0001);
    EXPECT_GE(removed_mm3 * energy_J_per_mm3, energy * 0.5) << "most of the energy removes material";
    return removed_mm3;
  };
  const double soft = removedAfter(2.0, 1.0), hard = removedAfter(20.0, 1.0);
  EXPECT_GT(hard, 0.0);
  EXPECT_NEAR(hard / soft, 0.1, 0.05) << "soft " << soft << " mm^3, hard " << hard << " mm^3";
  const double pressed = removedAfter(2.0, 2.0);
  EXPECT_NEAR(pressed / soft, 2.0, 0.3) << "twice the force";
}

// A hardness changed while drilling applies from the next cut: ten times harder, a tenth as fast.
TEST(MaterialRemoval, HardnessChangesLive) {
  const auto eroded = [](double factor) {
    auto volume = uniformBlock(41, 0.5e-3);
    MaterialRemoval drill(volume, {}, oneMaterial(1.0));
    drill.setSpecificEnergy(0, 1.0 * factor);
    drill.setSpecificEnergy(0, -1.0);  // refused
    drill.setSpecificEnergy(3, 5.0);   // no such material: ignored
    EXPECT_DOUBLE_EQ(drill.specificEnergy(0), factor);
    Eigen::Vector3d c(0, 0, 0.0095);
    for (int t = 0; t < 1000; ++t, c.z() -= 2e-6) drill.cut(c, 1e-3, 1.0, 1e-3, 100.0, true);
    return drill.erodedVolume_mm3();
  };
  EXPECT_NEAR(eroded(10.0) / eroded(1.0), 0.1, 0.05);
}

// F only decreases (nothing is added), voxels out of reach keep their values, no force cuts
// nothing, and cut() allocates nothing.
TEST(MaterialRemoval, OnlyLowersTheFieldAndAllocatesNothing) {
  auto volume = uniformBlock(41, 0.5e-3);
  const std::vector<std::byte> before = volume->bytes();
  MaterialRemoval drill(volume, {}, oneMaterial());
  EXPECT_EQ(drill.cut({0, 0, 0.009}, 2e-3, 0.0, 1e-3, 100.0, true).voxels_removed, 0);
  EXPECT_EQ(drill.cut({0, 0, 0.009}, 2e-3, 5.0, 1e-3, 100.0, false).voxels_removed, 0);
  EXPECT_EQ(drill.cut({0, 0, 0.009}, 2e-3, std::nan(""), 1e-3, 100.0, true).voxels_removed, 0);
  EXPECT_EQ(volume->bytes(), before);
  int removed = 0;
  {
    test::AllocationGuard guard;
    for (int t = 0; t < 200; ++t) removed += drill.cut({0, 0, 0.0098 - 2e-5 * t}, 2e-3, 1e3, 1e-3, 100.0, true).voxels_removed;
    EXPECT_EQ(guard.count(), 0u);
  }
  EXPECT_GT(removed, 0);
  const auto& after = volume->bytes();
  for (std::size_t i = 0; i < after.size(); ++i) ASSERT_LE(static_cast<int>(after[i]), static_cast<int>(before[i]));
  // The log hands every removed voxel to the picture, once.
  std::vector<std::uint64_t> log(100000);
  const std::size_t n = drill.drainRemoved(log);
  EXPECT_EQ(n, drill.removedVoxels());
  for (std::size_t i = 0; i < n; ++i) EXPECT_EQ(static_cast<int>(after[log[i]]), 0);
  EXPECT_EQ(drill.drainRemoved(log), 0u);
}

// Per-voxel materials: a critical material is counted apart; a harder layer slows the burr.
TEST(MaterialRemoval, CriticalMaterialIsCounted) {
  auto volume = uniformBlock(41, 0.5e-3);
  std::vector<std::uint8_t> material(volume->geometry().voxelCount(), 0);
  for (std::size_t i = 0; i < material.size(); ++i)
    if ((i / (41 * 41)) < 20) material[i] = 1;  // the lower half is a "nerve"
  MaterialRemoval drill(volume, material, {{"bone", 1.0, false}, {"nerve", 1.0, true}});
  int critical = 0;
  for (int t = 0; t < 400; ++t) {
    const CutResult cut = drill.cut({0, 0, 0.006 - 2e-5 * t}, 2e-3, 1e9, 1e-3, 100.0, true);
    critical += cut.critical_removed;
    EXPECT_EQ(cut.critical_material, cut.critical_removed > 0 ? 1 : -1);
  }
  EXPECT_GT(drill.removedVoxels(0), 0u);
  EXPECT_GT(drill.removedVoxels(1), 0u);
  EXPECT_EQ(static_cast<std::uint64_t>(critical), drill.removedVoxels(1));
}

// The cut reports the hardness of what it cut: one material's specific energy inside it, a
// value between the two across their boundary, 0 when nothing was cut.
TEST(MaterialRemoval, CutReportsTheHardnessOfWhatItCuts) {
  const auto cutAt = [](double z_m, double force_N) {
    auto volume = uniformBlock(41, 0.5e-3);
    std::vector<std::uint8_t> material(volume->geometry().voxelCount(), 0);
    for (std::size_t i = 0; i < material.size(); ++i)
      if ((i / (41 * 41)) < 20) material[i] = 1;  // z < 0: the harder material
    MaterialRemoval drill(volume, material, {{"cancellous", 1.0, false}, {"cortical", 3.0, false}});
    return drill.cut({0, 0, z_m}, 2e-3, force_N, 1e-3, 100.0, true);
  };
  EXPECT_NEAR(cutAt(0.005, 1.0).specific_energy_J_per_mm3, 1.0, 1e-12);
  EXPECT_NEAR(cutAt(-0.005, 1.0).specific_energy_J_per_mm3, 3.0, 1e-12);
  const double across = cutAt(0.0, 1.0).specific_energy_J_per_mm3;
  EXPECT_GT(across, 1.5);
  EXPECT_LT(across, 2.5);
  EXPECT_EQ(cutAt(0.005, 0.0).specific_energy_J_per_mm3, 0.0) << "no force: no cut";
  EXPECT_EQ(cutAt(0.05, 1.0).specific_energy_J_per_mm3, 0.0) << "far above the block: nothing in reach";
  // The cut's material is that of the voxel nearest the burr's centre (the deepest in reach):
  // voxel centres lie at multiples of 0.5 mm, layer z = 0 and above is material 0.
  EXPECT_EQ(cutAt(0.005, 1.0).material, 0);
  EXPECT_EQ(cutAt(-0.005, 1.0).material, 1);
  EXPECT_EQ(cutAt(0.0006, 1.0).material, 0) << "nearest voxel centre at z = +0.5 mm";
  EXPECT_EQ(cutAt(-0.0006, 1.0).material, 1) << "nearest voxel centre at z = -0.5 mm";
  EXPECT_EQ(cutAt(0.05, 1.0).material, -1) << "nothing cut";
}

// The guarantees stay while drilling: a drill pressed into a block by a device far below it
// sinks as it cuts, and no point of the proxy is ever inside the carved field (checked against
// the field after every tick's removal), with a bounded step per tick. With the edge test too:
// a move its edges stop leaves the place in the contact set, so the burr is in contact and cuts.
TEST(MaterialRemoval, ProxyNeverPenetratesTheCarvedField) {
  for (const int edge_test : {0, 1}) {
    SCOPED_TRACE(edge_test ? "edge test on" : "edge test off");
    auto volume = uniformBlock(41, 0.5e-3);
    auto tool = test::meshTool(datasets::makeBuiltinTool("drill"), 0.5e-3);
    RendererOptions o;
    o.gains.linear_N_per_m = 500.0;
    o.edge_test = edge_test;
    HapticRenderer renderer(volume, tool, o, Pose::FromTranslation({0, 0, 0.012}), 100.0);
    MaterialRemoval drill(volume, {}, oneMaterial(2.0));
    const Pose X_WD = Pose::FromTranslation({0, 0, 0.000});  // 12 mm into the block
    double previous_z = 0.012, max_step = 0.0;
    for (int t = 0; t < 1000; ++t) {
      const TickOutput out = renderer.tick(X_WD, 100.0);
      const Eigen::Vector3d burr = out.X_WP * Eigen::Vector3d::Zero();
      drill.cut(burr, 2.5e-3, out.force_W_N.norm(), 1e-3, 100.0, out.stats.contacts > 0);
      for (const auto& p_T : tool->point_shell.points_T_m())
        ASSERT_FALSE(volume->isInside(out.X_WP * p_T, 100.0)) << "tick " << t;
      max_step = std::max(max_step, std::abs(out.X_WP.p_AB_m.z() - previous_z));
      previous_z = out.X_WP.p_AB_m.z();
    }
    EXPECT_LT(previous_z, 0.0085 + 2.5e-3 - 1e-3) << "the burr sank less than 1 mm into the block";
    EXPECT_GT(previous_z, 0.0) << "the burr cannot pass the device";
    EXPECT_LE(max_step, o.max_travel_per_tick_m + 1e-12);
    EXPECT_GT(drill.removedVoxels(), 0u);
  }
}

// A cavity removed before the first cut: its voxels (out of range and already removed ones
// skipped) take the lowest value and are cut no more, neither counted nor logged, the tree equals a
// rebuild of the same voxels (the oracle), and a burr pressed there next removes only what is left.
TEST(MaterialRemoval, RemoveCavityCarvesBeforeTheFirstCutUncountedAndUnlogged) {
  auto v = uniformBlock(24, 0.001);
  const auto& g = v->geometry();
  std::vector<std::uint64_t> cavity;
  for (int k = 0; k < 24; ++k)
    for (int j = 0; j < 24; ++j)
      for (int i = 0; i < 24; ++i)
        if (Eigen::Vector3d(i - 12, j - 12, k - 20).norm() <= 3.0)
          cavity.push_back(static_cast<std::uint64_t>(i + 24 * (j + 24 * k)));
  std::size_t solid = 0;
  for (const std::uint64_t index : cavity) solid += v->rawAt(index) != 0.0;
  ASSERT_GT(solid, 20u);
  ASSERT_LT(solid, cavity.size()) << "the test needs cavity voxels already empty (outside the block)";
  cavity.push_back(g.voxelCount() + 5);  // out of range: skipped
  MaterialRemoval removal(v, {}, oneMaterial());
  EXPECT_EQ(removal.removeCavity(cavity), solid);
  EXPECT_EQ(removal.removeCavity(cavity), 0u) << "removed already";
  for (std::size_t n = 0; n + 1 < cavity.size(); ++n) ASSERT_EQ(v->rawAt(cavity[n]), 0.0);
  EXPECT_EQ(removal.removedVoxels(), 0u);
  EXPECT_EQ(removal.erodedVolume_mm3(), 0.0);
  std::uint64_t log[8];
  EXPECT_EQ(removal.drainRemoved(log), 0u);
  const ScalarVolume rebuilt = ScalarVolume::FromBytes(g, VoxelType::kUInt8, v->bytes());
  expectSameRanges(v->minMaxTree(), rebuilt.minMaxTree(), "uint8");
  // The burr inside the cavity, touching only its wall: what it removes was never in the cavity.
  const Eigen::Vector3d c = g.origin_W_m + g.spacing_m.cwiseProduct(Eigen::Vector3d(12, 12, 19));
  std::uint64_t cut = 0;
  for (int tick = 0; tick < 200; ++tick) cut += static_cast<std::uint64_t>(removal.cut(c, 0.0025, 5.0, 1e-3, 100.0, true).voxels_removed);
  EXPECT_GT(cut, 0u);
  EXPECT_EQ(removal.removedVoxels(), cut);
  std::vector<std::uint64_t> drained(cut + 1);
  ASSERT_EQ(removal.drainRemoved(drained), cut);
  for (std::uint64_t n = 0; n < cut; ++n)
    EXPECT_FALSE(std::binary_search(cavity.begin(), cavity.end() - 1, drained[n])) << "voxel " << drained[n];
}

// The box of cuts since a mark (what a recording restarted while drilling catches up): empty
// after markCuts(); after cuts in a second place it holds every voxel whose bytes changed since
// the mark (the oracle: a byte-wise diff of the field), and none of the first place's.
TEST(MaterialRemoval, TheBoxOfCutsSinceAMarkHoldsEveryVoxelRemovedSinceThen) {
  auto v = uniformBlock(32, 0.001);
  const auto& g = v->geometry();
  MaterialRemoval removal(v, {}, oneMaterial(0.05));
  std::array<int, 3> lo{}, hi{};
  EXPECT_FALSE(removal.cutsSinceMark(lo, hi)) << "nothing cut yet";
  const auto at = [&](double i, double j, double k) { return Eigen::Vector3d(g.origin_W_m + g.spacing_m.cwiseProduct(Eigen::Vector3d(i, j, k))); };
  std::uint64_t first = 0;
  for (int tick = 0; tick < 100; ++tick) first += static_cast<std::uint64_t>(removal.cut(at(8, 8, 1.5), 0.002, 5.0, 1e-3, 100.0, true).voxels_removed);
  ASSERT_GT(first, 0u);
  ASSERT_TRUE(removal.cutsSinceMark(lo, hi));
  removal.markCuts();
  EXPECT_FALSE(removal.cutsSinceMark(lo, hi)) << "empty after the mark";
  const std::vector<std::byte> at_mark(v->bytes().begin(), v->bytes().end());
  std::uint64_t second = 0;
  for (int tick = 0; tick < 100; ++tick) second += static_cast<std::uint64_t>(removal.cut(at(22, 20, 1.5), 0.002, 5.0, 1e-3, 100.0, true).voxels_removed);
  ASSERT_GT(second, 0u);
  ASSERT_TRUE(removal.cutsSinceMark(lo, hi));
  std::uint64_t changed = 0;
  for (std::size_t index = 0; index < at_mark.size(); ++index) {
    if (at_mark[index] == v->bytes()[index]) continue;
    ++changed;
    const std::array<int, 3> ijk = g.voxelOf(index);
    for (int a = 0; a < 3; ++a) {
      EXPECT_GE(ijk[a], lo[a]) << "voxel " << index;
      EXPECT_LE(ijk[a], hi[a]) << "voxel " << index;
    }
  }
  EXPECT_EQ(changed, second);
  EXPECT_GT(lo[0], 8 + 2) << "the first place's cuts are not in the box";
  std::cout << "cut " << first << " voxels, marked, cut " << second << " more in the box [" << lo[0] << ".." << hi[0]
            << "] x [" << lo[1] << ".." << hi[1] << "] x [" << lo[2] << ".." << hi[2] << "]\n";
}

TEST(MaterialRemoval, RejectsBadInput) {
  auto volume = uniformBlock(9, 1e-3);
  EXPECT_THROW(MaterialRemoval(nullptr, {}, oneMaterial()), std::invalid_argument);
  EXPECT_THROW(MaterialRemoval(volume, {}, {}), std::invalid_argument);
  EXPECT_THROW(MaterialRemoval(volume, {}, oneMaterial(0.0)), std::invalid_argument);
  EXPECT_THROW(MaterialRemoval(volume, std::vector<std::uint8_t>(5, 0), oneMaterial()), std::invalid_argument);
  EXPECT_THROW(MaterialRemoval(volume, std::vector<std::uint8_t>(volume->geometry().voxelCount(), 3), oneMaterial()),
               std::invalid_argument);
}

}  // namespace
}  // namespace vh::haptics
