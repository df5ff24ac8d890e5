#include "vh/haptics/worker_pool.h"

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

WorkerPool::WorkerPool(int lanes) : lanes_(lanes) {
  if (lanes < 1 || lanes > kMaxLanes)
    throw std::invalid_argument("WorkerPool: " + std::to_string(lanes) + " lanes, must be in [1, " +
                                std::to_string(kMaxLanes) + "]");
  threads_.reserve(static_cast<std::size_t>(lanes - 1));
  try {
    for (int lane = 1; lane < lanes; ++lane) threads_.emplace_back([this, lane] { threadLoop(lane); });
  } catch (...) {
    stop_.store(true, std::memory_order_release);
    epoch_.fetch_add(1, std::memory_order_release);
    epoch_.notify_all();
    for (auto& t : threads_) t.join();
    throw;
  }
}

WorkerPool::~WorkerPool() {
  stop_.store(true, std::memory_order_release);
  epoch_.fetch_add(1, std::memory_order_release);
  epoch_.notify_all();
  for (auto& t : threads_) t.join();
}

void WorkerPool::threadLoop(int lane) noexcept {
  std::uint32_t seen = 0;
  for (;;) {
    std::uint32_t now = epoch_.load(std::memory_order_acquire);
    for (int spin = 0; now == seen && spin < kSpinIterations; ++spin) {
      cpuRelax();
      now = epoch_.load(std::memory_order_acquire);
    }
    while (now == seen) {
      sleeping_.fetch_add(1, std::memory_order_seq_cst);
      epoch_.wait(seen, std::memory_order_seq_cst);
      sleeping_.fetch_sub(1, std::memory_order_relaxed);
      now = epoch_.load(std::memory_order_acquire);
    }
    seen = now;
    if (stop_.load(std::memory_order_acquire)) return;
    job_(context_, lane);
    running_.fetch_sub(1, std::memory_order_release);
  }
}

void WorkerPool::run(Job job, void* context) noexcept {
  if (lanes_ == 1) {
    job(context, 0);
    return;
  }
  job_ = job;
  context_ = context;
  running_.store(lanes_ - 1, std::memory_order_relaxed);
  epoch_.fetch_add(1, std::memory_order_seq_cst);
  // A thread that announced it sleeps either sees the new epoch in wait() or is woken here.
  if (sleeping_.load(std::memory_order_seq_cst) > 0) epoch_.notify_all();
  job(context, 0);
  while (running_.load(std::memory_order_acquire) != 0) cpuRelax();
}

}  // namespace vh::haptics
