#pragma once
/// @file
/// A hostile DICOM server for tests: it answers C-ECHO as any PACS does, and every C-FIND with
/// one pending response whose identifier is a byte string given by the test, sent as it is (no
/// DCMTK parse or write of it on this side: the bytes a broken or malicious server would send),
/// then a final Success. Built on DCMTK's association and PDU layers (ASC, DIMSE, DUL), so that
/// the client's side is exactly what a real server's bytes reach. Runs on a thread of its own,
/// on a loopback port from the kernel.

#include <atomic>
#include <cstdint>
#include <string>
#include <thread>

#include "vh/io/pacs.h"

namespace vh::io::test {

class HostilePacs {
 public:
  /// Serves `identifier` (a dataset's bytes, no preamble or meta header) in implicit VR little
  /// endian, or explicit VR little endian when `explicit_vr`.
  explicit HostilePacs(std::string identifier, bool explicit_vr = false);
  ~HostilePacs();
  HostilePacs(const HostilePacs&) = delete;
  HostilePacs& operator=(const HostilePacs&) = delete;

  /// True once the server listens (it answers an echo); false when it did not start in 30 s.
  bool waitUntilUp();
  /// How our client reaches it: 127.0.0.1, its port, AE titles HOSTILEPACS / VHTEST, `timeout_s`.
  PacsServer server(int timeout_s = 10) const;
  /// C-FIND requests answered with the identifier so far.
  int findsAnswered() const { return finds_.load(); }

 private:
  void run();

  std::string identifier_;
  bool explicit_vr_;
  int port_ = 0;
  std::atomic<bool> stop_{false};
  std::atomic<int> finds_{0};
  std::thread thread_;
};

/// A loopback port that nothing listens on: one the kernel just gave out, closed again (9, the
/// discard port, unused on test machines, when none could be had).
int closedPort();

/// A STUDY-level identifier (implicit VR little endian) whose Content Sequence holds itself
/// `depth` times: an item in a sequence in an item..., every length undefined and never closed.
std::string nestedSequencesIdentifier(int depth);

/// A STUDY-level identifier (implicit VR little endian) of about 150 bytes whose Patient's Name
/// declares `declared_bytes` and carries 100.
std::string absurdLengthIdentifier(std::uint32_t declared_bytes);

}  // namespace vh::io::test
