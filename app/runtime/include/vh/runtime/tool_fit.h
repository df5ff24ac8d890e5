#pragma once
/// @file
/// Whether this computer renders a tool on a scene on time, and the finest point spacing that
/// does: the fit check. The live solver (servo_factory.h) stops a tick at its deadline (900 us at
/// 1 kHz) and goes on where it stopped on the next: a tool too fine for the computer is then late
/// (the proxy behind the hand, the wall soft) in the ticks that matter, a fast twist in contact.
/// The check measures it before the hand feels it.
///
/// The model: a tick's cost is its work (haptics::TickStats::critical_work, in units of one
/// trilinear sample, counted the same on every computer) times this computer's cost of a unit
/// [ns], which a warm-up measures. The warm-up is a scripted touch of the tool on the scene's felt
/// surface (down onto it over the volume's centre, pressed, slid, pried and twisted at the speeds
/// of `bench table1`'s hand; fitWarmupTrajectory()), run by the full solve (no budget, no
/// deadline: the reference) with the edge test as the application runs it. The deadline becomes
/// a work budget (deadline / cost of a unit); the same touch run again with that budget beside the
/// full solve gives the ticks it cuts and how far its proxy falls behind (runtime::ProxyLag), as
/// `bench table1` measures them. Given the cost of a unit (ToolFitOptions::ns_per_work), the
/// verdict is deterministic, which is how it is tested.

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "vh/haptics/pose.h"
#include "vh/haptics/scalar_volume.h"
#include "vh/runtime/scene.h"
#include "vh/runtime/trajectory.h"

namespace vh::runtime {

/// How the fit check runs and judges.
struct ToolFitOptions {
  /// Ticks of the warm-up touch (at 1 kHz); at least 100.
  int ticks = 700;
  /// The solver's deadline per tick [us]; 0: the application's, solverDeadline_us(1000) (900 us).
  double deadline_us = 0.0;
  /// The sweep's lanes; 0: the application's for the tool, solverLanesFor(its points).
  int lanes = 0;
  /// This computer's cost of one work unit [ns]; 0: measured by the warm-up's full solve, a
  /// least-squares line through its ticks' thread CPU time (wall time on several lanes) against
  /// their work on the critical path (ToolFit::fixed_us its intercept).
  double ns_per_work = 0.0;
  /// Most ticks cut, as a fraction of the warm-up's (0.1 %). The tool as chosen is late only
  /// when its warm-up cut more ticks than a tool cut this fraction of the time would by chance
  /// (cutsWithinChance(): 3 or more of 700 at 0.1 %; one cut tick in 700 says nothing about a rate
  /// of 1 in 1,000); a coarser spacing is offered only when its warm-up cut no more than this
  /// fraction of its ticks (none of 700).
  double max_cut_fraction = 0.001;
  /// Most the budgeted proxy may fall behind the full solve's [m] (0.5 mm).
  double max_behind_m = 0.0005;
  /// When the tool does not fit: coarser spacings tried, as factors of its own, finest first.
  std::vector<double> spacing_factors = {1.25, 1.5, 2.0, 2.5, 3.0, 4.0, 6.0, 8.0};
  /// When set and it becomes true, the check stops within a tick and throws ToolFitCancelled
  /// (the window's check of a tool no longer chosen, or of a window closing).
  const std::atomic<bool>* cancel = nullptr;
};

/// The most ticks of `ticks` a tool cut `fraction` of the time (0..1) is cut by chance at the
/// 5 % level: the largest k with P(X >= k) >= 0.05 for X ~ Binomial(ticks, fraction) (a one-sided
/// test: more cuts than this say the tool is cut more often). 2 for 700 ticks at 0.001, 9 for
/// 5,000; 0 for no ticks or a fraction <= 0.
int cutsWithinChance(int ticks, double fraction);

/// checkToolFit() was stopped through ToolFitOptions::cancel.
class ToolFitCancelled : public std::runtime_error {
 public:
  ToolFitCancelled() : std::runtime_error("the fit check was cancelled") {}
};

/// One point spacing of the tool, judged.
struct ToolFitRun {
  double spacing_m = 0.0;       ///< Point shell spacing [m].
  std::size_t points = 0;       ///< Shell points.
  int ticks = 0;                ///< Warm-up ticks run.
  int cut_ticks = 0;            ///< Ticks the deadline's work budget would cut.
  double behind_max_m = 0.0;    ///< Most the budgeted proxy was behind the full solve's [m].
  double behind_max_rad = 0.0;  ///< Same in rotation [rad].
  /// How closely the tool's mesh is felt [m]: feltGap() (tool_fidelity.h), the largest distance
  /// from the mesh to its points (joined by their edges with the edge test on).
  double felt_gap_m = 0.0;
  std::int64_t work_max = 0;    ///< The full solve's most work in a tick [units].
  std::int64_t work_p999 = 0;   ///< Its 99.9th percentile [units].
  bool fits = false;            ///< cut_ticks and behind_max_m within ToolFitOptions (see max_cut_fraction).

