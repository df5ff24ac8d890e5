// The GUI's sample ring (vh::audio::SampleRing): order kept across the wrap, full and empty
// ends, and a producer and a consumer thread that see every sample once, in order.
#include "vh/audio/sample_ring.h"

#include <algorithm>
#include <span>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

namespace vh::audio {
namespace {

TEST(SampleRing, KeepsOrderAcrossTheWrapAndStopsAtBothEnds) {
  SampleRing ring(5);
  const std::vector<float> a{1, 2, 3, 4};
  EXPECT_EQ(ring.push(a), 4u);
  std::vector<float> out(3);
  EXPECT_EQ(ring.pop(out), 3u);
  EXPECT_EQ(out, (std::vector<float>{1, 2, 3}));
  const std::vector<float> b{5, 6, 7, 8, 9};
  EXPECT_EQ(ring.push(b), 4u) << "one waiting, four places left";
  EXPECT_EQ(ring.size(), 5u);
  std::vector<float> all(10, -1.0f);
  EXPECT_EQ(ring.pop(all), 5u);
  EXPECT_EQ(std::vector<float>(all.begin(), all.begin() + 5), (std::vector<float>{4, 5, 6, 7, 8}));
  EXPECT_EQ(ring.pop(all), 0u);
  EXPECT_THROW(SampleRing(0), std::invalid_argument);
}

TEST(SampleRing, AProducerAndAConsumerThreadSeeEverySampleOnceInOrder) {
  SampleRing ring(257);
  constexpr int kSamples = 2000000;
  std::thread producer([&] {
    std::vector<float> block(97);
    int next = 0;
    while (next < kSamples) {
      const int n = std::min<int>(97, kSamples - next);
      for (int i = 0; i < n; ++i) block[static_cast<std::size_t>(i)] = static_cast<float>((next + i) % 65536);
      const std::size_t pushed = ring.push(std::span<const float>(block.data(), static_cast<std::size_t>(n)));
      next += static_cast<int>(pushed);
      // Full: give the core away (on a loaded machine the consumer may be waiting for it).
      if (pushed == 0) std::this_thread::yield();
    }
  });
  std::vector<float> got(61);
  int expected = 0, wrong = 0;
  while (expected < kSamples) {
    const std::size_t n = ring.pop(got);
    for (std::size_t i = 0; i < n; ++i, ++expected) wrong += got[i] != static_cast<float>(expected % 65536);
    if (n == 0) std::this_thread::yield();  // empty: likewise, for the producer
  }
  producer.join();
  EXPECT_EQ(wrong, 0);
  EXPECT_EQ(ring.size(), 0u);
}

}  // namespace
}  // namespace vh::audio
