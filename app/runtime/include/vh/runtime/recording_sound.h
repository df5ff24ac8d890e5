#pragma once
/// @file
/// The burr's sound of a session recording, from the recording alone: a replay
/// (replayRecording(), bit for bit) re-drills it and reports each record's burr
/// (ReplayProgress::on_drill_tick: burr on, the |F| and hardness of what it cut through
/// burrLoadOf(), the removal rate, critical contact or removal), the record's flags add the
/// technique rules active, and vh::audio::TimedSound renders it with the scene's burr. What a
/// headless run with `run --audio` wrote for the same ticks, sample for sample (the same mixer
/// fed the same states on the same frames); the sound track of `export --video`.
///
/// Honest limits: records after a replay mismatch (a recording the replay cannot reproduce, e.g.
/// after a tick cut short by the live deadline) are taken from the record alone: the burr on as
/// flagged, running free (no load: the replay no longer knows what it cut), the alert from the
/// technique bits only. A recording without a drill, or whose burr never ran, has no sound.

#include <cstdint>
#include <optional>
#include <vector>

#include "vh/audio/burr_sound.h"
#include "vh/audio/timed_sound.h"
#include "vh/runtime/burr_load.h"
#include "vh/runtime/recording.h"
#include "vh/runtime/replay.h"
#include "vh/runtime/scene.h"

namespace vh::runtime {

/// vh::audio's burr model with the drilling scene's no-load speed (drill.burr_speed_rpm) and
/// burr radius (burrOf()): what `run --audio` and the video's sound play. A scene without a
/// drill or tool: the defaults.
audio::BurrSoundModel burrSoundModelOf(const LoadedScene& scene);

/// One record's sound: the burr of `d`; the alert while `d` is critical or, with
/// `technique_alerts`, while a technique rule is active in `record_flags` (recordTechnique()).
audio::TimedBurrState soundStateOf(const DrillTick& d, std::uint32_t record_flags, bool technique_alerts = true);

/// A recording's sound: one state per record, the burr's model and the servo period.
struct RecordingSound {
  std::vector<audio::TimedBurrState> states;  ///< One per record, in order (time_s: the record's).
  audio::BurrSoundModel burr;                 ///< burrSoundModelOf() the recording's scene.
  double tick_period_s = 1e-3;                ///< One recorded servo period [s].
  /// Records taken from the record alone after a replay mismatch (see the file comment).
  std::uint64_t approximated_records = 0;

  /// Adds the state of `d`, the replay's burr after record states.size() of `recording`.
  void add(const DrillTick& d, const Recording& recording, bool technique_alerts = true);
  /// Fills the records the replay did not reach from the records alone (see the file comment).
  void completeFrom(const Recording& recording, bool technique_alerts = true);
  /// The renderer of this sound (audio::TimedSound). @throws as its constructor.
  audio::TimedSound renderer() const { return audio::TimedSound(states, tick_period_s, burr); }
};

/// The servo period a recording's metadata names (servo_rate_Hz; 1 ms when it names none) [s].
double recordedServoPeriod_s(const Recording& recording);

/// Whether any record of `recording` has the burr on (kRecordFlagDrillOn).
bool burrRan(const Recording& recording);

/// The sound of `recording` on `scene` (the scene it was recorded on, or loaded from its
/// metadata): a replay of the records (seconds on a big CT; progress and cancel through
/// `progress`, whose on_drill_tick is taken over). Empty when the scene has no drill, no record
/// has the burr on, or the replay was cancelled. Any thread; not the servo thread.
/// @throws as replayRecording().
std::optional<RecordingSound> recordingSound(const LoadedScene& scene, const Recording& recording,
                                             ReplayProgress progress = {}, bool technique_alerts = true);

}  // namespace vh::runtime
