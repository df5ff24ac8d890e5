#include "vh/simulation/stability_scenarios.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <sstream>

#include "vh/datasets/synthetic.h"

namespace vh::stability {

using haptics::Pose;

namespace {

datasets::GridSpec grid1mm() {
  datasets::GridSpec g;
  g.dims = {64, 64, 64};
  g.spacing_m = Eigen::Vector3d::Constant(1e-3);
  return g;
}

std::shared_ptr<const haptics::ToolModel> meshTool(const haptics::TriangleMesh& mesh, double spacing_m) {
  haptics::PointShellOptions o;
  o.spacing_m = spacing_m;
  return std::make_shared<haptics::ToolModel>(haptics::makeToolModel(mesh, o));
}

Pose poseOfCm(const haptics::ToolModel& tool, const Eigen::Vector3d& c, const Eigen::Quaterniond& R) {
  return {R, c - R * tool.mass.p_TCm_m};
}

/// Plane: press, hold, slide, hold, tilt, hold.
Scenario planePressSlideTilt(const std::shared_ptr<const haptics::ScalarVolume>& plane,
                             const std::shared_ptr<const haptics::ToolModel>& box, double half_h) {
  const Eigen::Vector3d up = Eigen::Vector3d::UnitZ();
  Scenario sc;
  sc.name = "plane press-slide-tilt";
  sc.volume = plane;
  sc.tool = box;
  const Eigen::Vector3d c0(0, 0, half_h + 0.002);
  sc.X_WP0 = poseOfCm(*box, c0, Eigen::Quaterniond::Identity());
  sc.start.c_W_m = c0;
  const double drop = 0.002 + kDepth_m;  // to kDepth_m past contact
  sc.hand = [c0, drop](double t) {
    HandTarget h;
    h.c_W_m = c0 + Eigen::Vector3d(0.015 * ramp(t, 0.85, 1.15), 0.0, -drop * ramp(t, 0.05, 0.25));
    h.v_W_mps = Eigen::Vector3d(0.015 * rampRate(t, 0.85, 1.15), 0.0, -drop * rampRate(t, 0.05, 0.25));
    const double a = 0.15 * ramp(t, 1.25, 1.45);
    h.R_W = Eigen::Quaterniond(Eigen::AngleAxisd(a, Eigen::Vector3d::UnitY()));
    h.w_W_radps = Eigen::Vector3d(0.0, 0.15 * rampRate(t, 1.25, 1.45), 0.0);
    return h;
  };
  sc.duration_s = 2.05;
  sc.settle = {{0.75, 0.85, up}, {1.95, 2.05, up}};
  return sc;
}

/// Sphere: press onto the top, hold, slide 0.5 rad around, hold.
Scenario spherePressSlide() {
  const Eigen::Vector3d up = Eigen::Vector3d::UnitZ();
  Scenario sc;
  sc.name = "sphere press-slide";
  sc.volume = std::make_shared<const haptics::ScalarVolume>(
      datasets::makeSphereVolume(grid1mm(), Eigen::Vector3d::Zero(), 0.020));
  sc.tool = meshTool(datasets::makeBuiltinTool("sphere"), 1e-3);
  const double r_rest = 0.020 + 0.005;
  const Eigen::Vector3d c0(0, 0, r_rest + 0.003);
  sc.X_WP0 = poseOfCm(*sc.tool, c0, Eigen::Quaterniond::Identity());
  sc.start.c_W_m = c0;
  sc.hand = [r_rest](double t) {
    HandTarget h;
    const double r = r_rest + 0.003 - (0.003 + kDepth_m) * ramp(t, 0.05, 0.25);
    const double dr = -(0.003 + kDepth_m) * rampRate(t, 0.05, 0.25);
    const double phi = 0.5 * ramp(t, 0.85, 1.15), dphi = 0.5 * rampRate(t, 0.85, 1.15);
    const Eigen::Vector3d dir(std::sin(phi), 0.0, std::cos(phi)), ddir(std::cos(phi), 0.0, -std::sin(phi));
    h.c_W_m = r * dir;
    h.v_W_mps = dr * dir + r * dphi * ddir;
    return h;
  };
  sc.duration_s = 1.75;
  sc.settle = {{0.75, 0.85, up}, {1.65, 1.75, Eigen::Vector3d(std::sin(0.5), 0.0, std::cos(0.5))}};
  return sc;
}

/// Tap: the target falls at 0.3 m/s from 10 mm above the plane and stops dead.
Scenario planeTap(const std::shared_ptr<const haptics::ScalarVolume>& plane,
                  const std::shared_ptr<const haptics::ToolModel>& box, double half_h) {
  const Eigen::Vector3d up = Eigen::Vector3d::UnitZ();
  Scenario sc;
  sc.name = "plane tap 0.3 m/s";
  sc.volume = plane;
  sc.tool = box;
  const Eigen::Vector3d c0(0, 0, half_h + 0.010);
  sc.X_WP0 = poseOfCm(*box, c0, Eigen::Quaterniond::Identity());
  sc.start.c_W_m = c0;
  const double speed = 0.3, t0 = 0.02, drop = 0.010 + kDepth_m, t1 = t0 + drop / speed;
  sc.hand = [=](double t) {
    HandTarget h;
    const double s = std::clamp((t - t0) / (t1 - t0), 0.0, 1.0);
    h.c_W_m = c0 - up * drop * s;
    h.v_W_mps = (t > t0 && t < t1) ? Eigen::Vector3d(-up * speed) : Eigen::Vector3d::Zero();
    return h;
  };
  sc.duration_s = 0.7;
  sc.settle = {{0.6, 0.7, up}};
  return sc;
}

/// Bounce: released handle reaching the plane at 0.1 m/s.
Scenario planeBounce(const std::shared_ptr<const haptics::ScalarVolume>& plane,
                     const std::shared_ptr<const haptics::ToolModel>& box, double half_h) {
  const Eigen::Vector3d up = Eigen::Vector3d::UnitZ();
  Scenario sc;
  sc.name = "plane bounce 0.1 m/s";
  sc.volume = plane;
  sc.tool = box;
  const Eigen::Vector3d c0(0, 0, half_h + 0.0005);
  sc.X_WP0 = poseOfCm(*box, c0, Eigen::Quaterniond::Identity());
  sc.start.c_W_m = c0;
  sc.start.v_W_mps = -0.1 * up;
  sc.duration_s = 0.3;
  sc.bounce = true;
  return sc;
}

}  // namespace

std::vector<Scenario> defaultScenarios() {
  std::vector<Scenario> out;
  const auto plane = std::make_shared<const haptics::ScalarVolume>(
      datasets::makePlaneVolume(grid1mm(), Eigen::Vector3d::UnitZ(), 0.0));
  // 10 x 10 x 4 mm box; Cm at its centre, bottom face 2 mm below Cm.
  const auto box = meshTool(datasets::makeBoxMesh({0.005, 0.005, 0.002}), 1e-3);
  const double half_h = 0.002;
  out.push_back(planePressSlideTilt(plane, box, half_h));
  out.push_back(spherePressSlide());
  out.push_back(planeTap(plane, box, half_h));
  out.push_back(planeBounce(plane, box, half_h));
  return out;
}

Scenario pegScenario() {
  Scenario sc;
  sc.name = "peg in blind hole";
  const double floor_z = -0.004;
  sc.volume = std::make_shared<const haptics::ScalarVolume>(datasets::makeBlockWithBlindHoleVolume(256, floor_z));
  sc.isovalue = datasets::kBlockIsovalue;
  // The snug peg 80 mm long with the paper's 1307 points (about 50 on its flat end).
  haptics::PointShellOptions ps;
  ps.point_count = 1307;
  sc.tool = std::make_shared<haptics::ToolModel>(
      haptics::makeToolModel(datasets::makeCylinderMesh(datasets::kPegRadius_m, 0.08, 64), ps));
  const auto& tool = *sc.tool;
  // Tip 3 mm above the block's top, centred over the hole.
  const Eigen::Vector3d tip0(0, 0, datasets::kBlockHalfHeight_m + 0.003);
  const Eigen::Vector3d c0 = tip0 + tool.mass.p_TCm_m;
  sc.X_WP0 = poseOfCm(tool, c0, Eigen::Quaterniond::Identity());
  sc.start.c_W_m = c0;
  // Lower the tip to kDepth_m below the hole's floor (0.05-0.45 s), hold (judged on the floor's
  // normal), pull the target 4 mm sideways (0.85-1.0 s; the clearance is 0.5 mm), hold, pry
  // 0.1 rad about y (1.2-1.35 s), hold (judged along -x: the wall at +x pushes the hand back).
  const double drop = tip0.z() - floor_z + kDepth_m;
  sc.hand = [c0, drop](double t) {
    HandTarget h;
    h.c_W_m = c0 + Eigen::Vector3d(0.004 * ramp(t, 0.85, 1.0), 0.0, -drop * ramp(t, 0.05, 0.45));
    h.v_W_mps = Eigen::Vector3d(0.004 * rampRate(t, 0.85, 1.0), 0.0, -drop * rampRate(t, 0.05, 0.45));
    h.R_W = Eigen::Quaterniond(Eigen::AngleAxisd(0.1 * ramp(t, 1.2, 1.35), Eigen::Vector3d::UnitY()));
    h.w_W_radps = Eigen::Vector3d(0.0, 0.1 * rampRate(t, 1.2, 1.35), 0.0);
    return h;
  };
  sc.duration_s = 1.85;
  sc.settle = {{0.75, 0.85, Eigen::Vector3d::UnitZ()}, {1.75, 1.85, -Eigen::Vector3d::UnitX()}};
  return sc;
}

Scenario wedgeScenario() {
  Scenario sc;
  sc.name = "wedge press-slide";
  // Solid: below either face, n1 . p < 0 or n2 . p < 0 (union: the larger signed distance).
  const double a = std::numbers::pi / 4.0;
  const Eigen::Vector3d n1(std::sin(a), 0.0, std::cos(a)), n2(-std::sin(a), 0.0, std::cos(a));
  sc.volume = std::make_shared<const haptics::ScalarVolume>(datasets::makeVolumeFromSignedDistance(
      grid1mm(), [n1, n2](const Eigen::Vector3d& p) { return std::max(-n1.dot(p), -n2.dot(p)); }));
  sc.tool = meshTool(datasets::makeBuiltinTool("sphere"), 1e-3);
  const double r_tool = 0.005, z_rest = r_tool / std::cos(a);  // touching both faces
  const Eigen::Vector3d c0(0, -0.005, z_rest + 0.002);
  sc.X_WP0 = poseOfCm(*sc.tool, c0, Eigen::Quaterniond::Identity());
  sc.start.c_W_m = c0;
  const double drop = 0.002 + kDepth_m;
  sc.hand = [c0, drop](double t) {
    HandTarget h;
    h.c_W_m = c0 + Eigen::Vector3d(0.0, 0.010 * ramp(t, 0.85, 1.15), -drop * ramp(t, 0.05, 0.25));
    h.v_W_mps = Eigen::Vector3d(0.0, 0.010 * rampRate(t, 0.85, 1.15), -drop * rampRate(t, 0.05, 0.25));
    return h;
  };
  sc.duration_s = 1.55;
  sc.settle = {{0.75, 0.85, Eigen::Vector3d::UnitZ()}, {1.45, 1.55, Eigen::Vector3d::UnitZ()}};
  return sc;
}

std::vector<Scenario> deviceScenarios() {
  std::vector<Scenario> all = defaultScenarios(), out;
  for (Scenario& sc : all)
    if (sc.name == "plane press-slide-tilt" || sc.name == "sphere press-slide") out.push_back(std::move(sc));
  out.push_back(wedgeScenario());
  return out;
}

Scenario slowPressScenario() {
  Scenario sc;
  sc.name = "plane slow press";
  sc.volume = std::make_shared<const haptics::ScalarVolume>(
      datasets::makePlaneVolume(grid1mm(), Eigen::Vector3d::UnitZ(), 0.0));
  sc.tool = meshTool(datasets::makeBoxMesh({0.005, 0.005, 0.002}), 1e-3);
  const Eigen::Vector3d c0(0, 0, 0.002 + 0.0002);  // 0.2 mm above the plane
  sc.X_WP0 = poseOfCm(*sc.tool, c0, Eigen::Quaterniond::Identity());
  sc.start.c_W_m = c0;
  const double drop = 0.0002 + kDepth_m;
  sc.hand = [c0, drop](double t) {
    HandTarget h;
    const double s = ramp(t, 0.2, 1.2) - ramp(t, 1.6, 2.6), ds = rampRate(t, 0.2, 1.2) - rampRate(t, 1.6, 2.6);
    h.c_W_m = c0 - Eigen::Vector3d::UnitZ() * drop * s;
    h.v_W_mps = -Eigen::Vector3d::UnitZ() * drop * ds;
    return h;
  };
  sc.duration_s = 2.8;
  sc.settle = {{1.3, 1.5, Eigen::Vector3d::UnitZ()}};
  return sc;
}

SweepOptions withDevice(const DeviceModelSpec& device, SweepOptions base) {
  base.servo_period_s = device.servoPeriod_s();
  base.signal = device.signalPath();
  base.passivity_floor_N_per_m = device.rated_stiffness_N_per_m;
  return base;
}

const char* toString(Behaviour b) {
  switch (b) {
    case Behaviour::kSettled: return "settled";
    case Behaviour::kDecaying: return "decaying";
    case Behaviour::kLimitCycle: return "LIMIT CYCLE";
    case Behaviour::kDiverged: return "DIVERGED";
  }
  return "?";
}

SimulationResult runScenario(const Scenario& sc, double k_lin, const DeviceParams& device, const HandParams& hand,
                             const SweepOptions& options) {
  haptics::RendererOptions o;
  o.gains.linear_N_per_m = k_lin;
  o.gains.angular_Nm_per_rad =
      options.lever_m > 0.0 ? k_lin * options.lever_m * options.lever_m
                            : k_lin * sc.tool->mass.I_Cm_T_kgm2.trace() / 3.0 / sc.tool->mass.mass_kg;
  if (options.standoff_fraction >= 0.0) o.standoff_fraction = options.standoff_fraction;
  // No stand-off at all: nor the lift after a stuck contact (the paper's solver, which never
  // moves the proxy against the coupling).
  if (options.standoff_fraction == 0.0) o.stuck_standoff_fraction = 0.0;
  o.detection_mode = options.detection_mode;
  haptics::HapticRenderer r(sc.volume, sc.tool, o, sc.X_WP0, sc.isovalue);
  SimulationConfig cfg;
  cfg.device = device;
  cfg.hand = sc.bounce ? HandParams::released() : hand;
  cfg.duration_s = sc.duration_s;
  cfg.isovalue = sc.isovalue;
  cfg.lift_bound_m = 2.0 * r.largestStandoff_m();
  cfg.check_penetration = options.check_penetration;
  cfg.verify_step_voxels = options.verify_step_voxels;
  cfg.servo_period_s = options.servo_period_s;
  cfg.signal = options.signal;
  cfg.passivity_control = options.passivity_control;
  cfg.passivity_floor_N_per_m = options.passivity_floor_N_per_m;
  return simulate(r, cfg, sc.hand, sc.start);
}

double passivityTolerance(double throughput_J) { return 1e-9 * throughput_J + 1e-12; }

double linearStabilityLimit(double m, double b, double k_h, double b_h, double T) {
  double lo = 1.0, hi = 1e7;
  if (contactSpectralRadius(m, b, k_h, b_h, hi, T) < 1.0) return hi;
  for (int i = 0; i < 100 && hi / lo > 1.0 + 1e-9; ++i) {
    const double mid = std::sqrt(lo * hi);
    (contactSpectralRadius(m, b, k_h, b_h, mid, T) < 1.0 ? lo : hi) = mid;
  }
  return std::sqrt(lo * hi);
}

namespace {

/// One scenario's run into the sweep point's totals and extremes.
void addRunTotals(StiffnessResult& s, const SimulationResult& r) {
  s.finite &= r.finite;
  s.bad_inputs += r.bad_inputs;
  s.solver_violations += r.solver_violations;
  s.solver_injected_J += r.solver_injected_J;
  s.lift_bound_violations += r.lift_bound_violations;
  s.worst_solver_work_J = std::min(s.worst_solver_work_J, r.worst_solver_work_J);
  s.max_penetration_over_eps = std::max(s.max_penetration_over_eps, r.max_penetration_m / r.epsilon_m);
  s.crossings += r.crossings;
  s.crossing_points += r.crossing_points;
  s.max_force_error_rel = std::max(s.max_force_error_rel, r.max_force_error_rel);
  s.controller_dissipated_J += r.controller_dissipated_J;
  s.controller_active_ticks += r.controller_active_ticks;
  s.saturated_ticks += r.saturated_ticks;
  s.controller_end_gain = std::min(s.controller_end_gain, r.controller_final_gain);
  s.max_e_gen_J = std::max(s.max_e_gen_J, r.max_e_gen_J);
  s.peak_force_N = std::max(s.peak_force_N, r.peak_force_N);
}

/// What one hold window of a run says: settled, decaying (the peak-to-peak force at most half
/// what it was kDecayLag_s before, in contact), and the mean normal force [N].
struct HoldVerdict {
  bool settled = false;
  bool decaying = false;
  double mean_force_N = 0.0;
};

/// Hold window `w` of run `r` at stiffness `k_lin` [N/m] with an encoder of resolution `q` [m]
/// (0: none): the contact lost, the force's peak-to-peak and decay, the handle's travel in
/// counts, into the extremes of `s`.
HoldVerdict checkHold(StiffnessResult& s, const SimulationResult& r, const Window& w, double k_lin, double q) {
  const Eigen::Vector3d n = w.normal_W;
  const auto fn = [n](const TickRecord& t) { return t.force.dot(n); };
  const double ptp = peakToPeak(r, w.t0_s, w.t1_s, fn);
  const double ptp_before = peakToPeak(r, w.t0_s - kDecayLag_s, w.t1_s - kDecayLag_s, fn);
  const double avg = mean(r, w.t0_s, w.t1_s, fn);
  const double rel = ptp / std::max(std::abs(avg), 1e-9);
  int lost = 0;
  for (const TickRecord& t : r.ticks)
    if (t.t_s >= w.t0_s && t.t_s <= w.t1_s && t.contacts == 0) ++lost;
  s.contact_lost_ticks += lost;
  s.settled_ptp_rel = std::max(s.settled_ptp_rel, rel);
  s.settled_ptp_N = std::max(s.settled_ptp_N, ptp);
  const double ratio = ptp / std::max(ptp_before, 1e-300);
  s.decay_ratio = std::max(s.decay_ratio, ratio);
  // A quantised encoder cannot hold the sensed position between two counts: a contact whose
  // handle stays within kDitherCounts counts and whose force moves by at most that many
  // counts' worth of spring (K q each) plus kSettledPtp is at rest, dithering at the floor.
  const double travel_counts =
      q > 0.0 ? peakToPeak(r, w.t0_s, w.t1_s, [n](const TickRecord& t) { return t.c_D.dot(n); }) / q : 0.0;
  const bool at_floor = q > 0.0 && travel_counts <= kDitherCounts &&
                        ptp <= kDitherCounts * k_lin * q + kSettledPtp * std::abs(avg);
  s.hold_ptp_counts = std::max(s.hold_ptp_counts, travel_counts);
  HoldVerdict v;
  v.settled = (rel < kSettledPtp || at_floor) && avg > 0.0 && lost == 0;
  v.decaying = ratio <= 0.5 && avg > 0.0 && lost == 0;
  v.mean_force_N = avg;
  return v;
}

}  // namespace

StiffnessResult evaluate(const std::vector<Scenario>& scenarios, double k_lin, const DeviceParams& device,
                         const HandParams& hand, const SweepOptions& options) {
  StiffnessResult s;
  s.k_lin = k_lin;
  s.k_ang = options.lever_m > 0.0 ? k_lin * options.lever_m * options.lever_m : 0.0;
  s.gains = options.lever_m > 0.0 ? "diag" : "scalar";
  s.device = device.name;
  s.mass_kg = device.mass_kg;
  s.damping = device.damping_Ns_per_m;
  s.servo_rate_Hz = 1.0 / options.servo_period_s;
  s.passivity_control = options.passivity_control;
  const double T = options.servo_period_s;
  s.colgate_k_max = colgateMaxStiffness(device.damping_Ns_per_m, T);
  s.colgate_k_max_hand = colgateMaxStiffness(device.damping_Ns_per_m + hand.damping_Ns_per_m, T);
  s.spectral_radius = contactSpectralRadius(device.mass_kg, device.damping_Ns_per_m, hand.stiffness_N_per_m,
                                            hand.damping_Ns_per_m, k_lin, T);
  s.linear_k_limit = linearStabilityLimit(device.mass_kg, device.damping_Ns_per_m, hand.stiffness_N_per_m,
                                          hand.damping_Ns_per_m, T);
  const double k_eff = k_lin * hand.stiffness_N_per_m / (k_lin + hand.stiffness_N_per_m);
  bool passive = true, settled = true, decaying = true, first_hold = true;
  for (const Scenario& sc : scenarios) {
    const SimulationResult r = runScenario(sc, k_lin, device, hand, options);
    addRunTotals(s, r);
    passive &= r.max_e_gen_J <= passivityTolerance(r.energy_in_J + r.energy_out_J);
    if (sc.bounce) s.bounce_ratio = r.energy_out_J / std::max(r.energy_in_J, 1e-300);
    for (const Window& w : sc.settle) {
      const HoldVerdict hold = checkHold(s, r, w, k_lin, options.signal.encoder_resolution_m);
      settled &= hold.settled;
      decaying &= hold.settled || hold.decaying;
      if (first_hold && sc.name.starts_with("plane")) {
        s.steady_force_error_rel = std::abs(hold.mean_force_N - k_eff * kDepth_m) / (k_eff * kDepth_m);
        first_hold = false;
      }
    }
    if (sc.name.starts_with("plane tap")) {
      const double avg = mean(r, sc.settle[0].t0_s, sc.settle[0].t1_s, [](const TickRecord& t) { return t.force.z(); });
      s.tap_overshoot = r.peak_force_N / std::max(avg, 1e-9);
    }
  }
  s.passive = passive;
  s.rendered_stiffness_N_per_m = s.controller_end_gain * k_lin;
  if (!s.finite || s.bad_inputs > 0)
    s.behaviour = Behaviour::kDiverged;
  else if (settled)
    s.behaviour = Behaviour::kSettled;
  else if (decaying)
    s.behaviour = Behaviour::kDecaying;
  else
    s.behaviour = Behaviour::kLimitCycle;
  return s;
}

ControllerPrice controllerPrice(const DeviceModelSpec& device, double k_lin, const HandParams& hand) {
  const Scenario sc = slowPressScenario();
  SweepOptions o = withDevice(device);
  o.check_penetration = false;
  const SimulationResult off = runScenario(sc, k_lin, device.params(kLever_m), hand, o);
  o.passivity_control = true;
  const SimulationResult on = runScenario(sc, k_lin, device.params(kLever_m), hand, o);
  ControllerPrice p;
  p.device = device.name;
  p.k_lin = k_lin;
  p.peak_force_N = off.peak_force_N;
  p.dissipated_J = on.controller_dissipated_J;
  p.work_in_J = off.energy_in_J;
  p.active_ticks = on.controller_active_ticks;
  std::vector<double> err;
  const std::size_t n = std::min(off.ticks.size(), on.ticks.size());
  double sum = 0.0;
  int in_contact = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const double e = (on.ticks[i].force - off.ticks[i].force).norm() / std::max(p.peak_force_N, 1e-9);
    err.push_back(e);
    if (off.ticks[i].contacts > 0 || on.ticks[i].contacts > 0) {
      sum += e;
      ++in_contact;
    }
  }
  if (!err.empty()) {
    std::vector<double> sorted = err;
    std::sort(sorted.begin(), sorted.end());
    p.max_force_error_rel = sorted.back();
    p.p999_force_error_rel = sorted[std::min(sorted.size() - 1, static_cast<std::size_t>(0.999 * (sorted.size() - 1) + 0.5))];
  }
  p.mean_force_error_rel = in_contact > 0 ? sum / in_contact : 0.0;
  const Window& w = sc.settle.front();
  const auto fn = [&w](const TickRecord& t) { return t.force.dot(w.normal_W); };
  const double f_off = mean(off, w.t0_s, w.t1_s, fn), f_on = mean(on, w.t0_s, w.t1_s, fn);
  p.hold_force_error_rel = std::abs(f_on - f_off) / std::max(std::abs(f_off), 1e-9);
  return p;
}

