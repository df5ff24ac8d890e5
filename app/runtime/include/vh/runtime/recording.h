#pragma once
/// @file
/// Session recordings: one fixed-size TickRecord per servo tick, pushed by the servo thread into
/// a preallocated lock-free single-producer / single-consumer ring (TickRing, tick_ring.h), drained to disk by
/// a writer thread (RecordingWriter) in checksummed chunks together with timestamped events
/// (RecordingEvent: markers, isovalue / tool / gains changes, device connect / disconnect), read
/// back by readRecording() (every good chunk; a damaged one is skipped and named), and exported as CSV (writeRecordingCsv(),
/// writeRecordingEventsCsv()) and JSON (writeRecordingJson()). The session metadata is made by
/// makeSessionMetadata() (session_metadata.h); replay.h replays a recording bit for bit.
///
/// ## File format, version 5 (`.vhrec`)
/// All integers and doubles are little-endian (IEEE-754 binary64 for doubles); the writer
/// refuses to build on a big-endian host. The file is written append-only.
///
///   File header (24 bytes, then the metadata):
///     offset  size  field
///          0     8  magic "VHREC\r\n\x1a" (bytes 56 48 52 45 43 0d 0a 1a)
///          8     4  uint32 format version (kRecordingFormatVersion = 5; readers accept 1 to 5)
///         12     4  uint32 record size in bytes (sizeof(TickRecord) = 224; 216 in version 4, 200 in 1 to 3)
///         16     4  uint32 metadata length M in bytes
///         20     4  uint32 CRC-32 of the M metadata bytes
///         24     M  metadata: one UTF-8 JSON object (makeSessionMetadata(): scene, dataset and
///                   its SHA-256, tool, point shell, gains, device, software version; plus
///                   "servo_rate_Hz" and "start_time_utc" added by the writer)
///   Then zero or more chunks, back to back, in any order, told apart by the tag; from version 3
///   on the last one is the end marker.
///   Record chunk:
///     offset  size  field
///          0     4  chunk tag "CHNK" (bytes 43 48 4e 4b)
///          4     4  uint32 record count N (1 .. 65535)
///          8     8  uint64 dropped records in total when the chunk was written (ring overflow)
///         16  N*R   N TickRecord, each the byte image of the struct (layout below; R = 224, or
///                   216 in version 4: the record up to critical_segment and 4 bytes of 0;
///                   200 in versions 1 to 3: the record up to and including flags)
///   16+N*R       4  uint32 CRC-32 of bytes [0, 16 + N*R) of the chunk
///   Event chunk (version 2 only; written before the record chunk it was flushed with):
///     offset  size  field
///          0     4  chunk tag "EVNT" (bytes 45 56 4e 54)
///          4     4  uint32 event count N (1 .. 65535)
///          8     4  uint32 payload length B in bytes (<= 16 MiB)
///         12     B  N events back to back, each:
///                     double  time_s   servo time since the recording started [s]
///                     uint64  tick     servo tick counter
///                     uint32  T, then T bytes: type, UTF-8 ("marker", "isovalue", ...)
///                     uint32  J, then J bytes: detail, UTF-8 JSON object text
///       12+B     4  uint32 CRC-32 of bytes [0, 12 + B) of the chunk
///   End marker (versions 3 to 5; written by close(), always the last chunk):
///     offset  size  field
///          0     4  chunk tag "ENDR" (bytes 45 4e 44 52)
///          4     4  uint32 status: 0 = closed normally; else the errno of the write that failed
///                   and ended the recording early (e.g. 28 ENOSPC, 27 EFBIG)
///          8     8  uint64 records written in total
///         16     8  uint64 dropped records in total (ring overflow)
///         24     4  uint32 CRC-32 of bytes [0, 24)
///   Version 4 files are the same with 216-byte records (no removed voxels nor deadline work:
///   a reader sets both to 0). Version 3 files also have 200-byte records (no proximity: a reader sets
///   critical_distance_m to NaN and critical_segment to -1); version 2 files also lack the end
///   marker; version 1 files also lack event chunks.
///
///   TickRecord (tick_record.h; 224 bytes; all frames are the scene (world) frame W, SI units):
///     offset  field
///          0  double   time_s          servo time since the recording started [s]
///          8  double   p_WD_m[3]       device (tool) position in W [m]
///         32  double   q_WD[4]         device orientation in W, unit quaternion (w, x, y, z)
///         64  double   p_WP_m[3]       proxy position in W [m]
///         88  double   q_WP[4]         proxy orientation in W (w, x, y, z)
///        120  double   force_W_N[3]    force on the user's hand in W [N]
///        144  double   torque_W_Nm[3]  torque on the user's hand in W [N*m]
///        168  double   isovalue        isovalue in the data's units (HU for CT)
///        176  uint64   tick            servo tick counter
///        184  double   tick_time_s     compute time of the tick [s]
///        192  uint32   contacts        contact set size
///        196  uint32   flags           kRecordFlag* bits (0..15), touched segment + 1 (16..31)
///        200  double   critical_distance_m  point shell to the nearest critical segment [m]
///                                      (critical_proximity.h; +inf: none within 20 mm)
///        208  int32    critical_segment     that segment's index, or -1
///        212  uint32   removed_voxels  voxels the burr removed whole on this tick
///        216  int64    deadline_work   1 + the work at which the solver's deadline on the
///                                      clock cut this tick, 0 when it did not (a replay stops
///                                      the tick there: replay.h)
///
///   Why a new version rather than spare bits: the distance needs a double's range and
///   precision (sub-millimetre near a nerve, +inf far away), and flags has 3 spare bits; events
///   alone would lose the per-tick curve the report plots. 16 more bytes a tick (8%). Version 5:
///   what the burr removed is counted where it happened (one rule for every writer: the record,
///   not an event a writer may forget) and a tick the clock cut is replayed as it ran; 8 more
///   bytes a tick (4%).
///
/// CRC-32 is the ISO-HDLC / zlib one (reflected polynomial 0xEDB88320, init and final XOR
/// 0xFFFFFFFF; crc32("123456789") = 0xCBF43926).
///
/// Size: 224 bytes per tick plus 20 bytes per record chunk; at 1 kHz with the default
/// 500-record chunks that is 224,040 bytes (about 219 KiB) per second of recording, about
/// 807 MB per hour, plus the header (24 bytes + the metadata, typically 1-2 KiB) and the events
/// (16 bytes of framing per event chunk, 24 bytes + type + detail per event, e.g. 57 bytes for
/// an isovalue change {"from":400,"to":500}; sessions have a few per minute).
///
/// Events come from RecordingWriter::addEvent() (any thread but the servo thread; e.g.
/// HapticThread::recordEvent() for markers, tool and gains changes) and from the writer thread
/// itself, which watches the records: an isovalue that differs from the previous record's gives
/// an "isovalue" event {"from":A,"to":B}; kRecordFlagDeviceDisconnected turning on / off gives
/// "device_disconnected" / "device_connected" (the first record's state is in the metadata; a
/// recording that starts disconnected gets a "device_disconnected" event at its first tick);
/// kRecordFlagJam turning on / off gives "jam" / "jam_cleared"; a technique rule's bit
/// (recordTechnique()) turning on gives "technique" {"rule":"force"|"speed"|"shaft"}; the nearest
/// critical segment's distance entering its warning / alarm distance (metadata's segments:
/// "warn_mm", "alarm_mm") gives "proximity_warn" / "proximity_alarm" {"segment", "distance_mm"},
/// leaving it "proximity_alarm_cleared" / "proximity_warn_cleared" {"segment", "to", "distance_mm"}.
///
/// A crash (even `kill -9`) loses only the records not yet written: the writer flushes a chunk
/// at least every RecordingWriterOptions::max_chunk_wall_s (< 1 s) and every chunk holds at most
/// RecordingWriterOptions::chunk_records (< 1 s of ticks; the writer enforces it). Such a
/// version 3 or 4 file lacks its end marker, and readRecording() says it is unfinished. A damaged
/// chunk costs that chunk only: readRecording() scans forward for the next chunk whose tag,
/// header and CRC-32 check out, goes on from there and names the damage (bytes skipped, ticks
/// missing) in a warning; a truncated tail is a warning too. A write that fails (disk full, file
/// size limit) stops the writing at once: the partly written chunk is cut off (the file ends on
/// its last whole chunk), failed() and failure() say so at once, and close() adds the end marker
/// with the errno when it still fits.

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <initializer_list>
#include <iosfwd>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <type_traits>
#include <vector>

