// The proximity query per tick (ProximityQuery, distance_field.h), the pruned query against
// sampling every shell point (the reference), side by side in one run. The segment: a nerve-like
// tube (radius 1 mm, 30 mm long) on the head phantom's grid (0.45 x 0.45 x 1 mm voxels), its
// distance field stored 20 mm around it. The tool: a ball of radius 5 mm with 1,000 or 20,000
// points. Poses: "far" (30 mm away: beyond the 20 mm range), "near" (2 mm of clearance), "inside"
// (the ball's surface 0.5 mm into the tube). A ratio table follows Google Benchmark's own.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <map>
#include <memory>
#include <numbers>
#include <string>
#include <vector>

#include <benchmark/benchmark.h>

#include "vh/haptics/distance_field.h"

namespace {

using vh::haptics::DistanceField;
using vh::haptics::PointShell;
using vh::haptics::Pose;
using vh::haptics::ProximityQuery;

constexpr double kToolRadius_m = 5e-3;

std::shared_ptr<const DistanceField> nerveField() {
  static const auto field = [] {
    vh::haptics::VolumeGeometry g;
    g.dims = {160, 160, 80};  // 72 x 72 x 80 mm of the phantom's 512 x 512 x 140 grid
    g.spacing_m = {0.45e-3, 0.45e-3, 1e-3};
    std::vector<std::uint8_t> mask(g.voxelCount(), 0);
    for (int k = 25; k < 55; ++k)  // the tube along z through (36, 36) mm
      for (int j = 0; j < g.dims[1]; ++j)
        for (int i = 0; i < g.dims[0]; ++i)
          if (std::hypot(i * 0.45e-3 - 0.036, j * 0.45e-3 - 0.036) <= 1e-3) mask[g.indexOf(i, j, k)] = 1;
    return std::make_shared<const DistanceField>(DistanceField::FromMask(g, mask, 0.02));
  }();
  return field;
}

/// A Fibonacci sphere, its points in Morton (Z-curve) order as makePointShell() gives them.
PointShell ballShell(int n) {
  std::vector<std::pair<std::uint64_t, Eigen::Vector3d>> keyed;
  const double golden = std::numbers::pi * (3.0 - std::sqrt(5.0));
  for (int i = 0; i < n; ++i) {
    const double z = 1.0 - 2.0 * (i + 0.5) / n, r = std::sqrt(1.0 - z * z);
    const Eigen::Vector3d p(r * std::cos(golden * i), r * std::sin(golden * i), z);
    std::uint64_t key = 0;
    for (int bit = 9; bit >= 0; --bit)
      for (int a = 0; a < 3; ++a)
        key = (key << 1) | ((static_cast<std::uint64_t>((p[a] + 1.0) * 511.5) >> bit) & 1u);
    keyed.emplace_back(key, kToolRadius_m * p);
  }
  std::sort(keyed.begin(), keyed.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  std::vector<Eigen::Vector3d> points;
  for (const auto& [key, p] : keyed) points.push_back(p);
  return PointShell(std::move(points));
}

Pose poseAt(const std::string& where) {
  const double clearance = where == "far" ? 30e-3 : where == "near" ? 2e-3 : -0.5e-3;
  return Pose::FromTranslation({0.036 + 1e-3 + kToolRadius_m + clearance, 0.036, 0.040});
}

void BM_Pruned(benchmark::State& state, int points, std::string where) {
  ProximityQuery query({nerveField()}, ballShell(points), 0.02);
  const Pose X_WP = poseAt(where);
  for (auto _ : state) benchmark::DoNotOptimize(query.evaluate(X_WP));
  state.counters["sampled"] = static_cast<double>(query.pointsSampled());
}

void BM_EveryPoint(benchmark::State& state, int points, std::string where) {
  const PointShell shell = ballShell(points);
  const auto field = nerveField();
  const Pose X_WP = poseAt(where);
  for (auto _ : state) {
    double best = std::numeric_limits<double>::infinity();
    for (const auto& p : shell.points_T_m()) best = std::min(best, field->sample_m(X_WP * p));
    benchmark::DoNotOptimize(best);
  }
}

class RatioReporter : public benchmark::ConsoleReporter {
 public:
  void ReportRuns(const std::vector<Run>& runs) override {
    for (const Run& r : runs) {
      t_[r.benchmark_name()] = r.GetAdjustedRealTime();
      const auto c = r.counters.find("sampled");
      if (c != r.counters.end()) sampled_[r.benchmark_name()] = c->second.value;
    }
    ConsoleReporter::ReportRuns(runs);
  }
  void Finalize() override {
    ConsoleReporter::Finalize();
    std::printf("\n%-8s %-7s %14s %14s %8s %9s\n", "points", "pose", "pruned [us]", "every pt [us]", "ratio", "sampled");
    for (const int n : {1000, 20000}) {
      for (const char* w : {"far", "near", "inside"}) {
        const std::string key = std::to_string(n) + "/" + w;
        const double a = t_["Pruned/" + key], b = t_["EveryPoint/" + key];  // [us]
        std::printf("%-8d %-7s %14.2f %14.2f %7.1fx %9.0f\n", n, w, a, b, b / a, sampled_["Pruned/" + key]);
      }
    }
  }

 private:
  std::map<std::string, double> t_, sampled_;
};

}  // namespace

int main(int argc, char** argv) {
  for (const int n : {1000, 20000}) {
    for (const char* w : {"far", "near", "inside"}) {
      const std::string key = std::to_string(n) + "/" + w;
      benchmark::RegisterBenchmark(("Pruned/" + key).c_str(), BM_Pruned, n, std::string(w))->Unit(benchmark::kMicrosecond);
      benchmark::RegisterBenchmark(("EveryPoint/" + key).c_str(), BM_EveryPoint, n, std::string(w))
          ->Unit(benchmark::kMicrosecond);
    }
  }
  benchmark::Initialize(&argc, argv);
  RatioReporter reporter;
  benchmark::RunSpecifiedBenchmarks(&reporter);
  benchmark::Shutdown();
  return 0;
}
