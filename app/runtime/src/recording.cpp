// Session recordings: the ring, the chunked file writer and reader, CSV / JSON export.
// The file format is documented in vh/runtime/recording.h.
#include "vh/runtime/recording.h"

#include "vh/runtime/jam_detector.h"

#include <algorithm>
#include <array>
#include <bit>
#include <chrono>
#include <cmath>
#include <cstring>
#include <ctime>
#include <fstream>
#include <iomanip>
#include <iterator>
#include <ostream>
#include <sstream>
#include <stdexcept>

#include <unistd.h>

#include <nlohmann/json.hpp>
#include <zlib.h>

#include "vh/io/private_files.h"

static_assert(std::endian::native == std::endian::little,
              "the recording format is little-endian; add byte swapping for this host");

namespace vh::runtime {
namespace {

constexpr std::array<char, 8> kMagic = {'V', 'H', 'R', 'E', 'C', '\r', '\n', '\x1a'};
constexpr std::array<char, 4> kChunkTag = {'C', 'H', 'N', 'K'};
constexpr std::array<char, 4> kEventTag = {'E', 'V', 'N', 'T'};
constexpr std::size_t kEventHeaderBytes = 12;
constexpr std::size_t kMaxEventPayloadBytes = std::size_t{16} << 20;
constexpr std::size_t kMaxChunkEvents = 65535;
constexpr std::size_t kFileHeaderBytes = 24;
constexpr std::size_t kChunkHeaderBytes = 16;
constexpr std::size_t kMaxChunkRecords = 65535;

void putU32(unsigned char* p, std::uint32_t v) noexcept { std::memcpy(p, &v, 4); }
void putU64(unsigned char* p, std::uint64_t v) noexcept { std::memcpy(p, &v, 8); }
std::uint32_t getU32(const unsigned char* p) noexcept {
  std::uint32_t v;
  std::memcpy(&v, p, 4);
  return v;
}
std::uint64_t getU64(const unsigned char* p) noexcept {
  std::uint64_t v;
  std::memcpy(&v, p, 8);
  return v;
}

/// Parses `text` (empty = {}) as a JSON object. @throws std::invalid_argument naming `what`.
nlohmann::json parseObject(const std::string& text, const std::string& what) {
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(text.empty() ? std::string("{}") : text);
  } catch (const nlohmann::json::exception& e) {
    throw std::invalid_argument(what + " is not JSON: " + e.what());
  }
  if (!j.is_object()) throw std::invalid_argument(what + " must be a JSON object, got: " + text);
  return j;
}

void appendBytes(std::string& out, const void* data, std::size_t size) {
  out.append(static_cast<const char*>(data), size);
}

}  // namespace

std::string utcNow() {
  const std::time_t now = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&now, &tm);
  char buf[32];
  std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", &tm);
  return buf;
}

std::uint32_t crc32(const void* data, std::size_t size, std::uint32_t crc) noexcept {
  // zlib's CRC-32 is this one (ISO-HDLC); crc32_z takes a size_t length.
  return static_cast<std::uint32_t>(::crc32_z(crc, static_cast<const Bytef*>(data), size));
}

// ---- RecordingWriter -----------------------------------------------------------------------------

namespace {
/// The segments a recording's metadata lists ("scene.segmentation.segments": [{"name",
/// "critical"}]); empty when none (or malformed: a recording stays readable).
void segmentList(const nlohmann::json& meta, std::vector<std::string>& names, std::vector<bool>& critical) {
  names.clear();
  critical.clear();
  try {
    if (!meta.is_object() || !meta.contains("scene") || !meta["scene"].contains("segmentation")) return;
    for (const auto& s : meta["scene"]["segmentation"].at("segments")) {
      names.push_back(s.at("name").get<std::string>());
      critical.push_back(s.value("critical", false));
    }
  } catch (const nlohmann::json::exception&) {
    names.clear();
    critical.clear();
  }
}
}  // namespace

