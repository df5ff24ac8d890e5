#pragma once
/// @file
/// Scripted hand scenarios on synthetic volumes for the stiffness sweep ("Stiff cases"),
/// and the classification of one stiffness as passive / stable.
///
/// Scenes (W: the volume frame; z up; metres):
///   plane   half-space z < 0 (64^3 grid of 1 mm), a 10 x 10 x 4 mm box tool, Cm at its centre.
///   sphere  a ball of radius 20 mm at the origin (64^3 of 1 mm), a 5 mm-radius ball tool.
///   hole    the paper's 256^3 block (0.25 mm voxels) with a blind hole (floor at z = -4 mm) and
///           the snug peg, 80 mm long, 1307 points (long runs only).
/// Scenarios (hand target trajectories; the target ends kDepth_m past the resting contact):
///   press-slide-tilt (plane)  lower onto the plane (0.05-0.25 s), hold (judged over 0.75-0.85 s),
///                             slide 15 mm in x (0.85-1.15 s, peak 79 mm/s), tilt 0.15 rad about
///                             y (1.25-1.45 s: one edge pivots), hold (judged over 1.95-2.05 s).
///   press-slide (sphere)      lower onto the top of the ball, hold (judged 0.75-0.85 s), slide
///                             0.5 rad around it (0.85-1.15 s, 12.5 mm), hold (judged 1.65-1.75 s).
///   tap (plane)               the target falls at 0.3 m/s from 10 mm above the plane to kDepth_m
///                             below contact and stops dead: the handle hits the wall.
///   bounce (plane)            the hand lets go; the handle reaches the plane at 0.1 m/s and
///                             bounces off freely (energy returned / energy absorbed).
///   peg (hole)                the peg lowered into the hole and pressed on its floor (about 50
///                             coplanar contacts), pulled sideways against the wall, pried.
#include <memory>
#include <string>
#include <vector>

#include "vh/simulation/device_catalog.h"
#include "vh/simulation/device_model.h"

