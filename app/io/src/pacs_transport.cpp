// The PACS client's deadline (Watchdog, WatchedTransportLayer) and DICOM TLS. See pacs_transport.h.

#include "pacs_transport.h"

#include <sys/socket.h>

#include <filesystem>
#include <system_error>

#include <openssl/ssl.h>
#include <openssl/x509.h>
#include <openssl/x509_vfy.h>

namespace vh::io::pacs_detail {
namespace {

using Clock = std::chrono::steady_clock;

/// A transport connection that DCMTK uses as the one it wraps (`inner`, which owns the socket),
/// the socket attached to the watchdog until it is closed.
class WatchedConnection : public DcmTransportConnection {
 public:
  WatchedConnection(DcmNativeSocketType socket, DcmTransportConnection* inner, Watchdog& watchdog)
      : DcmTransportConnection(socket), inner_(inner), watchdog_(watchdog) {
    watchdog_.attach(socket);
  }
  ~WatchedConnection() override {
    watchdog_.detach();  // before the socket closes: its number may be reused at once
    delete inner_;
  }
  WatchedConnection(const WatchedConnection&) = delete;
  WatchedConnection& operator=(const WatchedConnection&) = delete;

  OFCondition serverSideHandshake() override { return inner_->serverSideHandshake(); }
  OFCondition clientSideHandshake() override { return inner_->clientSideHandshake(); }
  OFCondition renegotiate(const char* suite) override { return inner_->renegotiate(suite); }
  ssize_t read(void* buf, size_t nbyte) override { return inner_->read(buf, nbyte); }
  ssize_t write(void* buf, size_t nbyte) override { return inner_->write(buf, nbyte); }
  void close() override {
    watchdog_.detach();
    inner_->close();
  }
  void closeTransportConnection() override {
    watchdog_.detach();
    inner_->closeTransportConnection();
  }
  unsigned long getPeerCertificateLength() override { return inner_->getPeerCertificateLength(); }
  unsigned long getPeerCertificate(void* buf, unsigned long len) override { return inner_->getPeerCertificate(buf, len); }
  OFBool networkDataAvailable(int timeout) override { return inner_->networkDataAvailable(timeout); }
  OFBool isTransparentConnection() override { return inner_->isTransparentConnection(); }
  OFString& dumpConnectionParameters(OFString& str) override { return inner_->dumpConnectionParameters(str); }

 private:
  DcmTransportConnection* inner_;
  Watchdog& watchdog_;
};

thread_local std::string t_certificate_problem;

/// OpenSSL's certificate check, kept as DCMTK's (the verdict unchanged); the first failure's
/// reason and certificate are remembered for the error message.
extern "C" int rememberCertificateProblem(int ok, X509_STORE_CTX* store) {
  if (ok == 0 && t_certificate_problem.empty()) {
    t_certificate_problem = X509_verify_cert_error_string(X509_STORE_CTX_get_error(store));
    if (X509* cert = X509_STORE_CTX_get_current_cert(store)) {
      char subject[256] = {};
      X509_NAME_oneline(X509_get_subject_name(cert), subject, sizeof subject);
      t_certificate_problem += std::string(" (certificate ") + subject + ")";
    }
  }
  return ok;
}

PacsError tlsError(const PacsServer& server, const std::string& what) {
  return PacsError("PACS " + server.describe() + ": DICOM TLS: " + what);
}

/// `file` must be a readable file; throws naming `role` and the file.
void requireFile(const PacsServer& server, const std::string& file, const char* role) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(file, ec)) {
    throw tlsError(server, std::string(role) + " '" + file + "' is not a readable file");
  }
}

}  // namespace

Watchdog::Watchdog(int limit_s) : limit_s_(std::max(1, limit_s)), deadline_(Clock::now() + std::chrono::seconds(limit_s_)) {
  thread_ = std::thread([this] { run(); });
}

Watchdog::~Watchdog() {
  {
    const std::lock_guard<std::mutex> lock(mutex_);
    stop_ = true;
  }
  wake_.notify_all();
  thread_.join();
}

void Watchdog::run() {
  std::unique_lock<std::mutex> lock(mutex_);
  while (!stop_) {
    if (Clock::now() >= deadline_) {
      expired_ = true;
      if (socket_ >= 0) ::shutdown(socket_, SHUT_RDWR);
      return;
    }
    wake_.wait_until(lock, deadline_);
  }
}

