// DICOM SEG (DICOM PS3.3 A.51 Segmentation IOD, C.8.20): segmentations written by DCMTK's own
// writer (DcmSegmentation::createBinarySegmentation / createFractionalSegmentation, addSegment,
// addFrame with FGPlanePosPatient and FGDerivationImage) from a known label map on a CT series,
// read back with the project's reader and compared voxel for voxel.
//
// The oracle is independent of the reader: the label map is given on the CT files' own pixels
// (column, row, file), each pixel's patient position comes from the CT files' headers read here
// with DCMTK (Image Position / Orientation (Patient), Pixel Spacing), and that position is taken
// to the loaded scan's voxel through the scan's VolumeGeometry. The colours are converted to
// CIELab here with the textbook sRGB -> XYZ (D65) -> L*a*b* formulas and the DICOM scaling of
// PS3.3 C.10.7.1.1, not with DCMTK's.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include <dcmtk/config/osconfig.h>
#include <dcmtk/dcmdata/dcdeftag.h>
#include <dcmtk/dcmdata/dcfilefo.h>
#include <dcmtk/dcmfg/fgderimg.h>
#include <dcmtk/dcmfg/fgfracon.h>
#include <dcmtk/dcmfg/fgpixmsr.h>
#include <dcmtk/dcmfg/fgplanor.h>
#include <dcmtk/dcmfg/fgplanpo.h>
#include <dcmtk/dcmiod/iodreferences.h>
#include <dcmtk/dcmseg/segdoc.h>
#include <dcmtk/dcmseg/segment.h>
#include <dcmtk/oflog/oflog.h>

#include "dicom_fixtures.h"
#include "io_test_support.h"
#include "vh/io/dicom_seg.h"
#include "vh/io/segmentation.h"

namespace vh::io {
namespace {

namespace fs = std::filesystem;
using test::TempDir;

// ---- the CT series, read with DCMTK ---------------------------------------------------------

/// One CT file: what a SEG frame on it refers to and copies.
struct CtSlice {
  fs::path file;
  std::string sop_class, sop_instance;
  Eigen::Vector3d ipp_mm = Eigen::Vector3d::Zero();  ///< Image Position (Patient), LPS [mm].
};

/// A CT series as its headers say (DCMTK), slices sorted along the normal.
struct CtSeries {
  std::vector<CtSlice> slices;
  std::string patient_id, study_uid, series_uid, for_uid;
  Eigen::Vector3d row_dir = Eigen::Vector3d::UnitX(), col_dir = Eigen::Vector3d::UnitY();
  double row_spacing_mm = 1.0, column_spacing_mm = 1.0;
  int rows = 0, columns = 0;

  Eigen::Vector3d normal() const { return row_dir.cross(col_dir).normalized(); }
  /// LPS [mm] of pixel (column c, row r) of slice k (PS3.3 C.7.6.2.1.1).
  Eigen::Vector3d pixelLps(int c, int r, int k) const {
    return slices[static_cast<std::size_t>(k)].ipp_mm + c * column_spacing_mm * row_dir + r * row_spacing_mm * col_dir;
  }
  double sliceSpacing() const { return (slices[1].ipp_mm - slices[0].ipp_mm).dot(normal()); }
};

std::string str(DcmItem& item, const DcmTagKey& tag) {
  OFString v;
  item.findAndGetOFStringArray(tag, v);
  return v.c_str();
}

double f64(DcmItem& item, const DcmTagKey& tag, unsigned long pos) {
  Float64 v = 0.0;
  EXPECT_TRUE(item.findAndGetFloat64(tag, v, pos).good()) << DcmTag(tag).getTagName();
  return v;
}

/// Every DICOM image file of `folder` (one series) through DCMTK.
CtSeries readCtSeries(const fs::path& folder) {
  CtSeries ct;
  for (const auto& entry : fs::directory_iterator(folder)) {
    DcmFileFormat file;
    if (!entry.is_regular_file() || file.loadFile(entry.path().c_str()).bad()) continue;
    DcmDataset& ds = *file.getDataset();
    if (!ds.tagExists(DCM_PixelData)) continue;
    CtSlice s;
    s.file = entry.path();
    s.sop_class = str(ds, DCM_SOPClassUID);
    s.sop_instance = str(ds, DCM_SOPInstanceUID);
    s.ipp_mm = {f64(ds, DCM_ImagePositionPatient, 0), f64(ds, DCM_ImagePositionPatient, 1),
                f64(ds, DCM_ImagePositionPatient, 2)};
    ct.slices.push_back(s);
    ct.patient_id = str(ds, DCM_PatientID);
    ct.study_uid = str(ds, DCM_StudyInstanceUID);
    ct.series_uid = str(ds, DCM_SeriesInstanceUID);
    ct.for_uid = str(ds, DCM_FrameOfReferenceUID);
    ct.row_dir = {f64(ds, DCM_ImageOrientationPatient, 0), f64(ds, DCM_ImageOrientationPatient, 1),
                  f64(ds, DCM_ImageOrientationPatient, 2)};
    ct.col_dir = {f64(ds, DCM_ImageOrientationPatient, 3), f64(ds, DCM_ImageOrientationPatient, 4),
                  f64(ds, DCM_ImageOrientationPatient, 5)};
    ct.row_spacing_mm = f64(ds, DCM_PixelSpacing, 0);
    ct.column_spacing_mm = f64(ds, DCM_PixelSpacing, 1);
    Uint16 rows = 0, columns = 0;
    ds.findAndGetUint16(DCM_Rows, rows);
    ds.findAndGetUint16(DCM_Columns, columns);
    ct.rows = rows;
    ct.columns = columns;
  }
  const Eigen::Vector3d n = ct.normal();
  std::sort(ct.slices.begin(), ct.slices.end(),
            [&](const CtSlice& a, const CtSlice& b) { return a.ipp_mm.dot(n) < b.ipp_mm.dot(n); });
  return ct;
}

// ---- the label map and its colours --------------------------------------------------------

/// The truth: per segment, one byte per CT pixel (column fastest, then row, then slice).
struct LabelMap {
  int columns = 0, rows = 0, slices = 0;
  std::vector<std::string> names, types;
  std::vector<std::array<double, 3>> rgb;
  std::vector<std::vector<std::uint8_t>> inside;

