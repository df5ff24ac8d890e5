// Tests of session recordings (app/runtime/src/recording.cpp): the SPSC ring, the chunked file
// format (round trip, crash truncation, kill -9, corruption skipped chunk by chunk, a write
// failure), dropped-record accounting, allocation-free push, and the CSV / JSON export (library
// and `volume-haptics export`).
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

#include <cerrno>
#include <csignal>

#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "file_size_limit.h"
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
  r.isovalue = 300.0 + static_cast<double>(i / 1000) * 25.0;  // changes every second
  r.tick = i;
  r.tick_time_s = 1e-5 * static_cast<double>(i % 13) + 1e-7;
  r.contacts = static_cast<std::uint32_t>(i % 5);
  r.flags = r.contacts > 0 ? kRecordFlagContact : 0u;
  r.removed_voxels = static_cast<std::uint32_t>(i % 3);
  r.deadline_work = i % 5 == 0 ? static_cast<std::int64_t>(1000 + i) : 0;
  return r;
}

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

struct ChunkAt {
  std::size_t offset = 0;
  std::string tag;  ///< "CHNK", "EVNT" or "ENDR".
  std::size_t size = 0;
};

/// Every chunk, walked from the header as the format documents it.
std::vector<ChunkAt> chunksOf(const std::string& bytes) {
  std::uint32_t meta = 0;
  std::memcpy(&meta, bytes.data() + 16, 4);
  std::vector<ChunkAt> chunks;
  std::size_t off = 24 + meta;
  while (off + 16 <= bytes.size()) {
    ChunkAt c;
    c.offset = off;
    c.tag = bytes.substr(off, 4);
    std::uint32_t count = 0, payload = 0;
    std::memcpy(&count, bytes.data() + off + 4, 4);
    std::memcpy(&payload, bytes.data() + off + 8, 4);
    c.size = c.tag == "EVNT"   ? 12 + std::size_t{payload} + 4
             : c.tag == "ENDR" ? 28
                               : 16 + std::size_t{count} * sizeof(TickRecord) + 4;
    chunks.push_back(c);
    off += c.size;
  }
  return chunks;
}

/// Byte offsets of every record chunk.
std::vector<std::size_t> chunkOffsets(const std::string& bytes) {
  std::vector<std::size_t> offsets;
  for (const ChunkAt& c : chunksOf(bytes))
    if (c.tag == "CHNK") offsets.push_back(c.offset);
  return offsets;
}

/// Like writeSession(), with an event every 300 records ("marker" with its index) added while
/// the records go in, and an isovalue that changes every 700 records.
fs::path writeSessionWithEvents(const fs::path& path, std::uint64_t n, std::size_t* user_events = nullptr) {
  RecordingWriterOptions opt;
  opt.ring_capacity = 1u << 16;
  RecordingWriter writer(path, R"({"scene":"block-peg"})", opt);
  std::size_t added = 0;
  for (std::uint64_t i = 0; i < n; ++i) {
    TickRecord r = makeRecord(i);
    r.isovalue = 300.0 + static_cast<double>(i / 700) * 10.0;
    EXPECT_TRUE(writer.push(r));
    if (i % 300 == 0) {
      writer.addEvent({r.time_s, r.tick, "marker", "{\"label\":\"m" + std::to_string(i) + "\"}"});
      ++added;
    }
  }
  writer.close();
  if (user_events != nullptr) *user_events = added;
  return path;
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
  // The writer turned the two isovalue changes into events.
  ASSERT_EQ(rec.events.size(), 2u);
  EXPECT_EQ(rec.events[0].type, "isovalue");
  EXPECT_EQ(rec.events[0].tick, 1000u);
  EXPECT_EQ(rec.events[0].time_s, makeRecord(1000).time_s);
  EXPECT_EQ(nlohmann::json::parse(rec.events[0].detail_json), nlohmann::json::parse(R"({"from":300.0,"to":325.0})"));
  EXPECT_EQ(rec.events[1].tick, 2000u);
  // Size: header, metadata, 20 bytes of framing per record chunk, the event chunks and the
  // 28-byte end marker, which says how the recording ended and how many ticks it holds.
  std::uintmax_t event_bytes = 0;
  const std::string bytes = readBytes(path);
  for (const ChunkAt& c : chunksOf(bytes))
    if (c.tag == "EVNT") event_bytes += c.size;
  EXPECT_EQ(rec.event_chunks, 2u);
  EXPECT_TRUE(rec.ended);
  EXPECT_EQ(rec.end_status, 0u);
  ASSERT_GE(bytes.size(), 28u);
  EXPECT_EQ(bytes.substr(bytes.size() - 28, 4), "ENDR");
  std::uint64_t ticks_in_end_marker = 0;
  std::memcpy(&ticks_in_end_marker, bytes.data() + bytes.size() - 20, 8);
  EXPECT_EQ(ticks_in_end_marker, 2500u);
  const std::uintmax_t expected_size = 24 + rec.metadata_json.size() + 2500 * sizeof(TickRecord) + rec.chunks * 20 + event_bytes + 28;
  EXPECT_EQ(fs::file_size(path), expected_size);
}

