#pragma once
/// @file
/// The tool's shadow on the felt surface: a depth cue for the eyes. A screen shows where the
/// tool is across the view but hardly how far it is from the surface along the line of sight;
/// a shadow cast by a light above the viewer that turns with the camera (shadowLightDirection_W())
/// falls on the isosurface under the tool and closes on the tool as it approaches, and a drop line
/// from the tool's nearest point to its shadow measures the gap that is left.
///
/// The shadow is cast on the field the hand feels (the haptic field at its isovalue, F(x) = s,
/// section 2.2 of the paper), with the exact segment test the proxy uses
/// (haptics::ScalarVolume::firstEntryOnSegment()): a shadow on the surface means the same surface
/// the hand meets there. No Qt or VTK here; SceneActors draws it.

#include <array>
#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <vector>

#include <Eigen/Core>

#include "vh/haptics/pose.h"
#include "vh/haptics/scalar_volume.h"
#include "vh/haptics/tool_model.h"
#include "vh/ui/view/device_manipulation.h"

namespace vh::ui {

/// Where a tool's sample points, cast along one direction, meet the isosurface.
struct ToolShadow {
  /// Shadow points on the isosurface in W [m]: one per sample whose ray meets it within reach
  /// (the outside end of the crossing's bracket, within u_tolerance of the surface).
  std::vector<Eigen::Vector3d> footprint_W_m;
  /// The drop line from the sample nearest to the surface along the direction to its shadow
  /// point, both in W [m]; only when has_gap (some sample's ray met the surface).
  bool has_gap = false;
  Eigen::Vector3d gap_from_W_m = Eigen::Vector3d::Zero();
  Eigen::Vector3d gap_to_W_m = Eigen::Vector3d::Zero();
  /// Length of the drop line [m] (the shortest distance along the direction from a sample
  /// to the surface).
  double gap_m = 0.0;
};

/// Casts `samples_T_m` (points of the tool in the tool frame T [m], some hundred:
/// toolShadowSamples()) at the pose `X_WP` along `direction_W` (normalised here; a zero or
/// non-finite one casts nothing) onto the isosurface F = `isovalue` of `field`, at most `reach_m`
/// [m] far (none: the diagonal of the field's grid, which a ray has left by then). Samples that
/// start inside the surface (F > isovalue: a tool in contact) cast nothing. Cost: one segment walk
/// per sample (cells skipped by their corners while the ray is in empty space).
ToolShadow castToolShadow(const haptics::ScalarVolume& field, double isovalue, const haptics::Pose& X_WP,
                          std::span<const Eigen::Vector3d> samples_T_m, const Eigen::Vector3d& direction_W,
                          std::optional<double> reach_m = std::nullopt);

/// The part of a field that drilling changed, carved: the box of voxels within one voxel of any
/// removed voxel (the only cells whose trilinear field differs from the field as loaded), as a
/// volume of its own on the same grid, with the removed voxels at the field's lowest value (as
/// the drill writes them: MaterialRemoval). The shadow then falls into the cavity the hand feels
/// without a second copy of the whole scan on the GUI's side (the servo thread's own copy is
/// never read here). Not thread-safe; the GUI thread keeps it (DrillController).
class CarvedRegion {
 public:
  /// Starts over on `field` (the felt field as loaded; shared, kept until the next reset or
  /// clear) with `removed` (linear indices of its grid, x fastest) carved out.
  void reset(std::shared_ptr<const haptics::ScalarVolume> field, std::span<const std::uint64_t> removed = {});
  /// Nothing carved, no field.
  void clear();
  /// Carves `removed` (linear indices of the field's grid; out of range: ignored) out too; the box
  /// grows to hold them (copied from the field again) or the new voxels are written into it.
  void remove(std::span<const std::uint64_t> removed);
  /// The carved box (null: nothing removed), on the field's grid offset to the box's first voxel.
  const haptics::ScalarVolume* box() const noexcept { return box_.get(); }
  /// The field it carves (null after clear()).
  const std::shared_ptr<const haptics::ScalarVolume>& field() const noexcept { return field_; }
  /// Voxels carved so far.
  std::size_t removedCount() const noexcept { return removed_.size(); }
  /// Changes with every reset, clear and remove that carved something (for a cache's key).
  std::uint64_t version() const noexcept { return version_; }

 private:
  /// Copies the box lo_..hi_ from the field and carves every removed voxel into it.
  void rebuild();
  /// Writes the field's lowest raw value at removed voxel `index` (inside the box); returns its
  /// voxel in the box.
  std::array<int, 3> carveInBox(std::uint64_t index);
  std::shared_ptr<const haptics::ScalarVolume> field_;
  std::vector<std::uint64_t> removed_;  // every carved voxel, in order
  std::array<int, 3> lo_{0, 0, 0}, hi_{-1, -1, -1};  // the box, inclusive, in the field's voxels
  std::unique_ptr<haptics::ScalarVolume> box_;
  std::uint64_t version_ = 0;
};

/// castToolShadow() on `field` carved by `carved` (its box read where a ray crosses it, `field`
/// elsewhere): the same shadow as on a copy of the field with the removed voxels set to its
/// lowest value, up to rounding. `carved` without a box, or on another field: castToolShadow().
ToolShadow castToolShadow(const haptics::ScalarVolume& field, const CarvedRegion& carved, double isovalue,
                          const haptics::Pose& X_WP, std::span<const Eigen::Vector3d> samples_T_m,
                          const Eigen::Vector3d& direction_W, std::optional<double> reach_m = std::nullopt);

/// The direction shadows are cast along for `camera`, unit: a light above the viewer's left
/// shoulder that turns with the camera, -up + right/2 + forward/2 normalised (the screen's down
/// and right and into the view). A shadow then falls below, right of and behind the tool, beside
/// it on the screen rather than hidden behind it, and meets the tool where the tool touches.
Eigen::Vector3d shadowLightDirection_W(const ViewCamera& camera);

/// At most `count` of `vertices_T_m`, spread over the tool: farthest-point sampling from the
/// first vertex (each next sample the vertex farthest from those taken), so a long shaft and a
/// small tip both cast. All vertices when there are no more than `count`. Deterministic.
std::vector<Eigen::Vector3d> shadowSamples(std::span<const Eigen::Vector3d> vertices_T_m, int count);

/// The samples the view casts `tool`'s shadow from, in T [m]: kShadowSamples of its point shell
/// (even over the surface; a mesh's long shaft has vertices only at its ends), else of its display
/// mesh's vertices.
inline constexpr int kShadowSamples = 128;
std::vector<Eigen::Vector3d> toolShadowSamples(const haptics::ToolModel& tool);

}  // namespace vh::ui
