#pragma once
/// @file
/// A simulated haptic device held by a simulated hand, closed around vh::haptics::HapticRenderer
/// the way a real servo loop closes it ("Stiff cases": stiffness against stability).
///
/// Model (SI units: m, s, kg, N, rad; every vector in the volume frame W):
///
///   device   one rigid handle, 6 DOF, decoupled per axis: translational mass m_d [kg] and
///            viscous damping b_d [N*s/m] on each axis; isotropic rotational inertia J_d [kg*m^2]
///            and damping b_r [N*m*s/rad] (isotropic, so no gyroscopic term). Its generalised
///            coordinate is the pose of the tool's centre of mass Cm: position c_D and
///            orientation R_WD. The renderer's X_WD is derived from it:
///            X_WD = (R_WD, c_D - R_WD p_TCm), so the coupling force acts at c_D.
///   hand     a spring-damper between the handle and a hand target (c_H(t), R_H(t)):
///            F_hand = k_h (c_H - c_D) + b_h (v_H - v_D),
///            tau_hand = k_hr rotvec(R_H R_WD^T) + b_hr (w_H - w_D).
///            The hand target is a scripted trajectory; k_h = 0 and b_h = 0 free the handle.
///   servo    the renderer's tick() runs at 1 / T (T = 1 ms): it samples X_WD at t_k = k T and
///            its force and torque are held (zero-order hold) on the handle over [t_k, t_k + T),
///            with no further delay.
///   plant    integrated with `substeps` classical Runge-Kutta (RK4) steps per servo period
///            (10 kHz by default), orientation as a quaternion (q' = 1/2 w q, renormalised).
///            Semi-implicit Euler was rejected: its energy error, -h^2 F^2 / 2m a step, is h / T
///            (10 %) of the hold's own energy generation and masked it as numerical damping.
///
/// Energy accounting (all exact for the integrated path, independent of the integrator's error):
///   W_out   work of the held coupling wrench on the handle: sum of F_k . (c_D(t_k+1) - c_D(t_k))
///           + tau_k . (angle swept), i.e. the energy that left the coupling into the device.
///   D_dev   work absorbed by the device's damper, integral of b |v|^2 + b_r |w|^2 (integrated
///           with the plant's state).
///   V       energy stored in the coupling spring at a sample, after the tick:
///           1/2 k_lin |c_D - c_P|^2 + 1/2 (k_ang / i) theta^T I_W(R_P) theta,
///           theta = rotvec(R_WD R_WP^T), i = trace(I_Cm) / 3 (the README's coupling, eq. 5).
///   E_gen   = V(t) - V(0) + W_out(t) - D_dev(t): energy created by the virtual environment plus
///           the device's damper, as seen by the hand. Passive ("energy out never exceeds energy
///           in") iff E_gen(t) <= 0 at every sample. Colgate and Schenkel's bound for a sampled
///           spring with zero-order hold: passive iff b_d > K T / 2 (+|B|, B = 0 here).
///   solver work per tick: the proxy moves from P_k-1 to P_k while the device is at D_k; the
///           work the coupling does on the proxy along that move is, by the trapezoid rule,
///           S_k = 1/2 (w_P(P_k-1, D_k) + w_P(P_k, D_k)) . dx_P,   w_P = -(wrench on the hand),
///           dx_P = (c_Pk - c_Pk-1, rotvec(R_Pk R_Pk-1^T)). The trapezoid rule is exact for the
///           translational spring: S_k,lin = V_lin(P_k-1) - V_lin(P_k). S_k >= 0 means the proxy
///           moved only where the spring pulled it: the solver put no energy into the coupling.
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "vh/haptics/haptic_renderer.h"

namespace vh::stability {

/// The handle's mechanics (per axis).
struct DeviceParams {
  std::string name = "device";
  double mass_kg = 0.2;              ///< Effective translational mass m_d [kg].
  double damping_Ns_per_m = 1.0;     ///< Viscous damping b_d [N*s/m].
  double inertia_kgm2 = 0.2 * 4e-4;  ///< Effective rotational inertia J_d [kg*m^2].
  double rot_damping_Nms = 4e-4;     ///< Rotational damping b_r [N*m*s/rad].