  std::size_t at(int c, int r, int k) const {
    return static_cast<std::size_t>(c) +
           static_cast<std::size_t>(columns) * (static_cast<std::size_t>(r) + static_cast<std::size_t>(rows) * k);
  }
  std::size_t count(std::size_t s) const {
    return static_cast<std::size_t>(std::count(inside[s].begin(), inside[s].end(), std::uint8_t{1}));
  }
};

/// Two overlapping balls and a box overlapping the second, a disc on three slices only, and a
/// slab with a hole through it, scaled to the CT's size (c, r, k in 0..1 of its extent).
LabelMap shapes(int columns, int rows, int slices) {
  LabelMap m;
  m.columns = columns, m.rows = rows, m.slices = slices;
  m.names = {"ball A", "ball B", "box", "sparse disc", "slab with a hole"};
  m.types = {"Bone", "Brain", "Organ", "Nerve", "Blood vessel"};
  m.rgb = {
      {{0.85, 0.30, 0.25}}, {{0.20, 0.55, 0.85}}, {{0.95, 0.80, 0.20}}, {{0.40, 0.75, 0.35}}, {{0.60, 0.40, 0.70}}};
  m.inside.assign(5, std::vector<std::uint8_t>(static_cast<std::size_t>(columns) * rows * slices, 0));
  const auto ball = [](double x, double y, double z, double cx, double cy, double cz, double rad) {
    return (x - cx) * (x - cx) + (y - cy) * (y - cy) + (z - cz) * (z - cz) <= rad * rad;
  };
  const std::array<int, 3> sparse_slices{slices / 5, slices / 2, (4 * slices) / 5};
  for (int k = 0; k < slices; ++k) {
    for (int r = 0; r < rows; ++r) {
      for (int c = 0; c < columns; ++c) {
        const double x = (c + 0.5) / columns, y = (r + 0.5) / rows, z = (k + 0.5) / slices;
        const std::size_t n = m.at(c, r, k);
        m.inside[0][n] = ball(x, y, z, 0.35, 0.45, 0.45, 0.18);
        m.inside[1][n] = ball(x, y, z, 0.50, 0.50, 0.50, 0.18);
        m.inside[2][n] = x >= 0.58 && x < 0.90 && y >= 0.15 && y < 0.85 && z >= 0.2 && z < 0.7;
        const bool on_sparse = std::find(sparse_slices.begin(), sparse_slices.end(), k) != sparse_slices.end();
        m.inside[3][n] = on_sparse && ball(x, y, 0.0, 0.7, 0.3, 0.0, 0.15);
        const bool slab = x >= 0.08 && x < 0.45 && y >= 0.62 && y < 0.95 && z >= 0.55 && z < 0.9;
        const bool hole = x >= 0.18 && x < 0.35 && y >= 0.72 && y < 0.85;
        m.inside[4][n] = slab && !hole;
      }
    }
  }
  return m;
}

/// sRGB (0..1) to DICOM's CIELab (PS3.3 C.10.7.1.1: L* 0..100 and a*, b* -128..127 scaled to
/// 0..65535), through linear RGB (IEC 61966-2-1), XYZ and L*a*b* with the D65 white point.
std::array<Uint16, 3> dicomLab(const std::array<double, 3>& rgb) {
  Eigen::Vector3d lin;
  for (int i = 0; i < 3; ++i) {
    const double c = rgb[static_cast<std::size_t>(i)];
    lin[i] = c <= 0.04045 ? c / 12.92 : std::pow((c + 0.055) / 1.055, 2.4);
  }
  Eigen::Matrix3d m;
  m << 0.4124564, 0.3575761, 0.1804375, 0.2126729, 0.7151522, 0.0721750, 0.0193339, 0.1191920, 0.9503041;
  const Eigen::Vector3d xyz = (m * lin).cwiseQuotient(Eigen::Vector3d(0.95047, 1.0, 1.08883));
  const auto f = [](double t) {
    return t > std::pow(6.0 / 29.0, 3) ? std::cbrt(t) : t / (3 * std::pow(6.0 / 29.0, 2)) + 4.0 / 29.0;
  };
  const double L = 116.0 * f(xyz.y()) - 16.0, a = 500.0 * (f(xyz.x()) - f(xyz.y())),
               b = 200.0 * (f(xyz.y()) - f(xyz.z()));
  return {static_cast<Uint16>(std::lround(L * 65535.0 / 100.0)),
          static_cast<Uint16>(std::lround((a + 128.0) * 65535.0 / 255.0)),
          static_cast<Uint16>(std::lround((b + 128.0) * 65535.0 / 255.0))};
}

// ---- the SEG, written by DCMTK -------------------------------------------------------------

/// How to write the SEG (and which fault to put in).
struct SegSpec {
  bool fractional = false;
  unsigned shuffle_seed = 1;          ///< 0: frames in order (segment, slice); else shuffled.
  std::string referenced_series;      ///< Empty: the CT's series.
  std::string frame_of_reference;     ///< Empty: the CT's.
  double shift_first_frame_mm = 0.0;  ///< Moves the first frame written along the normal.
  double pixel_spacing_scale = 1.0;   ///< Scales the written Pixel Spacing.
};

/// Frame pixels of segment s on slice k: 0/1 (BINARY) or 0..255 (FRACTIONAL: inside 128..255,
/// outside 0 or 127, so that the reader's threshold at half the maximum is what separates them).
std::vector<Uint8> framePixels(const LabelMap& m, std::size_t s, int k, bool fractional) {
  std::vector<Uint8> px(static_cast<std::size_t>(m.columns) * m.rows);
  for (int r = 0; r < m.rows; ++r) {
    for (int c = 0; c < m.columns; ++c) {
      const bool in = m.inside[s][m.at(c, r, k)] != 0;
      const std::size_t n = static_cast<std::size_t>(c) + static_cast<std::size_t>(m.columns) * r;
      if (!fractional)
        px[n] = in ? 1 : 0;
      else
        px[n] = static_cast<Uint8>(in ? 128 + (c * 7 + r * 13 + k * 5) % 128 : ((c + r + k) % 3 == 0 ? 127 : 0));
    }
  }
  return px;
}

std::string ds(double v) {
  char s[32];
  std::snprintf(s, sizeof(s), "%.10g", v);
  return s;
}

/// The SEG's segments (labels, codes, CIELab colours), shared functional groups and references.
void describeSeg(DcmSegmentation& seg, const CtSeries& ct, const LabelMap& m, const SegSpec& spec) {
  ASSERT_TRUE(seg.importFromSourceImage(ct.slices.front().file.c_str()).good());
  ASSERT_TRUE(seg.getSeries().setSeriesNumber("901").good());
  // A SEG needs a Frame of Reference UID (type 1); a CT without one (the shared CT head) gets a
  // new one, which its scan cannot contradict.
  const std::string frame = !spec.frame_of_reference.empty() ? spec.frame_of_reference
                            : ct.for_uid.empty()             ? "2.25.172683917437960133125734208402447203771"
                                                             : std::string();
  if (!frame.empty()) {
    ASSERT_TRUE(seg.getFrameOfReference().setFrameOfReferenceUID(frame.c_str()).good());
  }
  for (std::size_t s = 0; s < m.names.size(); ++s) {
    DcmSegment* segment = nullptr;
    ASSERT_TRUE(
        DcmSegment::create(segment, m.names[s].c_str(), CodeSequenceMacro("85756007", "SCT", "Tissue"),
                           CodeSequenceMacro("T-" + OFString(std::to_string(s).c_str()), "99VH", m.types[s].c_str()),
                           DcmSegTypes::SAT_MANUAL)
            .good());
    const auto lab = dicomLab(m.rgb[s]);
    ASSERT_TRUE(segment->setRecommendedDisplayCIELabValue(lab[0], lab[1], lab[2]).good());
    Uint16 number = 0;
    ASSERT_TRUE(seg.addSegment(segment, number).good());
    ASSERT_EQ(number, s + 1);
  }
  FGPixelMeasures measures;
  ASSERT_TRUE(measures
                  .setPixelSpacing((ds(ct.row_spacing_mm * spec.pixel_spacing_scale) + "\\" +
                                    ds(ct.column_spacing_mm * spec.pixel_spacing_scale))
                                       .c_str())
                  .good());
  ASSERT_TRUE(measures.setSliceThickness(ds(ct.sliceSpacing()).c_str()).good());
  ASSERT_TRUE(measures.setSpacingBetweenSlices(ds(ct.sliceSpacing()).c_str()).good());
  FGPlaneOrientationPatient orientation;
  ASSERT_TRUE(orientation
                  .setImageOrientationPatient(ds(ct.row_dir.x()).c_str(), ds(ct.row_dir.y()).c_str(),
                                              ds(ct.row_dir.z()).c_str(), ds(ct.col_dir.x()).c_str(),
                                              ds(ct.col_dir.y()).c_str(), ds(ct.col_dir.z()).c_str())
                  .good());
  ASSERT_TRUE(seg.addForAllFrames(measures).good());
  ASSERT_TRUE(seg.addForAllFrames(orientation).good());
  IODReferences refs;
  for (const CtSlice& s : ct.slices) {
    const std::string series = spec.referenced_series.empty() ? ct.series_uid : spec.referenced_series;
    refs.add(new IODImageReference(ct.patient_id.c_str(), ct.study_uid.c_str(), series.c_str(), s.sop_instance.c_str(),
                                   s.sop_class.c_str()));
  }
  ASSERT_GT(seg.getCommonInstanceReference().addReferences(refs), 0u);
  // Frames indexed by segment, then position (Frame Content's Dimension Index Values).
  const OFString organisation = "2.25.302315786418127365041529371148264981";
  IODMultiframeDimensionModule& dims = seg.getDimensions();
  ASSERT_TRUE(dims.addDimensionIndex(DCM_ReferencedSegmentNumber, organisation, DCM_SegmentIdentificationSequence,
                                     "ReferencedSegmentNumber")
                  .good());
  ASSERT_TRUE(
      dims.addDimensionIndex(DCM_ImagePositionPatient, organisation, DCM_PlanePositionSequence, "ImagePositionPatient")
          .good());
  auto item = std::make_unique<IODMultiframeDimensionModule::DimensionOrganizationItem>();
  ASSERT_TRUE(item->setDimensionOrganizationUID(organisation).good());
  dims.getDimensionOrganizationSequence().push_back(item.release());
}

/// Adds a frame for every (segment, slice) where the segment is present (a sparse SEG), in
/// shuffled order unless spec.shuffle_seed is 0, each with its plane position and its CT slice
/// as derivation image.
void addFrames(DcmSegmentation& seg, const CtSeries& ct, const LabelMap& m, const SegSpec& spec) {
  std::vector<std::pair<std::size_t, int>> frames;
  for (std::size_t s = 0; s < m.names.size(); ++s) {
    for (int k = 0; k < m.slices; ++k) {
      bool any = false;
      for (int r = 0; r < m.rows && !any; ++r)
        for (int c = 0; c < m.columns && !any; ++c) any = m.inside[s][m.at(c, r, k)] != 0;
      if (any) frames.emplace_back(s, k);
    }
  }
  if (spec.shuffle_seed != 0) std::shuffle(frames.begin(), frames.end(), std::mt19937(spec.shuffle_seed));
  bool first = true;
  for (const auto& [s, k] : frames) {
    const CtSlice& slice = ct.slices[static_cast<std::size_t>(k)];
    const Eigen::Vector3d p = slice.ipp_mm + (first ? spec.shift_first_frame_mm : 0.0) * ct.normal();
    first = false;
    FGPlanePosPatient position;
    ASSERT_TRUE(position.setImagePositionPatient(ds(p.x()).c_str(), ds(p.y()).c_str(), ds(p.z()).c_str()).good());
    ImageSOPInstanceReferenceMacro source;
    ASSERT_TRUE(source.setReferencedSOPClassUID(slice.sop_class.c_str()).good());
    ASSERT_TRUE(source.setReferencedSOPInstanceUID(slice.sop_instance.c_str()).good());
    std::unique_ptr<FGDerivationImage> derivation(
        DcmSegmentation::createDerivationImageFG(OFVector<ImageSOPInstanceReferenceMacro>(1, source), "label map"));
    ASSERT_NE(derivation, nullptr);
    FGFrameContent content;
    ASSERT_TRUE(content.setDimensionIndexValues(static_cast<Uint32>(s + 1), 0).good());
    ASSERT_TRUE(content.setDimensionIndexValues(static_cast<Uint32>(k + 1), 1).good());
    std::vector<Uint8> px = framePixels(m, s, k, spec.fractional);
    OFVector<FGBase*> groups;
    groups.push_back(&position);
    groups.push_back(derivation.get());
    groups.push_back(&content);
    ASSERT_TRUE(seg.addFrame(px.data(), static_cast<Uint16>(s + 1), groups).good())
        << "segment " << s << " slice " << k;
  }
}

/// Writes the label map `m` on `ct` as a DICOM SEG at `out` with DCMTK.
void writeSeg(const fs::path& out, const CtSeries& ct, const LabelMap& m, const SegSpec& spec) {
  OFLog::configure(OFLogger::OFF_LOG_LEVEL);  // the OFCondition says what failed; no console text
  const IODGeneralEquipmentModule::EquipmentInfo equipment("VolumeHaptics tests", "dicom_seg_test", "1", "1.0");
  const ContentIdentificationMacro content("1", "LABELMAP", "the test's label map", "Tester^Test");
  DcmSegmentation* created = nullptr;
  const OFCondition made =
      spec.fractional ? DcmSegmentation::createFractionalSegmentation(
                            created, static_cast<Uint16>(ct.rows), static_cast<Uint16>(ct.columns),
                            DcmSegTypes::SFT_PROBABILITY, 255, equipment, content)
                      : DcmSegmentation::createBinarySegmentation(created, static_cast<Uint16>(ct.rows),
                                                                  static_cast<Uint16>(ct.columns), equipment, content);
  std::unique_ptr<DcmSegmentation> seg(created);
  ASSERT_TRUE(made.good() && seg != nullptr) << made.text();
  ASSERT_NO_FATAL_FAILURE(describeSeg(*seg, ct, m, spec));
  ASSERT_NO_FATAL_FAILURE(addFrames(*seg, ct, m, spec));
  const OFCondition saved = seg->saveFile(out.c_str());
  ASSERT_TRUE(saved.good()) << saved.text();
}

// ---- the comparison ------------------------------------------------------------------------

/// Voxels where `seg` differs from `m`: every CT pixel of every segment, taken to the scan's
/// voxel through its LPS position and the scan's geometry; plus any segment voxel where no CT
/// pixel lies (a segment's voxel count beyond the voxels found at the CT's pixels).
std::size_t mismatches(const LoadedSegmentation& seg, const LoadedVolume& scan, const CtSeries& ct, const LabelMap& m) {
  const haptics::VolumeGeometry& g = scan.field->geometry();
  EXPECT_EQ(seg.segments.size(), m.names.size());
  std::size_t wrong = 0;
  std::vector<std::size_t> found(seg.segments.size(), 0);
  for (int k = 0; k < m.slices; ++k) {
    for (int r = 0; r < m.rows; ++r) {
      for (int c = 0; c < m.columns; ++c) {
        const Eigen::Vector3d u =
            (g.direction_W.transpose() * (ct.pixelLps(c, r, k) * 1e-3 - g.origin_W_m)).cwiseQuotient(g.spacing_m);
        const Eigen::Vector3d ijk = u.array().round();
        EXPECT_LT((u - ijk).norm(), 1e-3) << "CT pixel (" << c << ", " << r << ", " << k << ") is not a scan voxel";
        for (std::size_t s = 0; s < seg.segments.size() && s < m.names.size(); ++s) {
          const SegmentInfo& info = seg.segments[s];
          const bool got = seg.label(info.layer, static_cast<int>(ijk.x()), static_cast<int>(ijk.y()),
                                     static_cast<int>(ijk.z())) == info.label_value;
          if (got != (m.inside[s][m.at(c, r, k)] != 0)) ++wrong;
          if (got) ++found[s];
        }
      }
    }
  }
  for (std::size_t s = 0; s < seg.segments.size(); ++s) {
    const std::size_t count = seg.segments[s].voxel_count;
    wrong += count > found[s] ? count - found[s] : found[s] - count;
  }
  return wrong;
}

/// Names, IDs, codes, colours (within 2/255 of the label map's) and the overlap in layers.
void expectSegments(const LoadedSegmentation& seg, const LabelMap& m) {
  ASSERT_EQ(seg.segments.size(), m.names.size());
  EXPECT_TRUE(seg.from_dicom_seg);
  for (std::size_t s = 0; s < m.names.size(); ++s) {
    const SegmentInfo& info = seg.segments[s];
    EXPECT_EQ(info.name, m.names[s]);
    EXPECT_EQ(info.id, "Segment_" + std::to_string(s + 1));
    EXPECT_EQ(info.category, "Tissue");
    EXPECT_EQ(info.type, m.types[s]);
    EXPECT_EQ(info.voxel_count, m.count(s)) << info.name;
    for (std::size_t c = 0; c < 3; ++c)
      EXPECT_NEAR(info.color_rgb[c], m.rgb[s][c], 2.0 / 255.0) << info.name << " channel " << c;
  }
  // The balls overlap, and the box overlaps ball B: they cannot share a layer.
  EXPECT_GE(seg.layers.size(), 2u);
  EXPECT_NE(seg.segments[0].layer, seg.segments[1].layer);
  EXPECT_NE(seg.segments[1].layer, seg.segments[2].layer);
  EXPECT_EQ(seg.find("sparse disc"), 3);
}

/// The synthetic CT series of the tests: 24 x 20 x 12 voxels, 0.9 x 1.1 x 2 mm, oblique (20 deg
/// about an axis between L and P), written by the fixtures in `folder`.
CtSeries syntheticCt(const fs::path& folder) {
  const auto source = test::ballVolume({24, 20, 12}, {0.9, 1.1, 2.0}, {-10.0, 20.0, -50.0}, {0.8, 31.0, -38.0}, 6.0);
  test::SeriesSpec spec;
  spec.series_description = "SEG base";
  spec.oblique = Eigen::AngleAxisd(20.0 * M_PI / 180.0, Eigen::Vector3d(1, 1, 0).normalized()).toRotationMatrix();
  test::writeSeries(folder, source, spec);
  return readCtSeries(folder);
}

// ---- the tests -----------------------------------------------------------------------------

TEST(DicomSeg, ABinarySegOpensOnItsCtVoxelForVoxelWhateverTheFrameOrder) {
  TempDir dir("dicom-seg-binary");
  const CtSeries ct = syntheticCt(dir / "ct");
  ASSERT_EQ(ct.slices.size(), 12u);
  const LoadedVolume scan = loadVolume(dir / "ct");
  const LabelMap m = shapes(ct.columns, ct.rows, static_cast<int>(ct.slices.size()));
  int sparse_slices = 0;  // the sparse disc is on three slices only
  for (int k = 0; k < m.slices; ++k) {
    sparse_slices += std::any_of(m.inside[3].begin() + static_cast<std::ptrdiff_t>(m.at(0, 0, k)),
                                 m.inside[3].begin() + static_cast<std::ptrdiff_t>(m.at(0, 0, k + 1)),
                                 [](std::uint8_t v) { return v != 0; });
  }
  ASSERT_EQ(sparse_slices, 3);
  SegSpec in_order;
  in_order.shuffle_seed = 0;
  SegSpec shuffled;
  shuffled.shuffle_seed = 7;
  ASSERT_NO_FATAL_FAILURE(writeSeg(dir / "ordered.dcm", ct, m, in_order));
  ASSERT_NO_FATAL_FAILURE(writeSeg(dir / "shuffled-seg", ct, m, shuffled));  // no extension: found by content

  EXPECT_TRUE(isDicomSegmentationFile(dir / "shuffled-seg"));
  EXPECT_TRUE(isSegmentationFile(dir / "shuffled-seg"));
  EXPECT_FALSE(isDicomSegmentationFile(ct.slices.front().file));
  const LoadedSegmentation ordered = loadSegmentation(dir / "ordered.dcm", scan);
  const LoadedSegmentation seg = loadSegmentation(dir / "shuffled-seg", scan);
  EXPECT_EQ(mismatches(ordered, scan, ct, m), 0u);
  EXPECT_EQ(mismatches(seg, scan, ct, m), 0u);
  expectSegments(seg, m);
  for (const auto& n : seg.notices) EXPECT_EQ(n.find("read in this process"), std::string::npos) << n;
  EXPECT_EQ(seg.frame_of_reference_uid, ct.for_uid);
  EXPECT_EQ(seg.referenced_series_uids, std::vector<std::string>{ct.series_uid});
  // The layers are the scan's grid, and the frame order changes nothing.
  ASSERT_EQ(seg.layers.size(), ordered.layers.size());
  for (std::size_t l = 0; l < seg.layers.size(); ++l) {
    EXPECT_EQ(seg.layers[l]->geometry().dims, scan.field->geometry().dims);
    EXPECT_TRUE(seg.layers[l]->geometry().origin_W_m.isApprox(scan.field->geometry().origin_W_m, 1e-12));
    EXPECT_TRUE(seg.layers[l]->bytes() == ordered.layers[l]->bytes()) << "layer " << l;
  }
  // The comparison sees one voxel changed in the label map after the SEG was written.
  LabelMap changed = m;
  const std::size_t n = changed.at(ct.columns / 2, ct.rows / 2, static_cast<int>(ct.slices.size()) / 2);
  changed.inside[1][n] = changed.inside[1][n] != 0 ? 0 : 1;
  EXPECT_EQ(mismatches(seg, scan, ct, changed), 1u);
}

TEST(DicomSeg, AFractionalSegIsInsideAtHalfItsMaximum) {
  TempDir dir("dicom-seg-fractional");
  const CtSeries ct = syntheticCt(dir / "ct");
  const LoadedVolume scan = loadVolume(dir / "ct");
  const LabelMap m = shapes(ct.columns, ct.rows, static_cast<int>(ct.slices.size()));
  SegSpec spec;
  spec.fractional = true;
  spec.shuffle_seed = 3;
  ASSERT_NO_FATAL_FAILURE(writeSeg(dir / "fractional.dcm", ct, m, spec));
  const LoadedSegmentation seg = loadSegmentation(dir / "fractional.dcm", scan);
  EXPECT_EQ(mismatches(seg, scan, ct, m), 0u);
  expectSegments(seg, m);
  bool noticed = false;
  for (const auto& n : seg.notices)
    noticed = noticed || n.find("at least half the maximum (128 of 255)") != std::string::npos;
  EXPECT_TRUE(noticed) << "no notice of the threshold";
}

TEST(DicomSeg, WithoutAScanItOpensOnTheGridItsFramesSpan) {
  TempDir dir("dicom-seg-own-grid");
  const CtSeries ct = syntheticCt(dir / "ct");
  const LoadedVolume scan = loadVolume(dir / "ct");
  const LabelMap m = shapes(ct.columns, ct.rows, static_cast<int>(ct.slices.size()));
  ASSERT_NO_FATAL_FAILURE(writeSeg(dir / "seg.dcm", ct, m, SegSpec{}));
  const LoadedSegmentation seg = loadSegmentation(dir / "seg.dcm");
  expectSegments(seg, m);
  // Its grid is the scan's slices from the lowest frame to the highest: every one of its voxels
  // is the scan voxel at the same place, with the same segments.
  const LoadedSegmentation on_scan = loadSegmentation(dir / "seg.dcm", scan);
  const haptics::VolumeGeometry& g = seg.layers.front()->geometry();
  const haptics::VolumeGeometry& sg = scan.field->geometry();
  EXPECT_TRUE(g.direction_W.isApprox(sg.direction_W, 1e-6));
  EXPECT_TRUE(g.spacing_m.isApprox(sg.spacing_m, 1e-6));
  EXPECT_LT(g.dims[2], sg.dims[2]);  // the first and last CT slices hold no segment
  std::size_t wrong = 0;
  for (int k = 0; k < g.dims[2]; ++k) {
    for (int j = 0; j < g.dims[1]; ++j) {
      for (int i = 0; i < g.dims[0]; ++i) {
        const Eigen::Vector3d p = g.origin_W_m + g.direction_W * g.spacing_m.cwiseProduct(Eigen::Vector3d(i, j, k));
        const Eigen::Vector3d u = (sg.direction_W.transpose() * (p - sg.origin_W_m)).cwiseQuotient(sg.spacing_m);
        const Eigen::Vector3i v = u.array().round().cast<int>();
        EXPECT_LT((u - v.cast<double>()).norm(), 1e-3);
        for (std::size_t s = 0; s < seg.segments.size(); ++s) {
          const bool own = seg.label(seg.segments[s].layer, i, j, k) == seg.segments[s].label_value;
          const SegmentInfo& o = on_scan.segments[s];
          if (own != (on_scan.label(o.layer, v.x(), v.y(), v.z()) == o.label_value)) ++wrong;
        }
      }
    }
  }
  EXPECT_EQ(wrong, 0u);
}

TEST(DicomSeg, OnTheSharedCtHeadEveryVoxelMatches) {
  VH_REQUIRE_SHARED(folder, "ct/ct-head-small");
  TempDir dir("dicom-seg-ct-head");
  const CtSeries ct = readCtSeries(folder);
  ASSERT_GE(ct.slices.size(), 2u);
  const LoadedVolume scan = loadVolume(folder);
  ASSERT_EQ(scan.field->geometry().dims[2], static_cast<int>(ct.slices.size()));
  const LabelMap m = shapes(ct.columns, ct.rows, static_cast<int>(ct.slices.size()));
  SegSpec spec;
  spec.shuffle_seed = 11;
  ASSERT_NO_FATAL_FAILURE(writeSeg(dir / "head-seg.dcm", ct, m, spec));
  const LoadedSegmentation seg = loadSegmentation(dir / "head-seg.dcm", scan);
  EXPECT_EQ(mismatches(seg, scan, ct, m), 0u);
  expectSegments(seg, m);
}

TEST(DicomSeg, ASegThatDoesNotFitTheScanIsRefusedWithTheReason) {
  TempDir dir("dicom-seg-bad");
  const CtSeries ct = syntheticCt(dir / "ct");
  const LoadedVolume scan = loadVolume(dir / "ct");
  const LabelMap m = shapes(ct.columns, ct.rows, static_cast<int>(ct.slices.size()));
  SegSpec other_series;
  other_series.referenced_series = "1.2.826.0.1.3680043.8.498.1";
  SegSpec other_frame;
  other_frame.frame_of_reference = "1.2.826.0.1.3680043.8.498.2";
  SegSpec shifted;
  shifted.shift_first_frame_mm = 0.5 * ct.sliceSpacing();
  SegSpec spacing;
  spacing.pixel_spacing_scale = 1.25;
  ASSERT_NO_FATAL_FAILURE(writeSeg(dir / "other-series.dcm", ct, m, other_series));
  ASSERT_NO_FATAL_FAILURE(writeSeg(dir / "other-frame.dcm", ct, m, other_frame));
  ASSERT_NO_FATAL_FAILURE(writeSeg(dir / "shifted.dcm", ct, m, shifted));
  ASSERT_NO_FATAL_FAILURE(writeSeg(dir / "spacing.dcm", ct, m, spacing));
  for (const DicomIsolation isolation : {DicomIsolation::kAuto, DicomIsolation::kInProcess}) {
    VolumeLoadOptions options;
    options.dicom_isolation = isolation;
    const auto error = [&](const char* name) {
      return test::loadErrorOf([&] { (void)loadSegmentation(dir / name, scan, options); });
    };
    std::string e = error("other-series.dcm");
    EXPECT_CONTAINS(e, "other-series.dcm");
    EXPECT_CONTAINS(e, "it segments another series: its Referenced Series Sequence names 1.2.826.0.1.3680043.8.498.1");
    EXPECT_CONTAINS(e, ct.series_uid);
    e = error("other-frame.dcm");
    EXPECT_CONTAINS(e, "another frame of reference: the SEG's Frame of Reference UID is 1.2.826.0.1.3680043.8.498.2");
    e = error("shifted.dcm");
    EXPECT_CONTAINS(e, "shifted.dcm");
    EXPECT_CONTAINS(e, "lies between slices of the scan (slice index");
    e = error("spacing.dcm");
    EXPECT_CONTAINS(e, "(Pixel Spacing, rows \\ columns) is not the scan's");
  }
}

TEST(DicomSeg, DamagedFilesAndOtherDicomAreRefusedWithoutACrash) {
  TempDir dir("dicom-seg-damaged");
  const CtSeries ct = syntheticCt(dir / "ct");
  const LoadedVolume scan = loadVolume(dir / "ct");
  const LabelMap m = shapes(ct.columns, ct.rows, static_cast<int>(ct.slices.size()));
  ASSERT_NO_FATAL_FAILURE(writeSeg(dir / "whole.dcm", ct, m, SegSpec{}));
  const std::string bytes = test::readFile(dir / "whole.dcm");
  test::writeFile(dir / "half.dcm", bytes.substr(0, bytes.size() / 2));
  test::writeFile(dir / "garbage.dcm", std::string(128, '\0') + "DICM" + std::string(300, '\x7f'));
  for (const DicomIsolation isolation : {DicomIsolation::kAuto, DicomIsolation::kInProcess}) {
    VolumeLoadOptions options;
    options.dicom_isolation = isolation;
    std::string e = test::loadErrorOf([&] { (void)loadSegmentation(dir / "half.dcm", scan, options); });
    EXPECT_CONTAINS(e, "half.dcm");
    EXPECT_CONTAINS(e, "damaged");
    e = test::loadErrorOf([&] { (void)loadSegmentation(dir / "garbage.dcm", options); });
    EXPECT_CONTAINS(e, "garbage.dcm");
    EXPECT_CONTAINS(e, "damaged");
    e = test::loadErrorOf([&] { (void)loadSegmentation(ct.slices.front().file, scan, options); });
    EXPECT_CONTAINS(e, ct.slices.front().file.filename().string());
    EXPECT_CONTAINS(e, "not a DICOM SEG: its SOP Class is CTImageStorage (1.2.840.10008.5.1.4.1.1.2)");
    e = test::loadErrorOf([&] { (void)loadSegmentation(dir / "missing.dcm", options); });
    EXPECT_CONTAINS(e, "no such file");
  }
  EXPECT_FALSE(isSegmentationFile(dir / "garbage.dcm"));
}

}  // namespace
}  // namespace vh::io
