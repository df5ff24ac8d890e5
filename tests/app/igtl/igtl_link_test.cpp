// The OpenIGTLink link (vh/igtl/igtl_link.h) against loopback clients written with
// libOpenIGTLink (and one plain socket that never reads): transforms at the asked rate with RAS
// values, IMAGE messages opened with their geometry, malformed messages and dropped clients
// survived, and a stalled client never slowing the haptic thread.
#include "vh/igtl/igtl_link.h"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <signal.h>
#include <sys/socket.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstring>
#include <fstream>
#include <map>
#include <sstream>
#include <thread>
#include <utility>

#include <Eigen/Geometry>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <igtlClientSocket.h>
#include <igtlImageMessage.h>
#include <igtlMessageHeader.h>
#include <igtlSensorMessage.h>
#include <igtlStringMessage.h>
#include <igtlTimeStamp.h>
#include <igtlTransformMessage.h>
#include <igtlUnit.h>
#include <igtl_header.h>
#include <igtl_util.h>

#include "igtl_message.h"
#include "runtime_test_support.h"
#include "vh/runtime/scene.h"
#include "vh/runtime/session.h"
#include "vh/runtime/snapshot_channel.h"

namespace vh::igtl {
namespace {

using namespace std::chrono_literals;
using Clock = std::chrono::steady_clock;
using haptics::Pose;

double secondsSince(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

/// A port no one listens on now: probed with a plain socket (igtl::ServerSocket cannot bind
/// port 0), starting from a pid-dependent place so parallel test processes spread out.
int probeFreePort() {
  static int next = 20000 + static_cast<int>(getpid() % 2000) * 10;
  for (int tries = 0; tries < 500; ++tries) {
    const int port = next++;
    if (next > 60000) next = 20000;
    const int fd = socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_addr.s_addr = htonl(INADDR_ANY);
    a.sin_port = htons(static_cast<std::uint16_t>(port));
    const bool ok = bind(fd, reinterpret_cast<sockaddr*>(&a), sizeof(a)) == 0;
    close(fd);
    if (ok) return port;
  }
  return 0;
}

/// Starts `link` options on a free port (retrying when another process took it meanwhile).
std::unique_ptr<IgtlLink> startLink(std::shared_ptr<runtime::SnapshotChannel> channel, LinkOptions options) {
  for (int tries = 0; tries < 20; ++tries) {
    options.port = probeFreePort();
    auto link = std::make_unique<IgtlLink>(channel, options);
    try {
      link->start();
      return link;
    } catch (const std::runtime_error&) {
    }
  }
  ADD_FAILURE() << "no free port to listen on";
  return nullptr;
}

/// What a client read: one entry per message.
struct Received {
  std::string type, name;
  double t_s = 0.0;                         ///< Receive time since the client connected [s].
  Eigen::Matrix4d matrix = Eigen::Matrix4d::Zero();  ///< TRANSFORM
  std::vector<double> values;               ///< SENSOR
  std::uint64_t unit = 0;                     ///< SENSOR
  std::string text;                         ///< STRING
  double stamp_s = 0.0;                     ///< Header time stamp [s since the epoch].
};

/// A loopback OpenIGTLink client (libOpenIGTLink's ClientSocket and message classes).
class Client {
 public:
  bool connect(int port) {
    socket_ = ::igtl::ClientSocket::New();
    for (int i = 0; i < 50; ++i) {
      if (socket_->ConnectToServer("127.0.0.1", port) == 0) {
        // Generous: the link streams continuously, so a read that expects a message returns as
        // soon as one arrives; the timeout only ends a read the link never answers (a loaded
        // machine may delay the link's thread by far more than a frame period).
        socket_->SetReceiveTimeout(10000);
        t0_ = Clock::now();
        return true;
      }
      std::this_thread::sleep_for(20ms);
    }
    return false;
  }
  void close() { socket_->CloseSocket(); }
  ::igtl::ClientSocket& socket() { return *socket_; }

  /// Reads one message; false on timeout or a closed socket.
  bool read(Received& out) {
    ::igtl::MessageHeader::Pointer header = ::igtl::MessageHeader::New();
    header->InitPack();
    if (socket_->Receive(header->GetPackPointer(), header->GetPackSize()) != header->GetPackSize()) return false;
    header->Unpack();
    out = Received{};
    out.t_s = secondsSince(t0_);
    out.type = header->GetDeviceType();
    out.name = header->GetDeviceName();
    ::igtl::TimeStamp::Pointer ts = ::igtl::TimeStamp::New();
    header->GetTimeStamp(ts);
    out.stamp_s = ts->GetTimeStamp();
    const auto body = [&](::igtl::MessageBase& m) {
      m.SetMessageHeader(header);
      m.AllocatePack();
      if (socket_->Receive(m.GetPackBodyPointer(), m.GetPackBodySize()) != m.GetPackBodySize()) return false;
      return (m.Unpack(1) & ::igtl::MessageHeader::UNPACK_BODY) != 0;
    };
    if (out.type == "TRANSFORM") {
      ::igtl::TransformMessage::Pointer m = ::igtl::TransformMessage::New();
      if (!body(*m)) return false;
      ::igtl::Matrix4x4 matrix;
      m->GetMatrix(matrix);
      for (int r = 0; r < 4; ++r) {
        for (int c = 0; c < 4; ++c) out.matrix(r, c) = matrix[r][c];
      }
    } else if (out.type == "SENSOR") {
      ::igtl::SensorMessage::Pointer m = ::igtl::SensorMessage::New();
      if (!body(*m)) return false;
      for (unsigned i = 0; i < m->GetLength(); ++i) out.values.push_back(m->GetValue(i));
      out.unit = m->GetUnit();
    } else if (out.type == "STRING") {
      ::igtl::StringMessage::Pointer m = ::igtl::StringMessage::New();
      if (!body(*m)) return false;
      out.text = m->GetString();
    } else {
      if (socket_->Skip(header->GetBodySizeToRead(), 1) != header->GetBodySizeToRead()) return false;
    }
    return true;
  }

  /// Reads for `duration`; @return every message.
  std::vector<Received> readFor(std::chrono::duration<double> duration) {
    std::vector<Received> all;
    const auto end = Clock::now() + duration;
    Received r;
    while (Clock::now() < end && read(r)) all.push_back(r);
    return all;
  }

 private:
  ::igtl::ClientSocket::Pointer socket_;
  Clock::time_point t0_;
};

/// Publishes one coupling and one solver snapshot into `channel` (the test thread is the
/// channel's only producer).
void publish(runtime::SnapshotChannel& channel, const Pose& X_WP, const Pose& X_WD, const Eigen::Vector3d& force_W_N,
             int contacts, std::uint64_t tick, std::int64_t time_ns) {
  runtime::CouplingSnapshot& c = channel.couplingSlot();
  c.tick = tick;
  c.time_ns = time_ns;
  c.X_WP = X_WP;
  c.X_WD = X_WD;
  c.force_W_N = force_W_N;
  channel.publishCoupling();
  runtime::SolverSnapshot& s = channel.solverSlot();
  s.tick = tick;
  s.contacts = contacts;
  channel.publishSolver();
}

std::int64_t steadyNowNs() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(Clock::now().time_since_epoch()).count();
}
double wallNowS() {
  return std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
}

class IgtlLinkServing : public ::testing::Test {
 protected:
  // A client that vanishes must not kill the test process (libOpenIGTLink's send has no
  // MSG_NOSIGNAL).
  void SetUp() override { signal(SIGPIPE, SIG_IGN); }
};

// ---- Conversions ---------------------------------------------------------------------------

TEST(IgtlConversion, RasMatrixNegatesXAndYInMillimetres) {
  // 90 degrees about x of W (LPS): in RAS, whose x and y point the other way, that is -90
  // degrees about x; the translation (10, 20, 30) mm becomes (-10, -20, 30) mm.
  const Pose X_WT(Eigen::Quaterniond(Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitX())),
                  Eigen::Vector3d(0.010, 0.020, 0.030));
  Eigen::Matrix4d expected;
  expected << 1, 0, 0, -10,  //
      0, 0, 1, -20,          //
      0, -1, 0, 30,          //
      0, 0, 0, 1;
  EXPECT_TRUE(toRasMatrix_mm(X_WT).isApprox(expected, 1e-12)) << toRasMatrix_mm(X_WT);
  EXPECT_TRUE(toRas(Eigen::Vector3d(1, 2, 3)).isApprox(Eigen::Vector3d(-1, -2, 3)));
}

TEST(IgtlConversion, VolumeFromIjkToRasIsInLpsMetres) {
  Eigen::Matrix4d X = Eigen::Matrix4d::Identity();
  X.diagonal().head<3>() = Eigen::Vector3d(0.5, 0.7, 1.2);
  X.block<3, 1>(0, 3) = Eigen::Vector3d(10, 20, 30);
  std::vector<std::byte> bytes(2 * 3 * 4);
  const io::LoadedVolume v = volumeFromIjkToRas({2, 3, 4}, X, haptics::VoxelType::kUInt8, bytes, "T");
  const haptics::VolumeGeometry& g = v.field->geometry();
  EXPECT_TRUE(g.spacing_m.isApprox(Eigen::Vector3d(0.0005, 0.0007, 0.0012)));
  EXPECT_TRUE(g.origin_W_m.isApprox(Eigen::Vector3d(-0.010, -0.020, 0.030)));
  EXPECT_TRUE(g.direction_W.isApprox(Eigen::Vector3d(-1, -1, 1).asDiagonal().toDenseMatrix()));
  EXPECT_EQ(v.info.format, "OpenIGTLink");
  EXPECT_EQ(v.info.description, "T");
  ASSERT_NE(v.image, nullptr);
  X(0, 1) = 0.3;  // sheared
  EXPECT_THROW(volumeFromIjkToRas({2, 3, 4}, X, haptics::VoxelType::kUInt8, bytes, "T"), std::invalid_argument);
}

TEST(IgtlConversion, OptionsAreChecked) {
  LinkOptions o;
  o.port = 0;
  EXPECT_THROW(IgtlLink(nullptr, o), std::invalid_argument);
  o.port = 18944;
  o.rate_Hz = 0.0;
  EXPECT_THROW(IgtlLink(nullptr, o), std::invalid_argument);
  o.rate_Hz = 5000.0;
  o.servo_rate_Hz = 1000.0;
  EXPECT_DOUBLE_EQ(IgtlLink(nullptr, o).rate_Hz(), 1000.0);  // clamped to the servo rate
  EXPECT_EQ(IgtlLink(nullptr, o).statusText(), "OpenIGTLink off");
  o.bind_address = "localhost";  // a name, not an address
  EXPECT_THROW(IgtlLink(nullptr, o), std::invalid_argument);
  o.bind_address = "0.0.0.0";  // every interface: only with the clients named
  EXPECT_THROW(IgtlLink(nullptr, o), std::invalid_argument);
  o.allowed_clients = {"192.168.1.20"};
  EXPECT_NO_THROW(IgtlLink(nullptr, o));
  o.allowed_clients = {"192.168.1.20; rm -rf"};
  EXPECT_THROW(IgtlLink(nullptr, o), std::invalid_argument);
}

TEST(IgtlConversion, EscapesControlBytes) {
  EXPECT_EQ(escapeControl("CT\x1b[2J\n\x7f\\ok"), "CT\\x1b[2J\\x0a\\x7f\\\\ok");
  EXPECT_EQ(escapeControl("Slicer CT-1"), "Slicer CT-1");
}

// ---- Streaming -----------------------------------------------------------------------------

class IgtlLinkRate : public IgtlLinkServing, public ::testing::WithParamInterface<double> {};

TEST_P(IgtlLinkRate, StreamsTransformsAtTheAskedRateWithRasValues) {
  const double rate_Hz = GetParam();
  auto channel = std::make_shared<runtime::SnapshotChannel>();
  const Pose X_WP(Eigen::Quaterniond(Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized())),
                  Eigen::Vector3d(0.010, -0.020, 0.030));
  const Pose X_WD(Eigen::Quaterniond(Eigen::AngleAxisd(-0.4, Eigen::Vector3d(0, 1, 1).normalized())),
                  Eigen::Vector3d(0.011, -0.018, 0.027));
  const Eigen::Vector3d force_W_N(1.5, -2.0, 0.25);
  // The snapshot's time on the wall clock, bracketed by two wall-clock reads (a preemption
  // between the reads widens the bracket instead of failing the check).
  const double wall_before_s = wallNowS();
  const std::int64_t t_ns = steadyNowNs();
  const double wall_after_s = wallNowS();
  const double expected_stamp_s = 0.5 * (wall_before_s + wall_after_s);
  publish(*channel, X_WP, X_WD, force_W_N, 7, 1234, t_ns);

