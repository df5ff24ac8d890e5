#pragma once
/// @file
/// `--anonymize` for exports and reports: removes or replaces what identifies a patient in a
/// recording's session metadata (makeSessionMetadata()) and in the reader's warnings, following
/// DICOM PS3.15 Annex E, the Basic Application Level Confidentiality Profile, for the fields a
/// recording keeps:
///
/// | metadata field | DICOM attribute (Annex E action) | --anonymize |
/// |---|---|---|
/// | dataset.series_uid, scene.volume.series | Series Instance UID (U) | a "2.25." UID derived from the original's SHA-256: stable (the same series gives the same UID), unknown to any PACS |
/// | dataset.description | Series Description (X) | removed |
/// | start_time_utc | Study / Series / Acquisition Date and Time (X, Z, D) | removed |
/// | scene.source, scene.volume.path, dataset.path, scene.segmentation.path | (file and folder names, often a patient's name, ID or date) | "ANONYMIZED" |
/// | dataset.checksum_files | (file names) | removed (the SHA-256 stays) |
/// | dataset.notices, the reader's warnings | (free text naming files) | every removed name and path part replaced by "ANONYMIZED" |
///
/// The DICOM Patient Name, Patient ID, Birth Date, Institution and Accession Number are never
/// in a recording. Left as they are: the dataset's SHA-256, the scan's geometry, the segment
/// names, the device, and what the user typed (the "note"/"user" and marker labels).
/// The metadata gains "anonymized": {"profile", "removed", "replaced"} saying what was done.

#include <filesystem>
#include <string>
#include <vector>

#include "vh/runtime/recording.h"
#include "vh/runtime/runner.h"

namespace vh::runtime {

/// The text that replaces an identifier.
inline constexpr const char* kAnonymized = "ANONYMIZED";

/// A DICOM UID that stands for `uid`: "2.25." and the first 128 bits of SHA-256(uid) in decimal
/// (at most 44 characters; the same `uid` always gives the same result).
std::string anonymizedUid(const std::string& uid);

/// `metadata_json` (a recording's header object) with the fields above removed or replaced;
/// text that is not a JSON object comes back as "{}". `identifiers` (may be null) receives the
/// strings removed or replaced, and each file and folder name of the paths, for scrubText().
std::string anonymizeSessionMetadata(const std::string& metadata_json, std::vector<std::string>* identifiers = nullptr);

/// `path` (as given and made absolute) and each of its file and folder names: what identifies
/// the patient in text that names the path.
std::vector<std::string> pathIdentifiers(const std::filesystem::path& path);

/// `text` with every occurrence of each of `identifiers` (longest first; those under 3
/// characters are left, as they would hit ordinary words) replaced by "ANONYMIZED".
std::string scrubText(std::string text, const std::vector<std::string>& identifiers);

/// Anonymizes `recording` in place: its metadata as anonymizeSessionMetadata(), its warnings
/// scrubbed of the metadata's identifiers and of `recording_path` (the path, its file and
/// folder names). The records and events are left as they are.
/// @return the identifiers removed (for scrubText() of other text about the recording).
std::vector<std::string> anonymizeRecording(Recording& recording, const std::filesystem::path& recording_path = {});

/// `run --anonymize`: `report` (runHeadless()'s) with the scene file's, the volume's and the
/// trajectory's paths "ANONYMIZED" and the volume's notices scrubbed of their file and folder
/// names and of `identifiers` (the caller's: the series description and UID the loader read).
/// The figures are left as they are.
void anonymizeRunReport(RunReport& report, std::vector<std::string> identifiers);

}  // namespace vh::runtime
