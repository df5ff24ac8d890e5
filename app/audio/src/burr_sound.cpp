#include "vh/audio/burr_sound.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace vh::audio {

namespace {

constexpr double kPi = 3.14159265358979323846;
// The noise's band-pass is retuned this often [samples]: f0 moves smoothly, so the filter's
// small steps every third of a millisecond are inaudible.
constexpr int kRetuneSamples = 16;

void require(bool ok, const char* field, const char* range) {
  if (!ok) throw std::invalid_argument(std::string("BurrSoundModel::") + field + ": expected " + range);
}

void checkModel(const BurrSoundModel& m) {
  const auto in = [](double v, double lo, double hi) { return std::isfinite(v) && v >= lo && v <= hi; };
  require(in(m.sample_rate_Hz, 8000.0, 384000.0), "sample_rate_Hz", "8 kHz to 384 kHz");
  require(std::isfinite(m.nominal_speed_rpm) && m.nominal_speed_rpm > 0.0, "nominal_speed_rpm", "> 0");
  require(m.flutes >= 1 && m.flutes <= 64, "flutes", "1 to 64");
  require(std::isfinite(m.burr_radius_m) && m.burr_radius_m > 0.0, "burr_radius_m", "> 0");
  require(in(m.friction_coefficient, 0.0, 1e6), "friction_coefficient", ">= 0");
  require(std::isfinite(m.stall_torque_Nm) && m.stall_torque_Nm > 0.0, "stall_torque_Nm", "> 0");
  require(std::isfinite(m.reference_hardness_J_per_mm3) && m.reference_hardness_J_per_mm3 > 0.0,
          "reference_hardness_J_per_mm3", "> 0");
  require(in(m.min_speed_fraction, 1e-6, 1.0), "min_speed_fraction", "(0, 1]");
  require(in(m.mechanical_time_constant_s, 0.0, 10.0), "mechanical_time_constant_s", "0 to 10 s");
  require(in(m.level_time_constant_s, 0.0, 10.0), "level_time_constant_s", "0 to 10 s");
  require(in(m.gate_time_constant_s, 0.0, 10.0), "gate_time_constant_s", "0 to 10 s");
  require(in(m.idle_level, 0.0, 1.0), "idle_level", "[0, 1]");
  require(in(m.cutting_level, 0.0, 1.0), "cutting_level", "[0, 1]");
  require(std::isfinite(m.half_level_rate_mm3_per_s) && m.half_level_rate_mm3_per_s > 0.0, "half_level_rate_mm3_per_s", "> 0");
  require(in(m.second_harmonic, 0.0, 1.0), "second_harmonic", "[0, 1]");
  require(in(m.third_harmonic, 0.0, 1.0), "third_harmonic", "[0, 1]");
  require(in(m.whine_level, 0.0, 1.0), "whine_level", "[0, 1]");
  require(in(m.noise_level, 0.0, 1.0), "noise_level", "[0, 1]");
  require(in(m.noise_centre_fraction, 1e-3, 10.0), "noise_centre_fraction", "> 0 (at most 10)");
  require(in(m.noise_q, 0.1, 100.0), "noise_q", "0.1 to 100");
  require(m.noise_seed != 0u, "noise_seed", "!= 0");
}

/// Per-sample coefficient of a one-pole smoother with time constant tau_s; 1 (at once) for 0.
double smoothing(double tau_s, double fs) { return tau_s > 0.0 ? 1.0 - std::exp(-1.0 / (tau_s * fs)) : 1.0; }

/// A value counted as 0 when not finite or negative.
double nonNegative(double v) noexcept { return std::isfinite(v) && v > 0.0 ? v : 0.0; }

/// Weight of a partial at `f_Hz`: 1 up to 0.4 fs, fading to 0 at 0.45 fs (no aliasing, and a
/// partial crossing the limit as the pitch moves fades instead of switching).
double belowNyquist(double f_Hz, double fs) noexcept { return std::clamp((0.45 * fs - f_Hz) / (0.05 * fs), 0.0, 1.0); }

}  // namespace

BurrSound::BurrSound(const BurrSoundModel& model) : model_(model), rng_(model.noise_seed) {
  checkModel(model_);
  a_speed_ = smoothing(model_.mechanical_time_constant_s, model_.sample_rate_Hz);
  a_level_ = smoothing(model_.level_time_constant_s, model_.sample_rate_Hz);
  a_gate_ = smoothing(model_.gate_time_constant_s, model_.sample_rate_Hz);
  retuneNoise();
}

