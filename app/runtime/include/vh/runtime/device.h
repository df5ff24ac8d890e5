#pragma once
/// @file
/// Devices as the servo loop sees them: one complete sample per read, a force/torque command.

#include <atomic>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "vh/haptics/pose.h"
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

 private:
  TripleBuffer<haptics::Pose> poses_;
  haptics::Pose gui_pose_;  // GUI thread only
  haptics::Pose last_;      // servo thread only
  double time_s_ = 0.0;     // servo thread only
};

}  // namespace vh::runtime
