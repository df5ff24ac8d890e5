// The sound track of `export --video` (media_export.h, audio::addVorbisTrack()): a headless
// drilling run on the built-in sphere is recorded and exported; the file is then read with the
// reference libraries' decoders, independently of the writer: libogg for its logical streams
// (two, both BOS pages first), libvorbisfile for the sound (48 kHz mono, as long as the frames,
// its pitch while pushing on the motor line at the run's own |F|, measured with the tests' DFT)
// and libtheora's decoder for the video (every frame still decodes). --no-audio and a recording
// whose burr never ran give one Theora stream.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <string>
#include <span>
#include <vector>

#include <unistd.h>

#include <ogg/ogg.h>
#include <theora/theoradec.h>
#include <vorbis/vorbisfile.h>

#include "spectrum_oracle.h"
#include "vh/runtime/recording.h"
#include "vh/runtime/runner.h"
#include "vh/runtime/scene.h"
#include "vh/ui/export/media_export.h"

namespace vh::ui {
namespace {

namespace fs = std::filesystem;

/// The built-in drilling scene (resources/scenes/sphere-drill.json), with or without its drill.
runtime::SceneSpec sphere(bool drill) {
  return runtime::parseScene(std::string(R"({"volume": {"path": "builtin:sphere", "isovalue": 0},
      "tool": {"mesh": "builtin:drill", "point_spacing_m": 0.001},
      "coupling": {"linear_N_per_m": 400, "angular_Nm_per_rad": 1.0})") +
                                 (drill ? R"(, "drill": {"on": true, "burr_radius_m": 0.0025, "burr_speed_rpm": 80000,
                                          "hardness": {"tissue": 2.0}}})"
                                        : "}"),
                             "sphere-drill.json", {});
}

/// Free above the sphere until 0.5 s, down to 12.5 mm (into it) by 1.2 s, held until 2 s.
runtime::Trajectory press() {
  std::vector<runtime::TrajectorySample> keys;
  for (const auto& [t, z] : {std::pair{0.0, 0.030}, {0.5, 0.030}, {1.2, 0.0125}, {2.0, 0.0125}}) {
    runtime::TrajectorySample k;
    k.t_s = t;
    k.X_WD = haptics::Pose::FromTranslation({0.0, 0.0, z});
    keys.push_back(k);
  }
  return runtime::Trajectory(keys);
}

/// A recording of the press (and the live run's burr per tick).
fs::path recordPress(const fs::path& dir, bool drill, std::vector<runtime::DrillTick>* ticks = nullptr) {
  fs::create_directories(dir);
  runtime::RunOptions options;
  options.verify_step_voxels = 0.0;
  options.lag_reference = false;
  options.record = dir / (drill ? "drilled.vhrec" : "touched.vhrec");
  if (ticks != nullptr) options.on_drill_tick = [ticks](const runtime::DrillTick& d) { ticks->push_back(d); };
  runtime::runHeadless(runtime::loadScene(sphere(drill)), press(), options);
  return options.record;
}

/// An Ogg file's logical streams as libogg reads them: per serial number, its packets in order.
struct OggStreams {
  std::map<long, std::vector<std::vector<unsigned char>>> packets;
  std::vector<long> bos_order;    // serials of the BOS pages, in file order
  bool bos_pages_first = true;    // no other page before the last BOS page
};

OggStreams readOgg(const fs::path& path) {
  OggStreams out;
  std::ifstream in(path, std::ios::binary);
  ogg_sync_state sync;
  ogg_sync_init(&sync);
  std::map<long, ogg_stream_state> streams;
  bool data_seen = false;
  for (bool eof = false; !eof;) {
    char* buffer = ogg_sync_buffer(&sync, 4096);
    in.read(buffer, 4096);
    eof = in.gcount() == 0;
    ogg_sync_wrote(&sync, static_cast<long>(in.gcount()));
    ogg_page og;
    while (ogg_sync_pageout(&sync, &og) == 1) {
      const long serial = ogg_page_serialno(&og);
      if (ogg_page_bos(&og)) {
        out.bos_order.push_back(serial);
        if (data_seen) out.bos_pages_first = false;
        ogg_stream_init(&streams[serial], static_cast<int>(serial));
      } else {
        data_seen = true;
      }
      ogg_stream_pagein(&streams[serial], &og);
      ogg_packet op;
      while (ogg_stream_packetout(&streams[serial], &op) == 1)
        out.packets[serial].emplace_back(op.packet, op.packet + op.bytes);
    }
  }
  for (auto& [serial, s] : streams) ogg_stream_clear(&s);
  ogg_sync_clear(&sync);
  return out;
}

