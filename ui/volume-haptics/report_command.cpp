// `volume-haptics report`: the session report (vh/ui/export/session_report.h) and the cohort
// table (vh/runtime/session_metrics.h).

#include "report_command.h"

#include <cstdlib>
#include <iostream>
#include <memory>
#include <string>

#include <QApplication>

#include "vh/runtime/cohort_table.h"
#include "vh/ui/export/session_report.h"

namespace vh::app {
namespace {

struct ReportArgs {
  std::string input;
  std::string html;
  std::string reference;
  std::string table;
  bool per_material = false;
  ui::SessionReportOptions options;
};

int reportCommand(const ReportArgs& a) {
  if (a.html.empty() == a.table.empty())
    throw std::runtime_error("report: give either --html OUT.html (for one recording) or --table OUT.csv (for a folder)");
  if (!a.table.empty()) {
    if (!a.reference.empty()) throw std::runtime_error("report: --reference goes with --html, not --table");
    runtime::CohortTableOptions table;
    table.metrics = a.options.metrics;
    table.anonymize = a.options.anonymize;
    table.drilled_per_material = a.per_material;
    const std::size_t rows =
        runtime::writeCohortTable(a.input, a.table, table, [](std::size_t done, std::size_t total) {
          std::cerr << "\rvolume-haptics report: " << done << " of " << total << " recordings" << std::flush;
          if (done == total) std::cerr << '\n';
        });
    std::cout << "volume-haptics report: " << rows << (rows == 1 ? " recording" : " recordings") << " in "
              << a.table << std::endl;
    return EXIT_SUCCESS;
  }
  if (a.per_material) throw std::runtime_error("report: --per-material goes with --table (the HTML report always has it)");
  // Qt Charts draws through a QGraphicsScene, which needs a QApplication: on the offscreen
  // platform, so that no display is needed and no window appears.
  setenv("QT_QPA_PLATFORM", "offscreen", 1);
  int qt_argc = 1;
  char name[] = "volume-haptics";
  char* qt_argv[] = {name, nullptr};
  QApplication qt(qt_argc, qt_argv);
  for (const std::string& n : ui::writeSessionReport(a.input, a.html, a.options, a.reference))
    std::cerr << "volume-haptics report: warning: " << n << std::endl;
  std::cout << "volume-haptics report: " << a.html << std::endl;
  return EXIT_SUCCESS;
}

}  // namespace

CLI::App* addReportSubcommand(CLI::App& app, std::function<int()>& handler) {
  auto a = std::make_shared<ReportArgs>();
  CLI::App* cmd = app.add_subcommand(
      "report", "A session recording (.vhrec) to a self-contained HTML report (force, motion, contacts, segments, "
                "timing; optionally against a reference), or a folder of recordings to a CSV table (no display needed)");
  cmd->add_option("input", a->input, "The recording (.vhrec) for --html; a folder searched recursively for --table")
      ->required();
  cmd->add_option("--html", a->html, "HTML report to write (images inline, no network)");
  cmd->add_option("--reference", a->reference,
                  "A reference recording (an expert's) of the same scene to compare with: metrics side by side, "
                  "paths aligned by dynamic time warping");
  cmd->add_option("--table", a->table, "CSV to write: one row per recording found under input, every metric");
  cmd->add_flag("--per-material", a->per_material,
                "With --table: replay each recording that drilled on its scan for what the burr removed per material "
                "(a column removed_mm3[MATERIAL] each, air included), as the HTML report does; takes about as long as "
                "the drilling did");
  cmd->add_option("--force-threshold-N", a->options.metrics.force_threshold_N,
                  "Force above which time is counted [N]")
      ->capture_default_str()
      ->check(CLI::NonNegativeNumber);
  cmd->add_flag("!--no-anatomy", a->options.anatomy,
                "Draw the contact map without the scan behind it (the scan is then reloaded only for a recording that "
                "drilled, to replay it for its removal per material)");
  cmd->add_flag("--anonymize", a->options.anonymize,
                "Leave out what identifies the patient (DICOM PS3.15 Annex E, for the fields a recording keeps): "
                "paths and file names become ANONYMIZED, the series UID a 2.25 UID derived from it, the series "
                "description and the start date and time are removed");
  cmd->callback([&handler, a] { handler = [a] { return reportCommand(*a); }; });
  return cmd;
}

}  // namespace vh::app
