// A recording's burr sound (recording_sound.h) against the live run that made the recording: a
// headless drilling run on the built-in sphere writes its recording and, as `run --audio` does,
// its sound (TickSoundWriter, WAV); the recording alone, replayed, must give the same burr state
// at every tick and the same samples (to the WAV's 16-bit step), and its pitch while pushing must
// sit on the motor line at the recorded |F| (computed here from the model's equation, measured
// with the tests' own DFT).
#include <string>
#include <unistd.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <vector>

#include "spectrum_oracle.h"
#include "vh/audio/tick_sound.h"
#include "vh/audio/timed_sound.h"
#include "vh/audio/wav_file.h"
#include "vh/runtime/recording.h"
#include "vh/runtime/recording_sound.h"
#include "vh/runtime/runner.h"
#include "vh/runtime/scene.h"
#include "vh/runtime/session_metadata.h"

namespace vh::runtime {
namespace {

namespace fs = std::filesystem;

/// The built-in drilling scene (resources/scenes/sphere-drill.json: the synthetic sphere, top at
/// z = 20 mm, the drill's 2.5 mm burr spinning from the start, the sphere 2 J/mm^3 hard) with a
/// force rule that a push trips (its bits in the records; no alert in `run --audio`).
SceneSpec drillingSphere() {
  return parseScene(R"({"volume": {"path": "builtin:sphere", "isovalue": 0},
      "tool": {"mesh": "builtin:drill", "point_spacing_m": 0.001},
      "coupling": {"linear_N_per_m": 400, "angular_Nm_per_rad": 1.0},
      "drill": {"on": true, "burr_radius_m": 0.0025, "burr_speed_rpm": 80000, "hardness": {"tissue": 2.0}},
      "technique": {"safe_force_N": 2.0, "force_hold_s": 0.25}})",
                    "sphere-drill.json", {});
}

/// Above the sphere until 1 s, down to 12.5 mm by 2 s, held there until 3 s (as the `run
/// --audio` test, tests/app/audio/run_audio_cli_test.py).
Trajectory pressIntoTheSphere() {
  std::vector<TrajectorySample> keys;
  for (const auto& [t, z] : {std::pair{0.0, 0.030}, {1.0, 0.030}, {2.0, 0.0125}, {3.0, 0.0125}}) {
    TrajectorySample k;
    k.t_s = t;
    k.X_WD = haptics::Pose::FromTranslation({0.0, 0.0, z});
    keys.push_back(k);
  }
  return Trajectory(keys);
}

/// One live run, its recording, its ticks and its `run --audio` WAV, made once for the tests.
struct LiveRun {
  fs::path dir;
  std::vector<DrillTick> ticks;
  Recording recording;
  audio::WavData wav;
};

const LiveRun& liveRun() {
  static const LiveRun run = [] {
    LiveRun r;
    // One folder per process: ctest runs this file's tests as separate processes side by side,
    // and each makes the live run; a shared folder let one truncate the recording another read.
    r.dir = fs::path(VH_TEST_OUTPUT_DIR) / ("recording-sound-" + std::to_string(::getpid()));
    fs::create_directories(r.dir);
    const LoadedScene scene = loadScene(drillingSphere());
    RunOptions options;
    options.verify_step_voxels = 0.0;
    options.lag_reference = false;
    options.record = r.dir / "push.vhrec";
    audio::TickSoundWriter wav(r.dir / "push.wav", options.servo_rate_Hz, burrSoundModelOf(scene));
    options.on_drill_tick = [&](const DrillTick& d) {
      r.ticks.push_back(d);
      wav.tick({d.burr_on, d.force_N, d.specific_energy_J_per_mm3, d.removal_rate_mm3_per_s}, d.critical);
    };
    runHeadless(scene, pressIntoTheSphere(), options);
    wav.close();
    r.recording = readRecording(options.record);
    r.wav = audio::readWav(r.dir / "push.wav");
    return r;
  }();
  return run;
}

/// The recording's scene as `export` loads it: from its metadata alone.
LoadedScene sceneOfRecording(const Recording& recording) {
  SceneSpec spec = sceneFromSessionMetadata(recording.metadata_json);
  spec.device.reset();
  return loadScene(spec);
}

TEST(RecordingSound, TheReplayHearsTheLiveRunsBurrAtEveryTick) {
  const LiveRun& live = liveRun();
  ASSERT_EQ(live.recording.records.size(), live.ticks.size());
  const auto sound = recordingSound(sceneOfRecording(live.recording), live.recording, {}, /*technique_alerts=*/false);
  ASSERT_TRUE(sound.has_value());
  EXPECT_EQ(sound->approximated_records, 0u) << "the replay must reach the end";
  ASSERT_EQ(sound->states.size(), live.ticks.size());
  int cutting = 0;
  for (std::size_t i = 0; i < live.ticks.size(); ++i) {
    const DrillTick& d = live.ticks[i];
    const audio::TimedBurrState& s = sound->states[i];
    SCOPED_TRACE("tick " + std::to_string(d.tick));
    EXPECT_EQ(s.time_s, live.recording.records[i].time_s);
    EXPECT_EQ(s.burr.on, d.burr_on);
    EXPECT_EQ(s.burr.force_N, d.force_N);
    EXPECT_EQ(s.burr.specific_energy_J_per_mm3, d.specific_energy_J_per_mm3);
    EXPECT_EQ(s.burr.removal_rate_mm3_per_s, d.removal_rate_mm3_per_s);
    EXPECT_EQ(s.alert, d.critical);
    cutting += d.force_N > 0.0;
    if (::testing::Test::HasFailure()) break;
  }
  EXPECT_GT(cutting, 500) << "the burr must have cut for a good part of the push";
}

