// A PACS client on DCMTK's dcmnet (DcmSCU): C-ECHO, C-FIND (Study Root, STUDY and SERIES
// levels) and C-GET of one series, in the calling process (pacs_internal.h); the public
// functions of vh/io/pacs.h run these in the DICOM network process (pacs_process.cpp).

#include "vh/io/pacs.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <memory>
#include <mutex>
#include <string_view>
#include <system_error>

#include <dcmtk/config/osconfig.h>  // first, as DCMTK requires
#include <dcmtk/dcmdata/dcdeftag.h>
#include <dcmtk/dcmdata/dcfilefo.h>
#include <dcmtk/dcmdata/dcuid.h>
#include <dcmtk/dcmnet/diutil.h>
#include <dcmtk/dcmnet/scu.h>
#include <dcmtk/oflog/oflog.h>

#include "pacs_internal.h"
#include "pacs_transport.h"
#include "vh/io/private_files.h"

namespace vh::io {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

// DIMSE statuses (PS3.4 C.4.1.1.4, C.4.3.1.4, PS3.7 C).
constexpr Uint16 kStatusSuccess = 0x0000;
constexpr Uint16 kStatusCancel = 0xFE00;
constexpr Uint16 kStatusPending = 0xFF00;
constexpr Uint16 kStatusPendingWarning = 0xFF01;
constexpr Uint16 kStatusStoreOutOfResources = 0xA700;
// A C-GET ending "with one or more failures or warnings" (PS3.4 C.4.3.1.4).
constexpr Uint16 kStatusGetWarning = 0xB000;

/// How much longer than the operation's timeout DCMTK's per-PDU timeouts are [s].
constexpr int kDcmtkBackstopS = 5;

/// dcmnet's console log off (its messages would reach stderr; PacsError says what failed).
void initDcmtk() {
  static std::once_flag once;
  std::call_once(once, [] { OFLog::configure(OFLogger::OFF_LOG_LEVEL); });
}

using detail::pacsTrim;
using detail::pacsError;

std::string hex4(Uint16 v) {
  char buf[8];
  std::snprintf(buf, sizeof buf, "0x%04X", static_cast<unsigned>(v));
  return buf;
}

/// The settings a DICOM association needs, checked before any connection.
void checkServer(const PacsServer& s) {
  if (pacsTrim(s.host).empty()) throw pacsError(s, "no host name given");
  if (s.port < 1 || s.port > 65535) throw pacsError(s, "port " + std::to_string(s.port) + " is not in 1..65535");
  const auto check_aet = [&](const std::string& aet, const char* whose) {
    const std::string t = pacsTrim(aet);
    if (t.empty() || t.size() > 16 || t.find('\\') != std::string::npos) {
      throw pacsError(s, std::string(whose) + " AE title '" + aet + "' must have 1 to 16 characters, no backslash");
    }
  };
  check_aet(s.called_aet, "the called (server's)");
  check_aet(s.calling_aet, "the calling (our)");
  if (s.timeout_s < 1 || s.timeout_s > 3600) {
    throw pacsError(s, "timeout " + std::to_string(s.timeout_s) + " s is not in 1..3600 s");
  }
}

std::string text(DcmItem* ds, const DcmTagKey& tag) {
  OFString v;
  if (ds == nullptr || ds->findAndGetOFStringArray(tag, v).bad()) return {};
  return pacsTrim(std::string_view(v.c_str(), v.length()));
}

int number(DcmItem* ds, const DcmTagKey& tag) {
  const std::string v = text(ds, tag);
  try {
    std::size_t used = 0;
    const int n = std::stoi(v, &used);
    return used == v.size() && n >= 0 ? n : -1;
  } catch (const std::exception&) {
    return -1;
  }
}

/// What an association travels through: the operation's deadline and the transport layers.
/// Scu's first base, so that it is made before and destroyed after the DcmSCU that uses it.
struct ScuTransport {
  explicit ScuTransport(const PacsServer& server) : watchdog(server.timeout_s) {}
  pacs_detail::Watchdog watchdog;  // started now: the deadline counts from the operation's start
  std::unique_ptr<DcmTLSTransportLayer> tls;
  std::unique_ptr<pacs_detail::WatchedTransportLayer> layer;
};

/// Our DcmSCU: an association to `server`, and for C-GET the files written as they come.
class Scu : private ScuTransport, public DcmSCU {
 public:
  explicit Scu(const PacsServer& server) : ScuTransport(server), server_(server) {
    initDcmtk();
    checkServer(server);
    setAETitle(pacsTrim(server.calling_aet).c_str());
    setPeerAETitle(pacsTrim(server.called_aet).c_str());
    setPeerHostName(pacsTrim(server.host).c_str());
    setPeerPort(static_cast<Uint16>(server.port));
    // The watchdog bounds the whole operation. DCMTK's own timeouts bound each PDU, and restart
    // with the next: they are a backstop here, longer, so that the watchdog's error is the one
    // given. The TCP connection's is a process-wide DCMTK setting: every association sets it.
    setConnectionTimeout(server.timeout_s);
    setACSETimeout(static_cast<Uint32>(server.timeout_s + kDcmtkBackstopS));
    setDIMSEBlockingMode(DIMSE_NONBLOCKING);
    setDIMSETimeout(static_cast<Uint32>(server.timeout_s + kDcmtkBackstopS));
    setVerbosePCMode(OFFalse);
  }
  ~Scu() override {
    if (isConnected()) abortAssociation();
  }
  Scu(const Scu&) = delete;
  Scu& operator=(const Scu&) = delete;