  /// cut_ticks / ticks.
  double cutFraction() const noexcept { return ticks > 0 ? static_cast<double>(cut_ticks) / ticks : 0.0; }
};

/// What the fit check found.
struct ToolFit {
  double ns_per_work = 0.0;      ///< The cost of a work unit used [ns].
  /// What a tick costs besides its work [us] (the coupling, the bookkeeping), fitted with
  /// ns_per_work by least squares over the warm-up's ticks; 0 when the cost was given.
  double fixed_us = 0.0;
  bool ns_per_work_measured = false;  ///< Measured by this warm-up (else given).
  double deadline_us = 0.0;      ///< The deadline judged against [us].
  int lanes = 1;                 ///< The sweep's lanes.
  std::int64_t work_budget = 0;  ///< The deadline as work: (deadline_us - fixed_us) / ns_per_work [units].
  double warmup_s = 0.0;         ///< Wall time of the asked tool's warm-up [s].
  double full_solve_max_us = 0.0;  ///< The warm-up's slowest full-solve tick (wall) [us].
  ToolFitRun asked;              ///< The tool as chosen.
  /// When the chosen tool does not fit: the finest of the coarser spacings tried that fits (empty
  /// when none does, or the tool fits).
  std::optional<ToolFitRun> suggested;
  /// The spacings tried that did not fit either, finest first (for the message).
  std::vector<ToolFitRun> tried;

  bool fits() const noexcept { return asked.fits; }
  /// The warm-up's heaviest tick of `run` as a share of the deadline (its work over work_budget).
  double deadlineShare(const ToolFitRun& run) const noexcept {
    return static_cast<double>(run.work_max) / static_cast<double>(work_budget > 0 ? work_budget : 1);
  }
  /// One line for people, e.g. "the tool at 0.45 mm spacing (20,000 points): 412 in 1,000
  /// ticks late, 3.1 mm behind on this computer; at 0.90 mm (5,030 points): felt within 0.61 mm,
  /// fits this computer", or "... fits this computer (worst tick 61 % of the deadline)".
  std::string summary() const;
  /// The verdict as a JSON object (the one list of its fields, for the run report, bench table1
  /// and Python): fits, summary, ns_per_work, fixed_us, work_budget, deadline_us, lanes,
  /// warmup_s, ticks, cut_ticks, behind_max_m, work_max, work_p999, spacing_m, points, felt_gap_m, and
  /// suggested_spacing_m, suggested_points, suggested_felt_gap_m (null when none).
  std::string toJson() const;
};

/// The warm-up touch of `shell` on the isosurface F = `isovalue` of `volume`, `ticks` samples at
/// 1 kHz with the tool held at orientation R_WT: from 1 mm above the first contact over the
/// volume's centre (cast down along -z of W), 1 mm past it, pressed to 2 mm, slid 3 mm in x,
/// pried -0.3 rad about y and back, then pushed 2 mm more while twisting 0.4 rad about z, at the
/// speeds of bench table1's hand (its prying and wedging the fastest turns: about 2 rad/s).
/// When the ray meets nothing, the touch starts at the volume's mid height.
/// @throws std::invalid_argument for ticks < 100.
Trajectory fitWarmupTrajectory(const haptics::ScalarVolume& volume, const haptics::PointShell& shell,
                               double isovalue, const Eigen::Quaterniond& R_WT, int ticks);

/// The fit check of live's tool on live's felt surface (its gains, its edge test setting), off
/// the servo thread (it runs solvers of its own: a second or so for a 20,000-point tool).
/// @throws std::invalid_argument without a tool or a field, or for ticks < 100; ToolFitCancelled
///         when options.cancel became true.
ToolFit checkToolFit(const LiveValues& live, const ToolFitOptions& options = {});

}  // namespace vh::runtime
