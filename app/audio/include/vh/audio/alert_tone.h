#pragma once
/// @file
/// The alert: short beeps (a sine with raised-cosine edges, so a beep never clicks), one at a
/// time or repeated at a set rate while an alert lasts (a critical segment touched or cut).
/// Mixed with the burr on the same mixer (drill_mixer.h). One thread; mixInto() never
/// allocates, throws or locks.

#include <cstdint>
#include <span>

namespace vh::audio {

/// The beep's constants.
struct AlertToneModel {
  double sample_rate_Hz = 48000.0;  ///< Output rate [Hz], 8 kHz to 384 kHz.
  double frequency_Hz = 1000.0;     ///< Pitch of the beep [Hz], below half the sample rate.
  double beep_s = 0.08;             ///< Length of one beep, edges included [s], 10 ms to 1 s.
  double ramp_s = 0.005;            ///< Raised-cosine fade in and out [s], at most half a beep.
  double level = 0.3;               ///< Amplitude, in [0, 1].
};

/// Beeps on demand.
class AlertTone {
 public:
  /// @throws std::invalid_argument naming the field for a constant outside its range.
  explicit AlertTone(const AlertToneModel& model = {});

  /// While `on`, beeps `rate_Hz` times a second [Hz] (clamped to 0.5 Hz and to one beep plus a
  /// gap as long as its fades), the first from the next sample when it was off. Off: the beep
  /// sounding ends whole, no other starts. A non-finite rate counts as 4 Hz.
  void setRepeating(bool on, double rate_Hz = 4.0) noexcept;
  /// One beep from the next sample, unless one is sounding.
  void beep() noexcept;
  /// Whether a beep is sounding now.
  bool sounding() const noexcept { return beep_sample_ >= 0; }
  bool repeating() const noexcept { return repeating_; }

  /// Adds gain times the next out.size() samples to out. No allocation, no exception, no lock.
  void mixInto(std::span<float> out, float gain = 1.0f) noexcept;

 private:
  AlertToneModel model_;
  std::int64_t beep_samples_ = 0, ramp_samples_ = 0, min_period_samples_ = 0;
  std::int64_t beep_sample_ = -1;      // samples into the beep sounding; -1: none
  std::int64_t to_next_beep_ = 0;      // while repeating: samples until the next beep starts
  std::int64_t period_samples_ = 0;
  bool repeating_ = false;
  double phase_ = 0.0;                 // cycles [0, 1)
};

}  // namespace vh::audio
