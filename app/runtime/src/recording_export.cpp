/// @file
/// A recording's exports as text (recording.h): one CSV row per tick, one per event, and the
/// metadata, summary and events as JSON. The HDF5 export is recording_hdf5.cpp.

#include <filesystem>
#include <iomanip>
#include <ostream>
#include <string>
#include <utility>

#include <nlohmann/json.hpp>

#include "vh/io/private_files.h"
#include "vh/runtime/recording.h"

namespace vh::runtime {

void writeRecordingCsv(const Recording& recording, std::ostream& out) {
  out << "t_s,tick,device_x_m,device_y_m,device_z_m,device_qw,device_qx,device_qy,device_qz,"
         "proxy_x_m,proxy_y_m,proxy_z_m,proxy_qw,proxy_qx,proxy_qy,proxy_qz,"
         "force_x_N,force_y_N,force_z_N,torque_x_Nm,torque_y_Nm,torque_z_Nm,"
         "contacts,isovalue,tick_time_s,flags,critical_distance_m,critical_segment,removed_voxels,deadline_work\n";
  out << std::setprecision(17);
  for (const TickRecord& r : recording.records) {
    out << r.time_s << ',' << r.tick;
    for (double v : r.p_WD_m) out << ',' << v;
    for (double v : r.q_WD) out << ',' << v;
    for (double v : r.p_WP_m) out << ',' << v;
    for (double v : r.q_WP) out << ',' << v;
    for (double v : r.force_W_N) out << ',' << v;
    for (double v : r.torque_W_Nm) out << ',' << v;
    out << ',' << r.contacts << ',' << r.isovalue << ',' << r.tick_time_s << ',' << r.flags << ','
        << r.critical_distance_m << ',' << r.critical_segment << ',' << r.removed_voxels << ',' << r.deadline_work
        << '\n';
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