  /// A device whose rotational axes match its translational ones at the lever arm L [m]:
  /// J_d = m_d L^2, b_r = b_d L^2 (the same natural frequencies and damping ratios).
  static DeviceParams scaled(std::string name, double mass_kg, double damping_Ns_per_m, double lever_m);
};

/// The hand's grip on the handle.
struct HandParams {
  double stiffness_N_per_m = 500.0;   ///< k_h [N/m]; 0 releases the handle.
  double damping_Ns_per_m = 5.0;      ///< b_h [N*s/m].
  double rot_stiffness_Nm = 0.2;      ///< k_hr [N*m/rad].
  double rot_damping_Nms = 2e-3;      ///< b_hr [N*m*s/rad].
  static HandParams scaled(double k_N_per_m, double b_Ns_per_m, double lever_m);
  static HandParams released() { return {0.0, 0.0, 0.0, 0.0}; }
};

/// Where the hand wants the tool's centre of mass to be, and how fast that target moves.
struct HandTarget {
  Eigen::Vector3d c_W_m = Eigen::Vector3d::Zero();
  Eigen::Quaterniond R_W = Eigen::Quaterniond::Identity();
  Eigen::Vector3d v_W_mps = Eigen::Vector3d::Zero();
  Eigen::Vector3d w_W_radps = Eigen::Vector3d::Zero();
};
using HandTrajectory = std::function<HandTarget(double t_s)>;

/// Initial state of the handle (centre of mass).
struct DeviceState {
  Eigen::Vector3d c_W_m = Eigen::Vector3d::Zero();
  Eigen::Vector3d v_W_mps = Eigen::Vector3d::Zero();
  Eigen::Quaterniond R_W = Eigen::Quaterniond::Identity();
  Eigen::Vector3d w_W_radps = Eigen::Vector3d::Zero();
};

/// The device's signal path between the renderer and the handle (DeviceIo in
/// device_catalog.h). Defaults: the ideal device (exact position, the command held from the very
/// tick it was computed, no saturation, torque applied).
struct DeviceSignalPath {
  double encoder_resolution_m = 0.0;  ///< Position quantum of the sensed handle [m]; 0: exact.
  int delay_ticks = 0;                ///< Whole ticks before a command's hold starts.
  double max_force_N = 0.0;           ///< Force saturation [N]; 0: none.
  /// False: the device has no torque actuators (a 3-DOF force device): the coupling's torque is
  /// not applied and the hand alone turns the handle.
  bool torque_actuated = true;
};

struct SimulationConfig {
  DeviceParams device;
  HandParams hand;
  double servo_period_s = 1e-3;  ///< T: 1 kHz servo rate.
  int substeps = 10;             ///< Plant steps per servo period (10 kHz).
  double duration_s = 1.0;
  double isovalue = 0.0;
  bool check_penetration = true;  ///< Measure the proxy's depth inside the isosurface each tick.
  /// > 0: after every tick, haptics::CrossingVerifier samples each shell point's path over the
  /// tick every this many voxels; 0: crossings are not checked.
  double verify_step_voxels = 0.0;
  /// Largest translation the renderer's contact stand-off may add to one proxy move [m]
  /// (2 * standoff_fraction * epsilon, the cap of ConfigurationSolver::standoffTranslation);
  /// 0 when the stand-off is off. The lift pushes the proxy out of the surface, against the
  /// spring, so a tick may lose up to |F| * lift_bound_m of solver work to it.
  double lift_bound_m = 0.0;

