// `volume-haptics bench accuracy`: contact-position error, normal error and penetration against
// tick time, on volumes whose isosurface is known exactly (signed distance fields sampled by
// vh::datasets::makeVolumeFromSignedDistance), swept over epsilon, segment_fraction and the
// point-shell density.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <iostream>
#include <map>
#include <optional>
#include <sstream>
#include <tuple>

#include <Eigen/Geometry>

#include "vh/bench/report.h"
#include "vh/datasets/synthetic.h"
#include "vh/haptics/crossing_verifier.h"
#include "vh/haptics/haptic_renderer.h"
#include "vh/runtime/trajectory.h"
#include "vh/runtime/realtime.h"

namespace vh::bench {

namespace fs = std::filesystem;

namespace {

/// A solid with an exact signed distance [m] (positive inside) and where to touch it.
struct Surface {
  std::string name;
  std::function<double(const Eigen::Vector3d&)> sdf;
  Eigen::Vector3d touch_W_m;   ///< A point on the surface where the probe lands.
  Eigen::Vector3d slide_dir_W; ///< Tangent direction of the slide there.
  /// Thinnest feature [m]: a grid with coarser voxels cannot hold the shape (the sampled
  /// isosurface is another shape), so such runs are reported but left out of the summary.
  double min_feature_m = 1.0;
};

std::vector<Surface> surfaces() {
  const Eigen::Vector3d n = Eigen::Vector3d(0.25, 0.15, 1.0).normalized();
  return {
      {"plane (tilted)", [n](const Eigen::Vector3d& p) { return -n.dot(p); }, Eigen::Vector3d::Zero(),
       Eigen::Vector3d::UnitX()},
      {"sphere r 20 mm", [](const Eigen::Vector3d& p) { return 0.020 - p.norm(); }, {0.0, 0.0, 0.020},
       Eigen::Vector3d::UnitX()},
      {"torus R 18 r 7 mm",
       [](const Eigen::Vector3d& p) {
         const double q = std::hypot(p.x(), p.y()) - 0.018;
         return 0.007 - std::hypot(q, p.z());
       },
       {0.018, 0.0, 0.007}, Eigen::Vector3d::UnitY()},
      {"thin shell 1.5 mm", [](const Eigen::Vector3d& p) { return 0.00075 - std::abs(p.norm() - 0.020); },
       {0.0, 0.0, 0.02075}, Eigen::Vector3d::UnitX(), 0.0015},
  };
}

/// Unit inward gradient of a signed distance (central differences, 1 um).
Eigen::Vector3d inward(const Surface& s, const Eigen::Vector3d& p) {
  const double h = 1e-6;
  Eigen::Vector3d g;
  for (int a = 0; a < 3; ++a) {
    Eigen::Vector3d e = Eigen::Vector3d::Zero();
    e[a] = h;
    g[a] = (s.sdf(p + e) - s.sdf(p - e)) / (2 * h);
  }
  const double norm = g.norm();
  return norm > 0 ? Eigen::Vector3d(g / norm) : Eigen::Vector3d::UnitZ();
}

/// Closest surface point (a few Newton steps along the gradient).
Eigen::Vector3d project(const Surface& s, Eigen::Vector3d q) {
  for (int k = 0; k < 6; ++k) q -= s.sdf(q) * inward(s, q);
  return q;
}

struct Config {
  double epsilon_fraction;  ///< epsilon / f
  double segment_fraction;
  double spacing_m;         ///< point-shell spacing on the 4 mm ball
  std::string family;       ///< which sweep it belongs to
  bool operator<(const Config& o) const {
    return std::tie(epsilon_fraction, segment_fraction, spacing_m) <
           std::tie(o.epsilon_fraction, o.segment_fraction, o.spacing_m);
  }
  std::string label() const {
    return format("eps f/%g, seg %g, spacing %g mm", 1.0 / epsilon_fraction, segment_fraction, spacing_m * 1e3);
  }
};

struct RunResult {
  double mean_us = 0, p99_us = 0, cpu_mean_us = 0;
  double pos_err_mean_m = 0, pos_err_max_m = 0;
  double normal_err_mean_deg = 0, normal_err_max_deg = 0;
  double max_penetration_m = 0, epsilon_m = 0;
  std::size_t contact_samples = 0, points = 0;
  int ticks = 0;
  int crossings = 0;            ///< Ticks in which CrossingVerifier found a point carried inside.
  std::int64_t crossing_points = 0;
  double verify_s = 0.0;
  bool finite = true;
};

constexpr double kToolRadius_m = 0.004;

constexpr double kPush_m = 0.0015;
/// Crossing check after every tick (haptics::CrossingVerifier, outside the timed section): path
/// sampling step [voxels of each grid].
constexpr double kVerifyStepVoxels = 0.01;

RunResult runOne(const Surface& surf, std::shared_ptr<const haptics::ScalarVolume> volume,
                 std::shared_ptr<const haptics::ToolModel> tool, const Config& cfg, int ticks) {
  // Device path: from 5 mm above the touch point down to kPush_m past contact, then along the
  // surface 12 mm in slide_dir (each key projected onto the true surface), hold, retract.
  const Eigen::Vector3d s0 = project(surf, surf.touch_W_m);
  const Eigen::Vector3d n0 = -inward(surf, s0);
  std::vector<runtime::TrajectorySample> keys;
  const double duration = (ticks - 1) * 1e-3;
  const auto at = [&](double frac, const Eigen::Vector3d& p) {
    keys.push_back({frac * duration, haptics::Pose::FromTranslation(p)});
  };
  at(0.0, s0 + (kToolRadius_m + 0.005) * n0);
  at(0.15, s0 + (kToolRadius_m - kPush_m) * n0);
  const int m = 16;
  Eigen::Vector3d last = s0;
  for (int k = 1; k <= m; ++k) {
    const Eigen::Vector3d s = project(surf, s0 + 0.012 * k / m * surf.slide_dir_W);
    at(0.15 + 0.65 * k / m, s + (kToolRadius_m - kPush_m) * (-inward(surf, s)));
    last = s;
  }
  at(0.9, keys.back().X_WD.p_AB_m + Eigen::Vector3d(1e-7, 0, 0));
  at(1.0, last + (kToolRadius_m + 0.005) * (-inward(surf, last)));
  const runtime::Trajectory traj(std::move(keys));

  haptics::RendererOptions options;
  options.epsilon_m = cfg.epsilon_fraction * volume->featureSize_m();
  options.segment_fraction = cfg.segment_fraction;
  haptics::HapticRenderer renderer(volume, tool, options, traj.samples().front().X_WD, 0.0);
  const haptics::CrossingVerifier verifier(*volume, tool->point_shell, kVerifyStepVoxels);
  RunResult r;
  r.epsilon_m = renderer.epsilon_m();
  r.points = tool->point_shell.size();
  r.ticks = ticks;
  std::vector<double> times;
  times.reserve(static_cast<std::size_t>(ticks));
  double pos_sum = 0, normal_sum = 0, cpu_sum = 0;
  std::size_t cursor = 0;
  for (int i = 0; i < ticks; ++i) {
    const haptics::Pose X_WD = traj.poseAt(i * 1e-3, cursor);
    const double c0 = runtime::threadCpuTime_us();
    const haptics::TickOutput out = renderer.tick(X_WD, 0.0);
    cpu_sum += runtime::threadCpuTime_us() - c0;
    times.push_back(out.stats.exec_time_us);
    if (!out.X_WP.allFinite() || !out.force_W_N.allFinite()) {
      r.finite = false;
      continue;
    }
    // Outside the timed section: did the tick's motion carry a point into the (sampled) isosurface?
    const auto v0 = std::chrono::steady_clock::now();
    const haptics::CrossingVerifier::Result check =
        verifier.check(renderer.lastMotion(), renderer.lastTimeOfContact(), 0.0);
    r.verify_s += std::chrono::duration<double>(std::chrono::steady_clock::now() - v0).count();
    if (check.crossing_points > 0) {
      ++r.crossings;
      r.crossing_points += check.crossing_points;
    }
    for (const haptics::Contact& c : renderer.contacts()) {
      const double e = std::abs(surf.sdf(c.p_W_m));
      const Eigen::Vector3d n_true = -inward(surf, c.p_W_m);
      const double ang = std::acos(std::clamp(c.n_W.dot(n_true), -1.0, 1.0)) * 180.0 / M_PI;
      pos_sum += e;
      normal_sum += ang;
      r.pos_err_max_m = std::max(r.pos_err_max_m, e);
      r.normal_err_max_deg = std::max(r.normal_err_max_deg, ang);
      ++r.contact_samples;
    }
    for (const Eigen::Vector3d& p_T : tool->point_shell.points_T_m())
      r.max_penetration_m = std::max(r.max_penetration_m, surf.sdf(out.X_WP * p_T));
  }
  const Stats t = summarize(times);
  r.mean_us = t.mean;
  r.p99_us = t.p99;
  r.cpu_mean_us = cpu_sum / ticks;
  if (r.contact_samples > 0) {
    r.pos_err_mean_m = pos_sum / static_cast<double>(r.contact_samples);
    r.normal_err_mean_deg = normal_sum / static_cast<double>(r.contact_samples);
  }
  return r;
}

/// The sweeps of one run: grid resolutions [m], and one factor at a time around the paper's
/// setting (epsilon f/4, segment 1, 0.5 mm spacing): epsilon / f, segment fractions and
/// point-shell spacings [m], with the settings they make.
struct Sweep {
  std::vector<double> resolutions_m, eps, segs, spacings;
  std::vector<Config> configs;
};

Sweep accuracySweep(bool short_run) {
  Sweep w;
  w.resolutions_m = short_run ? std::vector<double>{1e-3} : std::vector<double>{2e-3, 1e-3, 5e-4};
  w.eps = short_run ? std::vector<double>{0.5, 0.25, 0.125} : std::vector<double>{0.5, 0.25, 0.125, 0.0625};
  w.segs = short_run ? std::vector<double>{1.0, 0.5} : std::vector<double>{1.0, 0.5, 0.25};
  w.spacings = short_run ? std::vector<double>{1e-3, 5e-4} : std::vector<double>{1e-3, 5e-4, 3.5e-4};
  for (double e : w.eps) w.configs.push_back({e, 1.0, 5e-4, "epsilon"});
  for (double s : w.segs)
    if (s != 1.0) w.configs.push_back({0.25, s, 5e-4, "segment"});
  for (double sp : w.spacings)
    if (sp != 5e-4) w.configs.push_back({0.25, 1.0, sp, "density"});
  return w;
}

/// The 4 mm ball's tool model at each point-shell spacing [m].
std::map<double, std::shared_ptr<const haptics::ToolModel>> ballTools(const std::vector<double>& spacings) {
  std::map<double, std::shared_ptr<const haptics::ToolModel>> tools;
  for (double sp : spacings) {
    haptics::PointShellOptions po;
    po.spacing_m = sp;
    tools[sp] = std::make_shared<const haptics::ToolModel>(
        haptics::makeToolModel(datasets::makeSphereMesh(kToolRadius_m, 4), po));
  }
  return tools;
}

/// One run's line of the report: the surface, the grid's voxel [m], the setting and the result.
nlohmann::ordered_json runJson(const Surface& surf, double voxel_m, const Config& cfg, const RunResult& r) {
  nlohmann::ordered_json j;
  j["surface"] = surf.name;
  j["voxel_m"] = voxel_m;
  j["family"] = cfg.family;
  j["epsilon_over_f"] = cfg.epsilon_fraction;
  j["epsilon_m"] = r.epsilon_m;
  j["segment_fraction"] = cfg.segment_fraction;
  j["point_spacing_m"] = cfg.spacing_m;
  j["points"] = r.points;
  j["ticks"] = r.ticks;
  j["mean_us"] = r.mean_us;
  j["p99_us"] = r.p99_us;
  j["cpu_mean_us"] = r.cpu_mean_us;
  j["contact_samples"] = r.contact_samples;
  j["position_error_mean_m"] = r.pos_err_mean_m;
  j["position_error_max_m"] = r.pos_err_max_m;
  j["normal_error_mean_deg"] = r.normal_err_mean_deg;
  j["normal_error_max_deg"] = r.normal_err_max_deg;
  j["max_penetration_m"] = r.max_penetration_m;
  j["crossings"] = r.crossings;
  j["crossing_points"] = r.crossing_points;
  j["verify_s"] = r.verify_s;
  j["finite"] = r.finite;
  j["resolved_by_grid"] = surf.min_feature_m >= voxel_m;
  return j;
}

/// Sums per setting over the runs whose grid holds the shape and that made contact.
struct Agg {
  double us = 0, pos_vox = 0, normal_deg = 0, pen_over_eps = 0;  // pen: the maximum over runs
  int n = 0;
  int crossings = 0;  // summed over the runs
};

/// Every surface at every resolution in every setting of `sweep`, `ticks` each: each run's line
/// into `runs`, the sums per setting into `agg`, and the runs without any contact into
/// `unresolved`.
void runSweep(const Sweep& sweep, const std::map<double, std::shared_ptr<const haptics::ToolModel>>& tools, int ticks,
              nlohmann::ordered_json& runs, std::map<Config, Agg>& agg, std::vector<std::string>& unresolved) {
  for (const Surface& surf : surfaces()) {
    for (double h : sweep.resolutions_m) {
      datasets::GridSpec grid;
      const int dims = static_cast<int>(std::lround(0.064 / h));
      grid.dims = {dims, dims, dims};
      grid.spacing_m = Eigen::Vector3d::Constant(h);
      auto volume = std::make_shared<const haptics::ScalarVolume>(datasets::makeVolumeFromSignedDistance(grid, surf.sdf));
      for (const Config& cfg : sweep.configs) {
        const RunResult r = runOne(surf, volume, tools.at(cfg.spacing_m), cfg, ticks);
        runs.push_back(runJson(surf, h, cfg, r));
        if (surf.min_feature_m < h) continue;
        if (r.contact_samples == 0) {
          unresolved.push_back(format("%s at %.2g mm voxels (%s)", surf.name.c_str(), h * 1e3, cfg.label().c_str()));
          continue;
        }
        Agg& a = agg[cfg];
        a.us += r.cpu_mean_us;
        a.pos_vox += r.pos_err_mean_m / h;
        a.normal_deg += r.normal_err_mean_deg;
        a.pen_over_eps = std::max(a.pen_over_eps, std::max(r.max_penetration_m, 0.0) / r.epsilon_m);
        a.crossings += r.crossings;
        ++a.n;
      }
      std::cout << "  " << surf.name << ", " << h * 1e3 << " mm voxels: done\n";
    }
  }
}

/// One setting averaged over its runs: CPU time per tick [us], mean contact error [voxels],
/// mean normal error [deg], the worst penetration / epsilon and the crossings summed.
struct Point {
  Config cfg;
  double us, pos_vox, normal_deg, pen_over_eps;
  int crossings;
};

/// The settings' averages, cheapest first.
std::vector<Point> settingPoints(const std::map<Config, Agg>& agg) {
  std::vector<Point> points;
  for (const auto& [cfg, a] : agg)
    if (a.n > 0)
      points.push_back({cfg, a.us / a.n, a.pos_vox / a.n, a.normal_deg / a.n, a.pen_over_eps, a.crossings});
  std::sort(points.begin(), points.end(), [](const Point& a, const Point& b) { return a.us < b.us; });
  return points;
}

/// Recommendation (epsilon and segment fraction; the point spacing belongs to the tool): over the
/// settings at the reference spacing, the cheapest point of their front within 10 % (or 0.02
/// voxel) of its best error. `best` gets that front's best error [voxels] (1e300: none).
/// @return the pick; none when no setting qualifies.
std::optional<Point> recommendedSetting(const std::vector<Point>& points, double& best) {
  std::vector<Point> front_ref;
  for (const Point& p : points)
    if (p.cfg.spacing_m == 5e-4 && p.pen_over_eps <= 1.0 && p.crossings == 0 &&
        (front_ref.empty() || p.pos_vox < front_ref.back().pos_vox))
      front_ref.push_back(p);
  best = 1e300;
  for (const Point& p : front_ref) best = std::min(best, p.pos_vox);
  for (const Point& p : front_ref)
    if (p.pos_vox <= std::max(1.10 * best, best + 0.02)) return p;
  return std::nullopt;
}

/// The paper's setting, the sweeps' centre (epsilon f/4, segment 1, 0.5 mm spacing), in
/// `points`; nullptr when it made no contact anywhere.
const Point* sweepCentre(const std::vector<Point>& points) {
  const Point* current = nullptr;
  for (const Point& p : points)
    if (p.cfg.epsilon_fraction == 0.25 && p.cfg.segment_fraction == 1.0 && p.cfg.spacing_m == 5e-4) current = &p;
  return current;
}

nlohmann::ordered_json pointJson(const Point& p) {
  return nlohmann::ordered_json{{"epsilon_over_f", p.cfg.epsilon_fraction}, {"segment_fraction", p.cfg.segment_fraction},
                                {"point_spacing_m", p.cfg.spacing_m}, {"family", p.cfg.family},
                                {"mean_us", p.us}, {"position_error_mean_voxels", p.pos_vox},
                                {"normal_error_mean_deg", p.normal_deg},
                                {"max_penetration_over_epsilon", p.pen_over_eps},
                                {"crossings", p.crossings}};
}

/// The Markdown's heading, how the runs were made, and one line per run.
void writeRunsTable(std::ostringstream& md, const nlohmann::ordered_json& report, const nlohmann::ordered_json& runs,
                    int ticks, std::size_t resolutions, bool short_run) {
  md << "## Error against run time (`volume-haptics bench accuracy" << (short_run ? " --short" : "") << "`)\n\n";
  md << "Run " << report["date_utc"].get<std::string>() << " on " << report["cpu_model"].get<std::string>()
     << ". A 4 mm ball pressed " << kPush_m * 1e3
     << " mm past contact and slid 12 mm along the surface (" << ticks
     << " ticks) on exact isosurfaces (signed distance sampled into float32 grids of 64 mm) at "
     << resolutions << " resolution(s). Position error: distance of each reported contact point to the "
        "true surface; normal error: angle between the contact normal and the true normal; penetration: deepest "
        "shell point inside the true surface. Default detection mode (accelerated). Times: mean wall time per "
        "tick per run; the per-setting summary and the Pareto front use the thread's CPU time per tick, which "
        "preemption on a busy machine does not inflate. Crossings: ticks in which haptics::CrossingVerifier, "
        "sampling each shell point's path over the tick every "
     << kVerifyStepVoxels
     << " voxel outside the timed section, found a point carried from outside into the grid's isosurface.\n\n";
  md << "| surface | voxel [mm] | setting | points | mean [us] | contact error mean / max [mm] | normal error mean / "
        "max [deg] | max penetration [mm] (epsilon) | crossings |\n|---|---|---|---|---|---|---|---|---|\n";
  for (const auto& j : runs) {
    const Config cfg{j["epsilon_over_f"].get<double>(), j["segment_fraction"].get<double>(),
                     j["point_spacing_m"].get<double>(), ""};
    md << "| " << j["surface"].get<std::string>() << " | " << format("%.2g", j["voxel_m"].get<double>() * 1e3) << " | "
       << cfg.label() << " | " << j["points"].get<std::size_t>() << " | " << format("%.1f", j["mean_us"].get<double>())
       << " | "
       << (j["contact_samples"].get<std::size_t>() == 0
               ? std::string("no contact")
               : format("%.4f / %.4f", 1e3 * j["position_error_mean_m"].get<double>(),
                        1e3 * j["position_error_max_m"].get<double>()))
       << " | " << format("%.2f / %.2f", j["normal_error_mean_deg"].get<double>(), j["normal_error_max_deg"].get<double>())
       << " | " << format("%.4f (%.4f)", 1e3 * j["max_penetration_m"].get<double>(), 1e3 * j["epsilon_m"].get<double>())
       << " | " << j["crossings"].get<int>() << " |\n";
  }
}

/// One line per setting (marked when on the Pareto front), then the runs without any contact.
void writeSettingsTable(std::ostringstream& md, const std::vector<Point>& points, const std::vector<Point>& front,
                        const std::vector<std::string>& unresolved) {
  md << "\nPer setting, averaged over the surfaces and resolutions whose grid holds the shape (the 1.5 mm shell "
        "on 2 mm voxels is left out: its sampled isosurface is another shape); errors in voxels of each grid; "
        "penetration: the worst run; crossings: summed over the runs:\n\n";
  md << "| setting | sweep | CPU mean [us] | contact error [voxels] | normal error [deg] | max penetration / epsilon | "
        "crossings | Pareto |\n|---|---|---|---|---|---|---|---|\n";
  for (const Point& p : points) {
    const bool on_front = std::any_of(front.begin(), front.end(), [&](const Point& f) {
      return !(f.cfg < p.cfg) && !(p.cfg < f.cfg);
    });
    md << "| " << p.cfg.label() << " | " << p.cfg.family << " | " << format("%.1f", p.us) << " | "
       << format("%.4f", p.pos_vox) << " | " << format("%.2f", p.normal_deg) << " | " << format("%.3f", p.pen_over_eps)
       << " | " << p.crossings << " | " << (on_front ? "yes" : "") << " |\n";
  }
  if (!unresolved.empty()) {
    md << "\nNo contact at all (the surface is not resolved by the grid, or the tool passed it): ";
    for (std::size_t i = 0; i < unresolved.size(); ++i) md << (i ? "; " : "") << unresolved[i];
    md << ".\n";
  }
}

/// The reasoning behind the recommendation, from the numbers of the settings table: the error
/// and penetration per epsilon of `eps`, and the spread of the CPU time per tick.
void writeReasoning(std::ostringstream& md, const std::vector<Point>& points, const std::vector<double>& eps) {
  std::string eps_err, eps_pen;
  double t_min = 1e300, t_max = 0.0, d_min = 1e300, d_max = 0.0;
  for (double e : eps)
    for (const Point& p : points)
      if (p.cfg.family == "epsilon" && p.cfg.epsilon_fraction == e) {
        eps_err += format("%sf/%g: %.3f", eps_err.empty() ? "" : ", ", 1.0 / e, p.pos_vox);
        eps_pen += format("%sf/%g: %.2f", eps_pen.empty() ? "" : ", ", 1.0 / e, p.pen_over_eps);
      }
  for (const Point& p : points) {
    if (p.cfg.spacing_m == 5e-4) {
      t_min = std::min(t_min, p.us);
      t_max = std::max(t_max, p.us);
    }
    if (p.cfg.family == "density" || p.cfg.spacing_m == 5e-4) {
      d_min = std::min(d_min, p.us);
      d_max = std::max(d_max, p.us);
    }
  }
  md << "\n\nReasoning, from the table: the contact error follows epsilon (" << eps_err
     << " voxel), because a contact is reported anywhere within epsilon of the surface; at the reference spacing "
        "the CPU time per tick hardly depends on epsilon or the segment fraction ("
     << format("%.1f to %.1f us", t_min, t_max)
     << ": bisection adds one sample per halving of epsilon), while the point spacing sets the cost ("
     << format("%.1f to %.1f us", d_min, d_max)
     << " over the spacings measured) and is a property of the tool (the smallest tool feature that is felt), so "
        "it is reported, not defaulted. The worst penetration against the true surface, in units of epsilon, was "
     << eps_pen
     << ": the trilinear isosurface itself departs from the true one by a fraction of a voxel on curved "
        "surfaces and the renderer keeps the proxy outside the isosurface it sees, so a very small epsilon no "
        "longer bounds the depth below the true surface; the settings that broke the bound were excluded. "
        "The renderer's default epsilon (RendererOptions::epsilon_m = 0) is f/8 since this benchmark; the "
        "segment fraction stays 1 (the paper's): smaller fractions bought no accuracy here.\n";
}

/// The "Recommended defaults" section: the rule, the pick against the sweep's centre (`current`,
/// may be null) and the reasoning; `best`: the front's best error [voxels].
void writeRecommendation(std::ostringstream& md, const std::optional<Point>& pick, const Point* current, double best,
                         const std::vector<Point>& points, const std::vector<double>& eps) {
  md << "\n### Recommended defaults\n\n";
  if (!pick) {
    md << "No setting produced contacts; nothing to recommend.\n";
    return;
  }
  md << "Rule: among the settings at the reference point spacing (0.5 mm) whose penetration stayed within "
        "epsilon of the true surface and that crossed no surface in every resolved run, the cheapest one on their Pareto front (CPU time "
        "per tick against mean contact error) whose error is within 10 % (or 0.02 voxel) of that front's best. "
        "Picked: **"
     << pick->cfg.label() << "**: " << format("%.1f us", pick->us) << " per tick, contact error "
     << format("%.4f", pick->pos_vox) << " voxel, normal error " << format("%.2f deg", pick->normal_deg)
     << " (front's best: " << format("%.4f", best) << " voxel).";
  if (current)
    md << " The sweep's centre (epsilon f/4, segment 1: the paper's setting and the renderer's default until this benchmark) measures "
       << format("%.1f us, %.4f voxel, %.2f deg", current->us, current->pos_vox, current->normal_deg) << ".";
  writeReasoning(md, points, eps);
}

/// The PNG charts: contact and normal error against CPU time per tick, per sweep (each with the
/// sweeps' centre), and the Pareto front. @return the files written (in `out`).
std::vector<std::string> accuracyPlots(const fs::path& out, const std::vector<Point>& points,
                                       const std::vector<Point>& front) {
  std::vector<std::string> plots;
  std::vector<Series> err_series, normal_series;
  for (const char* fam : {"epsilon", "segment", "density"}) {
    Series s{std::string(fam) + " sweep", {}, {}, true}, n{std::string(fam) + " sweep", {}, {}, true};
    for (const Point& p : points)
      if (p.cfg.family == fam || (p.cfg.epsilon_fraction == 0.25 && p.cfg.segment_fraction == 1.0 && p.cfg.spacing_m == 5e-4)) {
        s.x.push_back(p.us);
        s.y.push_back(p.pos_vox);
        n.x.push_back(p.us);
        n.y.push_back(p.normal_deg);
      }
    err_series.push_back(s);
    normal_series.push_back(n);
  }
  Series f{"Pareto front", {}, {}, false};
  for (const Point& p : front) {
    f.x.push_back(p.us);
    f.y.push_back(p.pos_vox);
  }
  err_series.push_back(f);
  if (plotXY(out / "accuracy_error_vs_time.png", "Contact error against tick time", "CPU time per tick [us]",
             "mean contact error [voxels]", err_series))
    plots.push_back("accuracy_error_vs_time.png");
  if (plotXY(out / "accuracy_normal_vs_time.png", "Normal error against tick time", "CPU time per tick [us]",
             "mean normal error [deg]", normal_series))
    plots.push_back("accuracy_normal_vs_time.png");
  return plots;
}

}  // namespace

fs::path runAccuracy(const CommonOptions& options) {
  const fs::path out = outputDir(options, "accuracy");
  const bool short_run = options.short_run;
  const int ticks = short_run ? 300 : 1200;
  const Sweep sweep = accuracySweep(short_run);
  const std::map<double, std::shared_ptr<const haptics::ToolModel>> tools = ballTools(sweep.spacings);

  nlohmann::ordered_json report = reportHeader("accuracy", short_run);
  report["ticks_per_run"] = ticks;
  report["tool"] = "ball, radius 4 mm";
  report["push_depth_m"] = kPush_m;
  report["verify_step_voxels"] = kVerifyStepVoxels;
  nlohmann::ordered_json runs = nlohmann::ordered_json::array();
  std::cout << "bench accuracy: " << surfaces().size() << " surfaces x " << sweep.resolutions_m.size()
            << " resolutions x " << sweep.configs.size() << " settings, " << ticks << " ticks each\n";
  std::map<Config, Agg> agg;
  std::vector<std::string> unresolved;
  runSweep(sweep, tools, ticks, runs, agg, unresolved);
  report["runs"] = runs;

  // Aggregate per setting and the Pareto front over (mean tick time, mean position error in voxels).
  const std::vector<Point> points = settingPoints(agg);
  std::vector<Point> front;
  for (const Point& p : points)
    if (front.empty() || p.pos_vox < front.back().pos_vox) front.push_back(p);
  double best = 1e300;
  const std::optional<Point> pick = recommendedSetting(points, best);
  const Point* current = sweepCentre(points);

  nlohmann::ordered_json settings = nlohmann::ordered_json::array(), front_json = nlohmann::ordered_json::array();
  for (const Point& p : points) settings.push_back(pointJson(p));
  for (const Point& p : front) front_json.push_back(pointJson(p));
  report["settings"] = settings;
  report["pareto_front"] = front_json;
  report["unresolved"] = unresolved;
  bool penetration_within_epsilon = true;
  for (const auto& j : runs)
    if (j["resolved_by_grid"].get<bool>())
      penetration_within_epsilon =
        penetration_within_epsilon && j["max_penetration_m"].get<double>() <= j["epsilon_m"].get<double>();
  report["penetration_within_epsilon_everywhere"] = penetration_within_epsilon;
  int crossings_total = 0;
  for (const auto& j : runs) crossings_total += j["crossings"].get<int>();
  report["crossings_total"] = crossings_total;
  if (pick) report["recommended"] = pointJson(*pick);

  std::ostringstream md;
  writeRunsTable(md, report, runs, ticks, sweep.resolutions_m.size(), short_run);
  writeSettingsTable(md, points, front, unresolved);
  writeRecommendation(md, pick, current, best, points, sweep.eps);
  report["recommendation_rule"] =
      "at 0.5 mm point spacing, penetration <= epsilon and no crossing in every resolved run: the cheapest Pareto setting "
      "within 10 % (or 0.02 voxel) of the front's best mean contact error";

  std::vector<std::string> plots;
  if (options.plots) plots = accuracyPlots(out, points, front);
  writeReport(out, "accuracy", report, md, plots);
  return out;
}

}  // namespace vh::bench
