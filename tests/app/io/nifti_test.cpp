// NIfTI-1 and NIfTI-2 volumes and label maps, checked against nibabel: nifti_fixtures.py writes
// the files with nibabel and, for a few voxels of each, where nibabel places them (patient LPS
// [m]) and the value it reads (scl_slope / scl_inter applied). Each sample's point must fall on
// a voxel centre of the loaded grid whose value is nibabel's: a wrong form, sign, slice order,
// unit or scaling puts the point on another voxel or off the grid. Damaged headers are written
// here, byte by byte, from a nibabel file.
#include <sys/stat.h>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "io_test_support.h"
#include "vh/io/segmentation.h"
#include "vh/io/volume_loader.h"

namespace vh::io {
namespace {

namespace fs = std::filesystem;
using test::loadErrorOf;
using test::readFile;
using test::TempDir;
using test::writeFile;

/// The fixture folder: nifti_fixtures.py run once per test process with Debian's Python.
class NiftiNibabel : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new TempDir("nifti_nibabel");
    const std::string cmd = std::string(VH_SYSTEM_PYTHON) + " " + VH_SOURCE_DIR + "/tests/app/io/nifti_fixtures.py " +
                            dir_->path().string() + " > " + (dir_->path() / "log.txt").string() + " 2>&1";
    status_ = std::system(cmd.c_str());
    if (status_ == 0) expected_ = nlohmann::json::parse(readFile(dir_->path() / "expected.json"));
  }
  static void TearDownTestSuite() {
    delete dir_;
    dir_ = nullptr;
  }
  void SetUp() override {
    if (WIFEXITED(status_) && WEXITSTATUS(status_) == 77) GTEST_SKIP() << "nibabel or numpy missing (python3-nibabel)";
    ASSERT_EQ(status_, 0) << "nifti_fixtures.py failed: " << readFile(dir_->path() / "log.txt");
  }
  static const nlohmann::json& entry(const std::string& file) {
    for (const auto& c : expected_["cases"]) {
      if (c["file"] == file) return c;
    }
    throw std::runtime_error("no case " + file);
  }
  static fs::path path(const std::string& file) { return dir_->path() / file; }

  /// Every sample of `file`'s case lies on a voxel centre of `field` holding nibabel's value.
  static void expectSamples(const haptics::ScalarVolume& field, const nlohmann::json& c) {
    const auto& g = field.geometry();
    for (int a = 0; a < 3; ++a) {
      EXPECT_EQ(g.dims[static_cast<std::size_t>(a)], c["shape"][a].get<int>()) << "axis " << a;
      EXPECT_NEAR(g.spacing_m[a], c["spacing_m"][a].get<double>(), 1e-6 * c["spacing_m"][a].get<double>()) << "axis " << a;
    }
    for (const auto& s : c["samples"]) {
      const Eigen::Vector3d p_W_m(s["p_LPS_m"][0].get<double>(), s["p_LPS_m"][1].get<double>(),
                                  s["p_LPS_m"][2].get<double>());
      const Eigen::Vector3d q = field.gridCoordinates(p_W_m);
      const std::string what = c["file"].get<std::string>() + " voxel " + s["ijk"].dump();
      for (int a = 0; a < 3; ++a) {
        EXPECT_NEAR(q[a], std::round(q[a]), 1e-3) << what << ": not on a voxel centre, grid coordinates " << q.transpose();
      }
      const double expected = s["value"].get<double>();
      EXPECT_NEAR(field.voxel(static_cast<int>(std::lround(q[0])), static_cast<int>(std::lround(q[1])),
                              static_cast<int>(std::lround(q[2]))),
                  expected, 1e-5 * std::abs(expected) + 1e-6)
          << what << " at grid " << q.transpose();
      EXPECT_TRUE(field.inBounds(p_W_m) || q.minCoeff() > -1e-3) << what;
    }
  }

  /// `file` loads as nibabel placed the file of case `case_file` (default: the same file).
  static void expectVolume(const std::string& file, const std::string& case_file = {}) {
    const auto& c = entry(case_file.empty() ? file : case_file);
    const LoadedVolume v = loadVolume(path(file));
    EXPECT_EQ(v.info.format, c["format"].get<std::string>());
    expectSamples(*v.field, c);
    if (c.contains("notice")) {
      bool found = false;
      for (const auto& n : v.info.notices) found = found || n.find(c["notice"].get<std::string>()) != std::string::npos;
      EXPECT_TRUE(found) << file << ": no notice containing \"" << c["notice"].get<std::string>() << "\"";
    }
  }

