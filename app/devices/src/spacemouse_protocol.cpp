#include "vh/devices/spacemouse_protocol.h"

#include <algorithm>
#include <cmath>

namespace vh::devices::spacemouse {

namespace {

constexpr std::array<Model, 10> kModels{{
    {0x046D, 0xC626, "SpaceNavigator", kDefaultAxisMap},
    {0x046D, 0xC62B, "SpaceMouse Pro", kDefaultAxisMap},
    {0x046D, 0xC629, "SpacePilot Pro", kDefaultAxisMap},
    {0x256F, 0xC62E, "SpaceMouse Wireless (cable)", kDefaultAxisMap},
    {0x256F, 0xC62F, "SpaceMouse Wireless (receiver)", kDefaultAxisMap},
    {0x256F, 0xC631, "SpaceMouse Pro Wireless (cable)", kDefaultAxisMap},
    {0x256F, 0xC632, "SpaceMouse Pro Wireless (receiver)", kDefaultAxisMap},
    {0x256F, 0xC633, "SpaceMouse Enterprise", kDefaultAxisMap},
    {0x256F, 0xC635, "SpaceMouse Compact", kDefaultAxisMap},
    {0x256F, 0xC652, "3Dconnexion Universal Receiver", kDefaultAxisMap},
}};

std::int16_t int16le(const std::uint8_t* p) noexcept {
  return static_cast<std::int16_t>(static_cast<std::uint16_t>(p[0] | (p[1] << 8)));
}

double shaped(double counts, const RateControlOptions& o) noexcept {
  if (!(o.full_scale_counts > 0.0)) return 0.0;
  const double x = counts / o.full_scale_counts;
  const double dz = std::clamp(o.deadzone, 0.0, 0.99);
  const double mag = std::max(0.0, std::abs(x) - dz) / (1.0 - dz);
  return std::copysign(std::min(mag, 1.0), x);
}

}  // namespace

std::span<const Model> knownModels() noexcept { return {kModels.data(), kModels.size()}; }

const Model* findModel(std::uint16_t vendor_id, std::uint16_t product_id) noexcept {
  for (const Model& m : kModels) {
    if (m.vendor_id == vendor_id && m.product_id == product_id) return &m;
  }
  return nullptr;
}

unsigned decodeReport(const std::uint8_t* report, std::size_t size, State& state) noexcept {
  if (report == nullptr || size == 0) return 0;
  switch (report[0]) {
    case kReportTranslation:
      if (size >= 13) {  // newer wireless models: all six axes in report 1
        for (std::size_t i = 0; i < 6; ++i) state.raw[i] = int16le(report + 1 + 2 * i);
        return kChangedTranslation | kChangedRotation;
      }
      if (size < 7) return 0;
      for (std::size_t i = 0; i < 3; ++i) state.raw[i] = int16le(report + 1 + 2 * i);
      return kChangedTranslation;
    case kReportRotation:
      if (size < 7) return 0;
      for (std::size_t i = 0; i < 3; ++i) state.raw[3 + i] = int16le(report + 1 + 2 * i);
      return kChangedRotation;
    case kReportButtons: {
      if (size < 2) return 0;
      std::uint32_t mask = 0;
      const std::size_t n = std::min<std::size_t>(size - 1, 4);
      for (std::size_t i = 0; i < n; ++i) mask |= static_cast<std::uint32_t>(report[1 + i]) << (8 * i);
      state.buttons = mask;
      return kChangedButtons;
    }
    case kReportBattery:
      if (size < 2) return 0;
      state.battery_percent = std::min<int>(report[1], 100);
      return kChangedBattery;
    default:
      return 0;
  }
}

std::array<std::uint8_t, 2> ledReport(bool on) noexcept {
  return {4, static_cast<std::uint8_t>(on ? 15 : 0)};
}

Deflection deflection(const State& state, const AxisMap& axes, const RateControlOptions& options) noexcept {
  Deflection d;
  for (int i = 0; i < 6; ++i) {
    const std::size_t src = std::min<std::size_t>(axes.source[static_cast<std::size_t>(i)], 5);
    const double counts = static_cast<double>(axes.sign[static_cast<std::size_t>(i)]) * state.raw[src];
    const double v = shaped(counts, options);
    if (i < 3) d.translation[i] = v;
    else d.rotation[i - 3] = v;
  }
  return d;
}

void RateController::reset(const haptics::Pose& X_BH) noexcept {
  X_BH_ = X_BH;
  v_B_.setZero();
  w_B_.setZero();
}

void RateController::step(const Deflection& d, double dt_s) noexcept {
  const double dt = std::isfinite(dt_s) ? std::clamp(dt_s, 0.0, options_.max_step_s) : 0.0;
  Eigen::Vector3d v = options_.max_speed_m_per_s * d.translation;
  Eigen::Vector3d w = options_.max_angular_speed_rad_per_s * d.rotation;
  if (!v.allFinite()) v.setZero();
  if (!w.allFinite()) w.setZero();
  Eigen::Vector3d p = X_BH_.p_AB_m + v * dt;
  const double r = options_.workspace_radius_m;
  const double n = p.norm();
  if (r > 0.0 && n > r) {
    // At the wall: stop there and drop the outward part of the velocity.
    const Eigen::Vector3d u = p / n;
    p = u * r;
    const double out = v.dot(u);
    if (out > 0.0) v -= out * u;
  }
  X_BH_.p_AB_m = p;
  X_BH_.R_AB = (haptics::quaternionFromRotationVector(w * dt) * X_BH_.R_AB).normalized();
  v_B_ = v;
  w_B_ = w;
}

}  // namespace vh::devices::spacemouse