RecordingWriter::RecordingWriter(const std::filesystem::path& path, const std::string& metadata_json,
                                 const RecordingWriterOptions& options)
    : path_(path), options_(options), ring_(options.ring_capacity) {
  if (options.chunk_records == 0 || options.chunk_records > kMaxChunkRecords)
    throw std::invalid_argument("RecordingWriter: chunk_records must be in [1, 65535], got " +
                                std::to_string(options.chunk_records));
  if (!(static_cast<double>(options.chunk_records) < options.servo_rate_Hz))
    throw std::invalid_argument("RecordingWriter: chunk_records (" + std::to_string(options.chunk_records) +
                                ") must hold under 1 s of ticks at servo_rate_Hz");
  if (!(options.max_chunk_wall_s > 0.0 && options.max_chunk_wall_s < 1.0))
    throw std::invalid_argument("RecordingWriter: max_chunk_wall_s must be in (0, 1) s");
  nlohmann::json meta = parseObject(metadata_json, "RecordingWriter: metadata");
  meta["servo_rate_Hz"] = options.servo_rate_Hz;
  if (!meta.contains("start_time_utc")) meta["start_time_utc"] = utcNow();
  segmentList(meta, segment_names_, segment_critical_);
  const std::string text = meta.dump();

  // Owner-only (0600) whatever the umask: a recording names the scan and carries the session.
  int fd = -1;
  try {
    fd = io::openPrivateFile(path);
  } catch (const std::runtime_error& e) {
    throw std::runtime_error(std::string("RecordingWriter: ") + e.what());
  }
  file_ = ::fdopen(fd, "wb");
  if (file_ == nullptr) {
    ::close(fd);
    throw std::runtime_error("RecordingWriter: cannot create " + path.string());
  }
  std::array<unsigned char, kFileHeaderBytes> header{};
  std::memcpy(header.data(), kMagic.data(), kMagic.size());
  putU32(header.data() + 8, kRecordingFormatVersion);
  putU32(header.data() + 12, static_cast<std::uint32_t>(sizeof(TickRecord)));
  putU32(header.data() + 16, static_cast<std::uint32_t>(text.size()));
  putU32(header.data() + 20, crc32(text.data(), text.size()));
  if (std::fwrite(header.data(), 1, header.size(), file_) != header.size() ||
      std::fwrite(text.data(), 1, text.size(), file_) != text.size() || std::fflush(file_) != 0) {
    std::fclose(file_);
    file_ = nullptr;
    throw std::runtime_error("RecordingWriter: cannot write the header of " + path.string());
  }
  chunk_.resize(options.chunk_records);
  thread_ = std::thread([this] { run(); });
}

RecordingWriter::~RecordingWriter() {
  try {
    close();
  } catch (...) {  // NOLINT(bugprone-empty-catch): documented, close() reports
  }
}

bool RecordingWriter::writeChunk(const TickRecord* records, std::size_t count) noexcept {
  if (count == 0) return true;
  std::array<unsigned char, kChunkHeaderBytes> header{};
  std::memcpy(header.data(), kChunkTag.data(), kChunkTag.size());
  putU32(header.data() + 4, static_cast<std::uint32_t>(count));
  putU64(header.data() + 8, ring_.dropped());
  const std::size_t payload = count * sizeof(TickRecord);
  std::uint32_t crc = crc32(header.data(), header.size());
  crc = crc32(records, payload, crc);
  std::array<unsigned char, 4> trailer{};
  putU32(trailer.data(), crc);
  const bool ok = std::fwrite(header.data(), 1, header.size(), file_) == header.size() &&
                  std::fwrite(records, 1, payload, file_) == payload &&
                  std::fwrite(trailer.data(), 1, trailer.size(), file_) == trailer.size() &&
                  std::fflush(file_) == 0;
  if (ok) written_.fetch_add(count, std::memory_order_relaxed);
  return ok;
}

