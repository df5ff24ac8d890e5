#include "vh/simulation/device_model.h"

#include "vh/haptics/crossing_verifier.h"
#include "vh/haptics/penetration.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <optional>

#include <Eigen/Eigenvalues>

#include "vh/haptics/configuration_solver.h"
#include "vh/haptics/passivity_controller.h"
#include "vh/simulation/device_catalog.h"

namespace vh::stability {

using haptics::HapticRenderer;
using haptics::Pose;
using haptics::quaternionFromRotationVector;
using haptics::rotationVector;

DeviceParams DeviceParams::scaled(std::string name, double mass_kg, double damping_Ns_per_m, double lever_m) {
  DeviceParams d;
  d.name = std::move(name);
  d.mass_kg = mass_kg;
  d.damping_Ns_per_m = damping_Ns_per_m;
  d.inertia_kgm2 = mass_kg * lever_m * lever_m;
  d.rot_damping_Nms = damping_Ns_per_m * lever_m * lever_m;
  return d;
}

HandParams HandParams::scaled(double k_N_per_m, double b_Ns_per_m, double lever_m) {
  const double l2 = lever_m * lever_m;
  return {k_N_per_m, b_Ns_per_m, k_N_per_m * l2, b_Ns_per_m * l2};
}

double solverWorkTolerance(double gross_J, double force_N, double torque_Nm, double coord_m) {
  constexpr double kEps = std::numeric_limits<double>::epsilon();
  return 1e-9 * gross_J + 16.0 * kEps * (force_N * coord_m + torque_Nm);
}

double ramp(double t, double t0, double t1) {
  if (t <= t0) return 0.0;
  if (t >= t1) return 1.0;
  return 0.5 - 0.5 * std::cos(std::numbers::pi * (t - t0) / (t1 - t0));
}

double rampRate(double t, double t0, double t1) {
  if (t <= t0 || t >= t1) return 0.0;
  const double w = std::numbers::pi / (t1 - t0);
  return 0.5 * w * std::sin(w * (t - t0));
}

namespace {

struct Coupling {
  double k_lin;
  double k_ang_over_i;
  Eigen::Matrix3d I_T;  // inertia about Cm in T
  Eigen::Vector3d p_TCm;

