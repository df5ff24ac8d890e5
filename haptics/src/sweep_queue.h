// The time-ordered queue of the sweeps (paper section 2.3), a binary min-heap of
// CollisionDetector::QueueEntry on the segment's start time: its order. Private to the
// collision detector (paper_sweep.cpp, accelerated_sweep.cpp).
#pragma once

namespace vh::haptics {

// Each including file's own (internal linkage), as when the sweeps were one file.
namespace {
// Min-heap on t_begin over a preallocated array.
struct Later {
  template <typename E>
  bool operator()(const E& a, const E& b) const noexcept { return a.t_begin > b.t_begin; }
};
}  // namespace

}  // namespace vh::haptics
