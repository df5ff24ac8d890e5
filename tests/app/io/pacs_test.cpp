// The PACS client (vh/io/pacs.h) against a real PACS: Orthanc, started by the ctest fixture
// pacs_orthanc_fixture.sh on free ports with the shared small CT head stored in it by DCMTK's
// storescu. The oracles are independent of the code under test: the dataset's own files (their
// count, UIDs and pixel bytes read with DCMTK's dcmdata) and the folder load of the original.

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <deque>
#include <fstream>
#include <functional>
#include <map>
#include <string>
#include <thread>

#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <gtest/gtest.h>
#include <vtkImageData.h>
#include <vtkPointData.h>
#include <vtkDataArray.h>

#include <dcmtk/config/osconfig.h>
#include <dcmtk/dcmdata/dcdeftag.h>
#include <dcmtk/dcmdata/dcfilefo.h>
#include <dcmtk/dcmdata/dcelem.h>
#include <dcmtk/dcmdata/dcuid.h>
#include <dcmtk/dcmnet/scp.h>

#include "hostile_pacs.h"
#include "io_test_support.h"
#include "vh/io/pacs.h"
#include "vh/io/volume_loader.h"

namespace vh::io {
namespace {

namespace fs = std::filesystem;
using test::closedPort;
using test::secondsSince;
using test::TempDir;
using Clock = std::chrono::steady_clock;

/// What the fixture wrote (fixture.env: key=value lines).
struct Fixture {
  std::map<std::string, std::string> values;
  bool ready() const { return values.count("status") && values.at("status") == "ready"; }
  std::string get(const std::string& key) const { return values.count(key) ? values.at(key) : std::string(); }
  PacsServer server() const {
    PacsServer s;
    s.host = get("host");
    s.port = std::stoi(get("dicom_port"));
    s.called_aet = get("aet");
    s.calling_aet = get("client_aet");
    s.timeout_s = 20;
    return s;
  }
};

Fixture readFixture(const char* env_file) {
  Fixture fx;
  std::ifstream in(env_file);
  std::string line;
  while (std::getline(in, line)) {
    const auto eq = line.find('=');
    if (eq != std::string::npos) fx.values[line.substr(0, eq)] = line.substr(eq + 1);
  }
  return fx;
}

/// The second Orthanc: DICOM TLS only, its CA and certificates made by the fixture.
const Fixture& tlsFixture() {
  static const Fixture f = readFixture(VH_PACS_TLS_FIXTURE_ENV);
  return f;
}

const Fixture& fixture() {
  static const Fixture f = [] {
    Fixture fx;
    std::ifstream in(VH_PACS_FIXTURE_ENV);
    std::string line;
    while (std::getline(in, line)) {
      const auto eq = line.find('=');
      if (eq != std::string::npos) fx.values[line.substr(0, eq)] = line.substr(eq + 1);
    }
    return fx;
  }();
  return f;
}

#define VH_REQUIRE_ORTHANC()                                                                        \
  if (!fixture().ready()) {                                                                         \
    GTEST_SKIP() << "no test PACS: "                                                                \
                 << (fixture().get("reason").empty() ? std::string("the fixture did not run (") + \
                                                           VH_PACS_FIXTURE_ENV + " missing)"        \
                                                     : fixture().get("reason"));                    \
  }

#define VH_REQUIRE_TLS_ORTHANC()                                                                        \
  if (!tlsFixture().ready()) {                                                                          \
    GTEST_SKIP() << "no DICOM TLS test PACS: "                                                          \
                 << (tlsFixture().get("reason").empty() ? std::string("the fixture did not run (") + \
                                                              VH_PACS_TLS_FIXTURE_ENV + " missing)"     \
                                                        : tlsFixture().get("reason"));                  \
  }

/// One file of the original series, read with DCMTK: its UIDs and pixel bytes.
struct Instance {
  std::string study_uid, series_uid, patient_name, patient_id;
  std::string pixels;
};

Instance readInstance(const fs::path& path) {
  DcmFileFormat file;
  EXPECT_TRUE(file.loadFile(path.c_str()).good()) << path;
  DcmDataset* ds = file.getDataset();
  Instance i;
  OFString v;
  if (ds->findAndGetOFString(DCM_StudyInstanceUID, v).good()) i.study_uid = v.c_str();
  if (ds->findAndGetOFString(DCM_SeriesInstanceUID, v).good()) i.series_uid = v.c_str();
  if (ds->findAndGetOFStringArray(DCM_PatientName, v).good()) i.patient_name = v.c_str();
  if (ds->findAndGetOFString(DCM_PatientID, v).good()) i.patient_id = v.c_str();
  DcmElement* pixel = nullptr;
  if (ds->findAndGetElement(DCM_PixelData, pixel).good() && pixel != nullptr) {
    Uint8* bytes = nullptr;
    if (pixel->getUint8Array(bytes).good() && bytes != nullptr) {
      i.pixels.assign(reinterpret_cast<const char*>(bytes), pixel->getLength());
    }
  }
  return i;
}

/// The original dataset's files by SOP Instance UID.
std::map<std::string, Instance> originalInstances() {
  std::map<std::string, Instance> out;
  for (const auto& e : fs::directory_iterator(fixture().get("dataset"))) {
    if (e.path().extension() != ".dcm") continue;
    DcmFileFormat file;
    if (file.loadFile(e.path().c_str()).bad()) continue;
    OFString uid;
    file.getDataset()->findAndGetOFString(DCM_SOPInstanceUID, uid);
    out[uid.c_str()] = readInstance(e.path());
  }
  return out;
}

/// FNV-1a over a volume's scalars, with its dimensions: equal volumes give equal sums.
std::uint64_t voxelChecksum(vtkImageData* image) {
  std::uint64_t h = 1469598103934665603ull;
  const auto mix = [&](const void* p, std::size_t n) {
    const auto* b = static_cast<const unsigned char*>(p);
    for (std::size_t k = 0; k < n; ++k) h = (h ^ b[k]) * 1099511628211ull;
  };
  int dims[3];
  image->GetDimensions(dims);
  mix(dims, sizeof dims);
  vtkDataArray* a = image->GetPointData()->GetScalars();
  mix(a->GetVoidPointer(0), static_cast<std::size_t>(a->GetNumberOfValues()) * static_cast<std::size_t>(a->GetDataTypeSize()));
  return h;
}

TEST(Pacs, EchoAnswers) {
  VH_REQUIRE_ORTHANC();
  const auto t0 = Clock::now();
  EXPECT_NO_THROW(pacsEcho(fixture().server()));
  std::printf("[ TIMING   ] C-ECHO %.3f s\n", secondsSince(t0));
}

TEST(Pacs, FindListsThePatientStudyAndSeriesWithItsInstanceCount) {
  VH_REQUIRE_ORTHANC();
  const std::map<std::string, Instance> original = originalInstances();
  ASSERT_FALSE(original.empty());
  const Instance& any = original.begin()->second;
  const PacsServer server = fixture().server();

  auto t0 = Clock::now();
  const std::vector<PacsStudy> studies = pacsFindStudies(server);
  std::printf("[ TIMING   ] C-FIND STUDY %.3f s: %zu studies\n", secondsSince(t0), studies.size());
  ASSERT_EQ(studies.size(), 1u);
  EXPECT_EQ(studies[0].study_uid, any.study_uid);
  EXPECT_EQ(studies[0].patient_id, any.patient_id);
  EXPECT_EQ(studies[0].patient_name, any.patient_name);
  EXPECT_EQ(studies[0].series_count, 1);
  const std::vector<PacsPatient> patients = pacsPatientsOf(studies);
  ASSERT_EQ(patients.size(), 1u);
  EXPECT_EQ(patients[0].id, any.patient_id);
  EXPECT_EQ(patients[0].studies.size(), 1u);

  // A patient-name filter with a wildcard finds it; another name finds nothing.
  PacsStudyQuery query;
  query.patient_name = any.patient_name.substr(0, 3) + "*";
  EXPECT_EQ(pacsFindStudies(server, query).size(), 1u) << query.patient_name;
  query.patient_name = "NOBODY-HERE*";
  EXPECT_TRUE(pacsFindStudies(server, query).empty());

  t0 = Clock::now();
  const std::vector<PacsSeries> series = pacsFindSeries(server, any.study_uid);
  std::printf("[ TIMING   ] C-FIND SERIES %.3f s: %zu series, %d instances (dataset: %zu files)\n", secondsSince(t0),
              series.size(), series.empty() ? -1 : series[0].instance_count, original.size());
  ASSERT_EQ(series.size(), 1u);
  EXPECT_EQ(series[0].series_uid, any.series_uid);
  EXPECT_EQ(series[0].study_uid, any.study_uid);
  EXPECT_EQ(series[0].modality, "CT");
  EXPECT_EQ(series[0].instance_count, static_cast<int>(original.size()));
  EXPECT_EQ(std::to_string(series[0].instance_count), fixture().get("instances"));
  EXPECT_TRUE(pacsFindSeries(server, any.study_uid, "MR").empty());

  const PacsSeries by_uid = pacsFindSeriesByUid(server, any.series_uid);
  EXPECT_EQ(by_uid.study_uid, any.study_uid);
  try {
    pacsFindSeriesByUid(server, "1.2.3.4.5.6.7");
    ADD_FAILURE() << "an unknown series UID was found";
  } catch (const PacsError& e) {
    EXPECT_CONTAINS(e.what(), "no series with Series Instance UID 1.2.3.4.5.6.7");
  }
}

TEST(Pacs, GetRetrievesTheSeriesWithTheOriginalVoxels) {
  VH_REQUIRE_ORTHANC();
  const std::map<std::string, Instance> original = originalInstances();
  ASSERT_FALSE(original.empty());
  const Instance& any = original.begin()->second;
  TempDir out("pacs_get");
  int calls = 0, last_total = 0, last_received = 0;
  PacsRetrieveOptions options;
  options.progress = [&](const PacsRetrieveProgress& p) {
    ++calls;
    EXPECT_EQ(p.received, last_received + 1);
    last_received = p.received;
    last_total = p.total;
    EXPECT_TRUE(fs::exists(p.last_file));
  };
  const auto t0 = Clock::now();
  // No study UID: looked up by the series' UID.
  const PacsRetrieveResult r = pacsRetrieveSeries(fixture().server(), "", any.series_uid, out.path() / "series", options);
  std::printf("[ TIMING   ] C-GET %zu files in %.3f s (%.1f ms per file)\n", r.files.size(), secondsSince(t0),
              1e3 * secondsSince(t0) / std::max<std::size_t>(1, r.files.size()));
  EXPECT_FALSE(r.cancelled);
  EXPECT_EQ(r.failed, 0);
  ASSERT_EQ(r.files.size(), original.size());
  EXPECT_EQ(calls, static_cast<int>(original.size()));
  EXPECT_EQ(last_total, static_cast<int>(original.size()));

  // Each retrieved file: an original instance (by SOP Instance UID) with its pixel bytes.
  std::size_t same_pixels = 0;
  for (const fs::path& f : r.files) {
    const std::string uid = f.stem().string();
    ASSERT_TRUE(original.count(uid)) << f;
    const Instance got = readInstance(f);
    EXPECT_EQ(got.series_uid, any.series_uid);
    same_pixels += got.pixels == original.at(uid).pixels && !got.pixels.empty() ? 1 : 0;
  }
  EXPECT_EQ(same_pixels, original.size());

  // The retrieved folder opens through the normal DICOM loader with the same voxels and
  // geometry as the original folder.
  const LoadedVolume a = loadVolume(fixture().get("dataset"));
  const LoadedVolume b = loadVolume(out.path() / "series");
  ASSERT_TRUE(a.image && b.image);
  const std::uint64_t ca = voxelChecksum(a.image.get());
  const std::uint64_t cb = voxelChecksum(b.image.get());
  std::printf("[ CHECKSUM ] voxels FNV-1a: original folder %016llx, retrieved %016llx\n",
              static_cast<unsigned long long>(ca), static_cast<unsigned long long>(cb));
  EXPECT_EQ(ca, cb);
  EXPECT_EQ(a.field->geometry().dims, b.field->geometry().dims);
  EXPECT_TRUE(a.field->geometry().spacing_m.isApprox(b.field->geometry().spacing_m, 1e-12));
  EXPECT_TRUE(a.field->geometry().origin_W_m.isApprox(b.field->geometry().origin_W_m, 1e-12));
  EXPECT_EQ(b.info.modality, "CT");
}

TEST(Pacs, AShortTimeoutLeavesAFastServerAlone) {
  // The control of the trickling server: a real PACS answering at its own speed within a short
  // timeout. A retrieval's deadline is for each next file, so a series may take longer in all.
  VH_REQUIRE_ORTHANC();
  const std::map<std::string, Instance> original = originalInstances();
  ASSERT_FALSE(original.empty());
  PacsServer server = fixture().server();
  // Short against the default 30 s, yet long enough for a loaded machine's Orthanc to answer
  // each step (the trickling server below is cut off at 3 s with nothing but 2-byte PDUs).
  server.timeout_s = 5;
  EXPECT_NO_THROW(pacsEcho(server));
  EXPECT_EQ(pacsFindStudies(server).size(), 1u);
  TempDir out("pacs_short_timeout");
  const auto t0 = Clock::now();
  const PacsRetrieveResult r = pacsRetrieveSeries(server, "", original.begin()->second.series_uid, out.path());
  std::printf("[ TIMING   ] C-GET with a 5 s timeout: %zu files in %.3f s\n", r.files.size(), secondsSince(t0));
  EXPECT_EQ(r.files.size(), original.size());
}

TEST(Pacs, CancelStopsARetrievalPartWay) {
  VH_REQUIRE_ORTHANC();
  const std::map<std::string, Instance> original = originalInstances();
  ASSERT_GT(original.size(), 20u);
  TempDir out("pacs_cancel");
  std::atomic<bool> cancel{false};
  int received = 0;
  PacsRetrieveOptions options;
  options.cancel = &cancel;
  options.progress = [&](const PacsRetrieveProgress& p) {
    received = p.received;
    if (p.received == 5) cancel = true;
  };
  const auto t0 = Clock::now();
  const PacsRetrieveResult r =
      pacsRetrieveSeries(fixture().server(), original.begin()->second.study_uid,
                         original.begin()->second.series_uid, out.path(), options);
  const double s = secondsSince(t0);
  std::printf("[ TIMING   ] cancelled after 5 files: %d received of %zu, stopped in %.3f s (%s)\n", received,
              original.size(), s,
              r.cancel_acknowledged ? "the server ended the C-GET: status Cancel" : "association aborted");
  EXPECT_TRUE(r.cancelled);
  EXPECT_TRUE(r.files.empty());
  EXPECT_GE(received, 5);
  EXPECT_LT(received, static_cast<int>(original.size()) / 2);
  EXPECT_TRUE(fs::is_empty(out.path())) << "the files of a cancelled retrieval are deleted";
  // The server is fine afterwards.
  EXPECT_NO_THROW(pacsEcho(fixture().server()));
}

TEST(Pacs, AWrongPortFailsClearlyInBoundedTime) {
  VH_REQUIRE_ORTHANC();
  PacsServer server = fixture().server();
  server.port = closedPort();
  server.timeout_s = 20;  // a refused connection fails at once; the bound below is the timeout's
  const auto t0 = Clock::now();
  try {
    pacsEcho(server);
    ADD_FAILURE() << "an echo to a closed port succeeded";
  } catch (const PacsError& e) {
    std::printf("[ TIMING   ] wrong port: failed in %.3f s: %s\n", secondsSince(t0), e.what());
    EXPECT_CONTAINS(e.what(), "PACS " + server.describe());
    EXPECT_CONTAINS(e.what(), "no connection");
  }
  EXPECT_LT(secondsSince(t0), server.timeout_s + 2.0);
}

TEST(Pacs, AnHttpPortIsNotTakenForADicomServer) {
  VH_REQUIRE_ORTHANC();
  PacsServer server = fixture().server();
  server.port = std::stoi(fixture().get("http_port"));  // Orthanc's web server answers there
  // Orthanc's HTTP answer, not the timeout, must end the echo: generous for a loaded machine.
  server.timeout_s = 20;
  const auto t0 = Clock::now();
  try {
    pacsEcho(server);
    ADD_FAILURE() << "an echo to an HTTP server succeeded";
  } catch (const PacsError& e) {
    std::printf("[ TIMING   ] HTTP port: failed in %.3f s: %s\n", secondsSince(t0), e.what());
    EXPECT_CONTAINS(e.what(), "not a DICOM server");
  }
  EXPECT_LT(secondsSince(t0), server.timeout_s + 2.0);
}

TEST(Pacs, ASilentServerFailsAfterTheConnectionTimeout) {
  // A socket that accepts connections (the kernel's backlog) and never says a word.
  const int listener = ::socket(AF_INET, SOCK_STREAM, 0);
  ASSERT_GE(listener, 0);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  addr.sin_port = 0;  // any free port
  ASSERT_EQ(::bind(listener, reinterpret_cast<sockaddr*>(&addr), sizeof addr), 0);
  ASSERT_EQ(::listen(listener, 4), 0);
  socklen_t len = sizeof addr;
  ASSERT_EQ(::getsockname(listener, reinterpret_cast<sockaddr*>(&addr), &len), 0);
  PacsServer server;
  server.host = "127.0.0.1";
  server.port = ntohs(addr.sin_port);
  server.timeout_s = 2;
  const auto t0 = Clock::now();
  try {
    pacsFindStudies(server);
    ADD_FAILURE() << "a query to a silent server succeeded";
  } catch (const PacsError& e) {
    std::printf("[ TIMING   ] silent server: failed in %.3f s: %s\n", secondsSince(t0), e.what());
    EXPECT_CONTAINS(e.what(), "no complete answer to the association request within the timeout of 2 s");
  }
  // Not before the 2 s timeout, and not as late as the default 30 s one: the bound leaves a
  // loaded machine's late wake-up room.
  EXPECT_GE(secondsSince(t0), 1.5);
  EXPECT_LT(secondsSince(t0), 12.0);
  ::close(listener);
}

/// A DICOM server (DCMTK's DcmSCP) that answers every C-FIND and C-GET with a failure status.
class FailingFindServer : public DcmSCP {
 public:
  static constexpr Uint16 kStatus = 0xC000;  // Failed: unable to process (PS3.4 C.4.1.1.4)