  LinkOptions options;
  options.rate_Hz = rate_Hz;
  options.segment_name = [](const runtime::HapticSnapshot& s) { return s.contacts > 0 ? std::string("bone") : std::string(); };
  const auto t_start = Clock::now();  // before the link's thread starts pacing its frames
  auto link = startLink(channel, options);
  ASSERT_NE(link, nullptr);
  Client client;
  ASSERT_TRUE(client.connect(link->options().port));
  const std::vector<Received> all = client.readFor(1.5s);

  // Independently: RAS = diag(-1, -1, 1) LPS for both the rotation's rows and columns, mm.
  const auto expectedRas = [](const Pose& X) {
    Eigen::Matrix4d M = Eigen::Matrix4d::Identity();
    const Eigen::Matrix3d R = X.R_AB.toRotationMatrix();
    const double s[3] = {-1.0, -1.0, 1.0};
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) M(r, c) = s[r] * s[c] * R(r, c);
      M(r, 3) = s[r] * 1000.0 * X.p_AB_m[r];
    }
    return M;
  };
  std::map<std::string, std::vector<const Received*>> by_name;
  for (const Received& r : all) by_name[r.name].push_back(&r);
  ASSERT_FALSE(by_name["ProxyToRAS"].empty());
  ASSERT_FALSE(by_name["DeviceToRAS"].empty());
  ASSERT_FALSE(by_name["Force"].empty());
  ASSERT_FALSE(by_name["ContactState"].empty());
  const Received& proxy = *by_name["ProxyToRAS"].back();
  const Received& device = *by_name["DeviceToRAS"].back();
  EXPECT_EQ(proxy.type, "TRANSFORM");
  EXPECT_TRUE(proxy.matrix.isApprox(expectedRas(X_WP), 1e-5)) << proxy.matrix << "\nexpected\n" << expectedRas(X_WP);
  EXPECT_TRUE(device.matrix.isApprox(expectedRas(X_WD), 1e-5)) << device.matrix;
  EXPECT_NEAR(proxy.matrix(0, 3), -10.0, 1e-4);  // x negated, mm
  EXPECT_NEAR(proxy.matrix(1, 3), 20.0, 1e-4);   // y negated, mm
  EXPECT_NEAR(proxy.matrix(2, 3), 30.0, 1e-4);
  // The snapshot's time, not the send time.
  EXPECT_NEAR(proxy.stamp_s, expected_stamp_s, 0.005 + 0.5 * (wall_after_s - wall_before_s));
  const Received& force = *by_name["Force"].back();
  EXPECT_EQ(force.type, "SENSOR");
  ASSERT_EQ(force.values.size(), 3u);
  EXPECT_DOUBLE_EQ(force.values[0], -1.5);
  EXPECT_DOUBLE_EQ(force.values[1], 2.0);
  EXPECT_DOUBLE_EQ(force.values[2], 0.25);
  EXPECT_NE(force.unit, 0u);
  const nlohmann::json state = nlohmann::json::parse(by_name["ContactState"].back()->text);
  EXPECT_EQ(state["contacts"], 7);
  EXPECT_EQ(state["tick"], 1234);
  EXPECT_NEAR(state["force_N"].get<double>(), force_W_N.norm(), 1e-12);
  EXPECT_EQ(state["segment"], "bone");

  // The rate: frames over the span between the first and the last (the client's clock). How
  // close it comes to the asked rate depends on the machine's load (a late frame is not made up
  // for): printed only. What follows from the link's pacing (absolute deadlines one period
  // apart, never a burst): it never sends faster than asked, so the frames sent by the stop are
  // at most one more than the asked rate times the time since before the start.
  const auto& frames = by_name["ProxyToRAS"];
  const double span_s = frames.back()->t_s - frames.front()->t_s;
  if (frames.size() >= 2 && span_s > 0.0) {
    std::cout << "[ rate ] asked " << rate_Hz << " Hz, received " << static_cast<double>(frames.size() - 1) / span_s
              << " Hz (" << frames.size() << " frames over " << span_s << " s)\n";
  }
  EXPECT_EQ(link->status().rate_Hz, rate_Hz);
  EXPECT_NEAR(static_cast<double>(by_name["DeviceToRAS"].size()), static_cast<double>(frames.size()), 1.0);

  const auto t_stop = Clock::now();
  link->stop();
  const double stop_ms = 1e3 * secondsSince(t_stop);
  const double running_s = secondsSince(t_start);
  const std::uint64_t sent = link->status().frames_sent;
  std::cout << "[ stop ] " << stop_ms << " ms with a client connected; " << sent << " frames sent in " << running_s
            << " s\n";
  EXPECT_LE(static_cast<double>(sent), rate_Hz * running_s + 1.0) << "faster than the asked rate";
  EXPECT_LE(frames.size(), sent);
  // Prompt: the link's thread waits at most 50 ms at a time for its next frame or the client;
  // the bound leaves a loaded machine's wake-up delays room, and still fails a stop that waits
  // for a client or a socket timeout.
  EXPECT_LT(stop_ms, 1000.0);
}

