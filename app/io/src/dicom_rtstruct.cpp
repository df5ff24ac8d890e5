// RT Structure Sets read with DCMTK's dcmrt (dicom_rtstruct.h): the ROIs' names, colours,
// frames of reference and contours, and the series the structure set references. Runs in the
// reader process ("rtstruct" mode) when it is found; the contours are rasterised on the scan
// afterwards (dicom_rtstruct_grid.cpp).
//
// Source: DICOM PS3.3 A.19 (RT Structure Set IOD), C.8.8.5 (Structure Set Module: Structure
// Set ROI Sequence, Referenced Frame of Reference Sequence), C.8.8.6 (ROI Contour Module: ROI
// Display Color, Contour Sequence, Contour Geometric Type, Contour Data). The attributes are
// DCMTK's (DRTStructureSetIOD); the dataset itself is consulted only for the SOP Class UID
// before DCMTK reads it.
#include "dicom_rtstruct_internal.h"

#include <algorithm>
#include <cmath>
#include <map>

#include <dcmtk/config/osconfig.h>  // DCMTK's configuration first
#include <dcmtk/dcmdata/dcdeftag.h>
#include <dcmtk/dcmdata/dcdict.h>
#include <dcmtk/dcmdata/dcfilefo.h>
#include <dcmtk/dcmdata/dcuid.h>
#include <dcmtk/dcmrt/drtstrct.h>

#include "dicom_seg_internal.h"
#include "loader_internal.h"
#include "vh/io/dicom_rtstruct.h"

