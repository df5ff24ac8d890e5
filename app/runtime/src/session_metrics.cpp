#include "vh/runtime/session_metrics.h"

#include "vh/runtime/even_samples.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <limits>
#include <stdexcept>

#include <nlohmann/json.hpp>

#include "vh/runtime/runner.h"

namespace vh::runtime {
namespace {

Eigen::Vector3d devicePosition(const TickRecord& r) { return {r.p_WD_m[0], r.p_WD_m[1], r.p_WD_m[2]}; }
Eigen::Vector3d proxyPosition(const TickRecord& r) { return {r.p_WP_m[0], r.p_WP_m[1], r.p_WP_m[2]}; }
double norm3(const double v[3]) { return std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]); }

/// A string member of a JSON object, "" when absent or not a string.
std::string stringAt(const nlohmann::json& j, const char* key) {
  if (!j.is_object()) return {};
  const auto it = j.find(key);
  return it != j.end() && it->is_string() ? it->get<std::string>() : std::string{};
}

/// The metadata's identity fields and servo rate (0 when absent).
void readIdentity(const Recording& recording, SessionMetrics& m) {
  nlohmann::json meta;
  try {
    meta = nlohmann::json::parse(recording.metadata_json);
  } catch (const nlohmann::json::exception&) {
    m.notices.push_back("the recording's metadata is not JSON: no scene, dataset or servo rate");
    return;
  }
  if (!meta.is_object()) return;
  const nlohmann::json scene = meta.value("scene", nlohmann::json::object());
  m.scene = stringAt(scene, "source");
  if (m.scene.empty() && scene.is_object()) m.scene = stringAt(scene.value("volume", nlohmann::json::object()), "path");
  m.dataset_sha256 = stringAt(meta.value("dataset", nlohmann::json::object()), "sha256");
  m.label = stringAt(meta, "user");
  if (m.label.empty()) m.label = stringAt(meta, "note");
  m.start_time_utc = stringAt(meta, "start_time_utc");
  const auto rate = meta.find("servo_rate_Hz");
  if (rate != meta.end() && rate->is_number() && rate->get<double>() > 0.0) m.servo_rate_Hz = rate->get<double>();
}

/// The servo period when the metadata lacks the rate: the median spacing of time_s.
double medianPeriod(const std::vector<TickRecord>& records) {
  std::vector<double> d;
  d.reserve(records.size());
  for (std::size_t i = 1; i < records.size(); ++i) d.push_back(records[i].time_s - records[i - 1].time_s);
  if (d.empty()) return 0.0;
  std::nth_element(d.begin(), d.begin() + static_cast<std::ptrdiff_t>(d.size() / 2), d.end());
  return d[d.size() / 2];
}

/// Path length, peak speed and the jerk measures of the device (file comment of the header).
void motionMetrics(const std::vector<TickRecord>& records, double dt, const MetricsOptions& options,
                   SessionMetrics& m) {
  const std::size_t n = records.size();
  // A placement (kRecordFlagPlacement on record i: the tools jumped between records i - 1 and i)
  // is not the hand's motion: no difference across one enters the path, the speed or the jerk.
  // placed[i] = placements among records 0..i-1, so (a, b] holds one iff placed[b + 1] > placed[a + 1].
  std::vector<std::size_t> placed(n + 1, 0);
  for (std::size_t i = 0; i < n; ++i) placed[i + 1] = placed[i] + ((records[i].flags & kRecordFlagPlacement) != 0 ? 1 : 0);
  const auto jumpIn = [&](std::size_t a, std::size_t b) { return placed[b + 1] > placed[a + 1]; };  // in (a, b]
  for (std::size_t i = 1; i < n; ++i) {
    if (jumpIn(i - 1, i)) continue;
    m.path_length_m += (devicePosition(records[i]) - devicePosition(records[i - 1])).norm();
    m.proxy_path_length_m += (proxyPosition(records[i]) - proxyPosition(records[i - 1])).norm();
  }
  if (m.duration_s > 0.0) m.mean_speed_m_per_s = m.path_length_m / m.duration_s;
  const std::size_t k = std::max<std::size_t>(1, static_cast<std::size_t>(std::lround(options.derivative_step_s / dt)));
  const double h = static_cast<double>(k) * dt;
  const auto p = [&](std::size_t i) { return devicePosition(records[i]); };
  for (std::size_t i = k; i + k < n; ++i) {
    if (jumpIn(i - k, i + k)) continue;
    m.peak_speed_m_per_s = std::max(m.peak_speed_m_per_s, ((p(i + k) - p(i - k)) / (2.0 * h)).norm());
  }
  double jerk_sq_sum = 0.0;
  std::size_t jerk_samples = 0;
  for (std::size_t i = 2 * k; i + 2 * k < n; ++i) {
    if (jumpIn(i - 2 * k, i + 2 * k)) continue;
    const Eigen::Vector3d jerk = (p(i + 2 * k) - 2.0 * p(i + k) + 2.0 * p(i - k) - p(i - 2 * k)) / (2.0 * h * h * h);
    jerk_sq_sum += jerk.squaredNorm();
    ++jerk_samples;
  }
  if (jerk_samples == 0) return;
  m.integrated_squared_jerk = jerk_sq_sum / static_cast<double>(jerk_samples) * m.duration_s;
  if (m.peak_speed_m_per_s > 0.0) {
    m.dimensionless_jerk =
        m.integrated_squared_jerk * std::pow(m.duration_s, 3) / (m.peak_speed_m_per_s * m.peak_speed_m_per_s);
    if (m.dimensionless_jerk > 0.0) m.log_dimensionless_jerk = -std::log(m.dimensionless_jerk);
  }
}

