// A recording's burr sound from its replay (vh/runtime/recording_sound.h).
#include "vh/runtime/recording_sound.h"

#include <algorithm>

#include <nlohmann/json.hpp>

#include "vh/runtime/drilling.h"
#include "vh/runtime/tick_record.h"

namespace vh::runtime {

audio::BurrSoundModel burrSoundModelOf(const LoadedScene& scene) {
  audio::BurrSoundModel model;
  if (!scene.spec.drill || scene.tool == nullptr) return model;
  model.nominal_speed_rpm = scene.spec.drill->burr_speed_rpm;
  model.burr_radius_m = burrOf(*scene.tool, *scene.spec.drill).radius_m;
  return model;
}

audio::TimedBurrState soundStateOf(const DrillTick& d, std::uint32_t record_flags, bool technique_alerts) {
  audio::TimedBurrState s;
  s.time_s = d.time_s;
  s.burr = {d.burr_on, d.force_N, d.specific_energy_J_per_mm3, d.removal_rate_mm3_per_s};
  s.alert = d.critical || (technique_alerts && recordTechnique(record_flags) != 0);
  return s;
}

void RecordingSound::add(const DrillTick& d, const Recording& recording, bool technique_alerts) {
  const std::size_t i = states.size();
  const std::uint32_t flags = i < recording.records.size() ? recording.records[i].flags : 0u;
  states.push_back(soundStateOf(d, flags, technique_alerts));
}

void RecordingSound::completeFrom(const Recording& recording, bool technique_alerts) {
  for (std::size_t i = states.size(); i < recording.records.size(); ++i) {
    const TickRecord& r = recording.records[i];
    DrillTick d;
    d.tick = r.tick;
    d.time_s = r.time_s;
    d.burr_on = (r.flags & kRecordFlagDrillOn) != 0;
    states.push_back(soundStateOf(d, r.flags, technique_alerts));
    ++approximated_records;
  }
}

double recordedServoPeriod_s(const Recording& recording) {
  double rate_Hz = 1000.0;
  try {
    rate_Hz = nlohmann::json::parse(recording.metadata_json).value("servo_rate_Hz", 1000.0);
  } catch (const nlohmann::json::exception&) {
  }
  return rate_Hz > 0.0 && rate_Hz <= 1e6 ? 1.0 / rate_Hz : 1e-3;
}

bool burrRan(const Recording& recording) {
  return std::any_of(recording.records.begin(), recording.records.end(),
                     [](const TickRecord& r) { return (r.flags & kRecordFlagDrillOn) != 0; });
}

std::optional<RecordingSound> recordingSound(const LoadedScene& scene, const Recording& recording,
                                             ReplayProgress progress, bool technique_alerts) {
  if (!scene.spec.drill || !burrRan(recording)) return std::nullopt;
  RecordingSound sound;
  sound.burr = burrSoundModelOf(scene);
  sound.tick_period_s = recordedServoPeriod_s(recording);
  progress.on_drill_tick = [&](const DrillTick& d) { sound.add(d, recording, technique_alerts); };
  const ReplayComparison replay = replayRecording(scene, recording, {}, progress);
  if (replay.cancelled) return std::nullopt;
  sound.completeFrom(recording, technique_alerts);
  return sound;
}

}  // namespace vh::runtime
