// The sound track of a video: Vorbis encoding and Ogg page interleaving (vh/audio/ogg_vorbis_track.h).
#include "vh/audio/ogg_vorbis_track.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <fstream>
#include <memory>
#include <ostream>
#include <stdexcept>
#include <string>
#include <vector>

#include <ogg/ogg.h>
#include <vorbis/codec.h>
#include <vorbis/vorbisenc.h>

namespace vh::audio {
namespace {

/// One Ogg page, its bytes (header then body) and what the interleaving needs of it.
struct Page {
  std::vector<unsigned char> bytes;
  std::int64_t granulepos = 0;
  bool header = false;  // a stream's header page (granule position 0: no data packet ends there)
  double end_s = 0.0;   // the time at which its last finished packet ends (data pages)
};

Page pageOf(const ogg_page& og) {
  Page p;
  p.bytes.assign(og.header, og.header + og.header_len);
  p.bytes.insert(p.bytes.end(), og.body, og.body + og.body_len);
  p.granulepos = ogg_page_granulepos(&og);
  return p;
}

/// An Ogg file of one logical stream: its pages, serial number and first page's body (the
/// identification header packet).
struct OneStream {
  std::vector<Page> pages;
  long serial = 0;
  std::vector<unsigned char> first_packet;
};

/// Every page of the Ogg file `path`, checked to be one logical stream.
OneStream readPages(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error(path.string() + ": cannot be read");
  ogg_sync_state sync;
  ogg_sync_init(&sync);
  std::unique_ptr<ogg_sync_state, int (*)(ogg_sync_state*)> guard(&sync, ogg_sync_clear);
  OneStream stream;
  std::vector<Page>& pages = stream.pages;
  for (bool eof = false; !eof;) {
    char* buffer = ogg_sync_buffer(&sync, 65536);
    in.read(buffer, 65536);
    eof = in.gcount() == 0;
    ogg_sync_wrote(&sync, static_cast<long>(in.gcount()));
    ogg_page og;
    for (int r; (r = ogg_sync_pageout(&sync, &og)) != 0;) {
      if (r < 0) throw std::runtime_error(path.string() + ": not a valid Ogg file (bytes skipped before a page)");
      if (pages.empty()) {
        stream.serial = ogg_page_serialno(&og);
        stream.first_packet.assign(og.body, og.body + og.body_len);
      } else if (ogg_page_serialno(&og) != stream.serial || ogg_page_bos(&og)) {
        throw std::runtime_error(path.string() + ": holds more than one logical stream");
      }
      pages.push_back(pageOf(og));
    }
  }
  if (pages.empty()) throw std::runtime_error(path.string() + ": not an Ogg file (no page)");
  return stream;
}

/// The Theora identification header's frame rate and granule shift (Theora specification
/// section 6.2: FRN, FRD at bytes 22..29, KFGSHIFT the 5 bits after the 6-bit QUAL at byte 40).
struct TheoraTiming {
  double fps = 0.0;
  int granule_shift = 0;
  double timeOf(std::int64_t granulepos) const noexcept {
    const std::int64_t key = granulepos >> granule_shift;
    const std::int64_t since = granulepos & ((std::int64_t{1} << granule_shift) - 1);
    return static_cast<double>(key + since) / fps;
  }
};

TheoraTiming theoraTiming(const std::filesystem::path& path, const std::vector<unsigned char>& ident) {
  if (ident.size() < 42 || ident[0] != 0x80 || std::memcmp(ident.data() + 1, "theora", 6) != 0)
    throw std::runtime_error(path.string() + ": its stream is not Theora (no identification header)");
  const auto u32 = [&](std::size_t at) {
    return (std::uint32_t{ident[at]} << 24) | (std::uint32_t{ident[at + 1]} << 16) | (std::uint32_t{ident[at + 2]} << 8) |
           std::uint32_t{ident[at + 3]};
  };
  const std::uint32_t frn = u32(22), frd = u32(26);
  if (frn == 0 || frd == 0) throw std::runtime_error(path.string() + ": the Theora stream has no frame rate");
  TheoraTiming t;
  t.fps = static_cast<double>(frn) / static_cast<double>(frd);
  t.granule_shift = ((ident[40] & 0x03) << 3) | (ident[41] >> 5);
  return t;
}

/// Marks header pages and the end time of each data page (a page where no packet ends, granule
/// position -1, takes the time of the page before it).
template <class TimeOf>
void timePages(std::vector<Page>& pages, TimeOf time_of) {
  double last_s = 0.0;
  bool data = false;
  for (Page& p : pages) {
    if (!data && p.granulepos == 0) {
      p.header = true;
      continue;
    }
    data = true;
    if (p.granulepos >= 0) last_s = time_of(p.granulepos);
    p.end_s = last_s;
  }
}

/// libvorbis' encoder and its Ogg stream, released together.
struct VorbisEncoder {
  vorbis_info info;
  vorbis_comment comment;
  vorbis_dsp_state dsp;
  vorbis_block block;
  ogg_stream_state stream;
  VorbisEncoder(long serial, double sample_rate_Hz, double quality) {
    vorbis_info_init(&info);
    if (vorbis_encode_init_vbr(&info, 1, static_cast<long>(std::lround(sample_rate_Hz)), static_cast<float>(quality)) != 0) {
      vorbis_info_clear(&info);
      throw std::runtime_error("the Vorbis encoder refused mono at " + std::to_string(sample_rate_Hz) + " Hz");
    }
    vorbis_comment_init(&comment);
    vorbis_comment_add_tag(&comment, "ENCODER", "volume-haptics");
    vorbis_analysis_init(&dsp, &info);
    vorbis_block_init(&dsp, &block);
    ogg_stream_init(&stream, static_cast<int>(serial));
  }
  ~VorbisEncoder() {
    ogg_stream_clear(&stream);
    vorbis_block_clear(&block);
    vorbis_dsp_clear(&dsp);
    vorbis_comment_clear(&comment);
    vorbis_info_clear(&info);
  }
  VorbisEncoder(const VorbisEncoder&) = delete;
  VorbisEncoder& operator=(const VorbisEncoder&) = delete;