  /// Proposes `abstract_syntax` (as SCU) in the uncompressed transfer syntaxes.
  void propose(const char* abstract_syntax, T_ASC_SC_ROLE role = ASC_SC_ROLE_DEFAULT) {
    OFList<OFString> syntaxes;
    syntaxes.push_back(UID_LittleEndianExplicitTransferSyntax);
    syntaxes.push_back(UID_LittleEndianImplicitTransferSyntax);
    if (addPresentationContext(abstract_syntax, syntaxes, role).bad()) {
      throw pacsError(server_, std::string("cannot propose ") + dcmFindNameOfUID(abstract_syntax, abstract_syntax));
    }
  }

  /// Opens the association; throws what failed, naming the server.
  void connect() {
    OFCondition cond = initNetwork();
    if (cond.bad()) throw pacsError(server_, std::string("cannot start the network: ") + cond.text());
    if (server_.tls) tls = pacs_detail::makeTlsLayer(server_);
    layer = std::make_unique<pacs_detail::WatchedTransportLayer>(watchdog, tls.get());
    cond = useSecureConnection(layer.get());
    if (cond.bad()) throw pacsError(server_, std::string("cannot set up the connection: ") + cond.text());
    cond = negotiateAssociation();
    if (cond.good()) return;
    const std::string why = cond.text();
    if (watchdog.expired() || (cond.module() == OFM_dcmnet && cond.code() == DULC_READTIMEOUT)) {
      throw pacsError(server_, "no complete answer to the association request within the timeout of " +
                              std::to_string(server_.timeout_s) + " s" +
                              (watchdog.expired() ? " (the connection was cut off)" : "") +
                              ": is a DICOM server listening on that port, and is it not overloaded?");
    }
    if (server_.tls) throwTlsFailure(cond);
    if (cond == DUL_ASSOCIATIONREJECTED) {
      throw pacsError(server_, "the server rejected the association (" + why + "): check the called AE title '" +
                              pacsTrim(server_.called_aet) + "' and that the server knows the calling AE title '" +
                              pacsTrim(server_.calling_aet) + "'");
    }
    if (cond.module() == OFM_dcmnet && (cond.code() == DULC_UNRECOGNIZEDPDUTYPE || cond.code() == DULC_ILLEGALPDU)) {
      throw pacsError(server_, "what answers on that port is not a DICOM server (" + why + ")");
    }
    if (cond == NET_EC_NoAcceptablePresentationContexts) {
      throw pacsError(server_, "the server accepts none of the services asked for (" + why + ")");
    }
    if (cond == DUL_PEERABORTEDASSOCIATION) {
      throw pacsError(server_, "the server closed the connection at once (" + why +
                              "): does it expect DICOM TLS on that port?");
    }
    throw pacsError(server_, "no connection (" + why + "): is the server running on that host and port?");
  }

