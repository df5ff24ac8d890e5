#pragma once
/// @file
/// 3Dconnexion SpaceMouse family (../shared/docs/devices.md, from spacenavd's documented
/// behaviour): the models by USB vendor / product id, HID input report decoding, the per-model
/// axis map into the device base frame B, and rate control (the puck's deflection sets the
/// velocity of a virtual handle pose X_BH). Pure code: no I/O, no allocation.
///
/// Frames: B is right-handed with x to the user's right, y away from the user, z up, origin
/// at the centre of the virtual workspace; H is the virtual handle.

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>

#include <Eigen/Core>

#include "vh/haptics/pose.h"

namespace vh::devices::spacemouse {

/// From the HID axes (order X, Y, Z, Rx, Ry, Rz) to B: axis i of B = sign[i] * raw[source[i]].
struct AxisMap {
  std::array<std::uint8_t, 6> source{0, 1, 2, 3, 4, 5};
  std::array<std::int8_t, 6> sign{1, 1, 1, 1, 1, 1};
};

/// The HID axes are x right, y towards the user, z down (pushing the cap down is +Z), the
/// rotations about the same axes: B's y and z and their rotations flip sign. Not verified on
/// hardware for every model: override SpaceMouseOptions::axis_map where a model differs.
inline constexpr AxisMap kDefaultAxisMap{{0, 1, 2, 3, 4, 5}, {1, -1, -1, 1, -1, -1}};

/// A known model.
struct Model {
  std::uint16_t vendor_id;
  std::uint16_t product_id;
  const char* name;
  AxisMap axes;
};

/// Every model the driver opens (VID 0x046D: SpaceNavigator, SpaceMouse Pro, SpacePilot Pro;
/// VID 0x256F: SpaceMouse Wireless and its receiver, Pro Wireless (cable and receiver),
/// Enterprise, Compact, Universal receiver).
std::span<const Model> knownModels() noexcept;
/// The model with this id, or nullptr.
const Model* findModel(std::uint16_t vendor_id, std::uint16_t product_id) noexcept;

/// HID report ids.
inline constexpr std::uint8_t kReportTranslation = 1;  ///< X, Y, Z int16 LE (7 bytes); 13 bytes: all six.
inline constexpr std::uint8_t kReportRotation = 2;     ///< Rx, Ry, Rz int16 LE (7 bytes).
inline constexpr std::uint8_t kReportButtons = 3;      ///< Button bit mask, LE (3-4 bytes and more).
inline constexpr std::uint8_t kReportBattery = 0x17;   ///< Battery percent (wireless).

/// Decoded input state (raw HID axes, counts of about -350..350).
struct State {
  std::array<std::int16_t, 6> raw{0, 0, 0, 0, 0, 0};  ///< X, Y, Z, Rx, Ry, Rz [counts].
  std::uint32_t buttons = 0;                          ///< Bit i: button i pressed.
  int battery_percent = -1;                           ///< -1: not reported.
};

/// Parts of State a report changed (decodeReport()'s result).
inline constexpr unsigned kChangedTranslation = 1u << 0;
inline constexpr unsigned kChangedRotation = 1u << 1;
inline constexpr unsigned kChangedButtons = 1u << 2;
inline constexpr unsigned kChangedBattery = 1u << 3;

/// Applies one input report (report id first) to `state`. @return the kChanged* bits, 0 for an
/// unknown id or a report too short for its id.
unsigned decodeReport(const std::uint8_t* report, std::size_t size, State& state) noexcept;

/// The LED output report: {4, 15} on, {4, 0} off.
std::array<std::uint8_t, 2> ledReport(bool on) noexcept;

/// Normalised deflection in B: each axis in [-1, 1].
struct Deflection {
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();  ///< Along x, y, z of B.
  Eigen::Vector3d rotation = Eigen::Vector3d::Zero();     ///< About x, y, z of B.
};

/// How deflection becomes motion.
struct RateControlOptions {
  double full_scale_counts = 350.0;         ///< Raw count of a full deflection.
  double deadzone = 0.05;                   ///< Fraction of full scale ignored around rest.
  double max_speed_m_per_s = 0.10;          ///< Handle speed at full deflection [m/s].
  double max_angular_speed_rad_per_s = 1.5; ///< Angular speed at full deflection [rad/s].
  double workspace_radius_m = 0.10;         ///< The handle stays within this ball around B's origin [m].
  double max_step_s = 0.05;                 ///< Longest time step integrated at once [s].
};

/// Raw axes through the axis map, normalised by full scale with a dead zone, clamped to [-1, 1]:
/// d = sign(x) * max(0, |x| / full - deadzone) / (1 - deadzone).
Deflection deflection(const State& state, const AxisMap& axes, const RateControlOptions& options) noexcept;

/// Rate control: the deflection sets the velocity of the handle pose X_BH, integrated over time
/// (translation in B, rotation about B's axes), kept inside the workspace ball.
class RateController {
 public:
  explicit RateController(const RateControlOptions& options = {}) noexcept : options_(options) {}
  /// Puts the handle at `X_BH` at rest.
  void reset(const haptics::Pose& X_BH = haptics::Pose::Identity()) noexcept;
  /// Advances by dt_s [s] (clamped to [0, max_step_s]) with the deflection held.
  void step(const Deflection& d, double dt_s) noexcept;
  /// Handle pose in B [m].
  const haptics::Pose& pose() const noexcept { return X_BH_; }
  /// Handle velocity in B [m/s] (zero along a wall of the workspace ball when pushing out).
  const Eigen::Vector3d& velocity_m_per_s() const noexcept { return v_B_; }
  /// Angular velocity in B [rad/s].
  const Eigen::Vector3d& angularVelocity_rad_per_s() const noexcept { return w_B_; }
  const RateControlOptions& options() const noexcept { return options_; }

 private:
  RateControlOptions options_;
  haptics::Pose X_BH_;
  Eigen::Vector3d v_B_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d w_B_ = Eigen::Vector3d::Zero();
};

}  // namespace vh::devices::spacemouse
