#pragma once
/// @file
/// The session report: one self-contained HTML page (no network: every picture is an inline
/// base64 PNG) that a teacher reads after a session. The numbers are runtime::SessionMetrics
/// (vh/runtime/session_metrics.h, which gives their definitions and sources), written with
/// their units to three significant digits (report_format.h); this part draws them with Qt
/// Charts and QPainter, rendered off screen into PNGs, and lays out the page, in this order:
///   - the metadata and a summary of the figures a teacher reads first;
///   - with a reference recording (same scene): the comparison, the metrics side by side with
///     their differences, the mean distance after dynamic time warping (Sakoe and Chiba 1978)
///     and both device paths on the axial and coronal views;
///   - |F| [N] and |torque| [N*m] over time, with the force threshold, the markers and the
///     critical events; the device's speed over time;
///   - the contact maps: the proxy's positions while in contact, coloured by |F|, on an axial,
///     a coronal and a sagittal view in the patient's frame (W is LPS), labelled L/R, A/P, S/I at
///     their sides, each seen from the side the tool was on (where the force on the hand
///     pointed), framed on at least 80 mm around the contacts with a scale bar, over the felt
///     surface of the recorded scene (the scan reloaded from the metadata, lit, darker when
///     farther);
///   - the segments touched; the events in words, a kind repeated more than 5 times in one row
///     (summariseEvents()); every metric.
/// A recording with damaged chunks, a damaged tail or no end marker gives the report of what
/// could be read, with the reader's notices at the top.
///
/// Needs a QApplication (Qt Charts draws through QGraphicsScene); without a display, create it
/// on Qt's "offscreen" platform (QT_QPA_PLATFORM=offscreen), as `volume-haptics report` does.

#include <filesystem>
#include <string>
#include <vector>

#include "vh/runtime/recording.h"
#include "vh/runtime/session_metrics.h"

namespace vh::ui {

/// What sessionReportHtml() draws.
struct SessionReportOptions {
  runtime::MetricsOptions metrics;  ///< Force threshold, derivative step.
  int chart_width = 960;            ///< Time charts' width [px].
  int chart_height = 320;           ///< Time charts' height [px].
  int map_size = 360;               ///< Each contact-map and path projection's side [px].
  std::size_t dtw_samples = 1000;   ///< Points per device path for the alignment.
  /// Draw the felt surface behind the contact map: the recorded scene is reloaded from the
  /// metadata (runtime::loadScene(); a missing or changed dataset gives a note instead).
  bool anatomy = true;
  /// Leave out what identifies the patient: the text is of copies anonymized as
  /// runtime::anonymizeRecording() (the scan still reloads from the original metadata), the
  /// titles are "ANONYMIZED" and "reference".
  bool anonymize = false;
};

/// The report of `recording` as one HTML document. `title` names it (the file's name).
/// `reference` (may be null), named `reference_title`, is compared with it; it must be of the
/// same scene.
/// Needs a QApplication on the calling (GUI) thread.
/// @throws std::invalid_argument when the reference is of another scene (the message says which
///         datasets) or options are out of range.
std::string sessionReportHtml(const runtime::Recording& recording, const std::string& title,
                              const SessionReportOptions& options = {},
                              const runtime::Recording* reference = nullptr,
                              const std::string& reference_title = {});

/// Writes sessionReportHtml() to `html`. @throws std::runtime_error when it cannot be written;
/// std::invalid_argument as sessionReportHtml().
void writeSessionReport(const runtime::Recording& recording, const std::string& title,
                        const std::filesystem::path& html, const SessionReportOptions& options = {},
                        const runtime::Recording* reference = nullptr, const std::string& reference_title = {});

/// Reads `recording` (and `reference` when not empty) and writes sessionReportHtml() to `html`.
/// @return the reader's and the metrics' notices (damage, an unfinished recording), for the
///         caller to show.
/// @throws std::runtime_error when a recording cannot be read at all (not a recording, damaged
///         header) or `html` cannot be written; std::invalid_argument as sessionReportHtml().
std::vector<std::string> writeSessionReport(const std::filesystem::path& recording, const std::filesystem::path& html,
                                            const SessionReportOptions& options = {},
                                            const std::filesystem::path& reference = {});

}  // namespace vh::ui