std::string markdownTable(const std::vector<StiffnessResult>& rows) {
  std::ostringstream o;
  o << "| gains | dev | m [kg] | b_d [N s/m] | K [N/m] | K_ang [N m/rad] | 2b_d/T | 2(b_d+b_h)/T | K* (rho=1) | rho | max E_gen [J] "
       "| passive | bounce out/in | hold ptp [N] (rel) | decay | lost | F err | tap peak/F | peak F [N] "
       "| solver viol. | injected [J] | pen/eps | behaviour |\n";
  o << "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n";
  char buf[640];
  for (const StiffnessResult& s : rows) {
    char kang[32];
    if (s.k_ang > 0.0)
      std::snprintf(kang, sizeof kang, "%.3g", s.k_ang);
    else
      std::snprintf(kang, sizeof kang, "K i/m");
    std::snprintf(buf, sizeof buf,
                  "| %s | %s | %.2f | %.2f | %.0f | %s | %.0f | %.0f | %.0f | %.4f | %.3g | %s | %.3f | %.3g (%.2g) | %.2f | %d "
                  "| %.2g | %.2f | %.3g | %d | %.2g | %.2f | %s |\n",
                  s.gains.c_str(), s.device.c_str(), s.mass_kg, s.damping, s.k_lin, kang, s.colgate_k_max,
                  s.colgate_k_max_hand, s.linear_k_limit, s.spectral_radius, s.max_e_gen_J, s.passive ? "yes" : "NO", s.bounce_ratio,
                  s.settled_ptp_N, s.settled_ptp_rel, s.decay_ratio, s.contact_lost_ticks, s.steady_force_error_rel,
                  s.tap_overshoot, s.peak_force_N, s.solver_violations, s.solver_injected_J,
                  s.max_penetration_over_eps, toString(s.behaviour));
    o << buf;
  }
  return o.str();
}

