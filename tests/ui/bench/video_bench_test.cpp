// vh::ui_bench: `bench video` in its short version (a recording made on the small CT head)
// writes a well-formed report whose frame times add up. The times are measurements: only their
// structure and consistency are checked here; the figures are in docs/benchmarks.md.
#include <filesystem>
#include <fstream>
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "report_json.h"
#include "vh/ui/bench/video_bench.h"

namespace vh::ui {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using test::number;

TEST(VideoBench, ShortRunTimesEachStageOfTheFrames) {
  const fs::path head = fs::path(VH_SHARED_DATASETS_DIR) / "ct" / "ct-head-small";
  if (!fs::exists(head)) GTEST_SKIP() << head << " is absent";
  VideoBenchOptions o;
  o.common.short_run = true;
  o.common.out_dir = fs::path(VH_UI_BENCH_TEST_OUTPUT_DIR) / "video";
  o.width = 160;
  o.height = 120;
  o.frames = 6;
  fs::remove_all(o.common.out_dir);
  const fs::path out = runVideoBench(o);
  ASSERT_EQ(out, o.common.out_dir);
  std::ifstream in(out / "video.json");
  ASSERT_TRUE(in.good());
  const json report = json::parse(in);
  EXPECT_EQ(report["benchmark"], "video");
  EXPECT_TRUE(fs::exists(out / "video.md"));
  EXPECT_GT(fs::file_size(out / "video-bench.ogv"), 0u) << "the video was written";
  EXPECT_TRUE(fs::exists(out / "video-bench.vhrec")) << "the recording made for it";
  EXPECT_EQ(number(report, "frames"), 6.0);
  EXPECT_EQ(number(report, "width"), 160.0);
  const json& f = report["frame_ms"];
  for (const char* stage : {"show", "render", "readback", "encode", "total"}) {
    SCOPED_TRACE(stage);
    ASSERT_TRUE(f.contains(stage));
    EXPECT_GE(number(f[stage], "mean"), 0.0);
    EXPECT_LE(number(f[stage], "p50"), number(f[stage], "max"));
  }
  // A frame is its stages: the means add up.
  const double sum = number(f["show"], "mean") + number(f["render"], "mean") + number(f["readback"], "mean") +
                     number(f["encode"], "mean");
  EXPECT_NEAR(number(f["total"], "mean"), sum, 1e-6 * sum + 1e-9);
  EXPECT_NEAR(number(report, "frames_per_s"), 1000.0 / number(f["total"], "mean"), 1e-6);
}

}  // namespace
}  // namespace vh::ui
