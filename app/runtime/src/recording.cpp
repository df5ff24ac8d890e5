// Session recordings: the ring, the chunked file writer and reader, CSV / JSON export.
// The file format is documented in vh/runtime/recording.h.
#include "vh/runtime/recording.h"

#include "vh/runtime/jam_detector.h"
#include "vh/runtime/recording_hdf5.h"
#include "recording_internal.h"
#include "vh/runtime/technique.h"

#include <algorithm>
#include <string_view>
#include <array>
#include <bit>
#include <chrono>
#include <cmath>
#include <cerrno>
#include <cstring>
#include <limits>
#include <ctime>
#include <fstream>
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
constexpr std::array<char, 4> kEndTag = {'E', 'N', 'D', 'R'};
constexpr std::size_t kEndChunkBytes = 28;
constexpr std::size_t kEventHeaderBytes = 12;
constexpr std::size_t kMaxEventPayloadBytes = std::size_t{16} << 20;
constexpr std::size_t kMaxChunkEvents = 65535;
constexpr std::size_t kFileHeaderBytes = 24;
constexpr std::size_t kChunkHeaderBytes = 16;
/// Bytes of one stored record: versions 1 to 3 stored the first 200 bytes of today's TickRecord
/// (up to and including flags), version 4 the first 216 (up to critical_segment, then 4 bytes
/// that were 0), version 5 the whole of it.
constexpr std::size_t recordBytes(std::uint32_t version) noexcept {
  return version >= 5 ? sizeof(TickRecord) : version == 4 ? kTickRecordBytesV4 : kTickRecordBytesV3;
}
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
void segmentList(const nlohmann::json& meta, std::vector<std::string>& names, std::vector<bool>& critical,
                 std::vector<ProximityThresholds>* thresholds = nullptr) {
  names.clear();
  critical.clear();
  if (thresholds != nullptr) thresholds->clear();
  try {
    if (!meta.is_object() || !meta.contains("scene") || !meta["scene"].contains("segmentation")) return;
    for (const auto& s : meta["scene"]["segmentation"].at("segments")) {
      names.push_back(s.at("name").get<std::string>());
      critical.push_back(s.value("critical", false));
      const ProximityThresholds defaults;  // metadata written before the thresholds: the defaults
      if (thresholds != nullptr)
        thresholds->push_back({1e-3 * s.value("warn_mm", 1e3 * defaults.warn_m),
                               1e-3 * s.value("alarm_mm", 1e3 * defaults.alarm_m)});
    }
  } catch (const nlohmann::json::exception&) {
    names.clear();
    critical.clear();
    if (thresholds != nullptr) thresholds->clear();
  }
}