TEST(Recording, EventsRoundTripInTickOrderAndAppearInTheJsonAndEventsCsv) {
  const fs::path dir = test::scratchDir();
  std::size_t user_events = 0;
  const fs::path path = writeSessionWithEvents(dir / "events.vhrec", 2500, &user_events);
  const Recording rec = readRecording(path);
  ASSERT_TRUE(rec.warnings.empty()) << rec.warnings.front();
  EXPECT_EQ(rec.records.size(), 2500u);
  std::size_t markers = 0, isovalue_changes = 0;
  for (std::size_t i = 0; i < rec.events.size(); ++i) {
    const RecordingEvent& e = rec.events[i];
    if (i > 0) {
      EXPECT_LE(rec.events[i - 1].tick, e.tick);
    }
    const nlohmann::json d = nlohmann::json::parse(e.detail_json);
    if (e.type == "marker") {
      const std::string label = d.at("label").get<std::string>();
      EXPECT_EQ(label.front(), 'm');
      EXPECT_EQ(label.substr(1), std::to_string(e.tick));
      EXPECT_EQ(e.time_s, makeRecord(e.tick).time_s);
      ++markers;
    } else if (e.type == "isovalue") {
      EXPECT_EQ(e.tick % 700, 0u);
      EXPECT_EQ(d.at("to").get<double>() - d.at("from").get<double>(), 10.0);
      ++isovalue_changes;
    }
  }
  EXPECT_EQ(markers, user_events);
  EXPECT_EQ(isovalue_changes, 3u);  // at 700, 1400, 2100
  EXPECT_EQ(rec.events.size(), markers + isovalue_changes);

  // addEvent rejects what is not a JSON object, and everything after close().
  RecordingWriter writer(dir / "bad-events.vhrec", "{}");
  VH_EXPECT_THROW_WITH(writer.addEvent({0.0, 1, "marker", "[1]"}), std::invalid_argument, "JSON object");
  VH_EXPECT_THROW_WITH(writer.addEvent({0.0, 1, "marker", "{oops"}), std::invalid_argument, "not JSON");
  VH_EXPECT_THROW_WITH(writer.addEvent({0.0, 1, "", "{}"}), std::invalid_argument, "empty event type");
  writer.addEvent({0.0, 1, "note", ""});  // empty detail = {}
  writer.close();
  VH_EXPECT_THROW_WITH(writer.addEvent({0.0, 1, "marker", "{}"}), std::logic_error, "closed");
  const Recording only_event = readRecording(dir / "bad-events.vhrec");
  ASSERT_EQ(only_event.events.size(), 1u);  // events without any record are written too
  EXPECT_EQ(only_event.events[0].type, "note");
  EXPECT_EQ(only_event.events[0].detail_json, "{}");
  EXPECT_TRUE(only_event.records.empty());

  // JSON export: the events with their details parsed.
  writeRecordingJson(rec, dir / "events.json");
  std::ifstream json_in(dir / "events.json");
  const nlohmann::json j = nlohmann::json::parse(json_in);
  ASSERT_EQ(j.at("events").size(), rec.events.size());
  EXPECT_EQ(j.at("events")[0].at("type"), rec.events[0].type);
  EXPECT_EQ(j.at("events")[0].at("tick"), rec.events[0].tick);
  EXPECT_TRUE(j.at("events")[0].at("detail").is_object());
  // Events CSV: header, one quoted row per event.
  std::stringstream csv;
  writeRecordingEventsCsv(rec, csv);
  std::string line;
  ASSERT_TRUE(std::getline(csv, line));
  EXPECT_EQ(line, "t_s,tick,type,detail_json");
  ASSERT_TRUE(std::getline(csv, line));
  EXPECT_EQ(line, "0,0,\"marker\",\"{\"\"label\"\":\"\"m0\"\"}\"");
  std::size_t rows = 1;
  while (std::getline(csv, line)) ++rows;
  EXPECT_EQ(rows, rec.events.size());
}

