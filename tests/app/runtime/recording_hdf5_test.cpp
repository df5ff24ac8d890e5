// Recordings as HDF5 (recording_hdf5.h): every field back bit for bit, the layout as documented
// (read with the HDF5 library's own API, not our reader), refusals of bad targets and of
// damaged or hostile files.
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <hdf5.h>

#include "runtime_test_support.h"
#include "vh/runtime/recording.h"
#include "vh/runtime/recording_hdf5.h"

namespace vh::runtime {
namespace {

namespace fs = std::filesystem;

/// A recording whose records hold the values a file format gets wrong: NaN, infinities, -0,
/// the integers' extremes; events with quotes, new lines and UTF-8; warnings; odd counters.
Recording awkwardRecording(std::size_t n) {
  Recording rec;
  rec.version = kRecordingFormatVersion;
  rec.metadata_json = R"({"scene":{"volume":{"path":"builtin:sphere","isovalue":0}},"servo_rate_Hz":1000,"user":"Zoë"})";
  for (std::size_t i = 0; i < n; ++i) {
    TickRecord r;
    r.time_s = static_cast<double>(i) * 1e-3;
    for (int k = 0; k < 3; ++k) {
      r.p_WD_m[k] = 0.01 * std::sin(static_cast<double>(i + k));
      r.p_WP_m[k] = -0.0;
      r.force_W_N[k] = static_cast<double>(i) / 7.0 - k;
      r.torque_W_Nm[k] = std::ldexp(1.0, -1074);  // the smallest subnormal
    }
    r.q_WD[2] = std::numeric_limits<double>::quiet_NaN();
    r.isovalue = i % 2 == 0 ? std::numeric_limits<double>::infinity() : -1024.5;
    r.tick = std::numeric_limits<std::uint64_t>::max() - i;
    r.tick_time_s = 1e-6 * static_cast<double>(i);
    r.contacts = std::numeric_limits<std::uint32_t>::max() - static_cast<std::uint32_t>(i);
    r.flags = 0xDEADBEEFu ^ static_cast<std::uint32_t>(i);
    r.critical_distance_m = i % 3 == 0 ? std::numeric_limits<double>::quiet_NaN() : 0.002;
    r.critical_segment = i % 2 == 0 ? -1 : std::numeric_limits<std::int32_t>::min();
    r.removed_voxels = static_cast<std::uint32_t>(i * 3);
    r.deadline_work = i % 2 == 0 ? std::numeric_limits<std::int64_t>::max() : std::numeric_limits<std::int64_t>::min();
    rec.records.push_back(r);
  }
  rec.events = {{0.5, 500, "marker", R"({"label":"nerve \"V2\"\nsecond line é"})"},
                {0.75, 750, "isovalue", R"({"from":400,"to":500})"},
                {1.0, 1000, "note", ""}};
  rec.warnings = {"a damaged chunk at byte 4096", "unfinished recording"};
  rec.chunks = 7;
  rec.event_chunks = 2;
  rec.dropped_records = 3;
  rec.bytes_ignored = 123456789012ull;
  rec.damaged_regions = 1;
  rec.ended = false;
  rec.end_status = 28;  // ENOSPC
  return rec;
}

void expectSame(const Recording& a, const Recording& b) {
  EXPECT_EQ(a.version, b.version);
  EXPECT_EQ(a.metadata_json, b.metadata_json);
  ASSERT_EQ(a.records.size(), b.records.size());
  for (std::size_t i = 0; i < a.records.size(); ++i)
    ASSERT_EQ(std::memcmp(&a.records[i], &b.records[i], sizeof(TickRecord)), 0) << "record " << i;
  ASSERT_EQ(a.events.size(), b.events.size());
  for (std::size_t i = 0; i < a.events.size(); ++i) {
    EXPECT_EQ(a.events[i].time_s, b.events[i].time_s);
    EXPECT_EQ(a.events[i].tick, b.events[i].tick);
    EXPECT_EQ(a.events[i].type, b.events[i].type);
    EXPECT_EQ(a.events[i].detail_json, b.events[i].detail_json);
  }
  EXPECT_EQ(a.warnings, b.warnings);
  EXPECT_EQ(a.chunks, b.chunks);
  EXPECT_EQ(a.event_chunks, b.event_chunks);
  EXPECT_EQ(a.dropped_records, b.dropped_records);
  EXPECT_EQ(a.bytes_ignored, b.bytes_ignored);
  EXPECT_EQ(a.damaged_regions, b.damaged_regions);
  EXPECT_EQ(a.ended, b.ended);
  EXPECT_EQ(a.end_status, b.end_status);
}

TEST(RecordingHdf5, EveryFieldComesBackBitForBit) {
  const fs::path path = test::scratchDir() / "awkward.h5";
  const Recording rec = awkwardRecording(40000);  // more than two compressed chunks per column
  writeRecordingHdf5(rec, path);
  EXPECT_TRUE(isHdf5File(path));
  EXPECT_EQ(fs::status(path).permissions() & fs::perms::all, fs::perms::owner_read | fs::perms::owner_write);
  expectSame(rec, readRecording(path));  // readRecording() recognises the HDF5 signature
}

TEST(RecordingHdf5, AnEmptyRecordingComesBackEmpty) {
  const fs::path path = test::scratchDir() / "empty.h5";
  Recording rec;
  rec.version = 1;
  writeRecordingHdf5(rec, path);
  expectSame(rec, readRecordingHdf5(path));
}

/// The layout with the HDF5 library's own calls: a column is where and what the header says.
TEST(RecordingHdf5, ColumnsAreWhereTheLayoutSays) {
  const fs::path path = test::scratchDir() / "layout.h5";
  const Recording rec = awkwardRecording(100);
  writeRecordingHdf5(rec, path);
  const hid_t file = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  ASSERT_GE(file, 0);
  std::vector<double> force_y(rec.records.size());
  const hid_t force = H5Dopen2(file, "/ticks/force_y_N", H5P_DEFAULT);
  ASSERT_GE(force, 0);
  ASSERT_GE(H5Dread(force, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, force_y.data()), 0);
  const hid_t stored = H5Dget_type(force);
  EXPECT_TRUE(H5Tequal(stored, H5T_IEEE_F64LE) > 0);
  H5Tclose(stored);
  H5Dclose(force);
  std::vector<std::int32_t> segment(rec.records.size());
  const hid_t seg = H5Dopen2(file, "/ticks/critical_segment", H5P_DEFAULT);
  ASSERT_GE(seg, 0);
  const hid_t seg_type = H5Dget_type(seg);
  EXPECT_TRUE(H5Tequal(seg_type, H5T_STD_I32LE) > 0);
  H5Tclose(seg_type);
  ASSERT_GE(H5Dread(seg, H5T_NATIVE_INT32, H5S_ALL, H5S_ALL, H5P_DEFAULT, segment.data()), 0);
  H5Dclose(seg);
  for (std::size_t i = 0; i < rec.records.size(); ++i) {
    EXPECT_EQ(force_y[i], rec.records[i].force_W_N[1]);
    EXPECT_EQ(segment[i], rec.records[i].critical_segment);
  }
  // Thirty columns, one per `export --csv` column.
  const hid_t ticks = H5Gopen2(file, "/ticks", H5P_DEFAULT);
  H5G_info_t info{};
  ASSERT_GE(H5Gget_info(ticks, &info), 0);
  EXPECT_EQ(info.nlinks, 30u);
  H5Gclose(ticks);
  H5Fclose(file);
}

TEST(RecordingHdf5, TargetsThatAreNotRegularFilesAreRefusedAndKept) {
  const fs::path dir = test::scratchDir();
  const Recording rec = awkwardRecording(10);
  {
    std::ofstream(dir / "real.h5") << "keep";
  }
  fs::create_symlink(dir / "real.h5", dir / "link.h5");
  EXPECT_THROW(writeRecordingHdf5(rec, dir / "link.h5"), std::runtime_error);
  EXPECT_TRUE(fs::is_symlink(dir / "link.h5"));
  std::ifstream real(dir / "real.h5");
  std::string kept;
  real >> kept;
  EXPECT_EQ(kept, "keep");
  try {
    writeRecordingHdf5(rec, "-");
    ADD_FAILURE() << "\"-\" was accepted";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("regular file"), std::string::npos) << e.what();
  }
  EXPECT_THROW(writeRecordingHdf5(rec, "/dev/null"), std::runtime_error);
  EXPECT_TRUE(fs::is_character_file("/dev/null"));
  for (const auto& entry : fs::directory_iterator(dir))  // no temporary file left behind
    EXPECT_EQ(entry.path().filename().string().rfind(".link", 0), std::string::npos) << entry.path();
}

