#include "vh/audio/wav_file.h"

#include <cerrno>
#include <cmath>
#include <cstring>
#include <stdexcept>
#include <string>

#include <fcntl.h>
#include <sndfile.h>
#include <unistd.h>

namespace vh::audio {

WavWriter::WavWriter(const std::filesystem::path& path, double sample_rate_Hz, int channels)
    : path_(path), channels_(channels) {
  if (!(std::isfinite(sample_rate_Hz) && sample_rate_Hz >= 1.0 && sample_rate_Hz <= 768000.0))
    throw std::invalid_argument("WavWriter: sample rate: expected 1 Hz to 768 kHz");
  if (channels < 1 || channels > 8) throw std::invalid_argument("WavWriter: channels: expected 1 to 8");
  // Opened here with 0600; libsndfile writes through it, this object closes it.
  fd_ = ::open(path.c_str(), O_RDWR | O_CREAT | O_TRUNC | O_CLOEXEC, 0600);
  if (fd_ < 0) throw std::runtime_error(path.string() + ": cannot write the sound: " + std::strerror(errno));
  SF_INFO info{};
  info.samplerate = static_cast<int>(std::lround(sample_rate_Hz));
  info.channels = channels;
  info.format = SF_FORMAT_WAV | SF_FORMAT_PCM_16;
  file_ = sf_open_fd(fd_, SFM_WRITE, &info, SF_FALSE);
  if (file_ == nullptr) {
    const std::string reason = sf_strerror(nullptr);
    ::close(fd_);
    throw std::runtime_error(path.string() + ": cannot write the sound: " + reason);
  }
  // Samples beyond [-1, 1] clip rather than wrap.
  sf_command(file_, SFC_SET_CLIPPING, nullptr, SF_TRUE);
}

WavWriter::~WavWriter() {
  if (file_ != nullptr) sf_close(file_);
  if (fd_ >= 0) ::close(fd_);
}

void WavWriter::write(std::span<const float> interleaved) {
  if (file_ == nullptr) throw std::runtime_error(path_.string() + ": the sound file is closed");
  const auto frames = static_cast<sf_count_t>(interleaved.size() / static_cast<std::size_t>(channels_));
  if (frames == 0) return;
  if (sf_writef_float(file_, interleaved.data(), frames) != frames)
    throw std::runtime_error(path_.string() + ": cannot write the sound: " + sf_strerror(file_));
  frames_ += static_cast<std::uint64_t>(frames);
}

void WavWriter::close() {
  if (file_ == nullptr) return;
  SNDFILE* file = file_;
  file_ = nullptr;
  sf_write_sync(file);
  const int error = sf_error(file);
  const std::string reason = error != SF_ERR_NO_ERROR ? sf_strerror(file) : std::string();
  const bool closed = sf_close(file) == 0;
  const int fd = fd_;
  fd_ = -1;
  const bool fd_closed = ::close(fd) == 0;
  if (!closed || !fd_closed || error != SF_ERR_NO_ERROR)
    throw std::runtime_error(path_.string() + ": cannot write the sound: " + (reason.empty() ? "close failed" : reason));
}

WavData readWav(const std::filesystem::path& path) {
  SF_INFO info{};
  SNDFILE* file = sf_open(path.c_str(), SFM_READ, &info);
  if (file == nullptr) throw std::runtime_error(path.string() + ": cannot read the sound: " + sf_strerror(nullptr));
  WavData data;
  data.sample_rate_Hz = info.samplerate;
  data.channels = info.channels;
  data.samples.resize(static_cast<std::size_t>(info.frames) * static_cast<std::size_t>(info.channels));
  const sf_count_t read = sf_readf_float(file, data.samples.data(), info.frames);
  sf_close(file);
  if (read != info.frames) throw std::runtime_error(path.string() + ": cannot read the sound: the file is short");
  return data;
}

}  // namespace vh::audio
