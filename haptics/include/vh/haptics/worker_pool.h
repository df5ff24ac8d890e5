#pragma once
/// @file
/// A fixed pool of solver threads for fork-join inside one servo tick (the configuration
/// solver's collision detection runs its lanes on it: haptics/README.md, "Several cores").

#include <atomic>
#include <cstdint>
#include <memory>
#include <thread>
#include <vector>

namespace vh::haptics {

/// Fixed pool of `lanes - 1` threads plus the caller: run() hands lane 0 to the calling thread
/// and lanes 1 .. lanes - 1 to the pool's threads, and returns when every lane is done.
///
/// run() neither allocates nor locks: the job is published through an atomic epoch; the threads
/// spin on it for spin_us after each job (servo ticks come every millisecond, several forks per
/// tick: a thread woken from sleep costs tens to hundreds of microseconds, more than a fork's
/// work), then sleep on it (std::atomic::wait, a futex), and the caller wakes them only when one
/// sleeps. The caller spins until the lanes are done. So while the solver runs, the pool's
/// threads keep their cores busy: give it only cores the coupling thread does not need.
/// The threads inherit the creating thread's scheduling policy and affinity; they never run
/// anything but jobs given to run().
/// Thread safety: run() may be called from any thread (a second concurrent caller runs its lanes
/// itself).
class WorkerPool {
 public:
  /// A lane's work: `context` as given to run(), `lane` in [0, lanes()). Must not throw.
  using Job = void (*)(void* context, int lane) noexcept;

  /// How long a thread spins on the epoch after a job before it sleeps [us]: two servo periods
  /// at 1 kHz.
  static constexpr double kDefaultSpin_us = 2000.0;
  /// Most lanes a pool runs.
  static constexpr int kMaxLanes = 64;

  /// @param lanes the lanes of each run(), in [1, kMaxLanes]: lanes - 1 threads are started.
  /// @param spin_us how long a thread spins for the next job before it sleeps [us], >= 0.
  /// @throws std::invalid_argument when lanes is outside [1, kMaxLanes] or spin_us is negative
  ///         or not finite; std::system_error when a thread cannot be started.
  explicit WorkerPool(int lanes, double spin_us = kDefaultSpin_us);
  /// Stops and joins the threads.
  ~WorkerPool();
  WorkerPool(const WorkerPool&) = delete;
  WorkerPool& operator=(const WorkerPool&) = delete;

  int lanes() const noexcept { return lanes_; }

  /// The process's shared pool for callers of up to `lanes` lanes: the largest live pool when it
  /// has at least `lanes` lanes, else a new pool of `lanes` lanes (which becomes the largest).
  /// Several renderers in one process (a benchmark's interleaved modes on different lane counts,
  /// a replay beside the live solver) so share one set of threads, and the threads that spin
  /// between jobs never outnumber the most cores one caller asked for: pools per lane count
  /// would each spin, and on a 16-core machine a sweep over 1 to 16 lanes ran 26 spinning
  /// threads. Ask for the largest count first (a caller that asks for more later gets a new
  /// pool beside the old one). Run a smaller caller's jobs with run(job, context, its lanes).
  /// Not for the servo path (it may start threads).
  /// @throws as the constructor.
  static std::shared_ptr<WorkerPool> shared(int lanes);

  /// Runs job(context, lane) for lane in [0, min(lanes, lanes())) (every lane when lanes <= 0),
  /// lane 0 on the caller, and returns when all are done (their writes are visible to the
  /// caller); the pool's other threads skip the job. No allocation, no lock: while another thread
  /// runs a job on the same pool, this call runs its lanes in turn on the caller instead of
  /// waiting.
  void run(Job job, void* context, int lanes = 0) noexcept;

 private:
  void threadLoop(int lane) noexcept;

  int lanes_ = 1;
  double spin_us_ = kDefaultSpin_us;
  Job job_ = nullptr;
  void* context_ = nullptr;
  // The job's sequence number above kLaneMask and its lane count below: one word, so that a
  // thread reads the lane count of the very job whose epoch it saw.
  static constexpr std::uint32_t kLaneMask = 0xFF;
  static constexpr std::uint32_t kEpochStep = kLaneMask + 1;
  static_assert(kMaxLanes <= static_cast<int>(kLaneMask), "a job's lane count must fit below the epoch's sequence");
  alignas(64) std::atomic<std::uint32_t> epoch_{0};
  alignas(64) std::atomic<int> running_{0};   // lanes of the current job not yet done
  alignas(64) std::atomic<int> sleeping_{0};  // threads waiting on epoch_
  std::atomic<bool> stop_{false};
  std::atomic<bool> busy_{false};  // a job is running
  std::vector<std::thread> threads_;
};

}  // namespace vh::haptics
