// `volume-haptics bench stability`: the coupling-stiffness sweep with the simulated device
// (vh::simulation, the same scenarios and verdicts as tests/haptics/stability) and a table of
// extreme cases with their outcomes, each run in both detection modes.
#include <algorithm>
#include <cmath>
#include <functional>
#include <iostream>
#include <sstream>

#include <Eigen/Geometry>

#include "vh/bench/report.h"
#include "vh/datasets/synthetic.h"
#include "vh/haptics/crossing_verifier.h"
#include "vh/haptics/haptic_renderer.h"
#include "vh/haptics/penetration.h"
#include "vh/simulation/stability_scenarios.h"

namespace vh::bench {

namespace fs = std::filesystem;

namespace {

using haptics::Pose;

/// One extreme case: a volume, a tool, a device path and an isovalue per tick, and a verdict.
struct ExtremeCase {
  std::string name;
  std::string setup;      ///< What is done.
  std::string criterion;  ///< What "pass" means.
  std::shared_ptr<const haptics::ScalarVolume> volume;
  std::shared_ptr<const haptics::ToolModel> tool;
  int ticks = 1000;
  std::function<Pose(int)> device;        ///< X_WD at tick i.
  std::function<double(int)> isovalue;    ///< s at tick i.
  /// True when the proxy pose is on the wrong side (a crossing), if the case can tell.
  std::function<bool(const Pose&)> crossed;
  /// Ticks whose penetration is judged (empty: all). Points swallowed by an isovalue change are
  /// inside by design until the tool is moved out (haptics/README.md, "Isovalue changes").
  std::function<bool(int)> penetration_judged;
};

/// Crossing check after every tick of the extreme cases (haptics::CrossingVerifier, outside the
/// timed section): path sampling step [voxels].
constexpr double kVerifyStepVoxels = 0.01;

struct CaseResult {
  int ticks = 0, max_contacts = 0, nan_ticks = 0, crossed_ticks = 0, contact_ticks = 0;
  /// Ticks in which the proxy carried a shell point from outside into the isosurface, and those points.
  int crossings = 0, crossing_points = 0;
  std::int64_t bad_inputs = 0;
  double max_penetration_over_eps = 0, max_force_N = 0, final_force_N = 0, mean_us = 0, max_us = 0;
  std::vector<double> force_N;
  std::vector<int> contacts;
};

CaseResult runCase(const ExtremeCase& c, haptics::DetectionMode mode) {
  haptics::RendererOptions options;
  options.detection_mode = mode;
  haptics::HapticRenderer renderer(c.volume, c.tool, options, c.device(0), c.isovalue(0));
  const haptics::CrossingVerifier verifier(*c.volume, c.tool->point_shell, kVerifyStepVoxels);
  CaseResult r;
  r.ticks = c.ticks;
  std::vector<double> times;
  for (int i = 0; i < c.ticks; ++i) {
    const double s = c.isovalue(i);
    const haptics::TickOutput out = renderer.tick(c.device(i), s);
    times.push_back(out.stats.exec_time_us);
    const bool finite = out.force_W_N.allFinite() && out.torque_W_Nm.allFinite() && out.X_WP.allFinite();
    r.force_N.push_back(finite ? out.force_W_N.norm() : -1.0);
    r.contacts.push_back(out.stats.contacts);
    if (!finite) {
      ++r.nan_ticks;
      continue;
    }
    // The tick's motion against this tick's isovalue: points it swallowed start inside and are
    // not counted; a point carried from outside in is.
    const haptics::CrossingVerifier::Result check =
        verifier.check(renderer.lastMotion(), renderer.lastTimeOfContact(), s);
    if (check.crossing_points > 0) {
      ++r.crossings;
      r.crossing_points += check.crossing_points;
    }
    r.max_contacts = std::max(r.max_contacts, out.stats.contacts);
    if (out.stats.contacts > 0) ++r.contact_ticks;
    r.max_force_N = std::max(r.max_force_N, out.force_W_N.norm());
    r.final_force_N = out.force_W_N.norm();
    const double pen = haptics::maxPenetration_m(*c.volume, c.tool->point_shell, out.X_WP, s);
    if (!c.penetration_judged || c.penetration_judged(i))
      r.max_penetration_over_eps = std::max(r.max_penetration_over_eps, pen / renderer.epsilon_m());
    if (c.crossed && c.crossed(out.X_WP)) ++r.crossed_ticks;
  }
  r.bad_inputs = renderer.badInputCount();
  const Stats t = summarize(times);
  r.mean_us = t.mean;
  r.max_us = t.max;
  return r;
}

Pose at(const Eigen::Vector3d& p, const Eigen::Quaterniond& R = Eigen::Quaterniond::Identity()) { return {R, p}; }
double lerp(double a, double b, double u) { return a + (b - a) * std::clamp(u, 0.0, 1.0); }

std::shared_ptr<const haptics::ToolModel> makeTool(const haptics::TriangleMesh& mesh, double spacing_m) {
  haptics::PointShellOptions po;
  po.spacing_m = spacing_m;
  return std::make_shared<const haptics::ToolModel>(haptics::makeToolModel(mesh, po));
}

/// Deterministic noise in [-1, 1] from a position (a hash of the voxel centre), summed four
/// times for a bell-shaped distribution (standard deviation ~0.58).
double noise(const Eigen::Vector3d& p) {
  double sum = 0.0;
  for (unsigned k = 0; k < 4; ++k) {
    std::uint64_t h = 1469598103934665603ull ^ k;
    for (int a = 0; a < 3; ++a) {
      h ^= static_cast<std::uint64_t>(std::llround(p[a] * 1e6) + 1000000007ll * a);
      h *= 1099511628211ull;
      h ^= h >> 29;
    }
    sum += static_cast<double>(h % 2000001) / 1000000.0 - 1.0;
  }
  return sum / 2.0;
}

/// True for a pose below the height z_m [m] of W: the proxy crossed a plate there.
std::function<bool(const Pose&)> belowHeight(double z_m) {
  return [z_m](const Pose& X) { return X.p_AB_m.z() < z_m; };
}

/// Many coplanar contacts: a flat box pressed onto a plane, slid and tilted.
ExtremeCase manyContactsCase(std::shared_ptr<const haptics::ScalarVolume> plane, int scale) {
  ExtremeCase c;
  c.name = "40+ simultaneous contacts";
  c.setup = "12 x 12 x 4 mm box (0.7 mm point spacing) pressed 2 mm into a plane, slid 10 mm, tilted 0.1 rad";
  c.criterion = "more than 40 contacts; penetration <= epsilon; finite";
  c.volume = std::move(plane);
  c.tool = makeTool(datasets::makeBoxMesh({0.006, 0.006, 0.002}), 7e-4);
  c.ticks = 500 * scale;
  const int n = c.ticks;
  c.device = [n](int i) {
    const double u = static_cast<double>(i) / n;
    const double z = u < 0.3 ? lerp(0.005, 0.0, u / 0.3) : 0.0;  // box bottom at z - 2 mm
    const double x = u < 0.4 ? 0.0 : lerp(0.0, 0.010, (u - 0.4) / 0.3);
    const double tilt = u < 0.75 ? 0.0 : lerp(0.0, 0.1, (u - 0.75) / 0.2);
    return at({x, 0.0, z}, Eigen::Quaterniond(Eigen::AngleAxisd(tilt, Eigen::Vector3d::UnitY())));
  };
  c.isovalue = [](int) { return 0.0; };
  return c;
}

/// One-voxel plate (isovalue plate_s, at height plate_z [m]), fast.
ExtremeCase fastPlateCase(std::shared_ptr<const haptics::ScalarVolume> plate, double plate_s, double plate_z,
                          std::shared_ptr<const haptics::ToolModel> ball5, int scale) {
  ExtremeCase c;
  c.name = "one-voxel plate at 1 m/s and 20 rad/s";
  c.setup = "5 mm ball driven down through a 1 mm plate at 1 m/s (1 mm per tick) spinning at 20 rad/s, then "
            "swept sideways at 1 m/s 40 mm below it";
  c.criterion = "the proxy never crosses the plate; penetration <= epsilon; finite";
  c.volume = std::move(plate);
  c.tool = std::move(ball5);
  c.ticks = 200 * scale;
  c.device = [plate_z](int i) {
    const double z = std::max(plate_z + 0.020 - 0.001 * i, plate_z - 0.040);
    const double x = i > 60 ? 0.001 * ((i - 60) % 40 < 20 ? (i - 60) % 40 : 40 - (i - 60) % 40) - 0.010 : 0.0;
    return at({x, 0.0, z}, Eigen::Quaterniond(Eigen::AngleAxisd(0.02 * i, Eigen::Vector3d::UnitX())));
  };
  c.isovalue = [plate_s](int) { return plate_s; };
  c.crossed = belowHeight(plate_z);
  return c;
}

/// Teleport across the plate of fastPlateCase().
ExtremeCase teleportCase(std::shared_ptr<const haptics::ScalarVolume> plate, double plate_s, double plate_z,
                         std::shared_ptr<const haptics::ToolModel> ball5, int scale) {
  ExtremeCase c;
  c.name = "device teleport";
  c.setup = "device jumps in one tick from 10 mm above the plate to 40 mm below it with a half turn; later a 20 m "
            "jump (a unit error) and back";
  c.criterion = "no crossing; the 20 m sample is rejected (zero force, counted); finite";
  c.volume = std::move(plate);
  c.tool = std::move(ball5);
  c.ticks = 100 * scale;
  const int n = c.ticks;
  c.device = [plate_z, n](int i) {
    if (i < n / 4) return at({0.0, 0.0, plate_z + 0.010});
    if (i == n / 2) return at({20.0, 0.0, 0.0});
    return at({0.0, 0.0, plate_z - 0.040}, Eigen::Quaterniond(Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitX())));
  };
  c.isovalue = [plate_s](int) { return plate_s; };
  c.crossed = belowHeight(plate_z);
  return c;
}

/// Isovalue swept through the tool (a 20 mm sphere, F = r - |p| [mm]).
ExtremeCase isovalueSweepCase(std::shared_ptr<const haptics::ScalarVolume> sphere,
                              std::shared_ptr<const haptics::ToolModel> ball5, int scale) {
  ExtremeCase c;
  c.name = "isovalue swept through the tool";
  c.setup = "5 mm ball pressed 1 mm onto a 20 mm sphere; the isovalue goes 0 -> -12 mm (the surface grows through "
            "the whole tool) -> +4 mm -> 0 while the device holds still, then lifts and presses again";
  c.criterion = "force during the sweep never above the force before it (+1 %); contact again after re-pressing; "
                "penetration <= epsilon before the sweep and after the lift (the swallowed tool is inside by "
                "design in between); finite";
  c.volume = std::move(sphere);
  c.tool = std::move(ball5);
  c.ticks = 400 * scale;
  const int n = c.ticks;
  c.device = [n](int i) {  // down, hold through the sweep, lift and press again
    const double u = static_cast<double>(i) / n;
    if (u < 0.8) return at({0.0, 0.0, lerp(0.030, 0.024, u / 0.2)});
    if (u < 0.9) return at({0.0, 0.0, lerp(0.024, 0.032, (u - 0.8) / 0.05)});
    return at({0.0, 0.0, lerp(0.032, 0.024, (u - 0.9) / 0.05)});
  };
  c.isovalue = [n](int i) {
    const double u = static_cast<double>(i) / n;
    if (u < 0.3) return 0.0;
    if (u < 0.5) return lerp(0.0, -12.0, (u - 0.3) / 0.2);
    if (u < 0.7) return lerp(-12.0, 4.0, (u - 0.5) / 0.2);
    return lerp(4.0, 0.0, (u - 0.7) / 0.1);
  };
  c.penetration_judged = [n](int i) { return i < static_cast<int>(0.3 * n) || i >= static_cast<int>(0.85 * n); };
  return c;
}

/// Anisotropic voxels.
ExtremeCase anisotropicCase(std::shared_ptr<const haptics::ToolModel> ball5, int scale) {
  datasets::GridSpec ga;
  ga.dims = {192, 192, 28};
  ga.spacing_m = {0.25e-3, 0.25e-3, 2e-3};
  ExtremeCase c;
  c.name = "anisotropic voxels";
  c.setup = "sphere r 20 mm sampled on 0.25 x 0.25 x 2 mm voxels; 5 mm ball pressed 1.5 mm and slid 0.4 rad "
            "around it";
  c.criterion = "penetration <= epsilon (f = 0.125 mm); finite";
  c.volume = std::make_shared<const haptics::ScalarVolume>(
      datasets::makeSphereVolume(ga, Eigen::Vector3d::Zero(), 0.020));
  c.tool = std::move(ball5);
  c.ticks = 500 * scale;
  const int n = c.ticks;
  c.device = [n](int i) {
    const double u = static_cast<double>(i) / n;
    const double r = u < 0.3 ? lerp(0.030, 0.0235, u / 0.3) : 0.0235;
    const double a = u < 0.3 ? 0.0 : lerp(0.0, 0.4, (u - 0.3) / 0.6);
    return at({r * std::sin(a), 0.0, r * std::cos(a)});
  };
  c.isovalue = [](int) { return 0.0; };
  return c;
}

/// Noisy CT, on the grid `gn`.
ExtremeCase noisyCtCase(const datasets::GridSpec& gn, std::shared_ptr<const haptics::ToolModel> ball5, int scale) {
  ExtremeCase c;
  c.name = "noisy CT";
  c.setup = "sphere r 20 mm in int16 with voxel noise of 0.3 mm standard deviation (in distance units); 5 mm ball "
            "pressed, held, slid";
  c.criterion = "penetration <= epsilon; finite (force ripple reported)";
  c.volume = std::make_shared<const haptics::ScalarVolume>(datasets::makeVolumeFromSignedDistance(
      gn, [](const Eigen::Vector3d& p) { return 0.020 - p.norm() + 0.3e-3 / 0.58 * noise(p); },
      haptics::VoxelType::kInt16));
  c.tool = std::move(ball5);
  c.ticks = 600 * scale;
  const int n = c.ticks;
  c.device = [n](int i) {
    const double u = static_cast<double>(i) / n;
    const double r = u < 0.2 ? lerp(0.030, 0.0235, u / 0.2) : 0.0235;
    const double a = u < 0.5 ? 0.0 : lerp(0.0, 0.4, (u - 0.5) / 0.4);
    return at({r * std::sin(a), 0.0, r * std::cos(a)});
  };
  c.isovalue = [](int) { return 0.0; };
  return c;
}

/// Tool larger than the volume.
ExtremeCase largeToolCase(int scale) {
  datasets::GridSpec gs;
  gs.dims = {16, 16, 16};
  ExtremeCase c;
  c.name = "tool larger than the volume";
  c.setup = "40 x 40 x 10 mm box (1 mm spacing) pressed onto a 6 mm sphere in a 16 mm grid, slid 10 mm";
  c.criterion = "contact made; penetration <= epsilon; finite";
  c.volume = std::make_shared<const haptics::ScalarVolume>(
      datasets::makeSphereVolume(gs, Eigen::Vector3d::Zero(), 0.006));
  c.tool = makeTool(datasets::makeBoxMesh({0.020, 0.020, 0.005}), 1e-3);
  c.ticks = 400 * scale;
  const int n = c.ticks;
  c.device = [n](int i) {
    const double u = static_cast<double>(i) / n;
    return at({u < 0.5 ? 0.0 : lerp(0.0, 0.010, (u - 0.5) / 0.4), 0.0, lerp(0.020, 0.009, u / 0.4)});
  };
  c.isovalue = [](int) { return 0.0; };
  return c;
}

/// Tool leaving the volume.
ExtremeCase leavingCase(std::shared_ptr<const haptics::ScalarVolume> plane,
                        std::shared_ptr<const haptics::ToolModel> ball5, int scale) {
  ExtremeCase c;
  c.name = "tool leaving the volume";
  c.setup = "5 mm ball pressed 2 mm into the plane and slid 60 mm in x, off the grid's edge at x = 31.5 mm";
  c.criterion = "contact while over the grid; no contact and zero force once outside; finite";
  c.volume = std::move(plane);
  c.tool = std::move(ball5);
  c.ticks = 600 * scale;
  const int n = c.ticks;
  c.device = [n](int i) {
    const double u = static_cast<double>(i) / n;
    return at({u < 0.2 ? 0.0 : lerp(0.0, 0.060, (u - 0.2) / 0.6), 0.0, lerp(0.010, 0.003, u / 0.15)});
  };
  c.isovalue = [](int) { return 0.0; };
  return c;
}

/// The extreme cases, in the order of the report (the full run: three times the ticks).
std::vector<ExtremeCase> extremeCases(bool short_run) {
  std::vector<ExtremeCase> cases;
  const int scale = short_run ? 1 : 3;
  datasets::GridSpec g64;  // 64^3 of 1 mm about the origin
  auto plane = std::make_shared<const haptics::ScalarVolume>(
      datasets::makePlaneVolume(g64, Eigen::Vector3d::UnitZ(), 0.0));  // inside z < 0
  auto ball5 = makeTool(datasets::makeBuiltinTool("sphere"), 1e-3);    // r 5 mm about the origin of T
  cases.push_back(manyContactsCase(plane, scale));
  auto plate = std::make_shared<const haptics::ScalarVolume>(datasets::makeThinPlateVolume(g64));
  const double plate_s = datasets::builtinIsovalue("thin-plate");
  const double plate_z = plate->geometry().origin_W_m.z() + plate->geometry().spacing_m.z() * (g64.dims[2] / 2);
  cases.push_back(fastPlateCase(plate, plate_s, plate_z, ball5, scale));
  cases.push_back(teleportCase(plate, plate_s, plate_z, ball5, scale));
  datasets::GridSpec g64f = g64;
  auto sphere = std::make_shared<const haptics::ScalarVolume>(
      datasets::makeSphereVolume(g64f, Eigen::Vector3d::Zero(), 0.020));  // F = r - |p| [mm]
  cases.push_back(isovalueSweepCase(sphere, ball5, scale));
  cases.push_back(anisotropicCase(ball5, scale));
  cases.push_back(noisyCtCase(g64, ball5, scale));
  cases.push_back(largeToolCase(scale));
  cases.push_back(leavingCase(plane, ball5, scale));
  return cases;
}

/// Judges a case's result by its criterion; returns "pass" or "FAIL: why".
std::string judge(const ExtremeCase& c, const CaseResult& r) {
  std::vector<std::string> why;
  if (r.nan_ticks > 0) why.push_back(format("%d non-finite ticks", r.nan_ticks));
  if (r.max_penetration_over_eps > 1.0) why.push_back(format("penetration %.2f epsilon", r.max_penetration_over_eps));
  if (r.crossed_ticks > 0) why.push_back(format("crossed on %d ticks", r.crossed_ticks));
  if (r.crossings > 0)
    why.push_back(format("crossings (CrossingVerifier) on %d ticks, %d points", r.crossings, r.crossing_points));
  if (c.name == "40+ simultaneous contacts" && r.max_contacts <= 40)
    why.push_back(format("only %d contacts", r.max_contacts));
  if (c.name == "device teleport" && r.bad_inputs < 1) why.push_back("the 20 m sample was not rejected");
  if (c.name == "isovalue swept through the tool") {
    const int n = r.ticks;
    double before = 0.0, during = 0.0;
    for (int i = 0; i < n; ++i) {
      if (i < static_cast<int>(0.3 * n)) before = r.force_N[static_cast<std::size_t>(i)];
      else if (i < static_cast<int>(0.8 * n)) during = std::max(during, r.force_N[static_cast<std::size_t>(i)]);
    }
    if (during > 1.01 * before + 1e-9) why.push_back(format("force %.3f N after the sweep began > %.3f N before", during, before));
    if (r.contacts.back() == 0) why.push_back("no contact at the end");
  }
  if (c.name == "tool larger than the volume" && r.contact_ticks == 0) why.push_back("no contact");
  if (c.name == "tool leaving the volume") {
    if (r.contact_ticks == 0) why.push_back("no contact");
    if (r.contacts.back() != 0 || r.final_force_N > 1e-9) why.push_back("still in contact outside the grid");
  }
  if (why.empty()) return "pass";
  std::string s = "FAIL:";
  for (const auto& w : why) s += " " + w + ";";
  return s;
}

/// The coupling-stiffness sweep: every stiffness ks [N/m] with every device and coupling (lever
/// [m]; 0: scalar k) in `scenarios`, each tick's motion checked for crossings.
std::vector<vh::stability::StiffnessResult> runStiffnessSweep(const std::vector<vh::stability::Scenario>& scenarios,
                                                              const std::vector<double>& ks,
                                                              const std::vector<vh::stability::DeviceParams>& devices,
                                                              const std::vector<double>& levers,
                                                              const vh::stability::HandParams& hand) {
  using namespace vh::stability;
  std::cout << "bench stability: stiffness sweep, " << ks.size() << " stiffnesses x " << devices.size()
            << " devices x " << levers.size() << " couplings x " << scenarios.size() << " scenarios\n";
  std::vector<StiffnessResult> rows;
  for (double lever : levers)
    for (const DeviceParams& d : devices)
      for (double k : ks) {
        SweepOptions sweep_options{-1.0, lever, true};
        sweep_options.verify_step_voxels = kVerifyStepVoxels;
        rows.push_back(evaluate(scenarios, k, d, hand, sweep_options));
      }
  return rows;
}

/// The Markdown's heading, how the sweep was made, and its table; the sweep into `report`
/// ("stiffness_sweep").
void writeStiffnessSweep(std::ostringstream& md, nlohmann::ordered_json& report,
                         const std::vector<vh::stability::StiffnessResult>& rows, bool short_run) {
  using namespace vh::stability;
  nlohmann::ordered_json sweep = nlohmann::ordered_json::array();
  md << "## Stiff and extreme cases (`volume-haptics bench stability" << (short_run ? " --short" : "") << "`)\n\n";
  md << "Run " << report["date_utc"].get<std::string>() << " on " << report["cpu_model"].get<std::string>()
     << ". The renderer closed around the simulated device (vh::simulation: mass-damper handle, 1 kHz zero-order "
        "hold, spring-damper hand k_h = 500 N/m, b_h = 5 N*s/m) in the scenarios of tests/haptics/stability (plane "
        "press-slide-tilt, sphere press-slide, tap, free bounce). Energy balance: the largest energy created by the "
        "loop, max E_gen (<= 0: passive); bounce: energy returned / absorbed by the coupling in the free bounce; "
        "oscillation: force peak-to-peak in the hold windows after settling. Colgate's passivity bound is "
        "K < 2 b / T. Crossings: ticks in which haptics::CrossingVerifier, sampling each shell point's path over "
        "the tick every "
     << kVerifyStepVoxels
     << " voxel, found a point carried from outside into the isosurface (summed over the scenarios; the "
        "verdict adds CROSSED).\n\n";
  md << "| K [N/m] | coupling | device (m, b) | Colgate 2b/T [N/m] | spectral radius | max E_gen [mJ] | passive | "
        "bounce out/in | peak force [N] | oscillation after settling [N] (rel.) | verdict | penetration / epsilon | "
        "crossings |\n";
  md << "|---|---|---|---|---|---|---|---|---|---|---|---|---|\n";
  for (const StiffnessResult& s : rows) {
    nlohmann::ordered_json j;
    j["k_lin_N_per_m"] = s.k_lin;
    j["coupling"] = s.gains;
    j["device"] = s.device;
    j["mass_kg"] = s.mass_kg;
    j["damping_Ns_per_m"] = s.damping;
    j["colgate_k_max_N_per_m"] = s.colgate_k_max;
    j["spectral_radius"] = finiteOr(s.spectral_radius);
    j["max_e_gen_J"] = finiteOr(s.max_e_gen_J);
    j["passive"] = s.passive;
    j["bounce_ratio"] = finiteOr(s.bounce_ratio);
    j["peak_force_N"] = finiteOr(s.peak_force_N);
    j["settled_ptp_N"] = finiteOr(s.settled_ptp_N);
    j["settled_ptp_rel"] = finiteOr(s.settled_ptp_rel);
    j["behaviour"] = toString(s.behaviour);
    j["stable"] = s.stable();
    j["solver_violations"] = s.solver_violations;
    j["max_penetration_over_epsilon"] = finiteOr(s.max_penetration_over_eps);
    j["crossings"] = s.crossings;
    j["crossing_points"] = s.crossing_points;
    j["finite"] = s.finite;
    sweep.push_back(j);
    md << "| " << format("%.0f", s.k_lin) << " | " << s.gains << " | " << s.device << " ("
       << format("%.1f kg, %.1f N*s/m", s.mass_kg, s.damping) << ") | " << format("%.0f", s.colgate_k_max) << " | "
       << format("%.3f", s.spectral_radius) << " | " << format("%.4g", 1e3 * s.max_e_gen_J) << " | "
       << (s.passive ? "yes" : "no") << " | " << format("%.3f", s.bounce_ratio) << " | "
       << format("%.2f", s.peak_force_N) << " | " << format("%.4f (%.3f)", s.settled_ptp_N, s.settled_ptp_rel) << " | "
       << toString(s.behaviour) << (s.crossings > 0 ? ", CROSSED" : "") << " | "
       << format("%.3f", s.max_penetration_over_eps) << " | " << s.crossings << " |\n";
  }
  report["stiffness_sweep"] = sweep;
}

/// Device models and the passivity controller: each catalogue model at its own servo rate, with
/// its encoder, one tick of delay and its force limit, on the plane, sphere and wedge; without and
/// with the passivity controller. Into `md` and `report` ("device_models"). @return the runs.
std::vector<vh::stability::StiffnessResult> runDeviceModels(std::ostringstream& md, nlohmann::ordered_json& report,
                                                            const vh::stability::HandParams& hand, bool short_run) {
  using namespace vh::stability;
  const std::vector<Scenario> device_scenes = deviceScenarios();
  const std::vector<double> model_ks =
      short_run ? std::vector<double>{50000} : std::vector<double>{1000, 3000, 10000, 20000, 50000};
  std::cout << "bench stability: device models, " << deviceCatalog().size() << " models x " << (model_ks.size() + 1)
            << " stiffnesses x 2 (passivity controller off / on) x " << device_scenes.size() << " scenes\n";
  md << "\n### Device models, with and without the passivity controller\n\n"
        "Each model of `vh::simulation::deviceCatalog()` (figures and sources in device_catalog.cpp) in the plane "
        "press-slide-tilt, sphere press-slide and wedge press-slide scenes, the coupling thread at the device's "
        "own servo rate, positions quantised to its encoder, every command one tick late and clamped to its "
        "force limit; 3-DOF force devices get no torque. K_rated is the closed-loop stiffness CHAI3D ships for "
        "the device (m_maxLinearStiffness). Verdict over the hold windows: settled (force ptp < 2 % of its mean, "
        "or the encoder's dither floor: handle within 2 counts, force ptp <= 2 K q), decaying, or LIMIT CYCLE. "
        "PC: the passivity controller (haptics::PassivityController) with its stiffness schedule floored at "
        "K_rated; rendered K: the stiffness the force port ends up rendering (the lowest over the scenes). "
        "Work taken: the work the controller took from the hand's port against the same run without it, summed "
        "over the three scenes (negative: the hand did less work against the softened spring).\n\n";
  md << "| device | rate [Hz] | K [N/m] | PC | verdict | rendered K [N/m] | hold ptp [N] (rel.) | handle travel [counts] "
        "| contact lost [ticks] | work taken [mJ] | PC active [ticks] | saturated [ticks] | crossings |\n"
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|\n";
  nlohmann::ordered_json models = nlohmann::ordered_json::array();
  std::vector<StiffnessResult> model_rows;
  for (const DeviceModelSpec& d : deviceCatalog()) {
    std::vector<double> ks_d{d.rated_stiffness_N_per_m};
    for (double k : model_ks)
      if (k > d.rated_stiffness_N_per_m) ks_d.push_back(k);
    for (double k : ks_d)
      for (bool pc : {false, true}) {
        SweepOptions o = withDevice(d);
        o.passivity_control = pc;
        o.verify_step_voxels = 0.05;
        const StiffnessResult s = evaluate(device_scenes, k, d.params(kLever_m), hand, o);
        model_rows.push_back(s);
        nlohmann::ordered_json j;
        j["device"] = d.name;
        j["servo_rate_Hz"] = d.servo_rate_Hz;
        j["k_lin_N_per_m"] = k;
        j["rated"] = k == d.rated_stiffness_N_per_m;
        j["passivity_control"] = pc;
        j["behaviour"] = toString(s.behaviour);
        j["stable"] = s.stable();
        j["hold_ptp_N"] = finiteOr(s.settled_ptp_N);
        j["hold_ptp_rel"] = finiteOr(s.settled_ptp_rel);
        j["hold_travel_counts"] = finiteOr(s.hold_ptp_counts);
        j["contact_lost_ticks"] = s.contact_lost_ticks;
        j["controller_dissipated_J"] = finiteOr(s.controller_dissipated_J);
        j["controller_active_ticks"] = s.controller_active_ticks;
        j["controller_end_gain"] = finiteOr(s.controller_end_gain);
        j["rendered_stiffness_N_per_m"] = finiteOr(s.rendered_stiffness_N_per_m);
        j["saturated_ticks"] = s.saturated_ticks;
        j["crossings"] = s.crossings;
        j["max_penetration_over_epsilon"] = finiteOr(s.max_penetration_over_eps);
        models.push_back(j);
        md << "| " << d.name << " | " << format("%.0f", d.servo_rate_Hz) << " | " << format("%.0f", k)
           << (k == d.rated_stiffness_N_per_m ? " (rated)" : "") << " | " << (pc ? "on" : "off") << " | "
           << toString(s.behaviour) << " | " << format("%.0f", s.rendered_stiffness_N_per_m) << " | "
           << format("%.3f (%.3f)", s.settled_ptp_N, s.settled_ptp_rel) << " | "
           << format("%.1f", s.hold_ptp_counts) << " | " << s.contact_lost_ticks << " | "
           << format("%.3g", 1e3 * s.controller_dissipated_J) << " | " << s.controller_active_ticks << " | "
           << s.saturated_ticks << " | " << s.crossings << " |\n";
      }
    std::cout << "  " << d.name << " done\n";
  }
  report["device_models"] = models;
  return model_rows;
}

/// The controller's price: a slow press at the rated stiffness of each model, without and with
/// the passivity controller. Into `md` and `report` ("controller_price").
void writeControllerPrice(std::ostringstream& md, nlohmann::ordered_json& report,
                          const vh::stability::HandParams& hand) {
  using namespace vh::stability;
  md << "\n#### The controller's price: a slow press at the rated stiffness\n\n"
        "The box lowered onto the plane at up to 5.8 mm/s to 5 mm past contact, held, lifted (scenario `plane slow "
        "press`), run without and with the controller through the same device path; force error = |F_with - "
        "F_without| per tick over the peak force.\n\n"
        "| device | K_rated [N/m] | peak force [N] | held-force error | mean error (in contact) | p99.9 error | "
        "max error | dissipated [mJ] | energy in [mJ] | PC active [ticks] |\n|---|---|---|---|---|---|---|---|---|---|\n";
  nlohmann::ordered_json prices = nlohmann::ordered_json::array();
  for (const DeviceModelSpec& d : deviceCatalog()) {
    const ControllerPrice p = controllerPrice(d, d.rated_stiffness_N_per_m, hand);
    prices.push_back({{"device", d.name},
                      {"k_lin_N_per_m", p.k_lin},
                      {"peak_force_N", p.peak_force_N},
                      {"hold_force_error_rel", p.hold_force_error_rel},
                      {"mean_force_error_rel", p.mean_force_error_rel},
                      {"p999_force_error_rel", p.p999_force_error_rel},
                      {"max_force_error_rel", p.max_force_error_rel},
                      {"dissipated_J", p.dissipated_J},
                      {"energy_in_J", p.work_in_J},
                      {"active_ticks", p.active_ticks}});
    md << "| " << d.name << " | " << format("%.0f", p.k_lin) << " | " << format("%.2f", p.peak_force_N) << " | "
       << format("%.2f %%", 100 * p.hold_force_error_rel) << " | " << format("%.2f %%", 100 * p.mean_force_error_rel)
       << " | " << format("%.1f %%", 100 * p.p999_force_error_rel) << " | "
       << format("%.1f %%", 100 * p.max_force_error_rel) << " | " << format("%.3g", 1e3 * p.dissipated_J) << " | "
       << format("%.3g", 1e3 * p.work_in_J) << " | " << p.active_ticks << " |\n";
  }
  report["controller_price"] = prices;
}

/// The extreme cases in both detection modes, judged. Into `md` and `report` ("extreme_cases").
void runExtremeCases(std::ostringstream& md, nlohmann::ordered_json& report, bool short_run) {
  std::cout << "bench stability: extreme cases (both detection modes)\n";
  nlohmann::ordered_json extreme = nlohmann::ordered_json::array();
  md << "\nExtreme cases, both detection modes (coupling 1000 N/m, 1 N*m/rad; scripted device). Crossings: ticks in "
        "which haptics::CrossingVerifier, sampling each shell point's path over the tick every "
     << kVerifyStepVoxels
     << " voxel, found a point carried from outside into the isosurface (a failure, like penetration beyond "
        "epsilon):\n\n";
  md << "| case | set-up | pass when | mode | outcome | ticks | max contacts | penetration / epsilon | crossings | "
        "max force [N] | bad samples | mean / max tick [us] |\n|---|---|---|---|---|---|---|---|---|---|---|---|\n";
  for (const ExtremeCase& c : extremeCases(short_run)) {
    nlohmann::ordered_json j;
    j["name"] = c.name;
    j["setup"] = c.setup;
    j["criterion"] = c.criterion;
    nlohmann::ordered_json modes;
    for (haptics::DetectionMode mode : {haptics::DetectionMode::kPaper, haptics::DetectionMode::kAccelerated}) {
      const CaseResult r = runCase(c, mode);
      const std::string outcome = judge(c, r);
      modes[haptics::toString(mode)] = {{"outcome", outcome},
                                        {"ticks", r.ticks},
                                        {"max_contacts", r.max_contacts},
                                        {"max_penetration_over_epsilon", r.max_penetration_over_eps},
                                        {"max_force_N", r.max_force_N},
                                        {"final_force_N", r.final_force_N},
                                        {"nan_ticks", r.nan_ticks},
                                        {"crossed_ticks", r.crossed_ticks},
                                        {"crossings", r.crossings},
                                        {"crossing_points", r.crossing_points},
                                        {"bad_device_samples", r.bad_inputs},
                                        {"mean_us", r.mean_us},
                                        {"max_us", r.max_us}};
      md << "| " << c.name << " | " << c.setup << " | " << c.criterion << " | " << haptics::toString(mode) << " | "
         << outcome << " | " << r.ticks << " | " << r.max_contacts << " | " << format("%.3f", r.max_penetration_over_eps)
         << " | " << r.crossings << " | " << format("%.2f", r.max_force_N) << " | " << r.bad_inputs << " | "
         << format("%.1f / %.1f", r.mean_us, r.max_us) << " |\n";
      std::cout << "  " << c.name << " [" << haptics::toString(mode) << "]: " << outcome << "\n";
    }
    j["modes"] = modes;
    extreme.push_back(j);
  }
  report["extreme_cases"] = extreme;
}

/// The PNG charts: the sweep's force oscillation against stiffness per coupling and device, and
/// the handle travel per device model without and with the controller. @return the files written.
std::vector<std::string> stabilityPlots(const fs::path& out, const std::vector<double>& levers,
                                        const std::vector<vh::stability::DeviceParams>& devices,
                                        const std::vector<vh::stability::StiffnessResult>& rows,
                                        const std::vector<vh::stability::StiffnessResult>& model_rows) {
  using namespace vh::stability;
  std::vector<std::string> plots;
  std::vector<Series> series;
  for (double lever : levers)
    for (const DeviceParams& d : devices) {
      Series s{std::string(lever > 0 ? "diag" : "scalar") + ", device " + d.name, {}, {}, false};
      for (const StiffnessResult& r : rows)
        if (r.device == d.name && r.gains == (lever > 0 ? "diag" : "scalar")) {
          s.x.push_back(r.k_lin);
          s.y.push_back(std::max(r.settled_ptp_rel, 1e-6));
        }
      series.push_back(s);
    }
  if (plotXY(out / "stability_oscillation.png", "Force oscillation after settling", "stiffness K [N/m]",
             "force peak-to-peak / mean force", series, true, true))
    plots.push_back("stability_oscillation.png");
  std::vector<Series> model_series;
  for (const DeviceModelSpec& d : deviceCatalog())
    for (bool pc : {false, true}) {
      Series s{d.name + (pc ? ", PC on" : ", PC off"), {}, {}, false};
      for (const StiffnessResult& r : model_rows)
        if (r.device == d.name && r.passivity_control == pc) {
          s.x.push_back(r.k_lin);
          s.y.push_back(std::max(r.hold_ptp_counts, 0.1));
        }
      model_series.push_back(s);
    }
  if (plotXY(out / "stability_device_models.png", "Handle travel in the hold windows, per device model",
             "stiffness K [N/m]", "handle travel [encoder counts]", model_series, true, true))
    plots.push_back("stability_device_models.png");
  return plots;
}

}  // namespace

