// Tests of the DICOM fixture writer itself, through vtk-dicom's own parser, reader and
// vtkDICOMCTRectifier (never through vh::io's loader, which the fixtures exist to test).

#include "dicom_fixtures.h"

#include <cmath>
#include <iostream>
#include <set>
#include <string>
#include <vector>

#include <Eigen/Geometry>
#include <gtest/gtest.h>
#include <vtkDICOMCTRectifier.h>
#include <vtkDICOMDictHash.h>
#include <vtkDICOMDirectory.h>
#include <vtkDICOMItem.h>
#include <vtkDICOMMetaData.h>
#include <vtkDICOMParser.h>
#include <vtkDICOMReader.h>
#include <vtkDICOMSequence.h>
#include <vtkDICOMValue.h>
#include <vtkImageData.h>
#include <vtkMatrix4x4.h>
#include <vtkStringArray.h>

#include "io_test_support.h"

namespace vh::io::test {
namespace {

constexpr char kCtHead[] = "ct/ct-head-small";
constexpr double kBoneStored = 1000.0;  // stored units (the oracle's threshold)
constexpr double kDsTolMm = 1e-4;       // DS text keeps ~12 significant digits

vtkSmartPointer<vtkDICOMMetaData> parse(const fs::path& file) {
  auto meta = vtkSmartPointer<vtkDICOMMetaData>::New();
  auto parser = vtkSmartPointer<vtkDICOMParser>::New();
  parser->SetFileName(file.string().c_str());
  parser->SetMetaData(meta);
  parser->Update();
  EXPECT_EQ(parser->GetErrorCode(), 0u) << file;
  return meta;
}

Eigen::Vector3d vec3(const vtkDICOMValue& v) {
  return {v.GetDouble(0), v.GetDouble(1), v.GetDouble(2)};
}

/// vtkDICOMReader over `files` (stored values, rows in file order).
vtkSmartPointer<vtkDICOMReader> readFiles(const std::vector<fs::path>& files) {
  auto names = vtkSmartPointer<vtkStringArray>::New();
  for (const auto& f : files) names->InsertNextValue(f.string());
  auto reader = vtkSmartPointer<vtkDICOMReader>::New();
  reader->SetFileNames(names);
  reader->SetMemoryRowOrderToFileNative();
  reader->AutoRescaleOff();
  reader->Update();
  EXPECT_EQ(reader->GetErrorCode(), 0u);
  return reader;
}

/// Weighted centroid (value - threshold) in LPS [mm] of an image in vtk-dicom's data frame.
Eigen::Vector3d centroidLps(vtkImageData* image, vtkMatrix4x4* lps_from_data, double threshold) {
  int ext[6];
  image->GetExtent(ext);
  double origin[3], spacing[3];
  image->GetOrigin(origin);
  image->GetSpacing(spacing);
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  double weight = 0.0;
  for (int k = ext[4]; k <= ext[5]; ++k)
    for (int j = ext[2]; j <= ext[3]; ++j)
      for (int i = ext[0]; i <= ext[1]; ++i) {
        const double value = image->GetScalarComponentAsDouble(i, j, k, 0);
        if (value <= threshold) continue;
        const double d[4] = {origin[0] + i * spacing[0], origin[1] + j * spacing[1],
                             origin[2] + k * spacing[2], 1.0};
        double p[4];
        lps_from_data->MultiplyPoint(d, p);
        sum += (value - threshold) * Eigen::Vector3d(p[0], p[1], p[2]);
        weight += value - threshold;
      }
  EXPECT_GT(weight, 0.0);
  return sum / weight;
}

class DicomFixture : public testing::Test {
 protected:
  void SetUp() override {
    dir_ = std::make_unique<TempDir>(testing::UnitTest::GetInstance()->current_test_info()->name());
  }
  fs::path folder(const std::string& name) const { return dir_->path() / name; }
  std::unique_ptr<TempDir> dir_;
};

TEST_F(DicomFixture, PlainSeriesReproducesTheSourceGeometry) {
  VH_REQUIRE_SHARED(shared, kCtHead);
  const SourceVolume src = ctHeadSmall();
  int dims[3];
  src.image->GetDimensions(dims);
  ASSERT_EQ(dims[0], 64);
  ASSERT_EQ(dims[1], 64);
  ASSERT_EQ(dims[2], 93);
  const WrittenSeries s = writeSeries(folder("plain"), src, SeriesSpec{});
  ASSERT_EQ(s.files.size(), 93u);
  EXPECT_TRUE(s.source_ijk_to_lps_mm.isApprox(src.ijk_to_lps_mm, 1e-12));
  const auto reader = readFiles(s.files);
  int out_dims[3];
  reader->GetOutput()->GetDimensions(out_dims);
  EXPECT_EQ(out_dims[2], 93);
  const Eigen::Vector3d oracle = landmarkLps(src, s, kBoneStored);
  const Eigen::Vector3d read =
      centroidLps(reader->GetOutput(), reader->GetPatientMatrix(), kBoneStored);
  EXPECT_LT((read - oracle).norm(), 1e-3) << read.transpose() << " vs " << oracle.transpose();
  EXPECT_EQ(parse(s.files[0])->Get(DC::Modality).AsString(), "CT");
  EXPECT_EQ(parse(s.files[0])->Get(DC::SOPClassUID).AsString(), "1.2.840.10008.5.1.4.1.1.2");
}

TEST_F(DicomFixture, TiltedSeriesPositionsFollowTheTableAndOrientationTheTiltedPlane) {
  VH_REQUIRE_SHARED(shared, kCtHead);
  const SourceVolume src = ctHeadSmall();
  SeriesSpec spec;
  spec.gantry_tilt_deg = 20.0;
  const WrittenSeries s = writeSeries(folder("tilted"), src, spec);
  ASSERT_EQ(s.files.size(), 93u);
  const Eigen::Vector3d w = src.ijk_to_lps_mm.block<3, 1>(0, 2);  // table step [mm]
  const Eigen::Vector3d p0 = vec3(parse(s.files[0])->Get(DC::ImagePositionPatient));
  const double t = 20.0 * M_PI / 180.0;
  for (size_t n = 0; n < s.files.size(); ++n) {
    const auto meta = parse(s.files[n]);
    const Eigen::Vector3d p = vec3(meta->Get(DC::ImagePositionPatient));
    EXPECT_LT((p - (p0 + double(n) * w)).norm(), kDsTolMm) << n;
    const vtkDICOMValue& iop = meta->Get(DC::ImageOrientationPatient);
    const Eigen::Vector3d row(iop.GetDouble(0), iop.GetDouble(1), iop.GetDouble(2));
    const Eigen::Vector3d col(iop.GetDouble(3), iop.GetDouble(4), iop.GetDouble(5));
    EXPECT_NEAR(col.dot(w.normalized()), std::sin(t), 1e-6);
    EXPECT_NEAR(row.dot(col), 0.0, 1e-6);
    EXPECT_NEAR(meta->Get(DC::GantryDetectorTilt).AsDouble(), 20.0, 1e-9);
  }
  // The written stack is sheared: the step along the normal is dz cos(t).
  EXPECT_NEAR(w.dot(s.normal_lps), w.norm() * std::cos(t), 1e-9);
  EXPECT_NEAR(vtkDICOMCTRectifier::GetGantryDetectorTilt(readFiles(s.files)->GetPatientMatrix()),
              20.0, 1e-3);
}

TEST_F(DicomFixture, RectifiedTiltedSeriesHasTheOracleLandmark) {
  VH_REQUIRE_SHARED(shared, kCtHead);
  // Padded: vtkDICOMCTRectifier keeps the input extent, centred, which cuts ~7 columns of
  // anatomy off the first and last slices of the 20 degree stack (0.5-0.8 mm centroid error).
  const SourceVolume src = paddedInPlane(ctHeadSmall(), 10);
  for (TiltConvention convention : {TiltConvention::kTiltedPlane,
                                    TiltConvention::kShearedPositions}) {
    SeriesSpec spec;
    spec.gantry_tilt_deg = 20.0;
    spec.tilt_convention = convention;
    const WrittenSeries s = writeSeries(
        folder(convention == TiltConvention::kTiltedPlane ? "plane" : "shear"), src, spec);
    const Eigen::Vector3d oracle = landmarkLps(src, s, kBoneStored);
    const auto reader = readFiles(s.files);
    auto rectifier = vtkSmartPointer<vtkDICOMCTRectifier>::New();
    rectifier->SetVolumeMatrix(reader->GetPatientMatrix());
    rectifier->SetInputConnection(reader->GetOutputPort());
    rectifier->SetInterpolationModeToLinear();
    rectifier->Update();
    const Eigen::Vector3d rectified =
        centroidLps(rectifier->GetOutput(), rectifier->GetRectifiedMatrix(), kBoneStored);
    // The error in voxels of the written series (its own axes): under a tenth on each axis.
    const Eigen::Vector3d error_voxels =
        s.source_ijk_to_lps_mm.topLeftCorner<3, 3>().inverse() * (rectified - oracle);
    std::cout << "[rectified - oracle] " << (rectified - oracle).norm() << " mm, voxels "
              << error_voxels.transpose() << "\n";
    EXPECT_LT(error_voxels.cwiseAbs().maxCoeff(), 0.1)
        << rectified.transpose() << " vs oracle " << oracle.transpose();
  }
}

TEST_F(DicomFixture, GappedSeriesMissesTheDroppedSlices) {
  VH_REQUIRE_SHARED(shared, kCtHead);
  SeriesSpec spec;
  spec.drop_slices = {40, 41, 42};
  const WrittenSeries s = writeSeries(folder("gap"), ctHeadSmall(), spec);
  ASSERT_EQ(s.files.size(), 90u);
  std::vector<double> along;
  for (const auto& f : s.files) {
    along.push_back(vec3(parse(f)->Get(DC::ImagePositionPatient)).dot(s.normal_lps));
  }
  std::sort(along.begin(), along.end());
  const double dz = 1.5;
  for (size_t n = 1; n < along.size(); ++n) {
    EXPECT_NEAR(along[n] - along[n - 1], n == 40 ? 4 * dz : dz, kDsTolMm) << n;
  }
}

TEST_F(DicomFixture, DuplicatesShareThePositionAndPixelsButNotTheUid) {
  VH_REQUIRE_SHARED(shared, kCtHead);
  SeriesSpec spec;
  spec.duplicate_slices = {10};
  const WrittenSeries s = writeSeries(folder("dup"), ctHeadSmall(), spec);
  ASSERT_EQ(s.files.size(), 94u);
  const auto a = parse(s.files[10]), b = parse(s.files[11]);
  EXPECT_LT((vec3(a->Get(DC::ImagePositionPatient)) - vec3(b->Get(DC::ImagePositionPatient))).norm(),
            1e-12);
  EXPECT_NE(a->Get(DC::SOPInstanceUID).AsString(), b->Get(DC::SOPInstanceUID).AsString());
  EXPECT_EQ(a->Get(DC::SeriesInstanceUID).AsString(), b->Get(DC::SeriesInstanceUID).AsString());
  const auto ra = readFiles({s.files[10]}), rb = readFiles({s.files[11]});
  const auto* pa = static_cast<const short*>(ra->GetOutput()->GetScalarPointer());
  const auto* pb = static_cast<const short*>(rb->GetOutput()->GetScalarPointer());
  EXPECT_TRUE(std::equal(pa, pa + 64 * 64, pb));
}

TEST_F(DicomFixture, JitteredSliceMovesAlongTheNormal) {
  VH_REQUIRE_SHARED(shared, kCtHead);
  SeriesSpec spec;
  spec.jitter_slices = {{30, 0.4}};
  const WrittenSeries s = writeSeries(folder("jitter"), ctHeadSmall(), spec);
  const Eigen::Vector3d p29 = vec3(parse(s.files[29])->Get(DC::ImagePositionPatient));
  const Eigen::Vector3d p30 = vec3(parse(s.files[30])->Get(DC::ImagePositionPatient));
  EXPECT_NEAR((p30 - p29).dot(s.normal_lps), 1.9, kDsTolMm);
  EXPECT_LT((p30 - s.voxelLps(0, 0, 30)).norm(), kDsTolMm);
}

TEST_F(DicomFixture, MultiFrameFileHasPerFramePositions) {
  VH_REQUIRE_SHARED(shared, kCtHead);
  SeriesSpec spec;
  spec.multi_frame = true;
  spec.gantry_tilt_deg = 10.0;
  const WrittenSeries s = writeSeries(folder("enhanced"), ctHeadSmall(), spec);
  ASSERT_EQ(s.files.size(), 1u);
  const auto meta = parse(s.files[0]);
  EXPECT_EQ(meta->Get(DC::SOPClassUID).AsString(), "1.2.840.10008.5.1.4.1.1.2.1");
  EXPECT_EQ(meta->Get(DC::NumberOfFrames).AsInt(), 93);
  const vtkDICOMValue& frames = meta->Get(DC::PerFrameFunctionalGroupsSequence);
  ASSERT_EQ(frames.GetNumberOfValues(), 93u);
  for (unsigned int f = 0; f < 93; ++f) {
    const vtkDICOMItem& item = frames.GetSequenceData()[f];
    const vtkDICOMValue& pos = item.Get(DC::PlanePositionSequence).GetSequenceData()[0].Get(
        DC::ImagePositionPatient);
    EXPECT_LT((vec3(pos) - s.slice_position_lps_mm[f]).norm(), kDsTolMm) << f;
  }
  // vtk-dicom's reader understands the functional groups: 93 slices, the sheared geometry.
  const auto reader = readFiles(s.files);
  int dims[3];
  reader->GetOutput()->GetDimensions(dims);
  EXPECT_EQ(dims[2], 93);
  EXPECT_NEAR(vtkDICOMCTRectifier::GetGantryDetectorTilt(reader->GetPatientMatrix()), 10.0, 1e-3);
}

TEST_F(DicomFixture, FourDSeriesHasDistinctTemporalPositions) {
  VH_REQUIRE_SHARED(shared, kCtHead);
  SeriesSpec spec;
  spec.time_points = 3;
  spec.subsample = 2;
  const SourceVolume src = ctHeadSmall();
  const WrittenSeries s = writeSeries(folder("4d"), src, spec);
  ASSERT_EQ(s.files.size(), 3u * 93u);
  std::set<int> phases;
  for (const auto& f : s.files) {
    const auto meta = parse(f);
    phases.insert(meta->Get(DC::TemporalPositionIdentifier).AsInt());
    EXPECT_EQ(meta->Get(DC::NumberOfTemporalPositions).AsInt(), 3);
    EXPECT_EQ(meta->Get(DC::Rows).AsInt(), 32);
  }
  EXPECT_EQ(phases, (std::set<int>{1, 2, 3}));
  // Phase 2 of slice 50 holds the source's values times phaseScale(2, 3).
  const auto r = readFiles({s.files[2 * 93 + 50]});
  const double written = r->GetOutput()->GetScalarComponentAsDouble(16, 16, 0, 0);
  EXPECT_NEAR(written, std::round(phaseScale(2, 3) * src.image->GetScalarComponentAsDouble(32, 32, 50, 0)),
              0.5);
}

TEST_F(DicomFixture, ObliqueMultiEchoMrBallLandsOnTheOracle) {
  const SourceVolume ball = ballVolume({40, 36, 30}, {1.0, 1.2, 2.0}, {-20, -25, -30},
                                       {3.0, -4.0, 2.0}, 8.0);
  SeriesSpec spec;
  spec.modality = "MR";
  spec.echoes = 2;
  spec.oblique = Eigen::AngleAxisd(0.3, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  const WrittenSeries s = writeSeries(folder("mr"), ball, spec);
  ASSERT_EQ(s.files.size(), 60u);
  std::set<double> echo_times;
  std::vector<fs::path> first_echo;
  for (const auto& f : s.files) {
    const auto meta = parse(f);
    EXPECT_EQ(meta->Get(DC::SOPClassUID).AsString(), "1.2.840.10008.5.1.4.1.1.4");
    echo_times.insert(meta->Get(DC::EchoTime).AsDouble());
    if (meta->Get(DC::EchoNumbers).AsInt() == 1) first_echo.push_back(f);
  }
  EXPECT_EQ(echo_times, (std::set<double>{10.0, 20.0}));
  ASSERT_EQ(first_echo.size(), 30u);
  const Eigen::Vector3d oracle = landmarkLps(ball, s, 1000.0);
  // The oracle is the rotated ball centre (the ball is symmetric on its grid up to sampling).
  EXPECT_LT((oracle - s.voxelLps(23.0, 17.5, 16.0)).norm(), 0.5);
  const auto reader = readFiles(first_echo);
  const Eigen::Vector3d read = centroidLps(reader->GetOutput(), reader->GetPatientMatrix(), 1000.0);
  EXPECT_LT((read - oracle).norm(), 1e-3) << read.transpose() << " vs " << oracle.transpose();
}

TEST_F(DicomFixture, SeveralSeriesShareOneFolder) {
  const SourceVolume ball = ballVolume({16, 16, 12}, {1.0, 1.0, 1.0}, {0, 0, 0}, {8, 8, 6}, 4.0);
  SeriesSpec a, b;
  a.series_description = "first";
  b.series_description = "second";
  b.series_number = 2;
  b.series_uid = "1.2.826.0.1.3680043.2.1125.99.14.2";
  const WrittenSeries sa = writeSeries(folder("two"), ball, a);
  const WrittenSeries sb = writeSeries(folder("two"), ball, b);
  EXPECT_EQ(sb.series_uid, b.series_uid);
  EXPECT_NE(sa.series_uid, sb.series_uid);
  auto directory = vtkSmartPointer<vtkDICOMDirectory>::New();
  directory->SetDirectoryName(folder("two").string().c_str());
  directory->Update();
  ASSERT_EQ(directory->GetNumberOfSeries(), 2);
  std::set<std::string> descriptions;
  for (int i = 0; i < 2; ++i) {
    descriptions.insert(directory->GetMetaDataForSeries(i)->Get(DC::SeriesDescription).AsString());
    EXPECT_EQ(directory->GetFileNamesForSeries(i)->GetNumberOfValues(), 12);
  }
  EXPECT_EQ(descriptions, (std::set<std::string>{"first", "second"}));
}

TEST_F(DicomFixture, DicomdirIsRefusedWithTheReason) {
  const SourceVolume ball = ballVolume({8, 8, 4}, {1.0, 1.0, 1.0}, {0, 0, 0}, {4, 4, 2}, 2.0);
  SeriesSpec spec;
  spec.dicomdir = true;
  try {
    writeSeries(folder("dicomdir"), ball, spec);
    ADD_FAILURE() << "no exception";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("DICOMDIR not supported"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace vh::io::test
