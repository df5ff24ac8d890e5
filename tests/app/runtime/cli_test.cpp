// Tests of the volume-haptics executable's headless subcommands (ui/volume-haptics/main.cpp), run
// as a child process without a display: exit codes and messages for bad input, a report for good
// input.
#include <sys/wait.h>

#include <unistd.h>

#include <array>
#include <cstdio>
#include <fstream>
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "runtime_test_support.h"
#include "vh/runtime/recording.h"
#include "vh/runtime/session_metrics.h"
#include "vh/runtime/trajectory.h"

namespace vh::runtime {
namespace {

namespace fs = std::filesystem;

struct ProcessResult {
  int exit_code = -1;
  std::string output;  // stdout and stderr
};

std::string quoted(const fs::path& p) {
  std::string out(1, '\'');  // built by appending: GCC 12 warns falsely on "'" + std::string
  out.append(p.string());
  out.push_back('\'');
  return out;
}

/// Runs volume-haptics with `args` (already quoted) and no display.
ProcessResult runApp(const std::string& args) {
  const std::string command =
      "env -u DISPLAY -u WAYLAND_DISPLAY " + quoted(VH_APP_EXECUTABLE) + " " + args + " 2>&1";
  ProcessResult result;
  FILE* pipe = popen(command.c_str(), "r");
  if (pipe == nullptr) return result;
  std::array<char, 4096> buffer{};
  while (std::fgets(buffer.data(), static_cast<int>(buffer.size()), pipe) != nullptr) result.output += buffer.data();
  const int status = pclose(pipe);
  result.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return result;
}

const fs::path kBlockScene = test::sourceDir() / "resources" / "scenes" / "block-peg.json";

TEST(Cli, HelpListsTheSubcommands) {
  const ProcessResult r = runApp("--help");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("run"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("make-trajectory"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("--screenshot"), std::string::npos) << r.output;
}

TEST(Cli, RunHelpExplainsEveryFigureOfTheSummaryLine) {
  const ProcessResult r = runApp("run --help");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  for (const char* figure : {"exec", "points", "contacts", "max force", "penetration", "nan ticks", "bad samples",
                             "crossings", "edges =", "work budget", "lag =", "behind =", "drilled =", "touched =",
                             "--note"})
    EXPECT_NE(r.output.find(figure), std::string::npos) << "run --help does not explain '" << figure << "'";
}

TEST(Cli, RunNeedsSceneAndTrajectory) {
  const ProcessResult r = runApp("run --trajectory t.csv");
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.output.find("--scene"), std::string::npos) << r.output;
}

TEST(Cli, RunWithAMissingSceneFailsNamingIt) {
  const ProcessResult r = runApp("run --scene /no/such/scene.json --trajectory /no/such/t.csv");
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("volume-haptics: error: /no/such/scene.json: scene file not found"), std::string::npos)
      << r.output;
}

TEST(Cli, RunWithABadTrajectoryNamesFileAndLine) {
  const fs::path csv = test::writeText(test::scratchDir() / "bad.csv", "t_s,x_m,y_m,z_m,qw,qx,qy,qz\n0,0,0,0.1,1,0,0,0\n1,x,0,0,1,0,0,0\n");
  const ProcessResult r = runApp("run --scene " + quoted(kBlockScene) + " --trajectory " + quoted(csv));
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find(csv.string() + ":3: column x_m: 'x' is not a number"), std::string::npos) << r.output;
}

TEST(Cli, GuiWithAMissingPathFailsBeforeOpeningAWindow) {
  const ProcessResult r = runApp("/no/such/volume.nrrd");
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("/no/such/volume.nrrd: no such file or folder"), std::string::npos) << r.output;
}

