// Patient files private (vh/io/private_files.h): every writer of recordings, exports, reports,
// drilled volumes and the run's report creates its file owner-only (0600, folders 0700) under a
// permissive umask (022, the default that made them 0644), replaces a wider file with a 0600
// one, and a write that fails (the file-size limit standing in for a full disk) leaves neither
// the target nor a temporary file beside it. The oracle is the kernel: stat() of what was
// written.
#include <signal.h>
#include <sys/resource.h>
#include <sys/stat.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "file_size_limit.h"
#include "runtime_test_support.h"
#include "vh/io/nrrd_writer.h"
#include "vh/io/private_files.h"
#include "vh/runtime/cohort_table.h"
#include "vh/runtime/recording.h"
#include "vh/runtime/runner.h"
#include "vh/runtime/session_metrics.h"

namespace vh::runtime {
namespace {

namespace fs = std::filesystem;

/// The permission bits of `path` as stat() reports them (-1 when it does not exist).
int modeOf(const fs::path& path) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) return -1;
  return static_cast<int>(st.st_mode & 07777);
}

/// Sets the process's umask for the test's lifetime.
class UmaskScope {
 public:
  explicit UmaskScope(mode_t mask) : old_(::umask(mask)) {}
  ~UmaskScope() { ::umask(old_); }

 private:
  mode_t old_;
};

using vh::test::FileSizeLimit;

std::vector<std::string> namesIn(const fs::path& dir) {
  std::vector<std::string> names;
  for (const auto& e : fs::directory_iterator(dir)) names.push_back(e.path().filename().string());
  std::sort(names.begin(), names.end());
  return names;
}

TickRecord recordAt(std::uint64_t i) {
  TickRecord r;
  r.time_s = static_cast<double>(i) * 1e-3;
  r.tick = i;
  r.force_W_N[0] = 0.001 * static_cast<double>(i);
  r.q_WD[0] = 1.0;
  r.q_WP[0] = 1.0;
  return r;
}

/// A recording of `n` ticks written with RecordingWriter at `path`.
void writeSession(const fs::path& path, std::uint64_t n) {
  RecordingWriterOptions options;
  options.chunk_records = 500;
  options.ring_capacity = 1u << 16;
  RecordingWriter writer(path, R"({"scene":"block-peg","patient_name":"DOE^JANE"})", options);
  for (std::uint64_t i = 0; i < n; ++i) ASSERT_TRUE(writer.push(recordAt(i)));
  writer.close();
}

io::NrrdVolume cube(std::vector<unsigned char>& voxels, int n) {
  voxels.assign(static_cast<std::size_t>(n) * n * n, 7);
  io::NrrdVolume v;
  v.dims = {n, n, n};
  v.type = "uchar";
  v.voxels = voxels.data();
  return v;
}

TEST(PrivateFiles, EveryWriterCreatesOwnerOnlyFilesUnderAPermissiveUmask) {
  const UmaskScope umask022(022);
  const fs::path dir = test::scratchDir() / "private";
  fs::create_directories(dir);
  {  // The umask alone would give 0644: the control that makes the checks below meaningful.
    std::ofstream(dir / "control.txt") << "x";
    ASSERT_EQ(modeOf(dir / "control.txt"), 0644);
  }
  const fs::path rec = dir / "session.vhrec";
  writeSession(rec, 1200);
  EXPECT_EQ(modeOf(rec), 0600) << "recording";
  const Recording recording = readRecording(rec);
  ASSERT_EQ(recording.records.size(), 1200u);

  writeRecordingCsv(recording, dir / "ticks.csv");
  EXPECT_EQ(modeOf(dir / "ticks.csv"), 0600) << "export --csv";
  writeRecordingJson(recording, dir / "meta.json");
  EXPECT_EQ(modeOf(dir / "meta.json"), 0600) << "export --json";
  writeRecordingEventsCsv(recording, dir / "events.csv");
  EXPECT_EQ(modeOf(dir / "events.csv"), 0600) << "export --events-csv";
  writeRunReport(RunReport{}, dir / "report.json");
  EXPECT_EQ(modeOf(dir / "report.json"), 0600) << "run --report";
  writeCohortTable(dir, dir / "cohort.csv");
  EXPECT_EQ(modeOf(dir / "cohort.csv"), 0600) << "report DIR --table";
  std::vector<unsigned char> voxels;
  io::writeNrrd(dir / "drilled.nrrd", cube(voxels, 8));
  EXPECT_EQ(modeOf(dir / "drilled.nrrd"), 0600) << "drilled volume";

  // A file that existed with wider permissions is replaced by a private one.
  std::ofstream(dir / "old.json") << "{}";
  ASSERT_EQ(modeOf(dir / "old.json"), 0644);
  writeRecordingJson(recording, dir / "old.json");
  EXPECT_EQ(modeOf(dir / "old.json"), 0600);
  std::ofstream(dir / "old.vhrec") << "x";
  writeSession(dir / "old.vhrec", 10);
  EXPECT_EQ(modeOf(dir / "old.vhrec"), 0600);

  // No temporary file is left behind by a successful write.
  for (const std::string& name : namesIn(dir)) EXPECT_NE(name.front(), '.') << name;
}

