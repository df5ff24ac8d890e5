// The OpenIGTLink link of vh/igtl/igtl_link.h.
//
// Sockets: plain POSIX, non-blocking: the server socket is bound to the chosen address (with
// SO_REUSEADDR, so a link restarted on the same port binds at once) and accepts with accept4();
// a connection from an address not allowed, or while a client is connected, is closed at once.
// The client's descriptor is driven with poll() and non-blocking send()/recv() (MSG_NOSIGNAL: a
// client that vanished is an EPIPE, not a SIGPIPE), so the link's thread never waits on a
// client: outgoing frames go through a bounded output buffer (a full one skips frames), incoming
// bytes feed a message parser that keeps only what has arrived. The messages themselves are
// packed and unpacked (CRC included) by libOpenIGTLink.
#include "vh/igtl/igtl_link.h"

#include "igtl_message.h"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <sstream>
#include <stdexcept>

#include <Eigen/SVD>
#include <nlohmann/json.hpp>

#include "vh/io/available_memory.h"
#include "vh/io/patient_frames.h"
#include "vh/runtime/scene.h"

#include <igtlImageMessage.h>
#include <igtlMessageHeader.h>
#include <igtlSensorMessage.h>
#include <igtlStringMessage.h>
#include <igtlTimeStamp.h>
#include <igtlTransformMessage.h>
#include <igtlUnit.h>
#include <igtl_header.h>
#include <igtl_util.h>

namespace vh::igtl {

namespace {

using detail::kHeaderSize;  // 58 bytes
using detail::kMinReceiveBytesPerSecond;
static_assert(kHeaderSize == IGTL_HEADER_SIZE);
constexpr std::size_t kImageHeaderSize = 72;            // IGTL_IMAGE_HEADER_SIZE, version 1
constexpr std::size_t kExtendedHeaderSize = 12;         // header version 2 (protocol 3)
/// Unsent bytes beyond which a frame is skipped (about 8 frames): the client is not reading, and
/// older poses queued for it are worth less than the newest.
constexpr std::size_t kMaxPendingOutput = 4 * 1024;
/// The kernel's send buffer for a client [bytes] (Linux doubles it): small, so a client that
/// falls behind gets the newest frames once it reads again, not seconds of stale ones.
constexpr int kClientSendBuffer = 32 * 1024;
constexpr std::size_t kMaxNotices = 64;
/// Pending connections the kernel queues before accept (all are looked at, then refused or taken).
constexpr int kListenBacklog = 8;
/// TCP keep-alive on the client: idle time before the first probe, interval, probes [s, s, 1]:
/// a client whose machine vanished frees the link within about 25 s.
constexpr int kKeepIdle_s = 10, kKeepInterval_s = 5, kKeepCount = 3;
constexpr std::int64_t kNsPerS = 1'000'000'000;

std::int64_t steadyNs() noexcept {
  timespec t{};
  clock_gettime(CLOCK_MONOTONIC, &t);
  return static_cast<std::int64_t>(t.tv_sec) * kNsPerS + t.tv_nsec;
}
std::int64_t wallNs() noexcept {
  timespec t{};
  clock_gettime(CLOCK_REALTIME, &t);
  return static_cast<std::int64_t>(t.tv_sec) * kNsPerS + t.tv_nsec;
}

std::uint64_t readBigEndian(const unsigned char* p, int bytes) noexcept {
  std::uint64_t v = 0;
  for (int i = 0; i < bytes; ++i) v = (v << 8) | p[i];
  return v;
}
void writeBigEndian(unsigned char* p, int bytes, std::uint64_t v) noexcept {
  for (int i = bytes - 1; i >= 0; --i) {
    p[i] = static_cast<unsigned char>(v & 0xff);
    v >>= 8;
  }
}

/// A field of a fixed-size, possibly unterminated char array.
std::string fixedString(const unsigned char* p, std::size_t n) {
  std::size_t len = 0;
  while (len < n && p[len] != 0) ++len;
  return std::string(reinterpret_cast<const char*>(p), len);
}

/// An IPv4 address from its dotted text; false when it is not one.
bool parseIpv4(const std::string& text, in_addr& out) { return inet_pton(AF_INET, text.c_str(), &out) == 1; }

std::string ipv4Text(const in_addr& address) {
  char text[INET_ADDRSTRLEN] = "?";
  inet_ntop(AF_INET, &address, text, sizeof(text));
  return text;
}

bool isLoopback(const in_addr& address) { return (ntohl(address.s_addr) >> 24) == 127; }

/// igtl::Matrix4x4 (float, [row][column]) from an Eigen matrix.
void toIgtl(const Eigen::Matrix4d& m, ::igtl::Matrix4x4& out) noexcept {
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 4; ++c) out[r][c] = static_cast<float>(m(r, c));
  }
}

