// DICOM SEG objects written with DCMTK from a known label map, and the comparison of a loaded
// segmentation with it (see dicom_seg_fixtures.h).
#include "dicom_seg_fixtures.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <random>
#include <utility>

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

namespace vh::io::test {

namespace fs = std::filesystem;

namespace {

// ---- DCMTK attribute access ----------------------------------------------------------------

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

// ---- the SEG's parts, written by DCMTK -------------------------------------------------------

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

}  // namespace

// ---- the CT series, read with DCMTK ---------------------------------------------------------

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

CtSeries syntheticCt(const fs::path& folder) {
  const auto source = ballVolume({24, 20, 12}, {0.9, 1.1, 2.0}, {-10.0, 20.0, -50.0}, {0.8, 31.0, -38.0}, 6.0);
  SeriesSpec spec;
  spec.series_description = "SEG base";
  spec.oblique = Eigen::AngleAxisd(20.0 * M_PI / 180.0, Eigen::Vector3d(1, 1, 0).normalized()).toRotationMatrix();
  writeSeries(folder, source, spec);
  return readCtSeries(folder);
}

// ---- the label map --------------------------------------------------------------------------

std::size_t LabelMap::count(std::size_t s) const {
  return static_cast<std::size_t>(std::count(inside[s].begin(), inside[s].end(), std::uint8_t{1}));
}

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

LabelMap firstSegments(LabelMap m, std::size_t n) {
  n = std::min(n, m.names.size());
  m.names.resize(n);
  m.types.resize(n);
  m.rgb.resize(n);
  m.inside.resize(n);
  return m;
}

// ---- the SEG, written by DCMTK -------------------------------------------------------------

void writeSeg(const fs::path& out, const CtSeries& ct, const LabelMap& m, const SegSpec& spec) {
  OFLog::configure(OFLogger::OFF_LOG_LEVEL);  // the OFCondition says what failed; no console text
  const IODGeneralEquipmentModule::EquipmentInfo equipment("VolumeHaptics tests", "dicom_seg_fixtures", "1", "1.0");
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

}  // namespace vh::io::test
