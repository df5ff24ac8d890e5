// Recordings end to end: `volume-haptics run --record` and `export` on a built-in scene (the
// recording replays bit for bit through the scene reloaded from its metadata), and a recorded
// session on the CT head phantom whose CSV export is read back with VTK's spreadsheet-style
// reader (vtkDelimitedTextReader). The phantom test is skipped with a message when the shared
// datasets are absent.
#include <array>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <vtkDelimitedTextReader.h>
#include <vtkNew.h>
#include <vtkTable.h>
#include <vtkVariant.h>

#include "runtime_test_support.h"
#include "vh/runtime/placement.h"
#include "vh/runtime/recording.h"
#include "vh/runtime/replay.h"
#include "vh/runtime/runner.h"
#include "vh/runtime/session_metadata.h"

namespace vh::runtime {
namespace {

namespace fs = std::filesystem;

/// Runs a shell command; returns its exit status and puts stdout + stderr in `output`.
int runCommand(const std::string& command, std::string& output) {
  FILE* pipe = popen((command + " 2>&1").c_str(), "r");
  if (pipe == nullptr) return -1;
  std::array<char, 4096> buffer{};
  while (std::fgets(buffer.data(), static_cast<int>(buffer.size()), pipe) != nullptr) output += buffer.data();
  return pclose(pipe);
}

std::string quoted(const fs::path& p) {
  std::string out(1, '\'');  // built by appending: GCC 12 warns falsely on "'" + std::string
  out.append(p.string());
  out.push_back('\'');
  return out;
}

TEST(RecordingCli, RunRecordWritesAReplayableRecordingAndExportWritesEvents) {
  const fs::path dir = test::scratchDir();
  const fs::path scene = test::writeText(dir / "sphere.json", R"({
    "volume": {"path": "builtin:sphere"},
    "tool": {"mesh": "builtin:sphere", "point_spacing_m": 0.0015},
    "coupling": {"linear_N_per_m": 1000, "angular_Nm_per_rad": 1.0}})");
  const auto at = [](double t, double x, double z) {
    TrajectorySample s;
    s.t_s = t;
    s.X_WD.p_AB_m = {x, 0.0, z};
    return s;
  };
  writeTrajectoryCsv(Trajectory({at(0.0, 0.0, 0.030), at(0.4, 0.0, 0.022), at(1.2, 0.006, 0.022)}),
                     dir / "press.csv");
  const fs::path rec_path = dir / "run.vhrec";
  std::string output;
  const std::string app = "env -u DISPLAY -u WAYLAND_DISPLAY '" + std::string(VH_APP_EXECUTABLE) + "'";
  ASSERT_EQ(runCommand(app + " run --scene " + quoted(scene) + " --trajectory " + quoted(dir / "press.csv") +
                           " --record " + quoted(rec_path),
                       output),
            0)
      << output;
  EXPECT_NE(output.find("recording written to"), std::string::npos) << output;

  const Recording rec = readRecording(rec_path);
  ASSERT_TRUE(rec.warnings.empty()) << rec.warnings.front();
  ASSERT_EQ(rec.records.size(), 1201u);  // t = 0 .. 1.2 s at 1 kHz
  EXPECT_EQ(rec.dropped_records, 0u);    // the runner waits for the writer instead of dropping
  std::size_t contact_ticks = 0;
  for (std::size_t i = 0; i < rec.records.size(); ++i) {
    ASSERT_EQ(rec.records[i].tick, i + 1);
    ASSERT_EQ(rec.records[i].time_s, static_cast<double>(i) / 1000.0);
    contact_ticks += rec.records[i].contacts > 0 ? 1 : 0;
  }
  EXPECT_GT(contact_ticks, 500u);
  const nlohmann::json meta = nlohmann::json::parse(rec.metadata_json);
  EXPECT_EQ(meta.at("device").at("kind"), "scripted");
  EXPECT_EQ(meta.at("scene").at("source"), scene.string());
  EXPECT_EQ(meta.at("servo_rate_Hz"), 1000.0);
  // The recorded initial pose is the trajectory's first: the replay starts where the run did.
  EXPECT_EQ(meta.at("scene").at("tool").at("initial_pose").at("p_m")[2], 0.030);
  const ReplayComparison replay = replayRecording(loadScene(sceneFromSessionMetadata(rec.metadata_json)), rec);
  EXPECT_TRUE(replay.identical) << "first difference at tick " << replay.first_mismatch_tick.value_or(0) << ": "
                                << replay.mismatch;
  EXPECT_EQ(replay.forces_compared, rec.records.size());

