#pragma once
/// @file
/// Lock-free single-producer / single-consumer triple buffer: the producer (haptic thread)
/// publishes whole values, the consumer (render thread) always reads the latest complete one.
/// Neither side blocks or allocates.

#include <array>
#include <atomic>
#include <cstdint>

namespace vh::runtime {

template <typename T>
class TripleBuffer {
 public:
  /// Producer: the slot to fill; call publish() when it is complete.
  T& writeSlot() noexcept { return slots_[write_]; }
  /// Producer: makes the filled slot the latest value.
  void publish() noexcept {
    const std::uint8_t prev = middle_.exchange(static_cast<std::uint8_t>(write_ | kDirty),
                                               std::memory_order_acq_rel);
    write_ = prev & kIndexMask;
  }
  /// Consumer: the latest published value (or the previous one when nothing new arrived).
  /// @return true when the value is new since the last call.
  bool read(T& out) noexcept {
    bool fresh = false;
    if (middle_.load(std::memory_order_relaxed) & kDirty) {
      const std::uint8_t prev = middle_.exchange(read_, std::memory_order_acq_rel);
      read_ = prev & kIndexMask;
      fresh = true;
    }
    out = slots_[read_];
    return fresh;
  }

 private:
  static constexpr std::uint8_t kDirty = 0x4;
  static constexpr std::uint8_t kIndexMask = 0x3;
  std::array<T, 3> slots_{};
  std::uint8_t write_ = 0;
  std::uint8_t read_ = 1;
  std::atomic<std::uint8_t> middle_{2};
};

}  // namespace vh::runtime
