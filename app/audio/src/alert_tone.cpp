#include "vh/audio/alert_tone.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace vh::audio {

namespace {

constexpr double kPi = 3.14159265358979323846;

void require(bool ok, const char* field, const char* range) {
  if (!ok) throw std::invalid_argument(std::string("AlertToneModel::") + field + ": expected " + range);
}

}  // namespace

AlertTone::AlertTone(const AlertToneModel& model) : model_(model) {
  const auto in = [](double v, double lo, double hi) { return std::isfinite(v) && v >= lo && v <= hi; };
  require(in(model.sample_rate_Hz, 8000.0, 384000.0), "sample_rate_Hz", "8 kHz to 384 kHz");
  require(std::isfinite(model.frequency_Hz) && model.frequency_Hz > 0.0 && model.frequency_Hz < 0.5 * model.sample_rate_Hz,
          "frequency_Hz", "> 0 and below half the sample rate");
  require(in(model.beep_s, 0.01, 1.0), "beep_s", "10 ms to 1 s");
  require(in(model.ramp_s, 0.0, 0.5 * model.beep_s), "ramp_s", "0 to half the beep");
  require(in(model.level, 0.0, 1.0), "level", "[0, 1]");
  beep_samples_ = std::max<std::int64_t>(1, std::llround(model.beep_s * model.sample_rate_Hz));
  ramp_samples_ = std::llround(model.ramp_s * model.sample_rate_Hz);
  min_period_samples_ = beep_samples_ + std::max<std::int64_t>(ramp_samples_, 1);
  period_samples_ = std::max<std::int64_t>(min_period_samples_, std::llround(model.sample_rate_Hz / 4.0));
}

void AlertTone::setRepeating(bool on, double rate_Hz) noexcept {
  if (!std::isfinite(rate_Hz)) rate_Hz = 4.0;
  rate_Hz = std::max(rate_Hz, 0.5);
  period_samples_ = std::max<std::int64_t>(min_period_samples_, std::llround(model_.sample_rate_Hz / rate_Hz));
  if (on && !repeating_) to_next_beep_ = 0;
  // A shorter period takes effect at once; a longer one after the next beep.
  to_next_beep_ = std::min(to_next_beep_, period_samples_);
  repeating_ = on;
}

void AlertTone::beep() noexcept {
  if (beep_sample_ < 0) {
    beep_sample_ = 0;
    phase_ = 0.0;
  }
}

void AlertTone::mixInto(std::span<float> out, float gain) noexcept {
  const double fs = model_.sample_rate_Hz;
  for (float& s : out) {
    if (repeating_) {
      if (to_next_beep_ <= 0) {
        beep();
        to_next_beep_ = period_samples_;
      }
      --to_next_beep_;
    }
    if (beep_sample_ < 0) continue;
    // Raised-cosine edges: 0 at the beep's first and last sample, 1 between the fades.
    double envelope = 1.0;
    const std::int64_t from_end = beep_samples_ - 1 - beep_sample_;
    const std::int64_t edge = std::min(beep_sample_, from_end);
    if (edge < ramp_samples_) envelope = 0.5 - 0.5 * std::cos(kPi * static_cast<double>(edge) / static_cast<double>(ramp_samples_));
    s += gain * static_cast<float>(model_.level * envelope * std::sin(2.0 * kPi * phase_));
    phase_ += model_.frequency_Hz / fs;
    phase_ -= std::floor(phase_);
    if (++beep_sample_ >= beep_samples_) beep_sample_ = -1;
  }
}

}  // namespace vh::audio
