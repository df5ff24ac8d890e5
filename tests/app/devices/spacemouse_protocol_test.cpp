// Tests of vh/devices/spacemouse_protocol.h: models by id, report decoding (translation,
// rotation, the 13-byte six-axis report, buttons, battery), the axis map, the dead zone, and rate
// control (deflection -> velocity of the handle pose, workspace ball).
#include "vh/devices/spacemouse_protocol.h"

#include <cmath>
#include <numbers>
#include <vector>

#include <gtest/gtest.h>

namespace vh::devices::spacemouse {
namespace {

std::vector<std::uint8_t> report(std::uint8_t id, std::initializer_list<std::int16_t> values) {
  std::vector<std::uint8_t> r{id};
  for (std::int16_t v : values) {
    r.push_back(static_cast<std::uint8_t>(static_cast<std::uint16_t>(v) & 0xFF));
    r.push_back(static_cast<std::uint8_t>(static_cast<std::uint16_t>(v) >> 8));
  }
  return r;
}

TEST(SpaceMouseProtocol, KnowsTheFamilyByVendorAndProductId) {
  EXPECT_EQ(knownModels().size(), 10u);
  const std::vector<std::pair<std::uint16_t, std::uint16_t>> ids = {
      {0x046D, 0xC626}, {0x046D, 0xC62B}, {0x046D, 0xC629}, {0x256F, 0xC62E}, {0x256F, 0xC62F},
      {0x256F, 0xC631}, {0x256F, 0xC632}, {0x256F, 0xC633}, {0x256F, 0xC635}, {0x256F, 0xC652}};
  for (const auto& [vid, pid] : ids) EXPECT_NE(findModel(vid, pid), nullptr) << std::hex << vid << ":" << pid;
  EXPECT_STREQ(findModel(0x046D, 0xC626)->name, "SpaceNavigator");
  EXPECT_EQ(findModel(0x046D, 0xC52B), nullptr);  // a Logitech receiver
  EXPECT_EQ(findModel(0x0403, 0xCB48), nullptr);  // a Falcon
}

TEST(SpaceMouseProtocol, DecodesTranslationRotationButtonsAndBattery) {
  State s;
  auto r = report(1, {100, -200, 350});
  EXPECT_EQ(decodeReport(r.data(), r.size(), s), kChangedTranslation);
  EXPECT_EQ(s.raw[0], 100);
  EXPECT_EQ(s.raw[1], -200);
  EXPECT_EQ(s.raw[2], 350);
  r = report(2, {-1, 2, -350});
  EXPECT_EQ(decodeReport(r.data(), r.size(), s), kChangedRotation);
  EXPECT_EQ(s.raw[3], -1);
  EXPECT_EQ(s.raw[5], -350);
  EXPECT_EQ(s.raw[0], 100);  // untouched
  const std::uint8_t buttons[] = {3, 0x05, 0x01, 0x00};
  EXPECT_EQ(decodeReport(buttons, sizeof buttons, s), kChangedButtons);
  EXPECT_EQ(s.buttons, 0x105u);
  const std::uint8_t battery[] = {0x17, 87};
  EXPECT_EQ(decodeReport(battery, sizeof battery, s), kChangedBattery);
  EXPECT_EQ(s.battery_percent, 87);
}

TEST(SpaceMouseProtocol, NewerModelsSendAllSixAxesInReportOne) {
  State s;
  const auto r = report(1, {1, 2, 3, 4, 5, -6});
  ASSERT_EQ(r.size(), 13u);
  EXPECT_EQ(decodeReport(r.data(), r.size(), s), kChangedTranslation | kChangedRotation);
  EXPECT_EQ(s.raw, (std::array<std::int16_t, 6>{1, 2, 3, 4, 5, -6}));
}

TEST(SpaceMouseProtocol, IgnoresUnknownAndShortReports) {
  State s;
  const std::uint8_t unknown[] = {9, 1, 2, 3};
  EXPECT_EQ(decodeReport(unknown, sizeof unknown, s), 0u);
  const std::uint8_t short_one[] = {1, 1, 2};
  EXPECT_EQ(decodeReport(short_one, sizeof short_one, s), 0u);
  EXPECT_EQ(decodeReport(nullptr, 0, s), 0u);
  EXPECT_EQ(s.raw, (std::array<std::int16_t, 6>{}));
}

TEST(SpaceMouseProtocol, LedReports) {
  EXPECT_EQ(ledReport(true), (std::array<std::uint8_t, 2>{4, 15}));
  EXPECT_EQ(ledReport(false), (std::array<std::uint8_t, 2>{4, 0}));
}

TEST(SpaceMouseProtocol, AxisMapAndDeadZone) {
  State s;
  s.raw = {350, 175, -350, 10, 0, 350};
  RateControlOptions o;
  o.deadzone = 0.1;
  const Deflection d = deflection(s, kDefaultAxisMap, o);
  EXPECT_DOUBLE_EQ(d.translation.x(), 1.0);
  EXPECT_NEAR(d.translation.y(), -(0.5 - 0.1) / 0.9, 1e-12);  // HID y towards the user -> B y away
  EXPECT_DOUBLE_EQ(d.translation.z(), 1.0);                   // pushing down is -z of B
  EXPECT_DOUBLE_EQ(d.rotation.x(), 0.0);                      // inside the dead zone
  EXPECT_DOUBLE_EQ(d.rotation.z(), -1.0);
  // A model whose axes differ: swapped x / y.
  AxisMap swapped = kDefaultAxisMap;
  swapped.source[0] = 1;
  swapped.source[1] = 0;
  swapped.sign[1] = 1;
  const Deflection e = deflection(s, swapped, o);
  EXPECT_NEAR(e.translation.x(), (0.5 - 0.1) / 0.9, 1e-12);
  EXPECT_DOUBLE_EQ(e.translation.y(), 1.0);
  // Beyond full scale: clamped.
  s.raw[0] = 1000;
  EXPECT_DOUBLE_EQ(deflection(s, kDefaultAxisMap, o).translation.x(), 1.0);
}

TEST(SpaceMouseRateControl, DeflectionSetsTheVelocityOfThePose) {
  RateControlOptions o;
  o.max_speed_m_per_s = 0.1;
  o.max_angular_speed_rad_per_s = 1.0;
  RateController rc(o);
  Deflection d;
  d.translation = {0.5, 0.0, -1.0};
  for (int i = 0; i < 100; ++i) rc.step(d, 0.001);  // 0.1 s
  EXPECT_TRUE(rc.pose().p_AB_m.isApprox(Eigen::Vector3d(0.005, 0.0, -0.01), 1e-12));
  EXPECT_TRUE(rc.velocity_m_per_s().isApprox(Eigen::Vector3d(0.05, 0.0, -0.1), 1e-12));
  // Released: at rest where it was.
  rc.step(Deflection{}, 0.5);
  EXPECT_TRUE(rc.pose().p_AB_m.isApprox(Eigen::Vector3d(0.005, 0.0, -0.01), 1e-12));
  EXPECT_EQ(rc.velocity_m_per_s(), Eigen::Vector3d::Zero());
  // Twist about z at full deflection for pi/2 s: a quarter turn.
  Deflection twist;
  twist.rotation = {0.0, 0.0, 1.0};
  const int n = 1000;
  for (int i = 0; i < n; ++i) rc.step(twist, 0.5 * std::numbers::pi / n);
  const Eigen::Quaterniond expected(Eigen::AngleAxisd(0.5 * std::numbers::pi, Eigen::Vector3d::UnitZ()));
  EXPECT_NEAR(rc.pose().R_AB.angularDistance(expected), 0.0, 1e-9);
  EXPECT_TRUE(rc.angularVelocity_rad_per_s().isApprox(Eigen::Vector3d(0.0, 0.0, 1.0)));
}

TEST(SpaceMouseRateControl, StaysInsideTheWorkspaceBallAndClampsLongSteps) {
  RateControlOptions o;
  o.workspace_radius_m = 0.05;
  o.max_speed_m_per_s = 1.0;
  o.max_step_s = 0.02;
  RateController rc(o);
  Deflection d;
  d.translation = {1.0, 0.0, 0.0};
  rc.step(d, 10.0);  // a 10 s gap counts as 20 ms
  EXPECT_NEAR(rc.pose().p_AB_m.x(), 0.02, 1e-12);
  for (int i = 0; i < 100; ++i) rc.step(d, 0.01);
  EXPECT_NEAR(rc.pose().p_AB_m.norm(), 0.05, 1e-12);
  EXPECT_NEAR(rc.velocity_m_per_s().x(), 0.0, 1e-12);  // no outward velocity at the wall
  d.translation = {1.0, 1.0, 0.0};
  rc.step(d, 0.01);
  EXPECT_LE(rc.pose().p_AB_m.norm(), 0.05 + 1e-12);
  EXPECT_GT(rc.velocity_m_per_s().y(), 0.0);  // sliding along the wall is allowed
  rc.step(d, std::nan(""));
  EXPECT_TRUE(rc.pose().p_AB_m.allFinite());
}

}  // namespace
}  // namespace vh::devices::spacemouse
