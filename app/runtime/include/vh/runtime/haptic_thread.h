#pragma once
/// @file
/// The embedded haptic loop, split over two real-time threads (paper section 3.2: the
/// configuration solver "cannot be guaranteed to terminate within the allotted time", so the
/// virtual coupling runs on a thread of its own):
///
///   * the **coupling thread**, at the device's rate (`servo_rate_Hz`, 1 kHz by default; e.g.
///     4 kHz): reads the device and tests the sample (SampleFilter: a glitch faster than the
///     device moves, outside its workspace or not finite is no sample: never coupled to, never
///     handed to the solver), applies the GUI's gains (clamped to the device's stable
///     stiffness) and isovalue, hands the sample to the solver, takes the latest proxy pose the
///     solver published, computes the wrench with its own haptics::VirtualCoupling (eq. 5, the
///     same code and gains as the renderer's step 6), applies the stop ramp (~50 ms) and the
///     safety layer (ForceSafety: a tick without a usable sample holds the last good command,
///     decaying over SafetyPolicy::fault_hold_s) and commands the device. It never waits for the solver: when
///     the solver is late the coupling keeps rendering the spring to the last proxy pose.
///   * the **solver thread**, at the solver rate (HapticThreadOptions::solver_rate_Hz; by
///     default the device's), runs HapticRenderer::tick() (steps 1-6 of section 2.1) on the
///     device samples, publishes the proxy pose for the coupling thread, the contacts and its
///     statistics for the GUI, and writes the recording (one TickRecord per solver tick).
///
/// Which samples the solver uses (SolverInput): at equal rates (the default) it uses every
/// device sample once, in order (catching up after a late wake-up, and skipping to the newest
/// only when it falls more than HapticThreadOptions::max_solver_backlog_s behind), so a session
/// recorded from a scripted device is the same whatever the scheduling; a slower solver uses the
/// newest sample at each of its ticks (the samples in between are counted as skipped, and the
/// recording holds the samples the solver used).
///
/// Lock-free exchange, no mutex, no allocation, no exception in either loop:
///   coupling -> solver: a ring of the last device samples (SampleRing, sample_ring.h), each
///                       with the isovalue and the applied gains read on the same coupling tick;
///   solver -> coupling: the proxy pose X_WP (TripleBuffer);
///   both -> GUI:        one TripleBuffer each (SnapshotChannel), merged by latestSnapshot()
///                       into a HapticSnapshot (haptic_snapshot.h);
///   both -> monitor:    optionally the same again into a second SnapshotChannel
///                       (HapticThreadOptions::monitor) for another consumer, e.g. OpenIGTLink;
///   GUI -> coupling:    gains and isovalue in atomics, applied at the coupling thread's next tick;
///   flags:              atomics (the coupling thread's force-limited / zeroed / stopping / deadline
///                       miss bits, read by the solver into its TickRecord).
///
/// Each thread sets itself up for real time (SCHED_FIFO, the memory lock) and wakes on an
/// absolute-deadline clock: realtime.h.
///
/// Frames and units: W the scene (world) frame [m]; D the device's tool frame; P the proxy's tool
/// frame; forces [N] and torques [N*m] in W on the user's hand about the tool's centre of mass;
/// times in the snapshot in microseconds, rates in Hz.

#include <array>
#include <atomic>
#include <cstdint>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include <Eigen/Core>

#include "vh/haptics/haptic_renderer.h"
#include "vh/runtime/device.h"
#include "vh/runtime/drilling.h"
#include "vh/runtime/guidance.h"
#include "vh/runtime/haptic_snapshot.h"
#include "vh/runtime/realtime.h"
#include "vh/runtime/segments.h"
#include "vh/runtime/technique.h"
#include "vh/runtime/recording.h"
#include "vh/runtime/thread_timing.h"
#include "vh/runtime/triple_buffer.h"

namespace vh::tissue {
class DeformableScene;
}

