// The fit check (tool_fit.h): a warm-up touch run by the full solve and by the deadline's work
// budget beside it, for the tool as chosen and, when it does not fit, for coarser spacings.
#include "vh/runtime/tool_fit.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <memory>
#include <stdexcept>
#include <tuple>
#include <utility>

#include <nlohmann/json.hpp>

#include "vh/haptics/haptic_renderer.h"
#include "vh/runtime/placement.h"
#include "vh/runtime/runner.h"
#include "vh/runtime/servo_factory.h"
#include "vh/runtime/tool_fidelity.h"
#include "vh/runtime/realtime.h"

namespace vh::runtime {
namespace {

using Clock = std::chrono::steady_clock;

Eigen::Quaterniond aa(double angle_rad, const Eigen::Vector3d& axis) {
  return Eigen::Quaterniond(Eigen::AngleAxisd(angle_rad, axis));
}

/// What the warm-up's full solve measured, tick by tick.
struct FullSolveRun {
  std::vector<std::int64_t> work;   ///< Critical work per tick [units].
  std::vector<double> time_us;      ///< Thread CPU time per tick (wall on several lanes) [us].
  std::vector<haptics::Pose> X_WP;  ///< Its proxy after each tick (NaN when not finite).
  double wall_max_us = 0.0;         ///< Its slowest tick (wall) [us].
};

/// The warm-up's full solve of `live` with `tool` over `traj`: no budget, no deadline.
FullSolveRun runFullSolve(const LiveValues& live, const std::shared_ptr<const haptics::ToolModel>& tool,
                          const Trajectory& traj, int ticks, int lanes, const std::atomic<bool>* cancel) {
  LiveValues with_tool = live;
  with_tool.tool = tool;
  haptics::RendererOptions options;
  options.work_budget = 0;
  options.deadline_us = 0.0;
  options.solver_lanes = lanes;
  std::unique_ptr<haptics::HapticRenderer> full = makeRenderer(with_tool, options, traj.poseAt(0.0));
  const double s = with_tool.hapticIsovalue();
  FullSolveRun run;
  run.work.reserve(static_cast<std::size_t>(ticks));
  run.time_us.reserve(static_cast<std::size_t>(ticks));
  run.X_WP.reserve(static_cast<std::size_t>(ticks));
  std::size_t cursor = 0;
  for (int i = 0; i < ticks; ++i) {
    if (cancel != nullptr && cancel->load(std::memory_order_relaxed)) throw ToolFitCancelled();
    const haptics::Pose X_WD = traj.poseAt(i * 1e-3, cursor);
    const double c0 = threadCpuTime_us();
    const auto w0 = Clock::now();
    const haptics::TickOutput out = full->tick(X_WD, s);
    const double wall = std::chrono::duration<double, std::micro>(Clock::now() - w0).count();
    const double cpu = threadCpuTime_us() - c0;
    run.time_us.push_back(lanes > 1 ? wall : cpu);
    run.wall_max_us = std::max(run.wall_max_us, wall);
    run.work.push_back(out.stats.critical_work);
    run.X_WP.push_back(out.X_WP);
  }
  return run;
}

/// The same touch with the work budget `budget`: the ticks it cuts and how far its proxy falls
/// behind the full solve's (`reference`).
std::pair<int, ProxyLag> runBudgeted(const LiveValues& live, const std::shared_ptr<const haptics::ToolModel>& tool,
                                     const Trajectory& traj, int ticks, int lanes, std::int64_t budget,
                                     const FullSolveRun& reference, const std::atomic<bool>* cancel) {
  LiveValues with_tool = live;
  with_tool.tool = tool;
  haptics::RendererOptions options;
  options.work_budget = budget;
  options.deadline_us = 0.0;
  options.solver_lanes = lanes;
  std::unique_ptr<haptics::HapticRenderer> budgeted = makeRenderer(with_tool, options, traj.poseAt(0.0));
  const double s = with_tool.hapticIsovalue();
  int cut = 0;
  ProxyLag lag;
  std::size_t cursor = 0;
  for (int i = 0; i < ticks; ++i) {
    if (cancel != nullptr && cancel->load(std::memory_order_relaxed)) throw ToolFitCancelled();
    const haptics::Pose X_WD = traj.poseAt(i * 1e-3, cursor);
    const haptics::TickOutput out = budgeted->tick(X_WD, s);
    cut += out.stats.budget_cut ? 1 : 0;
    const haptics::Pose& X_WP_full = reference.X_WP[static_cast<std::size_t>(i)];
    if (out.X_WP.allFinite() && X_WP_full.allFinite()) lag.add(out.X_WP, X_WP_full, X_WD);
  }
  return {cut, lag};
}

/// This computer's cost model from the full solve's ticks: time = fixed + per_unit x work, fitted
/// by least squares (the fixed part: what a tick costs besides the work it counts, the coupling
/// and the bookkeeping). @return {fixed [us], per unit [ns]}; per unit from the totals when the
/// fit is degenerate (all ticks of about the same work).
std::pair<double, double> fitCostModel(const FullSolveRun& run) {
  const std::size_t n = run.work.size();
  double sw = 0.0, st = 0.0, sww = 0.0, swt = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    const double w = static_cast<double>(run.work[i]), t = run.time_us[i];
    sw += w;
    st += t;
    sww += w * w;
    swt += w * t;
  }
  const double dn = static_cast<double>(std::max<std::size_t>(n, 1));
  const double var = sww - sw * sw / dn;
  if (n >= 2 && var > 0.0) {
    const double slope_us = (swt - sw * st / dn) / var;
    const double fixed_us = (st - slope_us * sw) / dn;
    if (slope_us > 0.0 && fixed_us >= 0.0) return {fixed_us, 1e3 * slope_us};
    if (slope_us > 0.0) return {0.0, 1e3 * st / std::max(sw, 1.0)};
  }
  return {0.0, 1e3 * st / std::max(sw, 1.0)};
}

std::int64_t percentile(std::vector<std::int64_t> v, double q) {
  if (v.empty()) return 0;
  const auto k = static_cast<std::size_t>(std::clamp(q * static_cast<double>(v.size() - 1), 0.0,
                                                     static_cast<double>(v.size() - 1)));
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(k), v.end());
  return v[k];
}