/// A file cut anywhere is refused with a message naming it, never read as part of a recording
/// (HDF5 keeps its object headers and the superblock's end-of-file address: a cut shows).
TEST(RecordingHdf5, ACutFileIsRefusedWhereverItIsCut) {
  const fs::path dir = test::scratchDir();
  writeRecordingHdf5(awkwardRecording(3000), dir / "whole.h5");
  std::ifstream in(dir / "whole.h5", std::ios::binary);
  const std::string bytes{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
  for (int part = 1; part < 40; ++part) {
    const std::size_t size = bytes.size() * static_cast<std::size_t>(part) / 40;
    const fs::path cut = dir / ("cut" + std::to_string(part) + ".h5");
    std::ofstream(cut, std::ios::binary).write(bytes.data(), static_cast<std::streamsize>(size));
    try {
      const Recording r = readRecording(cut);
      ADD_FAILURE() << "a file cut at " << size << " of " << bytes.size() << " bytes read as " << r.records.size()
                    << " records";
    } catch (const std::runtime_error& e) {
      EXPECT_NE(std::string(e.what()).find(cut.string()), std::string::npos) << e.what();
    }
  }
}

TEST(RecordingHdf5, MetadataNestedBeyondTheLimitIsRefusedAsTheVhrecReaderDoes) {
  const fs::path path = test::scratchDir() / "deep.h5";
  Recording rec = awkwardRecording(5);
  rec.metadata_json = std::string(kMaxRecordingJsonDepth + 1, '[') + std::string(kMaxRecordingJsonDepth + 1, ']');
  rec.events.push_back({1.0, 1, "note", std::string(500, '[') + std::string(500, ']')});
  writeRecordingHdf5(rec, path);  // written as given (a caller's own text)
  try {
    readRecording(path);
    ADD_FAILURE() << "metadata nested " << kMaxRecordingJsonDepth + 1 << " deep was read";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("nested"), std::string::npos) << e.what();
  }
  rec.metadata_json = "{}";
  writeRecordingHdf5(rec, path);
  const Recording back = readRecording(path);
  EXPECT_EQ(back.events.size(), rec.events.size() - 1);  // the deep event dropped, and said
  ASSERT_FALSE(back.warnings.empty());
  EXPECT_NE(back.warnings.back().find("dropped"), std::string::npos) << back.warnings.back();
}

/// The window reads only the .vhrec (its parser is this program's own and fuzzed; HDF5's is
/// neither, and a crash there would end a session): an HDF5 export is refused with the reason.
TEST(RecordingHdf5, TheWindowsReaderRefusesAnHdf5ExportSayingWhy) {
  const fs::path path = test::scratchDir() / "export.h5";
  writeRecordingHdf5(awkwardRecording(10), path);
  try {
    readRecording(path, RecordingFiles::kVhrecOnly);
    ADD_FAILURE() << "the window's reader read an HDF5 file";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("HDF5 export"), std::string::npos) << e.what();
  }
  EXPECT_EQ(readRecording(path, RecordingFiles::kVhrecOrHdf5).records.size(), 10u);
}

}  // namespace
}  // namespace vh::runtime
