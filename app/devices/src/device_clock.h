#pragma once
// The drivers' sample clock (private to vh::devices): seconds of std::chrono::steady_clock, the
// time base of DeviceSample::time_s and of the velocity estimate.
#include <chrono>

namespace vh::devices::detail {

/// Seconds since the steady clock's epoch [s]; monotonic, never throws.
inline double steadySeconds() noexcept {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

}  // namespace vh::devices::detail
