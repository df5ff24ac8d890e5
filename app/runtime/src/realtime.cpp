// The real-time plumbing of vh/runtime/realtime.h.
#include "vh/runtime/realtime.h"

#include <pthread.h>
#include <sched.h>
#include <sys/mman.h>
#include <sys/prctl.h>
#include <sys/resource.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <mutex>

namespace vh::runtime {

namespace {

constexpr std::int64_t kNsPerS = 1'000'000'000;

std::int64_t toNs(const timespec& t) noexcept { return static_cast<std::int64_t>(t.tv_sec) * kNsPerS + t.tv_nsec; }

timespec fromNs(std::int64_t ns) noexcept {
  timespec t{};
  t.tv_sec = static_cast<time_t>(ns / kNsPerS);
  t.tv_nsec = static_cast<long>(ns % kNsPerS);
  return t;
}

// The process's memory lock (mlockall is process-wide): taken by the first coupling thread that
// may lock, dropped (munlockall) when the last user is gone: the coupling threads that run, and
// the MemoryLockHolds that keep it over a restart of the threads.
std::mutex& memoryLockMutex() {
  static std::mutex m;
  return m;
}
int memory_lock_users = 0;  // guarded by memoryLockMutex()
bool memory_locked = false;  // guarded by memoryLockMutex()

// A coupling thread's use of the lock: locks the process's memory unless it is locked already.
// @return whether it is locked (then the caller releases it with releaseMemoryLock()).
bool acquireMemoryLock() noexcept {
  const std::lock_guard<std::mutex> guard(memoryLockMutex());
  if (!memory_locked) {
#ifdef MCL_ONFAULT
    // ONFAULT: resident pages are locked now, later ones when first touched (no pre-faulting of
    // large reservations such as thread stacks).
    memory_locked = mlockall(MCL_CURRENT | MCL_FUTURE | MCL_ONFAULT) == 0;
    if (!memory_locked && errno == EINVAL) memory_locked = mlockall(MCL_CURRENT | MCL_FUTURE) == 0;
#else
    memory_locked = mlockall(MCL_CURRENT | MCL_FUTURE) == 0;
#endif
  }
  if (memory_locked) ++memory_lock_users;
  return memory_locked;
}

}  // namespace

std::int64_t monotonicNs() noexcept {
  timespec t{};
  clock_gettime(CLOCK_MONOTONIC, &t);
  return toNs(t);
}

double threadCpuTime_us() noexcept {
  timespec t{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
  return 1e-3 * static_cast<double>(toNs(t));
}

void releaseMemoryLock() noexcept {
  const std::lock_guard<std::mutex> guard(memoryLockMutex());
  if (memory_lock_users > 0 && --memory_lock_users == 0 && memory_locked) {
    munlockall();  // tens of ms on a process holding a CT
    memory_locked = false;
  }
}

void configureRealtime(int priority, bool lock_memory, bool& fifo, bool& locked) noexcept {
  prctl(PR_SET_TIMERSLACK, 1UL, 0UL, 0UL, 0UL);
  sched_param param{};
  param.sched_priority = priority;
  fifo = pthread_setschedparam(pthread_self(), SCHED_FIFO, &param) == 0;
  locked = false;
  if (!fifo || !lock_memory) return;
  // Lock only when the limit cannot make later allocations fail (root or unlimited).
  rlimit limit{};
  if (geteuid() != 0 && (getrlimit(RLIMIT_MEMLOCK, &limit) != 0 || limit.rlim_cur != RLIM_INFINITY)) return;
  locked = acquireMemoryLock();
}

MemoryLockHold::MemoryLockHold() noexcept {
  const std::lock_guard<std::mutex> guard(memoryLockMutex());
  if (memory_locked) {
    ++memory_lock_users;
    held_ = true;
  }
}

MemoryLockHold::~MemoryLockHold() {
  if (held_) releaseMemoryLock();
}

PeriodicClock::PeriodicClock(double period_s, std::uint64_t ticks_before) noexcept
    : period_ns_(std::max<std::int64_t>(1, std::llround(period_s * 1e9))),
      next_ns_(monotonicNs()),
      previous_begin_ns_(next_ns_),
      window_start_ns_(next_ns_) {
  timing_.nominal_rate_Hz = 1.0 / period_s;
  timing_.ticks = ticks_before;
}

bool PeriodicClock::wait() noexcept {
  next_ns_ += period_ns_;
  const timespec deadline = fromNs(next_ns_);
  while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &deadline, nullptr) == EINTR) {
  }
  const std::int64_t begin_ns = monotonicNs();
  interval_s_ = 1e-9 * static_cast<double>(begin_ns - previous_begin_ns_);
  const double jitter_us = 1e-3 * static_cast<double>(std::llabs(begin_ns - previous_begin_ns_ - period_ns_));
  window_jitter_us_ = std::max(window_jitter_us_, jitter_us);
  previous_begin_ns_ = begin_ns;
  const bool missed = begin_ns - next_ns_ > period_ns_;
  if (missed) {
    ++timing_.deadline_misses;
    next_ns_ = begin_ns;
  }
  return missed;
}

void PeriodicClock::tick(std::int64_t begin_ns, std::int64_t end_ns) noexcept {
  ++timing_.ticks;
  ++window_ticks_;
  const double tick_us = 1e-3 * static_cast<double>(end_ns - begin_ns);
  window_sum_us_ += tick_us;
  window_max_us_ = std::max(window_max_us_, tick_us);
  const std::int64_t window_ns = end_ns - window_start_ns_;
  if (window_ns >= kNsPerS || !have_window_) {
    timing_.rate_Hz = window_ns > 0 ? static_cast<double>(window_ticks_) * 1e9 / static_cast<double>(window_ns) : 0.0;
    timing_.mean_tick_us = window_sum_us_ / static_cast<double>(window_ticks_);
    timing_.max_tick_us = window_max_us_;
    timing_.jitter_us = window_jitter_us_;
  }
  if (window_ns >= kNsPerS) {
    have_window_ = true;
    window_start_ns_ = end_ns;
    window_ticks_ = 0;
    window_sum_us_ = 0.0;
    window_max_us_ = 0.0;
    window_jitter_us_ = 0.0;
  }
}

}  // namespace vh::runtime