  DeviceSignalPath signal{};  ///< The device's signal path (the ideal device by default).
  /// Time-domain passivity controller (haptics::PassivityController) on both coupling ports,
  /// between the renderer and the delay line, told signal.delay_ticks and each port's stiffness.
  bool passivity_control = false;
  /// Its stiffness schedule's floor [N/m]: the gain never goes below this over k_lin (the same
  /// ratio on the torque port); 0: no schedule.
  double passivity_floor_N_per_m = 0.0;
};

/// One servo tick, recorded after the renderer ran (device sample at t_s).
struct TickRecord {
  double t_s = 0.0;
  haptics::Pose X_WD;                                 ///< The device sample given to tick().
  Eigen::Vector3d c_D = Eigen::Vector3d::Zero();      ///< Device Cm at the sample [m].
  Eigen::Vector3d v_D = Eigen::Vector3d::Zero();      ///< Device velocity at the sample [m/s].
  Eigen::Vector3d w_D = Eigen::Vector3d::Zero();      ///< Device angular velocity, W [rad/s].
  Eigen::Vector3d c_P = Eigen::Vector3d::Zero();      ///< Proxy Cm after the tick [m].
  Eigen::Vector3d theta = Eigen::Vector3d::Zero();    ///< rotvec(R_WD R_WP^T) after the tick [rad].
  /// Force the device applies to the hand over [t_s, t_s + T) [N]: the renderer's command after
  /// the passivity controller, the delay line and saturation (= the renderer's with the ideal
  /// device).
  Eigen::Vector3d force = Eigen::Vector3d::Zero();
  Eigen::Vector3d torque = Eigen::Vector3d::Zero();   ///< Torque on the hand about Cm (held) [N*m].
  Eigen::Vector3d force_rendered = Eigen::Vector3d::Zero();  ///< The renderer's force this tick [N].
  int contacts = 0;
  double solver_work_J = 0.0;        ///< S_k (>= 0: the proxy moved with the spring).
  double solver_work_lin_J = 0.0;    ///< Translational part of S_k (exact).
  double solver_work_ang_J = 0.0;    ///< Rotational part of S_k (trapezoid rule).
  double solver_gross_J = 0.0;       ///< Sum of |terms| of S_k, the scale of its rounding error.
  double solver_tolerance_J = 0.0;   ///< solverWorkTolerance() for this tick.
  double stored_J = 0.0;             ///< V after the tick.
  double w_out_J = 0.0;              ///< Cumulative W_out up to t_s.
  double d_dev_J = 0.0;              ///< Cumulative D_dev up to t_s.
  double e_gen_J = 0.0;              ///< E_gen at t_s (<= 0: passive so far).
  double penetration_m = 0.0;        ///< Deepest proxy point inside the isosurface after the tick.
  /// (|F_renderer - F_eq5| + |tau_renderer - tau_eq5| / L) / max(|F| + |tau| / L, 1 mN), L = 20 mm
  /// (the floor: free-space ticks leave ~1e-15 N*m of rounding torque, far below any device).
  double force_error_rel = 0.0;
};

struct SimulationResult {
  std::vector<TickRecord> ticks;
  bool finite = true;             ///< No NaN or infinity anywhere (renderer or plant).
  int bad_inputs = 0;             ///< Ticks the renderer rejected.
  double max_penetration_m = 0.0;
  int crossings = 0;                  ///< Ticks in which a shell point was carried into the isosurface.
  std::int64_t crossing_points = 0;   ///< Those points, summed (SimulationConfig::verify_step_voxels > 0).
  double max_force_error_rel = 0.0;
  double min_solver_margin_J = 0.0;   ///< min over ticks of S_k + tol_k (must stay >= 0).
  double worst_solver_work_J = 0.0;   ///< min over ticks of S_k (most negative).
  double worst_solver_work_rel = 0.0; ///< the same divided by the tick's gross work.
  int solver_violations = 0;          ///< Ticks with S_k < -tol_k.
  double solver_injected_J = 0.0;     ///< Sum of -S_k over the ticks with S_k < -tol_k.
  int lift_bound_violations = 0;      ///< Ticks with S_k < -(|F| lift_bound_m + tol_k).
  double max_e_gen_J = 0.0;           ///< max over ticks of E_gen (> 0: energy was created).
  double energy_in_J = 0.0;           ///< sum of the energy put into the coupling (F.dx < 0 parts).
  double energy_out_J = 0.0;          ///< sum of the energy the coupling gave (F.dx > 0 parts).
  double peak_force_N = 0.0;
  double epsilon_m = 0.0;
  /// Work the passivity controller took out of the hand's port [J]: sum over ticks of (the wrench
  /// the device would have applied without it - the wrench it applied) . the handle's
  /// displacement over the tick (both through the same delay and saturation; both ports).
  double controller_dissipated_J = 0.0;
  long controller_active_ticks = 0;   ///< Ticks on which either port's damper acted.
  double controller_final_gain = 1.0;  ///< The force port's schedule gain at the end.
  double controller_lowest_gain = 1.0; ///< Its lowest gain over the run.
  int saturated_ticks = 0;            ///< Ticks the device clamped the force to max_force_N.
};

/// Tolerance of the solver-work test for one tick [J]. Two rounding floors, both measured:
///  - the proxy pose is stored in doubles: a proxy that the solver holds still is re-derived
///    every tick (eq. 2 at t = 0, quaternion normalisation) and moves by a few ulp of its
///    coordinates; the coupling's work over that motion is |F| * ulp(|c|) + |tau| * ulp(1)
///    (seen: 1e-18 J at 14 N, 25 mm from the origin, while 1 ulp(0.025 m) * 14 N = 5e-17 J).
///    Allowed: 16 machine epsilons of |F| |c|_max + |tau|.
///  - cancellation among the terms of S_k, whose absolute sum is `gross_J`: 1e-9 relative (the
///    agreement the issue demands of the cone projection; the projection itself reaches 1e-12).
double solverWorkTolerance(double gross_J, double force_N, double torque_Nm, double coord_m);

/// Runs the closed loop from the renderer's current proxy, with the handle starting at `start`.
SimulationResult simulate(haptics::HapticRenderer& renderer, const SimulationConfig& config,
                          const HandTrajectory& hand, const DeviceState& start);

/// Peak-to-peak of f(record) over records with t in [t0, t1].
double peakToPeak(const SimulationResult& r, double t0, double t1,
                  const std::function<double(const TickRecord&)>& f);
/// Mean of f(record) over records with t in [t0, t1].
double mean(const SimulationResult& r, double t0, double t1, const std::function<double(const TickRecord&)>& f);

/// Linear analysis of a permanent contact along one axis: the handle (m, b) held by the hand
/// (k_h, b_h) pressed against a wall rendered as a sampled spring K with zero-order hold of
/// period T (the proxy fixed on the wall). Returns the spectral radius of the exact discrete
/// closed loop x_k+1 = (Phi - Gamma K [1 0]) x_k; < 1 is asymptotically stable.
double contactSpectralRadius(double m, double b, double k_h, double b_h, double K, double T);

/// Colgate and Schenkel's passivity bound for a virtual wall K with zero-order hold: b > K T / 2
/// + |B|. Returns the largest passive K for physical damping b (B = 0).
inline double colgateMaxStiffness(double b, double T) { return 2.0 * b / T; }

/// Smooth 0 -> 1 ramp over [t0, t1] (half cosine), and its time derivative.
double ramp(double t, double t0, double t1);
double rampRate(double t, double t0, double t1);

}  // namespace vh::stability
