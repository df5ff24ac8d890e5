// Replaying recordings: the replay device and the bit-for-bit re-run (vh/runtime/replay.h).
#include "vh/runtime/replay.h"

#include "vh/tissue/deformable_scene.h"

#include <algorithm>
#include <cstring>
#include <stdexcept>

#include <nlohmann/json.hpp>

#include "vh/runtime/servo_factory.h"

namespace vh::runtime {
namespace {

haptics::Pose poseOf(const double p[3], const double q[4]) {
  haptics::Pose X;
  X.p_AB_m = {p[0], p[1], p[2]};
  X.R_AB = Eigen::Quaterniond(q[0], q[1], q[2], q[3]);
  return X;
}

bool sameBits(double a, double b) noexcept { return std::memcmp(&a, &b, sizeof a) == 0; }

}  // namespace

ReplayDevice::ReplayDevice(std::vector<TickRecord> records, std::string source)
    : records_(std::move(records)), source_(std::move(source)) {
  if (records_.empty()) throw std::invalid_argument("ReplayDevice: the recording has no records");
}

std::string ReplayDevice::name() const {
  return source_.empty() ? std::string("Replay device") : "Replay device (" + source_ + ")";
}

bool ReplayDevice::read(DeviceSample& sample) noexcept {
  const std::size_t i = cursor_ < records_.size() ? cursor_ : records_.size() - 1;
  const TickRecord& r = records_[i];
  const bool past_end = cursor_ >= records_.size();
  sample.time_s = r.time_s;
  sample.X_WD = poseOf(r.p_WD_m, r.q_WD);
  sample.v_WD_m_per_s.setZero();
  sample.w_WD_rad_per_s.setZero();
  sample.buttons = 0;
  sample.connection = 0;
  sample.valid = past_end || (r.flags & kRecordFlagBadSample) == 0;
  if (!past_end) ++cursor_;
  reads_.fetch_add(1, std::memory_order_relaxed);
  if (cursor_ >= records_.size()) finished_.store(true, std::memory_order_release);
  return sample.valid;
}

void ReplayDevice::command(const Eigen::Vector3d& /*force_W_N*/, const Eigen::Vector3d& /*torque_W_Nm*/) noexcept {}

namespace {

/// A "gains" event: the coupling gains from its tick on.
struct GainsChange {
  std::uint64_t tick;
  haptics::CouplingGains gains;
};

/// A "hardness" event (Session::setHardness()): a material's specific energy from its tick on.
struct HardnessChange {
  std::uint64_t tick;
  std::string material;
  double J_per_mm3;
};

/// The recording's "gains" events, in tick order (readRecording() sorts events by tick); what an
/// event leaves out stays the scene's, and a malformed event changes nothing.
std::vector<GainsChange> gainsChanges(const Recording& recording, const haptics::CouplingGains& scene_gains) {
  std::vector<GainsChange> gains_changes;
  for (const RecordingEvent& e : recording.events) {
    if (e.type != "gains") continue;
    try {
      const nlohmann::json d = nlohmann::json::parse(e.detail_json);
      haptics::CouplingGains g = scene_gains;
      g.linear_N_per_m = d.value("linear_N_per_m", g.linear_N_per_m);
      g.angular_Nm_per_rad = d.value("angular_Nm_per_rad", g.angular_Nm_per_rad);
      g.passivity_control = d.value("passivity_control", g.passivity_control);
      gains_changes.push_back({e.tick, g});
    } catch (const nlohmann::json::exception&) {  // a malformed event changes nothing
    }
  }
  return gains_changes;
}

/// The recording's "hardness" events, in tick order; a malformed event changes nothing.
std::vector<HardnessChange> hardnessChanges(const Recording& recording) {
  std::vector<HardnessChange> hardness_changes;
  for (const RecordingEvent& e : recording.events) {
    if (e.type != "hardness") continue;
    try {
      const nlohmann::json d = nlohmann::json::parse(e.detail_json);
      hardness_changes.push_back({e.tick, d.at("material").get<std::string>(), d.at("J_per_mm3").get<double>()});
    } catch (const nlohmann::json::exception&) {  // a malformed event changes nothing
    }
  }
  return hardness_changes;
}

/// The "placement" events' proxy poses, in order, one per record flagged kRecordFlagPlacement; a
/// malformed event places nothing.
std::vector<haptics::Pose> placementPoses(const Recording& recording) {
  std::vector<haptics::Pose> placements;
  for (const RecordingEvent& e : recording.events) {
    if (e.type != "placement") continue;
    try {
      const std::vector<double> v = nlohmann::json::parse(e.detail_json).at("X_WP").get<std::vector<double>>();
      if (v.size() != 7) continue;
      haptics::Pose X;
      X.p_AB_m = {v[0], v[1], v[2]};
      X.R_AB = Eigen::Quaterniond(v[3], v[4], v[5], v[6]);
      placements.push_back(X);
    } catch (const nlohmann::json::exception&) {  // a malformed event places nothing
    }
  }
  return placements;
}

/// The servo rate the recording's metadata names [Hz]; 1000 when it names none or is malformed.
double recordedServoRate_Hz(const Recording& recording) {
  try {
    return nlohmann::json::parse(recording.metadata_json).value("servo_rate_Hz", 1000.0);
  } catch (const nlohmann::json::exception&) {
    return 1000.0;
  }
}

/// The material of `h` (every material it names) gets its specific energy.
void applyHardness(haptics::MaterialRemoval& removal, const HardnessChange& h) {
  for (std::size_t m = 0; m < removal.materials().size(); ++m)
    if (namesMaterial(h.material, removal.materials()[m].name)) removal.setSpecificEnergy(static_cast<int>(m), h.J_per_mm3);
}

/// The first mismatch into `result`: at record `index` (`r`), what differed, and the first
/// record up to it on which the solver's deadline cut the work short where the replay could not
/// repeat the cut (no TickRecord::deadline_work: format versions 1 to 4).
void markMismatch(ReplayComparison& result, const Recording& recording, const TickRecord& r, std::size_t index,
                  const char* what) {
  result.identical = false;
  result.first_mismatch_tick = r.tick;
  result.first_mismatch_index = index;
  result.mismatch = what;
  for (std::size_t k = 0; k <= index; ++k)
    if ((recording.records[k].flags & kRecordFlagDeadlineCut) != 0 && recording.records[k].deadline_work == 0) {
      result.deadline_cut_tick = recording.records[k].tick;
      break;
    }
}

/// The voxels the burr removed on this record, into the removal log.
void logRemovals(Drill& drill, ReplayComparison& result) {
  std::uint64_t buffer[4096];
  for (std::size_t n; (n = drill.removal().drainRemoved(buffer)) > 0;)
    result.removed_voxels.insert(result.removed_voxels.end(), buffer, buffer + n);
  result.removed_after_record.push_back(result.removed_voxels.size());
}

/// What of the re-run tick differs, bit for bit, from record `r`: the proxy pose, the contact
/// count and, on a rendered tick (`rendered`) whose command the safety layer left alone, the
/// wrench. @return nullptr when nothing differs (`forces_compared` counts the wrenches compared).
const char* recordMismatch(const haptics::HapticRenderer& renderer, const haptics::TickOutput& out, bool rendered,
                           const TickRecord& r, std::uint64_t& forces_compared) {
  const haptics::Pose& X_WP = renderer.proxyPose();
  for (int k = 0; k < 3; ++k)
    if (!sameBits(X_WP.p_AB_m[k], r.p_WP_m[k])) return "proxy position";
  if (!sameBits(X_WP.R_AB.w(), r.q_WP[0]) || !sameBits(X_WP.R_AB.x(), r.q_WP[1]) ||
      !sameBits(X_WP.R_AB.y(), r.q_WP[2]) || !sameBits(X_WP.R_AB.z(), r.q_WP[3]))
    return "proxy orientation";
  if (renderer.contacts().size() != r.contacts) return "contacts";
  if (rendered && (r.flags & (kRecordFlagForceLimited | kRecordFlagForceZeroed | kRecordFlagStopping)) == 0) {
    for (int k = 0; k < 3; ++k)
      if (!sameBits(out.force_W_N[k], r.force_W_N[k])) return "force";
    for (int k = 0; k < 3; ++k)
      if (!sameBits(out.torque_W_Nm[k], r.torque_W_Nm[k])) return "torque";
    ++forces_compared;
  }
  return nullptr;
}

}  // namespace

ReplayComparison replayRecording(const LoadedScene& scene, const Recording& recording,
                                 const haptics::RendererOptions& options, const ReplayProgress& progress) {
  if (recording.records.empty()) throw std::invalid_argument("replayRecording: the recording has no records");
  const std::vector<GainsChange> gains_changes = gainsChanges(recording, scene.spec.gains);
  // With a drill, the renderer feels its own copy of the field, carved on the ticks the
  // recording flags (kRecordFlagDrillOn) exactly as the solver thread did.
  DrillingRenderer servo =
      makeServoRenderer(LiveValues::initial(scene), options, scene.X_WT_initial, recordedServoRate_Hz(recording));
  std::unique_ptr<haptics::HapticRenderer> renderer = std::move(servo.renderer);
  // "hardness" events, applied like the gains: before the first record after their tick.
  const std::vector<HardnessChange> hardness_changes =
      servo.drill != nullptr ? hardnessChanges(recording) : std::vector<HardnessChange>{};
  const std::vector<haptics::Pose> placements = placementPoses(recording);
  std::size_t next_placement = 0;
  std::size_t next_hardness = 0;
  renderer->setGains(renderer->coupling().gains());  // as the haptic thread does before its first tick
  ReplayDevice device(recording.records, "replayRecording");
  ReplayComparison result;
  std::size_t next_gains = 0;
  const bool gains_flagged = std::any_of(recording.records.begin(), recording.records.end(),
                                         [](const TickRecord& r) { return (r.flags & kRecordFlagGainsApplied) != 0; });
  const double record_count = static_cast<double>(recording.records.size());
  const double period_s = 1.0 / recordedServoRate_Hz(recording);
  double eroded_mm3 = servo.drill != nullptr ? servo.drill->removal().erodedVolume_mm3() : 0.0;
  for (std::size_t i = 0; i < recording.records.size(); ++i) {
    if (i % 1000 == 0) {
      if (progress.cancel != nullptr && progress.cancel->load(std::memory_order_relaxed)) {
        result.cancelled = true;
        return result;
      }
      if (progress.progress) progress.progress(static_cast<double>(i) / record_count);
    }
    const TickRecord& r = recording.records[i];
    while (next_hardness < hardness_changes.size() && hardness_changes[next_hardness].tick < r.tick)
      applyHardness(servo.drill->removal(), hardness_changes[next_hardness++]);
    // Where the solver flagged the tick it applied new gains on, there (the latest event stamped
    // before it); an older recording: on the first record after the event's tick.
    if (!gains_flagged || (r.flags & kRecordFlagGainsApplied) != 0) {
      while (next_gains < gains_changes.size() && gains_changes[next_gains].tick < r.tick) {
        renderer->setGains(gains_changes[next_gains].gains);
        ++next_gains;
      }
    }
    if ((r.flags & kRecordFlagPlacement) != 0 && next_placement < placements.size())
      renderer->resetProxy(placements[next_placement++]);
    DeviceSample sample;
    const bool ok = device.read(sample) && sample.valid && sample.X_WD.allFinite();
    haptics::TickOutput out;
    haptics::CutResult cut;
    const bool drill_on = ok && servo.drill != nullptr && (r.flags & kRecordFlagDrillOn) != 0;
    if (ok) {
      if (servo.tissue != nullptr) (void)servo.tissue->step(sample.X_WD, *renderer);  // as the live solver did
      // A tick the live solver's deadline cut stops at the same work (no clock here).
      renderer->cutNextTickAtWork(r.deadline_work);
      out = renderer->tick(sample.X_WD, r.isovalue);
      ++result.ticks_replayed;
      if (drill_on) cut = servo.drill->step(*renderer, out);
    }
    if (servo.drill != nullptr) logRemovals(*servo.drill, result);  // the removal log, record by record
    const char* what = recordMismatch(*renderer, out, ok, r, result.forces_compared);
    // From format version 5 on a record counts the voxels its tick's burr removed.
    if (what == nullptr && recording.version >= 5 && static_cast<std::uint64_t>(std::max(0, cut.voxels_removed)) != r.removed_voxels)
      what = "removed voxels";
    if (what != nullptr) {
      markMismatch(result, recording, r, i, what);
      return result;
    }
    if (servo.drill != nullptr && progress.on_drill_tick) {
      const int segment = recordSegment(r.flags);
      const bool critical_contact = segment >= 0 && scene.segments && scene.segments->isCritical(segment) && r.contacts > 0;
      const double eroded_now_mm3 = servo.drill->removal().erodedVolume_mm3();
      progress.on_drill_tick(
          drillTickOf(r.tick, r.time_s, drill_on, cut, out, eroded_now_mm3 - eroded_mm3, period_s, critical_contact));
      eroded_mm3 = eroded_now_mm3;
    }
  }
  if (servo.drill != nullptr) {
    result.drilled_field = std::make_shared<haptics::ScalarVolume>(servo.drill->removal().volume());
    result.drill = drillReportOf(*servo.drill, scene);
  }
  if (progress.progress) progress.progress(1.0);
  return result;
}

std::string replayDifference(const ReplayComparison& replay, const Recording& recording) {
  if (replay.identical || !replay.first_mismatch_tick) return {};
  std::string text = "the replay differs from the recording from record " + std::to_string(replay.first_mismatch_index) +
                     " on (tick " + std::to_string(*replay.first_mismatch_tick) + ": " + replay.mismatch + ")";
  if (replay.deadline_cut_tick) {
    text += ": the live solver's deadline on the clock cut tick " + std::to_string(*replay.deadline_cut_tick) +
            ", and this recording (format version " + std::to_string(recording.version) +
            ") does not say where, so the replay did that tick whole";
  } else {
    text += ": no tick before it was cut by the clock, so the replay should have matched; please report it with the "
            "recording";
  }
  return text;
}

std::shared_ptr<const haptics::ScalarVolume> drilledFieldAtEnd(const LoadedScene& scene, const Recording& recording,
                                                               std::string& difference) {
  if (!scene.spec.drill.has_value()) throw std::invalid_argument("the recorded scene has no drill");
  if (recording.records.empty()) throw std::invalid_argument("the recording has no records");
  const ReplayComparison replay = replayRecording(scene, recording);
  difference = replayDifference(replay, recording);
  return difference.empty() ? replay.drilled_field : nullptr;
}

}  // namespace vh::runtime
