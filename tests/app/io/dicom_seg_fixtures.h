#pragma once
/// @file
/// DICOM SEG (DICOM PS3.3 A.51 Segmentation IOD, C.8.20) objects written by DCMTK's own writer
/// (DcmSegmentation::createBinarySegmentation / createFractionalSegmentation, addSegment,
/// addFrame with FGPlanePosPatient and FGDerivationImage) from a known label map on a CT series,
/// and the voxel-for-voxel comparison of a loaded segmentation with that label map. Shared by
/// the vh::io tests and the GUI tests.
///
/// The oracle is independent of vh::io's reader: the label map is given on the CT files' own
/// pixels (column, row, file), each pixel's patient position comes from the CT files' headers
/// read here with DCMTK (Image Position / Orientation (Patient), Pixel Spacing), and that
/// position is taken to the loaded scan's voxel through the scan's VolumeGeometry. The colours
/// are converted to CIELab with the textbook sRGB -> XYZ (D65) -> L*a*b* formulas and the DICOM
/// scaling of PS3.3 C.10.7.1.1, not with DCMTK's.
///
/// The writers report failures as gtest failures (fatal within them): wrap writeSeg() in
/// ASSERT_NO_FATAL_FAILURE.

#include <array>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "vh/io/segmentation.h"
#include "vh/io/volume_loader.h"

namespace vh::io::test {

/// One CT file: what a SEG frame on it refers to and copies.
struct CtSlice {
  std::filesystem::path file;
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

/// Every DICOM image file of `folder` (one series) through DCMTK.
CtSeries readCtSeries(const std::filesystem::path& folder);

/// The synthetic CT series of the tests: 24 x 20 x 12 voxels, 0.9 x 1.1 x 2 mm, oblique (20 deg
/// about an axis between L and P), written by the DICOM fixtures (dicom_fixtures.h) in `folder`
/// and read back with readCtSeries().
CtSeries syntheticCt(const std::filesystem::path& folder);

/// The truth: per segment, one byte per CT pixel (column fastest, then row, then slice).
struct LabelMap {
  int columns = 0, rows = 0, slices = 0;
  std::vector<std::string> names, types;    ///< SegmentLabel; SegmentedPropertyType meaning.
  std::vector<std::array<double, 3>> rgb;  ///< sRGB 0..1 (written as CIELab).
  std::vector<std::vector<std::uint8_t>> inside;

  std::size_t at(int c, int r, int k) const {
    return static_cast<std::size_t>(c) +
           static_cast<std::size_t>(columns) * (static_cast<std::size_t>(r) + static_cast<std::size_t>(rows) * k);
  }
  /// Pixels inside segment s.
  std::size_t count(std::size_t s) const;
};

/// Two overlapping balls ("ball A", "ball B") and a box overlapping the second, a disc on three
/// slices only, and a slab with a hole through it, scaled to the CT's size (c, r, k in 0..1 of
/// its extent).
LabelMap shapes(int columns, int rows, int slices);

/// The first `n` segments of `m` (e.g. the two overlapping balls of shapes()).
LabelMap firstSegments(LabelMap m, std::size_t n);

/// How to write the SEG (and which fault to put in).
struct SegSpec {
  bool fractional = false;
  unsigned shuffle_seed = 1;          ///< 0: frames in order (segment, slice); else shuffled.
  std::string referenced_series;      ///< Empty: the CT's series.
  std::string frame_of_reference;     ///< Empty: the CT's.
  double shift_first_frame_mm = 0.0;  ///< Moves the first frame written along the normal.
  double pixel_spacing_scale = 1.0;   ///< Scales the written Pixel Spacing.
};

/// Writes the label map `m` on `ct` as a DICOM SEG at `out` with DCMTK: its segments (labels,
/// codes, CIELab colours), the shared functional groups and references to every CT slice, and a
/// frame for every (segment, slice) where the segment is present (a sparse SEG), shuffled unless
/// spec.shuffle_seed is 0. BINARY frames are 0/1; FRACTIONAL ones 0..255 with inside 128..255
/// and outside 0 or 127 (the reader's threshold at half the maximum is what separates them).
void writeSeg(const std::filesystem::path& out, const CtSeries& ct, const LabelMap& m, const SegSpec& spec);

/// Voxels where `seg` differs from `m`: every CT pixel of every segment, taken to the scan's
/// voxel through its LPS position and the scan's geometry; plus any segment voxel where no CT
/// pixel lies (a segment's voxel count beyond the voxels found at the CT's pixels). Also a test
/// failure when the segment counts differ or a CT pixel is not at a scan voxel.
std::size_t mismatches(const LoadedSegmentation& seg, const LoadedVolume& scan, const CtSeries& ct, const LabelMap& m);

}  // namespace vh::io::test