namespace vh::io {
namespace detail {
namespace {

std::string text(const OFString& s) { return trim(std::string_view(s.c_str(), s.length())); }

void addUnique(std::vector<std::string>& list, const std::string& uid) {
  if (!uid.empty() && std::find(list.begin(), list.end(), uid) == list.end()) list.push_back(uid);
}

/// The structure set's own series and the frames of reference and series it references
/// (C.8.8.5: Referenced Frame of Reference Sequence > RT Referenced Study Sequence > RT
/// Referenced Series Sequence).
void readReferences(DRTStructureSetIOD& rs, RtStructFile& out) {
  OFString value;
  if (rs.getSeriesInstanceUID(value).good()) out.series_uid = text(value);
  auto& frames = rs.getReferencedFrameOfReferenceSequence();
  for (std::size_t f = 0; f < frames.getNumberOfItems(); ++f) {
    auto& frame = frames.getItem(f);
    if (frame.getFrameOfReferenceUID(value).good()) addUnique(out.frame_of_reference_uids, text(value));
    auto& studies = frame.getRTReferencedStudySequence();
    for (std::size_t s = 0; s < studies.getNumberOfItems(); ++s) {
      auto& series = studies.getItem(s).getRTReferencedSeriesSequence();
      for (std::size_t r = 0; r < series.getNumberOfItems(); ++r) {
        if (series.getItem(r).getSeriesInstanceUID(value).good()) addUnique(out.referenced_series_uids, text(value));
      }
    }
  }
}

/// The Structure Set ROI Sequence: number, name, frame of reference of each ROI.
void readRois(DRTStructureSetIOD& rs, const fs::path& path, RtStructFile& out) {
  auto& rois = rs.getStructureSetROISequence();
  for (std::size_t n = 0; n < rois.getNumberOfItems(); ++n) {
    auto& item = rois.getItem(n);
    RtStructRoi roi;
    Sint32 number = 0;
    if (item.getROINumber(number).bad()) {
      fail(path, "a damaged RT Structure Set: item " + std::to_string(n + 1) +
                     " of the Structure Set ROI Sequence has no ROI Number");
    }
    roi.number = static_cast<int>(number);
    OFString value;
    if (item.getROIName(value).good()) roi.name = text(value);
    if (item.getReferencedFrameOfReferenceUID(value).good()) roi.frame_of_reference_uid = text(value);
    for (const auto& other : out.rois) {
      if (other.number == roi.number) {
        fail(path, "a damaged RT Structure Set: ROI Number " + std::to_string(number) + " is used twice");
      }
    }
    out.rois.push_back(std::move(roi));
  }
  if (out.rois.empty()) fail(path, "no ROIs: the RT Structure Set's Structure Set ROI Sequence is empty or unreadable");
}

/// One contour's geometric type and points (Contour Data: x\y\z triples, LPS mm).
RtStructContour readContour(const DRTContourSequence::Item& item, const std::string& name, const fs::path& path) {
  RtStructContour c;
  OFString type;
  if (item.getContourGeometricType(type).good()) c.type = text(type);
  OFVector<Float64> data;
  item.getContourData(data);
  if (data.size() % 3 != 0) {
    fail(path, name + ": its Contour Data holds " + std::to_string(data.size()) +
                   " numbers, not x\\y\\z triples (C.8.8.6.1)");
  }
  for (std::size_t p = 0; p + 2 < data.size(); p += 3) {
    const Eigen::Vector3d point(data[p], data[p + 1], data[p + 2]);
    if (!point.allFinite()) fail(path, name + ": its Contour Data holds a number that is not finite");
    c.points_mm.push_back(point);
  }
  return c;
}

/// The ROI Contour Sequence: each item's colour and contours, given to its ROI.
void readContours(DRTStructureSetIOD& rs, const fs::path& path, RtStructFile& out) {
  std::map<int, std::size_t> index_of;
  for (std::size_t r = 0; r < out.rois.size(); ++r) index_of[out.rois[r].number] = r;
  auto& items = rs.getROIContourSequence();
  for (std::size_t n = 0; n < items.getNumberOfItems(); ++n) {
    auto& item = items.getItem(n);
    Sint32 number = 0;
    if (item.getReferencedROINumber(number).bad()) {
      fail(path, "a damaged RT Structure Set: item " + std::to_string(n + 1) +
                     " of the ROI Contour Sequence has no Referenced ROI Number");
    }
    const auto it = index_of.find(static_cast<int>(number));
    if (it == index_of.end()) {
      out.notices.push_back("contours of ROI " + std::to_string(number) +
                            ", which the Structure Set ROI Sequence does not name, were skipped");
      continue;
    }
    RtStructRoi& roi = out.rois[it->second];
    Sint32 rgb[3] = {0, 0, 0};
    if (item.getROIDisplayColor(rgb[0], 0).good() && item.getROIDisplayColor(rgb[1], 1).good() &&
        item.getROIDisplayColor(rgb[2], 2).good()) {
      roi.has_color = true;
      for (int c = 0; c < 3; ++c) roi.color[static_cast<std::size_t>(c)] = std::clamp(static_cast<int>(rgb[c]), 0, 255);
    }
    auto& contours = item.getContourSequence();
    for (std::size_t c = 0; c < contours.getNumberOfItems(); ++c) {
      const std::string name = "ROI " + std::to_string(roi.number) + " (\"" + roi.name + "\") contour " +
                               std::to_string(c + 1);
      roi.contours.push_back(readContour(contours.getItem(c), name, path));
    }
  }
}

}  // namespace

RtStructFile readDicomRtStructInProcess(const fs::path& path) {
  DcmFileFormat file;
  loadDicomFile(path, "an RT Structure Set", file);
  DcmDataset& ds = *file.getDataset();
  OFString value;
  ds.findAndGetOFString(DCM_SOPClassUID, value);
  const std::string sop_class = text(value);
  if (sop_class != kRtStructureSetStorageUid) {
    fail(path, "not an RT Structure Set: its SOP Class is " +
                   (sop_class.empty() ? std::string("missing") : sopClassName(sop_class)) +
                   ", not RT Structure Set Storage (" + kRtStructureSetStorageUid + ")");
  }
  DRTStructureSetIOD rs;
  const OFCondition read = rs.read(ds);
  if (read.bad()) fail(path, std::string("a damaged RT Structure Set (DCMTK: ") + read.text() + ")");
  RtStructFile out;
  readReferences(rs, out);
  readRois(rs, path, out);
  readContours(rs, path, out);
  return out;
}

}  // namespace detail

bool isDicomRtStructFile(const std::filesystem::path& path) noexcept {
  return detail::mediaStorageSopClassUid(path) == kRtStructureSetStorageUid;
}

}  // namespace vh::io