namespace vh::runtime {

class SnapshotChannel;  // snapshot_channel.h

/// Which device samples the solver thread uses.
enum class SolverInput {
  kAuto,        ///< kEverySample when the solver and device rates are equal, else kLatest.
  kEverySample, ///< Every sample once, in order (deterministic); only at the device's rate.
  kLatest,      ///< The newest sample at each solver tick (the last one again when none is new).
};

/// Settings of HapticThread beyond the device rate. The defaults reproduce the single-rate loop:
/// a 1 kHz solver using every 1 kHz device sample.
struct HapticThreadOptions {
  /// Rate of the solver thread [Hz]; 0 = the device (servo) rate.
  double solver_rate_Hz = 0.0;
  SolverInput solver_input = SolverInput::kAuto;
  /// kEverySample: when the solver is this far behind the device [s], it skips to the newest
  /// sample instead of catching up (bounds the proxy's lag; the skipped samples are counted).
  double max_solver_backlog_s = 0.25;
  /// The scene's segments: each solver tick names the segment its contacts touch
  /// (HapticSnapshot::segment, and TickRecord::flags >> kRecordSegmentShift) and measures the
  /// nearest critical segment (HapticSnapshot::critical_segment / critical_distance_m, and
  /// TickRecord::critical_segment / critical_distance_m). Null: none.
  std::shared_ptr<const SegmentSet> segments;
  /// Test only: called on the solver thread at the end of every solver tick (e.g. to make the
  /// solver slow). Must not throw; it may allocate or sleep (the loop's guarantees then no
  /// longer hold for the solver).
  void (*solver_tick_hook)(void* context) = nullptr;
  void* solver_tick_hook_context = nullptr;
  /// When set, both threads also publish every tick into this channel (one copy into a triple
  /// buffer each; no lock, no allocation), for a consumer other than the GUI (e.g. the
  /// OpenIGTLink link) at up to the servo rate. Shared: it outlives the threads; a thread
  /// rebuilt with the same options keeps feeding it. Only one HapticThread may feed a channel
  /// at a time (the next one once the previous one stopped).
  std::shared_ptr<SnapshotChannel> monitor;
  /// Drilling (drilling.h): the burr and the removal that carves the renderer's own field (the
  /// same object the renderer holds: makeServoRenderer()). While setDrilling(true), every solver
  /// tick with a usable sample runs Drill::step() after the renderer's tick, on the solver
  /// thread (no allocation, no lock), and its record carries kRecordFlagDrillOn. Null: no drill.
  std::shared_ptr<Drill> drill;
  /// Soft tissue (tissue_scene.h): the deformable scene whose field the renderer feels (the same
  /// object makeServoRenderer() built it on). Every solver tick with a usable sample runs its
  /// step() before the renderer's tick, on the solver thread (no allocation, no lock). Null: none.
  /// Given to makeHapticThread(): a scene of earlier, stopped threads to reuse (makeServoRenderer()'s
  /// `reuse`); it sets the one the threads step.
  std::shared_ptr<tissue::DeformableScene> tissue;
  /// The technique rules (technique.h), evaluated by the solver thread after every tick with a
  /// usable sample (and the drill's cut); their active bits go into the record's flags
  /// (recordTechniqueBits()) and the GUI's snapshot. Null: no rules. Shared only to keep the
  /// options copyable; only the solver thread touches it.
  std::shared_ptr<ServoTechnique> technique;
};

/// Runs the coupling and the solver threads (see the file comment).
class HapticThread {
 public:
  /// @param renderer takes ownership; @param device read and commanded by the coupling thread;
  /// @param servo_rate_Hz the coupling thread's (device) rate.
  /// @throws std::invalid_argument for a missing renderer or device, a rate that is not a
  ///         positive number, or kEverySample with a solver rate other than the device's.
  HapticThread(std::unique_ptr<haptics::HapticRenderer> renderer, std::shared_ptr<Device> device,
               double isovalue, double servo_rate_Hz = 1000.0, const HapticThreadOptions& options = {});
  ~HapticThread();  ///< Stops the threads (force ramped to zero).
  HapticThread(const HapticThread&) = delete;
  HapticThread& operator=(const HapticThread&) = delete;

