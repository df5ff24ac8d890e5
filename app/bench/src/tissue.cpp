// `volume-haptics bench tissue`: the whole servo tick with soft tissue against the rigid tick on
// the same scene, as the application builds both (runtime::makeServoRenderer() with the scene's
// "tissue" section, runtime::makeRenderer() without it), one device trajectory rendered by both,
// tick by tick interleaved (figures move 30-60 % between runs on a shared machine: the ratio is
// what compares). Per scene: mean / p99.9 / max of the whole tick [us], ticks over 500 us and over
// the 1 ms period, ticks the deadline cut, the peak force, crossings of the felt field by a dense
// check of every tick's motion (outside the timed part), the tissue's step and its parts, the
// ticks the springing-back surface carried the proxy, the build (region, factorisation,
// compliance table). Scenes:
//   - the built-in gel with a stiffer inclusion (the gel-palpation scene's tissue and tool), the
//     ball pressed 2 mm in beside the inclusion, slid over it and lifted;
//   - the shared small CT head (ct/ct-head-small) with its soft tissue as the tissue on 6 mm
//     cells (one touchable layer: the compliance table must fit the 1 GiB limit), the ball
//     pressed 3 mm into the deepest soft tissue a horizontal line finds (the tissue over the
//     scalp's bone is thinner than a cell, held by it), slid 10 mm up and taken out;
//   - the step's time per lattice size on the gel (3, 2 and 1.5 mm cells).
// --short (the ctest entry): fewer ticks, and no deadline on the clock, so that what the test
// checks does not depend on the machine's load.
#include <array>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <iostream>
#include <optional>
#include <sstream>

#include <nlohmann/json.hpp>

#include "vh/bench/bench.h"
#include "vh/bench/report.h"
#include "vh/datasets/synthetic.h"
#include "vh/haptics/crossing_verifier.h"
#include "vh/runtime/drilling.h"
#include "vh/runtime/scene.h"
#include "vh/runtime/servo_factory.h"
#include "vh/runtime/tissue_scene.h"
#include "vh/tissue/deformable_scene.h"

