#pragma once
/// @file
/// The OpenIGTLink link ("Work with 3D Slicer"): a TCP server on its own thread that
/// streams the haptic session to one client (3D Slicer's OpenIGTLinkIF module, or any
/// OpenIGTLink client) and receives volumes from it.
///
/// Sent at LinkOptions::rate_Hz (60 Hz by default, at most the servo rate), from the latest
/// snapshot of a runtime::SnapshotChannel the haptic threads feed (HapticThreadOptions::monitor):
///   * TRANSFORM "ProxyToRAS" and "DeviceToRAS": X_RAS_P and X_RAS_D, 4x4, translation in mm, in
///     Slicer's patient RAS (see toRasMatrix_mm());
///   * SENSOR "Force": the force on the hand, 3 values (R, A, S) [N] (unit newton);
///   * STRING "ContactState": a JSON object {"tick": coupling tick, "contacts": n,
///     "force_N": |F|, "segment": name or null} (LinkOptions::segment_name fills "segment").
/// Every message carries the snapshot's time (its steady-clock time mapped to the wall clock).
///
/// Received: IMAGE messages (scalar, one component, a whole volume; any scalar type; big- or
/// little-endian; RAS or LPS), only with LinkOptions::accept_images: converted to a volume in W
/// (patient LPS, metres; see volumeFromIjkToRas()) and queued (at most
/// LinkOptions::max_queued_images) for takeReceivedImage(); the link never applies one itself.
/// Other message types are skipped. Malformed messages (bad CRC, a body size that disagrees
/// with the IMAGE header, sizes over LinkOptions::max_message_bytes or over the memory
/// available, truncated data) are dropped with a notice (takeNotices()); a message that cannot
/// be skipped safely (oversized, or idle half-received for LinkOptions::partial_timeout_s)
/// closes the client. A body is read in bounded chunks into a buffer that grows with what has
/// arrived: a header declaring a huge body costs nothing until the bytes come.
///
/// Who may connect (threat model in docs/slicer.md): the server listens on
/// LinkOptions::bind_address (127.0.0.1 by default: only this machine); a client is accepted
/// only from 127.0.0.1 or an address in LinkOptions::allowed_clients, and only while no other
/// client is connected (a second connection is refused, so no one can push the user's client
/// off). Refused connections are counted, named in the status and reported as notices. Text
/// from the wire (device names, types) is escaped in notices (control bytes as \xNN).
///
/// Why a library of its own (vh::igtl, app/igtl/) and not part of vh::runtime: the runtime is
/// linked by everything (devices, bench, every test) and stays free of libOpenIGTLink; it only
/// offers the generic SnapshotChannel. The link uses runtime and io; ui and the executable use it.
///
/// Threads: the link's own thread does all socket work (accept, send, receive); the haptic
/// threads only publish into the channel (never blocked by the link: a slow or stalled client
/// makes the link skip frames, not the servo loop wait). One client at a time: while one is
/// connected, new connections are refused (a client whose machine vanished is found by TCP
/// keep-alive within about 25 s, and Slicer reconnects after that); a client that disconnects
/// is not an error, the link keeps listening. The public members may
/// be called from any thread except the link's own; nothing throws out of the link's thread.
///
/// Frames: W the scene (world) frame = patient LPS [m] (as io::loadVolume reads DICOM / NRRD);
/// RAS = Slicer's patient frame [mm]: p_RAS = F p_W * 1000 with F = diag(-1, -1, 1).

#include <array>
#include <atomic>
#include <cstdint>
#include <cstddef>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include <Eigen/Core>

#include "vh/haptics/pose.h"
#include "vh/haptics/scalar_volume.h"
#include "vh/io/patient_frames.h"
#include "vh/io/volume_loader.h"
#include "vh/runtime/haptic_thread.h"
#include "vh/runtime/snapshot_channel.h"