fs::path runStability(const CommonOptions& options) {
  const fs::path out = outputDir(options, "stability");
  const bool short_run = options.short_run;
  nlohmann::ordered_json report = reportHeader("stability", short_run);
  report["verify_step_voxels"] = kVerifyStepVoxels;

  // --- Stiffness sweep --------------------------------------------------------------------
  using namespace vh::stability;
  const std::vector<double> ks = short_run ? std::vector<double>{1000, 5000, 50000}
                                           : std::vector<double>{100, 300, 1000, 3000, 5000, 10000, 30000, 50000};
  std::vector<DeviceParams> devices{DeviceParams::scaled("A", 0.2, 1.0, kLever_m)};
  if (!short_run) devices.push_back(DeviceParams::scaled("B", 0.1, 0.0, kLever_m));
  const std::vector<double> levers = short_run ? std::vector<double>{kLever_m} : std::vector<double>{kLever_m, 0.0};
  const HandParams hand = HandParams::scaled(500.0, 5.0, kLever_m);
  std::vector<Scenario> scenarios = defaultScenarios();
  const std::vector<StiffnessResult> rows = runStiffnessSweep(scenarios, ks, devices, levers, hand);
  std::ostringstream md;
  writeStiffnessSweep(md, report, rows, short_run);

  // --- Device models and the passivity controller ------------------------------------------
  const std::vector<StiffnessResult> model_rows = runDeviceModels(md, report, hand, short_run);
  writeControllerPrice(md, report, hand);

  // --- Extreme cases ---------------------------------------------------------------------
  runExtremeCases(md, report, short_run);

  std::vector<std::string> plots;
  if (options.plots) plots = stabilityPlots(out, levers, devices, rows, model_rows);
  writeReport(out, "stability", report, md, plots);
  return out;
}

}  // namespace vh::bench