  /// The accepted presentation context for `abstract_syntax`; throws when the server refused it.
  T_ASC_PresentationContextID contextFor(const char* abstract_syntax, const char* what) {
    const T_ASC_PresentationContextID id = findAnyPresentationContextID(abstract_syntax, "");
    if (id == 0) throw pacsError(server_, std::string("the server does not offer ") + what);
    return id;
  }

  /// Ends the association politely (a failed release is no error: the work is done).
  void release() {
    if (isConnected()) releaseAssociation();
  }

  /// Throws why a TLS association failed when it is TLS that failed: the server's certificate, or
  /// the handshake (a server that does not speak TLS on that port).
  void throwTlsFailure(const OFCondition& cond) const {
    const std::string problem = pacs_detail::lastCertificateProblem();
    if (!problem.empty()) {
      throw pacsError(server_, "DICOM TLS: the server's certificate was refused: " + problem + ", checked against the CA '" +
                              server_.ca_cert + "' for the host name '" + pacsTrim(server_.host) + "'");
    }
    if (cond.module() == OFM_dcmtls) {
      throw pacsError(server_, std::string("DICOM TLS: the handshake failed (") + cond.text() +
                              "): does the server speak DICOM TLS on that port, and accept our certificate?");
    }
  }

  /// Throws the timeout error when the deadline passed (`what` stopped by it, e.g. "C-FIND").
  void throwIfTimedOut(const std::string& what) const {
    if (!watchdog.expired()) return;
    throw pacsError(server_, what + " did not finish within the timeout of " + std::to_string(server_.timeout_s) +
                            " s, so the connection was cut off: is the server or the network very slow?");
  }

  // ---- C-GET ----

  /// Prepares the C-STORE sub-operations' handling: files go to `folder`.
  void startRetrieve(const fs::path& folder, const PacsRetrieveOptions& options, T_ASC_PresentationContextID get_id) {
    folder_ = folder;
    options_ = &options;
    get_id_ = get_id;
    progress_.total = options.expected_instances;
  }

  const std::vector<fs::path>& files() const { return files_; }
  bool cancelRequested() const { return options_ != nullptr && options_->cancel != nullptr && options_->cancel->load(); }
  bool cancelSent() const { return cancel_sent_; }
  Uint16 finalStatus() const { return final_status_; }
  bool finalReceived() const { return final_received_; }
  int failedSubops() const { return failed_; }
  const std::string& writeError() const { return write_error_; }

 protected:
  OFCondition handleSTORERequest(const T_ASC_PresentationContextID /*presID*/, DcmDataset* incoming,
                                 OFBool& continue_session, Uint16& store_status) override {
    std::unique_ptr<DcmDataset> dataset(incoming);
    if (!dataset) return DIMSE_NULLKEY;
    const std::string sop_uid = text(dataset.get(), DCM_SOPInstanceUID);
    std::string name = sop_uid.empty() ? "instance-" + std::to_string(files_.size() + 1) : sop_uid;
    for (char& c : name) {
      if (c != '.' && (c < '0' || c > '9') && (c < 'A' || c > 'Z') && (c < 'a' || c > 'z') && c != '-') c = '_';
    }
    const fs::path path = folder_ / (name + ".dcm");
    DcmFileFormat file(dataset.release(), OFFalse /* takes ownership */);
    OFCondition cond = EC_Normal;
    try {
      createPrivateFile(path);  // 0600 before DCMTK writes into it (fopen "wb" keeps the mode)
    } catch (const std::runtime_error& e) {
      cond = makeOFCondition(OFM_dcmdata, 1, OF_error, e.what());
    }
    if (cond.good()) cond = file.saveFile(path.c_str(), EXS_Unknown, EET_ExplicitLength, EGL_recalcGL,
                                           EPD_noChange, 0, 0, EWM_fileformat);
    if (cond.bad()) {
      std::error_code ec;
      fs::remove(path, ec);
      if (write_error_.empty()) write_error_ = "cannot write " + path.string() + ": " + cond.text();
      store_status = kStatusStoreOutOfResources;
      continue_session = OFFalse;
      return EC_Normal;
    }
    if (std::find(files_.begin(), files_.end(), path) == files_.end()) files_.push_back(path);
    store_status = kStatusSuccess;
    watchdog.restart();  // a retrieval's deadline is for the next file
    progress_.received = static_cast<int>(files_.size());
    progress_.last_file = path;
    if (options_->progress) options_->progress(progress_);
    // A server that answers each sub-operation with a pending C-GET response is asked to stop
    // there, between two sub-operations; one that does not, here.
    if (cancelRequested() && (!saw_pending_ || cancel_sent_)) onCancel(continue_session);
    return EC_Normal;
  }