#include "vh/runtime/segments.h"
#include "vh/runtime/tick_record.h"
#include "vh/runtime/tick_ring.h"

namespace vh::runtime {

inline constexpr std::uint32_t kRecordingFormatVersion = 5;
/// Deepest nesting of arrays and objects readRecording() accepts in the metadata (deeper: the
/// recording is refused as damaged) and in an event's detail (deeper: the event is dropped,
/// with a warning). What this program writes nests under 10 levels.
inline constexpr std::size_t kMaxRecordingJsonDepth = 100;


/// One timestamped event of a session (marker, isovalue change, tool change, device
/// connect/disconnect, ...).
struct RecordingEvent {
  double time_s = 0.0;       ///< Servo time since the recording started [s] (same clock as TickRecord::time_s).
  std::uint64_t tick = 0;    ///< Servo tick counter (same as TickRecord::tick).
  std::string type;          ///< "marker", "isovalue", "tool", "gains", "device_connected", "device_disconnected", "note", ...
  std::string detail_json;   ///< A JSON object text, e.g. {"label":"nerve"} or {"from":400,"to":500}.
};

/// The current UTC time as ISO-8601 "YYYY-MM-DDTHH:MM:SSZ" (metadata's start_time_utc).
std::string utcNow();

/// CRC-32 (ISO-HDLC / zlib) of `size` bytes, continuing from `crc` (0 to start).
std::uint32_t crc32(const void* data, std::size_t size, std::uint32_t crc = 0) noexcept;

/// How RecordingWriter sizes its ring and chunks.
struct RecordingWriterOptions {
  std::size_t ring_capacity = 1u << 14;  ///< Records the ring holds (16 s at 1 kHz).
  /// Records per chunk at most: < servo_rate_Hz (under 1 s of ticks) and <= 65535.
  std::size_t chunk_records = 500;
  double max_chunk_wall_s = 0.5;         ///< A non-empty chunk is written at least this often [s].
  double servo_rate_Hz = 1000.0;         ///< Stored in the metadata [Hz].
};

/// Writes a recording: the servo thread push()es, a writer thread drains the ring to disk.
class RecordingWriter {
 public:
  /// Creates (truncates) `path`, writes the header and starts the writer thread.
  /// @param metadata_json a JSON object (scene, dataset, device, ...), stored in the header.
  /// @throws std::invalid_argument when metadata_json is not a JSON object or the options are
  ///         out of range; std::runtime_error when the file cannot be created or written.
  RecordingWriter(const std::filesystem::path& path, const std::string& metadata_json,
                  const RecordingWriterOptions& options = {});
  /// Calls close() (errors are swallowed; call close() to see them).
  ~RecordingWriter();
  RecordingWriter(const RecordingWriter&) = delete;
  RecordingWriter& operator=(const RecordingWriter&) = delete;