std::string jsonReport(const std::vector<StiffnessResult>& rows, const HandParams& hand) {
  std::ostringstream o;
  o.precision(9);
  o << "{\n  \"servo_period_s\": 0.001,\n  \"substeps\": 10,\n  \"lever_m\": " << kLever_m
    << ",\n  \"hand_depth_m\": " << kDepth_m << ",\n  \"hand\": {\"k_N_per_m\": " << hand.stiffness_N_per_m
    << ", \"b_Ns_per_m\": " << hand.damping_Ns_per_m << ", \"k_rot_Nm_per_rad\": " << hand.rot_stiffness_Nm
    << ", \"b_rot_Nms\": " << hand.rot_damping_Nms << "},\n  \"rows\": [\n";
  for (std::size_t i = 0; i < rows.size(); ++i) {
    const StiffnessResult& s = rows[i];
    o << "    {\"gains\": \"" << s.gains << "\", \"device\": \"" << s.device << "\", \"mass_kg\": " << s.mass_kg
      << ", \"damping_Ns_per_m\": " << s.damping << ", \"k_lin_N_per_m\": " << s.k_lin
      << ", \"k_ang_Nm_per_rad\": " << (s.k_ang > 0.0 ? std::to_string(s.k_ang) : std::string("null"))
      << ", \"colgate_k_max\": " << s.colgate_k_max << ", \"colgate_k_max_with_hand\": " << s.colgate_k_max_hand
      << ", \"spectral_radius\": " << s.spectral_radius << ", \"linear_k_limit\": " << s.linear_k_limit << ", \"max_e_gen_J\": " << s.max_e_gen_J
      << ", \"passive\": " << (s.passive ? "true" : "false") << ", \"bounce_energy_ratio\": " << s.bounce_ratio
      << ", \"hold_ptp_N\": " << s.settled_ptp_N << ", \"hold_ptp_rel\": " << s.settled_ptp_rel
      << ", \"decay_ratio\": " << s.decay_ratio << ", \"contact_lost_ticks\": " << s.contact_lost_ticks
      << ", \"steady_force_error_rel\": " << s.steady_force_error_rel << ", \"tap_overshoot\": " << s.tap_overshoot
      << ", \"peak_force_N\": " << s.peak_force_N << ", \"solver_violations\": " << s.solver_violations
      << ", \"solver_injected_J\": " << s.solver_injected_J << ", \"worst_solver_work_J\": " << s.worst_solver_work_J
      << ", \"lift_bound_violations\": " << s.lift_bound_violations
      << ", \"max_penetration_over_epsilon\": " << s.max_penetration_over_eps
      << ", \"max_force_error_rel\": " << s.max_force_error_rel << ", \"finite\": " << (s.finite ? "true" : "false")
      << ", \"bad_inputs\": " << s.bad_inputs << ", \"behaviour\": \"" << toString(s.behaviour) << "\", \"stable\": "
      << (s.stable() ? "true" : "false") << "}" << (i + 1 < rows.size() ? "," : "") << "\n";
  }
  o << "  ]\n}\n";
  return o.str();
}

}  // namespace vh::stability