namespace vh::stability {

/// Hand target depth past the resting contact [m]: the steady force is k_eff * kDepth_m with
/// k_eff = K k_h / (K + k_h).
inline constexpr double kDepth_m = 0.005;
/// The lever arm that scales rotational quantities: k_ang = k_lin L^2, J_d = m_d L^2, ...
inline constexpr double kLever_m = 0.02;

/// A hold window over which the settled contact is judged.
struct Window {
  double t0_s, t1_s;
  Eigen::Vector3d normal_W;  ///< Contact normal: the force component that is judged.
};

struct Scenario {
  std::string name;
  std::shared_ptr<const haptics::ScalarVolume> volume;
  std::shared_ptr<const haptics::ToolModel> tool;
  double isovalue = 0.0;
  haptics::Pose X_WP0;         ///< Initial proxy pose (free of the surface).
  DeviceState start;           ///< Initial handle state (Cm).
  HandTrajectory hand;         ///< Empty: the hand is released.
  double duration_s = 1.0;
  std::vector<Window> settle;  ///< Windows where the contact must be settled.
  bool bounce = false;         ///< The free-bounce scenario (hand released).
};

/// The scenarios run by default (plane press-slide-tilt, sphere press-slide, tap, bounce).
std::vector<Scenario> defaultScenarios();
/// The peg-in-hole scenario on the paper's 256^3 block (long runs only).
Scenario pegScenario();
/// A V-groove of two 45-degree faces meeting along y at z = 0 (64^3 grid of 1 mm), the 5 mm
/// ball tool pressed into it (two contacts at once: a wedged contact), held
/// (judged 0.75-0.85 s along +z), slid 10 mm along the groove (0.85-1.15 s), held (1.45-1.55 s).
Scenario wedgeScenario();
/// The per-device sweep's scenes: plane press-slide-tilt, sphere press-slide, wedge.
std::vector<Scenario> deviceScenarios();
/// The passivity controller's price: the box lowered slowly onto the plane (kDepth_m past
/// contact over 0.2-1.2 s, 5.8 mm/s at most), held, lifted off (1.6-2.6 s). Judged 1.3-1.5 s.
Scenario slowPressScenario();

/// Verdict on the closed loop with the hand, from the hold windows.
enum class Behaviour {
  kSettled,     ///< Every hold window: force peak-to-peak < kSettledPtp of its mean (or at the
                ///< encoder's dither floor, kDitherCounts), no contact lost.
  kDecaying,    ///< Not yet settled, but the oscillation at least halves over kDecayLag_s and the
                ///< contact holds through the window: asymptotically stable, under-damped.
  kLimitCycle,  ///< Sustained oscillation or chatter (contact lost and regained): unstable.
  kDiverged,    ///< Non-finite values or device samples the renderer rejected.
};
const char* toString(Behaviour b);

/// Largest relative force peak-to-peak in a hold window of a settled contact.
inline constexpr double kSettledPtp = 0.02;
/// With a quantised encoder (SweepOptions::signal.encoder_resolution_m > 0) a hold window is also
/// settled when the handle travels at most this many counts along the normal and the force's
/// peak-to-peak is at most this many times K q (plus kSettledPtp of the mean): the dither
/// between adjacent counts that no controller can remove.
inline constexpr double kDitherCounts = 2.0;
/// The oscillation is compared with itself this long before the hold window [s].
inline constexpr double kDecayLag_s = 0.3;

/// Everything measured for one (stiffness, device, gains) over a set of scenarios.
struct StiffnessResult {
  double k_lin = 0.0, k_ang = 0.0;   ///< k_ang: 0 when matched to each tool (k_lin i / m).
  std::string gains;                 ///< "diag" (k_ang = k_lin L^2) or "scalar" (k_ang = k_lin i / m).
  std::string device;
  double mass_kg = 0.0, damping = 0.0;
  double colgate_k_max = 0.0;        ///< 2 b_d / T.
  double colgate_k_max_hand = 0.0;   ///< 2 (b_d + b_h) / T: the hand's damping counted too.
  double spectral_radius = 0.0;      ///< Linear permanent-contact analysis (< 1: stable).
  double linear_k_limit = 0.0;       ///< The K where that spectral radius reaches 1 [N/m].
  // Energy.
  double max_e_gen_J = 0.0;          ///< Over all scenarios: > tolerance means energy was created.
  bool passive = false;              ///< E_gen <= passivityTolerance() in every scenario.
  double bounce_ratio = 0.0;         ///< Energy out / energy in of the coupling, free bounce.
  // Behaviour with the hand.
  Behaviour behaviour = Behaviour::kSettled;
  double settled_ptp_rel = 0.0;      ///< Largest force peak-to-peak in a hold window / mean force.
  double settled_ptp_N = 0.0;
  double decay_ratio = 0.0;          ///< Largest ptp(window) / ptp(window - kDecayLag_s).
  int contact_lost_ticks = 0;        ///< Ticks without contact inside the hold windows.
  double steady_force_error_rel = 0.0; ///< |F - k_eff depth| / (k_eff depth), first plane hold.
  double tap_overshoot = 0.0;        ///< Peak force / steady force in the tap.
  double peak_force_N = 0.0;
  // Invariants and the solver's energy.
  int solver_violations = 0;         ///< Ticks where the proxy moved against the coupling.
  double solver_injected_J = 0.0;    ///< Energy those ticks put into the coupling spring.
  double worst_solver_work_J = 0.0;  ///< Most negative S_k.
  int lift_bound_violations = 0;     ///< Ticks whose S_k is below -|F| * stand-off lift bound.
  double max_penetration_over_eps = 0.0;
  int crossings = 0;                 ///< Ticks with a crossing, summed over the scenarios.
  std::int64_t crossing_points = 0;  ///< Points those ticks carried into the isosurface.
  double max_force_error_rel = 0.0;
  bool finite = true;
  int bad_inputs = 0;
  // The device path and the passivity controller.
  double servo_rate_Hz = 1000.0;
  bool passivity_control = false;
  double hold_ptp_counts = 0.0;          ///< Largest handle travel along the normal in a hold window,
                                         ///< in encoder counts (0 with an exact encoder).
  double controller_dissipated_J = 0.0;  ///< SimulationResult::controller_dissipated_J, summed.
  long controller_active_ticks = 0;
  int saturated_ticks = 0;
  /// The passivity controller's stiffness schedule: the lowest gain any scene ended with, and the
  /// stiffness the force port then rendered, gain * K [N/m] (K without the controller).
  double controller_end_gain = 1.0;
  double rendered_stiffness_N_per_m = 0.0;

