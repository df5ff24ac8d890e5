// Tests of vh-make-datasets (datasets/tools/make_datasets.cpp): the NRRD and OBJ files it writes
// into the build tree load back through vh::io as exactly the volumes and tools of vh::datasets.
#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "runtime_test_support.h"
#include "vh/datasets/synthetic.h"
#include "vh/io/volume_loader.h"

namespace vh::runtime {
namespace {

namespace fs = std::filesystem;

fs::path syntheticDir() { return test::generatedData() / "synthetic"; }

class MakeDatasets : public ::testing::TestWithParam<const char*> {};

TEST_P(MakeDatasets, NrrdLoadsBackAsTheBuiltinVolume) {
  const std::string name = GetParam();
  const fs::path file = syntheticDir() / (name + ".nrrd");
  ASSERT_TRUE(fs::exists(file)) << file << " (written by the vh_synthetic_data build target)";
  const io::LoadedVolume loaded = io::loadVolume(file);
  const haptics::ScalarVolume expected = datasets::makeBuiltinVolume(name);
  const auto& g = loaded.field->geometry();
  const auto& e = expected.geometry();
  EXPECT_EQ(g.dims, e.dims);
  EXPECT_LT((g.spacing_m - e.spacing_m).norm(), 1e-15);
  EXPECT_LT((g.origin_W_m - e.origin_W_m).norm(), 1e-15);
  EXPECT_TRUE(g.direction_W.isApprox(e.direction_W));
  EXPECT_EQ(loaded.field->voxelType(), expected.voxelType());
  EXPECT_TRUE(loaded.field->bytes() == expected.bytes()) << "voxel data differs";
  EXPECT_EQ(loaded.field->minValue(), expected.minValue());
  EXPECT_EQ(loaded.field->maxValue(), expected.maxValue());
}

INSTANTIATE_TEST_SUITE_P(Volumes, MakeDatasets, ::testing::Values("plane", "sphere", "thin-plate", "block-with-hole"),
                         [](const ::testing::TestParamInfo<const char*>& param_info) {
                           std::string s = param_info.param;
                           for (char& c : s) {
                             if (c == '-') c = '_';
                           }
                           return s;
                         });

TEST(MakeDatasetsTools, ObjLoadsBackAsTheBuiltinTool) {
  for (const char* name : {"peg", "probe", "drill", "sphere"}) {
    const fs::path file = syntheticDir() / (std::string(name) + ".obj");
    ASSERT_TRUE(fs::exists(file)) << file;
    const haptics::TriangleMesh loaded = io::loadMesh(file);
    const haptics::TriangleMesh expected = datasets::makeBuiltinTool(name);
    EXPECT_EQ(loaded.triangles.size(), expected.triangles.size()) << name;
    EXPECT_NEAR(loaded.area_m2(), expected.area_m2(), 1e-6 * expected.area_m2()) << name;
    EXPECT_NEAR(loaded.signedVolume_m3(), expected.signedVolume_m3(), 1e-6 * std::abs(expected.signedVolume_m3()))
        << name;
    EXPECT_LT((loaded.boundsMin_T_m() - expected.boundsMin_T_m()).norm(), 1e-8) << name;
    EXPECT_LT((loaded.boundsMax_T_m() - expected.boundsMax_T_m()).norm(), 1e-8) << name;
  }
}

TEST(MakeDatasetsTools, ManifestListsEveryFileWithItsIsovalue) {
  std::ifstream in(syntheticDir() / "manifest.json");
  ASSERT_TRUE(in.good());
  const nlohmann::json manifest = nlohmann::json::parse(in);
  ASSERT_EQ(manifest["volumes"].size(), 4u);
  for (const auto& v : manifest["volumes"]) {
    const std::string name = v["name"].get<std::string>();
    EXPECT_EQ(v["isovalue"].get<double>(), datasets::builtinIsovalue(name)) << name;
    EXPECT_TRUE(fs::exists(syntheticDir() / v["file"].get<std::string>())) << name;
  }
  ASSERT_EQ(manifest["tools"].size(), 4u);
  for (const auto& t : manifest["tools"]) EXPECT_TRUE(fs::exists(syntheticDir() / t["file"].get<std::string>()));
}

}  // namespace
}  // namespace vh::runtime
