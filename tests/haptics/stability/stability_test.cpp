// Stiff cases: the renderer closed around a simulated device and hand, coupling
// stiffness 100 .. 50,000 N/m, torsional stiffness over the matching range. See device_model.h
// for the model, units and the energy bookkeeping, scenarios.h for the scenes and the verdicts.
//
// Two couplings are compared:
//   diag    the README's gains, K = diag(k_lin / 2m, k_ang / 2i) with k_ang = k_lin (20 mm)^2
//           (0.04 .. 20 N*m/rad);
//   scalar  the paper's eq. 5 with one scalar k: K M = (k / 2m) M, i.e. k_ang = k_lin i / m.
// The configuration solver moves the proxy by a projection in the mass metric M; only with the
// scalar coupling is the coupling's energy a multiple of that metric, so only then does the
// projection guarantee that the proxy never moves against the coupling (see the DISABLED_
// reproductions below for what the diagonal coupling does).
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <numbers>

#include <gtest/gtest.h>

#include "vh/simulation/stability_scenarios.h"
#include "vh/haptics/configuration_solver.h"
#include "vh/haptics/virtual_coupling.h"

namespace vh::stability {
namespace {

constexpr double kT = 1e-3;
const std::vector<double> kStiffnesses{100, 300, 1000, 3000, 5000, 10000, 30000, 50000};

DeviceParams deviceA() { return DeviceParams::scaled("A", 0.2, 1.0, kLever_m); }  // damped, 0.2 kg
DeviceParams deviceB() { return DeviceParams::scaled("B", 0.1, 0.0, kLever_m); }  // undamped, light
HandParams hand() { return HandParams::scaled(500.0, 5.0, kLever_m); }

const std::vector<Scenario>& scenarios() {
  static const std::vector<Scenario> s = defaultScenarios();
  return s;
}

// <base>.json for the default (accelerated) mode, <base>_paper.json for the paper's path.
std::string reportName(const std::string& base, haptics::DetectionMode mode) {
  return base + (mode == haptics::DetectionMode::kPaper ? "_paper" : "") + ".json";
}

void writeReport(const std::string& file, const std::vector<StiffnessResult>& rows) {
  const std::string path = std::string(VH_STABILITY_REPORT_DIR) + "/" + file;
  std::ofstream(path) << jsonReport(rows, hand());
  std::cout << markdownTable(rows) << "(written to " << path << ")\n";
}

// --- The harness against closed-form results ---------------------------------------------

// The tests that run the renderer run in both detection modes.
std::string modeName(const ::testing::TestParamInfo<haptics::DetectionMode>& p) { return haptics::toString(p.param); }
#define VH_BOTH_MODES(suite)                                                    \
  class suite : public ::testing::TestWithParam<haptics::DetectionMode> {};     \
  INSTANTIATE_TEST_SUITE_P(Modes, suite,                                        \
                           ::testing::Values(haptics::DetectionMode::kPaper,    \
                                             haptics::DetectionMode::kAccelerated), modeName)
VH_BOTH_MODES(StabilitySolverModes);
VH_BOTH_MODES(StabilitySweepModes);
VH_BOTH_MODES(StabilityLongModes);

// Colgate and Schenkel: a mass-damper touching a zero-order-hold spring is stable for
// K < ~2b/T when bT/m is small. The exact discrete analysis must agree within 10 %.
TEST(StabilityHarness, LinearAnalysisAgreesWithColgatesBound) {
  for (double b : {0.5, 1.0, 3.0}) {
    const double k_star = linearStabilityLimit(0.2, b, 0.0, 0.0, kT);
    EXPECT_NEAR(k_star, colgateMaxStiffness(b, kT), 0.1 * colgateMaxStiffness(b, kT)) << "b = " << b;
  }
  // The hand's damping adds to the device's.
  EXPECT_NEAR(linearStabilityLimit(0.2, 1.0, 500.0, 5.0, kT), colgateMaxStiffness(6.0, kT),
              0.1 * colgateMaxStiffness(6.0, kT));
  EXPECT_LT(contactSpectralRadius(0.2, 1.0, 500.0, 5.0, 1000.0, kT), 1.0);
  EXPECT_GT(contactSpectralRadius(0.1, 0.0, 500.0, 5.0, 50000.0, kT), 1.0);
}

// A released, undamped handle bouncing off the plane: the zero-order hold acts as a negative
// damper K T / 2, so the coupling returns more than it took: E_out / E_in = 1 + (pi / 2) w T
// to first order in w T (w = sqrt(K / m); the contact lasts pi / w at speed v0 cos(w t)).
// The energy bookkeeping must also close: E_gen at the end = the handle's kinetic energy gain.
TEST(StabilityHarness, FreeBounceMatchesTheZeroOrderHoldPrediction) {
  const Scenario& bounce = scenarios().back();
  ASSERT_TRUE(bounce.bounce);
  const DeviceParams dev = deviceB();
  for (double k : {100.0, 300.0, 1000.0}) {
    const SimulationResult r = runScenario(bounce, k, dev, hand(), {0.0, 0.0});
    const double ratio = r.energy_out_J / r.energy_in_J;
    const double wT = std::sqrt(k / dev.mass_kg) * kT;
    EXPECT_NEAR(ratio - 1.0, std::numbers::pi / 2.0 * wT, 0.15 * std::numbers::pi / 2.0 * wT) << "K = " << k;
    const double v0 = bounce.start.v_W_mps.norm();
    const double v1 = r.ticks.back().v_D.norm(), w1 = r.ticks.back().w_D.norm();
    const double ke_gain = 0.5 * dev.mass_kg * (v1 * v1 - v0 * v0) + 0.5 * dev.inertia_kgm2 * w1 * w1;
    EXPECT_NEAR(r.ticks.back().e_gen_J, ke_gain, 1e-4 * std::abs(ke_gain)) << "K = " << k;
    std::printf("bounce K = %.0f: E_out / E_in = %.5f, 1 + (pi/2) w T = %.5f; E_gen %.6g J, KE gain %.6g J\n", k,
                ratio, 1.0 + std::numbers::pi / 2.0 * wT, r.ticks.back().e_gen_J, ke_gain);
    EXPECT_EQ(r.ticks.back().contacts, 0) << "the handle must have left the plane";
  }
}

// --- The configuration solver never injects energy ---------------------------------------

// Strict: the paper's algorithm (scalar coupling, no contact stand-off), every scenario, every
// stiffness, both devices: at every tick the coupling does non-negative work on the proxy,
// S_k >= -tol_k (device_model.h; tol_k is rounding only, see solverWorkTolerance()).
TEST_P(StabilitySolverModes, ProxyNeverMovesAgainstTheCoupling) {
  const SweepOptions paper{0.0, 0.0, true, GetParam()};
  for (const DeviceParams& dev : {deviceA(), deviceB()})
    for (double k : kStiffnesses)
      for (const Scenario& sc : scenarios()) {
        const SimulationResult r = runScenario(sc, k, dev, hand(), paper);
        SCOPED_TRACE(sc.name + ", device " + dev.name + ", K = " + std::to_string(k));
        EXPECT_TRUE(r.finite);
        EXPECT_EQ(r.bad_inputs, 0);
        EXPECT_EQ(r.solver_violations, 0) << "worst S_k " << r.worst_solver_work_J << " J, injected "
                                          << r.solver_injected_J << " J";
        EXPECT_GE(r.min_solver_margin_J, 0.0);
        EXPECT_LE(r.max_penetration_m, r.epsilon_m);
        EXPECT_LE(r.max_force_error_rel, 1e-9);
      }
}

// The optional contact stand-off (off by default) lifts contacts out of the surface, against
// the spring: with it on (epsilon / 4), that lift is the only motion against the coupling, and
// no tick loses more than |F| * (lift cap 2 * epsilon / 4) of solver work.
TEST_P(StabilitySolverModes, StandOffLiftIsTheOnlyMotionAgainstTheCoupling) {
  const SweepOptions standoff{0.25, 0.0, false, GetParam()};
  int lifts = 0;
  double injected = 0.0, throughput = 0.0;
  for (const DeviceParams& dev : {deviceA(), deviceB()})
    for (double k : kStiffnesses)
      for (const Scenario& sc : scenarios()) {
        const SimulationResult r = runScenario(sc, k, dev, hand(), standoff);
        SCOPED_TRACE(sc.name + ", device " + dev.name + ", K = " + std::to_string(k));
        EXPECT_EQ(r.lift_bound_violations, 0) << "worst S_k " << r.worst_solver_work_J << " J";
        lifts += r.solver_violations;
        injected += r.solver_injected_J;
        throughput += r.energy_in_J + r.energy_out_J;
      }
  std::printf("stand-off epsilon / 4: %d lifts moved the proxy against the coupling, %.3g J in all (%.2g of the "
              "%.3g J that went through the coupling)\n",
              lifts, injected, injected / throughput, throughput);
}

// Positive control for the reproduction below: one contact, one solver step, scalar coupling.
// A 5 mm ball (i / m = 1e-5 m^2) resting on the plane z = 0 with its contact point 1 mm off the
// bottom; the device 1 mm down and 1 mm sideways.
struct OneContact {
  haptics::MassProperties mass;
  haptics::Pose P = haptics::Pose::FromTranslation({0, 0, 0.005});
  haptics::Pose D = haptics::Pose::FromTranslation({0.001, 0, 0.004});
  haptics::Contact contact;
  OneContact() {
    mass.mass_kg = 0.004;
    mass.I_Cm_T_kgm2 = Eigen::Matrix3d::Identity() * 0.004 * 1e-5;
    contact.point_index = 0;
    contact.p_W_m = {0.001, 0.0, 0.005 - std::sqrt(0.005 * 0.005 - 0.001 * 0.001)};
    contact.n_W = Eigen::Vector3d::UnitZ();
    contact.clearance_m = 1e-6;
  }
  // Coupling energy 1/2 k |dc|^2 + 1/2 (k_ang / i) theta^T I_W theta (the README's eq. 5).
  double energy(const haptics::Pose& X_WP, const haptics::CouplingGains& g) const {
    const Eigen::Vector3d dc = D.p_AB_m - X_WP.p_AB_m;
    const Eigen::Vector3d th = haptics::rotationVector(D.R_AB * X_WP.R_AB.conjugate());
    const double i = mass.I_Cm_T_kgm2.trace() / 3.0;
    return 0.5 * g.linear_N_per_m * dc.squaredNorm() + 0.5 * g.angular_Nm_per_rad / i * th.dot(mass.I_Cm_T_kgm2 * th);
  }
  // Energy before and after the solver's full step (no collision detection involved).
  std::pair<double, double> step(const haptics::CouplingGains& g) const {
    haptics::ConfigurationSolver solver;
    solver.setGains(g);  // the renderer's solver projects in the coupling's metric
    const haptics::RigidMotion m = solver.constrainedMotion(P, D, mass, {&contact, 1}, 0.0);
    return {energy(P, g), energy(m.poseAt(1.0), g)};
  }
};

TEST(StabilitySolver, ScalarCouplingOneContactStepLowersTheCouplingEnergy) {
  const OneContact s;
  const double k = 5000.0;
  const auto [before, after] = s.step({k, k * 1e-5});  // k_ang = k i / m
  EXPECT_LT(after, before);
}

// Regression for a core defect, fixed by projecting in the coupling's metric: with the
// diagonal coupling and the M-metric projection the solver's step raised the coupling energy
// from 5.0 mJ to 10.3 mJ.
// The M-metric projection prefers a 0.09 rad roll of the ball (cheap in M: i / m = 1e-5 m^2)
// that the torsional spring (k_ang / i = 40 k_lin / m) charges heavily. Fix: project in the
// coupling's metric K M (= diag(k_lin I, k_ang I_W / i) up to a factor) instead of M; the two
// agree for the paper's scalar k. Checked by hand with ConeProjector on this case: in the
// coupling metric the step is a 0.0025 rad roll and the energy falls to 2.49 mJ.
TEST(StabilitySolver, DiagonalCouplingOneContactStepLowersTheCouplingEnergy) {
  const OneContact s;
  const double k = 5000.0;
  const auto [before, after] = s.step({k, k * kLever_m * kLever_m});
  EXPECT_LT(after, before) << "coupling energy " << before << " J -> " << after << " J";
}

// Regression at the renderer level (was: the ball sliding over the sphere with the diagonal
// coupling (no stand-off, so only the solver moves the proxy) at 1000 N/m on device A: the proxy
// rolls against the torsional spring on 712 ticks (worst -1.1 mJ, 9.9 mJ in all), and the
// coupling gives the device 9.2 mJ for 3.7 mJ taken (E_gen = +7.8 mJ), although Colgate's
// bound (2 b / T = 2000 N/m) says this device is passive at 1000 N/m, as the scalar coupling
// shows (E_gen <= 0). The fix of the one-contact case fixes this too.
TEST_P(StabilitySolverModes, DiagonalCouplingSphereSlideNeverMovesAgainstTheCoupling) {
  const Scenario& sphere = scenarios()[1];
  const SimulationResult r = runScenario(sphere, 1000.0, deviceA(), hand(), {0.0, kLever_m, true, GetParam()});
  EXPECT_EQ(r.solver_violations, 0) << "worst S_k " << r.worst_solver_work_J << " J, injected "
                                    << r.solver_injected_J << " J";
  EXPECT_LE(r.max_e_gen_J, passivityTolerance(r.energy_in_J + r.energy_out_J))
      << "energy in " << r.energy_in_J << " J, out " << r.energy_out_J << " J";
}

// --- The sweep ------------------------------------------------------------------------------

std::vector<StiffnessResult> sweep(const std::vector<Scenario>& scs, const std::vector<double>& ks,
                                   const std::vector<DeviceParams>& devices, haptics::DetectionMode mode) {
  std::vector<StiffnessResult> rows;
  for (double lever : {kLever_m, 0.0})
    for (const DeviceParams& d : devices)
      for (double k : ks) rows.push_back(evaluate(scs, k, d, hand(), {-1.0, lever, false, mode}));
  return rows;
}

// Expectations that hold for any row of a sweep.
void checkRow(const StiffnessResult& s) {
  SCOPED_TRACE(s.gains + ", device " + s.device + ", K = " + std::to_string(s.k_lin));
  EXPECT_TRUE(s.finite);
  EXPECT_EQ(s.bad_inputs, 0);
  EXPECT_LE(s.max_force_error_rel, 1e-9);
  if (s.gains == "scalar") {
    // The paper's algorithm (the default: no stand-off) never moves the proxy against the
    // scalar coupling; were the stand-off on, only its bounded lift could.
    EXPECT_EQ(s.lift_bound_violations, 0) << "worst S_k " << s.worst_solver_work_J << " J";
    if (haptics::RendererOptions{}.standoff_fraction == 0.0) {
      EXPECT_EQ(s.solver_violations, 0) << "worst S_k " << s.worst_solver_work_J << " J";
    }
    // Passivity as Colgate predicts it for the device's own damping (factor 2 of margin).
    if (s.k_lin <= 0.5 * s.colgate_k_max) {
      EXPECT_TRUE(s.passive) << "max E_gen " << s.max_e_gen_J << " J";
    }
    if (s.k_lin >= 2.0 * s.colgate_k_max) {
      EXPECT_FALSE(s.passive) << "max E_gen " << s.max_e_gen_J << " J";
    }
  }
  // The closed loop with the hand behaves as the linear analysis predicts, away from its edge.
  if (s.spectral_radius <= 0.995) {
    EXPECT_TRUE(s.stable()) << toString(s.behaviour);
  }
  if (s.spectral_radius >= 1.01) {
    EXPECT_FALSE(s.stable()) << toString(s.behaviour);
  }
  // Friction-free, quasi-static contact: the settled force is k_eff * depth (the proxy rests
  // within epsilon of the surface: 2 epsilon of depth error at most).
  if (s.behaviour == Behaviour::kSettled) {
    EXPECT_LE(s.steady_force_error_rel, 0.01 + 2.0 * 0.25e-3 / kDepth_m);
  }
}

TEST_P(StabilitySweepModes, StiffnessFrom100To50000NPerM) {
  const std::vector<StiffnessResult> rows = sweep(scenarios(), kStiffnesses, {deviceA(), deviceB()}, GetParam());
  writeReport(reportName("stability_report", GetParam()), rows);
  for (const StiffnessResult& s : rows) {
    checkRow(s);
    SCOPED_TRACE(s.gains + ", device " + s.device + ", K = " + std::to_string(s.k_lin));
    // Up to the paper's 5000 N/m both devices hold a stable contact with the hand.
    if (s.k_lin <= 5000.0) {
      EXPECT_TRUE(s.stable()) << toString(s.behaviour);
    }
    // The paper's 5000 N/m on the 0.2 kg device: 0.5 s after the hand stops, the force varies
    // by less than 10 % of itself, the contact holds, and the force is k_eff * depth.
    if (s.k_lin == 5000.0 && s.device == "A") {
      EXPECT_LT(s.settled_ptp_rel, 0.10);
      EXPECT_EQ(s.contact_lost_ticks, 0);
      EXPECT_LE(s.steady_force_error_rel, 0.01 + 2.0 * 0.25e-3 / kDepth_m);
    }
    // The undamped device is never passive: every contact gains the hold's K T / 2 v^2.
    if (s.gains == "scalar" && s.device == "B") {
      EXPECT_FALSE(s.passive);
    }
  }
}

// --- Long runs (labels stability;long) ---------------------------------------------------------

TEST_P(StabilityLongModes, FullSweep) {
  std::vector<double> ks;
  for (double k = 100.0; k <= 50000.0 * 1.0001; k *= std::pow(500.0, 1.0 / 18.0)) ks.push_back(std::round(k));
  const std::vector<DeviceParams> devices{deviceA(), deviceB(), DeviceParams::scaled("C", 0.2, 3.0, kLever_m),
                                          DeviceParams::scaled("D", 0.1, 1.0, kLever_m),
                                          DeviceParams::scaled("E", 0.5, 2.0, kLever_m)};
  const std::vector<StiffnessResult> rows = sweep(scenarios(), ks, devices, GetParam());
  writeReport(reportName("stability_report_long", GetParam()), rows);
  for (const StiffnessResult& s : rows) checkRow(s);
  // The strict solver test over the whole grid.
  for (const DeviceParams& dev : devices)
    for (double k : ks)
      for (const Scenario& sc : scenarios()) {
        const SimulationResult r = runScenario(sc, k, dev, hand(), {0.0, 0.0, true, GetParam()});
        EXPECT_EQ(r.solver_violations, 0) << sc.name << ", device " << dev.name << ", K = " << k;
      }
}

TEST_P(StabilityLongModes, PegInHole) {
  const std::vector<Scenario> peg{pegScenario()};
  std::vector<StiffnessResult> rows;
  for (double lever : {kLever_m, 0.0})
    for (double k : kStiffnesses) rows.push_back(evaluate(peg, k, deviceA(), hand(), {-1.0, lever, true, GetParam()}));
  writeReport(reportName("stability_report_peg", GetParam()), rows);
  for (const StiffnessResult& s : rows) {
    SCOPED_TRACE(s.gains + ", K = " + std::to_string(s.k_lin));
    EXPECT_TRUE(s.finite);
    EXPECT_LE(s.max_penetration_over_eps, 1.0);
    if (s.gains == "scalar") {
      EXPECT_EQ(s.lift_bound_violations, 0);
    }
  }
  for (double k : kStiffnesses) {
    const SimulationResult r = runScenario(peg[0], k, deviceA(), hand(), {0.0, 0.0, true, GetParam()});
    EXPECT_EQ(r.solver_violations, 0) << "K = " << k << ", worst S_k " << r.worst_solver_work_J << " J";
    EXPECT_LE(r.max_penetration_m, r.epsilon_m);
  }
}

}  // namespace
}  // namespace vh::stability
