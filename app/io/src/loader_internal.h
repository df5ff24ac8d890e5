#pragma once
/// @file
/// Pieces shared by the format loaders of vh::io. Private to the library.

#include <array>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <Eigen/Core>
#include <vtkSmartPointer.h>

#include "vh/haptics/scalar_volume.h"
#include "vh/io/dicom_series.h"
#include "vh/io/volume_loader.h"

class vtkImageData;

namespace vh::io::detail {

namespace fs = std::filesystem;

/// Throws LoadError("<path>: <problem>").
[[noreturn]] void fail(const fs::path& path, const std::string& problem);

/// A volume as a reader produced it, before conversion into the field's voxel types: either a
/// reader's vtkImageData (`image`), or voxels already in a field voxel type (`voxels`, taken
/// back from the reader process), which become the field's own without a copy.
struct RawVolume {
  vtkSmartPointer<vtkImageData> image;  ///< Reader output; its spacing and origin are ignored.
  /// When `image` is null: the voxels (x fastest; geometry.dims.prod() of `voxel_type`).
  std::vector<std::byte> voxels;
  haptics::VoxelType voxel_type = haptics::VoxelType::kInt16;
  haptics::VolumeGeometry geometry;     ///< Geometry in W [m]; dims are `image`'s when it is set.
  double value_scale = 1.0;             ///< F = value_scale * stored + value_offset.
  double value_offset = 0.0;
  VolumeInfo info;
};

/// Validates `raw` (dimensions, one scalar component, voxel count), makes the voxels a
/// ScalarVolume (keeping uint8 / int16 / uint16 / float32 as stored, converting other types;
/// an integer rescale whose values fit int16, a CT's RescaleIntercept, is applied once, so the
/// field holds data units) and builds the rendering image (metres, data units): the field's own
/// buffer when the field holds data units (imageFromField()), so one copy of the voxels serves
/// the hand and the picture. `raw`'s image is released as soon as its voxels are converted.
/// @throws LoadError naming `path`.
LoadedVolume finishVolume(RawVolume raw, const fs::path& path);

/// The field voxel type that stores a VTK scalar type (VTK_UNSIGNED_CHAR, VTK_SHORT,
/// VTK_UNSIGNED_SHORT, VTK_FLOAT) as is; nullopt for the others (converted by finishVolume()).
std::optional<haptics::VoxelType> fieldVoxelTypeOf(int vtk_type);

/// Folder levels a DICOM folder is scanned to: a DICOMDIR tree (DICOM/PA0/ST0/SE0/IM0) is four.
inline constexpr int kDicomScanDepth = 4;

/// Format loaders. `path` exists; each throws LoadError naming the file and the problem.
/// loadDicom() reads in the reader process when one is available (isolated_load.cpp: a parser
/// crash cannot take the application down), else in this process through loadDicomRaw().
LoadedVolume loadDicom(const fs::path& path, const VolumeLoadOptions& options);
/// loadMesh() in this process (the reader process's "mesh" mode; VTK's mesh readers crash on some damaged
/// files: see tests/fuzz/known-crashes).
haptics::TriangleMesh loadMeshInProcess(const fs::path& path, double scale_to_m);

/// listDicomSeries() in this process (the reader process's "list" mode; see dicom_series.h).
std::vector<DicomSeriesInfo> listDicomSeriesInProcess(const fs::path& folder,
                                                      const std::function<void(int, int)>& progress,
                                                      const std::atomic<bool>* cancel);

/// A NRRD or MetaImage read in the reader process when it is found (VTK's readers crash or hang
/// on some damaged files: tests/fuzz/known-crashes), else `in_process()`.
LoadedVolume loadFileIsolated(const fs::path& path, const VolumeLoadOptions& options,
                              const std::function<LoadedVolume()>& in_process);

/// The DICOM read itself, in this process: the series chosen, regularised, not yet converted.
RawVolume loadDicomRaw(const fs::path& path, const VolumeLoadOptions& options);
/// `layer`: which layer of a 4-D layered NRRD (3D Slicer's .seg.nrrd with overlapping
/// segments); 0 for a 3-D NRRD.
LoadedVolume loadNrrd(const fs::path& path, int layer = 0);
/// The "key:=value" pairs of a NRRD header (keys as written), e.g. 3D Slicer's
/// "Segment0_Name" -> "tumour". Reads the header only (the project's own parser, fuzzed with
/// the NRRD target).
/// @throws LoadError naming the file for a missing file or a malformed header.
std::map<std::string, std::string> readNrrdKeyValues(const fs::path& path);
LoadedVolume loadMetaImage(const fs::path& path);

/// Display colour n of the segments that name none (a qualitative palette, repeating), each in
/// 0..1.
std::array<double, 3> segmentPaletteColour(std::size_t n);

// --- small text and geometry helpers -------------------------------------------------------

std::string trim(std::string_view s);
std::string toLower(std::string_view s);
/// Splits on white space.
std::vector<std::string> splitWords(std::string_view s);
/// Parses a finite double; nullopt when `s` is not one.
std::optional<double> parseDouble(std::string_view s);
/// Parses an integer; nullopt when `s` is not one.
std::optional<long long> parseInt(std::string_view s);

/// Bytes in a file, or nullopt when it cannot be stat'ed.
std::optional<std::uintmax_t> fileSize(const fs::path& path);

/// Splits a 3 x 3 matrix whose columns are the grid axes scaled by the voxel size (any length
/// unit) into unit directions and spacings, both returned through the out parameters.
/// @throws LoadError naming `path` when an axis has zero length or the axes are not orthogonal
///         (sheared grids are not supported).
void splitAxes(const Eigen::Matrix3d& axes, const fs::path& path, Eigen::Matrix3d& direction_W,
               Eigen::Vector3d& spacing);

/// Factor from a length unit name ("mm", "m", "cm", "um", "micron", "µm") to metres; nullopt
/// for an unknown name. An empty name means millimetres.
std::optional<double> lengthUnitToMetres(std::string_view unit);

/// "64x64x93"
std::string dimsString(const std::array<int, 3>& dims);

}  // namespace vh::io::detail