INSTANTIATE_TEST_SUITE_P(Rates, IgtlLinkRate, ::testing::Values(60.0, 250.0),
                         [](const auto& param_info) { return std::to_string(static_cast<int>(param_info.param)) + "Hz"; });

// ---- Receiving volumes ---------------------------------------------------------------------

/// A 20 x 16 x 12 int16 IMAGE with spacing (0.5, 0.7, 1.2) mm, first voxel at `corner_RAS_mm`,
/// axes `N_RAS` (columns), values v(i, j, k) = i + 20 j - 7 k; `coordinate` RAS or LPS (the
/// geometry is then given in LPS), `big_endian` swaps the voxels' bytes.
::igtl::ImageMessage::Pointer makeImage(const Eigen::Matrix3d& N_RAS, const Eigen::Vector3d& corner_RAS_mm,
                                        bool lps = false, bool big_endian = false) {
  const int dims[3] = {20, 16, 12};
  const float spacing[3] = {0.5f, 0.7f, 1.2f};
  ::igtl::ImageMessage::Pointer m = ::igtl::ImageMessage::New();
  m->SetDimensions(dims[0], dims[1], dims[2]);
  m->SetSpacing(spacing[0], spacing[1], spacing[2]);
  m->SetScalarTypeToInt16();
  m->SetDeviceName("SlicerCT");
  m->SetEndian(big_endian ? ::igtl::ImageMessage::ENDIAN_BIG : ::igtl::ImageMessage::ENDIAN_LITTLE);
  // OpenIGTLink's origin is the image's centre.
  const Eigen::Vector3d centre = corner_RAS_mm + N_RAS * Eigen::Vector3d(0.5 * 19 * 0.5, 0.5 * 15 * 0.7, 0.5 * 11 * 1.2);
  const Eigen::Matrix3d F = Eigen::Vector3d(-1, -1, 1).asDiagonal();
  const Eigen::Matrix3d N = lps ? Eigen::Matrix3d(F * N_RAS) : N_RAS;
  const Eigen::Vector3d p = lps ? Eigen::Vector3d(F * centre) : centre;
  ::igtl::Matrix4x4 matrix;
  ::igtl::IdentityMatrix(matrix);
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) matrix[r][c] = static_cast<float>(N(r, c));
    matrix[r][3] = static_cast<float>(p[r]);
  }
  m->SetMatrix(matrix);
  m->SetCoordinateSystem(lps ? ::igtl::ImageMessage::COORDINATE_LPS : ::igtl::ImageMessage::COORDINATE_RAS);
  m->AllocateScalars();
  auto* v = static_cast<std::int16_t*>(m->GetScalarPointer());
  for (int k = 0; k < dims[2]; ++k) {
    for (int j = 0; j < dims[1]; ++j) {
      for (int i = 0; i < dims[0]; ++i) {
        std::int16_t value = static_cast<std::int16_t>(i + 20 * j - 7 * k);
        if (big_endian) value = static_cast<std::int16_t>(((value & 0xff) << 8) | ((value >> 8) & 0xff));
        v[i + dims[0] * (j + dims[1] * k)] = value;
      }
    }
  }
  m->Pack();
  return m;
}

Eigen::Matrix3d obliqueAxes() {
  return Eigen::AngleAxisd(0.5, Eigen::Vector3d(1, 1, 0.5).normalized()).toRotationMatrix();
}

