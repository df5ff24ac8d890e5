#pragma once
/// @file
/// RT Structure Sets (RTSTRUCT; DICOM PS3.3 A.19 RT Structure Set IOD, C.8.8.5 Structure Set
/// Module, C.8.8.6 ROI Contour Module), read through DCMTK's dcmrt and rasterised onto the scan
/// they were drawn on, into the same LoadedSegmentation as a DICOM SEG (dicom_seg.h).
///
/// A structure set names its ROIs in the Structure Set ROI Sequence (ROI Number, ROI Name,
/// Referenced Frame of Reference UID) and outlines each in the ROI Contour Sequence (Referenced
/// ROI Number, ROI Display Color, and a Contour Sequence of planar polygons: Contour Geometric
/// Type CLOSED_PLANAR, Contour Data x\y\z per point in patient LPS mm). Each ROI becomes one
/// segment: id "ROI_N" (N its ROI Number), name its ROI Name (else "ROI N"), colour its ROI
/// Display Color / 255 (else a palette colour).
///
/// Rasterisation: a contour lies on the scan slice nearest its points' mean position along the
/// scan's slice axis (the points mapped to voxel coordinates u = D^T (p - origin) / spacing, as
/// for a DICOM SEG frame: dicom_seg_grid.cpp); all closed contours of one ROI on one slice are
/// filled together by a scanline fill with the even-odd rule at voxel centres (Foley, van Dam,
/// Feiner, Hughes, "Computer Graphics: Principles and Practice", 2nd ed., 3.6 "Filling
/// Polygons"; the even-odd rule of 3D Slicer's and plastimatch's contour rasterisation), so a
/// contour inside another is a hole and one inside a hole an island. A voxel centre (i, j) is
/// inside when an odd number of edges cross the row j to its left (edges taken half-open in the
/// row coordinate, so that a vertex on the row counts once).
///
/// Frames: contour points are patient LPS in millimetres; the layers are on the scan's grid, W
/// patient LPS in metres, as for loadVolume(). Overlapping ROIs go into separate label layers,
/// as a DICOM SEG's overlapping segments do.
#include <filesystem>

#include "vh/io/segmentation.h"
#include "vh/io/volume_loader.h"

namespace vh::io {

/// SOP Class UID of RT Structure Set Storage (DICOM PS3.4 B.5).
inline constexpr char kRtStructureSetStorageUid[] = "1.2.840.10008.5.1.4.1.1.481.3";

/// A contour within this fraction of the slice spacing of a scan slice lies on it; further off
/// it lies between two slices and is refused (a contour drawn on another series' slices).
inline constexpr double kRtStructOnSliceFraction = 0.25;

/// True when `path` is a DICOM file (the "DICM" preamble) whose SOP Class UID is RT Structure
/// Set Storage; only the file's meta header is read. Never throws (false when unreadable).
bool isDicomRtStructFile(const std::filesystem::path& path) noexcept;

/// Loads an RT Structure Set onto `scan`, read by DCMTK's dcmrt in the reader process when it
/// is found (reader_process.h: a crash on a damaged file becomes a LoadError), else in this
/// process with a notice. Each ROI with closed contours is rasterised on the scan's grid (see
/// the file comment) into a segment; overlapping ROIs go into separate layers.
///
/// References: when the scan has a Frame of Reference UID, it must be one the Referenced Frame
/// of Reference Sequence names (when that is present) and each ROI's Referenced Frame of
/// Reference UID (when present); when the scan has a Series Instance UID and the structure set
/// names referenced series (RT Referenced Series Sequence), the scan's must be one of them. A
/// scan without DICOM UIDs (a NRRD) is matched by position only, with a notice.
/// Notices (LoadedSegmentation::notices), not errors: ROIs without contours and POINT,
/// OPEN_PLANAR or OPEN_NONPLANAR contours are skipped; a closed contour of fewer than 3 points
/// or one that crosses itself is still filled by the even-odd rule (a crossing makes the
/// doubly enclosed part a hole).
/// @param scan the scan (a loaded volume) the structure set was drawn on; required.
/// @param options cancel, progress, dicom_isolation and the watchdog as for loadVolume().
/// @throws LoadError naming the file and the problem: missing, not DICOM, damaged or cut short,
///         not RT Structure Set Storage (its SOP Class named), no scan given, another frame of
///         reference or series than the scan's, a contour between two of the scan's slices or
///         outside them (the ROI, the contour and its slice position named), contour data that
///         is not x\y\z triples, or no ROI with closed contours; LoadCancelled when cancelled.
LoadedSegmentation loadDicomRtStruct(const std::filesystem::path& path, const LoadedVolume* scan,
                                     const VolumeLoadOptions& options = {});

}  // namespace vh::io
