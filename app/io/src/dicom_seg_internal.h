#pragma once
/// @file
/// A DICOM SEG as read (dicom_seg.h), before it is placed on a grid: what the reader process
/// hands back (reader_transfer.h), so that DCMTK runs only there. Private to vh::io.
///
/// Frames: positions and directions are patient LPS, lengths in millimetres, as in the file.

#include <array>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "vh/io/volume_loader.h"

class DcmFileFormat;

namespace vh::io::detail {

namespace fs = std::filesystem;

/// One item of the Segment Sequence (PS3.3 C.8.20.2).
struct DicomSegSegment {
  int number = 0;                            ///< Segment Number (frames refer to it).
  std::string label;                         ///< Segment Label.
  std::string category;                      ///< Segmented Property Category Code Sequence's Code Meaning.
  std::string type;                          ///< Segmented Property Type Code Sequence's Code Meaning.
  bool has_lab = false;                      ///< Recommended Display CIELab Value present.
  std::array<int, 3> lab{};                  ///< That value as stored: L, a, b in 0..65535 (PS3.3 C.10.7.1.1).
  std::array<double, 3> rgb{0.5, 0.5, 0.5};  ///< That colour in sRGB, each in 0..1 (when has_lab).
};

/// One frame: one segment on one image plane.
struct DicomSegFrame {
  int segment = 0;                                        ///< Referenced Segment Number.
  Eigen::Vector3d position_mm = Eigen::Vector3d::Zero();  ///< Image Position (Patient), LPS [mm].
  Eigen::Vector3d row_dir = Eigen::Vector3d::UnitX();     ///< Along a row (column index grows), LPS.
  Eigen::Vector3d col_dir = Eigen::Vector3d::UnitY();     ///< Down a column (row index grows), LPS.
  double row_spacing_mm = 1.0;                            ///< Pixel Spacing[0]: between rows (centres), along col_dir.
  double column_spacing_mm = 1.0;                         ///< Pixel Spacing[1]: between columns, along row_dir.
  /// Inside pixels, packed: bit (n % 8) of byte n / 8 for pixel n = column + columns * row.
  std::vector<std::uint8_t> mask;
  bool inside(std::size_t pixel) const noexcept { return ((mask[pixel >> 3] >> (pixel & 7u)) & 1u) != 0; }
};

/// What a DICOM SEG holds that a segmentation needs.
struct DicomSegFile {
  std::string series_uid;              ///< The SEG's own Series Instance UID.
  std::string frame_of_reference_uid;  ///< Frame of Reference UID (empty when absent).
  /// Series Instance UIDs of its Referenced Series Sequence (Common Instance Reference Module).
  std::vector<std::string> referenced_series_uids;
  bool fractional = false;                 ///< Segmentation Type FRACTIONAL (else BINARY).
  int rows = 0, columns = 0;               ///< Every frame's size.
  double slice_thickness_mm = 0.0;         ///< Pixel Measures' Slice Thickness (0: absent).
  double spacing_between_slices_mm = 0.0;  ///< Pixel Measures' Spacing Between Slices (0: absent).
  std::vector<DicomSegSegment> segments;   ///< In the file's order.
  std::vector<DicomSegFrame> frames;       ///< In the file's order.
  std::vector<std::string> notices;        ///< What the reader chose, one sentence each.
};

/// Bytes of a packed mask of `pixels` pixels.
inline std::size_t maskBytes(std::size_t pixels) { return (pixels + 7) / 8; }

/// Reads a DICOM SEG in this process with DCMTK (the reader process's "seg" mode).
/// @throws LoadError naming `path` (see loadDicomSegmentation()).
DicomSegFile readDicomSegInProcess(const fs::path& path);

/// Reads a DICOM SEG in the reader process when it is found (isolated_load.cpp), else through
/// readDicomSegInProcess() (with a notice when `options` allow either).
/// @throws LoadError naming `path`; LoadCancelled.
DicomSegFile readDicomSeg(const fs::path& path, const VolumeLoadOptions& options);

/// Segments as labels in uint8 layers on the scan's grid (LoadedSegmentation's layered form):
/// each segment takes the next label of the first layer where it overlaps no other, a new layer
/// when none fits, at most kLabelsPerLayer labels a layer.
struct SegmentLayers {
  static constexpr int kLabelsPerLayer = 255;
  std::size_t voxel_count = 0;                     ///< Voxels of the grid (each layer's size).
  std::vector<std::vector<std::uint8_t>> voxels;   ///< The layers' labels, 0: none.
  std::vector<int> used;                           ///< Labels taken in each layer.

  /// The first layer with a free label where `fits(layer)` holds (a new layer when none), and
  /// its next label, now taken. @return {layer index, label (1..kLabelsPerLayer)}.
  std::pair<std::size_t, int> take(const std::function<bool(const std::vector<std::uint8_t>& layer)>& fits);
};

/// True when `path` starts with the DICOM preamble: 128 bytes, then "DICM". Never throws.
bool hasDicomPreamble(const fs::path& path) noexcept;

/// The Media Storage SOP Class UID (0002,0002) of a DICOM file's meta header, read by DCMTK
/// (nothing past the meta header); empty when `path` is not a readable DICOM file. Never throws.
std::string mediaStorageSopClassUid(const fs::path& path) noexcept;

/// "CTImageStorage (1.2.840.10008.5.1.4.1.1.2)", or the UID alone when DCMTK does not know it.
std::string sopClassName(const std::string& uid);

/// Deepest nesting of sequences that the SEG and RT Structure Set readers let DCMTK parse. Real
/// files nest a few levels (a SEG's functional groups: 3; an RT Structure Set's references: 4);
/// DCMTK 3.6.7 parses nested sequences by recursion without a limit, and tens of thousands of
/// levels overflow its stack (a crash, not an error).
inline constexpr std::size_t kMaxDicomNesting = 128;

/// How deep the sequences of the DICOM file `path` nest (0: none; 1: a sequence at the top
/// level; ...), found by walking its element headers without DCMTK (dicom_nesting.cpp), in its
/// meta information and data set; the walk stops once the depth exceeds `limit` (and returns
/// limit + 1), at the end of the file, or where the encoding cannot be followed (DCMTK stops
/// there too). Errs towards counting more levels than DCMTK would parse; a deflated data set is
/// not walked. Never throws but std::bad_alloc; 0 for a file that cannot be opened.
std::size_t dicomNestingDepth(const fs::path& path, std::size_t limit);

/// Reads the whole DICOM file `path` into `file` with DCMTK (its log off, the RLE decoder
/// registered), for the SEG and RT Structure Set readers; `kind` names what the file should be
/// ("a DICOM SEG") in the error for a path that is no file. Afterwards file.getDataset() is set.
/// @throws LoadError naming `path`: no such file, not a file, DCMTK's dictionary not loaded,
///         sequences nested deeper than kMaxDicomNesting (checked before DCMTK parses), or a
///         damaged, cut short or non-DICOM file (with DCMTK's reason).
void loadDicomFile(const fs::path& path, const std::string& kind, DcmFileFormat& file);

}  // namespace vh::io::detail
