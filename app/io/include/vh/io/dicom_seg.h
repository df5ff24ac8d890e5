#pragma once
/// @file
/// DICOM Segmentation objects (DICOM SEG; DICOM PS3.3 A.51 Segmentation IOD, C.8.20
/// Segmentation Image Module), read through DCMTK's dcmseg into the same LoadedSegmentation as a
/// 3D Slicer `.seg.nrrd` (segmentation.h).
///
/// A SEG is one multi-frame file: its Segment Sequence names the segments (Segment Label,
/// Segmented Property Category and Type, Recommended Display CIELab Value), and each frame is
/// one segment on one image plane: the frame's Segment Identification gives the segment, its
/// Plane Position (Patient) the plane's first pixel, the shared (or per-frame) Plane
/// Orientation (Patient) and Pixel Measures the plane's axes and pixel size. Frames come in any
/// order and only where a segment is present (a SEG is sparse). BINARY frames are 1 bit a
/// pixel (DCMTK unpacks them); FRACTIONAL frames hold 0..Maximum Fractional Value, and a pixel
/// is inside its segment where the value is at least half the maximum.
///
/// Frames: DICOM positions are patient LPS in millimetres; W is patient LPS in metres, as for
/// loadVolume(). Overlapping segments go into separate label layers (LoadedSegmentation::layers,
/// as a layered `.seg.nrrd`): a segment joins the first layer where none of its voxels is taken.
#include <filesystem>

#include "vh/io/segmentation.h"
#include "vh/io/volume_loader.h"

namespace vh::io {

/// SOP Class UID of Segmentation Storage (DICOM PS3.4 B.5).
inline constexpr char kSegmentationStorageUid[] = "1.2.840.10008.5.1.4.1.1.66.4";

/// True when `path` is a DICOM file (the "DICM" preamble) whose SOP Class UID is Segmentation
/// Storage; only the file's meta header is read. Never throws (false when unreadable).
bool isDicomSegmentationFile(const std::filesystem::path& path) noexcept;

/// Loads a DICOM SEG, read by DCMTK in the reader process when it is found (reader_process.h:
/// a crash on a damaged file becomes a LoadError), else in this process with a notice.
///
/// With a `scan`, each frame is placed on the scan's grid: its slice is its Image Position
/// (Patient) projected onto the scan's slice axis, and its rows, columns, pixel spacing,
/// orientation and in-plane position must be the scan's; the layers then have the scan's
/// geometry, voxel for voxel. The scan's DICOM Series Instance UID must be one the SEG's
/// Referenced Series Sequence names, and its Frame of Reference UID the SEG's (a scan without
/// DICOM UIDs, e.g. a NRRD, is matched by position only, with a notice). Without a scan the
/// layers lie on the grid the frames span: the frames' plane axes, and slices at the Spacing
/// Between Slices of the Pixel Measures (else the Slice Thickness when every gap is a whole
/// number of it, else the smallest gap), from the first frame's plane to the last one's.
/// Segments: id "Segment_N" (N its Segment Number), name its Segment Label (else its
/// Segmented Property Type, else "Segment N"), colour from its CIELab value (DCMTK's
/// IODCIELabUtil::dicomLab2RGB: CIE L*a*b* (D65) to sRGB, PS3.3 C.10.7.1.1), else a palette.
/// @param scan the scan the SEG is opened on, or null for the SEG's own grid.
/// @param options cancel, progress, dicom_isolation and the watchdog as for loadVolume().
/// @throws LoadError naming the file and the problem: missing, not DICOM, damaged or cut
///         short, not Segmentation Storage (its SOP Class named), frames without position,
///         orientation or pixel spacing, a frame naming no segment of the file, a frame whose
///         geometry is not the scan's (which attribute and both values named) or that falls
///         between or outside the scan's slices, a referenced series or frame of reference
///         that is not the scan's, or a SEG with no segment; LoadCancelled when cancelled.
LoadedSegmentation loadDicomSegmentation(const std::filesystem::path& path, const LoadedVolume* scan,
                                         const VolumeLoadOptions& options = {});

}  // namespace vh::io