  explicit FailingFindServer(Uint16 port) {
    OFList<OFString> syntaxes;
    syntaxes.push_back(UID_LittleEndianExplicitTransferSyntax);
    syntaxes.push_back(UID_LittleEndianImplicitTransferSyntax);
    getConfig().setAETitle("FAILINGPACS");
    getConfig().setPort(port);
    getConfig().addPresentationContext(UID_VerificationSOPClass, syntaxes);
    getConfig().addPresentationContext(UID_FINDStudyRootQueryRetrieveInformationModel, syntaxes);
    getConfig().addPresentationContext(UID_GETStudyRootQueryRetrieveInformationModel, syntaxes);
    getConfig().setConnectionBlockingMode(DUL_NOBLOCK);  // so that listen() can stop
    getConfig().setConnectionTimeout(1);
  }
  std::atomic<bool> stop{false};

 protected:
  OFBool stopAfterConnectionTimeout() override { return stop.load(); }
  OFCondition handleIncomingCommand(T_DIMSE_Message* msg, const DcmPresentationContextInfo& info) override {
    if (msg->CommandField == DIMSE_C_GET_RQ) return failGet(msg->msg.CGetRQ, info.presentationContextID);
    if (msg->CommandField != DIMSE_C_FIND_RQ) return DcmSCP::handleIncomingCommand(msg, info);
    DcmDataset* keys = nullptr;
    const OFCondition cond = receiveFINDRequest(msg->msg.CFindRQ, info.presentationContextID, keys);
    delete keys;
    if (cond.bad()) return cond;
    return sendFINDResponse(info.presentationContextID, msg->msg.CFindRQ.MessageID,
                            msg->msg.CFindRQ.AffectedSOPClassUID, nullptr, kStatus);
  }
  OFCondition failGet(const T_DIMSE_C_GetRQ& request, T_ASC_PresentationContextID id) {
    DcmDataset* keys = nullptr;
    const OFCondition cond = receiveDIMSEDataset(&id, &keys);
    delete keys;
    if (cond.bad()) return cond;
    T_DIMSE_Message response{};
    response.CommandField = DIMSE_C_GET_RSP;
    T_DIMSE_C_GetRSP& rsp = response.msg.CGetRSP;
    rsp.MessageIDBeingRespondedTo = request.MessageID;
    OFStandard::strlcpy(rsp.AffectedSOPClassUID, request.AffectedSOPClassUID, sizeof rsp.AffectedSOPClassUID);
    rsp.DataSetType = DIMSE_DATASET_NULL;
    rsp.DimseStatus = kStatus;
    rsp.opts = O_GET_AFFECTEDSOPCLASSUID;
    return sendDIMSEMessage(id, &response, nullptr);
  }
};

/// A man in the middle between our client and a DICOM server on `upstream_port`: it passes the
/// server's first PDU (the association's answer) at once, then cuts every P-DATA-TF PDU the
/// server sends into P-DATA-TF PDUs that carry two bytes each (PS3.8 9.3.5 and PS3.7 E: a PDV
/// may hold any even-length fragment of a message) and sends one a second. Each PDU arrives well within any per-read
/// timeout; a message never ends. It counts the PDUs it trickled and the connections the client
/// closed (recv() returning 0: the OS's word), and drops a connection after kGiveUpS, so that a
/// client without a deadline fails the test's time bound instead of hanging it.
class TricklingProxy {
 public:
  static constexpr double kGiveUpS = 20.0;

