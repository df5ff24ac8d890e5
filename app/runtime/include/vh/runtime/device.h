#pragma once
/// @file
/// Devices as the servo loop sees them: one complete sample per read, a force/torque command.

#include <atomic>
#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "vh/haptics/pose.h"
#include "vh/runtime/trajectory.h"
#include "vh/runtime/triple_buffer.h"

namespace vh::runtime {

/// One complete device sample (never mixed from two reads).
struct DeviceSample {
  double time_s = 0.0;      ///< Device time [s].
  haptics::Pose X_WD;       ///< Device (tool) pose in the world frame W [m].
  unsigned buttons = 0;     ///< Button bit mask.
  bool valid = false;       ///< False when the device delivered nothing usable.
};

/// Interface every device implements. read() and command() are called from the servo thread
/// only and must not block, allocate or throw.
class Device {
 public:
  virtual ~Device() = default;
  virtual std::string name() const = 0;
  /// Reads the latest sample; @return false when the device has nothing (e.g. disconnected).
  virtual bool read(DeviceSample& sample) noexcept = 0;
  /// Commands a force [N] and torque [N*m] in W on the user's hand.
  virtual void command(const Eigen::Vector3d& force_W_N, const Eigen::Vector3d& torque_W_Nm) noexcept = 0;
};

/// The last force/torque command sent to a device (on the user's hand, in W).
struct DeviceCommand {
  Eigen::Vector3d force_W_N = Eigen::Vector3d::Zero();    ///< Force [N] in W.
  Eigen::Vector3d torque_W_Nm = Eigen::Vector3d::Zero();  ///< Torque [N*m] in W.
  std::uint64_t count = 0;                                ///< Commands received so far.
};

/// The last force/torque command of a device without hardware, handed from the servo thread to
/// one reader (GUI or test) through a triple buffer. record() never blocks or allocates.
class CommandLog {
 public:
  /// Servo thread: stores a command (numbered from 1).
  void record(const Eigen::Vector3d& force_W_N, const Eigen::Vector3d& torque_W_Nm) noexcept {
    DeviceCommand& slot = buffer_.writeSlot();
    slot.force_W_N = force_W_N;
    slot.torque_W_Nm = torque_W_Nm;
    slot.count = ++count_;
    buffer_.publish();
  }
  /// Reader: the latest command; @return true when it is new since the last call.
  bool last(DeviceCommand& out) noexcept { return buffer_.read(out); }

 private:
  TripleBuffer<DeviceCommand> buffer_;
  std::uint64_t count_ = 0;  // servo thread only
};

/// A device driven by the GUI (mouse and keyboard): the GUI thread sets the target pose, the
/// servo thread reads it. Forces are recorded (last command) but go nowhere.
class SimulatedDevice final : public Device {
 public:
  explicit SimulatedDevice(const haptics::Pose& X_WD_initial);
  std::string name() const override { return "Simulated device (mouse/keyboard)"; }
  /// GUI thread: the pose the device moves to.
  void setPose(const haptics::Pose& X_WD) noexcept;
  /// GUI thread: the last pose set.
  haptics::Pose pose() const noexcept;
  bool read(DeviceSample& sample) noexcept override;
  void command(const Eigen::Vector3d& force_W_N, const Eigen::Vector3d& torque_W_Nm) noexcept override;
  /// One consumer thread (e.g. the GUI or a test): the latest command the servo thread sent.
  /// @return true when it is newer than the last call's.
  bool lastCommand(DeviceCommand& out) noexcept { return commands_.last(out); }

 private:
  TripleBuffer<haptics::Pose> poses_;
  CommandLog commands_;  // servo thread -> one consumer
  haptics::Pose gui_pose_;  // GUI thread only
  haptics::Pose last_;      // servo thread only
  double time_s_ = 0.0;     // servo thread only: device time [s] (steady clock since construction)
  double t0_s_ = 0.0;       // steady clock at construction [s]
};

/// A device that replays a trajectory (e.g. loadTrajectoryCsv()): each read() advances the
/// device time by a fixed step from the trajectory's start, so a replay is deterministic and
/// independent of wall-clock jitter (one read per servo tick). Past the end it holds the last
/// pose. Forces are recorded (last command) but go nowhere.
class ScriptedDevice final : public Device {
 public:
  /// @param trajectory non-empty; @param step_s device time per read [s] (the servo period).
  /// @throws std::invalid_argument for an empty trajectory or step_s <= 0.
  explicit ScriptedDevice(Trajectory trajectory, double step_s = 1e-3, std::string source = {});
  std::string name() const override;
  /// Servo thread: the pose at t = start + reads * step_s (always valid; the last pose after
  /// the end).
  bool read(DeviceSample& sample) noexcept override;
  void command(const Eigen::Vector3d& force_W_N, const Eigen::Vector3d& torque_W_Nm) noexcept override;
  /// One consumer thread: the latest command sent. @return true when newer than the last call's.
  bool lastCommand(DeviceCommand& out) noexcept { return commands_.last(out); }

  const Trajectory& trajectory() const noexcept { return trajectory_; }
  /// Reads served so far (any thread).
  std::uint64_t reads() const noexcept { return reads_.load(std::memory_order_relaxed); }
  /// True once a read's time reached the trajectory's end (any thread).
  bool finished() const noexcept { return finished_.load(std::memory_order_acquire); }

 private:
  Trajectory trajectory_;
  double step_s_;
  std::string source_;
  std::size_t cursor_ = 0;  // servo thread only
  std::atomic<std::uint64_t> reads_{0};
  std::atomic<bool> finished_{false};
  CommandLog commands_;
};

}  // namespace vh::runtime
