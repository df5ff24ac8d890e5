// Tests of vh/runtime/triple_buffer.h: semantics on one thread, and a producer/consumer stress
// test in which the consumer must never see a torn (half-written) value nor go back in time.
#include "vh/runtime/triple_buffer.h"

#include <array>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <thread>

#include <gtest/gtest.h>

namespace vh::runtime {
namespace {

TEST(TripleBuffer, LatestValueWinsAndFreshnessIsReported) {
  TripleBuffer<int> buffer;
  int value = -1;
  EXPECT_FALSE(buffer.read(value));  // nothing published yet
  buffer.writeSlot() = 1;
  buffer.publish();
  EXPECT_TRUE(buffer.read(value));
  EXPECT_EQ(value, 1);
  EXPECT_FALSE(buffer.read(value));  // same value again, not fresh
  EXPECT_EQ(value, 1);
  buffer.writeSlot() = 2;
  buffer.publish();
  buffer.writeSlot() = 3;
  buffer.publish();
  EXPECT_TRUE(buffer.read(value));
  EXPECT_EQ(value, 3);  // 2 was overwritten: the consumer only sees the latest
  EXPECT_FALSE(buffer.read(value));
  EXPECT_EQ(value, 3);
}

TEST(TripleBuffer, ProducerAndReaderNeverShareASlot) {
  // After any interleaving of publishes and reads the writer's slot is never the one read.
  TripleBuffer<int> buffer;
  int value = 0;
  for (int i = 1; i < 100; ++i) {
    buffer.writeSlot() = i;
    if (i % 3 != 0) buffer.publish();
    if (i % 2 == 0) buffer.read(value);
    buffer.writeSlot() = -1;  // scribble on the writer's slot: readers must not see it
    int check = 0;
    buffer.read(check);
    EXPECT_NE(check, -1) << i;
  }
}

/// A value that is easy to tear: every word must equal the sequence number (scrambled).
struct Wide {
  std::uint64_t seq = 0;
  std::array<std::uint64_t, 63> words{};
  void fill(std::uint64_t s) {
    seq = s;
    for (std::size_t i = 0; i < words.size(); ++i) words[i] = s * 0x9E3779B97F4A7C15ULL + i;
  }
  bool consistent() const {
    for (std::size_t i = 0; i < words.size(); ++i) {
      if (words[i] != seq * 0x9E3779B97F4A7C15ULL + i) return false;
    }
    return true;
  }
};

TEST(TripleBuffer, StressConsumerNeverSeesATornOrOlderValue) {
  TripleBuffer<Wide> buffer;
  std::atomic<bool> done{false};
  std::atomic<bool> consumer_started{false};
  std::atomic<std::uint64_t> fresh_reads{0};  // the consumer's, for the producer's half-way wait
  constexpr std::uint64_t kPublishes = 300'000;
  std::thread producer([&] {
    // Overlap with the consumer even on a loaded 2-core machine: start once it runs, give the
    // core away now and then, and half way wait until the consumer has read a value (so it read
    // one mid-run and another later, whatever the scheduler did; the deadline only ends a hang).
    while (!consumer_started.load(std::memory_order_acquire)) std::this_thread::yield();
    const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(60);
    for (std::uint64_t s = 1; s <= kPublishes; ++s) {
      buffer.writeSlot().fill(s);
      buffer.publish();
      if (s % 512 == 0) std::this_thread::yield();
      if (s == kPublishes / 2) {
        while (fresh_reads.load(std::memory_order_acquire) == 0 && std::chrono::steady_clock::now() < give_up)
          std::this_thread::yield();
      }
    }
    done.store(true, std::memory_order_release);
  });
  Wide value;
  std::uint64_t last_seq = 0, reads = 0, fresh = 0, torn = 0, backwards = 0;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(120);
  consumer_started.store(true, std::memory_order_release);
  while (true) {
    const bool finished = done.load(std::memory_order_acquire);
    if (buffer.read(value)) fresh_reads.store(++fresh, std::memory_order_release);
    ++reads;
    if (value.seq != 0 && !value.consistent()) ++torn;
    if (value.seq < last_seq) ++backwards;
    last_seq = value.seq;
    if (finished) break;
    ASSERT_LT(std::chrono::steady_clock::now(), deadline) << "producer did not finish";
  }
  producer.join();
  buffer.read(value);
  EXPECT_EQ(torn, 0u);
  EXPECT_EQ(backwards, 0u);
  EXPECT_EQ(value.seq, kPublishes);  // the last value always arrives
  EXPECT_TRUE(value.consistent());
  EXPECT_GT(fresh, 1u) << "reads " << reads;  // the consumer really ran concurrently
}

}  // namespace
}  // namespace vh::runtime
