// Test of vh/devices/io_thread_device.h on its own, with a loop that counts its iterations:
// start and stop join the thread, every start is a new connection, and the problem text and
// the connected flag the loop sets are what problem() and connected() show.
#include "vh/devices/io_thread_device.h"

#include <atomic>
#include <chrono>
#include <cstdint>
#include <string>
#include <thread>

#include <gtest/gtest.h>

namespace vh::devices {
namespace {

using namespace std::chrono_literals;

/// The smallest IoThreadDevice: its loop reports the connection it runs on, then counts
/// iterations until asked to stop; `exited` is set as the loop returns.
class CountingDevice final : public IoThreadDevice {
 public:
  ~CountingDevice() override { stopIoThread(); }
  std::string name() const override { return "counting"; }
  bool read(runtime::DeviceSample&) noexcept override { return false; }
  void command(const Eigen::Vector3d&, const Eigen::Vector3d&) noexcept override {}

  void start() {
    exited.store(false);
    startIoThread([this] { loop(); });
  }
  void stop() noexcept { stopIoThread(); }
  std::uint32_t connectionNow() const noexcept { return connection(); }

  std::atomic<std::uint64_t> iterations{0};
  std::atomic<bool> exited{false};

 private:
  void loop() noexcept {
    setProblem({"running on connection ", std::to_string(connection())});
    while (!stopRequested()) {
      iterations.fetch_add(1);
      std::this_thread::sleep_for(100us);
    }
    exited.store(true);
  }
};

/// Waits up to 30 s for `iterations` to pass `above` (returns as soon as it does).
bool waitForIterations(const CountingDevice& d, std::uint64_t above) {
  const auto deadline = std::chrono::steady_clock::now() + 30s;
  while (d.iterations.load() <= above && std::chrono::steady_clock::now() < deadline) std::this_thread::sleep_for(1ms);
  return d.iterations.load() > above;
}

TEST(IoThreadDevice, StartRunsTheLoopStopJoinsItAndEachStartIsANewConnection) {
  CountingDevice d;
  EXPECT_FALSE(d.connected());
  EXPECT_EQ(d.problem(), "");
  const std::uint32_t first = d.connectionNow();

  for (std::uint32_t start = 1; start <= 2; ++start) {
    d.start();
    EXPECT_TRUE(d.connected());
    EXPECT_EQ(d.connectionNow(), first + start);
    const std::uint64_t before = d.iterations.load();
    ASSERT_TRUE(waitForIterations(d, before + 10)) << "the loop does not run";
    // The loop set its text before its first iteration.
    EXPECT_EQ(d.problem(), "running on connection " + std::to_string(first + start));

    d.stop();
    EXPECT_TRUE(d.exited.load()) << "stopIoThread() returned before the loop did";
    const std::uint64_t stopped_at = d.iterations.load();
    std::this_thread::sleep_for(20ms);
    EXPECT_EQ(d.iterations.load(), stopped_at) << "the loop still runs after stopIoThread()";
    EXPECT_TRUE(d.connected()) << "stopping leaves the connected flag to the driver";
    EXPECT_EQ(d.connectionNow(), first + start);
  }
  d.stop();  // again: no thread, no-op
  EXPECT_EQ(d.connectionNow(), first + 2);
}

}  // namespace
}  // namespace vh::devices
