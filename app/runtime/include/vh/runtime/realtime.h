#pragma once
/// @file
/// The real-time plumbing of the haptic threads (haptic_thread.h; docs/devices.md, "Servo loop
/// timing"): the monotonic clock, the best-effort SCHED_FIFO set-up of a thread, the process's
/// memory lock (mlockall) shared by the coupling threads and MemoryLockHold, and the
/// absolute-deadline periodic wake-up that keeps a thread's ThreadTiming. Linux (POSIX) only.
/// Nothing here throws or allocates after construction; only the memory lock takes a mutex
/// (once at a thread's start and once at its end, never inside a tick).

#include <cstdint>

#include "vh/runtime/thread_timing.h"

namespace vh::runtime {

/// CLOCK_MONOTONIC (std::chrono::steady_clock's clock on Linux) now [ns].
std::int64_t monotonicNs() noexcept;

/// CPU time the calling thread has used [us] (CLOCK_THREAD_CPUTIME_ID: it does not advance while
/// the thread is preempted), to tell a computation's own cost from a busy machine's delays.
double threadCpuTime_us() noexcept;

/// Best effort real-time set-up of the calling thread: 1 ns timer slack, SCHED_FIFO at
/// `priority` (1..99) and, when that worked and `lock_memory`, the process's memory lock
/// (mlockall, only for root or with an unlimited RLIMIT_MEMLOCK, so that later allocations
/// cannot fail on the limit). Every failure (EPERM in a container or for a normal user) silently
/// leaves the default.
/// @param[out] fifo whether the thread got SCHED_FIFO.
/// @param[out] locked whether the memory is locked for this thread; then the thread calls
///             releaseMemoryLock() once when it ends.
void configureRealtime(int priority, bool lock_memory, bool& fifo, bool& locked) noexcept;

/// Drops one user of the process's memory lock (configureRealtime() with `locked` true); the
/// last user unlocks (munlockall: tens of ms on a process holding a CT).
void releaseMemoryLock() noexcept;

/// Keeps the process's memory lock over a stop and a start of haptic threads. The coupling thread
/// locks the process's memory when it may (SCHED_FIFO, and root or an unlimited RLIMIT_MEMLOCK:
/// mlockall, process-wide), and the lock is dropped (munlockall, 20 to 40 ms on a process holding a
/// 512 x 512 x 140 CT, in the coupling thread's last act, which stop() waits for) only when the last
/// coupling thread and the last hold are gone. A hold made while the memory is locked keeps it
/// locked until the hold is destroyed; made while it is not, it does nothing.
/// Every restart of running threads by the Session holds one (a recording's, and a new tool,
/// device, segmentation, edge test, drill or monitor), so neither the stop nor the new threads'
/// start pays for unlocking and locking again.
class MemoryLockHold {
 public:
  MemoryLockHold() noexcept;
  ~MemoryLockHold();
  MemoryLockHold(const MemoryLockHold&) = delete;
  MemoryLockHold& operator=(const MemoryLockHold&) = delete;
  /// Whether the memory was locked when this hold was made (then it keeps it locked).
  bool holding() const noexcept { return held_; }

 private:
  bool held_ = false;
};

/// An absolute-deadline periodic wake-up (clock_nanosleep on CLOCK_MONOTONIC) with the
/// statistics of ThreadTiming: on an overrun of more than one period it counts a deadline miss
/// and resynchronises (no catch-up wake-ups). One thread.
class PeriodicClock {
 public:
  /// @param period_s the period [s] (> 0); @param ticks_before ThreadTiming::ticks to start from.
  PeriodicClock(double period_s, std::uint64_t ticks_before) noexcept;

  /// Sleeps until the next deadline. @return whether this wake-up missed its deadline.
  bool wait() noexcept;
  /// The interval between the last two wake-ups [s].
  double interval_s() const noexcept { return interval_s_; }

  /// One tick that ran from begin_ns to end_ns (monotonicNs()); closes the window after 1 s.
  void tick(std::int64_t begin_ns, std::int64_t end_ns) noexcept;
  const ThreadTiming& timing() const noexcept { return timing_; }

 private:
  std::int64_t period_ns_;
  std::int64_t next_ns_;
  std::int64_t previous_begin_ns_;
  std::int64_t window_start_ns_;
  double interval_s_ = 0.0;
  std::uint64_t window_ticks_ = 0;
  double window_sum_us_ = 0.0, window_max_us_ = 0.0, window_jitter_us_ = 0.0;
  bool have_window_ = false;
  ThreadTiming timing_;
};

}  // namespace vh::runtime