/// Voxels of an IMAGE in one of ScalarVolume's types: uint8, int16, uint16 and float32 as they
/// are; int8 widened to int16; int32 / uint32 to int16 / uint16 when the range fits, else
/// float32; float64 to float32. `raw` is in host byte order.
haptics::VoxelType convertVoxels(int scalar_type, const unsigned char* raw, std::size_t count,
                                 std::vector<std::byte>& out) {
  const auto copyAs = [&](auto tag_in, auto tag_out) {
    using In = decltype(tag_in);
    using Out = decltype(tag_out);
    out.resize(count * sizeof(Out));
    for (std::size_t i = 0; i < count; ++i) {
      In v;
      std::memcpy(&v, raw + i * sizeof(In), sizeof(In));
      const Out o = static_cast<Out>(v);
      std::memcpy(out.data() + i * sizeof(Out), &o, sizeof(Out));
    }
  };
  const auto range = [&](auto tag_in) {
    using In = decltype(tag_in);
    double lo = std::numeric_limits<double>::infinity(), hi = -lo;
    for (std::size_t i = 0; i < count; ++i) {
      In v;
      std::memcpy(&v, raw + i * sizeof(In), sizeof(In));
      lo = std::min(lo, static_cast<double>(v));
      hi = std::max(hi, static_cast<double>(v));
    }
    return std::pair<double, double>(lo, hi);
  };
  switch (scalar_type) {
    case ::igtl::ImageMessage::TYPE_UINT8:
      out.assign(reinterpret_cast<const std::byte*>(raw), reinterpret_cast<const std::byte*>(raw) + count);
      return haptics::VoxelType::kUInt8;
    case ::igtl::ImageMessage::TYPE_INT16:
      out.assign(reinterpret_cast<const std::byte*>(raw), reinterpret_cast<const std::byte*>(raw) + 2 * count);
      return haptics::VoxelType::kInt16;
    case ::igtl::ImageMessage::TYPE_UINT16:
      out.assign(reinterpret_cast<const std::byte*>(raw), reinterpret_cast<const std::byte*>(raw) + 2 * count);
      return haptics::VoxelType::kUInt16;
    case ::igtl::ImageMessage::TYPE_FLOAT32:
      out.assign(reinterpret_cast<const std::byte*>(raw), reinterpret_cast<const std::byte*>(raw) + 4 * count);
      return haptics::VoxelType::kFloat32;
    case ::igtl::ImageMessage::TYPE_INT8:
      copyAs(std::int8_t{}, std::int16_t{});
      return haptics::VoxelType::kInt16;
    case ::igtl::ImageMessage::TYPE_INT32: {
      const auto [lo, hi] = range(std::int32_t{});
      if (lo >= -32768.0 && hi <= 32767.0) {
        copyAs(std::int32_t{}, std::int16_t{});
        return haptics::VoxelType::kInt16;
      }
      copyAs(std::int32_t{}, float{});
      return haptics::VoxelType::kFloat32;
    }
    case ::igtl::ImageMessage::TYPE_UINT32: {
      const auto [lo, hi] = range(std::uint32_t{});
      (void)lo;
      if (hi <= 65535.0) {
        copyAs(std::uint32_t{}, std::uint16_t{});
        return haptics::VoxelType::kUInt16;
      }
      copyAs(std::uint32_t{}, float{});
      return haptics::VoxelType::kFloat32;
    }
    case ::igtl::ImageMessage::TYPE_FLOAT64:
      copyAs(double{}, float{});
      return haptics::VoxelType::kFloat32;
    default:
      throw std::invalid_argument("unsupported scalar type " + std::to_string(scalar_type));
  }
}

}  // namespace

// ---- Conversions ---------------------------------------------------------------------------

std::string escapeControl(const std::string& text) {
  static const char* const kHex = "0123456789abcdef";
  std::string out;
  out.reserve(text.size());
  for (const char ch : text) {
    const auto c = static_cast<unsigned char>(ch);
    if (c == '\\') {
      out += "\\\\";
    } else if (c < 0x20 || c >= 0x7f) {
      out += "\\x";
      out += kHex[c >> 4];
      out += kHex[c & 0xf];
    } else {
      out += ch;
    }
  }
  return out;
}

Eigen::Matrix4d toRasMatrix_mm(const haptics::Pose& X_WT) {
  const Eigen::Matrix3d F = io::rasFromLpsMatrix();
  Eigen::Matrix4d X = Eigen::Matrix4d::Identity();
  X.topLeftCorner<3, 3>() = F * X_WT.R_AB.toRotationMatrix() * F;
  X.topRightCorner<3, 1>() = 1000.0 * (F * X_WT.p_AB_m);
  return X;
}

io::LoadedVolume volumeFromIjkToRas(const std::array<int, 3>& dims, const Eigen::Matrix4d& X_RAS_IJK_mm,
                                    haptics::VoxelType type, std::vector<std::byte> bytes,
                                    const std::string& name) {
  if (!X_RAS_IJK_mm.allFinite()) throw std::invalid_argument("the IJK-to-RAS matrix is not finite");
  const Eigen::Matrix3d F = io::lpsFromRasMatrix();
  haptics::VolumeGeometry g;
  g.dims = dims;
  Eigen::Matrix3d D_RAS;
  for (int a = 0; a < 3; ++a) {
    const Eigen::Vector3d axis_mm = X_RAS_IJK_mm.block<3, 1>(0, a);
    const double spacing_mm = axis_mm.norm();
    if (!(spacing_mm > 0.0)) throw std::invalid_argument("axis " + std::to_string(a) + " has zero spacing");
    g.spacing_m[a] = 1e-3 * spacing_mm;
    D_RAS.col(a) = axis_mm / spacing_mm;
  }
  // The matrix travels as float: tolerate float rounding, refuse a sheared grid, and hand
  // ScalarVolume the nearest orthogonal matrix (polar decomposition).
  if (!(D_RAS.transpose() * D_RAS).isApprox(Eigen::Matrix3d::Identity(), 1e-3)) {
    throw std::invalid_argument("the image axes are not orthogonal (sheared grids are not supported)");
  }
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(F * D_RAS, Eigen::ComputeFullU | Eigen::ComputeFullV);
  g.direction_W = svd.matrixU() * svd.matrixV().transpose();
  g.origin_W_m = 1e-3 * (F * X_RAS_IJK_mm.block<3, 1>(0, 3));
  auto field = std::make_shared<const haptics::ScalarVolume>(haptics::ScalarVolume::FromBytes(g, type, std::move(bytes)));
  io::LoadedVolume volume;
  volume.image = io::imageFromField(field);
  volume.field = std::move(field);
  volume.info.source = std::string(runtime::kIgtlVolumePrefix) + name;
  volume.info.format = "OpenIGTLink";
  volume.info.description = name;
  return volume;
}