  void start();
  /// Ramps the force to zero over ~50 ms, then joins both threads.
  void stop();
  bool running() const noexcept { return running_.load(std::memory_order_acquire); }
  /// After the threads started: whether both got SCHED_FIFO (coupling priority 80, solver 79;
  /// else SCHED_OTHER with a 1 ns timer slack) and whether the process's memory is locked for
  /// the coupling thread (mlockall, shared with other users: MemoryLockHold).
  bool realtimeScheduling() const noexcept;
  bool memoryLocked() const noexcept { return memory_locked_.load(std::memory_order_acquire); }
  /// The coupling thread's (device) rate [Hz].
  double servoRate_Hz() const noexcept { return 1.0 / period_s_; }
  /// The solver thread's rate [Hz] (TickRecord::time_s counts its periods).
  double solverRate_Hz() const noexcept { return 1.0 / solver_period_s_; }
  /// Whether the solver uses every device sample (SolverInput resolved).
  bool solverUsesEverySample() const noexcept { return every_sample_; }

  /// Applied at the coupling thread's next tick; it reaches the solver with that tick's sample.
  void setIsovalue(double isovalue) noexcept { isovalue_.store(isovalue, std::memory_order_relaxed); }
  double isovalue() const noexcept { return isovalue_.load(std::memory_order_relaxed); }
  /// Applied at the coupling thread's next tick (clamped to the device's stable stiffness), and
  /// by the solver (its metric) with that tick's sample. While recording, also records a "gains"
  /// event with the clamped (applied) gains
  /// {"linear_N_per_m": k, "angular_Nm_per_rad": k_r, "passivity_control": b, "requested": {...}}.
  /// With passivity_control on, the coupling thread runs a time-domain passivity controller
  /// (haptics/passivity_controller.h) on its force and on its torque, after the coupling and
  /// before the stop ramp and the safety layer; a gain change keeps the controllers' state and
  /// the rendered stiffness continuous (PassivityPort). Not on a haptic thread.
  void setGains(const haptics::CouplingGains& gains) noexcept;

  /// Haptic guidance (guidance.h) toward `expert`'s path with `gains` (clampGuidance() to the
  /// device's limits), from the coupling thread's next tick; null turns it off. The coupling
  /// thread adds the force to the coupling's after its passivity controller and before the stop
  /// ramp and the safety layer; the snapshot shows it and the nearest point. While recording,
  /// also records a "guidance" event (guidance.h; {"off": true} when turned off). GUI thread;
  /// every path handed over is kept until the thread is destroyed (the coupling thread may
  /// still read one after it was replaced).
  void setGuidance(std::shared_ptr<const ExpertPath> expert, const haptics::GuidanceGains& gains);
  /// The path set last (GUI thread), or null.
  const std::shared_ptr<const ExpertPath>& guidance() const noexcept { return guide_; }

  /// The device button that spins the burr while held (bit 0 of DeviceSample::buttons: a Falcon's
  /// or a Touch's first button, a SpaceMouse's left key), as a surgeon's foot pedal does.
  static constexpr unsigned kDrillButton = 1u;
  /// Starts or stops the burr (a key, the Haptics menu); applied at the solver's next tick. The
  /// burr also spins while the device's kDrillButton is held (recorded per tick like this
  /// switch). A no-op without HapticThreadOptions::drill. Any thread.
  void setDrilling(bool on) noexcept { drilling_.store(on, std::memory_order_relaxed); }
  bool drilling() const noexcept { return options_.drill != nullptr && drilling_.load(std::memory_order_relaxed); }
  /// Holds the burr's removal from the solver's next tick on, whatever turns the burr (setDrilling(),
  /// the device's button), while the force goes on; releaseCutting() ends the hold. Returns once
  /// no removal can run any more: the drill's field is then written by no thread until released,
  /// so it may be read (cavityOf()) while the threads run, which is how a recording restarts the
  /// threads on a drilled field without first letting the force go (Session::prepareRecording()).
  /// Blocks the calling thread (never a haptic thread) for at most one solver tick, or
  /// `timeout_ms` [ms]. Ticks of the hold record no kRecordFlagDrillOn.
  /// @return true when held (also before start() and after stop(): nothing cuts); false without a
  ///         drill, or when the solver did not finish a tick within `timeout_ms` (threads that
  ///         ended by themselves, a stalled solver); then nothing is held.
  bool holdCutting(double timeout_ms = 100.0);
  void releaseCutting() noexcept { cutting_held_.store(false, std::memory_order_seq_cst); }
  bool cuttingHeld() const noexcept { return cutting_held_.load(std::memory_order_relaxed); }
  /// The drill (HapticThreadOptions::drill), or null. Its removal log (MaterialRemoval::
  /// drainRemoved()) has one consumer: the picture.
  const std::shared_ptr<Drill>& drill() const noexcept { return options_.drill; }
  /// The soft tissue (HapticThreadOptions::tissue), or null. Its deformed window
  /// (DeformableScene::takeDeformedWindow()) has one consumer: the picture.
  const std::shared_ptr<tissue::DeformableScene>& tissue() const noexcept { return options_.tissue; }

