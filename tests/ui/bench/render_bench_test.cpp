// vh::ui_bench: `bench render` in its short version (the small CT head, two small windows, 0.3 s
// a row) writes a well-formed report. No timing thresholds: only structure, finiteness, counts
// and the consistency of the figures with one another are checked. How many frames a row holds
// depends on the machine's speed and load (at least 3), so no check depends on that number.
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <numeric>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "report_json.h"
#include "vh/ui/bench/render_bench.h"

namespace vh::ui {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

using test::number;

void expectStats(const json& s, const std::string& where) {
  SCOPED_TRACE(where);
  EXPECT_GT(number(s, "n"), 0.0);
  const double p50 = number(s, "p50"), p99 = number(s, "p99"), p999 = number(s, "p99_9"), max = number(s, "max");
  EXPECT_GT(p50, 0.0);
  EXPECT_LE(p50, p99);
  EXPECT_LE(p99, p999);
  EXPECT_LE(p999, max);
  EXPECT_TRUE(std::isfinite(max));
}

TEST(RenderBench, ShortRunWritesRowsAndServoFiguresOnAndOff) {
  const fs::path head = fs::path(VH_SHARED_DATASETS_DIR) / "ct" / "ct-head-small";
  if (!fs::exists(head)) GTEST_SKIP() << head << " is absent";
  RenderBenchOptions o;
  o.common.short_run = true;
  o.common.out_dir = fs::path(VH_UI_BENCH_TEST_OUTPUT_DIR) / "render";
  o.sizes = {{320, 240}, {480, 270}};
  o.row_seconds = 0.3;
  fs::remove_all(o.common.out_dir);
  const fs::path out = runRenderBench(o);
  ASSERT_EQ(out, o.common.out_dir);

  std::ifstream in(out / "render.json");
  ASSERT_TRUE(in.good());
  const json report = json::parse(in);
  EXPECT_EQ(report["benchmark"], "render");
  EXPECT_TRUE(fs::exists(out / "render.md"));
  EXPECT_FALSE(fs::exists(out / "render-ticks.vhrec")) << "the tick recording is a temporary file";
  ASSERT_TRUE(report["renderer"].is_string());
  const std::string renderer = report["renderer"];
  EXPECT_FALSE(renderer.empty());
  EXPECT_NE(renderer, "unknown");
  EXPECT_GE(number(report, "max_3d_texture"), 256.0);
  EXPECT_EQ(report["volume"]["dims"], json({64, 64, 93}));

  const double row_s = number(report, "row_seconds");
  EXPECT_DOUBLE_EQ(row_s, o.row_seconds);

  // 2 sizes x (isosurface, composite, MIP, drilling as the window draws them; isosurface and
  // drilling again with the moving frames ray cast), each at the size asked for.
  const json& rows = report["rows"];
  ASSERT_TRUE(rows.is_array());
  ASSERT_EQ(rows.size(), 12u);
  const char* modes[] = {"isosurface", "composite", "mip", "drilling", "isosurface", "drilling"};
  for (std::size_t i = 0; i < rows.size(); ++i) {
    const json& r = rows[i];
    SCOPED_TRACE(r.dump());
    EXPECT_EQ(r["mode"], modes[i % 6]);
    const bool ray_cast_row = i % 6 >= 4;
    EXPECT_EQ(r["moving_view"], ray_cast_row ? "ray cast" : "auto");
    EXPECT_EQ(number(r, "width"), i < 6 ? 320.0 : 480.0);
    EXPECT_EQ(number(r, "height"), i < 6 ? 240.0 : 270.0);
    // The surface mesh only ever replaces the isosurface's moving frames, never the composite or
    // the MIP, nor a row told to ray cast; whether the automatic choice takes it depends on the
    // renderer's speed (printed, not checked), and a mesh drawn has triangles.
    const double mesh_frames = number(r, "surface_mesh_frames");
    if (ray_cast_row || r["mode"] == "composite" || r["mode"] == "mip") EXPECT_EQ(mesh_frames, 0.0);
    EXPECT_LE(mesh_frames, number(r, "frames"));
    if (mesh_frames > 0.0) EXPECT_GT(number(r, "surface_mesh_triangles"), 0.0);
    std::cout << "row " << i << ": " << mesh_frames << " frames drew the surface mesh (measured, not checked)\n";
    EXPECT_EQ(r["renderer"], renderer);
    const double frames = number(r, "frames");
    ASSERT_GE(frames, 3.0) << "a row draws frames until its time is up, and at least 3";
    const double fps = number(r, "fps_mean"), mean = number(r, "frame_ms_mean"), p99 = number(r, "frame_ms_p99"),
                 max = number(r, "frame_ms_max");
    EXPECT_GT(fps, 0.0);
    EXPECT_GT(mean, 0.0);
    EXPECT_LE(mean, max);
    EXPECT_LE(p99, max);
    // The frames fill the row: the row lasted (frames / fps) at least its time, each frame was timed
    // inside it, and the mean and the largest frame time are those of the frames listed.
    ASSERT_TRUE(r["frames_ms"].is_array());
    const std::vector<double> frames_ms = r["frames_ms"].get<std::vector<double>>();
    ASSERT_EQ(static_cast<double>(frames_ms.size()), frames);
    const double sum_ms = std::accumulate(frames_ms.begin(), frames_ms.end(), 0.0);
    const double row_ms = 1000.0 * frames / fps;
    EXPECT_GE(row_ms, 1000.0 * row_s - 1e-6) << "the row ended before its time";
    EXPECT_LE(sum_ms, row_ms * (1.0 + 1e-9) + 1e-6) << "the frames' times add up to more than the row's";
    EXPECT_NEAR(mean, sum_ms / frames, 1e-9 * sum_ms + 1e-12);
    EXPECT_DOUBLE_EQ(max, *std::max_element(frames_ms.begin(), frames_ms.end()));
    std::cout << "row " << i << ": " << frames << " frames, " << fps << " fps (measured, not checked)\n";
    EXPECT_GT(number(r, "still_frame_ms"), 0.0);
    // A still frame casts a ray per pixel; only after still frames slower than SceneActors'
    // kStillSlowMs (3 s: a slow or busy machine) do the next ones step down, to 1.5 px at most.
    const double still_px = number(r, "still_image_sample_px");
    EXPECT_GE(still_px, 1.0);
    EXPECT_LE(still_px, 1.5);
    EXPECT_GE(number(r, "interactive_image_sample_px"), 1.0);
    EXPECT_GE(number(r, "interactive_sample_voxels"), 0.99);
    // Each frame of the row was painted. How many paints come on top (the row's picture, its
    // still frame, an expose after the resize, still frames when a busy machine stalls a frame
    // past the still delay) depends on the machine's load: printed, not checked.
    const double paints = std::round(number(r, "paints_per_frame") * frames);
    EXPECT_GE(paints, frames) << "a frame was not painted";
    std::cout << "row " << i << ": " << paints << " paints for " << frames << " frames (measured, not checked)\n";
    // Each frame's render and swap, timed inside it: no frame's parts outlast the frame.
    ASSERT_EQ(r["frames_paint_ms"].size(), r["frames_ms"].size());
    ASSERT_EQ(r["frames_swap_ms"].size(), r["frames_ms"].size());
    for (std::size_t k = 0; k < r["frames_ms"].size(); ++k) {
      const double paint = r["frames_paint_ms"][k].get<double>(), swap = r["frames_swap_ms"][k].get<double>();
      EXPECT_GT(paint, 0.0) << "frame " << k;
      EXPECT_GT(swap, 0.0) << "frame " << k;
      EXPECT_LE(paint + swap, r["frames_ms"][k].get<double>() + 1e-6) << "frame " << k;
    }
    if (r["mode"] == "drilling") {
      EXPECT_TRUE(r.contains("removed_voxels"));
      EXPECT_TRUE(r.contains("partial_uploads"));
      EXPECT_TRUE(r.contains("full_uploads"));
    }
  }

  // The soft tissue rows: the gel pressed by its ball, one row per size; the view took the
  // deformed windows the haptic thread published and showed them (how many depends on the
  // machine's speed: printed; that there were some while the ball pressed is checked).
  const json& tissue = report["tissue_rows"];
  ASSERT_TRUE(tissue.is_array());
  ASSERT_EQ(tissue.size(), o.sizes.size());
  double windows = 0.0, deepest_mm = 0.0;
  for (std::size_t i = 0; i < tissue.size(); ++i) {
    const json& r = tissue[i];
    SCOPED_TRACE(r.dump().substr(0, 400));
    EXPECT_EQ(r["mode"], "tissue");
    EXPECT_EQ(number(r, "width"), o.sizes[i][0]);
    EXPECT_EQ(number(r, "height"), o.sizes[i][1]);
    EXPECT_GE(number(r, "frames"), 3.0);
    const double shown = number(r, "deformed_windows_shown");
    EXPECT_NEAR(number(r, "deformed_windows_per_s") * number(r, "frames") / number(r, "fps_mean"), shown, 1e-6 * shown + 1e-9);
    EXPECT_LE(number(r, "tissue_show_ms_max"), number(r, "frame_ms_max")) << "showing a window is part of its frame";
    windows += shown;
    deepest_mm = std::max(deepest_mm, number(r, "indentation_mm_max"));
    std::cout << "tissue row " << i << ": " << shown << " deformed windows shown (measured, not checked)\n";
  }
  EXPECT_GT(windows, 0.0) << "the view never showed the tissue deformed";
  EXPECT_GT(deepest_mm, 0.1) << "the ball pressed 3 mm past the gel's surface: the shown tissue gave";
  EXPECT_LT(deepest_mm, 6.0) << "deeper than the press";

  // The servo figures, rendering on and off, from the same run.
  const json& servo = report["servo"];
  expectStats(servo["solver_tick_us"]["rendering_on"], "solver, rendering on");
  expectStats(servo["solver_tick_us"]["rendering_off"], "solver, rendering off");
  for (const char* k : {"rendering_on", "rendering_off"}) {
    EXPECT_GT(number(servo["coupling_max_tick_us"], k), 0.0) << k;
    EXPECT_TRUE(servo["deadline_misses"][k].is_number_unsigned()) << k;
  }
}

}  // namespace
}  // namespace vh::ui
