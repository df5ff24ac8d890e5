// PET values in SUV (body weight), after the QIBA / Uniform Protocols for Imaging in Medicine
// "Vendor-neutral pseudo-code for SUV calculation" and DICOM PS3.3 C.8.9.1 (PET Series module)
// and C.8.9.2 (PET Isotope module); see pet_suv.h.
//
// SUVbw = activity concentration [Bq/ml] * PatientWeight [kg] * 1000 [g/kg] / decayed dose [Bq],
// taking 1 ml of tissue as 1 g: 1 is the dose spread evenly over the body. The dose is
// RadionuclideTotalDose (at RadiopharmaceuticalStartTime) decayed to the time the images are
// decay-corrected to: dose * 2^(-dt / RadionuclideHalfLife).
#include "pet_suv.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <iomanip>
#include <optional>
#include <sstream>
#include <utility>

#include <vtkDICOMDictHash.h>
#include <vtkDICOMItem.h>
#include <vtkDICOMMetaData.h>
#include <vtkDICOMTag.h>
#include <vtkDICOMValue.h>

#include "loader_internal.h"

namespace vh::io::detail {
namespace {

constexpr double kSecondsPerDay = 86400.0;

/// A DICOM time: seconds since midnight, and the day (days since 1970-01-01) when a date is known.
struct DicomTime {
  std::optional<long long> day;
  double seconds = 0.0;
};

bool allDigits(const std::string& s) {
  return std::all_of(s.begin(), s.end(), [](char c) { return std::isdigit(static_cast<unsigned char>(c)) != 0; });
}

std::string toUpper(std::string s) {
  for (char& c : s) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  return s;
}

/// Days since 1970-01-01 of a Gregorian date (H. Hinnant's days_from_civil).
long long daysFromCivil(long long y, int m, int d) {
  y -= m <= 2 ? 1 : 0;
  const long long era = (y >= 0 ? y : y - 399) / 400;
  const long long yoe = y - era * 400;
  const long long doy = (153 * (m > 2 ? m - 3 : m + 9) + 2) / 5 + d - 1;
  const long long doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
  return era * 146097 + doe - 719468;
}

/// A DA value ("YYYYMMDD", or ACR-NEMA's "YYYY.MM.DD") as days since 1970-01-01.
std::optional<long long> parseDate(std::string s) {
  s.erase(std::remove(s.begin(), s.end(), '.'), s.end());
  if (s.size() != 8 || !allDigits(s)) return std::nullopt;
  const int y = std::stoi(s.substr(0, 4)), m = std::stoi(s.substr(4, 2)), d = std::stoi(s.substr(6, 2));
  if (m < 1 || m > 12 || d < 1 || d > 31) return std::nullopt;
  return daysFromCivil(y, m, d);
}

/// A TM value ("HH", "HHMM", "HHMMSS", "HHMMSS.FFFFFF", or ACR-NEMA's "HH:MM:SS.F") as seconds
/// since midnight.
std::optional<double> parseTime(std::string s) {
  s.erase(std::remove(s.begin(), s.end(), ':'), s.end());
  const std::size_t dot = s.find('.');
  const std::string whole = s.substr(0, dot);
  const std::string fraction = dot == std::string::npos ? std::string() : s.substr(dot + 1);
  if (whole.size() < 2 || whole.size() > 6 || whole.size() % 2 != 0 || !allDigits(whole) || !allDigits(fraction)) {
    return std::nullopt;
  }
  const int hh = std::stoi(whole.substr(0, 2));
  const int mm = whole.size() >= 4 ? std::stoi(whole.substr(2, 2)) : 0;
  const int ss = whole.size() >= 6 ? std::stoi(whole.substr(4, 2)) : 0;
  if (hh > 23 || mm > 59 || ss > 60) return std::nullopt;
  const double f = fraction.empty() ? 0.0 : std::stod("0." + fraction);
  return hh * 3600.0 + mm * 60.0 + ss + f;
}

/// A DT value ("YYYYMMDDHHMMSS.FFFFFF&ZZXX"): date and time (the UTC offset is ignored: every
/// time of one series is taken in the same zone). Null without at least the hour.
std::optional<DicomTime> parseDateTime(std::string s) {
  s = trim(s);
  const std::size_t zone = s.find_first_of("+-");
  if (zone != std::string::npos) s.resize(zone);
  if (s.size() < 10) return std::nullopt;
  const auto day = parseDate(s.substr(0, 8));
  const auto seconds = parseTime(s.substr(8));
  if (!day || !seconds) return std::nullopt;
  return DicomTime{day, *seconds};
}

std::string text(const vtkDICOMValue& v) { return v.IsValid() ? trim(v.AsString()) : std::string(); }

/// The first number of a DS / IS / FD value; null when absent, empty or not finite.
std::optional<double> number(const vtkDICOMValue& v) {
  if (!v.IsValid() || v.GetNumberOfValues() == 0) return std::nullopt;
  const double d = v.GetDouble(0);
  return std::isfinite(d) ? std::optional<double>(d) : std::nullopt;
}

/// A time attribute, with the date of `date_tag` when that parses (instance i of `md`).
std::optional<DicomTime> timeOf(vtkDICOMMetaData* md, int i, vtkDICOMTag date_tag, vtkDICOMTag time_tag) {
  const auto seconds = parseTime(text(md->Get(i, time_tag)));
  if (!seconds) return std::nullopt;
  return DicomTime{parseDate(text(md->Get(i, date_tag))), *seconds};
}

/// b - a [s]: from the dates when both have one, else from the times of day alone.
double secondsFrom(const DicomTime& a, const DicomTime& b) {
  double d = b.seconds - a.seconds;
  if (a.day && b.day) d += static_cast<double>(*b.day - *a.day) * kSecondsPerDay;
  return d;
}

/// The earliest and the latest acquisition of the series: AcquisitionDateTime, else
/// AcquisitionDate and AcquisitionTime, of every instance. Null when no instance has one.
std::optional<std::pair<DicomTime, DicomTime>> acquisitionSpan(vtkDICOMMetaData* md) {
  std::optional<std::pair<DicomTime, DicomTime>> span;
  for (int i = 0; i < md->GetNumberOfInstances(); ++i) {
    auto t = parseDateTime(text(md->Get(i, DC::AcquisitionDateTime)));
    if (!t) t = timeOf(md, i, DC::AcquisitionDate, DC::AcquisitionTime);
    if (!t) continue;
    if (!span) {
      span.emplace(*t, *t);
      continue;
    }
    if (secondsFrom(span->first, *t) < 0.0) span->first = *t;
    if (secondsFrom(span->second, *t) > 0.0) span->second = *t;
  }
  return span;
}

/// "09:41:07" (the time of day, to the second).
std::string clockText(const DicomTime& t) {
  const long s = std::lround(std::floor(t.seconds)) % 86400;
  char out[16];
  std::snprintf(out, sizeof(out), "%02ld:%02ld:%02ld", s / 3600, s / 60 % 60, s % 60);
  return out;
}

/// Four significant digits: "70", "370", "0.0002894".
std::string brief(double v) {
  std::ostringstream os;
  os << std::setprecision(4) << v;
  return os.str();
}

/// Item 0 of the RadiopharmaceuticalInformationSequence: the dose, its half-life and when it was
/// injected.
struct Injection {
  std::optional<double> dose_bq;
  std::optional<double> half_life_s;
  std::optional<DicomTime> start;  ///< RadiopharmaceuticalStartDateTime, else ...StartTime (no date).
};

/// The injection from instance 0 of `md`; false when the sequence is missing or empty.
bool readInjection(vtkDICOMMetaData* md, Injection& out) {
  const vtkDICOMValue& seq = md->Get(0, DC::RadiopharmaceuticalInformationSequence);
  const vtkDICOMItem* items = seq.IsValid() ? seq.GetSequenceData() : nullptr;
  if (items == nullptr || seq.GetNumberOfValues() == 0) return false;
  const vtkDICOMItem& drug = items[0];
  out.dose_bq = number(drug.Get(DC::RadionuclideTotalDose));
  out.half_life_s = number(drug.Get(DC::RadionuclideHalfLife));
  out.start = parseDateTime(text(drug.Get(DC::RadiopharmaceuticalStartDateTime)));
  if (!out.start) {
    const auto seconds = parseTime(text(drug.Get(DC::RadiopharmaceuticalStartTime)));
    if (seconds) out.start = DicomTime{std::nullopt, *seconds};
  }
  return true;
}

/// The time the images are decay-corrected to for START (NONE: the first acquisition, which the
/// caller treats alike), as the QIBA pseudo-code chooses it: SeriesDate / SeriesTime unless it is
/// after the earliest acquisition (a series written by post-processing), then that acquisition.
std::optional<DicomTime> referenceTime(vtkDICOMMetaData* md, const std::string& decay,
                                       const std::optional<std::pair<DicomTime, DicomTime>>& span) {
  if (decay == "none") return span ? std::optional<DicomTime>(span->first) : timeOf(md, 0, DC::SeriesDate, DC::SeriesTime);
  const auto series = timeOf(md, 0, DC::SeriesDate, DC::SeriesTime);
  if (series && !(span && secondsFrom(span->first, *series) > 0.0)) return series;
  return span ? std::optional<DicomTime>(span->first) : std::nullopt;
}

/// The SUV of a BQML series; `out` has unit "Bq/ml" and returns with in_suv = false and a
/// notice naming the attribute when one is missing or unusable.
PetSuv bqmlToSuv(vtkDICOMMetaData* md, PetSuv out) {
  const auto notSuv = [&](const std::string& why) {
    out.notice = "PET values in Bq/ml, not SUV: " + why;
    return out;
  };
  const auto weight_kg = number(md->Get(0, DC::PatientWeight));
  if (!weight_kg) return notSuv("PatientWeight is missing");
  if (!(*weight_kg > 0.0)) return notSuv("PatientWeight is " + brief(*weight_kg) + " kg");
  Injection injection;
  if (!readInjection(md, injection)) return notSuv("RadiopharmaceuticalInformationSequence is missing");
  if (!injection.dose_bq) return notSuv("RadionuclideTotalDose is missing");
  if (!(*injection.dose_bq > 0.0)) return notSuv("RadionuclideTotalDose is " + brief(*injection.dose_bq) + " Bq");
  const std::string decay = toLower(text(md->Get(0, DC::DecayCorrection)));
  if (decay.empty()) return notSuv("DecayCorrection is missing");
  if (decay != "start" && decay != "admin" && decay != "none") {
    return notSuv("DecayCorrection '" + text(md->Get(0, DC::DecayCorrection)) + "' is not START, ADMIN or NONE");
  }
  const std::string at = injection.start ? " at " + clockText(*injection.start) : std::string();
  double decayed_bq = *injection.dose_bq;
  std::string corrected = injection.start ? clockText(*injection.start) : std::string("the injection");
  std::string caveat;
  if (decay != "admin") {
    if (!injection.half_life_s) return notSuv("RadionuclideHalfLife is missing");
    if (!(*injection.half_life_s > 0.0)) return notSuv("RadionuclideHalfLife is " + brief(*injection.half_life_s) + " s");
    if (!injection.start) return notSuv("RadiopharmaceuticalStartTime is missing");
    const auto span = acquisitionSpan(md);
    const auto reference = referenceTime(md, decay, span);
    if (!reference) return notSuv("SeriesTime and AcquisitionTime are missing");
    double dt_s = secondsFrom(*injection.start, *reference);
    // Times without both dates: a scan earlier in the day than the injection is the next day.
    if (!(injection.start->day && reference->day) && dt_s < 0.0) dt_s += kSecondsPerDay;
    if (dt_s < 0.0) {
      return notSuv("the injection (" + clockText(*injection.start) + ") is after the scan (" + clockText(*reference) + ")");
    }
    decayed_bq *= std::exp2(-dt_s / *injection.half_life_s);
    corrected = clockText(*reference);
    if (decay == "none" && span) {
      const double low = 100.0 * (1.0 - std::exp2(-secondsFrom(span->first, span->second) / *injection.half_life_s));
      caveat = "; the slices are not decay-corrected: the factor is for the first acquisition, the last reads " +
               brief(low) + " % low";
    }
  }
  out.factor = *weight_kg * 1000.0 / decayed_bq;
  if (!std::isfinite(out.factor) || !(out.factor > 0.0)) return notSuv("the SUV factor is not a finite positive number");
  out.in_suv = true;
  out.unit = "SUVbw";
  out.notice = "PET in SUV (body weight): weight " + brief(*weight_kg) + " kg, injected dose " +
               brief(*injection.dose_bq * 1e-6) + " MBq" + at + ", decay-corrected to " + corrected +
               " (DecayCorrection " + toUpper(decay) + "), factor " + brief(out.factor) + caveat;
  return out;
}

PetSuv petSuvOf(vtkDICOMMetaData* md) {
  PetSuv out;
  if (md == nullptr || md->GetNumberOfInstances() == 0) {
    out.notice = "PET values as stored, not SUV: the series has no header";
    return out;
  }
  const std::string units = text(md->Get(0, DC::Units));
  if (toLower(units) == "gml") {
    out.in_suv = true;
    out.unit = "SUVbw";
    out.notice = "PET in SUV (body weight) as stored (Units GML)";
    return out;
  }
  if (toLower(units) != "bqml") {
    out.notice = units.empty() ? std::string("PET values as stored, not SUV: Units is missing")
                               : "PET values in " + units + ", not SUV: SUV needs Units BQML (Bq/ml)";
    return out;
  }
  out.unit = "Bq/ml";
  return bqmlToSuv(md, out);
}

}  // namespace

PetSuv petSuv(vtkDICOMMetaData* md) noexcept {
  try {
    return petSuvOf(md);
  } catch (...) {  // e.g. std::bad_alloc: a header problem never fails the load
    PetSuv out;
    out.notice = "PET values as stored, not SUV: the PET header could not be read";
    return out;
  }
}

}  // namespace vh::io::detail
