// Loading the real datasets (DICOM, NRRD) and imageFromField.
#include <chrono>
#include <cmath>
#include <iostream>
#include <memory>

#include <gtest/gtest.h>
#include <vtkDataArray.h>
#include <vtkImageData.h>
#include <vtkNew.h>
#include <vtkPointData.h>
#include <vtkSmartPointer.h>

#include "dicom_fixtures.h"
#include "io_test_support.h"
#include "vh/io/volume_loader.h"

namespace {

namespace fs = std::filesystem;
using vh::haptics::ScalarVolume;
using vh::haptics::VolumeGeometry;
using vh::haptics::VoxelType;
using vh::io::LoadedVolume;
using vh::io::loadVolume;
using vh::io::test::secondsSince;

/// The image and the field describe the same grid: dims, spacing and origin in metres.
void expectImageMatchesField(const LoadedVolume& v) {
  ASSERT_NE(v.field, nullptr);
  ASSERT_NE(v.image, nullptr);
  const auto& g = v.field->geometry();
  int d[3];
  v.image->GetDimensions(d);
  EXPECT_EQ(d[0], g.dims[0]);
  EXPECT_EQ(d[1], g.dims[1]);
  EXPECT_EQ(d[2], g.dims[2]);
  double s[3];
  double o[3];
  v.image->GetSpacing(s);
  v.image->GetOrigin(o);
  for (int a = 0; a < 3; ++a) {
    EXPECT_DOUBLE_EQ(s[a], g.spacing_m[a]);
    EXPECT_DOUBLE_EQ(o[a], g.origin_W_m[a]);
  }
  vtkDataArray* scalars = v.image->GetPointData()->GetScalars();
  ASSERT_NE(scalars, nullptr);
  EXPECT_EQ(static_cast<std::size_t>(scalars->GetNumberOfTuples()), g.voxelCount());
  double r[2];
  scalars->GetRange(r);
  // The image holds data units: the same range as the field.
  EXPECT_NEAR(r[0], v.field->minValue(), 1e-3);
  EXPECT_NEAR(r[1], v.field->maxValue(), 1e-3);
  // Direction is orthonormal.
  EXPECT_TRUE((g.direction_W.transpose() * g.direction_W).isIdentity(1e-9));
  // A field in data units is the picture's voxels too: one copy, not two.
  if (v.field->valueScale() == 1.0 && v.field->valueOffset() == 0.0) {
    EXPECT_EQ(scalars->GetVoidPointer(0), static_cast<const void*>(v.field->bytes().data()))
        << "the rendering image holds a copy of the field's voxels";
  }
}

double scalarSum(vtkImageData* image) {
  vtkDataArray* a = image->GetPointData()->GetScalars();
  double sum = 0.0;
  for (vtkIdType i = 0; i < a->GetNumberOfTuples(); ++i) sum += a->GetTuple1(i);
  return sum;
}

TEST(DicomLoad, CtHeadSmall) {
  VH_REQUIRE_SHARED(dir, "ct/ct-head-small");
  const auto t0 = std::chrono::steady_clock::now();
  const LoadedVolume v = loadVolume(dir);
  std::cout << "[timing] ct-head-small (DICOM, 93 files): " << secondsSince(t0) << " s\n";
  const auto& g = v.field->geometry();
  EXPECT_EQ(g.dims, (std::array<int, 3>{64, 64, 93}));
  EXPECT_NEAR(g.spacing_m.x(), 3.2e-3, 1e-9);
  EXPECT_NEAR(g.spacing_m.y(), 3.2e-3, 1e-9);
  EXPECT_NEAR(g.spacing_m.z(), 1.5e-3, 1e-9);
  EXPECT_EQ(v.field->voxelType(), VoxelType::kInt16);
  // Plausible CT values (this head has no rescale; its values are 0..~3900).
  EXPECT_GE(v.field->minValue(), -1100.0);
  EXPECT_LE(v.field->maxValue(), 4096.0);
  EXPECT_GT(v.field->maxValue() - v.field->minValue(), 1000.0);
  EXPECT_EQ(v.info.format, "DICOM");
  EXPECT_EQ(v.info.modality, "CT");
  EXPECT_EQ(v.info.value_unit, "HU");
  EXPECT_EQ(v.info.source, dir);
  expectImageMatchesField(v);
}

TEST(DicomLoad, PhilipsHeadPhantom) {
  VH_REQUIRE_SHARED(dir, "ct/philips-head-phantom-bone");
  const auto t0 = std::chrono::steady_clock::now();
  testing::internal::CaptureStderr();
  const LoadedVolume v = loadVolume(dir);
  EXPECT_EQ(testing::internal::GetCapturedStderr(), "");
  std::cout << "[timing] philips-head-phantom-bone (DICOM, 140 files, 512x512): "
            << secondsSince(t0) << " s\n";
  const auto& g = v.field->geometry();
  EXPECT_EQ(g.dims, (std::array<int, 3>{512, 512, 140}));
  EXPECT_NEAR(g.spacing_m.x(), 0.451e-3, 0.001e-3);
  EXPECT_NEAR(g.spacing_m.y(), 0.451e-3, 0.001e-3);
  EXPECT_NEAR(g.spacing_m.z(), 1.0e-3, 1e-9);
  EXPECT_GE(v.field->minValue(), -1024.0);
  EXPECT_LE(v.field->maxValue(), 3071.0);
  EXPECT_LT(v.field->minValue(), -900.0);  // air
  EXPECT_GT(v.field->maxValue(), 1500.0);  // bone
  // Axial slices: D = I in patient LPS; the origin is the first slice's ImagePositionPatient.
  EXPECT_TRUE(g.direction_W.cwiseAbs().isIdentity(1e-6));
  EXPECT_NEAR(g.origin_W_m.x(), -0.1155, 1e-6);
  EXPECT_NEAR(g.origin_W_m.y(), -0.00185, 1e-6);
  EXPECT_EQ(v.info.modality, "CT");
  EXPECT_EQ(v.info.description, "BONE BRAIN 1MM");
  // Stored as unsigned 12-bit in uint16 with RescaleIntercept -1024: the integer rescale is
  // applied once, so the field holds HU as int16 (scale 1, offset 0) and the rendering image
  // shares its buffer (expectImageMatchesField()).
  EXPECT_EQ(v.field->voxelType(), VoxelType::kInt16);
  EXPECT_EQ(v.field->valueScale(), 1.0);
  EXPECT_EQ(v.field->valueOffset(), 0.0);
  EXPECT_EQ(v.image->GetPointData()->GetScalars()->GetDataType(), VTK_SHORT);
  // The HU are the files' stored values rescaled: vtkDICOMReader's own read of the folder
  // (stored values and the series' rescale) gives the same sum, whatever the voxel order.
  const vh::io::test::SourceVolume stored = vh::io::test::readSourceSeries(dir);
  EXPECT_EQ(stored.rescale_slope, 1.0);
  EXPECT_EQ(stored.rescale_intercept, -1024.0);
  vtkDataArray* s = stored.image->GetPointData()->GetScalars();
  ASSERT_EQ(static_cast<std::size_t>(s->GetNumberOfTuples()), g.voxelCount());
  double expected_sum = 0.0, field_sum = 0.0;
  for (vtkIdType i = 0; i < s->GetNumberOfTuples(); ++i)
    expected_sum += stored.rescale_slope * s->GetTuple1(i) + stored.rescale_intercept;
  const auto* hu = reinterpret_cast<const std::int16_t*>(v.field->bytes().data());
  for (std::size_t i = 0; i < g.voxelCount(); ++i) field_sum += hu[i];
  EXPECT_EQ(field_sum, expected_sum);
  expectImageMatchesField(v);
}

TEST(DicomLoad, OneFileOfASeriesLoadsTheSeries) {
  VH_REQUIRE_SHARED(file, "ct/ct-head-small/CTHead40.dcm");
  const LoadedVolume v = loadVolume(file);
  EXPECT_EQ(v.field->geometry().dims, (std::array<int, 3>{64, 64, 93}));
}

TEST(NrrdLoad, HeadsqQuarterDetachedSliceFiles) {
  VH_REQUIRE_SHARED(header, "nrrd/headsq-quarter/quarter.nhdr");
  const auto t0 = std::chrono::steady_clock::now();
  const LoadedVolume v = loadVolume(header);
  std::cout << "[timing] headsq-quarter (NRRD, 93 slice files): " << secondsSince(t0) << " s\n";
  const auto& g = v.field->geometry();
  EXPECT_EQ(g.dims, (std::array<int, 3>{64, 64, 93}));
  EXPECT_NEAR(g.spacing_m.x(), 3.2e-3, 1e-12);
  EXPECT_NEAR(g.spacing_m.z(), 1.5e-3, 1e-12);
  EXPECT_EQ(v.field->voxelType(), VoxelType::kInt16);
  EXPECT_EQ(v.info.format, "NRRD");
  EXPECT_TRUE(g.direction_W.isIdentity());
  EXPECT_TRUE(g.origin_W_m.isZero());
  expectImageMatchesField(v);
}

TEST(NrrdLoad, HeadsqQuarterHasTheSameVoxelsAsTheDicomHead) {
  VH_REQUIRE_SHARED(header, "nrrd/headsq-quarter/quarter.nhdr");
  VH_REQUIRE_SHARED(dir, "ct/ct-head-small");
  const LoadedVolume nrrd = loadVolume(header);
  const LoadedVolume dicom = loadVolume(dir);
  EXPECT_EQ(nrrd.field->minValue(), dicom.field->minValue());
  EXPECT_EQ(nrrd.field->maxValue(), dicom.field->maxValue());
  EXPECT_DOUBLE_EQ(scalarSum(nrrd.image.get()), scalarSum(dicom.image.get()));
  // Voxel for voxel: rows in the files' own order on both sides (vtkNrrdReader's row flip for
  // "3D-left-handed" undone); the slice files run in opposite order (quarter.93 holds the same
  // pixels as CTHead1.dcm, which lies at z = 0).
  int mismatches = 0;
  for (int k = 0; k < 93; ++k)
    for (int j = 0; j < 64; ++j)
      for (int i = 0; i < 64; ++i)
        if (nrrd.field->voxel(i, j, k) != dicom.field->voxel(i, j, 92 - k)) ++mismatches;
  EXPECT_EQ(mismatches, 0);
}

TEST(NrrdLoad, MrBrainGzipWithLpsSpaceDirections) {
  VH_REQUIRE_SHARED(file, "nrrd/mr-brain/brain1_image.nrrd");
  const auto t0 = std::chrono::steady_clock::now();
  const LoadedVolume v = loadVolume(file);
  std::cout << "[timing] mr-brain brain1 (NRRD gzip): " << secondsSince(t0) << " s\n";
  const auto& g = v.field->geometry();
  EXPECT_EQ(g.dims, (std::array<int, 3>{256, 256, 25}));
  EXPECT_NEAR(g.spacing_m.x(), 0.78125e-3, 1e-12);
  EXPECT_NEAR(g.spacing_m.y(), 0.78125e-3, 1e-12);
  EXPECT_NEAR(g.spacing_m.z(), 6.5e-3, 1e-12);
  // space directions (0.78,0,0) (0,-0.78,0) (0,0,6.5) in LPS: the j axis points anterior.
  EXPECT_FALSE(g.direction_W.isIdentity());
  EXPECT_NEAR(g.direction_W(1, 1), -1.0, 1e-12);
  EXPECT_NEAR(g.direction_W(0, 0), 1.0, 1e-12);
  EXPECT_NEAR(g.direction_W(2, 2), 1.0, 1e-12);
  EXPECT_NEAR(g.origin_W_m.x(), -0.099609375, 1e-9);
  EXPECT_NEAR(g.origin_W_m.y(), 0.099609375, 1e-9);
  EXPECT_NEAR(g.origin_W_m.z(), -0.078, 1e-9);
  // The last voxel lies at origin + D * S * (n - 1): y decreases along j.
  const Eigen::Vector3d last =
      g.origin_W_m + g.direction_W * g.spacing_m.cwiseProduct(Eigen::Vector3d(255, 255, 24));
  EXPECT_NEAR(last.y(), 0.099609375 - 255 * 0.78125e-3, 1e-9);
  EXPECT_GT(v.field->maxValue(), 1000.0);
  expectImageMatchesField(v);

  VH_REQUIRE_SHARED(file2, "nrrd/mr-brain/brain2_image.nrrd");
  const LoadedVolume v2 = loadVolume(file2);
  EXPECT_EQ(v2.field->geometry().dims, (std::array<int, 3>{256, 256, 23}));
}

TEST(NrrdLoad, EngineGzipDetached) {
  VH_REQUIRE_SHARED(header, "classic/engine/engine.nhdr");
  const auto t0 = std::chrono::steady_clock::now();
  const LoadedVolume v = loadVolume(header);
  std::cout << "[timing] engine (NRRD detached gzip, 8 MB): " << secondsSince(t0) << " s\n";
  const auto& g = v.field->geometry();
  EXPECT_EQ(g.dims, (std::array<int, 3>{256, 256, 128}));
  EXPECT_EQ(v.field->voxelType(), VoxelType::kUInt8);
  EXPECT_NEAR(g.spacing_m.x(), 1e-3, 1e-12);  // unitless in the file: taken as mm
  EXPECT_EQ(v.field->minValue(), 0.0);
  EXPECT_EQ(v.field->maxValue(), 255.0);
  expectImageMatchesField(v);
}

TEST(NrrdLoad, CtBunnyBigEndianSliceFiles) {
  std::string why_not;
  const fs::path header = vh::io::test::unpackedBunny(&why_not);
  if (header.empty()) GTEST_SKIP() << why_not;
  const auto t0 = std::chrono::steady_clock::now();
  const LoadedVolume v = loadVolume(header);
  std::cout << "[timing] ct-bunny (NRRD, 361 big-endian slice files, 512x512x361): "
            << secondsSince(t0) << " s\n";
  const auto& g = v.field->geometry();
  EXPECT_EQ(g.dims, (std::array<int, 3>{512, 512, 361}));
  EXPECT_NEAR(g.spacing_m.x(), 0.337891e-3, 1e-12);
  EXPECT_NEAR(g.spacing_m.z(), 0.5e-3, 1e-12);
  EXPECT_EQ(v.field->voxelType(), VoxelType::kInt16);
  // Stored values (HU + 1024, -2000 outside the scan circle). With the wrong byte order the
  // range would span most of int16.
  EXPECT_EQ(v.field->minValue(), -2000.0);
  EXPECT_LE(v.field->maxValue(), 4095.0);
  EXPECT_GT(v.field->maxValue(), 1500.0);
  // The corner lies outside the scan circle; the centre of the middle slice is inside it.
  EXPECT_EQ(v.field->voxel(0, 0, 180), -2000.0);
  EXPECT_GT(v.field->voxel(256, 256, 180), -1500.0);
  expectImageMatchesField(v);
}

TEST(ImageFromField, KeepsTypeWithoutRescale) {
  VolumeGeometry g;
  g.dims = {3, 2, 2};
  g.spacing_m = {1e-3, 2e-3, 3e-3};
  g.origin_W_m = {0.1, 0.2, 0.3};
  std::vector<std::int16_t> voxels(12);
  for (std::size_t i = 0; i < voxels.size(); ++i) voxels[i] = static_cast<std::int16_t>(i * 10 - 50);
  const auto field = ScalarVolume::FromVoxels(g, voxels);
  const auto image = vh::io::imageFromField(field);
  int d[3];
  image->GetDimensions(d);
  EXPECT_EQ(d[0], 3);
  EXPECT_EQ(d[2], 2);
  double s[3];
  image->GetSpacing(s);
  EXPECT_DOUBLE_EQ(s[1], 2e-3);
  double o[3];
  image->GetOrigin(o);
  EXPECT_DOUBLE_EQ(o[2], 0.3);
  vtkDataArray* a = image->GetPointData()->GetScalars();
  ASSERT_NE(a, nullptr);
  EXPECT_EQ(a->GetDataType(), VTK_SHORT);
  for (vtkIdType i = 0; i < 12; ++i) EXPECT_EQ(a->GetTuple1(i), voxels[static_cast<std::size_t>(i)]);
}

TEST(ImageFromField, RescalesToDataUnits) {
  VolumeGeometry g;
  g.dims = {2, 2, 2};
  std::vector<std::uint16_t> stored{0, 1000, 1024, 2048, 3000, 4095, 10, 20};
  // Integer rescale that fits int16: short HU.
  const auto ct = ScalarVolume::FromVoxels(g, stored, 1.0, -1024.0);
  const auto hu = vh::io::imageFromField(ct);
  vtkDataArray* a = hu->GetPointData()->GetScalars();
  EXPECT_EQ(a->GetDataType(), VTK_SHORT);
  for (vtkIdType i = 0; i < 8; ++i) {
    EXPECT_EQ(a->GetTuple1(i), stored[static_cast<std::size_t>(i)] - 1024.0);
  }
  // Fractional scale: float.
  const auto mr = ScalarVolume::FromVoxels(g, stored, 0.5, 0.25);
  const auto mr_image = vh::io::imageFromField(mr);
  vtkDataArray* b = mr_image->GetPointData()->GetScalars();
  EXPECT_EQ(b->GetDataType(), VTK_FLOAT);
  for (vtkIdType i = 0; i < 8; ++i) {
    EXPECT_FLOAT_EQ(static_cast<float>(b->GetTuple1(i)),
                    static_cast<float>(0.5 * stored[static_cast<std::size_t>(i)] + 0.25));
  }
}

TEST(ImageFromField, ASharedFieldInDataUnitsIsWrappedNotCopied) {
  VolumeGeometry g;
  g.dims = {4, 3, 2};
  g.spacing_m = {1e-3, 2e-3, 3e-3};
  std::vector<std::int16_t> voxels(24);
  for (std::size_t i = 0; i < voxels.size(); ++i) voxels[i] = static_cast<std::int16_t>(100 * i - 1000);
  auto field = std::make_shared<const ScalarVolume>(ScalarVolume::FromVoxels(g, voxels));
  const std::weak_ptr<const ScalarVolume> watch = field;
  vh::io::ImagePtr image = vh::io::imageFromField(field);
  vtkDataArray* a = image->GetPointData()->GetScalars();
  ASSERT_NE(a, nullptr);
  EXPECT_EQ(a->GetDataType(), VTK_SHORT);
  EXPECT_EQ(a->GetVoidPointer(0), static_cast<const void*>(field->bytes().data()));
  EXPECT_EQ(image->GetScalarPointer(), static_cast<const void*>(field->bytes().data()));
  for (vtkIdType i = 0; i < 24; ++i) EXPECT_EQ(a->GetTuple1(i), voxels[static_cast<std::size_t>(i)]);
  // A carved picture is a DeepCopy: its own buffer, and writing it leaves the field alone.
  vtkNew<vtkImageData> carved;
  carved->DeepCopy(image.get());
  EXPECT_NE(carved->GetScalarPointer(), image->GetScalarPointer());
  carved->GetPointData()->GetScalars()->SetComponent(5, 0, -1024.0);
  EXPECT_EQ(field->voxel(1, 1, 0), voxels[5]);
  // The field lives while a VTK object holds the image, after every other holder is gone.
  vtkSmartPointer<vtkImageData> held = image.get();
  field.reset();
  image.reset();
  ASSERT_FALSE(watch.expired());
  EXPECT_EQ(held->GetPointData()->GetScalars()->GetTuple1(23), voxels[23]);
  held = nullptr;
  EXPECT_TRUE(watch.expired()) << "the image's array still holds the field after it was destroyed";
}

TEST(ImageFromField, ASharedFieldWithARescaleGetsARescaledCopy) {
  VolumeGeometry g;
  g.dims = {2, 2, 2};
  std::vector<std::uint16_t> stored{0, 1000, 1024, 2048, 3000, 4095, 10, 20};
  const auto ct = std::make_shared<const ScalarVolume>(ScalarVolume::FromVoxels(g, stored, 1.0, -1024.0));
  const auto image = vh::io::imageFromField(ct);
  vtkDataArray* a = image->GetPointData()->GetScalars();
  EXPECT_EQ(a->GetDataType(), VTK_SHORT);
  EXPECT_NE(a->GetVoidPointer(0), static_cast<const void*>(ct->bytes().data()));
  for (vtkIdType i = 0; i < 8; ++i) EXPECT_EQ(a->GetTuple1(i), stored[static_cast<std::size_t>(i)] - 1024.0);
}

TEST(ImageFromField, EmptyFieldGivesEmptyImage) {
  const auto image = vh::io::imageFromField(ScalarVolume());
  ASSERT_NE(image, nullptr);
  EXPECT_EQ(image->GetPointData()->GetScalars(), nullptr);
}

}  // namespace
