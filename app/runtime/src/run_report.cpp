// The headless run's report as JSON and as one line (runner.h: RunReport::toJson(), summary(),
// writeRunReport()); apart from the runner so that the run and its report each have a file.
#include "vh/runtime/runner.h"

#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "vh/io/private_files.h"

namespace vh::runtime {

namespace {
/// The report's "proximity": per critical segment, the time within its warning and alarm
/// distances and the closest approach (null when never within kProximityRange_m).
nlohmann::ordered_json proximityJson(const std::vector<SegmentProximityStats>& proximity) {
  const auto finite = [](double v) { return std::isfinite(v) ? nlohmann::ordered_json(v) : nlohmann::ordered_json(nullptr); };
  nlohmann::ordered_json out = nlohmann::ordered_json::array();
  for (const SegmentProximityStats& p : proximity) {
    out.push_back({{"name", p.name},
                   {"warn_mm", 1e3 * p.thresholds.warn_m},
                   {"alarm_mm", 1e3 * p.thresholds.alarm_m},
                   {"time_within_warn_s", p.time_within_warn_s},
                   {"time_within_alarm_s", p.time_within_alarm_s},
                   {"warnings", p.warnings},
                   {"alarms", p.alarms},
                   {"closest_mm", finite(1e3 * p.closest_m)},
                   {"closest_time_s", finite(p.closest_time_s)}});
  }
  return out;
}

/// The report's "segments": time in contact, peak force and touches per labelled segment.
nlohmann::ordered_json segmentContactsJson(const std::vector<SegmentContact>& segment_contacts) {
  nlohmann::ordered_json segments = nlohmann::ordered_json::array();
  for (const SegmentContact& c : segment_contacts) {
    segments.push_back({{"name", c.name},
                        {"critical", c.critical},
                        {"time_in_contact_s", c.time_in_contact_s},
                        {"peak_force_N", c.peak_force_N},
                        {"touches", c.touches}});
  }
  return segments;
}

/// A drilling run's removal into the report: the volumes removed and eroded, the burr, the carved
/// field's hash and what was removed of each material.
void addDrillJson(nlohmann::ordered_json& j, const DrillReport& drill) {
  j["removed_mm3"] = drill.removed_mm3;
  j["eroded_mm3"] = drill.eroded_mm3;
  j["burr_radius_m"] = drill.burr_radius_m;
  j["drilled_field_sha256"] = drill.drilled_field_sha256;
  j["removed"] = nlohmann::ordered_json::array();
  for (const auto& m : drill.materials)
    j["removed"].push_back({{"material", m.name},
                            {"segment", m.segment.empty() ? nlohmann::ordered_json(nullptr) : nlohmann::ordered_json(m.segment)},
                            {"critical", m.critical},
                            {"voxels", m.voxels},
                            {"removed_mm3", m.removed_mm3},
                            {"voxels_below_surface", m.voxels_below_surface},
                            {"below_surface_mm3", m.below_surface_mm3},
                            {"specific_energy_J_per_mm3", m.specific_energy_J_per_mm3}});
}
}  // namespace

std::string RunReport::toJson() const {
  nlohmann::ordered_json j;
  j["scene"] = scene;
  j["trajectory"] = trajectory;
  j["volume"] = volume;
  j["volume_notices"] = volume_notices;
  j["volume_dims"] = volume_dims;
  j["volume_spacing_m"] = {volume_spacing_m.x(), volume_spacing_m.y(), volume_spacing_m.z()};
  j["isovalue"] = isovalue;
  j["tool"] = tool;
  j["point_count"] = point_count;
  j["point_spacing_m"] = point_spacing_m;
  if (tool_fit) j["tool_fit"] = nlohmann::ordered_json::parse(tool_fit->toJson());
  j["epsilon_m"] = epsilon_m;
  j["feature_size_m"] = feature_size_m;
  j["servo_rate_Hz"] = servo_rate_Hz;
  j["trajectory_duration_s"] = trajectory_duration_s;
  j["ticks"] = ticks;
  j["mean_us"] = mean_us;
  j["p50_us"] = p50_us;
  j["p99_us"] = p99_us;
  j["max_us"] = max_us;
  j["ticks_over_1ms"] = ticks_over_1ms;
  j["total_s"] = total_s;
  j["max_contacts"] = max_contacts;
  j["mean_contacts"] = mean_contacts;
  j["ticks_in_contact"] = ticks_in_contact;
  j["first_contact_tick"] = first_contact_tick;
  j["max_force_N"] = max_force_N;
  j["max_torque_Nm"] = max_torque_Nm;
  j["mean_volume_samples"] = mean_volume_samples;
  j["max_penetration_m"] = max_penetration_m;
  j["max_penetration_tick"] = max_penetration_tick;
  j["ticks_penetrating"] = ticks_penetrating;
  j["nan_ticks"] = nan_ticks;
  // Not checked: null (never a 0 that reads as "no crossing").
  const auto checked = [this](std::int64_t v) { return crossingsChecked() ? nlohmann::ordered_json(v) : nlohmann::ordered_json(nullptr); };
  j["verify_step_voxels"] = verify_step_voxels;
  j["crossings"] = checked(crossings);
  j["crossing_points"] = checked(crossing_points);
  j["first_crossing_tick"] = checked(first_crossing_tick);
  j["edge_crossings"] = checked(edge_crossings);
  j["first_edge_crossing_tick"] = checked(first_edge_crossing_tick);
  j["verify_s"] = verify_s;
  j["bad_device_samples"] = bad_device_samples;
  j["implausible_samples"] = implausible_samples;
  j["held_ticks"] = held_ticks;
  j["max_command_force_N"] = max_command_force_N;
  j["initial_points_inside"] = initial_points_inside;
  j["final_force_N"] = final_force_N;
  j["final_proxy_device_distance_m"] = final_proxy_device_distance_m;
  j["max_proxy_device_distance_m"] = max_proxy_device_distance_m;
  j["jams"] = jams;
  j["jam_ticks"] = jam_ticks;
  j["first_jam_tick"] = first_jam_tick;
  j["work_budget"] = work_budget;
  j["budget_cuts"] = budget_cuts;
  j["max_work"] = max_work;
  // Not measured: null.
  j["lag_ticks"] = lag_ticks >= 0 ? nlohmann::ordered_json(lag_ticks) : nlohmann::ordered_json(nullptr);
  j["max_lag_m"] = max_lag_m >= 0.0 ? nlohmann::ordered_json(max_lag_m) : nlohmann::ordered_json(nullptr);
  j["max_lag_rad"] = max_lag_rad >= 0.0 ? nlohmann::ordered_json(max_lag_rad) : nlohmann::ordered_json(nullptr);
  j["max_behind_m"] = lag_ticks >= 0 ? nlohmann::ordered_json(max_behind_m) : nlohmann::ordered_json(nullptr);
  j["max_behind_rad"] = lag_ticks >= 0 ? nlohmann::ordered_json(max_behind_rad) : nlohmann::ordered_json(nullptr);
  j["segments"] = segmentContactsJson(segment_contacts);
  j["proximity"] = proximityJson(proximity);
  if (drill) addDrillJson(j, *drill);
  if (tissue) {
    nlohmann::ordered_json t;
    t["max_indentation_m"] = tissue->max_indentation_m;
    t["max_push_N"] = tissue->max_push_N;
    t["force_by_indentation"] = nlohmann::ordered_json::array();
    for (const auto& [indentation_m, force_N] : tissue->force_by_indentation)
      t["force_by_indentation"].push_back({{"indentation_m", indentation_m}, {"max_force_N", force_N}});
    t["mean_step_us"] = tissue->mean_step_us;
    t["max_step_us"] = tissue->max_step_us;
    j["tissue"] = t;
  }
  nlohmann::ordered_json technique;
  for (int k = 0; k < kTechniqueRuleCount; ++k)
    technique[std::string(techniqueRuleName(k))] = technique_episodes[static_cast<std::size_t>(k)];
  j["technique_episodes"] = technique;
  if (guidance) j["guidance"] = nlohmann::ordered_json::parse(guidance->toJson());
  return j.dump(2) + "\n";
}

std::string RunReport::summary() const {
  char line[640];
  std::snprintf(line, sizeof line,
                "ticks %llu, exec mean %.0f us, p50 %.0f us, p99 %.0f us, max %.0f us; %zu points; contacts <= %d "
                "(mean %.1f); max force %.2f N; penetration %.4f mm (epsilon %.4f mm); nan ticks %llu; bad samples %llu; ",
                static_cast<unsigned long long>(ticks), mean_us, p50_us, p99_us, max_us, point_count, max_contacts,
                mean_contacts, max_force_N, max_penetration_m * 1e3, epsilon_m * 1e3,
                static_cast<unsigned long long>(nan_ticks), static_cast<unsigned long long>(bad_device_samples));
  std::string out = line;
  if (!crossingsChecked()) {
    out += "crossings not checked (verify step 0)";
  } else if (crossings == 0) {
    std::snprintf(line, sizeof line, "crossings 0 (checked at %g voxel)", verify_step_voxels);
    out += line;
  } else {
    std::snprintf(line, sizeof line, "crossings %lld (%lld point%s, first at tick %lld; checked at %g voxel)",
                  static_cast<long long>(crossings), static_cast<long long>(crossing_points),
                  crossing_points == 1 ? "" : "s", static_cast<long long>(first_crossing_tick), verify_step_voxels);
    out += line;
  }
  if (crossingsChecked()) {
    if (edge_crossings == 0) {
      out += ", edges 0";
    } else {
      std::snprintf(line, sizeof line, ", edges %lld (first at tick %lld)", static_cast<long long>(edge_crossings),
                    static_cast<long long>(first_edge_crossing_tick));
      out += line;
    }
  }
  if (work_budget > 0) {
    std::snprintf(line, sizeof line, "; work budget %lld: %llu ticks cut, max work %lld",
                  static_cast<long long>(work_budget), static_cast<unsigned long long>(budget_cuts),
                  static_cast<long long>(max_work));
    out += line;
    if (lag_ticks >= 0) {
      std::snprintf(line, sizeof line,
                    ", lag behind the unbudgeted proxy %.3f mm, %.4f rad (%lld ticks), behind %.3f mm, %.4f rad",
                    max_lag_m * 1e3, max_lag_rad, static_cast<long long>(lag_ticks), max_behind_m * 1e3,
                    max_behind_rad);
      out += line;
    }
  }
  if (jams == 0) {
    out += "; jams 0";
  } else {
    std::snprintf(line, sizeof line, "; jams %llu (%llu ticks, first at tick %lld)", static_cast<unsigned long long>(jams),
                  static_cast<unsigned long long>(jam_ticks), static_cast<long long>(first_jam_tick));
    out += line;
  }
  std::snprintf(line, sizeof line, "; technique: force %llu, speed %llu, shaft %llu",
                static_cast<unsigned long long>(technique_episodes[0]),
                static_cast<unsigned long long>(technique_episodes[1]),
                static_cast<unsigned long long>(technique_episodes[2]));
  out += line;
  if (drill) {
    std::snprintf(line, sizeof line, "; drilled %.2f mm^3", drill->removed_mm3);
    out += line;
    bool first = true;
    for (const auto& m : drill->materials) {
      if (m.voxels == 0) continue;
      std::snprintf(line, sizeof line, "%s%s %.2f mm^3%s", first ? " (" : ", ", m.name.c_str(), m.removed_mm3,
                    m.critical ? " CRITICAL" : "");
      first = false;
      out += line;
      if (m.voxels_below_surface > 0) {
        std::snprintf(line, sizeof line, " [%.2f of it below the felt surface]", m.below_surface_mm3);
        out += line;
      }
    }
    if (!first) out += ")";
  }
  if (guidance) out += "; " + guidance->summary();
  for (const SegmentContact& c : segment_contacts) {
    if (c.ticks == 0) continue;
    std::snprintf(line, sizeof line, "; touched %s%s: %.3f s, peak %.2f N, %llu touch%s", c.name.c_str(),
                  c.critical ? " (CRITICAL)" : "", c.time_in_contact_s, c.peak_force_N,
                  static_cast<unsigned long long>(c.touches), c.touches == 1 ? "" : "es");
    out += line;
  }
  out += proximitySummary(proximity);
  return out;
}

void writeRunReport(const RunReport& report, const std::filesystem::path& path) {
  io::PrivateOutput file(path);  // 0600, renamed into place only when whole
  file.stream() << report.toJson();
  file.commit();
}

}  // namespace vh::runtime