void RecordingWriter::pushWaiting(const TickRecord& record) noexcept {
  while (ring_.size() >= ring_.capacity()) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  (void)ring_.push(record);
}

void RecordingWriter::addEvent(const RecordingEvent& event) {
  if (event.type.empty()) throw std::invalid_argument("RecordingWriter::addEvent: empty event type");
  RecordingEvent copy = event;
  copy.detail_json = parseObject(event.detail_json, "RecordingWriter::addEvent: detail of \"" + event.type + "\"").dump();
  const std::lock_guard<std::mutex> lock(events_mutex_);
  if (closed_) throw std::logic_error("RecordingWriter::addEvent: the recording " + path_.string() + " is closed");
  pending_events_.push_back(std::move(copy));
}

void RecordingWriter::deriveEvents(const TickRecord* records, std::size_t count) {
  std::vector<RecordingEvent> derived;
  for (std::size_t i = 0; i < count; ++i) {
    const TickRecord& r = records[i];
    const bool disconnected = (r.flags & kRecordFlagDeviceDisconnected) != 0;
    if (!have_previous_) {
      have_previous_ = true;
      if (disconnected) derived.push_back({r.time_s, r.tick, "device_disconnected", "{}"});
    } else {
      if (disconnected != previous_disconnected_)
        derived.push_back({r.time_s, r.tick, disconnected ? "device_disconnected" : "device_connected", "{}"});
      // Bit comparison: a NaN isovalue (never expected) does not give an event per tick.
      if (std::memcmp(&r.isovalue, &previous_isovalue_, sizeof(double)) != 0) {
        nlohmann::json d;
        d["from"] = previous_isovalue_;
        d["to"] = r.isovalue;
        derived.push_back({r.time_s, r.tick, "isovalue", d.dump()});
      }
    }
    // The touched segment: "segment" when it changes, "critical_contact" on entering
    // a critical one.
    const int segment = recordSegment(r.flags);
    if (segment != previous_segment_) {
      const auto name = [this](int s) {
        return s >= 0 && static_cast<std::size_t>(s) < segment_names_.size()
                   ? nlohmann::json(segment_names_[static_cast<std::size_t>(s)])
                   : nlohmann::json(nullptr);
      };
      nlohmann::json d;
      d["from"] = name(previous_segment_);
      d["to"] = name(segment);
      derived.push_back({r.time_s, r.tick, "segment", d.dump()});
      if (segment >= 0 && static_cast<std::size_t>(segment) < segment_critical_.size() &&
          segment_critical_[static_cast<std::size_t>(segment)]) {
        nlohmann::json c;
        c["segment"] = name(segment);
        derived.push_back({r.time_s, r.tick, "critical_contact", c.dump()});
      }
      previous_segment_ = segment;
    }
    const bool jammed = (r.flags & kRecordFlagJam) != 0;
    if (jammed != previous_jammed_) {
      derived.push_back({r.time_s, r.tick, jammed ? "jam" : "jam_cleared",
                         jammed ? nlohmann::json{{"ticks", kJamTicks + 1}}.dump() : std::string("{}")});
      previous_jammed_ = jammed;
    }
    previous_disconnected_ = disconnected;
    previous_isovalue_ = r.isovalue;
  }
  if (derived.empty()) return;
  const std::lock_guard<std::mutex> lock(events_mutex_);
  pending_events_.insert(pending_events_.end(), std::make_move_iterator(derived.begin()),
                         std::make_move_iterator(derived.end()));
}

