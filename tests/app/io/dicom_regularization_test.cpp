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
#include <vtkDICOMDictHash.h>
#include <vtkDICOMMetaData.h>
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
    EXPECT_TRUE(anyNotice(v, "onto " + std::to_string(g.dims[0]) + " x " + std::to_string(g.dims[1]) +
                                 " pixels a slice (the slices are 64 x 64)"))
        << "a grid larger than the slices is said: " << notices(v);
    EXPECT_LT((g.direction_W.transpose() * g.direction_W - Eigen::Matrix3d::Identity()).norm(), 1e-9);
    EXPECT_GT(g.dims[1], 64);
  }
}

/// An oblique MR series as scanners and PACS write it: ImagePositionPatient to three decimals,
/// ImageOrientationPatient to six, and one slice 0.6 mm off (so the stack is regularised). The
/// rounding moves the slices off one another in their planes by about a micrometre: the grid
/// keeps the slices' 48 x 64 pixels (not 49 x 65 with a row and a column of background), the
/// notices say what was resampled, and the ball is where the files put it (to a tenth of a voxel).
TEST_F(DicomRegularization, PositionsRoundedAsScannersWriteThemKeepTheSlicesSize) {
  const Eigen::Vector3d centre(5.0, -20.0, 40.0);
  const SourceVolume src = ballVolume({48, 64, 24}, {0.45, 0.45, 3.0}, {-5.0, -30.0, 10.0}, centre, 6.0);
  SeriesSpec spec;
  spec.modality = "MR";
  spec.oblique = Eigen::AngleAxisd(0.3, Eigen::Vector3d(2, 1, 0.7).normalized()).toRotationMatrix();
  spec.jitter_slices = {{11, 0.6}};
  spec.instance_tags = [](vtkDICOMMetaData* meta, int instance, int) {
    for (const auto& [tag, scale] : {std::pair{DC::ImagePositionPatient, 1e3}, std::pair{DC::ImageOrientationPatient, 1e6}}) {
      const vtkDICOMValue& value = meta->Get(instance, tag);
      double x[6] = {};
      const int n = static_cast<int>(std::min<unsigned>(6, value.GetNumberOfValues()));
      value.GetValues(x, static_cast<unsigned>(n));
      for (int a = 0; a < n; ++a) x[a] = std::round(x[a] * scale) / scale;
      meta->Set(instance, tag, vtkDICOMValue(vtkDICOMVR::DS, x, static_cast<unsigned>(n)));
    }
  };
  const WrittenSeries s = writeSeries(folder("rounded"), src, spec);
  const LoadedVolume v = expectLandmark(src, s, {}, 1000.0);
  const auto& g = v.field->geometry();
  EXPECT_EQ(g.dims[0], 48) << notices(v);
  EXPECT_EQ(g.dims[1], 64) << notices(v);
  EXPECT_TRUE(anyNotice(v, "uneven slice spacing")) << notices(v);
  EXPECT_FALSE(anyNotice(v, "sheared")) << notices(v);
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

/// A two-part head CT as GE writes it: 14 slices 4 mm thick at 4 mm, then 13 slices 7 mm
/// thick at 7 mm (the step between the parts, 5.5 mm, what the two slices cover), with
/// SliceThickness per file. The stored values are linear in the written LPS position (exact
/// integers), so the loaded field's value at each voxel tells where that voxel lies.
struct TwoPartSeries {
  static constexpr int kThin = 14, kThick = 13;
  static double dMm(int k) { return k < kThin ? 4.0 * k : 4.0 * (kThin - 1) + 5.5 + 7.0 * (k - kThin); }
  static double value(const Eigen::Vector3d& p_mm) { return 10.0 + 3.0 * p_mm.x() + 2.0 * p_mm.y() + 20.0 * p_mm.z(); }
  static SourceVolume source() {
    const Eigen::Vector3d origin(-16.0, -16.0, 0.0);
    SourceVolume src = ballVolume({16, 16, kThin + kThick}, {2.0, 2.0, 4.0}, origin, origin, 0.0);
    auto* p = static_cast<short*>(src.image->GetScalarPointer());
    for (int k = 0; k < kThin + kThick; ++k)
      for (int j = 0; j < 16; ++j)
        for (int i = 0; i < 16; ++i) {
          *p++ = static_cast<short>(value(origin + Eigen::Vector3d(2.0 * i, 2.0 * j, dMm(k))));
        }
    return src;
  }
  static SeriesSpec spec() {
    SeriesSpec spec;
    for (int k = kThin; k < kThin + kThick; ++k) spec.jitter_slices.emplace_back(k, dMm(k) - 4.0 * k);
    spec.instance_tags = [](vtkDICOMMetaData* meta, int instance, int k) {
      meta->Set(instance, DC::SliceThickness, k < kThin ? 4.0 : 7.0);
    };
    return spec;
  }
};

/// The largest distance [mm] along the slice normal between where the loaded field's voxels are
/// and where their values were written (TwoPartSeries::value; 1/20 mm per unit).
double twoPartErrorMm(const LoadedVolume& v) {
  const auto& g = v.field->geometry();
  double worst = 0.0;
  for (int k = 0; k < g.dims[2]; ++k)
    for (int j = 0; j < g.dims[1]; ++j)
      for (int i = 0; i < g.dims[0]; ++i) {
        const Eigen::Vector3d p_mm =
            (g.origin_W_m + g.direction_W * g.spacing_m.cwiseProduct(Eigen::Vector3d(i, j, k))) * 1e3;
        worst = std::max(worst, std::abs(v.field->voxel(i, j, k) - TwoPartSeries::value(p_mm)) / 20.0);
      }
  return worst;
}

TEST_F(DicomRegularization, AChangeOfSliceThicknessIsNotAGap) {
  const SourceVolume src = TwoPartSeries::source();
  const WrittenSeries s = writeSeries(folder("two-part"), src, TwoPartSeries::spec());
  const LoadedVolume v = loadVolume(s.folder);
  std::cout << "[two parts]" << notices(v) << "\n";
  ASSERT_EQ(v.info.notices.size(), 1u) << notices(v);
  EXPECT_CONTAINS(v.info.notices[0],
                  "slices in 2 parts: 14 at 4.00 mm (4.00 mm thick), then 13 at 7.00 mm (7.00 mm thick): resampled to");
  EXPECT_FALSE(anyNotice(v, "missing")) << notices(v);
  EXPECT_FALSE(anyNotice(v, "uneven")) << notices(v);
  // The finest part's spacing, evened out to span 0 .. 141.5 mm: 35 steps of 4.04 mm.
  const auto& g = v.field->geometry();
  EXPECT_EQ(g.dims[2], 36);
  EXPECT_NEAR(g.spacing_m.z(), 141.5e-3 / 35, 1e-9);
  EXPECT_NEAR(g.spacing_m.z(), 4e-3, 0.05e-3);
  // Every voxel within a tenth of a voxel (0.4 mm) of where its value was written; the
  // linear field makes the interpolation exact, so the bound is the rounding to integers.
  const double error_mm = twoPartErrorMm(v);
  std::cout << "[two parts] worst position error " << error_mm << " mm\n";
  EXPECT_LT(error_mm, 0.1 * 4.0);
  EXPECT_LT(error_mm, 0.05);
}

TEST_F(DicomRegularization, AMissingSliceOfAThinPartIsStillAGap) {
  const SourceVolume src = TwoPartSeries::source();
  SeriesSpec spec = TwoPartSeries::spec();
  spec.drop_slices = {6};
  const WrittenSeries s = writeSeries(folder("two-part-gap"), src, spec);
  const LoadedVolume v = loadVolume(s.folder);
  std::cout << "[two parts, gap]" << notices(v) << "\n";
  EXPECT_TRUE(anyNotice(v, "slices in 2 parts: 13 at 4.00 mm (4.00 mm thick), then 13 at 7.00 mm")) << notices(v);
  // Files 6 and 7 (0-based 5 and 6 in writing order) hold source slices 5 and 7.
  EXPECT_TRUE(anyNotice(v, "missing slice: a gap of 8.00 mm (about 1 slice) between " +
                               s.files[5].filename().string() + " at 20.00 mm and " +
                               s.files[6].filename().string() + " at 28.00 mm"))
      << notices(v);
  EXPECT_EQ(std::count_if(v.info.notices.begin(), v.info.notices.end(),
                          [](const std::string& n) { return n.find("missing") != std::string::npos; }),
            1);
  EXPECT_FALSE(anyNotice(v, "uneven")) << notices(v);
  EXPECT_EQ(v.field->geometry().dims[2], 36);
  EXPECT_LT(twoPartErrorMm(v), 0.05);
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

/// The field linear in (u, v, d) [mm] the regulariser's tests resample.
double linearField(const Eigen::Vector3d& uvd) { return 3.0 + 2.0 * uvd.x() - 1.5 * uvd.y() + 4.0 * uvd.z(); }

/// A stack of `columns` x `rows` slices of the given pixel spacings [mm] at `offset_mm` (u, v, d
/// of each slice's first pixel), and its voxels of linearField(), slice by slice.
detail::SliceStack linearStack(int columns, int rows, double column_mm, double row_mm,
                               const std::vector<Eigen::Vector3d>& offset_mm, std::vector<double>& voxels) {
  detail::SliceStack stack;
  stack.columns = columns;
  stack.rows = rows;
  stack.column_spacing_mm = column_mm;
  stack.row_spacing_mm = row_mm;
  stack.offset_mm = offset_mm;
  voxels.clear();
  for (const Eigen::Vector3d& o : offset_mm)
    for (int j = 0; j < rows; ++j)
      for (int i = 0; i < columns; ++i) voxels.push_back(linearField(o + Eigen::Vector3d(i * column_mm, j * row_mm, 0.0)));
  return stack;
}

TEST(SliceStack, ResamplingIsExactForLinearFieldsOnShearedGappedStacks) {
  const std::vector<double> d = {0.0, 1.0, 2.0, 5.0, 6.0, 7.1, 8.0};  // a gap and a jitter
  std::vector<Eigen::Vector3d> offsets;
  for (double dk : d) offsets.emplace_back(0.0, 0.35 * dk, dk);  // sheared along v
  std::vector<double> in;
  const detail::SliceStack stack = linearStack(9, 7, 0.8, 0.6, offsets, in);
  const auto field = linearField;
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

TEST(SliceStack, OffsetsWithinTheRoundingKeepTheSlicesSizeAndTheirEdges) {
  // Slices off one another in their planes by up to a micrometre (positions and orientation
  // cosines rounded as scanners write them), one step uneven: regularised onto the slices' own
  // 9 x 7 pixels, every grid point inside a footprint within the rounding, so a linear field is
  // reproduced to its slope times that micrometre, at the edges too (no background).
  const std::vector<double> d = {0.0, 3.0, 6.0, 9.6, 12.0, 15.0};
  const double offsets[][2] = {{0.0, 0.0}, {1e-3, -4e-4}, {-7e-4, 1e-3}, {3e-4, 8e-4}, {-1e-3, -1e-3}, {6e-4, 2e-4}};
  std::vector<Eigen::Vector3d> offset_mm;
  for (std::size_t k = 0; k < d.size(); ++k) offset_mm.emplace_back(offsets[k][0], offsets[k][1], d[k]);
  std::vector<double> in;
  const detail::SliceStack stack = linearStack(9, 7, 0.45, 0.5, offset_mm, in);
  const auto field = linearField;
  const detail::StackAnalysis a = detail::analyseStack(stack);
  EXPECT_FALSE(a.sheared);
  EXPECT_TRUE(a.uneven);
  const detail::RegularGrid grid = detail::regularGridFor(stack, a);
  EXPECT_EQ(grid.dims[0], 9);
  EXPECT_EQ(grid.dims[1], 7);
  std::vector<double> out(static_cast<std::size_t>(grid.dims[0]) * grid.dims[1] * grid.dims[2]);
  ASSERT_TRUE(detail::resampleStack(in.data(), stack, grid, -1000.0, out.data()));
  const double slope_bound = (2.0 + 1.5) * 2e-3;  // |grad| along u and v times twice the largest offset
  for (int z = 0; z < grid.dims[2]; ++z)
    for (int y = 0; y < grid.dims[1]; ++y)
      for (int x = 0; x < grid.dims[0]; ++x) {
        const Eigen::Vector3d uvd = grid.origin_mm + grid.spacing_mm.cwiseProduct(Eigen::Vector3d(x, y, z));
        EXPECT_NEAR(out[(static_cast<std::size_t>(z) * grid.dims[1] + y) * grid.dims[0] + x], field(uvd), slope_bound)
            << x << " " << y << " " << z;
      }
}

/// The stack of a two-part head CT: 14 slices 4 mm thick at 4 mm, a 5.5 mm step, 13 slices
/// 7 mm thick at 7 mm; `thickness` false leaves the thickness unknown.
detail::SliceStack twoPartStack(bool thickness) {
  detail::SliceStack stack;
  stack.columns = stack.rows = 4;
  for (int k = 0; k < 27; ++k) {
    stack.offset_mm.emplace_back(0.0, 0.0, k < 14 ? 4.0 * k : 57.5 + 7.0 * (k - 14));
    if (thickness) stack.thickness_mm.push_back(k < 14 ? 4.0 : 7.0);
  }
  return stack;
}

TEST(SliceStack, PartsOfDifferentThicknessAreNoGaps) {
  for (bool thickness : {true, false}) {
    const detail::StackAnalysis a = detail::analyseStack(twoPartStack(thickness));
    EXPECT_TRUE(a.uneven);
    EXPECT_TRUE(a.gaps.empty()) << thickness;
    EXPECT_FALSE(a.irregular_steps);
    ASSERT_EQ(a.parts.size(), 2u);
    EXPECT_EQ(a.parts[0].first, 0);
    EXPECT_EQ(a.parts[0].slices(), 14);
    EXPECT_EQ(a.parts[1].first, 14);
    EXPECT_EQ(a.parts[1].slices(), 13);
    EXPECT_NEAR(a.parts[0].spacing_mm, 4.0, 1e-12);
    EXPECT_NEAR(a.parts[1].spacing_mm, 7.0, 1e-12);
    EXPECT_EQ(a.parts[1].thickness_mm, thickness ? 7.0 : 0.0);
    EXPECT_NEAR(a.grid_spacing_mm, 4.0, 1e-12);
    const detail::RegularGrid grid = detail::regularGridFor(twoPartStack(thickness), a);
    EXPECT_EQ(grid.dims[2], 36);
    EXPECT_NEAR(grid.origin_mm.z() + 35 * grid.spacing_mm.z(), 141.5, 1e-9);
  }
  // The parts meet without a transition step (the 7 mm part's first step starts at the last
  // 4 mm slice): 1.5 mm uncovered, no slice missing.
  detail::SliceStack abrupt = twoPartStack(true);
  for (int k = 14; k < 27; ++k) abrupt.offset_mm[k].z() += 1.5;
  const detail::StackAnalysis b = detail::analyseStack(abrupt);
  EXPECT_TRUE(b.gaps.empty());
  EXPECT_EQ(b.parts.size(), 2u);
  // A 4 mm slice missing is a gap; where thick slices cover the step, it is not.
  detail::SliceStack gapped = twoPartStack(true);
  gapped.offset_mm.erase(gapped.offset_mm.begin() + 6);
  gapped.thickness_mm.erase(gapped.thickness_mm.begin() + 6);
  const detail::StackAnalysis c = detail::analyseStack(gapped);
  ASSERT_EQ(c.gaps.size(), 1u);
  EXPECT_EQ(c.gaps[0].slice, 5);
  EXPECT_EQ(c.gaps[0].missing, 1);
  EXPECT_EQ(c.parts.size(), 2u);
  EXPECT_FALSE(c.irregular_steps);
  for (double& t : gapped.thickness_mm) t = 8.0;
  EXPECT_TRUE(detail::analyseStack(gapped).gaps.empty());
}

TEST(SliceStack, RegularStacksAreRecognised) {
  detail::SliceStack stack;
  stack.columns = stack.rows = 4;
  for (int k = 0; k < 5; ++k) stack.offset_mm.emplace_back(1e-5, 0.0, 1.25 * k + (k == 3 ? 4e-4 : 0.0));
  EXPECT_TRUE(detail::analyseStack(stack).regular());
}

}  // namespace
}  // namespace vh::io::test
