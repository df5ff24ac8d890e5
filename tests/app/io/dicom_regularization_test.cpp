// Every clinical scan opens: series written by the fixtures (gantry tilt, missing,
// duplicated and displaced slices, multi-frame, 4-D, oblique, several series) loaded through
// vh::io::loadVolume(). The oracle is each written series' own geometry: the bone (or ball)
// centroid of the source voxels at the patient positions they were written to must match the
// loaded field's centroid in W to a tenth of a voxel.

#include <algorithm>
#include <cmath>
#include <iostream>
#include <string>

#include <gtest/gtest.h>
#include <vtkImageData.h>

#include "dicom_fixtures.h"
#include "io_test_support.h"
#include "slice_stack.h"
#include "vh/io/dicom_series.h"
#include "vh/io/volume_loader.h"

namespace vh::io::test {
namespace {

constexpr char kCtHead[] = "ct/ct-head-small";
constexpr double kBoneStored = 1000.0;

/// Centroid [mm, LPS] of the loaded field's voxels above `threshold` (data units), weighted by
/// (value - threshold): the loader's side of the oracle.
Eigen::Vector3d loadedCentroidMm(const LoadedVolume& v, double threshold) {
  const auto& g = v.field->geometry();
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  double weight = 0.0;
  for (int k = 0; k < g.dims[2]; ++k)
    for (int j = 0; j < g.dims[1]; ++j)
      for (int i = 0; i < g.dims[0]; ++i) {
        const double w = v.field->voxel(i, j, k) - threshold;
        if (w <= 0.0) continue;
        const Eigen::Vector3d p = g.origin_W_m + g.direction_W * g.spacing_m.cwiseProduct(Eigen::Vector3d(i, j, k));
        sum += w * p;
        weight += w;
      }
  EXPECT_GT(weight, 0.0);
  return sum / weight * 1e3;
}

/// The landmark error in voxels of the written series along its own axes.
Eigen::Vector3d errorVoxels(const WrittenSeries& s, const Eigen::Vector3d& error_mm) {
  return s.source_ijk_to_lps_mm.topLeftCorner<3, 3>().inverse() * error_mm;
}

bool anyNotice(const LoadedVolume& v, const std::string& text) {
  return std::any_of(v.info.notices.begin(), v.info.notices.end(),
                     [&](const std::string& n) { return n.find(text) != std::string::npos; });
}

std::string notices(const LoadedVolume& v) {
  std::string out;
  for (const auto& n : v.info.notices) out += "\n  " + n;
  return out;
}

/// Loads `s` and checks its landmark against the oracle to a tenth of a voxel on each axis.
LoadedVolume expectLandmark(const SourceVolume& src, const WrittenSeries& s, const VolumeLoadOptions& options = {},
                            double threshold_stored = kBoneStored) {
  const LoadedVolume v = loadVolume(s.folder, options);
  const Eigen::Vector3d oracle = landmarkLps(src, s, threshold_stored);
  const double threshold = src.rescale_slope * threshold_stored + src.rescale_intercept;
  const Eigen::Vector3d loaded = loadedCentroidMm(v, threshold);
  const Eigen::Vector3d err = errorVoxels(s, loaded - oracle);
  std::cout << "[landmark] " << s.folder.filename().string() << ": " << (loaded - oracle).norm() << " mm, voxels "
            << err.transpose() << notices(v) << "\n";
  EXPECT_LT(err.cwiseAbs().maxCoeff(), 0.1) << loaded.transpose() << " vs oracle " << oracle.transpose();
  return v;
}

class DicomRegularization : public testing::Test {
 protected:
  void SetUp() override {
    dir_ = std::make_unique<TempDir>(testing::UnitTest::GetInstance()->current_test_info()->name());
  }
  fs::path folder(const std::string& name) const { return dir_->path() / name; }
  std::unique_ptr<TempDir> dir_;
};

TEST_F(DicomRegularization, PlainSeriesLoadsWithoutNotices) {
  VH_REQUIRE_SHARED(shared, kCtHead);
  const SourceVolume src = ctHeadSmall();
  const WrittenSeries s = writeSeries(folder("plain"), src, SeriesSpec{});
  const LoadedVolume v = expectLandmark(src, s);
  EXPECT_TRUE(v.info.notices.empty()) << notices(v);
  EXPECT_EQ(v.field->geometry().dims[2], 93);
}

TEST_F(DicomRegularization, GantryTiltIsResampledAndSaid) {
  VH_REQUIRE_SHARED(shared, kCtHead);
  const SourceVolume src = ctHeadSmall();
  for (TiltConvention convention : {TiltConvention::kTiltedPlane, TiltConvention::kShearedPositions}) {
    SeriesSpec spec;
    spec.gantry_tilt_deg = 18.5;
    spec.tilt_convention = convention;
    const WrittenSeries s =
        writeSeries(folder(convention == TiltConvention::kTiltedPlane ? "plane" : "shear"), src, spec);
    const LoadedVolume v = expectLandmark(src, s);
    EXPECT_TRUE(anyNotice(v, "resampled from a gantry tilt of 18.5 deg")) << notices(v);
    // The grid is rectilinear (orthonormal directions) and keeps every slice's anatomy.
    const auto& g = v.field->geometry();
    EXPECT_LT((g.direction_W.transpose() * g.direction_W - Eigen::Matrix3d::Identity()).norm(), 1e-9);
    EXPECT_GT(g.dims[1], 64);
  }
}

TEST_F(DicomRegularization, MissingSlicesAreFilledAndTheirPositionsSaid) {
  VH_REQUIRE_SHARED(shared, kCtHead);
  const SourceVolume src = ctHeadSmall();
  SeriesSpec spec;
  spec.drop_slices = {40, 41, 42};
  const WrittenSeries s = writeSeries(folder("gap"), src, spec);
  const LoadedVolume v = expectLandmark(src, s);
  EXPECT_EQ(v.field->geometry().dims[2], 93);
  EXPECT_NEAR(v.field->geometry().spacing_m.z(), 1.5e-3, 1e-9);
  EXPECT_TRUE(anyNotice(v, "missing slices: a gap of 6.00 mm (about 3 slices)")) << notices(v);
  // The gap's neighbours are named by file and position.
  EXPECT_TRUE(anyNotice(v, s.files[39].filename().string())) << notices(v);
  EXPECT_TRUE(anyNotice(v, s.files[40].filename().string())) << notices(v);
}

TEST_F(DicomRegularization, AMissingSliceOfTheRealHeadKeepsTheOtherSlicesExact) {
  VH_REQUIRE_SHARED(shared, kCtHead);
  const LoadedVolume full = loadVolume(shared);
  TempDir tmp("missing_slice");
  for (const auto& e : fs::directory_iterator(shared)) {
    if (e.path().filename() != "CTHead50.dcm") fs::copy_file(e.path(), tmp / e.path().filename().string());
  }
  const LoadedVolume gapped = loadVolume(tmp.path());
  EXPECT_TRUE(anyNotice(gapped, "CTHead49.dcm")) << notices(gapped);
  EXPECT_TRUE(anyNotice(gapped, "CTHead51.dcm")) << notices(gapped);
  const auto& g = gapped.field->geometry();
  const auto& f = full.field->geometry();
  ASSERT_EQ(g.dims, f.dims);
  EXPECT_LT((g.origin_W_m - f.origin_W_m).norm(), 1e-9);
  // Slices that were read land on grid planes (exact); the filled one lies between its
  // neighbours' values, and close to the real slice the test removed.
  int differing = 0;
  double error_sum = 0.0, real_sum = 0.0;
  for (int k = 0; k < g.dims[2]; ++k)
    for (int j = 0; j < g.dims[1]; ++j)
      for (int i = 0; i < g.dims[0]; ++i) {
        const double a = gapped.field->voxel(i, j, k), b = full.field->voxel(i, j, k);
        if (a == b) continue;
        ++differing;
        ASSERT_NE(k, 0);
        ASSERT_NE(k + 1, g.dims[2]);
        const double lo = std::min(full.field->voxel(i, j, k - 1), full.field->voxel(i, j, k + 1));
        const double hi = std::max(full.field->voxel(i, j, k - 1), full.field->voxel(i, j, k + 1));
        EXPECT_GE(a, lo - 1.0);
        EXPECT_LE(a, hi + 1.0);
        error_sum += std::abs(a - b);
        real_sum += std::abs(b);
      }
  EXPECT_LE(differing, g.dims[0] * g.dims[1]);  // one slice at most
  std::cout << "[filled slice] mean |filled - real| / mean |real| = " << error_sum / std::max(real_sum, 1.0) << "\n";
  EXPECT_LT(error_sum, 0.25 * real_sum);
}

TEST_F(DicomRegularization, ExactDuplicatesAreDroppedAndSaid) {
  VH_REQUIRE_SHARED(shared, kCtHead);
  const SourceVolume src = ctHeadSmall();
  SeriesSpec spec;
  spec.duplicate_slices = {10, 60};
  const WrittenSeries s = writeSeries(folder("dup"), src, spec);
  const LoadedVolume v = expectLandmark(src, s);
  EXPECT_EQ(v.field->geometry().dims[2], 93);
  EXPECT_TRUE(anyNotice(v, "dropped 2 duplicate slices")) << notices(v);
}

TEST_F(DicomRegularization, UnevenSpacingIsResampledToTheMedian) {
  VH_REQUIRE_SHARED(shared, kCtHead);
  const SourceVolume src = ctHeadSmall();
  SeriesSpec spec;
  spec.jitter_slices = {{30, 0.4}, {31, -0.3}};
  const WrittenSeries s = writeSeries(folder("jitter"), src, spec);
  const LoadedVolume v = expectLandmark(src, s);
  EXPECT_TRUE(anyNotice(v, "uneven slice spacing")) << notices(v);
  EXPECT_NEAR(v.field->geometry().spacing_m.z(), 1.5e-3, 1e-6);
}

TEST_F(DicomRegularization, EnhancedMultiFrameOpens) {
  VH_REQUIRE_SHARED(shared, kCtHead);
  const SourceVolume src = ctHeadSmall();
  SeriesSpec spec;
  spec.multi_frame = true;
  const WrittenSeries s = writeSeries(folder("enhanced"), src, spec);
  const LoadedVolume v = expectLandmark(src, s);
  EXPECT_EQ(v.field->geometry().dims[2], 93);
  SeriesSpec tilted = spec;
  tilted.gantry_tilt_deg = 10.0;
  const WrittenSeries t = writeSeries(folder("enhanced-tilt"), src, tilted);
  const LoadedVolume vt = expectLandmark(src, t);
  EXPECT_TRUE(anyNotice(vt, "gantry tilt of 10.0 deg")) << notices(vt);
}

TEST_F(DicomRegularization, FourDSeriesOpensTheChosenPhase) {
  VH_REQUIRE_SHARED(shared, kCtHead);
  const SourceVolume src = ctHeadSmall();
  SeriesSpec spec;
  spec.time_points = 3;
  const WrittenSeries s = writeSeries(folder("4d"), src, spec);
  const LoadedVolume first = expectLandmark(src, s);
  EXPECT_EQ(first.info.phase_count, 3);
  EXPECT_TRUE(anyNotice(first, "3 time points")) << notices(first);
  VolumeLoadOptions options;
  options.dicom_phase = 2;
  const LoadedVolume third = loadVolume(s.folder, options);
  EXPECT_EQ(third.info.phase, 2);
  // Phase t holds the source's stored values times phaseScale(t, 3).
  const auto& g = third.field->geometry();
  ASSERT_EQ(g.dims, first.field->geometry().dims);
  const double slope = src.rescale_slope, intercept = src.rescale_intercept;
  int checked = 0;
  for (int k = 0; k < g.dims[2]; k += 7)
    for (int j = 0; j < g.dims[1]; j += 5)
      for (int i = 0; i < g.dims[0]; i += 5) {
        const double stored0 = (first.field->voxel(i, j, k) - intercept) / slope;
        const double stored2 = (third.field->voxel(i, j, k) - intercept) / slope;
        EXPECT_NEAR(stored2, std::round(stored0 * phaseScale(2, 3)), 1.0) << i << " " << j << " " << k;
        ++checked;
      }
  EXPECT_GT(checked, 1000);
  options.dicom_phase = 3;
  EXPECT_CONTAINS(loadErrorOf([&] { loadVolume(s.folder, options); }), "time point 4 asked for, but the series has 3");
}

TEST_F(DicomRegularization, ObliqueMultiEchoMrIsFeltWhereItIs) {
  // A ball in an oblique MR acquisition (rows and columns off the patient axes), two echoes.
  const Eigen::Vector3d centre(12.0, -30.0, 45.0);
  const SourceVolume src = ballVolume({48, 48, 40}, {1.0, 1.0, 1.5}, {-10.0, -55.0, 10.0}, centre, 9.0);
  SeriesSpec spec;
  spec.modality = "MR";
  spec.echoes = 2;
  spec.oblique = Eigen::AngleAxisd(0.4, Eigen::Vector3d(1, 2, 0.5).normalized()).toRotationMatrix();
  const WrittenSeries s = writeSeries(folder("oblique"), src, spec);
  const LoadedVolume v = expectLandmark(src, s, {}, 1000.0);
  EXPECT_EQ(v.info.phase_count, 2);
  // The haptic field answers in W: the ball's centre is inside, a point 12 mm off it is not.
  const Eigen::Vector3d c_W = (s.source_ijk_to_lps_mm.topLeftCorner<3, 3>() *
                                   (src.ijk_to_lps_mm.topLeftCorner<3, 3>().inverse() *
                                    (centre - src.ijk_to_lps_mm.block<3, 1>(0, 3))) +
                               s.source_ijk_to_lps_mm.block<3, 1>(0, 3)) * 1e-3;
  EXPECT_GT(v.field->sample(c_W), 1000.0);
  EXPECT_LT(v.field->sample(c_W + 12e-3 * s.normal_lps), 1.0);
}

TEST_F(DicomRegularization, SeriesAreChosenByNumberUidOrDescription) {
  VH_REQUIRE_SHARED(shared, kCtHead);
  const SourceVolume src = ctHeadSmall();
  SeriesSpec big;
  big.series_number = 3;
  big.series_description = "Head 1.5 mm";
  SeriesSpec small = big;
  small.series_number = 7;
  small.series_description = "Bone scout";
  small.drop_slices = {};
  for (int k = 20; k < 93; ++k) small.drop_slices.push_back(k);
  const WrittenSeries a = writeSeries(folder("study"), src, big);
  const WrittenSeries b = writeSeries(folder("study"), src, small);
  const LoadedVolume largest = loadVolume(a.folder);
  EXPECT_EQ(largest.info.series_number, 3);
  EXPECT_TRUE(anyNotice(largest, "loaded series 3 'Head 1.5 mm' (93 files) of 2 series")) << notices(largest);
  VolumeLoadOptions options;
  options.dicom_series = "7";
  EXPECT_EQ(loadVolume(a.folder, options).field->geometry().dims[2], 20);
  options.dicom_series = b.series_uid;
  EXPECT_EQ(loadVolume(a.folder, options).info.series_number, 7);
  options.dicom_series = "SCOUT";
  EXPECT_EQ(loadVolume(a.folder, options).info.series_number, 7);
  options.dicom_series = "lung";
  const std::string msg = loadErrorOf([&] { loadVolume(a.folder, options); });
  EXPECT_CONTAINS(msg, "no series matches 'lung'");
  EXPECT_CONTAINS(msg, "series 7 'Bone scout' (20 files)");
}

TEST_F(DicomRegularization, TheLoadReportsProgressAndCanBeCancelled) {
  VH_REQUIRE_SHARED(shared, kCtHead);
  VolumeLoadOptions options;
  double last = -1.0;
  bool monotone = true;
  options.progress = [&](double f) {
    monotone = monotone && f >= last;
    last = f;
  };
  loadVolume(shared, options);
  EXPECT_TRUE(monotone);
  EXPECT_GT(last, 0.6);
  std::atomic<bool> cancel{false};
  options.cancel = &cancel;
  options.progress = [&](double) { cancel = true; };
  EXPECT_THROW(loadVolume(shared, options), LoadCancelled);
}

TEST(DicomDir, OpeningTheIndexOpensItsSeries) {
  VH_REQUIRE_SHARED(phantom, "ct/philips-head-phantom-bone");
  const fs::path dirfile = phantom / "DIRFILE";
  if (!fs::exists(dirfile)) GTEST_SKIP() << "no DIRFILE in " << phantom;
  const LoadedVolume v = loadVolume(dirfile);
  EXPECT_EQ(v.field->geometry().dims[2], 140);
}

// ---- The regulariser alone, on fields linear in (u, v, d): exact --------------------------------

TEST(SliceStack, ResamplingIsExactForLinearFieldsOnShearedGappedStacks) {
  detail::SliceStack stack;
  stack.columns = 9;
  stack.rows = 7;
  stack.column_spacing_mm = 0.8;
  stack.row_spacing_mm = 0.6;
  const std::vector<double> d = {0.0, 1.0, 2.0, 5.0, 6.0, 7.1, 8.0};  // a gap and a jitter
  for (double dk : d) stack.offset_mm.emplace_back(0.0, 0.35 * dk, dk);  // sheared along v
  const auto field = [](const Eigen::Vector3d& uvd) { return 3.0 + 2.0 * uvd.x() - 1.5 * uvd.y() + 4.0 * uvd.z(); };
  std::vector<double> in;
  for (std::size_t k = 0; k < d.size(); ++k)
    for (int j = 0; j < stack.rows; ++j)
      for (int i = 0; i < stack.columns; ++i)
        in.push_back(field(stack.offset_mm[k] + Eigen::Vector3d(i * 0.8, j * 0.6, 0.0)));
  const detail::StackAnalysis a = detail::analyseStack(stack);
  EXPECT_TRUE(a.sheared);
  EXPECT_TRUE(a.uneven);
  ASSERT_EQ(a.gaps.size(), 1u);
  EXPECT_EQ(a.gaps[0].slice, 2);
  EXPECT_EQ(a.gaps[0].missing, 2);
  EXPECT_NEAR(a.shear_deg, std::atan(0.35) * 180.0 / M_PI, 1e-9);
  const detail::RegularGrid grid = detail::regularGridFor(stack, a);
  EXPECT_EQ(grid.dims[2], 9);
  EXPECT_EQ(grid.dims[0], 9);
  EXPECT_GE(grid.dims[1], 7 + static_cast<int>(0.35 * 8.0 / 0.6));
  std::vector<double> out(static_cast<std::size_t>(grid.dims[0]) * grid.dims[1] * grid.dims[2]);
  const double background = -1000.0;
  ASSERT_TRUE(detail::resampleStack(in.data(), stack, grid, background, out.data()));
  int inside = 0;
  for (int z = 0; z < grid.dims[2]; ++z)
    for (int y = 0; y < grid.dims[1]; ++y)
      for (int x = 0; x < grid.dims[0]; ++x) {
        const Eigen::Vector3d uvd = grid.origin_mm + grid.spacing_mm.cwiseProduct(Eigen::Vector3d(x, y, z));
        // Inside both neighbouring slices' footprints along v (the shear moves them).
        const double v0 = 0.35 * uvd.z();
        const double value = out[(static_cast<std::size_t>(z) * grid.dims[1] + y) * grid.dims[0] + x];
        if (uvd.y() >= v0 + 0.35 * 3.0 + 1e-9 && uvd.y() <= v0 + 6 * 0.6 - 0.35 * 3.0 - 1e-9) {
          EXPECT_NEAR(value, field(uvd), 1e-9) << x << " " << y << " " << z;
          ++inside;
        } else {
          EXPECT_GE(value, background - 1e-9);
        }
      }
  EXPECT_GT(inside, 50);
}

TEST(SliceStack, RegularStacksAreRecognised) {
  detail::SliceStack stack;
  stack.columns = stack.rows = 4;
  for (int k = 0; k < 5; ++k) stack.offset_mm.emplace_back(1e-5, 0.0, 1.25 * k + (k == 3 ? 4e-4 : 0.0));
  EXPECT_TRUE(detail::analyseStack(stack).regular());
}

}  // namespace
}  // namespace vh::io::test
