#include "vh/ui/export/report_format.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <map>
#include <string>

#include <nlohmann/json.hpp>

#include "vh/runtime/technique.h"

namespace vh::ui {
namespace {

/// `text` of a fixed-point number without the zeros after its decimal point ("4.50" -> "4.5",
/// "4.00" -> "4"), and "-0" as "0".
std::string trimZeros(std::string text) {
  if (text.find('.') != std::string::npos) {
    while (!text.empty() && text.back() == '0') text.pop_back();
    if (!text.empty() && text.back() == '.') text.pop_back();
  }
  if (text == "-0") text = "0";
  return text;
}

std::string fixed(double v, int decimals) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*f", std::max(0, decimals), v);
  return buf;
}

/// The integer `e` in superscript digits ("⁻⁶", "¹²").
std::string superscript(int e) {
  static const char* kDigit[] = {"⁰", "¹", "²", "³", "⁴", "⁵", "⁶", "⁷", "⁸", "⁹"};
  std::string out = e < 0 ? "⁻" : "";
  const std::string digits = std::to_string(std::abs(e));
  for (char c : digits) out += kDigit[c - '0'];
  return out;
}

/// Decimal places that give |v| `significant` significant digits (none for large values).
int decimalsFor(double v, int significant) {
  if (v == 0.0 || !std::isfinite(v)) return 0;
  const int magnitude = static_cast<int>(std::floor(std::log10(std::fabs(v))));
  return std::max(0, significant - 1 - magnitude);
}

std::string withUnit(const std::string& number, const std::string& unit) {
  return unit.empty() ? number : number + " " + unit;
}

/// The unit as printed: "N*m" -> "N·m", "^k" -> superscript k.
std::string unitText(std::string_view unit) {
  std::string out;
  for (std::size_t i = 0; i < unit.size(); ++i) {
    if (unit[i] == '*') {
      out += "·";
    } else if (unit[i] == '^' && i + 1 < unit.size() && (std::isdigit(static_cast<unsigned char>(unit[i + 1])) != 0)) {
      int e = 0;
      while (i + 1 < unit.size() && (std::isdigit(static_cast<unsigned char>(unit[i + 1])) != 0))
        e = 10 * e + (unit[++i] - '0');
      out += superscript(e);
    } else {
      out += unit[i];
    }
  }
  return out;
}

/// |v| rounded to `significant` significant digits (so that 0.00099999 counts as 0.001 when a
/// unit is picked for it).
double roundedMagnitude(double v, int significant) {
  const double a = std::fabs(v);
  if (a == 0.0 || !std::isfinite(a)) return a;
  const double scale = std::pow(10.0, significant - 1 - static_cast<int>(std::floor(std::log10(a))));
  return std::round(a * scale) / scale;
}

std::string durationText(double v, int significant) {
  const double a = roundedMagnitude(v, significant);
  if (a == 0.0) return "0 s";
  if (a < 1e-3) return formatNumber(v * 1e6, significant) + " µs";
  if (a < 1.0) return formatNumber(v * 1e3, significant) + " ms";
  if (a < 120.0) return formatNumber(v, significant) + " s";
  const long long total = std::llround(a);
  const std::string sign = v < 0 ? "-" : "";
  char buf[64];
  if (total < 3600) std::snprintf(buf, sizeof buf, "%lld min %02lld s", total / 60, total % 60);
  else std::snprintf(buf, sizeof buf, "%lld h %02lld min", total / 3600, (total % 3600 + 30) / 60 % 60);
  return sign + buf;
}

// ---- events in words ------------------------------------------------------------------------------

using Json = nlohmann::json;

std::string quoted(const std::string& s) { return "“" + s + "”"; }

std::string stringField(const Json& d, const char* key) {
  return d.is_object() && d.contains(key) && d[key].is_string() ? d[key].get<std::string>() : std::string();
}

bool numberField(const Json& d, const char* key, double& out) {
  if (!d.is_object() || !d.contains(key) || !d[key].is_number()) return false;
  out = d[key].get<double>();
  return true;
}

/// A segment name from a "segment" event's "from"/"to" (null: none).
std::string segmentName(const Json& d, const char* key) {
  if (!d.is_object() || !d.contains(key) || d[key].is_null()) return {};
  return d[key].is_string() ? d[key].get<std::string>() : d[key].dump();
}

/// "critical_removed" -> "Critical removed".
std::string typeWords(const std::string& type) {
  std::string out = type;
  std::replace(out.begin(), out.end(), '_', ' ');
  if (!out.empty()) out[0] = static_cast<char>(std::toupper(static_cast<unsigned char>(out[0])));
  return out;
}

/// A field as "name value": a key ending in a unit (_m, _s, _N, _Nm, _mm3) gives its value in
/// that unit and loses the suffix ("distance_m": 0.012 -> "distance 12 mm").
std::string fieldText(std::string key, const Json& v) {
  std::string value;
  if (v.is_string()) value = v.get<std::string>();
  else if (v.is_boolean()) value = v.get<bool>() ? "yes" : "no";
  else if (!v.is_number()) value = v.dump();
  else {
    const double x = v.get<double>();
    value = formatNumber(x);
    static const std::pair<std::string_view, std::string_view> kSuffix[] = {
        {"_mm3", "mm^3"}, {"_Nm", "N*m"}, {"_m", "m"}, {"_s", "s"}, {"_N", "N"}};
    for (const auto& [suffix, unit] : kSuffix) {
      if (key.size() > suffix.size() && key.compare(key.size() - suffix.size(), suffix.size(), suffix) == 0) {
        value = formatQuantity(x, unit);
        key.resize(key.size() - suffix.size());
        break;
      }
    }
  }
  std::replace(key.begin(), key.end(), '_', ' ');
  return key + " " + value;
}

std::string genericText(const std::string& type, const Json& d) {
  std::string out = typeWords(type);
  if (!d.is_object() || d.empty()) return out;
  std::string fields;
  for (const auto& [key, value] : d.items()) {
    if (value.is_object() || value.is_array()) continue;
    if (!fields.empty()) fields += ", ";
    fields += fieldText(key, value);
  }
  return fields.empty() ? out : out + ": " + fields;
}

std::string isoText(double v, const std::string& unit) {
  return withUnit(formatNumber(v, 4), unit);
}

/// One event in words.
std::string eventText(const runtime::RecordingEvent& e, const Json& d, const std::string& value_unit) {
  double a = 0.0, b = 0.0;
  if (e.type == "marker") {
    const std::string label = stringField(d, "label");
    return label.empty() ? "Marker" : "Marker " + quoted(label);
  }
  if (e.type == "isovalue" && numberField(d, "from", a) && numberField(d, "to", b))
    return "Isovalue " + formatNumber(a, 4) + " → " + isoText(b, value_unit);
  if (e.type == "segment") {
    const std::string from = segmentName(d, "from"), to = segmentName(d, "to");
    if (to.empty()) return from.empty() ? "No segment touched" : "Left segment " + quoted(from);
    return from.empty() ? "Touched segment " + quoted(to) : "From segment " + quoted(from) + " to " + quoted(to);
  }
  if (e.type == "critical_contact") return "Critical segment " + quoted(stringField(d, "segment")) + " touched";
  if (e.type == "critical_removed") {
    std::string out = "Critical segment " + quoted(stringField(d, "segment")) + " drilled";
    if (numberField(d, "mm3", a)) out += ": " + formatQuantity(a, "mm^3");
    return out;
  }
  if (e.type == "tool") {
    std::string out = "Tool " + quoted(stringField(d, "tool"));
    if (numberField(d, "point_spacing_m", a)) out += " (points " + formatQuantity(a, "m") + " apart)";
    return out;
  }
  if (e.type == "gains" && numberField(d, "linear_N_per_m", a) && numberField(d, "angular_Nm_per_rad", b))
    return "Coupling stiffness " + formatNumber(a) + " N/m, " + formatNumber(b) + " N·m/rad";
  if (e.type == "hardness") {
    std::string out = "Material " + quoted(stringField(d, "material"));
    if (numberField(d, "J_per_mm3", a)) out += ", " + formatNumber(a) + " J/mm³ to remove";
    return out;
  }
  if (e.type.rfind("proximity_", 0) == 0) {
    const std::string where = quoted(stringField(d, "segment"));
    const std::string at = numberField(d, "distance_mm", a) ? ": " + formatNumber(a, 3) + " mm" : std::string();
    if (e.type == "proximity_warn") return "Within the warning distance of " + where + at;
    if (e.type == "proximity_alarm") return "Within the alarm distance of " + where + at;
    if (e.type == "proximity_alarm_cleared") return "Out of the alarm distance of " + where + at;
    if (e.type == "proximity_warn_cleared") return "Clear of " + where + at;
  }
  if (e.type == "technique") {
    const std::string rule = stringField(d, "rule");
    for (int k = 0; k < runtime::kTechniqueRuleCount; ++k)
      if (rule == runtime::techniqueRuleName(k)) return "Technique: " + std::string(runtime::techniqueRuleAdvice(k));
  }
  if (e.type == "device_connected") return "Device connected";
  if (e.type == "device_disconnected") return "Device disconnected";
  return genericText(e.type, d);
}

bool criticalType(const std::string& type) {
  return type == "marker" || type == "critical_contact" || type == "critical_removed" || type == "technique" ||
         type == "proximity_alarm";
}

/// The summary row's text of `n` events of one kind (`first`, `last` their first and last).
std::string summaryText(const std::string& type, const std::vector<const runtime::RecordingEvent*>& run,
                        const std::string& value_unit) {
  const std::string times = " " + std::to_string(run.size()) + " times";
  const Json first = Json::parse(run.front()->detail_json, nullptr, false);
  const Json last = Json::parse(run.back()->detail_json, nullptr, false);
  double a = 0.0, b = 0.0;
  if (type == "isovalue" && numberField(first, "from", a) && numberField(last, "to", b))
    return "Isovalue changed" + times + ", " + formatNumber(a, 4) + " → " + isoText(b, value_unit);
  // The names met, in order of their first appearance (at most 6).
  const auto names = [&](auto name_of) {
    std::vector<std::string> seen;
    for (const auto* e : run) {
      const std::string n = name_of(Json::parse(e->detail_json, nullptr, false));
      if (!n.empty() && std::find(seen.begin(), seen.end(), n) == seen.end()) seen.push_back(n);
    }
    std::string out;
    for (std::size_t i = 0; i < seen.size() && i < 6; ++i) out += (i > 0 ? ", " : "") + seen[i];
    if (seen.size() > 6) out += ", …";
    return out;
  };
  if (type == "segment") {
    const std::string touched = names([](const Json& d) { return segmentName(d, "to"); });
    return "Touched segment changed" + times + (touched.empty() ? "" : " (" + touched + ")");
  }
  if (type == "critical_contact")
    return "Critical segments touched" + times + " (" + names([](const Json& d) { return stringField(d, "segment"); }) + ")";
  if (type == "critical_removed") {
    double mm3 = 0.0;
    for (const auto* e : run) {
      double v = 0.0;
      if (numberField(Json::parse(e->detail_json, nullptr, false), "mm3", v)) mm3 += v;
    }
    return "Critical segments drilled" + times + " (" + names([](const Json& d) { return stringField(d, "segment"); }) +
           "), " + formatQuantity(mm3, "mm^3") + " in all";
  }
  if (type == "device_disconnected") return "Device disconnected" + times;
  if (type == "device_connected") return "Device connected" + times;
  return typeWords(type) + times + "; the last: " + eventText(*run.back(), last, value_unit);
}

}  // namespace

