#pragma once
// The tests' own measurement of a rendered sound, independent of the synthesis: the strongest
// frequency by a plain DFT (Hann window, every bin of a band, then a fine scan of the DTFT around
// the best bin), RMS, and the largest first and second differences between samples.
#include <algorithm>
#include <cmath>
#include <complex>
#include <cstddef>
#include <span>
#include <vector>

namespace vh::audio::oracle {

inline constexpr double kPi = 3.14159265358979323846;

/// |DTFT|^2 of the Hann-windowed x at frequency f [Hz] (sample rate fs [Hz]).
inline double windowedPower(std::span<const float> x, double fs, double f_Hz) {
  const std::size_t n = x.size();
  std::complex<double> sum = 0.0;
  const std::complex<double> step = std::polar(1.0, -2.0 * kPi * f_Hz / fs);
  std::complex<double> rot = 1.0;
  for (std::size_t i = 0; i < n; ++i) {
    const double w = 0.5 - 0.5 * std::cos(2.0 * kPi * static_cast<double>(i) / static_cast<double>(n));
    sum += w * static_cast<double>(x[i]) * rot;
    rot *= step;
    if ((i & 1023u) == 1023u) rot /= std::abs(rot);  // keep the rotation on the unit circle
  }
  return std::norm(sum);
}

/// The frequency [Hz] of the largest periodogram peak of x between lo_Hz and hi_Hz: each DFT bin
/// of the band (a table of cos / sin of 2 pi k / n, n a power of two), then the DTFT sampled
/// every bin / 200 over the best bin's neighbours. Accurate to well under a bin for one
/// dominant partial.
inline double peakFrequency_Hz(std::span<const float> x, double fs, double lo_Hz, double hi_Hz) {
  const std::size_t n = x.size();  // a power of two
  std::vector<double> windowed(n), c(n), s(n);
  for (std::size_t i = 0; i < n; ++i) {
    windowed[i] = (0.5 - 0.5 * std::cos(2.0 * kPi * static_cast<double>(i) / static_cast<double>(n))) * x[i];
    c[i] = std::cos(2.0 * kPi * static_cast<double>(i) / static_cast<double>(n));
    s[i] = std::sin(2.0 * kPi * static_cast<double>(i) / static_cast<double>(n));
  }
  const double bin = fs / static_cast<double>(n);
  const auto k_lo = static_cast<std::size_t>(std::max(1.0, std::floor(lo_Hz / bin)));
  const auto k_hi = static_cast<std::size_t>(std::min(static_cast<double>(n / 2 - 1), std::ceil(hi_Hz / bin)));
  std::size_t best_k = k_lo;
  double best = -1.0;
  for (std::size_t k = k_lo; k <= k_hi; ++k) {
    double re = 0.0, im = 0.0;
    for (std::size_t i = 0; i < n; ++i) {
      const std::size_t j = (k * i) & (n - 1);
      re += windowed[i] * c[j];
      im -= windowed[i] * s[j];
    }
    const double p = re * re + im * im;
    if (p > best) {
      best = p;
      best_k = k;
    }
  }
  double best_f = static_cast<double>(best_k) * bin;
  best = windowedPower(x, fs, best_f);
  for (int step = -200; step <= 200; ++step) {
    const double f = (static_cast<double>(best_k) + step / 200.0) * bin;
    const double p = windowedPower(x, fs, f);
    if (p > best) {
      best = p;
      best_f = f;
    }
  }
  return best_f;
}

inline double rms(std::span<const float> x) {
  double sum = 0.0;
  for (float v : x) sum += static_cast<double>(v) * v;
  return x.empty() ? 0.0 : std::sqrt(sum / static_cast<double>(x.size()));
}

/// max |x[i] - x[i-1]|.
inline double maxJump(std::span<const float> x) {
  double m = 0.0;
  for (std::size_t i = 1; i < x.size(); ++i) m = std::max(m, std::abs(static_cast<double>(x[i]) - x[i - 1]));
  return m;
}

/// max |x[i] - 2 x[i-1] + x[i-2]|: near 0 for smooth low tones, the size of the step at a click.
inline double maxSecondDifference(std::span<const float> x) {
  double m = 0.0;
  for (std::size_t i = 2; i < x.size(); ++i)
    m = std::max(m, std::abs(static_cast<double>(x[i]) - 2.0 * x[i - 1] + x[i - 2]));
  return m;
}

}  // namespace vh::audio::oracle
