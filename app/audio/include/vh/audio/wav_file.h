#pragma once
/// @file
/// WAV files through libsndfile: mono or multichannel float samples in [-1, 1] written as 16-bit
/// PCM (the most widely read WAV), and read back as float (tests, tools).

#include <cstdint>
#include <filesystem>
#include <span>
#include <vector>

typedef struct sf_private_tag SNDFILE;  // sndfile.h's handle, kept out of this header

namespace vh::audio {

/// A WAV file being written: 16-bit PCM, created with permissions 0600 (a session's sound is
/// the session's data, like its trace and recording). It is written under a hidden name beside
/// the target (".NAME.partial-PID") and renamed into place by close() once whole, so a failed
/// write (a full disk), an object destroyed without close() or a killed process never leaves a
/// file at the target that looks like a whole sound; only a regular file is ever replaced.
class WavWriter {
 public:
  /// Starts writing `path` (replaced when close() succeeds).
  /// @throws std::invalid_argument for a sample rate outside 1 Hz to 768 kHz or channels outside 1 to 8;
  ///         std::runtime_error naming the file and libsndfile's reason when it cannot be created,
  ///         or when `path` exists and is not a regular file.
  WavWriter(const std::filesystem::path& path, double sample_rate_Hz, int channels = 1);
  ~WavWriter();  ///< Closes the file when close() was not called (errors are then lost).
  WavWriter(const WavWriter&) = delete;
  WavWriter& operator=(const WavWriter&) = delete;

  /// Appends frames (interleaved when channels > 1; samples outside [-1, 1] clip).
  /// @throws std::runtime_error naming the file when the write fails (a full disk); after close().
  void write(std::span<const float> interleaved);
  /// Completes the header, closes and renames the file into place. @throws std::runtime_error
  /// naming the file when that fails (nothing is then left at the target or beside it).
  void close();
  std::uint64_t frames() const noexcept { return frames_; }  ///< Frames written so far.
  const std::filesystem::path& path() const noexcept { return path_; }

 private:
  std::filesystem::path path_;
  SNDFILE* file_ = nullptr;
  int fd_ = -1;  // the file libsndfile writes through (not closed by it)
  std::filesystem::path temp_path_;  // where it is written until close() renames it
  int channels_ = 1;
  std::uint64_t frames_ = 0;
};

/// A sound file's contents.
struct WavData {
  double sample_rate_Hz = 0.0;
  int channels = 0;
  std::vector<float> samples;  ///< frames x channels, interleaved, in [-1, 1].
  std::uint64_t frames() const noexcept { return channels > 0 ? samples.size() / static_cast<std::size_t>(channels) : 0; }
};

/// Reads a sound file libsndfile knows (WAV among others).
/// @throws std::runtime_error naming the file and libsndfile's reason when it cannot be read.
WavData readWav(const std::filesystem::path& path);

}  // namespace vh::audio
