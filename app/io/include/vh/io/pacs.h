#pragma once
/// @file
/// A DICOM network client for a PACS: verify the connection (C-ECHO), list studies and series
/// (C-FIND, Study Root Query/Retrieve Information Model), and retrieve one series into a folder
/// (C-GET, the files arriving on the same association, so no port needs to be opened for the
/// server to call back as C-MOVE would). The protocol is DCMTK's dcmnet (DcmSCU); nothing of it
/// is reimplemented here, and no DCMTK header is in this one.
///
/// Every call opens its own association and closes it before returning, within
/// PacsServer::timeout_s; calls may run on any thread, several at once. Errors are PacsError
/// exceptions naming the server ("VHPACS at 127.0.0.1:4242") and what failed.
///
/// Each call runs in the DICOM network process (the reader program's `pacs` mode, see
/// reader_process.h), as the scan readers do: DCMTK parses an answer with recursion as deep as
/// its nesting and allocates a value's declared length before its bytes arrive, so a hostile or
/// broken server's answer (a sequence nested 100,000 deep; a 156-byte response that declares
/// 3.6 GB) ends that process, and the call throws "... the DICOM network process crashed
/// (SIGSEGV) on the server's answer to C-FIND ...": the calling program, a recording in progress
/// and the haptic threads go on. The calling side's own deadline, the timeout plus 3 s, covers
/// what the operation's watchdog cannot cut off (the host name's lookup). Without the reader
/// program (a build without it) the call runs in the calling process.

#include <atomic>
#include <filesystem>
#include <functional>
#include <stdexcept>
#include <string>
#include <vector>

namespace vh::io {

/// Where the PACS is and who we are to it.
struct PacsServer {
  std::string host = "localhost";          ///< Host name or address of the server.
  int port = 104;                          ///< Its DICOM port, 1..65535 (104 is DICOM's own; Orthanc uses 4242).
  std::string called_aet = "ORTHANC";      ///< The server's AE title (at most 16 characters).
  std::string calling_aet = "VOLUMEHAPTICS";  ///< Ours, as the server knows it (at most 16 characters).
  /// The longest an operation may take [s], 1..3600: an echo or a query from connecting to its
  /// last answer; a retrieval until its first file and then from one file to the next (a large
  /// series may take longer in all). It bounds the whole time, not each wait for the next bytes,
  /// so a server that answers a byte at a time is cut off all the same.
  int timeout_s = 30;

  /// DICOM TLS (PS3.15 Annex B, BCP 195 profile: TLS 1.2 or later) instead of plain TCP. The
  /// server's certificate must verify against `ca_cert` and name `host` (as a DNS name, or as an
  /// IP address when `host` is one).
  bool tls = false;
  std::string ca_cert;      ///< PEM file of the CA certificate(s) trusted for the server's; required with `tls`.
  std::string client_cert;  ///< PEM file of our certificate, for a server that asks for one (with `client_key`).
  std::string client_key;   ///< PEM file of its private key (unencrypted); both or neither.

  /// "CALLED at HOST:PORT", how messages name the server.
  std::string describe() const;

