#include "vh/simulation/device_catalog.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace vh::stability {

DeviceParams DeviceModelSpec::params(double lever_m) const {
  return DeviceParams::scaled(name, mass_kg, damping_Ns_per_m, lever_m);
}

// Sources (see device_catalog.h for the three kinds):
//   [vendor]   manufacturer data sheets as quoted in the device-model requirements; not re-checked
//              here.
//   [CHAI3D]   chai3d/chai3d@7c76b1f (CHAI3D 3.2), src/devices/CPhantomDevices.cpp lines 495-580
//              and src/devices/CDeltaDevices.cpp lines 781-1146 (m_maxLinearForce,
//              m_maxLinearStiffness).
//   [estimate] derived here. Damping: no identified per-device figure was found in this session,
//              so b_d = K_rated T / 2, the damping with which CHAI3D's own highest stiffness sits
//              exactly at Colgate and Schenkel's bound K < 2 b / T (Colgate and Schenkel 1997,
//              "Passivity of a class of sampled-data systems: application to haptic interfaces",
//              J. Robotic Systems 14(1)). This ties the model to what CHAI3D found stable on the
//              real device, but it is an estimate, and a conservative one (the hand's damping,
//              not counted, helps in practice).
//   Servo rates: the Phantom / Touch family runs the OpenHaptics servo loop at 1 kHz [vendor];
//              the Falcon updates its motors at 1 kHz (Novint, quoted at
//              http://piglix.com/piglix/Novint: "the motors are updated 1000 times per second");
//              Force Dimension devices: 4 kHz [estimate: the DHD SDK's loop over USB 2.0 commonly
//              runs at 4 kHz; the vendor quotes "up to" higher rates].

namespace {

/// The Falcon.
DeviceModelSpec falconSpec() {
  DeviceModelSpec d;
  d.name = "Falcon";
  d.mass_kg = 0.15;                   // [estimate] moving arms + grip; no published figure found.
  d.damping_Ns_per_m = 1.5;           // [estimate] 3000 N/m * 1 ms / 2.
  d.encoder_resolution_m = 25.4e-3 / 400.0;  // [vendor] "400 dpi" = 0.0635 mm.
  d.servo_rate_Hz = 1000.0;           // Novint (piglix.com/piglix/Novint), 1 kHz.
  d.max_force_N = 9.0;                // [vendor] ~9 N (CHAI3D: 8.0 N).
  d.vendor_stiffness_N_per_m = 0.0;    // No vendor stiffness found.
  d.rated_stiffness_N_per_m = 3000.0;  // [CHAI3D] CDeltaDevices.cpp, DHD_DEVICE_FALCON.
  return d;
}

/// The Touch.
DeviceModelSpec touchSpec() {
  DeviceModelSpec d;
  d.name = "Touch";
  d.mass_kg = 0.045;                  // [vendor, estimate] "apparent mass at tip" ~45 g as
                                      // commonly quoted; not re-checked.
  d.damping_Ns_per_m = 0.2;           // [estimate] 400 N/m * 1 ms / 2.
  d.encoder_resolution_m = 0.055e-3;  // [vendor] nominal position resolution 0.055 mm.
  d.servo_rate_Hz = 1000.0;           // [vendor] OpenHaptics servo loop, 1 kHz.
  d.max_force_N = 3.3;                // [vendor] 3.3 N; [CHAI3D] 3.3 N.
  d.vendor_stiffness_N_per_m = 1260.0; // [vendor] x axis 1.26 N/mm.
  d.rated_stiffness_N_per_m = 400.0; // [CHAI3D] CPhantomDevices.cpp, "Touch".
  return d;
}

/// The Touch X.
DeviceModelSpec touchXSpec() {
  DeviceModelSpec d;
  d.name = "Touch X";
  d.mass_kg = 0.045;                  // [vendor, estimate] apparent mass at tip ~45 g; not re-checked.
  d.damping_Ns_per_m = 0.5;           // [estimate] 1000 N/m * 1 ms / 2 (PHANTOM Desktop's figure).
  d.encoder_resolution_m = 0.023e-3;  // [vendor] 0.023 mm.
  d.servo_rate_Hz = 1000.0;           // [vendor] OpenHaptics servo loop, 1 kHz.
  d.max_force_N = 7.9;                // [vendor] 7.9 N; [CHAI3D] 7.9 N (PHANTOM Desktop).
  d.vendor_stiffness_N_per_m = 1860.0; // [vendor] x axis 1.86 N/mm.
  d.rated_stiffness_N_per_m = 1000.0;  // [CHAI3D] "PHANTOM Desktop", the Touch X's predecessor
                                        // (CHAI3D 3.2 has no "Touch X" entry).
  return d;
}

/// The omega.6.
DeviceModelSpec omega6Spec() {
  DeviceModelSpec d;
  d.name = "omega.6";
  d.mass_kg = 0.2;                    // [estimate] delta-mechanism moving mass; no published
                                      // apparent-mass figure found.
  d.damping_Ns_per_m = 0.625;         // [estimate] 5000 N/m * 0.25 ms / 2.
  d.encoder_resolution_m = 0.01e-3;   // [vendor] translation resolution < 0.01 mm (bound used).
  d.servo_rate_Hz = 4000.0;           // [estimate] see the header comment.
  d.max_force_N = 12.0;               // [vendor] 12 N; [CHAI3D] 12 N.
  d.vendor_stiffness_N_per_m = 14500.0;  // [vendor] closed-loop stiffness 14.5 N/mm.
  d.rated_stiffness_N_per_m = 5000.0;  // [CHAI3D] CDeltaDevices.cpp, omega.6.
  return d;
}

/// The sigma.7.
DeviceModelSpec sigma7Spec() {
  DeviceModelSpec d;
  d.name = "sigma.7";
  d.mass_kg = 0.5;                    // [estimate] heavier delta with a 3-DOF active wrist;
                                      // no published apparent-mass figure found.
  d.damping_Ns_per_m = 0.5;           // [estimate] 4000 N/m * 0.25 ms / 2.
  d.encoder_resolution_m = 0.0015e-3; // [estimate] vendor figure recalled as < 0.0015 mm,
                                      // not verified in this session.
  d.servo_rate_Hz = 4000.0;           // [estimate] see the header comment.
  d.max_force_N = 20.0;               // [vendor] 20 N (CHAI3D: 12 N).
  d.torque_actuated = true;           // [vendor] active rotations: 6-DOF force feedback + gripper.
  d.vendor_stiffness_N_per_m = 14500.0;  // [vendor] 14.5 N/mm.
  d.rated_stiffness_N_per_m = 4000.0;  // [CHAI3D] CDeltaDevices.cpp, sigma.7.
  return d;
}

/// The Phantom Premium 1.5.
DeviceModelSpec phantomPremium15Spec() {
  DeviceModelSpec d;
  d.name = "Phantom Premium 1.5";
  d.mass_kg = 0.075;                  // [vendor, estimate] apparent mass at tip < 75 g as
                                      // commonly quoted; not re-checked.
  d.damping_Ns_per_m = 0.4;           // [estimate] 800 N/m * 1 ms / 2.
  d.encoder_resolution_m = 0.03e-3;   // [vendor] 0.03 mm.
  d.servo_rate_Hz = 1000.0;           // [vendor] OpenHaptics servo loop, 1 kHz.
  d.max_force_N = 8.5;                // [vendor] 8.5 N; [CHAI3D] 8.5 N.
  d.torque_actuated = false;          // [vendor] the Premium 1.5 renders force only (its
                                      // "6DOF" variant, CHAI3D's entry, adds torque motors).
  d.vendor_stiffness_N_per_m = 3500.0; // [vendor] 3.5 N/mm.
  d.rated_stiffness_N_per_m = 800.0; // [CHAI3D] "PHANTOM Premium 1.5 6DOF".
  return d;
}

}  // namespace