/// How a run's cut ticks are judged against ToolFitOptions::max_cut_fraction (see there).
enum class Evidence {
  kLateBeyondChance,  ///< the tool as chosen: late only when its cuts are more than chance
  kCleanRun,          ///< a spacing to offer: cut no more than the fraction of its ticks
};

/// Judges `tool` at `spacing_m`: its warm-up's full solve `full`, and the same touch run again
/// with the work budget beside it.
ToolFitRun judge(const LiveValues& live, const std::shared_ptr<const haptics::ToolModel>& tool, double spacing_m,
                 const Trajectory& traj, const ToolFitOptions& options, int lanes, std::int64_t budget,
                 const FullSolveRun& full, Evidence evidence) {
  // Where no tick of the full solve reached the budget, the budgeted run is the full solve tick
  // for tick (the budget only ever stops a tick's work at it): nothing cut, nothing behind, and
  // the warm-up is not run a second time.
  const bool within = std::all_of(full.work.begin(), full.work.end(), [&](std::int64_t w) { return w < budget; });
  const auto [cut, lag] = within ? std::pair<int, ProxyLag>{0, ProxyLag{}}
                                 : runBudgeted(live, tool, traj, options.ticks, lanes, budget, full, options.cancel);
  ToolFitRun r;
  r.spacing_m = spacing_m;
  r.points = tool->point_shell.size();
  r.ticks = options.ticks;
  r.cut_ticks = cut;
  r.behind_max_m = std::max(0.0, lag.max_behind_m);
  r.behind_max_rad = std::max(0.0, lag.max_behind_rad);
  r.felt_gap_m = feltGap(*tool, live.tool_spec.edge_test).max_gap_m;
  r.work_max = full.work.empty() ? 0 : *std::max_element(full.work.begin(), full.work.end());
  r.work_p999 = percentile(full.work, 0.999);
  const bool few_cuts = evidence == Evidence::kLateBeyondChance
                            ? r.cut_ticks <= cutsWithinChance(r.ticks, options.max_cut_fraction)
                            : r.cutFraction() <= options.max_cut_fraction;
  r.fits = few_cuts && r.behind_max_m <= options.max_behind_m;
  return r;
}

std::string mm(double m) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.2f mm", 1e3 * m);
  return buf;
}

/// 20000 as "20,000".
std::string thousands(long long n) {
  const std::string digits = std::to_string(n < 0 ? -n : n);
  std::string s = n < 0 ? "-" : "";
  for (std::size_t i = 0; i < digits.size(); ++i) {
    if (i > 0 && (digits.size() - i) % 3 == 0) s += ',';
    s += digits[i];
  }
  return s;
}

