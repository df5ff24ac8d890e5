// The solver's worker pool (haptics/README.md, "Several cores"): every lane runs exactly once
// per run(), on distinct threads, and its writes are visible to the caller when run() returns;
// the pool survives many back-to-back forks and forks after its threads went to sleep.
#include <atomic>
#include <chrono>
#include <set>
#include <stdexcept>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "vh/haptics/worker_pool.h"

namespace vh::haptics {
namespace {

struct Tally {
  std::vector<int> runs;                     // per lane, plain ints: run() must publish them
  std::vector<std::thread::id> thread_of;    // per lane, the last thread that ran it
  std::atomic<int> concurrent{0}, most_concurrent{0};
};

void countLane(void* context, int lane) noexcept {
  auto* tally = static_cast<Tally*>(context);
  const int now = tally->concurrent.fetch_add(1) + 1;
  int seen = tally->most_concurrent.load();
  while (now > seen && !tally->most_concurrent.compare_exchange_weak(seen, now)) {
  }
  ++tally->runs[static_cast<std::size_t>(lane)];
  tally->thread_of[static_cast<std::size_t>(lane)] = std::this_thread::get_id();
  // Long enough that the lanes overlap when there are cores for them.
  const auto until = std::chrono::steady_clock::now() + std::chrono::microseconds(20);
  while (std::chrono::steady_clock::now() < until) {
  }
  tally->concurrent.fetch_sub(1);
}

TEST(WorkerPool, EveryLaneRunsOncePerRunOnItsOwnThread) {
  for (int lanes : {1, 2, 3, 5}) {
    WorkerPool pool(lanes);
    ASSERT_EQ(pool.lanes(), lanes);
    Tally tally;
    tally.runs.assign(static_cast<std::size_t>(lanes), 0);
    tally.thread_of.assign(static_cast<std::size_t>(lanes), {});
    constexpr int kRuns = 2000;
    for (int r = 0; r < kRuns; ++r) {
      pool.run(&countLane, &tally);
      if (r == kRuns / 2) std::this_thread::sleep_for(std::chrono::milliseconds(30));  // the threads sleep
    }
    std::set<std::thread::id> threads(tally.thread_of.begin(), tally.thread_of.end());
    for (int lane = 0; lane < lanes; ++lane) EXPECT_EQ(tally.runs[static_cast<std::size_t>(lane)], kRuns) << lanes << " lanes, lane " << lane;
    EXPECT_EQ(threads.size(), static_cast<std::size_t>(lanes)) << "each lane on its own thread";
    EXPECT_EQ(tally.thread_of[0], std::this_thread::get_id()) << "lane 0 runs on the caller";
    EXPECT_LE(tally.most_concurrent.load(), lanes);
    std::cout << lanes << " lanes: at most " << tally.most_concurrent.load() << " ran at once\n";
  }
}

// Two threads forking on the one shared pool at once: neither waits for the other (the second
// runs its lanes itself), and every lane of both runs once per run().
TEST(WorkerPool, SharedPoolServesTwoCallersAtOnce) {
  const auto pool = WorkerPool::shared(3);
  EXPECT_EQ(pool, WorkerPool::shared(3)) << "one pool for callers of the same count";
  Tally a, b;
  for (Tally* t : {&a, &b}) {
    t->runs.assign(3, 0);
    t->thread_of.assign(3, {});
  }
  constexpr int kRuns = 500;
  std::thread other([&] {
    for (int r = 0; r < kRuns; ++r) pool->run(&countLane, &b);
  });
  for (int r = 0; r < kRuns; ++r) pool->run(&countLane, &a);
  other.join();
  for (int lane = 0; lane < 3; ++lane) {
    EXPECT_EQ(a.runs[static_cast<std::size_t>(lane)], kRuns);
    EXPECT_EQ(b.runs[static_cast<std::size_t>(lane)], kRuns);
  }
}

// A caller of fewer lanes on a larger pool: exactly its lanes run, once each per run(), on
// distinct threads, lane 0 on the caller; the pool's other threads leave the job alone, and a
// later full run still reaches every lane.
TEST(WorkerPool, RunsOnlyTheLanesItIsGivenOnALargerPool) {
  WorkerPool pool(5);
  for (int lanes : {1, 2, 3, 5}) {
    Tally tally;
    tally.runs.assign(5, 0);
    tally.thread_of.assign(5, {});
    constexpr int kRuns = 1000;
    for (int r = 0; r < kRuns; ++r) {
      pool.run(&countLane, &tally, lanes);
      if (r == kRuns / 2) std::this_thread::sleep_for(std::chrono::milliseconds(30));  // the threads sleep
    }
    for (int lane = 0; lane < 5; ++lane)
      EXPECT_EQ(tally.runs[static_cast<std::size_t>(lane)], lane < lanes ? kRuns : 0) << lanes << " lanes, lane " << lane;
    std::set<std::thread::id> threads(tally.thread_of.begin(), tally.thread_of.begin() + lanes);
    EXPECT_EQ(threads.size(), static_cast<std::size_t>(lanes)) << "each lane on its own thread";
    EXPECT_EQ(tally.thread_of[0], std::this_thread::get_id()) << "lane 0 runs on the caller";
    EXPECT_LE(tally.most_concurrent.load(), lanes);
  }
}

// Callers of different lane counts taking turns on one pool, as a benchmark's interleaved
// modes do: a thread left out of one job may see its epoch late, while the caller already
// writes the next; every lane must still run exactly once per job that includes it (a lane
// count read apart from the job's epoch ran a job twice and left the caller waiting forever).
TEST(WorkerPool, CallersOfDifferentLaneCountsTakeTurns) {
  WorkerPool pool(5);
  Tally tally;
  tally.runs.assign(5, 0);
  tally.thread_of.assign(5, {});
  constexpr int kCounts[] = {2, 5, 3, 4, 2, 2, 5};
  std::vector<int> expected(5, 0);
  for (int r = 0; r < 4000; ++r) {
    const int lanes = kCounts[r % 7];
    pool.run(&countLane, &tally, lanes);
    for (int lane = 0; lane < lanes; ++lane) ++expected[static_cast<std::size_t>(lane)];
  }
  for (int lane = 0; lane < 5; ++lane)
    EXPECT_EQ(tally.runs[static_cast<std::size_t>(lane)], expected[static_cast<std::size_t>(lane)]) << "lane " << lane;
}

// Callers of 2, 4 and 8 lanes share the 8-lane pool asked for first (one set of spinning
// threads, not three); a caller of more lanes than any live pool gets a new one.
TEST(WorkerPool, SharedPoolIsTheLargestLiveOne) {
  const auto eight = WorkerPool::shared(8);
  ASSERT_EQ(eight->lanes(), 8);
  EXPECT_EQ(WorkerPool::shared(2), eight);
  EXPECT_EQ(WorkerPool::shared(4), eight);
  EXPECT_EQ(WorkerPool::shared(8), eight);
  const auto nine = WorkerPool::shared(9);
  EXPECT_NE(nine, eight);
  EXPECT_EQ(nine->lanes(), 9);
  EXPECT_EQ(WorkerPool::shared(8), nine) << "the largest live pool serves every smaller caller";
}

TEST(WorkerPool, RejectsALaneCountOutsideItsRange) {
  EXPECT_THROW(WorkerPool(0), std::invalid_argument);
  EXPECT_THROW(WorkerPool(WorkerPool::kMaxLanes + 1), std::invalid_argument);
}

}  // namespace
}  // namespace vh::haptics
