// The solver thread's half of a servo tick (haptic_thread.cpp's solverLoop()): its state from
// tick to tick, the renderer's step with the jam test and the burr, the tick's record, the
// technique rules and the snapshot for the GUI. Private to vh::runtime; apart from
// haptic_thread.cpp so that each file keeps one job. Everything here runs on the solver thread:
// no allocation, no throw, no lock.
#pragma once

#include <algorithm>
#include <atomic>
#include <cstdint>
#include <span>

#include "vh/haptics/haptic_renderer.h"
#include "vh/tissue/deformable_scene.h"
#include "vh/runtime/burr_load.h"
#include "vh/runtime/critical_proximity.h"
#include "vh/runtime/drilling.h"
#include "vh/runtime/jam_detector.h"
#include "vh/runtime/placement.h"
#include "vh/runtime/recording.h"
#include "vh/runtime/sample_ring.h"
#include "vh/runtime/snapshot_channel.h"
#include "vh/runtime/technique.h"
#include "vh/runtime/tick_record.h"
#include "vh/runtime/triple_buffer.h"

namespace vh::runtime::detail {

/// A placement the coupling thread passed on (coupling -> solver): the solver resets its proxy
/// to X_WP before it solves sample number `sample` (or the first one after it that it uses).
struct PlacedSample {
  std::uint64_t count = 0;   ///< Placements passed on so far (this one included).
  std::uint64_t sample = 0;  ///< The number (SampleRing) of the first sample at the placed device pose.
  haptics::Pose X_WP;
};

/// The poses and wrench of a solver tick into its record: the device pose it ticked with
/// (X_WD), the proxy pose after it (X_WP) and the renderer's wrench.
inline void writeRecordPoses(TickRecord& rec, const haptics::Pose& X_WD, const haptics::Pose& X_WP,
                             const haptics::TickOutput& out) noexcept {
  for (int k = 0; k < 3; ++k) {
    rec.p_WD_m[k] = X_WD.p_AB_m[k];
    rec.p_WP_m[k] = X_WP.p_AB_m[k];
    rec.force_W_N[k] = out.force_W_N[k];
    rec.torque_W_Nm[k] = out.torque_W_Nm[k];
  }
  rec.q_WD[0] = X_WD.R_AB.w(); rec.q_WD[1] = X_WD.R_AB.x();
  rec.q_WD[2] = X_WD.R_AB.y(); rec.q_WD[3] = X_WD.R_AB.z();
  rec.q_WP[0] = X_WP.R_AB.w(); rec.q_WP[1] = X_WP.R_AB.x();
  rec.q_WP[2] = X_WP.R_AB.y(); rec.q_WP[3] = X_WP.R_AB.z();
}

/// A solver tick's own recording flags: contact, bad sample, non-finite wrench, device
/// disconnected, the segment touched.
inline std::uint32_t solverRecordFlags(std::uint32_t contacts, const CouplingSample& in, const haptics::TickOutput& out,
                                       int segment) noexcept {
  const bool nonfinite = !out.force_W_N.allFinite() || !out.torque_W_Nm.allFinite();
  return (contacts > 0 ? kRecordFlagContact : 0u) | (in.ok ? 0u : kRecordFlagBadSample) |
         (nonfinite ? kRecordFlagNonFinite : 0u) | (in.connected ? 0u : kRecordFlagDeviceDisconnected) |
         (in.ok && out.stats.deadline_cut ? kRecordFlagDeadlineCut : 0u) | recordSegmentBits(segment);
}
/// A solver tick's contacts into its snapshot: their number, the segment touched and the first
/// ones (at most HapticSnapshot::kMaxContactsShown).
inline void showContacts(SolverSnapshot& snap, std::span<const haptics::Contact> contacts, int segment) noexcept {
  snap.contacts = static_cast<int>(contacts.size());
  snap.segment = segment;
  const int shown = std::min<int>(snap.contacts, HapticSnapshot::kMaxContactsShown);
  snap.contacts_shown = shown;
  for (int i = 0; i < shown; ++i) {
    snap.contact_p_W_m[static_cast<std::size_t>(i)] = contacts[static_cast<std::size_t>(i)].p_W_m;
    snap.contact_n_W[static_cast<std::size_t>(i)] = contacts[static_cast<std::size_t>(i)].n_W;
  }
}
/// The solver thread's state from tick to tick (solverLoop()).
struct SolverState {
  std::uint64_t tick = 0;
  std::uint64_t rejected = 0;
  std::uint64_t skipped = 0;
  std::uint64_t record_first_tick = 0;         // tick of the current recording's first record
  RecordingWriter* active_recorder = nullptr;  // the recorder of the current recording
  std::uint64_t consumed = 0;                  // the latest sample number taken from the ring
  CouplingSample input, last_input;
  bool have_last = false;
  haptics::CouplingGains gains;   // the renderer's
  haptics::Pose X_WD_used;        // the latest pose the renderer ticked with
  std::uint64_t placements = 0;   // applied (PlacedSample::count)
  PlacedSample placed;            // the latest placement passed on
  std::uint32_t wake_flags = 0;   // deadline miss of this wake-up (first tick only)
  JamDetector jam;                // kRecordFlagJam
};

/// A placement the coupling thread passed on, once its sample has been taken: the proxy jumps
/// with the device. @return kRecordFlagPlacement then, else 0.
inline std::uint32_t applyPlacement(SolverState& st, TripleBuffer<PlacedSample>& placed,
                                    haptics::HapticRenderer& renderer,
                                    std::atomic<std::uint64_t>& placements_applied) noexcept {
  placed.read(st.placed);
  if (st.placed.count <= st.placements || st.consumed < st.placed.sample) return 0u;
  st.placements = st.placed.count;
  renderer.resetProxy(st.placed.X_WP);
  placements_applied.fetch_add(1, std::memory_order_acq_rel);
  return kRecordFlagPlacement;
}

/// What the renderer made of a solver tick's sample.
struct SolverTickResult {
  haptics::TickOutput out;
  bool bad_input = false;
  std::uint32_t drill_flags = 0;
  haptics::CutResult cut;  // the burr's, when it spun
  bool stuck = false;  // a jam candidate (jam_detector.h)
  bool shaft_only = false;  // with a drill: contacts, none on the burr (HapticSnapshot::shaft_only)
};

/// Renders a good sample `in` (after the tissue's step, when there is tissue), tests it for a jam
/// and cuts with the burr when the drill runs (`drilling`: the switch or the sample's button,
/// unless cutting is held).
inline void renderSolverSample(SolverState& st, const CouplingSample& in, haptics::HapticRenderer& renderer,
                               Drill* drill, const std::atomic<bool>& cutting_held, const std::atomic<bool>& drilling,
                               SolverTickResult& t, tissue::DeformableScene* tissue = nullptr) noexcept {
  st.X_WD_used = in.X_WD;
  const haptics::Pose X_WP_before = renderer.proxyPose();
  // Soft tissue yields to this sample first: the renderer then feels the deformed field.
  if (tissue != nullptr) (void)tissue->step(in.X_WD, renderer);
  t.out = renderer.tick(in.X_WD, in.isovalue);
  t.bad_input = t.out.stats.bad_input;
  if (t.bad_input) ++st.rejected;
  // The jam detector (jam_detector.h); the device's own freedom is tested only on candidates.
  const haptics::ToolModel& tool = renderer.tool();
  t.stuck = !t.bad_input &&
            JamDetector::candidate(X_WP_before, renderer.proxyPose(), in.X_WD, tool.mass.p_TCm_m,
                                   static_cast<int>(renderer.contacts().size())) &&
            countPointsInside(renderer.volume(), tool.point_shell, in.X_WD, renderer.feltIsovalue()) == 0;
  if (drill != nullptr) t.shaft_only = !t.bad_input && !renderer.contacts().empty() && !drill->burrTouches(renderer);
  // seq_cst with solver_ticks_: holdCutting()'s handshake (a tick that starts after the one it
  // waited for sees the hold).
  if (drill != nullptr && !cutting_held.load(std::memory_order_seq_cst) &&
      (drilling.load(std::memory_order_relaxed) || in.drill_button)) {
    t.cut = drill->step(renderer, t.out);
    t.drill_flags = kRecordFlagDrillOn;
  }
}

/// A solver tick's record (lock-free push; a full ring drops the record and counts it), its
/// times from the current recording's first tick.
inline void recordSolverTick(RecordingWriter& recorder, const SolverState& st, const CouplingSample& in,
                             const SolverTickResult& t, const haptics::Pose& X_WP, std::size_t contacts,
                             int segment, const CriticalDistance& nearest, double period_s, std::int64_t tick_ns,
                             std::uint32_t flags) noexcept {
  const haptics::TickOutput& out = t.out;
  TickRecord rec;
  rec.time_s = static_cast<double>(st.tick - st.record_first_tick) * period_s;
  rec.tick = st.tick;
  writeRecordPoses(rec, in.ok ? in.X_WD : st.X_WD_used, X_WP, out);
  rec.isovalue = in.isovalue;
  rec.tick_time_s = 1e-9 * static_cast<double>(tick_ns);
  rec.contacts = static_cast<std::uint32_t>(contacts);
  rec.flags = solverRecordFlags(rec.contacts, in, out, segment) | flags;
  rec.critical_distance_m = nearest.distance_m;
  rec.critical_segment = nearest.segment;
  rec.removed_voxels = static_cast<std::uint32_t>(std::max(0, t.cut.voxels_removed));
  rec.deadline_work = in.ok ? out.stats.deadline_work : 0;  // where a replay stops the tick
  (void)recorder.push(rec);
}

/// The burr of solver tick `t` into `snap` (HapticSnapshot::burr_on ..): on this thread, the only
/// one that cuts, the drill's eroded volume is read safely.
inline void showBurr(SolverSnapshot& snap, const SolverTickResult& t, const Drill* drill) noexcept {
  snap.burr_on = t.drill_flags != 0;
  snap.drill = drill != nullptr;
  snap.shaft_only = t.shaft_only;
  const BurrLoad load = burrLoadOf(t.cut, t.out);
  snap.burr_force_N = load.force_N;
  snap.burr_specific_energy_J_per_mm3 = load.specific_energy_J_per_mm3;
  snap.burr_eroded_mm3 = drill != nullptr ? drill->removal().erodedVolume_mm3() : 0.0;
}

/// The technique rules after solver tick `t` (technique.h), as record flags: evaluated on ticks
/// that rendered a usable sample; a tick that did not keeps the rules as they were.
inline std::uint32_t solverTechnique(ServoTechnique* technique, const SolverState& st, const CouplingSample& in,
                                     const SolverTickResult& t, std::span<const haptics::Contact> contacts, int segment,
                                     double nearest_critical_m, double period_s, bool placed) noexcept {
  if (technique == nullptr) return 0;
  if (!in.ok || t.bad_input) return recordTechniqueBits(technique->monitor().active());
  return recordTechniqueBits(technique->tick(static_cast<double>(st.tick) * period_s, in.X_WD, t.out.force_W_N.norm(),
                                             contacts, t.drill_flags != 0, t.cut.material, segment, nearest_critical_m,
                                             placed));
}

/// A solver tick's snapshot to the GUI and the optional monitor.
inline void publishSolverTick(SnapshotChannel& gui, SnapshotChannel* monitor, const SolverState& st, double isovalue,
                              std::span<const haptics::Contact> contacts, int segment, const CriticalDistance& nearest,
                              const ThreadTiming& timing, const SolverTickResult& t, const Drill* drill,
                              std::uint32_t technique_flags) noexcept {
  SolverSnapshot& snap = gui.solverSlot();
  snap.technique = recordTechnique(technique_flags);
  snap.tick = st.tick;
  snap.isovalue = isovalue;
  showContacts(snap, contacts, segment);
  snap.critical_segment = nearest.segment;
  snap.critical_distance_m = nearest.distance_m;
  showBurr(snap, t, drill);
  snap.rejected = st.rejected;
  snap.skipped = st.skipped;
  snap.timing = timing;
  if (monitor != nullptr) {
    monitor->solverSlot() = snap;
    monitor->publishSolver();
  }
  gui.publishSolver();
}

/// The samples waiting at this wake-up, each through `solve`: with `every_sample`, every sample
/// once, in order (skipping to the newest only when `backlog_limit` behind); else the newest, or
/// the last one again when nothing new arrived.
template <class Solve>
inline void solvePendingSamples(SolverState& st, const SampleRing& samples, bool every_sample,
                                std::uint64_t backlog_limit, Solve& solve) noexcept {
  const std::uint64_t latest = samples.latest();
  if (every_sample) {
    // Every sample once, in order; skip to the newest only when too far behind (or when the
    // coupling thread overwrote the next one, which the backlog limit prevents).
    while (st.consumed < latest) {
      std::uint64_t next = st.consumed + 1;
      if (latest - next >= backlog_limit) next = latest;
      if (!samples.read(next, st.input)) {
        next = samples.latest();
        if (!samples.read(next, st.input)) break;
      }
      st.skipped += next - st.consumed - 1;
      st.consumed = next;
      solve(st.input);
    }
    return;
  }
  // The newest sample; the last one again when nothing new arrived.
  if (latest > st.consumed && samples.read(latest, st.input)) {
    if (st.have_last) st.skipped += latest - st.consumed - 1;
    st.consumed = latest;
    st.last_input = st.input;
    st.have_last = true;
  }
  if (st.have_last) solve(st.last_input);
}

}  // namespace vh::runtime::detail