TEST(Recording, DeviceDisconnectFlagsBecomeConnectAndDisconnectEvents) {
  const fs::path path = test::scratchDir() / "connection.vhrec";
  RecordingWriter writer(path, "{}");
  for (std::uint64_t i = 0; i < 1200; ++i) {
    TickRecord r = makeRecord(i);
    r.isovalue = 300.0;
    // Disconnected from the start to tick 99, again over ticks 500..799.
    if (i < 100 || (i >= 500 && i < 800)) r.flags |= kRecordFlagDeviceDisconnected;
    ASSERT_TRUE(writer.push(r));
  }
  writer.close();
  const Recording rec = readRecording(path);
  ASSERT_EQ(rec.events.size(), 4u);
  const std::vector<std::pair<std::string, std::uint64_t>> expected = {
      {"device_disconnected", 0}, {"device_connected", 100}, {"device_disconnected", 500}, {"device_connected", 800}};
  for (std::size_t i = 0; i < expected.size(); ++i) {
    EXPECT_EQ(rec.events[i].type, expected[i].first) << "event " << i;
    EXPECT_EQ(rec.events[i].tick, expected[i].second) << "event " << i;
    EXPECT_EQ(rec.events[i].time_s, makeRecord(expected[i].second).time_s);
  }
}

TEST(Recording, ReadsVersionOneAndTwoFiles) {
  // A version 2 file is a version 3 file without the end marker, and a version 1 file one
  // without event chunks either, with their version in the header.
  const fs::path dir = test::scratchDir();
  RecordingWriter writer(dir / "v3.vhrec", R"({"scene":"x"})");
  for (std::uint64_t i = 0; i < 600; ++i) ASSERT_TRUE(writer.push(makeRecord(i)));  // one isovalue: no events
  writer.close();
  std::string bytes = readBytes(dir / "v3.vhrec");
  const std::vector<ChunkAt> chunks = chunksOf(bytes);
  ASSERT_EQ(chunks.back().tag, "ENDR");
  ASSERT_EQ(chunks.back().offset + 28, bytes.size());
  for (std::size_t i = 0; i + 1 < chunks.size(); ++i) ASSERT_EQ(chunks[i].tag, "CHNK");
  bytes.resize(chunks.back().offset);
  bytes = test::asVersion3Recording(bytes);  // 200-byte records, as versions 1 to 3 stored them
  for (const char version : {'\x01', '\x02'}) {
    bytes[8] = version;
    writeBytes(dir / "old.vhrec", bytes);
    const Recording rec = readRecording(dir / "old.vhrec");
    EXPECT_EQ(rec.version, static_cast<std::uint32_t>(version));
    EXPECT_TRUE(rec.warnings.empty()) << rec.warnings.front();  // no end marker expected
    EXPECT_FALSE(rec.ended);
    ASSERT_EQ(rec.records.size(), 600u);
    for (std::uint64_t i = 0; i < 600; ++i) {
      const TickRecord want = makeRecord(i);
      ASSERT_EQ(std::memcmp(&rec.records[i], &want, kTickRecordBytesV3), 0);  // up to flags
      ASSERT_TRUE(std::isnan(rec.records[i].critical_distance_m));                      // not measured
    }
    EXPECT_TRUE(rec.events.empty());
  }
}