TEST(RecordingSound, TheReplaysSoundIsTheLiveRunsSampleForSample) {
  const LiveRun& live = liveRun();
  const auto sound = recordingSound(sceneOfRecording(live.recording), live.recording, {}, false);
  ASSERT_TRUE(sound.has_value());
  audio::TimedSound renderer = sound->renderer();
  ASSERT_EQ(renderer.frames(), live.wav.frames()) << "as long as the run";
  EXPECT_EQ(renderer.sampleRate_Hz(), live.wav.sample_rate_Hz);
  std::vector<float> x(renderer.frames());
  renderer.render(x);
  double worst = 0.0;
  for (std::size_t i = 0; i < x.size(); ++i)
    worst = std::max(worst, std::abs(static_cast<double>(x[i]) - live.wav.samples[i]));
  EXPECT_LE(worst, 1.0 / 32767.0 + 1e-6) << "the WAV holds the same sound to its 16-bit step";

  // The pitch while pushing (2.4 .. 2.6 s): the motor line n = n0 (1 - mu |F| r (e / e_ref) /
  // T_stall) at the window's mean |F|, f0 = flutes n / 60 (BurrSoundModel's defaults, the scene's
  // speed and radius, its 2 J/mm^3).
  const double fs = renderer.sampleRate_Hz();
  const auto a = static_cast<std::size_t>(2.4 * fs), n = std::size_t{8192};
  double force_sum = 0.0;
  int count = 0;
  for (const auto& s : sound->states)
    if (s.time_s >= 2.4 && s.time_s < 2.4 + n / fs) force_sum += s.burr.force_N, ++count;
  ASSERT_GT(count, 0);
  const double force_N = force_sum / count;
  const double rpm = std::max(0.1, 1.0 - 0.2 * force_N * 0.0025 * (2.0 / 0.6) / 0.01) * 80000.0;
  const double expected_Hz = 6.0 * rpm / 60.0;
  const double measured_Hz =
      audio::oracle::peakFrequency_Hz(std::span<const float>(x.data() + a, n), fs, 0.5 * expected_Hz, 1.5 * expected_Hz);
  std::cout << "pushing at " << force_N << " N: f0 " << measured_Hz << " Hz, the motor line's " << expected_Hz << " Hz\n";
  EXPECT_LT(expected_Hz, 0.95 * 8000.0) << "the push must load the burr";
  EXPECT_NEAR(measured_Hz, expected_Hz, 0.02 * expected_Hz);
}

TEST(RecordingSound, TechniqueRulesSoundTheAlertWhileActive) {
  const LiveRun& live = liveRun();
  const auto sound = recordingSound(sceneOfRecording(live.recording), live.recording);
  ASSERT_TRUE(sound.has_value());
  int active = 0;
  for (std::size_t i = 0; i < sound->states.size(); ++i) {
    const bool rule = recordTechnique(live.recording.records[i].flags) != 0;
    active += rule;
    EXPECT_EQ(sound->states[i].alert, rule || live.ticks[i].critical) << "record " << i;
  }
  EXPECT_GT(active, 100) << "the push must trip the force rule";
}

TEST(RecordingSound, RecordsTheReplayCannotReproduceRunFreeAsFlagged) {
  const LiveRun& live = liveRun();
  Recording tampered = live.recording;
  const std::size_t k = tampered.records.size() / 2;  // in the push: its force is compared
  tampered.records[k].force_W_N[2] += 1.0;
  const auto sound = recordingSound(sceneOfRecording(tampered), tampered, {}, false);
  ASSERT_TRUE(sound.has_value());
  ASSERT_EQ(sound->states.size(), tampered.records.size());
  EXPECT_EQ(sound->approximated_records, tampered.records.size() - k);
  for (std::size_t i = k; i < tampered.records.size(); ++i) {
    EXPECT_EQ(sound->states[i].burr.on, (tampered.records[i].flags & kRecordFlagDrillOn) != 0);
    EXPECT_EQ(sound->states[i].burr.force_N, 0.0);
  }
}

TEST(RecordingSound, NoSoundWithoutADrillOrWhenTheBurrNeverRan) {
  const LiveRun& live = liveRun();
  Recording idle = live.recording;
  for (TickRecord& r : idle.records) r.flags &= ~kRecordFlagDrillOn;
  EXPECT_FALSE(recordingSound(sceneOfRecording(idle), idle).has_value());
  SceneSpec no_drill = sceneFromSessionMetadata(live.recording.metadata_json);
  no_drill.device.reset();
  no_drill.drill.reset();
  EXPECT_FALSE(recordingSound(loadScene(no_drill), live.recording).has_value());
}

}  // namespace
}  // namespace vh::runtime
