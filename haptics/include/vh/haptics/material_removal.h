#pragma once
/// @file
/// Drilling: a spherical burr that removes the material it presses on, carving the very field
/// the configuration solver feels (haptics/README.md, "Drilling").
///
/// Removal model (energy based, after Agus, Giachetti, Gobbetti, Zanetti and Zorcolo, "Real-time
/// haptic and visual simulation of bone dissection", Presence 12(1), 2003): the burr spinning at
/// angular speed omega with radius r converts the power P = |F| omega r (|F| the contact force
/// the hand pushes with) into removed material, each material taking its specific cutting energy
/// e [J/mm^3] (its hardness) per mm^3 removed:  dV/dt = P / e.  Per servo tick of dt seconds the
/// energy P dt is shared among the voxels within the burr's reach (voxel centres inside the
/// burr, distance < r), weighted by how deep they lie inside that reach (the deepest go first); a voxel whose material reaches zero is removed: its raw value becomes the volume's
/// lowest (ScalarVolume::lowestRaw(): air), so F only ever decreases, the felt surface retreats
/// and never moves onto the proxy. When the burr touches the surface but no voxel above the
/// isovalue lies within that reach (a surface up to one voxel diagonal from its voxels), the
/// reach grows for that tick to a quarter voxel beyond the nearest felt voxel (at most r + one
/// voxel diagonal), so a pressing burr always cuts, and only the layer it touches. Shares are
/// kept in 1/65535 of a voxel, rounded down with the remainder carried on: the removed volume
/// never exceeds the energy delivered over e.
///
/// Threads: cut() writes the volume in place. It runs on the servo thread between renderer
/// ticks, the only thread that queries that volume (the renderer's private copy), so no reader
/// ever sees a half-written field; the min-max tree and the Lipschitz bounds are refreshed over
/// the touched bricks before cut() returns. Removed voxels are also pushed into a lock-free
/// single-producer / single-consumer log (drainRemoved()) from which the picture is updated
/// without reading the haptic copy. cut() never allocates, throws or blocks.

#include <array>
#include <atomic>
#include <climits>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "vh/haptics/scalar_volume.h"

namespace vh::haptics {

/// One material of the voxels (a hardness class): cortical bone, a segment, ...
struct CuttingMaterial {
  std::string name;                          ///< Shown and reported ("cortical bone", a segment name).
  double specific_energy_J_per_mm3 = 1.0;    ///< Energy to remove 1 mm^3 (the hardness), > 0.
  bool critical = false;                     ///< Removing any of it is reported (a nerve, the dura).
};

/// Settings of the burr's removal.
struct RemovalModel {
  /// Burr angular speed omega [rad/s]: 80,000 rpm, an otologic drill's usual speed.
  double burr_speed_rad_per_s = 80000.0 * 2.0 * 3.14159265358979323846 / 60.0;
  /// Removed voxels the picture's log holds before it drops (the consumer drains it each frame).
  std::size_t log_capacity = std::size_t{1} << 22;
};

/// What one cut() did.
struct CutResult {
  int voxels_in_reach = 0;         ///< Voxels (not yet removed) that shared the energy.
  int voxels_removed = 0;          ///< Voxels removed on this tick.
  int critical_removed = 0;        ///< Of those, voxels of a critical material.
  int critical_material = -1;      ///< The (first) critical material they belong to, or -1.
  double energy_J = 0.0;           ///< Energy the burr delivered, P dt [J].
  /// Hardness of what the burr cut: the specific energies of the voxels in reach, weighted by
  /// their shares of the energy [J/mm^3]; 0 when nothing was cut (energy_J 0).
  double specific_energy_J_per_mm3 = 0.0;
  /// The material of the voxel deepest in the burr's reach (the largest share of the energy),
  /// index into MaterialRemoval::materials(); -1 when nothing was cut.
  int material = -1;
  bool widened = false;            ///< The reach grew to one voxel diagonal (see the file comment).
};

/// A burr carving one volume. Owns the material state (one uint16 per voxel: the fraction of
/// its material left, 65535 = whole) and the removal log, sized at construction.
class MaterialRemoval {
 public:
  static constexpr std::uint16_t kWhole = 65535;