// Format version 4 (216-byte records: proximity, but neither removed voxels nor the deadline's
// work) still reads: the proximity as stored, the two newer fields 0.
TEST(Recording, ReadsVersionFourFiles) {
  const fs::path dir = test::scratchDir();
  RecordingWriter writer(dir / "v5.vhrec", R"({"scene":"x"})");
  for (std::uint64_t i = 0; i < 600; ++i) {
    TickRecord r = makeRecord(i);
    r.critical_distance_m = 1e-3 * static_cast<double>(i % 7);
    r.critical_segment = static_cast<std::int32_t>(i % 3) - 1;
    r.removed_voxels = static_cast<std::uint32_t>(i % 4);
    r.deadline_work = static_cast<std::int64_t>(i % 2) * 1234;
    ASSERT_TRUE(writer.push(r));
  }
  writer.close();
  const Recording current = readRecording(dir / "v5.vhrec");
  ASSERT_EQ(current.version, 5u);
  ASSERT_EQ(current.records.size(), 600u);
  EXPECT_EQ(current.records[3].removed_voxels, 3u);
  EXPECT_EQ(current.records[3].deadline_work, 1234);
  writeBytes(dir / "v4.vhrec", test::asVersion4Recording(readBytes(dir / "v5.vhrec")));
  const Recording rec = readRecording(dir / "v4.vhrec");
  EXPECT_EQ(rec.version, 4u);
  EXPECT_TRUE(rec.warnings.empty()) << rec.warnings.front();
  EXPECT_TRUE(rec.ended);
  ASSERT_EQ(rec.records.size(), 600u);
  for (std::size_t i = 0; i < 600; ++i) {
    ASSERT_EQ(std::memcmp(&rec.records[i], &current.records[i], kTickRecordBytesV4 - 4), 0);  // up to the segment
    ASSERT_EQ(rec.records[i].removed_voxels, 0u);
    ASSERT_EQ(rec.records[i].deadline_work, 0);
  }
  std::string wrong = readBytes(dir / "v4.vhrec");
  wrong[8] = '\x05';  // version 5 named over 216-byte records
  writeBytes(dir / "wrong.vhrec", wrong);
  VH_EXPECT_THROW_WITH(readRecording(dir / "wrong.vhrec"), std::runtime_error, "record size 216 bytes, expected 224 for version 5");
}

// JSON nested 100,000 deep in the metadata (its CRC-32 right) is refused at once as damaged,
// and an event whose detail nests 200,000 deep is dropped with a warning while the rest reads:
// before, `export --json` ran past 60 s and 4 GB pretty-printing them (the indentation grows
// with the depth). No clock is checked: the test would not end if the reader took minutes.
TEST(Recording, JsonNestedThousandsDeepIsRefusedOrDropped) {
  const fs::path dir = test::scratchDir();
  const std::string good = readBytes(writeSession(dir / "ok.vhrec", 10));
  const auto u32 = [](const std::string& b, std::size_t at) {
    std::uint32_t v = 0;
    std::memcpy(&v, b.data() + at, 4);
    return v;
  };
  const auto put32 = [](std::string& b, std::size_t at, std::uint32_t v) { std::memcpy(b.data() + at, &v, 4); };
  const auto le32 = [](std::uint32_t v) { return std::string(reinterpret_cast<const char*>(&v), 4); };
  const std::uint32_t meta_size = u32(good, 16);
  const std::string deep_meta = "{\"a\":" + std::string(100000, '[') + std::string(100000, ']') + "}";
  std::string bad = good.substr(0, 24) + deep_meta + good.substr(24 + meta_size);
  put32(bad, 16, static_cast<std::uint32_t>(deep_meta.size()));
  put32(bad, 20, crc32(deep_meta.data(), deep_meta.size()));
  writeBytes(dir / "deep-meta.vhrec", bad);
  VH_EXPECT_THROW_WITH(readRecording(dir / "deep-meta.vhrec"), std::runtime_error,
                       "damaged metadata: JSON nested 100001 deep (at most 100)");

  // An event chunk with one deep "marker" and one plain one, before the end marker.
  const auto event = [&](const std::string& detail) {
    const double t = 0.001;
    const std::uint64_t tick = 1;
    std::string e(reinterpret_cast<const char*>(&t), 8);
    e += std::string(reinterpret_cast<const char*>(&tick), 8);
    e += le32(6) + "marker" + le32(static_cast<std::uint32_t>(detail.size())) + detail;
    return e;
  };
  const std::string payload = event("{\"x\":" + std::string(200000, '[') + std::string(200000, ']') + "}") +
                              event(R"({"label": "kept"})");
  std::string chunk = "EVNT" + le32(2) + le32(static_cast<std::uint32_t>(payload.size())) + payload;
  chunk += le32(crc32(chunk.data(), chunk.size()));
  ASSERT_EQ(good.substr(good.size() - 28, 4), "ENDR");
  writeBytes(dir / "deep-event.vhrec", good.substr(0, good.size() - 28) + chunk + good.substr(good.size() - 28));
  const Recording rec = readRecording(dir / "deep-event.vhrec");
  EXPECT_EQ(rec.records.size(), 10u);
  ASSERT_EQ(rec.events.size(), 1u);
  EXPECT_EQ(rec.events[0].detail_json, R"({"label": "kept"})");
  bool said = false;
  for (const std::string& w : rec.warnings) said = said || w.find("1 event(s) dropped") != std::string::npos;
  EXPECT_TRUE(said);
}