/// The event of a change of proximity level (critical_proximity.h) between two records, or an
/// empty type: entering the warning or alarm distance of the nearest critical segment, or leaving it.
RecordingEvent proximityEvent(const TickRecord& r, ProximityLevel from, ProximityLevel to, int from_segment,
                              const std::vector<std::string>& names) {
  const auto name = [&names](int s) {
    return s >= 0 && static_cast<std::size_t>(s) < names.size() ? nlohmann::json(names[static_cast<std::size_t>(s)])
                                                                  : nlohmann::json(nullptr);
  };
  nlohmann::json d;
  const char* type = "";
  if (to > from) {
    type = to == ProximityLevel::kAlarm ? "proximity_alarm" : "proximity_warn";
    d["segment"] = name(r.critical_segment);
    d["distance_mm"] = 1e3 * r.critical_distance_m;
  } else {
    type = from == ProximityLevel::kAlarm ? "proximity_alarm_cleared" : "proximity_warn_cleared";
    d["segment"] = name(from_segment);
    d["to"] = to == ProximityLevel::kWarn ? "warn" : "clear";
    if (std::isfinite(r.critical_distance_m)) d["distance_mm"] = 1e3 * r.critical_distance_m;
  }
  return {r.time_s, r.tick, type, d.dump()};
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
  segmentList(meta, segment_names_, segment_critical_, &segment_thresholds_);
  const std::string text = meta.dump();

  // Owner-only (0600) whatever the umask: a recording names the scan and carries the session.
  try {
    fd_ = io::openPrivateFile(path);
  } catch (const std::runtime_error& e) {
    throw std::runtime_error(std::string("RecordingWriter: ") + e.what());
  }
  std::array<unsigned char, kFileHeaderBytes> header{};
  std::memcpy(header.data(), kMagic.data(), kMagic.size());
  putU32(header.data() + 8, kRecordingFormatVersion);
  putU32(header.data() + 12, static_cast<std::uint32_t>(sizeof(TickRecord)));
  putU32(header.data() + 16, static_cast<std::uint32_t>(text.size()));
  putU32(header.data() + 20, crc32(text.data(), text.size()));
  if (!writeWhole({{header.data(), header.size()}, {text.data(), text.size()}})) {
    ::close(fd_);
    fd_ = -1;
    throw std::runtime_error("RecordingWriter: cannot write the header of " + path.string() + ": " + failure());
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

namespace {
/// What a write's errno means to the user: "disk full (No space left on device)".
std::string writeErrorText(int error_number) {
  std::string cause;
  switch (error_number) {
    case ENOSPC: cause = "disk full"; break;
    case EDQUOT: cause = "disk quota exceeded"; break;
    case EFBIG: cause = "file size limit reached"; break;
    case EIO: cause = "input/output error on the disk"; break;
    default: cause = "write failed"; break;
  }
  return cause + " (" + std::strerror(error_number) + ")";
}
}  // namespace

std::string RecordingWriter::failure() const {
  const int error_number = error_number_.load(std::memory_order_acquire);
  if (error_number != 0) return writeErrorText(error_number);
  return failed() ? std::string("write failed (out of memory)") : std::string();
}

bool RecordingWriter::writeWhole(std::initializer_list<Bytes> parts) noexcept {
  if (fd_ < 0) return false;
  std::uint64_t written = 0;
  for (const Bytes& part : parts) {
    const auto* p = static_cast<const unsigned char*>(part.data);
    std::size_t left = part.size;
    while (left > 0) {
      const ::ssize_t n = ::write(fd_, p, left);
      if (n < 0 && errno == EINTR) continue;
      if (n <= 0) {
        error_number_.store(n < 0 ? errno : EIO, std::memory_order_release);
        // The file ends on its last whole chunk: a reader sees no truncated one.
        if (::ftruncate(fd_, static_cast<::off_t>(file_size_)) == 0) (void)::lseek(fd_, 0, SEEK_END);
        failed_.store(true, std::memory_order_release);
        return false;
      }
      p += n;
      left -= static_cast<std::size_t>(n);
      written += static_cast<std::uint64_t>(n);
    }
  }
  file_size_ += written;
  return true;
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
  const bool ok = writeWhole({{header.data(), header.size()}, {records, payload}, {trailer.data(), trailer.size()}});
  if (ok) written_.fetch_add(count, std::memory_order_relaxed);
  return ok;
}

void RecordingWriter::writeEndMarker() noexcept {
  std::array<unsigned char, kEndChunkBytes> end{};
  std::memcpy(end.data(), kEndTag.data(), kEndTag.size());
  putU32(end.data() + 4, static_cast<std::uint32_t>(error_number_.load(std::memory_order_acquire)));
  putU64(end.data() + 8, written_.load(std::memory_order_relaxed));
  putU64(end.data() + 16, ring_.dropped());
  putU32(end.data() + 24, crc32(end.data(), 24));
  // After a failure too (with its errno): one try, which may not fit either; the first cause
  // stays the one reported.
  const bool had_failed = failed();
  const int error_number = error_number_.load(std::memory_order_acquire);
  if (!writeWhole({{end.data(), end.size()}}) && had_failed) error_number_.store(error_number, std::memory_order_release);
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

ProximityLevel RecordingWriter::proximityLevelOf(const TickRecord& r) const noexcept {
  const auto s = static_cast<std::size_t>(r.critical_segment);
  if (r.critical_segment < 0 || s >= segment_thresholds_.size()) return ProximityLevel::kClear;
  // The same segment as the last record: with hysteresis (proximityLevelAfter()).
  const ProximityLevel after = r.critical_segment == previous_critical_segment_ ? previous_level_ : ProximityLevel::kClear;
  return proximityLevelAfter(after, r.critical_distance_m, segment_thresholds_[s]);
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
    const ProximityLevel level = proximityLevelOf(r);
    if (level != previous_level_) {
      derived.push_back(proximityEvent(r, previous_level_, level, previous_critical_segment_, segment_names_));
      previous_level_ = level;
    }
    previous_critical_segment_ = r.critical_segment;
    const bool jammed = (r.flags & kRecordFlagJam) != 0;
    if (jammed != previous_jammed_) {
      derived.push_back({r.time_s, r.tick, jammed ? "jam" : "jam_cleared",
                         jammed ? nlohmann::json{{"ticks", kJamTicks + 1}}.dump() : std::string("{}")});
      previous_jammed_ = jammed;
    }
    // A technique rule that became active: one event per episode (the monitor's hold and
    // clear times already keep a flickering condition to one).
    const std::uint32_t technique = recordTechnique(r.flags);
    for (int rule = 0; rule < kTechniqueRuleCount; ++rule) {
      const std::uint32_t bit = 1u << rule;
      if ((technique & bit) && !(previous_technique_ & bit)) {
        derived.push_back({r.time_s, r.tick, "technique",
                           nlohmann::json{{"rule", std::string(techniqueRuleName(rule))}}.dump()});
      }
    }
    previous_technique_ = technique;
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
      if (!writeWhole({{header.data(), header.size()}, {payload.data(), payload.size()}, {trailer.data(), trailer.size()}}))
        return false;
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
      if (!failed() && !(writeEvents() && writeChunk(chunk_.data(), filled)))
        failed_.store(true, std::memory_order_release);
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
  writeEndMarker();
  const bool closed_ok = ::close(fd_) == 0;
  if (!closed_ok && error_number_.load() == 0) error_number_.store(errno);
  fd_ = -1;
  if (failed() || !closed_ok) {
    throw std::runtime_error("RecordingWriter: " + path_.string() + ": " + failure() + "; " +
                             std::to_string(recordsWritten()) + " ticks kept");
  }
}

/// The deepest nesting of arrays and objects in JSON text `text` (brackets inside strings not
/// counted); O(n), no parse. Any text: what is not JSON gives some depth, and the parse says the rest.
std::size_t jsonNestingDepth(std::string_view text) noexcept {
  std::size_t depth = 0, deepest = 0;
  bool in_string = false, escaped = false;
  for (const char c : text) {
    if (in_string) {
      if (escaped) escaped = false;
      else if (c == '\\') escaped = true;
      else if (c == '"') in_string = false;
      continue;
    }
    if (c == '"') in_string = true;
    else if (c == '[' || c == '{') deepest = std::max(deepest, ++depth);
    else if ((c == ']' || c == '}') && depth > 0) --depth;
  }
  return deepest;
}

void requireMetadataDepth(const std::string& where, const std::string& metadata_json) {
  // What this program writes nests a few levels; text nested thousands deep makes every reader
  // of it (parse, pretty print: the indentation grows with the depth) take minutes and gigabytes.
  if (const std::size_t depth = jsonNestingDepth(metadata_json); depth > kMaxRecordingJsonDepth)
    throw std::runtime_error(where + "damaged metadata: JSON nested " + std::to_string(depth) + " deep (at most " +
                             std::to_string(kMaxRecordingJsonDepth) + ")");
}

void dropTooDeepEvents(const std::string& where, Recording& rec) {
  // Events whose detail nests deeper than anything written here are dropped, and said.
  const auto too_deep = [](const RecordingEvent& e) { return jsonNestingDepth(e.detail_json) > kMaxRecordingJsonDepth; };
  if (const auto dropped = std::count_if(rec.events.begin(), rec.events.end(), too_deep); dropped > 0) {
    rec.events.erase(std::remove_if(rec.events.begin(), rec.events.end(), too_deep), rec.events.end());
    rec.warnings.push_back(where + std::to_string(dropped) + " event(s) dropped: their detail is JSON nested deeper than " +
                           std::to_string(kMaxRecordingJsonDepth) + " levels");
  }
}

// ---- Reader ----------------------------------------------------------------------------------------

namespace {

/// The whole file in one read (a 5-minute recording is 60 MB): sized by the file's length, then
/// whatever else a file still being written has by the time it is read.
/// @throws std::runtime_error when it cannot be opened.
std::string readWholeFile(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error("readRecording: cannot open " + path.string());
  std::string bytes;
  std::error_code size_error;
  const std::uintmax_t expected = std::filesystem::file_size(path, size_error);
  if (!size_error) {
    bytes.resize(static_cast<std::size_t>(expected));
    in.read(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    bytes.resize(static_cast<std::size_t>(in.gcount()));
  }
  if (in) bytes.append(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  return bytes;
}


/// Checks the file header and the metadata, sets rec.version and rec.metadata_json.
/// @return the offset of the first chunk. @throws std::runtime_error as readRecording().
std::size_t readHeader(const std::string& bytes, const std::string& where, Recording& rec) {
  const auto* data = reinterpret_cast<const unsigned char*>(bytes.data());
  const std::size_t size = bytes.size();
  if (size < kFileHeaderBytes || std::memcmp(data, kMagic.data(), kMagic.size()) != 0)
    throw std::runtime_error("readRecording: " + where + "not a volume-haptics recording (bad magic)");
  rec.version = getU32(data + 8);
  if (rec.version < 1 || rec.version > kRecordingFormatVersion)
    throw std::runtime_error("readRecording: " + where + "unsupported format version " + std::to_string(rec.version));
  const std::uint32_t record_size = getU32(data + 12);
  if (record_size != recordBytes(rec.version))
    throw std::runtime_error("readRecording: " + where + "record size " + std::to_string(record_size) +
                             " bytes, expected " + std::to_string(recordBytes(rec.version)) + " for version " +
                             std::to_string(rec.version));
  const std::uint32_t meta_size = getU32(data + 16);
  if (size - kFileHeaderBytes < meta_size || crc32(data + kFileHeaderBytes, meta_size) != getU32(data + 20))
    throw std::runtime_error("readRecording: " + where + "damaged metadata header");
  rec.metadata_json.assign(bytes, kFileHeaderBytes, meta_size);
  requireMetadataDepth("readRecording: " + where, rec.metadata_json);
  return kFileHeaderBytes + meta_size;
}

/// The `count` events of an event chunk's `payload` bytes at `p`. @return false when their
/// framing does not fill the payload exactly.
bool parseEvents(const unsigned char* p, std::size_t payload, std::uint32_t count, std::vector<RecordingEvent>& out) {
  const unsigned char* const end = p + payload;
  for (std::uint32_t i = 0; i < count; ++i) {
    RecordingEvent e;
    if (end - p < 20) return false;
    std::memcpy(&e.time_s, p, 8);
    e.tick = getU64(p + 8);
    const std::uint32_t type_size = getU32(p + 16);
    p += 20;
    if (static_cast<std::size_t>(end - p) < std::size_t{type_size} + 4) return false;
    e.type.assign(reinterpret_cast<const char*>(p), type_size);
    p += type_size;
    const std::uint32_t detail_size = getU32(p);
    p += 4;
    if (static_cast<std::size_t>(end - p) < detail_size) return false;
    e.detail_json.assign(reinterpret_cast<const char*>(p), detail_size);
    p += detail_size;
    out.push_back(std::move(e));
  }
  return p == end;
}

enum class ChunkKind { kRecords, kEvents, kEnd };

/// A chunk that checked out (size > 0), or why not (problem).
struct CheckedChunk {
  ChunkKind kind = ChunkKind::kRecords;
  std::size_t size = 0;               ///< Bytes of the whole chunk; 0 when it is not good.
  std::string problem;
  std::vector<RecordingEvent> events;  ///< kEvents: its events.
};

bool hasTag(const unsigned char* chunk, std::size_t left, const std::array<char, 4>& tag) noexcept {
  return left >= tag.size() && std::memcmp(chunk, tag.data(), tag.size()) == 0;
}

/// Checks the chunk at `chunk` (`left` bytes to the end of the file): its tag (the kinds
/// `version` has), header sanity, length and CRC-32, and for events their framing.
CheckedChunk checkChunk(const unsigned char* chunk, std::size_t left, std::uint32_t version) {
  CheckedChunk c;
  if (version >= 2 && hasTag(chunk, left, kEventTag)) {
    c.kind = ChunkKind::kEvents;
    const std::uint32_t count = left >= kEventHeaderBytes ? getU32(chunk + 4) : 0;
    const std::uint32_t payload = left >= kEventHeaderBytes ? getU32(chunk + 8) : 0;
    if (left < kEventHeaderBytes) c.problem = "truncated event chunk header";
    else if (count == 0 || count > kMaxChunkEvents || payload > kMaxEventPayloadBytes)
      c.problem = "bad event chunk (" + std::to_string(count) + " events, " + std::to_string(payload) + " bytes)";
    else if (left < kEventHeaderBytes + payload + 4)
      c.problem = "truncated event chunk (" + std::to_string(left) + " of " +
                  std::to_string(kEventHeaderBytes + payload + 4) + " bytes)";
    else if (crc32(chunk, kEventHeaderBytes + payload) != getU32(chunk + kEventHeaderBytes + payload))
      c.problem = "event chunk checksum mismatch";
    else if (!parseEvents(chunk + kEventHeaderBytes, payload, count, c.events)) c.problem = "malformed event chunk";
    else c.size = kEventHeaderBytes + payload + 4;
  } else if (version >= 3 && hasTag(chunk, left, kEndTag)) {
    c.kind = ChunkKind::kEnd;
    if (left < kEndChunkBytes) c.problem = "truncated end marker";
    else if (crc32(chunk, kEndChunkBytes - 4) != getU32(chunk + kEndChunkBytes - 4)) c.problem = "end marker checksum mismatch";
    else c.size = kEndChunkBytes;
  } else if (left < kChunkHeaderBytes) {
    c.problem = "truncated chunk header";
  } else if (!hasTag(chunk, left, kChunkTag)) {
    c.problem = "bad chunk tag";
  } else {
    const std::uint32_t count = getU32(chunk + 4);
    const std::size_t payload = std::size_t{count} * recordBytes(version);
    if (count == 0 || count > kMaxChunkRecords) c.problem = "bad chunk record count " + std::to_string(count);
    else if (left < kChunkHeaderBytes + payload + 4)
      c.problem = "truncated chunk (" + std::to_string(left) + " of " + std::to_string(kChunkHeaderBytes + payload + 4) +
                  " bytes)";
    else if (crc32(chunk, kChunkHeaderBytes + payload) != getU32(chunk + kChunkHeaderBytes + payload))
      c.problem = "chunk checksum mismatch";
    else c.size = kChunkHeaderBytes + payload + 4;
  }
  return c;
}

/// Adds the good chunk `c` at `chunk` to `rec`.
void addChunk(const unsigned char* chunk, CheckedChunk& c, Recording& rec) {
  if (c.kind == ChunkKind::kEvents) {
    rec.events.insert(rec.events.end(), std::make_move_iterator(c.events.begin()), std::make_move_iterator(c.events.end()));
    ++rec.event_chunks;
  } else if (c.kind == ChunkKind::kEnd) {
    rec.ended = true;
    rec.end_status = getU32(chunk + 4);
  } else {
    const std::size_t count = getU32(chunk + 4);
    const std::size_t first = rec.records.size();
    rec.records.resize(first + count);
    if (rec.version >= 5) {
      std::memcpy(rec.records.data() + first, chunk + kChunkHeaderBytes, count * sizeof(TickRecord));
    } else {  // older records are shorter: what they lack was not stored
      const std::size_t bytes = recordBytes(rec.version);
      for (std::size_t k = 0; k < count; ++k) {
        TickRecord& r = rec.records[first + k];
        std::memcpy(static_cast<void*>(&r), chunk + kChunkHeaderBytes + k * bytes, bytes);
        r.removed_voxels = 0;  // version 4's reserved bytes
        r.deadline_work = 0;
        if (rec.version < 4) {  // no proximity was measured
          r.critical_distance_m = std::numeric_limits<double>::quiet_NaN();
          r.critical_segment = -1;
        }
      }
    }
    rec.dropped_records = getU64(chunk + 8);
    ++rec.chunks;
  }
}

/// The offset of the first good chunk after `from` (a tag of `version`'s kinds whose header,
/// length and CRC-32 check out), or `size` when there is none.
std::size_t nextGoodChunk(const unsigned char* data, std::size_t size, std::size_t from, std::uint32_t version) {
  for (std::size_t at = from + 1; at + 4 <= size; ++at) {
    const unsigned char* p = data + at;
    if (!hasTag(p, size - at, kChunkTag) && !hasTag(p, size - at, kEventTag) && !hasTag(p, size - at, kEndTag)) continue;
    if (checkChunk(p, size - at, version).size > 0) return at;
  }
  return size;
}

/// A damaged stretch skipped: from `offset` (where `problem` was found) to the next good chunk.
struct Damage {
  std::size_t offset = 0;
  std::size_t bytes = 0;
  std::size_t records_before = 0;  ///< Records read before it.
  std::size_t chunks_before = 0;   ///< Good chunks read before it.
  std::string problem;
};

/// The warning for a damage that the reader went on after: the bytes and the ticks it cost
/// (the gap in the tick counter around it; after the last record, by the end marker's count).
std::string damageWarning(const std::string& where, const Damage& d, const Recording& rec,
                          std::uint64_t records_in_end_marker) {
  std::ostringstream msg;
  msg << where << d.problem << " at byte " << d.offset << " (after " << d.chunks_before
      << " good chunks): skipped " << d.bytes << " damaged bytes to the next good chunk at byte " << d.offset + d.bytes;
  const std::size_t i = d.records_before;
  if (i > 0 && i < rec.records.size() && rec.records[i].tick > rec.records[i - 1].tick + 1) {
    const std::uint64_t first = rec.records[i - 1].tick + 1;
    const std::uint64_t last = rec.records[i].tick - 1;
    msg << "; ticks " << first << " to " << last << " are missing (" << last - first + 1 << " ticks)";
  } else if (i == 0 && !rec.records.empty()) {
    msg << "; the ticks before tick " << rec.records.front().tick << " are missing";
  } else if (i > 0 && i == rec.records.size() && records_in_end_marker > i) {
    msg << "; the " << records_in_end_marker - i << " ticks after tick " << rec.records.back().tick << " are missing";
  } else {
    msg << "; no ticks are missing around it";
  }
  return msg.str();
}

/// The warnings about how the recording ended: no end marker, a write failure, ticks the end
/// marker counts that damaged chunks lost.
void endWarnings(const std::uint64_t records_in_end_marker, Recording& rec) {
  const std::string kept = std::to_string(rec.records.size()) + " ticks kept";
  if (rec.version >= 3 && !rec.ended) {
    rec.warnings.push_back("unfinished recording: ended without its end marker (the program stopped, or a write "
                           "failed, while recording); " + kept);
    return;
  }
  if (rec.ended && rec.end_status != 0) {
    rec.warnings.push_back("the recording ended early: " + writeErrorText(static_cast<int>(rec.end_status)) + "; " + kept);
  }
  if (rec.ended && records_in_end_marker > rec.records.size()) {
    rec.warnings.push_back(kept + " of the " + std::to_string(records_in_end_marker) +
                           " written (the others were in damaged chunks)");
  }
}

}  // namespace

Recording readRecording(const std::filesystem::path& path) { return readRecording(path, RecordingFiles::kVhrecOrHdf5); }

Recording readRecording(const std::filesystem::path& path, RecordingFiles files) {
  if (isHdf5File(path)) {
    if (files == RecordingFiles::kVhrecOnly)
      throw std::runtime_error(path.string() + ": an HDF5 export of a recording; the window opens the .vhrec it came "
                               "from (volume-haptics export, report and Python read HDF5 exports)");
    return readRecordingHdf5(path);
  }
  const std::string bytes = readWholeFile(path);
  const auto* data = reinterpret_cast<const unsigned char*>(bytes.data());
  const std::size_t size = bytes.size();
  const std::string where = path.string() + ": ";
  Recording rec;
  std::size_t offset = readHeader(bytes, where, rec);
  rec.records.reserve(size / sizeof(TickRecord));  // an upper bound: every chunk byte a record
  std::vector<Damage> damages;
  std::string tail_warning;  // a bad tail: after the damages, which come before it in the file
  std::uint64_t records_in_end_marker = 0;
  while (offset < size && !rec.ended) {
    CheckedChunk c = checkChunk(data + offset, size - offset, rec.version);
    if (c.size > 0) {
      addChunk(data + offset, c, rec);
      if (c.kind == ChunkKind::kEnd) records_in_end_marker = getU64(data + offset + 8);
      offset += c.size;
      continue;
    }
    const std::size_t next = nextGoodChunk(data, size, offset, rec.version);
    rec.bytes_ignored += next - offset;
    if (next < size) {
      damages.push_back({offset, next - offset, rec.records.size(), rec.chunks + rec.event_chunks, c.problem});
      ++rec.damaged_regions;
    } else {
      std::ostringstream msg;
      msg << where << c.problem << " at byte " << offset << " (after " << rec.chunks + rec.event_chunks
          << " good chunks); ignored the last " << size - offset << " bytes";
      tail_warning = msg.str();
    }
    offset = next;
  }
  if (rec.ended && offset < size) {
    rec.bytes_ignored += size - offset;
    tail_warning = where + std::to_string(size - offset) + " bytes after the end marker ignored";
  }
  for (const Damage& d : damages) rec.warnings.push_back(damageWarning(where, d, rec, records_in_end_marker));
  if (!tail_warning.empty()) rec.warnings.push_back(tail_warning);
  endWarnings(records_in_end_marker, rec);
  dropTooDeepEvents(where, rec);
  std::stable_sort(rec.events.begin(), rec.events.end(),
                   [](const RecordingEvent& a, const RecordingEvent& b) { return a.tick < b.tick; });
  return rec;
}

// ---- Segments ------------------------------------------------------------------------------------

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

std::vector<SegmentProximityStats> segmentProximity(const Recording& recording, double dt_s) {
  const nlohmann::json meta = nlohmann::json::parse(recording.metadata_json, nullptr, false);
  std::vector<std::string> names;
  std::vector<bool> critical;
  std::vector<ProximityThresholds> thresholds;
  segmentList(meta, names, critical, &thresholds);
  std::vector<int> critical_segments;
  for (std::size_t s = 0; s < critical.size(); ++s)
    if (critical[s]) critical_segments.push_back(static_cast<int>(s));
  if (critical_segments.empty()) return {};
  ProximityTally tally(critical_segments, names, thresholds);
  if (recording.version < 4) {
    tally.markUnmeasured();
    return tally.segments();
  }
  for (const TickRecord& r : recording.records) {
    tally.add(r.critical_segment, r.critical_distance_m, r.time_s, dt_s);
    tally.endTick();
  }
  return tally.segments();
}

}  // namespace vh::runtime
