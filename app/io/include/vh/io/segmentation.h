#pragma once
/// @file
/// Segmentations: 3D Slicer's `.seg.nrrd`, plain label-map NRRDs and NIfTIs and DICOM Segmentation
/// objects (DICOM SEG, read through DCMTK: dicom_seg.h), and the smoothed indicator field whose
/// isosurface is the felt surface of chosen segments.
///
/// A `.seg.nrrd` (3D Slicer's Segmentations module, vtkMRMLSegmentationStorageNode) is a NRRD
/// of integer labels, 3-D (one layer) or 4-D with a leading "list" axis (one layer per group of
/// overlapping segments), whose header names each segment with key/value pairs:
/// `SegmentN_ID`, `SegmentN_Name`, `SegmentN_Color` (r g b in 0..1), `SegmentN_LabelValue`,
/// `SegmentN_Layer`, `SegmentN_Extent`, ... Segment N occupies the voxels of layer
/// `SegmentN_Layer` whose value is `SegmentN_LabelValue`. A NRRD without these keys is read as a
/// label map: each distinct non-zero value is one segment, "Label V". A DICOM SEG gives the same
/// segments and layers (dicom_seg.h), placed on the scan's grid when it is opened on a scan.
///
/// Frames and units as loadVolume(): W is patient LPS in metres (a RAS file is converted).
#include <array>
#include <filesystem>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "vh/haptics/scalar_volume.h"
#include "vh/io/volume_loader.h"

namespace vh::io {

/// One segment of a segmentation.
struct SegmentInfo {
  std::string id;    ///< Slicer's SegmentN_ID ("Segment_1"), "Label_V", or "Segment_N" (DICOM SEG).
  std::string name;  ///< Slicer's SegmentN_Name ("right lung"), "Label V", or the DICOM Segment Label.
  std::array<double, 3> color_rgb{0.5, 0.5, 0.5};  ///< Display colour, each in 0..1.
  int label_value = 1;                 ///< The voxel value that marks the segment in its layer.
  int layer = 0;                       ///< Which layer (0 for a 3-D file).
  std::size_t voxel_count = 0;         ///< Voxels of the segment (0: empty).
  std::string category;  ///< DICOM SEG: Segmented Property Category's meaning ("Tissue"); else empty.
  std::string type;      ///< DICOM SEG: Segmented Property Type's meaning ("Bone"); else empty.
};

/// A loaded segmentation: its segments and the label layers they live in.
struct LoadedSegmentation {
  std::filesystem::path source;        ///< The file read.
  std::vector<SegmentInfo> segments;   ///< In the file's order (SegmentN), or by label value.
  /// Label layers (values as stored; one per layer of the file), all on the same grid in W [m].
  std::vector<std::shared_ptr<const haptics::ScalarVolume>> layers;
  bool from_slicer = false;            ///< The header named the segments (a .seg.nrrd).
  bool from_dicom_seg = false;         ///< A DICOM SEG (its Segment Sequence named the segments).
  std::string frame_of_reference_uid;  ///< DICOM SEG: its Frame of Reference UID; else empty.
  /// DICOM SEG: the Series Instance UIDs its Referenced Series Sequence names; else empty.
  std::vector<std::string> referenced_series_uids;
  std::vector<std::string> notices;    ///< What the loader chose or corrected, one sentence each.