TEST(Recording, CrashTruncationOpensUpToTheLastGoodChunkLosingUnderOneSecond) {
  const fs::path path = writeSession(test::scratchDir() / "crash.vhrec", 4000);
  const std::string bytes = readBytes(path);
  const std::vector<std::size_t> chunks = chunkOffsets(bytes);
  ASSERT_GE(chunks.size(), 2u);
  // Cut in the middle of the last chunk, as a kill -9 during its write would.
  const std::size_t cut = chunks.back() + (bytes.size() - 28 - chunks.back()) / 2;
  writeBytes(path, bytes.substr(0, cut));

  const Recording rec = readRecording(path);
  ASSERT_EQ(rec.warnings.size(), 2u);
  EXPECT_NE(rec.warnings[0].find("truncated chunk"), std::string::npos) << rec.warnings[0];
  EXPECT_NE(rec.warnings[1].find("unfinished recording"), std::string::npos) << rec.warnings[1];
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
  ASSERT_EQ(rec2.warnings.size(), 2u);
  EXPECT_NE(rec2.warnings[0].find("truncated chunk header"), std::string::npos) << rec2.warnings[0];
  EXPECT_EQ(rec2.records.size(), rec.records.size());
}

TEST(Recording, CrashTruncationInsideAnEventChunkKeepsEverythingBeforeIt) {
  const fs::path path = writeSessionWithEvents(test::scratchDir() / "crash-events.vhrec", 3000);
  const std::string bytes = readBytes(path);
  const Recording full = readRecording(path);
  const std::vector<ChunkAt> chunks = chunksOf(bytes);
  // The last event chunk that has record chunks before it.
  std::size_t k = chunks.size();
  for (std::size_t i = chunks.size(); i-- > 1;) {
    if (chunks[i].tag == "EVNT") {
      k = i;
      break;
    }
  }
  ASSERT_LT(k, chunks.size()) << "no event chunk after the first chunk";
  std::size_t records_before = 0, events_before = 0;
  for (std::size_t i = 0; i < k; ++i) {
    std::uint32_t count = 0;
    std::memcpy(&count, bytes.data() + chunks[i].offset + 4, 4);
    (chunks[i].tag == "CHNK" ? records_before : events_before) += count;
  }
  for (const std::size_t cut : {chunks[k].offset + 5, chunks[k].offset + chunks[k].size - 3}) {
    writeBytes(path, bytes.substr(0, cut));
    const Recording rec = readRecording(path);
    ASSERT_EQ(rec.warnings.size(), 2u);
    EXPECT_NE(rec.warnings[0].find("truncated event chunk"), std::string::npos) << rec.warnings[0];
    EXPECT_NE(rec.warnings[1].find("unfinished recording"), std::string::npos) << rec.warnings[1];
    EXPECT_EQ(rec.records.size(), records_before);
    EXPECT_EQ(rec.events.size(), events_before);
    EXPECT_EQ(rec.bytes_ignored, cut - chunks[k].offset);
    for (std::size_t i = 0; i < rec.events.size(); ++i) EXPECT_EQ(rec.events[i].tick, full.events[i].tick);
  }
}