const std::vector<DeviceModelSpec>& deviceCatalog() {
  static const std::vector<DeviceModelSpec> catalog = {falconSpec(), touchSpec(),  touchXSpec(),
                                                       omega6Spec(), sigma7Spec(), phantomPremium15Spec()};
  return catalog;
}

const DeviceModelSpec* findDevice(std::string_view name) {
  for (const DeviceModelSpec& d : deviceCatalog())
    if (d.name == name) return &d;
  return nullptr;
}

double quantize(double x_m, double q_m) noexcept {
  if (!(q_m > 0.0)) return x_m;
  return std::round(x_m / q_m) * q_m;
}

Eigen::Vector3d quantize(const Eigen::Vector3d& x_m, double q_m) noexcept {
  return {quantize(x_m.x(), q_m), quantize(x_m.y(), q_m), quantize(x_m.z(), q_m)};
}

DeviceIo::DeviceIo(const DeviceSignalPath& path)
    : q_m_(path.encoder_resolution_m),
      max_force_N_(path.max_force_N > 0.0 ? path.max_force_N : INFINITY),
      delay_(path.delay_ticks),
      torque_actuated_(path.torque_actuated) {
  if (delay_ < 0 || delay_ > kMaxDelayTicks)
    throw std::invalid_argument("DeviceIo: delay_ticks " + std::to_string(delay_) + " is outside [0, " +
                                std::to_string(kMaxDelayTicks) + "]");
  reset();
}

Eigen::Vector3d DeviceIo::sense(const Eigen::Vector3d& c_true_m) const noexcept { return quantize(c_true_m, q_m_); }

namespace {
// Ring of delay + 1 slots: write at head, read the slot written `delay` pushes ago.
Eigen::Vector3d pushPop(std::array<Eigen::Vector3d, DeviceIo::kMaxDelayTicks + 1>& line, int& head, int delay,
                        const Eigen::Vector3d& in) {
  const int n = delay + 1;
  line[static_cast<std::size_t>(head)] = in;
  const int read = (head + n - delay) % n;
  head = (head + 1) % n;
  return line[static_cast<std::size_t>(read)];
}
}  // namespace

Eigen::Vector3d DeviceIo::actuate(const Eigen::Vector3d& command_N) noexcept {
  Eigen::Vector3d f = pushPop(force_line_, head_f_, delay_, command_N);
  const double n = f.norm();
  if (n > max_force_N_) {
    f *= max_force_N_ / n;
    ++saturated_;
  }
  return f;
}

Eigen::Vector3d DeviceIo::actuateTorque(const Eigen::Vector3d& command_Nm) noexcept {
  const Eigen::Vector3d t = pushPop(torque_line_, head_t_, delay_, command_Nm);
  return torque_actuated_ ? t : Eigen::Vector3d::Zero();
}

void DeviceIo::reset() noexcept {
  for (auto& v : force_line_) v.setZero();
  for (auto& v : torque_line_) v.setZero();
  head_f_ = head_t_ = 0;
  saturated_ = 0;
}

}  // namespace vh::stability
