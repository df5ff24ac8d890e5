#pragma once
/// @file
/// What a drill removed, per material, by one rule wherever it is shown: `run`'s report (the
/// drill of the run) and a recording's replay (the drill of the replay, which carves what the
/// recording's session carved; the session report's table per material).

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "vh/runtime/drilling.h"
#include "vh/runtime/recording.h"
#include "vh/runtime/scene.h"

namespace vh::runtime {

/// What the drill removed in a run or during a recording (scenes with a "drill" section).
struct DrillReport {
  struct Material {
    std::string name;              ///< "cortical bone", a segment's name, ...
    std::string segment;           ///< The segment's name when the material is a segment; else empty.
    bool critical = false;         ///< A critical segment.
    std::uint64_t voxels = 0;      ///< Voxels removed.
    double removed_mm3 = 0.0;      ///< voxels x voxel volume [mm^3].
    /// Of those, voxels whose value was below the felt isovalue (centres outside the felt
    /// surface: air, or tissue not felt at this isovalue) that the burr's reach took with it, and
    /// their volume [mm^3]. Lowering them moves the felt surface only where it passes between
    /// them and felt voxels (trilinear interpolation), and hardly at all for air already near
    /// the lowest value.
    std::uint64_t voxels_below_surface = 0;
    double below_surface_mm3 = 0.0;
    double specific_energy_J_per_mm3 = 0.0;  ///< Its hardness.
  };
  double burr_radius_m = 0.0;      ///< The burr [m].
  double removed_mm3 = 0.0;        ///< Whole voxels removed, all materials [mm^3].
  double eroded_mm3 = 0.0;         ///< Material the energy removed, whole voxels and parts [mm^3].
  /// Per material (HU classes, then segments), then on a CT "air": the removed voxels below
  /// kAirBelow_HU in the scan, taken out of the HU class rows that charged them (drilling.h).
  std::vector<Material> materials;
  /// SHA-256 of the carved field's raw voxels at the end (a replay's must match).
  std::string drilled_field_sha256;
};

/// What `drill` removed since it was built, per material: its removal's count per material
/// (MaterialRemoval::removedVoxels(); the cavity it started from is not counted), and of each
/// count the voxels whose value in `scene`'s felt field lay below the felt isovalue. On a CT
/// (the scan in HU on the felt grid) the removed voxels of an HU class (not a segment) whose
/// scan value is below kAirBelow_HU are taken out of that class's row into a last row "air"
/// (the burr's reach charges them at the class's hardness; the row gives that hardness).
/// The carved field's SHA-256. Off the servo thread: one pass over the field's voxels.
/// @param drill a drill built on scene's felt field (the same grid; else no "below" counts and no air).
DrillReport drillReportOf(const Drill& drill, const LoadedScene& scene);

/// What the burr removed during a recording, per material, or why that is not known.
struct RecordingDrillReport {
  std::optional<DrillReport> report;  ///< Empty when not known (see why).
  std::string why;                    ///< Why there is no report, in words; empty with one.
};

/// Whether `recording`'s burr removed anything during it (format version 5 on: its records'
/// TickRecord::removed_voxels; older: a "drilled" event, which only `run` wrote).
bool drilledDuring(const Recording& recording);

/// What `recording`'s burr removed during it, per material and as air: `recording` replayed on
/// `scene` (the scene it was recorded on, reloaded from its metadata) and drillReportOf() of the
/// replay's drill (ReplayComparison::drill; the cavity the recording started on is not counted).
/// A replay that parts from the recording gives no report, and `why` says at which record and
/// why when that is known (replayDifference()); so does a scene without a drill, and a replay
/// that throws (its message). As long as the recording's drilling took, on the calling thread.
/// Never throws for a bad recording: every error becomes `why`.
RecordingDrillReport drillReportOfRecording(const LoadedScene& scene, const Recording& recording);

}  // namespace vh::runtime
