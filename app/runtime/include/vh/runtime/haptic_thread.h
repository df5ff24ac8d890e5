#pragma once
/// @file
/// The embedded servo loop: a thread that runs HapticRenderer::tick() at the servo rate
/// (1 kHz), reads the device, writes forces and publishes snapshots for the render thread.
/// GUI commands (isovalue, gains, device target) go in through atomics / triple buffers and
/// are applied at the start of the next tick. The loop never allocates, locks or throws.

#include <array>
#include <atomic>
#include <cstdint>
#include <memory>
#include <thread>

#include <Eigen/Core>

#include "vh/haptics/haptic_renderer.h"
#include "vh/runtime/device.h"
#include "vh/runtime/recording.h"
#include "vh/runtime/triple_buffer.h"

namespace vh::runtime {

/// What the render thread sees of the haptic thread: one consistent tick.
struct HapticSnapshot {
  static constexpr int kMaxContactsShown = 64;
  std::uint64_t tick = 0;                 ///< Tick counter.
  haptics::Pose X_WP;                     ///< Proxy pose in W.
  haptics::Pose X_WD;                     ///< Device pose in W.
  Eigen::Vector3d force_W_N = Eigen::Vector3d::Zero();
  Eigen::Vector3d torque_W_Nm = Eigen::Vector3d::Zero();
  double isovalue = 0.0;
  int contacts = 0;                       ///< Contact set size.
  int contacts_shown = 0;                 ///< Entries filled in contact_p_W_m / contact_n_W.
  std::array<Eigen::Vector3d, kMaxContactsShown> contact_p_W_m{};
  std::array<Eigen::Vector3d, kMaxContactsShown> contact_n_W{};
  // Over the last second:
  double servo_rate_Hz = 0.0;
  double mean_tick_us = 0.0;
  double max_tick_us = 0.0;
  std::uint64_t deadline_misses = 0;      ///< Ticks that started > 1 period late (total).
  std::uint64_t bad_device_samples = 0;   ///< Total.
};

/// Runs the servo loop on its own thread.
class HapticThread {
 public:
  /// @param renderer takes ownership; @param device read and commanded by the servo thread.
  HapticThread(std::unique_ptr<haptics::HapticRenderer> renderer, std::shared_ptr<Device> device,
               double isovalue, double servo_rate_Hz = 1000.0);
  ~HapticThread();  ///< Stops the thread (force ramped to zero).
  HapticThread(const HapticThread&) = delete;
  HapticThread& operator=(const HapticThread&) = delete;

  void start();
  /// Ramps the force to zero over ~50 ms, then joins the thread.
  void stop();
  bool running() const noexcept { return running_.load(std::memory_order_acquire); }
  /// After the loop started: whether it got SCHED_FIFO (else it runs under SCHED_OTHER with a
  /// 1 ns timer slack) and locked its memory (mlockall; undone when the loop ends).
  bool realtimeScheduling() const noexcept { return fifo_.load(std::memory_order_acquire); }
  bool memoryLocked() const noexcept { return memory_locked_.load(std::memory_order_acquire); }
  double servoRate_Hz() const noexcept { return 1.0 / period_s_; }

  /// Applied at the start of the next tick.
  void setIsovalue(double isovalue) noexcept { isovalue_.store(isovalue, std::memory_order_relaxed); }
  double isovalue() const noexcept { return isovalue_.load(std::memory_order_relaxed); }
  void setGains(const haptics::CouplingGains& gains) noexcept;

  /// Records every tick from the next one on into `recorder` (one TickRecord per tick, pushed
  /// without blocking or allocating; a full ring drops the record and the recorder counts it).
  /// Not owned: it must outlive the recording. Set it before start(), or clear it (nullptr) and
  /// only destroy the recorder after stop(): the servo thread may be inside push() otherwise.
  /// TickRecord::time_s counts servo periods (tick * period) from the first recorded tick.
  void setRecorder(RecordingWriter* recorder) noexcept { recorder_.store(recorder, std::memory_order_release); }

  /// Latest snapshot (never blocks). @return true when it is newer than the last call's.
  bool latestSnapshot(HapticSnapshot& out) noexcept { return snapshots_.read(out); }

 private:
  void loop() noexcept;

  std::unique_ptr<haptics::HapticRenderer> renderer_;
  std::shared_ptr<Device> device_;
  double period_s_;
  std::atomic<double> isovalue_;
  std::atomic<double> gain_linear_;
  std::atomic<double> gain_angular_;
  std::atomic<bool> gains_dirty_{false};
  std::atomic<bool> stop_requested_{false};
  std::atomic<bool> running_{false};
  std::atomic<bool> fifo_{false};
  std::atomic<bool> memory_locked_{false};
  std::atomic<RecordingWriter*> recorder_{nullptr};
  TripleBuffer<HapticSnapshot> snapshots_;
  std::thread thread_;
};

}  // namespace vh::runtime
