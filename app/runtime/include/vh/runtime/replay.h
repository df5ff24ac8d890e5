#pragma once
/// @file
/// Replaying recordings (recording.h): ReplayDevice feeds the recorded device poses back one per
/// read, and replayRecording() re-runs a recording through a fresh renderer of the same scene
/// and reports the first tick whose proxy pose, force or torque differs bit for bit from the
/// recorded one (the determinism check).

#include <atomic>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "vh/haptics/haptic_renderer.h"
#include "vh/runtime/burr_load.h"
#include "vh/runtime/device.h"
#include "vh/runtime/drill_report.h"
#include "vh/runtime/recording.h"
#include "vh/runtime/scene.h"

namespace vh::runtime {

/// A Device that returns a recording's device poses, one record per read (like ScriptedDevice
/// steps its trajectory): read i returns record i's X_WD (p_WD_m, q_WD) with time_s = the
/// record's time_s; a record flagged kRecordFlagBadSample reads as invalid (no sample), as the
/// servo thread saw it. After the last record it keeps returning the last pose (valid) and
/// finished() is true. Forces commanded to it are ignored. connected() is true.
class ReplayDevice final : public Device {
 public:
  /// @param records non-empty, in tick order. @param source names it in name().
  /// @throws std::invalid_argument for no records.
  explicit ReplayDevice(std::vector<TickRecord> records, std::string source = {});
  std::string name() const override;
  bool read(DeviceSample& sample) noexcept override;
  void command(const Eigen::Vector3d& force_W_N, const Eigen::Vector3d& torque_W_Nm) noexcept override;
  /// The record the next read() returns (records().size() once finished); servo thread.
  std::size_t cursor() const noexcept { return cursor_; }
  const std::vector<TickRecord>& records() const noexcept { return records_; }
  /// Reads served so far (any thread).
  std::uint64_t reads() const noexcept { return reads_.load(std::memory_order_relaxed); }
  /// True once every record was read (any thread).
  bool finished() const noexcept { return finished_.load(std::memory_order_acquire); }

