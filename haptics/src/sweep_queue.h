// The time-ordered queue of the sweeps (paper section 2.3), a binary min-heap of QueueEntry
// on the segment's start time: its entry and its order. Private to the collision detector
// (paper_sweep.cpp, accelerated_sweep.cpp, sweep_lanes.h).
#pragma once

#include <cstdint>

namespace vh::haptics {

namespace detail {
// One segment (or run of segments) of a point's path waiting in the queue.
struct QueueEntry {
  double t_begin;  // start of the segment to test
  int point;
  std::int64_t segment;  // segment index along the point's path
  // kAccelerated: segments [segment, segment + run) are not yet proven empty; 0 means sample
  // the end of `segment` directly (the paper's step).
  std::int64_t run = 0;
};
}  // namespace detail

// Each including file's own (internal linkage), as when the sweeps were one file.
namespace {
// Min-heap on t_begin over a preallocated array.
struct Later {
  template <typename E>
  bool operator()(const E& a, const E& b) const noexcept { return a.t_begin > b.t_begin; }
};
}  // namespace

}  // namespace vh::haptics