void expectSlicerCt(const io::LoadedVolume& v, const Eigen::Matrix3d& N_RAS, const Eigen::Vector3d& corner_RAS_mm) {
  ASSERT_NE(v.field, nullptr);
  const haptics::VolumeGeometry& g = v.field->geometry();
  EXPECT_EQ(g.dims, (std::array<int, 3>{20, 16, 12}));
  EXPECT_TRUE(g.spacing_m.isApprox(Eigen::Vector3d(0.0005, 0.0007, 0.0012), 1e-6)) << g.spacing_m.transpose();
  const Eigen::Matrix3d F = Eigen::Vector3d(-1, -1, 1).asDiagonal();
  EXPECT_TRUE(g.origin_W_m.isApprox(1e-3 * F * corner_RAS_mm, 1e-5)) << g.origin_W_m.transpose();
  EXPECT_TRUE(g.direction_W.isApprox(F * N_RAS, 1e-5)) << g.direction_W;
  EXPECT_EQ(v.field->voxelType(), haptics::VoxelType::kInt16);
  for (const auto& [i, j, k] : std::vector<std::array<int, 3>>{{0, 0, 0}, {19, 0, 0}, {3, 15, 0}, {7, 9, 11}, {19, 15, 11}}) {
    EXPECT_DOUBLE_EQ(v.field->voxel(i, j, k), i + 20 * j - 7 * k) << i << " " << j << " " << k;
  }
  EXPECT_EQ(v.info.format, "OpenIGTLink");
  EXPECT_EQ(v.info.description, "SlicerCT");
  EXPECT_NE(v.image, nullptr);
}

std::optional<io::LoadedVolume> waitForVolume(IgtlLink& link) {
  std::optional<io::LoadedVolume> v;
  test::waitUntil([&] { return (v = link.takeReceivedVolume()).has_value(); });
  return v;
}

