// Tests of session metadata (app/runtime/src/session_metadata.cpp): the stored scene reloads to
// the same scene, dataset checksums (files, detached NRRD data, folders, built-ins) match the
// documented `sha256sum` recipe, and a missing or changed dataset is refused with both checksums.
#include <fstream>
#include <stdexcept>
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "runtime_test_support.h"
#include "vh/runtime/session_metadata.h"
#include "vh/runtime/sha256.h"

namespace vh::runtime {
namespace {

namespace fs = std::filesystem;

std::string sha256Of(const std::string& text) {
  Sha256 sha;
  sha.update(text);
  return sha.hexDigest();
}

TEST(Sha256, MatchesTheFipsExamples) {
  EXPECT_EQ(sha256Of("abc"), "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
  EXPECT_EQ(sha256Of(""), "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855");
  EXPECT_EQ(sha256Of("abcdbcdecdefdefgefghfghighijhijkijkljklmklmnlmnomnopnopq"),
            "248d6a61d20638b8e5c026930c3e6039a33ce45964ff2167f6ecedd419db06c1");
  // FIPS 180-2's third example: a million 'a', streamed in uneven pieces.
  Sha256 million;
  const std::string piece(997, 'a');
  std::size_t left = 1000000;
  for (; left >= piece.size(); left -= piece.size()) million.update(piece);
  million.update(piece.data(), left);
  EXPECT_EQ(million.hexDigest(), "cdc76e5c9914fb9281a1c7e284d73e67f1809a48a497200e046d39ccc7112cd0");
  EXPECT_EQ(million.hexDigest(), "cdc76e5c9914fb9281a1c7e284d73e67f1809a48a497200e046d39ccc7112cd0");
  EXPECT_THROW(million.update("a"), std::logic_error);
}

TEST(SessionMetadata, StoresTheSceneDatasetToolDeviceAndReloadsTheSameScene) {
  const LoadedScene& scene = test::sphereBallScene();
  const std::string text = makeSessionMetadata(scene, {"Scripted device (x)", "scripted", "first try"});
  const nlohmann::json j = nlohmann::json::parse(text);
  EXPECT_EQ(j.at("software").at("version").get<std::string>().empty(), false);
  EXPECT_EQ(j.at("start_time_utc").get<std::string>().size(), 20u);  // 2026-11-21T18:00:00Z
  EXPECT_EQ(j.at("dataset").at("kind"), "builtin");
  EXPECT_EQ(j.at("dataset").at("sha256"), sha256Of("builtin:sphere"));
  EXPECT_EQ(j.at("dataset").at("dims").size(), 3u);
  EXPECT_EQ(j.at("tool").at("point_count"), scene.tool->point_shell.size());
  EXPECT_GT(j.at("tool").at("point_spacing_m").get<double>(), 0.0);
  EXPECT_EQ(j.at("gains").at("linear_N_per_m"), 1000.0);
  EXPECT_EQ(j.at("device").at("kind"), "scripted");
  EXPECT_EQ(j.at("note"), "first try");

  const SceneSpec spec = sceneFromSessionMetadata(text);
  EXPECT_EQ(spec.volume.path, "builtin:sphere");
  EXPECT_TRUE(spec.volume.isovalue_set);
  EXPECT_EQ(spec.volume.isovalue, scene.isovalue);
  EXPECT_EQ(spec.tool.mesh, "builtin:sphere");
  EXPECT_EQ(spec.tool.point_spacing_m, 0.0015);
  EXPECT_FALSE(spec.device.has_value());
  const LoadedScene reloaded = loadScene(spec);
  EXPECT_EQ(reloaded.X_WT_initial.p_AB_m, scene.X_WT_initial.p_AB_m);  // bit for bit through JSON
  EXPECT_EQ(reloaded.X_WT_initial.R_AB.coeffs(), scene.X_WT_initial.R_AB.coeffs());
  EXPECT_EQ(reloaded.tool->point_shell.size(), scene.tool->point_shell.size());
  EXPECT_EQ(reloaded.spec.gains.linear_N_per_m, scene.spec.gains.linear_N_per_m);

  VH_EXPECT_THROW_WITH(sceneFromSessionMetadata("{\"x\":1}"), std::runtime_error, "no \"scene\"");
  VH_EXPECT_THROW_WITH(sceneFromSessionMetadata("nope"), std::runtime_error, "not JSON");
}

TEST(SessionMetadata, CarriesThePassivitySwitch) {
  LoadedScene scene = test::sphereBallScene();  // a copy: the switch is set on it below
  const std::string off = makeSessionMetadata(scene, {"Simulated device", "simulated", ""});
  EXPECT_EQ(nlohmann::json::parse(off).at("gains").at("passivity_control"), false);
  EXPECT_FALSE(sceneFromSessionMetadata(off).gains.passivity_control);
  scene.spec.gains.passivity_control = true;
  const std::string on = makeSessionMetadata(scene, {"Simulated device", "simulated", ""});
  EXPECT_EQ(nlohmann::json::parse(on).at("scene").at("coupling").at("passivity_control"), true);
  EXPECT_TRUE(sceneFromSessionMetadata(on).gains.passivity_control);
  // Metadata written before the switch existed: off.
  nlohmann::json old = nlohmann::json::parse(on);
  old["scene"]["coupling"].erase("passivity_control");
  EXPECT_FALSE(sceneFromSessionMetadata(old.dump()).gains.passivity_control);
}

TEST(SessionMetadata, ChecksumsFollowTheSha256sumRecipeAndCatchAChangedDataset) {
  const fs::path dir = test::scratchDir();
  // A NRRD with detached data: header + data file.
  const std::string raw(2 * 2 * 2, '\x07');
  test::writeText(dir / "vol" / "v.raw", raw);
  const std::string header =
      "NRRD0004\ntype: uint8\ndimension: 3\nsizes: 2 2 2\nspacings: 1 1 1\nencoding: raw\ndata file: v.raw\n\n";
  test::writeText(dir / "vol" / "v.nhdr", header);
  const DatasetChecksum nrrd = datasetChecksum((dir / "vol" / "v.nhdr").string());
  EXPECT_EQ(nrrd.kind, "nrrd");
  ASSERT_EQ(nrrd.files, (std::vector<std::string>{"v.nhdr", "v.raw"}));
  EXPECT_EQ(nrrd.sha256, sha256Of(sha256Of(header) + "  v.nhdr\n" + sha256Of(raw) + "  v.raw\n"));
  // A folder (DICOM series): every file, sorted by relative path.
  test::writeText(dir / "series" / "b", "second");
  test::writeText(dir / "series" / "a", "first");
  test::writeText(dir / "series" / "sub" / "c", "third");
  const DatasetChecksum folder = datasetChecksum((dir / "series").string());
  EXPECT_EQ(folder.kind, "dicom-folder");
  EXPECT_EQ(folder.sha256, sha256Of(sha256Of("first") + "  a\n" + sha256Of("second") + "  b\n" + sha256Of("third") +
                                    "  sub/c\n"));
  // A single file: its bytes.
  EXPECT_EQ(datasetChecksum((dir / "series" / "a").string()).sha256, sha256Of("first"));
  // Changed data (same size, so only the time tells the cache): a new checksum.
  test::writeText(dir / "series" / "a", "fir5t");
  fs::last_write_time(dir / "series" / "a", fs::last_write_time(dir / "series" / "a") + std::chrono::seconds(2));
  EXPECT_NE(datasetChecksum((dir / "series").string()).sha256, folder.sha256);
  VH_EXPECT_THROW_WITH(datasetChecksum((dir / "absent").string()), std::runtime_error, "missing",
                       (dir / "absent").string());

  // A recording's metadata whose dataset changed since, or is gone.
  nlohmann::json meta = nlohmann::json::parse(makeSessionMetadata(test::sphereBallScene(), {}));
  meta["scene"]["volume"]["path"] = (dir / "vol" / "v.nhdr").string();
  meta["dataset"]["sha256"] = nrrd.sha256;
  EXPECT_NO_THROW(sceneFromSessionMetadata(meta.dump()));
  test::writeText(dir / "vol" / "v.raw", std::string(8, '\x08'));
  fs::last_write_time(dir / "vol" / "v.raw", fs::last_write_time(dir / "vol" / "v.raw") + std::chrono::seconds(2));
  const std::string changed = datasetChecksum((dir / "vol" / "v.nhdr").string()).sha256;
  VH_EXPECT_THROW_WITH(sceneFromSessionMetadata(meta.dump()), std::runtime_error, "differs from the recorded",
                       (dir / "vol" / "v.nhdr").string(), nrrd.sha256, changed);
  meta["scene"]["volume"]["path"] = (dir / "gone.nrrd").string();
  VH_EXPECT_THROW_WITH(sceneFromSessionMetadata(meta.dump()), std::runtime_error, "missing",
                       (dir / "gone.nrrd").string());
}

}  // namespace
}  // namespace vh::runtime