  /// @param volume the volume to carve, in place (the renderer's private copy; see the file
  ///        comment for the threads).
  /// @param voxel_material per voxel (x fastest), the index into `materials`; empty: material 0
  ///        for every voxel.
  /// @param materials at most 255, each with a finite specific energy > 0.
  /// @throws std::invalid_argument for a null or empty volume, a voxel_material of the wrong
  ///         size or with an index out of range, no materials or a bad energy, a model with a
  ///         non-positive burr speed or an empty log.
  MaterialRemoval(std::shared_ptr<ScalarVolume> volume, std::vector<std::uint8_t> voxel_material,
                  std::vector<CuttingMaterial> materials, const RemovalModel& model = {});

  /// One tick of drilling: the burr (centre burr_center_W_m in W [m], radius burr_radius_m [m])
  /// pressing with |force_N| [N] for dt_s [s] removes material as in the file comment. Nothing is
  /// removed when force_N, dt_s or the radius is not positive or not finite, or when
  /// burr_touches is false (the burr is not among the contacts: the force comes from elsewhere
  /// on the tool). `isovalue` [data units] decides which voxels are felt (for the widened reach).
  /// No allocation, no exception, no lock.
  CutResult cut(const Eigen::Vector3d& burr_center_W_m, double burr_radius_m, double force_N, double dt_s,
                double isovalue, bool burr_touches) noexcept;

  /// Removes the voxels at linear indices `voxels` (x fastest) outright, before the first cut():
  /// a cavity drilled earlier (carried over a rebuild of the haptic threads, or the one a
  /// recording started with). Each becomes lowestRaw() with no material left, as if cut, but is
  /// neither counted in removedVoxels() / erodedVolume_mm3() nor put in the removal log (whoever
  /// shows the cavity has it already). Indices out of range and voxels already removed are
  /// skipped; the min-max tree and Lipschitz bounds are refreshed over the box of the removed
  /// ones. Not while another thread queries the volume (call it before the renderer ticks).
  /// @return the voxels it removed.
  std::size_t removeCavity(std::span<const std::uint64_t> voxels) noexcept;

  /// Starts a new record of where cut() removes voxels (cutsSinceMark()): empty from here on.
  /// Only while nothing cuts: before the first cut(), while the thread that cuts is held from
  /// cutting (runtime's HapticThread::holdCutting()), or after it stopped.
  void markCuts() noexcept;
  /// The box of the voxels cut() removed since the last markCuts() (or since construction), in
  /// voxel indices [lo, hi] per axis of the volume's grid. Read under the same condition as
  /// markCuts(). removeCavity() does not count.
  /// @return false when nothing was removed since then (lo and hi untouched).
  bool cutsSinceMark(std::array<int, 3>& lo, std::array<int, 3>& hi) const noexcept;

  /// Changes material m's specific energy [J/mm^3] from the next cut() on (the Segments panel's
  /// hardness); any thread, lock-free. Ignored for an index out of range or an energy that is
  /// not finite and > 0.
  void setSpecificEnergy(int material, double J_per_mm3) noexcept;
  /// Material m's specific energy now [J/mm^3] (materials() keeps the one it was built with).
  double specificEnergy(int material) const noexcept {
    return energy_J_per_voxel_[static_cast<std::size_t>(material)].load(std::memory_order_relaxed) / voxel_mm3_;
  }

  const ScalarVolume& volume() const noexcept { return *volume_; }
  /// The same field, shared: the renderer that feels what this removal carves holds it too.
  std::shared_ptr<const ScalarVolume> sharedVolume() const noexcept { return volume_; }
  const std::vector<CuttingMaterial>& materials() const noexcept { return materials_; }
  const RemovalModel& model() const noexcept { return model_; }
  /// Voxels removed so far per material (index as materials()); safe to read from any thread.
  std::uint64_t removedVoxels(int material) const noexcept {
    return removed_[static_cast<std::size_t>(material)].load(std::memory_order_relaxed);
  }
  /// Voxels removed so far, all materials.
  std::uint64_t removedVoxels() const noexcept;
  /// Material removed so far, whole voxels and the eroded parts of others [mm^3] (what the
  /// energy paid for; removedVoxels() counts only whole voxels, what is felt and seen).
  /// Read on the thread that calls cut().
  double erodedVolume_mm3() const noexcept { return static_cast<double>(eroded_) / kWhole * voxel_mm3_; }
  /// Volume of one voxel [mm^3].
  double voxelVolume_mm3() const noexcept { return voxel_mm3_; }
  /// Material of the voxel at linear index `index` (x fastest).
  int materialOf(std::size_t index) const noexcept { return voxel_material_.empty() ? 0 : voxel_material_[index]; }

