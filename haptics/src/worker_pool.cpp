#include "vh/haptics/worker_pool.h"

#include <chrono>
#include <cmath>
#include <mutex>
#include <stdexcept>
#include <string>

#if defined(__x86_64__) || defined(__i386__)
#include <immintrin.h>
#endif

namespace vh::haptics {
namespace {
inline void cpuRelax() noexcept {
#if defined(__x86_64__) || defined(__i386__)
  _mm_pause();
#else
  std::this_thread::yield();
#endif
}
}  // namespace

WorkerPool::WorkerPool(int lanes, double spin_us) : lanes_(lanes), spin_us_(spin_us) {
  if (lanes < 1 || lanes > kMaxLanes)
    throw std::invalid_argument("WorkerPool: " + std::to_string(lanes) + " lanes, must be in [1, " +
                                std::to_string(kMaxLanes) + "]");
  if (!(spin_us >= 0.0) || !std::isfinite(spin_us))
    throw std::invalid_argument("WorkerPool: the spin time must be finite and >= 0 us");
  threads_.reserve(static_cast<std::size_t>(lanes - 1));
  try {
    for (int lane = 1; lane < lanes; ++lane) threads_.emplace_back([this, lane] { threadLoop(lane); });
  } catch (...) {
    stop_.store(true, std::memory_order_release);
    epoch_.fetch_add(kEpochStep, std::memory_order_release);
    epoch_.notify_all();
    for (auto& t : threads_) t.join();
    throw;
  }
}

WorkerPool::~WorkerPool() {
  stop_.store(true, std::memory_order_release);
  epoch_.fetch_add(kEpochStep, std::memory_order_release);
  epoch_.notify_all();
  for (auto& t : threads_) t.join();
}

void WorkerPool::threadLoop(int lane) noexcept {
  std::uint32_t seen = 0;
  for (;;) {
    std::uint32_t now = epoch_.load(std::memory_order_acquire);
    if (now == seen) {
      // Spin, reading the clock every 64 pauses, until spin_us has passed since the last job.
      const auto until = std::chrono::steady_clock::now() +
                         std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                             std::chrono::duration<double, std::micro>(spin_us_));
      for (int spin = 1; now == seen; ++spin) {
        cpuRelax();
        now = epoch_.load(std::memory_order_acquire);
        if ((spin & 63) == 0 && std::chrono::steady_clock::now() >= until) break;
      }
    }
    while (now == seen) {
      sleeping_.fetch_add(1, std::memory_order_seq_cst);
      epoch_.wait(seen, std::memory_order_seq_cst);
      sleeping_.fetch_sub(1, std::memory_order_relaxed);
      now = epoch_.load(std::memory_order_acquire);
    }
    seen = now;
    if (stop_.load(std::memory_order_acquire)) return;
    // The job's lane count travels in the epoch word itself: a thread that skipped the last job
    // may see its epoch only after the caller began writing the next one.
    if (lane < static_cast<int>(now & kLaneMask)) {
      job_(context_, lane);
      running_.fetch_sub(1, std::memory_order_release);
    }
  }
}

std::shared_ptr<WorkerPool> WorkerPool::shared(int lanes) {
  static std::mutex mutex;
  static std::weak_ptr<WorkerPool> largest;
  const std::lock_guard<std::mutex> lock(mutex);
  std::shared_ptr<WorkerPool> pool = largest.lock();
  if (pool && pool->lanes() >= lanes) return pool;
  std::shared_ptr<WorkerPool> made = std::make_shared<WorkerPool>(lanes);
  largest = made;
  return made;
}

void WorkerPool::run(Job job, void* context, int lanes) noexcept {
  const int n = lanes <= 0 || lanes > lanes_ ? lanes_ : lanes;
  if (n == 1 || busy_.exchange(true, std::memory_order_acquire)) {
    for (int lane = 0; lane < n; ++lane) job(context, lane);
    return;
  }
  job_ = job;
  context_ = context;
  running_.store(n - 1, std::memory_order_relaxed);
  const std::uint32_t epoch = epoch_.load(std::memory_order_relaxed);
  epoch_.store(((epoch & ~kLaneMask) + kEpochStep) | static_cast<std::uint32_t>(n), std::memory_order_seq_cst);
  // A thread that announced it sleeps either sees the new epoch in wait() or is woken here.
  if (sleeping_.load(std::memory_order_seq_cst) > 0) epoch_.notify_all();
  job(context, 0);
  while (running_.load(std::memory_order_acquire) != 0) cpuRelax();
  busy_.store(false, std::memory_order_release);
}

}  // namespace vh::haptics
