// Tests of session recordings (app/runtime/src/recording.cpp): the SPSC ring, the chunked file
// format (round trip, crash truncation, corruption), dropped-record accounting, allocation-free
// push, and the CSV / JSON export (library and `volume-haptics export`).
#include <array>
#include <chrono>
#include <iostream>
#include <thread>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "allocation_guard.h"
#include "runtime_test_support.h"
#include "vh/runtime/haptic_thread.h"
#include "vh/runtime/recording.h"
#include "vh/runtime/scene.h"

namespace vh::runtime {
namespace {

namespace fs = std::filesystem;

/// A record whose every field depends on i (so any misplaced byte shows).
TickRecord makeRecord(std::uint64_t i) {
  TickRecord r;
  const double t = static_cast<double>(i) * 1e-3;
  r.time_s = t;
  for (int k = 0; k < 3; ++k) {
    r.p_WD_m[k] = 0.01 * std::sin(t + k);
    r.p_WP_m[k] = 0.01 * std::cos(t + k) / 3.0;
    r.force_W_N[k] = std::sin(7.0 * t + k) * 2.5;
    r.torque_W_Nm[k] = std::cos(5.0 * t + k) * 0.01;
  }
  const double a = 0.5 * t;
  r.q_WD[0] = std::cos(a);
  r.q_WD[3] = std::sin(a);
  r.q_WP[0] = std::cos(a / 2);
  r.q_WP[1] = std::sin(a / 2);
  r.isovalue = 300.0 + static_cast<double>(i % 7);
  r.tick = i;
  r.tick_time_s = 1e-5 * static_cast<double>(i % 13) + 1e-7;
  r.contacts = static_cast<std::uint32_t>(i % 5);
  r.flags = r.contacts > 0 ? kRecordFlagContact : 0u;
  return r;
}

/// Hash of the scripted 2 s press-slide session (RecordingReplay test); see there.
constexpr std::uint64_t kPinnedSessionHash = 0x3cb8c56f15262ad4ull;

bool sameBytes(const TickRecord& a, const TickRecord& b) { return std::memcmp(&a, &b, sizeof a) == 0; }

/// Writes `n` records (one per ms) with chunks of `chunk` records; returns the path.
fs::path writeSession(const fs::path& path, std::uint64_t n, std::size_t chunk = 500) {
  RecordingWriterOptions opt;
  opt.chunk_records = chunk;
  opt.ring_capacity = 1u << 16;
  RecordingWriter writer(path, R"({"scene":"block-peg","device":"scripted"})", opt);
  for (std::uint64_t i = 0; i < n; ++i) EXPECT_TRUE(writer.push(makeRecord(i)));
  writer.close();
  EXPECT_EQ(writer.recordsWritten(), n);
  return path;
}

std::string readBytes(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}
void writeBytes(const fs::path& path, const std::string& bytes) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
}

/// Byte offsets of every chunk, walked from the header as the format documents it.
std::vector<std::size_t> chunkOffsets(const std::string& bytes) {
  std::uint32_t meta = 0;
  std::memcpy(&meta, bytes.data() + 16, 4);
  std::vector<std::size_t> offsets;
  std::size_t off = 24 + meta;
  while (off + 16 <= bytes.size()) {
    offsets.push_back(off);
    std::uint32_t count = 0;
    std::memcpy(&count, bytes.data() + off + 4, 4);
    off += 16 + std::size_t{count} * sizeof(TickRecord) + 4;
  }
  return offsets;
}

TEST(Recording, Crc32MatchesTheStandardCheckValue) {
  const char* s = "123456789";
  EXPECT_EQ(crc32(s, 9), 0xCBF43926u);
  EXPECT_EQ(crc32(s + 4, 5, crc32(s, 4)), 0xCBF43926u);  // incremental
}

TEST(Recording, RoundTripKeepsEveryRecordBitForBit) {
  const fs::path path = writeSession(test::scratchDir() / "session.vhrec", 2500);
  // Header + metadata + chunks of <= 500 records, 20 bytes of framing each.
  const Recording rec = readRecording(path);
  EXPECT_TRUE(rec.warnings.empty()) << rec.warnings.front();
  EXPECT_EQ(rec.version, kRecordingFormatVersion);
  ASSERT_EQ(rec.records.size(), 2500u);
  for (std::uint64_t i = 0; i < 2500; ++i) ASSERT_TRUE(sameBytes(rec.records[i], makeRecord(i))) << "record " << i;
  EXPECT_EQ(rec.dropped_records, 0u);
  EXPECT_EQ(rec.bytes_ignored, 0u);
  const nlohmann::json meta = nlohmann::json::parse(rec.metadata_json);
  EXPECT_EQ(meta.at("scene"), "block-peg");
  EXPECT_EQ(meta.at("servo_rate_Hz"), 1000.0);
  EXPECT_TRUE(meta.contains("start_time_utc"));
  const std::uintmax_t expected_size = 24 + rec.metadata_json.size() + 2500 * 200 + rec.chunks * 20;
  EXPECT_EQ(fs::file_size(path), expected_size);
}

TEST(Recording, CrashTruncationOpensUpToTheLastGoodChunkLosingUnderOneSecond) {
  const fs::path path = writeSession(test::scratchDir() / "crash.vhrec", 4000);
  const std::string bytes = readBytes(path);
  const std::vector<std::size_t> chunks = chunkOffsets(bytes);
  ASSERT_GE(chunks.size(), 2u);
  // Cut in the middle of the last chunk, as a kill -9 during its write would.
  const std::size_t cut = chunks.back() + (bytes.size() - chunks.back()) / 2;
  writeBytes(path, bytes.substr(0, cut));

  const Recording rec = readRecording(path);
  ASSERT_EQ(rec.warnings.size(), 1u);
  EXPECT_NE(rec.warnings[0].find("truncated chunk"), std::string::npos) << rec.warnings[0];
  EXPECT_EQ(rec.chunks, chunks.size() - 1);
  EXPECT_EQ(rec.bytes_ignored, cut - chunks.back());
  ASSERT_FALSE(rec.records.empty());
  for (std::size_t i = 0; i < rec.records.size(); ++i) ASSERT_TRUE(sameBytes(rec.records[i], makeRecord(i)));
  // Lost: the records of the cut chunk, at 1 ms each (one default chunk is 0.5 s).
  const double lost_s = static_cast<double>(4000 - rec.records.size()) * 1e-3;
  EXPECT_LT(lost_s, 1.0);
  EXPECT_GT(lost_s, 0.0);

  // A cut inside a chunk header too.
  writeBytes(path, bytes.substr(0, chunks.back() + 7));
  const Recording rec2 = readRecording(path);
  ASSERT_EQ(rec2.warnings.size(), 1u);
  EXPECT_NE(rec2.warnings[0].find("truncated chunk header"), std::string::npos) << rec2.warnings[0];
  EXPECT_EQ(rec2.records.size(), rec.records.size());
}

TEST(Recording, CorruptedMiddleChunkStopsTheReaderBeforeItWithAWarning) {
  const fs::path path = writeSession(test::scratchDir() / "corrupt.vhrec", 5000);
  std::string bytes = readBytes(path);
  const std::vector<std::size_t> chunks = chunkOffsets(bytes);
  ASSERT_GE(chunks.size(), 3u);
  const std::size_t bad = chunks.size() / 2;
  bytes[chunks[bad] + 16 + 1234] ^= 0x10;  // one bit in a record of the middle chunk
  writeBytes(path, bytes);

  const Recording rec = readRecording(path);
  ASSERT_EQ(rec.warnings.size(), 1u);
  EXPECT_NE(rec.warnings[0].find("checksum mismatch"), std::string::npos) << rec.warnings[0];
  EXPECT_NE(rec.warnings[0].find("at byte " + std::to_string(chunks[bad])), std::string::npos) << rec.warnings[0];
  EXPECT_EQ(rec.chunks, bad);
  EXPECT_EQ(rec.bytes_ignored, bytes.size() - chunks[bad]);
  for (std::size_t i = 0; i < rec.records.size(); ++i) ASSERT_TRUE(sameBytes(rec.records[i], makeRecord(i)));
}

TEST(Recording, DamagedHeadersThrowWithTheReason) {
  const fs::path dir = test::scratchDir();
  const fs::path path = writeSession(dir / "ok.vhrec", 10);
  std::string bytes = readBytes(path);

  writeBytes(dir / "magic.vhrec", "not a recording at all, just text");
  VH_EXPECT_THROW_WITH(readRecording(dir / "magic.vhrec"), std::runtime_error, "bad magic");
  std::string v2 = bytes;
  v2[8] = 2;
  writeBytes(dir / "v2.vhrec", v2);
  VH_EXPECT_THROW_WITH(readRecording(dir / "v2.vhrec"), std::runtime_error, "unsupported format version 2");
  std::string meta = bytes;
  meta[26] ^= 0x01;
  writeBytes(dir / "meta.vhrec", meta);
  VH_EXPECT_THROW_WITH(readRecording(dir / "meta.vhrec"), std::runtime_error, "damaged metadata");
  VH_EXPECT_THROW_WITH(readRecording(dir / "missing.vhrec"), std::runtime_error, "cannot open");
  VH_EXPECT_THROW_WITH(RecordingWriter(dir / "x.vhrec", "[1,2]"), std::invalid_argument, "JSON object");
  RecordingWriterOptions too_long;
  too_long.chunk_records = 1000;  // a whole second at 1 kHz: a crash could lose >= 1 s
  VH_EXPECT_THROW_WITH(RecordingWriter(dir / "x.vhrec", "{}", too_long), std::invalid_argument,
                       "under 1 s of ticks");
  VH_EXPECT_THROW_WITH(RecordingWriter(dir / "no" / "such" / "dir.vhrec", "{}"), std::runtime_error,
                       "cannot create");
}

TEST(Recording, RingOverflowCountsDrops) {
  TickRing ring(3);  // rounded up to 4
  EXPECT_EQ(ring.capacity(), 4u);
  int accepted = 0;
  for (std::uint64_t i = 0; i < 10; ++i) accepted += ring.push(makeRecord(i)) ? 1 : 0;
  EXPECT_EQ(accepted, 4);
  EXPECT_EQ(ring.dropped(), 6u);
  std::array<TickRecord, 8> out{};
  ASSERT_EQ(ring.pop(out.data(), out.size()), 4u);
  for (std::uint64_t i = 0; i < 4; ++i) EXPECT_TRUE(sameBytes(out[i], makeRecord(i)));
  EXPECT_TRUE(ring.push(makeRecord(42)));  // room again after the pop
  EXPECT_EQ(ring.size(), 1u);
}

TEST(Recording, WriterStoresTheDroppedCountAndNeverLosesRecordsSilently) {
  const fs::path path = test::scratchDir() / "drops.vhrec";
  RecordingWriterOptions opt;
  opt.ring_capacity = 4;  // far too small: the writer cannot keep up with a tight loop
  opt.chunk_records = 100;
  RecordingWriter writer(path, "{}", opt);
  std::uint64_t accepted = 0;
  for (std::uint64_t i = 0; i < 20000; ++i) accepted += writer.push(makeRecord(i)) ? 1 : 0;
  writer.close();
  EXPECT_GT(writer.dropped(), 0u);
  const Recording rec = readRecording(path);
  EXPECT_TRUE(rec.warnings.empty());
  EXPECT_EQ(rec.records.size(), accepted);
  EXPECT_EQ(rec.records.size() + rec.dropped_records, 20000u);
  for (std::size_t i = 1; i < rec.records.size(); ++i) EXPECT_LT(rec.records[i - 1].tick, rec.records[i].tick);
}

TEST(Recording, PushAllocatesNothing) {
  RecordingWriterOptions opt;
  opt.ring_capacity = 64;  // overflows too: the drop path must not allocate either
  RecordingWriter writer(test::scratchDir() / "alloc.vhrec", "{}", opt);
  const TickRecord r = makeRecord(7);
  std::size_t allocations = 0;
  {
    test::AllocationGuard guard;
    for (int i = 0; i < 5000; ++i) (void)writer.push(r);
    allocations = guard.count();
  }
  EXPECT_EQ(allocations, 0u);
  writer.close();
}

/// Splits one CSV line (no quoting: the export writes numbers only).
std::vector<std::string> splitCsv(const std::string& line) {
  std::vector<std::string> cells;
  std::stringstream ss(line);
  std::string cell;
  while (std::getline(ss, cell, ',')) cells.push_back(cell);
  return cells;
}

/// Parses an exported CSV back into records (checks the header's columns on the way).
std::vector<TickRecord> parseCsv(std::istream& in) {
  std::string line;
  EXPECT_TRUE(std::getline(in, line));
  const std::vector<std::string> header = splitCsv(line);
  EXPECT_EQ(header.size(), 26u);
  EXPECT_EQ(header.front(), "t_s");
  EXPECT_EQ(header[16], "force_x_N");
  EXPECT_EQ(header[21], "torque_z_Nm");
  std::vector<TickRecord> out;
  while (std::getline(in, line)) {
    const std::vector<std::string> c = splitCsv(line);
    EXPECT_EQ(c.size(), 26u) << line;
    if (c.size() != 26) break;
    TickRecord r;
    std::size_t k = 0;
    auto num = [&] { return std::strtod(c[k++].c_str(), nullptr); };
    r.time_s = num();
    r.tick = std::stoull(c[k++]);
    for (double& v : r.p_WD_m) v = num();
    for (double& v : r.q_WD) v = num();
    for (double& v : r.p_WP_m) v = num();
    for (double& v : r.q_WP) v = num();
    for (double& v : r.force_W_N) v = num();
    for (double& v : r.torque_W_Nm) v = num();
    r.contacts = static_cast<std::uint32_t>(std::stoul(c[k++]));
    r.isovalue = num();
    r.tick_time_s = num();
    r.flags = static_cast<std::uint32_t>(std::stoul(c[k++]));
    out.push_back(r);
  }
  return out;
}

TEST(RecordingExport, CsvParsesBackBitForBit) {
  const Recording rec = readRecording(writeSession(test::scratchDir() / "csv.vhrec", 1500));
  std::stringstream csv;
  writeRecordingCsv(rec, csv);
  const std::vector<TickRecord> back = parseCsv(csv);
  ASSERT_EQ(back.size(), rec.records.size());
  for (std::size_t i = 0; i < back.size(); ++i) ASSERT_TRUE(sameBytes(back[i], rec.records[i])) << "row " << i;
}

TEST(RecordingExport, CommandLineWritesCsvAndJson) {
  const fs::path dir = test::scratchDir();
  const fs::path rec_path = writeSession(dir / "cli.vhrec", 1200);
  const fs::path csv = dir / "out.csv";
  const fs::path json = dir / "meta.json";
  const std::string command = "env -u DISPLAY -u WAYLAND_DISPLAY '" + std::string(VH_APP_EXECUTABLE) + "' export '" +
                              rec_path.string() + "' --csv '" + csv.string() + "' --json '" + json.string() +
                              "' 2>&1";
  FILE* pipe = popen(command.c_str(), "r");
  ASSERT_NE(pipe, nullptr);
  std::string output;
  std::array<char, 4096> buffer{};
  while (std::fgets(buffer.data(), static_cast<int>(buffer.size()), pipe) != nullptr) output += buffer.data();
  const int status = pclose(pipe);
  ASSERT_EQ(status, 0) << output;
  EXPECT_NE(output.find("1200 records"), std::string::npos) << output;

  std::ifstream csv_in(csv);
  const std::vector<TickRecord> back = parseCsv(csv_in);
  ASSERT_EQ(back.size(), 1200u);
  for (std::uint64_t i = 0; i < back.size(); ++i) ASSERT_TRUE(sameBytes(back[i], makeRecord(i)));
  std::ifstream json_in(json);
  const nlohmann::json meta = nlohmann::json::parse(json_in);
  EXPECT_EQ(meta.at("records"), 1200);
  EXPECT_EQ(meta.at("metadata").at("scene"), "block-peg");
  EXPECT_EQ(meta.at("dropped_records"), 0);

  // A missing file: a clear error, non-zero exit.
  FILE* bad = popen(("'" + std::string(VH_APP_EXECUTABLE) + "' export '" + (dir / "nope.vhrec").string() +
                     "' --csv '" + csv.string() + "' 2>&1")
                        .c_str(),
                    "r");
  ASSERT_NE(bad, nullptr);
  std::string bad_output;
  while (std::fgets(buffer.data(), static_cast<int>(buffer.size()), bad) != nullptr) bad_output += buffer.data();
  EXPECT_NE(pclose(bad), 0);
  EXPECT_NE(bad_output.find("cannot open"), std::string::npos) << bad_output;
}

// ---- Record through the haptic thread, replay through a fresh renderer --------------------------


/// Scripted 2 s session: approach the sphere's top, press 3 mm in, slide and twist, hold.
Trajectory pressSlideTrajectory() {
  const auto at = [](double t, double x, double z, double angle) {
    TrajectorySample s;
    s.t_s = t;
    s.X_WD.p_AB_m = {x, 0.0, z};
    s.X_WD.R_AB = Eigen::Quaterniond(Eigen::AngleAxisd(angle, Eigen::Vector3d::UnitZ()));
    return s;
  };
  return Trajectory({at(0.0, 0.0, 0.032, 0.0), at(0.5, 0.0, 0.022, 0.0), at(1.5, 0.008, 0.022, 0.6),
                     at(2.0, 0.008, 0.022, 0.6)});
}

haptics::Pose poseOf(const double p[3], const double q[4]) {
  haptics::Pose X;
  X.p_AB_m = {p[0], p[1], p[2]};
  X.R_AB = Eigen::Quaterniond(q[0], q[1], q[2], q[3]);
  return X;
}

bool sameBits(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; }

/// FNV-1a over the deterministic part of the first `n` records (poses, force, torque, contacts).
std::uint64_t sessionHash(const std::vector<TickRecord>& records, std::size_t n) {
  std::uint64_t h = 1469598103934665603ull;
  const auto mix = [&h](const void* data, std::size_t size) {
    const auto* b = static_cast<const unsigned char*>(data);
    for (std::size_t i = 0; i < size; ++i) h = (h ^ b[i]) * 1099511628211ull;
  };
  for (std::size_t i = 0; i < n; ++i) {
    const TickRecord& r = records[i];
    mix(r.p_WD_m, sizeof r.p_WD_m);
    mix(r.q_WD, sizeof r.q_WD);
    mix(r.p_WP_m, sizeof r.p_WP_m);
    mix(r.q_WP, sizeof r.q_WP);
    mix(r.force_W_N, sizeof r.force_W_N);
    mix(r.torque_W_Nm, sizeof r.torque_W_Nm);
    mix(&r.contacts, sizeof r.contacts);
  }
  return h;
}

TEST(RecordingReplay, HapticThreadRecordingReplaysBitForBitThroughAFreshRenderer) {
  const LoadedScene& scene = test::sphereBallScene();
  auto device = std::make_shared<ScriptedDevice>(pressSlideTrajectory(), 1e-3, "press-slide");
  const fs::path path = test::scratchDir() / "thread.vhrec";
  RecordingWriter writer(path, R"({"scene":"builtin:sphere","device":"scripted press-slide"})");
  {
    auto thread = scene.makeHapticThread(device);
    thread->setRecorder(&writer);
    thread->start();
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(20);
    while (!device->finished() && std::chrono::steady_clock::now() < deadline)
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    thread->stop();
  }
  writer.close();
  ASSERT_TRUE(device->finished());
  const Recording rec = readRecording(path);
  ASSERT_TRUE(rec.warnings.empty()) << rec.warnings.front();
  ASSERT_EQ(rec.dropped_records, 0u);
  ASSERT_GE(rec.records.size(), 2000u);
  EXPECT_EQ(rec.records.size(), device->reads());

  // Replay the recorded device poses through a fresh renderer, as the haptic thread drives it.
  std::unique_ptr<haptics::HapticRenderer> renderer = scene.makeRenderer();
  renderer->setGains(renderer->coupling().gains());
  std::size_t contact_ticks = 0, forces_compared = 0;
  for (std::size_t i = 0; i < rec.records.size(); ++i) {
    const TickRecord& r = rec.records[i];
    ASSERT_EQ(r.tick, i + 1);
    ASSERT_EQ(r.flags & kRecordFlagBadSample, 0u);
    const haptics::TickOutput out = renderer->tick(poseOf(r.p_WD_m, r.q_WD), r.isovalue);
    const haptics::Pose X_WP = renderer->proxyPose();
    for (int k = 0; k < 3; ++k) ASSERT_TRUE(sameBits(X_WP.p_AB_m[k], r.p_WP_m[k])) << "tick " << r.tick;
    ASSERT_TRUE(sameBits(X_WP.R_AB.w(), r.q_WP[0]) && sameBits(X_WP.R_AB.x(), r.q_WP[1]) &&
                sameBits(X_WP.R_AB.y(), r.q_WP[2]) && sameBits(X_WP.R_AB.z(), r.q_WP[3]))
        << "tick " << r.tick;
    ASSERT_EQ(renderer->contacts().size(), r.contacts) << "tick " << r.tick;
    contact_ticks += r.contacts > 0 ? 1 : 0;
    if ((r.flags & (kRecordFlagStopping | kRecordFlagForceZeroed)) == 0) {  // sent unchanged
      for (int k = 0; k < 3; ++k) {
        ASSERT_TRUE(sameBits(out.force_W_N[k], r.force_W_N[k])) << "tick " << r.tick;
        ASSERT_TRUE(sameBits(out.torque_W_Nm[k], r.torque_W_Nm[k])) << "tick " << r.tick;
      }
      ++forces_compared;
    }
  }
  EXPECT_GT(contact_ticks, 1000u);  // the session really pressed on the surface
  EXPECT_GE(forces_compared, 2000u);
  // Pinned for this build: the first 2000 ticks (2 s) of the scripted session. A change here means
  // the renderer's output changed (update the pin only for an intended change).
  const std::uint64_t hash = sessionHash(rec.records, 2000);
  std::cout << "[ recording ] session hash 0x" << std::hex << hash << std::dec << std::endl;
  EXPECT_EQ(hash, kPinnedSessionHash);
}

}  // namespace
}  // namespace vh::runtime
