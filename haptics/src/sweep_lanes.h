// One lane of the accelerated sweep on several cores (haptics/README.md, "Several cores"): its
// share of the point-shell tree, its own queue, counters and clock reads, its share of a forked
// edge test. Private to the collision detector (collision_detector_impl.h; the lanes' shares
// are dealt in sweep_lanes.cpp).
#pragma once

#include <cstddef>
#include <cstdint>
#include <limits>
#include <vector>

#include "vh/haptics/sweep.h"

#include "detector_work.h"
#include "sweep_queue.h"

namespace vh::haptics::detail {

// One lane of the accelerated sweep (setLanes()): its share of the point-shell tree, its own
// queue and counters. Lane 0 runs on the caller.
struct alignas(64) Lane {  // a cache line of its own: the lanes write their counters all the time
  WorkCounters counters;
  ClockCheck clock;
  std::int64_t base_work = 0;       // budgetWork() when the lanes were forked
  std::vector<int> roots;           // point-shell tree nodes it walks, in order
  std::vector<QueueEntry> heap;     // capacity: its points
  std::vector<int> stack;           // traversal stack, capacity = nodes
  // collectActive(): the nodes its walk reached, in walk order (~node when culled), capacity =
  // nodes; read backwards when the walk is done, to mark the nodes it found near the surface.
  std::vector<int> walk_log;
  std::size_t walk_logged = 0;
  std::vector<int> active;          // its points not culled by the walk, capacity: its points
  std::size_t active_count = 0;
  std::size_t queued = 0;           // heap entries of the contact pass (at the front)
  std::size_t count = 0;            // heap entries
  std::size_t walk_count = 0;       // collectActive(): entries written when the budget stopped it
  int walk_top = 0;                 // collectActive(): stack height when the budget stopped it
  int phase = 0;                    // 1: walk, 2: time-ordered queue, 3: done
  bool walk_stopped = false;        // the walk was stopped by the budget
  bool pop_pending = false;
  bool cut = false;                 // stopped by the budget; proven free over [0, cut_t]
  double cut_t = 0.0;
  SweepResult result;               // its first hit so far
  std::vector<int> root_ranks;      // per root: its place in the single-lane walk's order
  // Per rank (frontier_): the work this lane did on that root since the last rebalance
  // (only the lane holding a root writes its entry; rebalanceLanes() reads and clears it).
  std::vector<std::int64_t> root_work;
  std::size_t walk_root = 0;        // collectActive(): roots started so far
  // Its share of a forked edge test (edgesCrossAt()): the rank of the root where it found the
  // first crossing edge (j, k) or was stopped by the budget; INT_MAX: neither.
  int edge_rank = std::numeric_limits<int>::max(), edge_cut_rank = std::numeric_limits<int>::max();
  int edge_j = -1, edge_k = -1;
};  // (alignas rounds its size up to whole lines: nothing of the next lane shares its last line)

}  // namespace vh::haptics::detail