void Watchdog::restart() {
  const std::lock_guard<std::mutex> lock(mutex_);
  if (!expired_) deadline_ = Clock::now() + std::chrono::seconds(limit_s_);
}

bool Watchdog::expired() const {
  const std::lock_guard<std::mutex> lock(mutex_);
  return expired_;
}

void Watchdog::attach(DcmNativeSocketType socket) {
  const std::lock_guard<std::mutex> lock(mutex_);
  socket_ = socket;
  if (expired_ && socket_ >= 0) ::shutdown(socket_, SHUT_RDWR);
}

void Watchdog::detach() {
  const std::lock_guard<std::mutex> lock(mutex_);
  socket_ = -1;
}

DcmTransportConnection* WatchedTransportLayer::createConnection(DcmNativeSocketType socket, OFBool /*use_secure_layer*/) {
  // DcmSCU asks for a "secure layer" once a layer of its own is set; TLS is what `tls_` says.
  DcmTransportConnection* inner = tls_ != nullptr ? tls_->createConnection(socket, OFTrue)
                                                  : DcmTransportLayer::createConnection(socket, OFFalse);
  if (inner == nullptr) return nullptr;
  return new WatchedConnection(socket, inner, watchdog_);
}

std::unique_ptr<DcmTLSTransportLayer> makeTlsLayer(const PacsServer& server) {
  static std::once_flag once;
  std::call_once(once, [] { DcmTLSTransportLayer::initializeOpenSSL(); });
  t_certificate_problem.clear();
  if (server.ca_cert.empty()) {
    throw tlsError(server, "no CA certificate given: the server's certificate must be checked against one");
  }
  requireFile(server, server.ca_cert, "the CA certificate");
  if (server.client_cert.empty() != server.client_key.empty()) {
    throw tlsError(server, "our certificate and its private key go together: give both or neither");
  }
  auto layer = std::make_unique<DcmTLSTransportLayer>(NET_REQUESTOR, nullptr, OFFalse);
  SSL_CTX* context = layer->getNativeHandle();
  if (context == nullptr) throw tlsError(server, "OpenSSL could not make a TLS context");
  OFCondition cond = layer->setTLSProfile(TSP_Profile_BCP195);
  if (cond.good()) cond = layer->activateCipherSuites();
  if (cond.bad()) throw tlsError(server, std::string("cannot set the BCP 195 cipher suites: ") + cond.text());
  if (layer->addTrustedCertificateFile(server.ca_cert.c_str(), DCF_Filetype_PEM).bad()) {
    throw tlsError(server, "the CA certificate '" + server.ca_cert + "' is not a PEM certificate");
  }
  if (!server.client_cert.empty()) {
    requireFile(server, server.client_cert, "our certificate");
    requireFile(server, server.client_key, "our private key");
    if (layer->setCertificateFile(server.client_cert.c_str(), DCF_Filetype_PEM).bad()) {
      throw tlsError(server, "our certificate '" + server.client_cert + "' is not a PEM certificate");
    }
    if (layer->setPrivateKeyFile(server.client_key.c_str(), DCF_Filetype_PEM).bad()) {
      throw tlsError(server, "our private key '" + server.client_key + "' is not an unencrypted PEM key");
    }
    if (!layer->checkPrivateKeyMatchesCertificate()) {
      throw tlsError(server, "the private key '" + server.client_key + "' is not that of the certificate '" +
                                 server.client_cert + "'");
    }
  }
  layer->setCertificateVerification(DCV_requireCertificate);
  SSL_CTX_set_verify(context, SSL_CTX_get_verify_mode(context), rememberCertificateProblem);
  // The certificate must name the host we connect to: an address as an IP address, else a DNS name.
  X509_VERIFY_PARAM* param = SSL_CTX_get0_param(context);
  if (X509_VERIFY_PARAM_set1_ip_asc(param, server.host.c_str()) != 1) {
    X509_VERIFY_PARAM_set1_host(param, server.host.c_str(), 0);
  }
  return layer;
}

std::string lastCertificateProblem() { return t_certificate_problem; }

}  // namespace vh::io::pacs_detail
