// Tests of vh/runtime/tick_ring.h: capacity, overflow drops counted, wrap-around past the
// capacity many times, and one producer / one consumer thread: every record either arrives once,
// in order, byte for byte, or is counted as dropped. The oracle is the producer's own numbering.
#include "vh/runtime/tick_ring.h"

#include <array>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <cstring>
#include <stdexcept>
#include <thread>

#include <gtest/gtest.h>

namespace vh::runtime {
namespace {

/// A record whose every field derives from i (so a torn or misplaced one shows).
TickRecord numbered(std::uint64_t i) {
  TickRecord r;
  r.tick = i;
  r.time_s = static_cast<double>(i) * 1e-3;
  for (int k = 0; k < 3; ++k) r.force_W_N[k] = static_cast<double>(i) + k;
  r.contacts = static_cast<std::uint32_t>(i % 7);
  r.flags = static_cast<std::uint32_t>(i * 2654435761u);
  return r;
}

bool sameBytes(const TickRecord& a, const TickRecord& b) { return std::memcmp(&a, &b, sizeof a) == 0; }

TEST(TickRing, CapacityIsRoundedUpAndChecked) {
  EXPECT_EQ(TickRing(1).capacity(), 2u);
  EXPECT_EQ(TickRing(3).capacity(), 4u);
  EXPECT_EQ(TickRing(64).capacity(), 64u);
  EXPECT_THROW(TickRing(0), std::invalid_argument);
  EXPECT_THROW(TickRing((std::size_t{1} << 28) + 1), std::invalid_argument);
}

TEST(TickRing, OverflowDropsAndCountsTheNewest) {
  TickRing ring(3);  // rounded up to 4
  int accepted = 0;
  for (std::uint64_t i = 0; i < 10; ++i) accepted += ring.push(numbered(i)) ? 1 : 0;
  EXPECT_EQ(accepted, 4);
  EXPECT_EQ(ring.dropped(), 6u);
  EXPECT_EQ(ring.size(), 4u);
  std::array<TickRecord, 8> out{};
  ASSERT_EQ(ring.pop(out.data(), out.size()), 4u);
  for (std::uint64_t i = 0; i < 4; ++i) EXPECT_TRUE(sameBytes(out[i], numbered(i))) << i;  // the oldest kept
  EXPECT_TRUE(ring.push(numbered(42)));  // room again after the pop
  EXPECT_EQ(ring.size(), 1u);
  EXPECT_EQ(ring.dropped(), 6u);
}

TEST(TickRing, WrapsAroundManyTimesInOrder) {
  TickRing ring(8);
  std::array<TickRecord, 5> out{};
  std::uint64_t pushed = 0, popped = 0;
  for (int round = 0; round < 100; ++round) {  // 3 in, up to 5 out: the indices wrap ~40 times
    for (int k = 0; k < 3; ++k) ASSERT_TRUE(ring.push(numbered(pushed++)));
    const std::size_t n = ring.pop(out.data(), out.size());
    for (std::size_t k = 0; k < n; ++k) ASSERT_TRUE(sameBytes(out[k], numbered(popped++))) << popped;
  }
  EXPECT_EQ(popped, pushed);
  EXPECT_EQ(ring.size(), 0u);
  EXPECT_EQ(ring.dropped(), 0u);
  EXPECT_EQ(ring.pop(out.data(), 0), 0u);
}

TEST(TickRing, TwoThreadsDeliverEachRecordOnceInOrderOrCountItDropped) {
  TickRing ring(64);
  constexpr std::uint64_t kRecords = 200'000;
  std::atomic<bool> done{false};
  std::atomic<bool> consumer_started{false};
  std::uint64_t accepted = 0;
  std::thread producer([&] {
    while (!consumer_started.load(std::memory_order_acquire)) std::this_thread::yield();
    for (std::uint64_t i = 0; i < kRecords; ++i) {
      accepted += ring.push(numbered(i)) ? 1 : 0;
      if (i % 1024 == 0) std::this_thread::yield();  // overlap even on a loaded 2-core machine
    }
    done.store(true, std::memory_order_release);
  });
  std::array<TickRecord, 16> out{};
  std::uint64_t received = 0, out_of_order = 0, torn = 0;
  std::uint64_t next_at_least = 0;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(120);
  consumer_started.store(true, std::memory_order_release);
  while (true) {
    const bool finished = done.load(std::memory_order_acquire);
    const std::size_t n = ring.pop(out.data(), out.size());
    for (std::size_t k = 0; k < n; ++k) {
      if (out[k].tick < next_at_least) ++out_of_order;  // dropped ones leave gaps, never go back
      if (!sameBytes(out[k], numbered(out[k].tick))) ++torn;
      next_at_least = out[k].tick + 1;
    }
    received += n;
    if (finished && n == 0) break;
    ASSERT_LT(std::chrono::steady_clock::now(), deadline) << "producer did not finish";
  }
  producer.join();
  EXPECT_EQ(out_of_order, 0u);
  EXPECT_EQ(torn, 0u);
  EXPECT_EQ(received, accepted);
  EXPECT_EQ(received + ring.dropped(), kRecords);
  EXPECT_GT(received, out.size()) << "the consumer really ran concurrently";
}

}  // namespace
}  // namespace vh::runtime
