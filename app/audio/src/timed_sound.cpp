#include "vh/audio/timed_sound.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace vh::audio {

TimedSound::TimedSound(std::vector<TimedBurrState> states, double tick_period_s, const BurrSoundModel& burr,
                       const AlertToneModel& alert, double alert_rate_Hz)
    : states_(std::move(states)), mixer_(burr, alert), alert_rate_Hz_(alert_rate_Hz) {
  if (!(std::isfinite(tick_period_s) && tick_period_s > 0.0 && tick_period_s <= 10.0))
    throw std::invalid_argument("TimedSound: tick period: expected > 0 s (at most 10 s)");
  for (std::size_t k = 0; k < states_.size(); ++k) {
    if (!std::isfinite(states_[k].time_s) || (k > 0 && states_[k].time_s < states_[k - 1].time_s))
      throw std::invalid_argument("TimedSound: state " + std::to_string(k) + ": time not finite or before the one before");
  }
  if (!states_.empty()) end_frame_ = frameAt(states_.back().time_s + tick_period_s);
}

std::uint64_t TimedSound::frameAt(double t_s) const noexcept {
  if (states_.empty()) return 0;
  const double x = std::floor((t_s - states_.front().time_s) * mixer_.sampleRate_Hz() + 1e-6);
  return x > 0.0 ? static_cast<std::uint64_t>(x) : 0;
}

void TimedSound::render(std::span<float> out) noexcept {
  std::size_t done = 0;
  while (done < out.size()) {
    // Every state that starts at or before the next frame (those of one frame: the last wins).
    while (next_ < states_.size() && next_frame_ <= frame_) {
      mixer_.burr().setState(states_[next_].burr);
      mixer_.alert().setRepeating(states_[next_].alert, alert_rate_Hz_);
      ++next_;
      next_frame_ = next_ < states_.size() ? frameAt(states_[next_].time_s) : 0;
    }
    std::uint64_t n = out.size() - done;
    if (next_ < states_.size()) n = std::min<std::uint64_t>(n, next_frame_ - frame_);
    mixer_.render(out.subspan(done, static_cast<std::size_t>(n)));
    done += static_cast<std::size_t>(n);
    frame_ += n;
  }
}

void TimedSound::skipTo(std::uint64_t frame) noexcept {
  float block[1024];
  while (frame_ < frame) render(std::span<float>(block, static_cast<std::size_t>(std::min<std::uint64_t>(1024, frame - frame_))));
}

}  // namespace vh::audio