namespace vh::igtl {

/// OpenIGTLink's registered TCP port (IANA), the default of Slicer's connectors.
inline constexpr int kDefaultPort = 18944;

/// Largest IMAGE body the link accepts [bytes]: 1 GiB of voxels (1024^3 uint8, 512^3 float64)
/// plus room for the image and extended headers and metadata.
inline constexpr std::uint64_t kMaxImageBodyBytes = (std::uint64_t{1} << 30) + 64 * 1024;

struct LinkOptions {
  int port = kDefaultPort;   ///< TCP port to listen on, 1..65535.
  /// IPv4 address of the interface to listen on: "127.0.0.1" (this machine only) by default;
  /// "0.0.0.0" for every interface. Any address but a loopback one needs allowed_clients.
  std::string bind_address = "127.0.0.1";
  /// IPv4 addresses of the clients accepted besides 127.0.0.1 (always accepted); others are
  /// refused at once.
  std::vector<std::string> allowed_clients;
  /// IMAGE messages are received (and queued for takeReceivedImage()); false: refused with a
  /// notice, their bodies skipped, nothing kept.
  bool accept_images = true;
  /// Received volumes kept until taken; an IMAGE arriving while the queue is full is refused.
  /// 0: each IMAGE is received, checked and said (the notice), none kept (a headless run, where
  /// nothing opens or declines a volume, so none waits either).
  std::size_t max_queued_images = 1;
  /// A message half received with nothing more for this long closes the client [s], > 0; so
  /// does one still not whole this long plus its size at 1 MB/s after its first byte (a client
  /// trickling a byte at a time).
  double partial_timeout_s = 10.0;
  /// An allowed client connecting while another is connected takes its place when that one has
  /// neither sent a byte nor taken one of the link's for this long [s], > 0: a client that hung,
  /// or went away without closing, does not keep the only slot. One that reads the frames or
  /// sends keeps it, and the newcomer is refused.
  double takeover_idle_s = 5.0;
  double rate_Hz = 60.0;     ///< Frames per second (one of each message per frame) [Hz], > 0.
  /// The haptic threads' servo rate [Hz]: rate_Hz is clamped to it (the channel holds nothing
  /// newer between two servo ticks).
  double servo_rate_Hz = 1000.0;
  std::string proxy_name = "ProxyToRAS";     ///< Device name of the proxy's TRANSFORM.
  std::string device_name = "DeviceToRAS";   ///< Device name of the device's TRANSFORM.
  std::string force_name = "Force";          ///< Device name of the force's SENSOR.
  std::string contact_name = "ContactState"; ///< Device name of the contact STRING.
  /// Largest message body accepted [bytes] (a 512^3 int16 volume is 256 MiB); larger ones, and
  /// IMAGE bodies larger than the memory available (io::availableMemoryBytes() less a margin),
  /// are refused and the client closed (the stream cannot be resynchronised cheaply).
  std::uint64_t max_message_bytes = kMaxImageBodyBytes;
  /// Called on the link's thread with each notice as it happens (besides takeNotices()), e.g.
  /// to print it; must not throw or block.
  std::function<void(const std::string& notice)> on_notice;
  /// Hook for the segment under the tool (the felt segments of a segmentation): called on the
  /// link's thread once per frame with the latest snapshot; a non-empty result is sent as
  /// "segment" in ContactState, else null. Must not throw (an exception is caught and the
  /// segment left null).
  std::function<std::string(const runtime::HapticSnapshot& snapshot)> segment_name;
};

/// What the link is doing, for the status bar and tests (a copy; cheap).
struct LinkStatus {
  bool listening = false;          ///< The server socket is bound and the thread runs.
  int port = 0;                    ///< The port listened on.
  std::string bind_address;        ///< The address listened on ("127.0.0.1").
  double rate_Hz = 0.0;            ///< The frame rate after clamping [Hz].
  bool connected = false;          ///< A client is connected now.
  std::string peer;                ///< The client's address ("127.0.0.1:53412"), or empty.
  std::uint64_t clients = 0;       ///< Clients accepted since start().
  std::uint64_t frames_sent = 0;   ///< Frames (TRANSFORM x2, SENSOR, STRING) sent since start().
  std::uint64_t frames_skipped = 0;///< Frames not sent because the client's socket was full.
  std::uint64_t messages_received = 0;  ///< Whole messages read from clients.
  std::uint64_t images_received = 0;    ///< IMAGE messages turned into volumes.
  std::uint64_t messages_rejected = 0;  ///< Malformed, unsupported or refused messages dropped.
  std::uint64_t connections_refused = 0;  ///< Connections closed at once (not allowed, or busy).
  std::string last_refused;             ///< The address of the last refused connection, or empty.
  /// Bytes the link holds for the message being received now (its buffer's capacity).
  std::size_t receive_buffer_bytes = 0;
};

/// A volume received from a client, with who sent it.
struct ReceivedImage {
  io::LoadedVolume volume;
  std::string peer;  ///< The sender's address and port ("127.0.0.1:53412").
};

/// `text` with control and non-ASCII bytes as \xNN and backslashes doubled: wire text made
/// safe for a log line or a terminal.
std::string escapeControl(const std::string& text);

/// A TRANSFORM's matrix for a pose in W: X_RAS_T as a 4x4 with translation in mm:
/// [F R_WT F, 1000 F p_W_m; 0 0 0 1], F = diag(-1, -1, 1) (LPS -> RAS).
Eigen::Matrix4d toRasMatrix_mm(const haptics::Pose& X_WT);

/// A vector in W (LPS) expressed in RAS: F v = (-x, -y, z) (same units).
inline Eigen::Vector3d toRas(const Eigen::Vector3d& v_W) { return io::rasFromLps(v_W); }

/// A volume in W from an image in RAS millimetres (as an IMAGE message carries it, after the
/// centre-to-corner shift of its origin).
/// @param dims voxels along i, j, k (each >= 2).
/// @param X_RAS_IJK_mm IJK-to-RAS: columns 0..2 are the i, j, k axes scaled by the spacing
///        [mm per voxel], column 3 the centre of voxel (0, 0, 0) [mm] (Slicer's IJKToRAS).
/// @param type, bytes voxels x fastest, native byte order, voxelCount * size bytes.
/// @param name the volume's name (VolumeInfo::description; format "OpenIGTLink").
/// @return field and image with spacing_m [m], origin_W_m [m] and direction_W (orthonormal,
///         re-orthonormalised from the float matrix) in LPS.
/// @throws std::invalid_argument for dims < 2, a zero, non-finite or non-orthogonal axis, or
///         a byte count that does not match (ScalarVolume's checks).
io::LoadedVolume volumeFromIjkToRas(const std::array<int, 3>& dims, const Eigen::Matrix4d& X_RAS_IJK_mm,
                                    haptics::VoxelType type, std::vector<std::byte> bytes,
                                    const std::string& name);

class IgtlLink {
 public:
  /// @param channel the feed to stream (shared with the haptic threads; null: stream nothing,
  ///        still receive volumes).
  /// @throws std::invalid_argument for a port outside 1..65535, a rate or timeout that is not
  ///         > 0, a bind address or allowed client that is not an IPv4 address, or a bind
  ///         address other than a loopback one with no allowed clients.
  IgtlLink(std::shared_ptr<runtime::SnapshotChannel> channel, LinkOptions options);
  ~IgtlLink();  ///< stop()
  IgtlLink(const IgtlLink&) = delete;
  IgtlLink& operator=(const IgtlLink&) = delete;