  explicit TricklingProxy(int upstream_port) : upstream_port_(upstream_port) {
    listener_ = ::socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in addr = loopback(0);
    socklen_t len = sizeof addr;
    ok_ = listener_ >= 0 && ::bind(listener_, reinterpret_cast<sockaddr*>(&addr), sizeof addr) == 0 &&
          ::listen(listener_, 4) == 0 && ::getsockname(listener_, reinterpret_cast<sockaddr*>(&addr), &len) == 0;
    port_ = ntohs(addr.sin_port);
    thread_ = std::thread([this] { run(); });
  }
  ~TricklingProxy() {
    stop_ = true;
    thread_.join();
    ::close(listener_);
  }
  bool ok() const { return ok_; }
  int port() const { return port_; }
  int pdusTrickled() const { return trickled_; }
  int closedByClient() const { return closed_by_client_; }

 private:
  static sockaddr_in loopback(int port) {
    sockaddr_in addr{};
    addr.sin_family = AF_INET;
    addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    addr.sin_port = htons(static_cast<uint16_t>(port));
    return addr;
  }
  void run() {
    while (!stop_) {
      pollfd p{listener_, POLLIN, 0};
      if (::poll(&p, 1, 100) <= 0) continue;
      const int client = ::accept(listener_, nullptr, nullptr);
      if (client < 0) continue;
      const int server = ::socket(AF_INET, SOCK_STREAM, 0);
      const sockaddr_in addr = loopback(upstream_port_);
      if (::connect(server, reinterpret_cast<const sockaddr*>(&addr), sizeof addr) == 0) relay(client, server);
      ::close(server);
      ::close(client);
    }
  }
  /// Splits the complete PDUs at the start of `in` into `out`: the first whole, P-DATA-TF ones
  /// into two-byte PDUs, others whole.
  /// A PDU to send, and whether it is one of the two-byte ones (sent one a second).
  struct Pdu {
    std::string bytes;
    bool trickled;
  };
  void slice(std::string& in, std::deque<Pdu>& out) {
    while (in.size() >= 6) {
      const std::size_t length = (std::size_t{static_cast<unsigned char>(in[2])} << 24) |
                                 (std::size_t{static_cast<unsigned char>(in[3])} << 16) |
                                 (std::size_t{static_cast<unsigned char>(in[4])} << 8) | static_cast<unsigned char>(in[5]);
      if (in.size() < 6 + length) return;
      const std::string pdu = in.substr(0, 6 + length);
      in.erase(0, 6 + length);
      if (pdu[0] != 0x04 || !first_passed_) {
        out.push_back({pdu, false});
        first_passed_ = true;
        continue;
      }
      for (std::size_t at = 6; at + 6 <= pdu.size();) {  // PDV items: length, context, control header, data
        const std::size_t item = (std::size_t{static_cast<unsigned char>(pdu[at])} << 24) |
                                 (std::size_t{static_cast<unsigned char>(pdu[at + 1])} << 16) |
                                 (std::size_t{static_cast<unsigned char>(pdu[at + 2])} << 8) |
                                 static_cast<unsigned char>(pdu[at + 3]);
        const char context = pdu[at + 4];
        const char control = pdu[at + 5];
        for (std::size_t k = at + 6; k + 1 < at + 4 + item; k += 2) {
          const bool last = k + 2 == at + 4 + item;  // only the last two keep "last fragment"
          const char header = last ? control : static_cast<char>(control & ~0x02);
          out.push_back(
              {{'\x04', '\0', '\0', '\0', '\0', '\x08', '\0', '\0', '\0', '\x04', context, header, pdu[k], pdu[k + 1]}, true});
        }
        at += 4 + item;
      }
    }
  }
  void relay(int client, int server) {
    first_passed_ = false;
    std::string from_server;
    std::deque<Pdu> queue;
    const auto start = Clock::now();
    auto next = start;
    while (!stop_ && secondsSince(start) < kGiveUpS) {
      pollfd fds[2] = {{client, POLLIN, 0}, {server, POLLIN, 0}};
      if (::poll(fds, 2, 50) > 0) {
        char buf[65536];
        if (fds[0].revents != 0) {
          const ssize_t n = ::recv(client, buf, sizeof buf, 0);
          if (n <= 0) {
            ++closed_by_client_;
            return;
          }
          ::send(server, buf, static_cast<std::size_t>(n), MSG_NOSIGNAL);
        }
        if (fds[1].revents != 0) {
          const ssize_t n = ::recv(server, buf, sizeof buf, 0);
          if (n > 0) from_server.append(buf, static_cast<std::size_t>(n));
        }
      }
      slice(from_server, queue);
      while (!queue.empty() && !queue.front().trickled) {  // in order, the whole ones at once
        ::send(client, queue.front().bytes.data(), queue.front().bytes.size(), MSG_NOSIGNAL);
        queue.pop_front();
      }
      if (!queue.empty() && Clock::now() >= next) {
        ::send(client, queue.front().bytes.data(), queue.front().bytes.size(), MSG_NOSIGNAL);
        queue.pop_front();
        ++trickled_;
        next = Clock::now() + std::chrono::seconds(1);
      }
    }
  }

