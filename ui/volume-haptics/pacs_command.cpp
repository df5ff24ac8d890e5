// `volume-haptics pacs`: echo, find and get against a DICOM server (vh/io/pacs.h).

#include "pacs_command.h"

#include <atomic>
#include <csignal>
#include <iostream>
#include <memory>
#include <string>

#include "vh/io/pacs.h"

namespace vh::app {
namespace {

/// The options every pacs command shares, with their defaults (the GUI's Preferences hold its own).
struct PacsArgs {
  io::PacsServer server;
  std::string patient, patient_id, study, modality;
  std::string series_uid, out;
};

std::atomic<bool> g_interrupted{false};
void onInterrupt(int) { g_interrupted = true; }

void addServerOptions(CLI::App* cmd, PacsArgs& a) {
  cmd->add_option("--host", a.server.host, "The PACS host name or address")->capture_default_str();
  cmd->add_option("--port", a.server.port, "Its DICOM port (Orthanc: 4242)")
      ->capture_default_str()
      ->check(CLI::Range(1, 65535));
  cmd->add_option("--aet", a.server.called_aet, "The PACS's AE title (called AE title)")->capture_default_str();
  cmd->add_option("--calling-aet", a.server.calling_aet,
                  "Our AE title, as the PACS knows it (it must be configured there for find and get)")
      ->capture_default_str();
  cmd->add_option("--timeout", a.server.timeout_s,
                  "Longest an echo or a query may take in all, and a retrieval for each next file [s]; "
                  "past it the connection is cut off")
      ->capture_default_str()
      ->check(CLI::Range(1, 3600));
  cmd->add_flag("--tls", a.server.tls, "DICOM TLS (PS3.15 Annex B, TLS 1.2 or later) instead of plain TCP");
  cmd->add_option("--ca-cert", a.server.ca_cert,
                  "With --tls: PEM file of the CA certificate the server's certificate must verify against "
                  "(it must also name --host)")
      ->check(CLI::ExistingFile);
  cmd->add_option("--cert", a.server.client_cert, "With --tls: PEM file of our certificate, for a server that asks for one")
      ->check(CLI::ExistingFile);
  cmd->add_option("--key", a.server.client_key, "With --tls: PEM file of our certificate's private key (unencrypted)")
      ->check(CLI::ExistingFile);
}

/// Tab-separated, one line per study and per series, for scripts: level, UID, study UID,
/// patient, patient ID, date, modality, series number, files, description.
void printHeader() { std::cout << "level\tuid\tstudy_uid\tpatient\tpatient_id\tdate\tmodality\tnumber\tfiles\tdescription\n"; }

void printStudy(const io::PacsStudy& s) {
  std::cout << "study\t" << s.study_uid << '\t' << s.study_uid << '\t' << s.patient_name << '\t' << s.patient_id << '\t'
            << s.study_date << '\t' << s.modalities << "\t\t\t" << s.description << '\n';
}

void printSeries(const io::PacsSeries& s, const io::PacsStudy* study) {
  std::cout << "series\t" << s.series_uid << '\t' << s.study_uid << '\t' << (study ? study->patient_name : "") << '\t'
            << (study ? study->patient_id : "") << '\t' << (study ? study->study_date : "") << '\t' << s.modality
            << '\t' << (s.number >= 0 ? std::to_string(s.number) : "") << '\t'
            << (s.instance_count >= 0 ? std::to_string(s.instance_count) : "") << '\t' << s.description << '\n';
}

int findCommand(const PacsArgs& a) {
  printHeader();
  if (!a.study.empty()) {
    for (const io::PacsSeries& s : io::pacsFindSeries(a.server, a.study, a.modality)) printSeries(s, nullptr);
    return 0;
  }
  io::PacsStudyQuery query;
  query.patient_name = a.patient;
  query.patient_id = a.patient_id;
  for (const io::PacsStudy& study : io::pacsFindStudies(a.server, query)) {
    printStudy(study);
    for (const io::PacsSeries& s : io::pacsFindSeries(a.server, study.study_uid, a.modality)) printSeries(s, &study);
  }
  return 0;
}

int getCommand(const PacsArgs& a) {
  // Ctrl+C cancels the retrieval cleanly (C-CANCEL; the partial files are deleted).
  std::signal(SIGINT, onInterrupt);
  std::signal(SIGTERM, onInterrupt);
  io::PacsRetrieveOptions options;
  options.cancel = &g_interrupted;
  options.progress = [](const io::PacsRetrieveProgress& p) {
    std::cerr << "\rvolume-haptics pacs get: " << p.received;
    if (p.total > 0) std::cerr << " of " << p.total;
    std::cerr << " files" << std::flush;
  };
  const io::PacsRetrieveResult r = io::pacsRetrieveSeries(a.server, a.study, a.series_uid, a.out, options);
  std::cerr << '\n';
  if (r.cancelled) {
    std::cerr << "volume-haptics pacs get: cancelled; the files received were deleted\n";
    return 1;
  }
  std::cout << "volume-haptics pacs get: " << r.files.size() << " files of series " << a.series_uid << " in "
            << r.folder.string() << " (" << r.seconds << " s";
  if (r.failed > 0) std::cout << ", " << r.failed << " failed on the server";
  std::cout << ")\n";
  return 0;
}

}  // namespace

CLI::App* addPacsSubcommand(CLI::App& app, std::function<int()>& handler) {
  auto args = std::make_shared<PacsArgs>();
  CLI::App* pacs = app.add_subcommand("pacs", "A DICOM server (PACS): check it, list its studies and series, retrieve "
                                              "a series into a folder (C-ECHO, C-FIND, C-GET; no display needed)");
  pacs->require_subcommand(1);

  CLI::App* echo = pacs->add_subcommand("echo", "Check that the PACS answers (C-ECHO)");
  addServerOptions(echo, *args);
  echo->callback([&handler, args] {
    handler = [args] {
      io::pacsEcho(args->server);
      std::cout << "volume-haptics pacs echo: " << args->server.describe() << " answers\n";
      return 0;
    };
  });

  CLI::App* find = pacs->add_subcommand(
      "find", "List studies and their series, tab-separated: level, uid, study_uid, patient, patient_id, date, "
              "modality, number, files, description");
  addServerOptions(find, *args);
  find->add_option("--patient", args->patient, "Patient's name to match (DICOM wildcards * and ?), e.g. 'DOE*'");
  find->add_option("--patient-id", args->patient_id, "Patient ID to match");
  find->add_option("--study", args->study, "List only the series of this Study Instance UID");
  find->add_option("--modality", args->modality, "Only series of this modality (CT, MR, PT, ...)");
  find->callback([&handler, args] { handler = [args] { return findCommand(*args); }; });

  CLI::App* get = pacs->add_subcommand(
      "get", "Retrieve one series (C-GET) into a folder, one file per instance, then open it with "
             "`volume-haptics DIR`; Ctrl+C cancels");
  addServerOptions(get, *args);
  get->add_option("series", args->series_uid, "The Series Instance UID (from `pacs find`)")->required();
  get->add_option("--out", args->out, "The folder to write the files to (created when missing)")->required();
  get->add_option("--study", args->study, "Its Study Instance UID (default: looked up by the series UID)");
  get->callback([&handler, args] { handler = [args] { return getCommand(*args); }; });
  return pacs;
}

}  // namespace vh::app
