#pragma once
/// @file
/// The servo thread's TickRecords on their way to the recording's writer thread (recording.h):
/// a preallocated lock-free single-producer / single-consumer ring that drops (and counts)
/// rather than waits.

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <memory>

#include "vh/runtime/tick_record.h"

namespace vh::runtime {

/// Preallocated lock-free ring for exactly one producer thread (push) and one consumer thread
/// (pop). push() never blocks, allocates or throws; when full the record is dropped and counted.
class TickRing {
 public:
  /// @param capacity records; rounded up to a power of two (>= 2).
  /// @throws std::invalid_argument when capacity is 0 or absurdly large (> 2^28).
  explicit TickRing(std::size_t capacity);

  /// Producer only. @return false (and counts a drop) when the ring is full.
  bool push(const TickRecord& record) noexcept;
  /// Consumer only: moves up to `max` records into `out`. @return how many.
  std::size_t pop(TickRecord* out, std::size_t max) noexcept;
  /// Records dropped because the ring was full (any thread).
  std::uint64_t dropped() const noexcept { return dropped_.load(std::memory_order_relaxed); }
  /// Records waiting (approximate from a third thread; exact from producer or consumer).
  std::size_t size() const noexcept;
  std::size_t capacity() const noexcept { return mask_ + 1; }

 private:
  std::unique_ptr<TickRecord[]> slots_;
  std::size_t mask_;
  alignas(64) std::atomic<std::uint64_t> head_{0};  // next write (producer)
  alignas(64) std::atomic<std::uint64_t> tail_{0};  // next read (consumer)
  alignas(64) std::atomic<std::uint64_t> dropped_{0};
};

}  // namespace vh::runtime