  /// Binds the address and port and starts the link's thread; no effect when running.
  /// @throws std::runtime_error "OpenIGTLink: cannot listen on 127.0.0.1:N (...)".
  void start();
  /// Closes the client and the server socket and joins the thread; returns within one wait of
  /// the link's loop (at most 50 ms: the sockets are non-blocking, a stalled client cannot
  /// hold it). Idempotent.
  void stop();
  bool running() const noexcept { return running_.load(std::memory_order_acquire); }

  const LinkOptions& options() const noexcept { return options_; }
  /// The frame rate after clamping to (0, servo rate] [Hz].
  double rate_Hz() const noexcept { return rate_Hz_; }
  LinkStatus status() const;
  /// "OpenIGTLink: listening on 127.0.0.1:18944", "OpenIGTLink: connected to 127.0.0.1:53412
  /// (on 127.0.0.1:18944)", or "OpenIGTLink off"; then "; refused N (last A)" once a
  /// connection was refused.
  std::string statusText() const;

  /// The oldest volume received and not taken yet (the GUI's timer, tests), or none.
  std::optional<ReceivedImage> takeReceivedImage();
  /// takeReceivedImage() without the sender.
  std::optional<io::LoadedVolume> takeReceivedVolume();
  /// Notices since the last call (rejected messages with the reason, clients connecting and
  /// leaving), oldest first; at most the last 64 are kept.
  std::vector<std::string> takeNotices();

 private:
  struct Impl;  // sockets and messages (igtl types stay out of this header)
  void run() noexcept;
  void notice(std::string text);
  // The jobs of run()'s loop (the link's thread only).
  void sendFrame();                        ///< One frame: the four messages from the latest snapshot.
  bool flush();                            ///< Writes what it can of the output; false when the client is gone.
  bool receive();                          ///< Reads what the client sent; false when it is gone.
  void handleImage();                      ///< A whole IMAGE message arrived (header and body in Impl).
  void acceptClients();                    ///< Takes the pending connections (refusing those not allowed).
  void dropIdlePartial();                  ///< Closes a client whose half-sent message went idle.
  bool startMessage();                     ///< A whole header arrived: false to close the client.
  void closeClient(const std::string& why);
  void reject(const std::string& why);     ///< Counts and reports a rejected message.

  std::shared_ptr<runtime::SnapshotChannel> channel_;
  LinkOptions options_;
  double rate_Hz_;
  std::unique_ptr<Impl> impl_;
  std::thread thread_;
  std::atomic<bool> running_{false};
  std::atomic<bool> stop_requested_{false};
  mutable std::mutex mutex_;  ///< Guards status_, inbox_, notices_.
  LinkStatus status_;
  std::deque<ReceivedImage> inbox_;
  std::deque<std::string> notices_;
};

}  // namespace vh::igtl
