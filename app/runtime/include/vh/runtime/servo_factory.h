// The servo factory: the one place a scene's renderer and its haptic threads are built (the GUI
// through Session, the headless runs, replays and benches), with the live solver's lanes and
// deadline. Apart from scene.h (what a scene is and how it loads) so that the solver's
// configuration is found under its own name.
#pragma once

#include <cstddef>
#include <memory>

#include "vh/haptics/haptic_renderer.h"
#include "vh/haptics/pose.h"
#include "vh/runtime/device.h"
#include "vh/runtime/drilling.h"
#include "vh/runtime/haptic_thread.h"
#include "vh/runtime/scene.h"
#include "vh/runtime/technique.h"

namespace vh::runtime {

/// A renderer on `live`'s felt field (hapticField()) at hapticIsovalue(), with its gains and
/// tool, the proxy at `X_WP` in W [m]; the rest of `options` as given.
/// @throws std::invalid_argument as HapticRenderer's constructor (no field, no tool).
std::unique_ptr<haptics::HapticRenderer> makeRenderer(const LiveValues& live, haptics::RendererOptions options,
                                                      const haptics::Pose& X_WP);

/// The pose-free, costly half of live's drilling renderer (live.drill present): prepareDrill() of
/// the felt field with the hardness of makeDrillMaterials() (two passes over the field's voxels:
/// about 0.3 s on a 512 x 512 x 140 CT). Off the servo thread.
/// @throws std::invalid_argument without live.drill or a field, and as makeDrillMaterials() and
///         prepareDrill().
PreparedDrill prepareServoDrill(const LiveValues& live);

/// The renderer of `live` for a haptic thread or a replay: makeRenderer() when live.drill is
/// absent; else makeDrillingRenderer() on prepareServoDrill(live) (slow: passes over the field's
/// voxels), or on `prepared` when given (prepareServoDrill() of the same `live`: the same
/// renderer, only its cost paid earlier; moved from).
/// Soft tissue (live.tissue): the deformable scene of makeTissueScene() (seconds to a minute for
/// thousands of lattice nodes), or `reuse` reset to rest when it was built for live's scan and
/// isovalue (haptic threads rebuilt on the same scene: a recording starting, a tool or device
/// changed); `reuse` must no longer be stepped by another thread. Its step runs on
/// options.solver_lanes lanes, the configuration solver's (DeformableScene::setLanes(): the
/// same contacts and field on any count).
/// @throws std::invalid_argument as makeRenderer() and makeDrillingRenderer().
DrillingRenderer makeServoRenderer(const LiveValues& live, const haptics::RendererOptions& options,
                                   const haptics::Pose& X_WP, double servo_rate_Hz,
                                   PreparedDrill* prepared = nullptr,
                                   std::shared_ptr<tissue::DeformableScene> reuse = nullptr);

/// The technique rules of `live` in a servo loop (technique.h): the safe level of each of
/// `drill`'s materials and of each segment, the drill's burr (none without a drill).
/// @throws std::invalid_argument as TechniqueRules::validate().
std::unique_ptr<ServoTechnique> makeServoTechnique(const LiveValues& live, const Drill* drill);

/// The one place a renderer and its haptic threads are built (the GUI through Session, the
/// headless tests through LoadedScene): a HapticThread (not started) driving `device` at
/// `servo_rate_Hz` on makeRenderer(live, options, X_WP) with options solverLanesFor(the tool's
/// points) lanes and solverDeadline_us(servo_rate_Hz), at live's felt isovalue and gains, naming the segment
/// of each contact when there are segments (HapticThreadOptions::segments); `options` as
/// HapticThreadOptions (e.g. the monitor channel the Session shares); `prepared` as
/// makeServoRenderer()'s.
/// @throws std::invalid_argument as HapticThread's and HapticRenderer's constructors.
std::unique_ptr<HapticThread> makeHapticThread(const LiveValues& live, std::shared_ptr<Device> device,
                                               double servo_rate_Hz, const haptics::Pose& X_WP,
                                               const HapticThreadOptions& options = {},
                                               PreparedDrill* prepared = nullptr);

/// The cores the live solver's sweep runs on (haptics::RendererOptions::solver_lanes): the
/// machine's hardware threads less two (the coupling thread keeps its core, the GUI and the
/// ray caster another), at least 1, at most 8. VH_SOLVER_LANES overrides it (1 to 64).
int defaultSolverLanes();
/// Point shells smaller than this run their sweep on one lane (solverLanesFor()).
inline constexpr std::size_t kPointsForSeveralLanes = 800;
/// The lanes of the live solver for a tool of `shell_points` points: defaultSolverLanes() from
/// kPointsForSeveralLanes points up, one below, so that a small tool starts no solver threads
/// (VH_SOLVER_LANES, when set, applies to every tool). On 16 cores (docs/benchmarks.md,
/// 2026-11-26) the 518-point drill's full solve was no faster on 2 to 16 lanes than on one
/// (0.74x to 0.91x) and its worst tick grew from 50 us on one lane to 336 us on 8 and 1.6 ms on
/// 16, while the 1,307-point peg gained 1.4x on 2 lanes and 2.3x on 8.
int solverLanesFor(std::size_t shell_points);
/// The same rule on a machine whose default is `machine_lanes` (at least 1), the environment
/// aside.
int solverLanesFor(std::size_t shell_points, int machine_lanes);
/// The live solver's deadline per tick [us] (haptics::RendererOptions::deadline_us): 90 % of a
/// servo period at `servo_rate_Hz` (900 us at 1 kHz), the rest for the coupling and the mirror.
double solverDeadline_us(double servo_rate_Hz);

}  // namespace vh::runtime
