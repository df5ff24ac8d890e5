// The PACS client against hostile servers: answers that crash DCMTK's parser (sequences nested
// 100,000 deep), that declare gigabytes in a small response, and the fuzzer's known crashes of
// the response parser, each sent as raw bytes by a server of the test's own (hostile_pacs.h).
// The oracle is the calling process itself: it goes on, and the error names what happened. Each
// operation runs in the DICOM network process (vh/io/pacs.h); the calling side's deadline covers
// a network process that hangs where no socket can be cut (a host name lookup).

#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

#include <gtest/gtest.h>

#include "hostile_pacs.h"
#include "io_test_support.h"
#include "vh/io/pacs.h"

namespace vh::io {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;
using namespace vh::io::test;  // HostilePacs (hostile_pacs.h), TempDir, secondsSince

/// The calling process's resident memory [bytes] (/proc/self/statm).
std::uint64_t residentBytes() {
  std::ifstream statm("/proc/self/statm");
  std::uint64_t pages = 0, resident = 0;
  statm >> pages >> resident;
  return resident * static_cast<std::uint64_t>(sysconf(_SC_PAGESIZE));
}

TEST(PacsHostile, AnAnswerNested100000DeepEndsTheNetworkProcessNotTheCaller) {
  HostilePacs pacs(nestedSequencesIdentifier(100'000));
  ASSERT_TRUE(pacs.waitUntilUp()) << "the hostile server did not start";
  try {
    const auto studies = pacsFindStudies(pacs.server());
    ADD_FAILURE() << "a C-FIND of an answer nested 100,000 deep returned " << studies.size() << " studies";
  } catch (const PacsError& e) {
    std::printf("[ MESSAGE  ] nested 100,000 deep: %s\n", e.what());
    EXPECT_CONTAINS(e.what(), pacs.server().describe());
    EXPECT_CONTAINS(e.what(), "the DICOM network process crashed (SIGSEGV) on the server's answer to C-FIND");
  }
  EXPECT_EQ(pacs.findsAnswered(), 1) << "the hostile answer was not sent";
  // The caller goes on: the same server still answers an echo, and a series query fails the same way.
  EXPECT_NO_THROW(pacsEcho(pacs.server()));
  EXPECT_THROW(pacsFindSeries(pacs.server(), "1.2.3.4"), PacsError);
}

TEST(PacsHostile, TheFuzzersKnownCrashesOfTheResponseParserAreAnswersThatEndNothing) {
  const fs::path folder = fs::path(VH_SOURCE_DIR) / "tests/fuzz/known-crashes/pacs_response";
  int served = 0;
  for (const auto& entry : fs::directory_iterator(folder)) {
    std::ifstream in(entry.path(), std::ios::binary);
    const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    ASSERT_FALSE(bytes.empty()) << entry.path();
    // The fuzz target's first byte picks the transfer syntax: implicit or explicit VR little
    // endian are what our client proposes (a server cannot answer in another).
    const int syntax = static_cast<unsigned char>(bytes[0]) & 3;
    if (syntax > 1) continue;
    HostilePacs pacs(bytes.substr(1), syntax == 1);
    ASSERT_TRUE(pacs.waitUntilUp()) << "the hostile server did not start";
    std::string outcome;
    try {
      outcome = std::to_string(pacsFindStudies(pacs.server()).size()) + " studies";
    } catch (const PacsError& e) {
      outcome = e.what();
      EXPECT_CONTAINS(e.what(), pacs.server().describe());
    }
    std::printf("[ MESSAGE  ] %s: %s\n", entry.path().filename().c_str(), outcome.c_str());
    EXPECT_GE(pacs.findsAnswered(), 1) << entry.path();
    EXPECT_NO_THROW(pacsEcho(pacs.server())) << entry.path();
    ++served;
  }
  EXPECT_GE(served, 1) << "no known crash in " << folder;
}

TEST(PacsHostile, ASmallAnswerThatDeclaresGigabytesIsANamedErrorAndCostsTheCallerNothing) {
  const std::string identifier = absurdLengthIdentifier(3'600'000'000u);
  std::printf("[ MESSAGE  ] the answer's identifier: %zu bytes declaring 3.6 GB\n", identifier.size());
  ASSERT_LT(identifier.size(), 200u);
  HostilePacs pacs(identifier);
  ASSERT_TRUE(pacs.waitUntilUp()) << "the hostile server did not start";
  const std::uint64_t before = residentBytes();
  const auto t0 = Clock::now();
  try {
    const auto studies = pacsFindStudies(pacs.server(5));
    ADD_FAILURE() << "a C-FIND of an answer declaring 3.6 GB in " << identifier.size() << " bytes returned "
                  << studies.size() << " studies";
  } catch (const PacsError& e) {
    std::printf("[ MESSAGE  ] declares 3.6 GB: failed in %.3f s: %s\n", secondsSince(t0), e.what());
    EXPECT_CONTAINS(e.what(), pacs.server().describe());
    EXPECT_CONTAINS(e.what(), "C-FIND failed");
    EXPECT_CONTAINS(e.what(), "not a well-formed DICOM dataset");
  }
  EXPECT_EQ(pacs.findsAnswered(), 1);
  // Not the value's declared length: what the caller holds grows by far less than 3.6 GB.
  EXPECT_LT(residentBytes(), before + (std::uint64_t{256} << 20));
  EXPECT_NO_THROW(pacsEcho(pacs.server()));
}

TEST(PacsHostile, TheDeadlineCoversANetworkProcessThatHangsWhereNoSocketCanBeCut) {
  // A host name lookup that the resolver never answers blocks before there is a socket for the
  // operation's watchdog to shut down. A stand-in network program that hangs plays it: the
  // calling side's deadline (the timeout and a margin) must stop it.
  TempDir dir("pacs_hanging");
  const fs::path program = dir.path() / "hanging-network-process";
  {
    std::ofstream out(program);
    out << "#!/bin/sh\nexec sleep 120\n";
  }
  fs::permissions(program, fs::perms::owner_all);
  ASSERT_EQ(setenv("VH_DICOM_WORKER", program.c_str(), 1), 0);
  PacsServer server;
  server.host = "pacs.example.invalid";
  server.port = 104;
  server.timeout_s = 1;
  const auto t0 = Clock::now();
  try {
    pacsEcho(server);
    ADD_FAILURE() << "an echo through a hanging network process returned";
  } catch (const PacsError& e) {
    std::printf("[ TIMING   ] hanging network process: failed in %.3f s: %s\n", secondsSince(t0), e.what());
    EXPECT_CONTAINS(e.what(), "C-ECHO did not finish within the timeout of 1 s, so the DICOM network process was stopped");
    EXPECT_CONTAINS(e.what(), "pacs.example.invalid");
  }
  unsetenv("VH_DICOM_WORKER");
  // Not before the timeout; well before the stand-in's 120 s (a loaded machine's late wake-up
  // has room).
  EXPECT_GE(secondsSince(t0), 1.0);
  EXPECT_LT(secondsSince(t0), 30.0);
}

}  // namespace
}  // namespace vh::io