// ---- The link ------------------------------------------------------------------------------

struct IgtlLink::Impl {
  int server_fd = -1;
  int client_fd = -1;  ///< Owned (closed by closeClient()).
  std::string peer;
  std::vector<in_addr> allowed;            ///< 127.0.0.1 and LinkOptions::allowed_clients.
  std::int64_t last_byte_ns = 0;           ///< When the client's last byte arrived (steady clock).
  std::int64_t last_taken_ns = 0;          ///< When the client last took bytes of ours (a send progressed).
  std::int64_t message_start_ns = 0;       ///< When the first byte of the message being received arrived.
  std::vector<unsigned char> output;     ///< Packed messages not yet sent.
  std::size_t output_sent = 0;           ///< Bytes of `output` already sent.

  // Incoming message parser.
  std::array<unsigned char, kHeaderSize> header{};
  std::size_t header_got = 0;
  bool in_body = false;
  bool keep_body = false;  ///< IMAGE: keep the body; else discard it.
  std::uint64_t body_size = 0;
  std::uint64_t body_got = 0;
  std::vector<unsigned char> body;  ///< What has arrived of a kept body (grows with it, never ahead).
  std::array<unsigned char, 64 * 1024> scratch{};

  // Outgoing messages (built once, packed per frame).
  ::igtl::TransformMessage::Pointer proxy = ::igtl::TransformMessage::New();
  ::igtl::TransformMessage::Pointer device = ::igtl::TransformMessage::New();
  ::igtl::SensorMessage::Pointer force = ::igtl::SensorMessage::New();
  ::igtl::StringMessage::Pointer contact = ::igtl::StringMessage::New();
  ::igtl::TimeStamp::Pointer stamp = ::igtl::TimeStamp::New();
  runtime::HapticSnapshot snapshot;  ///< The consumer's copy (large: kept, not on the stack).
  bool have_snapshot = false;
  std::int64_t wall_minus_steady_ns = 0;

  ~Impl() {
    if (client_fd >= 0) ::close(client_fd);
    if (server_fd >= 0) ::close(server_fd);
  }
};

IgtlLink::IgtlLink(std::shared_ptr<runtime::SnapshotChannel> channel, LinkOptions options)
    : channel_(std::move(channel)), options_(std::move(options)), rate_Hz_(options_.rate_Hz) {
  if (options_.port < 1 || options_.port > 65535) {
    throw std::invalid_argument("OpenIGTLink: port must be in 1..65535, not " + std::to_string(options_.port));
  }
  if (!(options_.rate_Hz > 0.0) || !std::isfinite(options_.rate_Hz)) {
    throw std::invalid_argument("OpenIGTLink: rate must be a positive number of Hz");
  }
  if (options_.servo_rate_Hz > 0.0 && std::isfinite(options_.servo_rate_Hz)) {
    rate_Hz_ = std::min(rate_Hz_, options_.servo_rate_Hz);
  }
  if (!(options_.partial_timeout_s > 0.0) || !std::isfinite(options_.partial_timeout_s)) {
    throw std::invalid_argument("OpenIGTLink: the partial-message timeout must be a positive number of seconds");
  }
  if (!(options_.takeover_idle_s > 0.0) || !std::isfinite(options_.takeover_idle_s)) {
    throw std::invalid_argument("OpenIGTLink: the idle time before a new client takes over must be a positive number "
                                "of seconds");
  }
  in_addr address{};
  if (!parseIpv4(options_.bind_address, address)) {
    throw std::invalid_argument("OpenIGTLink: the address to listen on must be an IPv4 address such as 127.0.0.1, not '" +
                                escapeControl(options_.bind_address) + "'");
  }
  for (const std::string& client : options_.allowed_clients) {
    if (!parseIpv4(client, address)) {
      throw std::invalid_argument("OpenIGTLink: an allowed client must be an IPv4 address, not '" + escapeControl(client) + "'");
    }
  }
  parseIpv4(options_.bind_address, address);
  if (!isLoopback(address) && options_.allowed_clients.empty()) {
    throw std::invalid_argument("OpenIGTLink: listening on " + options_.bind_address +
                                " lets other machines connect: name the clients allowed (--igtl-allow ADDRESS)");
  }
  // A body must fit the library's int sizes.
  options_.max_message_bytes = std::min<std::uint64_t>(options_.max_message_bytes, (std::uint64_t{1} << 31) - 4096);
}

IgtlLink::~IgtlLink() { stop(); }

