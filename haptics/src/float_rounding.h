// Doubles kept as floats with the rounding on the safe side, for bounds stored in half the
// memory (the step bricks' derivative ranges, the bricks' local Lipschitz bounds, the edge
// test's certificates): the float nearest x at or below it, or at or above it.
#pragma once

#include <cmath>
#include <limits>

namespace vh::haptics {

inline float floatBelow(double x) noexcept {
  const auto f = static_cast<float>(x);
  return static_cast<double>(f) > x ? std::nextafter(f, -std::numeric_limits<float>::infinity()) : f;
}

inline float floatAbove(double x) noexcept {
  const auto f = static_cast<float>(x);
  return static_cast<double>(f) < x ? std::nextafter(f, std::numeric_limits<float>::infinity()) : f;
}

}  // namespace vh::haptics
