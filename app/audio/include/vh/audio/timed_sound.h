#pragma once
/// @file
/// A sound from time-stamped burr states (a recording's records, each the state of one servo
/// tick), rendered block by block through a DrillMixer: the sound track of an exported video.
///
/// Timing: state k holds over output frames [frameAt(t_k), frameAt(t_k+1)), frameAt(t) =
/// floor((t - t_0) fs + 1e-6), the last state for one tick period and on after it (a video may
/// end up to a frame period later). For ticks at i / rate these are exactly the frames of
/// TickSoundWriter (tick_sound.h), so a recording of a headless run sounds as `run --audio`
/// wrote it, sample for sample.

#include <cstdint>
#include <span>
#include <vector>

#include "vh/audio/drill_mixer.h"

namespace vh::audio {

/// One tick's burr and alert from its time on.
struct TimedBurrState {
  double time_s = 0.0;  ///< When it starts [s] (a record's time_s), not decreasing from one to the next.
  BurrState burr;       ///< The burr's state.
  bool alert = false;   ///< The alert beeps (AlertTone::setRepeating()).
};

/// Renders a sequence of TimedBurrState (see the file comment).
class TimedSound {
 public:
  /// @param states in time order (copied); empty: silence. @param tick_period_s how long the
  /// last state holds before the end of the sequence [s], > 0. @param alert_rate_Hz beeps per
  /// second while a state's alert is on [Hz].
  /// @throws std::invalid_argument for a period out of range, times that decrease or are not
  ///         finite, and as DrillMixer's constructor.
  TimedSound(std::vector<TimedBurrState> states, double tick_period_s, const BurrSoundModel& burr = {},
             const AlertToneModel& alert = {}, double alert_rate_Hz = 4.0);

  /// Renders the next out.size() frames (mono, in [-1, 1]); past the end, the last state goes on.
  /// No allocation, no exception.
  void render(std::span<float> out) noexcept;
  /// Renders and drops the frames up to `frame` (a video that starts after the first state):
  /// the smoothed speed and levels there are as they were in the session. No-op when at or past it.
  void skipTo(std::uint64_t frame) noexcept;

  /// The output frame at time t_s [s] (see the file comment; 0 before the first state).
  std::uint64_t frameAt(double t_s) const noexcept;
  /// Frames until the last state's tick period ends.
  std::uint64_t frames() const noexcept { return end_frame_; }
  std::uint64_t frame() const noexcept { return frame_; }  ///< Frames rendered so far.
  double sampleRate_Hz() const noexcept { return mixer_.sampleRate_Hz(); }
  DrillMixer& mixer() noexcept { return mixer_; }

 private:
  std::vector<TimedBurrState> states_;
  DrillMixer mixer_;
  double alert_rate_Hz_;
  std::uint64_t end_frame_ = 0;
  std::uint64_t frame_ = 0;          // frames rendered
  std::size_t next_ = 0;             // the next state to apply
  std::uint64_t next_frame_ = 0;     // where it starts
};

}  // namespace vh::audio
