#pragma once
/// @file
/// A session's sound from its servo ticks: each tick's burr state and alert hold for one tick
/// period, rendered through a DrillMixer into a WAV file (`volume-haptics run --audio`). Tick i
/// (0-based) covers output frames [floor(i fs / rate), floor((i + 1) fs / rate)), so the sound
/// lasts exactly ticks / rate seconds and never drifts from the ticks, whatever the ratio of
/// the two rates.

#include <cstdint>
#include <filesystem>
#include <vector>

#include "vh/audio/drill_mixer.h"
#include "vh/audio/wav_file.h"

namespace vh::audio {

/// Renders ticks into a WAV file, block by block.
class TickSoundWriter {
 public:
  /// @param tick_rate_Hz the servo rate the ticks come at [Hz], > 0 and finite.
  /// @param alert_rate_Hz beeps per second while a tick's alert is on [Hz].
  /// @throws std::invalid_argument for a tick rate out of range and as DrillMixer's constructor;
  ///         std::runtime_error as WavWriter's.
  TickSoundWriter(const std::filesystem::path& wav, double tick_rate_Hz, const BurrSoundModel& burr = {},
                  const AlertToneModel& alert = {}, double alert_rate_Hz = 4.0);

  /// One tick: `state` and `alert` (the alert beeping, AlertTone::setRepeating()) from now on,
  /// rendered for one tick period. No allocation (the block buffer is sized at construction).
  /// @throws std::runtime_error naming the file when a write fails.
  void tick(const BurrState& state, bool alert);
  /// Writes what is buffered and closes the file. @throws std::runtime_error naming the file.
  void close();

  std::uint64_t ticks() const noexcept { return ticks_; }
  std::uint64_t frames() const noexcept { return frames_; }  ///< Frames rendered so far.
  DrillMixer& mixer() noexcept { return mixer_; }

 private:
  void flush();

  DrillMixer mixer_;
  WavWriter wav_;
  double tick_rate_Hz_, alert_rate_Hz_;
  std::uint64_t ticks_ = 0, frames_ = 0;
  std::vector<float> block_;  // rendered, not yet written
  std::size_t filled_ = 0;
};

}  // namespace vh::audio
