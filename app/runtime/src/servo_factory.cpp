// The servo factory (servo_factory.h): renderers and haptic threads for a scene's live values,
// the live solver's lanes and deadline.
#include "vh/runtime/servo_factory.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <optional>
#include <stdexcept>
#include <thread>
#include <utility>

#include "vh/haptics/worker_pool.h"
#include "vh/runtime/tissue_scene.h"
#include "vh/tissue/deformable_scene.h"

namespace vh::runtime {

namespace {
/// A renderer feeling `field` at live's felt isovalue with its gains, edge test and tool.
std::unique_ptr<haptics::HapticRenderer> rendererOn(std::shared_ptr<const haptics::ScalarVolume> field,
                                                    const LiveValues& live, haptics::RendererOptions options,
                                                    const haptics::Pose& X_WP) {
  options.gains = live.gains;
  options.edge_test = live.tool_spec.edge_test ? 1 : 0;
  return std::make_unique<haptics::HapticRenderer>(std::move(field), live.tool, options, X_WP, live.hapticIsovalue());
}
}  // namespace

std::unique_ptr<haptics::HapticRenderer> makeRenderer(const LiveValues& live, haptics::RendererOptions options,
                                                      const haptics::Pose& X_WP) {
  return rendererOn(live.hapticField(), live, std::move(options), X_WP);
}

std::unique_ptr<haptics::HapticRenderer> LoadedScene::makeRenderer(haptics::RendererOptions options,
                                                                   const std::optional<haptics::Pose>& X_WP) const {
  return runtime::makeRenderer(LiveValues::initial(*this), options, X_WP.value_or(X_WT_initial));
}

namespace {
/// VH_SOLVER_LANES when it is a whole count in 1..WorkerPool::kMaxLanes.
std::optional<int> solverLanesFromEnvironment() {
  if (const char* env = std::getenv("VH_SOLVER_LANES")) {
    char* end = nullptr;
    const long lanes = std::strtol(env, &end, 10);
    if (end != env && *end == '\0' && lanes >= 1 && lanes <= haptics::WorkerPool::kMaxLanes)
      return static_cast<int>(lanes);
  }
  return std::nullopt;
}

/// The machine's rule: its hardware threads less two, 1 to 8.
int machineSolverLanes() {
  const int threads = static_cast<int>(std::thread::hardware_concurrency());
  return std::clamp(threads - 2, 1, 8);
}
}  // namespace

int defaultSolverLanes() { return solverLanesFromEnvironment().value_or(machineSolverLanes()); }

int solverLanesFor(std::size_t shell_points, int machine_lanes) {
  return shell_points < kPointsForSeveralLanes ? 1 : std::max(machine_lanes, 1);
}

int solverLanesFor(std::size_t shell_points) {
  if (const std::optional<int> lanes = solverLanesFromEnvironment()) return *lanes;
  return solverLanesFor(shell_points, machineSolverLanes());
}

double solverDeadline_us(double servo_rate_Hz) {
  return servo_rate_Hz > 0.0 && std::isfinite(servo_rate_Hz) ? 0.9e6 / servo_rate_Hz : 0.0;
}

PreparedDrill prepareServoDrill(const LiveValues& live) {
  if (!live.drill) throw std::invalid_argument("prepareServoDrill: the scene has no drill");
  if (live.hapticField() == nullptr || live.scan_field == nullptr)
    throw std::invalid_argument("drilling needs a volume");
  return prepareDrill(*live.hapticField(),
                      makeDrillMaterials(*live.hapticField(), *live.scan_field, live.scan_in_HU,
                                         live.segments.get(), *live.drill),
                      *live.drill);
}

DrillingRenderer makeServoRenderer(const LiveValues& live, const haptics::RendererOptions& options,
                                   const haptics::Pose& X_WP, double servo_rate_Hz, PreparedDrill* prepared,
                                   std::shared_ptr<tissue::DeformableScene> reuse) {
  if (live.tissue) {
    if (live.drill) throw std::invalid_argument("tissue: not with a drill (cutting soft tissue is not supported yet)");
    if (live.feltSegments()) throw std::invalid_argument("tissue: not with felt segments");
    if (live.tool == nullptr) throw std::invalid_argument("tissue needs a tool");
    DrillingRenderer out;
    if (reuse != nullptr && &reuse->scan() == live.scan_field.get() && reuse->isovalue() == live.isovalue) {
      reuse->reset();  // the same scene and surface: the costly model kept, back to rest
      out.tissue = std::move(reuse);
    } else {
      out.tissue = makeTissueScene(*live.tissue, live.scan_field, live.isovalue, live.scan_in_HU,
                                   live.segments != nullptr ? &live.segments->segmentation() : nullptr);
    }
    out.tissue->setLanes(std::clamp(options.solver_lanes, 1, haptics::WorkerPool::kMaxLanes));
    out.renderer = rendererOn(out.tissue->feltVolume(), live, options, X_WP);
    return out;
  }
  if (!live.drill) return {makeRenderer(live, options, X_WP), nullptr, nullptr};
  if (live.hapticField() == nullptr || live.scan_field == nullptr)
    throw std::invalid_argument("drilling needs a volume");
  haptics::RendererOptions with_gains = options;
  with_gains.gains = live.gains;
  with_gains.edge_test = live.tool_spec.edge_test ? 1 : 0;
  if (live.tool == nullptr) throw std::invalid_argument("drilling needs a tool");
  (void)burrOf(*live.tool, *live.drill);  // its errors before the preparation's cost
  PreparedDrill drill = prepared != nullptr && prepared->removal != nullptr ? std::move(*prepared) : prepareServoDrill(live);
  return makeDrillingRenderer(std::move(drill), live.hapticIsovalue(), live.tool, *live.drill, with_gains, X_WP,
                              servo_rate_Hz);
}

std::unique_ptr<ServoTechnique> makeServoTechnique(const LiveValues& live, const Drill* drill) {
  std::vector<std::string> materials, segments;
  if (drill != nullptr) {
    for (const haptics::CuttingMaterial& m : drill->removal().materials()) materials.push_back(m.name);
  }
  if (live.segments != nullptr) {
    for (std::size_t s = 0; s < live.segments->size(); ++s) segments.push_back(live.segments->name(static_cast<int>(s)));
  }
  const Eigen::Vector3d burr_center_T_m = drill != nullptr ? drill->burr().center_T_m : Eigen::Vector3d::Zero();
  return std::make_unique<ServoTechnique>(live.technique, materials, segments, burr_center_T_m,
                                          drill != nullptr ? drill->burr().radius_m : 0.0);
}

std::unique_ptr<HapticThread> makeHapticThread(const LiveValues& live, std::shared_ptr<Device> device,
                                               double servo_rate_Hz, const haptics::Pose& X_WP,
                                               const HapticThreadOptions& options, PreparedDrill* prepared) {
  HapticThreadOptions with_segments = options;
  with_segments.segments = live.segments;
  haptics::RendererOptions solver;
  solver.solver_lanes = solverLanesFor(live.tool != nullptr ? live.tool->point_shell.size() : 0);
  solver.deadline_us = solverDeadline_us(servo_rate_Hz);
  DrillingRenderer r = makeServoRenderer(live, solver, X_WP,
                                         options.solver_rate_Hz > 0.0 ? options.solver_rate_Hz : servo_rate_Hz,
                                         prepared, options.tissue);
  with_segments.drill = r.drill;
  with_segments.tissue = r.tissue;
  with_segments.technique = makeServoTechnique(live, r.drill.get());
  auto thread = std::make_unique<HapticThread>(std::move(r.renderer), std::move(device), live.hapticIsovalue(),
                                               servo_rate_Hz, with_segments);
  thread->setGains(live.gains);
  if (live.drill) thread->setDrilling(live.drill->on);
  return thread;
}

std::unique_ptr<HapticThread> LoadedScene::makeHapticThread(std::shared_ptr<Device> device, double servo_rate_Hz,
                                                            const std::optional<haptics::Pose>& X_WP,
                                                            const HapticThreadOptions& options) const {
  return runtime::makeHapticThread(LiveValues::initial(*this), std::move(device), servo_rate_Hz,
                                   X_WP.value_or(X_WT_initial), options);
}

}  // namespace vh::runtime
