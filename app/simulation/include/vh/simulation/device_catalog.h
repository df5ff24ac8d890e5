#pragma once
/// @file
/// Models of real haptic devices for the stability sweep, and the sensing/actuation
/// path a real device puts between the renderer and its handle: encoder quantisation of the
/// position, a delay of whole servo ticks on the force command, and force saturation.
///
/// Every figure is cited next to it in device_catalog.cpp. Three kinds of source:
///   [vendor]  the manufacturer's published specification, as quoted in the brief
///             (vendor data sheets; NOT re-checked against the sheets in this session);
///   [CHAI3D]  the device table of CHAI3D 3.2 (BSD, chai3d/chai3d@7c76b1f,
///             src/devices/CPhantomDevices.cpp and CDeltaDevices.cpp, read in this session):
///             m_maxLinearForce and m_maxLinearStiffness, the stiffness CHAI3D's examples use
///             as the highest they render on that device;
///   [estimate] a figure derived here, with its derivation stated.
/// Units: SI (m, s, kg, N).
#include <array>
#include <cstddef>
#include <string>
#include <string_view>
#include <vector>

#include <Eigen/Core>

#include "vh/simulation/device_model.h"

namespace vh::stability {

/// Published and estimated figures of one device (translational, per axis).
struct DeviceModelSpec {
  std::string name;                        ///< e.g. "Touch X".
  double mass_kg = 0.0;                    ///< Effective (apparent) mass at the handle m_d [kg].
  double damping_Ns_per_m = 0.0;           ///< Viscous damping of the mechanism b_d [N*s/m].
  double encoder_resolution_m = 0.0;       ///< Position quantum at the handle [m] (0: exact).
  double servo_rate_Hz = 1000.0;           ///< Rate of the device's servo loop = coupling thread [Hz].
  double max_force_N = 0.0;                ///< Peak force the device can exert [N].
  /// Rated max stiffness [N/m]: the maximum closed-loop stiffness the device's open driver ships
  /// for it, CHAI3D's m_maxLinearStiffness ("maximum closed loop linear stiffness"), the figure
  /// CHAI3D's applications scale their materials to. The paper's 5,000 N/m on Force Dimension
  /// devices matches it.
  double rated_stiffness_N_per_m = 0.0;
  /// The vendor's "stiffness" figure [N/m] where one is published (0: none); a mechanism figure,
  /// reported beside the rated one and swept, not promised.
  double vendor_stiffness_N_per_m = 0.0;
  int delay_ticks = 1;                     ///< Force command takes effect this many ticks late.
  bool torque_actuated = false;            ///< Motors on the rotations (6-DOF force feedback).

  /// Servo period T = 1 / servo_rate_Hz [s].
  double servoPeriod_s() const { return 1.0 / servo_rate_Hz; }
  /// The handle's mechanics, rotational axes matched at lever arm `lever_m` (DeviceParams::scaled).
  DeviceParams params(double lever_m) const;
  /// Its encoder, delay, force limit and torque motors as a signal path for DeviceIo / simulate().
  DeviceSignalPath signalPath() const { return {encoder_resolution_m, delay_ticks, max_force_N, torque_actuated}; }
  /// Colgate and Schenkel's passivity bound 2 b_d / T of the device alone [N/m].
  double colgateBound_N_per_m() const { return 2.0 * damping_Ns_per_m * servo_rate_Hz; }
};

/// The six modelled devices: Falcon, Touch, Touch X, omega.6, sigma.7, Phantom Premium 1.5.
const std::vector<DeviceModelSpec>& deviceCatalog();
/// The catalogue entry named `name` (exact match), or nullptr.
const DeviceModelSpec* findDevice(std::string_view name);

/// Position quantisation of an incremental encoder, per axis: round(x / q) * q. q <= 0: exact.
double quantize(double x_m, double q_m) noexcept;
Eigen::Vector3d quantize(const Eigen::Vector3d& x_m, double q_m) noexcept;

/// The device's signal path, one call each per servo tick (no allocation):
///   sense()    the position the renderer sees: the true handle position quantised;
///   actuate()  the force the motors apply over this tick: the command given delay_ticks ticks
///              earlier (zero before that), clamped to max_force_N in magnitude (direction kept).
class DeviceIo {
 public:
  static constexpr int kMaxDelayTicks = 8;
  /// @throws std::invalid_argument if path.delay_ticks is outside [0, kMaxDelayTicks].
  explicit DeviceIo(const DeviceSignalPath& path);
  /// The catalogue device's path (DeviceModelSpec::signalPath()). @throws as above.
  explicit DeviceIo(const DeviceModelSpec& spec) : DeviceIo(spec.signalPath()) {}
  Eigen::Vector3d sense(const Eigen::Vector3d& c_true_m) const noexcept;
  /// Pushes this tick's command and returns the force applied over this tick [N].
  Eigen::Vector3d actuate(const Eigen::Vector3d& command_N) noexcept;
  /// Torque goes through the same delay line (not saturated); zero when !torque_actuated.
  Eigen::Vector3d actuateTorque(const Eigen::Vector3d& command_Nm) noexcept;
  void reset() noexcept;
  int saturatedTicks() const noexcept { return saturated_; }

 private:
  double q_m_, max_force_N_;
  int delay_;
  bool torque_actuated_;
  std::array<Eigen::Vector3d, kMaxDelayTicks + 1> force_line_{}, torque_line_{};
  int head_f_ = 0, head_t_ = 0;
  int saturated_ = 0;
};

}  // namespace vh::stability
