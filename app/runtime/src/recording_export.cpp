/// @file
/// A recording's exports as text (recording.h): one CSV row per tick, one per event, and the
/// metadata, summary and events as JSON. The HDF5 export is recording_hdf5.cpp.

#include <cstdint>
#include <cstring>
#include <filesystem>
#include <iomanip>
#include <ostream>
#include <span>
#include <string>
#include <utility>

#include <nlohmann/json.hpp>

#include "vh/io/private_files.h"
#include "vh/runtime/recording.h"
#include "vh/runtime/tick_columns.h"

namespace vh::runtime {
namespace {

/// The value of type T at `at` (a column's place in a TickRecord).
template <typename T>
T valueAt(const unsigned char* at) {
  T v;
  std::memcpy(&v, at, sizeof(T));
  return v;
}

}  // namespace

void writeRecordingCsv(const Recording& recording, std::ostream& out) {
  const std::span<const TickColumn> columns = tickColumns();
  for (std::size_t c = 0; c < columns.size(); ++c) out << (c == 0 ? "" : ",") << columns[c].name;
  out << '\n' << std::setprecision(17);
  for (const TickRecord& r : recording.records) {
    const auto* bytes = reinterpret_cast<const unsigned char*>(&r);
    for (std::size_t c = 0; c < columns.size(); ++c) {
      if (c != 0) out << ',';
      const unsigned char* at = bytes + columns[c].offset;
      switch (columns[c].kind) {
        case TickColumn::kF64: out << valueAt<double>(at); break;
        case TickColumn::kU64: out << valueAt<std::uint64_t>(at); break;
        case TickColumn::kU32: out << valueAt<std::uint32_t>(at); break;
        case TickColumn::kI32: out << valueAt<std::int32_t>(at); break;
        case TickColumn::kI64: out << valueAt<std::int64_t>(at); break;
      }
    }
    out << '\n';
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

}  // namespace vh::runtime