// What libOpenIGTLink takes as it comes is checked by the link: a byte order that is neither
// big (1) nor little (2) and a spacing beyond any scan's are refused naming the value (an endian
// of 7 was read as big-endian; a spacing of 1e38 mm was refused as "a zero or non-finite axis").
TEST(IgtlImage, AnUnknownByteOrderAndAnAbsurdSpacingAreRefusedNamingTheValue) {
  const auto decode = [](::igtl::ImageMessage::Pointer m) {
    m->Pack();
    const auto* p = static_cast<const unsigned char*>(m->GetPackPointer());
    detail::HeaderBytes header{};
    std::memcpy(header.data(), p, detail::kHeaderSize);
    const std::vector<unsigned char> body(p + detail::kHeaderSize, p + m->GetPackSize());
    return detail::decodeImageMessage(header, body);
  };
  const auto refusal = [&](::igtl::ImageMessage::Pointer m) {
    try {
      (void)decode(m);
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("(taken)");
  };
  EXPECT_EQ(decode(makeImage(Eigen::Matrix3d::Identity(), Eigen::Vector3d::Zero())).field->geometry().dims[0], 20)
      << "the same message as it should be";
  ::igtl::ImageMessage::Pointer endian = makeImage(Eigen::Matrix3d::Identity(), Eigen::Vector3d::Zero());
  endian->SetEndian(7);
  EXPECT_NE(refusal(endian).find("endian 7 (1: big-endian, 2: little-endian)"), std::string::npos) << refusal(endian);
  ::igtl::ImageMessage::Pointer huge = makeImage(Eigen::Matrix3d::Identity(), Eigen::Vector3d::Zero());
  huge->SetSpacing(1e38f, 0.7f, 1.2f);
  // (libOpenIGTLink carries the spacing in the matrix's column norms: 1e38 comes back as inf.)
  EXPECT_NE(refusal(huge).find("mm along axis 0 (expected 0.001 to 10000 mm)"), std::string::npos) << refusal(huge);
  ::igtl::ImageMessage::Pointer tiny = makeImage(Eigen::Matrix3d::Identity(), Eigen::Vector3d::Zero());
  tiny->SetSpacing(0.5f, 1e-9f, 1.2f);
  EXPECT_NE(refusal(tiny).find("along axis 1"), std::string::npos) << refusal(tiny);
}

TEST_F(IgtlLinkServing, ReceivedImageOpensWithItsSpacingOriginAndDirection) {
  auto link = startLink(nullptr, LinkOptions{});
  ASSERT_NE(link, nullptr);
  Client client;
  ASSERT_TRUE(client.connect(link->options().port));
  const Eigen::Matrix3d N = obliqueAxes();
  const Eigen::Vector3d corner(12.5, -30.25, 47.0);
  ::igtl::ImageMessage::Pointer image = makeImage(N, corner);
  ASSERT_EQ(client.socket().Send(image->GetPackPointer(), image->GetPackSize()), 1);
  const std::optional<io::LoadedVolume> v = waitForVolume(*link);
  ASSERT_TRUE(v.has_value()) << "no volume; status: " << link->statusText();
  expectSlicerCt(*v, N, corner);

  // The same volume in LPS and big-endian.
  image = makeImage(N, corner, /*lps=*/true, /*big_endian=*/true);
  ASSERT_EQ(client.socket().Send(image->GetPackPointer(), image->GetPackSize()), 1);
  const std::optional<io::LoadedVolume> v2 = waitForVolume(*link);
  ASSERT_TRUE(v2.has_value());
  expectSlicerCt(*v2, N, corner);
  EXPECT_EQ(link->status().images_received, 2u);

  // It opens as a scene, exactly as a loaded file.
  const runtime::SceneSpec spec = runtime::sceneForLoadedVolume(*v);
  EXPECT_EQ(spec.volume.path, "igtl:SlicerCT");
  const runtime::LoadedScene scene = runtime::loadScene(spec, *v);
  EXPECT_EQ(scene.volume.field, v->field);
  EXPECT_NE(scene.tool, nullptr);
  EXPECT_GT(scene.isovalue, v->field->minValue());
  EXPECT_LT(scene.isovalue, v->field->maxValue());
}

// ---- Robustness ----------------------------------------------------------------------------

/// The image's packed bytes with the body cut to `body_bytes` and the header's size and CRC
/// made consistent with the cut body (a message that is well-formed on the wire but whose
/// IMAGE header promises more voxels than it carries).
std::vector<unsigned char> truncatedImage(::igtl::ImageMessage& image, std::size_t body_bytes) {
  const auto* p = static_cast<const unsigned char*>(image.GetPackPointer());
  std::vector<unsigned char> bytes(p, p + IGTL_HEADER_SIZE + body_bytes);
  const std::uint64_t crc = crc64(bytes.data() + IGTL_HEADER_SIZE, body_bytes, 0ULL);
  for (int i = 0; i < 8; ++i) {
    bytes[42 + i] = static_cast<unsigned char>(static_cast<std::uint64_t>(body_bytes) >> (56 - 8 * i));
    bytes[50 + i] = static_cast<unsigned char>(crc >> (56 - 8 * i));
  }
  return bytes;
}

TEST_F(IgtlLinkServing, MalformedMessagesAndDroppedClientsLeaveTheLinkServing) {
  auto channel = std::make_shared<runtime::SnapshotChannel>();
  publish(*channel, Pose(), Pose(), Eigen::Vector3d::Zero(), 0, 1, steadyNowNs());
  LinkOptions options;
  options.rate_Hz = 100.0;
  options.max_message_bytes = 1 << 20;
  auto link = startLink(channel, options);
  ASSERT_NE(link, nullptr);
  const int port = link->options().port;
  const Eigen::Matrix3d N = obliqueAxes();
  const Eigen::Vector3d corner(1, 2, 3);

  {  // A bad CRC, then an IMAGE whose voxels are cut short: both rejected, the connection kept.
    Client client;
    ASSERT_TRUE(client.connect(port));
    ::igtl::ImageMessage::Pointer image = makeImage(N, corner);
    std::vector<unsigned char> bytes(static_cast<const unsigned char*>(image->GetPackPointer()),
                                     static_cast<const unsigned char*>(image->GetPackPointer()) + image->GetPackSize());
    bytes[IGTL_HEADER_SIZE + 200] ^= 0x5a;
    ASSERT_EQ(client.socket().Send(bytes.data(), static_cast<int>(bytes.size())), 1);
    const std::vector<unsigned char> cut = truncatedImage(*image, 72 + 100);
    ASSERT_EQ(client.socket().Send(cut.data(), static_cast<int>(cut.size())), 1);
    const std::vector<unsigned char> tiny = truncatedImage(*image, 10);  // shorter than the image header
    ASSERT_EQ(client.socket().Send(tiny.data(), static_cast<int>(tiny.size())), 1);
    ASSERT_TRUE(test::waitUntil([&] { return link->status().messages_rejected >= 3; })) << link->status().messages_rejected;
    image = makeImage(N, corner);
    ASSERT_EQ(client.socket().Send(image->GetPackPointer(), image->GetPackSize()), 1);
    const std::optional<io::LoadedVolume> v = waitForVolume(*link);
    ASSERT_TRUE(v.has_value());
    expectSlicerCt(*v, N, corner);
    Received r;
    EXPECT_TRUE(client.read(r));  // still streaming on the same connection
    bool saw_reason = false;
    for (const std::string& n : link->takeNotices()) saw_reason = saw_reason || n.find("CRC") != std::string::npos;
    EXPECT_TRUE(saw_reason);
  }
  {  // A body size over the limit: the client is dropped, the link keeps listening.
    Client client;
    ASSERT_TRUE(client.connect(port));
    ::igtl::ImageMessage::Pointer image = makeImage(N, corner);
    std::vector<unsigned char> header(static_cast<const unsigned char*>(image->GetPackPointer()),
                                      static_cast<const unsigned char*>(image->GetPackPointer()) + IGTL_HEADER_SIZE);
    header[42] = 0x40;  // 2^62 bytes
    ASSERT_EQ(client.socket().Send(header.data(), static_cast<int>(header.size())), 1);
    ASSERT_TRUE(test::waitUntil([&] { return link->status().messages_rejected >= 4 && !link->status().connected; }));
  }
  {  // Half an IMAGE, then the client vanishes.
    Client client;
    ASSERT_TRUE(client.connect(port));
    ASSERT_TRUE(test::waitUntil([&] { return link->status().connected; }));
    ::igtl::ImageMessage::Pointer image = makeImage(N, corner);
    ASSERT_EQ(client.socket().Send(image->GetPackPointer(), image->GetPackSize() / 2), 1);
    std::this_thread::sleep_for(50ms);
    client.close();
    ASSERT_TRUE(test::waitUntil([&] { return !link->status().connected; }));
  }
  {  // A client that disconnects while frames are being sent to it, twice.
    for (int i = 0; i < 2; ++i) {
      Client client;
      ASSERT_TRUE(client.connect(port));
      Received r;
      ASSERT_TRUE(client.read(r));
      client.close();
      std::this_thread::sleep_for(50ms);
    }
  }
  // Still serving: a new client gets the transforms (counted: read until 11 arrived, however
  // long a loaded machine takes to send them; a link that stopped streaming fails the read).
  Client client;
  ASSERT_TRUE(client.connect(port));
  int transforms = 0;
  Received received;
  while (transforms <= 10 && client.read(received)) transforms += received.name == "ProxyToRAS";
  EXPECT_GT(transforms, 10);
  EXPECT_TRUE(link->running());
  EXPECT_EQ(link->status().images_received, 1u);
  EXPECT_GE(link->status().clients, 6u);
}

TEST_F(IgtlLinkServing, SecondClientIsRefusedWhileOneIsConnected) {
  auto channel = std::make_shared<runtime::SnapshotChannel>();
  publish(*channel, Pose(), Pose(), Eigen::Vector3d::Zero(), 0, 1, steadyNowNs());
  auto link = startLink(channel, LinkOptions{});
  ASSERT_NE(link, nullptr);
  Client first, second;
  ASSERT_TRUE(first.connect(link->options().port));
  Received r;
  ASSERT_TRUE(first.read(r));
  ASSERT_TRUE(second.connect(link->options().port));  // the kernel completes the handshake...
  EXPECT_FALSE(second.read(r));                        // ...the link closes it at once
  EXPECT_TRUE(first.read(r));                          // the first client keeps its stream
  const LinkStatus status = link->status();
  EXPECT_EQ(status.clients, 1u);
  EXPECT_EQ(status.connections_refused, 1u);
  EXPECT_TRUE(status.connected);
  EXPECT_NE(link->statusText().find("connected to 127.0.0.1:"), std::string::npos) << link->statusText();
  EXPECT_NE(link->statusText().find("refused 1"), std::string::npos) << link->statusText();
  bool said = false;
  for (const std::string& n : link->takeNotices()) said = said || n.find("one client at a time") != std::string::npos;
  EXPECT_TRUE(said);
  // Once the first leaves, the next one is taken.
  first.close();
  ASSERT_TRUE(test::waitUntil([&] { return !link->status().connected; }));
  Client third;
  ASSERT_TRUE(third.connect(link->options().port));
  EXPECT_TRUE(third.read(r));
}

// ---- Who may connect -----------------------------------------------------------------------

/// The local addresses of the TCP sockets listening on `port`, as the kernel lists them in
/// /proc/net/tcp (what `ss -ltn` prints): "127.0.0.1", "0.0.0.0".
std::vector<std::string> listeningAddresses(int port) {
  std::ifstream in("/proc/net/tcp");
  std::string line;
  std::getline(in, line);  // column names
  std::vector<std::string> out;
  while (std::getline(in, line)) {
    std::istringstream fields(line);
    std::string slot, local, remote, state;
    fields >> slot >> local >> remote >> state;
    if (state != "0A") continue;  // TCP_LISTEN
    const std::size_t colon = local.find(':');
    if (std::stoi(local.substr(colon + 1), nullptr, 16) != port) continue;
    in_addr a{};
    a.s_addr = static_cast<std::uint32_t>(std::stoul(local.substr(0, colon), nullptr, 16));  // as stored: network order
    char text[INET_ADDRSTRLEN];
    inet_ntop(AF_INET, &a, text, sizeof(text));
    out.emplace_back(text);
  }
  return out;
}

/// A plain TCP connection to 127.0.0.1:port from the local address `from` (127.0.0.2 is on lo
/// too: a second address of this machine, so the allow list decides); -1 when it fails.
/// receive_buffer_bytes > 0: the socket's SO_RCVBUF, set before connecting (a client whose
/// buffer a link fills quickly).
int connectFrom(const char* from, int port, int receive_buffer_bytes = 0) {
  const int fd = socket(AF_INET, SOCK_STREAM, 0);
  if (receive_buffer_bytes > 0)
    setsockopt(fd, SOL_SOCKET, SO_RCVBUF, &receive_buffer_bytes, sizeof receive_buffer_bytes);
  sockaddr_in local{};
  local.sin_family = AF_INET;
  inet_pton(AF_INET, from, &local.sin_addr);
  sockaddr_in server{};
  server.sin_family = AF_INET;
  server.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  server.sin_port = htons(static_cast<std::uint16_t>(port));
  if (bind(fd, reinterpret_cast<sockaddr*>(&local), sizeof(local)) != 0 ||
      connect(fd, reinterpret_cast<sockaddr*>(&server), sizeof(server)) != 0) {
    close(fd);
    return -1;
  }
  timeval timeout{10, 0};  // generous, as Client's: a refused connection is closed at once
  setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &timeout, sizeof(timeout));
  return fd;
}

