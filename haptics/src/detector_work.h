// The collision detector's work (CollisionDetector::work(): the work budget's unit) as each
// thread of work counts it, the weights of its kinds of work, and its clock reads against the
// deadline. Private to the collision detector (collision_detector_impl.h).
#pragma once

#include <cstdint>

#include "vh/haptics/collision_detector.h"

namespace vh::haptics {
inline EdgeTestCounts& operator+=(EdgeTestCounts& a, const EdgeTestCounts& b) noexcept {
  a.points_held += b.points_held;
  a.points_boxed += b.points_boxed;
  a.points_walked += b.points_walked;
  a.edges_walked += b.edges_walked;
  return a;
}
}  // namespace vh::haptics

namespace vh::haptics::detail {

// Relative costs, in trilinear samples, of a min-max tree box query (plus 1 per
// kTreeNodesPerWork nodes it reads), of a cell the exact segment test walks, and of the extra
// for a cell whose cubic it examines. A least-squares fit of the thread CPU time of 40,000
// Engine and Hole ticks (2-core Xeon, 2.0 GHz) to the counts gave 0.044 us per sample, 0.07
// per box query, 0.001 to 0.025 per tree node, 0.14 per walked cell and 0.02 to 0.2 more per
// examined cell. Walked cells are counted because, uncounted, Hole's worst ticks walked
// about 1,200 cells (150 us) beyond their budget.
inline constexpr std::int64_t kBoxQueryWork = 2;
inline constexpr std::int64_t kTreeNodesPerWork = 4;
// A box query the bricks could not clear is asked again of the voxels themselves
// (ScalarVolume::voxelUpperBoundInBox()) when its box covers at most kVoxelQueryMax voxels
// (4 x 4 x 4: a ball of about one voxel's radius); counted as one sample plus one per
// kVoxelsPerWork voxels read (an estimate from the tree nodes' cost, not fitted). 64 against
// 216 and 512: the same samples saved on table1's scenes, for less reading.
inline constexpr int kVoxelQueryMax = 64;
inline constexpr std::int64_t kVoxelsPerWork = 16;
inline constexpr std::int64_t kCellWalkWork = 3;
inline constexpr std::int64_t kCellWork = 3;

// Work counted in the units of CollisionDetector::work() (see there), per thread of work.
struct WorkCounters {
  std::int64_t samples = 0, box_queries = 0, tree_nodes = 0, cells_walked = 0, cells = 0;
  std::int64_t voxel_queries = 0, voxels = 0;  // voxel-level box queries and the voxels they read
  std::int64_t other = 0;  // beyond samples, cells and box queries (sample units)
  // The edge test's decisions per point (not work: their costs are counted above;
  // CollisionDetector::edgeTestCounts()).
  EdgeTestCounts edge;
  std::int64_t total() const noexcept {
    return samples + other + kCellWork * cells + kCellWalkWork * cells_walked + kBoxQueryWork * box_queries +
           voxel_queries + voxels / kVoxelsPerWork + tree_nodes / kTreeNodesPerWork;
  }
  WorkCounters& operator+=(const WorkCounters& o) noexcept {
    samples += o.samples;
    box_queries += o.box_queries;
    voxel_queries += o.voxel_queries;
    voxels += o.voxels;
    tree_nodes += o.tree_nodes;
    cells_walked += o.cells_walked;
    cells += o.cells;
    other += o.other;
    edge += o.edge;
    return *this;
  }
};
// When the clock was last read, in work units, and whether the deadline had passed then.
struct ClockCheck {
  std::int64_t next = 0;
  bool late = false;
  std::int64_t late_work = 0;  // the work at the read that found the deadline passed
};

}  // namespace vh::haptics::detail
