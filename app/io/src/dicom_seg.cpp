// DICOM SEG read with DCMTK's dcmseg (dicom_seg.h): the Segment Sequence, and per frame its
// segment, image plane and inside pixels. Runs in the reader process ("seg" mode) when it is
// found; the frames are placed on a grid afterwards (dicom_seg_grid.cpp).
//
// Source: DICOM PS3.3 A.51 (Segmentation IOD), C.8.20 (Segmentation Series and Image
// Modules), C.7.6.16 (Multi-frame Functional Groups: Pixel Measures, Plane Position (Patient),
// Plane Orientation (Patient), Segment Identification). The pixels and the functional groups
// are DCMTK's (DcmSegmentation, FGInterface, DcmSegUtils::unpackBinaryFrame); the dataset is
// consulted only for what DCMTK 3.6.7 does not expose or does not check before use.
#include "dicom_seg_internal.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <fstream>
#include <memory>
#include <mutex>

#include <dcmtk/config/osconfig.h>  // DCMTK's configuration first
#include <dcmtk/dcmdata/dcdeftag.h>
#include <dcmtk/dcmdata/dcdict.h>
#include <dcmtk/dcmdata/dcfilefo.h>
#include <dcmtk/dcmdata/dcrledrg.h>
#include <dcmtk/dcmdata/dcuid.h>
#include <dcmtk/dcmfg/fginterface.h>
#include <dcmtk/dcmfg/fgpixmsr.h>
#include <dcmtk/dcmfg/fgplanor.h>
#include <dcmtk/dcmfg/fgplanpo.h>
#include <dcmtk/dcmfg/fgseg.h>
#include <dcmtk/dcmiod/cielabutil.h>
#include <dcmtk/dcmseg/segdoc.h>
#include <dcmtk/dcmseg/segment.h>
#include <dcmtk/dcmseg/segutils.h>
#include <dcmtk/oflog/oflog.h>

#include "loader_internal.h"
#include "vh/io/dicom_seg.h"

