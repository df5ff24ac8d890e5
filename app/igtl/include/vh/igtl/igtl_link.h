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
/// little-endian; RAS or LPS): converted to a volume in W (patient LPS, metres; see
/// volumeFromIjkToRas()) and queued for takeReceivedVolume(). Other message types are skipped.
/// Malformed messages (bad CRC, a body size that disagrees with the IMAGE header, sizes over
/// LinkOptions::max_message_bytes, truncated data) are dropped with a notice (notices());
/// a message that cannot be skipped safely (truncated, oversized) closes the client.
///
/// Why a library of its own (vh::igtl, app/igtl/) and not part of vh::runtime: the runtime is
/// linked by everything (devices, bench, every test) and stays free of libOpenIGTLink; it only
/// offers the generic SnapshotChannel. The link uses runtime and io; ui and the executable use it.
///
/// Threads: the link's own thread does all socket work (accept, send, receive); the haptic
/// threads only publish into the channel (never blocked by the link: a slow or stalled client
/// makes the link skip frames, not the servo loop wait). One client at a time: a new
/// connection replaces the current one (Slicer reconnecting after a drop is the common case); a
/// client that disconnects is not an error, the link keeps listening. The public members may
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

struct LinkOptions {
  int port = kDefaultPort;   ///< TCP port to listen on (all interfaces), 1..65535.
  double rate_Hz = 60.0;     ///< Frames per second (one of each message per frame) [Hz], > 0.
  /// The haptic threads' servo rate [Hz]: rate_Hz is clamped to it (the channel holds nothing
  /// newer between two servo ticks).
  double servo_rate_Hz = 1000.0;
  std::string proxy_name = "ProxyToRAS";     ///< Device name of the proxy's TRANSFORM.
  std::string device_name = "DeviceToRAS";   ///< Device name of the device's TRANSFORM.
  std::string force_name = "Force";          ///< Device name of the force's SENSOR.
  std::string contact_name = "ContactState"; ///< Device name of the contact STRING.
  /// Largest message body accepted [bytes] (a 512^3 int16 volume is 256 MiB); larger ones are
  /// refused and the client closed (the stream cannot be resynchronised cheaply).
  std::uint64_t max_message_bytes = std::uint64_t{1} << 30;
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
  double rate_Hz = 0.0;            ///< The frame rate after clamping [Hz].
  bool connected = false;          ///< A client is connected now.
  std::string peer;                ///< The client's address ("127.0.0.1:53412"), or empty.
  std::uint64_t clients = 0;       ///< Clients accepted since start().
  std::uint64_t frames_sent = 0;   ///< Frames (TRANSFORM x2, SENSOR, STRING) sent since start().
  std::uint64_t frames_skipped = 0;///< Frames not sent because the client's socket was full.
  std::uint64_t messages_received = 0;  ///< Whole messages read from clients.
  std::uint64_t images_received = 0;    ///< IMAGE messages turned into volumes.
  std::uint64_t messages_rejected = 0;  ///< Malformed or unsupported messages dropped.
};

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
  /// @throws std::invalid_argument for a port outside 1..65535 or a rate that is not > 0.
  IgtlLink(std::shared_ptr<runtime::SnapshotChannel> channel, LinkOptions options);
  ~IgtlLink();  ///< stop()
  IgtlLink(const IgtlLink&) = delete;
  IgtlLink& operator=(const IgtlLink&) = delete;

  /// Binds the port and starts the link's thread; no effect when running.
  /// @throws std::runtime_error "OpenIGTLink: cannot listen on port N (in use?)".
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
  /// "listening on 18944", "connected to 127.0.0.1 (port 18944)", or "off".
  std::string statusText() const;

  /// The oldest volume received and not taken yet (the GUI's timer, tests), or none.
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
  void acceptClient();                     ///< Takes a pending connection (replacing the client).
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
  std::deque<io::LoadedVolume> inbox_;
  std::deque<std::string> notices_;
};

}  // namespace vh::igtl
