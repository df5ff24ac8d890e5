// datasets/manifest.json: complete, well-formed, and its checksums match the shared datasets
// that are present (absent ones are reported and skipped).
#include <chrono>
#include <fstream>
#include <iostream>
#include <set>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "io_test_support.h"
#include "vh/runtime/sha256.h"

namespace {

namespace fs = std::filesystem;
using vh::runtime::sha256File;
using vh::runtime::sha256Folder;
using vh::io::test::sharedDir;

nlohmann::json manifest() {
  std::ifstream in(fs::path(VH_SOURCE_DIR) / "datasets/manifest.json");
  EXPECT_TRUE(in) << "datasets/manifest.json missing";
  return nlohmann::json::parse(in);
}

TEST(DatasetManifest, Sha256KnownAnswers) {
  vh::runtime::Sha256 empty;
  EXPECT_EQ(empty.hexDigest(), "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855");
  vh::runtime::Sha256 abc;
  abc.update("abc");
  EXPECT_EQ(abc.hexDigest(), "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
  vh::runtime::Sha256 split;  // 56-byte message across updates
  split.update("abcdbcdecdefdefgefghfghighijhijk");
  split.update("ijkljklmklmnlmnomnopnopq");
  EXPECT_EQ(split.hexDigest(), "248d6a61d20638b8e5c026930c3e6039a33ce45964ff2167f6ecedd419db06c1");
}

TEST(DatasetManifest, EntriesAreComplete) {
  const auto m = manifest();
  ASSERT_TRUE(m.contains("datasets"));
  ASSERT_TRUE(m.contains("checksum_rule"));
  std::set<std::string> ids;
  for (const auto& d : m["datasets"]) {
    for (const char* key : {"id", "path", "kind", "source_url", "licence", "credit", "sha256"}) {
      EXPECT_TRUE(d.contains(key) && d[key].is_string() && !d[key].get<std::string>().empty())
          << "dataset " << d.value("id", "?") << " lacks " << key;
    }
    EXPECT_EQ(d["sha256"].get<std::string>().size(), 64u) << d["id"];
    EXPECT_EQ(d["source_url"].get<std::string>().rfind("https://", 0), 0u) << d["id"];
    EXPECT_TRUE(ids.insert(d["id"].get<std::string>()).second) << "duplicate id " << d["id"];
  }
  for (const char* id : {"ct-head-small", "philips-head-phantom-bone", "headsq-quarter", "mr-brain",
                         "ct-bunny", "engine", "drill-stl", "dental-probe", "wrench"}) {
    EXPECT_EQ(ids.count(id), 1u) << "manifest lacks " << id;
  }
}

TEST(DatasetManifest, ChecksumsMatchSharedDatasets) {
  const auto m = manifest();
  const auto t0 = std::chrono::steady_clock::now();
  int checked = 0;
  for (const auto& d : m["datasets"]) {
    const fs::path p = sharedDir() / d["path"].get<std::string>();
    if (!fs::exists(p)) {
      std::cout << "shared dataset missing, not checked: " << p.string() << "\n";
      continue;
    }
    if (fs::is_directory(p)) {
      EXPECT_EQ(sha256Folder(p), d["sha256"].get<std::string>()) << p;
      if (d.contains("files")) {
        for (const auto& [name, sha] : d["files"].items()) {
          EXPECT_EQ(sha256File(p / name), sha.get<std::string>()) << p / name;
        }
      }
    } else {
      EXPECT_EQ(sha256File(p), d["sha256"].get<std::string>()) << p;
    }
    if (d.contains("licence_file")) {
      const fs::path l = sharedDir() / d["licence_file"].get<std::string>();
      if (fs::exists(l)) {
        EXPECT_EQ(sha256File(l), d["licence_file_sha256"].get<std::string>()) << l;
      }
    }
    ++checked;
  }
  std::cout << "[timing] manifest checksums of " << checked << " datasets: "
            << vh::io::test::secondsSince(t0) << " s\n";
  if (checked == 0) GTEST_SKIP() << "shared dataset missing: " << sharedDir().string();
}

TEST(DatasetManifest, CoversEverySharedDataFile) {
  if (!fs::exists(sharedDir())) GTEST_SKIP() << "shared dataset missing: " << sharedDir().string();
  const auto m = manifest();
  std::vector<fs::path> covered;
  for (const auto& d : m["datasets"]) {
    covered.push_back(sharedDir() / d["path"].get<std::string>());
    if (d.contains("licence_file")) covered.push_back(sharedDir() / d["licence_file"].get<std::string>());
  }
  for (const auto& e : fs::recursive_directory_iterator(sharedDir())) {
    if (!e.is_regular_file() || e.path().filename() == "README.md") continue;
    bool found = false;
    for (const auto& c : covered) {
      const auto rel = fs::relative(e.path(), c);
      if (e.path() == c || (!rel.empty() && *rel.begin() != "..")) found = true;
    }
    EXPECT_TRUE(found) << "not in datasets/manifest.json: " << e.path();
  }
}

}  // namespace