void IgtlLink::start() {
  if (thread_.joinable()) return;
  impl_ = std::make_unique<Impl>();
  Impl& m = *impl_;
  const std::string where = options_.bind_address + ":" + std::to_string(options_.port);
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_port = htons(static_cast<std::uint16_t>(options_.port));
  parseIpv4(options_.bind_address, address.sin_addr);
  m.server_fd = ::socket(AF_INET, SOCK_STREAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
  const int on = 1;
  if (m.server_fd < 0 || setsockopt(m.server_fd, SOL_SOCKET, SO_REUSEADDR, &on, sizeof(on)) != 0 ||
      ::bind(m.server_fd, reinterpret_cast<const sockaddr*>(&address), sizeof(address)) != 0 ||
      ::listen(m.server_fd, kListenBacklog) != 0) {
    const std::string why = std::strerror(errno);
    impl_.reset();
    throw std::runtime_error("OpenIGTLink: cannot listen on " + where + " (" + why + ")");
  }
  in_addr loopback{};
  loopback.s_addr = htonl(INADDR_LOOPBACK);
  m.allowed.push_back(loopback);
  for (const std::string& client : options_.allowed_clients) {
    in_addr a{};
    parseIpv4(client, a);
    m.allowed.push_back(a);
  }
  m.proxy->SetDeviceName(options_.proxy_name.c_str());
  m.device->SetDeviceName(options_.device_name.c_str());
  m.force->SetDeviceName(options_.force_name.c_str());
  m.force->SetLength(3);
  ::igtl::Unit::Pointer newton = ::igtl::Unit::New();
  newton->Init();
  newton->SetPrefix(::igtl::Unit::SI_PREFIX_NONE);
  newton->Append(::igtl::Unit::SI_DERIVED_NEWTON, 1);
  m.force->SetUnit(newton);
  m.contact->SetDeviceName(options_.contact_name.c_str());
  m.wall_minus_steady_ns = wallNs() - steadyNs();
  {
    const std::lock_guard<std::mutex> lock(mutex_);
    status_ = LinkStatus{};
    status_.listening = true;
    status_.port = options_.port;
    status_.bind_address = options_.bind_address;
    status_.rate_Hz = rate_Hz_;
  }
  stop_requested_.store(false, std::memory_order_release);
  running_.store(true, std::memory_order_release);
  try {
    thread_ = std::thread([this] { run(); });
  } catch (...) {
    running_.store(false, std::memory_order_release);
    impl_.reset();
    throw;
  }
}

void IgtlLink::stop() {
  stop_requested_.store(true, std::memory_order_release);
  if (thread_.joinable()) thread_.join();
  impl_.reset();  // closes the client and the server socket
  running_.store(false, std::memory_order_release);
  const std::lock_guard<std::mutex> lock(mutex_);
  status_.listening = false;
  status_.connected = false;
  status_.peer.clear();
}

LinkStatus IgtlLink::status() const {
  const std::lock_guard<std::mutex> lock(mutex_);
  return status_;
}

std::string IgtlLink::statusText() const {
  const LinkStatus s = status();
  if (!s.listening) return "OpenIGTLink off";
  const std::string where = s.bind_address + ":" + std::to_string(s.port);
  std::string text = s.connected ? "OpenIGTLink: connected to " + s.peer + " (on " + where + ")"
                                 : "OpenIGTLink: listening on " + where;
  if (s.connections_refused > 0) {
    text += "; refused " + std::to_string(s.connections_refused) + " (last " + s.last_refused + ")";
  }
  return text;
}

std::optional<ReceivedImage> IgtlLink::takeReceivedImage() {
  const std::lock_guard<std::mutex> lock(mutex_);
  if (inbox_.empty()) return std::nullopt;
  ReceivedImage v = std::move(inbox_.front());
  inbox_.pop_front();
  return v;
}

std::optional<io::LoadedVolume> IgtlLink::takeReceivedVolume() {
  std::optional<ReceivedImage> image = takeReceivedImage();
  if (!image) return std::nullopt;
  return std::move(image->volume);
}

std::vector<std::string> IgtlLink::takeNotices() {
  const std::lock_guard<std::mutex> lock(mutex_);
  std::vector<std::string> out(notices_.begin(), notices_.end());
  notices_.clear();
  return out;
}

void IgtlLink::notice(std::string text) {
  if (options_.on_notice) {
    try {
      options_.on_notice(text);
    } catch (...) {  // NOLINT(bugprone-empty-catch): a failing printer loses one line, not the link
    }
  }
  const std::lock_guard<std::mutex> lock(mutex_);
  notices_.push_back(std::move(text));
  while (notices_.size() > kMaxNotices) notices_.pop_front();
}

namespace {

/// Packs `message` stamped with `stamp` onto the end of `output`.
void appendMessage(std::vector<unsigned char>& output, ::igtl::MessageBase& message,
                   ::igtl::TimeStamp::Pointer& stamp) {
  message.SetTimeStamp(stamp);
  message.Pack();
  const auto* p = static_cast<const unsigned char*>(message.GetPackPointer());
  output.insert(output.end(), p, p + message.GetPackSize());
}

/// Bytes per voxel of an IMAGE scalar type; 0 for an unknown type.
std::uint64_t scalarSize(int type) noexcept {
  switch (type) {
    case ::igtl::ImageMessage::TYPE_INT8: case ::igtl::ImageMessage::TYPE_UINT8: return 1;
    case ::igtl::ImageMessage::TYPE_INT16: case ::igtl::ImageMessage::TYPE_UINT16: return 2;
    case ::igtl::ImageMessage::TYPE_INT32: case ::igtl::ImageMessage::TYPE_UINT32:
    case ::igtl::ImageMessage::TYPE_FLOAT32: return 4;
    case ::igtl::ImageMessage::TYPE_FLOAT64: return 8;
    default: return 0;
  }
}

/// The image's voxel-to-RAS matrix X_RAS_IJK [mm]. Geometry: unit axes (columns 0..2) and the
/// image centre (column 3), OpenIGTLink's convention; the first voxel's centre is (dims - 1) / 2
/// voxels back from it. @return false for a zero or non-finite axis.
bool imageIjkToRas_mm(::igtl::ImageMessage& image, const int (&dims)[3], Eigen::Matrix4d& X) {
  ::igtl::Matrix4x4 matrix;
  image.GetMatrix(matrix);
  float spacing[3];
  image.GetSpacing(spacing);
  X = Eigen::Matrix4d::Identity();
  Eigen::Vector3d centre;
  for (int r = 0; r < 3; ++r) centre[r] = matrix[r][3];
  for (int a = 0; a < 3; ++a) {
    Eigen::Vector3d axis(matrix[0][a], matrix[1][a], matrix[2][a]);
    const double n = axis.norm();
    if (!(n > 0.0) || !std::isfinite(n)) return false;
    X.block<3, 1>(0, a) = axis / n * static_cast<double>(spacing[a]);
  }
  X.block<3, 1>(0, 3) = centre - X.topLeftCorner<3, 3>() * Eigen::Vector3d(0.5 * (dims[0] - 1), 0.5 * (dims[1] - 1), 0.5 * (dims[2] - 1));
  if (image.GetCoordinateSystem() == ::igtl::ImageMessage::COORDINATE_LPS) {
    X.topRows<3>() = io::rasFromLpsMatrix() * X.topRows<3>();  // LPS -> RAS
  }
  return true;
}

}  // namespace

// ---- Incoming messages (igtl_message.h) ----------------------------------------------------

namespace detail {

MessageHeaderFields parseMessageHeader(const HeaderBytes& header) {
  MessageHeaderFields f;
  f.version = static_cast<std::uint16_t>(readBigEndian(header.data(), 2));
  f.type = fixedString(header.data() + 2, 12);
  f.device_name = fixedString(header.data() + 14, 20);
  f.timestamp = readBigEndian(header.data() + 34, 8);
  f.body_size = readBigEndian(header.data() + 42, 8);
  f.crc = readBigEndian(header.data() + 50, 8);
  return f;
}

namespace {

[[noreturn]] void refuse(const std::string& why) { throw std::invalid_argument(why); }

/// The content of an IMAGE body (the image header and voxels) and the version-1 header that
/// libOpenIGTLink 1.11 reads with it: for header version 2 (protocol 3: extended header,
/// content, metadata) the CRC is checked over the whole body here and the header rewritten to
/// version 1 with the content's size and CRC.
std::pair<const unsigned char*, std::uint64_t> imageContent(const HeaderBytes& header,
                                                            const std::vector<unsigned char>& body,
                                                            HeaderBytes& v1_header) {
  const MessageHeaderFields fields = parseMessageHeader(header);
  v1_header = header;
  if (fields.version == 1) return {body.data(), body.size()};
  if (fields.version != 2) refuse("unknown header version " + std::to_string(fields.version));
  if (body.size() < kExtendedHeaderSize) refuse("body shorter than its extended header");
  const std::uint64_t crc = crc64(const_cast<unsigned char*>(body.data()), body.size(), 0ULL);
  if (crc != fields.crc) refuse("CRC mismatch");
  const std::uint64_t ext = readBigEndian(body.data(), 2);
  const std::uint64_t meta_header = readBigEndian(body.data() + 2, 2);
  const std::uint64_t meta = readBigEndian(body.data() + 4, 4);
  if (ext < kExtendedHeaderSize || ext + meta_header + meta > body.size()) {
    refuse("extended header sizes exceed the body");
  }
  const unsigned char* content = body.data() + ext;
  const std::uint64_t content_size = body.size() - ext - meta_header - meta;
  writeBigEndian(v1_header.data(), 2, 1);
  writeBigEndian(v1_header.data() + 42, 8, content_size);
  writeBigEndian(v1_header.data() + 50, 8, crc64(const_cast<unsigned char*>(content), content_size, 0ULL));
  return {content, content_size};
}

}  // namespace

io::LoadedVolume decodeImageMessage(const HeaderBytes& header, const std::vector<unsigned char>& body) {
  HeaderBytes v1_header{};
  const auto [content, content_size] = imageContent(header, body, v1_header);
  if (content_size < kImageHeaderSize) refuse("body shorter than the image header");
  ::igtl::MessageHeader::Pointer igtl_header = ::igtl::MessageHeader::New();
  igtl_header->InitPack();
  std::memcpy(igtl_header->GetPackPointer(), v1_header.data(), kHeaderSize);
  igtl_header->Unpack();
  ::igtl::ImageMessage::Pointer image = ::igtl::ImageMessage::New();
  image->SetMessageHeader(igtl_header);
  image->AllocatePack();
  if (static_cast<std::uint64_t>(image->GetPackBodySize()) != content_size) refuse("body size mismatch");
  std::memcpy(image->GetPackBodyPointer(), content, content_size);
  if (!(image->Unpack(1) & ::igtl::MessageHeader::UNPACK_BODY)) refuse("CRC mismatch or unknown image header version");
  int dims[3], sub_dims[3], sub_off[3];
  image->GetDimensions(dims);
  image->GetSubVolume(sub_dims, sub_off);
  if (image->GetNumComponents() != 1) {
    refuse(std::to_string(image->GetNumComponents()) + " components (only scalar volumes)");
  }
  for (int a = 0; a < 3; ++a) {
    if (dims[a] < 2) {
      refuse(std::to_string(dims[0]) + " x " + std::to_string(dims[1]) + " x " + std::to_string(dims[2]) +
             " voxels (at least 2 along every axis)");
    }
    if (sub_dims[a] != dims[a] || sub_off[a] != 0) refuse("a sub-volume (only whole volumes)");
  }
  const int type = image->GetScalarType();
  const std::uint64_t scalar_size = scalarSize(type);
  if (scalar_size == 0) refuse("unknown scalar type " + std::to_string(type));
  const std::uint64_t count =
      static_cast<std::uint64_t>(dims[0]) * static_cast<std::uint64_t>(dims[1]) * static_cast<std::uint64_t>(dims[2]);
  if (kImageHeaderSize + count * scalar_size != content_size) {
    refuse(std::to_string(content_size - kImageHeaderSize) + " bytes of voxels, expected " +
           std::to_string(count * scalar_size));
  }
  // What libOpenIGTLink takes as it comes: the byte order (any value but 2 read as big-endian)
  // and the spacing (1e38 mm reached the volume's checks as "non-finite").
  const int endian = image->GetEndian();
  if (endian != ::igtl::ImageMessage::ENDIAN_BIG && endian != ::igtl::ImageMessage::ENDIAN_LITTLE)
    refuse("endian " + std::to_string(endian) + " (1: big-endian, 2: little-endian)");
  float spacing_mm[3];
  image->GetSpacing(spacing_mm);
  for (int a = 0; a < 3; ++a) {
    const double s = spacing_mm[a];
    if (!(s >= kMinImageSpacing_mm && s <= kMaxImageSpacing_mm)) {
      char text[128];
      std::snprintf(text, sizeof text, "spacing %g mm along axis %d (expected %g to %g mm)", s, a, kMinImageSpacing_mm,
                    kMaxImageSpacing_mm);
      refuse(text);
    }
  }
  auto* voxels = static_cast<unsigned char*>(image->GetScalarPointer());
  const bool little_host = igtl_is_little_endian() != 0;
  const bool little_data = image->GetEndian() == ::igtl::ImageMessage::ENDIAN_LITTLE;
  if (scalar_size > 1 && little_host != little_data) {
    for (std::uint64_t i = 0; i < count; ++i) std::reverse(voxels + i * scalar_size, voxels + (i + 1) * scalar_size);
  }
  Eigen::Matrix4d X;
  if (!imageIjkToRas_mm(*image, dims, X)) refuse("a zero or non-finite axis");
  std::vector<std::byte> bytes;
  const haptics::VoxelType voxel_type = convertVoxels(type, voxels, static_cast<std::size_t>(count), bytes);
  return volumeFromIjkToRas({dims[0], dims[1], dims[2]}, X, voxel_type, std::move(bytes),
                            escapeControl(fixedString(header.data() + 14, 20)));
}

}  // namespace detail

void IgtlLink::closeClient(const std::string& why) {
  Impl& m = *impl_;
  if (m.client_fd < 0) return;
  if (m.in_body || m.header_got > 0) {
    notice("OpenIGTLink: a message from " + m.peer + " was cut off (" + std::to_string(m.in_body ? m.body_got : m.header_got) +
           " bytes of it received)");
  }
  notice("OpenIGTLink: client " + m.peer + " " + why);
  ::close(m.client_fd);
  m.client_fd = -1;
  m.output.clear();
  m.output_sent = 0;
  m.header_got = 0;
  m.in_body = false;
  m.body.clear();
  m.body.shrink_to_fit();
  const std::lock_guard<std::mutex> lock(mutex_);
  status_.connected = false;
  status_.peer.clear();
  status_.receive_buffer_bytes = 0;
}

void IgtlLink::reject(const std::string& why) {
  notice("OpenIGTLink: rejected a message from " + impl_->peer + ": " + why);
  const std::lock_guard<std::mutex> lock(mutex_);
  ++status_.messages_rejected;
}

bool IgtlLink::flush() {
  Impl& m = *impl_;
  while (m.output_sent < m.output.size()) {
    const ssize_t n = ::send(m.client_fd, m.output.data() + m.output_sent, m.output.size() - m.output_sent,
                             MSG_NOSIGNAL | MSG_DONTWAIT);
    if (n > 0) {
      m.output_sent += static_cast<std::size_t>(n);
      m.last_taken_ns = steadyNs();
      continue;
    }
    if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) return true;
    if (n < 0 && errno == EINTR) continue;
    return false;
  }
  m.output.clear();
  m.output_sent = 0;
  return true;
}