TEST(Cli, OutputFoldersAreCreatedOrRefusedBeforeTheLoad) {
  const fs::path dir = test::scratchDir() / "outputs";
  fs::remove_all(dir);
  const fs::path csv = dir / "t.csv";
  // make-trajectory into a folder that does not exist yet: created.
  const ProcessResult made = runApp("make-trajectory --scene " + quoted(kBlockScene) +
                                    " --ray-start 0.015 0 0.04 --slide-m 0.002 --out " + quoted(dir / "traj" / "t.csv"));
  ASSERT_EQ(made.exit_code, 0) << made.output;
  ASSERT_TRUE(fs::exists(dir / "traj" / "t.csv"));
  fs::copy_file(dir / "traj" / "t.csv", csv);
  // run --record and --report into missing folders: created, the files written.
  const fs::path rec = dir / "rec" / "a" / "t.vhrec";
  const ProcessResult ran = runApp("run --verify-step 0 --scene " + quoted(kBlockScene) + " --trajectory " + quoted(csv) +
                                   " --record " + quoted(rec) + " --note 'trainee A' --report " +
                                   quoted(dir / "reports" / "r.json"));
  ASSERT_EQ(ran.exit_code, 0) << ran.output;
  EXPECT_TRUE(fs::exists(rec));
  EXPECT_TRUE(fs::exists(dir / "reports" / "r.json"));
  EXPECT_EQ(computeSessionMetrics(readRecording(rec)).label, "trainee A") << "--note is the cohort table's label";
  // A folder that cannot be made (a file is in the way): refused before the scene is read (the
  // scene named does not exist, and the message is about the recording's folder).
  test::writeText(dir / "blocker", "a file");
  const ProcessResult refused = runApp("run --scene /no/such/scene.json --trajectory " + quoted(csv) + " --record " +
                                       quoted(dir / "blocker" / "sub" / "t.vhrec"));
  EXPECT_EQ(refused.exit_code, 1) << refused.output;
  EXPECT_NE(refused.output.find("--record"), std::string::npos) << refused.output;
  EXPECT_NE(refused.output.find("cannot create the folder"), std::string::npos) << refused.output;
  EXPECT_EQ(refused.output.find("scene file not found"), std::string::npos) << refused.output;
}

TEST(Cli, MakeTrajectoryThenRunWithoutADisplay) {
  const fs::path dir = test::scratchDir();
  const fs::path csv = dir / "t.csv";
  const fs::path report = dir / "report.json";
  const ProcessResult made = runApp("make-trajectory --scene " + quoted(kBlockScene) +
                                    " --ray-start 0.015 0 0.04 --slide-dir 0 1 0 --slide-m 0.01 --out " + quoted(csv));
  ASSERT_EQ(made.exit_code, 0) << made.output;
  const Trajectory trajectory = loadTrajectoryCsv(csv);
  EXPECT_GT(trajectory.duration_s(), 3.0);
  EXPECT_NEAR(trajectory.samples().front().X_WD.p_AB_m.x(), 0.015, 1e-12);

  const ProcessResult ran =
      runApp("run --check --scene " + quoted(kBlockScene) + " --trajectory " + quoted(csv) + " --report " + quoted(report));
  ASSERT_EQ(ran.exit_code, 0) << ran.output;
  EXPECT_NE(ran.output.find("volume-haptics run: ticks"), std::string::npos) << ran.output;
  std::ifstream in(report);
  ASSERT_TRUE(in.good()) << report;
  const nlohmann::json j = nlohmann::json::parse(in);
  EXPECT_EQ(j["ticks"].get<std::uint64_t>(), static_cast<std::uint64_t>(trajectory.duration_s() * 1000.0 + 1e-9) + 1);
  EXPECT_GT(j["max_contacts"].get<int>(), 0);
  EXPECT_LE(j["max_penetration_m"].get<double>(), j["epsilon_m"].get<double>());
  EXPECT_EQ(j["nan_ticks"].get<int>(), 0);
  // --check also fails on crossings; checked by default at 0.01 voxel.
  EXPECT_EQ(j["crossings"].get<std::int64_t>(), 0);
  EXPECT_EQ(j["crossing_points"].get<std::int64_t>(), 0);
  EXPECT_EQ(j["first_crossing_tick"].get<std::int64_t>(), -1);
  EXPECT_DOUBLE_EQ(j["verify_step_voxels"].get<double>(), 0.01);
  EXPECT_NE(ran.output.find("crossings 0 (checked at 0.01 voxel)"), std::string::npos) << ran.output;

  // --verify-step 0: not checked, reported as null (not 0), and --check says so.
  const fs::path report_off = dir / "report-off.json";
  const ProcessResult off = runApp("run --check --verify-step 0 --scene " + quoted(kBlockScene) + " --trajectory " +
                                   quoted(csv) + " --report " + quoted(report_off));
  ASSERT_EQ(off.exit_code, 0) << off.output;
  EXPECT_NE(off.output.find("crossings not checked"), std::string::npos) << off.output;
  EXPECT_NE(off.output.find("warning: --check without the crossing check"), std::string::npos) << off.output;
  std::ifstream in_off(report_off);
  const nlohmann::json j_off = nlohmann::json::parse(in_off);
  EXPECT_TRUE(j_off["crossings"].is_null());
  EXPECT_EQ(j_off["verify_step_voxels"].get<double>(), 0.0);

  const ProcessResult negative =
      runApp("run --verify-step -1 --scene " + quoted(kBlockScene) + " --trajectory " + quoted(csv));
  EXPECT_NE(negative.exit_code, 0) << negative.output;
  EXPECT_NE(negative.output.find("--verify-step"), std::string::npos) << negative.output;
}

}  // namespace
TEST(Cli, RunStreamsOverOpenIgtlinkOnlyWhenAsked) {
  const fs::path dir = test::scratchDir();
  const fs::path csv = dir / "t.csv";
  ASSERT_EQ(runApp("make-trajectory --scene " + quoted(kBlockScene) + " --ray-start 0.015 0 0.04 --slide-m 0.002 --out " +
                   quoted(csv)).exit_code, 0);
  const std::string common = " --verify-step 0 --no-lag-reference --scene " + quoted(kBlockScene) + " --trajectory " + quoted(csv);
  const ProcessResult off = runApp("run" + common);
  ASSERT_EQ(off.exit_code, 0) << off.output;
  EXPECT_EQ(off.output.find("OpenIGTLink"), std::string::npos) << "off by default: " << off.output;
  // A port from a pid-dependent range (no client connects: the run streams to nobody).
  const int port = 40000 + static_cast<int>(getpid() % 20000);
  const ProcessResult on = runApp("run --igtl-port " + std::to_string(port) + " --igtl-rate 5000" + common);
  ASSERT_EQ(on.exit_code, 0) << on.output;
  EXPECT_NE(on.output.find("OpenIGTLink: listening on 127.0.0.1:" + std::to_string(port) + " at 1000 Hz"), std::string::npos)
      << "the rate is clamped to the servo rate: " << on.output;
  EXPECT_NE(on.output.find("OpenIGTLink sent 0 frames to 0 clients"), std::string::npos) << on.output;
  // Every interface only with the clients named.
  const ProcessResult open = runApp("run --igtl-port " + std::to_string(port) + " --igtl-bind 0.0.0.0" + common);
  EXPECT_NE(open.exit_code, 0) << open.output;
  EXPECT_NE(open.output.find("--igtl-allow"), std::string::npos) << open.output;
  const ProcessResult bad = runApp("run --igtl-port 0" + common);
  EXPECT_NE(bad.exit_code, 0);
  EXPECT_NE(bad.output.find("--igtl-port"), std::string::npos) << bad.output;
}

