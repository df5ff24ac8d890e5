#pragma once
/// @file
/// Drilling in a scene: the scene file's "drill" section, the burr on the tool, the hardness of
/// each voxel (per segment, else from HU) and the step that follows each renderer tick on the
/// servo thread and in a replay alike (haptics/material_removal.h for the removal itself).
///
/// A scene without a "drill" section starts none of it (no copy of the field, no material state).
/// With one, the renderer feels a private copy of the felt field, which the burr carves between
/// ticks on the solver thread; the scene's own field (the picture's source) is never written.
/// What was carved outlives the renderer as a DrilledCavity: a rebuilt renderer's copy starts
/// with it removed (the voxels a burr had only partly eroded start whole again).
///
/// Frames and units: W the scene frame [m]; T the tool frame [m]; hardness as the specific
/// cutting energy [J/mm^3] (MaterialRemoval's model, after Agus et al., Presence 2003).

#include <array>
#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "vh/haptics/haptic_renderer.h"
#include "vh/haptics/material_removal.h"
#include "vh/haptics/scalar_volume.h"
#include "vh/haptics/tool_model.h"
#include "vh/runtime/segments.h"

namespace vh::tissue {
class DeformableScene;
}

namespace vh::runtime {

/// The voxels a burr removed from a felt field: the drilled state that outlives the renderer
/// that carved it. Session keeps it when it rebuilds the haptic threads (a new tool, segments,
/// device) and the new drill starts from it; a recording's metadata carries the one its session
/// started from, so that a replay carves on from the same field (session_metadata.h).
struct DrilledCavity {
  haptics::VolumeGeometry grid;       ///< The felt field's grid the indices refer to (W [m]).
  std::vector<std::uint64_t> voxels;  ///< Linear indices (x fastest) of the removed voxels, ascending.
};

/// A box of voxels of a grid: indices [lo, hi] on each axis (i, j, k).
struct VoxelBox {
  std::array<int, 3> lo{0, 0, 0};
  std::array<int, 3> hi{-1, -1, -1};
};

/// The cavity of `carved` (a drill's copy of `undrilled`, the same grid) on undrilled's grid: the
/// voxels whose raw value differs from `undrilled`'s (a burr only ever writes a removed voxel),
/// and those of `started_from` (the cavity the copy started with, cavityVoxelsOn() this grid:
/// kept even where the field was already at its lowest, e.g. outside a felt segment). One pass
/// over the voxels, a row at a time where the row is untouched (about 10 ms on a 512 x 512 x 140
/// CT), or over those in `within` only (clipped to the grid; e.g. where the burr cut since a
/// mark, haptics::MaterialRemoval::cutsSinceMark()); off the servo thread.
/// @throws std::invalid_argument when the two grids differ.
DrilledCavity cavityOf(const haptics::ScalarVolume& carved, const haptics::ScalarVolume& undrilled,
                       const DrilledCavity* started_from = nullptr, const std::optional<VoxelBox>& within = std::nullopt);

/// The voxels of `grid` (linear indices, x fastest, ascending) that lie in `cavity`: its own
/// indices on the same grid; on another grid (the felt field changed, or the picture's scan),
/// each voxel of `grid` whose centre's nearest voxel of cavity.grid was removed.
std::vector<std::uint64_t> cavityVoxelsOn(const DrilledCavity& cavity, const haptics::VolumeGeometry& grid);

/// The scene file's "drill" section.
struct DrillSpec {
  bool on = false;                                ///< "on": the burr spins from the start (else a key or button starts it).
  double burr_radius_m = 0.0;                     ///< "burr_radius_m", 1 to 6 mm; 0: from the tool (burrOf()).
  std::optional<Eigen::Vector3d> burr_center_T_m; ///< "burr_center_T_m" in T [m]; absent: from the tool.
  double burr_speed_rpm = 80000.0;                ///< "burr_speed_rpm", > 0.
  /// "hardness": specific cutting energy [J/mm^3] by material name: a segment's name or ID, or
  /// "cortical bone", "cancellous bone", "soft tissue" (CT in HU), "tissue" (other data).
  std::map<std::string, double> hardness_J_per_mm3;
  /// The cavity drilled before the haptic threads were (re)built, which the drill starts from
  /// (never from a scene file: Session keeps it over a rebuild, a recording's metadata brings
  /// back the one its session started from). Null: the undrilled field.
  std::shared_ptr<const DrilledCavity> cavity;
};

/// Below it a CT voxel is reported as air, not soft tissue, when the burr removes it (half way
/// from water to air: mostly air; the burr charges it at soft tissue's hardness) [HU].
inline constexpr double kAirBelow_HU = -500.0;

/// Default hardness of the HU classes [J/mm^3] and their limits [HU]: soft tissue below
/// kCancellousFrom_HU, cancellous bone up to kCorticalFrom_HU, cortical bone above (limits after
/// the usual CT windows of trabecular and compact bone).
inline constexpr double kCancellousFrom_HU = 250.0;
inline constexpr double kCorticalFrom_HU = 800.0;
inline constexpr double kSoftTissue_J_per_mm3 = 0.1;
inline constexpr double kCancellousBone_J_per_mm3 = 0.6;
inline constexpr double kCorticalBone_J_per_mm3 = 2.0;
/// Hardness of data not in HU (MR, a built-in volume) [J/mm^3].
inline constexpr double kTissue_J_per_mm3 = 0.6;

/// The burr: a sphere on the tool.
struct Burr {
  Eigen::Vector3d center_T_m = Eigen::Vector3d::Zero();  ///< Centre in T [m].
  double radius_m = 0.0025;                             ///< Radius [m].
};

/// The burr of `tool` under `spec`: the spec's centre and radius where given; else the tool's
/// tip: the mesh vertex farthest from the centre of mass, the centre one radius inside it
/// towards the centre of mass, radius 2.5 mm (the built-in drill's ball: centre at T's origin).
/// @throws std::invalid_argument for a radius outside 1 to 6 mm or a non-finite centre.
Burr burrOf(const haptics::ToolModel& tool, const DrillSpec& spec);

/// Materials of the voxels of a felt field.
struct DrillMaterials {
  std::vector<std::uint8_t> voxel_material;        ///< Per voxel of the felt field (x fastest).
  std::vector<haptics::CuttingMaterial> materials; ///< Indexed by voxel_material.
  /// The segment of each material (index into the SegmentSet), -1 for the HU classes.
  std::vector<int> segment_of_material;
};

/// Whether `given` (a scene's "hardness" key, a Segments panel edit, a recorded hardness event)
/// names the material or segment `name`: the same text, ignoring ASCII case.
bool namesMaterial(const std::string& given, const std::string& name);

/// The hardness of each voxel of `felt` (the field the hand feels, in W): the segment whose label
/// covers the voxel's centre (nearest voxel of its layer) when `segments` is given, with the
/// spec's hardness for the segment's name or ID, else the HU class of its mean scan value;
/// outside every segment, or without segments, the HU class of the scan's value there
/// (`hounsfield`: the scan is CT in HU), else one material "tissue". A segment marked critical
/// makes a critical material. Off the servo thread (allocates; about 30 ns per voxel).
/// @throws std::invalid_argument for a hardness in the spec that is not > 0 or names no material.
DrillMaterials makeDrillMaterials(const haptics::ScalarVolume& felt, const haptics::ScalarVolume& scan,
                                  bool hounsfield, const SegmentSet* segments, const DrillSpec& spec);

/// The burr and its removal on one renderer's private field: what the solver thread (and a
/// replay) runs after each renderer tick while the drill is on.
class Drill {
 public:
  /// @param removal carves the renderer's field (the same object). @param dt_s one solver period [s].
  /// @param cavity_at_start the cavity `removal` started from (MaterialRemoval::removeCavity()), or null.
  Drill(std::shared_ptr<haptics::MaterialRemoval> removal, Burr burr, double dt_s,
        std::vector<int> segment_of_material, std::shared_ptr<const DrilledCavity> cavity_at_start = nullptr);