  bool operator==(const PacsServer& other) const = default;
};

/// A PACS operation failed; what() names the server and what went wrong, e.g.
/// "PACS VHPACS at 127.0.0.1:4242: no connection (Connection refused): is the server running on
/// that port?".
class PacsError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// One study as a C-FIND at STUDY level reports it (empty strings: not reported).
struct PacsStudy {
  std::string patient_name;        ///< Patient's Name, DICOM PN ("Family^Given").
  std::string patient_id;          ///< Patient ID.
  std::string patient_birth_date;  ///< YYYYMMDD.
  std::string patient_sex;         ///< M, F or O.
  std::string study_uid;           ///< Study Instance UID.
  std::string study_date;          ///< YYYYMMDD.
  std::string study_time;          ///< HHMMSS[.frac].
  std::string description;         ///< Study Description.
  std::string accession_number;    ///< Accession Number.
  std::string modalities;          ///< Modalities in Study, backslash-separated ("CT\PT").
  int series_count = -1;           ///< Number of Study Related Series; -1: not reported.
};

/// One series as a C-FIND at SERIES level reports it.
struct PacsSeries {
  std::string study_uid;    ///< Study Instance UID of its study.
  std::string series_uid;   ///< Series Instance UID.
  std::string modality;     ///< CT, MR, PT, SEG, RTSTRUCT, ...
  std::string description;  ///< Series Description.
  int number = -1;          ///< Series Number; -1: not reported.
  int instance_count = -1;  ///< Number of Series Related Instances (the files); -1: not reported.
};

/// A patient and the studies found for them, for a tree of patients > studies > series.
struct PacsPatient {
  std::string name, id, birth_date, sex;  ///< As in PacsStudy.
  std::vector<PacsStudy> studies;         ///< In the order the server sent them.
};

/// What to look for; DICOM wildcards * and ? are allowed in the names and ids; empty matches all.
struct PacsStudyQuery {
  std::string patient_name;  ///< Patient's Name, e.g. "DOE*" (matching is the server's, usually case-insensitive).
  std::string patient_id;    ///< Patient ID.
  std::string study_date;    ///< YYYYMMDD or a range YYYYMMDD-YYYYMMDD.
};

/// Checks that the server answers: an association and a C-ECHO.
/// @throws PacsError when there is no connection, the association is rejected or the echo fails;
///   when it takes longer than `server.timeout_s` ("... within the timeout of 30 s"); with TLS,
///   when the server's certificate does not verify (the message says why, e.g. "unable to get
///   local issuer certificate") or the server does not speak TLS.
void pacsEcho(const PacsServer& server);

/// The studies matching `query` (C-FIND at STUDY level, Study Root model), with their patient.
/// @throws PacsError as pacsEcho(), and when the server answers the query with a failure status
///   (e.g. "C-FIND failed: status 0xC000 (unable to process)").
std::vector<PacsStudy> pacsFindStudies(const PacsServer& server, const PacsStudyQuery& query = {});

/// The series of one study (C-FIND at SERIES level, Study Root model), with their instance
/// counts. `modality` (e.g. "CT") narrows them when not empty.
/// @throws PacsError as pacsFindStudies().
std::vector<PacsSeries> pacsFindSeries(const PacsServer& server, const std::string& study_uid,
                                       const std::string& modality = {});

/// The series with this Series Instance UID, whatever its study (C-FIND at SERIES level).
/// @throws PacsError as pacsFindStudies(), and when no series has that UID.
PacsSeries pacsFindSeriesByUid(const PacsServer& server, const std::string& series_uid);

/// The patients of `studies` (the Study Root model has no patient level: patients are the
/// studies grouped by Patient ID, or by name when the ID is empty), in order of first appearance.
std::vector<PacsPatient> pacsPatientsOf(const std::vector<PacsStudy>& studies);

/// How a retrieval is going; passed to RetrieveOptions::progress after each file.
struct PacsRetrieveProgress {
  int received = 0;   ///< Files written so far.
  int total = -1;     ///< Files expected (the series' instance count, or the server's count of sub-operations); -1: unknown.
  int failed = 0;     ///< Sub-operations the server reports as failed so far.
  std::filesystem::path last_file;  ///< The file just written.
};

/// How pacsRetrieveSeries() reports and stops.
struct PacsRetrieveOptions {
  /// Called on the retrieving thread after each file received (keep it short: the server waits).
  std::function<void(const PacsRetrieveProgress&)> progress;
  /// When set and it becomes true, the retrieval stops: checked after each file; a C-CANCEL is
  /// sent to the server, which should end the C-GET; if it goes on sending for more than
  /// `cancel_grace_s`, the association is aborted. The files received are then deleted.
  const std::atomic<bool>* cancel = nullptr;
  double cancel_grace_s = 2.0;  ///< [s]
  /// The number of files expected (e.g. PacsSeries::instance_count), for progress; -1: ask the server.
  int expected_instances = -1;
};

/// What a retrieval brought.
struct PacsRetrieveResult {
  std::filesystem::path folder;             ///< Where the files are (the `out_dir` given).
  std::vector<std::filesystem::path> files; ///< One per instance, named SOP_INSTANCE_UID.dcm; empty when cancelled.
  int failed = 0;                           ///< Sub-operations the server reports as failed (or with warnings).
  bool cancelled = false;                   ///< Stopped through PacsRetrieveOptions::cancel.
  /// When cancelled: the server answered the C-CANCEL by ending the C-GET (else we aborted the association).
  bool cancel_acknowledged = false;
  double seconds = 0.0;                     ///< Wall time of the retrieval [s].
};

/// Retrieves every instance of series `series_uid` of study `study_uid` into `out_dir` (created
/// when missing; files of other series in it are left alone) by C-GET at SERIES level (Study
/// Root model). `study_uid` may be empty: it is then looked up (pacsFindSeriesByUid()).
/// Offers the storage SOP classes of images, segmentations and RT objects in uncompressed
/// transfer syntaxes (the server converts compressed ones, or reports those files as failed).
/// @throws PacsError as pacsFindStudies(); when the C-GET ends with a failure status, when no
///   file arrived, or when a file cannot be written to `out_dir`.
PacsRetrieveResult pacsRetrieveSeries(const PacsServer& server, const std::string& study_uid,
                                      const std::string& series_uid, const std::filesystem::path& out_dir,
                                      const PacsRetrieveOptions& options = {});

}  // namespace vh::io