/// Force, torque, contact, drilling and timing counts, tick by tick.
void tickMetrics(const std::vector<TickRecord>& records, double dt, double threshold_N, SessionMetrics& m) {
  std::vector<double> forces;
  forces.reserve(records.size());
  double force_sum = 0.0, contact_force_sum = 0.0, torque_sum = 0.0, tick_sum = 0.0;
  std::uint64_t above = 0, contact = 0, drill = 0;
  for (const TickRecord& r : records) {
    if (r.flags & kRecordFlagDrillOn) ++drill;
    if (r.flags & kRecordFlagDeadlineMiss) ++m.deadline_misses;
    if (r.flags & kRecordFlagDeadlineCut) ++m.deadline_cuts;
    if (r.flags & kRecordFlagBadSample) ++m.bad_samples;
    if (r.flags & kRecordFlagForceLimited) ++m.force_limited_ticks;
    if (r.flags & kRecordFlagNonFinite) ++m.non_finite_ticks;
    tick_sum += r.tick_time_s;
    m.max_tick_s = std::max(m.max_tick_s, r.tick_time_s);
    // A placement's tick is not the hand's (the tools jumped just before it): its force is left out.
    if ((r.flags & kRecordFlagPlacement) != 0) continue;
    const double f = norm3(r.force_W_N);
    const double t = norm3(r.torque_W_Nm);
    forces.push_back(f);
    force_sum += f;
    torque_sum += t;
    m.max_force_N = std::max(m.max_force_N, f);
    m.max_torque_Nm = std::max(m.max_torque_Nm, t);
    if (f > threshold_N) ++above;
    if (r.contacts > 0) {
      ++contact;
      contact_force_sum += f;
    }
  }
  const auto n = static_cast<double>(records.size());
  const auto felt = static_cast<double>(std::max<std::size_t>(1, forces.size()));
  m.mean_force_N = force_sum / felt;
  m.mean_torque_Nm = torque_sum / felt;
  m.mean_tick_s = tick_sum / n;
  if (contact > 0) m.mean_contact_force_N = contact_force_sum / static_cast<double>(contact);
  std::sort(forces.begin(), forces.end());
  m.p95_force_N = nearestRankPercentile(forces, 0.95);
  m.time_above_threshold_s = static_cast<double>(above) * dt;
  m.time_in_contact_s = static_cast<double>(contact) * dt;
  m.drill_on_s = static_cast<double>(drill) * dt;
}

