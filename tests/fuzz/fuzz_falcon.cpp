// Fuzz target: Novint Falcon bulk-IN transfers through the driver's pure code, as
// FalconDevice's I/O thread uses it: falcon::stripFtdiStatus() on each transfer,
// falcon::PacketParser feed() / next() to reassemble 16-byte status packets, then the encoders
// through encoderToAngle_rad() and forwardKinematics() (warm-started at the last solution); the
// first transfer also through isBootCheckReply().
// Input: a sequence of transfers, each one length byte (mod 65; a transfer is at most one
// 64-byte USB packet) and that many bytes.
// Expected: no crash, no sanitizer report.
#include <cstddef>
#include <cstdint>

#include <Eigen/Core>

#include "vh/devices/falcon_kinematics.h"
#include "vh/devices/falcon_protocol.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  namespace falcon = vh::devices::falcon;
  falcon::PacketParser parser;
  Eigen::Vector3d p_K(0.0, 0.0, falcon::kForwardStartZ_m);
  bool have_position = false;
  bool first = true;
  std::size_t at = 0;
  while (at < size) {
    const std::size_t n = data[at] % (falcon::kUsbPacketBytes + 1);
    ++at;
    const std::size_t take = n < size - at ? n : size - at;
    std::uint8_t raw[falcon::kUsbPacketBytes];
    std::uint8_t serial[falcon::kUsbPacketBytes];
    for (std::size_t i = 0; i < take; ++i) raw[i] = data[at + i];
    at += take;
    const std::size_t got = falcon::stripFtdiStatus(raw, take, serial);
    if (first) {
      (void)falcon::isBootCheckReply(serial, got);
      first = false;
    }
    if (got >= 4) {
      std::int16_t word = 0;
      (void)falcon::decodeWord(serial, word);
    }
    parser.feed(serial, got);
    falcon::Status status;
    while (parser.next(status)) {
      const Eigen::Vector3d theta(falcon::encoderToAngle_rad(status.encoder[0]),
                                  falcon::encoderToAngle_rad(status.encoder[1]),
                                  falcon::encoderToAngle_rad(status.encoder[2]));
      Eigen::Vector3d p_new;
      const Eigen::Vector3d start = have_position ? p_K : Eigen::Vector3d(0.0, 0.0, falcon::kForwardStartZ_m);
      if (falcon::forwardKinematics(theta, p_new, start)) {
        p_K = p_new;
        have_position = true;
      }
    }
  }
  return 0;
}
