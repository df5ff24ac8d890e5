// What a drill removed, per material (drill_report.h).

#include "vh/runtime/drill_report.h"

#include <algorithm>
#include <cstddef>
#include <exception>
#include <vector>

#include "vh/runtime/default_isovalue.h"
#include "vh/runtime/replay.h"
#include "vh/runtime/sha256.h"

namespace vh::runtime {

DrillReport drillReportOf(const Drill& drill, const LoadedScene& scene) {
  DrillReport d;
  const haptics::MaterialRemoval& removal = drill.removal();
  d.burr_radius_m = drill.burr().radius_m;
  d.removed_mm3 = drill.removed_mm3();
  d.eroded_mm3 = removal.erodedVolume_mm3();
  Sha256 sha;
  sha.update(removal.volume().bytes().data(), removal.volume().bytes().size());
  d.drilled_field_sha256 = sha.hexDigest();
  // Which removed voxels lay below the felt isovalue: the carved field against the felt field
  // as loaded (the drill carves a copy), the cavity the run began with left out.
  // Of a CT's HU classes, the removed voxels that were air in the scan (below kAirBelow_HU: the
  // partial volume at the skin and in the sinuses, which the burr's reach takes at soft tissue's
  // hardness) are reported as air, not as the class that charged them.
  const std::size_t material_count = removal.materials().size();
  std::vector<std::uint64_t> below(material_count, 0), air(material_count, 0), air_below(material_count, 0);
  const haptics::ScalarVolume& carved = removal.volume();
  const haptics::ScalarVolume* felt = scene.hapticField().get();
  const haptics::ScalarVolume* scan = scene.volume.field.get();
  const bool split_air = scan != nullptr && inHounsfieldUnits(scene.volume) && scan->geometry().sameGridAs(carved.geometry());
  if (felt != nullptr && felt->geometry().sameGridAs(carved.geometry())) {
    std::vector<bool> at_start;
    if (const auto& cavity = drill.cavityAtStart(); cavity != nullptr) {
      at_start.assign(carved.geometry().voxelCount(), false);
      for (const std::uint64_t v : cavity->voxels)
        if (v < at_start.size()) at_start[v] = true;
    }
    const double lowest = carved.lowestRaw(), isovalue = scene.hapticIsovalue();
    for (std::size_t i = 0; i < carved.geometry().voxelCount(); ++i) {
      if (carved.rawAt(i) != lowest || felt->rawAt(i) == lowest || (!at_start.empty() && at_start[i])) continue;
      const auto m = static_cast<std::size_t>(removal.materialOf(i));
      const bool is_below = felt->valueScale() * felt->rawAt(i) + felt->valueOffset() < isovalue;
      below[m] += is_below;
      if (split_air && drill.segmentOfMaterial(static_cast<int>(m)) < 0 &&
          scan->valueScale() * scan->rawAt(i) + scan->valueOffset() < kAirBelow_HU) {
        ++air[m];
        air_below[m] += is_below;
      }
    }
  }
  DrillReport::Material air_row;
  air_row.name = "air";
  for (std::size_t m = 0; m < material_count; ++m) {
    const auto& material = removal.materials()[m];
    DrillReport::Material row;
    row.name = material.name;
    row.segment = drill.segmentOfMaterial(static_cast<int>(m)) >= 0 && scene.segments ? material.name : "";
    row.critical = material.critical;
    const std::uint64_t removed = removal.removedVoxels(static_cast<int>(m));
    const std::uint64_t as_air = std::min(air[m], removed);
    row.voxels = removed - as_air;
    row.removed_mm3 = static_cast<double>(row.voxels) * removal.voxelVolume_mm3();
    row.voxels_below_surface = std::min(below[m] - air_below[m], row.voxels);  // air_below[m] <= below[m]
    row.below_surface_mm3 = static_cast<double>(row.voxels_below_surface) * removal.voxelVolume_mm3();
    row.specific_energy_J_per_mm3 = material.specific_energy_J_per_mm3;
    d.materials.push_back(row);
    if (as_air > 0) {
      air_row.voxels += as_air;
      air_row.voxels_below_surface += std::min(air_below[m], as_air);
      air_row.specific_energy_J_per_mm3 = material.specific_energy_J_per_mm3;  // what it was charged at
    }
  }
  if (air_row.voxels > 0) {
    air_row.removed_mm3 = static_cast<double>(air_row.voxels) * removal.voxelVolume_mm3();
    air_row.below_surface_mm3 = static_cast<double>(air_row.voxels_below_surface) * removal.voxelVolume_mm3();
    d.materials.push_back(air_row);
  }
  return d;
}

bool drilledDuring(const Recording& recording) {
  if (recording.version >= 5)
    return std::any_of(recording.records.begin(), recording.records.end(),
                       [](const TickRecord& r) { return r.removed_voxels > 0; });
  return std::any_of(recording.events.begin(), recording.events.end(),
                     [](const RecordingEvent& e) { return e.type == "drilled"; });
}

RecordingDrillReport drillReportOfRecording(const LoadedScene& scene, const Recording& recording) {
  RecordingDrillReport drilled;
  try {
    const ReplayComparison replay = replayRecording(scene, recording);
    if (!replay.identical) drilled.why = replayDifference(replay, recording);
    else if (!replay.drill) drilled.why = "the reloaded scene has no drill";
    else drilled.report = replay.drill;
  } catch (const std::exception& e) {
    drilled.why = std::string("the replay failed (") + e.what() + ")";
  }
  return drilled;
}

}  // namespace vh::runtime
