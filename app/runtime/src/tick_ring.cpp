// The servo thread's record ring of vh/runtime/tick_ring.h.
#include "vh/runtime/tick_ring.h"

#include <algorithm>
#include <stdexcept>
#include <string>

namespace vh::runtime {

namespace {

std::size_t roundUpPow2(std::size_t n) {
  std::size_t c = 2;
  while (c < n) c <<= 1;
  return c;
}

}  // namespace

TickRing::TickRing(std::size_t capacity) {
  if (capacity == 0 || capacity > (std::size_t{1} << 28))
    throw std::invalid_argument("TickRing: capacity must be in [1, 2^28], got " + std::to_string(capacity));
  const std::size_t n = roundUpPow2(capacity);
  slots_ = std::make_unique<TickRecord[]>(n);
  mask_ = n - 1;
}

bool TickRing::push(const TickRecord& record) noexcept {
  const std::uint64_t head = head_.load(std::memory_order_relaxed);
  const std::uint64_t tail = tail_.load(std::memory_order_acquire);
  if (head - tail > mask_) {
    dropped_.fetch_add(1, std::memory_order_relaxed);
    return false;
  }
  slots_[static_cast<std::size_t>(head) & mask_] = record;
  head_.store(head + 1, std::memory_order_release);
  return true;
}

std::size_t TickRing::pop(TickRecord* out, std::size_t max) noexcept {
  const std::uint64_t tail = tail_.load(std::memory_order_relaxed);
  const std::uint64_t head = head_.load(std::memory_order_acquire);
  const std::size_t n = static_cast<std::size_t>(std::min<std::uint64_t>(head - tail, max));
  for (std::size_t i = 0; i < n; ++i) out[i] = slots_[static_cast<std::size_t>(tail + i) & mask_];
  tail_.store(tail + n, std::memory_order_release);
  return n;
}

std::size_t TickRing::size() const noexcept {
  const std::uint64_t tail = tail_.load(std::memory_order_acquire);
  const std::uint64_t head = head_.load(std::memory_order_acquire);
  return static_cast<std::size_t>(head - tail);
}

}  // namespace vh::runtime
