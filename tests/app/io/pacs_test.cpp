// The PACS client (vh/io/pacs.h) against a real PACS: Orthanc, started by the ctest fixture
// pacs_orthanc_fixture.sh on free ports with the shared small CT head stored in it by DCMTK's
// storescu. The oracles are independent of the code under test: the dataset's own files (their
// count, UIDs and pixel bytes read with DCMTK's dcmdata) and the folder load of the original.

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <map>
#include <string>
#include <thread>

#include <arpa/inet.h>
#include <netinet/in.h>
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

#include "io_test_support.h"
#include "vh/io/pacs.h"
#include "vh/io/volume_loader.h"

namespace vh::io {
namespace {

namespace fs = std::filesystem;
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
    s.connect_timeout_s = 5;
    s.response_timeout_s = 20;
    return s;
  }
};

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

/// A loopback port that nothing listens on: one the kernel just gave out, closed again.
int closedPort() {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  socklen_t len = sizeof addr;
  const bool ok = ::bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) == 0 &&
                  ::getsockname(fd, reinterpret_cast<sockaddr*>(&addr), &len) == 0;
  ::close(fd);
  return ok ? ntohs(addr.sin_port) : 9;  // 9: discard, unused on test machines
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
  const auto t0 = Clock::now();
  try {
    pacsEcho(server);
    ADD_FAILURE() << "an echo to a closed port succeeded";
  } catch (const PacsError& e) {
    std::printf("[ TIMING   ] wrong port: failed in %.3f s: %s\n", secondsSince(t0), e.what());
    EXPECT_CONTAINS(e.what(), "PACS " + server.describe());
    EXPECT_CONTAINS(e.what(), "no connection");
  }
  EXPECT_LT(secondsSince(t0), server.connect_timeout_s + 2.0);
}

TEST(Pacs, AnHttpPortIsNotTakenForADicomServer) {
  VH_REQUIRE_ORTHANC();
  PacsServer server = fixture().server();
  server.port = std::stoi(fixture().get("http_port"));  // Orthanc's web server answers there
  const auto t0 = Clock::now();
  try {
    pacsEcho(server);
    ADD_FAILURE() << "an echo to an HTTP server succeeded";
  } catch (const PacsError& e) {
    std::printf("[ TIMING   ] HTTP port: failed in %.3f s: %s\n", secondsSince(t0), e.what());
    EXPECT_CONTAINS(e.what(), "not a DICOM server");
  }
  EXPECT_LT(secondsSince(t0), server.connect_timeout_s + 2.0);
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
  server.connect_timeout_s = 2;
  const auto t0 = Clock::now();
  try {
    pacsFindStudies(server);
    ADD_FAILURE() << "a query to a silent server succeeded";
  } catch (const PacsError& e) {
    std::printf("[ TIMING   ] silent server: failed in %.3f s: %s\n", secondsSince(t0), e.what());
    EXPECT_CONTAINS(e.what(), "no answer to the association request within 2 s");
  }
  EXPECT_GE(secondsSince(t0), 1.5);
  EXPECT_LT(secondsSince(t0), 5.0);
  ::close(listener);
}

/// A DICOM server (DCMTK's DcmSCP) that answers every C-FIND with a failure status.
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
    getConfig().setConnectionBlockingMode(DUL_NOBLOCK);  // so that listen() can stop
    getConfig().setConnectionTimeout(1);
  }
  std::atomic<bool> stop{false};

 protected:
  OFBool stopAfterConnectionTimeout() override { return stop.load(); }
  OFCondition handleIncomingCommand(T_DIMSE_Message* msg, const DcmPresentationContextInfo& info) override {
    if (msg->CommandField != DIMSE_C_FIND_RQ) return DcmSCP::handleIncomingCommand(msg, info);
    DcmDataset* keys = nullptr;
    const OFCondition cond = receiveFINDRequest(msg->msg.CFindRQ, info.presentationContextID, keys);
    delete keys;
    if (cond.bad()) return cond;
    return sendFINDResponse(info.presentationContextID, msg->msg.CFindRQ.MessageID,
                            msg->msg.CFindRQ.AffectedSOPClassUID, nullptr, kStatus);
  }
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
  server.connect_timeout_s = 2;
  // Up once it answers an echo.
  bool up = false;
  for (int i = 0; i < 50 && !up; ++i) {
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