  /// After renderer.tick() returned `out`: the burr at the proxy cuts with |out.force_W_N| when one
  /// of the contacts lies on it (within its radius plus the collision tolerance, twice).
  /// No allocation, no exception, no lock.
  haptics::CutResult step(const haptics::HapticRenderer& renderer, const haptics::TickOutput& out) noexcept;
  /// Whether one of the renderer's contacts lies on the burr (the test step() cuts by): false
  /// with contacts means only the shaft or handle touches, and the burr cannot cut. No
  /// allocation, no exception, no lock.
  bool burrTouches(const haptics::HapticRenderer& renderer) const noexcept;

  haptics::MaterialRemoval& removal() noexcept { return *removal_; }
  const haptics::MaterialRemoval& removal() const noexcept { return *removal_; }
  const Burr& burr() const noexcept { return burr_; }
  /// The cavity this drill's field started from (removed before its first cut, neither counted
  /// in removed_mm3() nor logged), or null: what the picture shows before the log's voxels.
  const std::shared_ptr<const DrilledCavity>& cavityAtStart() const noexcept { return cavity_at_start_; }
  /// The segment of material m (index into the scene's SegmentSet), or -1.
  int segmentOfMaterial(int m) const noexcept {
    return m >= 0 && static_cast<std::size_t>(m) < segment_of_material_.size() ? segment_of_material_[m] : -1;
  }
  /// Removed volume so far [mm^3], all materials (whole voxels).
  double removed_mm3() const noexcept {
    return static_cast<double>(removal_->removedVoxels()) * removal_->voxelVolume_mm3();
  }