  static TempDir* dir_;
  static int status_;
  static nlohmann::json expected_;
};

TempDir* NiftiNibabel::dir_ = nullptr;
int NiftiNibabel::status_ = -1;
nlohmann::json NiftiNibabel::expected_;

TEST_F(NiftiNibabel, ObliqueSformWinsOverQformGzip) { expectVolume("oblique_sform.nii.gz"); }
TEST_F(NiftiNibabel, QformOnlyWithReversedAxes) { expectVolume("flipped_qform.nii"); }
TEST_F(NiftiNibabel, ScaledValuesInMicrometres) { expectVolume("scaled_micron.nii"); }
TEST_F(NiftiNibabel, Nifti2InMetres) { expectVolume("nifti2.nii"); }
TEST_F(NiftiNibabel, BigEndianHdrImgPair) {
  expectVolume("pair.hdr");
  expectVolume("pair.img", "pair.hdr");  // either file of the pair
}
TEST_F(NiftiNibabel, NoFormIsPixdimAlone) { expectVolume("no_form.nii"); }
TEST_F(NiftiNibabel, ShearedSformGivesWayToQform) { expectVolume("sheared_sform.nii"); }
TEST_F(NiftiNibabel, FourDimensionalFirstVolume) {
  expectVolume("series4d.nii.gz");
  EXPECT_EQ(loadVolume(path("series4d.nii.gz")).info.phase_count, 3);
}

TEST_F(NiftiNibabel, LabelMapAsSegmentation) {
  const auto& c = entry("labels.nii.gz");
  EXPECT_TRUE(isSegmentationFile(path("labels.nii.gz")));  // intent_code NIFTI_INTENT_LABEL
  EXPECT_FALSE(isSegmentationFile(path("oblique_sform.nii.gz")));
  const LoadedSegmentation seg = loadSegmentation(path("labels.nii.gz"));
  ASSERT_EQ(seg.layers.size(), 1u);
  expectSamples(*seg.layers[0], c);
  ASSERT_EQ(seg.segments.size(), c["labels"].size());
  for (const auto& s : seg.segments) {
    const std::string label = std::to_string(s.label_value);
    ASSERT_TRUE(c["labels"].contains(label)) << "unexpected label " << label;
    EXPECT_EQ(s.voxel_count, c["labels"][label].get<std::size_t>()) << "label " << label;
  }
}

// ---- damaged files ---------------------------------------------------------------------------

/// `bytes` with `n` bytes of `value` (native order, as nibabel wrote the little-endian file on a
/// little-endian machine) at `offset`.
template <typename T>
std::string patched(std::string bytes, std::size_t offset, T value) {
  std::memcpy(bytes.data() + offset, &value, sizeof(T));
  return bytes;
}

class NiftiDamaged : public NiftiNibabel {
 protected:
  /// The LoadError of `bytes` written as `name`.
  std::string errorOf(const std::string& bytes, const std::string& name = "bad.nii") {
    TempDir tmp("nifti_damaged");
    writeFile(tmp / name, bytes);
    return loadErrorOf([&] { loadVolume(tmp / name); });
  }
  std::string good() { return readFile(path("flipped_qform.nii")); }  // int16 7 x 6 x 5, vox_offset 352
};

TEST_F(NiftiDamaged, TruncatedHeader) {
  const std::string msg = errorOf(good().substr(0, 200));
  EXPECT_CONTAINS(msg, "bad.nii");
  EXPECT_CONTAINS(msg, "truncated NIfTI-1 header: 200 of 348 bytes");
}

TEST_F(NiftiDamaged, TruncatedVoxels) {
  const std::string msg = errorOf(good().substr(0, 352 + 100));
  EXPECT_CONTAINS(msg, "truncated: expected 420 bytes of voxel data, found 100");
}

TEST_F(NiftiDamaged, TruncatedGzip) {
  const std::string gz = readFile(path("oblique_sform.nii.gz"));
  const std::string msg = errorOf(gz.substr(0, gz.size() / 2), "bad.nii.gz");
  EXPECT_CONTAINS(msg, "bad.nii.gz");
  EXPECT_CONTAINS(msg, "truncated");
}

