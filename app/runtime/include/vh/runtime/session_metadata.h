#pragma once
/// @file
/// Session metadata for recordings (the JSON object in a .vhrec header, recording.h): what the
/// session ran on, enough to reload the scene and to tell whether the dataset on disk is the one
/// that was recorded.
///
/// Layout (keys; all lengths in metres, gains in SI units):
/// {
///   "format": "volume-haptics session", "software": {"name": "volume-haptics", "version": "0.1.0"},
///   "start_time_utc": "2026-11-21T18:00:00Z", "servo_rate_Hz": 1000,
///   "scene": {"source": "/abs/scene.json" or "",
///             "volume": {"path": "/abs/ct/folder" or "builtin:sphere", "isovalue": 400},
///             "tool": {"mesh": "/abs/drill.stl" or "builtin:probe", "scale_to_m": 0.00044,
///                      "point_spacing_m": 0.001, "point_count": 0,
///                      "initial_pose": {"p_m": [x, y, z], "q_wxyz": [w, x, y, z]}},
///             "coupling": {"linear_N_per_m": 2000, "angular_Nm_per_rad": 2,
///                          "passivity_control": false},
///             "drill": {"on": true, "burr_speed_rpm": 80000, "hardness": {...},  // with a drill
///                       "cavity": {"dims", "origin_W_m", "spacing_m", "direction_W" (row by row),
///                                  "runs": [first, count, ...]}}},  // drilled before the start
///   "dataset": {"path": ..., "kind": "dicom-folder" | "nrrd" | "metaimage" | "file" | "builtin",
///               "dims": [nx, ny, nz], "spacing_m": [sx, sy, sz], "value_unit": ...,
///               "sha256": "hex", "checksum_files": ["I10", ...] (the files the checksum covers)},
///   "tool": {"mesh": ..., "point_count": N, "point_spacing_m": mean nearest-neighbour spacing},
///   "device": {"name": ..., "kind": ...}, "note": ...
/// }
/// The isovalue is the live value when the recording started (resolved, never "unset"); the
/// initial pose is the proxy pose the recording's haptic threads started from (the GUI rebuilds
/// threads that had already run there: Session::prepareRecording()), so a reloaded scene starts
/// exactly where the recorded one did (doubles round-trip bit for bit). So does a drilled cavity (LiveValues::drill->cavity: the felt field's
/// voxels removed before the haptic threads were built or last stopped, as runs of linear
/// indices on its grid): the replay's drill starts from it, as the session's did.
///
/// Dataset checksum (SHA-256, own implementation in sha256.h: no dependency provides one):
///   - a file: SHA-256 of its bytes; a NRRD with detached data (.nhdr) or a MetaImage header
///     (.mhd): SHA-256 of the lines "<sha256 of file>  <file name>\n" for the header, then each
///     data file it names (in the header's order);
///   - a folder (DICOM series): SHA-256 of the lines "<sha256>  <relative path>\n" over every
///     regular file under it, sorted by relative path (byte order), i.e. the digest of
///     `find . -type f | sed 's|^\./||' | LC_ALL=C sort | xargs sha256sum`;
///   - a built-in volume: SHA-256 of its name ("builtin:sphere"; built-ins have no parameters
///     beyond their name and the software version, which is stored too).
/// Hashing a folder reads every byte (about 70 MB for the CT phantom, under a second); the
/// result is cached per path, size and modification time for the process, so a session that
/// starts several recordings hashes it once. Never call these functions on the servo thread.

#include <filesystem>
#include <string>
#include <vector>

#include "vh/runtime/scene.h"

namespace vh::runtime {

/// What makeSessionMetadata() stores about the device and the session.
struct SessionInfo {
  std::string device_name;  ///< Device::name(), e.g. "Novint Falcon 1234".
  std::string device_kind;  ///< "simulated", "scripted", "falcon", "spacemouse", "replay", ...
  std::string note;         ///< Free text (user's note); stored when non-empty.
};

/// A dataset's identity: what the checksum covers and its SHA-256 (hex, lower case).
struct DatasetChecksum {
  std::string kind;                         ///< "dicom-folder", "nrrd", "metaimage", "file", "builtin", "array".
  std::string sha256;                       ///< Hex digest (64 characters).
  std::vector<std::string> files;           ///< Files covered (relative to the folder / header's folder).
};

/// The volume path of a scene whose volume was given as an array (Python's load_scene(): no file);
/// its metadata's dataset checksum is the SHA-256 of the voxels' bytes (kind "array").
inline constexpr const char* kArrayVolumePath = "array";

/// The checksum of a volume path as documented above (cached per path, total size and newest
/// modification time). Any thread but the servo thread; thread-safe.
/// @throws std::runtime_error naming the path when it is missing or a file cannot be read.
DatasetChecksum datasetChecksum(const std::string& volume_path);

/// JSON object text for RecordingWriter's header: scene (enough to reload it: volume path,
/// isovalue, tool (path/builtin, scale, point spacing/count), gains, initial pose), dataset
/// identity (path, kind, dimensions, spacing) and checksum, tool, point-shell spacing and point
/// count, gains, device, software version, start time (UTC ISO-8601), servo rate (1000 Hz; the
/// writer overwrites it with RecordingWriterOptions::servo_rate_Hz).
/// Hashes the dataset (datasetChecksum(): cached); call it off the servo thread.
/// @throws std::runtime_error when the dataset cannot be read for its checksum.
/// `scene` gives what was loaded (the volume's path, series, phase, dataset identity); `live`
/// what was felt (isovalue, tool, initial pose, gains, segments: Session::live() in the GUI).
std::string makeSessionMetadata(const LoadedScene& scene, const LiveValues& live, const SessionInfo& info);
/// makeSessionMetadata() of a scene with the values it was loaded with (headless runs).
inline std::string makeSessionMetadata(const LoadedScene& scene, const SessionInfo& info) {
  return makeSessionMetadata(scene, LiveValues::initial(scene), info);
}

/// The scene a recording was made on (no device section: a recording replays through
/// ReplayDevice, replay.h). Initial pose and isovalue are the recorded ones.
/// @throws std::runtime_error naming the dataset when it is missing, or when its checksum
///         differs from the recorded one (the message says which file/folder and both
///         checksums); std::runtime_error for metadata that is not JSON or lacks the scene.
SceneSpec sceneFromSessionMetadata(const std::string& metadata_json);

/// loadScene() of sceneFromSessionMetadata(metadata_json) without its device and OpenIGTLink
/// sections: the scene a recording was made on, to replay or report it (nothing is opened but
/// the dataset and the tool). Not for the servo thread.
/// @throws as sceneFromSessionMetadata() and loadScene().
LoadedScene loadRecordedScene(const std::string& metadata_json);

}  // namespace vh::runtime
