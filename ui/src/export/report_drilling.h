#pragma once
// The session report's table of what the burr removed during a recording, per material
// (session_report.cpp): whether to ask for it, the replay that gives it, and its HTML.

#include <optional>
#include <string>
#include <vector>

#include "vh/runtime/drill_report.h"
#include "vh/runtime/recording.h"
#include "vh/runtime/scene.h"

namespace vh::ui::detail {

/// What the burr removed during the recording, per material, from a replay of it on its scene.
struct DrilledByMaterial {
  std::optional<runtime::DrillReport> report;  ///< Empty when not replayed (see why).
  std::string why;                             ///< Why there is no report (empty: none was asked for).
};

/// Whether the recording's burr removed anything (format version 5 on: its records'
/// removed_voxels; older: a "drilled" event).
bool drilledDuring(const runtime::Recording& rec);

/// `rec` replayed on `scene` (the scene it was recorded on, reloaded from its metadata) for
/// what its burr removed per material (runtime::ReplayComparison::drill); a replay that differs
/// from the recording, or fails, gives no report and says why (where it parted). Off the GUI
/// thread: as long as the recording's drilling. The replay's errors become `why`.
DrilledByMaterial drilledByMaterialOf(const runtime::LoadedScene& scene, const runtime::Recording& rec);

/// The report's section "Drilled away, per material" (`run`'s rule: drill_report.h): the rows
/// with voxels, critical ones marked, and their sum; or why it is not known, its text scrubbed
/// of `scrub` (runtime::scrubText()); empty when nothing was asked for.
std::string drilledByMaterialSection(const DrilledByMaterial& d, const std::vector<std::string>& scrub);

}  // namespace vh::ui::detail