  /// Servo thread only: never blocks, allocates or throws. @return false when dropped.
  bool push(const TickRecord& record) noexcept { return ring_.push(record); }
  /// For producers that are not real-time (the headless runner, which ticks faster than the
  /// writer drains): waits (sleeping 1 ms at a time) while the ring is full instead of dropping.
  /// One producer thread only, as push(); never mix the two on different threads.
  void pushWaiting(const TickRecord& record) noexcept;
  /// Adds an event; any thread but the servo thread; thread-safe; may allocate. It is written
  /// to disk with the next chunk flush (at most max_chunk_wall_s later) and at close().
  /// An empty detail_json stands for {}.
  /// @throws std::invalid_argument when detail_json is not a JSON object or type is empty;
  ///         std::logic_error after close().
  void addEvent(const RecordingEvent& event);
  /// Stops the writer thread after it drained the ring, writes the last chunk and the end
  /// marker, closes the file. Idempotent.
  /// @throws std::runtime_error when a write failed (the message names the cause, as failure()).
  void close();

  /// True once a write failed (any thread): nothing more is written; what was is kept whole.
  bool failed() const noexcept { return failed_.load(std::memory_order_acquire); }
  /// The cause of the failure, e.g. "disk full (No space left on device)" or "file size limit
  /// reached (File too large)"; empty when none (any thread).
  std::string failure() const;

