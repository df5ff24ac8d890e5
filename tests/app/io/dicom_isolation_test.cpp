// No input crashes the application: scans and meshes are read in the reader process
// (vh/io/reader_process.h). A reader crash there becomes a LoadError naming the file; damaged
// copies of a real series never take the test process down.

#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <fstream>
#include <iostream>
#include <random>

#include <gtest/gtest.h>
#include <vtkImageData.h>

#include "io_test_support.h"
#include "vh/io/dicom_series.h"
#include "vh/io/reader_process.h"
#include "vh/io/volume_loader.h"

namespace vh::io::test {
namespace {

constexpr char kCtHead[] = "ct/ct-head-small";

/// Sets an environment variable for the scope.
class ScopedEnv {
 public:
  ScopedEnv(const char* name, const std::string& value) : name_(name) {
    if (const char* old = std::getenv(name)) old_ = old, had_ = true;
    setenv(name, value.c_str(), 1);
  }
  ~ScopedEnv() {
    if (had_) setenv(name_, old_.c_str(), 1);
    else unsetenv(name_);
  }

 private:
  const char* name_;
  std::string old_;
  bool had_ = false;
};

TEST(DicomIsolation, TheWorkerIsLookedForBesideTheProgramThenInTheInstalledLayout) {
  // An installed or unpacked package (packaging/): PREFIX/bin/volume-haptics finds
  // PREFIX/libexec/volume-haptics/volume-haptics-dicom-worker before the build tree's worker.
  const auto candidates = readerProcessCandidates("/opt/vh/usr/bin");
  ASSERT_GE(candidates.size(), 3u);
  EXPECT_EQ(candidates[0], std::filesystem::path("/opt/vh/usr/bin/volume-haptics-dicom-worker"));
  EXPECT_EQ(candidates[1], std::filesystem::path("/opt/vh/usr/libexec/volume-haptics/volume-haptics-dicom-worker"));
  EXPECT_EQ(candidates.back().filename(), "volume-haptics-dicom-worker");
  EXPECT_EQ(candidates.back().parent_path().filename(), "app") << "the build tree's build/app/ comes last";
  // Without the executable's folder only the build tree's worker is left.
  EXPECT_EQ(readerProcessCandidates({}).size(), 1u);
}

TEST(DicomIsolation, TheWorkerIsBuiltAndGivesTheSameVolumeAsTheInProcessRead) {
  VH_REQUIRE_SHARED(phantom, "ct/philips-head-phantom-bone");
  ASSERT_FALSE(readerProcessPath().empty()) << "volume-haptics-dicom-worker not found";
  VolumeLoadOptions worker, in_process;
  worker.dicom_isolation = DicomIsolation::kWorker;
  in_process.dicom_isolation = DicomIsolation::kInProcess;
  // The isolation's price on the 140-slice phantom, measured side by side (reported, not asserted).
  double t_worker = 0.0, t_in = 0.0;
  LoadedVolume a, b;
  for (int round = 0; round < 3; ++round) {
    auto t0 = std::chrono::steady_clock::now();
    a = loadVolume(phantom, worker);
    t_worker += secondsSince(t0);
    t0 = std::chrono::steady_clock::now();
    b = loadVolume(phantom, in_process);
    t_in += secondsSince(t0);
  }
  std::cout << "[isolation] 140-slice phantom (512 x 512 x 140 int16): worker " << t_worker / 3 << " s, in process "
            << t_in / 3 << " s, ratio " << t_worker / t_in << "\n";
  const auto& g = a.field->geometry();
  ASSERT_EQ(g.dims, b.field->geometry().dims);
  EXPECT_EQ(g.origin_W_m, b.field->geometry().origin_W_m);
  EXPECT_EQ(g.spacing_m, b.field->geometry().spacing_m);
  EXPECT_EQ(g.direction_W, b.field->geometry().direction_W);
  EXPECT_EQ(a.info.description, b.info.description);
  EXPECT_EQ(a.info.series_uid, b.info.series_uid);
  for (int k = 0; k < g.dims[2]; k += 13)
    for (int j = 0; j < g.dims[1]; j += 7)
      for (int i = 0; i < g.dims[0]; i += 7) ASSERT_EQ(a.field->voxel(i, j, k), b.field->voxel(i, j, k));
  // Both paths keep one copy of the voxels (HU in int16): the picture's scalars are the field's.
  EXPECT_TRUE(a.field->bytes() == b.field->bytes());
  EXPECT_EQ(a.image->GetScalarPointer(), static_cast<const void*>(a.field->bytes().data()));
  EXPECT_EQ(b.image->GetScalarPointer(), static_cast<const void*>(b.field->bytes().data()));
}

TEST(DicomIsolation, AWorkerCrashNamesTheFileAndLoadsNothing) {
  VH_REQUIRE_SHARED(head, kCtHead);
  // A stand-in worker that crashes as vtk-dicom did: the load ends in SIGSEGV; the probe
  // names a file, then crashes on it.
  TempDir tmp("crash_worker");
  const fs::path script = tmp / "worker.sh";
  writeFile(script,
            "#!/bin/sh\n"
            "if [ \"$1\" = probe ]; then echo \"file $2/CTHead7.dcm\"; echo ok; echo \"file $2/CTHead8.dcm\"; fi\n"
            "kill -SEGV $$\n");
  fs::permissions(script, fs::perms::owner_all);
  ScopedEnv env("VH_DICOM_WORKER", script.string());
  const std::string msg = loadErrorOf([&] { loadVolume(head); });
  EXPECT_CONTAINS(msg, "the DICOM reader crashed (SIGSEGV) on " + (head / "CTHead8.dcm").string());
  EXPECT_CONTAINS(msg, "nothing was loaded");
  EXPECT_CONTAINS(msg, "To open the series without it, move CTHead8.dcm out of the folder");
}

TEST(DicomIsolation, ASeriesReadThatCrashesOnlyBesideOtherSlicesNamesTheDamagedSlice) {
  VH_REQUIRE_SHARED(head, kCtHead);
  // A stand-in worker that crashes as the held-back damaged series does: each file parses alone
  // (the probe stops on none), but reading the series crashes whenever CTHead8.dcm is read
  // with any other slice. The series read is repeated on halves of the files (folders of links
  // to them) until the damaged slice is found.
  TempDir tmp("crash_series");
  const fs::path script = tmp / "worker.sh";
  writeFile(script,
            "#!/bin/sh\n"
            "if [ \"$1\" = load ]; then\n"
            "  n=$(ls \"$2\" | wc -l)\n"
            "  if ls \"$2\" | grep -q 'CTHead8.dcm$' && [ \"$n\" -ge 2 ]; then kill -SEGV $$; fi\n"
            "  echo 'error the stand-in reads no pixels'; exit 1\n"
            "fi\n"
            "exit 0\n");
  fs::permissions(script, fs::perms::owner_all);
  ScopedEnv env("VH_DICOM_WORKER", script.string());
  const std::string msg = loadErrorOf([&] { loadVolume(head); });
  EXPECT_CONTAINS(msg, "the DICOM reader crashed (SIGSEGV) on " + (head / "CTHead8.dcm").string());
  EXPECT_CONTAINS(msg, "To open the series without it, move CTHead8.dcm out of the folder");
  // The folders of links are gone.
  std::error_code ec;
  const std::string prefix = "vh-dicom-bisect-" + std::to_string(getpid()) + "-";
  for (const auto& e : fs::directory_iterator(fs::temp_directory_path(), ec))
    EXPECT_NE(e.path().filename().string().rfind(prefix, 0), 0u) << e.path() << " was left behind";
}

TEST(DicomIsolation, ListingSeriesRunsInTheWorkerToo) {
  VH_REQUIRE_SHARED(phantom, "ct/philips-head-phantom-bone");
  ASSERT_FALSE(readerProcessPath().empty());
  int last_done = -1, last_total = -1;
  const auto listed = listDicomSeries(phantom, [&](int done, int total) {
    last_done = done;
    last_total = total;
  });
  ASSERT_EQ(listed.size(), 1u);
  EXPECT_EQ(last_done, last_total);
  EXPECT_EQ(listed[0].slice_count, 140);
  EXPECT_EQ(listed[0].files.size(), 140u);
  EXPECT_FALSE(listed[0].series_uid.empty());
  // The stand-in worker that crashes: the listing names the file.
  TempDir tmp("crash_list");
  const fs::path script = tmp / "worker.sh";
  writeFile(script, "#!/bin/sh\nif [ \"$1\" = probe ]; then echo \"file $2/I10\"; fi\nkill -SEGV $$\n");
  fs::permissions(script, fs::perms::owner_all);
  ScopedEnv env("VH_DICOM_WORKER", script.string());
  const std::string msg = loadErrorOf([&] { listDicomSeries(phantom); });
  EXPECT_CONTAINS(msg, "the DICOM reader crashed (SIGSEGV) on " + (phantom / "I10").string());
  EXPECT_CONTAINS(msg, "To open the series without it, move I10 out of the folder");
}

TEST(DicomIsolation, MeshesThatCrashVtkReadersAreRefusedNotFatal) {
  // Inputs the fuzzing campaign found to crash VTK 9.1's OBJ and PLY readers in process
  // (tests/fuzz/known-crashes/mesh); through the reader process each is a LoadError.
  ASSERT_FALSE(readerProcessPath().empty());
  const fs::path known = fs::path(VH_SOURCE_DIR) / "tests" / "fuzz" / "known-crashes" / "mesh";
  if (!fs::exists(known)) GTEST_SKIP() << "no known crashes in " << known;
  TempDir tmp("crash_meshes");
  int tried = 0;
  for (const auto& e : fs::directory_iterator(known)) {
    const std::string name = e.path().filename().string();
    if (name.find("oom") != std::string::npos) continue;  // allocation bombs: bounded elsewhere
    const std::string ext = name.substr(0, 3);
    const fs::path copy = tmp / (name + "." + ext);
    fs::copy_file(e.path(), copy);
    const std::string msg = loadErrorOf([&] { loadMesh(copy, 0.001); });
    EXPECT_CONTAINS(msg, copy.string());
    ++tried;
  }
  EXPECT_GE(tried, 4);
}

TEST(DicomIsolation, VolumeFilesThatCrashVtkReadersAreRefusedNotFatal) {
  // NRRD and MetaImage inputs that crash VTK 9.1's readers in process (known-crashes; the
  // hang and the allocation bomb left out): read in the reader process, each is a LoadError.
  ASSERT_FALSE(readerProcessPath().empty());
  const fs::path known = fs::path(VH_SOURCE_DIR) / "tests" / "fuzz" / "known-crashes";
  if (!fs::exists(known / "nrrd")) GTEST_SKIP() << "no known crashes in " << known;
  TempDir tmp("crash_volumes");
  int tried = 0;
  for (const char* kind : {"nrrd", "metaimage"}) {
    for (const auto& e : fs::directory_iterator(known / kind)) {
      const std::string name = e.path().filename().string();
      if (name.find("hang") != std::string::npos || name.find("too-big") != std::string::npos ||
          name.find("oom") != std::string::npos || name.find("leak") != std::string::npos)
        continue;
      const fs::path copy = tmp / (name + (std::string(kind) == "nrrd" ? ".nrrd" : ".mha"));
      fs::copy_file(e.path(), copy, fs::copy_options::overwrite_existing);
      const std::string msg = loadErrorOf([&] { loadVolume(copy); });
      EXPECT_CONTAINS(msg, copy.string());
      ++tried;
    }
  }
  EXPECT_GE(tried, 3);
}

TEST(DicomIsolation, AReaderStuckOnADamagedFileIsStoppedByTheWatchdog) {
  // vtkmetaio's MET_Read loops forever on this header (found by fuzz_metaimage). Read in the
  // worker with a 1 s watchdog (plus 1 s per 8 MiB: nothing for a file this small), the load
  // fails with a LoadError naming the file instead of waiting for ever.
  ASSERT_FALSE(readerProcessPath().empty());
  const fs::path hang = fs::path(VH_SOURCE_DIR) / "tests/fuzz/known-crashes/metaimage/hang-vtkmetaio-MET_Read.mha";
  if (!fs::exists(hang)) GTEST_SKIP() << "no " << hang;
  TempDir tmp("stuck_reader");
  const fs::path copy = tmp / "stuck.mha";
  fs::copy_file(hang, copy);
  VolumeLoadOptions options;
  options.worker_stall_timeout_s = 1.0;
  const auto start = std::chrono::steady_clock::now();
  const std::string msg = loadErrorOf([&] { loadVolume(copy, options); });
  const double took_s = secondsSince(start);
  std::cout << "[isolation] stuck reader stopped after " << took_s << " s: " << msg << "\n";
  EXPECT_CONTAINS(msg, copy.string());
  EXPECT_CONTAINS(msg, "stopped responding");
  EXPECT_GE(took_s, 1.0);
  EXPECT_LT(took_s, 10.0);
}

TEST(DicomIsolation, TheWatchdogLeavesAnOrdinaryReadAlone) {
  // A 5 s watchdog (a twelfth of the default) on the 140-slice phantom (progress every slice)
  // and a NRRD volume (no progress while reading one file): both load as without it. Not 1 s:
  // the watchdog also counts the reader program's start before its first line, which a loaded
  // machine can stretch towards a second.
  VH_REQUIRE_SHARED(phantom, "ct/philips-head-phantom-bone");
  VH_REQUIRE_SHARED(mr_brain, "nrrd/mr-brain/brain1_image.nrrd");
  VolumeLoadOptions options;
  options.dicom_isolation = DicomIsolation::kWorker;
  options.worker_stall_timeout_s = 5.0;
  EXPECT_EQ(loadVolume(phantom, options).field->geometry().dims[2], 140);
  EXPECT_GT(loadVolume(mr_brain, options).field->geometry().voxelCount(), 0u);
}

TEST(DicomIsolation, CancellingKillsTheWorkerAtOnce) {
  VH_REQUIRE_SHARED(phantom, "ct/philips-head-phantom-bone");
  std::atomic<bool> cancel{false};
  VolumeLoadOptions options;
  options.dicom_isolation = DicomIsolation::kWorker;
  options.cancel = &cancel;
  std::chrono::steady_clock::time_point asked;
  options.progress = [&](double f) {
    if (f > 0.05 && !cancel) {
      asked = std::chrono::steady_clock::now();
      cancel = true;
    }
  };
  EXPECT_THROW(loadVolume(phantom, options), LoadCancelled);
  const double latency_s = secondsSince(asked);
  std::cout << "[isolation] cancel latency " << latency_s * 1e3 << " ms\n";
  EXPECT_LT(latency_s, 5.0);  // the poll period is 50 ms; generous for a loaded machine
}

/// Damages 1 to 3 slices of a copy of the small CT head (bytes changed, cut, inserted or the
/// file truncated), as the experiment that found the parser's crashes did.
void damageCopy(const fs::path& from, const fs::path& to, std::mt19937& rng) {
  fs::create_directories(to);
  std::vector<fs::path> files;
  for (const auto& e : fs::directory_iterator(from)) files.push_back(e.path());
  std::sort(files.begin(), files.end());
  for (const auto& f : files) fs::copy_file(f, to / f.filename());
  const int n_damaged = std::uniform_int_distribution<int>(1, 3)(rng);
  for (int d = 0; d < n_damaged; ++d) {
    const fs::path victim = to / files[std::uniform_int_distribution<std::size_t>(0, files.size() - 1)(rng)].filename();
    std::string bytes = readFile(victim);
    if (bytes.empty()) continue;
    std::uniform_int_distribution<std::size_t> pos(0, bytes.size() - 1);
    switch (std::uniform_int_distribution<int>(0, 3)(rng)) {
      case 0:  // bytes changed, in the header most often
        for (int k = 0; k < 16; ++k) bytes[std::min(pos(rng), k % 2 ? std::size_t{1200} : bytes.size() - 1)] = static_cast<char>(rng());
        break;
      case 1:  // a run cut out
        bytes.erase(pos(rng), std::uniform_int_distribution<std::size_t>(1, 4096)(rng));
        break;
      case 2:  // bytes inserted
        bytes.insert(pos(rng), std::string(std::uniform_int_distribution<std::size_t>(1, 512)(rng), static_cast<char>(rng())));
        break;
      default:  // truncated
        bytes.resize(pos(rng));
    }
    writeFile(victim, bytes);
  }
}

TEST(DicomIsolation, DamagedCopiesOfARealSeriesNeverCrashTheProcess) {
  VH_REQUIRE_SHARED(head, kCtHead);
  ASSERT_FALSE(readerProcessPath().empty());
  // CI: 20 copies; the experiment: VH_DAMAGED_COPIES=300.
  const char* env = std::getenv("VH_DAMAGED_COPIES");
  const int copies = env != nullptr ? std::atoi(env) : 20;
  std::mt19937 rng(15);
  int loaded = 0, refused = 0, crashed = 0;
  for (int c = 0; c < copies; ++c) {
    TempDir tmp("damaged_" + std::to_string(c));
    damageCopy(head, tmp / "series", rng);
    try {
      loadVolume(tmp / "series");
      ++loaded;
    } catch (const LoadError& e) {
      ++refused;
      const std::string what = e.what();
      if (what.find("crashed") != std::string::npos) ++crashed;
      EXPECT_NE(what.find((tmp / "series").string()), std::string::npos) << what;
    }
  }
  std::cout << "[damaged copies] " << copies << " copies: " << loaded << " loaded, " << refused << " refused ("
            << crashed << " of them a reader process crash, named); the test process never crashed\n";
  EXPECT_EQ(loaded + refused, copies);
}

}  // namespace
}  // namespace vh::io::test
