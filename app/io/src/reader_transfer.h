#pragma once
/// @file
/// What the reader process hands back to the application through its output file, written in
/// the reader process and read in the application. Private to vh::io.
///
/// Volume files ("load" and "volume" modes): "VHRAW1\n", the length of a JSON header as 8 bytes
/// (native byte order: both ends are the same program build), the header (geometry in W [m],
/// value scale and offset, VolumeInfo, the voxel type), then the voxels as stored.
/// Series lists ("list"): a JSON array of DicomSeriesInfo. Meshes ("mesh"): the vertex and
/// triangle counts (uint64 each), the vertices (3 doubles each, [m]), the triangles (3 ints).
/// DICOM SEGs ("seg"): the header (the SEG's UIDs, segments, and each frame's segment and plane),
/// then each frame's packed inside pixels (DicomSegFrame::mask), frame after frame.
/// RT Structure Sets ("rtstruct"): the header alone (UIDs, ROIs, contour points in LPS mm).

#include <filesystem>
#include <vector>

#include "dicom_rtstruct_internal.h"
#include "dicom_seg_internal.h"
#include "loader_internal.h"
#include "vh/haptics/scalar_volume.h"
#include "vh/io/dicom_series.h"
#include "vh/io/volume_loader.h"

namespace vh::io::detail {

/// Writes a loaded field (NRRD, MetaImage: converted voxels) with `info` to `out`.
/// @throws LoadError naming `out` when it cannot be written.
void writeField(const haptics::ScalarVolume& field, const VolumeInfo& info, const fs::path& out);
/// Reads what writeField() wrote to `in`; info.source is `source`.
/// @throws LoadError naming `source` when `in` is unreadable, cut short or invalid.
LoadedVolume readField(const fs::path& in, const fs::path& source);

/// Writes a DICOM read as the reader produced it (not yet converted) to `out`.
/// @throws LoadError naming `out` when `raw` has no voxels or `out` cannot be written.
void writeRaw(const RawVolume& raw, const fs::path& out);
/// Reads what writeRaw() wrote to `in`.
/// @throws LoadError naming `source` when `in` is unreadable or cut short.
RawVolume readRaw(const fs::path& in, const fs::path& source);

/// Writes a series list to `out` as JSON (no error check: a missing list fails to parse).
void writeSeriesList(const std::vector<DicomSeriesInfo>& series, const fs::path& out);
/// Reads what writeSeriesList() wrote to `in`.
/// @throws LoadError naming `source` when `in` is unreadable.
std::vector<DicomSeriesInfo> readSeriesList(const fs::path& in, const fs::path& source);

/// Writes a tool mesh (vertices in T [m]) to `out`.
/// @throws LoadError naming `source` when `out` cannot be written.
void writeMesh(const haptics::TriangleMesh& mesh, const fs::path& out, const fs::path& source);
/// Reads what writeMesh() wrote to `in`, checking counts and triangle indices.
/// @throws LoadError naming `source` when `in` is unreadable, cut short or inconsistent.
haptics::TriangleMesh readMesh(const fs::path& in, const fs::path& source);

/// Writes a DICOM SEG as read (dicom_seg_internal.h) to `out`.
/// @throws LoadError naming `out` when it cannot be written.
void writeDicomSeg(const DicomSegFile& seg, const fs::path& out);
/// Reads what writeDicomSeg() wrote to `in`.
/// @throws LoadError naming `source` when `in` is unreadable, cut short or invalid.
DicomSegFile readDicomSegTransfer(const fs::path& in, const fs::path& source);

/// Writes an RT Structure Set as read (dicom_rtstruct_internal.h) to `out`.
/// @throws LoadError naming `out` when it cannot be written.
void writeDicomRtStruct(const RtStructFile& rs, const fs::path& out);
/// Reads what writeDicomRtStruct() wrote to `in`.
/// @throws LoadError naming `source` when `in` is unreadable, cut short or invalid.
RtStructFile readDicomRtStructTransfer(const fs::path& in, const fs::path& source);

}  // namespace vh::io::detail