  /// The three header packets: the identification header alone on the first (BOS) page, the
  /// comment and setup headers on the next, as the Vorbis I specification asks (appendix A.2).
  void headers(std::vector<Page>& pages) {
    ogg_packet ident, comments, setup;
    vorbis_analysis_headerout(&dsp, &comment, &ident, &comments, &setup);
    ogg_stream_packetin(&stream, &ident);
    flush(pages);
    ogg_stream_packetin(&stream, &comments);
    ogg_stream_packetin(&stream, &setup);
    flush(pages);
  }
  void flush(std::vector<Page>& pages) {
    ogg_page og;
    while (ogg_stream_flush(&stream, &og) != 0) pages.push_back(pageOf(og));
  }
  /// Encodes what the analysis has buffered into packets and full pages.
  void drain(std::vector<Page>& pages) {
    ogg_packet op;
    ogg_page og;
    while (vorbis_analysis_blockout(&dsp, &block) == 1) {
      vorbis_analysis(&block, nullptr);
      vorbis_bitrate_addblock(&block);
      while (vorbis_bitrate_flushpacket(&dsp, &op) == 1) {
        ogg_stream_packetin(&stream, &op);
        while (ogg_stream_pageout(&stream, &og) != 0) pages.push_back(pageOf(og));
      }
    }
  }
};

/// The Vorbis stream of `frames` samples from `source`, as pages.
std::vector<Page> encodeVorbis(long serial, std::uint64_t frames, double sample_rate_Hz, const SampleSource& source,
                               double quality) {
  VorbisEncoder enc(serial, sample_rate_Hz, quality);
  std::vector<Page> pages;
  enc.headers(pages);
  constexpr std::uint64_t kBlock = 4096;
  std::vector<float> block(kBlock);
  for (std::uint64_t done = 0; done < frames;) {
    const auto n = static_cast<std::size_t>(std::min(kBlock, frames - done));
    source(std::span<float>(block.data(), n));
    float** buffer = vorbis_analysis_buffer(&enc.dsp, static_cast<int>(n));
    std::copy(block.begin(), block.begin() + static_cast<std::ptrdiff_t>(n), buffer[0]);
    vorbis_analysis_wrote(&enc.dsp, static_cast<int>(n));
    enc.drain(pages);
    done += n;
  }
  vorbis_analysis_wrote(&enc.dsp, 0);  // the end: the last packet gets the total as granule, e_o_s
  enc.drain(pages);
  enc.flush(pages);
  return pages;
}

}  // namespace

VorbisTrackResult addVorbisTrack(const std::filesystem::path& theora_ogv, std::ostream& out, std::uint64_t frames,
                                 double sample_rate_Hz, const SampleSource& source, double quality) {
  if (!(std::isfinite(sample_rate_Hz) && sample_rate_Hz >= 8000.0 && sample_rate_Hz <= 192000.0))
    throw std::invalid_argument("addVorbisTrack: sample rate: expected 8 kHz to 192 kHz");
  if (!(std::isfinite(quality) && quality >= -0.1 && quality <= 1.0))
    throw std::invalid_argument("addVorbisTrack: quality: expected -0.1 to 1");
  if (frames == 0) throw std::invalid_argument("addVorbisTrack: no sound frames");
  OneStream video = readPages(theora_ogv);
  const TheoraTiming timing = theoraTiming(theora_ogv, video.first_packet);
  timePages(video.pages, [&](std::int64_t gp) { return timing.timeOf(gp); });
  std::vector<Page> sound = encodeVorbis(video.serial + 1, frames, sample_rate_Hz, source, quality);
  timePages(sound, [&](std::int64_t gp) { return static_cast<double>(gp) / sample_rate_Hz; });
  VorbisTrackResult result;
  result.sample_frames = frames;
  result.theora_pages = video.pages.size();
  result.vorbis_pages = sound.size();
  for (const Page& p : video.pages)
    if (p.granulepos > 0) result.video_s = std::max(result.video_s, timing.timeOf(p.granulepos));
  const auto write = [&](const Page& p) { out.write(reinterpret_cast<const char*>(p.bytes.data()), static_cast<std::streamsize>(p.bytes.size())); };
  // BOS pages first (video, then sound), then the other header pages, then data by time.
  write(video.pages.front());
  write(sound.front());
  std::size_t v = 1, a = 1;
  while (v < video.pages.size() && video.pages[v].header) write(video.pages[v++]);
  while (a < sound.size() && sound[a].header) write(sound[a++]);
  while (v < video.pages.size() || a < sound.size()) {
    const bool video_next = a == sound.size() || (v < video.pages.size() && video.pages[v].end_s <= sound[a].end_s);
    write(video_next ? video.pages[v++] : sound[a++]);
  }
  out.flush();
  if (!out) throw std::runtime_error("the video with its sound track could not be written");
  return result;
}

}  // namespace vh::audio