void IgtlLink::sendFrame() {
  Impl& m = *impl_;
  if (channel_ != nullptr && channel_->read(m.snapshot)) m.have_snapshot = true;
  if (m.client_fd < 0 || !m.have_snapshot) return;
  if (m.output.size() - m.output_sent > kMaxPendingOutput) {
    const std::lock_guard<std::mutex> lock(mutex_);
    ++status_.frames_skipped;
    return;
  }
  const runtime::HapticSnapshot& s = m.snapshot;
  const std::int64_t t_ns = s.time_ns != 0 ? s.time_ns + m.wall_minus_steady_ns : wallNs();
  m.stamp->SetTime(static_cast<::igtl_uint32>(t_ns / kNsPerS), static_cast<::igtl_uint32>(t_ns % kNsPerS));
  ::igtl::Matrix4x4 matrix;
  toIgtl(toRasMatrix_mm(s.X_WP), matrix);
  m.proxy->SetMatrix(matrix);
  appendMessage(m.output, *m.proxy, m.stamp);
  toIgtl(toRasMatrix_mm(s.X_WD), matrix);
  m.device->SetMatrix(matrix);
  appendMessage(m.output, *m.device, m.stamp);
  const Eigen::Vector3d force_RAS_N = toRas(s.force_W_N);
  for (unsigned i = 0; i < 3; ++i) m.force->SetValue(i, force_RAS_N[static_cast<int>(i)]);
  appendMessage(m.output, *m.force, m.stamp);
  nlohmann::json state;
  state["tick"] = s.tick;
  state["contacts"] = s.contacts;
  state["force_N"] = s.force_W_N.allFinite() ? s.force_W_N.norm() : 0.0;
  std::string segment;
  if (options_.segment_name) {
    try {
      segment = options_.segment_name(s);
    } catch (...) {  // NOLINT(bugprone-empty-catch): the hook's failure leaves the segment null
      segment.clear();
    }
  }
  state["segment"] = segment.empty() ? nlohmann::json(nullptr) : nlohmann::json(segment);
  std::string text = state.dump();
  m.contact->SetString(text);
  appendMessage(m.output, *m.contact, m.stamp);
  if (!flush()) {
    closeClient("disconnected (send failed)");
    return;
  }
  const std::lock_guard<std::mutex> lock(mutex_);
  ++status_.frames_sent;
}

