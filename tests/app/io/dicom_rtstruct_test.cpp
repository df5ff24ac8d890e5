// RT Structure Sets (DICOM PS3.3 A.19 RT Structure Set IOD, C.8.8.5 / C.8.8.6): structure sets
// written by DCMTK's own writer (DRTStructureSetIOD) from shapes defined analytically (balls, a
// box, a ring with a hole) on a synthetic CT series, read back through the project's reader and
// compared with the analytic voxelisation: a voxel is in a shape when its centre, placed by the
// CT writer's own geometry (WrittenSeries::voxelLps), is inside the shape. Dice >= 0.98 per ROI.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include <dcmtk/config/osconfig.h>  // DCMTK's configuration first
#include <dcmtk/dcmdata/dcdeftag.h>
#include <dcmtk/dcmdata/dcfilefo.h>
#include <dcmtk/dcmdata/dcuid.h>
#include <dcmtk/dcmrt/drtstrct.h>

#include "dicom_fixtures.h"
#include "io_test_support.h"
#include "loader_internal.h"
#include "vh/io/dicom_rtstruct.h"
#include "vh/io/segmentation.h"

namespace vh::io {
namespace {

namespace fs = std::filesystem;
using test::TempDir;

constexpr double kPi = 3.14159265358979323846;

// ---- writing structure sets with DCMTK ------------------------------------------------------

/// One ROI to write: its name, colour (none: the reader's palette) and contours, each a
/// polygon in patient LPS [mm] with its Contour Geometric Type.
struct RoiSpec {
  std::string name;
  std::optional<std::array<int, 3>> color;
  std::vector<std::pair<std::string, std::vector<Eigen::Vector3d>>> contours;
};

struct RtSpec {
  std::string frame_uid;   ///< Referenced Frame of Reference UID (the CT's).
  std::string series_uid;  ///< Referenced series (the CT's); empty: none written.
  std::vector<RoiSpec> rois;
};

std::string ds(double v) {
  char s[32];
  std::snprintf(s, sizeof(s), "%.4f", v);
  return s;
}

std::string uid() {
  char buffer[100];
  return dcmGenerateUniqueIdentifier(buffer, SITE_INSTANCE_UID_ROOT);
}

/// Writes `spec` as an RT Structure Set with DCMTK's DRTStructureSetIOD.
void writeRtStruct(const fs::path& path, const RtSpec& spec) {
  DRTStructureSetIOD rs;
  ASSERT_TRUE(rs.setPatientName("Fixture^RT").good());
  rs.setPatientID("VH-RT");
  rs.setStudyInstanceUID(uid().c_str());
  rs.setSeriesInstanceUID(uid().c_str());
  rs.setSOPInstanceUID(uid().c_str());
  rs.setSOPClassUID(UID_RTStructureSetStorage);
  rs.setModality("RTSTRUCT");
  rs.setStructureSetLabel("fixture");
  rs.setStructureSetDate("20260101");
  rs.setStructureSetTime("120000");
  DRTReferencedFrameOfReferenceSequence::Item* frame = nullptr;
  ASSERT_TRUE(rs.getReferencedFrameOfReferenceSequence().addItem(frame).good());
  frame->setFrameOfReferenceUID(spec.frame_uid.c_str());
  if (!spec.series_uid.empty()) {
    DRTRTReferencedStudySequence::Item* study = nullptr;
    ASSERT_TRUE(frame->getRTReferencedStudySequence().addItem(study).good());
    study->setReferencedSOPClassUID(UID_RETIRED_DetachedStudyManagementSOPClass);
    study->setReferencedSOPInstanceUID(uid().c_str());
    DRTRTReferencedSeriesSequence::Item* series = nullptr;
    ASSERT_TRUE(study->getRTReferencedSeriesSequence().addItem(series).good());
    series->setSeriesInstanceUID(spec.series_uid.c_str());
    DRTContourImageSequence::Item* image = nullptr;
    ASSERT_TRUE(series->getContourImageSequence().addItem(image).good());
    image->setReferencedSOPClassUID(UID_CTImageStorage);
    image->setReferencedSOPInstanceUID(uid().c_str());
  }
  for (std::size_t r = 0; r < spec.rois.size(); ++r) {
    const RoiSpec& roi = spec.rois[r];
    const std::string number = std::to_string(r + 1);
    DRTStructureSetROISequence::Item* ss = nullptr;
    ASSERT_TRUE(rs.getStructureSetROISequence().addItem(ss).good());
    ss->setROINumber(number.c_str());
    ss->setReferencedFrameOfReferenceUID(spec.frame_uid.c_str());
    ss->setROIName(roi.name.c_str());
    ss->setROIGenerationAlgorithm("MANUAL");
    DRTROIContourSequence::Item* rc = nullptr;
    ASSERT_TRUE(rs.getROIContourSequence().addItem(rc).good());
    rc->setReferencedROINumber(number.c_str());
    if (roi.color) {
      const auto& c = *roi.color;
      const std::string rgb = std::to_string(c[0]) + "\\" + std::to_string(c[1]) + "\\" + std::to_string(c[2]);
      rc->setROIDisplayColor(rgb.c_str());
    }
    for (std::size_t n = 0; n < roi.contours.size(); ++n) {
      DRTContourSequence::Item* contour = nullptr;
      ASSERT_TRUE(rc->getContourSequence().addItem(contour).good());
      std::string data;
      for (const auto& p : roi.contours[n].second) {
        for (const double c : {p.x(), p.y(), p.z()}) {
          if (!data.empty()) data += '\\';
          data += ds(c);
        }
      }
      contour->setContourNumber(std::to_string(n + 1).c_str());
      contour->setContourGeometricType(roi.contours[n].first.c_str());
      contour->setNumberOfContourPoints(std::to_string(roi.contours[n].second.size()).c_str());
      ASSERT_TRUE(contour->setContourData(data.c_str()).good());
    }
    DRTRTROIObservationsSequence::Item* obs = nullptr;
    ASSERT_TRUE(rs.getRTROIObservationsSequence().addItem(obs).good());
    obs->setObservationNumber(number.c_str());
    obs->setReferencedROINumber(number.c_str());
    obs->setRTROIInterpretedType("ORGAN");
  }
  DcmFileFormat file;
  const OFCondition written = rs.write(*file.getDataset());
  ASSERT_TRUE(written.good()) << written.text();
  const OFCondition saved = file.saveFile(path.c_str(), EXS_LittleEndianExplicit);
  ASSERT_TRUE(saved.good()) << saved.text();
}

/// A 64-gon of radius r about c in the plane z = c.z (LPS mm); clockwise when `reverse`.
std::vector<Eigen::Vector3d> circle(const Eigen::Vector3d& c, double r, bool reverse = false) {
  std::vector<Eigen::Vector3d> p;
  for (int n = 0; n < 64; ++n) {
    const double a = (reverse ? -1.0 : 1.0) * 2.0 * kPi * n / 64.0;
    p.emplace_back(c.x() + r * std::cos(a), c.y() + r * std::sin(a), c.z());
  }
  return p;
}

// ---- the analytic shapes -------------------------------------------------------------------

/// A shape: inside(p) for a point in LPS mm, and its contours on the plane z (LPS mm).
struct Shape {
  RoiSpec roi;
  std::function<bool(const Eigen::Vector3d&)> inside;
  std::function<std::vector<std::vector<Eigen::Vector3d>>(double z)> section;
};

Shape ball(const std::string& name, std::optional<std::array<int, 3>> color, const Eigen::Vector3d& c, double r) {
  Shape s;
  s.roi = {name, color, {}};
  s.inside = [c, r](const Eigen::Vector3d& p) { return (p - c).squaredNorm() < r * r; };
  s.section = [c, r](double z) {
    std::vector<std::vector<Eigen::Vector3d>> out;
    const double q = r * r - (z - c.z()) * (z - c.z());
    if (q > 0.0) out.push_back(circle({c.x(), c.y(), z}, std::sqrt(q)));
    return out;
  };
  return s;
}

Shape box(const std::string& name, std::array<int, 3> color, const Eigen::Vector3d& lo, const Eigen::Vector3d& hi) {
  Shape s;
  s.roi = {name, color, {}};
  s.inside = [lo, hi](const Eigen::Vector3d& p) {
    return (p.array() > lo.array()).all() && (p.array() < hi.array()).all();
  };
  s.section = [lo, hi](double z) {
    std::vector<std::vector<Eigen::Vector3d>> out;
    if (z > lo.z() && z < hi.z()) {
      out.push_back({{lo.x(), lo.y(), z}, {hi.x(), lo.y(), z}, {hi.x(), hi.y(), z}, {lo.x(), hi.y(), z}});
    }
    return out;
  };
  return s;
}

/// An annulus cylinder about the z axis through c: r_in < radius < r_out, z0 < z < z1.
Shape ring(const std::string& name, std::array<int, 3> color, const Eigen::Vector3d& c, double r_in, double r_out,
           double z0, double z1) {
  Shape s;
  s.roi = {name, color, {}};
  s.inside = [=](const Eigen::Vector3d& p) {
    const double d = std::hypot(p.x() - c.x(), p.y() - c.y());
    return d > r_in && d < r_out && p.z() > z0 && p.z() < z1;
  };
  s.section = [=](double z) {
    std::vector<std::vector<Eigen::Vector3d>> out;
    if (z > z0 && z < z1) {
      out.push_back(circle({c.x(), c.y(), z}, r_out));
      out.push_back(circle({c.x(), c.y(), z}, r_in, true));  // the hole, drawn the other way round
    }
    return out;
  };
  return s;
}

// ---- the synthetic CT ----------------------------------------------------------------------

struct Ct {
  test::WrittenSeries series;
  std::string frame_uid;  ///< Read from the first CT file with DCMTK.
  Eigen::Vector3i dims{48, 48, 24};
};

std::string frameOfReferenceOf(const fs::path& file) {
  DcmFileFormat f;
  EXPECT_TRUE(f.loadFile(file.c_str()).good()) << file;
  OFString v;
  f.getDataset()->findAndGetOFString(DCM_FrameOfReferenceUID, v);
  return v.c_str();
}

/// 48 x 48 x 24 voxels of 1 x 1 x 2 mm, axial, first voxel at (-23.5, -23.5, -23) LPS mm.
Ct syntheticCt(const fs::path& folder) {
  Ct ct;
  const auto source = test::ballVolume(ct.dims, {1.0, 1.0, 2.0}, {-23.5, -23.5, -23.0}, {0.0, 0.0, 0.0}, 15.0);
  test::SeriesSpec spec;
  spec.series_description = "rtstruct fixture";
  ct.series = test::writeSeries(folder, source, spec);
  ct.frame_uid = frameOfReferenceOf(ct.series.files.front());
  return ct;
}

/// The shapes' contours on every CT slice (z of the slice as written).
RtSpec contoured(const Ct& ct, std::vector<Shape>& shapes) {
  RtSpec spec{ct.frame_uid, ct.series.series_uid, {}};
  for (Shape& s : shapes) {
    for (const Eigen::Vector3d& p : ct.series.slice_position_lps_mm) {
      for (auto& poly : s.section(p.z())) s.roi.contours.emplace_back("CLOSED_PLANAR", std::move(poly));
    }
    spec.rois.push_back(s.roi);
  }
  return spec;
}

/// Dice of ROI `s` of `seg` with the voxels whose centre is inside `shape`.
double dice(const LoadedSegmentation& seg, std::size_t s, const Ct& ct, const Shape& shape,
            std::size_t* truth = nullptr) {
  const SegmentInfo& info = seg.segments[s];
  std::size_t a = 0, b = 0, both = 0;
  for (int k = 0; k < ct.dims.z(); ++k)
    for (int j = 0; j < ct.dims.y(); ++j)
      for (int i = 0; i < ct.dims.x(); ++i) {
        const bool in_seg = seg.label(info.layer, i, j, k) == info.label_value;
        const bool in_shape = shape.inside(ct.series.voxelLps(i, j, k));
        a += in_seg;
        b += in_shape;
        both += in_seg && in_shape;
      }
  if (truth != nullptr) *truth = b;
  return a + b == 0 ? 0.0 : 2.0 * static_cast<double>(both) / static_cast<double>(a + b);
}

std::vector<Shape> fourShapes() {
  return {ball("Ball A", std::array<int, 3>{255, 0, 0}, {-5.2, 0.3, -2.0}, 10.0),
          ball("Ball B", std::nullopt, {6.1, 0.7, 1.0}, 8.0),
          box("Box", {0, 128, 255}, {8.3, -19.4, -22.0}, {19.6, -9.2, -14.0}),
          ring("Ring", {10, 200, 30}, {0.4, 0.2, 0.0}, 5.0, 11.0, 12.0, 22.0)};
}

bool mentions(const std::vector<std::string>& notices, const std::string& part) {
  for (const auto& n : notices)
    if (n.find(part) != std::string::npos) return true;
  return false;
}

// ---- the tests -----------------------------------------------------------------------------

TEST(DicomRtStruct, RoisOpenOnTheirCtAsSegmentsMatchingTheAnalyticShapes) {
  TempDir dir("dicom-rtstruct");
  const Ct ct = syntheticCt(dir / "ct");
  const LoadedVolume scan = loadVolume(dir / "ct");
  ASSERT_EQ(scan.field->geometry().dims, (std::array<int, 3>{48, 48, 24}));
  ASSERT_LT((scan.field->geometry().origin_W_m * 1e3 - ct.series.voxelLps(0, 0, 0)).norm(), 1e-3);
  std::vector<Shape> shapes = fourShapes();
  RtSpec spec = contoured(ct, shapes);
  spec.rois[2].contours.push_back({"POINT", {{12.0, -12.0, -17.0}}});  // skipped, with a notice
  spec.rois.push_back({"Empty", std::array<int, 3>{1, 2, 3}, {}});       // no contours: skipped
  const fs::path file = dir / "rs.dcm";
  writeRtStruct(file, spec);
  ASSERT_TRUE(isDicomRtStructFile(file));
  ASSERT_TRUE(isSegmentationFile(file));
  EXPECT_FALSE(isDicomRtStructFile(ct.series.files.front()));

  for (const auto isolation : {DicomIsolation::kAuto, DicomIsolation::kInProcess}) {
    VolumeLoadOptions options;
    options.dicom_isolation = isolation;
    const LoadedSegmentation seg = loadSegmentation(file, scan, options);
    ASSERT_EQ(seg.segments.size(), 4u);
    for (std::size_t s = 0; s < shapes.size(); ++s) {
      std::size_t truth = 0;
      const double d = dice(seg, s, ct, shapes[s], &truth);
      std::printf("[ DICE     ] synthetic CT, %s: %.4f (%zu voxels, analytic %zu)\n", shapes[s].roi.name.c_str(), d,
                  seg.segments[s].voxel_count, truth);
      EXPECT_GE(d, 0.98) << shapes[s].roi.name;
      EXPECT_GT(truth, 300u) << shapes[s].roi.name;
      EXPECT_EQ(seg.segments[s].name, shapes[s].roi.name);
      EXPECT_EQ(seg.segments[s].id, "ROI_" + std::to_string(s + 1));
    }
    // Colours exact (ROI Display Color / 255); Ball B has none: the palette's second colour.
    EXPECT_EQ(seg.segments[0].color_rgb, (std::array<double, 3>{1.0, 0.0, 0.0}));
    EXPECT_EQ(seg.segments[1].color_rgb, detail::segmentPaletteColour(1));
    EXPECT_EQ(seg.segments[2].color_rgb, (std::array<double, 3>{0.0, 128.0 / 255.0, 1.0}));
    EXPECT_EQ(seg.segments[3].color_rgb, (std::array<double, 3>{10.0 / 255.0, 200.0 / 255.0, 30.0 / 255.0}));
    // The balls overlap: separate layers; the box and the ring share the first ball's.
    EXPECT_NE(seg.segments[0].layer, seg.segments[1].layer);
    EXPECT_EQ(seg.segments[2].layer, seg.segments[0].layer);
    EXPECT_EQ(seg.segments[3].layer, seg.segments[0].layer);
    EXPECT_TRUE(mentions(seg.notices, "\"Empty\") has no contours: skipped")) << ::testing::PrintToString(seg.notices);
    EXPECT_TRUE(mentions(seg.notices, "not CLOSED_PLANAR")) << ::testing::PrintToString(seg.notices);
    EXPECT_EQ(seg.find("ring"), 3);
    EXPECT_EQ(seg.referenced_series_uids, std::vector<std::string>{ct.series.series_uid});
  }
}

// ROIs that all overlap (the same square on the middle slice, 40 times): each needs a layer of
// its own, a label map of the scan's size, and past 32 layers the structure set is refused
// naming the ROI and the limit; 32 of them open (1,000 such ROIs took 6.0 GB and over a minute).
TEST(DicomRtStruct, RoisOverlappingMoreThanThirtyTwoDeepAreRefused) {
  TempDir dir("dicom-rtstruct-overlap");
  const Ct ct = syntheticCt(dir / "ct");
  const LoadedVolume scan = loadVolume(dir / "ct");
  const double z = ct.series.slice_position_lps_mm[12].z();
  const std::vector<Eigen::Vector3d> square = {{-5.0, -5.0, z}, {5.0, -5.0, z}, {5.0, 5.0, z}, {-5.0, 5.0, z}};
  const auto spec = [&](int rois) {
    RtSpec r{ct.frame_uid, ct.series.series_uid, {}};
    for (int n = 0; n < rois; ++n) r.rois.push_back({"square " + std::to_string(n + 1), std::nullopt, {{"CLOSED_PLANAR", square}}});
    return r;
  };
  writeRtStruct(dir / "32.dcm", spec(32));
  const LoadedSegmentation fits = loadSegmentation(dir / "32.dcm", scan);
  EXPECT_EQ(fits.segments.size(), 32u);
  EXPECT_EQ(fits.layers.size(), 32u);
  writeRtStruct(dir / "40.dcm", spec(40));
  try {
    (void)loadSegmentation(dir / "40.dcm", scan);
    FAIL() << "40 layers of overlapping ROIs opened";
  } catch (const LoadError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("ROI \"square 33\" overlaps ROIs in 32 layers already"), std::string::npos) << what;
    EXPECT_NE(what.find("at most 32 layers"), std::string::npos) << what;
  }
}

TEST(DicomRtStruct, TheRingsHoleIsEmptyAndItsWallFull) {
  TempDir dir("dicom-rtstruct-ring");
  const Ct ct = syntheticCt(dir / "ct");
  const LoadedVolume scan = loadVolume(dir / "ct");
  std::vector<Shape> shapes = {ring("Ring", {10, 200, 30}, {0.4, 0.2, 0.0}, 5.0, 11.0, 12.0, 22.0)};
  writeRtStruct(dir / "rs.dcm", contoured(ct, shapes));
  const LoadedSegmentation seg = loadSegmentation(dir / "rs.dcm", scan);
  ASSERT_EQ(seg.segments.size(), 1u);
  std::size_t hole = 0, wall = 0, hole_filled = 0, wall_missed = 0;
  for (int k = 0; k < ct.dims.z(); ++k)
    for (int j = 0; j < ct.dims.y(); ++j)
      for (int i = 0; i < ct.dims.x(); ++i) {
        const Eigen::Vector3d p = ct.series.voxelLps(i, j, k);
        if (p.z() < 12.0 || p.z() > 22.0) continue;
        const double d = std::hypot(p.x() - 0.4, p.y() - 0.2);
        const bool in = seg.label(0, i, j, k) == seg.segments[0].label_value;
        if (d < 4.5) hole += 1, hole_filled += in;
        if (d > 5.5 && d < 10.5) wall += 1, wall_missed += !in;
      }
  EXPECT_GT(hole, 200u);
  EXPECT_EQ(hole_filled, 0u) << "voxels filled in the ring's hole";
  EXPECT_GT(wall, 1000u);
  EXPECT_EQ(wall_missed, 0u) << "voxels of the ring's wall missed";
}

TEST(DicomRtStruct, ABallOnTheSharedCtHead) {
  VH_REQUIRE_SHARED(folder, "ct/ct-head-small");
  const LoadedVolume scan = loadVolume(folder);
  const haptics::VolumeGeometry& g = scan.field->geometry();
  fs::path first;
  DcmFileFormat f;  // the CT's UIDs, read with DCMTK from its first readable file
  for (const auto& e : fs::directory_iterator(folder))
    if (e.is_regular_file() && (first.empty() || e.path() < first) && DcmFileFormat().loadFile(e.path().c_str()).good())
      first = e.path();
  ASSERT_FALSE(first.empty()) << "no DICOM file in " << folder;
  ASSERT_TRUE(f.loadFile(first.c_str()).good());
  OFString frame_uid, series_uid;
  f.getDataset()->findAndGetOFString(DCM_FrameOfReferenceUID, frame_uid);
  f.getDataset()->findAndGetOFString(DCM_SeriesInstanceUID, series_uid);
  // A ball of 25 mm about the grid's middle; its circles on every slice the ball crosses.
  const auto lps = [&](double i, double j, double k) -> Eigen::Vector3d {
    return (g.origin_W_m + g.direction_W * g.spacing_m.cwiseProduct(Eigen::Vector3d(i, j, k))) * 1e3;
  };
  const Eigen::Vector3d c = lps(0.5 * (g.dims[0] - 1) + 0.3, 0.5 * (g.dims[1] - 1) - 0.2, 0.5 * (g.dims[2] - 1) + 0.4);
  const double r = 25.0;
  RoiSpec roi{"Head ball", std::array<int, 3>{200, 100, 50}, {}};
  const Eigen::Vector3d u = g.direction_W.col(0), v = g.direction_W.col(1), n = g.direction_W.col(2);
  for (int k = 0; k < g.dims[2]; ++k) {
    const Eigen::Vector3d o = lps(0, 0, k);
    const double dz = (o - c).dot(n);
    if (r * r - dz * dz <= 0.0) continue;
    const double rk = std::sqrt(r * r - dz * dz);
    const Eigen::Vector3d ck = c + dz * n;
    std::vector<Eigen::Vector3d> poly;
    for (int m = 0; m < 64; ++m) {
      const double a = 2.0 * kPi * m / 64.0;
      poly.push_back(ck + rk * (std::cos(a) * u + std::sin(a) * v));
    }
    roi.contours.emplace_back("CLOSED_PLANAR", std::move(poly));
  }
  TempDir dir("dicom-rtstruct-head");
  // The small CT head has no Frame of Reference UID: the structure set gets a new one (its
  // references are then checked by series only, as the reader's notice says).
  const std::string frame = frame_uid.empty() ? uid() : std::string(frame_uid.c_str());
  writeRtStruct(dir / "rs.dcm", {frame, series_uid.c_str(), {roi}});
  const LoadedSegmentation seg = loadSegmentation(dir / "rs.dcm", scan);
  ASSERT_EQ(seg.segments.size(), 1u);
  std::size_t a = 0, b = 0, both = 0;
  for (int k = 0; k < g.dims[2]; ++k)
    for (int j = 0; j < g.dims[1]; ++j)
      for (int i = 0; i < g.dims[0]; ++i) {
        const bool in_seg = seg.label(0, i, j, k) == seg.segments[0].label_value;
        const bool in_ball = (lps(i, j, k) - c).norm() < r;
        a += in_seg, b += in_ball, both += in_seg && in_ball;
      }
  const double d = 2.0 * static_cast<double>(both) / static_cast<double>(a + b);
  std::printf("[ DICE     ] ct-head-small, ball of 25 mm: %.4f (%zu voxels, analytic %zu)\n", d, a, b);
  EXPECT_GT(b, 500u);
  EXPECT_GE(d, 0.98);
  EXPECT_EQ(seg.segments[0].name, "Head ball");
}

// ---- bad input: a clear error, never a crash ----------------------------------------------

TEST(DicomRtStruct, BadInputIsAClearError) {
  TempDir dir("dicom-rtstruct-bad");
  const Ct ct = syntheticCt(dir / "ct");
  const LoadedVolume scan = loadVolume(dir / "ct");
  std::vector<Shape> shapes = {ball("Ball A", std::array<int, 3>{255, 0, 0}, {-5.2, 0.3, -2.0}, 10.0)};
  const RtSpec good = contoured(ct, shapes);

  RtSpec other_frame = good;
  other_frame.frame_uid = "1.2.826.0.1.3680043.2.1125.99.7";
  writeRtStruct(dir / "frame.dcm", other_frame);
  std::string e = test::loadErrorOf([&] { loadSegmentation(dir / "frame.dcm", scan); });
  EXPECT_CONTAINS(e, "frame.dcm");
  EXPECT_CONTAINS(e, "another frame of reference");
  EXPECT_CONTAINS(e, "1.2.826.0.1.3680043.2.1125.99.7");

  RtSpec other_series = good;
  other_series.series_uid = "1.2.826.0.1.3680043.2.1125.99.8";
  writeRtStruct(dir / "series.dcm", other_series);
  e = test::loadErrorOf([&] { loadSegmentation(dir / "series.dcm", scan); });
  EXPECT_CONTAINS(e, "another series");

  RtSpec between = good;  // a square half a slice (1 mm) above slice 3
  const double z = ct.series.slice_position_lps_mm[3].z() + 1.0;
  between.rois[0].contours.push_back({"CLOSED_PLANAR", {{-3, -3, z}, {3, -3, z}, {3, 3, z}, {-3, 3, z}}});
  writeRtStruct(dir / "between.dcm", between);
  e = test::loadErrorOf([&] { loadSegmentation(dir / "between.dcm", scan); });
  EXPECT_CONTAINS(e, "between.dcm");
  EXPECT_CONTAINS(e, "\"Ball A\") contour");
  EXPECT_CONTAINS(e, "lies between slices of the scan (at slice index 3.50");

  writeRtStruct(dir / "whole.dcm", good);
  const std::string bytes = test::readFile(dir / "whole.dcm");
  test::writeFile(dir / "cut.dcm", bytes.substr(0, bytes.size() / 2));
  e = test::loadErrorOf([&] { loadSegmentation(dir / "cut.dcm", scan); });
  EXPECT_CONTAINS(e, "cut.dcm");
  EXPECT_CONTAINS(e, "not a readable DICOM file (damaged, cut short or not DICOM)");

  e = test::loadErrorOf([&] { loadDicomRtStruct(ct.series.files.front(), &scan); });
  EXPECT_CONTAINS(e, "not an RT Structure Set: its SOP Class is CTImageStorage");

  e = test::loadErrorOf([&] { loadSegmentation(dir / "whole.dcm"); });
  EXPECT_CONTAINS(e, "open that scan first");

  RtSpec points_only = good;  // only a POINT: no ROI to show
  points_only.rois[0].contours = {{"POINT", {{0, 0, ct.series.slice_position_lps_mm[3].z()}}}};
  writeRtStruct(dir / "points.dcm", points_only);
  e = test::loadErrorOf([&] { loadSegmentation(dir / "points.dcm", scan); });
  EXPECT_CONTAINS(e, "no ROI with closed contours");
}

TEST(DicomRtStruct, OpenAndSelfCrossingContoursFillByEvenOddWithANotice) {
  TempDir dir("dicom-rtstruct-odd");
  const Ct ct = syntheticCt(dir / "ct");
  const LoadedVolume scan = loadVolume(dir / "ct");
  const double z = ct.series.slice_position_lps_mm[5].z();
  // A bow tie (crosses itself at the origin) and a two-point "polygon".
  RoiSpec odd{"Odd", std::array<int, 3>{9, 9, 9},
              {{"CLOSED_PLANAR", {{-10.2, -6.1, z}, {10.3, 6.2, z}, {10.3, -6.1, z}, {-10.2, 6.2, z}}},
               {"CLOSED_PLANAR", {{0, 0, z}, {5, 5, z}}}}};
  writeRtStruct(dir / "odd.dcm", {ct.frame_uid, ct.series.series_uid, {odd}});
  const LoadedSegmentation seg = loadSegmentation(dir / "odd.dcm", scan);
  ASSERT_EQ(seg.segments.size(), 1u);
  EXPECT_GT(seg.segments[0].voxel_count, 50u);
  EXPECT_TRUE(mentions(seg.notices, "cross themselves")) << ::testing::PrintToString(seg.notices);
  EXPECT_TRUE(mentions(seg.notices, "fewer than 3 points")) << ::testing::PrintToString(seg.notices);
}

}  // namespace
}  // namespace vh::io