/// The cavity at the recording's start from its metadata (scene.drill.cavity's runs; the felt
/// voxel's volume from drilling.felt_voxel_volume_mm3, else the cavity's grid) and, from format
/// version 5 on, what the burr removed during it from the records. Older recordings' "drilled"
/// event is read by segmentMetrics(); the totals are summed by cavityTotals().
void drillingMetrics(const Recording& recording, SessionMetrics& m) {
  const nlohmann::json meta = nlohmann::json::parse(recording.metadata_json, nullptr, false);
  if (!meta.is_object()) return;
  double voxel_mm3 = 0.0;
  if (const auto d = meta.find("drilling"); d != meta.end() && d->is_object()) {
    const auto v = d->find("felt_voxel_volume_mm3");
    if (v != d->end() && v->is_number() && std::isfinite(v->get<double>()) && v->get<double>() > 0.0) voxel_mm3 = v->get<double>();
  }
  // Any member may be missing or of another type (a damaged or foreign metadata): then nothing.
  const auto objectAt = [](const nlohmann::json& j, const char* key) {
    const auto it = j.is_object() ? j.find(key) : j.end();
    return j.is_object() && it != j.end() && it->is_object() ? *it : nlohmann::json::object();
  };
  const nlohmann::json cavity = objectAt(objectAt(objectAt(meta, "scene"), "drill"), "cavity");
  {
    const auto runs_it = cavity.find("runs");
    const nlohmann::json runs = runs_it != cavity.end() && runs_it->is_array() ? *runs_it : nlohmann::json::array();
    for (std::size_t r = 1; runs.is_array() && r < runs.size(); r += 2)
      if (runs[r].is_number_unsigned()) m.cavity_at_start_voxels += runs[r].get<std::uint64_t>();
    const auto spacing_it = cavity.find("spacing_m");
    const nlohmann::json spacing = spacing_it != cavity.end() ? *spacing_it : nlohmann::json::array();
    if (voxel_mm3 == 0.0 && spacing.is_array() && spacing.size() == 3 && spacing[0].is_number() &&
        spacing[1].is_number() && spacing[2].is_number())
      voxel_mm3 = 1e9 * spacing[0].get<double>() * spacing[1].get<double>() * spacing[2].get<double>();
  }
  if (!(voxel_mm3 > 0.0 && std::isfinite(voxel_mm3))) voxel_mm3 = 0.0;
  m.cavity_at_start_mm3 = static_cast<double>(m.cavity_at_start_voxels) * voxel_mm3;
  if (recording.version < 5) return;
  std::uint64_t removed = 0;
  for (const TickRecord& r : recording.records) removed += r.removed_voxels;
  m.removed_voxels = removed;
  m.removed_mm3 = static_cast<double>(removed) * voxel_mm3;
  if (removed > 0 && recording.dropped_records > 0)
    m.notices.push_back("the volume drilled away counts the records kept: " + std::to_string(recording.dropped_records) +
                        " were dropped while recording");
}

/// The cavity at the end: what it started with and what was removed during the recording.
void cavityTotals(SessionMetrics& m) {
  m.cavity_voxels = m.cavity_at_start_voxels + m.removed_voxels;
  m.cavity_mm3 = m.cavity_at_start_mm3 + m.removed_mm3;
}

/// Per segment: contact (segmentContacts(), rescaled to dt) and the critical_removed events.
void segmentMetrics(const Recording& recording, double dt, SessionMetrics& m) {
  for (const SegmentContact& c : segmentContacts(recording)) {
    SegmentMetrics s;
    s.name = c.name;
    s.critical = c.critical;
    s.time_in_contact_s = static_cast<double>(c.ticks) * dt;
    s.peak_force_N = c.peak_force_N;
    s.touches = c.touches;
    if (s.critical) {
      m.critical_contact_s += s.time_in_contact_s;
      m.critical_touches += s.touches;
    }
    m.segments.push_back(s);
  }
  for (const RecordingEvent& e : recording.events) {
    if (e.type == "marker") ++m.markers;
    if (e.type == "technique") {
      const nlohmann::json d = nlohmann::json::parse(e.detail_json.empty() ? "{}" : e.detail_json, nullptr, false);
      const std::string rule = d.is_object() ? stringAt(d, "rule") : std::string();
      for (int k = 0; k < kTechniqueRuleCount; ++k)
        if (rule == techniqueRuleName(k)) ++m.technique_events[static_cast<std::size_t>(k)];
      continue;
    }
    if (e.type == "drilled") {  // older recordings (drillingMetrics())
      if (recording.version >= 5) continue;
      const nlohmann::json d = nlohmann::json::parse(e.detail_json.empty() ? "{}" : e.detail_json, nullptr, false);
      if (d.is_object()) {  // the totals when the recording closed: the last one counts
        m.removed_voxels = d.value("voxels", std::uint64_t{0});
        m.removed_mm3 = d.value("mm3", 0.0);
      }
      continue;
    }
    if (e.type != "critical_removed") continue;
    const nlohmann::json d = nlohmann::json::parse(e.detail_json.empty() ? "{}" : e.detail_json, nullptr, false);
    if (!d.is_object()) continue;
    const std::string name = stringAt(d, "segment");
    const auto voxels = d.value("voxels", std::uint64_t{0});
    const double mm3 = d.value("mm3", 0.0);
    m.critical_removed_voxels += voxels;
    m.critical_removed_mm3 += mm3;
    auto it = std::find_if(m.segments.begin(), m.segments.end(), [&](const SegmentMetrics& s) { return s.name == name; });
    if (it == m.segments.end()) {
      SegmentMetrics s;
      s.name = name;
      s.critical = true;
      it = m.segments.insert(m.segments.end(), s);
    }
    it->removed_voxels += voxels;
    it->removed_mm3 += mm3;
  }
}

}  // namespace

