#include "vh/audio/tick_sound.h"

#include <cmath>
#include <stdexcept>

namespace vh::audio {

namespace {
// Frames buffered before a write: about 85 ms at 48 kHz.
constexpr std::size_t kBlockFrames = 4096;

double checkedTickRate(double tick_rate_Hz) {
  if (!(std::isfinite(tick_rate_Hz) && tick_rate_Hz > 0.0 && tick_rate_Hz <= 1e6))
    throw std::invalid_argument("TickSoundWriter: tick rate: expected > 0 Hz (at most 1 MHz)");
  return tick_rate_Hz;
}
}  // namespace

TickSoundWriter::TickSoundWriter(const std::filesystem::path& wav, double tick_rate_Hz, const BurrSoundModel& burr,
                                 const AlertToneModel& alert, double alert_rate_Hz)
    : mixer_(burr, alert),
      wav_(wav, burr.sample_rate_Hz),
      tick_rate_Hz_(checkedTickRate(tick_rate_Hz)),
      alert_rate_Hz_(alert_rate_Hz),
      block_(kBlockFrames) {}

void TickSoundWriter::tick(const BurrState& state, bool alert) {
  mixer_.burr().setState(state);
  mixer_.alert().setRepeating(alert, alert_rate_Hz_);
  ++ticks_;
  // The frames up to the end of this tick, from the tick count (no drift over a long run).
  const double fs = mixer_.sampleRate_Hz();
  const auto end = static_cast<std::uint64_t>(std::floor(static_cast<double>(ticks_) * fs / tick_rate_Hz_ + 1e-6));
  while (frames_ < end) {
    const std::size_t n = std::min<std::uint64_t>(end - frames_, block_.size() - filled_);
    mixer_.render(std::span<float>(block_.data() + filled_, n));
    filled_ += n;
    frames_ += n;
    if (filled_ == block_.size()) flush();
  }
}

void TickSoundWriter::flush() {
  wav_.write(std::span<const float>(block_.data(), filled_));
  filled_ = 0;
}

void TickSoundWriter::close() {
  flush();
  wav_.close();
}

}  // namespace vh::audio