std::string verdict(const ToolFitRun& r, const ToolFit& fit) {
  if (r.fits) {
    char buf[96];
    std::snprintf(buf, sizeof buf, "fits this computer (worst tick %.0f %% of the deadline)",
                  100.0 * fit.deadlineShare(r));
    return "felt within " + mm(r.felt_gap_m) + ", " + buf;
  }
  return thousands(r.cut_ticks) + " in " + thousands(r.ticks) + " ticks late, " + mm(r.behind_max_m) +
         " behind on this computer";
}

}  // namespace

int cutsWithinChance(int ticks, double fraction) {
  if (ticks <= 0 || !(fraction > 0.0)) return 0;
  if (fraction >= 1.0) return ticks;
  // P(X >= k) for X ~ Binomial(ticks, fraction), from P(X = 0) up; the largest k - 1 whose tail
  // P(X >= k) is still 5 % or more.
  const double q = 1.0 - fraction;
  double p_k = std::pow(q, ticks);  // P(X = 0)
  double tail = 1.0;                // P(X >= 0)
  for (int k = 0; k < ticks; ++k) {
    tail -= p_k;  // now P(X >= k + 1)
    if (tail < 0.05) return k;
    p_k *= static_cast<double>(ticks - k) / static_cast<double>(k + 1) * fraction / q;  // P(X = k + 1)
  }
  return ticks;
}

Trajectory fitWarmupTrajectory(const haptics::ScalarVolume& volume, const haptics::PointShell& shell,
                               double isovalue, const Eigen::Quaterniond& R_WT, int ticks) {
  if (ticks < 100) throw std::invalid_argument("the fit check's warm-up needs at least 100 ticks");
  const Eigen::Vector3d ez = Eigen::Vector3d::UnitZ(), ex = Eigen::Vector3d::UnitX(), ey = Eigen::Vector3d::UnitY();
  haptics::Pose start = poseAboveVolume(volume, shell, R_WT, 0.01);
  const double f = volume.featureSize_m();
  const haptics::VolumeGeometry& g = volume.geometry();
  Eigen::Vector3d extent;
  for (int a = 0; a < 3; ++a) extent[a] = g.spacing_m[a] * (g.dims[a] - 1);
  extent = (g.direction_W * extent).cwiseAbs();
  const Eigen::Vector3d centre = g.pointOf_W(Eigen::Vector3d((g.dims[0] - 1) * 0.5, (g.dims[1] - 1) * 0.5,
                                                             (g.dims[2] - 1) * 0.5));
  const std::optional<double> d = firstContactDistance(volume, shell, start, -ez, extent.z() + 0.2, isovalue, 0.25 * f);
  Eigen::Vector3d c = start.p_AB_m;
  c.z() = d ? c.z() - *d : centre.z();
  // Key durations [s] at bench table1's speeds (its hand: descents about 10 mm/s pressed,
  // slides about 15 mm/s, prying and wedging about 2 rad/s).
  struct Key {
    double dt;
    Eigen::Vector3d p;
    Eigen::Quaterniond R;
  };
  const Eigen::Vector3d pressed = c - 0.002 * ez;
  const Eigen::Vector3d slid = pressed + 0.003 * ex;
  const std::vector<Key> keys = {
      {0.0, c + 0.001 * ez, R_WT},
      {0.05, c - 0.001 * ez, R_WT},                              // onto the surface and 1 mm past it
      {0.1, pressed, R_WT},                                      // pressing
      {0.2, slid, R_WT},                                         // sliding
      {0.15, slid, aa(-0.3, ey) * R_WT},                         // prying
      {0.15, slid, R_WT},                                        // and back
      {0.2, slid - 0.002 * ez, aa(0.4, ez) * R_WT},              // wedging: pushed while twisting
  };
  double total = 0.0;
  for (const Key& k : keys) total += k.dt;
  const double scale = ((ticks - 1) * 1e-3) / total;  // the touch in `ticks` ticks
  std::vector<TrajectorySample> samples;
  double t = 0.0;
  for (const Key& k : keys) {
    t += k.dt * scale;
    samples.push_back({t, haptics::Pose{k.R, k.p}});
  }
  return Trajectory(std::move(samples));
}