  /// Index of the segment whose name or ID is `name_or_id` (case-insensitive), or -1.
  int find(const std::string& name_or_id) const;
  /// Label of the voxel (i, j, k) of `layer` (indices clamped to the grid).
  int label(int layer, int i, int j, int k) const noexcept;
  /// The voxel of the layers' grid nearest to p_W_m (W [m]; its grid coordinates rounded): what a
  /// point of another grid (a scan's voxel centre) takes its segments from.
  /// @return false (ijk untouched) without layers or when that voxel lies outside the grid.
  bool nearestVoxel(const Eigen::Vector3d& p_W_m, std::array<int, 3>& ijk) const noexcept;
};

/// Loads a segmentation (.seg.nrrd, a label-map .nrrd / .nhdr, a NIfTI label map (.nii, .nii.gz,
/// .hdr/.img: each distinct non-zero value one segment, as a NRRD label map), or a DICOM SEG: a
/// ".dcm" file or any file with the DICOM preamble). NRRD: the voxels are read by loadVolume() (in the reader
/// process when it is found), the segment names from the header, on the file's own grid. DICOM
/// SEG: loadDicomSegmentation() without a scan, on the grid its frames span.
/// @param options as loadVolume()'s (cancel, progress, watchdog); its nrrd_layer is ignored.
/// @throws LoadError naming the file and the problem: not a NRRD or DICOM SEG, a damaged file, a
///         segment whose layer is missing, non-integer labels, more than 4096 distinct labels in a
///         label map, or no segment at all; for a DICOM SEG as loadDicomSegmentation().
LoadedSegmentation loadSegmentation(const std::filesystem::path& path, const VolumeLoadOptions& options = {});

/// A segmentation from a label map already in memory (an array made in Python): each distinct
/// non-zero integer value of `labels` one segment, as a label-map file gives them ("Label V",
/// id "Label_V"), named `names[V]` where given; `source` names it in messages.
/// @throws LoadError naming `source` for non-integer labels, labels outside 0..65535, more than
///         4096 distinct labels, a name for a label that no voxel has, or no segment at all.
LoadedSegmentation segmentationFromLabels(std::shared_ptr<const haptics::ScalarVolume> labels,
                                          const std::filesystem::path& source,
                                          const std::map<int, std::string>& names = {});

/// Loads a segmentation opened on `scan`: a DICOM SEG is placed on the scan's grid, voxel for
/// voxel, and its referenced series and frame of reference checked against the scan's
/// (loadDicomSegmentation()); a NRRD is read as by the overload without a scan (its own grid).
/// @throws LoadError as loadSegmentation(path, options), and for a DICOM SEG that does not fit
///         the scan (another series or frame of reference, frames off the scan's grid).
LoadedSegmentation loadSegmentation(const std::filesystem::path& path, const LoadedVolume& scan,
                                    const VolumeLoadOptions& options = {});

/// True when `path` names a segmentation that names its segments: a 3D Slicer segmentation (its
/// name ends in ".seg.nrrd", or a NRRD whose header has "Segment0_" keys), a NIfTI that says it
/// holds labels (intent_code NIFTI_INTENT_LABEL, 1002) or a DICOM SEG (SOP Class UID
/// Segmentation Storage, from the file's meta header). Never throws (false when
/// unreadable).
bool isSegmentationFile(const std::filesystem::path& path) noexcept;

/// Name filter for a Qt file dialog that opens segmentations.
std::string segmentationFileDialogFilter();

/// The smoothed indicator field of the chosen segments: 1 inside any of them, 0 outside,
/// convolved with a Gaussian of standard deviation `sigma_voxels` (in voxels of the
/// segmentation's grid, per axis), stored as uint8 with value_scale 1/255 (F in 0..1), on the
/// segmentation's grid padded by ceil(3 sigma) + 1 voxels on every side (so the surface closes
/// inside the grid). The felt surface is its isosurface F = 0.5 (kSegmentSurfaceLevel): a
/// smooth surface within about half a voxel of the voxels' boundary, where the blocky voxel steps
/// are smoothed away; it is a ScalarVolume like any scan, so the renderer's guarantees (no
/// penetration, no crossing) hold for it unchanged. See README, "Segmentations".
/// @param segments indices into seg.segments (at least one).
/// @param sigma_voxels >= 0 (0: the trilinear indicator itself; blocky).
/// @throws std::invalid_argument for no or unknown segments, or a negative or non-finite sigma.
std::shared_ptr<const haptics::ScalarVolume> segmentIndicatorField(const LoadedSegmentation& seg,
                                                                  const std::vector<int>& segments,
                                                                  double sigma_voxels = 1.0);

/// The level of the felt surface in segmentIndicatorField() (F = 0.5: halfway between outside
/// and inside).
inline constexpr double kSegmentSurfaceLevel = 0.5;

}  // namespace vh::io
