#pragma once
/// @file
/// IoThreadDevice: the base of the hardware drivers that talk to their device on an I/O thread
/// of their own: FalconDevice (libusb), SpaceMouseDevice (hidapi) and DhdDevice (Force
/// Dimension SDK). OpenHapticsDevice runs in the vendor's scheduler and does not use it.
///
/// What it owns, and nothing more: the I/O thread with its stop request, the connected flag,
/// the connection counter (DeviceSample::connection), the problem text behind its mutex, and
/// the Device overrides connected() and problem() that read them. What each driver keeps:
/// opening its device, the loop body, read() / command(), and the order of its own steps
/// around startIoThread() and stopIoThread() (the Falcon drops its transport after the join,
/// the SpaceMouse turns its LED off after it, DHD closes the device).
///
/// A base class rather than a member helper: connected() and problem() are Device overrides
/// that every such driver implements the same way; a base implements them once, where a member
/// would leave two forwarding overrides in each driver. The base has no virtual hooks: drivers
/// call its protected helpers in their own order, so each driver's open / stop / reconnect
/// sequence stays readable in its own file.
///
/// Threads:
///   - the owner thread (the driver's constructor, reconnect() and destructor; GUI or loader
///     thread, one at a time): startIoThread(), stopIoThread();
///   - the I/O thread: the loop; it polls stopRequested(), reads connection(), and reports with
///     setProblem() and markDisconnected();
///   - the servo thread: connected() and connection() only (lock-free atomics, never block);
///   - any thread but the servo thread: problem() (takes the mutex, copies the text).
///
/// Memory orders: stores release, loads acquire; the connection counter is bumped with
/// acq_rel. The thread's start and join order everything else (std::thread).

#include <atomic>
#include <cstdint>
#include <functional>
#include <initializer_list>
#include <mutex>
#include <string>
#include <string_view>
#include <thread>

#include "vh/runtime/device.h"

namespace vh::devices {

/// A runtime::Device whose driver runs a loop on an I/O thread (see the file comment).
class IoThreadDevice : public runtime::Device {
 public:
  IoThreadDevice(const IoThreadDevice&) = delete;
  IoThreadDevice& operator=(const IoThreadDevice&) = delete;

  /// Any thread: false before the first start, after markDisconnected() (the loop gave up or
  /// the owner is reconnecting) and until the next startIoThread(). Lock-free, never blocks.
  bool connected() const noexcept final { return connected_.load(std::memory_order_acquire); }
  /// Any thread but the servo thread: the last text set (empty when fine). Takes the mutex and
  /// copies the text.
  std::string problem() const final;

 protected:
  IoThreadDevice() = default;
  /// Stops and joins a thread still running. A driver whose loop uses its own members must
  /// stop the thread in its own destructor, before those members go.
  ~IoThreadDevice() override;

  /// Owner thread: clears the stop request, bumps the connection counter, sets the connected
  /// flag, then starts `loop` (noexcept: std::thread ends the program on an exception) on a
  /// new I/O thread. No thread may be running (stopIoThread() first). Only the I/O thread reads
  /// the stop request, and it does not exist yet: clearing the request before or after the
  /// counter is bumped is the same to every other thread.
  /// @throws std::system_error when the thread cannot be created (the flags are set already).
  void startIoThread(std::function<void()> loop);
  /// Owner thread: requests the loop to stop and joins the thread (no-op without one). The
  /// connected flag is left as it is: the drivers' steps after the join read it.
  void stopIoThread() noexcept;

  /// I/O thread: true once stopIoThread() has asked the loop to return.
  bool stopRequested() const noexcept { return stop_.load(std::memory_order_acquire); }
  /// Any thread, lock-free: clears the connected flag (read() then returns false).
  void markDisconnected() noexcept { connected_.store(false, std::memory_order_release); }
  /// Any thread, lock-free: the counter startIoThread() bumps; a sample carries the value of
  /// the connection it was measured on.
  std::uint32_t connection() const noexcept { return connection_.load(std::memory_order_acquire); }

  /// Any thread but the servo thread: sets the problem text to the concatenation of `parts`
  /// (built before the lock is taken). Usable from the I/O thread: when memory for the text
  /// cannot be had, the previous text stays and nothing is thrown.
  void setProblem(std::initializer_list<std::string_view> parts) noexcept;
  /// setProblem() of one part.
  void setProblem(std::string_view text) noexcept { setProblem({text}); }
  /// Any thread but the servo thread: empties the problem text.
  void clearProblem() noexcept { setProblem(std::string_view{}); }

 private:
  std::thread io_;                            // owner thread only
  std::atomic<bool> stop_{false};             // owner thread -> I/O thread
  std::atomic<bool> connected_{false};        // I/O and owner threads -> any thread
  std::atomic<std::uint32_t> connection_{0};  // owner thread -> I/O and servo threads
  mutable std::mutex problem_mutex_;          // guards problem_
  std::string problem_;
};

}  // namespace vh::devices
