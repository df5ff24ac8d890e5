#pragma once
/// @file
/// What a swept query of the collision detector (paper section 2.3, step 4) runs and returns:
/// the detection path, the segment test, and the first time of contact. CollisionDetector::sweep()
/// (collision_detector.h) runs it.

#include <ostream>

namespace vh::haptics {

/// Which collision-detection path runs.
/// - kPaper: section 2.3 as published: every point's arc is split into ceil(s / f) equal time
///   segments (s = path-length bound, f = feature size), each segment end is sampled, the first
///   crossing is bisected. Kept as the reference path and for side-by-side benchmarks.
/// - kAccelerated: the same contract (first time of contact to the same tolerance, same contact
///   set) computed with fewer samples: see haptics/README.md, "Speed".
enum class DetectionMode { kPaper, kAccelerated };


/// How one segment of a point's path is tested against the isosurface.
/// - kExact (default): the cells the segment's chord crosses are walked and the trilinear cubic
///   in each is solved for the first entry (ScalarVolume::firstEntryOnSegment), so a feature of
///   any thickness is found; rotating points' arcs are split into chords of sagitta <= epsilon / 64
///   and the threshold is lowered by the Lipschitz bound times the sagitta, so the arc itself is
///   covered (haptics/README.md, "Never through").
/// - kEndSample: the earlier test, the paper's (section 2.3): sample the segment's end, bisect
///   when it is inside. Misses features thinner than a segment (f) that a segment crosses
///   between its ends; kept only as the "before" column of `bench table1` and to show that the
///   crossing oracle catches tunnels.
enum class SegmentTest { kExact, kEndSample };

/// "paper" or "accelerated".
const char* toString(DetectionMode mode) noexcept;
/// "exact" or "end-sample".
const char* toString(SegmentTest test) noexcept;
/// Writes toString(mode) (also names parametrised tests).
inline std::ostream& operator<<(std::ostream& os, DetectionMode mode) { return os << toString(mode); }

/// Result of a swept query.
struct SweepResult {
  double t = 1.0;         ///< First time of contact in [0, 1] (1 = no contact).
  double t_inside = 1.0;  ///< End of the bisection interval (the hit point is inside there).
  int hit_point = -1;     ///< Point that collided first, or -1.
  /// The work budget ran out before the sweep was done: t is the time up to which
  /// every point's path is proven free (hit_point -1); the rest of the motion is left for the
  /// next tick.
  bool budget_cut = false;
};

}  // namespace vh::haptics
