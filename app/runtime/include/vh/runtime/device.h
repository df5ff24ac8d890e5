#pragma once
/// @file
/// Devices as the servo loop sees them: identity, limits, sensed / actuated degrees of freedom,
/// one complete sample per read, a force/torque command; the one safety layer every command
/// goes through (ForceSafety); the workspace mapping from a device's base frame to the scene
/// (WorkspaceMapping, MappedDevice).
///
/// Frames (see also haptics/README.md):
///   W  the scene (world) frame [m].
///   B  a hardware device's base frame [m], origin at the centre of its workspace.
///   H  the device's handle (grip / puck) frame; a hardware driver reports X_BH.
///   D  the device frame the renderer sees in W (the tool's pose): X_WD = mapping(X_BH).
/// Devices without hardware (SimulatedDevice, ScriptedDevice) report X_WD directly.
///
/// Hardware drivers live in vh::devices (app/devices/); this header knows no hardware.

#include <atomic>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "vh/haptics/pose.h"
#include "vh/haptics/virtual_coupling.h"
#include "vh/runtime/trajectory.h"
#include "vh/runtime/triple_buffer.h"

namespace vh::runtime {

// ---- Degrees of freedom ------------------------------------------------------------------------

/// A set of degrees of freedom (bits: x, y, z translation, then rotations about x, y, z).
using DofMask = unsigned;
inline constexpr DofMask kDofX = 1u << 0;
inline constexpr DofMask kDofY = 1u << 1;
inline constexpr DofMask kDofZ = 1u << 2;
inline constexpr DofMask kDofRx = 1u << 3;
inline constexpr DofMask kDofRy = 1u << 4;
inline constexpr DofMask kDofRz = 1u << 5;
inline constexpr DofMask kDofNone = 0u;
inline constexpr DofMask kDofTranslation = kDofX | kDofY | kDofZ;
inline constexpr DofMask kDofRotation = kDofRx | kDofRy | kDofRz;
inline constexpr DofMask kDofAll = kDofTranslation | kDofRotation;

// ---- Identity, limits, safety policy -----------------------------------------------------------

/// Who a device is (for the GUI and logs).
struct DeviceIdentity {
  std::string model;         ///< e.g. "Novint Falcon", "SpaceNavigator", "Simulated device".
  std::string manufacturer;  ///< e.g. "Novint", "3Dconnexion"; empty when unknown.
  std::string serial;        ///< Serial number; empty when unknown.
  std::string backend;       ///< "virtual", "hidapi", "libusb", ...
};

/// What a device can render, in the frame its commands are expressed in (W for a MappedDevice,
/// whose stiffness and damping limits account for the workspace scale). Defaults are unbounded:
/// they fit devices without hardware; every hardware driver states its own.
struct DeviceLimits {
  static constexpr double kUnbounded = std::numeric_limits<double>::infinity();
  double max_force_N = kUnbounded;                      ///< Largest |force| [N].
  double max_torque_Nm = kUnbounded;                    ///< Largest |torque| [N*m].
  double max_linear_stiffness_N_per_m = kUnbounded;     ///< Stable at 1 kHz [N/m].
  double max_angular_stiffness_Nm_per_rad = kUnbounded; ///< Stable at 1 kHz [N*m/rad].
  double max_linear_damping_N_s_per_m = kUnbounded;     ///< [N*s/m].
  double workspace_radius_m = kUnbounded;               ///< Radius of the reachable ball [m].
  /// Centre of the reachable ball, in the frame of the samples [m] (B's origin for a hardware
  /// driver; p_WB for a MappedDevice).
  Eigen::Vector3d workspace_centre_m = Eigen::Vector3d::Zero();
  /// Fastest the handle's origin can move [m/s]: a sample farther from the last good one than
  /// this speed allows is a glitch (SampleFilter). Default kHandleMaxSpeed_m_per_s; hardware
  /// drivers state their model's (README, "Implausible device samples").
  double max_speed_m_per_s = kHandleMaxSpeed_m_per_s;
  /// Fastest the handle can turn [rad/s]; default kHandleMaxAngularSpeed_rad_per_s.
  double max_angular_speed_rad_per_s = kHandleMaxAngularSpeed_rad_per_s;

