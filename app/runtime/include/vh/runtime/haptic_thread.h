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
#include <string>
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
  /// Applied at the start of the next tick (clamped to the device's stable stiffness). While
  /// recording, also records a "gains" event with the clamped (applied) gains
  /// {"linear_N_per_m": k, "angular_Nm_per_rad": k_r, "requested": {...}}. Not on the servo thread.
  void setGains(const haptics::CouplingGains& gains) noexcept;

  /// Records every tick from the next one on into `recorder` (one TickRecord per tick, pushed
  /// without blocking or allocating; a full ring drops the record and the recorder counts it).
  /// Not owned: it must outlive the recording. Set it before start(), or clear it (nullptr) and
  /// only destroy the recorder after stop(): the servo thread may be inside push() otherwise.
  /// TickRecord::time_s counts servo periods (tick * period) from the recording's first tick (a
  /// new recorder, or the same one set again after nullptr, starts a new clock).
  /// The servo thread also sets kRecordFlagDeviceDisconnected while Device::connected() is false
  /// (the writer turns changes into device_connected / device_disconnected events) and
  /// kRecordFlagForceLimited when the safety layer changed the force or torque.
  void setRecorder(RecordingWriter* recorder) noexcept { recorder_.store(recorder, std::memory_order_release); }

  /// Adds an event to the current recording stamped with the latest servo tick and time; a
  /// no-op when not recording. Any thread but the servo thread (it allocates). The recorder
  /// must not be destroyed concurrently (see setRecorder()).
  /// @throws std::invalid_argument when detail_json is not a JSON object (RecordingWriter::addEvent()).
  void recordEvent(const std::string& type, const std::string& detail_json);

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
  /// Latest recorded tick and its TickRecord::time_s (servo thread writes; 0 before the first).
  /// Packed: tick in the atomic, time recomputed from it and the first recorded tick.
  std::atomic<std::uint64_t> latest_recorded_tick_{0};
  std::atomic<std::uint64_t> first_recorded_tick_{0};
  TripleBuffer<HapticSnapshot> snapshots_;
  std::thread thread_;
};

}  // namespace vh::runtime