void IgtlLink::handleImage() {
  Impl& m = *impl_;
  const std::string name = escapeControl(fixedString(m.header.data() + 14, 20));
  try {
    io::LoadedVolume volume = detail::decodeImageMessage(m.header, m.body);
    const std::array<int, 3> dims = volume.field->geometry().dims;
    const bool kept = options_.max_queued_images > 0;  // 0: checked and said, nothing kept (a headless run)
    notice("OpenIGTLink: received volume '" + name + "' (" + std::to_string(dims[0]) + " x " + std::to_string(dims[1]) +
           " x " + std::to_string(dims[2]) + ") from " + m.peer + (kept ? "" : " (checked, not kept)"));
    const std::lock_guard<std::mutex> lock(mutex_);
    if (kept) inbox_.push_back(ReceivedImage{std::move(volume), m.peer});
    ++status_.images_received;
  } catch (const std::exception& e) {
    reject("IMAGE '" + name + "': " + e.what());
  }
}

bool IgtlLink::startMessage() {
  Impl& m = *impl_;
  const detail::MessageHeaderFields fields = detail::parseMessageHeader(m.header);
  m.body_size = fields.body_size;
  const std::string type = escapeControl(fields.type);
  const std::string what = type + " '" + escapeControl(fields.device_name) + "'";
  m.header_got = 0;
  if (m.body_size > options_.max_message_bytes) {
    reject(what + ": body of " + std::to_string(m.body_size) + " bytes exceeds the limit of " +
           std::to_string(options_.max_message_bytes));
    return false;  // cannot skip that much safely: drop the client
  }
  m.in_body = true;
  m.body_got = 0;
  m.keep_body = false;
  m.body.clear();
  if (type != "IMAGE") return true;  // skipped as it arrives
  if (!options_.accept_images) {
    reject(what + ": receiving images is off (the image is skipped, not opened)");
    return true;
  }
  std::size_t queued = 0;
  {
    const std::lock_guard<std::mutex> lock(mutex_);
    queued = inbox_.size();
  }
  if (options_.max_queued_images > 0 && queued >= options_.max_queued_images) {
    reject(what + ": a volume received before is still waiting to be opened or declined (the image is skipped)");
    return true;
  }
  if (!io::fitsInMemory(m.body_size)) {
    reject(what + ": body of " + io::formatBytes(m.body_size) + " but " +
           io::formatBytes(io::availableMemoryBytes().value_or(0)) + " of memory is available");
    return false;
  }
  m.keep_body = true;  // the buffer grows with what arrives (receive())
  return true;
}