ToolFit checkToolFit(const LiveValues& live, const ToolFitOptions& options) {
  if (!live.tool || !live.hapticField()) throw std::invalid_argument("the fit check needs a tool and a field");
  if (options.ticks < 100) throw std::invalid_argument("the fit check's warm-up needs at least 100 ticks");
  ToolFit fit;
  fit.deadline_us = options.deadline_us > 0.0 ? options.deadline_us : solverDeadline_us(1000.0);
  fit.lanes = options.lanes > 0 ? options.lanes : solverLanesFor(live.tool->point_shell.size());
  const double spacing_m = live.pointSpacing_m();
  const auto touch = [&](const haptics::ToolModel& tool) {
    return fitWarmupTrajectory(*live.hapticField(), tool.point_shell, live.hapticIsovalue(), live.X_WT_initial.R_AB,
                               options.ticks);
  };
  // The tool as chosen: its full solve calibrates the cost model, unless the cost is given.
  const auto t0 = Clock::now();
  const Trajectory traj = touch(*live.tool);
  const FullSolveRun full = runFullSolve(live, live.tool, traj, options.ticks, fit.lanes, options.cancel);
  double fixed_us = 0.0;
  if (options.ns_per_work > 0.0) {
    fit.ns_per_work = options.ns_per_work;
  } else {
    std::tie(fixed_us, fit.ns_per_work) = fitCostModel(full);
    fit.ns_per_work_measured = true;
  }
  fit.fixed_us = fixed_us;
  fit.work_budget = std::max<std::int64_t>(
      1, static_cast<std::int64_t>(1e3 * std::max(0.0, fit.deadline_us - fixed_us) / fit.ns_per_work));
  fit.asked = judge(live, live.tool, spacing_m, traj, options, fit.lanes, fit.work_budget, full,
                    Evidence::kLateBeyondChance);
  fit.full_solve_max_us = full.wall_max_us;
  fit.warmup_s = std::chrono::duration<double>(Clock::now() - t0).count();
  if (fit.asked.fits || live.tool->mesh_T.triangles.empty()) return fit;
  // Coarser spacings, finest first, until one fits (the cost model as calibrated).
  for (double factor : options.spacing_factors) {
    haptics::PointShellOptions shell;
    shell.spacing_m = spacing_m * factor;
    std::shared_ptr<const haptics::ToolModel> coarser;
    try {
      coarser = std::make_shared<const haptics::ToolModel>(haptics::makeToolModel(live.tool->mesh_T, shell));
    } catch (const std::invalid_argument&) {
      break;  // too coarse for the mesh
    }
    const int lanes = options.lanes > 0 ? options.lanes : solverLanesFor(coarser->point_shell.size());
    const Trajectory coarse_traj = touch(*coarser);
    const FullSolveRun coarse_full = runFullSolve(live, coarser, coarse_traj, options.ticks, lanes, options.cancel);
    ToolFitRun r = judge(live, coarser, shell.spacing_m, coarse_traj, options, lanes, fit.work_budget, coarse_full,
                         Evidence::kCleanRun);
    if (r.fits) {
      fit.suggested = r;
      break;
    }
    fit.tried.push_back(r);
  }
  return fit;
}

std::string ToolFit::summary() const {
  std::string s = "the tool at " + mm(asked.spacing_m) + " spacing (" + thousands(static_cast<long long>(asked.points)) +
                  " points): " + verdict(asked, *this);
  if (asked.fits) return s;
  if (suggested) {
    s += "; at " + mm(suggested->spacing_m) + " (" + thousands(static_cast<long long>(suggested->points)) +
         " points): " + verdict(*suggested, *this);
  } else {
    s += "; no coarser spacing tried fits";
  }
  return s;
}

std::string ToolFit::toJson() const {
  const auto optional = [&](auto value) { return suggested ? nlohmann::ordered_json(value) : nlohmann::ordered_json(); };
  const nlohmann::ordered_json j = {
      {"fits", fits()},
      {"summary", summary()},
      {"ns_per_work", ns_per_work},
      {"fixed_us", fixed_us},
      {"work_budget", work_budget},
      {"deadline_us", deadline_us},
      {"lanes", lanes},
      {"warmup_s", warmup_s},
      {"ticks", asked.ticks},
      {"cut_ticks", asked.cut_ticks},
      {"behind_max_m", asked.behind_max_m},
      {"work_max", asked.work_max},
      {"work_p999", asked.work_p999},
      {"spacing_m", asked.spacing_m},
      {"points", asked.points},
      {"felt_gap_m", asked.felt_gap_m},
      {"suggested_spacing_m", optional(suggested ? suggested->spacing_m : 0.0)},
      {"suggested_points", optional(suggested ? suggested->points : std::size_t{0})},
      {"suggested_felt_gap_m", optional(suggested ? suggested->felt_gap_m : 0.0)}};
  return j.dump();
}

}  // namespace vh::runtime
