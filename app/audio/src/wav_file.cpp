#include "vh/audio/wav_file.h"

#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
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
  // Only a regular file is replaced (a link, a folder or a device is refused, as every output).
  std::error_code ec;
  const std::filesystem::file_status existing = std::filesystem::symlink_status(path, ec);
  if (!ec && std::filesystem::exists(existing) && !std::filesystem::is_regular_file(existing))
    throw std::runtime_error(path.string() + ": cannot write the sound: not a regular file (a link, folder or device is "
                                             "never replaced)");
  // Written beside it under a hidden name, renamed into place by close() once whole: a full disk
  // or a kill leaves no file that looks like a whole sound (the header's sizes come last).
  temp_path_ = path.parent_path() / ("." + path.filename().string() + ".partial-" + std::to_string(::getpid()));
  // Opened here with 0600; libsndfile writes through it, this object closes it.
  fd_ = ::open(temp_path_.c_str(), O_RDWR | O_CREAT | O_TRUNC | O_CLOEXEC, 0600);
  if (fd_ < 0) throw std::runtime_error(path.string() + ": cannot write the sound: " + std::strerror(errno));
  SF_INFO info{};
  info.samplerate = static_cast<int>(std::lround(sample_rate_Hz));
  info.channels = channels;
  info.format = SF_FORMAT_WAV | SF_FORMAT_PCM_16;
  file_ = sf_open_fd(fd_, SFM_WRITE, &info, SF_FALSE);
  if (file_ == nullptr) {
    const std::string reason = sf_strerror(nullptr);
    ::close(fd_);
    ::unlink(temp_path_.c_str());
    throw std::runtime_error(path.string() + ": cannot write the sound: " + reason);
  }
  // Samples beyond [-1, 1] clip rather than wrap.
  sf_command(file_, SFC_SET_CLIPPING, nullptr, SF_TRUE);
}

WavWriter::~WavWriter() {
  // Not closed (a failed write, an exception): the partial sound goes, nothing is renamed.
  if (file_ != nullptr) sf_close(file_);
  if (fd_ >= 0) ::close(fd_);
  if (!temp_path_.empty()) ::unlink(temp_path_.c_str());
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
  const std::filesystem::path temp = std::move(temp_path_);
  temp_path_.clear();
  if (!closed || !fd_closed || error != SF_ERR_NO_ERROR) {
    ::unlink(temp.c_str());
    throw std::runtime_error(path_.string() + ": cannot write the sound: " + (reason.empty() ? "close failed" : reason));
  }
  if (::rename(temp.c_str(), path_.c_str()) != 0) {
    const int e = errno;
    ::unlink(temp.c_str());
    throw std::runtime_error(path_.string() + ": cannot write the sound: " + std::strerror(e));
  }
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