bool IgtlLink::receive() {
  Impl& m = *impl_;
  for (;;) {
    unsigned char* target = nullptr;
    std::size_t want = 0;
    if (!m.in_body) {
      target = m.header.data() + m.header_got;
      want = kHeaderSize - m.header_got;
    } else {
      target = m.scratch.data();
      want = static_cast<std::size_t>(std::min<std::uint64_t>(m.scratch.size(), m.body_size - m.body_got));
    }
    if (want > 0) {
      const ssize_t n = ::recv(m.client_fd, target, want, MSG_DONTWAIT);
      if (n == 0) return false;
      if (n < 0) {
        if (errno == EAGAIN || errno == EWOULDBLOCK) return true;
        if (errno == EINTR) continue;
        return false;
      }
      m.last_byte_ns = steadyNs();
      if (!m.in_body && m.header_got == 0) m.message_start_ns = m.last_byte_ns;  // a new message begins
      if (!m.in_body) {
        m.header_got += static_cast<std::size_t>(n);
      } else {
        if (m.keep_body) {
          m.body.insert(m.body.end(), target, target + n);
          const std::lock_guard<std::mutex> lock(mutex_);
          status_.receive_buffer_bytes = m.body.capacity();
        }
        m.body_got += static_cast<std::uint64_t>(n);
      }
    }
    if (!m.in_body && m.header_got == kHeaderSize && !startMessage()) return false;
    if (m.in_body && m.body_got == m.body_size) {
      m.in_body = false;
      m.header_got = 0;
      {
        const std::lock_guard<std::mutex> lock(mutex_);
        ++status_.messages_received;
      }
      if (m.keep_body) {
        handleImage();
        m.body.clear();
        m.body.shrink_to_fit();
        const std::lock_guard<std::mutex> lock(mutex_);
        status_.receive_buffer_bytes = 0;
      }
    }
  }
}

void IgtlLink::dropIdlePartial() {
  Impl& m = *impl_;
  if (m.client_fd < 0 || (!m.in_body && m.header_got == 0)) return;
  const std::int64_t now = steadyNs();
  const auto timeout_ns = static_cast<std::int64_t>(options_.partial_timeout_s * 1e9);
  if (now - m.last_byte_ns >= timeout_ns) {
    reject("a message was left half sent for " + std::to_string(options_.partial_timeout_s) + " s");
    closeClient("dropped (a message idle half sent)");
    return;
  }
  // A message trickling in (a byte now and then, each within the idle timeout) is cut off too:
  // the whole of it must arrive within the timeout plus its size at kMinReceiveBytesPerSecond.
  const double bytes = static_cast<double>(kHeaderSize) + (m.in_body ? static_cast<double>(m.body_size) : 0.0);
  const double allowed_s = options_.partial_timeout_s + bytes / kMinReceiveBytesPerSecond;
  if (static_cast<double>(now - m.message_start_ns) < allowed_s * 1e9) return;
  char text[160];
  std::snprintf(text, sizeof text, "a message of %.0f bytes took longer than %.1f s to arrive (at least %.0f kB/s after the first %.1f s)",
                bytes, allowed_s, kMinReceiveBytesPerSecond / 1e3, options_.partial_timeout_s);
  reject(text);
  closeClient("dropped (a message trickling in)");
}

