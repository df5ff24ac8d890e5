#include "vh/ui/sound_output.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>

#include <QApplication>
#include <QAudioDevice>
#include <QAudioFormat>
#include <QAudioSink>
#include <QElapsedTimer>
#include <QIODevice>
#include <QMediaDevices>
#include <QTimer>

#include "vh/runtime/haptic_snapshot.h"

namespace vh::ui {

namespace {

/// What the sink pulls: the ring's samples as float or 16-bit frames, silence where the ring
/// ran dry (counted in its underruns), so the stream never stops.
class RingSource final : public QIODevice {
 public:
  RingSource(audio::SampleRing& ring, QObject* parent) : QIODevice(parent), ring_(ring) {}
  void setInt16(bool int16) noexcept { int16_ = int16; }
  bool isSequential() const override { return true; }

 protected:
  qint64 readData(char* data, qint64 max_bytes) override {
    const qint64 frame_bytes = int16_ ? 2 : 4;
    const qint64 frames = max_bytes / frame_bytes;
    std::array<float, 512> chunk{};
    for (qint64 done = 0; done < frames;) {
      const auto want = static_cast<std::size_t>(std::min<qint64>(static_cast<qint64>(chunk.size()), frames - done));
      const std::size_t got = ring_.pop(std::span<float>(chunk.data(), want));
      if (got < want) {
        std::fill(chunk.begin() + static_cast<std::ptrdiff_t>(got), chunk.begin() + static_cast<std::ptrdiff_t>(want), 0.0f);
        ring_.countUnderrun(want - got);
      }
      char* out = data + done * frame_bytes;
      if (int16_) {
        for (std::size_t i = 0; i < want; ++i) {
          const auto v = static_cast<std::int16_t>(std::lround(std::clamp(chunk[i], -1.0f, 1.0f) * 32767.0f));
          std::memcpy(out + 2 * i, &v, 2);
        }
      } else {
        std::memcpy(out, chunk.data(), want * sizeof(float));
      }
      done += static_cast<qint64>(want);
    }
    return frames * frame_bytes;
  }
  qint64 writeData(const char*, qint64) override { return -1; }

