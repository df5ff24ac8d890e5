// The accelerated sweep's state (haptics/README.md, "Speed"): each point's path and search,
// the sweep the work budget cut (resumed on the next tick), the arc of a walk of the
// point-shell tree and a leaf's field steps. Private to the collision detector
// (collision_detector_impl.h; the sweep itself is in accelerated_sweep.cpp).
#pragma once

#include <cstddef>
#include <cstdint>

#include <Eigen/Core>

#include "vh/haptics/rigid_motion.h"
#include "vh/haptics/sweep.h"

namespace vh::haptics::detail {

// Per point, the path of the current sweep: one cache line per point, so that lanes working on
// different points never write to the same line. Every point the tree walk reaches is set up
// here (setupPath()); most are then culled by their own ball and touch nothing else.
struct alignas(64) PointState {
  Eigen::Vector3d r0 = Eigen::Vector3d::Zero();  // radial vector at t = 0 (W)
  double dt = 1.0;                // segment length in time
  double path = 0.0;              // path-length bound
  double sagitta = 0.0;           // its chords' sagitta [m] (kExact with rotation, else 0)
  double clear_until = 0.0;       // kAccelerated: proven outside over [0, clear_until] of the last sweep
  std::int32_t segments = 0;      // kAccelerated: segment count of the last sweep
  // kAccelerated: the last sweep's exact walk of this point examined a cell (a cell with a
  // corner above the threshold: the surface is within a voxel of its path), or a near point's
  // path was proven free along its direction. The next sweep then tests it along its
  // direction and walks it without first asking the min-max tree about its path's ball, which
  // near the surface only says "may hit" (a point resting on the surface, or sliding along it).
  std::uint8_t near_surface = 0;
};
static_assert(sizeof(PointState) == 64, "one cache line per point");
// Per point, the search's own state: touched only for the points that are sampled or queued
// (a line of its own per point, as PointState).
struct alignas(64) PointSearch {
  Eigen::Vector3d chord_end_ijk = Eigen::Vector3d::Zero();  // grid coordinates of the last chord's end
  double chord_end_t = -1.0;          // ... the last chord end's time
  std::int64_t clear_segments = 0;    // kAccelerated: leading segments proven empty
  std::uint32_t chord_end_stamp = 0;  // the chord end is valid when equal to chord_stamp_ (this sweep)
  unsigned char backoff = 0;          // kAccelerated: direct steps after a failed test = 2^backoff
};
// The state of an accelerated sweep between ticks (a cut sweep resumes on the next tick).
struct PendingSweep {
  bool active = false;         // a cut sweep can be resumed
  RigidMotion motion;
  double isovalue = 0.0;
  int phase = 0;               // 0: contact points, 1: the lanes (walk, then time-ordered queue)
  std::size_t contact_index = 0;
  double walk_t = 1.0;         // the lanes walk the tree over [0, walk_t] (the contact pass's hit)
  SweepResult result;          // first hit of the contact pass
};
// collectActive()'s arc over [0, t_max]: the tool's rotation and its centre of mass in W [m]
// at t_max / 2, about which the balls that hold a node's points' arcs, or one point's, are
// centred; with `queue`, each point's path is tested and queued.
struct WalkArc {
  const RigidMotion& motion;
  double t_max;
  double isovalue;
  bool queue;
  Eigen::Matrix3d R_mid;
  Eigen::Vector3d c_mid_W_m;
};
// F's steps per grid axis over a leaf's ball (ScalarVolume::gridStepRange()), read at its
// first near point: state 0 not read yet, 1 read, -1 the ball leaves the grid.
struct LeafSteps {
  int state = 0;
  Eigen::Vector3d lo, hi;
};

}  // namespace vh::haptics::detail
