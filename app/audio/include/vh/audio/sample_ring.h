#pragma once
/// @file
/// A lock-free single-producer / single-consumer ring of float samples: the GUI thread renders
/// the mixer's samples into it, the audio output reads them from its own thread (the sound's
/// path in the GUI: ui/sound_output.h). Capacity fixed at construction; push() and pop() never
/// allocate, block or throw.

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

namespace vh::audio {

class SampleRing {
 public:
  /// @param capacity samples the ring holds (> 0; e.g. a quarter of a second at the output rate).
  /// @throws std::invalid_argument for 0.
  explicit SampleRing(std::size_t capacity);

  /// Producer: appends as many of `samples` as fit. @return how many were appended.
  std::size_t push(std::span<const float> samples) noexcept;
  /// Consumer: moves up to out.size() of the oldest samples into `out`. @return how many.
  std::size_t pop(std::span<float> out) noexcept;
  /// Samples waiting now (exact on either side for its own view; the other side may move it).
  std::size_t size() const noexcept {
    return static_cast<std::size_t>(head_.load(std::memory_order_acquire) - tail_.load(std::memory_order_acquire));
  }
  std::size_t capacity() const noexcept { return buffer_.size(); }
  /// Samples the consumer asked for and did not get (the producer fell behind), total.
  std::uint64_t underruns() const noexcept { return underruns_.load(std::memory_order_relaxed); }
  /// Consumer: counts `n` samples it had to make up (silence) in underruns().
  void countUnderrun(std::size_t n) noexcept { underruns_.fetch_add(n, std::memory_order_relaxed); }

 private:
  std::vector<float> buffer_;
  alignas(64) std::atomic<std::uint64_t> head_{0};  // written by the producer
  alignas(64) std::atomic<std::uint64_t> tail_{0};  // written by the consumer
  std::atomic<std::uint64_t> underruns_{0};
};

}  // namespace vh::audio
