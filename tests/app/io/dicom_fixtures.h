#pragma once
/// @file
/// Writers of synthetic-but-real DICOM series for the loader tests ("Every clinical
/// scan opens"): the voxels of a source volume (the shared small CT head, or a caller's volume)
/// written through vtk-dicom's vtkDICOMWriter and CT / MR generators (PET through the MR one),
/// with the geometry and the faults of real scans: gantry tilt, oblique planes, missing,
/// duplicated and displaced slices, enhanced multi-frame files, 4-D (temporal) and multi-echo
/// series.
///
/// Frames: every position here is patient LPS in millimetres, as DICOM writes it. A voxel index
/// (i, j, k) is the SOURCE volume's (column, row, slice); the writer puts source column i of row
/// j of slice k at pixel (i / subsample, j / subsample) of the file(s) for slice k.

#include <filesystem>
#include <functional>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>
#include <vtkSmartPointer.h>

class vtkImageData;
class vtkDICOMMetaData;

namespace vh::io::test {

/// The voxels a series is written from.
struct SourceVolume {
  vtkSmartPointer<vtkImageData> image;  ///< Stored values (e.g. int16), one component.
  /// Voxel index (i, j, k) -> patient LPS [mm] of the source (its own geometry, which the
  /// fixtures' geometry starts from).
  Eigen::Matrix4d ijk_to_lps_mm = Eigen::Matrix4d::Identity();
  double rescale_slope = 1.0;      ///< Data value = slope * stored + intercept (HU for CT).
  double rescale_intercept = 0.0;  ///< See rescale_slope.
  /// Patient, study and equipment tags copied into every written file; may be null.
  vtkSmartPointer<vtkDICOMMetaData> shared_tags;
};

/// Reads a DICOM folder (one series) with vtkDICOMReader: stored values (no rescale), rows in
/// file order, ijk_to_lps_mm from the reader's patient matrix.
/// @throws std::runtime_error when the folder holds no readable series.
SourceVolume readSourceSeries(const std::filesystem::path& folder);

/// The shared small CT head (ct/ct-head-small: 64 x 64 x 93, int16, 3.2 x 3.2 x 1.5 mm).
/// @throws std::runtime_error when it is missing (guard with VH_REQUIRE_SHARED first).
SourceVolume ctHeadSmall();

/// A synthetic int16 volume: `background` everywhere, `value` inside a ball of `radius_mm`
/// about `centre_lps_mm`; axis-aligned LPS grid with voxel (0, 0, 0) at `origin_lps_mm`.
SourceVolume ballVolume(const Eigen::Vector3i& dims, const Eigen::Vector3d& spacing_mm,
                        const Eigen::Vector3d& origin_lps_mm, const Eigen::Vector3d& centre_lps_mm,
                        double radius_mm, short value = 2000, short background = 0);

/// `src` with `pad` voxels of background (its minimum stored value) added on each side of
/// every slice; ijk_to_lps_mm shifted so that the anatomy stays where it was. For tilted
/// series that a rectifier resamples into the same extent (vtkDICOMCTRectifier does), which
/// otherwise cuts anatomy off the first and last slices.
SourceVolume paddedInPlane(const SourceVolume& src, int pad);

/// How a CT gantry tilt is written (both are sheared grids that vtkDICOMCTRectifier rectifies).
enum class TiltConvention {
  /// What tilted scanners (GE, Siemens, Toshiba head CTs) write: ImageOrientationPatient is
  /// the tilted image plane (row = u, column = cos(t) v + sin(t) w) and ImagePositionPatient
  /// moves along the table axis w only, so the slice stack is sheared along the column
  /// direction by tan(t) per unit of slice spacing. This is the default.
  kTiltedPlane,
  /// An axial-looking variant: ImageOrientationPatient stays (u, v) and the positions shear
  /// along v by tan(t) * (distance along w), i.e. slice k is at o + k dz (w + tan(t) v).
  kShearedPositions,
};

/// What to write. u, v, w are the source's unit column, row and slice axes in LPS (for the CT
/// head: L, P, S); spacings and the first voxel's position are the source's.
struct SeriesSpec {
  /// "CT" (CT Image Storage), "MR" (MR Image Storage) or "PT" (PET Image Storage, written
  /// through the MR generator with the SOP class and Modality changed; the PET tags come from
  /// `instance_tags`).
  std::string modality = "CT";
  /// CT gantry tilt [deg], also written as GantryDetectorTilt (0018,1120).
  double gantry_tilt_deg = 0.0;
  TiltConvention tilt_convention = TiltConvention::kTiltedPlane;
  /// Rotation applied to the row, column and stacking directions about the first voxel
  /// (oblique MR / CT); applied after the tilt.
  Eigen::Matrix3d oblique = Eigen::Matrix3d::Identity();
  std::vector<int> drop_slices;       ///< Source slices not written (missing slices).
  /// Source slices written twice: a second file, same position and pixels, new SOP Instance UID.
  std::vector<int> duplicate_slices;
  /// (k, d): source slice k displaced by d [mm] along the image normal (irregular spacing).
  std::vector<std::pair<int, double>> jitter_slices;
  /// One Enhanced CT / Enhanced MR Image Storage file, with per-frame PlanePositionSequence.
  bool multi_frame = false;
  /// 4-D: temporal positions, each a full copy of the volume with stored values times
  /// phaseScale(t, time_points); TemporalPositionIdentifier, NumberOfTemporalPositions and
  /// TriggerTime (100 ms per phase) are written.
  int time_points = 1;
  /// Multi-echo MR: EchoTime 10 ms * (e + 1), EchoNumbers e + 1, stored values times
  /// echoScale(e), same positions.
  int echoes = 1;
  /// Also write a DICOMDIR. Not supported (see writeSeries()); must stay false.
  bool dicomdir = false;
  std::string series_description = "fixture";
  int series_number = 1;
  std::string series_uid;  ///< Empty: generated.
  int subsample = 1;       ///< Keep every n-th column and row (smaller files).
  /// File name prefix inside the folder; empty: "S<series_number>_".
  std::string file_prefix;
  /// When set, called last for each written file (single-frame series): (metadata, instance,
  /// source slice k), to add or replace tags, e.g. the PET Series and Isotope modules or a
  /// per-file RescaleSlope.
  std::function<void(vtkDICOMMetaData* meta, int instance, int k)> instance_tags;
};

/// What was written.
struct WrittenSeries {
  std::filesystem::path folder;
  std::vector<std::filesystem::path> files;  ///< In writing order.
  std::string series_uid;
  /// Source voxel index (i, j, k) -> patient LPS [mm] at which that voxel was written (before
  /// dropping slices; without the jitter): a shear for the tilt, a rotation for `oblique`.
  Eigen::Matrix4d source_ijk_to_lps_mm = Eigen::Matrix4d::Identity();
  /// Unit normal of the written image planes (row x column), LPS.
  Eigen::Vector3d normal_lps = Eigen::Vector3d::UnitZ();
  /// Per source slice k: the jitter [mm] along normal_lps (0 for most).
  std::vector<double> slice_jitter_mm;
  /// Per source slice k: ImagePositionPatient [mm] of its file(s) (also for dropped slices).
  std::vector<Eigen::Vector3d> slice_position_lps_mm;
  int columns = 0;    ///< Written image size.
  int rows = 0;       ///< See columns.
  int subsample = 1;  ///< The spec's subsample.
  /// The exact LPS position [mm] of source voxel (i, j, k) as written, jitter included.
  Eigen::Vector3d voxelLps(double i, double j, double k) const;
};

/// Writes one series from `source` into `folder` (created if missing). Several series may be
/// written into one folder (different series_number / file_prefix).
/// @throws std::runtime_error when vtk-dicom fails, for a bad spec, or for spec.dicomdir:
///         vtk-dicom 0.8 writes no DICOMDIR (vtkDICOMDirectory only reads one) and no DICOMDIR
///         writer (GDCM's gdcmgendir, DCMTK's dcmmkdir) is installed.
WrittenSeries writeSeries(const std::filesystem::path& folder, const SourceVolume& source,
                          const SeriesSpec& spec);

/// Stored-value factor of temporal position t of n: 1 + t / n (phase 0 is the source itself).
double phaseScale(int t, int n);
/// Stored-value factor of echo e: 1 / (1 + 0.5 e) (echo 0 is the source itself).
double echoScale(int e);

/// The loader tests' oracle: the centroid, patient LPS [mm], of the source voxels whose
/// stored value exceeds `threshold_stored`, weighted by (value - threshold), each voxel taken
/// at series.voxelLps(i, j, k): only the columns and rows the series kept (subsample), all
/// source slices (dropped ones included, the truth a gap filler approximates).
/// @throws std::runtime_error when no voxel exceeds the threshold.
Eigen::Vector3d landmarkLps(const SourceVolume& source, const WrittenSeries& series,
                            double threshold_stored);

}  // namespace vh::io::test
