// Headers written to attack the readers: a printf format in MetaImage's ElementDataFile, data
// files outside the header's folder, spacings of 0 / nan / negative, a FIFO where a file should
// be, and a few bytes declaring half a terabyte. Each is refused with a LoadError naming the
// file and the reason before VTK or the reader opens anything; the controls beside them (the
// same header with a harmless value) load, so the refusals are the checks' and nothing else's.
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <thread>

#include <gtest/gtest.h>

#include "io_test_support.h"
#include "vh/io/segmentation.h"
#include "vh/io/volume_loader.h"

namespace {

namespace fs = std::filesystem;
using vh::io::loadVolume;
using vh::io::test::loadErrorOf;
using vh::io::test::secondsSince;
using vh::io::test::TempDir;
using vh::io::test::writeFile;

const std::string kNrrdCommon = "NRRD0004\ntype: short\ndimension: 3\nsizes: 4 3 2\nendian: little\nencoding: raw\n";
const std::string kMetaCommon = "ObjectType = Image\nNDims = 3\nDimSize = 4 3 2\nElementType = MET_SHORT\n";
const std::string kVoxels(48, '\x01');  // 4 x 3 x 2 shorts

/// A FIFO at `path`; a helper opens its write end after `after` so that a reader blocked in
/// open() is released (the test then fails on time instead of hanging). Join before the end.
class Fifo {
 public:
  Fifo(const fs::path& path, std::chrono::milliseconds after) : path_(path) {
    if (::mkfifo(path.c_str(), 0600) != 0) ADD_FAILURE() << "mkfifo " << path;
    releaser_ = std::thread([this, after] {
      const auto end = std::chrono::steady_clock::now() + after;
      while (!done_ && std::chrono::steady_clock::now() < end) std::this_thread::sleep_for(std::chrono::milliseconds(10));
      if (done_) return;
      const int fd = ::open(path_.c_str(), O_WRONLY | O_NONBLOCK);  // succeeds only with a reader waiting
      if (fd >= 0) ::close(fd);
    });
  }
  ~Fifo() {
    done_ = true;
    releaser_.join();
  }