  /// [estimate] The default speed limit [m/s], for devices that state none (simulated,
  /// scripted): about handleMaxSpeed_m_per_s() of the Falcon (4.9 m/s), the device the
  /// simulated one stands in for. Hardware drivers state their model's.
  static constexpr double kHandleMaxSpeed_m_per_s = 5.0;
  /// [estimate] The default angular speed limit [rad/s]: fast wrist rotations peak at about
  /// 10-15 rad/s (600-900 deg/s); twice that.
  static constexpr double kHandleMaxAngularSpeed_rad_per_s = 30.0;
};

/// [estimate] The hand's own top speed with a grounded handle [m/s]: fast, deliberate arm
/// movements peak at about 2 m/s at the hand.
inline constexpr double kHandSpeed_m_per_s = 2.0;

/// [estimate] The fastest a grounded haptic handle can move [m/s]: the hand's speed
/// (kHandSpeed_m_per_s) plus what the device's own peak force F [N] gives its moving mass m [kg]
/// released across its workspace (diameter 2 r [m]): sqrt(4 F r / m) (uniform acceleration
/// F / m over 2 r). E.g. the Falcon (8 N, r 0.04 m, 0.15 kg): 2 + 2.9 = 4.9 m/s. The moving
/// masses are app/simulation device_catalog.cpp's. Non-positive inputs: kHandSpeed_m_per_s.
inline double handleMaxSpeed_m_per_s(double max_force_N, double workspace_radius_m, double moving_mass_kg) noexcept {
  const double a = max_force_N > 0.0 && workspace_radius_m > 0.0 && moving_mass_kg > 0.0
                       ? 4.0 * max_force_N * workspace_radius_m / moving_mass_kg
                       : 0.0;
  return kHandSpeed_m_per_s + (a > 0.0 && a < std::numeric_limits<double>::infinity() ? std::sqrt(a) : 0.0);
}

/// How the safety layer (ForceSafety) engages and watches a device. Defaults disable every
/// gate: they fit devices without a hand on them (simulated, scripted); hardware drivers return
/// SafetyPolicy::forHardware() or their own.
struct SafetyPolicy {
  static constexpr double kNever = std::numeric_limits<double>::infinity();
  /// After enabling (and after every watchdog trip, reconnection or non-finite force) the output
  /// stays zero until the computed |force| <= engage_force_N and |torque| <= engage_torque_Nm.
  double engage_force_N = kNever;    ///< [N]; infinity: engage at once.
  double engage_torque_Nm = kNever;  ///< [N*m]; infinity: engage at once.
  /// Once engaged, the output is scaled from 0 to 1 linearly over this time [s]; 0: no ramp.
  double ramp_time_s = 0.0;
  /// A tick that starts more than this after the previous one (the loop stalled) is a fault
  /// tick: the device held the last command through the gap, and this tick holds it again
  /// (fault_hold_s) instead of commanding a force computed after the stall [s]; a stall longer
  /// than silent_s is an outage (re-arm, see fault_hold_s). Infinity: never.
  double watchdog_s = kNever;
  /// A device whose valid samples keep the same time_s for longer than this is silent: its
  /// ticks are fault ticks (held and decayed, fault_hold_s) [s]; infinity: never.
  double silent_s = kNever;
  /// A short fault (a tick without a usable sample, a late tick) holds the last good command and
  /// decays it linearly to zero over this much servo time [s] (each fault tick ages the hold by
  /// one nominal period: after one missed tick at 1 kHz 90 % is left, after 5 ms 50 %). When
  /// the hold has decayed to zero the layer re-arms for an outage: once good ticks return the
  /// output ramps up from zero over ramp_time_s, with no engage gate. 0: zero at once.
  double fault_hold_s = kDefaultFaultHold_s;
  static constexpr double kDefaultFaultHold_s = 0.010;