  OFCondition handleCGETResponse(const T_ASC_PresentationContextID presID, RetrieveResponse* response,
                                 OFBool& continue_session) override {
    const OFCondition cond = DcmSCU::handleCGETResponse(presID, response, continue_session);
    if (response == nullptr) return cond;
    const Uint16 status = response->m_status;
    failed_ = std::max(failed_, static_cast<int>(response->m_numberOfFailedSubops));
    if (status == kStatusPending || status == kStatusPendingWarning) {
      saw_pending_ = true;
      watchdog.restart();
      const int total = static_cast<int>(response->m_numberOfCompletedSubops + response->m_numberOfFailedSubops +
                                         response->m_numberOfWarningSubops + response->m_numberOfRemainingSubops);
      if (progress_.total < 0 && total > 0) progress_.total = total;
      progress_.failed = failed_;
      // Between two sub-operations: the moment to ask the server to stop.
      if (cancelRequested()) onCancel(continue_session);
    } else {
      final_received_ = true;
      final_status_ = status;
      continue_session = OFFalse;
    }
    return cond;
  }

 private:
  /// Asks the server to stop (C-CANCEL, once); gives up waiting after the grace period.
  void onCancel(OFBool& continue_session) {
    if (!cancel_sent_) {
      cancel_sent_ = true;
      cancel_time_ = Clock::now();
      sendCANCELRequest(get_id_);
      return;
    }
    const double waited = std::chrono::duration<double>(Clock::now() - cancel_time_).count();
    if (waited > options_->cancel_grace_s) continue_session = OFFalse;
  }