TEST(PrivateFiles, FoldersAreOwnerOnly) {
  const UmaskScope umask022(022);
  const fs::path base = test::scratchDir() / "private-dirs";
  fs::create_directories(base);
  ASSERT_EQ(modeOf(base), 0755);  // what the umask gives
  io::createPrivateDirectories(base / "pacs" / "1.2.840.113619.2.1");
  EXPECT_EQ(modeOf(base / "pacs"), 0700);
  EXPECT_EQ(modeOf(base / "pacs" / "1.2.840.113619.2.1"), 0700);
  EXPECT_EQ(modeOf(base), 0755) << "a folder that existed is left as it was";
  io::createPrivateDirectories(base / "pacs");  // exists: no error
  EXPECT_THROW(io::createPrivateDirectories("/proc/version/x"), std::runtime_error);
}

TEST(PrivateFiles, AFailedWriteLeavesNoPartialFile) {
  const fs::path dir = test::scratchDir() / "private-full";
  fs::create_directories(dir);
  const fs::path rec = dir / "session.vhrec";
  writeSession(rec, 20000);
  const Recording recording = readRecording(rec);
  ASSERT_EQ(recording.records.size(), 20000u);
  std::ofstream(dir / "kept.csv") << "the previous export\n";
  std::vector<unsigned char> voxels;
  const io::NrrdVolume volume = cube(voxels, 64);  // 256 KiB of voxels
  const std::vector<std::string> before = namesIn(dir);
  {
    const FileSizeLimit full(64 * 1024);
    EXPECT_THROW(writeRecordingCsv(recording, dir / "ticks.csv"), std::runtime_error);
    EXPECT_THROW(writeRecordingCsv(recording, dir / "kept.csv"), std::runtime_error);
    EXPECT_THROW(io::writeNrrd(dir / "drilled.nrrd", volume), std::runtime_error);
    io::PrivateOutput abandoned(dir / "abandoned.html");  // an exception before commit()
    abandoned.stream() << "<html>";
  }
  EXPECT_FALSE(fs::exists(dir / "ticks.csv"));
  EXPECT_FALSE(fs::exists(dir / "drilled.nrrd"));
  EXPECT_FALSE(fs::exists(dir / "abandoned.html"));
  EXPECT_EQ(namesIn(dir), before) << "a temporary file was left behind";
  std::ifstream kept(dir / "kept.csv");
  std::string line;
  std::getline(kept, line);
  EXPECT_EQ(line, "the previous export") << "a failed export replaced the file it was to update";
  // Without the limit the same writes succeed (the failures above were the limit's).
  writeRecordingCsv(recording, dir / "ticks.csv");
  EXPECT_GT(fs::file_size(dir / "ticks.csv"), 64u * 1024u);
}

// Only a regular file is ever replaced (the atomic write renames a temporary file over its
// target): a FIFO of the test's own is written in place and stays a FIFO, "-" writes to the
// standard output, a symbolic link and a folder are refused with the reason and left as they
// were (before, each of them was replaced by a regular file: /dev/stdout, /dev/full, a link in
// the user's folder). The oracle is the kernel: lstat() and what a reader of the FIFO receives.
TEST(PrivateFiles, OnlyARegularFileIsEverReplaced) {
  const fs::path dir = test::scratchDir() / "private-nonregular";
  fs::remove_all(dir);
  fs::create_directories(dir);
  const fs::path rec = dir / "session.vhrec";
  writeSession(rec, 50);
  const Recording recording = readRecording(rec);
  std::ostringstream expected;
  writeRecordingCsv(recording, expected);

  // A FIFO: what the export writes reaches its reader; it is still a FIFO afterwards.
  const fs::path fifo = dir / "ticks.fifo";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  std::string received;
  std::thread reader([&] {
    std::ifstream in(fifo, std::ios::binary);
    received.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  });
  writeRecordingCsv(recording, fifo);
  reader.join();
  struct stat st {};
  ASSERT_EQ(::lstat(fifo.c_str(), &st), 0);
  EXPECT_TRUE(S_ISFIFO(st.st_mode)) << "the FIFO was replaced by a regular file";
  EXPECT_EQ(received, expected.str());

  // "-": the standard output.
  testing::internal::CaptureStdout();
  writeRecordingCsv(recording, "-");
  const std::string out = testing::internal::GetCapturedStdout();
  EXPECT_EQ(out, expected.str());
  EXPECT_FALSE(fs::exists("-")) << "a file named - was written";

  // A symbolic link: refused, the link and the file it points to untouched.
  std::ofstream(dir / "real.csv") << "keep\n";
  fs::create_symlink(dir / "real.csv", dir / "link.csv");
  try {
    writeRecordingCsv(recording, dir / "link.csv");
    ADD_FAILURE() << "a symbolic link was written through";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("symbolic link"), std::string::npos) << e.what();
  }
  EXPECT_TRUE(fs::is_symlink(dir / "link.csv"));
  std::ifstream real(dir / "real.csv");
  std::string line;
  std::getline(real, line);
  EXPECT_EQ(line, "keep");

  // A folder: refused, left as it was.
  fs::create_directories(dir / "a-folder.csv");
  EXPECT_THROW(writeRecordingCsv(recording, dir / "a-folder.csv"), std::runtime_error);
  EXPECT_TRUE(fs::is_directory(dir / "a-folder.csv"));
  EXPECT_EQ(namesIn(dir), (std::vector<std::string>{"a-folder.csv", "link.csv", "real.csv", "session.vhrec", "ticks.fifo"}))
      << "a temporary file was left behind";
}

}  // namespace
}  // namespace vh::runtime