  /// Consumer side of the removal log (one thread, e.g. the GUI): moves up to out.size() linear
  /// voxel indices (x fastest) removed since the last call into `out`, in removal order.
  /// @return how many were written.
  std::size_t drainRemoved(std::span<std::uint64_t> out) noexcept;
  /// Removed voxels the log dropped because the consumer fell behind (total).
  std::uint64_t droppedFromLog() const noexcept { return dropped_.load(std::memory_order_relaxed); }

 private:
  std::shared_ptr<ScalarVolume> volume_;
  std::vector<std::uint8_t> voxel_material_;
  std::vector<CuttingMaterial> materials_;
  std::array<std::atomic<double>, 256> energy_J_per_voxel_{};  // per material: energy to remove one whole voxel
  RemovalModel model_;
  std::vector<std::uint16_t> remaining_;    // per voxel, kWhole = intact, 0 = removed
  double voxel_mm3_ = 0.0;
  double removed_raw_ = 0.0;
  std::uint64_t eroded_ = 0;  // material removed [1/65535 voxel]
  double carry_ = 0.0;  // rounding remainder of the last share [1/65535 voxel], carried on
  // The box of the voxels cut() removed since markCuts(), grown by min / max; empty (hi < lo)
  // after markCuts().
  static constexpr std::array<int, 3> kNoCutLo{INT_MAX, INT_MAX, INT_MAX}, kNoCutHi{-1, -1, -1};
  std::array<int, 3> cut_lo_ = kNoCutLo, cut_hi_ = kNoCutHi;
  std::array<std::atomic<std::uint64_t>, 256> removed_{};
  // Removal log: ring of linear indices; head written by cut(), tail by drainRemoved().
  std::vector<std::uint64_t> log_;
  alignas(64) std::atomic<std::uint64_t> head_{0};
  alignas(64) std::atomic<std::uint64_t> tail_{0};
  std::atomic<std::uint64_t> dropped_{0};
  // The voxels not yet removed whose centres lie within a reach [m] of the burr's centre: their
  // box of voxel indices (clipped to the grid), the sum of their weights reach - d [m] (d: the
  // centre distance), their count, and whether one is felt (and the nearest felt one's d [m]).
  struct BurrReach {
    std::array<int, 3> lo{}, hi{};
    double sum_w = 0.0;
    int count = 0;
    bool felt = false;
    double nearest_felt = 0.0;
  };
  // One pass over the voxels within `reach` [m] of c (the burr's centre, grid coordinates) into
  // r; felt: raw above raw_threshold (below it when the raw-to-data scale is negative: !rising).
  void gatherReach(const Eigen::Vector3d& c, double reach, double raw_threshold, bool rising,
                   BurrReach& r) const noexcept;
  // The reach cut() shares its energy within [m], with its voxels in r: the burr's radius when a
  // voxel there is felt; else, widened (widened = true), a quarter voxel beyond the nearest felt
  // voxel within one voxel diagonal beyond the burr. False when none is felt there.
  bool feltReach(const Eigen::Vector3d& c, double burr_radius_m, double raw_threshold, bool rising, double& reach,
                 BurrReach& r, bool& widened) const noexcept;
  // Shares energy_J [J] over r's voxels within `reach` [m] of c by weight reach - d, eroding
  // each (the rounding carried on, carry_) and removing those used up (removeVoxel()); their box
  // grows changed_lo / changed_hi (voxel indices).
  void shareEnergy(const Eigen::Vector3d& c, double reach, const BurrReach& r, double energy_J, CutResult& result,
                   std::array<int, 3>& changed_lo, std::array<int, 3>& changed_hi) noexcept;
  // Voxel idx (material m) used up: written as removed, counted (critical too), and put in the
  // removal log at `head` (dropped when the log, read up to `tail`, is full).
  void removeVoxel(std::size_t idx, int m, std::uint64_t& head, std::uint64_t tail, CutResult& result) noexcept;
};

}  // namespace vh::haptics