 private:
  std::shared_ptr<haptics::MaterialRemoval> removal_;
  Burr burr_;
  double dt_s_;
  std::vector<int> segment_of_material_;
  std::shared_ptr<const DrilledCavity> cavity_at_start_;
};

/// A renderer on a drill's private field and the Drill that carves it (makeDrillingRenderer()).
struct DrillingRenderer {
  std::unique_ptr<haptics::HapticRenderer> renderer;
  std::shared_ptr<Drill> drill;
  /// Soft tissue (tissue_scene.h): the renderer feels its field, which its step() rewrites before
  /// each tick; null: none. Never with a drill.
  std::shared_ptr<tissue::DeformableScene> tissue;
};

/// The costly half of a drilling renderer, which does not depend on the proxy: a private copy of
/// `felt` (so that drilling never writes a shared field) with spec.cavity removed
/// (cavityVoxelsOn() the felt grid), and the removal (materials, per-voxel remains) that carves
/// it. About 0.15 s on a 512 x 512 x 140 CT, so that it can be built while the threads it
/// replaces still render the force (Session::prepareRecording()). Off the servo thread.
struct PreparedDrill {
  std::shared_ptr<haptics::MaterialRemoval> removal;  ///< Carves its own copy of the felt field.
  std::vector<int> segment_of_material;                ///< DrillMaterials::segment_of_material.
  std::shared_ptr<const DrilledCavity> cavity;         ///< spec.cavity, removed from the copy.
};
/// @throws std::invalid_argument for a burr speed that is not > 0, and as MaterialRemoval's
///         constructor.
PreparedDrill prepareDrill(const haptics::ScalarVolume& felt, DrillMaterials materials, const DrillSpec& spec);

/// Catches `prepared` up with what `old_drill` cut after `prepared` was built from `cavity` (the
/// old drill's cavity then, on `undrilled`'s grid): the voxels of the box cut since the old
/// removal's last markCuts() that differ from `undrilled` and are not in `cavity` are removed from
/// prepared's field (MaterialRemoval::removeCavity()) and added to `cavity` and prepared.cavity
/// (a new object; `cavity` may be null before). A recording restarted while drilling builds the
/// new drill this way while the old threads still cut (Session::prepareRecording()). Only after
/// the old drill's threads stopped, and before prepared's renderer is built.
/// @return the voxels removed from prepared's field.
/// @throws std::invalid_argument as cavityOf().
std::size_t catchUpCavity(const Drill& old_drill, const haptics::ScalarVolume& undrilled,
                          std::shared_ptr<const DrilledCavity>& cavity, PreparedDrill& prepared);

/// A renderer on `prepared`'s field (felt at `felt_isovalue`) with `options`, `tool`, proxy at
/// X_WP in W [m], and the Drill with spec's burr that carves that field at `servo_rate_Hz`; the
/// cavity was removed before the renderer first reads the field. The same inputs give the same
/// state, whenever `prepared` was built (the live threads and a replay alike).
/// @throws std::invalid_argument as HapticRenderer's constructor, burrOf(), and for a missing
///         tool or a prepared drill without a removal.
DrillingRenderer makeDrillingRenderer(PreparedDrill prepared, double felt_isovalue,
                                      std::shared_ptr<const haptics::ToolModel> tool, const DrillSpec& spec,
                                      const haptics::RendererOptions& options, const haptics::Pose& X_WP,
                                      double servo_rate_Hz);

}  // namespace vh::runtime