TEST(Recording, CorruptedEventChunkCostsOnlyItsEvents) {
  const fs::path path = writeSessionWithEvents(test::scratchDir() / "corrupt-events.vhrec", 3000);
  std::string bytes = readBytes(path);
  const std::vector<ChunkAt> chunks = chunksOf(bytes);
  std::size_t k = 0;
  for (std::size_t i = 1; i < chunks.size(); ++i) {
    if (chunks[i].tag == "EVNT") {
      k = i;
      break;
    }
  }
  ASSERT_GT(k, 0u);
  bytes[chunks[k].offset + 12 + 20] ^= 0x04;  // a byte of the first event's type
  writeBytes(path, bytes);
  const Recording rec = readRecording(path);
  ASSERT_EQ(rec.warnings.size(), 1u);
  EXPECT_NE(rec.warnings[0].find("event chunk checksum mismatch"), std::string::npos) << rec.warnings[0];
  EXPECT_NE(rec.warnings[0].find("at byte " + std::to_string(chunks[k].offset)), std::string::npos) << rec.warnings[0];
  EXPECT_NE(rec.warnings[0].find("no ticks are missing"), std::string::npos) << rec.warnings[0];
  EXPECT_EQ(rec.bytes_ignored, chunks[k].size);
  EXPECT_EQ(rec.damaged_regions, 1u);
  EXPECT_EQ(rec.chunks + rec.event_chunks, chunks.size() - 2);  // all but the damaged one and the end marker
  EXPECT_TRUE(rec.ended);
  ASSERT_EQ(rec.records.size(), 3000u);
  for (std::uint64_t i = 0; i < rec.records.size(); ++i) ASSERT_EQ(rec.records[i].tick, i);
  std::uint32_t lost = 0;
  std::memcpy(&lost, bytes.data() + chunks[k].offset + 4, 4);
  const Recording whole = readRecording(writeSessionWithEvents(test::scratchDir() / "whole-events.vhrec", 3000));
  EXPECT_EQ(rec.events.size() + lost, whole.events.size());
}

TEST(Recording, OneDamagedChunkCostsThatChunkOnly) {
  // Ten chunks of 500 ticks; one byte flipped in chunk k (in a record, in the header's count,
  // in the tag): every other chunk's ticks read back as written.
  const fs::path path = writeSession(test::scratchDir() / "corrupt.vhrec", 5000);
  const std::string whole = readBytes(path);
  const std::vector<std::size_t> chunks = chunkOffsets(whole);
  ASSERT_EQ(chunks.size(), 10u);
  for (const std::size_t k : {std::size_t{0}, std::size_t{4}, std::size_t{9}}) {
    for (const std::size_t at : {std::size_t{16 + 1234}, std::size_t{5}, std::size_t{1}}) {
      std::string bytes = whole;
      bytes[chunks[k] + at] = static_cast<char>(bytes[chunks[k] + at] ^ 0x10);
      writeBytes(path, bytes);
      const Recording rec = readRecording(path);
      SCOPED_TRACE("chunk " + std::to_string(k) + ", byte " + std::to_string(at));
      ASSERT_EQ(rec.records.size(), 4500u);
      for (std::size_t i = 0; i < rec.records.size(); ++i) {
        const std::uint64_t tick = i < 500 * k ? i : i + 500;  // the oracle: the ticks written
        ASSERT_TRUE(sameBytes(rec.records[i], makeRecord(tick))) << "record " << i;
      }
      EXPECT_EQ(rec.chunks, 9u);
      EXPECT_EQ(rec.damaged_regions, 1u);
      EXPECT_TRUE(rec.ended);
      const std::size_t chunk_bytes = 16 + 500 * sizeof(TickRecord) + 4;
      EXPECT_EQ(rec.bytes_ignored, chunk_bytes);
      ASSERT_EQ(rec.warnings.size(), 2u);
      const std::string& w = rec.warnings[0];
      EXPECT_NE(w.find("at byte " + std::to_string(chunks[k])), std::string::npos) << w;
      EXPECT_NE(w.find("skipped " + std::to_string(chunk_bytes) + " damaged bytes"), std::string::npos) << w;
      if (k == 0) {
        EXPECT_NE(w.find("the ticks before tick 500 are missing"), std::string::npos) << w;
      } else if (k == 9) {
        EXPECT_NE(w.find("the 500 ticks after tick 4499 are missing"), std::string::npos) << w;
      } else {
        EXPECT_NE(w.find("ticks " + std::to_string(500 * k) + " to " + std::to_string(500 * k + 499) +
                         " are missing (500 ticks)"),
                  std::string::npos)
            << w;
      }
      EXPECT_NE(rec.warnings[1].find("4500 ticks kept of the 5000 written"), std::string::npos) << rec.warnings[1];
    }
  }
}

/// A kill -9 while recording: the child writes `n` records, waits until they are on disk and
/// kills itself. @return the recording.
fs::path killedWhileRecording(const fs::path& path, std::uint64_t n) {
  const pid_t child = ::fork();
  if (child == 0) {
    RecordingWriterOptions opt;
    opt.ring_capacity = 1u << 16;
    auto* writer = new RecordingWriter(path, R"({"scene":"killed"})", opt);  // never closed
    for (std::uint64_t i = 0; i < n; ++i) (void)writer->push(makeRecord(i));
    while (writer->recordsWritten() < n) std::this_thread::sleep_for(std::chrono::milliseconds(5));
    ::kill(::getpid(), SIGKILL);
    ::_exit(3);
  }
  int status = 0;
  EXPECT_EQ(::waitpid(child, &status, 0), child);
  EXPECT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL) << "status " << status;
  return path;
}