namespace vh::bench {
namespace fs = std::filesystem;

namespace {

using Clock = std::chrono::steady_clock;
double since_us(Clock::time_point a) { return std::chrono::duration<double, std::micro>(Clock::now() - a).count(); }

constexpr const char* kHead = "ct/ct-head-small";


/// Where and how a scene is pressed: from `start_W_m` (the ball's centre, free) along the unit
/// `press_W` to `depth_m` past where the ball first meets the surface, then slid by `slide_W_m`.
struct Press {
  Eigen::Vector3d start_W_m = Eigen::Vector3d::Zero();
  Eigen::Vector3d press_W = -Eigen::Vector3d::UnitZ();
  double depth_m = 0.002;
  Eigen::Vector3d slide_W_m = Eigen::Vector3d::Zero();
};

/// The press's path, one pose per 1 ms tick (a quarter of the ticks in a short run): to
/// `contact_m + depth_m` along press_W in 1.5 s, held 0.5 s, slid in 2 s, held 0.5 s, back out
/// along -press_W to 3 mm beyond the start's depth in 1 s.
std::vector<haptics::Pose> pressSlideLift(const Press& press, double contact_m, bool short_run) {
  std::vector<haptics::Pose> path;
  const double scale = short_run ? 0.25 : 1.0;
  const auto segment = [&](const Eigen::Vector3d& a, const Eigen::Vector3d& b, int ticks) {
    for (int t = 1; t <= ticks; ++t) path.push_back(haptics::Pose::FromTranslation(a + (b - a) * (static_cast<double>(t) / ticks)));
  };
  const Eigen::Vector3d a = press.start_W_m;
  const Eigen::Vector3d in = a + (contact_m + press.depth_m) * press.press_W;
  const Eigen::Vector3d across = in + press.slide_W_m;
  segment(a, in, static_cast<int>(1500 * scale));
  segment(in, in, static_cast<int>(500 * scale));
  segment(in, across, static_cast<int>(2000 * scale));
  segment(across, across, static_cast<int>(500 * scale));
  segment(across, a + press.slide_W_m - 0.003 * press.press_W, static_cast<int>(1000 * scale));
  return path;
}

/// The CT head's press: of the horizontal lines (along +-x and +-y of W, every 3 mm over the
/// middle half of the scan's height), the one whose soft tissue (from the surface at `isovalue`
/// to the first value above `rigid_above`) is deepest; the ball starts 5 mm outside the surface
/// there and slides 10 mm up.
Press deepestTissueSite(const haptics::ScalarVolume& field, double isovalue, double rigid_above, double radius_m) {
  const haptics::VolumeGeometry& g = field.geometry();
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(1e300), hi = -lo;
  for (int c = 0; c < 8; ++c) {
    const Eigen::Vector3d corner((c & 1) ? g.dims[0] - 1 : 0, (c & 2) ? g.dims[1] - 1 : 0, (c & 4) ? g.dims[2] - 1 : 0);
    const Eigen::Vector3d p = g.pointOf_W(corner);
    lo = lo.cwiseMin(p), hi = hi.cwiseMax(p);
  }
  Press best;
  double best_depth = -1.0;
  constexpr double kStep = 0.5e-3;
  const std::array<Eigen::Vector3d, 4> directions{Eigen::Vector3d(1, 0, 0), Eigen::Vector3d(-1, 0, 0),
                                                 Eigen::Vector3d(0, 1, 0), Eigen::Vector3d(0, -1, 0)};
  for (const Eigen::Vector3d& d : directions) {
    const int axis = d.x() != 0.0 ? 0 : 1, across = 1 - axis;
    for (double z = lo.z() + 0.25 * (hi.z() - lo.z()); z <= lo.z() + 0.75 * (hi.z() - lo.z()); z += 3e-3)
      for (double w = lo[across]; w <= hi[across]; w += 3e-3) {
        Eigen::Vector3d p;
        p[axis] = d[axis] > 0 ? lo[axis] : hi[axis];
        p[across] = w;
        p.z() = z;
        double t = 0.0, entry = -1.0, depth = 0.0;
        const double length = hi[axis] - lo[axis];
        for (; t < length; t += kStep) {
          const Eigen::Vector3d q = p + t * d;
          const double F = field.sample(q);
          if (entry < 0.0 && F >= isovalue) entry = t;
          if (entry >= 0.0 && F > rigid_above) break;
        }
        if (entry < 0.0) continue;
        depth = t - entry;
        if (depth > best_depth) {
          best_depth = depth;
          best.press_W = d;
          best.start_W_m = p + (entry - radius_m - 0.005) * d;
          best.slide_W_m = Eigen::Vector3d(0, 0, 0.010);
          best.depth_m = 0.003;
        }
      }
  }
  return best;
}

/// The gel's press: the ball from 3.5 mm above the top, 6 mm left of the inclusion, 2 mm in, slid
/// 11 mm right over the inclusion.
Press gelPress() {
  Press p;
  p.start_W_m = Eigen::Vector3d(-0.006, 0.0, datasets::kGelTop_m + 0.0035);
  p.press_W = -Eigen::Vector3d::UnitZ();
  p.depth_m = 0.002;
  p.slide_W_m = Eigen::Vector3d(0.011, 0.0, 0.0);
  return p;
}

/// Mean, p99.9, max and the ticks over 500 us and over the 1 ms period of `values` [us].
nlohmann::ordered_json statsJson(const std::vector<double>& values) {
  const Stats s = summarize(values);
  int over_500 = 0, over_period = 0;
  for (const double v : values) over_500 += v > 500.0, over_period += v > 1000.0;
  return {{"mean_us", s.mean}, {"p99_9_us", s.p999}, {"max_us", s.max}, {"over_500us", over_500},
          {"over_1ms", over_period}};
}

/// One scene rendered with its tissue and rigid, interleaved; `press` null: the head's deepest
/// tissue (deepestTissueSite()).
nlohmann::ordered_json runScene(const std::string& name, runtime::SceneSpec spec, std::optional<Press> press,
                                bool short_run) {
  nlohmann::ordered_json row;
  row["scene"] = name;
  const runtime::LoadedScene scene = runtime::loadScene(spec);
  runtime::LiveValues live = runtime::LiveValues::initial(scene);
  // As the application runs it: one lane, the deadline, the edge test. The short run (the ctest
  // entry's) has no deadline on the clock: on a loaded machine a burst of cut ticks leaves the
  // proxy behind the device and the felt peak depends on the load (forced bursts of 5-44 cut
  // ticks gave the gel 1.88 to 4.55 N), so its figures would too.
  haptics::RendererOptions ro;
  ro.deadline_us = short_run ? 0.0 : runtime::solverDeadline_us(1000.0);
  ro.solver_lanes = 1;
  const haptics::ToolModel& tool = *scene.tool;
  double radius_m = 0.0;  // the ball's
  for (const Eigen::Vector3d& p : tool.point_shell.points_T_m()) radius_m = std::max(radius_m, p.norm());
  if (!press) {
    press = deepestTissueSite(*scene.volume.field, scene.isovalue, spec.tissue->rigid_above.value_or(1e300), radius_m);
  }
  // Where the ball meets the surface along the press: its leading point first inside.
  const Eigen::Vector3d lead = press->start_W_m + radius_m * press->press_W;
  double contact_m = 0.0;
  while (contact_m < 0.15 && !scene.volume.field->isInside(lead + contact_m * press->press_W, scene.isovalue))
    contact_m += 5e-5;
  const haptics::Pose X_start = haptics::Pose::FromTranslation(press->start_W_m);
  row["start_W_m"] = {press->start_W_m.x(), press->start_W_m.y(), press->start_W_m.z()};
  row["press_W"] = {press->press_W.x(), press->press_W.y(), press->press_W.z()};
  row["contact_from_start_m"] = contact_m;
  row["press_depth_m"] = press->depth_m;
  row["slide_m"] = press->slide_W_m.norm();

  const auto build_start = Clock::now();
  runtime::DrillingRenderer soft;
  try {
    soft = runtime::makeServoRenderer(live, ro, X_start, 1000.0);
  } catch (const std::exception& e) {
    row["refused"] = e.what();
    return row;
  }
  row["build_s"] = since_us(build_start) * 1e-6;
  tissue::DeformableScene& tissue = *soft.tissue;
  row["tissue_voxels"] = tissue.region().tissue_voxels;
  row["lattice_nodes"] = tissue.region().model.lattice().nodeCount();
  row["touchable_nodes"] = tissue.compliance().nodeCount();
  row["table_MB"] = tissue.compliance().bytes() / 1e6;
  row["cell_m"] = live.tissue->cell_size_m;
  row["touchable_layers"] = live.tissue->touchable_layers;
  live.tissue.reset();
  const auto rigid = runtime::makeRenderer(live, ro, X_start);
  const double iso = scene.isovalue;
  const haptics::CrossingVerifier soft_check(*tissue.feltVolume(), tool.point_shell, 1e-2);
  const haptics::CrossingVerifier rigid_check(*scene.volume.field, tool.point_shell, 1e-2);
  const double k = soft.renderer->coupling().gains().linear_N_per_m;
  row["coupling_N_per_m"] = k;
  row["tool_points"] = tool.point_shell.size();

  const std::vector<haptics::Pose> path = pressSlideLift(*press, contact_m, short_run);
  std::vector<double> soft_us, rigid_us, step_us;
  soft_us.reserve(path.size()), rigid_us.reserve(path.size()), step_us.reserve(path.size());
  double gather = 0, solve = 0, displace = 0, resample = 0, write = 0;
  int soft_cut = 0, rigid_cut = 0, soft_cross = 0, rigid_cross = 0, held_back = 0, clipped = 0, window = 0, carried = 0;
  double peak_soft = 0, peak_rigid = 0, deepest = 0, peak_push = 0;
  for (const haptics::Pose& X : path) {
    auto a = Clock::now();
    const tissue::DeformableStep s = tissue.step(X, *soft.renderer);
    const haptics::TickOutput so = soft.renderer->tick(X, iso);
    soft_us.push_back(since_us(a));
    a = Clock::now();
    const haptics::TickOutput ri = rigid->tick(X, iso);
    rigid_us.push_back(since_us(a));
    step_us.push_back(s.step_us);
    gather += s.gather_us, solve += s.solve_us, displace += s.displace_us, resample += s.resample_us,
        write += s.write_us;
    window = std::max(window, s.window_voxels);
    held_back += s.felt_fraction < 1.0, clipped += s.window_clipped, carried += s.proxy_carried_m > 0.0;
    deepest = std::max(deepest, s.indentation_m);
    peak_push = std::max(peak_push, s.contact.force_on_device_N.norm());
    soft_cut += so.stats.deadline_cut, rigid_cut += ri.stats.deadline_cut;
    peak_soft = std::max(peak_soft, so.force_W_N.norm());
    peak_rigid = std::max(peak_rigid, ri.force_W_N.norm());
    soft_cross += soft_check.check(soft.renderer->lastMotion(), soft.renderer->lastTimeOfContact(), iso).crossing_points;
    rigid_cross += rigid_check.check(rigid->lastMotion(), rigid->lastTimeOfContact(), iso).crossing_points;
  }
  const double n = static_cast<double>(path.size());
  row["ticks"] = path.size();
  row["tissue_tick"] = statsJson(soft_us);
  row["tissue_step"] = statsJson(step_us);
  row["rigid_tick"] = statsJson(rigid_us);
  row["step_parts_mean_us"] = {{"gather", gather / n}, {"solve", solve / n}, {"displace", displace / n},
                               {"resample", resample / n}, {"write", write / n}};
  row["largest_window_voxels"] = window;
  row["ticks_held_back"] = held_back;
  row["ticks_proxy_carried"] = carried;
  row["windows_clipped"] = clipped;
  row["tissue_cut"] = soft_cut;
  row["rigid_cut"] = rigid_cut;
  row["tissue_peak_force_N"] = peak_soft;
  row["rigid_peak_force_N"] = peak_rigid;
  row["tissue_peak_push_N"] = peak_push;
  row["deepest_indentation_m"] = deepest;
  row["tissue_crossings"] = soft_cross;
  row["rigid_crossings"] = rigid_cross;
  return row;
}

std::string tickLine(const std::string& what, const nlohmann::ordered_json& t, const std::string& cut, double peak_N,
                     const std::string& crossings) {
  return format("| %s | %.0f | %.0f | %.0f | %d | %d | %s | %.3f | %s |\n", what.c_str(), t["mean_us"].get<double>(),
                t["p99_9_us"].get<double>(), t["max_us"].get<double>(), t["over_500us"].get<int>(),
                t["over_1ms"].get<int>(), cut.c_str(), peak_N, crossings.c_str());
}

}  // namespace

runtime::SceneSpec gelPalpationScene(double cell_m) {
  runtime::SceneSpec spec = runtime::parseScene(R"({
      "volume": {"path": "builtin:gel-with-inclusion", "isovalue": 50},
      "tool": {"mesh": "builtin:sphere", "point_spacing_m": 0.0005,
               "initial_pose": {"p_m": [-0.006, 0, 0.0195], "q_wxyz": [1, 0, 0, 0]}},
      "tissue": {"bands": [{"min": 10, "max": 150, "material": "gel"},
                           {"min": 150, "max": 300, "material": "gel inclusion"}],
                 "rigid_above": 300, "cell_size_m": 0.002}})",
                                                "bench-tissue-gel.json", {});
  spec.tissue->cell_size_m = cell_m;
  return spec;
}