 private:
  audio::SampleRing& ring_;
  bool int16_ = false;
};

audio::BurrSoundModel burrModel(double speed_rpm, double radius_m) {
  audio::BurrSoundModel model;
  model.sample_rate_Hz = SoundOutput::kSampleRate_Hz;
  if (speed_rpm > 0.0 && std::isfinite(speed_rpm)) model.nominal_speed_rpm = speed_rpm;
  if (radius_m > 0.0 && std::isfinite(radius_m)) model.burr_radius_m = radius_m;
  return model;
}

audio::AlertToneModel alertModel() {
  audio::AlertToneModel model;
  model.sample_rate_Hz = SoundOutput::kSampleRate_Hz;
  return model;
}

// A snapshot older than this leaves the burr to fade out (the haptic threads stopped) [ms].
constexpr qint64 kStaleSnapshot_ms = 150;

}  // namespace

SoundOutput::SoundOutput(QObject* parent)
    : QObject(parent),
      mixer_(std::make_unique<audio::DrillMixer>(burrModel(0.0, 0.0), alertModel())),
      ring_(static_cast<std::size_t>(0.5 * kSampleRate_Hz)),
      block_(1024) {
  source_ = new RingSource(ring_, this);
  source_->open(QIODevice::ReadOnly);
}

SoundOutput::~SoundOutput() {
  if (sink_ != nullptr) sink_->stop();
}

void SoundOutput::start() {
  if (sink_ != nullptr || told_) return;
  const QAudioDevice device = QMediaDevices::defaultAudioOutput();
  if (device.isNull()) {
    stopWithNotice("no audio output was found");
    return;
  }
  QAudioFormat format;
  format.setSampleRate(static_cast<int>(kSampleRate_Hz));
  format.setChannelCount(1);
  format.setSampleFormat(QAudioFormat::Float);
  bool int16 = false;
  if (!device.isFormatSupported(format)) {
    format.setSampleFormat(QAudioFormat::Int16);
    int16 = true;
    if (!device.isFormatSupported(format)) {
      stopWithNotice(device.description() + " plays neither float nor 16-bit mono at 48 kHz");
      return;
    }
  }
  static_cast<RingSource*>(source_)->setInt16(int16);
  sink_ = new QAudioSink(device, format, this);
  sink_->setBufferSize(static_cast<qsizetype>(0.05 * kSampleRate_Hz) * (int16 ? 2 : 4));
  connect(sink_, &QAudioSink::stateChanged, this, [this](QAudio::State state) {
    if (sink_ != nullptr && state == QAudio::StoppedState && sink_->error() != QAudio::NoError)
      stopWithNotice("the audio output stopped (error " + QString::number(static_cast<int>(sink_->error())) + ")");
  });
  auto* keep_fed = new QTimer(sink_);  // also between snapshots, and to fade a burr whose snapshots stopped
  keep_fed->setInterval(15);
  connect(keep_fed, &QTimer::timeout, this, [this] {
    if (last_follow_.isValid() && last_follow_.elapsed() > kStaleSnapshot_ms) mixer_->burr().setState({});
    fillRing();
  });
  keep_fed->start();
  fillRing();
  sink_->start(source_);
  if (sink_ != nullptr && sink_->error() != QAudio::NoError)
    stopWithNotice("the audio output " + device.description() + " did not start");
}

void SoundOutput::stopWithNotice(const QString& why) {
  if (sink_ != nullptr) {
    QAudioSink* sink = sink_;
    sink_ = nullptr;
    sink->stop();
    sink->deleteLater();
  }
  if (told_) return;
  told_ = true;
  const QString text = "Sound off: " + why + "; the window carries on silent";
  qWarning("volume-haptics: %s", qPrintable(text));
  emit message(text, 10000);
}

void SoundOutput::setBurr(double speed_rpm, double radius_m) {
  if (speed_rpm == speed_rpm_ && radius_m == radius_m_) return;
  speed_rpm_ = speed_rpm;
  radius_m_ = radius_m;
  mixer_ = std::make_unique<audio::DrillMixer>(burrModel(speed_rpm, radius_m), alertModel());
}

void SoundOutput::follow(const runtime::HapticSnapshot& snapshot) {
  last_follow_.start();
  // The removal rate: the eroded volume's growth over the time between two snapshots (a new
  // drill starts from 0 again: no rate across it).
  if (snapshot.time_ns != 0 && snapshot.time_ns != eroded_time_ns_) {
    if (eroded_time_ns_ != 0 && snapshot.burr_eroded_mm3 >= eroded_mm3_ && snapshot.time_ns > eroded_time_ns_) {
      removal_rate_mm3_per_s_ =
          (snapshot.burr_eroded_mm3 - eroded_mm3_) / (1e-9 * static_cast<double>(snapshot.time_ns - eroded_time_ns_));
    } else {
      removal_rate_mm3_per_s_ = 0.0;
    }
    eroded_mm3_ = snapshot.burr_eroded_mm3;
    eroded_time_ns_ = snapshot.time_ns;
  }
  mixer_->burr().setState({burr_enabled_ && snapshot.burr_on, snapshot.burr_force_N,
                           snapshot.burr_specific_energy_J_per_mm3, removal_rate_mm3_per_s_});
  if (sink_ != nullptr || render_always_) fillRing();
}

void SoundOutput::beep() {
  if (sink_ == nullptr && !render_always_) {
    QApplication::beep();
    return;
  }
  mixer_->alert().beep();
  fillRing();
}

void SoundOutput::setProximityCue(bool on, double rate_Hz) {
  mixer_->alert().setRepeating(on, rate_Hz);
  if (sink_ != nullptr || render_always_) fillRing();
}

void SoundOutput::fillRing() {
  const auto lead = static_cast<std::size_t>(kLead_s * kSampleRate_Hz);
  while (ring_.size() < lead) {
    const std::size_t n = std::min(block_.size(), lead - ring_.size());
    mixer_->render(std::span<float>(block_.data(), n));
    ring_.push(std::span<const float>(block_.data(), n));
  }
}

}  // namespace vh::ui
