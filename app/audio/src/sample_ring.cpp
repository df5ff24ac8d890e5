#include "vh/audio/sample_ring.h"

#include <algorithm>
#include <stdexcept>

namespace vh::audio {

SampleRing::SampleRing(std::size_t capacity) {
  if (capacity == 0) throw std::invalid_argument("SampleRing: capacity must be > 0");
  buffer_.assign(capacity, 0.0f);
}

std::size_t SampleRing::push(std::span<const float> samples) noexcept {
  const std::uint64_t head = head_.load(std::memory_order_relaxed);
  const std::uint64_t tail = tail_.load(std::memory_order_acquire);  // the consumer's reads are done
  const std::size_t n = std::min(samples.size(), buffer_.size() - static_cast<std::size_t>(head - tail));
  for (std::size_t i = 0; i < n; ++i) buffer_[(head + i) % buffer_.size()] = samples[i];
  head_.store(head + n, std::memory_order_release);  // the samples before the new head
  return n;
}

std::size_t SampleRing::pop(std::span<float> out) noexcept {
  const std::uint64_t tail = tail_.load(std::memory_order_relaxed);
  const std::uint64_t head = head_.load(std::memory_order_acquire);  // the producer's writes are seen
  const std::size_t n = std::min(out.size(), static_cast<std::size_t>(head - tail));
  for (std::size_t i = 0; i < n; ++i) out[i] = buffer_[(tail + i) % buffer_.size()];
  tail_.store(tail + n, std::memory_order_release);
  return n;
}

}  // namespace vh::audio
