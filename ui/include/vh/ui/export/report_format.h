#pragma once
/// @file
/// Numbers for people, as the session report prints them: a few significant digits, no
/// exponent a reader must decode ("6.39 µs", not "6.392e-06 s"), times and lengths in the unit
/// that keeps them readable, ranges with an en dash ("98–130 N", not "98-1.3e+02"), and the
/// recording's events in words. All text is UTF-8 (µ, ×, superscript digits, ², ³, ·, –, →).

#include <string>
#include <string_view>
#include <vector>

#include "vh/runtime/recording.h"

namespace vh::ui {

/// `s` safe inside HTML text and attribute values: & < > " written as entities.
std::string escapeHtml(const std::string& s);

/// `v` with `significant` significant digits (1 .. 15; 3 by default), trailing zeros after the
/// decimal point dropped: 130.3 -> "130", 98.44 -> "98.4", 0.012345 -> "0.0123", 4.0 -> "4".
/// Integers below 10^6 are printed whole (12345 -> "12345"); magnitudes of 10^6 and more, or
/// below 10^-3 (but not 0), in powers of ten: 6.263e12 -> "6.26 × 10¹²", 6.4e-6 -> "6.4 × 10⁻⁶".
/// Non-finite values: "n/a". -0 is "0".
std::string formatNumber(double v, int significant = 3);

/// `v` in `unit` with the unit, rescaled where a smaller unit reads better:
///  - "s": below 1 ms in µs, below 1 s in ms, from 2 min on as "1 min 32 s" / "1 h 05 min";
///  - "m": below 1 m in mm (below 0.1 mm in µm); "m/s": below 0.1 m/s in mm/s;
///  - "N*m" is written "N·m", "mm^3" "mm³", "m^2/s^5" "m²/s⁵" (a ^k after a unit becomes a
///    superscript); an empty unit gives the bare number.
/// The unit is picked for the value as rounded (0.00099999 s is "1 ms").
/// Examples: (6.392e-6, "s") -> "6.39 µs", (0.25, "m") -> "250 mm", (92.0, "s") -> "92 s".
std::string formatQuantity(double v, std::string_view unit, int significant = 3);

/// The closed range [lo, hi] in `unit` with one unit and an en dash, both ends to the same
/// decimal place, chosen so that `hi` has `significant` significant digits:
/// (97.7, 130.3, "N") -> "98–130 N", (0.5, 1.25, "N") -> "0.50–1.25 N". Units as
/// formatQuantity() writes them, without rescaling (both ends keep one unit).
std::string formatRange(double lo, double hi, std::string_view unit, int significant = 3);

/// A time on the recording's clock as minutes, seconds and tenths: 12.34 -> "0:12.3", 92.0 ->
/// "1:32.0", 3725 -> "1:02:05.0". Negative or non-finite: "n/a".
std::string formatClock(double t_s);

/// One row of the report's events table: one event in words, or a run of one repeated kind
/// summarised.
struct EventRow {
  double first_s = 0.0;      ///< Time of the (first) event [s], the recording's clock.
  double last_s = 0.0;       ///< Time of the last event of a summarised run [s] (== first_s for one).
  std::size_t count = 1;     ///< Events this row stands for.
  std::string type;          ///< The recorded type ("isovalue", "marker", ...).
  std::string text;          ///< What happened, in words (UTF-8, not escaped for HTML).
  bool critical = false;     ///< A marker or a critical segment touched or drilled.
};

/// The events as rows for a reader: in time order, each event in words ("Isovalue 250 → 400
/// HU", "Marker “nerve”", "Tool: drill (points 1.5 mm apart)"), except that a kind that occurs
/// more than `max_listed` times is one row at its first time, e.g. "Isovalue changed 300 times,
/// 250 → 400 HU" (first from, last to) or "Segment touched changed 40 times (Liver, Kidney)",
/// with its first and last time. Markers, critical contacts and critical removals are always
/// listed one by one (they are what a teacher looks for). `value_unit` is the scan's unit
/// ("HU", "SUV", or empty) for isovalues. Unknown types are written as their name and fields.
std::vector<EventRow> summariseEvents(const std::vector<runtime::RecordingEvent>& events,
                                      const std::string& value_unit, std::size_t max_listed = 5);

}  // namespace vh::ui