TEST(Recording, KillNineLeavesARecordingReadAsUnfinished) {
  const fs::path dir = test::scratchDir();
  const Recording rec = readRecording(killedWhileRecording(dir / "killed.vhrec", 1234));
  ASSERT_EQ(rec.records.size(), 1234u);
  for (std::uint64_t i = 0; i < 1234; ++i) ASSERT_TRUE(sameBytes(rec.records[i], makeRecord(i)));
  EXPECT_FALSE(rec.ended);
  ASSERT_EQ(rec.warnings.size(), 1u);
  EXPECT_NE(rec.warnings[0].find("unfinished recording: ended without its end marker"), std::string::npos)
      << rec.warnings[0];
  EXPECT_NE(rec.warnings[0].find("1234 ticks kept"), std::string::npos) << rec.warnings[0];
  // The same records closed normally: finished, no warning.
  const Recording closed = readRecording(writeSession(dir / "closed.vhrec", 1234));
  EXPECT_TRUE(closed.ended);
  EXPECT_EQ(closed.end_status, 0u);
  EXPECT_TRUE(closed.warnings.empty());
}

using vh::test::FileSizeLimit;

TEST(Recording, AWriteFailureStopsAtOnceAndKeepsEveryWholeChunk) {
  const fs::path path = test::scratchDir() / "full.vhrec";
  const rlim_t limit = 300000;  // room for the header and 2 whole chunks of 500 ticks, not 3
  std::string close_error;
  std::uint64_t written = 0;
  std::string failure;
  {
    const FileSizeLimit full(limit);
    RecordingWriterOptions opt;
    opt.ring_capacity = 1u << 16;
    RecordingWriter writer(path, R"({"scene":"full"})", opt);
    for (std::uint64_t i = 0; i < 5000; ++i) ASSERT_TRUE(writer.push(makeRecord(i)));
    // The writer thread reaches the limit on its own; polled with a generous deadline (it may
    // run late on a loaded machine).
    EXPECT_TRUE(test::waitUntil([&] { return writer.failed(); }));
    failure = writer.failure();
    try {
      writer.close();
    } catch (const std::runtime_error& e) {
      close_error = e.what();
    }
    written = writer.recordsWritten();
  }
  EXPECT_EQ(failure, "file size limit reached (File too large)");
  EXPECT_NE(close_error.find("file size limit reached (File too large); 1000 ticks kept"), std::string::npos)
      << close_error;
  EXPECT_EQ(written, 1000u);
  // The file (stat) ends on whole chunks: the 2 record chunks, the isovalue event at tick 1000
  // (written before the chunk that failed), and the end marker, which fitted once the partly
  // written chunk was cut off.
  struct stat st{};
  ASSERT_EQ(::stat(path.c_str(), &st), 0);
  EXPECT_LE(static_cast<rlim_t>(st.st_size), limit);
  const std::string bytes = readBytes(path);
  ASSERT_EQ(bytes.size(), static_cast<std::size_t>(st.st_size));
  const std::vector<ChunkAt> chunks = chunksOf(bytes);
  std::string tags;
  for (const ChunkAt& c : chunks) tags += c.tag + " ";
  EXPECT_EQ(tags, "CHNK CHNK EVNT ENDR ");
  ASSERT_FALSE(chunks.empty());
  EXPECT_EQ(chunks.back().offset + chunks.back().size, bytes.size());
  const Recording rec = readRecording(path);
  ASSERT_EQ(rec.records.size(), 1000u);
  for (std::uint64_t i = 0; i < 1000; ++i) ASSERT_TRUE(sameBytes(rec.records[i], makeRecord(i)));
  EXPECT_TRUE(rec.ended);
  EXPECT_EQ(rec.end_status, static_cast<std::uint32_t>(EFBIG));
  ASSERT_EQ(rec.warnings.size(), 1u);  // no truncated chunk: only how it ended
  EXPECT_EQ(rec.warnings[0], "the recording ended early: file size limit reached (File too large); 1000 ticks kept");
}

