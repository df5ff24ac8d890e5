#pragma once
/// @file
/// A session recording as one HDF5 file (`volume-haptics export --hdf5`,
/// `volume_haptics.Recording.to_hdf5()`), for h5py, pandas, MATLAB and the rest of the
/// surgical-data world without this program, and read back by readRecording() (which recognises
/// the HDF5 signature), so `report`, `export` and the replay take either file.
///
/// Layout (layout version kRecordingHdf5LayoutVersion; docs/python.md shows it with h5py):
///
///   /                   attributes: vh_format "VolumeHaptics recording", vh_layout_version,
///                       recording_format_version (the .vhrec's), chunks, event_chunks,
///                       dropped_records, bytes_ignored, damaged_regions, ended, end_status
///   /metadata           scalar string: the recording's metadata JSON object, verbatim
///   /scene              scalar string: metadata["scene"] as JSON (absent when it has none)
///   /warnings           (W,) strings: the read-back warnings of the source (damage, an unfinished tail)
///   /ticks/<column>     (N,) one dataset per `export --csv` column, in its order (t_s, tick,
///                       device_x_m, ...): float64, except tick uint64, contacts, flags and
///                       removed_voxels uint32, critical_segment int32, deadline_work int64;
///                       attributes unit (SI: "s", "m", "N", "N*m", "1", "data units") and
///                       description; chunked and deflate-compressed
///   /events/t_s, tick, type, detail_json   (E,) one row per event, in order
///   /markers/t_s, tick, label              (M,) the "marker" events with their labels
///   /volume/scan        optional: the scan's voxels as felt (data units), shape (nx, ny, nz)
///                       indexed [i, j, k] in h5py / NumPy (MATLAB's h5read gives [k, j, i]);
///                       float32 when every value is exact in it, else float64; compressed;
///                       attributes affine_LPS_m (4 x 4: index -> patient LPS [m], voxel centres
///                       at integer indices), isovalue, unit
///   /volume/drilled     optional, with a drill: the felt field as the replay carved it at the
///                       recording's end, same shape, type and attributes as /volume/scan
///
/// Strings are variable-length UTF-8. Every value the .vhrec's records hold is stored exactly,
/// so an HDF5 file read back equals the recording it was written from, record for record.

#include <filesystem>
#include <memory>

#include "vh/haptics/scalar_volume.h"
#include "vh/runtime/recording.h"

namespace vh::runtime {

inline constexpr int kRecordingHdf5LayoutVersion = 1;

/// What /volume holds (both optional; null: left out).
struct RecordingHdf5Volumes {
  const haptics::ScalarVolume* scan = nullptr;     ///< The scan as felt (the scene's volume).
  const haptics::ScalarVolume* drilled = nullptr;  ///< The drilled field at the end (same grid).
};

/// Whether `path` starts with the HDF5 signature (bytes 89 48 44 46 0d 0a 1a 0a). False when it
/// cannot be read.
bool isHdf5File(const std::filesystem::path& path);

/// Writes `recording` (and `volumes`) to `path` in the layout above, through io::PrivateOutput
/// (0600, renamed into place only when whole: a failed write leaves no file that looks whole).
/// @throws std::runtime_error "cannot write PATH: ..." for a target that is not a regular file
///         or a new name (HDF5 needs a file it can seek: not "-" nor a device), a full disk or
///         any HDF5 failure; std::invalid_argument when the two volumes' grids differ.
void writeRecordingHdf5(const Recording& recording, const std::filesystem::path& path,
                        const RecordingHdf5Volumes& volumes = {});

/// writeRecordingHdf5() with /volume/scan from the scene `recording` was made on (loaded from
/// `scene_metadata_json`, the recording's own metadata when empty, e.g. the original of an
/// anonymized copy: the dataset where it says, with the recorded checksum) and, with a drill,
/// /volume/drilled from a replay of it (replayRecording()). Not for the servo thread.
/// @return "" or, when the replay parts from the recording, why (replayDifference()): the
///         drilled field is then left out, and the file written without it.
/// @throws std::runtime_error as sceneFromSessionMetadata() (dataset missing or changed, a
///         recording of an array volume, which names no file), loadScene() and writeRecordingHdf5().
std::string writeRecordingHdf5WithVolume(const Recording& recording, const std::filesystem::path& path,
                                         const std::string& scene_metadata_json = {});

/// Reads a recording written by writeRecordingHdf5() (readRecording() calls it for an HDF5
/// file). The volumes are not read.
/// @throws std::runtime_error naming the file for one that HDF5 cannot open, that is not a
///         VolumeHaptics recording, has a newer layout, or lacks or mis-sizes a column.
Recording readRecordingHdf5(const std::filesystem::path& path);

}  // namespace vh::runtime