bool RecordingWriter::writeEvents() noexcept {
  try {
    std::vector<RecordingEvent> events;
    {
      const std::lock_guard<std::mutex> lock(events_mutex_);
      events.swap(pending_events_);
    }
    std::stable_sort(events.begin(), events.end(),
                     [](const RecordingEvent& a, const RecordingEvent& b) { return a.tick < b.tick; });
    std::size_t first = 0;
    while (first < events.size()) {
      std::string payload;
      std::size_t n = 0;
      while (first + n < events.size() && n < kMaxChunkEvents) {
        const RecordingEvent& e = events[first + n];
        if (e.type.size() + e.detail_json.size() + 32 > kMaxEventPayloadBytes) {  // absurd: skip it
          ++first;
          continue;
        }
        if (payload.size() + e.type.size() + e.detail_json.size() + 32 > kMaxEventPayloadBytes) break;
        appendBytes(payload, &e.time_s, 8);
        appendBytes(payload, &e.tick, 8);
        const auto type_size = static_cast<std::uint32_t>(e.type.size());
        const auto detail_size = static_cast<std::uint32_t>(e.detail_json.size());
        appendBytes(payload, &type_size, 4);
        payload += e.type;
        appendBytes(payload, &detail_size, 4);
        payload += e.detail_json;
        ++n;
      }
      if (n == 0) break;
      std::array<unsigned char, kEventHeaderBytes> header{};
      std::memcpy(header.data(), kEventTag.data(), kEventTag.size());
      putU32(header.data() + 4, static_cast<std::uint32_t>(n));
      putU32(header.data() + 8, static_cast<std::uint32_t>(payload.size()));
      std::uint32_t crc = crc32(header.data(), header.size());
      crc = crc32(payload.data(), payload.size(), crc);
      std::array<unsigned char, 4> trailer{};
      putU32(trailer.data(), crc);
      const bool ok = std::fwrite(header.data(), 1, header.size(), file_) == header.size() &&
                      std::fwrite(payload.data(), 1, payload.size(), file_) == payload.size() &&
                      std::fwrite(trailer.data(), 1, trailer.size(), file_) == trailer.size() &&
                      std::fflush(file_) == 0;
      if (!ok) return false;
      events_written_.fetch_add(n, std::memory_order_relaxed);
      first += n;
    }
    return true;
  } catch (...) {  // allocation failure
    return false;
  }
}

