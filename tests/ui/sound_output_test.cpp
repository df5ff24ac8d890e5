// The window's sound (ui/sound_output.h) on Qt's offscreen platform, with or without an audio
// output: without one the window carries on silent and says so once; the stream the sink would
// pull follows the snapshots (pitch measured with the audio tests' own DFT: free running, then
// pushing), fades out with the checkbox, and carries the alert beep.
#include "vh/ui/sound_output.h"

#include <cmath>
#include <iostream>
#include <vector>

#include <QAudioDevice>
#include <QMediaDevices>
#include <QSignalSpy>

#include <gtest/gtest.h>

#include "spectrum_oracle.h"
#include "vh/runtime/haptic_snapshot.h"

namespace vh::ui {
namespace {

constexpr double kFs = SoundOutput::kSampleRate_Hz;

// Snapshots at 60 Hz for `seconds`, each followed by what a sink pulls in one frame (800
// samples): the samples pulled.
std::vector<float> play(SoundOutput& sound, runtime::HapticSnapshot& snap, double seconds, double eroded_mm3_per_s = 0.0) {
  std::vector<float> pulled;
  const int frames = static_cast<int>(std::lround(seconds * 60.0));
  std::vector<float> chunk(800);
  for (int i = 0; i < frames; ++i) {
    snap.time_ns += 16666667;
    snap.burr_eroded_mm3 += eroded_mm3_per_s / 60.0;
    sound.follow(snap);
    const qint64 got = sound.source()->read(reinterpret_cast<char*>(chunk.data()), 800 * 4);
    EXPECT_EQ(got, 800 * 4) << "the stream never stops";
    pulled.insert(pulled.end(), chunk.begin(), chunk.end());
  }
  return pulled;
}

double pitch(const std::vector<float>& x) {
  return audio::oracle::peakFrequency_Hz(std::span<const float>(x).last(8192), kFs, 100.0, 20000.0);
}

TEST(SoundOutput, WithoutAnOutputTheWindowCarriesOnSilentAndSaysSoOnce) {
  SoundOutput sound;
  QSignalSpy said(&sound, &SoundOutput::message);
  sound.setBurrEnabled(true);
  sound.start();
  sound.start();
  runtime::HapticSnapshot snap;
  snap.burr_on = true;
  for (int i = 0; i < 10; ++i) {
    snap.time_ns += 16666667;
    sound.follow(snap);
  }
  sound.beep();
  if (!QMediaDevices::audioOutputs().isEmpty() && sound.playing()) {
    GTEST_SKIP() << "this machine has an audio output (" << QMediaDevices::defaultAudioOutput().description().toStdString()
                 << "): it plays; the silent path is not taken";
  }
  EXPECT_FALSE(sound.playing());
  ASSERT_EQ(said.count(), 1) << "once, however often it is asked";
  const QString text = said.at(0).at(0).toString();
  std::cout << "message: " << text.toStdString() << "\n";
  EXPECT_TRUE(text.startsWith("Sound off: ")) << text.toStdString();
  EXPECT_EQ(sound.ring().size(), 0u) << "nothing rendered for no one";
}

TEST(SoundOutput, TheStreamFollowsTheBurrTheCheckboxAndTheAlert) {
  SoundOutput sound;
  sound.renderWithoutOutput();
  sound.setBurr(80000.0, 0.0025);
  sound.setBurrEnabled(true);
  runtime::HapticSnapshot snap;
  snap.burr_on = true;
  const std::vector<float> free = play(sound, snap, 0.5);
  snap.burr_force_N = 4.0;
  snap.burr_specific_energy_J_per_mm3 = 0.6;
  const std::vector<float> pushing = play(sound, snap, 0.5, 10.0);
  // vh::audio's motor line: 6 flutes x 80,000 rpm / 60 free; x (1 - 0.2 x 4 N x 2.5 mm / 10 mN*m) pushing.
  std::cout << "pulled stream: free " << pitch(free) << " Hz, pushing 4 N " << pitch(pushing) << " Hz\n";
  EXPECT_NEAR(pitch(free), 8000.0, 160.0);
  EXPECT_NEAR(pitch(pushing), 6400.0, 128.0);
  EXPECT_GT(audio::oracle::rms(std::span<const float>(pushing).last(8192)),
            1.3 * audio::oracle::rms(std::span<const float>(free).last(8192)))
      << "louder while removing 10 mm^3/s";
  sound.setBurrEnabled(false);
  const std::vector<float> off = play(sound, snap, 0.5);
  EXPECT_LT(audio::oracle::rms(std::span<const float>(off).last(8192)), 1e-4) << "the checkbox fades it out";
  sound.beep();
  const std::vector<float> beep = play(sound, snap, 0.25);
  std::cout << "alert: " << pitch(beep) << " Hz\n";
  EXPECT_NEAR(pitch(beep), 1000.0, 20.0);
  // A dry ring: silence, counted.
  std::vector<float> dry(48000);
  EXPECT_EQ(sound.source()->read(reinterpret_cast<char*>(dry.data()), 48000 * 4), 48000 * 4);
  EXPECT_GT(sound.ring().underruns(), 0u);
}

}  // namespace
}  // namespace vh::ui