  PacsServer server_;
  fs::path folder_;
  const PacsRetrieveOptions* options_ = nullptr;
  T_ASC_PresentationContextID get_id_ = 0;
  PacsRetrieveProgress progress_;
  std::vector<fs::path> files_;
  std::string write_error_;
  bool saw_pending_ = false;
  bool cancel_sent_ = false;
  Clock::time_point cancel_time_;
  bool final_received_ = false;
  Uint16 final_status_ = kStatusSuccess;
  int failed_ = 0;
};

/// `cond` as the end of a message; when the server dropped the association mid-operation, the
/// likely reason: it does not allow our AE title that operation.
std::string why(const OFCondition& cond, const PacsServer& server) {
  std::string text = cond.text();
  if (cond == DUL_PEERABORTEDASSOCIATION) {
    text += ": the server ended the association; does it know the calling AE title '" + pacsTrim(server.calling_aet) +
            "' and allow it this?";
  } else if (cond == DIMSE_BADDATA) {
    text += ": the server's answer is not a well-formed DICOM dataset (cut short, or a value that declares more "
            "bytes than were sent); nothing of it was used";
  }
  return text;
}

/// Runs one C-FIND of `keys`; returns the matches' datasets.
std::vector<std::unique_ptr<DcmDataset>> find(const PacsServer& server, DcmDataset& keys) {
  Scu scu(server);
  scu.propose(UID_FINDStudyRootQueryRetrieveInformationModel);
  scu.connect();
  const T_ASC_PresentationContextID id =
      scu.contextFor(UID_FINDStudyRootQueryRetrieveInformationModel, "queries (C-FIND, Study Root model)");
  OFList<QRResponse*> responses;
  const OFCondition cond = scu.sendFINDRequest(id, &keys, &responses);
  std::vector<std::unique_ptr<DcmDataset>> matches;
  Uint16 final_status = kStatusSuccess;
  bool final_seen = false;
  for (QRResponse* r : responses) {
    std::unique_ptr<QRResponse> owned(r);
    if (r->m_status == kStatusPending || r->m_status == kStatusPendingWarning) {
      if (r->m_dataset != nullptr) {
        matches.emplace_back(r->m_dataset);
        r->m_dataset = nullptr;  // now ours
      }
    } else {
      final_seen = true;
      final_status = r->m_status;
    }
  }
  if (cond.bad()) scu.throwIfTimedOut("C-FIND");
  if (cond.bad()) throw pacsError(server, "C-FIND failed: " + why(cond, server));
  if (!final_seen) throw pacsError(server, "C-FIND failed: the server sent no final response");
  if (final_status != kStatusSuccess) {
    throw pacsError(server, "C-FIND failed: status " + hex4(final_status) + " (" + DU_cfindStatusString(final_status) + ")");
  }
  scu.release();
  return matches;
}

/// The keys of a SERIES-level query: what we want back, `study_uid` / `series_uid` / `modality`
/// as matching keys when not empty.
void seriesKeys(DcmDataset& keys, const std::string& study_uid, const std::string& series_uid,
                const std::string& modality) {
  keys.putAndInsertString(DCM_QueryRetrieveLevel, "SERIES");
  keys.putAndInsertString(DCM_StudyInstanceUID, study_uid.c_str());
  keys.putAndInsertString(DCM_SeriesInstanceUID, series_uid.c_str());
  keys.putAndInsertString(DCM_Modality, modality.c_str());
  keys.putAndInsertString(DCM_SeriesDescription, "");
  keys.putAndInsertString(DCM_SeriesNumber, "");
  keys.putAndInsertString(DCM_NumberOfSeriesRelatedInstances, "");
}

/// A retrieval stopped on purpose: the server ended the C-GET (status Cancel), or we stop
/// listening (abort); the files received are deleted.
void endCancelled(Scu& scu, PacsRetrieveResult& result) {
  if (scu.finalReceived()) {
    result.cancel_acknowledged = scu.finalStatus() == kStatusCancel;
    scu.release();
  } else {
    scu.abortAssociation();
  }
  std::error_code ec;
  for (const fs::path& f : scu.files()) fs::remove(f, ec);
  result.cancelled = true;
}

}  // namespace