void RecordingWriter::run() noexcept {
  using Clock = std::chrono::steady_clock;
  const auto max_wait = std::chrono::duration_cast<Clock::duration>(
      std::chrono::duration<double>(options_.max_chunk_wall_s));
  std::size_t filled = 0;
  auto chunk_started = Clock::now();
  auto events_started = Clock::now();
  for (;;) {
    const bool stopping = stop_.load(std::memory_order_acquire);
    const std::size_t n = ring_.pop(chunk_.data() + filled, chunk_.size() - filled);
    if (n > 0) {
      try {
        deriveEvents(chunk_.data() + filled, n);
      } catch (...) {  // allocation failure: the records still get written
        failed_.store(true, std::memory_order_relaxed);
      }
    }
    if (filled == 0 && n > 0) chunk_started = Clock::now();
    filled += n;
    const bool full = filled == chunk_.size();
    const bool due = filled > 0 && Clock::now() - chunk_started >= max_wait;
    bool events_due = false;
    if (filled == 0) {  // events without records (e.g. nothing ticking) still go out in time
      const std::lock_guard<std::mutex> lock(events_mutex_);
      if (pending_events_.empty()) {
        events_started = Clock::now();
      } else {
        events_due = Clock::now() - events_started >= max_wait;
      }
    }
    if (full || due || events_due || (stopping && n == 0)) {
      if (!failed_.load(std::memory_order_relaxed) && !(writeEvents() && writeChunk(chunk_.data(), filled)))
        failed_.store(true, std::memory_order_relaxed);
      filled = 0;
      events_started = Clock::now();
    }
    if (stopping && n == 0) break;  // drained after the stop request
    if (n == 0) std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
}

void RecordingWriter::close() {
  {
    const std::lock_guard<std::mutex> lock(events_mutex_);
    if (closed_) return;
    closed_ = true;  // later addEvent() calls throw; pending ones are written below
  }
  stop_.store(true, std::memory_order_release);
  if (thread_.joinable()) thread_.join();
  const bool closed_ok = std::fclose(file_) == 0;
  file_ = nullptr;
  if (failed_.load() || !closed_ok) throw std::runtime_error("RecordingWriter: write failed on " + path_.string());
}

// ---- Reader ----------------------------------------------------------------------------------------

Recording readRecording(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error("readRecording: cannot open " + path.string());
  // One read of the whole file (a 5-minute recording is 60 MB): sized by the file's length, then
  // whatever else a file still being written has by the time it is read.
  std::string bytes;
  std::error_code size_error;
  const std::uintmax_t expected = std::filesystem::file_size(path, size_error);
  if (!size_error) {
    bytes.resize(static_cast<std::size_t>(expected));
    in.read(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    bytes.resize(static_cast<std::size_t>(in.gcount()));
  }
  if (in) bytes.append(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  const auto* data = reinterpret_cast<const unsigned char*>(bytes.data());
  const std::size_t size = bytes.size();
  const std::string where = path.string() + ": ";
  if (size < kFileHeaderBytes || std::memcmp(data, kMagic.data(), kMagic.size()) != 0)
    throw std::runtime_error("readRecording: " + where + "not a volume-haptics recording (bad magic)");
  Recording rec;
  rec.records.reserve(size / sizeof(TickRecord));  // an upper bound: every chunk byte a record
  rec.version = getU32(data + 8);
  if (rec.version != 1 && rec.version != kRecordingFormatVersion)
    throw std::runtime_error("readRecording: " + where + "unsupported format version " + std::to_string(rec.version));
  const std::uint32_t record_size = getU32(data + 12);
  if (record_size != sizeof(TickRecord))
    throw std::runtime_error("readRecording: " + where + "record size " + std::to_string(record_size) +
                             " bytes, expected " + std::to_string(sizeof(TickRecord)));
  const std::uint32_t meta_size = getU32(data + 16);
  if (size - kFileHeaderBytes < meta_size ||
      crc32(data + kFileHeaderBytes, meta_size) != getU32(data + 20))
    throw std::runtime_error("readRecording: " + where + "damaged metadata header");
  rec.metadata_json.assign(bytes, kFileHeaderBytes, meta_size);

  std::size_t offset = kFileHeaderBytes + meta_size;
  while (offset < size) {
    const std::size_t left = size - offset;
    const unsigned char* chunk = data + offset;
    std::string problem;
    if (rec.version >= 2 && left >= kEventTag.size() && std::memcmp(chunk, kEventTag.data(), kEventTag.size()) == 0) {
      if (left < kEventHeaderBytes) {
        problem = "truncated event chunk header";
      } else {
        const std::uint32_t count = getU32(chunk + 4);
        const std::uint32_t payload = getU32(chunk + 8);
        if (count == 0 || count > kMaxChunkEvents || payload > kMaxEventPayloadBytes) {
          problem = "bad event chunk (" + std::to_string(count) + " events, " + std::to_string(payload) + " bytes)";
        } else if (left < kEventHeaderBytes + payload + 4) {
          problem = "truncated event chunk (" + std::to_string(left) + " of " +
                    std::to_string(kEventHeaderBytes + payload + 4) + " bytes)";
        } else if (crc32(chunk, kEventHeaderBytes + payload) != getU32(chunk + kEventHeaderBytes + payload)) {
          problem = "event chunk checksum mismatch";
        } else {
          std::vector<RecordingEvent> events;
          const unsigned char* p = chunk + kEventHeaderBytes;
          const unsigned char* const end = p + payload;
          for (std::uint32_t i = 0; i < count && problem.empty(); ++i) {
            RecordingEvent e;
            if (end - p < 20) {
              problem = "malformed event chunk";
              break;
            }
            std::memcpy(&e.time_s, p, 8);
            e.tick = getU64(p + 8);
            const std::uint32_t type_size = getU32(p + 16);
            p += 20;
            if (static_cast<std::size_t>(end - p) < std::size_t{type_size} + 4) {
              problem = "malformed event chunk";
              break;
            }
            e.type.assign(reinterpret_cast<const char*>(p), type_size);
            p += type_size;
            const std::uint32_t detail_size = getU32(p);
            p += 4;
            if (static_cast<std::size_t>(end - p) < detail_size) {
              problem = "malformed event chunk";
              break;
            }
            e.detail_json.assign(reinterpret_cast<const char*>(p), detail_size);
            p += detail_size;
            events.push_back(std::move(e));
          }
          if (problem.empty() && p != end) problem = "malformed event chunk";
          if (problem.empty()) {
            rec.events.insert(rec.events.end(), std::make_move_iterator(events.begin()),
                              std::make_move_iterator(events.end()));
            ++rec.event_chunks;
            offset += kEventHeaderBytes + payload + 4;
            continue;
          }
        }
      }
    } else if (left < kChunkHeaderBytes) {
      problem = "truncated chunk header";
    } else if (std::memcmp(chunk, kChunkTag.data(), kChunkTag.size()) != 0) {
      problem = "bad chunk tag";
    } else {
      const std::uint32_t count = getU32(chunk + 4);
      const std::size_t payload = std::size_t{count} * sizeof(TickRecord);
      if (count == 0 || count > kMaxChunkRecords) {
        problem = "bad chunk record count " + std::to_string(count);
      } else if (left < kChunkHeaderBytes + payload + 4) {
        problem = "truncated chunk (" + std::to_string(left) + " of " +
                  std::to_string(kChunkHeaderBytes + payload + 4) + " bytes)";
      } else if (crc32(chunk, kChunkHeaderBytes + payload) != getU32(chunk + kChunkHeaderBytes + payload)) {
        problem = "chunk checksum mismatch";
      } else {
        const std::size_t first = rec.records.size();
        rec.records.resize(first + count);
        std::memcpy(rec.records.data() + first, chunk + kChunkHeaderBytes, payload);
        rec.dropped_records = getU64(chunk + 8);
        ++rec.chunks;
        offset += kChunkHeaderBytes + payload + 4;
        continue;
      }
    }
    rec.bytes_ignored = left;
    std::ostringstream msg;
    msg << where << problem << " at byte " << offset << " (chunk " << rec.chunks + rec.event_chunks << "); kept "
        << rec.chunks + rec.event_chunks << " good chunks (" << rec.records.size() << " records, "
        << rec.events.size() << " events), ignored the last " << left << " bytes";
    rec.warnings.push_back(msg.str());
    break;
  }
  std::stable_sort(rec.events.begin(), rec.events.end(),
                   [](const RecordingEvent& a, const RecordingEvent& b) { return a.tick < b.tick; });
  return rec;
}

// ---- Export ----------------------------------------------------------------------------------------

void writeRecordingCsv(const Recording& recording, std::ostream& out) {
  out << "t_s,tick,device_x_m,device_y_m,device_z_m,device_qw,device_qx,device_qy,device_qz,"
         "proxy_x_m,proxy_y_m,proxy_z_m,proxy_qw,proxy_qx,proxy_qy,proxy_qz,"
         "force_x_N,force_y_N,force_z_N,torque_x_Nm,torque_y_Nm,torque_z_Nm,"
         "contacts,isovalue,tick_time_s,flags\n";
  out << std::setprecision(17);
  for (const TickRecord& r : recording.records) {
    out << r.time_s << ',' << r.tick;
    for (double v : r.p_WD_m) out << ',' << v;
    for (double v : r.q_WD) out << ',' << v;
    for (double v : r.p_WP_m) out << ',' << v;
    for (double v : r.q_WP) out << ',' << v;
    for (double v : r.force_W_N) out << ',' << v;
    for (double v : r.torque_W_Nm) out << ',' << v;
    out << ',' << r.contacts << ',' << r.isovalue << ',' << r.tick_time_s << ',' << r.flags << '\n';
  }
}

void writeRecordingCsv(const Recording& recording, const std::filesystem::path& path) {
  io::PrivateOutput file(path);  // 0600, renamed into place only when whole
  writeRecordingCsv(recording, file.stream());
  file.commit();
}

void writeRecordingEventsCsv(const Recording& recording, std::ostream& out) {
  const auto quoted = [](const std::string& text) {
    std::string q = "\"";
    for (char c : text) {
      if (c == '"') q += '"';
      q += c;
    }
    return q + '"';
  };
  out << "t_s,tick,type,detail_json\n" << std::setprecision(17);
  for (const RecordingEvent& e : recording.events)
    out << e.time_s << ',' << e.tick << ',' << quoted(e.type) << ',' << quoted(e.detail_json) << '\n';
}

void writeRecordingEventsCsv(const Recording& recording, const std::filesystem::path& path) {
  io::PrivateOutput file(path);
  writeRecordingEventsCsv(recording, file.stream());
  file.commit();
}

void writeRecordingJson(const Recording& recording, const std::filesystem::path& path) {
  nlohmann::json j;
  try {
    j["metadata"] = nlohmann::json::parse(recording.metadata_json);
  } catch (const nlohmann::json::exception&) {
    j["metadata"] = recording.metadata_json;  // keep it verbatim when it does not parse
  }
  j["format_version"] = recording.version;
  j["records"] = recording.records.size();
  j["chunks"] = recording.chunks;
  j["event_chunks"] = recording.event_chunks;
  j["duration_s"] = recording.records.empty()
                        ? 0.0
                        : recording.records.back().time_s - recording.records.front().time_s;
  j["dropped_records"] = recording.dropped_records;
  j["warnings"] = recording.warnings;
  nlohmann::json events = nlohmann::json::array();
  for (const RecordingEvent& e : recording.events) {
    nlohmann::json item;
    item["t_s"] = e.time_s;
    item["tick"] = e.tick;
    item["type"] = e.type;
    try {
      item["detail"] = nlohmann::json::parse(e.detail_json);
    } catch (const nlohmann::json::exception&) {
      item["detail"] = e.detail_json;  // verbatim when it does not parse
    }
    events.push_back(std::move(item));
  }
  j["events"] = std::move(events);
  nlohmann::json segments = nlohmann::json::array();
  for (const SegmentContact& c : segmentContacts(recording)) {
    segments.push_back({{"name", c.name},
                        {"critical", c.critical},
                        {"time_in_contact_s", c.time_in_contact_s},
                        {"peak_force_N", c.peak_force_N},
                        {"touches", c.touches}});
  }
  j["segments"] = std::move(segments);
  io::PrivateOutput file(path);
  file.stream() << j.dump(2) << '\n';
  file.commit();
}

std::vector<SegmentContact> segmentContacts(const Recording& recording) {
  nlohmann::json meta;
  try {
    meta = nlohmann::json::parse(recording.metadata_json);
  } catch (const nlohmann::json::exception&) {
    return {};
  }
  std::vector<std::string> names;
  std::vector<bool> critical;
  segmentList(meta, names, critical);
  if (names.empty()) return {};
  const double rate = meta.is_object() && meta.contains("servo_rate_Hz") && meta["servo_rate_Hz"].is_number()
                          ? meta["servo_rate_Hz"].get<double>()
                          : 1000.0;
  SegmentContactTally tally(names, critical);
  for (const TickRecord& r : recording.records) {
    const double f = std::sqrt(r.force_W_N[0] * r.force_W_N[0] + r.force_W_N[1] * r.force_W_N[1] +
                               r.force_W_N[2] * r.force_W_N[2]);
    tally.add(recordSegment(r.flags), f, rate > 0.0 ? 1.0 / rate : 0.0);
  }
  return tally.segments();
}

}  // namespace vh::runtime
