#pragma once
/// @file
/// Segments in a scene: which segments of a segmentation (3D Slicer .seg.nrrd or a
/// label map) are felt, shown and critical, the felt field, and which segment a contact touches.
///
/// Felt: the haptic field becomes io::segmentIndicatorField() of the felt segments (smoothed
/// indicator, surface at F = 0.5); the scan stays the picture. Shown: coloured surfaces beside
/// the ray-cast scan. Critical: touching one is an alert in the GUI and an event in the
/// recording. Every contact is named by its segment (segmentOf()), on the solver thread.
///
/// Frames and units: W is the scene frame (patient LPS) in metres, as io::loadVolume().
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "vh/haptics/collision_detector.h"
#include "vh/haptics/distance_field.h"
#include "vh/haptics/scalar_volume.h"
#include "vh/io/segmentation.h"
#include "vh/runtime/critical_proximity.h"

namespace vh::runtime {

/// The scene file's "segmentation" section.
struct SegmentationSpec {
  std::string path;                   ///< .seg.nrrd or label-map NRRD (resolved like the volume).
  std::vector<std::string> felt;      ///< Segment names or IDs felt; empty: the scan's isosurface is felt.
  /// Segment names or IDs shown; absent ("shown" not in the scene): every segment.
  std::optional<std::vector<std::string>> shown;
  std::vector<std::string> critical;  ///< Segment names or IDs whose touch is an alert.
  double smoothing_voxels = 1.0;      ///< Sigma of the felt field's Gaussian [voxels of the segmentation].
  ProximitySpec proximity;            ///< Warning and alarm distances of the critical segments.
};

/// A loaded segmentation and the choices made on it. Immutable and shared (the haptic threads
/// read it while the GUI holds it).
class SegmentSet {
 public:
  /// Builds the felt field and one distance field per critical segment (critical_proximity.h).
  /// @param felt, shown, critical indices into seg.segments.
  /// @param thresholds per segment (one per seg.segments entry), or empty: the defaults.
  /// @throws std::invalid_argument for an index out of range, a bad smoothing (as
  ///         io::segmentIndicatorField()), a thresholds list of the wrong length or bad thresholds.
  SegmentSet(io::LoadedSegmentation seg, std::vector<int> felt, std::vector<int> shown, std::vector<int> critical,
             double smoothing_voxels, std::vector<ProximityThresholds> thresholds = {});

  /// Resolves the spec's names against `seg` (names or IDs, case-insensitive) and builds the set.
  /// @throws std::runtime_error naming `source` and the unknown segment, listing those there are,
  ///         or a segment given thresholds ("proximity.per_segment") that is not critical.
  static std::shared_ptr<const SegmentSet> fromSpec(io::LoadedSegmentation seg, const SegmentationSpec& spec,
                                                    const std::string& source);

  const io::LoadedSegmentation& segmentation() const noexcept { return seg_; }
  std::size_t size() const noexcept { return seg_.segments.size(); }
  const io::SegmentInfo& segment(int s) const { return seg_.segments.at(static_cast<std::size_t>(s)); }
  const std::vector<int>& felt() const noexcept { return felt_; }
  const std::vector<int>& shown() const noexcept { return shown_; }
  const std::vector<int>& critical() const noexcept { return critical_; }
  bool isFelt(int s) const noexcept;
  bool isShown(int s) const noexcept;
  bool isCritical(int s) const noexcept;
  double smoothingVoxels() const noexcept { return smoothing_voxels_; }
  /// One distance field per critical segment, in critical()'s order (critical_proximity.h).
  const std::vector<std::shared_ptr<const haptics::DistanceField>>& criticalFields() const noexcept {
    return critical_fields_;
  }
  /// The warning and alarm distances of segment s (meaningful for critical ones).
  const ProximityThresholds& thresholds(int s) const { return thresholds_.at(static_cast<std::size_t>(s)); }
  /// All of them, one per segment.
  const std::vector<ProximityThresholds>& proximityThresholds() const noexcept { return thresholds_; }
  /// The same set with other thresholds (one per segment), sharing the felt and distance fields
  /// (cheap: what the GUI calls when a threshold is changed).
  /// @throws std::invalid_argument for the wrong length or bad thresholds.
  std::shared_ptr<const SegmentSet> withThresholds(std::vector<ProximityThresholds> thresholds) const;
  /// The felt field (null when no segment is felt); its surface is F = io::kSegmentSurfaceLevel.
  const std::shared_ptr<const haptics::ScalarVolume>& feltField() const noexcept { return felt_field_; }

  /// The felt segment nearest to p_W within two voxels (grid distance to the nearest voxel
  /// labelled with it), or -1. Felt surfaces lie within about half a voxel of their voxels, so
  /// a contact on one is named by its segment. No allocation; thread-safe.
  int segmentAt(const Eigen::Vector3d& p_W_m) const noexcept;
  /// The segment most of `contacts` touch (at most 16 of them, evenly spread, are examined;
  /// ties go to the first found), or -1 for none. No allocation; thread-safe.
  int segmentOf(std::span<const haptics::Contact> contacts) const noexcept;
  /// The name of segment s, or "" for -1.
  std::string name(int s) const;

 private:
  io::LoadedSegmentation seg_;
  std::vector<int> felt_, shown_, critical_;
  double smoothing_voxels_ = 1.0;
  std::shared_ptr<const haptics::ScalarVolume> felt_field_;
  std::vector<std::shared_ptr<const haptics::DistanceField>> critical_fields_;
  std::vector<ProximityThresholds> thresholds_;
  SegmentSet() = default;
  void setThresholds(std::vector<ProximityThresholds> thresholds);
  struct FeltLabel {
    int segment = -1;
    int layer = 0;
    int label = 0;
  };
  std::vector<FeltLabel> felt_labels_;
};

/// The names of a scene's segments for a thread other than the GUI's (the OpenIGTLink link names
/// the touched segment in its ContactState): set on the GUI thread when the segments change,
/// read elsewhere. Thread-safe (a mutex; never used on the haptic threads).
class SegmentNameTable {
 public:
  /// Takes the names of `set`'s segments (null: none).
  void set(const SegmentSet* set);
  /// The name of segment `s` (HapticSnapshot::segment), or "" for -1 or an unknown index.
  std::string name(int s) const;

 private:
  mutable std::mutex mutex_;
  std::vector<std::string> names_;
};

/// Contact with one segment over a session: what the export and the headless run report.
struct SegmentContact {
  std::string name;               ///< Segment name.
  bool critical = false;          ///< Marked critical.
  std::uint64_t ticks = 0;        ///< Ticks whose contacts touched it.
  double time_in_contact_s = 0.0; ///< ticks * servo period [s].
  double peak_force_N = 0.0;      ///< Largest |force| on the hand while touching it [N].
  std::uint64_t touches = 0;      ///< Separate touches (entries into contact with it).
};

/// Adds up SegmentContact per segment, tick by tick (the runner's loop, a recording's records).
class SegmentContactTally {
 public:
  /// @param names, critical one entry per segment (same length).
  /// @throws std::invalid_argument when the lengths differ.
  SegmentContactTally(const std::vector<std::string>& names, const std::vector<bool>& critical);
  /// One tick of `dt_s` seconds touching `segment` (-1: none) with |force| `force_N`.
  void add(int segment, double force_N, double dt_s) noexcept;
  const std::vector<SegmentContact>& segments() const noexcept { return segments_; }

 private:
  std::vector<SegmentContact> segments_;
  int previous_ = -1;
};

}  // namespace vh::runtime