  /// Hardware defaults: engage below 0.3 N and 0.02 N*m, 0.25 s ramp, 10 ms watchdog (10 missed
  /// ticks at 1 kHz), silent after 50 ms without a new sample, 10 ms fault hold.
  static SafetyPolicy forHardware() noexcept {
    SafetyPolicy p;
    p.engage_force_N = 0.3;
    p.engage_torque_Nm = 0.02;
    p.ramp_time_s = 0.25;
    p.watchdog_s = 0.010;
    p.silent_s = 0.050;
    return p;
  }
};

/// How far past a device's rated stiffness the coupling may be set while the passivity
/// controller is on (CouplingGains::passivity_control): its stiffness schedule then renders what
/// the device takes, never less than the rating (docs/benchmarks.md, "Device models and the
/// passivity controller").
inline constexpr double kPassivityStiffnessHeadroom = 20.0;

/// The coupling gains limited to what the device renders stably (linear and angular stiffness
/// clamped to DeviceLimits, or to kPassivityStiffnessHeadroom times them with the passivity
/// controller on; a non-finite or negative gain becomes 0).
haptics::CouplingGains clampGains(const haptics::CouplingGains& gains, const DeviceLimits& limits) noexcept;

// ---- Samples and the interface -----------------------------------------------------------------

/// One complete device sample (never mixed from two reads).
struct DeviceSample {
  double time_s = 0.0;      ///< Device time [s]; advances with every new measurement.
  haptics::Pose X_WD;       ///< Device (tool) pose in the world frame W [m] (X_BH for a raw
                            ///< hardware driver, before MappedDevice).
  Eigen::Vector3d v_WD_m_per_s = Eigen::Vector3d::Zero();    ///< Velocity of D's origin in W [m/s].
  Eigen::Vector3d w_WD_rad_per_s = Eigen::Vector3d::Zero();  ///< Angular velocity of D in W [rad/s].
  unsigned buttons = 0;     ///< Button bit mask (bit i = button i pressed).
  /// Changes whenever the device was reconnected or switched source: the safety layer then
  /// re-arms its engage gate (the hand may be anywhere).
  std::uint32_t connection = 0;
  bool valid = false;       ///< False when the device delivered nothing usable.
};

class SimulatedDevice;

/// Interface every device implements. read() and command() are called from the servo thread
/// only and must not block, allocate or throw. limits(), safetyPolicy(), sensedDof(),
/// actuatedDof() and connected() are cheap and callable from any thread.
class Device {
 public:
  virtual ~Device() = default;
  virtual std::string name() const = 0;
  /// Identity for the GUI (default: model = name(), backend "virtual").
  virtual DeviceIdentity identity() const { return {name(), {}, {}, "virtual"}; }
  /// Limits in the frame of the commands (default: unbounded, for devices without hardware).
  virtual DeviceLimits limits() const noexcept { return {}; }
  /// How the safety layer engages and watches this device (default: no gates).
  virtual SafetyPolicy safetyPolicy() const noexcept { return {}; }
  /// Degrees of freedom the pose measures (the others stay constant).
  virtual DofMask sensedDof() const noexcept { return kDofAll; }
  /// Degrees of freedom the device renders: force needs all of kDofTranslation, torque all of
  /// kDofRotation; the safety layer drops the rest (a 3-DOF Falcon gets no torque, while the
  /// renderer still uses the full 6-DOF pose).
  virtual DofMask actuatedDof() const noexcept { return kDofAll; }
  /// False while a hardware device is unplugged or failed (read() then returns false).
  virtual bool connected() const noexcept { return true; }
  /// Any thread but the servo thread: why the device is disconnected or not usable yet (e.g.
  /// "not homed yet: ..."), for the GUI; empty when fine.
  virtual std::string problem() const { return {}; }
  /// Any thread but the servo thread: reopens a disconnected hardware device (no-op otherwise).
  /// @throws std::runtime_error when the device cannot be opened (the message says why).
  virtual void reconnect() {}
  /// GUI thread: the simulated device the mouse and keys move while this device is in use (the
  /// device itself for a SimulatedDevice, the stand-in of a hardware device while it stands in),
  /// else null.
  virtual SimulatedDevice* simulatedDevice() noexcept { return nullptr; }
  /// Reads the latest sample; @return false when the device has nothing (e.g. disconnected).
  virtual bool read(DeviceSample& sample) noexcept = 0;
  /// Commands a force [N] and torque [N*m] in W on the user's hand.
  virtual void command(const Eigen::Vector3d& force_W_N, const Eigen::Vector3d& torque_W_Nm) noexcept = 0;
};

// ---- The safety layer ----------------------------------------------------------------------------

/// What the servo loop hands the safety layer every tick.
struct SafetyInput {
  bool sample_ok = false;        ///< read() succeeded with a valid sample and a finite pose.
  double sample_time_s = 0.0;    ///< The sample's DeviceSample::time_s.
  std::uint32_t connection = 0;  ///< The sample's DeviceSample::connection.
  /// SampleFilter re-seeded on this sample (the device is somewhere else than its last good
  /// sample said): the engage gate re-arms as for a new connection.
  bool reseeded = false;
  double tick_interval_s = 0.0;  ///< Wall time since the previous tick started [s].
  /// The servo loop's nominal period [s], the age one fault tick adds to a hold
  /// (SafetyPolicy::fault_hold_s); 0: tick_interval_s.
  double period_s = 0.0;
  Eigen::Vector3d force_W_N = Eigen::Vector3d::Zero();    ///< Computed force [N] in W.
  Eigen::Vector3d torque_W_Nm = Eigen::Vector3d::Zero();  ///< Computed torque [N*m] in W.
};

/// The one safety layer between the renderer and every device (used by HapticThread and the
/// headless runner). Per tick, in this order:
///   1. a new connection (the hand may be anywhere) or a non-finite force or torque: zero
///      output, engage gate re-armed;
///   2. fault tick: no usable sample (missing, or rejected by SampleFilter), a silent device
///      (SafetyPolicy::silent_s) or a late tick (SafetyPolicy::watchdog_s): the last good
///      command is held and decays linearly to zero over SafetyPolicy::fault_hold_s (the wall a
///      hand presses on stays); once it has decayed to zero, or after a stall longer than
///      silent_s, the layer re-arms for an outage: good ticks then ramp the output up from the
///      held value (zero) over ramp_time_s, without waiting for the hand to let go;
///   3. degrees of freedom the device does not actuate are dropped (torque of a 3-DOF device);
///   4. engage gate: after enable() or a gate re-arm, the output stays zero until the computed
///      force and torque are small (SafetyPolicy::engage_force_N / engage_torque_Nm);
///   5. clamp |force| and |torque| to DeviceLimits (direction kept);
///   6. ramp: once engaged the output goes linearly from the value it starts from (zero, or the
///      held value after an outage) to the computed one over SafetyPolicy::ramp_time_s.
/// step() never allocates, blocks or throws; every output is finite and within the limits.
class ForceSafety {
 public:
  enum class State : std::uint8_t {
    kOff,                   ///< Disabled: zero output.
    kWaitingForSmallForce,  ///< Armed: zero output until the computed force is small.
    kRamping,               ///< Engaged, output scaled up over the ramp time.
    kEngaged,               ///< Full (clamped) output.
  };
  /// Counters since construction (or resetStats()).
  struct Stats {
    std::uint64_t ticks = 0;
    std::uint64_t zeroed_ticks = 0;        ///< Ticks with a zero output for any reason.
    std::uint64_t clamped_ticks = 0;       ///< Ticks whose force or torque was clamped.
    std::uint64_t nonfinite_commands = 0;  ///< Computed forces/torques with a NaN or infinity.
    std::uint64_t missing_samples = 0;     ///< Ticks without a usable sample.
    std::uint64_t silent_trips = 0;        ///< Times the device was found silent.
    std::uint64_t watchdog_trips = 0;      ///< Late ticks (missed ticks).
    std::uint64_t held_ticks = 0;          ///< Fault ticks that sent the held, decaying command.
    std::uint64_t outages = 0;             ///< Re-arms after an outage (hold decayed or long stall).
    std::uint64_t dropped_dof_ticks = 0;   ///< Ticks with a non-zero force/torque the device cannot render.
  };