 private:
  std::vector<TickRecord> records_;
  std::string source_;
  std::size_t cursor_ = 0;  // servo thread only
  std::atomic<std::uint64_t> reads_{0};
  std::atomic<bool> finished_{false};
};

/// What replayRecording() found.
struct ReplayComparison {
  std::uint64_t ticks_replayed = 0;   ///< Records whose device sample was rendered.
  std::uint64_t forces_compared = 0;  ///< Records whose force / torque were compared.
  bool identical = true;              ///< Every compared value equal bit for bit.
  /// The first record that differs (TickRecord::tick and its index), and what differed:
  /// "proxy position", "proxy orientation", "force", "torque", "contacts" or (format version 5
  /// on, with a drill) "removed voxels".
  std::optional<std::uint64_t> first_mismatch_tick;
  std::size_t first_mismatch_index = 0;
  std::string mismatch;
  /// With a mismatch: the first record at or before it whose tick the live run's deadline on the
  /// clock cut (kRecordFlagDeadlineCut) without saying where (TickRecord::deadline_work 0: format
  /// versions 1 to 4), which a replay (no clock) cannot reproduce; empty when no such tick came
  /// before the mismatch (then the mismatch is not the machine's load). A cut tick with its
  /// deadline_work is replayed as it ran (HapticRenderer::cutNextTickAtWork()).
  std::optional<std::uint64_t> deadline_cut_tick;
  /// With a drill in the scene: the felt field as carved by the replay when it finished (null
  /// otherwise); compare its bytes with the live run's.
  std::shared_ptr<const haptics::ScalarVolume> drilled_field;
  /// With a drill: the voxels the replay removed (linear indices of the felt field, x fastest),
  /// in removal order, and after each record how many of them were removed by then (one entry
  /// per record replayed): what a viewer applies to show the cavity at any time of the replay.
  std::vector<std::uint64_t> removed_voxels;
  std::vector<std::uint64_t> removed_after_record;
  /// With a drill, once every record was replayed (a mismatch or a cancel stops before): what
  /// the replay's drill removed during the recording, per material and as air, by the rule of
  /// `run`'s report (drillReportOf(): the cavity the recording started from is not counted).
  /// Its voxels sum to removed_voxels.size(), which for an identical replay of a format 5
  /// recording is the records' TickRecord::removed_voxels summed (session_metrics.h).
  std::optional<DrillReport> drill;
  /// ReplayProgress::cancel stopped it before the end (nothing after that record compared, no
  /// drilled_field).
  bool cancelled = false;
};

/// Progress of a long replayRecording() (a drilled recording on a big CT takes seconds), for a
/// caller that runs it on a thread of its own, and what it hears on the way.
struct ReplayProgress {
  /// Called on the replaying thread with the fraction of the records replayed (0..1), every 1000
  /// records and once at the end; may be empty.
  std::function<void(double fraction)> progress;
  /// When set and true (written by any thread), the replay stops at the next 1000th record:
  /// ReplayComparison::cancelled.
  const std::atomic<bool>* cancel = nullptr;
  /// With a drill in the scene: called on the replaying thread after each record, in order, with
  /// the burr's state as the headless run reports it (drillTickOf(): burr on where the record
  /// flags kRecordFlagDrillOn and its sample was rendered, the replayed cut's load, the eroded
  /// volume over one recorded servo period, critical when the cut removed part of a critical
  /// segment or the record's contacts lie on one; tick and time the record's); may be empty. Not
  /// called for the records after a mismatch or a cancel.
  std::function<void(const DrillTick&)> on_drill_tick;
};

/// Re-runs `recording` through a fresh renderer of `scene` (scene.makeRenderer(options), so the
/// proxy starts at scene.X_WT_initial, which must be the recorded initial pose: use
/// loadScene(sceneFromSessionMetadata(recording.metadata_json)) or the scene it was recorded on)
/// fed by a ReplayDevice, as the haptic thread drives it: gains set once before the first tick
/// (the scene's), each record's isovalue, no tick for a record flagged kRecordFlagBadSample.
/// A "gains" event ({"linear_N_per_m": k, "angular_Nm_per_rad": k_r}) is applied before the
/// record the solver flagged kRecordFlagGainsApplied after the event's tick (exact, unless two
/// changes came within one solver tick and the solver saw only the second); in a recording
/// without those flags, before the first record after its tick (exact only when the change
/// took effect on the next tick).
/// After each rendered tick it compares the proxy pose (always), the contact count, and the
/// force and torque (only on records without kRecordFlagForceLimited, kRecordFlagForceZeroed or
/// kRecordFlagStopping, where the safety layer sent the renderer's output unchanged), and stops
/// at the first difference. With a drill whose spec has a cavity (the one the recording started
/// from: its metadata), the drill's field starts with it removed, as the session's did. Not for
/// the servo thread (allocates). Thread-safe for distinct calls (`scene` is only read).
/// @throws std::invalid_argument for a recording without records; as HapticRenderer's
///         constructor.
ReplayComparison replayRecording(const LoadedScene& scene, const Recording& recording,
                                 const haptics::RendererOptions& options = {}, const ReplayProgress& progress = {});

/// What `replay` (replayRecording() of `recording`) found, in words for a user: "" when it
/// matched every record; else the record and tick it parted at, what differed, and why when that
/// is known (a tick the live solver's deadline cut in a recording of format version 4 or older,
/// which does not say where it stopped), e.g. "the replay differs from the recording from record
/// 19006 on (tick 20112: proxy position): the live solver's deadline on the clock cut tick 20050,
/// and this recording (format version 4) does not say where, so the replay did that tick whole".
std::string replayDifference(const ReplayComparison& replay, const Recording& recording);

/// The drilled field at the end of `recording`, as a replay of it on `scene` (the scene it was
/// recorded on) carves it. Not for the servo thread.
/// @return the field; null when the replay parts from the recording, with `difference` saying
///         why (replayDifference()), else `difference` empty.
/// @throws std::invalid_argument when the scene has no drill or the recording no records; as
///         replayRecording().
std::shared_ptr<const haptics::ScalarVolume> drilledFieldAtEnd(const LoadedScene& scene, const Recording& recording,
                                                               std::string& difference);

}  // namespace vh::runtime