  int upstream_port_;
  int listener_ = -1;
  int port_ = 0;
  bool ok_ = false;
  bool first_passed_ = false;
  std::atomic<bool> stop_{false};
  std::atomic<int> trickled_{0};
  std::atomic<int> closed_by_client_{0};
  std::thread thread_;
};

TEST(Pacs, AFindFailureStatusIsNamed) {
  const int port = closedPort();
  FailingFindServer scp(static_cast<Uint16>(port));
  std::thread listening([&] { scp.listen(); });
  PacsServer server;
  server.host = "127.0.0.1";
  server.port = port;
  server.called_aet = "FAILINGPACS";
  server.calling_aet = "VHTEST";
  server.timeout_s = 20;  // the failure status must end the C-FIND, not a timeout on a loaded machine
  // Up once it answers an echo (polled with a generous deadline: the thread may start late).
  bool up = false;
  const auto give_up = Clock::now() + std::chrono::seconds(30);
  while (!up && Clock::now() < give_up) {
    try {
      pacsEcho(server);
      up = true;
    } catch (const PacsError&) {
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
  }
  EXPECT_TRUE(up) << "the test server did not start on port " << port;
  try {
    pacsFindStudies(server);
    ADD_FAILURE() << "a failed C-FIND returned";
  } catch (const PacsError& e) {
    std::printf("[ MESSAGE  ] C-FIND failure: %s\n", e.what());
    EXPECT_CONTAINS(e.what(), "PACS FAILINGPACS at 127.0.0.1:" + std::to_string(port));
    EXPECT_CONTAINS(e.what(), "C-FIND failed: status 0xC000");
  }
  scp.stop = true;
  listening.join();
}

/// Starts `scp` listening on a thread; true once it answers an echo from `server`.
bool startServer(FailingFindServer& scp, std::thread& listening, const PacsServer& server) {
  listening = std::thread([&scp] { scp.listen(); });
  const auto give_up = Clock::now() + std::chrono::seconds(30);  // the thread may start late
  while (Clock::now() < give_up) {
    try {
      pacsEcho(server);
      return true;
    } catch (const PacsError&) {
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
  }
  return false;
}

TEST(Pacs, ATricklingServerIsCutOffAtTheTimeout) {
  // A server that sends its answers two bytes a second, each pair in a PDU of its own: DCMTK's
  // own timeouts restart with every PDU and never fire; the operation's deadline must.
  const int port = closedPort();
  FailingFindServer scp(static_cast<Uint16>(port));
  PacsServer direct;
  direct.host = "127.0.0.1";
  direct.port = port;
  direct.called_aet = "FAILINGPACS";
  direct.calling_aet = "VHTEST";
  std::thread listening;
  ASSERT_TRUE(startServer(scp, listening, direct)) << "the test server did not start on port " << port;
  TricklingProxy proxy(port);
  ASSERT_TRUE(proxy.ok());
  PacsServer server = direct;
  server.port = proxy.port();
  server.timeout_s = 3;
  TempDir out("pacs_trickle");
  PacsRetrieveOptions known;  // the study UID and the count given: no C-FIND before the C-GET
  known.expected_instances = 1;
  const std::vector<std::pair<std::string, std::function<void()>>> operations = {
      {"C-ECHO", [&] { pacsEcho(server); }},
      {"C-FIND", [&] { pacsFindStudies(server); }},
      {"C-GET", [&] { pacsRetrieveSeries(server, "1.2.3", "1.2.3.4", out.path() / "series", known); }},
  };
  int closed = 0;
  for (const auto& [name, operation] : operations) {
    const int trickled_before = proxy.pdusTrickled();
    const auto t0 = Clock::now();
    try {
      operation();
      ADD_FAILURE() << name << " through a trickling server succeeded";
    } catch (const PacsError& e) {
      std::printf("[ TIMING   ] trickling server, %s: failed in %.3f s after %d two-byte PDUs: %s\n", name.c_str(),
                  secondsSince(t0), proxy.pdusTrickled() - trickled_before, e.what());
      EXPECT_CONTAINS(e.what(), name);
      EXPECT_CONTAINS(e.what(), "did not finish within the timeout of 3 s");
    }
    const double s = secondsSince(t0);
    EXPECT_GE(s, 2.5) << name << ": it failed before the timeout, so not because of it";
    EXPECT_LT(s, 3.0 * server.timeout_s) << name;
    // More than one PDU came within the timeout: no wait for the next one was long.
    EXPECT_GE(proxy.pdusTrickled() - trickled_before, 2) << name;
    // The proxy sees the connection closed by the client.
    ++closed;
    const auto give_up = Clock::now() + std::chrono::seconds(30);
    while (proxy.closedByClient() < closed && Clock::now() < give_up) {
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
    EXPECT_EQ(proxy.closedByClient(), closed) << name;
  }
  EXPECT_TRUE(!fs::exists(out.path() / "series") || fs::is_empty(out.path() / "series"));
  // The server itself, not through the proxy, still answers at once.
  EXPECT_NO_THROW(pacsEcho(direct));
  scp.stop = true;
  listening.join();
}

/// The TLS Orthanc with its CA, as a client that trusts that CA connects to it.
PacsServer tlsServer() {
  PacsServer s = tlsFixture().server();
  s.tls = true;
  s.ca_cert = tlsFixture().get("ca_cert");
  return s;
}

TEST(PacsTls, EchoAndFindOverTlsWithTheServersCa) {
  VH_REQUIRE_TLS_ORTHANC();
  const PacsServer server = tlsServer();
  EXPECT_NO_THROW(pacsEcho(server));
  // The study of the files the fixture stored, as DCMTK reads them from the dataset.
  const Instance any = originalInstances().begin()->second;
  const std::vector<PacsStudy> studies = pacsFindStudies(server);
  ASSERT_EQ(studies.size(), 1u);
  EXPECT_EQ(studies[0].study_uid, any.study_uid);
  EXPECT_EQ(studies[0].patient_id, any.patient_id);
  const std::vector<PacsSeries> series = pacsFindSeries(server, any.study_uid);
  ASSERT_EQ(series.size(), 1u);
  EXPECT_EQ(std::to_string(series[0].instance_count), tlsFixture().get("instances"));
  // With our own certificate too (the server checks it against the same CA when given).
  PacsServer with_cert = server;
  with_cert.client_cert = tlsFixture().get("client_cert");
  with_cert.client_key = tlsFixture().get("client_key");
  EXPECT_NO_THROW(pacsEcho(with_cert));
}

TEST(PacsTls, AServerCertificateFromAnotherCaIsRefused) {
  VH_REQUIRE_TLS_ORTHANC();
  PacsServer server = tlsServer();
  server.ca_cert = tlsFixture().get("other_ca_cert");
  try {
    pacsFindStudies(server);
    ADD_FAILURE() << "a server whose certificate does not verify was queried";
  } catch (const PacsError& e) {
    std::printf("[ MESSAGE  ] another CA: %s\n", e.what());
    EXPECT_CONTAINS(e.what(), "the server's certificate was refused");
    // OpenSSL's reason: the chain ends in a CA we do not trust.
    EXPECT_CONTAINS(e.what(), "self-signed certificate in certificate chain");
    EXPECT_CONTAINS(e.what(), server.ca_cert);
  }
}

TEST(PacsTls, AServerCertificateForAnotherHostIsRefused) {
  VH_REQUIRE_TLS_ORTHANC();
  PacsServer server = tlsServer();
  server.host = "127.0.0.2";  // the loopback too, but not an address the certificate names
  try {
    pacsEcho(server);
    ADD_FAILURE() << "a certificate for 127.0.0.1 and localhost was taken for 127.0.0.2";
  } catch (const PacsError& e) {
    std::printf("[ MESSAGE  ] another host: %s\n", e.what());
    EXPECT_CONTAINS(e.what(), "the server's certificate was refused: IP address mismatch");
  }
}

TEST(PacsTls, APlainClientToTheTlsPortFailsClearly) {
  VH_REQUIRE_TLS_ORTHANC();
  PacsServer server = tlsServer();
  server.tls = false;
  try {
    pacsEcho(server);
    ADD_FAILURE() << "a plain association with a DICOM TLS port succeeded";
  } catch (const PacsError& e) {
    std::printf("[ MESSAGE  ] plain client, TLS port: %s\n", e.what());
    EXPECT_CONTAINS(e.what(), "does it expect DICOM TLS on that port?");
  }
  // And a TLS client to the plain port of the other Orthanc.
  VH_REQUIRE_ORTHANC();
  PacsServer plain = fixture().server();
  plain.tls = true;
  plain.ca_cert = server.ca_cert;
  try {
    pacsEcho(plain);
    ADD_FAILURE() << "a TLS association with a plain DICOM port succeeded";
  } catch (const PacsError& e) {
    std::printf("[ MESSAGE  ] TLS client, plain port: %s\n", e.what());
    EXPECT_CONTAINS(e.what(), "DICOM TLS: the handshake failed");
  }
}

TEST(PacsTls, MissingOrMismatchedFilesAreNamedBeforeAnyConnection) {
  PacsServer server;
  server.tls = true;
  try {
    pacsEcho(server);
    ADD_FAILURE();
  } catch (const PacsError& e) {
    EXPECT_CONTAINS(e.what(), "no CA certificate given");
  }
  server.ca_cert = "/nonexistent/ca.pem";
  try {
    pacsEcho(server);
    ADD_FAILURE();
  } catch (const PacsError& e) {
    EXPECT_CONTAINS(e.what(), "the CA certificate '/nonexistent/ca.pem' is not a readable file");
  }
  if (!tlsFixture().ready()) return;
  server.ca_cert = tlsFixture().get("ca_cert");
  server.client_cert = tlsFixture().get("client_cert");
  server.client_key = tlsFixture().get("ca_cert");  // a certificate, not a key
  try {
    pacsEcho(server);
    ADD_FAILURE();
  } catch (const PacsError& e) {
    EXPECT_CONTAINS(e.what(), "is not an unencrypted PEM key");
  }
}

TEST(Pacs, AnUnknownCalledAeTitleIsRejected) {
  VH_REQUIRE_ORTHANC();
  PacsServer server = fixture().server();
  server.called_aet = "NOT-THE-PACS";
  try {
    pacsFindStudies(server);
    ADD_FAILURE() << "a query to the wrong AE title succeeded";
  } catch (const PacsError& e) {
    EXPECT_CONTAINS(e.what(), "rejected the association");
    EXPECT_CONTAINS(e.what(), "NOT-THE-PACS");
  }
}

TEST(Pacs, AnUnknownCallingAeTitleMayNotQuery) {
  VH_REQUIRE_ORTHANC();
  PacsServer server = fixture().server();
  server.calling_aet = "STRANGER";  // not among Orthanc's modalities: echo yes, C-FIND no
  EXPECT_NO_THROW(pacsEcho(server));
  try {
    pacsFindStudies(server);
    ADD_FAILURE() << "an unknown AE's query succeeded";
  } catch (const PacsError& e) {
    std::printf("[ MESSAGE  ] unknown calling AE title: %s\n", e.what());
    EXPECT_CONTAINS(e.what(), "PACS " + server.describe());
    EXPECT_CONTAINS(e.what(), "C-FIND failed");
    EXPECT_CONTAINS(e.what(), "calling AE title 'STRANGER'");
  }
}

TEST(Pacs, BadSettingsAreNamedBeforeAnyConnection) {
  PacsServer server;
  server.port = 0;
  try {
    pacsEcho(server);
    ADD_FAILURE();
  } catch (const PacsError& e) {
    EXPECT_CONTAINS(e.what(), "port 0 is not in 1..65535");
  }
  server.port = 104;
  server.calling_aet = "A-NAME-LONGER-THAN-16";
  try {
    pacsEcho(server);
    ADD_FAILURE();
  } catch (const PacsError& e) {
    EXPECT_CONTAINS(e.what(), "1 to 16 characters");
  }
}

}  // namespace
}  // namespace vh::io