  ForceSafety() = default;
  ForceSafety(const DeviceLimits& limits, const SafetyPolicy& policy, DofMask actuated) noexcept {
    configure(limits, policy, actuated);
  }
  /// Sets the device's limits, policy and actuated DOF (takes effect at the next step()).
  void configure(const DeviceLimits& limits, const SafetyPolicy& policy, DofMask actuated) noexcept;
  /// Updates the limits only (e.g. after a workspace scale change); cheap, allocation free.
  void setLimits(const DeviceLimits& limits) noexcept { limits_ = limits; }
  /// Arms the layer: output stays zero until the computed force is small, then ramps up.
  void enable() noexcept;
  /// Zero output from the next step() on.
  void disable() noexcept { state_ = State::kOff; }

  /// One servo tick: the command to send for `in`, written to force_W_N / torque_W_Nm.
  void step(const SafetyInput& in, Eigen::Vector3d& force_W_N, Eigen::Vector3d& torque_W_Nm) noexcept;

  State state() const noexcept { return state_; }
  /// Current ramp factor in [0, 1] (0 unless engaged).
  double rampFactor() const noexcept;
  const Stats& stats() const noexcept { return stats_; }
  const DeviceLimits& limits() const noexcept { return limits_; }
  const SafetyPolicy& policy() const noexcept { return policy_; }