/// Reads from `fd` until `bytes` arrived (true) or the link closed it / the 10 s timeout (false).
bool readsBytes(int fd, std::size_t bytes) {
  std::vector<char> buffer(bytes);
  std::size_t got = 0;
  while (got < bytes) {
    const ssize_t n = recv(fd, buffer.data() + got, bytes - got, 0);
    if (n <= 0) return false;
    got += static_cast<std::size_t>(n);
  }
  return true;
}

/// The process's resident memory [bytes] (the second field of /proc/self/statm, in pages).
std::int64_t residentBytes() {
  std::ifstream in("/proc/self/statm");
  std::int64_t size = 0, resident = 0;
  in >> size >> resident;
  return resident * static_cast<std::int64_t>(sysconf(_SC_PAGESIZE));
}

/// A bare 58-byte header (version 1) of `type` named `name` declaring `body_bytes` of body.
std::vector<unsigned char> bareHeader(const std::string& type, const std::string& name, std::uint64_t body_bytes) {
  std::vector<unsigned char> h(IGTL_HEADER_SIZE, 0);
  h[1] = 1;
  std::memcpy(h.data() + 2, type.data(), std::min<std::size_t>(type.size(), 12));
  std::memcpy(h.data() + 14, name.data(), std::min<std::size_t>(name.size(), 20));
  for (int i = 0; i < 8; ++i) h[42 + i] = static_cast<unsigned char>(body_bytes >> (56 - 8 * i));
  return h;
}

TEST_F(IgtlLinkServing, ListensOnLoopbackOnlyUnlessAnotherAddressIsNamed) {
  auto link = startLink(nullptr, LinkOptions{});
  ASSERT_NE(link, nullptr);
  EXPECT_EQ(listeningAddresses(link->options().port), std::vector<std::string>{"127.0.0.1"});
  EXPECT_EQ(link->status().bind_address, "127.0.0.1");
  link->stop();
  EXPECT_TRUE(listeningAddresses(link->options().port).empty());

  LinkOptions every;
  every.bind_address = "0.0.0.0";
  every.allowed_clients = {"127.0.0.3"};
  auto open = startLink(nullptr, every);
  ASSERT_NE(open, nullptr);
  EXPECT_EQ(listeningAddresses(open->options().port), std::vector<std::string>{"0.0.0.0"});
}

TEST_F(IgtlLinkServing, RefusesClientsNotAllowed) {
  auto channel = std::make_shared<runtime::SnapshotChannel>();
  publish(*channel, Pose(), Pose(), Eigen::Vector3d::Zero(), 0, 1, steadyNowNs());
  auto link = startLink(channel, LinkOptions{});
  ASSERT_NE(link, nullptr);
  const int port = link->options().port;
  const int stranger = connectFrom("127.0.0.2", port);
  ASSERT_GE(stranger, 0) << "cannot connect from 127.0.0.2: " << std::strerror(errno);
  EXPECT_FALSE(readsBytes(stranger, IGTL_HEADER_SIZE));  // closed without a frame
  close(stranger);
  ASSERT_TRUE(test::waitUntil([&] { return link->status().connections_refused == 1; }));
  EXPECT_EQ(link->status().last_refused, "127.0.0.2");
  EXPECT_EQ(link->status().clients, 0u);
  bool logged = false;
  for (const std::string& n : link->takeNotices()) {
    logged = logged || (n.find("refused a connection from 127.0.0.2") != std::string::npos &&
                        n.find("not an allowed client") != std::string::npos);
  }
  EXPECT_TRUE(logged);
  EXPECT_NE(link->statusText().find("last 127.0.0.2"), std::string::npos) << link->statusText();
  const int local = connectFrom("127.0.0.1", port);  // this machine's own loopback: allowed
  ASSERT_GE(local, 0);
  EXPECT_TRUE(readsBytes(local, IGTL_HEADER_SIZE));
  close(local);
  link->stop();

  LinkOptions named;
  named.allowed_clients = {"127.0.0.2"};
  publish(*channel, Pose(), Pose(), Eigen::Vector3d::Zero(), 0, 2, steadyNowNs());  // a frame for the new link
  auto allowing = startLink(channel, named);
  ASSERT_NE(allowing, nullptr);
  const int friendly = connectFrom("127.0.0.2", allowing->options().port);
  ASSERT_GE(friendly, 0);
  EXPECT_TRUE(readsBytes(friendly, IGTL_HEADER_SIZE));
  EXPECT_EQ(allowing->status().connections_refused, 0u);
  close(friendly);
}

// A client that connects and then neither reads nor sends (hung, or gone without closing) held
// the only slot for good: every later client was refused. Once it has been silent both ways for
// takeover_idle_s (its receive buffer full, so the link's sends stop progressing), a newcomer
// takes its place and the silent one is closed, said in a notice.
TEST_F(IgtlLinkServing, AClientSilentBothWaysGivesUpTheSlotToANewcomer) {
  auto channel = std::make_shared<runtime::SnapshotChannel>();
  publish(*channel, Pose(), Pose(), Eigen::Vector3d::Zero(), 0, 1, steadyNowNs());
  LinkOptions options;
  options.takeover_idle_s = 0.5;
  options.rate_Hz = 500.0;  // fills the silent client's buffers within a second or two
  auto link = startLink(channel, options);
  ASSERT_NE(link, nullptr);
  const int port = link->options().port;
  // The silent client: a small receive buffer it never reads.
  const int silent = connectFrom("127.0.0.1", port, 1024);
  ASSERT_GE(silent, 0);
  ASSERT_TRUE(test::waitUntil([&] { return link->status().connected; }));
  // Newcomers are refused while the silent client's buffers still take frames, then one is taken.
  int accepted = -1;
  ASSERT_TRUE(test::waitUntil([&] {
    const int fd = connectFrom("127.0.0.1", port);
    if (fd >= 0 && readsBytes(fd, IGTL_HEADER_SIZE)) {
      accepted = fd;
      return true;
    }
    if (fd >= 0) close(fd);
    std::this_thread::sleep_for(100ms);
    return false;
  }));
  EXPECT_EQ(link->status().clients, 2u);
  bool said = false;
  for (const std::string& n : link->takeNotices()) said = said || n.find("nothing sent or read") != std::string::npos;
  EXPECT_TRUE(said);
  // The silent client was closed: after what was in its buffer, the end of the stream.
  std::vector<char> drain(4096);
  ssize_t n = 0;
  while ((n = recv(silent, drain.data(), drain.size(), 0)) > 0) {
  }
  EXPECT_EQ(n, 0) << "the silent client's connection is still open";
  close(silent);
  close(accepted);
}

