#include "vh/audio/drill_mixer.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace vh::audio {

PeakLimiter::PeakLimiter(double sample_rate_Hz, double threshold, double release_s) : threshold_(threshold) {
  if (!(std::isfinite(sample_rate_Hz) && sample_rate_Hz >= 8000.0 && sample_rate_Hz <= 384000.0))
    throw std::invalid_argument("PeakLimiter: sample rate: expected 8 kHz to 384 kHz");
  if (!(std::isfinite(threshold) && threshold > 0.0 && threshold <= 1.0))
    throw std::invalid_argument("PeakLimiter: threshold: expected (0, 1]");
  if (!(std::isfinite(release_s) && release_s >= 0.0 && release_s <= 10.0))
    throw std::invalid_argument("PeakLimiter: release: expected 0 to 10 s");
  a_release_ = release_s > 0.0 ? 1.0 - std::exp(-1.0 / (release_s * sample_rate_Hz)) : 1.0;
}

void PeakLimiter::process(std::span<float> samples) noexcept {
  for (float& s : samples) {
    const double x = std::isfinite(s) ? static_cast<double>(s) : 0.0;
    const double magnitude = std::abs(x);
    const double allowed = magnitude > threshold_ ? threshold_ / magnitude : 1.0;
    gain_ = std::min(gain_ + a_release_ * (1.0 - gain_), allowed);  // release towards 1, attack at once
    if (gain_ < 1.0) ++limited_;
    // The clamp only guards against rounding: gain <= threshold / |x| already.
    s = static_cast<float>(std::clamp(x * gain_, -threshold_, threshold_));
  }
}

DrillMixer::DrillMixer(const BurrSoundModel& burr, const AlertToneModel& alert, double limiter_threshold)
    : burr_(burr), alert_(alert), limiter_(burr.sample_rate_Hz, limiter_threshold) {
  if (burr.sample_rate_Hz != alert.sample_rate_Hz)
    throw std::invalid_argument("DrillMixer: the burr's and the alert's sample rates differ");
}

void DrillMixer::setGains(float burr, float alert) noexcept {
  if (std::isfinite(burr)) burr_gain_ = std::clamp(burr, 0.0f, 4.0f);
  if (std::isfinite(alert)) alert_gain_ = std::clamp(alert, 0.0f, 4.0f);
}

void DrillMixer::render(std::span<float> out) noexcept {
  std::fill(out.begin(), out.end(), 0.0f);
  burr_.mixInto(out, burr_gain_);
  alert_.mixInto(out, alert_gain_);
  limiter_.process(out);
}

}  // namespace vh::audio