 private:
  /// What kind of tick step() has: the engage gate to re-arm, a fault (hold the last good
  /// command), a stall longer than a silent device (an outage at once).
  struct TickKind {
    bool gate = false;
    bool fault = false;
    bool stall = false;
  };
  TickKind classifyTick(const SafetyInput& in, double dt) noexcept;
  /// A fault tick: the last good command, decaying linearly over the hold; an outage once spent.
  void holdLastCommand(double period_s, bool stall, Eigen::Vector3d& force_W_N, Eigen::Vector3d& torque_W_Nm) noexcept;
  /// While waiting for a small force: whether `f` and `tau` are small enough to engage (then
  /// the ramp starts). Always true once engaged.
  bool passEngageGate(const Eigen::Vector3d& f, const Eigen::Vector3d& tau) noexcept;
  void rearm() noexcept;

  DeviceLimits limits_;
  Eigen::Vector3d held_force_W_N_ = Eigen::Vector3d::Zero();    // the last good tick's output
  Eigen::Vector3d held_torque_W_Nm_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d ramp_from_force_W_N_ = Eigen::Vector3d::Zero();  // where the ramp starts
  Eigen::Vector3d ramp_from_torque_W_Nm_ = Eigen::Vector3d::Zero();
  double hold_age_s_ = 0.0;  // servo time the current hold has decayed for
  bool outage_ = false;      // re-armed for an outage: the hold is spent
  SafetyPolicy policy_;
  DofMask actuated_ = kDofAll;
  State state_ = State::kOff;
  double ramp_elapsed_s_ = 0.0;
  double last_sample_time_s_ = std::numeric_limits<double>::quiet_NaN();
  double stale_s_ = 0.0;
  std::uint32_t connection_ = 0;
  bool have_connection_ = false;
  bool silent_ = false;
  Stats stats_;
};

// ---- Workspace mapping -------------------------------------------------------------------------

/// Maps a hardware device's handle pose X_BH (base frame B) into the scene:
///   p_WD = p_WB + scale * R_WB * p_BH,   R_WD = R_WB * R_BH * R_HD.
/// Forces and torques go back rotated only (F_B = R_WB^T F_W): the device's position is scaled,
/// its force is not, so the hand feels a coupling stiffness k [N/m] in W as k * scale.
struct WorkspaceMapping {
  double scale = 1.0;                 ///< Metres in W per metre at the device (> 0).
  haptics::Pose X_WB;                 ///< Base frame B in W: rotation R_WB, offset p_WB [m].
  Eigen::Quaterniond R_HD = Eigen::Quaterniond::Identity();  ///< Tool orientation relative to the handle.

  /// X_WD for the handle pose X_BH [m].
  haptics::Pose toWorld(const haptics::Pose& X_BH) const noexcept;
  /// Velocity of the tool origin in W [m/s] for the handle's velocity v_BH in B [m/s].
  Eigen::Vector3d linearVelocityToWorld(const Eigen::Vector3d& v_B_m_per_s) const noexcept {
    return scale * (X_WB.R_AB * v_B_m_per_s);
  }
  /// Angular velocity in W [rad/s] for one in B [rad/s].
  Eigen::Vector3d angularVelocityToWorld(const Eigen::Vector3d& w_B_rad_per_s) const noexcept {
    return X_WB.R_AB * w_B_rad_per_s;
  }
  /// A force [N] or torque [N*m] in W expressed in B (rotation only).
  Eigen::Vector3d vectorToDevice(const Eigen::Vector3d& v_W) const noexcept { return X_WB.R_AB.conjugate() * v_W; }
  /// The device's limits as seen in W: stiffness and damping divided by scale, the workspace
  /// radius multiplied by it, force and torque unchanged.
  DeviceLimits limitsInWorld(const DeviceLimits& device_limits) const noexcept;
  /// True for a finite scale > 0, finite offset and non-zero, finite quaternions.
  bool valid() const noexcept;
  /// @throws std::invalid_argument naming the bad field when !valid().
  void validate() const;
};

/// A hardware device seen through a WorkspaceMapping: its samples come out in W, its commands
/// go back to B. The GUI may change the mapping while the servo thread runs (setMapping(); it
/// takes effect at the next read, and the safety layer re-engages through its gate because the
/// sample's `connection` changes).
class MappedDevice final : public Device {
 public:
  /// @param raw a device whose samples are in its base frame B (DeviceSample::X_WD holds X_BH).
  /// @throws std::invalid_argument for a null device or an invalid mapping.
  MappedDevice(std::shared_ptr<Device> raw, const WorkspaceMapping& mapping);

