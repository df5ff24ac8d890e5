#include "vh/haptics/cone_projection.h"

#include <cstdint>
#include <iostream>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "allocation_guard.h"
#include "vh/haptics/configuration_solver.h"

namespace vh::haptics {
namespace {

struct Problem {
  Matrix6d M;
  Vector6d a_u;
  std::vector<Vector6d> J;
};

Eigen::Vector3d unit(std::mt19937& rng) {
  std::normal_distribution<double> nd;
  return Eigen::Vector3d(nd(rng), nd(rng), nd(rng)).normalized();
}

// A tool-like mass matrix (kg-normalised) and contact rows from random points and normals.
Problem randomProblem(std::mt19937& rng, int m, int degenerate_kind) {
  std::uniform_real_distribution<double> u(0.2, 2.0);
  Problem p;
  const Eigen::Matrix3d R = Eigen::Quaterniond(unit(rng).x(), unit(rng).y(), unit(rng).z(), 0.3).normalized().toRotationMatrix();
  const Eigen::Vector3d moments = 1e-4 * Eigen::Vector3d(u(rng), u(rng), 0.05 * u(rng));
  p.M.setZero();
  p.M.topLeftCorner<3, 3>().setIdentity();
  p.M.bottomRightCorner<3, 3>() = R * moments.asDiagonal() * R.transpose();
  std::normal_distribution<double> nd;
  for (int i = 0; i < 6; ++i) p.a_u[i] = (i < 3 ? 0.01 : 0.3) * nd(rng);
  const Eigen::Vector3d c = Eigen::Vector3d::Zero();
  for (int i = 0; i < m; ++i) {
    const Eigen::Vector3d pt = 0.02 * Eigen::Vector3d(nd(rng), nd(rng), nd(rng));
    Eigen::Vector3d n = unit(rng);
    // Bias normals against the pull so that constraints are active.
    if (n.dot(p.a_u.head<3>()) > 0) n = -n;
    p.J.push_back(constraintRow(pt, n, c));
  }
  if (m >= 2) {
    switch (degenerate_kind) {
      case 1: p.J[1] = p.J[0]; break;                   // duplicated
      case 2: p.J[1] = -p.J[0]; break;                  // opposing: motion along it is forbidden
      case 3: {                                         // near-parallel, 1e-9 rad apart
        const Eigen::Vector3d axis = unit(rng);
        const Eigen::Matrix3d tiny = Eigen::AngleAxisd(1e-9, axis).toRotationMatrix();
        p.J[1].head<3>() = tiny * p.J[0].head<3>();
        p.J[1].tail<3>() = tiny * p.J[0].tail<3>();
        break;
      }
      case 4:                                           // rank deficient: sums of others
        for (int i = 2; i < m; ++i) p.J[i] = 0.5 * (p.J[i - 1] + p.J[i - 2]);
        break;
      default: break;
    }
  }
  return p;
}

double metricDistance(const Matrix6d& M, const Vector6d& a, const Vector6d& b) {
  return std::sqrt((a - b).dot(M * (a - b)));
}

TEST(ConeProjection, AgreesWithTheExhaustiveReferenceOnRandomCones) {
  std::mt19937 rng(42);
  ConeProjector projector(64);
  int checked = 0;
  for (int n = 0; n < 3000; ++n) {
    const int m = 1 + n % 9;
    const Problem p = randomProblem(rng, m, n % 5);
    const ConeProjection fast = projector.project(p.M, p.a_u, p.J);
    const Vector6d ref = projectOntoConeReference(p.M, p.a_u, p.J);
    ASSERT_TRUE(fast.converged) << "problem " << n;
    const double scale = std::max(metricDistance(p.M, p.a_u, Vector6d::Zero()), 1e-300);
    // Both are the projection: their distance in the metric is tiny relative to |a_u|_M.
    EXPECT_LT(metricDistance(p.M, fast.a_c, ref) / scale, 1e-7) << "problem " << n << " m=" << m;
    ++checked;
  }
  EXPECT_EQ(checked, 3000);
}

// 10^5 random problems, 1 to 60 constraints, a fifth each plain, duplicated, opposing,
// near-parallel (1e-9 rad) and rank-deficient: Wilhelmsen's solver agrees with Hildreth's
// independent reference to 1e-9 of |a_u| in the mass metric. Near-parallel rows define the cone
// only to their angle: both solvers may settle on either twin, so that kind is held to 5e-9
// (measured worst: 2.2e-9). The reference gives up on a few fully constrained, degenerate cones
// (its multipliers are not unique and converge slowly); they are counted, must stay rare, and
// the fast answer there is still certified by the KKT test below.
TEST(ConeProjection, AgreesWithHildrethsReferenceOnAHundredThousandProblems) {
  std::mt19937 rng(2024);
  ConeProjector projector(64);
  double worst[5] = {0, 0, 0, 0, 0};
  int compared = 0, uncertified = 0;
  for (int n = 0; compared < 100000; ++n) {
    const int m = 1 + n % 60;
    const int kind = n % 5;
    const Problem p = randomProblem(rng, m, kind);
    const ConeProjection fast = projector.project(p.M, p.a_u, p.J);
    ASSERT_TRUE(fast.converged) << "problem " << n;
    Vector6d ref;
    try {
      ref = projectOntoConeHildreth(p.M, p.a_u, p.J);
    } catch (const std::runtime_error&) {
      ++uncertified;
      continue;
    }
    ++compared;
    const double err = metricDistance(p.M, fast.a_c, ref) / metricDistance(p.M, p.a_u, Vector6d::Zero());
    worst[kind] = std::max(worst[kind], err);
    ASSERT_LT(err, kind == 3 ? 5e-9 : 1e-9) << "problem " << n << " m=" << m << " kind " << kind;
  }
  RecordProperty("worst_plain", std::to_string(worst[0]));
  RecordProperty("worst_near_parallel", std::to_string(worst[3]));
  RecordProperty("uncertified", uncertified);
  EXPECT_LT(uncertified, 100) << "the reference could not certify " << uncertified << " problems";
  std::cout << "worst relative error by kind (plain, duplicated, opposing, near-parallel, rank-deficient): "
            << worst[0] << " " << worst[1] << " " << worst[2] << " " << worst[3] << " " << worst[4] << "; "
            << uncertified << " problems the reference could not certify\n";
}

// Warm starts: from the right face, a wrong one, a partial one and junk indices the
// result is still the projection (Hildreth's independent reference), and the right face takes
// fewer iterations than a cold start.
TEST(ConeProjection, WarmStartFromAnyGuessGivesTheSameProjection) {
  std::mt19937 rng(913);
  ConeProjector projector(64);
  std::int64_t cold_iterations = 0, warm_iterations = 0;
  int compared = 0;
  for (int n = 0; compared < 5000; ++n) {
    const int m = 2 + n % 40;
    const Problem p = randomProblem(rng, m, n % 5 == 3 ? 0 : n % 5);
    const ConeProjection cold = projector.project(p.M, p.a_u, p.J);
    ASSERT_TRUE(cold.converged);
    Vector6d ref;
    try {
      ref = projectOntoConeHildreth(p.M, p.a_u, p.J);
    } catch (const std::runtime_error&) {
      continue;
    }
    ++compared;
    const double scale = metricDistance(p.M, p.a_u, Vector6d::Zero());
    std::vector<std::vector<int>> guesses;
    guesses.emplace_back(cold.active_rows.begin(), cold.active_rows.begin() + cold.active);  // the right face
    if (cold.active > 1) guesses.emplace_back(cold.active_rows.begin() + 1, cold.active_rows.begin() + cold.active);
    std::uniform_int_distribution<int> row(0, m - 1);
    guesses.push_back({row(rng), row(rng), row(rng), row(rng), row(rng), row(rng)});  // random, maybe repeated
    guesses.push_back({-3, m, m + 7, row(rng)});                                       // out of range
    for (std::size_t g = 0; g < guesses.size(); ++g) {
      const ConeProjection warm = projector.project(p.M, p.a_u, p.J, {}, guesses[g]);
      ASSERT_TRUE(warm.converged) << "problem " << n << " guess " << g;
      ASSERT_LT(metricDistance(p.M, warm.a_c, ref) / scale, 1e-9) << "problem " << n << " m=" << m << " guess " << g;
      if (g == 0) {
        cold_iterations += cold.iterations;
        warm_iterations += warm.iterations;
      }
    }
  }
  std::cout << "iterations over " << compared << " problems: cold " << cold_iterations << ", warm (right face) "
            << warm_iterations << "\n";
  EXPECT_LT(warm_iterations * 2, cold_iterations);
}

TEST(ConeProjection, BothReferencesAgree) {
  std::mt19937 rng(77);
  for (int n = 0; n < 2000; ++n) {
    if (n % 5 == 3) continue;  // near-parallel: see above
    const Problem p = randomProblem(rng, 1 + n % 10, n % 5);
    const Vector6d a = projectOntoConeReference(p.M, p.a_u, p.J);
    Vector6d b;
    try {
      b = projectOntoConeHildreth(p.M, p.a_u, p.J);
    } catch (const std::runtime_error&) {
      continue;
    }
    EXPECT_LT(metricDistance(p.M, a, b) / metricDistance(p.M, p.a_u, Vector6d::Zero()), 1e-9) << "problem " << n;
  }
}

TEST(ConeProjection, SatisfiesTheKktConditions) {
  std::mt19937 rng(8);
  ConeProjector projector(64);
  std::vector<double> lambda(60);
  for (int n = 0; n < 100000; ++n) {
    const int m = 1 + n % 60;
    const Problem p = randomProblem(rng, m, n % 5);
    const ConeProjection r = projector.project(p.M, p.a_u, p.J, std::span<double>(lambda.data(), m));
    ASSERT_TRUE(r.converged);
    const double scale = p.a_u.norm();
    Vector6d correction = Vector6d::Zero();
    for (int i = 0; i < m; ++i) {
      const double g = p.J[i].dot(r.a_c) / p.J[i].norm();
      EXPECT_GT(g, -1e-9 * scale) << "feasibility, problem " << n << " row " << i;  // J a >= 0
      EXPECT_GE(lambda[i], 0.0);                                                  // lambda >= 0
      EXPECT_LT(std::abs(lambda[i] * g), 1e-8 * scale * (1 + lambda[i]));          // complementarity
      correction += lambda[i] * p.J[i];
    }
    // Stationarity: a_c = a_u + M^-1 J^T lambda.
    const Vector6d expected = p.a_u + p.M.ldlt().solve(correction);
    EXPECT_LT((expected - r.a_c).norm(), 1e-8 * (1 + scale)) << "problem " << n;
  }
}

TEST(ConeProjection, SimpleCasesHaveKnownAnswers) {
  ConeProjector projector;
  const Matrix6d M = Matrix6d::Identity();
  Vector6d a_u;
  a_u << 1, 0, -1, 0, 0, 0;
  // No constraint: unchanged.
  EXPECT_EQ(projector.project(M, a_u, {}).a_c, a_u);
  // A floor (normal +z at the centre): the downward part is removed, sliding stays.
  const std::vector<Vector6d> floor{constraintRow(Eigen::Vector3d::Zero(), Eigen::Vector3d::UnitZ(), Eigen::Vector3d::Zero())};
  const Vector6d a = projector.project(M, a_u, floor).a_c;
  EXPECT_NEAR(a[0], 1.0, 1e-15);
  EXPECT_NEAR(a[2], 0.0, 1e-15);
  // Pulling away from the floor is free.
  a_u[2] = 1.0;
  EXPECT_EQ(projector.project(M, a_u, floor).a_c, a_u);
}

TEST(ConeProjection, DoesNotAllocate) {
  std::mt19937 rng(1);
  ConeProjector projector(64);
  const Problem p = randomProblem(rng, 40, 4);
  test::AllocationGuard guard;
  const ConeProjection r = projector.project(p.M, p.a_u, p.J);
  EXPECT_EQ(guard.count(), 0u);
  EXPECT_TRUE(r.converged);
}

}  // namespace
}  // namespace vh::haptics
