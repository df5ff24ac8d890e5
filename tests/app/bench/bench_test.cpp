// vh::bench: each benchmark runs in its short version and writes well-formed reports. No timing
// thresholds: only structure, finiteness and counts are checked (the numbers are measurements).
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <set>
#include <fstream>
#include <iterator>
#include <sstream>
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "vh/bench/bench.h"

namespace vh::bench {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

json readJson(const fs::path& p) {
  std::ifstream in(p);
  EXPECT_TRUE(in.good()) << p;
  return json::parse(in);  // throws (and fails the test) on malformed JSON
}

std::string readText(const fs::path& p) {
  std::ifstream in(p);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// nlohmann-json writes NaN and infinity as null: a null anywhere means a non-finite number.
void expectNoNull(const json& j, const std::string& where = "$") {
  if (j.is_null()) {
    ADD_FAILURE() << where << " is null (a non-finite number?)";
    return;
  }
  if (j.is_object()) {
    for (const auto& [k, v] : j.items()) expectNoNull(v, where + "." + k);
  }
  if (j.is_array()) {
    for (std::size_t i = 0; i < j.size(); ++i) expectNoNull(j[i], where + "[" + std::to_string(i) + "]");
  }
  if (j.is_number_float()) {
    EXPECT_TRUE(std::isfinite(j.get<double>())) << where;
  }
}

double number(const json& j, const std::string& key) {
  EXPECT_TRUE(j.contains(key)) << "missing key " << key;
  if (!j.contains(key) || !j[key].is_number()) {
    ADD_FAILURE() << key << " is not a number";
    return 0.0;
  }
  return j[key].get<double>();
}

bool display() {
  const char* d = std::getenv("DISPLAY");
  return d != nullptr && *d != '\0';
}

void expectPngs(const fs::path& dir, const json& report, std::size_t at_least) {
  ASSERT_TRUE(report.contains("plots"));
  if (!display()) {
    std::cout << "no DISPLAY: plots are skipped by design, not checked\n";
    EXPECT_TRUE(report["plots"].empty());
    return;
  }
  EXPECT_GE(report["plots"].size(), at_least);
  for (const auto& name : report["plots"]) {
    const fs::path png = dir / name.get<std::string>();
    std::ifstream in(png, std::ios::binary);
    ASSERT_TRUE(in.good()) << png;
    unsigned char sig[8] = {};
    in.read(reinterpret_cast<char*>(sig), 8);
    const unsigned char expected[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
    EXPECT_EQ(0, std::memcmp(sig, expected, 8)) << png << " is not a PNG";
    EXPECT_GT(fs::file_size(png), 1000u) << png;
  }
}

/// The crossing fields of one run or mode (haptics::CrossingVerifier after every tick): present,
/// integers, consistent. @return the number of ticks with a crossing.
std::int64_t expectCrossingFields(const json& j, double ticks) {
  EXPECT_TRUE(j.contains("crossings")) << "missing key crossings";
  EXPECT_TRUE(j.contains("crossing_points")) << "missing key crossing_points";
  if (!j.contains("crossings") || !j["crossings"].is_number_integer()) {
    ADD_FAILURE() << "crossings is not an integer";
    return -1;
  }
  const auto crossings = j["crossings"].get<std::int64_t>();
  const auto points = j["crossing_points"].get<std::int64_t>();
  EXPECT_GE(crossings, 0) << "checked by default";
  EXPECT_LE(static_cast<double>(crossings), ticks);
  EXPECT_GE(points, crossings) << "a tick with a crossing has at least one point";
  EXPECT_EQ(points == 0, crossings == 0);
  if (j.contains("first_crossing_tick")) {
    const auto first = j["first_crossing_tick"].get<std::int64_t>();
    EXPECT_EQ(first == -1, crossings == 0) << first;
    EXPECT_LT(static_cast<double>(first), ticks);
  }
  return crossings;
}

fs::path outDir(const std::string& name) {
  const fs::path dir = fs::path(VH_BENCH_TEST_OUTPUT_DIR) / name;
  fs::remove_all(dir);
  return dir;
}

// A short table1 run of the built-in Hole scene in the accelerated mode only, into `out_name`.
Table1Options shortAcceleratedHole(const std::string& out_name) {
  Table1Options options;
  options.common.short_run = true;
  options.common.out_dir = outDir(out_name);
  options.scene = "Hole";
  options.modes = ModeSelection::kAccelerated;
  options.large_tools = false;
  options.verify_references = true;  // the full solves' crossings checked too (tests check them)
  return options;
}

TEST(Bench, table1AcceleratedModeKeepsItsWorkBudgetAndReportsItsLag) {
  // The accelerated column runs with the work budget (the application's setting) and
  // beside it without, interleaved. Work is counted, not timed: no tick exceeds the budget by
  // more than the pruning of a capped contact set and one queue step.
  Table1Options options = shortAcceleratedHole("table1-budget");
  options.work_budget = 3000;
  const fs::path dir = runTable1(options);
  const json report = readJson(dir / "table1.json");
  ASSERT_EQ(report["scenes"].size(), 1u);
  int ran = 0;
  for (const auto& row : report["scenes"]) {
    if (row["status"] != "ran") continue;
    ++ran;
    ASSERT_TRUE(row["modes"].contains("accelerated")) << row["name"];
    ASSERT_TRUE(row["modes"].contains("accelerated-unbudgeted")) << row["name"];
    const json& m = row["modes"]["accelerated"];
    EXPECT_EQ(number(m, "work_budget"), 3000.0);
    EXPECT_LE(number(m, "max_work"), 3000.0 + 64 * 12 + 200);
    EXPECT_GE(number(m, "budget_cuts"), 0.0);
    EXPECT_GE(number(m, "lag_ticks"), 0.0);
    EXPECT_GE(number(m, "max_lag_m"), 0.0);
    EXPECT_GE(number(m, "max_lag_rad"), 0.0);
    // Behind: the budgeted proxy's distance to the device less the full solve's, which the
    // triangle inequality bounds by their distance from each other (the lag).
    EXPECT_LE(number(m, "max_behind_m"), number(m, "max_lag_m") + 1e-12);
    EXPECT_LE(number(m, "max_behind_rad"), number(m, "max_lag_rad") + 1e-9);
    // The control: the full solve again with one device sample in 1,000 held (at tick 500 of
    // each thousand), its distance from the full solve.
    const json& full = row["modes"]["accelerated-unbudgeted"];
    ASSERT_TRUE(full.contains("held_samples")) << row["name"];
    const auto ticks = static_cast<std::int64_t>(number(full, "ticks"));
    EXPECT_EQ(number(full, "held_every"), 1000.0);
    EXPECT_EQ(number(full, "held_samples"), static_cast<double>((ticks + 499) / 1000));
    EXPECT_GE(number(full, "held_apart_max_m"), 0.0);
    EXPECT_GE(number(full, "held_apart_max_rad"), 0.0);
    EXPECT_FALSE(m.contains("held_samples")) << "the control runs beside the full solve only";
    EXPECT_EQ(number(m, "crossings"), 0.0) << row["name"];
    EXPECT_EQ(number(row["modes"]["accelerated-unbudgeted"], "crossings"), 0.0) << row["name"];
    EXPECT_FALSE(row["modes"]["accelerated-unbudgeted"].contains("work_budget"));
    ASSERT_TRUE(row.contains("never_behind")) << row["name"];
    EXPECT_TRUE(row["never_behind"]["met"].is_boolean());
  }
  EXPECT_EQ(ran, 1) << "the Hole scene is built in: it always runs";
  std::ifstream md(dir / "table1.md");
  const std::string text((std::istreambuf_iterator<char>(md)), std::istreambuf_iterator<char>());
  EXPECT_NE(text.find("Never behind:"), std::string::npos);
}

TEST(Bench, table1EdgeTestColumnRunsBesideTheAcceleratedModeAndNeverCrosses) {
  // --edge-test: the accelerated mode as the application runs it, again with the edge test
  // between shell points, interleaved; its cost over the accelerated mode in the same run.
  Table1Options options = shortAcceleratedHole("table1-edges");
  options.edge_test = true;
  const fs::path dir = runTable1(options);
  const json report = readJson(dir / "table1.json");
  ASSERT_EQ(report["scenes"].size(), 1u);
  const json& row = report["scenes"][0];
  ASSERT_EQ(row["status"], "ran");
  ASSERT_TRUE(row["modes"].contains("accelerated-edges"));
  const json& e = row["modes"]["accelerated-edges"];
  EXPECT_EQ(number(e, "crossings"), 0.0);
  EXPECT_GT(number(e, "cpu_mean_us"), 0.0);
  ASSERT_TRUE(row.contains("ratio_edges_over_accelerated"));
  const json& q = row["ratio_edges_over_accelerated"];
  EXPECT_NEAR(number(q, "cpu_mean"), number(e, "cpu_mean_us") / number(row["modes"]["accelerated"], "cpu_mean_us"), 1e-9);
  EXPECT_EQ(q["within_1_2x"].get<bool>(), number(q, "cpu_mean") <= 1.2);
  // The edge test's own time, and the rest of its ticks beside the ticks without it.
  EXPECT_GT(number(e, "edge_test_mean_us"), 0.0);
  EXPECT_NEAR(number(e, "cpu_mean_without_edge_test_us"), number(e, "cpu_mean_us") - number(e, "edge_test_mean_us"), 1e-9);
  EXPECT_NEAR(number(q, "cpu_mean_without_edge_test"),
              number(e, "cpu_mean_without_edge_test_us") / number(row["modes"]["accelerated"], "cpu_mean_us"), 1e-9);
  EXPECT_FALSE(row["modes"]["accelerated"].contains("edge_test_mean_us")) << "no edge test there";
  // Its lag: against the edge test's own full solve (no budget, no deadline), run beside it.
  ASSERT_TRUE(row["modes"].contains("accelerated-edges-unbudgeted"));
  const json& full = row["modes"]["accelerated-edges-unbudgeted"];
  EXPECT_EQ(number(full, "crossings"), 0.0);
  EXPECT_FALSE(full.contains("budget_cuts")) << "the reference runs the full solve";
  ASSERT_TRUE(e.contains("max_lag_m"));
  EXPECT_GE(number(e, "max_lag_m"), 0.0);
  EXPECT_LE(number(e, "lag_ticks"), number(e, "ticks"));
  // No tick cut: the same device samples give the full solve's proxy on every tick.
  if (number(e, "budget_cuts") == 0.0) EXPECT_EQ(number(e, "max_lag_m"), 0.0);
  ASSERT_TRUE(row.contains("never_behind_edges"));
  EXPECT_TRUE(row["never_behind_edges"]["met"].is_boolean());
  std::ifstream md(dir / "table1.md");
  const std::string text((std::istreambuf_iterator<char>(md)), std::istreambuf_iterator<char>());
  EXPECT_NE(text.find("| Hole, edge test |"), std::string::npos) << "its row in the Never behind table";
}

TEST(Bench, table1LanesSweepReportsHowEvenlyTheLanesSharedTheWork) {
  // --lanes-sweep: the full solve on each lane count, with the lanes' share of the work: all of
  // it over lanes x the work on the ticks' critical paths (TickStats::critical_work). Exactly 1
  // on one lane (nothing ran beside the caller), within (1 / lanes, 1] on several.
  Table1Options options = shortAcceleratedHole("table1-lanes");
  options.lane_sweep = {1, 2};
  const fs::path dir = runTable1(options);
  const json report = readJson(dir / "table1.json");
  ASSERT_EQ(report["scenes"].size(), 1u);
  const json& row = report["scenes"][0];
  ASSERT_EQ(row["status"], "ran");
  for (const int lanes : {1, 2}) {
    const std::string key = "accelerated-lanes-" + std::to_string(lanes);
    ASSERT_TRUE(row["modes"].contains(key)) << key;
    const json& m = row["modes"][key];
    EXPECT_EQ(number(m, "lanes_used"), lanes) << key;
    const double share = number(m, "lane_efficiency");
    if (lanes == 1) {
      EXPECT_EQ(share, 1.0);
    } else {
      EXPECT_GT(share, 1.0 / lanes) << "both lanes must have worked";
      EXPECT_LE(share, 1.0);
    }
  }
  std::ifstream md(dir / "table1.md");
  const std::string text((std::istreambuf_iterator<char>(md)), std::istreambuf_iterator<char>());
  EXPECT_NE(text.find("| lane efficiency |"), std::string::npos) << "the scaling table's column";
}

TEST(Bench, table1ShortWritesBothModesForEveryScene) {
  Table1Options options;
  options.common.short_run = true;
  options.common.out_dir = outDir("table1");
  options.before = true;  // the "before" column (end-sample segment test)
  options.verify_references = true;
  const fs::path dir = runTable1(options);
  const json report = readJson(dir / "table1.json");
  expectNoNull(report);
  for (const char* key : {"benchmark", "date_utc", "cpu_model", "ticks_per_run", "modes", "scenes",
                          "verify_step_voxels"})
    EXPECT_TRUE(report.contains(key)) << key;
  EXPECT_EQ(report["benchmark"], "table1");
  EXPECT_FALSE(report["cpu_model"].get<std::string>().empty());
  EXPECT_EQ(report["ticks_per_run"], 1000);
  EXPECT_EQ(report["verify_step_voxels"].get<double>(), 0.01);
  // Both detection modes, the accelerated one also without its work budget, by default also as
  // the application runs it (the edge test, budgeted and not), and the "before" column
  // (end-sample segment test).
  EXPECT_EQ(report["modes"], json({"paper", "accelerated", "accelerated-unbudgeted", "accelerated-edges",
                                   "accelerated-edges-unbudgeted", "accelerated-end-sample"}));
  ASSERT_EQ(report["scenes"].size(), 4u) << "one row per Table 1 scene (short runs have no large-tool rows)";
  int ran = 0;
  for (const json& row : report["scenes"]) {
    SCOPED_TRACE(row["name"].get<std::string>());
    if (row["status"] == "skipped") {
      std::cout << row["name"].get<std::string>() << " skipped: " << row["reason"].get<std::string>() << "\n";
      EXPECT_FALSE(row["reason"].get<std::string>().empty());
      EXPECT_NE(row["name"], "Hole") << "the Hole scene is built in and never skipped";
      continue;
    }
    ++ran;
    EXPECT_GT(number(row, "points"), 0.0);
    EXPECT_GT(number(row["paper"], "mean_us"), 0.0);
    ASSERT_TRUE(row["modes"].contains("paper"));
    ASSERT_TRUE(row["modes"].contains("accelerated"));
    ASSERT_TRUE(row["modes"].contains("accelerated-end-sample"));
    EXPECT_EQ(number(row, "verify_step_voxels"), 0.01);
    const bool builtin = row["volume"].get<std::string>().rfind("builtin:", 0) == 0;
    for (const char* mode : {"paper", "accelerated", "accelerated-unbudgeted", "accelerated-end-sample"}) {
      SCOPED_TRACE(mode);
      const json& m = row["modes"][mode];
      EXPECT_EQ(m["ticks"], 1000);
      EXPECT_EQ(m["segment_test"], std::string(mode) == "accelerated-end-sample" ? "end-sample" : "exact");
      EXPECT_FALSE(m["label"].get<std::string>().empty());
      EXPECT_LE(number(m, "cpu_mean_us"), number(m, "cpu_max_us"));
      EXPECT_LE(number(m, "cpu_p99_9_us"), number(m, "cpu_max_us"));
      EXPECT_GE(number(m, "mean_cells"), 0.0);
      // The crossing check ran on every mode's moves (after the run, outside the timed ticks).
      EXPECT_GT(number(m, "verify_s"), 0.0);
      const std::int64_t crossings = expectCrossingFields(m, 1000.0);
      // The exact segment test never lets the proxy through the surface; the end sample
      // (the "before" column) may. Asserted on the built-in scene; reported for the others.
      if (std::string(mode) != "accelerated-end-sample") {
        if (builtin) {
          EXPECT_EQ(crossings, 0) << "first at tick " << m["first_crossing_tick"];
        } else if (crossings != 0) {
          std::cout << "NOTE: " << mode << " mode crossed on " << crossings << " ticks\n";
        }
      }
      const double mean = number(m, "mean_us"), p50 = number(m, "p50_us"), p99 = number(m, "p99_us"),
                   p999 = number(m, "p99_9_us"), max = number(m, "max_us");
      EXPECT_GT(mean, 0.0);
      EXPECT_LE(p50, p99);
      EXPECT_LE(p99, p999);
      EXPECT_LE(p999, max);
      EXPECT_LE(mean, max);
      EXPECT_GE(number(m, "mean_contacts"), 0.0);
      EXPECT_LE(number(m, "mean_contacts"), number(m, "max_contacts"));
      EXPECT_GT(number(m, "mean_volume_samples"), 0.0);
      EXPECT_GE(number(m, "max_penetration_m"), 0.0);
      EXPECT_EQ(m["nan_ticks"], 0);
    }
    EXPECT_GT(number(row["ratio_paper_over_accelerated"], "mean"), 0.0);
    ASSERT_TRUE(row.contains("ratio_exact_over_end_sample"));
    const json& q = row["ratio_exact_over_end_sample"];
    EXPECT_GT(number(q, "cpu_mean"), 0.0);
    EXPECT_GT(number(q, "cpu_p99_9"), 0.0);
    EXPECT_GT(number(q, "cpu_max"), 0.0);
    EXPECT_TRUE(q["within_1_3x"].is_boolean());
    EXPECT_GE(number(row, "max_proxy_difference_exact_vs_end_sample_m"), 0.0);
    EXPECT_GT(number(row["modes"]["paper"], "max_contacts"), 0.0) << "the trajectory never touched the surface";
  }
  EXPECT_GE(ran, 1);
  const std::string md = readText(dir / "table1.md");
  EXPECT_NE(md.find("| scene | tool | points (paper) | mode | mean [us]"), std::string::npos);
  EXPECT_NE(md.find("| Hole |"), std::string::npos);
  EXPECT_NE(md.find("Speed-up of the accelerated path"), std::string::npos);
  EXPECT_NE(md.find("| max penetration [mm] (epsilon) | crossings |"), std::string::npos);
  EXPECT_NE(md.find("| accelerated (end-sample, before) |"), std::string::npos);
  EXPECT_NE(md.find("Before and after the exact segment test"), std::string::npos);
  EXPECT_NE(md.find("Exact segment test target"), std::string::npos);
  EXPECT_NE(md.find(report["cpu_model"].get<std::string>()), std::string::npos);
  expectPngs(dir, report, static_cast<std::size_t>(ran) + 2);
}

TEST(Bench, accuracyShortWritesCurvesParetoFrontAndRecommendation) {
  CommonOptions options;
  options.short_run = true;
  options.out_dir = outDir("accuracy");
  const fs::path dir = runAccuracy(options);
  const json report = readJson(dir / "accuracy.json");
  expectNoNull(report);
  EXPECT_EQ(report["benchmark"], "accuracy");
  // 4 surfaces x 1 resolution x 5 settings in the short version.
  ASSERT_EQ(report["runs"].size(), 20u);
  std::set<std::string> surfaces;
  for (const json& r : report["runs"]) {
    surfaces.insert(r["surface"].get<std::string>());
    EXPECT_GT(number(r, "mean_us"), 0.0);
    EXPECT_GE(number(r, "position_error_mean_m"), 0.0);
    EXPECT_LE(number(r, "position_error_mean_m"), number(r, "position_error_max_m"));
    EXPECT_GE(number(r, "normal_error_mean_deg"), 0.0);
    EXPECT_LE(number(r, "normal_error_max_deg"), 180.0);
    EXPECT_TRUE(r["finite"].get<bool>());
    // Synthetic volumes, default (exact) segment test: never through the grid's isosurface.
    EXPECT_EQ(expectCrossingFields(r, number(r, "ticks")), 0)
        << r["surface"].get<std::string>() << ", " << r["voxel_m"] << " m voxels";
  }
  EXPECT_EQ(surfaces.size(), 4u);
  EXPECT_EQ(report["verify_step_voxels"].get<double>(), 0.01);
  EXPECT_EQ(report["crossings_total"].get<int>(), 0);
  for (const json& p : report["settings"]) EXPECT_TRUE(p["crossings"].is_number_integer());
  ASSERT_FALSE(report["pareto_front"].empty());
  EXPECT_LE(report["pareto_front"].size(), report["settings"].size());
  ASSERT_TRUE(report.contains("recommended"));
  const std::string md = readText(dir / "accuracy.md");
  EXPECT_NE(md.find("### Recommended defaults"), std::string::npos);
  EXPECT_NE(md.find("| surface | voxel [mm] | setting |"), std::string::npos);
  EXPECT_NE(md.find("| max penetration [mm] (epsilon) | crossings |"), std::string::npos);
  EXPECT_NE(md.find("| max penetration / epsilon | crossings | Pareto |"), std::string::npos);
  expectPngs(dir, report, 2);
}

TEST(Bench, stabilityShortWritesSweepAndExtremeCases) {
  CommonOptions options;
  options.short_run = true;
  options.out_dir = outDir("stability");
  const fs::path dir = runStability(options);
  const json report = readJson(dir / "stability.json");
  expectNoNull(report);
  EXPECT_EQ(report["benchmark"], "stability");
  ASSERT_EQ(report["stiffness_sweep"].size(), 3u);
  for (const json& r : report["stiffness_sweep"]) {
    EXPECT_GT(number(r, "k_lin_N_per_m"), 0.0);
    EXPECT_GE(number(r, "peak_force_N"), 0.0);
    EXPECT_GE(number(r, "settled_ptp_N"), 0.0);
    EXPECT_TRUE(r.contains("behaviour"));
  }
  ASSERT_EQ(report["extreme_cases"].size(), 8u);
  for (const json& c : report["extreme_cases"]) {
    SCOPED_TRACE(c["name"].get<std::string>());
    for (const char* mode : {"paper", "accelerated"}) {
      ASSERT_TRUE(c["modes"].contains(mode));
      const std::string outcome = c["modes"][mode]["outcome"];
      EXPECT_TRUE(outcome == "pass" || outcome.rfind("FAIL:", 0) == 0) << outcome;
      EXPECT_GT(number(c["modes"][mode], "ticks"), 0.0);
      // Both modes use the exact segment test: no crossing, and a crossing would fail the case.
      const std::int64_t crossings = expectCrossingFields(c["modes"][mode], number(c["modes"][mode], "ticks"));
      EXPECT_EQ(crossings, 0) << mode;
      if (crossings > 0) {
        EXPECT_NE(outcome.find("crossings"), std::string::npos) << outcome;
      }
    }
  }
  // Device models: each at its rated stiffness and at 50,000 N/m, controller off and
  // on; every model stable at its rating without the controller.
  ASSERT_EQ(report["device_models"].size(), 24u);
  int rated_stable = 0;
  for (const json& r : report["device_models"]) {
    EXPECT_TRUE(r.contains("behaviour"));
    EXPECT_GE(number(r, "hold_travel_counts"), 0.0);
    EXPECT_EQ(number(r, "crossings"), 0.0) << r["device"];
    if (r["rated"].get<bool>() && !r["passivity_control"].get<bool>()) rated_stable += r["stable"].get<bool>() ? 1 : 0;
  }
  EXPECT_EQ(rated_stable, 6);
  ASSERT_EQ(report["controller_price"].size(), 6u);
  for (const json& p : report["controller_price"]) EXPECT_LE(number(p, "hold_force_error_rel"), 0.05) << p["device"];
  const std::string md = readText(dir / "stability.md");
  EXPECT_NE(md.find("### Device models, with and without the passivity controller"), std::string::npos);
  EXPECT_NE(md.find("| K [N/m] |"), std::string::npos);
  EXPECT_NE(md.find("| case | set-up |"), std::string::npos);
  EXPECT_NE(md.find("| penetration / epsilon | crossings |"), std::string::npos);
  EXPECT_EQ(report["verify_step_voxels"].get<double>(), 0.01);
  expectPngs(dir, report, 1);
}

}  // namespace
}  // namespace vh::bench

namespace vh::bench {
namespace {
// Drilling: the six capsule cases within one voxel layer of the analytic swept volume (the
// oracle), and the drilling/touching ratios of one run, side by side (no timing threshold here:
// the target lives in the report).
TEST(Bench, drillingShortWritesCapsuleCasesAndRatios) {
  CommonOptions options;
  options.short_run = true;
  options.out_dir = std::filesystem::path(VH_BENCH_TEST_OUTPUT_DIR) / "drilling";
  const std::filesystem::path dir = runDrilling(options);
  std::ifstream in(dir / "drilling.json");
  const nlohmann::json report = nlohmann::json::parse(in);
  ASSERT_EQ(report["capsule_cases"].size(), 6u);
  for (const auto& c : report["capsule_cases"]) {
    EXPECT_LE(c["error_voxel_layers"].get<double>(), 1.0) << c.dump();
    EXPECT_GT(c["removed_mm3"].get<double>(), 0.0);
  }
  if (report.contains("timing_skipped")) GTEST_SKIP() << report["timing_skipped"].get<std::string>();
  EXPECT_GT(report["p99_9_ratio"].get<double>(), 0.0);
  EXPECT_GT(report["max_ratio"].get<double>(), 0.0);
  EXPECT_GT(report["removed_mm3"].get<double>(), 0.0) << "the scripted press reaches the skull and cuts";
  EXPECT_GT(report["contact_ticks"].get<int>(), 0);
}
// bench tissue, short: the gel (and the CT head's soft tissue when the shared data is there) built
// as the application builds them, pressed, slid and lifted with tissue and rigid; the report's
// figures are printed, not asserted, beside what must hold on any machine: the press indents the
// tissue, neither felt field is crossed, the CT head's region fits the compliance table's limit.
TEST(Bench, tissueShortPressesTheGelAndTheHeadWithoutCrossing) {
  CommonOptions options;
  options.short_run = true;
  options.out_dir = std::filesystem::path(VH_BENCH_TEST_OUTPUT_DIR) / "tissue";
  const std::filesystem::path dir = runTissue(options);
  std::ifstream in(dir / "tissue.json");
  const nlohmann::json report = nlohmann::json::parse(in);
  ASSERT_GE(report["scenes"].size(), 1u);
  for (const auto& row : report["scenes"]) {
    ASSERT_FALSE(row.contains("refused")) << row.dump();
    EXPECT_GT(row["ticks"].get<int>(), 1000);
    EXPECT_EQ(row["tissue_crossings"].get<int>(), 0) << row["scene"];
    EXPECT_EQ(row["rigid_crossings"].get<int>(), 0) << row["scene"];
    EXPECT_GT(row["deepest_indentation_m"].get<double>(), 0.3e-3) << row["scene"] << ": the tissue did not yield";
    EXPECT_GT(row["tissue_tick"]["mean_us"].get<double>(), 0.0);
    EXPECT_LT(row["tissue_peak_force_N"].get<double>(), row["rigid_peak_force_N"].get<double>())
        << row["scene"] << ": the same press on tissue must feel softer than on the rigid scan";
  }
  if (report.contains("head_skipped")) std::printf("%s\n", report["head_skipped"].get<std::string>().c_str());
  else EXPECT_EQ(report["scenes"].size(), 2u);
  ASSERT_EQ(report["lattice_sweep"].size(), 2u);
  EXPECT_LT(report["lattice_sweep"][0]["lattice_nodes"].get<int>(), report["lattice_sweep"][1]["lattice_nodes"].get<int>());
}

}  // namespace
}  // namespace vh::bench
