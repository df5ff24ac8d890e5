// Tests of vh/runtime/sample_ring.h: the fields survive the trip, numbering, wrap-around (a
// sample is held until `capacity` newer ones arrive, then read() refuses it), the consumer's
// account of overwritten samples from the numbers, and one producer / one consumer thread: every
// sample read is whole (all its fields from the same push) and the numbers only go forward.
// The oracle is the producer's own numbering: every field is a function of the sample's number.
#include "vh/runtime/sample_ring.h"

#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <thread>

#include <gtest/gtest.h>

namespace vh::runtime {
namespace {

/// A sample whose every field derives from n.
CouplingSample numbered(std::uint64_t n) {
  const double x = static_cast<double>(n);
  CouplingSample s;
  s.X_WD.p_AB_m = {x, 2.0 * x, -x};
  s.X_WD.R_AB = Eigen::Quaterniond(x + 1.0, 0.5 * x, 0.25 * x, -x);  // not normalised: stored as read
  s.isovalue = 300.0 + x;
  s.gains.linear_N_per_m = 1000.0 + x;
  s.gains.angular_Nm_per_rad = 0.1 * x;
  s.gains.passivity_control = (n % 2) == 1;
  s.ok = (n % 3) != 0;
  s.connected = (n % 5) != 0;
  s.drill_button = (n % 7) == 0;
  return s;
}

/// Whether `s` is exactly numbered(n), field by field.
bool isNumbered(const CouplingSample& s, std::uint64_t n) {
  const CouplingSample e = numbered(n);
  return s.X_WD.p_AB_m == e.X_WD.p_AB_m && s.X_WD.R_AB.coeffs() == e.X_WD.R_AB.coeffs() && s.isovalue == e.isovalue &&
         s.gains.linear_N_per_m == e.gains.linear_N_per_m && s.gains.angular_Nm_per_rad == e.gains.angular_Nm_per_rad &&
         s.gains.passivity_control == e.gains.passivity_control && s.ok == e.ok && s.connected == e.connected &&
         s.drill_button == e.drill_button;
}

TEST(SampleRing, EveryFieldArrivesAndSamplesAreNumberedFromOne) {
  SampleRing ring(5);
  EXPECT_EQ(ring.capacity(), 8u);  // rounded up to a power of two
  EXPECT_EQ(SampleRing(1).capacity(), 2u);
  EXPECT_EQ(ring.latest(), 0u);
  CouplingSample out;
  EXPECT_FALSE(ring.read(1, out));  // nothing pushed yet
  for (std::uint64_t n = 1; n <= 7; ++n) EXPECT_EQ(ring.push(numbered(n)), n);
  EXPECT_EQ(ring.latest(), 7u);
  for (std::uint64_t n = 1; n <= 7; ++n) {
    ASSERT_TRUE(ring.read(n, out)) << n;
    EXPECT_TRUE(isNumbered(out, n)) << n;
  }
  EXPECT_FALSE(ring.read(8, out));  // not pushed yet (its slot still holds nothing)
}

TEST(SampleRing, WrapAroundOverwritesTheOldestAndReadRefusesIt) {
  SampleRing ring(4);
  const std::uint64_t capacity = ring.capacity();
  const std::uint64_t pushed = 5 * capacity + 3;  // the slots wrap five times and a bit
  for (std::uint64_t n = 1; n <= pushed; ++n) ring.push(numbered(n));
  CouplingSample out = numbered(999);
  for (std::uint64_t n = 1; n <= pushed - capacity; ++n) {
    EXPECT_FALSE(ring.read(n, out)) << "sample " << n << " was overwritten";
  }
  EXPECT_TRUE(isNumbered(out, 999)) << "a refused read leaves the output alone";
  for (std::uint64_t n = pushed - capacity + 1; n <= pushed; ++n) {
    ASSERT_TRUE(ring.read(n, out)) << n;
    EXPECT_TRUE(isNumbered(out, n)) << n;
  }
}

TEST(SampleRing, OverrunIsAccountedFromTheNumbers) {
  // A consumer that read up to sample `consumed`, then was away while the producer pushed
  // more than the ring holds: it finds the oldest it can still read and counts the rest lost,
  // as the solver thread counts skipped samples.
  SampleRing ring(8);
  for (std::uint64_t n = 1; n <= 3; ++n) ring.push(numbered(n));
  std::uint64_t consumed = 3;
  for (std::uint64_t n = 4; n <= 30; ++n) ring.push(numbered(n));
  CouplingSample out;
  std::uint64_t next = consumed + 1, lost = 0;
  while (!ring.read(next, out)) {
    ++lost;
    ++next;
  }
  EXPECT_EQ(next, ring.latest() - ring.capacity() + 1);  // the oldest held: 23
  EXPECT_EQ(lost, 19u);                                  // 4 .. 22
  EXPECT_TRUE(isNumbered(out, next));
  std::uint64_t read = 1;
  for (consumed = next; consumed < ring.latest(); ++consumed, ++read) ASSERT_TRUE(ring.read(consumed + 1, out));
  EXPECT_EQ(read, ring.capacity());
  EXPECT_EQ(read + lost, 27u);  // every sample after the first three: read or lost
}

TEST(SampleRing, TwoThreadsReadWholeSamplesInOrder) {
  SampleRing ring(16);
  constexpr std::uint64_t kSamples = 300'000;
  std::atomic<bool> consumer_started{false};
  std::thread producer([&] {
    while (!consumer_started.load(std::memory_order_acquire)) std::this_thread::yield();
    for (std::uint64_t n = 1; n <= kSamples; ++n) {
      ring.push(numbered(n));
      if (n % 512 == 0) std::this_thread::yield();  // overlap even on a loaded 2-core machine
    }
  });
  CouplingSample out;
  std::uint64_t consumed = 0, read = 0, lost = 0, torn = 0, refused_while_held = 0;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(120);
  consumer_started.store(true, std::memory_order_release);
  while (consumed < kSamples) {
    const std::uint64_t latest = ring.latest();
    if (latest == consumed) {
      ASSERT_LT(std::chrono::steady_clock::now(), deadline) << "producer did not finish";
      continue;
    }
    const std::uint64_t n = consumed + 1;
    if (ring.read(n, out)) {
      ++read;
      if (!isNumbered(out, n)) ++torn;
      consumed = n;
    } else if (ring.latest() - n >= ring.capacity() - 1) {
      ++lost;  // overwritten (or being overwritten): skip it, as the solver does
      consumed = n;
    } else {
      ++refused_while_held;  // held and not being written: must not happen
      consumed = n;
    }
  }
  producer.join();
  EXPECT_EQ(torn, 0u);
  EXPECT_EQ(refused_while_held, 0u);
  EXPECT_EQ(read + lost, kSamples);
  EXPECT_GT(read, 0u);
  ASSERT_TRUE(ring.read(kSamples, out));
  EXPECT_TRUE(isNumbered(out, kSamples));  // the last sample always arrives
}

}  // namespace
}  // namespace vh::runtime
