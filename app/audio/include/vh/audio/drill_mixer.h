#pragma once
/// @file
/// The drilling sound's mixer: the burr (burr_sound.h) and the alert (alert_tone.h) summed with
/// their gains, then a peak limiter so that the sum never clips.
///
/// Limiter: feed-forward, instantaneous attack and exponential release (Giannoulis, Massberg
/// and Reiss, "Digital Dynamic Range Compressor Design - A Tutorial and Analysis", J. Audio Eng.
/// Soc. 60(6), 2012: a limiter is a compressor of infinite ratio). The gain of a
/// sample is at most threshold / |x|, so every output sample lies in [-threshold, threshold];
/// it recovers towards 1 with the release time constant. A non-finite sample becomes 0.
/// One thread; render() and process() never allocate, throw or lock.

#include <cstdint>
#include <span>

#include "vh/audio/alert_tone.h"
#include "vh/audio/burr_sound.h"

namespace vh::audio {

/// A peak limiter (see the file comment).
class PeakLimiter {
 public:
  /// @param threshold highest output magnitude, in (0, 1]. @param release_s gain recovery time constant [s], >= 0.
  /// @throws std::invalid_argument for a rate, threshold or release out of range.
  PeakLimiter(double sample_rate_Hz, double threshold = 0.98, double release_s = 0.05);

  /// Limits `samples` in place: each ends in [-threshold, threshold]. No allocation, no exception.
  void process(std::span<float> samples) noexcept;
  double gain() const noexcept { return gain_; }          ///< The gain now, in (0, 1].
  double threshold() const noexcept { return threshold_; }
  /// Samples so far whose gain was below 1 (the limiter acted).
  std::uint64_t limitedSamples() const noexcept { return limited_; }

 private:
  double threshold_, a_release_, gain_ = 1.0;
  std::uint64_t limited_ = 0;
};

/// The burr and the alert on one output.
class DrillMixer {
 public:
  /// @param limiter_threshold the peak limiter's threshold, in (0, 1].
  /// @throws std::invalid_argument as BurrSound's, AlertTone's and PeakLimiter's constructors, and
  ///         when the two models' sample rates differ.
  explicit DrillMixer(const BurrSoundModel& burr = {}, const AlertToneModel& alert = {}, double limiter_threshold = 0.98);

  BurrSound& burr() noexcept { return burr_; }
  AlertTone& alert() noexcept { return alert_; }
  const PeakLimiter& limiter() const noexcept { return limiter_; }
  double sampleRate_Hz() const noexcept { return burr_.model().sample_rate_Hz; }

  /// The burr's and the alert's gains, in [0, 4] (clamped; non-finite: unchanged), from the next
  /// block on. To fade the burr out without a click, switch it off (BurrState::on) instead.
  void setGains(float burr, float alert) noexcept;

  /// Renders out.size() samples: the burr plus the alert, limited. No allocation, no exception.
  void render(std::span<float> out) noexcept;

 private:
  BurrSound burr_;
  AlertTone alert_;
  PeakLimiter limiter_;
  float burr_gain_ = 1.0f, alert_gain_ = 1.0f;
};

}  // namespace vh::audio