std::string cohortLabel(const SessionMetrics& m, const std::filesystem::path& file) {
  return m.label.empty() ? file.stem().string() : m.label;
}

SessionMetrics computeSessionMetrics(const Recording& recording, const MetricsOptions& options) {
  if (!std::isfinite(options.force_threshold_N) || options.force_threshold_N < 0.0)
    throw std::invalid_argument("the force threshold must be a finite number >= 0 N");
  if (!(options.derivative_step_s > 0.0) || !std::isfinite(options.derivative_step_s))
    throw std::invalid_argument("the derivative step must be > 0 s");
  SessionMetrics m;
  m.notices = recording.warnings;
  m.force_threshold_N = options.force_threshold_N;
  m.records = recording.records.size();
  m.dropped_records = recording.dropped_records;
  readIdentity(recording, m);
  const std::vector<TickRecord>& records = recording.records;
  if (m.servo_rate_Hz <= 0.0) {
    const double period = medianPeriod(records);
    m.servo_rate_Hz = period > 0.0 ? 1.0 / period : 1000.0;
    m.notices.push_back("the metadata names no servo rate: " + std::to_string(m.servo_rate_Hz) +
                        " Hz taken from the records' times");
  }
  if (m.dropped_records > 0)
    m.notices.push_back(std::to_string(m.dropped_records) +
                        " records were dropped while recording: times in contact and above the threshold "
                        "count the records kept");
  drillingMetrics(recording, m);
  if (records.empty()) {
    m.notices.push_back("the recording holds no ticks: every metric is 0");
    cavityTotals(m);
    return m;
  }
  const double dt = 1.0 / m.servo_rate_Hz;
  m.duration_s = records.back().time_s - records.front().time_s;
  tickMetrics(records, dt, options.force_threshold_N, m);
  motionMetrics(records, dt, options, m);
  segmentMetrics(recording, dt, m);
  cavityTotals(m);
  m.proximity = segmentProximity(recording, dt);
  return m;
}

std::vector<MetricValue> metricValues(const SessionMetrics& m) {
  const auto count = [](std::uint64_t v) { return static_cast<double>(v); };
  return {
      {"duration_s", "Duration", "s", m.duration_s},
      {"records", "Servo ticks recorded", "", count(m.records)},
      {"path_length_m", "Path length of the device", "m", m.path_length_m},
      {"proxy_path_length_m", "Path length of the proxy", "m", m.proxy_path_length_m},
      {"mean_speed_m_per_s", "Mean speed of the device", "m/s", m.mean_speed_m_per_s},
      {"peak_speed_m_per_s", "Peak speed of the device", "m/s", m.peak_speed_m_per_s},
      {"integrated_squared_jerk_m2_per_s5", "Integrated squared jerk of the device", "m^2/s^5",
       m.integrated_squared_jerk},
      {"dimensionless_jerk", "Dimensionless jerk (Hogan & Sternad 2009)", "", m.dimensionless_jerk},
      {"log_dimensionless_jerk", "Log dimensionless jerk (higher is smoother)", "", m.log_dimensionless_jerk},
      {"mean_force_N", "Mean |F|", "N", m.mean_force_N},
      {"mean_contact_force_N", "Mean |F| in contact", "N", m.mean_contact_force_N},
      {"p95_force_N", "95th percentile of |F|", "N", m.p95_force_N},
      {"max_force_N", "Peak |F|", "N", m.max_force_N},
      {"force_threshold_N", "Force threshold", "N", m.force_threshold_N},
      {"time_above_threshold_s", "Time with |F| above the threshold", "s", m.time_above_threshold_s},
      {"mean_torque_Nm", "Mean |torque|", "N*m", m.mean_torque_Nm},
      {"max_torque_Nm", "Peak |torque|", "N*m", m.max_torque_Nm},
      {"time_in_contact_s", "Time in contact", "s", m.time_in_contact_s},
      {"critical_contact_s", "Time touching critical segments", "s", m.critical_contact_s},
      {"critical_touches", "Touches of critical segments", "", count(m.critical_touches)},
      {"drill_on_s", "Time with the burr spinning", "s", m.drill_on_s},
      {"cavity_at_start_mm3", "Cavity when the recording began", "mm^3", m.cavity_at_start_mm3},
      {"removed_mm3", "Volume drilled away during the recording", "mm^3", m.removed_mm3},
      {"cavity_mm3", "Cavity when the recording ended", "mm^3", m.cavity_mm3},
      {"critical_removed_voxels", "Critical voxels drilled away", "", count(m.critical_removed_voxels)},
      {"critical_removed_mm3", "Critical volume drilled away", "mm^3", m.critical_removed_mm3},
      {"markers", "Markers", "", count(m.markers)},
      {"technique_force_events", "Technique: pushed too hard for too long", "", count(m.technique_events[0])},
      {"technique_speed_events", "Technique: too fast near a critical segment", "", count(m.technique_events[1])},
      {"technique_shaft_events", "Technique: burr spinning with the shaft on bone", "", count(m.technique_events[2])},
      {"deadline_misses", "Servo deadline misses", "", count(m.deadline_misses)},
      {"deadline_cuts", "Ticks the solver's deadline cut short", "", count(m.deadline_cuts)},
      {"mean_tick_s", "Mean solver tick time", "s", m.mean_tick_s},
      {"max_tick_s", "Longest solver tick", "s", m.max_tick_s},
      {"bad_samples", "Ticks without a device sample", "", count(m.bad_samples)},
      {"force_limited_ticks", "Ticks the safety layer limited", "", count(m.force_limited_ticks)},
      {"non_finite_ticks", "Ticks with a non-finite result", "", count(m.non_finite_ticks)},
      {"dropped_records", "Records dropped by the writer", "", count(m.dropped_records)},
  };
}

