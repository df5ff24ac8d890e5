#pragma once
/// @file
/// Timing statistics of one haptic thread (the coupling or the solver thread of haptic_thread.h),
/// filled by its PeriodicClock (realtime.h) and shown through HapticSnapshot (haptic_snapshot.h).

#include <cstdint>

namespace vh::runtime {

/// Timing of one of the two haptic threads. Rate, tick times and jitter are over the last
/// rolling window of one second (until the first window closes, over the running one).
struct ThreadTiming {
  double nominal_rate_Hz = 0.0;       ///< The rate the thread is set to [Hz].
  double rate_Hz = 0.0;               ///< Ticks per second over the window [Hz].
  double mean_tick_us = 0.0;          ///< Mean execution time of a tick [us].
  double max_tick_us = 0.0;           ///< Longest tick execution time [us].
  /// Period jitter: the largest |actual interval between two wake-ups - nominal period| [us].
  double jitter_us = 0.0;
  std::uint64_t deadline_misses = 0;  ///< Wake-ups that started > 1 period late (total since start()).
  std::uint64_t ticks = 0;            ///< Ticks since the thread was created (total).
};

}  // namespace vh::runtime
