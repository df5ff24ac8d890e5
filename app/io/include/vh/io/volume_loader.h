#pragma once
/// @file
/// Loading volumes (DICOM series, NRRD, MetaImage) and tool meshes (STL, OBJ, PLY) through VTK.
/// Units are converted once, here, into metres; values stay in the data's units (HU for CT).

#include <filesystem>
#include <memory>
#include <stdexcept>
#include <string>

#include <vtkSmartPointer.h>

#include "vh/haptics/scalar_volume.h"
#include "vh/haptics/triangle_mesh.h"

class vtkImageData;

namespace vh::io {

/// A load failed. what() names the file and the problem, e.g.
/// "/data/x.nrrd: truncated: expected 8388608 bytes of voxel data, found 1000".
class LoadError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Descriptive facts about a loaded volume, for the UI and session metadata.
struct VolumeInfo {
  std::filesystem::path source;  ///< File or folder loaded.
  std::string format;            ///< "DICOM", "NRRD", "MetaImage".
  std::string modality;          ///< "CT", "MR", ... or empty.
  std::string value_unit;        ///< "HU" for CT, else empty.
  std::string description;       ///< Series description or file name.
  std::string patient_name;      ///< DICOM patient name, or empty.
};

/// A loaded volume: the haptic field and the same voxels as a vtkImageData for rendering.
/// Both describe the same world frame W [m]: `image` has spacing and origin in metres and no
/// direction; the renderer applies `field->geometry().direction_W` about the origin
/// (p_W = origin + D * (p_image - origin)).
struct LoadedVolume {
  std::shared_ptr<const haptics::ScalarVolume> field;
  vtkSmartPointer<vtkImageData> image;  ///< Scalars in data units (rescaled), metres.
  VolumeInfo info;
};

/// Loads a DICOM folder (or one file of a series), a NRRD (.nrrd/.nhdr) or a MetaImage
/// (.mha/.mhd). DICOM: the largest series in the folder is read (sorted by position, rescaled
/// to HU, oriented from Image Orientation (Patient)).
/// @throws LoadError naming the file and the problem: missing path, not a volume, corrupt or
///         truncated file, inconsistent slices.
LoadedVolume loadVolume(const std::filesystem::path& path);

/// Loads a triangle mesh (STL, OBJ, PLY), triangulated, coordinates multiplied by `scale_to_m`.
/// @throws LoadError for a missing or unreadable file, or a mesh with no triangles.
haptics::TriangleMesh loadMesh(const std::filesystem::path& path, double scale_to_m = 1.0);

/// A vtkImageData (metres, no direction) over the voxels of a field, e.g. for synthetic
/// volumes; values in data units.
vtkSmartPointer<vtkImageData> imageFromField(const haptics::ScalarVolume& field);

}  // namespace vh::io
