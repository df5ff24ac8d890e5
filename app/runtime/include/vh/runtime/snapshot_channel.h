#pragma once
/// @file
/// A lock-free feed of the haptic threads' state to one consumer thread: the coupling thread
/// and the solver thread each publish whole values into a TripleBuffer (no lock, no allocation,
/// no exception: a copy and an atomic exchange), the consumer merges the latest of both into a
/// HapticSnapshot without blocking either side.
///
/// HapticThread feeds the GUI through one (HapticThread::latestSnapshot()); a second, optional
/// one (HapticThreadOptions::monitor, shared with the Session that builds the threads, so a
/// rebuilt thread keeps feeding it) serves another consumer at up to the servo rate, e.g. the
/// OpenIGTLink link (vh/igtl/igtl_link.h), independently of the GUI's reads.
///
/// Producers: at most one coupling thread and one solver thread at a time (a HapticThread's
/// two; the next HapticThread may publish once the previous one has stopped). Consumer: one
/// thread at a time.
///
/// Frames and units as in haptic_snapshot.h: W the scene (world) frame [m], forces [N] and
/// torques [N*m] in W on the user's hand.

#include <array>
#include <limits>
#include <cstdint>

#include <Eigen/Core>

#include "vh/haptics/pose.h"
#include "vh/runtime/haptic_snapshot.h"
#include "vh/runtime/thread_timing.h"
#include "vh/runtime/triple_buffer.h"

namespace vh::runtime {

/// What the coupling thread publishes after each of its ticks.
struct CouplingSnapshot {
  std::uint64_t tick = 0;          ///< Coupling ticks so far.
  std::int64_t time_ns = 0;        ///< CLOCK_MONOTONIC (std::chrono::steady_clock) time of the tick's start [ns].
  haptics::Pose X_WP;              ///< Proxy pose in W the coupling used.
  haptics::Pose X_WD;              ///< Device pose in W the coupling used.
  Eigen::Vector3d force_W_N = Eigen::Vector3d::Zero();    ///< Commanded force on the hand in W [N].
  Eigen::Vector3d torque_W_Nm = Eigen::Vector3d::Zero();  ///< Commanded torque on the hand in W [N*m].
  std::uint64_t bad_samples = 0;   ///< Device reads without a usable sample (total).
  /// Of those, samples SampleFilter rejected as implausible: a jump faster than the device
  /// moves, a pose outside its workspace, a non-finite pose (total).
  std::uint64_t implausible_samples = 0;
  std::uint64_t held_ticks = 0;    ///< Fault ticks that sent the held, decaying command (total).
  /// Passivity control (CouplingGains::passivity_control): port-ticks on which a controller
  /// damped (force and torque ports counted apart), and the energy it took out as predicted when
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
  ThreadTiming timing;             ///< The coupling thread's timing.
};

/// What the solver thread publishes after each of its ticks.
struct SolverSnapshot {
  std::uint64_t tick = 0;          ///< Solver ticks so far.
  double isovalue = 0.0;           ///< Isovalue of the tick (data units).
  int contacts = 0;                ///< Contact set size after the tick.
  int contacts_shown = 0;          ///< Entries filled in contact_p_W_m / contact_n_W.
  int segment = -1;                ///< Segment the contacts touch (SegmentSet::segmentOf()), or -1.
  int critical_segment = -1;       ///< HapticSnapshot::critical_segment and the one below.
  double critical_distance_m = std::numeric_limits<double>::infinity();
  bool drill = false;              ///< HapticSnapshot::drill and shaft_only.
  bool shaft_only = false;
  bool burr_on = false;            ///< HapticSnapshot::burr_on and the three below.
  double burr_force_N = 0.0;
  double burr_specific_energy_J_per_mm3 = 0.0;
  double burr_eroded_mm3 = 0.0;
  std::uint32_t technique = 0;     ///< HapticSnapshot::technique.
  std::array<Eigen::Vector3d, HapticSnapshot::kMaxContactsShown> contact_p_W_m{};  ///< Contact points in W [m].
  std::array<Eigen::Vector3d, HapticSnapshot::kMaxContactsShown> contact_n_W{};    ///< Unit normals in W.
  std::uint64_t rejected = 0;      ///< Device poses the renderer rejected (total).
  std::uint64_t skipped = 0;       ///< Device samples the solver never used (total).
  ThreadTiming timing;             ///< The solver thread's timing.
};

/// Merges the two threads' latest values into `out` (HapticSnapshot's fields).
void mergeSnapshots(const CouplingSnapshot& c, const SolverSnapshot& s, HapticSnapshot& out) noexcept;

/// Two triple buffers (coupling, solver) and the consumer's last values; see the file comment.
class SnapshotChannel {
 public:
  /// Coupling thread: the slot to fill, then publishCoupling().
  CouplingSnapshot& couplingSlot() noexcept { return coupling_.writeSlot(); }
  void publishCoupling() noexcept { coupling_.publish(); }
  /// Solver thread: the slot to fill, then publishSolver().
  SolverSnapshot& solverSlot() noexcept { return solver_.writeSlot(); }
  void publishSolver() noexcept { solver_.publish(); }

  /// Consumer: the latest of both threads merged into `out` (the previous values of a thread
  /// that published nothing new). Never blocks. @return true when either published since the
  /// last call.
  bool read(HapticSnapshot& out) noexcept {
    const bool fresh_coupling = coupling_.read(last_coupling_);
    const bool fresh_solver = solver_.read(last_solver_);
    mergeSnapshots(last_coupling_, last_solver_, out);
    return fresh_coupling || fresh_solver;
  }

 private:
  TripleBuffer<CouplingSnapshot> coupling_;
  TripleBuffer<SolverSnapshot> solver_;
  CouplingSnapshot last_coupling_;  ///< Consumer side.
  SolverSnapshot last_solver_;      ///< Consumer side.
};

}  // namespace vh::runtime