TEST(Recording, DamagedHeadersThrowWithTheReason) {
  const fs::path dir = test::scratchDir();
  const fs::path path = writeSession(dir / "ok.vhrec", 10);
  std::string bytes = readBytes(path);

  writeBytes(dir / "magic.vhrec", "not a recording at all, just text");
  VH_EXPECT_THROW_WITH(readRecording(dir / "magic.vhrec"), std::runtime_error, "bad magic");
  std::string v6 = bytes;
  v6[8] = 6;
  writeBytes(dir / "v6.vhrec", v6);
  VH_EXPECT_THROW_WITH(readRecording(dir / "v6.vhrec"), std::runtime_error, "unsupported format version 6");
  std::string v3 = bytes;  // a version 3 header over version 5's 224-byte records
  v3[8] = 3;
  writeBytes(dir / "v3.vhrec", v3);
  VH_EXPECT_THROW_WITH(readRecording(dir / "v3.vhrec"), std::runtime_error, "record size 224 bytes, expected 200 for version 3");
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
  EXPECT_EQ(header.size(), 30u);
  EXPECT_EQ(header[28], "removed_voxels");
  EXPECT_EQ(header[29], "deadline_work");
  EXPECT_EQ(header[26], "critical_distance_m");
  EXPECT_EQ(header.front(), "t_s");
  EXPECT_EQ(header[16], "force_x_N");
  EXPECT_EQ(header[21], "torque_z_Nm");
  std::vector<TickRecord> out;
  while (std::getline(in, line)) {
    const std::vector<std::string> c = splitCsv(line);
    EXPECT_EQ(c.size(), 30u) << line;
    if (c.size() != 30) break;
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
    r.critical_distance_m = num();
    r.critical_segment = std::stoi(c[k++]);
    r.removed_voxels = static_cast<std::uint32_t>(std::stoul(c[k++]));
    r.deadline_work = std::stoll(c[k++]);
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
  std::string bad_command(1, '\'');  // built by appending: GCC 12 warns falsely on "'" + std::string
  bad_command.append(VH_APP_EXECUTABLE).append("' export '").append((dir / "nope.vhrec").string());
  bad_command.append("' --csv '").append(csv.string()).append("' 2>&1");
  FILE* bad = popen(bad_command.c_str(), "r");
  ASSERT_NE(bad, nullptr);
  std::string bad_output;
  while (std::fgets(buffer.data(), static_cast<int>(buffer.size()), bad) != nullptr) bad_output += buffer.data();
  EXPECT_NE(pclose(bad), 0);
  EXPECT_NE(bad_output.find("cannot open"), std::string::npos) << bad_output;
}

TEST(RecordingExport, CommandLineSaysARecordingIsUnfinished) {
  // A kill -9 that ended on a chunk boundary: nothing truncated, but `export` and `report`
  // both say the recording is unfinished and how many ticks it kept.
  const fs::path dir = test::scratchDir();
  const fs::path rec_path = killedWhileRecording(dir / "killed.vhrec", 1500);
  const auto run = [](const std::string& args, std::string& output) {
    const std::string command = "env -u DISPLAY -u WAYLAND_DISPLAY '" + std::string(VH_APP_EXECUTABLE) + "' " + args + " 2>&1";
    FILE* pipe = popen(command.c_str(), "r");
    if (pipe == nullptr) return -1;
    std::array<char, 4096> buffer{};
    while (std::fgets(buffer.data(), static_cast<int>(buffer.size()), pipe) != nullptr) output += buffer.data();
    return pclose(pipe);
  };
  const std::string expected = "unfinished recording: ended without its end marker (the program stopped, or a write "
                               "failed, while recording); 1500 ticks kept";
  std::string output;
  ASSERT_EQ(run("export '" + rec_path.string() + "' --csv '" + (dir / "out.csv").string() + "'", output), 0) << output;
  EXPECT_NE(output.find("warning: " + expected), std::string::npos) << output;
  std::string report_output;
  const fs::path html = dir / "report.html";
  ASSERT_EQ(run("report '" + rec_path.string() + "' --no-anatomy --html '" + html.string() + "'", report_output), 0)
      << report_output;
  EXPECT_NE(report_output.find("warning: " + expected), std::string::npos) << report_output;
  EXPECT_NE(readBytes(html).find(expected), std::string::npos);
}

}  // namespace
}  // namespace vh::runtime