namespace detail {

PacsStudy studyFromResponse(DcmItem* ds) {
  PacsStudy s;
  s.patient_name = text(ds, DCM_PatientName);
  s.patient_id = text(ds, DCM_PatientID);
  s.patient_birth_date = text(ds, DCM_PatientBirthDate);
  s.patient_sex = text(ds, DCM_PatientSex);
  s.study_uid = text(ds, DCM_StudyInstanceUID);
  s.study_date = text(ds, DCM_StudyDate);
  s.study_time = text(ds, DCM_StudyTime);
  s.description = text(ds, DCM_StudyDescription);
  s.accession_number = text(ds, DCM_AccessionNumber);
  s.modalities = text(ds, DCM_ModalitiesInStudy);
  s.series_count = number(ds, DCM_NumberOfStudyRelatedSeries);
  return s;
}

PacsSeries seriesFromResponse(DcmItem* ds) {
  PacsSeries s;
  s.study_uid = text(ds, DCM_StudyInstanceUID);
  s.series_uid = text(ds, DCM_SeriesInstanceUID);
  s.modality = text(ds, DCM_Modality);
  s.description = text(ds, DCM_SeriesDescription);
  s.number = number(ds, DCM_SeriesNumber);
  s.instance_count = number(ds, DCM_NumberOfSeriesRelatedInstances);
  return s;
}

std::string pacsTrim(std::string_view s) {
  const auto first = s.find_first_not_of(" \t\r\n");
  if (first == std::string_view::npos) return {};
  return std::string(s.substr(first, s.find_last_not_of(" \t\r\n") - first + 1));
}

PacsError pacsError(const PacsServer& server, const std::string& what) {
  return PacsError("PACS " + server.describe() + ": " + what);
}

void checkPacsServer(const PacsServer& server) { checkServer(server); }

void pacsEchoInProcess(const PacsServer& server) {
  Scu scu(server);
  scu.propose(UID_VerificationSOPClass);
  scu.connect();
  const T_ASC_PresentationContextID id = scu.contextFor(UID_VerificationSOPClass, "verification (C-ECHO)");
  const OFCondition cond = scu.sendECHORequest(id);
  if (cond.bad()) scu.throwIfTimedOut("C-ECHO");
  if (cond.bad()) throw pacsError(server, std::string("C-ECHO failed: ") + cond.text());
  scu.release();
}

std::vector<PacsStudy> pacsFindStudiesInProcess(const PacsServer& server, const PacsStudyQuery& query) {
  DcmDataset keys;
  keys.putAndInsertString(DCM_QueryRetrieveLevel, "STUDY");
  keys.putAndInsertString(DCM_PatientName, query.patient_name.c_str());
  keys.putAndInsertString(DCM_PatientID, query.patient_id.c_str());
  keys.putAndInsertString(DCM_PatientBirthDate, "");
  keys.putAndInsertString(DCM_PatientSex, "");
  keys.putAndInsertString(DCM_StudyInstanceUID, "");
  keys.putAndInsertString(DCM_StudyDate, query.study_date.c_str());
  keys.putAndInsertString(DCM_StudyTime, "");
  keys.putAndInsertString(DCM_StudyDescription, "");
  keys.putAndInsertString(DCM_AccessionNumber, "");
  keys.putAndInsertString(DCM_ModalitiesInStudy, "");
  keys.putAndInsertString(DCM_NumberOfStudyRelatedSeries, "");
  std::vector<PacsStudy> studies;
  for (const auto& ds : find(server, keys)) {
    PacsStudy s = detail::studyFromResponse(ds.get());
    if (!s.study_uid.empty()) studies.push_back(std::move(s));
  }
  return studies;
}

std::vector<PacsSeries> pacsFindSeriesInProcess(const PacsServer& server, const std::string& study_uid,
                                                const std::string& modality) {
  if (pacsTrim(study_uid).empty()) throw pacsError(server, "a series query needs the Study Instance UID");
  DcmDataset keys;
  seriesKeys(keys, pacsTrim(study_uid), "", pacsTrim(modality));
  std::vector<PacsSeries> series;
  for (const auto& ds : find(server, keys)) {
    PacsSeries s = detail::seriesFromResponse(ds.get());
    if (s.study_uid.empty()) s.study_uid = pacsTrim(study_uid);
    if (!s.series_uid.empty()) series.push_back(std::move(s));
  }
  std::stable_sort(series.begin(), series.end(), [](const PacsSeries& a, const PacsSeries& b) { return a.number < b.number; });
  return series;
}

PacsSeries pacsFindSeriesByUidInProcess(const PacsServer& server, const std::string& series_uid) {
  if (pacsTrim(series_uid).empty()) throw pacsError(server, "no Series Instance UID given");
  DcmDataset keys;
  seriesKeys(keys, "", pacsTrim(series_uid), "");
  for (const auto& ds : find(server, keys)) {
    PacsSeries s = detail::seriesFromResponse(ds.get());
    if (s.series_uid == pacsTrim(series_uid) && !s.study_uid.empty()) return s;
  }
  throw pacsError(server, "no series with Series Instance UID " + pacsTrim(series_uid));
}

}  // namespace detail

std::string PacsServer::describe() const {
  return pacsTrim(called_aet) + " at " + pacsTrim(host) + ":" + std::to_string(port);
}

std::vector<PacsPatient> pacsPatientsOf(const std::vector<PacsStudy>& studies) {
  std::vector<PacsPatient> patients;
  for (const PacsStudy& s : studies) {
    const auto same = [&](const PacsPatient& p) {
      return s.patient_id.empty() ? p.id.empty() && p.name == s.patient_name : p.id == s.patient_id;
    };
    auto it = std::find_if(patients.begin(), patients.end(), same);
    if (it == patients.end()) {
      patients.push_back({s.patient_name, s.patient_id, s.patient_birth_date, s.patient_sex, {}});
      it = std::prev(patients.end());
    }
    it->studies.push_back(s);
  }
  return patients;
}