TEST_F(NiftiDamaged, BadSizeofHdr) {
  EXPECT_CONTAINS(errorOf(patched<std::int32_t>(good(), 0, 123)), "sizeof_hdr is 123 (348 for NIfTI-1, 540 for NIfTI-2)");
}

TEST_F(NiftiDamaged, ZeroNegativeAndHugeDimensions) {
  EXPECT_CONTAINS(errorOf(patched<std::int16_t>(good(), 42, 0)), "dim[1] is 0 (0 or negative)");
  EXPECT_CONTAINS(errorOf(patched<std::int16_t>(good(), 44, -5)), "dim[2] is -5 (0 or negative)");
  EXPECT_CONTAINS(errorOf(patched<std::int16_t>(good(), 40, 0)), "dim[0] (the number of dimensions) is 0");
  std::string huge = good();
  for (std::size_t a = 1; a <= 3; ++a) huge = patched<std::int16_t>(huge, 40 + 2 * a, 32767);
  EXPECT_CONTAINS(errorOf(huge), "absurd number of voxels");
  // Large but plausible: the voxel data is then too short.
  EXPECT_CONTAINS(errorOf(patched<std::int16_t>(good(), 42, 3000)), "truncated: expected 180000 bytes of voxel data");
}

TEST_F(NiftiDamaged, UnknownAndNonScalarDatatypes) {
  EXPECT_CONTAINS(errorOf(patched<std::int16_t>(good(), 70, 999)), "unknown datatype 999");
  EXPECT_CONTAINS(errorOf(patched<std::int16_t>(good(), 70, 32)), "complex64");
  // A vector image: dim[0] = 5, dim[5] = 3 values per voxel (dim[4] = 1 time point).
  EXPECT_CONTAINS(errorOf(patched<std::int16_t>(patched<std::int16_t>(patched<std::int16_t>(good(), 40, 5), 48, 1), 50, 3)),
                  "has 3 values per voxel");
}

TEST_F(NiftiDamaged, AnalyzeWithoutMagic) {
  std::string analyze = good();
  std::memset(analyze.data() + 344, 0, 4);
  EXPECT_CONTAINS(errorOf(analyze, "old.hdr"), "Analyze 7.5");
}

TEST_F(NiftiDamaged, PairWithoutItsImage) {
  TempDir tmp("nifti_pair");
  writeFile(tmp / "alone.hdr", readFile(path("pair.hdr")));
  EXPECT_CONTAINS(loadErrorOf([&] { loadVolume(tmp / "alone.hdr"); }), "the voxel file alone.img is missing");
}

// A pair's voxel file follows the rules of every detached data file: a .img that is a link to a
// file outside the header's folder (before: /etc/shadow's first bytes loaded as voxels), or a
// FIFO, is refused naming it; a link within the folder still reads.
TEST_F(NiftiDamaged, PairImageLinkedOutsideItsFolderOrAFifoIsRefused) {
  TempDir tmp("nifti_pair_link");
  TempDir elsewhere("nifti_pair_secret");
  const std::string img = readFile(path("pair.img"));
  writeFile(elsewhere / "secret.bin", img);  // right size: only where it lies refuses it
  writeFile(tmp / "pair2.hdr", readFile(path("pair.hdr")));
  std::filesystem::create_symlink(elsewhere / "secret.bin", tmp / "pair2.img");
  const std::string msg = loadErrorOf([&] { loadVolume(tmp / "pair2.hdr"); });
  EXPECT_CONTAINS(msg, "pair2.img");
  EXPECT_CONTAINS(msg, "outside the header's folder");
  EXPECT_CONTAINS(loadErrorOf([&] { loadVolume(tmp / "pair2.img"); }), "outside the header's folder");

  writeFile(tmp / "pair3.hdr", readFile(path("pair.hdr")));
  ASSERT_EQ(::mkfifo((tmp / "pair3.img").c_str(), 0600), 0);
  EXPECT_CONTAINS(loadErrorOf([&] { loadVolume(tmp / "pair3.hdr"); }), "a FIFO, not a regular file");

  writeFile(tmp / "real.img", img);  // a link beside its header: read
  writeFile(tmp / "pair4.hdr", readFile(path("pair.hdr")));
  std::filesystem::create_symlink("real.img", tmp / "pair4.img");
  EXPECT_NO_THROW(loadVolume(tmp / "pair4.hdr"));
}

}  // namespace
}  // namespace vh::io
