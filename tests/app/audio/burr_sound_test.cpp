// The burr's sound (vh::audio), measured by the tests' own DFT (spectrum_oracle.h): the pitch
// free running and under load against the motor line's numbers, the level against the removal
// rate, the mixer's bound with alerts on, no clicks at parameter steps, no allocation per
// block, and the tick-paced WAV writer.
#include <algorithm>
#include <cmath>
#include <csignal>
#include <filesystem>
#include <iostream>
#include <string>
#include <vector>

#include <sys/resource.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include "allocation_guard.h"
#include "spectrum_oracle.h"
#include "vh/audio/alert_tone.h"
#include "vh/audio/burr_sound.h"
#include "vh/audio/drill_mixer.h"
#include "vh/audio/tick_sound.h"
#include "vh/audio/wav_file.h"

namespace vh::audio {
namespace {

constexpr double kFs = 48000.0;
constexpr std::size_t kWindow = 8192;  // 0.17 s: bins of 5.9 Hz

// The state held for settle_s, then `n` samples of it.
std::vector<float> steady(BurrSound& sound, const BurrState& state, double settle_s, std::size_t n) {
  sound.setState(state);
  std::vector<float> skip(static_cast<std::size_t>(settle_s * kFs));
  sound.render(skip);
  std::vector<float> out(n);
  sound.render(out);
  return out;
}

BurrState cutting(double force_N, double hardness_J_per_mm3, double rate_mm3_per_s = 5.0) {
  return {true, force_N, hardness_J_per_mm3, rate_mm3_per_s};
}

// The motor line written out here from the documented model: f0 = flutes n / 60 with
// n = n0 max(1 - mu F r (e / e_ref) / T_stall, min fraction).
double expectedFundamental_Hz(const BurrSoundModel& m, double force_N, double hardness) {
  const double torque = m.friction_coefficient * force_N * m.burr_radius_m * hardness / m.reference_hardness_J_per_mm3;
  return m.flutes * m.nominal_speed_rpm / 60.0 * std::max(1.0 - torque / m.stall_torque_Nm, m.min_speed_fraction);
}

double measuredFundamental_Hz(const std::vector<float>& x) { return oracle::peakFrequency_Hz(x, kFs, 100.0, 20000.0); }

TEST(BurrSound, FreeRunningPitchIsFlutesTimesRevolutionsPerSecond) {
  for (const auto& [rpm, flutes] : {std::pair{80000.0, 6}, std::pair{40000.0, 8}, std::pair{20000.0, 2}}) {
    BurrSoundModel model;
    model.nominal_speed_rpm = rpm;
    model.flutes = flutes;
    BurrSound sound(model);
    const double f = measuredFundamental_Hz(steady(sound, cutting(0.0, 0.6, 0.0), 0.2, kWindow));
    const double expected = flutes * rpm / 60.0;
    std::cout << rpm << " rpm, " << flutes << " flutes: fundamental " << f << " Hz (expected " << expected << ")\n";
    EXPECT_NEAR(f, expected, 0.02 * expected);
    EXPECT_NEAR(sound.fundamental_Hz(), expected, 1e-6 * expected);
  }
}

TEST(BurrSound, PitchFallsMonotonicallyAsThePushRises) {
  const BurrSoundModel model;
  BurrSound sound(model);
  double previous = 1e9;
  for (double force_N : {0.0, 1.0, 2.0, 3.0, 4.0, 5.0}) {
    const double f = measuredFundamental_Hz(steady(sound, cutting(force_N, 0.6), 0.2, kWindow));
    const double expected = expectedFundamental_Hz(model, force_N, 0.6);
    std::cout << "|F| " << force_N << " N on 0.6 J/mm^3: fundamental " << f << " Hz (motor line " << expected << ")\n";
    EXPECT_LT(f, previous - 100.0) << "at " << force_N << " N";
    EXPECT_NEAR(f, expected, 0.01 * expected) << "at " << force_N << " N";
    previous = f;
  }
}

TEST(BurrSound, HarderMaterialAtTheSameForceGivesALowerPitch) {
  const BurrSoundModel model;
  BurrSound sound(model);
  double previous = 1e9;
  for (double hardness : {0.1, 0.6, 2.0}) {  // soft tissue, cancellous, cortical bone (drilling.h's defaults)
    const double f = measuredFundamental_Hz(steady(sound, cutting(2.0, hardness), 0.2, kWindow));
    std::cout << "2 N on " << hardness << " J/mm^3: fundamental " << f << " Hz (motor line "
              << expectedFundamental_Hz(model, 2.0, hardness) << ")\n";
    EXPECT_LT(f, previous - 100.0) << "at " << hardness << " J/mm^3";
    EXPECT_NEAR(f, expectedFundamental_Hz(model, 2.0, hardness), 0.01 * f);
    previous = f;
  }
}

TEST(BurrSound, LevelRisesWithTheRemovalRate) {
  BurrSound sound;
  double previous = 0.0;
  std::vector<double> levels;
  for (double rate : {0.0, 1.0, 3.0, 10.0, 30.0}) {
    const double level = oracle::rms(steady(sound, cutting(1.0, 0.6, rate), 0.1, 9600));
    std::cout << "removal " << rate << " mm^3/s: RMS " << level << "\n";
    EXPECT_GT(level, previous * 1.05) << "at " << rate << " mm^3/s";
    previous = level;
    levels.push_back(level);
  }
  EXPECT_GT(levels.back(), 1.8 * levels.front());
  // Off: silent once the gate has closed.
  EXPECT_LT(oracle::rms(steady(sound, BurrState{}, 0.5, 4800)), 1e-4);
}

// A loud burr and loud beeps: their plain sum leaves [-1, 1]; the mixer's never does.
TEST(DrillMixer, SumNeverClipsWithAlertsOn) {
  BurrSoundModel loud;
  loud.idle_level = 1.0;
  loud.cutting_level = 1.0;
  loud.noise_level = 1.0;
  AlertToneModel beep;
  beep.level = 1.0;
  DrillMixer mixer(loud, beep);
  BurrSound burr(loud);
  AlertTone alert(beep);
  const BurrState state = cutting(1.5, 2.0, 50.0);
  mixer.burr().setState(state);
  burr.setState(state);
  mixer.alert().setRepeating(true, 8.0);
  alert.setRepeating(true, 8.0);
  std::vector<float> mixed(48000), sum(48000, 0.0f);
  mixer.render(mixed);
  burr.mixInto(sum);
  alert.mixInto(sum);
  double raw_peak = 0.0, peak = 0.0;
  for (std::size_t i = 0; i < mixed.size(); ++i) {
    raw_peak = std::max(raw_peak, std::abs(static_cast<double>(sum[i])));
    peak = std::max(peak, std::abs(static_cast<double>(mixed[i])));
    ASSERT_TRUE(std::isfinite(mixed[i]));
  }
  std::cout << "raw sum peak " << raw_peak << ", mixed peak " << peak << ", limited samples "
            << mixer.limiter().limitedSamples() << "\n";
  EXPECT_GT(raw_peak, 1.5) << "the case must need the limiter";
  EXPECT_LE(peak, 0.98 + 1e-6);
  EXPECT_GT(peak, 0.9) << "limited, not silenced";
  EXPECT_GT(mixer.limiter().limitedSamples(), 0u);
  // The limiter alone: non-finite input becomes 0, anything else ends within the threshold.
  PeakLimiter limiter(kFs, 0.5);
  std::vector<float> odd{std::nanf(""), 1e30f, -3.0f, 0.25f, INFINITY};
  limiter.process(odd);
  for (float v : odd) EXPECT_LE(std::abs(v), 0.5f);
  EXPECT_EQ(odd[0], 0.0f);
}

TEST(AlertTone, BeepsAtTheSetRateAndEndsWhole) {
  AlertTone alert;
  alert.setRepeating(true, 5.0);
  std::vector<float> x(48000, 0.0f);
  alert.mixInto(x);
  int onsets = 0;
  for (std::size_t i = 1; i < x.size(); ++i) onsets += x[i - 1] == 0.0f && x[i] != 0.0f && (i < 2 || x[i - 2] == 0.0f);
  EXPECT_EQ(onsets, 5) << "one beep each 0.2 s";
  // Switched off mid-beep: it ends on its fade, none starts after.
  alert.setRepeating(true, 5.0);
  std::vector<float> y(480, 0.0f);
  alert.mixInto(y);
  alert.setRepeating(false);
  std::vector<float> z(48000, 0.0f);
  alert.mixInto(z);
  EXPECT_FALSE(alert.sounding());
  std::size_t last = 0;
  for (std::size_t i = 0; i < z.size(); ++i)
    if (z[i] != 0.0f) last = i;
  EXPECT_LT(last, static_cast<std::size_t>(0.08 * kFs)) << "only the beep that was sounding";
  EXPECT_LT(oracle::maxJump(z), 0.3 * 2.0 * oracle::kPi * 1000.0 / kFs * 1.01) << "no click as it ends";
}

// A low burr (400 Hz) without noise: the tone's own largest step between samples is known
// (sum of amplitude x 2 pi f / fs over its partials), so a click stands out. The same steps
// without smoothing must click (the check can fail).
TEST(BurrSound, ParameterStepsMakeNoClick) {
  BurrSoundModel model;
  model.nominal_speed_rpm = 12000.0;
  model.flutes = 2;
  model.noise_level = 0.0;
  const double w0 = 2.0 * oracle::kPi * 400.0 / kFs;
  const double amplitude = model.idle_level + model.cutting_level;
  const double bound = amplitude * (w0 + model.second_harmonic * 2.0 * w0 + model.third_harmonic * 3.0 * w0 +
                                    model.whine_level * w0 / 2.0);
  const auto render_steps = [](BurrSound& sound) {
    std::vector<float> all;
    for (const BurrState& s : {BurrState{}, cutting(0.0, 0.6, 0.0), cutting(3.0, 0.6, 0.0), cutting(3.0, 2.0, 0.0),
                               cutting(3.0, 2.0, 30.0), cutting(0.0, 2.0, 0.0), BurrState{}}) {
      sound.setState(s);
      std::vector<float> block(4801);  // steps fall on varied phases
      sound.render(block);
      all.insert(all.end(), block.begin(), block.end());
    }
    return all;
  };
  BurrSound smooth(model);
  const std::vector<float> x = render_steps(smooth);
  std::cout << "largest jump " << oracle::maxJump(x) << " (tone's own bound " << bound << "), second difference "
            << oracle::maxSecondDifference(x) << "\n";
  EXPECT_LE(oracle::maxJump(x), 1.1 * bound);
  EXPECT_LT(oracle::maxSecondDifference(x), 0.01);
  BurrSoundModel abrupt = model;
  abrupt.mechanical_time_constant_s = 0.0;
  abrupt.level_time_constant_s = 0.0;
  abrupt.gate_time_constant_s = 0.0;
  BurrSound hard(abrupt);
  const std::vector<float> y = render_steps(hard);
  std::cout << "without smoothing: largest jump " << oracle::maxJump(y) << ", second difference "
            << oracle::maxSecondDifference(y) << "\n";
  EXPECT_GT(oracle::maxSecondDifference(y), 0.03);
}

TEST(DrillMixer, RenderingAllocatesNothing) {
  DrillMixer mixer;
  std::vector<float> block(512);
  vh::test::AllocationGuard guard;
  for (int i = 0; i < 200; ++i) {
    mixer.burr().setState(cutting(0.01 * i, 0.6 + 0.01 * i, 0.1 * i));
    mixer.alert().setRepeating(i % 50 < 25, 6.0);
    if (i == 100) mixer.alert().beep();
    mixer.render(block);
  }
  EXPECT_EQ(guard.count(), 0u);
}

TEST(BurrSound, BadModelIsRefusedNamingTheField) {
  BurrSoundModel m;
  m.flutes = 0;
  try {
    BurrSound s(m);
    FAIL() << "no exception";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("flutes"), std::string::npos) << e.what();
  }
  BurrSoundModel n;
  n.stall_torque_Nm = -1.0;
  EXPECT_THROW(BurrSound{n}, std::invalid_argument);
  AlertToneModel a;
  a.frequency_Hz = 30000.0;
  EXPECT_THROW(AlertTone{a}, std::invalid_argument);
  BurrSoundModel r;
  r.sample_rate_Hz = 44100.0;
  EXPECT_THROW(DrillMixer(r, AlertToneModel{}), std::invalid_argument) << "rates differ";
}

// Ticks at a rate that does not divide the sample rate: the file lasts ticks / rate exactly,
// its rate is the mixer's, and the push lowers its pitch.
// A WAV whose writing fails (a full disk: the process's file size limit at 64 kB, 2 s of 48 kHz
// 16-bit sound is 192 kB) or that is abandoned without close() (an exception, a kill) leaves
// nothing at its path and nothing beside it: before, the first looked like a valid 0.13 s sound
// and a killed one declared 0 bytes over the audio. A whole one is renamed into place; a link
// at the path is refused, never replaced.
TEST(WavWriter, OnlyAWholeSoundIsEverAtItsPath) {
  const auto dir = std::filesystem::path(VH_TEST_OUTPUT_DIR) / ("wav-" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  const std::vector<float> second(48000, 0.25f);
  {
    WavWriter whole(dir / "whole.wav", 48000.0);
    whole.write(second);
    EXPECT_FALSE(std::filesystem::exists(dir / "whole.wav")) << "not there until whole";
    whole.close();
  }
  EXPECT_EQ(readWav(dir / "whole.wav").frames(), 48000u);
  {
    WavWriter abandoned(dir / "abandoned.wav", 48000.0);
    abandoned.write(second);
  }  // destroyed without close()
  EXPECT_FALSE(std::filesystem::exists(dir / "abandoned.wav"));
  {
    ::signal(SIGXFSZ, SIG_IGN);
    rlimit old{};
    ::getrlimit(RLIMIT_FSIZE, &old);
    const rlimit small{64 * 1024, old.rlim_max};
    ::setrlimit(RLIMIT_FSIZE, &small);
    bool failed = false;
    try {
      WavWriter full(dir / "full.wav", 48000.0);
      full.write(second);
      full.write(second);
      full.close();
    } catch (const std::runtime_error& e) {
      failed = std::string(e.what()).find("full.wav: cannot write the sound") != std::string::npos;
    }
    ::setrlimit(RLIMIT_FSIZE, &old);
    ::signal(SIGXFSZ, SIG_DFL);
    EXPECT_TRUE(failed) << "the failed write is an error naming the file";
  }
  EXPECT_FALSE(std::filesystem::exists(dir / "full.wav"));
  std::filesystem::create_symlink(dir / "whole.wav", dir / "link.wav");
  EXPECT_THROW(WavWriter(dir / "link.wav", 48000.0), std::runtime_error);
  std::vector<std::string> names;
  for (const auto& e : std::filesystem::directory_iterator(dir)) names.push_back(e.path().filename().string());
  std::sort(names.begin(), names.end());
  EXPECT_EQ(names, (std::vector<std::string>{"link.wav", "whole.wav"})) << "no partial file left beside them";
}

TEST(TickSoundWriter, WritesTheTicksSoundAtTheirPace) {
  const auto path = std::filesystem::path(VH_TEST_OUTPUT_DIR) / "tick_sound.wav";
  std::filesystem::remove(path);
  const double tick_rate = 1024.0;
  TickSoundWriter writer(path, tick_rate);
  for (int i = 0; i < 1024; ++i) writer.tick(cutting(0.0, 0.6, 0.0), false);  // 1 s free
  for (int i = 0; i < 1024; ++i) writer.tick(cutting(4.0, 0.6, 5.0), i == 100);  // 1 s pushing, one alert
  writer.close();
  const WavData wav = readWav(path);
  EXPECT_EQ(wav.sample_rate_Hz, 48000.0);
  EXPECT_EQ(wav.channels, 1);
  EXPECT_EQ(wav.frames(), 96000u);
  EXPECT_EQ((std::filesystem::status(path).permissions() & std::filesystem::perms::others_read),
            std::filesystem::perms::none);
  const std::span<const float> all(wav.samples);
  const double free_f = oracle::peakFrequency_Hz(all.subspan(40000, kWindow), kFs, 100.0, 20000.0);
  const double pushed_f = oracle::peakFrequency_Hz(all.subspan(86000, kWindow), kFs, 100.0, 20000.0);
  std::cout << "WAV: free " << free_f << " Hz, pushing 4 N " << pushed_f << " Hz\n";
  EXPECT_NEAR(free_f, 8000.0, 160.0);
  const double pushed_expected = expectedFundamental_Hz(BurrSoundModel{}, 4.0, 0.6);
  EXPECT_NEAR(pushed_f, pushed_expected, 0.01 * pushed_expected);
  EXPECT_THROW(TickSoundWriter(std::filesystem::path(VH_TEST_OUTPUT_DIR) / "no-such-folder" / "x.wav", 1000.0),
               std::runtime_error);
}

}  // namespace
}  // namespace vh::audio