namespace detail {

PacsRetrieveResult pacsRetrieveSeriesInProcess(const PacsServer& server, const std::string& study_uid,
                                               const std::string& series_uid, const fs::path& out_dir,
                                               const PacsRetrieveOptions& options) {
  const auto t0 = Clock::now();
  PacsRetrieveOptions opts = options;
  std::string study = pacsTrim(study_uid);
  const std::string series = pacsTrim(series_uid);
  if (series.empty()) throw pacsError(server, "no Series Instance UID given");
  if (study.empty() || opts.expected_instances < 0) {
    const PacsSeries found = pacsFindSeriesByUidInProcess(server, series);
    if (study.empty()) study = found.study_uid;
    if (opts.expected_instances < 0) opts.expected_instances = found.instance_count;
  }
  // The series folder and its missing parents owner-only (0700), its files 0600: a whole
  // series with the patient's name and images.
  std::error_code ec;
  try {
    createPrivateDirectories(out_dir);
  } catch (const std::runtime_error& e) {
    throw pacsError(server, e.what());
  }

  Scu scu(server);
  scu.propose(UID_GETStudyRootQueryRetrieveInformationModel);
  // The files come back as C-STORE sub-operations on this association: we are their SCP.
  for (int i = 0; i < numberOfDcmLongSCUStorageSOPClassUIDs; ++i) {
    scu.propose(dcmLongSCUStorageSOPClassUIDs[i], ASC_SC_ROLE_SCP);
  }
  scu.connect();
  const T_ASC_PresentationContextID id =
      scu.contextFor(UID_GETStudyRootQueryRetrieveInformationModel, "retrieval by C-GET (Study Root model)");
  DcmDataset keys;
  keys.putAndInsertString(DCM_QueryRetrieveLevel, "SERIES");
  keys.putAndInsertString(DCM_StudyInstanceUID, study.c_str());
  keys.putAndInsertString(DCM_SeriesInstanceUID, series.c_str());
  scu.startRetrieve(out_dir, opts, id);
  const OFCondition cond = scu.sendCGETRequest(id, &keys, nullptr);

  PacsRetrieveResult result;
  result.folder = out_dir;
  result.failed = scu.failedSubops();
  if (scu.cancelRequested() && (scu.cancelSent() || !scu.finalReceived())) {
    endCancelled(scu, result);
    result.seconds = std::chrono::duration<double>(Clock::now() - t0).count();
    return result;
  }
  const auto remove_files = [&] {
    for (const fs::path& f : scu.files()) fs::remove(f, ec);
  };
  if (!scu.writeError().empty()) {
    remove_files();
    throw pacsError(server, "C-GET of series " + series + ": " + scu.writeError());
  }
  if (cond.bad()) {
    remove_files();
    scu.throwIfTimedOut("C-GET of series " + series + " (" + std::to_string(scu.files().size()) + " files so far)");
    throw pacsError(server, "C-GET of series " + series + " failed after " + std::to_string(scu.files().size()) +
                           " files: " + why(cond, server));
  }
  const Uint16 status = scu.finalStatus();
  const bool warning = status == kStatusGetWarning || (status & 0xF000) == 0xB000;
  if (!scu.finalReceived() || (status != kStatusSuccess && !warning && status != kStatusCancel)) {
    remove_files();
    throw pacsError(server, "C-GET of series " + series + " failed: status " + hex4(status) + " (" +
                           DU_cgetStatusString(status) + ")");
  }
  scu.release();
  if (scu.files().empty()) {
    throw pacsError(server, "C-GET of series " + series + " brought no files" +
                           (result.failed > 0 ? " (" + std::to_string(result.failed) +
                                                    " failed on the server: a storage class or transfer syntax we "
                                                    "did not offer?)"
                                              : ""));
  }
  result.files = scu.files();
  result.seconds = std::chrono::duration<double>(Clock::now() - t0).count();
  return result;
}

}  // namespace detail
}  // namespace vh::io