namespace vh::io {
namespace detail {
namespace {

/// DCMTK set up once per process: its console log off (its messages would reach stderr; the
/// LoadError says what went wrong instead), and the RLE decoder registered so that dcmseg can
/// decompress an RLE Lossless SEG.
void initDcmtk() {
  static std::once_flag once;
  std::call_once(once, [] {
    OFLog::configure(OFLogger::OFF_LOG_LEVEL);
    DcmRLEDecoderRegistration::registerCodecs();
  });
}

std::string text(const OFString& s) { return trim(std::string_view(s.c_str(), s.length())); }

/// The checks DCMTK 3.6.7 leaves to the caller before its frames may be used: Segmentation
/// Storage, BINARY or FRACTIONAL, and as many frames as per-frame functional groups
/// (DcmSegmentation::getFrame() indexes its frames unchecked when they disagree).
void checkDataset(DcmDataset& ds, const fs::path& path, int& frames) {
  OFString value;
  ds.findAndGetOFString(DCM_SOPClassUID, value);
  const std::string sop_class = text(value);
  if (sop_class != kSegmentationStorageUid) {
    fail(path, "not a DICOM SEG: its SOP Class is " +
                   (sop_class.empty() ? std::string("missing") : sopClassName(sop_class)) +
                   ", not Segmentation Storage (" + kSegmentationStorageUid + ")");
  }
  ds.findAndGetOFString(DCM_SegmentationType, value);
  if (text(value) != "BINARY" && text(value) != "FRACTIONAL") {
    fail(path, "a damaged DICOM SEG: Segmentation Type \"" + text(value) + "\" is neither BINARY nor FRACTIONAL");
  }
  Sint32 n = 0;
  if (ds.findAndGetSint32(DCM_NumberOfFrames, n).bad() || n < 1) {
    fail(path, "a damaged DICOM SEG: Number of Frames is missing or not positive");
  }
  DcmSequenceOfItems* per_frame = nullptr;
  const unsigned long items =
      ds.findAndGetSequence(DCM_PerFrameFunctionalGroupsSequence, per_frame).good() && per_frame != nullptr
          ? per_frame->card()
          : 0;
  if (items != static_cast<unsigned long>(n)) {
    fail(path, "a damaged DICOM SEG: " + std::to_string(n) + " frames but " + std::to_string(items) +
                   " items of the Per-frame Functional Groups Sequence");
  }
  frames = static_cast<int>(n);
}

/// The Segment Sequence, numbered 1, 2, 3, ... as PS3.3 C.8.20.2 requires (DCMTK numbers the
/// segments by their place in the sequence; a file numbered otherwise is refused rather than
/// its frames given to the wrong segments).
void readSegments(DcmSegmentation& seg, DcmDataset& ds, const fs::path& path, DicomSegFile& out) {
  const std::size_t n = seg.getNumberOfSegments();
  if (n == 0) fail(path, "no segments: the DICOM SEG's Segment Sequence is empty or unreadable");
  for (std::size_t s = 1; s <= n; ++s) {
    DcmItem* item = nullptr;
    Uint16 number = 0;
    if (ds.findAndGetSequenceItem(DCM_SegmentSequence, item, static_cast<signed long>(s - 1)).bad() ||
        item == nullptr || item->findAndGetUint16(DCM_SegmentNumber, number).bad() || number != s) {
      fail(path, "a damaged DICOM SEG: item " + std::to_string(s) + " of the Segment Sequence has Segment Number " +
                     std::to_string(number) + "; the numbers must run 1, 2, 3, ... (PS3.3 C.8.20.2)");
    }
    DcmSegment* segment = seg.getSegment(s);
    if (segment == nullptr) fail(path, "a damaged DICOM SEG: segment " + std::to_string(s) + " is unreadable");
    DicomSegSegment d;
    d.number = static_cast<int>(s);
    OFString value;
    if (segment->getSegmentLabel(value).good()) d.label = text(value);
    if (segment->getSegmentedPropertyCategoryCode().getCodeMeaning(value).good()) d.category = text(value);
    if (segment->getSegmentedPropertyTypeCode().getCodeMeaning(value).good()) d.type = text(value);
    Uint16 L = 0, a = 0, b = 0;
    if (segment->getRecommendedDisplayCIELabValue(L, a, b).good()) {
      d.has_lab = true;
      d.lab = {L, a, b};
      // CIE L*a*b* (D65) to sRGB in 0..1, the DICOM scaling undone first (PS3.3 C.10.7.1.1).
      IODCIELabUtil::dicomLab2RGB(d.rgb[0], d.rgb[1], d.rgb[2], L, a, b);
      for (double& c : d.rgb) c = std::isfinite(c) ? std::clamp(c, 0.0, 1.0) : 0.5;
    }
    out.segments.push_back(std::move(d));
  }
}

/// Frame f's segment and image plane from its functional groups (per-frame, else shared).
DicomSegFrame framePlane(FGInterface& groups, Uint32 f, const fs::path& path, DicomSegFile& out) {
  const std::string name = "frame " + std::to_string(f + 1);
  auto* segment = static_cast<FGSegmentation*>(groups.get(f, DcmFGTypes::EFG_SEGMENTATION));
  auto* position = static_cast<FGPlanePosPatient*>(groups.get(f, DcmFGTypes::EFG_PLANEPOSPATIENT));
  auto* orientation = static_cast<FGPlaneOrientationPatient*>(groups.get(f, DcmFGTypes::EFG_PLANEORIENTPATIENT));
  auto* measures = static_cast<FGPixelMeasures*>(groups.get(f, DcmFGTypes::EFG_PIXELMEASURES));
  DicomSegFrame frame;
  Uint16 number = 0;
  if (segment == nullptr || segment->getReferencedSegmentNumber(number).bad()) {
    fail(path, "a damaged DICOM SEG: " + name + " has no Segment Identification (Referenced Segment Number)");
  }
  frame.segment = number;
  Float64 p[3] = {0, 0, 0}, o[6] = {0, 0, 0, 0, 0, 0}, spacing[2] = {0, 0};
  if (position == nullptr || position->getImagePositionPatient(p[0], p[1], p[2]).bad()) {
    fail(path, name + " has no Plane Position (Patient): a SEG without positions cannot be placed on a scan");
  }
  if (orientation == nullptr || orientation->getImageOrientationPatient(o[0], o[1], o[2], o[3], o[4], o[5]).bad()) {
    fail(path, name + " has no Plane Orientation (Patient): a SEG without orientation cannot be placed on a scan");
  }
  if (measures == nullptr || measures->getPixelSpacing(spacing[0], 0).bad() ||
      measures->getPixelSpacing(spacing[1], 1).bad()) {
    fail(path, name + " has no Pixel Measures (Pixel Spacing): a SEG without pixel spacing cannot be placed on a scan");
  }
  frame.position_mm = Eigen::Vector3d(p[0], p[1], p[2]);
  frame.row_dir = Eigen::Vector3d(o[0], o[1], o[2]);
  frame.col_dir = Eigen::Vector3d(o[3], o[4], o[5]);
  frame.row_spacing_mm = spacing[0];
  frame.column_spacing_mm = spacing[1];
  const bool finite = frame.position_mm.allFinite() && frame.row_dir.allFinite() && frame.col_dir.allFinite();
  if (!finite || frame.row_dir.norm() < 0.5 || frame.col_dir.norm() < 0.5 || !(spacing[0] > 0.0) ||
      !(spacing[1] > 0.0) || !std::isfinite(spacing[0]) || !std::isfinite(spacing[1])) {
    fail(path, name + ": its position, orientation or pixel spacing is not a valid number");
  }
  frame.row_dir.normalize();
  frame.col_dir.normalize();
  if (std::abs(frame.row_dir.dot(frame.col_dir)) > 1e-3) {
    fail(path, name + ": its Image Orientation (Patient) rows and columns are not perpendicular");
  }
  Float64 thickness = 0.0, between = 0.0;
  if (f == 0 && measures->getSliceThickness(thickness).good() && thickness > 0.0) out.slice_thickness_mm = thickness;
  if (f == 0 && measures->getSpacingBetweenSlices(between).good() && between > 0.0)
    out.spacing_between_slices_mm = between;
  return frame;
}

/// Frame f's inside pixels, packed: BINARY frames unpacked by DCMTK, FRACTIONAL values inside
/// at half the maximum or more (`above` counts values over the maximum, taken as inside).
void frameMask(DcmSegmentation& seg, Uint32 f, int max_fractional, const fs::path& path, DicomSegFile& out,
               DicomSegFrame& frame, std::size_t& above) {
  const std::size_t pixels = static_cast<std::size_t>(out.rows) * static_cast<std::size_t>(out.columns);
  const DcmIODTypes::Frame* stored = seg.getFrame(f);
  if (stored == nullptr || stored->pixData == nullptr) {
    fail(path, "a damaged DICOM SEG: frame " + std::to_string(f + 1) + " has no pixels");
  }
  frame.mask.assign(maskBytes(pixels), 0);
  const Uint8* values = stored->pixData;
  std::unique_ptr<DcmIODTypes::Frame> unpacked;
  if (!out.fractional) {
    if (stored->length < maskBytes(pixels))
      fail(path, "a damaged DICOM SEG: frame " + std::to_string(f + 1) + " is cut short");
    unpacked.reset(
        DcmSegUtils::unpackBinaryFrame(stored, static_cast<Uint16>(out.rows), static_cast<Uint16>(out.columns)));
    if (unpacked == nullptr || unpacked->pixData == nullptr || unpacked->length < pixels) {
      fail(path, "a damaged DICOM SEG: frame " + std::to_string(f + 1) + " could not be unpacked");
    }
    values = unpacked->pixData;
  } else if (stored->length < pixels) {
    fail(path, "a damaged DICOM SEG: frame " + std::to_string(f + 1) + " is cut short");
  }
  for (std::size_t n = 0; n < pixels; ++n) {
    const int v = values[n];
    const bool inside = out.fractional ? 2 * v >= max_fractional : v != 0;
    if (out.fractional && v > max_fractional) ++above;
    if (inside) frame.mask[n >> 3] = static_cast<std::uint8_t>(frame.mask[n >> 3] | (1u << (n & 7u)));
  }
}

/// Every frame: its plane (framePlane()) and inside pixels (frameMask()).
void readFrames(DcmSegmentation& seg, DcmDataset& ds, int frames, const fs::path& path, DicomSegFile& out) {
  Uint16 rows = 0, columns = 0;
  ds.findAndGetUint16(DCM_Rows, rows);
  ds.findAndGetUint16(DCM_Columns, columns);
  if (rows == 0 || columns == 0) fail(path, "a damaged DICOM SEG: Rows or Columns is missing or 0");
  out.rows = rows;
  out.columns = columns;
  out.fractional = seg.getSegmentationType() == DcmSegTypes::ST_FRACTIONAL;
  Uint16 max_fractional = 0;
  if (out.fractional &&
      (ds.findAndGetUint16(DCM_MaximumFractionalValue, max_fractional).bad() || max_fractional == 0)) {
    fail(path, "a damaged DICOM SEG: a FRACTIONAL SEG without a positive Maximum Fractional Value");
  }
  FGInterface& groups = seg.getFunctionalGroups();
  if (groups.getNumberOfFrames() != static_cast<std::size_t>(frames)) {
    fail(path, "a damaged DICOM SEG: its functional groups describe " + std::to_string(groups.getNumberOfFrames()) +
                   " frames, Number of Frames is " + std::to_string(frames));
  }
  std::size_t above = 0;
  for (int f = 0; f < frames; ++f) {
    DicomSegFrame frame = framePlane(groups, static_cast<Uint32>(f), path, out);
    frameMask(seg, static_cast<Uint32>(f), max_fractional, path, out, frame, above);
    out.frames.push_back(std::move(frame));
  }
  if (out.fractional) {
    const char* kind = seg.getSegmentationFractionalType() == DcmSegTypes::SFT_OCCUPANCY ? "OCCUPANCY" : "PROBABILITY";
    out.notices.push_back(std::string("a FRACTIONAL DICOM SEG (") + kind + ", maximum " +
                          std::to_string(max_fractional) +
                          "): a voxel is inside a segment where its value is at least half the maximum (" +
                          std::to_string((max_fractional + 1) / 2) + " of " + std::to_string(max_fractional) + ")");
    if (above > 0) {
      out.notices.push_back(std::to_string(above) + " fractional value(s) above the maximum, taken as inside");
    }
  }
}

/// The SEG's own series, its frame of reference and the series it references.
void readReferences(DcmSegmentation& seg, DicomSegFile& out) {
  OFString value;
  if (seg.getSeries().getSeriesInstanceUID(value).good()) out.series_uid = text(value);
  if (seg.getFrameOfReference().getFrameOfReferenceUID(value).good()) out.frame_of_reference_uid = text(value);
  for (auto* item : seg.getCommonInstanceReference().getReferencedSeriesItems()) {
    if (item != nullptr && item->getSeriesInstanceUID(value).good() && !text(value).empty()) {
      out.referenced_series_uids.push_back(text(value));
    }
  }
}

}  // namespace

std::string sopClassName(const std::string& uid) {
  const char* name = dcmFindNameOfUID(uid.c_str(), nullptr);
  return name == nullptr ? uid : std::string(name) + " (" + uid + ")";
}

std::string mediaStorageSopClassUid(const fs::path& path) noexcept {
  try {
    if (!hasDicomPreamble(path) || dicomNestingDepth(path, kMaxDicomNesting) > kMaxDicomNesting) return {};
    initDcmtk();
    DcmFileFormat file;  // the meta header only
    if (file.loadFile(path.c_str(), EXS_Unknown, EGL_noChange, DCM_MaxReadLength, ERM_metaOnly).bad()) return {};
    OFString uid;
    if (file.getMetaInfo() == nullptr || file.getMetaInfo()->findAndGetOFString(DCM_MediaStorageSOPClassUID, uid).bad()) {
      return {};
    }
    return text(uid);
  } catch (...) {
    return {};
  }
}

bool hasDicomPreamble(const fs::path& path) noexcept {
  try {
    std::ifstream f(path, std::ios::binary);
    char head[132];
    if (!f.read(head, sizeof(head))) return false;
    return std::memcmp(head + 128, "DICM", 4) == 0;
  } catch (...) {
    return false;
  }
}

void loadDicomFile(const fs::path& path, const std::string& kind, DcmFileFormat& file) {
  initDcmtk();
  std::error_code ec;
  if (!fs::exists(path, ec)) fail(path, "no such file");
  if (!fs::is_regular_file(path, ec)) fail(path, "not " + kind + ": not a file");
  if (!dcmDataDict.isDictionaryLoaded()) {
    fail(path, "DCMTK's DICOM dictionary is not loaded (dicom.dic of libdcmtk17; see DCMDICTPATH)");
  }
  const std::size_t depth = dicomNestingDepth(path, kMaxDicomNesting);
  if (depth > kMaxDicomNesting) {
    fail(path, "a damaged DICOM file: its sequences nest more than " + std::to_string(kMaxDicomNesting) +
                   " levels deep (real files nest a few), which the DICOM parser cannot read safely");
  }
  const OFCondition loaded = file.loadFile(path.c_str());
  if (loaded.bad() || file.getDataset() == nullptr) {
    fail(path, std::string("not a readable DICOM file (damaged, cut short or not DICOM): ") + loaded.text());
  }
}

DicomSegFile readDicomSegInProcess(const fs::path& path) {
  // DcmSegmentation::loadFile() is DcmFileFormat::loadFile() then loadDataset(); done here in
  // two steps so that the dataset can be checked first (checkDataset()).
  DcmFileFormat file;
  loadDicomFile(path, "a DICOM SEG", file);
  DcmDataset& ds = *file.getDataset();
  int frames = 0;
  checkDataset(ds, path, frames);
  DcmSegmentation* loaded_seg = nullptr;
  const OFCondition read = DcmSegmentation::loadDataset(ds, loaded_seg);
  std::unique_ptr<DcmSegmentation> seg(loaded_seg);
  if (read.bad() || seg == nullptr) {
    fail(path, std::string("a damaged DICOM SEG (DCMTK: ") + read.text() + ")");
  }
  DicomSegFile out;
  readReferences(*seg, out);
  readSegments(*seg, ds, path, out);
  readFrames(*seg, ds, frames, path, out);
  return out;
}

}  // namespace detail

bool isDicomSegmentationFile(const std::filesystem::path& path) noexcept {
  return detail::mediaStorageSopClassUid(path) == kSegmentationStorageUid;
}

}  // namespace vh::io