  bool stable() const { return behaviour == Behaviour::kSettled || behaviour == Behaviour::kDecaying; }
};

struct SweepOptions {
  double standoff_fraction = -1.0;  ///< < 0: the renderer's default; 0: no lift at all (nor after a stuck contact).
  double lever_m = kLever_m;        ///< k_ang = k_lin lever^2; <= 0: k_ang = k_lin i / m (scalar k).
  bool check_penetration = true;    ///< Measure the proxy's depth every tick (a third of the cost).
  /// Collision-detection path of the renderer (both must pass the same tests).
  haptics::DetectionMode detection_mode = haptics::DetectionMode::kAccelerated;
  /// > 0: crossings checked after every tick at this step [voxels] (SimulationConfig).
  double verify_step_voxels = 0.0;
  // The device: its servo period and signal path (SimulationConfig's fields).
  double servo_period_s = 1e-3;
  DeviceSignalPath signal{};
  bool passivity_control = false;
  double passivity_floor_N_per_m = 0.0;  ///< SimulationConfig::passivity_floor_N_per_m.
};

/// `base` with the servo period and signal path of a catalogue device (device_catalog.h), and
/// its rated stiffness as the passivity controller's floor.
SweepOptions withDevice(const DeviceModelSpec& device, SweepOptions base = {});

/// Runs one scenario at linear stiffness k_lin. Torsional stiffness: options.lever_m > 0 gives
/// k_ang = k_lin lever^2 (the README's diagonal K); <= 0 matches it to the tool's mass metric,
/// k_ang = k_lin i / m (the paper's scalar k in eq. 5: K M = (k / 2m) M).
SimulationResult runScenario(const Scenario& sc, double k_lin, const DeviceParams& device, const HandParams& hand,
                             const SweepOptions& options = {});

/// Runs every scenario for one (stiffness, device) and classifies it (see Behaviour; passive:
/// E_gen within passivityTolerance() in every scenario).
StiffnessResult evaluate(const std::vector<Scenario>& scenarios, double k_lin, const DeviceParams& device,
                         const HandParams& hand, const SweepOptions& options = {});

/// The stiffness at which contactSpectralRadius() reaches 1 (bisection over [1, 1e7] N/m).
double linearStabilityLimit(double m, double b, double k_h, double b_h, double T);

/// The passivity controller's price on one device: slowPressScenario() at stiffness
/// k_lin run twice through the device's signal path, without and with the controller; the
/// forces the hand got are compared tick by tick.
struct ControllerPrice {
  std::string device;
  double k_lin = 0.0;
  double peak_force_N = 0.0;             ///< Largest |F| without the controller.
  double max_force_error_rel = 0.0;      ///< max_k |F_with - F_without| / peak_force_N.
  double p999_force_error_rel = 0.0;     ///< 99.9th percentile of the same.
  double mean_force_error_rel = 0.0;     ///< Mean of the same over the ticks in contact.
  double hold_force_error_rel = 0.0;     ///< |mean F_with - mean F_without| / mean F_without, hold window.
  double dissipated_J = 0.0;             ///< Work the controller took from the hand's port.
  double work_in_J = 0.0;                ///< Energy the hand put into the coupling without it.
  long active_ticks = 0;
};
ControllerPrice controllerPrice(const DeviceModelSpec& device, double k_lin, const HandParams& hand);

/// Markdown table of a sweep.
std::string markdownTable(const std::vector<StiffnessResult>& rows);
/// JSON report of a sweep (written by hand: the core has no JSON library).
std::string jsonReport(const std::vector<StiffnessResult>& rows, const HandParams& hand);

/// Passivity tolerance on E_gen [J]: created energy below this is rounding (1e-9 of the
/// energy that went through the coupling, plus 1e-12 J).
double passivityTolerance(double throughput_J);

}  // namespace vh::stability