  std::uint64_t dropped() const noexcept { return ring_.dropped(); }
  /// Records written to disk so far (any thread).
  std::uint64_t recordsWritten() const noexcept { return written_.load(std::memory_order_relaxed); }
  /// Events written to disk so far (any thread).
  std::uint64_t eventsWritten() const noexcept { return events_written_.load(std::memory_order_relaxed); }
  const std::filesystem::path& path() const noexcept { return path_; }

 private:
  void run() noexcept;
  bool writeChunk(const TickRecord* records, std::size_t count) noexcept;
  struct Bytes {
    const void* data;
    std::size_t size;
  };
  /// Writes one chunk (its parts back to back) at the end of the file; on failure records
  /// errno, cuts the file back to its last whole chunk and sets failed_.
  bool writeWhole(std::initializer_list<Bytes> parts) noexcept;
  /// close(): the end marker (status = the failure's errno, 0 when none).
  void writeEndMarker() noexcept;
  /// Writer thread: events the records imply (isovalue changes, device (dis)connection).
  void deriveEvents(const TickRecord* records, std::size_t count);
  /// Writer thread: writes the pending events as one event chunk (nothing when none).
  bool writeEvents() noexcept;

  std::filesystem::path path_;
  RecordingWriterOptions options_;
  TickRing ring_;
  int fd_ = -1;
  std::uint64_t file_size_ = 0;                 // bytes of whole chunks written (writer thread)
  std::atomic<int> error_number_{0};            // errno of the failed write; 0 when none
  std::vector<TickRecord> chunk_;
  std::mutex events_mutex_;
  std::vector<RecordingEvent> pending_events_;  // guarded by events_mutex_
  bool have_previous_ = false;                  // writer thread: deriveEvents() state
  bool previous_jammed_ = false;                // writer thread: deriveEvents() state
  std::uint32_t previous_technique_ = 0;        // writer thread: deriveEvents() state
  int previous_segment_ = -1;
  std::vector<std::string> segment_names_;      // from the metadata (constant)
  std::vector<bool> segment_critical_;
  std::vector<ProximityThresholds> segment_thresholds_;  // from the metadata (constant)
  ProximityLevel previous_level_ = ProximityLevel::kClear;  // writer thread: deriveEvents() state
  int previous_critical_segment_ = -1;
  /// The proximity level of a record against its segment's thresholds from the metadata.
  ProximityLevel proximityLevelOf(const TickRecord& r) const noexcept;
  double previous_isovalue_ = 0.0;
  bool previous_disconnected_ = false;
  std::atomic<std::uint64_t> events_written_{0};
  std::atomic<bool> stop_{false};
  std::atomic<bool> failed_{false};
  std::atomic<std::uint64_t> written_{0};
  std::thread thread_;
  bool closed_ = false;
};

/// A recording as read back.
struct Recording {
  std::uint32_t version = 0;
  std::string metadata_json;           ///< The header's JSON object, verbatim.
  std::vector<TickRecord> records;     ///< Every record of every good chunk, in order.
  /// Every event of every good chunk, in order (sorted by tick, stable; empty for version 1).
  std::vector<RecordingEvent> events;
  std::size_t chunks = 0;              ///< Good record chunks read.
  std::size_t event_chunks = 0;        ///< Good event chunks read.
  std::uint64_t dropped_records = 0;   ///< Ring overflows as of the last good record chunk.
  std::uint64_t bytes_ignored = 0;     ///< Bytes not read: damaged chunks skipped and a bad tail.
  std::size_t damaged_regions = 0;     ///< Damaged stretches skipped (each up to the next good chunk).
  /// Versions 3 and 4: the end marker was read (the writer closed the file). False for older versions.
  bool ended = false;
  /// The end marker's status: 0, or the errno of the write failure that ended the recording.
  std::uint32_t end_status = 0;
  /// Damage, a truncated tail, a missing end marker or a write failure, one sentence each;
  /// empty for a whole file.
  std::vector<std::string> warnings;
};

/// Reads every good chunk of a recording. A damaged chunk is skipped (the reader resumes at
/// the next chunk whose tag, header and CRC-32 check out) and a truncated tail ignored, each
/// with a warning naming the byte offset, the bytes and the ticks lost; a version 3 or 4 file
/// without its end marker gets an "unfinished recording" warning.
/// An event whose detail nests deeper than kMaxRecordingJsonDepth is dropped with a warning.
/// @throws std::runtime_error when the file cannot be opened, is not a recording (magic), has
///         an unsupported version or record size, or a damaged header / metadata (metadata
///         nested deeper than kMaxRecordingJsonDepth included).
Recording readRecording(const std::filesystem::path& path);

/// Which files a reader takes: a command-line tool or a script (where a crash in a library's
/// parser ends that command only) reads both the .vhrec and its HDF5 export; the window, which
/// holds a session and haptic threads, reads only the .vhrec, whose parser is this program's own
/// and fuzzed (the HDF5 library's parser is neither).
enum class RecordingFiles { kVhrecOrHdf5, kVhrecOnly };

/// readRecording() for `files`. @throws std::runtime_error as readRecording(), and for an HDF5
///         file under kVhrecOnly ("an HDF5 export of a recording: ... open the .vhrec it came from").
Recording readRecording(const std::filesystem::path& path, RecordingFiles files);

/// One CSV row per record, header line with SI units:
/// `t_s,tick,device_x_m,device_y_m,device_z_m,device_qw,device_qx,device_qy,device_qz,
/// proxy_x_m,...,proxy_qz,force_x_N,force_y_N,force_z_N,torque_x_Nm,torque_y_Nm,torque_z_Nm,
/// contacts,isovalue,tick_time_s,flags,critical_distance_m,critical_segment,removed_voxels,
/// deadline_work` (the distance "inf" beyond the range, "nan" where not measured). Doubles are written with 17 significant digits (they
/// read back bit for bit).
void writeRecordingCsv(const Recording& recording, std::ostream& out);
/// The same to a file. @throws std::runtime_error when it cannot be written.
void writeRecordingCsv(const Recording& recording, const std::filesystem::path& path);
/// One CSV row per event: `t_s,tick,type,detail_json` (type and detail quoted as RFC 4180:
/// in double quotes, inner quotes doubled). @throws std::runtime_error when it cannot be written.
void writeRecordingEventsCsv(const Recording& recording, std::ostream& out);
void writeRecordingEventsCsv(const Recording& recording, const std::filesystem::path& path);
/// The metadata plus a summary (version, records, chunks, duration_s, dropped_records,
/// warnings) and the events ("events": [{"t_s", "tick", "type", "detail"}], detail parsed) as
/// pretty-printed JSON. @throws std::runtime_error when it cannot be written.
void writeRecordingJson(const Recording& recording, const std::filesystem::path& path);

/// Time in contact, peak force and touches per segment of a recording, from the
/// segment each record names (recordSegment()) and the segments its metadata lists
/// ("scene": {"segmentation": {"segments": [{"name", "critical"}, ...]}}); empty when it has none.
std::vector<SegmentContact> segmentContacts(const Recording& recording);

/// Per critical segment of the metadata's segmentation (with its thresholds there; the defaults
/// when absent): the time within its warning and alarm distances, the entries and the closest
/// approach, from each record's nearest critical segment (TickRecord::critical_segment), each
/// record lasting `dt_s`. Only the nearest critical segment is recorded per tick, so where two
/// are within their warning distances at once, only the nearer counts then. A recording of
/// format version 1 to 3 has no distances: every closest_m is NaN. Empty without critical segments.
std::vector<SegmentProximityStats> segmentProximity(const Recording& recording, double dt_s);

}  // namespace vh::runtime