void IgtlLink::acceptClients() {
  Impl& m = *impl_;
  for (;;) {
    sockaddr_in address{};
    socklen_t length = sizeof(address);
    const int fd = ::accept4(m.server_fd, reinterpret_cast<sockaddr*>(&address), &length, SOCK_NONBLOCK | SOCK_CLOEXEC);
    if (fd < 0) {
      if (errno == EINTR || errno == ECONNABORTED) continue;
      return;  // EAGAIN: none left (or a transient error: the next poll tries again)
    }
    const std::string peer = ipv4Text(address.sin_addr) + ":" + std::to_string(ntohs(address.sin_port));
    const bool allowed = std::any_of(m.allowed.begin(), m.allowed.end(),
                                     [&](const in_addr& a) { return a.s_addr == address.sin_addr.s_addr; });
    if (allowed && m.client_fd >= 0) {
      // The connected client has been silent both ways for takeover_idle_s: hung, or gone
      // without closing (its buffers full). The newcomer takes the slot.
      const double idle_s = 1e-9 * static_cast<double>(steadyNs() - std::max(m.last_byte_ns, m.last_taken_ns));
      if (idle_s >= options_.takeover_idle_s) {
        char text[160];
        std::snprintf(text, sizeof text, "dropped: nothing sent or read for %.1f s, and %s connected", idle_s,
                      peer.c_str());
        closeClient(text);
      }
    }
    if (!allowed || m.client_fd >= 0) {
      // Counted and said before the socket is closed: whoever sees the close sees the refusal.
      notice("OpenIGTLink: refused a connection from " + peer +
             (allowed ? " (one client at a time: " + m.peer + " is connected)" : " (not an allowed client)"));
      {
        const std::lock_guard<std::mutex> lock(mutex_);
        ++status_.connections_refused;
        status_.last_refused = ipv4Text(address.sin_addr);
      }
      ::close(fd);
      continue;
    }
    m.client_fd = fd;
    setsockopt(fd, SOL_SOCKET, SO_SNDBUF, &kClientSendBuffer, sizeof(kClientSendBuffer));
    const int on = 1;
    setsockopt(fd, SOL_SOCKET, SO_KEEPALIVE, &on, sizeof(on));
    setsockopt(fd, IPPROTO_TCP, TCP_KEEPIDLE, &kKeepIdle_s, sizeof(kKeepIdle_s));
    setsockopt(fd, IPPROTO_TCP, TCP_KEEPINTVL, &kKeepInterval_s, sizeof(kKeepInterval_s));
    setsockopt(fd, IPPROTO_TCP, TCP_KEEPCNT, &kKeepCount, sizeof(kKeepCount));
    m.peer = peer;
    m.last_byte_ns = steadyNs();
    m.last_taken_ns = m.last_byte_ns;
    notice("OpenIGTLink: client " + m.peer + " connected");
    const std::lock_guard<std::mutex> lock(mutex_);
    status_.connected = true;
    status_.peer = m.peer;
    ++status_.clients;
  }
}

void IgtlLink::run() noexcept {
  Impl& m = *impl_;
  const auto period_ns = static_cast<std::int64_t>(std::llround(1e9 / rate_Hz_));
  std::int64_t next_frame_ns = steadyNs();
  try {
    while (!stop_requested_.load(std::memory_order_acquire)) {
      const std::int64_t now = steadyNs();
      if (now >= next_frame_ns) {
        sendFrame();
        next_frame_ns += period_ns;
        if (now - next_frame_ns > period_ns) next_frame_ns = now + period_ns;  // fell behind: no burst
      }
      // Wait for the next frame, a connection, data, or room for pending output; at most
      // 50 ms so stop() is prompt.
      dropIdlePartial();
      pollfd fds[2];
      fds[0] = {m.server_fd, POLLIN, 0};
      nfds_t count = 1;
      if (m.client_fd >= 0) {
        fds[1] = {m.client_fd, static_cast<short>(POLLIN | (m.output.empty() ? 0 : POLLOUT)), 0};
        count = 2;
      }
      const std::int64_t wait_ns = std::clamp<std::int64_t>(next_frame_ns - steadyNs(), 0, 50'000'000);
      const timespec timeout{static_cast<time_t>(wait_ns / kNsPerS), static_cast<long>(wait_ns % kNsPerS)};
      const int ready = ppoll(fds, count, &timeout, nullptr);
      if (ready <= 0) continue;
      if (count == 2 && fds[1].revents != 0) {
        if ((fds[1].revents & (POLLIN | POLLHUP | POLLERR)) != 0 && !receive()) {
          closeClient("disconnected");
        } else if ((fds[1].revents & POLLOUT) != 0 && !flush()) {
          closeClient("disconnected (send failed)");
        }
      }
      if ((fds[0].revents & POLLIN) != 0) acceptClients();
    }
  } catch (const std::exception& e) {
    notice(std::string("OpenIGTLink: the link stopped: ") + e.what());
  } catch (...) {
    notice("OpenIGTLink: the link stopped (unknown error)");
  }
  if (m.client_fd >= 0) closeClient("closed (the link stopped)");
  running_.store(false, std::memory_order_release);
}

}  // namespace vh::igtl