bool startsWith(const std::vector<unsigned char>& packet, const char* magic, std::size_t n) {
  return packet.size() >= n && std::memcmp(packet.data(), magic, n) == 0;
}

/// Frames libtheora decodes from a Theora stream's packets (-1 when its headers are refused).
int decodeTheora(const std::vector<std::vector<unsigned char>>& packets, int& width, int& height) {
  th_info info;
  th_comment comment;
  th_setup_info* setup = nullptr;
  th_info_init(&info);
  th_comment_init(&comment);
  std::size_t k = 0;
  for (; k < packets.size(); ++k) {
    ogg_packet op{};
    op.packet = const_cast<unsigned char*>(packets[k].data());
    op.bytes = static_cast<long>(packets[k].size());
    op.b_o_s = k == 0;
    const int r = th_decode_headerin(&info, &comment, &setup, &op);
    if (r == 0) break;  // the first video packet
    if (r < 0) return -1;
  }
  th_dec_ctx* decoder = th_decode_alloc(&info, setup);
  width = static_cast<int>(info.pic_width);
  height = static_cast<int>(info.pic_height);
  int frames = 0;
  for (; k < packets.size() && decoder != nullptr; ++k) {
    ogg_packet op{};
    op.packet = const_cast<unsigned char*>(packets[k].data());
    op.bytes = static_cast<long>(packets[k].size());
    op.granulepos = -1;
    ogg_int64_t granule = 0;
    const int r = th_decode_packetin(decoder, &op, &granule);
    if (r == 0 || r == TH_DUPFRAME) ++frames;
    th_ycbcr_buffer image;
    if (r == 0 && th_decode_ycbcr_out(decoder, image) != 0) return -1;
  }
  th_decode_free(decoder);
  th_setup_free(setup);
  th_comment_clear(&comment);
  th_info_clear(&info);
  return frames;
}

/// The sound of an Ogg file's Vorbis stream, decoded by libvorbisfile.
struct Decoded {
  long rate_Hz = 0;
  int channels = 0;
  std::int64_t pcm_total = 0;
  std::vector<float> samples;  // first channel
};

Decoded decodeVorbis(const fs::path& path) {
  Decoded d;
  OggVorbis_File vf;
  if (ov_fopen(path.c_str(), &vf) != 0) return d;
  const vorbis_info* vi = ov_info(&vf, -1);
  d.rate_Hz = vi->rate;
  d.channels = vi->channels;
  d.pcm_total = ov_pcm_total(&vf, -1);
  int section = 0;
  for (;;) {
    float** pcm = nullptr;
    const long n = ov_read_float(&vf, &pcm, 4096, &section);
    if (n <= 0) break;
    d.samples.insert(d.samples.end(), pcm[0], pcm[0] + n);
  }
  ov_clear(&vf);
  return d;
}

MediaExportOptions smallVideo(const fs::path& ogv) {
  MediaExportOptions options;
  options.video = ogv;
  options.fps = 10.0;
  options.width = 96;
  options.height = 64;
  return options;
}