// A client that reads the frames (and sends nothing, as a viewer that only listens) keeps the
// slot: a newcomer is refused. The idle time is long enough (3 s) that only a client silent
// both ways, not a busy machine, reaches it.
TEST_F(IgtlLinkServing, AClientThatReadsKeepsTheSlot) {
  auto channel = std::make_shared<runtime::SnapshotChannel>();
  publish(*channel, Pose(), Pose(), Eigen::Vector3d::Zero(), 0, 1, steadyNowNs());
  LinkOptions options;
  options.takeover_idle_s = 3.0;
  auto link = startLink(channel, options);
  ASSERT_NE(link, nullptr);
  Client reader;
  ASSERT_TRUE(reader.connect(link->options().port));
  Received r;
  for (int i = 0; i < 20; ++i) ASSERT_TRUE(reader.read(r));
  const int newcomer = connectFrom("127.0.0.1", link->options().port);
  ASSERT_GE(newcomer, 0);
  EXPECT_FALSE(readsBytes(newcomer, IGTL_HEADER_SIZE)) << "the newcomer took a reading client's slot";
  close(newcomer);
  EXPECT_TRUE(reader.read(r));
  EXPECT_EQ(link->status().clients, 1u);
}

/// A link whose half-sent messages time out after 1 s, and a raw socket connected to it (-1
/// when it could not connect).
std::pair<std::unique_ptr<IgtlLink>, int> linkWithOneSecondPartialTimeout() {
  LinkOptions options;
  options.partial_timeout_s = 1.0;
  auto link = startLink(nullptr, options);
  const int fd = link != nullptr ? connectFrom("127.0.0.1", link->options().port) : -1;
  return {std::move(link), fd};
}

