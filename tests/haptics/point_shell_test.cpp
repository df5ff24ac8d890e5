#include "vh/haptics/point_shell.h"

#include <algorithm>
#include <cmath>
#include <iostream>
#include <limits>
#include <random>
#include <vector>
#include <numbers>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include "vh/datasets/synthetic.h"
#include "vh/haptics/tool_model.h"

namespace vh::haptics {
namespace {

TEST(PointShell, ResampledToTheRequestedSpacingAndEvenlySpread) {
  const TriangleMesh mesh = datasets::makeCylinderMesh(0.005, 0.03, 48);
  PointShellOptions o;
  o.spacing_m = 1e-3;
  const PointShell shell = makePointShell(mesh, o);
  // Poisson-disk: no two points closer than the spacing; the mean nearest-neighbour distance
  // stays within a small factor of it (vertices alone would leave the side bare).
  const auto& pts = shell.points_T_m();
  double min_d = 1e9;
  for (std::size_t i = 0; i < pts.size(); ++i)
    for (std::size_t j = i + 1; j < pts.size(); ++j) min_d = std::min(min_d, (pts[i] - pts[j]).norm());
  EXPECT_GE(min_d, 1e-3 * (1 - 1e-9));
  const double mean_nn = shell.meanNearestNeighbourSpacing_m();
  EXPECT_GT(mean_nn, 1e-3);
  EXPECT_LT(mean_nn, 1.6e-3);
  const double area = mesh.area_m2();
  EXPECT_GT(shell.size(), area / (2.0 * 1e-3 * 1e-3));  // maximal Poisson-disk density
  // Every point on the surface; normals unit and outward.
  ASSERT_TRUE(shell.hasNormals());
  for (std::size_t i = 0; i < pts.size(); ++i) {
    const Eigen::Vector3d& p = pts[i];
    const double radial = std::hypot(p.x(), p.y());
    const bool on_side = std::abs(radial - 0.005) < 1e-4;  // chordal error of 48 segments
    const bool on_cap = std::abs(p.z()) < 1e-12 || std::abs(p.z() - 0.03) < 1e-12;
    EXPECT_TRUE(on_side || on_cap) << p.transpose();
    EXPECT_NEAR(shell.normals_T()[i].norm(), 1.0, 1e-9);
    const Eigen::Vector3d outward = on_cap ? Eigen::Vector3d(0, 0, p.z() > 0.015 ? 1 : -1)
                                           : Eigen::Vector3d(p.x(), p.y(), 0).normalized();
    EXPECT_GT(shell.normals_T()[i].dot(outward), 0.9);
  }
}

TEST(PointShell, ExactPointCountWhenRequested) {
  const TriangleMesh mesh = datasets::makeBuiltinTool("drill");
  for (std::size_t n : {50u, 518u, 2000u}) {
    PointShellOptions o;
    o.point_count = n;
    EXPECT_EQ(makePointShell(mesh, o).size(), n);
  }
}

// Points in spatial order: consecutive indices lie near each other on the tool (the collision
// detector reads a region's points from neighbouring memory). The oracle: the same points in a
// random order, whose consecutive points lie about a mean chord of the tool apart.
TEST(PointShell, PointsComeInSpatialOrder) {
  const TriangleMesh mesh = datasets::makeBuiltinTool("drill");
  PointShellOptions o;
  o.point_count = 2000;
  const PointShell shell = makePointShell(mesh, o);
  const auto meanStep = [](const std::vector<Eigen::Vector3d>& p) {
    double sum = 0.0;
    for (std::size_t i = 0; i + 1 < p.size(); ++i) sum += (p[i + 1] - p[i]).norm();
    return sum / static_cast<double>(p.size() - 1);
  };
  std::vector<Eigen::Vector3d> shuffled = shell.points_T_m();
  std::mt19937 rng(7);
  std::shuffle(shuffled.begin(), shuffled.end(), rng);
  const double ordered_m = meanStep(shell.points_T_m()), random_m = meanStep(shuffled);
  std::cout << "mean step between consecutive points: " << ordered_m * 1e3 << " mm in the shell's order, "
            << random_m * 1e3 << " mm shuffled\n";
  EXPECT_LT(ordered_m, 0.1 * random_m);
}

// The mean nearest-neighbour spacing from the grid search equals the brute force over every
// pair, to the bit, on shells of every shape the grid can meet: a tool's shell, points on a
// line, on a plane, in one far cluster and a lone point, duplicates, two points.
TEST(PointShell, MeanNearestNeighbourSpacingEqualsTheBruteForce) {
  const auto brute_force = [](const std::vector<Eigen::Vector3d>& p) {
    double sum = 0.0;
    for (std::size_t i = 0; i < p.size(); ++i) {
      double best = std::numeric_limits<double>::infinity();
      for (std::size_t j = 0; j < p.size(); ++j)
        if (j != i) best = std::min(best, (p[i] - p[j]).squaredNorm());
      sum += std::sqrt(best);
    }
    return sum / static_cast<double>(p.size());
  };
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-0.05, 0.05);
  std::vector<std::vector<Eigen::Vector3d>> cases;
  PointShellOptions o;
  o.point_count = 3000;
  cases.push_back(makePointShell(datasets::makeBuiltinTool("drill"), o).points_T_m());
  std::vector<Eigen::Vector3d> line, plane, clusters, duplicates;
  for (int i = 0; i < 500; ++i) line.emplace_back(u(rng), 0.0, 0.0);
  for (int i = 0; i < 2000; ++i) plane.emplace_back(u(rng), u(rng), 0.01);
  for (int i = 0; i < 400; ++i) clusters.emplace_back(1e-3 * u(rng), 1e-3 * u(rng), 1e-3 * u(rng));
  clusters.emplace_back(3.0, -2.0, 5.0);  // one point far away: its neighbour is in the cluster
  for (int i = 0; i < 300; ++i) duplicates.push_back(i % 3 == 0 ? Eigen::Vector3d(0.01, 0.02, 0.03)
                                                                : Eigen::Vector3d(u(rng), u(rng), u(rng)));
  cases.push_back(line);
  cases.push_back(plane);
  cases.push_back(clusters);
  cases.push_back(duplicates);
  cases.push_back({Eigen::Vector3d::Zero(), Eigen::Vector3d(0.0, 0.0, 0.004)});
  for (std::size_t c = 0; c < cases.size(); ++c) {
    const double expected = brute_force(cases[c]);
    EXPECT_EQ(PointShell(cases[c]).meanNearestNeighbourSpacing_m(), expected) << "case " << c;
    EXPECT_GT(expected, 0.0) << "case " << c;
  }
  EXPECT_EQ(PointShell({Eigen::Vector3d::Zero()}).meanNearestNeighbourSpacing_m(), 0.0);
}

TEST(PointShell, RejectsBadInput) {
  PointShellOptions o;
  EXPECT_THROW(makePointShell(TriangleMesh{}, o), std::invalid_argument);
  o.spacing_m = 1e-7;
  EXPECT_THROW(makePointShell(datasets::makeSphereMesh(0.05), o), std::invalid_argument);
  EXPECT_THROW(PointShell({Eigen::Vector3d(0, std::nan(""), 0)}), std::invalid_argument);
  EXPECT_THROW(PointShell({Eigen::Vector3d::Zero()}, {Eigen::Vector3d::UnitX(), Eigen::Vector3d::UnitY()}),
               std::invalid_argument);
}

TEST(MassProperties, SolidCylinderMatchesClosedForm) {
  const double r = 0.004, h = 0.05, rho = 7800.0;
  const TriangleMesh mesh = datasets::makeCylinderMesh(r, h, 256);
  const MassProperties mp = massPropertiesFromMesh(mesh, rho);
  const double m = rho * std::numbers::pi * r * r * h;
  EXPECT_NEAR(mp.mass_kg, m, 1e-3 * m);
  EXPECT_NEAR(mp.p_TCm_m.z(), h / 2, 1e-9);
  EXPECT_NEAR(mp.p_TCm_m.head<2>().norm(), 0.0, 1e-9);
  EXPECT_NEAR(mp.I_Cm_T_kgm2(2, 2), m * r * r / 2, 2e-3 * m * r * r / 2);
  const double transverse = m * (3 * r * r + h * h) / 12;
  EXPECT_NEAR(mp.I_Cm_T_kgm2(0, 0), transverse, 2e-3 * transverse);
  EXPECT_NEAR(mp.I_Cm_T_kgm2(0, 1), 0.0, 1e-6 * transverse);
  // The 6x6 mass matrix in W rotates the inertia block.
  const Eigen::Matrix3d R = Eigen::AngleAxisd(std::numbers::pi / 2, Eigen::Vector3d::UnitX()).toRotationMatrix();
  const auto M = mp.massMatrix_W(R);
  EXPECT_NEAR(M(0, 0), mp.mass_kg, 1e-15);
  EXPECT_NEAR(M(4, 4), mp.I_Cm_T_kgm2(2, 2), 1e-12);  // T's z axis now lies along W's y
}

TEST(MassProperties, BoxMatchesClosedForm) {
  const Eigen::Vector3d h(0.01, 0.02, 0.005);
  const MassProperties mp = massPropertiesFromMesh(datasets::makeBoxMesh(h), 1000.0);
  const double m = 1000.0 * 8 * h.prod();
  EXPECT_NEAR(mp.mass_kg, m, 1e-12);
  EXPECT_NEAR(mp.I_Cm_T_kgm2(0, 0), m * (4 * h.y() * h.y() + 4 * h.z() * h.z()) / 12, 1e-12);
}

}  // namespace
}  // namespace vh::haptics