  Eigen::Vector3d cm(const Pose& X) const { return X * p_TCm; }
  Eigen::Matrix3d I_W(const Pose& X_WP) const {
    const Eigen::Matrix3d R = X_WP.R_AB.toRotationMatrix();
    return R * I_T * R.transpose();
  }
  // Wrench on the hand (eq. 5 as the README states it), recomputed independently of the core.
  void handWrench(const Pose& X_WP, const Pose& X_WD, Eigen::Vector3d& f, Eigen::Vector3d& tau) const {
    f = -k_lin * (cm(X_WD) - cm(X_WP));
    const Eigen::Vector3d th = rotationVector(X_WD.R_AB * X_WP.R_AB.conjugate());
    tau = -k_ang_over_i * (I_W(X_WP) * th);
  }
  double stored(const Pose& X_WP, const Pose& X_WD) const {
    const Eigen::Vector3d d = cm(X_WD) - cm(X_WP);
    const Eigen::Vector3d th = rotationVector(X_WD.R_AB * X_WP.R_AB.conjugate());
    return 0.5 * k_lin * d.squaredNorm() + 0.5 * k_ang_over_i * th.dot(I_W(X_WP) * th);
  }
};

double penetration(const haptics::ScalarVolume& vol, const haptics::ToolModel& tool, const Pose& X_WP, double s) {
  return haptics::maxPenetration_m(vol, tool.point_shell, X_WP, s);
}

// Handle state for the fine integration; phi (angle swept, integral of w) and damper_J (the
// damper's absorbed work) are integrated with it and reset every servo period.
struct PlantState {
  Eigen::Vector3d c, v;
  Eigen::Quaterniond q;
  Eigen::Vector3d w, phi;
  double damper_J;
};

struct PlantRate {
  Eigen::Vector3d dc, dv;
  Eigen::Vector4d dq;
  Eigen::Vector3d dw, dphi;
  double ddamper;
};

PlantRate plantRate(const PlantState& y, double t, const Eigen::Vector3d& F, const Eigen::Vector3d& tau,
                    const DeviceParams& dev, const HandParams& hp, const HandTrajectory& hand) {
  const Eigen::Quaterniond q = y.q.normalized();
  const HandTarget ht = hand ? hand(t) : HandTarget{y.c, q, y.v, y.w};
  const Eigen::Vector3d f_hand = hp.stiffness_N_per_m * (ht.c_W_m - y.c) + hp.damping_Ns_per_m * (ht.v_W_mps - y.v);
  const Eigen::Vector3d t_hand =
      hp.rot_stiffness_Nm * rotationVector(ht.R_W * q.conjugate()) + hp.rot_damping_Nms * (ht.w_W_radps - y.w);
  PlantRate r;
  r.dc = y.v;
  r.dv = (F + f_hand - dev.damping_Ns_per_m * y.v) / dev.mass_kg;
  // q' = 1/2 (0, w) q, w in W.
  r.dq = 0.5 * (Eigen::Quaterniond(0.0, y.w.x(), y.w.y(), y.w.z()) * y.q).coeffs();
  r.dw = (tau + t_hand - dev.rot_damping_Nms * y.w) / dev.inertia_kgm2;
  r.dphi = y.w;
  r.ddamper = dev.damping_Ns_per_m * y.v.squaredNorm() + dev.rot_damping_Nms * y.w.squaredNorm();
  return r;
}

PlantState advance(const PlantState& y, const PlantRate& r, double h) {
  PlantState o = y;
  o.c += h * r.dc;
  o.v += h * r.dv;
  o.q.coeffs() += h * r.dq;
  o.w += h * r.dw;
  o.phi += h * r.dphi;
  o.damper_J += h * r.ddamper;
  return o;
}

// One classical Runge-Kutta step of the handle under the held wrench (F, tau).
PlantState rk4Step(const PlantState& y, double t, double h, const Eigen::Vector3d& F, const Eigen::Vector3d& tau,
                   const DeviceParams& dev, const HandParams& hp, const HandTrajectory& hand) {
  const PlantRate k1 = plantRate(y, t, F, tau, dev, hp, hand);
  const PlantRate k2 = plantRate(advance(y, k1, 0.5 * h), t + 0.5 * h, F, tau, dev, hp, hand);
  const PlantRate k3 = plantRate(advance(y, k2, 0.5 * h), t + 0.5 * h, F, tau, dev, hp, hand);
  const PlantRate k4 = plantRate(advance(y, k3, h), t + h, F, tau, dev, hp, hand);
  PlantRate sum;
  sum.dc = (k1.dc + 2.0 * k2.dc + 2.0 * k3.dc + k4.dc) / 6.0;
  sum.dv = (k1.dv + 2.0 * k2.dv + 2.0 * k3.dv + k4.dv) / 6.0;
  sum.dq = (k1.dq + 2.0 * k2.dq + 2.0 * k3.dq + k4.dq) / 6.0;
  sum.dw = (k1.dw + 2.0 * k2.dw + 2.0 * k3.dw + k4.dw) / 6.0;
  sum.dphi = (k1.dphi + 2.0 * k2.dphi + 2.0 * k3.dphi + k4.dphi) / 6.0;
  sum.ddamper = (k1.ddamper + 2.0 * k2.ddamper + 2.0 * k3.ddamper + k4.ddamper) / 6.0;
  PlantState o = advance(y, sum, h);
  o.q.normalize();
  return o;
}

/// Options of a passivity controller port of stiffness `port_stiffness` (N/m or Nm/rad): the
/// device's delay, and a gain floor from cfg.passivity_floor_N_per_m relative to the linear
/// coupling stiffness `k_lin` [N/m].
haptics::PassivityOptions passivityOptions(const SimulationConfig& cfg, double k_lin, double port_stiffness) {
  haptics::PassivityOptions options;
  options.delay_ticks = cfg.signal.delay_ticks;
  if (cfg.passivity_floor_N_per_m > 0.0 && k_lin > 0.0)
    options.min_gain = std::min(1.0, cfg.passivity_floor_N_per_m / k_lin);
  options.port_stiffness = port_stiffness;
  return options;
}

/// The device's signal path and the optional passivity controller (force and torque ports),
/// with the same path fed the renderer's own commands: what the hand would have got without
/// the controller, for its exact price. Also what the controller's ports were told last tick.
struct CommandPath {
  DeviceIo io;
  haptics::PassivityController pc_force, pc_torque;
  DeviceIo io_uncontrolled;
  Eigen::Vector3d c_sensed_prev;  ///< Sensed handle centre of mass, last tick [m, W].
  Eigen::Quaterniond q_prev;      ///< Handle orientation, last tick (W).

