#pragma once
/// @file
/// The cohort table: one CSV row of session metrics (session_metrics.h) per recording in a folder,
/// for a research group's studies (`volume-haptics report DIR --table`, pandas, R, a spreadsheet).

#include <cstddef>
#include <filesystem>
#include <functional>

#include "vh/runtime/session_metrics.h"

namespace vh::runtime {

/// How writeCohortTable() writes its table.
struct CohortTableOptions {
  MetricsOptions metrics;
  /// Leave out what identifies the patient: each recording as anonymizeRecording()
  /// (anonymize.h), and the file column (and a label taken from it) "ANONYMIZED <row number>".
  bool anonymize = false;
  /// What the burr removed per material, by the session report's rule
  /// (drillReportOfRecording(): each recording that drilled, drilledDuring(), replayed on its
  /// scene reloaded from its metadata; so is a recording older than format version 5 whose scene
  /// has a drill, as the window's did not say whether they drilled). Adds a column "removed_mm3[<material>]" [mm^3] for every
  /// material any recording's scene has (its HU classes or segments, then "air"), in the order
  /// they are first met. A row gets 0 in each for a recording that removed nothing, empty cells
  /// and a notice saying why for a recording whose removal is not known (its scene cannot be
  /// reloaded, or the replay parts from it), and empty cells for a material its scene lacks.
  /// A replay takes about as long as the recording's drilling did; recordings in a row on the
  /// same scene (the metadata's scene and dataset) share one load of the scan.
  bool drilled_per_material = false;
};

/// Writes the cohort table: one CSV row (RFC 4180) per recording under `dir` (findRecordings()):
/// file (relative to dir), scene, dataset_sha256, label (cohortLabel()), start_time_utc, then
/// every metricValues() key, then with CohortTableOptions::drilled_per_material the columns
/// per material, then "notices" (the recording's warnings joined by "; "). A recording that
/// cannot be read at all still gets a row, with its error in "notices" and empty metrics.
/// `progress(done, total)` is called after each recording (may be empty). Not for the servo
/// thread.
/// @return the number of rows written.
/// @throws std::runtime_error when `dir` cannot be listed or `csv` cannot be written.
std::size_t writeCohortTable(const std::filesystem::path& dir, const std::filesystem::path& csv,
                             const CohortTableOptions& options = {},
                             const std::function<void(std::size_t, std::size_t)>& progress = {});

}  // namespace vh::runtime