TEST_F(IgtlLinkServing, HugeDeclaredBodyAllocatesOnlyWhatArrivesAndIdlePartialIsDropped) {
  auto [link, fd] = linkWithOneSecondPartialTimeout();
  ASSERT_NE(link, nullptr);
  ASSERT_GE(fd, 0);
  const std::int64_t rss_before = residentBytes();
  std::vector<unsigned char> bytes = bareHeader("IMAGE", "Big", std::uint64_t{1} << 30);
  bytes.resize(bytes.size() + 100'000, 0x11);  // the first 100 kB of the promised 1 GiB
  ASSERT_EQ(send(fd, bytes.data(), bytes.size(), MSG_NOSIGNAL), static_cast<ssize_t>(bytes.size()));
  // Either the link holds what arrived (the machine has 1 GiB to spare) or it refused the
  // message for want of memory; in neither case 1 GiB is taken.
  ASSERT_TRUE(test::waitUntil([&] {
    const LinkStatus s = link->status();
    return s.receive_buffer_bytes >= 100'000 || s.messages_rejected > 0;
  }));
  const LinkStatus held = link->status();
  const std::int64_t rss_after = residentBytes();
  std::cout << "[ 2^30 header ] buffer " << held.receive_buffer_bytes << " bytes, RSS " << rss_before / 1024 << " -> "
            << rss_after / 1024 << " kB\n";
  EXPECT_LE(held.receive_buffer_bytes, 256u * 1024u);
  EXPECT_LT(rss_after - rss_before, std::int64_t{64} << 20);
  // Silent past the timeout: the half message is dropped with its client.
  if (held.messages_rejected == 0) {
    EXPECT_TRUE(held.connected);  // waiting for the rest, not dropped yet
  }
  ASSERT_TRUE(test::waitUntil([&] { return !link->status().connected; }));
  EXPECT_EQ(link->status().receive_buffer_bytes, 0u);
  bool said = false;
  for (const std::string& n : link->takeNotices()) {
    said = said || n.find("half sent") != std::string::npos || n.find("memory is available") != std::string::npos;
  }
  EXPECT_TRUE(said);
  close(fd);
}

// A client trickling a message in, one byte every 0.4 s (each within the 1 s idle timeout), is
// cut off once the message has taken longer than the timeout plus its size at 1 MB/s, while it
// is still trickling: before, each byte restarted the idle timer and the link waited as long as
// the bytes kept coming (1 byte every 2 s was not cut off in 30 s). The check is on what was
// sent by then, not on a clock: the drop comes before the 40th of the header's 58 bytes.
TEST_F(IgtlLinkServing, AMessageTricklingInIsCutOff) {
  auto [link, fd] = linkWithOneSecondPartialTimeout();
  ASSERT_NE(link, nullptr);
  ASSERT_GE(fd, 0);
  ASSERT_TRUE(test::waitUntil([&] { return link->status().connected; }));
  const std::vector<unsigned char> header = bareHeader("STRING", "slow", 10);
  int sent = 0;
  for (; sent < 40 && link->status().connected; ++sent) {
    if (send(fd, header.data() + sent, 1, MSG_NOSIGNAL) != 1) break;
    std::this_thread::sleep_for(400ms);
  }
  EXPECT_LT(sent, 40) << "still connected after 40 bytes over 16 s";
  ASSERT_TRUE(test::waitUntil([&] { return !link->status().connected; }));
  bool said = false;
  for (const std::string& n : link->takeNotices()) said = said || n.find("took longer than") != std::string::npos;
  EXPECT_TRUE(said);
  close(fd);
}

// A link that keeps no volume (max_queued_images 0: a headless run, where nothing opens or
// declines one) receives, checks and says every IMAGE: three in a row are all received, none
// refused; with a queue of one, the second and third were refused as "still waiting to be opened
// or declined" (the check can fail).
TEST_F(IgtlLinkServing, ALinkThatKeepsNoVolumeReceivesEveryImage) {
  for (const std::size_t queue : {std::size_t{0}, std::size_t{1}}) {
    LinkOptions options;
    options.max_queued_images = queue;
    auto link = startLink(nullptr, options);
    ASSERT_NE(link, nullptr);
    Client client;
    ASSERT_TRUE(client.connect(link->options().port));
    for (int n = 0; n < 3; ++n) {
      ::igtl::ImageMessage::Pointer image = makeImage(obliqueAxes(), Eigen::Vector3d(1, 2, 3));
      image->Pack();
      ASSERT_EQ(client.socket().Send(image->GetPackPointer(), image->GetPackSize()), 1);
    }
    ASSERT_TRUE(test::waitUntil([&] { return link->status().messages_received == 3; }));
    if (queue == 0) {
      EXPECT_EQ(link->status().images_received, 3u);
      EXPECT_EQ(link->status().messages_rejected, 0u);
      EXPECT_FALSE(link->takeReceivedImage().has_value()) << "none kept";
    } else {
      EXPECT_EQ(link->status().images_received, 1u);
      EXPECT_EQ(link->status().messages_rejected, 2u);
    }
  }
}

TEST_F(IgtlLinkServing, ImagesRefusedWhenNotAcceptedWithTheirNameEscaped) {
  LinkOptions options;
  options.accept_images = false;
  std::vector<std::string> printed;
  std::mutex printed_mutex;
  options.on_notice = [&](const std::string& n) {
    const std::lock_guard<std::mutex> lock(printed_mutex);
    printed.push_back(n);
  };
  auto link = startLink(nullptr, options);
  ASSERT_NE(link, nullptr);
  Client client;
  ASSERT_TRUE(client.connect(link->options().port));
  ::igtl::ImageMessage::Pointer image = makeImage(obliqueAxes(), Eigen::Vector3d(1, 2, 3));
  image->SetDeviceName("CT\x1b[2J\a");  // a terminal escape in the name
  image->Pack();
  ASSERT_EQ(client.socket().Send(image->GetPackPointer(), image->GetPackSize()), 1);
  ASSERT_TRUE(test::waitUntil([&] { return link->status().messages_received == 1; }));
  EXPECT_EQ(link->status().images_received, 0u);
  EXPECT_EQ(link->status().messages_rejected, 1u);
  EXPECT_FALSE(link->takeReceivedImage().has_value());
  EXPECT_TRUE(link->status().connected);  // the image was skipped, the stream goes on
  std::vector<std::string> notices = link->takeNotices();
  bool refused = false;
  for (const std::string& n : notices) {
    EXPECT_EQ(n.find('\x1b'), std::string::npos) << n;
    EXPECT_EQ(n.find('\a'), std::string::npos) << n;
    refused = refused || (n.find("receiving images is off") != std::string::npos && n.find("CT\\x1b[2J\\x07") != std::string::npos);
  }
  EXPECT_TRUE(refused);
  const std::lock_guard<std::mutex> lock(printed_mutex);
  EXPECT_FALSE(printed.empty());  // the hook saw them as they happened
}

TEST_F(IgtlLinkServing, AReceivedVolumeWaitingRefusesTheNextAndNamesItsSender) {
  auto link = startLink(nullptr, LinkOptions{});
  ASSERT_NE(link, nullptr);
  Client client;
  ASSERT_TRUE(client.connect(link->options().port));
  ::igtl::ImageMessage::Pointer image = makeImage(obliqueAxes(), Eigen::Vector3d(1, 2, 3));
  ASSERT_EQ(client.socket().Send(image->GetPackPointer(), image->GetPackSize()), 1);
  ASSERT_EQ(client.socket().Send(image->GetPackPointer(), image->GetPackSize()), 1);
  ASSERT_TRUE(test::waitUntil([&] { return link->status().messages_received == 2; }));
  EXPECT_EQ(link->status().images_received, 1u);
  EXPECT_EQ(link->status().messages_rejected, 1u);
  std::optional<ReceivedImage> first = link->takeReceivedImage();
  ASSERT_TRUE(first.has_value());
  EXPECT_EQ(first->peer.rfind("127.0.0.1:", 0), 0u) << first->peer;
  EXPECT_FALSE(link->takeReceivedImage().has_value());
}

// ---- Never blocking the haptic thread ------------------------------------------------------

TEST_F(IgtlLinkServing, StalledClientNeverSlowsTheHapticThread) {
  const runtime::LoadedScene& scene = test::sphereBallScene();
  auto channel = std::make_shared<runtime::SnapshotChannel>();
  runtime::HapticThreadOptions thread_options;
  thread_options.monitor = channel;
  auto device = std::make_shared<runtime::SimulatedDevice>(scene.X_WT_initial);
  auto thread = scene.makeHapticThread(device, 1000.0, {}, thread_options);

  LinkOptions options;
  options.rate_Hz = 1000.0;  // as fast as the servo loop: the most the link can ask of it
  options.servo_rate_Hz = thread->servoRate_Hz();
  auto link = startLink(channel, options);
  ASSERT_NE(link, nullptr);

  // A client with a tiny receive buffer that never reads.
  const int fd = socket(AF_INET, SOCK_STREAM, 0);
  const int small = 4096;
  setsockopt(fd, SOL_SOCKET, SO_RCVBUF, &small, sizeof(small));
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  a.sin_port = htons(static_cast<std::uint16_t>(link->options().port));
  ASSERT_EQ(connect(fd, reinterpret_cast<sockaddr*>(&a), sizeof(a)), 0);

  thread->start();
  runtime::HapticSnapshot before, after;
  ASSERT_TRUE(test::waitUntil([&] { return thread->latestSnapshot(before) && before.tick > 100; }));
  ASSERT_TRUE(test::waitUntil([&] { return link->status().frames_skipped > 50; }))
      << "the link never found the client's socket full: sent " << link->status().frames_sent;
  const std::uint64_t skipped_before = link->status().frames_skipped;
  thread->latestSnapshot(before);
  const auto t0 = Clock::now();
  // Counted, not timed: with the client's socket full, the coupling thread goes on for 1000
  // ticks (a link that blocked the haptic thread would stop them) while the link's thread keeps
  // skipping frames (one blocked in send would skip none). However slowly a loaded machine runs
  // them, both get there; the deadline only ends a run where one of them stopped.
  const bool went_on = test::waitUntil(
      [&] {
        return thread->latestSnapshot(after) && after.tick > before.tick + 1000 &&
               link->status().frames_skipped > skipped_before + 100;
      },
      60000ms);
  const double elapsed_s = secondsSince(t0);
  const LinkStatus status = link->status();
  std::cout << "[ stalled ] coupling " << static_cast<double>(after.tick - before.tick) / elapsed_s << " ticks/s over "
            << elapsed_s << " s (window rate " << after.coupling.rate_Hz << " Hz, " << after.coupling.deadline_misses
            << " misses); link sent " << status.frames_sent << ", skipped " << status.frames_skipped << "\n";
  EXPECT_TRUE(went_on) << "coupling ticks " << after.tick - before.tick << ", frames skipped "
                       << status.frames_skipped - skipped_before;
  EXPECT_TRUE(status.connected);  // a slow client is not dropped, its frames are skipped

  const auto t_stop = Clock::now();
  link->stop();
  const double stop_ms = 1e3 * secondsSince(t_stop);
  std::cout << "[ stop ] " << stop_ms << " ms with a stalled client\n";
  EXPECT_LT(stop_ms, 1000.0);  // as above: never waiting on the stalled client
  thread->stop();
  close(fd);
}

TEST_F(IgtlLinkServing, SessionRebuildKeepsFeedingTheChannel) {
  auto channel = std::make_shared<runtime::SnapshotChannel>();
  runtime::Session session(1000.0);
  session.setMonitor(channel);
  const runtime::LoadedScene& scene = test::sphereBallScene();
  session.setScene(scene, std::make_shared<runtime::SimulatedDevice>(scene.X_WT_initial));
  session.startHaptics();
  runtime::HapticSnapshot s;
  ASSERT_TRUE(test::waitUntil([&] { return channel->read(s) && s.tick > 50; }));
  session.stopHaptics();
  channel->read(s);
  EXPECT_GT(s.tick, 50u);
  session.setDevice(std::make_shared<runtime::SimulatedDevice>(scene.X_WT_initial));  // rebuilds the threads
  EXPECT_TRUE(channel->read(s));
  EXPECT_EQ(s.tick, 0u);  // the new thread's first publication
  session.startHaptics();
  EXPECT_TRUE(test::waitUntil([&] { return channel->read(s) && s.tick > 50; })) << "the rebuilt thread feeds nothing";
  session.stopHaptics();
}

}  // namespace
}  // namespace vh::igtl