TEST(Cli, RunOnAGappedSeriesWarnsAndGoesOn) {
  // Every clinical scan opens: a CT series with a missing slice opens; the headless run says
  // where the gap is.
  const fs::path head = test::sharedDatasets() / "ct" / "ct-head-small";
  if (!fs::exists(head)) GTEST_SKIP() << "shared dataset missing: " << head;
  const fs::path dir = test::scratchDir();
  const fs::path series = dir / "gapped";
  fs::create_directories(series);
  for (const auto& e : fs::directory_iterator(head)) {
    if (e.path().filename() != "CTHead50.dcm") fs::copy_file(e.path(), series / e.path().filename());
  }
  const fs::path scene = test::writeText(dir / "s.json", "{\"volume\": {\"path\": " + nlohmann::json(series.string()).dump() + "}}");
  const fs::path csv = test::writeText(dir / "t.csv", "0,0,0,0.4,1,0,0,0\n0.01,0,0,0.4,1,0,0,0\n");
  const fs::path report = dir / "report.json";
  const ProcessResult ran = runApp("run --verify-step 0 --no-lag-reference --scene " + quoted(scene) +
                                   " --trajectory " + quoted(csv) + " --report " + quoted(report));
  ASSERT_EQ(ran.exit_code, 0) << ran.output;
  EXPECT_NE(ran.output.find("volume-haptics run: warning: missing slice"), std::string::npos) << ran.output;
  EXPECT_NE(ran.output.find("CTHead49.dcm"), std::string::npos) << ran.output;
  EXPECT_NE(ran.output.find("CTHead51.dcm"), std::string::npos) << ran.output;
  std::ifstream in(report);
  const nlohmann::json j = nlohmann::json::parse(in);
  ASSERT_FALSE(j["volume_notices"].empty());
  EXPECT_EQ(j["volume_dims"][2].get<int>(), 93);

  // A series the folder does not hold is an error that lists what it holds.
  const ProcessResult wrong = runApp("run --series lung --verify-step 0 --no-lag-reference --scene " + quoted(scene) +
                                     " --trajectory " + quoted(csv));
  EXPECT_NE(wrong.exit_code, 0) << wrong.output;
  EXPECT_NE(wrong.output.find("no series matches 'lung'"), std::string::npos) << wrong.output;
}

}  // namespace vh::runtime
