#pragma once
// How the PACS client's associations travel (private to vh::io: DCMTK and OpenSSL headers).
//
// The deadline: DCMTK's ACSE and DIMSE timeouts bound each wait for the next bytes, so a server
// that sends one byte a second holds a call forever. A Watchdog gives an operation one deadline;
// when it passes, it shuts the association's socket down (both directions), and whatever DCMTK is
// blocked in (a read, a write, the TLS handshake) returns with an error at once. DCMTK reaches
// the socket only through a transport connection, so WatchedTransportLayer wraps the one DCMTK
// makes (plain TCP or TLS) and tells the watchdog the socket while it is open.
//
// DICOM TLS (PS3.15 Annex B, the BCP 195 profile) is DCMTK's dcmtls (DcmTLSTransportLayer).

#include <chrono>
#include <condition_variable>
#include <memory>
#include <mutex>
#include <string>
#include <thread>

#include <dcmtk/config/osconfig.h>  // first, as DCMTK requires
#include <dcmtk/dcmnet/dcmlayer.h>
#include <dcmtk/dcmnet/dcmtrans.h>
#include <dcmtk/dcmtls/tlslayer.h>

#include "vh/io/pacs.h"

namespace vh::io::pacs_detail {

/// One operation's deadline, `limit_s` after construction or the last restart(); once it passes,
/// the attached socket is shut down. Thread-safe: a thread of its own waits for the deadline.
class Watchdog {
 public:
  explicit Watchdog(int limit_s);
  ~Watchdog();
  Watchdog(const Watchdog&) = delete;
  Watchdog& operator=(const Watchdog&) = delete;

  /// The deadline again `limit_s` from now (a retrieval after each file); no effect once expired.
  void restart();
  /// True once the deadline passed (the socket, if any, was then shut down).
  bool expired() const;
  int limitSeconds() const { return limit_s_; }
  /// The socket to shut down at the deadline (at once when it has passed); detach() before it closes.
  void attach(DcmNativeSocketType socket);
  void detach();

 private:
  void run();

  const int limit_s_;
  mutable std::mutex mutex_;
  std::condition_variable wake_;
  std::chrono::steady_clock::time_point deadline_;  // guarded by mutex_
  DcmNativeSocketType socket_ = -1;                 // guarded by mutex_
  bool expired_ = false;                            // guarded by mutex_
  bool stop_ = false;                               // guarded by mutex_
  std::thread thread_;
};

/// DCMTK's transport layer for one association, its connections watched by `watchdog`: plain TCP,
/// or TLS through `tls` when it is not null. Both must outlive the association.
class WatchedTransportLayer : public DcmTransportLayer {
 public:
  WatchedTransportLayer(Watchdog& watchdog, DcmTLSTransportLayer* tls) : watchdog_(watchdog), tls_(tls) {}
  DcmTransportConnection* createConnection(DcmNativeSocketType socket, OFBool use_secure_layer) override;

 private:
  Watchdog& watchdog_;
  DcmTLSTransportLayer* tls_;
};

/// A DICOM TLS client for `server`: TLS 1.2 or later with BCP 195's cipher suites, the server's
/// certificate verified against `server.ca_cert` and issued for `server.host` (its DNS name or IP
/// address), our certificate and key sent when given.
/// @throws PacsError naming the file that cannot be read or the key that does not match.
std::unique_ptr<DcmTLSTransportLayer> makeTlsLayer(const PacsServer& server);

/// Why the last certificate check on this thread failed, in OpenSSL's words ("self-signed
/// certificate in certificate chain", "certificate has expired", "hostname mismatch"); empty
/// when it passed. Cleared by makeTlsLayer().
std::string lastCertificateProblem();

}  // namespace vh::io::pacs_detail
