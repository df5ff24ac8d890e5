#pragma once
/// @file
/// An RT Structure Set as read (dicom_rtstruct.h), before its contours are rasterised on a
/// scan: what the reader process hands back (reader_transfer.h), so that DCMTK runs only there.
/// Private to vh::io.
///
/// Frames: contour points are patient LPS in millimetres, as in the file (ContourData).

#include <array>
#include <filesystem>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "vh/io/volume_loader.h"

namespace vh::io::detail {

namespace fs = std::filesystem;

/// One item of a ROI's Contour Sequence (PS3.3 C.8.8.6).
struct RtStructContour {
  std::string type;                       ///< Contour Geometric Type: CLOSED_PLANAR, POINT, OPEN_PLANAR, ...
  std::vector<Eigen::Vector3d> points_mm;  ///< Contour Data, LPS [mm], in the file's order.
};

/// One ROI: its Structure Set ROI Sequence item (C.8.8.5) and its ROI Contour Sequence item
/// (C.8.8.6), joined by ROI Number.
struct RtStructRoi {
  int number = 0;                      ///< ROI Number.
  std::string name;                    ///< ROI Name (may be empty).
  std::string frame_of_reference_uid;  ///< Referenced Frame of Reference UID of the ROI (may be empty).
  bool has_color = false;              ///< ROI Display Color present.
  std::array<int, 3> color{};          ///< ROI Display Color: r, g, b in 0..255.
  std::vector<RtStructContour> contours;
};

/// What an RT Structure Set holds that a segmentation needs.
struct RtStructFile {
  std::string series_uid;  ///< The structure set's own Series Instance UID.
  /// Frame of Reference UIDs of its Referenced Frame of Reference Sequence (C.8.8.5).
  std::vector<std::string> frame_of_reference_uids;
  /// Series Instance UIDs under RT Referenced Study Sequence > RT Referenced Series Sequence.
  std::vector<std::string> referenced_series_uids;
  std::vector<RtStructRoi> rois;     ///< In the Structure Set ROI Sequence's order.
  std::vector<std::string> notices;  ///< What the reader chose, one sentence each.
};

/// Reads an RT Structure Set in this process with DCMTK's dcmrt (the reader process's
/// "rtstruct" mode).
/// @throws LoadError naming `path` (see loadDicomRtStruct()).
RtStructFile readDicomRtStructInProcess(const fs::path& path);

/// Reads an RT Structure Set in the reader process when it is found (isolated_load.cpp), else
/// through readDicomRtStructInProcess() (with a notice when `options` allow either).
/// @throws LoadError naming `path`; LoadCancelled.
RtStructFile readDicomRtStruct(const fs::path& path, const VolumeLoadOptions& options);

}  // namespace vh::io::detail