TEST(VideoSound, TheExportedVideoCarriesTheBurrsSoundAsVorbis) {
  const fs::path dir = fs::temp_directory_path() / ("vh-video-sound-" + std::to_string(::getpid()));
  std::vector<runtime::DrillTick> ticks;
  const fs::path rec = recordPress(dir, true, &ticks);
  const runtime::Recording recording = runtime::readRecording(rec);
  using Clock = std::chrono::steady_clock;
  const auto t0 = Clock::now();
  ASSERT_EQ(exportRecordingMedia(0, nullptr, rec, smallVideo(dir / "with.ogv")), 0);
  const auto t1 = Clock::now();
  MediaExportOptions silent = smallVideo(dir / "without.ogv");
  silent.sound = false;
  ASSERT_EQ(exportRecordingMedia(0, nullptr, rec, silent), 0);
  const auto t2 = Clock::now();
  std::cout << "export of " << recording.records.size() << " records: with sound "
            << std::chrono::duration<double>(t1 - t0).count() << " s, " << fs::file_size(dir / "with.ogv")
            << " bytes; without " << std::chrono::duration<double>(t2 - t1).count() << " s, "
            << fs::file_size(dir / "without.ogv") << " bytes\n";

  // Two logical streams, their BOS pages first: Theora's and Vorbis's.
  const OggStreams ogg = readOgg(dir / "with.ogv");
  ASSERT_EQ(ogg.bos_order.size(), 2u);
  EXPECT_TRUE(ogg.bos_pages_first);
  const long video = ogg.bos_order[0], sound = ogg.bos_order[1];
  EXPECT_TRUE(startsWith(ogg.packets.at(video).front(), "\x80theora", 7));
  EXPECT_TRUE(startsWith(ogg.packets.at(sound).front(), "\x01vorbis", 7));
  // The video: every frame of the time range decodes, at the size asked for.
  const double span_s = recording.records.back().time_s - recording.records.front().time_s;
  const int frames = static_cast<int>(std::floor(span_s * 10.0 + 1e-9)) + 1;
  int width = 0, height = 0;
  EXPECT_EQ(decodeTheora(ogg.packets.at(video), width, height), frames);
  EXPECT_EQ(width, 96);
  EXPECT_EQ(height, 64);
  // The same video stream, packet for packet, as the export without sound.
  const OggStreams plain = readOgg(dir / "without.ogv");
  ASSERT_EQ(plain.bos_order.size(), 1u);
  EXPECT_EQ(plain.packets.begin()->second.size(), ogg.packets.at(video).size());

  // The sound: 48 kHz mono, as long as the frames (frames / fps), within a frame.
  const Decoded d = decodeVorbis(dir / "with.ogv");
  ASSERT_EQ(d.rate_Hz, 48000);
  EXPECT_EQ(d.channels, 1);
  EXPECT_NEAR(static_cast<double>(d.pcm_total) / d.rate_Hz, frames / 10.0, 0.1);
  EXPECT_EQ(static_cast<std::int64_t>(d.samples.size()), d.pcm_total);
  // Its pitch while pushing (1.6 .. 1.77 s): the motor line at the live run's mean |F| there.
  const double fs_Hz = 48000.0;
  const std::size_t a = static_cast<std::size_t>(1.6 * fs_Hz), n = 8192;
  ASSERT_GE(d.samples.size(), a + n);
  double force = 0.0;
  int count = 0;
  for (const runtime::DrillTick& t : ticks)
    if (t.time_s >= 1.6 && t.time_s < 1.6 + n / fs_Hz) force += t.force_N, ++count;
  ASSERT_GT(count, 0);
  force /= count;
  const double rpm = std::max(0.1, 1.0 - 0.2 * force * 0.0025 * (2.0 / 0.6) / 0.01) * 80000.0;
  const double expected_Hz = 6.0 * rpm / 60.0;
  const double measured_Hz = audio::oracle::peakFrequency_Hz(std::span<const float>(d.samples.data() + a, n), fs_Hz,
                                                             0.5 * expected_Hz, 1.5 * expected_Hz);
  std::cout << "decoded f0 while pushing at " << force << " N: " << measured_Hz << " Hz (motor line " << expected_Hz
            << " Hz)\n";
  EXPECT_LT(expected_Hz, 0.95 * 8000.0) << "the push must load the burr";
  EXPECT_NEAR(measured_Hz, expected_Hz, 0.02 * expected_Hz);
  // Free running (0.1 .. 0.27 s): flutes x rpm / 60.
  EXPECT_NEAR(audio::oracle::peakFrequency_Hz(std::span<const float>(d.samples.data() + 4800, n), fs_Hz, 4000.0, 12000.0),
              8000.0, 0.02 * 8000.0);
  fs::remove_all(dir);
}

TEST(VideoSound, ARecordingWhoseBurrNeverRanGetsNoSoundTrack) {
  const fs::path dir = fs::temp_directory_path() / ("vh-video-nosound-" + std::to_string(::getpid()));
  const fs::path rec = recordPress(dir, false);
  ASSERT_EQ(exportRecordingMedia(0, nullptr, rec, smallVideo(dir / "touch.ogv")), 0);
  const OggStreams ogg = readOgg(dir / "touch.ogv");
  ASSERT_EQ(ogg.bos_order.size(), 1u);
  EXPECT_TRUE(startsWith(ogg.packets.begin()->second.front(), "\x80theora", 7));
  fs::remove_all(dir);
}

}  // namespace
}  // namespace vh::ui
