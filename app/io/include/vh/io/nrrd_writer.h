#pragma once
/// @file
/// Writing a volume as NRRD (the format's version 4: http://teem.sourceforge.net/nrrd/format.html)
/// for 3D Slicer: detached from nothing, one file, raw little-endian voxels, space
/// "left-posterior-superior" with directions and origin in millimetres (the scene frame W is
/// patient LPS in metres, io::loadVolume()). VTK 9.1 reads NRRD but writes none, hence this small
/// writer; what it writes is read back by VTK's vtkNrrdReader and by our loader in the tests.

#include <array>
#include <cstddef>
#include <filesystem>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

namespace vh::io {

/// One volume to write.
struct NrrdVolume {
  std::array<int, 3> dims{0, 0, 0};                          ///< Voxels along i, j, k.
  Eigen::Vector3d spacing_m{1e-3, 1e-3, 1e-3};               ///< Voxel size along i, j, k [m].
  Eigen::Vector3d origin_W_m = Eigen::Vector3d::Zero();      ///< Centre of voxel (0,0,0) in W (LPS) [m].
  Eigen::Matrix3d direction_W = Eigen::Matrix3d::Identity(); ///< Columns: unit i, j, k axes in W.
  /// NRRD type: "uchar", "short", "ushort", "float".
  std::string type = "short";
  const void* voxels = nullptr;                              ///< dims product voxels of `type`, x fastest.
  /// Extra "key:=value" lines (3D Slicer's segment fields, for example).
  std::vector<std::pair<std::string, std::string>> key_values;
};

/// Writes `volume` to `path` (replacing it).
/// @throws std::runtime_error naming the file for an unknown type, bad dimensions, no voxels or a
///         failed write.
void writeNrrd(const std::filesystem::path& path, const NrrdVolume& volume);

}  // namespace vh::io
