#pragma once
// The session report's table of what the burr removed during a recording, per material
// (session_report.cpp): its HTML.

#include <string>
#include <vector>

#include "vh/runtime/drill_report.h"

namespace vh::ui::detail {

/// What the burr removed during the recording, per material, from a replay of it on its scene
/// (runtime::drillReportOfRecording(), the cohort table's rule too), or why that is not known;
/// neither when nothing was asked for.
using DrilledByMaterial = runtime::RecordingDrillReport;

/// The report's section "Drilled away, per material" (`run`'s rule: drill_report.h): the rows
/// with voxels, critical ones marked, and their sum; or why it is not known, its text scrubbed
/// of `scrub` (runtime::scrubText()); empty when nothing was asked for.
std::string drilledByMaterialSection(const DrilledByMaterial& d, const std::vector<std::string>& scrub);

}  // namespace vh::ui::detail
