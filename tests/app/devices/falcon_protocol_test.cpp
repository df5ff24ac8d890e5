// Tests of vh/devices/falcon_protocol.h against the golden vectors of ../shared/docs/devices.md:
// nibble words, command and status packets, FTDI status stripping, stream reassembly, the set-up
// control transfers.
#include "vh/devices/falcon_protocol.h"

#include <random>
#include <vector>

#include <gtest/gtest.h>

namespace vh::devices::falcon {
namespace {

TEST(FalconProtocol, WordGoldenVector) {
  std::uint8_t out[4];
  encodeWord(0x1234, out);
  EXPECT_EQ(out[0], 0x45);
  EXPECT_EQ(out[1], 0x44);
  EXPECT_EQ(out[2], 0x43);
  EXPECT_EQ(out[3], 0x42);
  std::int16_t back = 0;
  ASSERT_TRUE(decodeWord(out, back));
  EXPECT_EQ(back, 0x1234);
}

TEST(FalconProtocol, WordsRoundTripOverTheWholeRange) {
  for (int v = -32768; v <= 32767; ++v) {
    std::uint8_t out[4];
    encodeWord(static_cast<std::int16_t>(v), out);
    for (std::uint8_t b : out) ASSERT_TRUE(b >= 0x41 && b <= 0x50);
    std::int16_t back = 0;
    ASSERT_TRUE(decodeWord(out, back));
    ASSERT_EQ(back, v);
  }
  const std::uint8_t bad[4] = {0x41, 0x40, 0x41, 0x41};
  std::int16_t v = 7;
  EXPECT_FALSE(decodeWord(bad, v));
  EXPECT_EQ(v, 7);
}

TEST(FalconProtocol, ZeroForceLedsOffGoldenVector) {
  const Packet p = encodeCommand({});
  Packet expected{};
  expected.fill(0x41);
  expected[0] = 0x3C;
  expected[15] = 0x3E;
  EXPECT_EQ(p, expected);
}

TEST(FalconProtocol, CommandCarriesMotorsLedsAndHoming) {
  Command c;
  c.motor = {0x1234, -1, 0};
  c.flags = kLedGreen | kHomingMode;
  const Packet p = encodeCommand(c);
  EXPECT_EQ(p[1], 0x45);
  EXPECT_EQ(p[4], 0x42);
  for (int i = 5; i <= 8; ++i) EXPECT_EQ(p[static_cast<std::size_t>(i)], 0x50) << i;  // -1 = 0xFFFF
  EXPECT_EQ(p[13], 0x41 + 0x3);
  EXPECT_EQ(p[14], 0x41);
}

TEST(FalconProtocol, StatusDecodesEncodersHomingAndButtons) {
  Status s;
  s.encoder = {-1200, 35, 32767};
  s.homed_mask = 0x5;
  s.buttons = 0xA;
  const Packet p = encodeStatus(s);
  EXPECT_EQ(p[13], 0x41 + ((0x5 << 4) | 0xA));  // ((b - 0x41) >> 4) & 7 homed, (b - 0x41) & 0xF buttons
  Status d;
  ASSERT_TRUE(decodeStatus(p.data(), d));
  EXPECT_EQ(d.encoder, s.encoder);
  EXPECT_EQ(d.homed_mask, 0x5);
  EXPECT_EQ(d.buttons, 0xA);
  EXPECT_FALSE(d.allHomed());
  Packet broken = p;
  broken[15] = 0x00;
  EXPECT_FALSE(decodeStatus(broken.data(), d));
  broken = p;
  broken[3] = 0x20;
  EXPECT_FALSE(decodeStatus(broken.data(), d));
}

TEST(FalconProtocol, FtdiStatusBytesAreStrippedFromEveryUsbPacket) {
  std::vector<std::uint8_t> in(128 + 10);
  for (std::size_t i = 0; i < in.size(); ++i) in[i] = static_cast<std::uint8_t>(i);
  std::vector<std::uint8_t> out(in.size());
  const std::size_t n = stripFtdiStatus(in.data(), in.size(), out.data());
  ASSERT_EQ(n, 62u + 62u + 8u);
  EXPECT_EQ(out[0], 2);
  EXPECT_EQ(out[61], 63);
  EXPECT_EQ(out[62], 66);   // second packet: bytes 64, 65 dropped
  EXPECT_EQ(out[124], 130); // third packet: bytes 128, 129 dropped
  std::uint8_t only_status[2] = {0x31, 0x60};
  EXPECT_EQ(stripFtdiStatus(only_status, 2, out.data()), 0u);
}

TEST(FalconProtocol, ParserReassemblesSplitPacketsAndSkipsJunk) {
  Status a;
  a.encoder = {1, 2, 3};
  a.homed_mask = 7;
  Status b;
  b.encoder = {-4, -5, -6};
  b.buttons = 1;
  const Packet pa = encodeStatus(a);
  const Packet pb = encodeStatus(b);
  std::vector<std::uint8_t> stream = {0x00, 0x3C, 0x99};  // junk, including a false start
  stream.insert(stream.end(), pa.begin(), pa.end());
  stream.insert(stream.end(), pb.begin(), pb.end());
  PacketParser parser;
  Status s;
  // Fed in awkward pieces.
  parser.feed(stream.data(), 5);
  EXPECT_FALSE(parser.next(s));
  parser.feed(stream.data() + 5, 17);
  ASSERT_TRUE(parser.next(s));
  EXPECT_EQ(s.encoder, a.encoder);
  EXPECT_FALSE(parser.next(s));
  parser.feed(stream.data() + 22, stream.size() - 22);
  ASSERT_TRUE(parser.next(s));
  EXPECT_EQ(s.encoder, b.encoder);
  EXPECT_EQ(s.buttons, 1);
  EXPECT_FALSE(parser.next(s));
  EXPECT_EQ(parser.discardedBytes(), 3u);
}

TEST(FalconProtocol, ParserSurvivesAFloodOfJunk) {
  PacketParser parser;
  std::mt19937 rng(3);
  std::vector<std::uint8_t> junk(5000);
  for (auto& j : junk) j = static_cast<std::uint8_t>(rng() & 0x3F);  // never '<'... mostly
  for (auto& j : junk) if (j == 0x3C) j = 0;
  parser.feed(junk.data(), junk.size());
  Status s;
  EXPECT_FALSE(parser.next(s));
  Status good;
  good.encoder = {9, 8, 7};
  const Packet p = encodeStatus(good);
  parser.feed(p.data(), p.size());
  ASSERT_TRUE(parser.next(s));
  EXPECT_EQ(s.encoder, good.encoder);
}

TEST(FalconProtocol, SetUpSequencesMatchTheDocument) {
  // 1. purge, latency 16; 2. 9600 baud, 8N1, no flow control; 3. RTS low, DTR low then high.
  const std::vector<std::pair<int, int>> boot = {{0, 1}, {0, 2}, {9, 16}, {3, 0x4138}, {4, 8},
                                                 {2, 0}, {1, 0x0200}, {1, 0x0100}, {1, 0x0101}};
  ASSERT_EQ(kBootloaderSetup.size(), boot.size());
  for (std::size_t i = 0; i < boot.size(); ++i) {
    EXPECT_EQ(kBootloaderSetup[i].request, boot[i].first) << i;
    EXPECT_EQ(kBootloaderSetup[i].value, boot[i].second) << i;
  }
  // 5. DTR low, baud divisor 0x15; 7. latency 1, divisor 2, purge.
  EXPECT_EQ(kLoaderSetup[0].request, 1);
  EXPECT_EQ(kLoaderSetup[0].value, 0x0100);
  EXPECT_EQ(kLoaderSetup[1].request, 3);
  EXPECT_EQ(kLoaderSetup[1].value, 0x15);
  EXPECT_EQ(kNormalModeSetup[0].request, 9);
  EXPECT_EQ(kNormalModeSetup[0].value, 1);
  EXPECT_EQ(kNormalModeSetup[1].request, 3);
  EXPECT_EQ(kNormalModeSetup[1].value, 2);
  EXPECT_EQ(kControlRequestType, 0x40);
  EXPECT_EQ(kVendorId, 0x0403);
  EXPECT_EQ(kProductId, 0xCB48);
}

TEST(FalconProtocol, BootCheckReplyAcceptsTheWholeOrItsStart) {
  const std::uint8_t full[4] = {0x0A, 0x44, 0x2C, 0x0D};
  EXPECT_TRUE(isBootCheckReply(full, 4));
  EXPECT_TRUE(isBootCheckReply(full, 2));
  EXPECT_FALSE(isBootCheckReply(full, 1));
  const std::uint8_t wrong[4] = {0x0A, 0x45, 0x2C, 0x0D};
  EXPECT_FALSE(isBootCheckReply(wrong, 4));
}

}  // namespace
}  // namespace vh::devices::falcon