 private:
  fs::path path_;
  std::atomic<bool> done_{false};
  std::thread releaser_;
};

TEST(HostileHeaders, MetaImageDataFilePatternNeverReachesAFormatFunction) {
  TempDir tmp("hostile_pattern");
  writeFile(tmp / "fmt.mhd", kMetaCommon + "ElementDataFile = %s%n%s 1 2 1\n");
  const std::string msg = loadErrorOf([&] { loadVolume(tmp / "fmt.mhd"); });
  EXPECT_CONTAINS(msg, "fmt.mhd");
  EXPECT_CONTAINS(msg, "file-name pattern");
  EXPECT_EQ(msg.find("crashed"), std::string::npos) << msg;
  // The control: the same header with a plain file name loads.
  writeFile(tmp / "plain.raw", kVoxels);
  writeFile(tmp / "plain.mhd", kMetaCommon + "ElementDataFile = plain.raw\n");
  EXPECT_EQ(loadVolume(tmp / "plain.mhd").field->geometry().dims, (std::array<int, 3>{4, 3, 2}));
}

TEST(HostileHeaders, DetachedDataFilesOnlyBesideTheirHeader) {
  TempDir tmp("hostile_escape");
  fs::create_directories(tmp / "case" / "data");
  writeFile(tmp / "outside.raw", kVoxels);
  writeFile(tmp / "case" / "data" / "inside.raw", kVoxels);
  const fs::path nhdr = tmp / "case" / "v.nhdr";
  for (const std::string& target : {std::string("../outside.raw"), (tmp / "outside.raw").string(),
                                    std::string("data/../../outside.raw"), std::string("/etc/passwd")}) {
    writeFile(nhdr, kNrrdCommon + "data file: " + target + "\n\n");
    const std::string msg = loadErrorOf([&] { loadVolume(nhdr); });
    EXPECT_CONTAINS(msg, "v.nhdr");
    EXPECT_CONTAINS(msg, "outside the header's folder");
  }
  const fs::path mhd = tmp / "case" / "v.mhd";
  for (const std::string& target : {std::string("../outside.raw"), std::string("/etc/passwd")}) {
    writeFile(mhd, kMetaCommon + "ElementDataFile = " + target + "\n");
    const std::string msg = loadErrorOf([&] { loadVolume(mhd); });
    EXPECT_CONTAINS(msg, "v.mhd");
    EXPECT_CONTAINS(msg, "outside the header's folder");
  }
  // A symbolic link beside the header that points out is resolved and refused too.
  fs::create_symlink(tmp / "outside.raw", tmp / "case" / "link.raw");
  writeFile(nhdr, kNrrdCommon + "data file: link.raw\n\n");
  EXPECT_CONTAINS(loadErrorOf([&] { loadVolume(nhdr); }), "outside the header's folder");
  // Controls: a file beside or below the header loads.
  writeFile(nhdr, kNrrdCommon + "data file: data/inside.raw\n\n");
  EXPECT_EQ(loadVolume(nhdr).field->geometry().dims, (std::array<int, 3>{4, 3, 2}));
  writeFile(mhd, kMetaCommon + "ElementDataFile = data/inside.raw\n");
  EXPECT_EQ(loadVolume(mhd).field->geometry().dims, (std::array<int, 3>{4, 3, 2}));
}

TEST(HostileHeaders, SpacingsOfZeroNanOrNegativeAreRefused) {
  TempDir tmp("hostile_spacing");
  for (const std::string spacings : {"0 0 0", "nan nan nan", "-2 -2 -2", "1 0 1"}) {
    writeFile(tmp / "s.nrrd", kNrrdCommon + "spacings: " + spacings + "\n\n" + kVoxels);
    const std::string msg = loadErrorOf([&] { loadVolume(tmp / "s.nrrd"); });
    EXPECT_CONTAINS(msg, "s.nrrd");
    EXPECT_CONTAINS(msg, "\"spacings\" must be positive numbers, found \"" + spacings + "\"");
  }
  writeFile(tmp / "ok.nrrd", kNrrdCommon + "spacings: 0.5 0.5 2\n\n" + kVoxels);
  EXPECT_NEAR(loadVolume(tmp / "ok.nrrd").field->geometry().spacing_m.z(), 0.002, 1e-12);

  writeFile(tmp / "v.raw", kVoxels);
  for (const std::string spacing : {"0 1 1", "-2 1 1"}) {
    writeFile(tmp / "s.mhd", kMetaCommon + "ElementSpacing = " + spacing + "\nElementDataFile = v.raw\n");
    const std::string msg = loadErrorOf([&] { loadVolume(tmp / "s.mhd"); });
    EXPECT_CONTAINS(msg, "ElementSpacing must be 3 positive numbers");
  }
  writeFile(tmp / "s.mhd", kMetaCommon + "ElementSpacing = nan nan nan\nElementDataFile = v.raw\n");
  EXPECT_CONTAINS(loadErrorOf([&] { loadVolume(tmp / "s.mhd"); }), "ElementSpacing");
}

// Voxels of 1e-30 mm (before: accepted, and `run`, `make-trajectory` and `load_scene` then ran
// for hours walking the volume in voxels; 1e-4 mm took 22 s) are refused at the load with the
// size; a micro-CT's 1 um voxels still load.
TEST(HostileHeaders, VoxelsBelowAMicrometreAreRefused) {
  TempDir tmp("hostile_tiny_voxels");
  writeFile(tmp / "v.raw", kVoxels);
  writeFile(tmp / "tiny.mhd", kMetaCommon + "ElementSpacing = 1e-30 1e-30 1e-30\nElementDataFile = v.raw\n");
  const std::string msg = loadErrorOf([&] { loadVolume(tmp / "tiny.mhd"); });
  EXPECT_CONTAINS(msg, "tiny.mhd");
  EXPECT_CONTAINS(msg, "below 0.001 mm (1 um)");
  writeFile(tmp / "tiny.nrrd", kNrrdCommon + "spacings: 1e-4 1 1\n\n" + kVoxels);
  EXPECT_CONTAINS(loadErrorOf([&] { loadVolume(tmp / "tiny.nrrd"); }), "a voxel side of 0.0001 mm");
  writeFile(tmp / "micro.mhd", kMetaCommon + "ElementSpacing = 0.001 0.001 0.001\nElementDataFile = v.raw\n");
  EXPECT_NEAR(loadVolume(tmp / "micro.mhd").field->geometry().spacing_m.x(), 1e-6, 1e-12);
}

TEST(HostileHeaders, AFifoNeverBlocksTheReader) {
  TempDir tmp("hostile_fifo");
  {  // A detached data file that is a FIFO.
    // Released after 60 s; the reader, which must not open it, is done long before (30 s leaves
    // a loaded machine room and still tells the two apart).
    const Fifo fifo(tmp / "data.raw", std::chrono::milliseconds(60000));
    writeFile(tmp / "v.nhdr", kNrrdCommon + "data file: data.raw\n\n");
    const auto t0 = std::chrono::steady_clock::now();
    const std::string msg = loadErrorOf([&] { loadVolume(tmp / "v.nhdr"); });
    EXPECT_LT(secondsSince(t0), 30.0) << "blocked on the FIFO until released";
    EXPECT_CONTAINS(msg, "data.raw is a FIFO");
  }
  {  // A segmentation path that is a FIFO.
    const Fifo fifo(tmp / "seg.nrrd", std::chrono::milliseconds(60000));
    const auto t0 = std::chrono::steady_clock::now();
    EXPECT_FALSE(vh::io::isSegmentationFile(tmp / "seg.nrrd"));
    const std::string msg = loadErrorOf([&] { vh::io::loadSegmentation(tmp / "seg.nrrd"); });
    EXPECT_LT(secondsSince(t0), 30.0) << "blocked on the FIFO until released";
    EXPECT_CONTAINS(msg, "seg.nrrd");
    EXPECT_CONTAINS(msg, "a FIFO, not a regular file");
  }
  // A device as the data file (it would never end).
  writeFile(tmp / "dev.nhdr", kNrrdCommon + "data file: /dev/zero\n\n");
  EXPECT_CONTAINS(loadErrorOf([&] { loadVolume(tmp / "dev.nhdr"); }), "outside the header's folder");
}

TEST(HostileHeaders, DeclaredVoxelsLargerThanMemoryAreRefusedBeforeReading) {
  TempDir tmp("hostile_memory");
  // 65536 x 65536 x 64 shorts: 512 GiB from a header of a few hundred bytes.
  writeFile(tmp / "big.nrrd", "NRRD0004\ntype: short\ndimension: 3\nsizes: 65536 65536 64\nendian: little\n"
                              "encoding: gzip\n\n\x1f\x8b" + std::string(100, '\0'));
  const std::string msg = loadErrorOf([&] { loadVolume(tmp / "big.nrrd"); });
  EXPECT_CONTAINS(msg, "big.nrrd");
  EXPECT_CONTAINS(msg, "declares 512 GiB of voxels but");
  EXPECT_CONTAINS(msg, "of memory is available");
  writeFile(tmp / "big.mha", "ObjectType = Image\nNDims = 3\nDimSize = 65536 65536 64\nElementType = MET_SHORT\n"
                             "CompressedData = True\nElementDataFile = LOCAL\n" + std::string(100, '\0'));
  const std::string meta = loadErrorOf([&] { loadVolume(tmp / "big.mha"); });
  EXPECT_CONTAINS(meta, "big.mha");
  EXPECT_CONTAINS(meta, "declares 512 GiB of voxels but");
}

}  // namespace