  /// New segment choices that leave the felt surface as it is (a segmentation opened to be
  /// seen, other segments shown or critical, other warning distances): from one solver tick on,
  /// the segment each tick touches and the nearest critical segment are measured on `segments`,
  /// and `technique` replaces the technique rules (their timers start afresh). The running
  /// threads go on between two ticks: the force is not interrupted (no stop, no ramp, no new
  /// thread), which a restart of the threads would do. Before start() or after stop(): at once.
  /// GUI thread; the solver takes the new parts at its next wake-up, allocating and freeing
  /// nothing (this thread builds them and frees the old ones). Blocks for about one solver
  /// period, at most `timeout_ms` [ms].
  /// @return false (nothing changes) with a drill (its materials follow the segments), while
  ///         recording (a recording's segments are its scene's), or when the solver took no new
  ///         parts within `timeout_ms` (threads that ended by themselves, a stalled solver);
  ///         the caller then restarts the threads.
  /// @throws std::bad_alloc (nothing changes).
  bool replaceSegments(std::shared_ptr<const SegmentSet> segments, std::shared_ptr<ServoTechnique> technique,
                       double timeout_ms = 100.0);

  /// Records every solver tick from the next one on into `recorder` (one TickRecord per solver
  /// tick, pushed without blocking or allocating; a full ring drops the record and the recorder
  /// counts it). Not owned: it must outlive the recording. Set it before start(), or clear it
  /// (nullptr) and only destroy the recorder after stop(): the solver thread may be inside
  /// push() otherwise.
  /// TickRecord: time_s counts solver periods (tick * period) from the recording's first tick (a
  /// new recorder, or the same one set again after nullptr, starts a new clock); the device pose
  /// is the sample the solver used on that tick, the proxy pose the one it produced, and the
  /// force / torque the virtual coupling's for exactly these two poses (the renderer's step 6,
  /// with the applied gains: what the coupling thread commands for this pair before its ramp
  /// and safety layer; the coupling thread's commands, computed from newer device poses, are in
  /// the snapshot). So a recording replays bit for bit (replay.h). Flags: kRecordFlagBadSample
  /// for a sample without a usable pose, kRecordFlagDeviceDisconnected while
  /// Device::connected() was false at that sample, kRecordFlagDeadlineMiss when either thread
  /// missed a deadline since the previous record, and kRecordFlagForceLimited / ForceZeroed /
  /// Stopping / NonFinite from the coupling thread's latest command.
  void setRecorder(RecordingWriter* recorder) noexcept { recorder_.store(recorder, std::memory_order_release); }

  /// A placement (Touch the Surface, Home, Reset Device): the proxy goes to `X_WP` and the
  /// simulated device to `X_WD` [m, W] together, between two ticks, so the coupling renders no
  /// spring stretched over the jump: the first tick with the device at `X_WD` starts from the
  /// proxy at `X_WP` (the solver resets it there: HapticRenderer::resetProxy(); the coupling
  /// thread couples to `X_WP` until the solver has), and the force is the spring between the
  /// two poses (at rest on a surface: the resting force). `X_WP` should be free (no shell point
  /// inside the felt surface). While recording: a "placement" event {"X_WP": [x, y, z, qw, qx,
  /// qy, qz], "X_WD": [...]} and kRecordFlagPlacement on the tick it takes effect. GUI thread;
  /// the device's sample filter takes the jump as no glitch.
  /// @return false (nothing changes) without a simulated device or for a non-finite pose.
  bool place(const haptics::Pose& X_WP, const haptics::Pose& X_WD);
  /// Placements the solver has applied since construction.
  std::uint64_t placementsApplied() const noexcept { return placements_applied_.load(std::memory_order_acquire); }

