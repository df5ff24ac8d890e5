#pragma once
/// @file
/// Coupling thread -> solver thread (haptic_thread.h): the last device samples, each with the
/// isovalue and the coupling gains read on the same coupling tick. Lock-free, one producer that
/// never waits (it overwrites the oldest sample) and one consumer that reads any sample still
/// held; neither allocates or throws after construction.

#include <array>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <memory>

#include <Eigen/Geometry>

#include "vh/haptics/pose.h"
#include "vh/haptics/virtual_coupling.h"

namespace vh::runtime {

/// One coupling tick's device sample as the solver gets it. Frames: W the scene (world) frame,
/// D the device's tool frame.
struct CouplingSample {
  haptics::Pose X_WD;            ///< As read (not normalised); meaningful only when ok.
  double isovalue = 0.0;         ///< HapticThread's isovalue on that coupling tick (data units).
  haptics::CouplingGains gains;  ///< The gains the coupling thread applied on that tick.
  bool ok = false;               ///< A usable sample (read() true, valid, finite).
  bool connected = true;         ///< Device::connected() right after the read.
  bool drill_button = false;     ///< The device's first button held (kDrillButton) on a usable sample.
};

/// The last `capacity()` samples, numbered 1, 2, ... One producer thread (push()) that never
/// waits: it overwrites the oldest slot. One consumer thread (read()) that reads any sample still
/// held: sample n is held until sample n + capacity() is pushed. Each slot is a sequence lock
/// (odd version while written) with relaxed atomic fields, so a torn read is detected (read()
/// returns false) and never undefined. The consumer tells how many samples it lost from the
/// numbers: latest() - n for the newest it read.
class SampleRing {
 public:
  /// @param capacity samples held; rounded up to a power of two (>= 2). Allocates.
  explicit SampleRing(std::size_t capacity) {
    std::size_t n = 2;
    while (n < capacity) n *= 2;
    slots_ = std::make_unique<Slot[]>(n);
    mask_ = n - 1;
  }
  std::size_t capacity() const noexcept { return mask_ + 1; }

  /// Producer. @return the new sample's number (1 for the first).
  std::uint64_t push(const CouplingSample& in) noexcept {
    const std::uint64_t seq = ++written_;
    Slot& s = slots_[seq & mask_];
    const std::uint64_t v = s.version.load(std::memory_order_relaxed);
    s.version.store(v + 1, std::memory_order_relaxed);
    std::atomic_thread_fence(std::memory_order_release);
    s.seq.store(seq, std::memory_order_relaxed);
    for (int k = 0; k < 3; ++k) s.value[k].store(in.X_WD.p_AB_m[k], std::memory_order_relaxed);
    s.value[3].store(in.X_WD.R_AB.w(), std::memory_order_relaxed);
    s.value[4].store(in.X_WD.R_AB.x(), std::memory_order_relaxed);
    s.value[5].store(in.X_WD.R_AB.y(), std::memory_order_relaxed);
    s.value[6].store(in.X_WD.R_AB.z(), std::memory_order_relaxed);
    s.value[7].store(in.isovalue, std::memory_order_relaxed);
    s.value[8].store(in.gains.linear_N_per_m, std::memory_order_relaxed);
    s.value[9].store(in.gains.angular_Nm_per_rad, std::memory_order_relaxed);
    s.flags.store((in.ok ? 1u : 0u) | (in.connected ? 2u : 0u) | (in.gains.passivity_control ? 4u : 0u) |
                      (in.drill_button ? 8u : 0u),
                  std::memory_order_relaxed);
    s.version.store(v + 2, std::memory_order_release);
    latest_.store(seq, std::memory_order_release);
    return seq;
  }
  /// Any thread: the newest sample's number (0: none yet).
  std::uint64_t latest() const noexcept { return latest_.load(std::memory_order_acquire); }
  /// Consumer: sample number `seq` into `out`. @return false (out unchanged) when sample `seq` is
  /// not (or no longer) held, or was being overwritten during the read.
  bool read(std::uint64_t seq, CouplingSample& out) const noexcept {
    const Slot& s = slots_[seq & mask_];
    const std::uint64_t v1 = s.version.load(std::memory_order_acquire);
    if ((v1 & 1u) != 0) return false;
    const std::uint64_t held = s.seq.load(std::memory_order_relaxed);
    double value[kValues];
    for (int k = 0; k < kValues; ++k) value[k] = s.value[k].load(std::memory_order_relaxed);
    const std::uint32_t flags = s.flags.load(std::memory_order_relaxed);
    std::atomic_thread_fence(std::memory_order_acquire);
    if (s.version.load(std::memory_order_relaxed) != v1 || held != seq) return false;
    out.X_WD.p_AB_m = {value[0], value[1], value[2]};
    out.X_WD.R_AB = Eigen::Quaterniond(value[3], value[4], value[5], value[6]);
    out.isovalue = value[7];
    out.gains.linear_N_per_m = value[8];
    out.gains.angular_Nm_per_rad = value[9];
    out.ok = (flags & 1u) != 0;
    out.connected = (flags & 2u) != 0;
    out.gains.passivity_control = (flags & 4u) != 0;
    out.drill_button = (flags & 8u) != 0;
    return true;
  }

 private:
  static constexpr int kValues = 10;
  struct Slot {
    std::atomic<std::uint64_t> version{0};
    std::atomic<std::uint64_t> seq{0};
    std::array<std::atomic<double>, kValues> value{};
    std::atomic<std::uint32_t> flags{0};
  };
  std::unique_ptr<Slot[]> slots_;
  std::size_t mask_ = 0;
  std::uint64_t written_ = 0;  // producer only
  std::atomic<std::uint64_t> latest_{0};
};

}  // namespace vh::runtime