DeviceSpeedSeries deviceSpeedSeries(const Recording& recording, double servo_rate_Hz, double derivative_step_s,
                                    std::size_t stride) {
  DeviceSpeedSeries out;
  const std::vector<TickRecord>& r = recording.records;
  if (!(servo_rate_Hz > 0.0) || !std::isfinite(servo_rate_Hz) || !(derivative_step_s > 0.0)) return out;
  const std::size_t k =
      std::max<std::size_t>(1, static_cast<std::size_t>(std::lround(derivative_step_s * servo_rate_Hz)));
  stride = std::max<std::size_t>(1, stride);
  // placed[i] = placements among records 0..i-1: (a, b] holds one iff placed[b + 1] > placed[a + 1].
  std::vector<std::size_t> placed(r.size() + 1, 0);
  for (std::size_t i = 0; i < r.size(); ++i) {
    const bool jump = (r[i].flags & kRecordFlagPlacement) != 0;
    placed[i + 1] = placed[i] + (jump ? 1 : 0);
    if (jump) out.placements_s.push_back(r[i].time_s);
  }
  out.pieces.emplace_back();
  for (std::size_t i = k; i + k < r.size(); i += stride) {
    if (placed[i + k + 1] > placed[i - k + 1]) {
      if (!out.pieces.back().empty()) out.pieces.emplace_back();
      continue;
    }
    const double v = (devicePosition(r[i + k]) - devicePosition(r[i - k])).norm() / (r[i + k].time_s - r[i - k].time_s);
    if (!std::isfinite(v)) continue;
    out.max_m_per_s = std::max(out.max_m_per_s, v);
    out.pieces.back().emplace_back(r[i].time_s, v);
  }
  if (out.pieces.back().empty()) out.pieces.pop_back();
  return out;
}

std::vector<Eigen::Vector3d> devicePathSamples(const Recording& recording, std::size_t count) {
  const std::size_t n = recording.records.size();
  std::vector<Eigen::Vector3d> out;
  if (n == 0 || count == 0) return out;
  if (n <= count || count == 1) {
    const std::size_t step = count == 1 ? n : 1;
    for (std::size_t i = 0; i < n; i += step) out.push_back(devicePosition(recording.records[i]));
    return out;
  }
  out.reserve(count);
  for (std::size_t j = 0; j < count; ++j)
    out.push_back(devicePosition(recording.records[evenlySpacedIndex(j, n, count)]));
  return out;
}

