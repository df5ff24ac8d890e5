#pragma once
/// @file
/// Loading volumes (DICOM series, NRRD, MetaImage, NIfTI) and tool meshes (STL, OBJ, PLY) through VTK.
/// Units are converted once, here, into metres; values stay in the data's units (HU for CT),
/// except PET in Bq/ml, which becomes SUV (body weight).

#include <atomic>
#include <filesystem>
#include <functional>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "vh/haptics/scalar_volume.h"
#include "vh/haptics/triangle_mesh.h"

class vtkImageData;

namespace vh::io {

/// The voxels for rendering: a vtkImageData shared without VTK in the public headers (the
/// layers above io, e.g. runtime, stay free of VTK). It holds one VTK reference (shareImage()).
using ImagePtr = std::shared_ptr<vtkImageData>;

/// Shares `image` (null gives null): takes a VTK reference, released when the last ImagePtr goes.
ImagePtr shareImage(vtkImageData* image);

/// A load failed. what() names the file and the problem, e.g.
/// "/data/x.nrrd: truncated: expected 8388608 bytes of voxel data, found 1000".
class LoadError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// The load was cancelled through VolumeLoadOptions::cancel; nothing was loaded.
class LoadCancelled : public LoadError {
 public:
  using LoadError::LoadError;
};

/// Where a volume file is read (the name is historical: DICOM, NRRD and MetaImage
/// alike). vtk-dicom's parser and VTK's NRRD and MetaImage readers have crashed on damaged
/// files; in the reader process (the `volume-haptics-dicom-worker` program, see reader_process.h)
/// such a crash ends that process and the load fails with a LoadError naming the file.
enum class DicomIsolation {
  kAuto,       ///< In the reader process when its program is found, else in this process (with a notice).
  kWorker,     ///< Only in the reader process; a LoadError when its program is missing.
  kInProcess,  ///< In this process (the reader process itself; tests of the reading code).
};

/// How loadVolume() picks and reads a volume. The series and phase apply to DICOM only.
struct VolumeLoadOptions {
  /// Which series of a DICOM folder: empty = the largest series that loads (a series that
  /// fails is skipped, with a notice); else a Series Number ("3"), a Series Instance UID, or
  /// text found in the Series Description (case-insensitive, e.g. "bone"), in that order.
  std::string dicom_series;
  /// A 4-D series (cardiac phases, dynamic frames, echoes): which time point, 0-based.
  int dicom_phase = 0;
  /// A 4-D layered NRRD (3D Slicer's .seg.nrrd with overlapping segments: "kinds: list domain
  /// domain domain"): which layer, 0-based. Ignored by the other formats.
  int nrrd_layer = 0;
  /// When set, called with the fraction done (0..1) from the loading thread.
  std::function<void(double fraction)> progress;
  /// When set and it becomes true, the load stops and throws LoadCancelled.
  const std::atomic<bool>* cancel = nullptr;
  DicomIsolation dicom_isolation = DicomIsolation::kAuto;
  /// Watchdog of the reader process [s]: a reader that reports nothing (no progress line) for
  /// this long is killed and the load fails with a LoadError naming the file ("the reader
  /// stopped responding"): a reader stuck on a damaged file (vtkmetaio's `MET_Read` loops
  /// forever on some headers) must not hang the program. Readers that report no progress while
  /// reading one file (NRRD, MetaImage, meshes) get 1 s more per 8 MiB of that file. 0 = no
  /// watchdog. Ignored in process (DicomIsolation::kInProcess or no reader program).
  double worker_stall_timeout_s = 60.0;
};

/// Descriptive facts about a loaded volume, for the UI and session metadata.
struct VolumeInfo {
  std::filesystem::path source;  ///< File or folder loaded.
  std::string format;            ///< "DICOM", "NRRD", "MetaImage", "NIfTI-1", "NIfTI-2".
  std::string modality;          ///< "CT", "MR", ... or empty.
  /// "HU" for CT; "SUVbw" for PET in SUV (body weight), "Bq/ml" for PET in Bq/ml whose header
  /// lacks what SUV needs (a notice names it); else empty.
  std::string value_unit;
  std::string description;       ///< Series description or file name.
  std::string patient_name;      ///< DICOM patient name, or empty.
  std::string series_uid;        ///< DICOM Series Instance UID, or empty.
  std::string frame_of_reference_uid;  ///< DICOM Frame of Reference UID, or empty.
  int series_number = 0;         ///< DICOM Series Number, 0 when absent.
  int phase = 0;                 ///< The time point loaded of a 4-D series (0-based).
  int phase_count = 1;           ///< Time points (phases, echoes) of the series; 1 when 3-D.
  /// What the loader chose or corrected, one sentence each, for the status bar, the console
  /// and the recording's metadata: "resampled from a gantry tilt of 18.5 deg", a gap's slice
  /// positions, dropped duplicates, which series of a folder was taken.
  std::vector<std::string> notices;
};

/// A loaded volume: the haptic field and the same voxels as a vtkImageData for rendering.
/// Both describe the same world frame W [m]: `image` has spacing and origin in metres and no
/// direction; the renderer applies `field->geometry().direction_W` about the origin
/// (p_W = origin + D * (p_image - origin)). When the field holds data units (value scale 1,
/// offset 0: every loaded CT whose HU fit int16), `image`'s scalars are the field's own buffer
/// (imageFromField() of the shared field): one copy of the voxels for the hand and the picture.
/// The smallest voxel side loadVolume() accepts [m]: 1 um (the finest micro-CT).
inline constexpr double kMinVoxelSide_m = 1e-6;

struct LoadedVolume {
  std::shared_ptr<const haptics::ScalarVolume> field;
  ImagePtr image;  ///< Scalars in data units (rescaled), metres; read only (may be the field's).
  VolumeInfo info;
};

/// Loads a DICOM folder (or one file of a series, or a DICOMDIR), a NRRD (.nrrd/.nhdr), a
/// MetaImage (.mha/.mhd) or a NIfTI-1 / NIfTI-2 (.nii, .nii.gz, .hdr/.img pair). DICOM: the series `options` names, else the largest that loads
/// (sorted by position, rescaled to HU, oriented from Image Orientation (Patient)); exact
/// duplicate slices are dropped, and a sheared stack (gantry tilt) or one with missing slices
/// or uneven spacing is resampled onto a rectilinear grid in the image planes' frame with the
/// median slice spacing (bilinear in plane, linear between slices); VolumeInfo::notices says
/// what was done. PET (Modality PT) in Bq/ml is scaled to SUVbw = Bq/ml * PatientWeight [kg] *
/// 1000 / injected dose [Bq] decayed to the images' decay-correction time (QIBA vendor-neutral
/// SUV pseudo-code; DICOM PS3.3 C.8.9.1), with a notice giving the factor, or why not.
/// @throws LoadError naming the file and the problem: missing path, not a volume, corrupt or
///         truncated file, inconsistent slices, no series matching options.dicom_series, a
///         phase out of range; LoadCancelled when options.cancel was set.
/// Geometry: W is the file's patient frame (DICOM / NRRD patient LPS; NRRD RAS/LAS converted to
/// LPS) in metres; lengths without units are millimetres. NIfTI (RAS+, converted to LPS): the
/// sform when sform_code > 0 (a sheared sform gives way to the qform when there is one), else
/// the qform when qform_code > 0, else pixdim alone, as nibabel and ITK; the unit from
/// xyzt_units; scl_slope / scl_inter applied as the field's value scale; a 4-D file's first
/// volume, with a notice. Voxels are kept as stored (uint8,
/// int16, uint16, float32; other types converted to int16 / uint16 when their range fits, else
/// float32), except that a uniform integer DICOM rescale whose values fit int16 (a CT's
/// RescaleIntercept, e.g. uint16 stored + -1024) is applied once: the field then holds int16
/// data units (HU) and the image shares its buffer. Other rescales (fractional, out of int16's
/// range) stay the field's value_scale / value_offset, with a rescaled copy for the image.
/// VTK's own error text during the load becomes the LoadError instead of console output.
/// A voxel side below kMinVoxelSide_m is refused (LoadError): no scanner makes one, and every
/// step that walks the volume in voxels would run for hours.
/// May be called from any thread (one load per thread at a time).
LoadedVolume loadVolume(const std::filesystem::path& path, const VolumeLoadOptions& options = {});

/// Loads a triangle mesh (STL, OBJ, PLY), triangulated, coordinates multiplied by `scale_to_m`.
/// Read in the reader process when it is found (reader_process.h): VTK 9.1's PLY and OBJ readers
/// crash on some damaged files (tests/fuzz/known-crashes), which then becomes a LoadError.
/// @throws LoadError for a missing or unreadable file, a mesh with no triangles, or a reader
///         crash.
haptics::TriangleMesh loadMesh(const std::filesystem::path& path, double scale_to_m = 1.0);

/// A vtkImageData (metres, no direction) with a copy of the voxels of a field, in data units
/// (int16 for an integer rescale that fits it, else float32 when the field has a rescale).
ImagePtr imageFromField(const haptics::ScalarVolume& field);

/// The same image over a shared field, without a copy where VTK allows: when the field holds
/// data units (valueScale() 1, valueOffset() 0), the image's scalars are the field's own voxel
/// buffer (a VTK array that does not own it; the field stays alive while any VTK array wraps it,
/// after its other holders are gone), so GetScalarPointer() is field->bytes().data(). Never
/// write through such an image: the haptic thread reads the same voxels (carve a DeepCopy).
/// Otherwise (a rescale, an empty or null field) as imageFromField(*field).
ImagePtr imageFromField(const std::shared_ptr<const haptics::ScalarVolume>& field);

/// Name filter for a Qt file dialog that opens volumes, e.g.
/// "Volumes (*.nrrd *.nhdr *.mha *.mhd *.dcm);;...". A DICOM series is opened by folder or by
/// any one of its files.
std::string volumeFileDialogFilter();

/// Name filter for a Qt file dialog that opens tool meshes (STL, OBJ, PLY).
std::string meshFileDialogFilter();

}  // namespace vh::io