double BurrSound::steadySpeed_rpm(const BurrState& state) const noexcept {
  if (!state.on) return 0.0;
  const double hardness = nonNegative(state.specific_energy_J_per_mm3);
  const double torque_Nm = model_.friction_coefficient * nonNegative(state.force_N) * model_.burr_radius_m *
                           hardness / model_.reference_hardness_J_per_mm3;
  const double fraction = std::max(1.0 - torque_Nm / model_.stall_torque_Nm, model_.min_speed_fraction);
  return model_.nominal_speed_rpm * fraction;
}

void BurrSound::setState(const BurrState& state) noexcept {
  target_ = state;
  target_speed_rpm_ = steadySpeed_rpm(state);
  const double rate = nonNegative(state.removal_rate_mm3_per_s);
  const double cutting = rate / (rate + model_.half_level_rate_mm3_per_s);
  target_tone_ = model_.idle_level + model_.cutting_level * cutting;
  target_noise_ = model_.noise_level * cutting;
}

void BurrSound::retuneNoise() noexcept {
  const double fs = model_.sample_rate_Hz;
  const double fc = std::clamp(model_.noise_centre_fraction * fundamental_Hz(), 50.0, 0.45 * fs);
  // Simper's trapezoidal SVF (Cytomic, "Solving the continuous SVF equations using trapezoidal
  // integration", 2013): g = tan(pi fc / fs), k = 1 / Q; the band output times k peaks at 1.
  const double g = std::tan(kPi * fc / fs);
  svf_k_ = 1.0 / model_.noise_q;
  svf_a1_ = 1.0 / (1.0 + g * (g + svf_k_));
  svf_a2_ = g * svf_a1_;
  svf_a3_ = g * svf_a2_;
  // White noise uniform in [-1, 1] (variance 1/3) through a unit-peak band-pass of bandwidth
  // fc / Q keeps about pi (fc / Q) / fs of its power (the resonator's noise bandwidth): scale to
  // unit RMS out.
  const double kept = std::max(kPi * (fc / model_.noise_q) / fs / 3.0, 1e-9);
  noise_gain_ = 1.0 / std::sqrt(kept);
  retune_countdown_ = kRetuneSamples;
}

float BurrSound::next() noexcept {
  const double fs = model_.sample_rate_Hz;
  speed_rpm_ += a_speed_ * (target_speed_rpm_ - speed_rpm_);
  tone_ += a_level_ * (target_tone_ - tone_);
  noise_ += a_level_ * (target_noise_ - noise_);
  gate_ += a_gate_ * ((target_.on ? 1.0 : 0.0) - gate_);
  if (--retune_countdown_ <= 0) retuneNoise();

  const double f_rot = speed_rpm_ / 60.0;
  const double f0 = f_rot * model_.flutes;
  phase_f0_ += f0 / fs;
  phase_f0_ -= std::floor(phase_f0_);
  phase_rot_ += f_rot / fs;
  phase_rot_ -= std::floor(phase_rot_);
  const double w = 2.0 * kPi * phase_f0_;
  double tone = belowNyquist(f0, fs) * std::sin(w) + model_.second_harmonic * belowNyquist(2.0 * f0, fs) * std::sin(2.0 * w) +
                model_.third_harmonic * belowNyquist(3.0 * f0, fs) * std::sin(3.0 * w) +
                model_.whine_level * belowNyquist(f_rot, fs) * std::sin(2.0 * kPi * phase_rot_);

  // xorshift32 (Marsaglia 2003): white noise, uniform in [-1, 1).
  rng_ ^= rng_ << 13;
  rng_ ^= rng_ >> 17;
  rng_ ^= rng_ << 5;
  const double white = static_cast<double>(rng_) / 2147483648.0 - 1.0;
  const double v3 = white - ic2_;
  const double v1 = svf_a1_ * ic1_ + svf_a2_ * v3;
  const double v2 = ic2_ + svf_a2_ * ic1_ + svf_a3_ * v3;
  ic1_ = 2.0 * v1 - ic1_;
  ic2_ = 2.0 * v2 - ic2_;
  const double band = svf_k_ * v1 * noise_gain_;

  return static_cast<float>(gate_ * (tone_ * tone + noise_ * band));
}

void BurrSound::render(std::span<float> out) noexcept {
  for (float& s : out) s = next();
}

void BurrSound::mixInto(std::span<float> out, float gain) noexcept {
  for (float& s : out) s += gain * next();
}

}  // namespace vh::audio
