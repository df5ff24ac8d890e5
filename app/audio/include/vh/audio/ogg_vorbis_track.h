#pragma once
/// @file
/// A sound track for an Ogg/Theora video: mono samples encoded as an Ogg Vorbis stream by
/// libvorbis (the reference encoder, Debian libvorbis-dev) and interleaved page by page with the
/// video's Theora stream by libogg (Debian libogg-dev) into one Ogg file with two logical
/// streams (RFC 3533 multiplexing; Ogg Theora in Ogg, Theora specification section 6.2, Vorbis
/// in Ogg, Vorbis I specification appendix A).
///
/// Layout written: both streams' first (BOS) pages, Theora's then Vorbis's; the rest of each
/// stream's header pages; then the data pages of both in the order of the time at which each
/// page ends: a Theora page's granule position is a frame count (keyframe index shifted by the
/// granule shift of the identification header, plus frames since it), its time frames / fps; a
/// Vorbis page's granule position is its last sample, its time samples / rate. Equal times put
/// the video first. The Theora pages are copied byte for byte (their CRCs stay valid).

#include <cstdint>
#include <filesystem>
#include <functional>
#include <iosfwd>
#include <span>

namespace vh::audio {

/// What addVorbisTrack() wrote.
struct VorbisTrackResult {
  std::uint64_t sample_frames = 0;   ///< Sound frames encoded (the Vorbis stream's last granule).
  double video_s = 0.0;              ///< The Theora stream's length: its last frame count / fps [s].
  std::uint64_t theora_pages = 0;    ///< Pages of the video stream copied.
  std::uint64_t vorbis_pages = 0;    ///< Pages of the sound stream written.
};

/// Fills its span with the next samples of the sound (mono, in [-1, 1]).
using SampleSource = std::function<void(std::span<float>)>;

/// Writes to `out` the Ogg file `theora_ogv` (an Ogg file holding one Theora stream, e.g. what
/// vtkOggTheoraWriter wrote) with a Vorbis stream of `frames` samples at `sample_rate_Hz` from
/// `source` (asked for a few thousand at a time), VBR at `quality` (libvorbis' scale, -0.1 to 1;
/// 0.3: about 80 kbit/s for mono 48 kHz). Memory: the video's pages and the encoded sound.
/// @throws std::invalid_argument for a rate outside 8 kHz to 192 kHz, a quality out of range or
///         no frames; std::runtime_error naming `theora_ogv` when it cannot be read, is not Ogg,
///         or holds anything but one Theora stream, and when the encoder fails or `out` fails.
VorbisTrackResult addVorbisTrack(const std::filesystem::path& theora_ogv, std::ostream& out, std::uint64_t frames,
                                 double sample_rate_Hz, const SampleSource& source, double quality = 0.3);

}  // namespace vh::audio
