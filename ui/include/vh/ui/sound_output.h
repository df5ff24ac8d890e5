#pragma once
/// @file
/// The window's sound: the drilling burr (vh::audio's synthesized model: its pitch falls with the
/// push and the hardness of what it cuts, its level rises with the removal rate) and the alert
/// beeps, on one mixer, played through Qt Multimedia.
///
/// Data flow: the view's haptic snapshot (about 60 Hz, GUI thread) -> follow() sets the burr's
/// state and renders the mixer's samples until a lock-free ring (vh::audio::SampleRing) holds
/// kLead_s of sound -> a QAudioSink in pull mode reads the ring through a QIODevice (silence
/// when it runs dry). The mixer runs on the GUI thread only; the ring is the one thing the two
/// sides share. Without an audio output (none, or one that fails) the window carries on silent
/// and says so once (message()); then beep() falls back to QApplication::beep().

#include <cstdint>
#include <memory>
#include <vector>

#include <QElapsedTimer>
#include <QObject>
#include <QString>

#include "vh/audio/drill_mixer.h"
#include "vh/audio/sample_ring.h"

class QAudioSink;
class QIODevice;

namespace vh::runtime {
struct HapticSnapshot;
}

namespace vh::ui {

class SoundOutput : public QObject {
  Q_OBJECT

 public:
  static constexpr double kSampleRate_Hz = 48000.0;
  /// Sound rendered ahead of the output [s]: the ring holds this much after each follow(); the
  /// snapshot-to-sound latency is about this plus the sink's own buffer.
  static constexpr double kLead_s = 0.08;

  explicit SoundOutput(QObject* parent = nullptr);
  ~SoundOutput() override;

  /// Opens the default audio output (48 kHz mono, float or 16-bit). None, or one that refuses the
  /// format or stops with an error: the sound stays off and message() says so, once.
  void start();
  /// True while a sink plays the ring.
  bool playing() const noexcept { return sink_ != nullptr; }

  /// The burr's sound on or off (the Segments panel's "Burr sound"); off, the burr fades out.
  void setBurrEnabled(bool on) noexcept { burr_enabled_ = on; }
  bool burrEnabled() const noexcept { return burr_enabled_; }
  /// The scene's burr: no-load speed [rpm] and radius [m]. A change rebuilds the mixer (a new
  /// sound starts); the same values do nothing.
  void setBurr(double speed_rpm, double radius_m);

  /// Follows the haptic threads' `snapshot`: the burr on (HapticSnapshot::burr_on and the
  /// checkbox), the force and hardness it cut with, and the removal rate (the eroded volume's
  /// growth since the last snapshot over the time between them); then fills the ring to kLead_s.
  /// Renders only while playing, or always after renderWithoutOutput() (tests).
  void follow(const runtime::HapticSnapshot& snapshot);
  /// One alert beep over the burr (a critical segment touched); without an output,
  /// QApplication::beep().
  void beep();
  /// The proximity cue: while `on`, the alert beeps `rate_Hz` times a second over the burr
  /// (audio::AlertTone::setRepeating()); off stops it. Without an output, silent.
  void setProximityCue(bool on, double rate_Hz);

  /// Tests: fill the ring on follow() although nothing plays it, and read it through source().
  void renderWithoutOutput() noexcept { render_always_ = true; }
  /// What the sink reads (format float, mono, kSampleRate_Hz): the ring, silence when it is dry.
  QIODevice* source() const noexcept { return source_; }
  const audio::SampleRing& ring() const noexcept { return ring_; }
  const audio::DrillMixer& mixer() const noexcept { return *mixer_; }

 signals:
  /// A note for the status bar (e.g. that there is no audio output).
  void message(const QString& text, int timeout_ms);

 private:
  void fillRing();
  void stopWithNotice(const QString& why);

  std::unique_ptr<audio::DrillMixer> mixer_;
  audio::SampleRing ring_;
  std::vector<float> block_;  // rendered before it goes into the ring
  QIODevice* source_ = nullptr;
  QAudioSink* sink_ = nullptr;
  bool burr_enabled_ = false;
  bool render_always_ = false;
  bool told_ = false;  // message() said the sound is off
  double speed_rpm_ = 0.0, radius_m_ = 0.0;
  double eroded_mm3_ = 0.0;       // the last snapshot's
  std::int64_t eroded_time_ns_ = 0;
  double removal_rate_mm3_per_s_ = 0.0;
  QElapsedTimer last_follow_;  // since the last follow(): a stale snapshot fades the burr out
};

}  // namespace vh::ui