  // export: CSV, JSON and the events CSV (a marker added to a copy of the recording's events).
  RecordingWriter writer(dir / "with-events.vhrec", rec.metadata_json);
  for (const TickRecord& r : rec.records) writer.pushWaiting(r);
  writer.addEvent({0.5, 501, "marker", R"({"label":"press"})"});
  writer.close();
  output.clear();
  ASSERT_EQ(runCommand(app + " export " + quoted(dir / "with-events.vhrec") + " --csv " + quoted(dir / "out.csv") +
                           " --json " + quoted(dir / "out.json") + " --events-csv " + quoted(dir / "events.csv"),
                       output),
            0)
      << output;
  EXPECT_NE(output.find("1201 records, 1 events"), std::string::npos) << output;
  std::ifstream events_in(dir / "events.csv");
  std::string line;
  ASSERT_TRUE(std::getline(events_in, line));
  EXPECT_EQ(line, "t_s,tick,type,detail_json");
  ASSERT_TRUE(std::getline(events_in, line));
  EXPECT_EQ(line, "0.5,501,\"marker\",\"{\"\"label\"\":\"\"press\"\"}\"");
  std::ifstream json_in(dir / "out.json");
  const nlohmann::json j = nlohmann::json::parse(json_in);
  EXPECT_EQ(j.at("records"), 1201);
  ASSERT_EQ(j.at("events").size(), 1u);
  EXPECT_EQ(j.at("events")[0].at("detail").at("label"), "press");
}

TEST(RecordingPhantom, CsvExportOfAPhantomSessionOpensInASpreadsheetStyleReader) {
  const fs::path data = test::sharedDatasets() / "ct" / "philips-head-phantom-bone";
  const fs::path mesh = test::sharedDatasets() / "meshes" / "drill" / "drill.stl";
  if (!fs::exists(data) || !fs::exists(mesh)) GTEST_SKIP() << "shared dataset absent: " << data << " or " << mesh;
  const fs::path dir = test::scratchDir();
  const LoadedScene scene = loadScene(loadSceneFile(test::sourceDir() / "resources" / "scenes" / "phantom-drill.json"));
  const auto& field = *scene.volume.field;
  // A short push-and-slide (about 1.8 s of ticks).
  PushSlideOptions push;
  push.hold_s = 0.1;
  push.approach_time_s = 0.3;
  push.push_time_s = 0.4;
  push.slide_time_s = 0.6;
  push.retract_time_s = 0.2;
  push.start_clearance_m = 0.005;
  push.push_depth_m = 0.003;
  push.slide_m = 0.006;
  const haptics::Pose start = poseAboveVolume(field, scene.tool->point_shell, scene.X_WT_initial.R_AB, 0.005);
  const PushSlidePlan plan = makePushSlideTrajectory(field, scene.tool->point_shell, scene.isovalue, start, push);
  RunOptions options;
  options.check_penetration = false;
  options.record = dir / "phantom.vhrec";
  const auto t0 = std::chrono::steady_clock::now();
  const RunReport report = runHeadless(scene, plan.trajectory, options);
  std::cout << "[ phantom ] " << report.ticks << " ticks recorded in "
            << std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count()
            << " s (incl. the dataset's SHA-256); " << fs::file_size(options.record) << " bytes" << std::endl;
  const Recording rec = readRecording(options.record);
  ASSERT_TRUE(rec.warnings.empty()) << rec.warnings.front();
  ASSERT_EQ(rec.records.size(), report.ticks);
  EXPECT_GT(report.ticks_in_contact, 0u);
  const nlohmann::json meta = nlohmann::json::parse(rec.metadata_json);
  EXPECT_EQ(meta.at("dataset").at("kind"), "dicom-folder");
  EXPECT_EQ(meta.at("dataset").at("sha256").get<std::string>().size(), 64u);
  EXPECT_EQ(meta.at("dataset").at("dims"), nlohmann::json::parse("[512,512,140]"));
  EXPECT_EQ(meta.at("tool").at("point_count"), scene.tool->point_shell.size());
  EXPECT_NO_THROW(sceneFromSessionMetadata(rec.metadata_json));  // the dataset on disk is the recorded one

  const fs::path csv = dir / "phantom.csv";
  writeRecordingCsv(rec, csv);
  vtkNew<vtkDelimitedTextReader> reader;
  reader->SetFileName(csv.string().c_str());
  reader->SetFieldDelimiterCharacters(",");
  reader->SetHaveHeaders(true);
  reader->SetDetectNumericColumns(true);
  reader->SetForceDouble(true);
  reader->Update();
  vtkTable* table = reader->GetOutput();
  ASSERT_NE(table, nullptr);
  const std::vector<std::string> expected = {
      "t_s",        "tick",       "device_x_m", "device_y_m", "device_z_m", "device_qw",   "device_qx",
      "device_qy",  "device_qz",  "proxy_x_m",  "proxy_y_m",  "proxy_z_m",  "proxy_qw",    "proxy_qx",
      "proxy_qy",   "proxy_qz",   "force_x_N",  "force_y_N",  "force_z_N",  "torque_x_Nm", "torque_y_Nm",
      "torque_z_Nm", "contacts",  "isovalue",   "tick_time_s", "flags", "critical_distance_m", "critical_segment",
      "removed_voxels", "deadline_work"};
  ASSERT_EQ(table->GetNumberOfColumns(), static_cast<vtkIdType>(expected.size()));
  for (std::size_t c = 0; c < expected.size(); ++c)
    EXPECT_EQ(std::string(table->GetColumnName(static_cast<vtkIdType>(c))), expected[c]);
  ASSERT_EQ(table->GetNumberOfRows(), static_cast<vtkIdType>(rec.records.size()));
  std::size_t contact_rows = 0;
  for (std::size_t i = 0; i < rec.records.size(); i += 97) {
    const TickRecord& r = rec.records[i];
    const auto row = static_cast<vtkIdType>(i);
    const auto value = [&](const char* column) { return table->GetValueByName(row, column).ToDouble(); };
    EXPECT_DOUBLE_EQ(value("t_s"), r.time_s) << "row " << i;
    EXPECT_EQ(value("tick"), static_cast<double>(r.tick));
    EXPECT_DOUBLE_EQ(value("proxy_z_m"), r.p_WP_m[2]) << "row " << i;
    EXPECT_DOUBLE_EQ(value("device_x_m"), r.p_WD_m[0]) << "row " << i;
    EXPECT_DOUBLE_EQ(value("force_z_N"), r.force_W_N[2]) << "row " << i;
    EXPECT_DOUBLE_EQ(value("isovalue"), 400.0);
    EXPECT_EQ(value("contacts"), static_cast<double>(r.contacts));
    contact_rows += r.contacts > 0 ? 1 : 0;
  }
  EXPECT_GT(contact_rows, 0u) << "the sampled rows include contact ticks (forces non-zero)";
}

}  // namespace
}  // namespace vh::runtime