  CommandPath(const SimulationConfig& cfg, const Coupling& cp, double k_ang_Nm_per_rad, const Eigen::Vector3d& c,
              const Eigen::Quaterniond& q)
      : io(cfg.signal),
        pc_force(passivityOptions(cfg, cp.k_lin, cp.k_lin)),
        pc_torque(passivityOptions(cfg, cp.k_lin, k_ang_Nm_per_rad)),
        io_uncontrolled(cfg.signal),
        c_sensed_prev(io.sense(c)),
        q_prev(q) {}
};

/// The wrench applied to the handle over a tick [N, Nm, W], and the one the renderer's own
/// commands would have given (`_free`).
struct AppliedWrench {
  Eigen::Vector3d F, tau, F_free, tau_free;
};

/// The commands: the renderer's wrench, through the passivity controller when it is on (each
/// port told its displacement over the last tick and the energy its spring holds,
/// `stored_J` in all), then the device's delay line and saturation.
AppliedWrench actuate(CommandPath& path, const SimulationConfig& cfg, const Coupling& cp, const Pose& X_WD,
                      const haptics::TickOutput& out, const Eigen::Vector3d& c_sensed, const Eigen::Quaterniond& q,
                      double stored_J, SimulationResult& res) {
  const double T = cfg.servo_period_s;
  Eigen::Vector3d F_cmd = out.force_W_N, tau_cmd = out.torque_W_Nm;
  if (cfg.passivity_control) {
    const Eigen::Vector3d d_lin = cp.cm(X_WD) - cp.cm(out.X_WP);
    const double stored_lin = 0.5 * cp.k_lin * d_lin.squaredNorm();
    const auto sf = path.pc_force.step(F_cmd, c_sensed - path.c_sensed_prev, T, stored_lin);
    const auto st = path.pc_torque.step(tau_cmd, rotationVector(q * path.q_prev.conjugate()), T,
                                        std::max(0.0, stored_J - stored_lin));
    res.controller_active_ticks += (sf.alpha > 0.0 || st.alpha > 0.0) ? 1 : 0;
    F_cmd = sf.effort_W;
    tau_cmd = st.effort_W;
  }
  path.c_sensed_prev = c_sensed;
  path.q_prev = q;
  AppliedWrench a;
  a.F = path.io.actuate(F_cmd);
  a.tau = path.io.actuateTorque(tau_cmd);
  a.F_free = path.io_uncontrolled.actuate(out.force_W_N);
  a.tau_free = path.io_uncontrolled.actuateTorque(out.torque_W_Nm);
  return a;
}

/// The hand's wrench (eq. 5) at the start (P_prev: f0, t0) and the end (P_k: f1, t1) of the
/// proxy's move over a tick [N, Nm, W].
struct MoveWrenches {
  Eigen::Vector3d f0, t0, f1, t1;
};

/// Solver work: the proxy's move from `P_prev` to `X_WP` under the spring to `X_WD` (trapezoid)
/// into `rec` with its tolerance; tick `k`'s share of the run's worst case and violations (a
/// lift bound of `lift_bound_m` [m]) into `res`. `c` is the handle's centre of mass [m, W].
MoveWrenches bookSolverWork(const Coupling& cp, const Pose& P_prev, const Pose& X_WP, const Pose& X_WD,
                            const Eigen::Vector3d& c, int k, double lift_bound_m, TickRecord& rec,
                            SimulationResult& res) {
  MoveWrenches m;
  cp.handWrench(P_prev, X_WD, m.f0, m.t0);
  cp.handWrench(X_WP, X_WD, m.f1, m.t1);
  const Eigen::Vector3d dc = cp.cm(X_WP) - cp.cm(P_prev);
  const Eigen::Vector3d dth = rotationVector(X_WP.R_AB * P_prev.R_AB.conjugate());
  // On the proxy the wrench is the opposite of the hand's.
  rec.solver_work_lin_J = -0.5 * (m.f0 + m.f1).dot(dc);
  rec.solver_work_ang_J = -0.5 * (m.t0 + m.t1).dot(dth);
  rec.solver_work_J = rec.solver_work_lin_J + rec.solver_work_ang_J;
  rec.solver_gross_J = 0.5 * ((m.f0.cwiseAbs() + m.f1.cwiseAbs()).dot(dc.cwiseAbs()) +
                              (m.t0.cwiseAbs() + m.t1.cwiseAbs()).dot(dth.cwiseAbs()));
  const double coord = std::max({c.norm(), rec.c_P.norm(), cp.cm(P_prev).norm()});
  rec.solver_tolerance_J = solverWorkTolerance(rec.solver_gross_J, std::max(m.f0.norm(), m.f1.norm()),
                                               std::max(m.t0.norm(), m.t1.norm()), coord);
  const double tol = rec.solver_tolerance_J;
  if (k == 0) {
    res.min_solver_margin_J = rec.solver_work_J + tol;
    res.worst_solver_work_J = rec.solver_work_J;
  }
  res.min_solver_margin_J = std::min(res.min_solver_margin_J, rec.solver_work_J + tol);
  if (rec.solver_work_J < res.worst_solver_work_J) {
    res.worst_solver_work_J = rec.solver_work_J;
    res.worst_solver_work_rel = rec.solver_work_J / std::max(rec.solver_gross_J, 1e-300);
  }
  if (rec.solver_work_J < -tol) {
    ++res.solver_violations;
    res.solver_injected_J -= rec.solver_work_J;
  }
  if (rec.solver_work_J < -(tol + std::max(m.f0.norm(), m.f1.norm()) * lift_bound_m)) ++res.lift_bound_violations;
  return m;
}

/// The tick's record before the checks: the device and proxy poses and the rendered force.
TickRecord startRecord(double t, const Pose& X_WD, const Eigen::Vector3d& c, const Eigen::Vector3d& v,
                       const Eigen::Vector3d& w, const Coupling& cp, const haptics::TickOutput& out) {
  TickRecord rec;
  rec.t_s = t;
  rec.X_WD = X_WD;
  rec.c_D = c;
  rec.v_D = v;
  rec.w_D = w;
  rec.c_P = cp.cm(out.X_WP);
  rec.theta = rotationVector(X_WD.R_AB * out.X_WP.R_AB.conjugate());
  rec.force_rendered = out.force_W_N;
  rec.contacts = out.stats.contacts;
  return rec;
}

/// The tick's force against eq. 5 recomputed here (`m`), and the energy books: the coupling's
/// stored energy (`v0`: on the `first` tick), the work out `w_out` and the device damper's
/// `d_dev` so far [J], and the energy generated; into `rec` and the maxima of `res`.
void checkForceAndEnergy(const Coupling& cp, const haptics::TickOutput& out, const Pose& X_WD, const MoveWrenches& m,
                         bool first, double w_out, double d_dev, double& v0, TickRecord& rec, SimulationResult& res) {
  // Force consistency with eq. 5 recomputed here.
  rec.force_error_rel = ((out.force_W_N - m.f1).norm() + (out.torque_W_Nm - m.t1).norm() / 0.02) /
                        std::max(m.f1.norm() + m.t1.norm() / 0.02, 1e-3);
  res.max_force_error_rel = std::max(res.max_force_error_rel, rec.force_error_rel);

  rec.stored_J = cp.stored(out.X_WP, X_WD);
  if (first) v0 = rec.stored_J;
  rec.w_out_J = w_out;
  rec.d_dev_J = d_dev;
  rec.e_gen_J = rec.stored_J - v0 + w_out - d_dev;
  res.max_e_gen_J = std::max(res.max_e_gen_J, rec.e_gen_J);
}

/// The proxy's penetration (SimulationConfig::check_penetration) and the crossing check of its
/// move (`verifier` not null), into `rec` and `res`.
void checkPenetrationAndCrossings(const HapticRenderer& renderer, const SimulationConfig& cfg,
                                  const haptics::TickOutput& out, const haptics::CrossingVerifier* verifier,
                                  TickRecord& rec, SimulationResult& res) {
  if (cfg.check_penetration) {
    rec.penetration_m = penetration(renderer.volume(), renderer.tool(), out.X_WP, cfg.isovalue);
    res.max_penetration_m = std::max(res.max_penetration_m, rec.penetration_m);
  }
  if (verifier) {
    const int crossed = verifier->check(renderer.lastMotion(), renderer.lastTimeOfContact(), cfg.isovalue).crossing_points;
    res.crossings += crossed > 0;
    res.crossing_points += crossed;
  }
}

/// The plant over the hold interval from time `t`: the applied wrench `a` held (zero-order hold)
/// over cfg.substeps RK4 steps of `h` [s]; the state (c, v, q, w) moves on, the held wrench's
/// work is added to `w_out` and the damper's to `d_dev` [J], the controller's share and the
/// energy in and out to `res`.
void holdWrench(const SimulationConfig& cfg, const HandTrajectory& hand, const AppliedWrench& a, double t, double h,
                Eigen::Vector3d& c, Eigen::Vector3d& v, Eigen::Quaterniond& q, Eigen::Vector3d& w, double& w_out,
                double& d_dev, SimulationResult& res) {
  // Plant over the hold interval: the applied wrench is held (zero-order hold).
  PlantState y{c, v, q, w, Eigen::Vector3d::Zero(), 0.0};
  const Eigen::Vector3d c_start = c;
  for (int s = 0; s < cfg.substeps; ++s) y = rk4Step(y, t + s * h, h, a.F, a.tau, cfg.device, cfg.hand, hand);
  // Exact work of the held wrench along the integrated path; the damper's work integrated
  // with the state (RK4): the energy books close to O(h^4), see
  // StabilityHarness.FreeBounceMatchesTheZeroOrderHoldPrediction.
  const double tick_work = a.F.dot(y.c - c_start) + a.tau.dot(y.phi);
  // The controller's share: the damping it added, held over this tick, against the motion.
  res.controller_dissipated_J += (a.F_free - a.F).dot(y.c - c_start) + (a.tau_free - a.tau).dot(y.phi);
  d_dev += y.damper_J;
  c = y.c;
  v = y.v;
  q = y.q.normalized();
  w = y.w;
  w_out += tick_work;
  (tick_work > 0.0 ? res.energy_out_J : res.energy_in_J) += std::abs(tick_work);
}

}  // namespace

SimulationResult simulate(HapticRenderer& renderer, const SimulationConfig& cfg, const HandTrajectory& hand,
                          const DeviceState& start) {
  SimulationResult res;
  res.epsilon_m = renderer.epsilon_m();
  const haptics::MassProperties& mass = renderer.tool().mass;
  const haptics::CouplingGains& gains = renderer.coupling().gains();
  const Coupling cp{gains.linear_N_per_m, gains.angular_Nm_per_rad / (mass.I_Cm_T_kgm2.trace() / 3.0),
                    mass.I_Cm_T_kgm2, mass.p_TCm_m};
  const double T = cfg.servo_period_s;
  const double h = T / cfg.substeps;
  const int n_ticks = static_cast<int>(std::lround(cfg.duration_s / T));
  res.ticks.reserve(static_cast<std::size_t>(n_ticks));

  std::optional<haptics::CrossingVerifier> verifier;
  if (cfg.verify_step_voxels > 0.0)
    verifier.emplace(renderer.volume(), renderer.tool().point_shell, cfg.verify_step_voxels);

  Eigen::Vector3d c = start.c_W_m, v = start.v_W_mps, w = start.w_W_radps;
  Eigen::Quaterniond q = start.R_W.normalized();
  double w_out = 0.0, d_dev = 0.0, v0 = 0.0;
  CommandPath path(cfg, cp, gains.angular_Nm_per_rad, c, q);

  for (int k = 0; k < n_ticks; ++k) {
    const double t = k * T;
    const Eigen::Vector3d c_sensed = path.io.sense(c);
    const Pose X_WD{q, c_sensed - q * mass.p_TCm_m};
    const Pose P_prev = renderer.proxyPose();
    const haptics::TickOutput out = renderer.tick(X_WD, cfg.isovalue);
    TickRecord rec = startRecord(t, X_WD, c, v, w, cp, out);
    if (out.stats.bad_input) ++res.bad_inputs;
    if (!out.force_W_N.allFinite() || !out.torque_W_Nm.allFinite() || !out.X_WP.allFinite()) {
      res.finite = false;
      res.ticks.push_back(rec);
      break;
    }
    const MoveWrenches m = bookSolverWork(cp, P_prev, out.X_WP, X_WD, c, k, cfg.lift_bound_m, rec, res);

    checkForceAndEnergy(cp, out, X_WD, m, k == 0, w_out, d_dev, v0, rec, res);
    checkPenetrationAndCrossings(renderer, cfg, out, verifier ? &*verifier : nullptr, rec, res);

    const AppliedWrench a = actuate(path, cfg, cp, X_WD, out, c_sensed, q, rec.stored_J, res);
    rec.force = a.F;
    rec.torque = a.tau;
    res.peak_force_N = std::max(res.peak_force_N, a.F.norm());

    holdWrench(cfg, hand, a, t, h, c, v, q, w, w_out, d_dev, res);
    if (!c.allFinite() || !v.allFinite() || !q.coeffs().allFinite()) {
      res.finite = false;
      res.ticks.push_back(rec);
      break;
    }
    res.ticks.push_back(rec);
  }
  res.saturated_ticks = path.io.saturatedTicks();
  res.controller_final_gain = path.pc_force.gain();
  res.controller_lowest_gain = path.pc_force.lowestGain();
  return res;
}

double peakToPeak(const SimulationResult& r, double t0, double t1, const std::function<double(const TickRecord&)>& f) {
  double lo = INFINITY, hi = -INFINITY;
  for (const TickRecord& rec : r.ticks)
    if (rec.t_s >= t0 && rec.t_s <= t1) {
      lo = std::min(lo, f(rec));
      hi = std::max(hi, f(rec));
    }
  return hi >= lo ? hi - lo : 0.0;
}

double mean(const SimulationResult& r, double t0, double t1, const std::function<double(const TickRecord&)>& f) {
  double sum = 0.0;
  int n = 0;
  for (const TickRecord& rec : r.ticks)
    if (rec.t_s >= t0 && rec.t_s <= t1) {
      sum += f(rec);
      ++n;
    }
  return n > 0 ? sum / n : 0.0;
}

namespace {
// exp(A) by scaling and squaring with a degree-18 Taylor series (small dense matrices only).
Eigen::Matrix3d expm(const Eigen::Matrix3d& A) {
  const double norm = A.cwiseAbs().rowwise().sum().maxCoeff();
  int squarings = 0;
  double scale = 1.0;
  while (norm * scale > 0.25) {
    scale *= 0.5;
    ++squarings;
  }
  const Eigen::Matrix3d As = A * scale;
  Eigen::Matrix3d term = Eigen::Matrix3d::Identity(), sum = Eigen::Matrix3d::Identity();
  for (int n = 1; n <= 18; ++n) {
    term = term * As / n;
    sum += term;
  }
  for (int i = 0; i < squarings; ++i) sum = sum * sum;
  return sum;
}
}  // namespace

double contactSpectralRadius(double m, double b, double k_h, double b_h, double K, double T) {
  // State (x, v) along the wall normal, x = penetration; input u = held coupling force.
  // Augmented exponential: exp([[A, B], [0, 0]] T) = [[Phi, Gamma], [0, 1]].
  Eigen::Matrix3d Aug = Eigen::Matrix3d::Zero();
  Aug(0, 1) = 1.0;
  Aug(1, 0) = -k_h / m;
  Aug(1, 1) = -(b + b_h) / m;
  Aug(1, 2) = 1.0 / m;
  const Eigen::Matrix3d E = expm(Aug * T);
  const Eigen::Matrix2d Phi = E.topLeftCorner<2, 2>();
  const Eigen::Vector2d Gamma = E.topRightCorner<2, 1>();
  Eigen::Matrix2d Acl = Phi;
  Acl.col(0) -= Gamma * K;  // u_k = -K x_k
  const Eigen::Vector2cd ev = Acl.eigenvalues();
  return std::max(std::abs(ev(0)), std::abs(ev(1)));
}

}  // namespace vh::stability