std::string formatNumber(double v, int significant) {
  if (!std::isfinite(v)) return "n/a";
  significant = std::clamp(significant, 1, 15);
  if (v == 0.0) return "0";
  const double a = std::fabs(v);
  if (a >= 1e6 || a < 1e-3) {
    int e = static_cast<int>(std::floor(std::log10(a)));
    std::string mantissa = fixed(v / std::pow(10.0, e), significant - 1);
    if (std::fabs(std::stod(mantissa)) >= 10.0) {  // 9.996 rounded up to 10.0
      ++e;
      mantissa = fixed(v / std::pow(10.0, e), significant - 1);
    }
    return trimZeros(mantissa) + " × 10" + superscript(e);
  }
  if (v == std::floor(v)) return trimZeros(fixed(v, 0));
  return trimZeros(fixed(v, decimalsFor(v, significant)));
}

std::string formatQuantity(double v, std::string_view unit, int significant) {
  if (!std::isfinite(v)) return "n/a";
  significant = std::clamp(significant, 1, 15);
  const double a = roundedMagnitude(v, significant);
  if (unit == "s") return durationText(v, significant);
  if (unit == "m") {
    if (a == 0.0) return "0 mm";
    if (a < 1e-4) return formatNumber(v * 1e6, significant) + " µm";
    if (a < 1.0) return formatNumber(v * 1e3, significant) + " mm";
  }
  if (unit == "m/s" && a < 0.1) return formatNumber(v * 1e3, significant) + " mm/s";
  return withUnit(formatNumber(v, significant), unitText(unit));
}

