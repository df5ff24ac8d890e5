#pragma once
/// @file
/// What the render thread (and any other consumer of a SnapshotChannel) sees of the haptic
/// threads of haptic_thread.h: one merged value, copied out without blocking them.
///
/// Frames and units: W the scene (world) frame [m]; D the device's tool frame; P the proxy's tool
/// frame; forces [N] and torques [N*m] in W on the user's hand about the tool's centre of mass;
/// times in microseconds, rates in Hz.

#include <array>
#include <cstdint>
#include <limits>

#include <Eigen/Core>

#include "vh/haptics/pose.h"
#include "vh/runtime/thread_timing.h"

namespace vh::runtime {

/// What the render thread sees of the haptic threads: the coupling thread's latest tick (poses,
/// force) and the solver thread's latest tick (contacts, isovalue). The force is exactly the one
/// commanded from X_WP and X_WD (after gains, ramp and safety layer); the contacts belong to the
/// solver tick that published X_WP or to a newer one.
struct HapticSnapshot {
  static constexpr int kMaxContactsShown = 64;
  std::uint64_t tick = 0;                 ///< Coupling (device) ticks so far; 0 before the first.
  std::uint64_t solver_tick = 0;          ///< Solver ticks so far (= TickRecord::tick while recording).
  /// CLOCK_MONOTONIC (std::chrono::steady_clock) time of the coupling tick's start [ns]; 0
  /// before the first.
  std::int64_t time_ns = 0;
  haptics::Pose X_WP;                     ///< Proxy pose in W the coupling used (the solver's latest).
  haptics::Pose X_WD;                     ///< Device pose in W the coupling used (the latest valid one).
  Eigen::Vector3d force_W_N = Eigen::Vector3d::Zero();    ///< Commanded force on the hand in W [N].
  Eigen::Vector3d torque_W_Nm = Eigen::Vector3d::Zero();  ///< Commanded torque on the hand in W [N*m].
  double isovalue = 0.0;                  ///< Isovalue of the solver's latest tick (data units).
  int contacts = 0;                       ///< Contact set size after the solver's latest tick.
  int contacts_shown = 0;                 ///< Entries filled in contact_p_W_m / contact_n_W.
  /// The segment the contacts touch (SegmentSet::segmentOf(), index into the scene's
  /// segments), or -1: no contact, no segments, or a contact on no felt segment.
  int segment = -1;
  /// The nearest critical segment to the proxy's point shell after the solver's latest tick
  /// (critical_proximity.h: index into the scene's segments; -1 when none is within
  /// kProximityRange_m or there are none) and its distance [m] (+infinity then). Compare it with
  /// SegmentSet::thresholds(critical_segment) for the warning and the alarm.
  int critical_segment = -1;
  double critical_distance_m = std::numeric_limits<double>::infinity();
  /// The burr on the solver's latest tick (drilling.h), what its sound follows: whether it spun,
  /// the |F| it cut with and the hardness of what it cut (haptics::CutResult; both 0 when it
  /// cut nothing), and the material the drill has eroded since it was built [mm^3] (its
  /// differences over time are the removal rate; a new drill starts again from 0).
  bool burr_on = false;
  double burr_force_N = 0.0;
  /// The scene's haptic threads have a drill; and on the solver's latest tick the tool touched
  /// with none of its contacts on the burr (Drill::burrTouches()): only the shaft or the handle
  /// touches, so the burr cannot cut however hard the hand presses.
  bool drill = false;
  bool shaft_only = false;
  double burr_specific_energy_J_per_mm3 = 0.0;
  double burr_eroded_mm3 = 0.0;
  /// The technique rules active after the solver's latest tick (technique.h: TechniqueRule
  /// bits; 0 without rules).
  std::uint32_t technique = 0;
  std::array<Eigen::Vector3d, kMaxContactsShown> contact_p_W_m{};  ///< Contact points in W [m].
  std::array<Eigen::Vector3d, kMaxContactsShown> contact_n_W{};    ///< Their unit surface normals in W.
  ThreadTiming coupling;                  ///< The coupling (device-rate) thread.
  ThreadTiming solver;                    ///< The solver (HapticRenderer::tick()) thread.
  /// Device reads without a usable sample plus device poses the renderer rejected (total).
  std::uint64_t bad_device_samples = 0;
  /// Of bad_device_samples: samples the coupling thread rejected before computing any force
  /// from them (SampleFilter: faster than the device moves, outside its workspace, not finite);
  /// never rendered, never handed to the solver (total).
  std::uint64_t implausible_samples = 0;
  /// Coupling ticks that held the last good command, decaying, through a short fault
  /// (SafetyPolicy::fault_hold_s; total).
  std::uint64_t held_ticks = 0;
  /// Device samples the solver never used: it runs slower than the device, or fell more than
  /// HapticThreadOptions::max_solver_backlog_s behind (total).
  std::uint64_t skipped_samples = 0;
  /// Passivity control (CouplingGains::passivity_control): port-ticks on which a controller
  /// damped (force and torque counted apart) and the energy it took out, as predicted when
  /// applied [J]; totals since start().
  std::uint64_t passivity_active_ticks = 0;
  double passivity_dissipated_J = 0.0;
  /// Guidance (HapticThread::setGuidance()): on, its force before the safety layer [N, W], and
  /// the expert's path's nearest point to the device (segment, s, position [m, W]).
  bool guidance_on = false;
  Eigen::Vector3d guidance_force_W_N = Eigen::Vector3d::Zero();
  std::int64_t guidance_segment = -1;
  double guidance_s = 0.0;
  Eigen::Vector3d guidance_nearest_W_m = Eigen::Vector3d::Zero();
};

}  // namespace vh::runtime