DtwAlignment dynamicTimeWarping(const std::vector<Eigen::Vector3d>& a, const std::vector<Eigen::Vector3d>& b) {
  if (a.empty() || b.empty()) throw std::invalid_argument("dynamic time warping needs two non-empty paths");
  const std::size_t n = a.size(), m = b.size();
  constexpr double kInf = std::numeric_limits<double>::infinity();
  std::vector<double> D(n * m, kInf);
  const auto at = [&](std::size_t i, std::size_t j) -> double& { return D[i * m + j]; };
  for (std::size_t i = 0; i < n; ++i) {
    for (std::size_t j = 0; j < m; ++j) {
      const double d = (a[i] - b[j]).norm();
      double best = 0.0;
      if (i > 0 || j > 0) {
        best = kInf;
        if (i > 0) best = std::min(best, at(i - 1, j));
        if (j > 0) best = std::min(best, at(i, j - 1));
        if (i > 0 && j > 0) best = std::min(best, at(i - 1, j - 1));
      }
      at(i, j) = d + best;
    }
  }
  DtwAlignment result;
  result.total_distance_m = at(n - 1, m - 1);
  // Back from (n-1, m-1), preferring the diagonal on ties.
  std::size_t i = n - 1, j = m - 1;
  result.path.emplace_back(i, j);
  while (i > 0 || j > 0) {
    if (i == 0) --j;
    else if (j == 0) --i;
    else {
      const double diag = at(i - 1, j - 1), up = at(i - 1, j), left = at(i, j - 1);
      if (diag <= up && diag <= left) --i, --j;
      else if (up <= left) --i;
      else --j;
    }
    result.path.emplace_back(i, j);
  }
  std::reverse(result.path.begin(), result.path.end());
  result.mean_distance_m = result.total_distance_m / static_cast<double>(result.path.size());
  return result;
}

SceneIdentity sceneIdentity(const std::string& metadata_json) {
  Recording r;
  r.metadata_json = metadata_json;
  SessionMetrics m;
  readIdentity(r, m);
  return {m.scene, m.dataset_sha256};
}

void requireSameScene(const SceneIdentity& session, const SceneIdentity& other, const std::string& role,
                      const std::string& purpose) {
  const auto identity = [](const SceneIdentity& m) {
    return m.dataset_sha256.empty() ? "volume " + (m.scene.empty() ? std::string("(unnamed)") : m.scene)
                                    : "dataset " + m.dataset_sha256.substr(0, 12);
  };
  const bool same = !session.dataset_sha256.empty() || !other.dataset_sha256.empty()
                        ? session.dataset_sha256 == other.dataset_sha256
                        : session.scene == other.scene;
  if (!same)
    throw std::invalid_argument(role + " was recorded on another scene (" + identity(other) + ", this session " +
                                identity(session) + "): " + purpose);
}

ReferenceComparison compareWithReference(const Recording& session, const SessionMetrics& session_metrics,
                                         const Recording& reference, const SessionMetrics& reference_metrics,
                                         std::size_t path_samples) {
  requireSameScene({session_metrics.scene, session_metrics.dataset_sha256},
                   {reference_metrics.scene, reference_metrics.dataset_sha256});
  if (session.records.empty() || reference.records.empty())
    throw std::invalid_argument("a comparison needs ticks in both recordings");
  ReferenceComparison c;
  c.session = metricValues(session_metrics);
  c.reference = metricValues(reference_metrics);
  c.path_samples = path_samples;
  c.session_path = devicePathSamples(session, path_samples);
  c.reference_path = devicePathSamples(reference, path_samples);
  c.alignment = dynamicTimeWarping(c.session_path, c.reference_path);
  return c;
}

std::vector<std::filesystem::path> findRecordings(const std::filesystem::path& dir) {
  std::error_code ec;
  if (!std::filesystem::is_directory(dir, ec)) throw std::runtime_error(dir.string() + ": not a folder");
  std::vector<std::filesystem::path> out;
  std::filesystem::recursive_directory_iterator it(dir, std::filesystem::directory_options::skip_permission_denied, ec);
  if (ec) throw std::runtime_error(dir.string() + ": cannot be listed (" + ec.message() + ")");
  for (; it != std::filesystem::recursive_directory_iterator(); it.increment(ec)) {
    if (ec) throw std::runtime_error(dir.string() + ": cannot be listed (" + ec.message() + ")");
    if (it->is_regular_file(ec) && it->path().extension() == ".vhrec") out.push_back(it->path());
  }
  std::sort(out.begin(), out.end());
  return out;
}

}  // namespace vh::runtime