std::string formatRange(double lo, double hi, std::string_view unit, int significant) {
  if (!std::isfinite(lo) || !std::isfinite(hi)) return withUnit("n/a", unitText(unit));
  const double top = std::max(std::fabs(lo), std::fabs(hi));
  std::string a, b;
  if (top >= 1e6 || (top < 1e-3 && top > 0.0)) {
    a = formatNumber(lo, significant), b = formatNumber(hi, significant);
  } else {
    const int decimals = decimalsFor(top, significant);
    a = fixed(lo, decimals), b = fixed(hi, decimals);
    if (a == "-0") a = "0";
  }
  return withUnit(a + "–" + b, unitText(unit));
}

std::string formatClock(double t_s) {
  if (!std::isfinite(t_s) || t_s < 0.0) return "n/a";
  const long long tenths = std::llround(t_s * 10.0);
  const long long s = tenths / 10, h = s / 3600, m = s / 60 % 60;
  char buf[64];
  if (h > 0) std::snprintf(buf, sizeof buf, "%lld:%02lld:%02lld.%lld", h, m, s % 60, tenths % 10);
  else std::snprintf(buf, sizeof buf, "%lld:%02lld.%lld", m, s % 60, tenths % 10);
  return buf;
}

std::vector<EventRow> summariseEvents(const std::vector<runtime::RecordingEvent>& events,
                                      const std::string& value_unit, std::size_t max_listed) {
  std::map<std::string, std::vector<const runtime::RecordingEvent*>> by_type;
  for (const auto& e : events) by_type[e.type].push_back(&e);
  std::vector<EventRow> rows;
  for (const auto& [type, run] : by_type) {
    if (type == "marker" || run.size() <= max_listed) {
      for (const auto* e : run) {
        EventRow row;
        row.first_s = row.last_s = e->time_s;
        row.type = type;
        row.text = eventText(*e, Json::parse(e->detail_json, nullptr, false), value_unit);
        row.critical = criticalType(type);
        rows.push_back(std::move(row));
      }
    } else {
      EventRow row;
      row.first_s = run.front()->time_s;
      row.last_s = run.back()->time_s;
      for (const auto* e : run) row.first_s = std::min(row.first_s, e->time_s), row.last_s = std::max(row.last_s, e->time_s);
      row.count = run.size();
      row.type = type;
      row.text = summaryText(type, run, value_unit);
      row.critical = criticalType(type);
      rows.push_back(std::move(row));
    }
  }
  std::stable_sort(rows.begin(), rows.end(), [](const EventRow& x, const EventRow& y) { return x.first_s < y.first_s; });
  return rows;
}

std::string escapeHtml(const std::string& s) {
  std::string out;
  out.reserve(s.size());
  for (char c : s) {
    switch (c) {
      case '&': out += "&amp;"; break;
      case '<': out += "&lt;"; break;
      case '>': out += "&gt;"; break;
      case '"': out += "&quot;"; break;
      default: out += c;
    }
  }
  return out;
}

}  // namespace vh::ui
