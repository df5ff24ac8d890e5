// The fit check (tool_fit.h): a warm-up touch run by the full solve and by the deadline's work
// budget beside it, for the tool as chosen and, when it does not fit, for coarser spacings.
#include "vh/runtime/tool_fit.h"

#include <time.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <memory>
#include <stdexcept>

#include "vh/haptics/haptic_renderer.h"
#include "vh/runtime/placement.h"
#include "vh/runtime/runner.h"
#include "vh/runtime/servo_factory.h"
#include "vh/runtime/tool_fidelity.h"

namespace vh::runtime {
namespace {

using Clock = std::chrono::steady_clock;

double threadCpu_us() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return 1e6 * static_cast<double>(ts.tv_sec) + 1e-3 * static_cast<double>(ts.tv_nsec);
}

Eigen::Quaterniond aa(double angle_rad, const Eigen::Vector3d& axis) {
  return Eigen::Quaterniond(Eigen::AngleAxisd(angle_rad, axis));
}

/// What one run of the warm-up measured.
struct WarmupRun {
  std::vector<std::int64_t> work;  ///< The full solve's critical work per tick [units].
  double cpu_us = 0.0, wall_us = 0.0, wall_max_us = 0.0;  ///< The full solve's totals and slowest tick.
  std::int64_t work_sum = 0;
  int cut_ticks = 0;  ///< The budgeted run's ticks cut.
  ProxyLag lag;       ///< The budgeted proxy against the full solve's.
  bool budgeted = false;
};

/// The warm-up of `tool`: the full solve over `traj`; with `budget` > 0 the budgeted solver
/// beside it, tick by tick, on the same device samples.
WarmupRun runWarmup(const LiveValues& live, const std::shared_ptr<const haptics::ToolModel>& tool,
                    const Trajectory& traj, int ticks, int lanes, std::int64_t budget) {
  LiveValues with_tool = live;
  with_tool.tool = tool;
  haptics::RendererOptions full_options;
  full_options.work_budget = 0;
  full_options.deadline_us = 0.0;
  full_options.solver_lanes = lanes;
  const haptics::Pose X_WD0 = traj.poseAt(0.0);
  std::unique_ptr<haptics::HapticRenderer> full = makeRenderer(with_tool, full_options, X_WD0);
  std::unique_ptr<haptics::HapticRenderer> budgeted;
  if (budget > 0) {
    haptics::RendererOptions budget_options = full_options;
    budget_options.work_budget = budget;
    budgeted = makeRenderer(with_tool, budget_options, X_WD0);
  }
  const double s = with_tool.hapticIsovalue();
  WarmupRun run;
  run.budgeted = budgeted != nullptr;
  run.work.reserve(static_cast<std::size_t>(ticks));
  std::size_t cursor = 0;
  for (int i = 0; i < ticks; ++i) {
    const haptics::Pose X_WD = traj.poseAt(i * 1e-3, cursor);
    const double c0 = threadCpu_us();
    const auto w0 = Clock::now();
    const haptics::TickOutput out = full->tick(X_WD, s);
    const double wall = std::chrono::duration<double, std::micro>(Clock::now() - w0).count();
    run.cpu_us += threadCpu_us() - c0;
    run.wall_us += wall;
    run.wall_max_us = std::max(run.wall_max_us, wall);
    run.work.push_back(out.stats.critical_work);
    run.work_sum += out.stats.critical_work;
    if (budgeted) {
      const haptics::TickOutput b = budgeted->tick(X_WD, s);
      run.cut_ticks += b.stats.budget_cut ? 1 : 0;
      if (b.X_WP.allFinite() && out.X_WP.allFinite()) run.lag.add(budgeted->proxyPose(), full->proxyPose(), X_WD);
    }
  }
  return run;
}

std::int64_t percentile(std::vector<std::int64_t> v, double q) {
  if (v.empty()) return 0;
  const auto k = static_cast<std::size_t>(std::clamp(q * static_cast<double>(v.size() - 1), 0.0,
                                                     static_cast<double>(v.size() - 1)));
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(k), v.end());
  return v[k];
}

/// Judges `tool` at `spacing_m`: its warm-up's full solve and budgeted run.
ToolFitRun judge(const LiveValues& live, const std::shared_ptr<const haptics::ToolModel>& tool, double spacing_m,
                 const ToolFitOptions& options, int lanes, std::int64_t budget, WarmupRun* kept = nullptr) {
  const Trajectory traj = fitWarmupTrajectory(*live.hapticField(), tool->point_shell, live.hapticIsovalue(),
                                              live.X_WT_initial.R_AB, options.ticks);
  WarmupRun run = runWarmup(live, tool, traj, options.ticks, lanes, budget);
  ToolFitRun r;
  r.spacing_m = spacing_m;
  r.points = tool->point_shell.size();
  r.ticks = options.ticks;
  r.cut_ticks = run.cut_ticks;
  r.behind_max_m = std::max(0.0, run.lag.max_behind_m);
  r.behind_max_rad = std::max(0.0, run.lag.max_behind_rad);
  r.felt_gap_m = feltGap(*tool, live.tool_spec.edge_test).max_gap_m;
  r.work_max = run.work.empty() ? 0 : *std::max_element(run.work.begin(), run.work.end());
  r.work_p999 = percentile(run.work, 0.999);
  r.fits = r.cutFraction() <= options.max_cut_fraction && r.behind_max_m <= options.max_behind_m;
  if (kept != nullptr) *kept = std::move(run);
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
                  100.0 * static_cast<double>(r.work_max) / static_cast<double>(std::max<std::int64_t>(1, fit.work_budget)));
    return "felt within " + mm(r.felt_gap_m) + ", " + buf;
  }
  return thousands(r.cut_ticks) + " in " + thousands(r.ticks) + " ticks late, " + mm(r.behind_max_m) +
         " behind on this computer";
}

}  // namespace

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
  // The tool as chosen: the full solve alone first when the cost of a unit is to be measured.
  const auto t0 = Clock::now();
  if (options.ns_per_work > 0.0) {
    fit.ns_per_work = options.ns_per_work;
  } else {
    WarmupRun calibration;
    const Trajectory traj = fitWarmupTrajectory(*live.hapticField(), live.tool->point_shell, live.hapticIsovalue(),
                                                live.X_WT_initial.R_AB, options.ticks);
    calibration = runWarmup(live, live.tool, traj, options.ticks, fit.lanes, 0);
    const double time_us = fit.lanes > 1 ? calibration.wall_us : calibration.cpu_us;
    fit.ns_per_work = 1e3 * time_us / static_cast<double>(std::max<std::int64_t>(1, calibration.work_sum));
    fit.ns_per_work_measured = true;
  }
  fit.work_budget = std::max<std::int64_t>(1, static_cast<std::int64_t>(1e3 * fit.deadline_us / fit.ns_per_work));
  WarmupRun asked_run;
  fit.asked = judge(live, live.tool, spacing_m, options, fit.lanes, fit.work_budget, &asked_run);
  fit.full_solve_max_us = asked_run.wall_max_us;
  fit.warmup_s = std::chrono::duration<double>(Clock::now() - t0).count();
  if (fit.asked.fits || live.tool->mesh_T.triangles.empty()) return fit;
  // Coarser spacings, finest first, until one fits.
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
    ToolFitRun r = judge(live, coarser, shell.spacing_m, options, lanes, fit.work_budget);
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

}  // namespace vh::runtime