fs::path runTissue(const CommonOptions& options) {
  const bool short_run = options.short_run;
  const fs::path out = outputDir(options, "tissue");
  nlohmann::ordered_json report = reportHeader("tissue", short_run);
  std::ostringstream md;
  md << "# Soft tissue: the whole tick with tissue against the rigid tick\n\n"
     << "One trajectory per scene rendered twice, tick by tick interleaved: with the scene's tissue "
        "(DeformableScene::step, then the renderer's tick on the deformed field) and rigid (the "
        "renderer's tick on the scan). Times are wall time per tick; crossings: a dense check of every "
        "tick's motion (1/100 voxel). No lag column: the budgeted solver has no unbudgeted "
        "reference on a field that moves with the proxy.\n";
  report["scenes"] = nlohmann::ordered_json::array();

  std::vector<std::pair<std::string, runtime::SceneSpec>> scenes;
  scenes.emplace_back("gel with an inclusion (2 mm cells)", gelPalpationScene(0.002));
  const fs::path head = runtime::sharedDatasetsDir() / kHead;
  if (fs::exists(head)) {
    runtime::SceneSpec spec = runtime::sceneForVolume(head);
    spec.volume.isovalue = 900.0;  // the classic headsq: soft tissue about 900-1180, bone above 1300
    spec.volume.isovalue_set = true;
    spec.tool.mesh = "builtin:sphere";
    spec.tool.point_spacing_m = 0.001;
    runtime::TissueSpec t;
    t.bands = {{850.0, 1300.0, "brain grey matter"}};  // the scalp and what lies under it up to bone
    t.rigid_above = 1300.0;
    t.cell_size_m = 0.006;
    t.touchable_layers = 1;
    spec.tissue = t;
    scenes.emplace_back("CT head, soft tissue (6 mm cells, 1 layer)", spec);
  } else {
    std::cout << "bench tissue: " << head.string() << " is absent: the CT head row is skipped\n";
    report["head_skipped"] = "absent: " + head.string();
  }
  for (const auto& [name, spec] : scenes) {
    std::optional<Press> press;  // the head: its deepest soft tissue
    if (name.rfind("gel", 0) == 0) press = gelPress();
    const nlohmann::ordered_json row = runScene(name, spec, press, short_run);
    report["scenes"].push_back(row);
    md << "\n## " << name << "\n\n";
    if (row.contains("refused")) {
      md << "Refused: " << row["refused"].get<std::string>() << "\n";
      continue;
    }
    md << format("%d tissue voxels; lattice %d nodes, %d touchable (compliance table %.0f MB); built in %.2f s; "
                 "%s ticks, ball of %d points, coupling %.0f N/m; pressed %.1f mm past first contact, slid %.0f mm.\n\n",
                 row["tissue_voxels"].get<int>(), row["lattice_nodes"].get<int>(), row["touchable_nodes"].get<int>(),
                 row["table_MB"].get<double>(), row["build_s"].get<double>(), row["ticks"].dump().c_str(),
                 row["tool_points"].get<int>(), row["coupling_N_per_m"].get<double>(),
                 row["press_depth_m"].get<double>() * 1e3, row["slide_m"].get<double>() * 1e3)
       << "| tick [us] | mean | p99.9 | max | > 500 us | > 1 ms | cut by the deadline | peak force [N] | crossings |\n"
       << "|---|---|---|---|---|---|---|---|---|\n"
       << tickLine("tissue (step + tick)", row["tissue_tick"], row["tissue_cut"].dump(),
                   row["tissue_peak_force_N"].get<double>(), row["tissue_crossings"].dump())
       << tickLine("of which the step (peak: the tissue's push)", row["tissue_step"], "", row["tissue_peak_push_N"].get<double>(), "")
       << tickLine("rigid (tick)", row["rigid_tick"], row["rigid_cut"].dump(), row["rigid_peak_force_N"].get<double>(),
                   row["rigid_crossings"].dump());
    const auto& p = row["step_parts_mean_us"];
    md << format("\nTissue over rigid: mean %.1fx, p99.9 %.1fx, max %.1fx. The step's parts, mean [us]: gather %.0f, "
                 "solve %.0f, displace %.0f, resample %.0f, write %.0f; largest window %d voxels; %d ticks the springing-back "
                 "surface carried the proxy, %d held back (a proxy point would have been swallowed), %d windows "
                 "clipped; deepest indentation %.2f mm.\n",
                 row["tissue_tick"]["mean_us"].get<double>() / row["rigid_tick"]["mean_us"].get<double>(),
                 row["tissue_tick"]["p99_9_us"].get<double>() / row["rigid_tick"]["p99_9_us"].get<double>(),
                 row["tissue_tick"]["max_us"].get<double>() / row["rigid_tick"]["max_us"].get<double>(),
                 p["gather"].get<double>(), p["solve"].get<double>(), p["displace"].get<double>(),
                 p["resample"].get<double>(), p["write"].get<double>(), row["largest_window_voxels"].get<int>(),
                 row["ticks_proxy_carried"].get<int>(), row["ticks_held_back"].get<int>(), row["windows_clipped"].get<int>(),
                 row["deepest_indentation_m"].get<double>() * 1e3);
  }

  // The step's time per lattice size (the gel; the 2 mm row is the scene above).
  md << "\n## The tissue's step per lattice size (gel)\n\n"
     << "| cell [mm] | nodes | touchable | table [MB] | build [s] | step mean [us] | step p99.9 | step max | "
        "whole tick p99.9 | deepest [mm] |\n|---|---|---|---|---|---|---|---|---|---|\n";
  report["lattice_sweep"] = nlohmann::ordered_json::array();
  std::vector<double> cells{0.003, 0.002};
  if (!short_run) cells.push_back(0.0015);
  for (const double cell : cells) {
    const nlohmann::ordered_json row = runScene(format("gel, %.1f mm cells", cell * 1e3), gelPalpationScene(cell), gelPress(), true);
    report["lattice_sweep"].push_back(row);
    if (row.contains("refused")) {
      md << format("| %.1f | refused: %s |\n", cell * 1e3, row["refused"].get<std::string>().c_str());
      continue;
    }
    md << format("| %.1f | %d | %d | %.0f | %.2f | %.0f | %.0f | %.0f | %.0f | %.2f |\n", cell * 1e3,
                 row["lattice_nodes"].get<int>(), row["touchable_nodes"].get<int>(), row["table_MB"].get<double>(),
                 row["build_s"].get<double>(), row["tissue_step"]["mean_us"].get<double>(),
                 row["tissue_step"]["p99_9_us"].get<double>(), row["tissue_step"]["max_us"].get<double>(),
                 row["tissue_tick"]["p99_9_us"].get<double>(), row["deepest_indentation_m"].get<double>() * 1e3);
  }
  writeReport(out, "tissue", report, md, {});
  return out;
}

}  // namespace vh::bench