  /// Adds an event to the current recording stamped with the latest solver tick and time; a
  /// no-op when not recording. Any thread but the haptic threads (it allocates). The recorder
  /// must not be destroyed concurrently (see setRecorder()).
  /// @throws std::invalid_argument when detail_json is not a JSON object (RecordingWriter::addEvent()).
  void recordEvent(const std::string& type, const std::string& detail_json);

  /// Moves the proxy to X_WP in W [m] without collision checking (HapticRenderer::resetProxy():
  /// the contact set cleared; points inside become embedded), for the next start(). Only while
  /// the threads are stopped and nothing records (a recording replays the renderer's own
  /// motion). @return false (nothing moved) while running or recording.
  bool placeProxy(const haptics::Pose& X_WP) noexcept;
  /// The renderer (its carved field, felt isovalue, tool and proxy pose); read it only while the
  /// threads are stopped.
  const haptics::HapticRenderer& renderer() const noexcept { return *renderer_; }

  /// Latest snapshot (never blocks; one consumer thread). @return true when either thread
  /// published something since the last call.
  bool latestSnapshot(HapticSnapshot& out) noexcept;

 private:
  struct Exchange;  // the lock-free buffers between the threads (haptic_thread.cpp)

  void couplingLoop() noexcept;
  void solverLoop() noexcept;

  std::unique_ptr<haptics::HapticRenderer> renderer_;
  std::shared_ptr<Device> device_;
  double period_s_;
  double solver_period_s_;
  bool every_sample_;
  HapticThreadOptions options_;
  /// The nearest critical segment after each solver tick (null: no critical segment); the
  /// solver thread's only.
  std::unique_ptr<CriticalProximity> proximity_;
  /// What replaceSegments() hands over: the solver swaps these with options_.segments,
  /// proximity_ and options_.technique (no allocation), and hands the old ones back.
  struct SegmentParts {
    std::shared_ptr<const SegmentSet> segments;
    std::unique_ptr<CriticalProximity> proximity;
    std::shared_ptr<ServoTechnique> technique;
  };
  void swapSegmentParts(SegmentParts& parts) noexcept;
  std::atomic<SegmentParts*> segments_pending_{nullptr};  ///< GUI -> solver (replaceSegments()).
  std::atomic<SegmentParts*> segments_retired_{nullptr};  ///< Solver -> GUI: taken, now holding the old ones.
  std::unique_ptr<Exchange> x_;
  std::atomic<double> isovalue_;
  std::atomic<double> gain_linear_;
  std::atomic<double> gain_angular_;
  std::atomic<bool> gain_passivity_{false};  ///< CouplingGains::passivity_control.
  std::atomic<bool> gains_dirty_{false};
  std::atomic<bool> drilling_{false};
  std::atomic<bool> guidance_dirty_{false};  ///< setGuidance() published a new command.
  std::shared_ptr<const ExpertPath> guide_;  ///< GUI thread.
  std::vector<std::shared_ptr<const ExpertPath>> guides_kept_;  ///< GUI thread: alive until destruction.
  std::atomic<bool> cutting_held_{false};  ///< holdCutting(); read by the solver each tick (seq_cst).
  std::atomic<std::uint64_t> solver_ticks_{0};  ///< Solver ticks finished (seq_cst; holdCutting()).
  std::atomic<std::uint64_t> placement_requests_{0};  ///< place() calls (the latest in Exchange::placement).
  std::atomic<std::uint64_t> placements_applied_{0};  ///< By the solver.
  std::atomic<bool> stop_requested_{false};
  std::atomic<bool> coupling_done_{false};  ///< The coupling thread ended: the solver stops too.
  std::atomic<bool> running_{false};
  std::atomic<bool> fifo_{false};
  std::atomic<bool> memory_locked_{false};
  /// recordEvent() stamped with solver tick `latest` (a recorded tick, 0 before the first).
  void recordEventAt(const std::string& type, const std::string& detail_json, std::uint64_t latest);
  std::atomic<RecordingWriter*> recorder_{nullptr};
  /// Latest recorded solver tick and the recording's first (solver thread writes; 0 before).
  std::atomic<std::uint64_t> latest_recorded_tick_{0};
  std::atomic<std::uint64_t> first_recorded_tick_{0};
  std::thread coupling_thread_;
  std::thread solver_thread_;
};

}  // namespace vh::runtime
