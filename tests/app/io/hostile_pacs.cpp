// A hostile DICOM server for tests (hostile_pacs.h).
#include "hostile_pacs.h"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>

#include <dcmtk/config/osconfig.h>  // first, as DCMTK requires
#include <dcmtk/dcmdata/dcuid.h>
#include <dcmtk/dcmnet/assoc.h>
#include <dcmtk/dcmnet/dimse.h>
#include <dcmtk/dcmnet/dul.h>

namespace vh::io::test {
namespace {

void putLE(std::string& out, std::uint32_t v, int bytes) {
  for (int i = 0; i < bytes; ++i) out += static_cast<char>((v >> (8 * i)) & 0xFF);
}

/// One element in implicit VR little endian: tag, 32-bit length, value.
std::string element(std::uint16_t group, std::uint16_t elem, const std::string& value) {
  std::string out;
  putLE(out, group, 2);
  putLE(out, elem, 2);
  putLE(out, static_cast<std::uint32_t>(value.size()), 4);
  return out + value;
}

std::string us(std::uint16_t v) {
  std::string out;
  putLE(out, v, 2);
  return out;
}

std::string evenText(std::string s, char pad) {
  if (s.size() % 2 != 0) s += pad;
  return s;
}

/// The command set of a C-FIND response (PS3.7 9.3.2.2), implicit VR little endian as every
/// command set is, with its group length.
std::string findResponseCommand(std::uint16_t message_id, std::uint16_t status, bool with_identifier) {
  const std::string body = element(0x0000, 0x0002, evenText(UID_FINDStudyRootQueryRetrieveInformationModel, '\0')) +
                           element(0x0000, 0x0100, us(0x8020)) + element(0x0000, 0x0120, us(message_id)) +
                           element(0x0000, 0x0800, us(with_identifier ? 0x0001 : 0x0101)) +
                           element(0x0000, 0x0900, us(status));
  std::string length;
  putLE(length, static_cast<std::uint32_t>(body.size()), 4);
  return element(0x0000, 0x0000, length) + body;
}

/// Sends `bytes` as P-DATA-TF PDVs of `type`, in fragments the association allows.
bool sendPdvs(T_ASC_Association* assoc, T_ASC_PresentationContextID id, DUL_DATAPDV type, const std::string& bytes) {
  const std::size_t most = std::max<unsigned long>(assoc->sendPDVLength, 16);
  std::size_t at = 0;
  do {
    const std::size_t n = std::min(most, bytes.size() - at);
    DUL_PDV pdv{};
    pdv.fragmentLength = n;
    pdv.presentationContextID = id;
    pdv.pdvType = type;
    pdv.lastPDV = at + n == bytes.size() ? OFTrue : OFFalse;
    pdv.data = const_cast<char*>(bytes.data() + at);
    DUL_PDVLIST list{};
    list.count = 1;
    list.pdv = &pdv;
    if (DUL_WritePDVs(&assoc->DULassociation, &list).bad()) return false;
    at += n;
  } while (at < bytes.size());
  return true;
}

}  // namespace

HostilePacs::HostilePacs(std::string identifier, bool explicit_vr)
    : identifier_(std::move(identifier)), explicit_vr_(explicit_vr), port_(closedPort()) {
  thread_ = std::thread([this] { run(); });
}

HostilePacs::~HostilePacs() {
  stop_ = true;
  thread_.join();
}

PacsServer HostilePacs::server(int timeout_s) const {
  PacsServer s;
  s.host = "127.0.0.1";
  s.port = port_;
  s.called_aet = "HOSTILEPACS";
  s.calling_aet = "VHTEST";
  s.timeout_s = timeout_s;
  return s;
}

bool HostilePacs::waitUntilUp() {
  const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(30);  // the thread may start late
  while (std::chrono::steady_clock::now() < give_up) {
    try {
      pacsEcho(server());
      return true;
    } catch (const PacsError&) {
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
  }
  return false;
}

void HostilePacs::run() {
  T_ASC_Network* net = nullptr;
  if (ASC_initializeNetwork(NET_ACCEPTOR, port_, 5, &net).bad()) return;
  const char* abstract_syntaxes[] = {UID_VerificationSOPClass, UID_FINDStudyRootQueryRetrieveInformationModel};
  const char* transfer_syntaxes[] = {explicit_vr_ ? UID_LittleEndianExplicitTransferSyntax
                                                 : UID_LittleEndianImplicitTransferSyntax};
  while (!stop_) {
    T_ASC_Association* assoc = nullptr;
    if (ASC_receiveAssociation(net, &assoc, ASC_DEFAULTMAXPDU, nullptr, nullptr, OFFalse, DUL_NOBLOCK, 1).bad()) {
      if (assoc != nullptr) ASC_destroyAssociation(&assoc);
      continue;
    }
    ASC_acceptContextsWithPreferredTransferSyntaxes(assoc->params, abstract_syntaxes, 2, transfer_syntaxes, 1);
    if (ASC_acknowledgeAssociation(assoc).good()) {
      while (!stop_) {
        T_ASC_PresentationContextID id = 0;
        T_DIMSE_Message msg{};
        const OFCondition cond = DIMSE_receiveCommand(assoc, DIMSE_NONBLOCKING, 1, &id, &msg, nullptr);
        if (cond == DIMSE_NODATAAVAILABLE) continue;
        if (cond == DUL_PEERREQUESTEDRELEASE) {
          ASC_acknowledgeRelease(assoc);
          break;
        }
        if (cond.bad()) break;  // the client is gone (its process ended)
        if (msg.CommandField == DIMSE_C_ECHO_RQ) {
          DIMSE_sendEchoResponse(assoc, id, &msg.msg.CEchoRQ, STATUS_Success, nullptr);
        } else if (msg.CommandField == DIMSE_C_FIND_RQ) {
          DcmDataset* keys = nullptr;
          DIMSE_receiveDataSetInMemory(assoc, DIMSE_BLOCKING, 0, &id, &keys, nullptr, nullptr);
          delete keys;
          const std::uint16_t message_id = msg.msg.CFindRQ.MessageID;
          ++finds_;
          if (!sendPdvs(assoc, id, DUL_COMMANDPDV, findResponseCommand(message_id, 0xFF00, true)) ||
              !sendPdvs(assoc, id, DUL_DATASETPDV, identifier_) ||
              !sendPdvs(assoc, id, DUL_COMMANDPDV, findResponseCommand(message_id, 0x0000, false))) {
            break;
          }
        } else {
          break;
        }
      }
    }
    ASC_dropSCPAssociation(assoc);
    ASC_destroyAssociation(&assoc);
  }
  ASC_dropNetwork(&net);
}

int closedPort() {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  socklen_t len = sizeof addr;
  const bool ok = ::bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) == 0 &&
                  ::getsockname(fd, reinterpret_cast<sockaddr*>(&addr), &len) == 0;
  ::close(fd);
  return ok ? ntohs(addr.sin_port) : 9;
}

std::string nestedSequencesIdentifier(int depth) {
  std::string out = element(0x0008, 0x0052, evenText("STUDY", ' ')) + element(0x0020, 0x000D, evenText("1.2.3.4", '\0'));
  const std::string level = [] {
    std::string l;
    putLE(l, 0x0040, 2);  // Content Sequence (0040,A730), SQ, undefined length
    putLE(l, 0xA730, 2);
    putLE(l, 0xFFFFFFFFu, 4);
    putLE(l, 0xFFFE, 2);  // Item, undefined length
    putLE(l, 0xE000, 2);
    putLE(l, 0xFFFFFFFFu, 4);
    return l;
  }();
  out.reserve(out.size() + level.size() * static_cast<std::size_t>(depth));
  for (int i = 0; i < depth; ++i) out += level;
  return out;
}

std::string absurdLengthIdentifier(std::uint32_t declared_bytes) {
  std::string out = element(0x0008, 0x0052, evenText("STUDY", ' ')) + element(0x0020, 0x000D, evenText("1.2.3.4", '\0'));
  putLE(out, 0x0010, 2);  // Patient's Name (0010,0010)
  putLE(out, 0x0010, 2);
  putLE(out, declared_bytes, 4);
  return out + std::string(100, 'A');
}

}  // namespace vh::io::test