  /// GUI thread: the mapping from the next read() on. @throws std::invalid_argument when invalid.
  void setMapping(const WorkspaceMapping& mapping);
  /// GUI thread: the last mapping set.
  WorkspaceMapping mapping() const;
  /// The wrapped driver.
  const std::shared_ptr<Device>& raw() const noexcept { return raw_; }

  std::string name() const override { return raw_->name(); }
  DeviceIdentity identity() const override { return raw_->identity(); }
  DeviceLimits limits() const noexcept override;
  SafetyPolicy safetyPolicy() const noexcept override { return raw_->safetyPolicy(); }
  DofMask sensedDof() const noexcept override { return raw_->sensedDof(); }
  DofMask actuatedDof() const noexcept override { return raw_->actuatedDof(); }
  bool connected() const noexcept override { return raw_->connected(); }
  std::string problem() const override { return raw_->problem(); }
  void reconnect() override { raw_->reconnect(); }
  bool read(DeviceSample& sample) noexcept override;
  void command(const Eigen::Vector3d& force_W_N, const Eigen::Vector3d& torque_W_Nm) noexcept override;

 private:
  std::shared_ptr<Device> raw_;
  TripleBuffer<WorkspaceMapping> mappings_;  // GUI thread -> servo thread
  WorkspaceMapping gui_mapping_;             // GUI thread only
  std::atomic<double> scale_;                // any thread (limits())
  WorkspaceMapping servo_mapping_;           // servo thread only
  std::uint32_t mapping_epoch_ = 0;          // servo thread only: bumped when the mapping changed
};

// ---- Devices without hardware --------------------------------------------------------------------

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
/// servo thread reads it. Forces are recorded (last command) but go nowhere. Velocities are the
/// finite difference of the last two reads.
class SimulatedDevice final : public Device {
 public:
  explicit SimulatedDevice(const haptics::Pose& X_WD_initial);
  std::string name() const override { return "Simulated device (mouse/keyboard)"; }
  DeviceIdentity identity() const override { return {"Simulated device (mouse/keyboard)", {}, {}, "virtual"}; }
  SimulatedDevice* simulatedDevice() noexcept override { return this; }
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
  bool have_read_ = false;  // servo thread only
};

/// A device that replays a trajectory (e.g. loadTrajectoryCsv()): each read() advances the
/// device time by a fixed step from the trajectory's start, so a replay is deterministic and
/// independent of wall-clock jitter (one read per servo tick). Past the end it holds the last
/// pose. Forces are recorded (last command) but go nowhere. Velocities are the finite
/// difference over one step. Limits, safety policy and actuated DOF default to those of a
/// device without hardware; setLimits() etc. make it stand in for a hardware device in tests.
class ScriptedDevice final : public Device {
 public:
  /// @param trajectory non-empty; @param step_s device time per read [s] (the servo period).
  /// @throws std::invalid_argument for an empty trajectory or step_s <= 0.
  explicit ScriptedDevice(Trajectory trajectory, double step_s = 1e-3, std::string source = {});
  std::string name() const override;
  DeviceLimits limits() const noexcept override { return limits_; }
  SafetyPolicy safetyPolicy() const noexcept override { return policy_; }
  DofMask actuatedDof() const noexcept override { return actuated_; }
  /// Before the servo thread starts: what the device claims to render (to stand in for
  /// hardware).
  void setLimits(const DeviceLimits& limits) noexcept { limits_ = limits; }
  void setSafetyPolicy(const SafetyPolicy& policy) noexcept { policy_ = policy; }
  void setActuatedDof(DofMask actuated) noexcept { actuated_ = actuated; }
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
  DeviceLimits limits_;
  SafetyPolicy policy_;
  DofMask actuated_ = kDofAll;
  std::size_t cursor_ = 0;  // servo thread only
  std::atomic<std::uint64_t> reads_{0};
  std::atomic<bool> finished_{false};
  CommandLog commands_;
};

}  // namespace vh::runtime
