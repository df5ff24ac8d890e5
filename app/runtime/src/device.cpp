#include "vh/runtime/device.h"

#include <chrono>
#include <stdexcept>

namespace vh::runtime {

namespace {

double steadySeconds() noexcept {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

}  // namespace

// ---- SimulatedDevice --------------------------------------------------------------------------

SimulatedDevice::SimulatedDevice(const haptics::Pose& X_WD_initial)
    : gui_pose_(X_WD_initial), last_(X_WD_initial), t0_s_(steadySeconds()) {
  poses_.writeSlot() = X_WD_initial;
  poses_.publish();
}

void SimulatedDevice::setPose(const haptics::Pose& X_WD) noexcept {
  gui_pose_ = X_WD;
  poses_.writeSlot() = X_WD;
  poses_.publish();
}

haptics::Pose SimulatedDevice::pose() const noexcept { return gui_pose_; }

bool SimulatedDevice::read(DeviceSample& sample) noexcept {
  poses_.read(last_);
  time_s_ = steadySeconds() - t0_s_;
  sample.time_s = time_s_;
  sample.X_WD = last_;
  sample.buttons = 0;
  sample.valid = true;
  return true;
}

void SimulatedDevice::command(const Eigen::Vector3d& force_W_N, const Eigen::Vector3d& torque_W_Nm) noexcept {
  commands_.record(force_W_N, torque_W_Nm);
}

// ---- ScriptedDevice ---------------------------------------------------------------------------

ScriptedDevice::ScriptedDevice(Trajectory trajectory, double step_s, std::string source)
    : trajectory_(std::move(trajectory)), step_s_(step_s), source_(std::move(source)) {
  if (trajectory_.empty()) throw std::invalid_argument("ScriptedDevice: empty trajectory");
  if (!(step_s_ > 0.0)) throw std::invalid_argument("ScriptedDevice: step_s must be > 0");
}

std::string ScriptedDevice::name() const {
  return source_.empty() ? std::string("Scripted device") : "Scripted device (" + source_ + ")";
}

bool ScriptedDevice::read(DeviceSample& sample) noexcept {
  const std::uint64_t n = reads_.load(std::memory_order_relaxed);
  const double t = trajectory_.startTime_s() + static_cast<double>(n) * step_s_;
  sample.time_s = t;
  sample.X_WD = trajectory_.poseAt(t, cursor_);
  sample.buttons = 0;
  sample.valid = true;
  reads_.store(n + 1, std::memory_order_relaxed);
  if (t >= trajectory_.endTime_s()) finished_.store(true, std::memory_order_release);
  return true;
}

void ScriptedDevice::command(const Eigen::Vector3d& force_W_N, const Eigen::Vector3d& torque_W_Nm) noexcept {
  commands_.record(force_W_N, torque_W_Nm);
}

}  // namespace vh::runtime
