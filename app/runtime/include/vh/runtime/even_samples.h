#pragma once
/// @file
/// Thinning a path to a fixed number of samples spread evenly over it (the paths dynamic time
/// warping compares: session_metrics.h's devicePathSamples(), guidance.h's run path).

#include <cmath>
#include <cstddef>

namespace vh::runtime {

/// Of `count` samples spread evenly over n items, first and last included, the index of sample j:
/// round(j (n - 1) / (count - 1)). Needs count >= 2 and j < count.
inline std::size_t evenlySpacedIndex(std::size_t j, std::size_t n, std::size_t count) noexcept {
  return static_cast<std::size_t>(
      std::llround(static_cast<double>(j) * static_cast<double>(n - 1) / static_cast<double>(count - 1)));
}

}  // namespace vh::runtime
