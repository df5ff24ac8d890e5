// Tests of `--anonymize` (app/runtime/src/anonymize.cpp): the replacement UID, and the
// command line's exports and reports of a recording of the shared CT head, whose folder is
// named after the patient as clinical exports often are: with --anonymize none of the
// patient's identifiers is in any output file (grep is the oracle), without it they are.
#include <array>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "runtime_test_support.h"
#include "vh/runtime/anonymize.h"

namespace vh::runtime {
namespace {

namespace fs = std::filesystem;

std::string readText(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

std::string quoted(const fs::path& p) {
  std::string q(1, '\'');  // built by appending: GCC 12 warns falsely on "'" + std::string
  return q.append(p.string()).append(1, '\'');
}

/// Runs the executable with `args`; its exit code, output and error in `output`.
int runApp(const std::string& args, std::string& output) {
  const std::string command = "env -u DISPLAY -u WAYLAND_DISPLAY '" + std::string(VH_APP_EXECUTABLE) + "' " + args + " 2>&1";
  FILE* pipe = popen(command.c_str(), "r");
  if (pipe == nullptr) return -1;
  std::array<char, 4096> buffer{};
  while (std::fgets(buffer.data(), static_cast<int>(buffer.size()), pipe) != nullptr) output += buffer.data();
  return pclose(pipe);
}

TEST(Anonymize, UidIsTheSha256BasedTwoTwentyFiveUid) {
  // Expected values from Python's hashlib: "2.25." + int(sha256(uid).hexdigest()[:32], 16).
  EXPECT_EQ(anonymizedUid("1.2.3"), "2.25.261189956532771003411213951354307305753");
  EXPECT_EQ(anonymizedUid("1.2.826.0.1.3680043.2.1125.1.65375240934815452318141136507497058"),
            "2.25.83455114795958941715140401491109379140");
}

TEST(Anonymize, ScrubTextReplacesEveryOccurrenceLongestFirst) {
  EXPECT_EQ(scrubText("/data/DOE_JOHN/a.dcm and DOE_JOHN", {"DOE_JOHN", "/data/DOE_JOHN/a.dcm", "a"}),
            "ANONYMIZED and ANONYMIZED");
}

// `run --anonymize`'s report: the scene's, the volume's and the trajectory's paths (folders
// named after a patient) replaced, the notices scrubbed of them and of the series' description
// and UID; the figures kept. Before, `run --report` held the description and the path.
TEST(Anonymize, ARunReportKeepsItsFiguresAndLosesThePatientsNames) {
  RunReport r;
  r.scene = "/data/DOE_JOHN_19700101/scene.json";
  r.volume = "/data/DOE_JOHN_19700101/CT HEAD";
  r.trajectory = "/data/DOE_JOHN_19700101/press.csv";
  r.volume_notices = {"series 'HEAD ROUTINE DOE' chosen of 3 in /data/DOE_JOHN_19700101/CT HEAD",
                      "series 1.2.840.113619.2.55.3.1 has a gap"};
  r.max_force_N = 3.25;
  anonymizeRunReport(r, {"HEAD ROUTINE DOE", "1.2.840.113619.2.55.3.1"});
  const std::string json = r.toJson();
  EXPECT_EQ(json.find("DOE"), std::string::npos) << json;
  EXPECT_EQ(json.find("1.2.840.113619"), std::string::npos) << json;
  EXPECT_EQ(r.scene, kAnonymized);
  EXPECT_EQ(r.volume, kAnonymized);
  EXPECT_EQ(r.trajectory, kAnonymized);
  EXPECT_NE(r.volume_notices[1].find("has a gap"), std::string::npos) << "the notice's meaning stays";
  EXPECT_EQ(r.max_force_N, 3.25);
  RunReport builtin;
  builtin.scene = "builtin";
  builtin.volume = "builtin:sphere";
  anonymizeRunReport(builtin, {});
  EXPECT_EQ(builtin.volume, "builtin:sphere") << "nothing of a patient in a built-in volume";
}

TEST(Anonymize, ExportsAndReportsOfACtHeadCarryNoPatientIdentifiers) {
  const fs::path head = test::sharedDatasets() / "ct" / "ct-head-small";
  if (!fs::exists(head)) GTEST_SKIP() << "shared dataset missing: " << head;
  // The phantom's Patient Name, Patient ID and Birth Date name its folder here (dcmdump of
  // CTHead1.dcm: (0010,0010) Austrialian, (0010,0020) 8775070, (0010,0030) 20060101; Study Date
  // 20090102, Institution "GDCM Hospital", Series Instance UID below).
  const fs::path dir = test::scratchDir();
  const fs::path series = dir / "Austrialian_8775070_20060101";
  fs::create_directories(series);
  for (const auto& e : fs::directory_iterator(head)) fs::copy_file(e.path(), series / e.path().filename());
  const std::string series_uid = "1.2.826.0.1.3680043.2.1125.1.65375240934815452318141136507497058";
  const fs::path scene = test::writeText(dir / "s.json", "{\"volume\": {\"path\": " + nlohmann::json(series.string()).dump() + "}}");
  const fs::path csv = test::writeText(dir / "t.csv", "0,0,0,0.4,1,0,0,0\n0.01,0,0,0.4,1,0,0,0\n");
  fs::create_directories(dir / "recordings");
  const fs::path rec = dir / "recordings" / "Austrialian-8775070.vhrec";
  std::string out;
  ASSERT_EQ(runApp("run --verify-step 0 --no-lag-reference --scene " + quoted(scene) + " --trajectory " + quoted(csv) +
                       " --record " + quoted(rec),
                   out),
            0)
      << out;

  const auto outputs = [&](const std::string& tag, const std::string& flag) {
    std::string text;
    EXPECT_EQ(runApp("export " + quoted(rec) + " --csv " + quoted(dir / (tag + ".csv")) + " --json " +
                         quoted(dir / (tag + ".json")) + " --events-csv " + quoted(dir / (tag + "-events.csv")) + flag,
                     text),
              0)
        << text;
    EXPECT_EQ(runApp("report " + quoted(rec) + " --html " + quoted(dir / (tag + ".html")) + flag, text), 0) << text;
    EXPECT_EQ(runApp("report " + quoted(dir / "recordings") + " --table " + quoted(dir / (tag + "-table.csv")) + flag, text),
              0)
        << text;
    return std::vector<fs::path>{dir / (tag + ".csv"), dir / (tag + ".json"), dir / (tag + "-events.csv"),
                                 dir / (tag + ".html"), dir / (tag + "-table.csv")};
  };
  const std::vector<fs::path> plain = outputs("plain", "");
  const nlohmann::json plain_json = nlohmann::json::parse(readText(plain[1]));
  const std::string start_time = plain_json.at("metadata").at("start_time_utc");  // "YYYY-MM-DDTHH:MM:SSZ"
  const std::string start_date = start_time.substr(0, 10);
  ASSERT_EQ(start_date.size(), 10u);
  // Without --anonymize the JSON, the report and the table name them.
  for (const std::string& id : {std::string("Austrialian"), std::string("8775070"), std::string("20060101"), series_uid,
                                start_date}) {
    EXPECT_NE(readText(plain[1]).find(id), std::string::npos) << "export --json lacks " << id;
  }
  for (const std::string& id : {std::string("Austrialian"), std::string("8775070"), start_date}) {
    EXPECT_NE(readText(plain[3]).find(id), std::string::npos) << "report --html lacks " << id;
    EXPECT_NE(readText(plain[4]).find(id), std::string::npos) << "report --table lacks " << id;
  }

  const std::vector<fs::path> anonymized = outputs("anon", " --anonymize");
  const std::string start_clock = start_time.substr(11, 8);
  for (const fs::path& file : anonymized) {
    const std::string text = readText(file);
    ASSERT_FALSE(text.empty()) << file;
    for (const std::string& id : {std::string("Austrialian"), std::string("8775070"), std::string("20060101"),
                                  std::string("20090102"), std::string("GDCM Hospital"), series_uid, start_date,
                                  start_clock, head.string(), series.string()}) {
      EXPECT_EQ(text.find(id), std::string::npos) << file.filename() << " holds " << id;
    }
  }
  // The JSON says what was done; the replaced UID is the stable one; the scan still reloads
  // for the report's contact map (from the original metadata, which stays out of the report).
  const nlohmann::json anon_json = nlohmann::json::parse(readText(anonymized[1]));
  EXPECT_EQ(anon_json.at("metadata").at("dataset").at("series_uid"), anonymizedUid(series_uid));
  EXPECT_EQ(anon_json.at("metadata").at("dataset").at("path"), "ANONYMIZED");
  EXPECT_FALSE(anon_json.at("metadata").at("dataset").contains("description"));
  EXPECT_TRUE(anon_json.at("metadata").at("anonymized").at("removed").is_array());
  EXPECT_EQ(anon_json.at("records"), plain_json.at("records"));
  EXPECT_EQ(readText(anonymized[0]), readText(plain[0]));  // the ticks are the same
  EXPECT_EQ(readText(anonymized[3]).find("could not be reloaded"), std::string::npos);
}

}  // namespace
}  // namespace vh::runtime
