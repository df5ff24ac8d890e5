#include "vh/runtime/session.h"

#include "vh/runtime/drilling.h"
#include "vh/runtime/placement.h"
#include "vh/runtime/servo_factory.h"
#include "vh/runtime/snapshot_channel.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>
#include <string>

#include <nlohmann/json.hpp>

namespace vh::runtime {

Session::Session(double servo_rate_Hz) : servo_rate_Hz_(servo_rate_Hz) {
  if (!(servo_rate_Hz > 0.0) || !std::isfinite(servo_rate_Hz)) {
    throw std::invalid_argument("Session: the servo rate must be a positive number of Hz, not " +
                                std::to_string(servo_rate_Hz));
  }
}

Session::~Session() {
  observers_.clear();  // nobody hears the shutdown
  if (haptics_ != nullptr) haptics_->stop();
}

int Session::addObserver(Observer observer) const {
  const int id = next_observer_++;
  observers_.emplace_back(id, std::move(observer));
  return id;
}

void Session::removeObserver(int id) const {
  observers_.erase(std::remove_if(observers_.begin(), observers_.end(), [id](const auto& o) { return o.first == id; }),
                   observers_.end());
}

void Session::notify(SessionChange what) {
  // A copy: an observer may add or remove observers.
  const auto observers = observers_;
  for (const auto& [id, observer] : observers) {
    if (observer) observer(what);
  }
}

void Session::setScene(LoadedScene scene, std::shared_ptr<Device> device) {
  if (scene.volume.field == nullptr) throw std::invalid_argument("Session: the scene has no volume field");
  const bool was_running = hapticsRunning();
  if (haptics_ != nullptr) haptics_->stop();
  haptics_.reset();
  tissue_kept_.reset();  // another scene's tissue
  loaded_ = std::move(scene);
  has_scene_ = true;
  live_ = LiveValues::initial(loaded_);
  value_min_ = loaded_.volume.field->minValue();
  value_max_ = loaded_.volume.field->maxValue();
  if (!(value_max_ > value_min_)) value_max_ = value_min_ + 1.0;
  live_.isovalue = std::clamp(live_.isovalue, value_min_, value_max_);
  device_ = std::move(device);
  rebuildHaptics(live_.X_WT_initial);
  notify(SessionChange::kScene | SessionChange::kIsovalue | SessionChange::kGains | SessionChange::kTool |
         SessionChange::kDevice | (was_running ? SessionChange::kRunning : SessionChange{}));
}

void Session::clear() {
  if (haptics_ != nullptr) haptics_->stop();
  haptics_.reset();
  tissue_kept_.reset();
  device_.reset();
  const haptics::CouplingGains gains = live_.gains;
  loaded_ = LoadedScene{};
  live_ = LiveValues{};
  live_.gains = gains;
  has_scene_ = false;
  value_min_ = 0.0;
  value_max_ = 1.0;
  notify(SessionChange::kScene | SessionChange::kDevice | SessionChange::kRunning);
}

void Session::setIsovalue(double isovalue) {
  if (!std::isfinite(isovalue) || !has_scene_) return;
  const double clamped = std::clamp(isovalue, value_min_, value_max_);
  if (clamped == live_.isovalue) return;
  if (live_.tissue && haptics_ != nullptr) {  // one surface for the tissue and the hand: rebuilt on it
    const double before = live_.isovalue;
    restartHaptics(
        SessionChange::kIsovalue,
        [&](const haptics::Pose& X_WP) {
          live_.isovalue = clamped;
          return X_WP;
        },
        [&] { live_.isovalue = before; });
    return;
  }
  live_.isovalue = clamped;
  // Felt segments: the isovalue sets only the scan's picture; the hand keeps the segments' surface.
  if (haptics_ != nullptr) haptics_->setIsovalue(live_.hapticIsovalue());
  notify(SessionChange::kIsovalue);
}

void Session::setGains(const haptics::CouplingGains& gains) {
  if (!std::isfinite(gains.linear_N_per_m) || !std::isfinite(gains.angular_Nm_per_rad) ||
      gains.linear_N_per_m < 0.0 || gains.angular_Nm_per_rad < 0.0) {
    return;
  }
  live_.gains = gains;
  // While recording, HapticThread::setGains() records a "gains" event.
  if (haptics_ != nullptr) haptics_->setGains(gains);
  notify(SessionChange::kGains);
}

void Session::setTool(std::shared_ptr<const haptics::ToolModel> tool, const ToolSpec& spec,
                      const haptics::Pose& X_WT_initial) {
  if (tool == nullptr) throw std::invalid_argument("Session::setTool: no tool");
  if (!has_scene_) throw std::invalid_argument("Session::setTool: no scene");
  // The new tool starts where it was asked to, not where the old proxy was.
  restartHaptics(SessionChange::kTool, [&](const haptics::Pose&) {
    live_.tool = std::move(tool);
    live_.tool_spec = spec;
    live_.X_WT_initial = X_WT_initial;
    if (SimulatedDevice* sim = simulatedDevice()) sim->setPose(X_WT_initial);
    return X_WT_initial;
  });
}

void Session::setEdgeTest(bool on) {
  if (!has_scene_) throw std::invalid_argument("Session::setEdgeTest: no scene");
  if (live_.tool_spec.edge_test == on) return;
  // Where the proxy is: free of the surface at its points; an edge already crossing there is
  // not held (the renderer starts no move from a crossing it did not cause).
  restartHaptics(SessionChange::kTool, [&](const haptics::Pose& X_WP) {
    live_.tool_spec.edge_test = on;
    return X_WP;
  });
}

void Session::setSegments(std::shared_ptr<const SegmentSet> segments, std::optional<SegmentationSpec> spec) {
  if (!has_scene_) throw std::invalid_argument("Session::setSegments: no scene");
  if (segments != nullptr && !spec) throw std::invalid_argument("Session::setSegments: segments without a spec");
  // Soft tissue made of segments: its region is rebuilt on the new ones (a failure, e.g. the
  // segments closed, leaves the old ones).
  const bool tissue_of_segments = live_.tissue && !live_.tissue->segments.empty();
  // The same felt surface (what is shown or critical changed, or segments opened to be seen):
  // the running threads take the new segments between two ticks, the hand feels no pause.
  if (haptics_ != nullptr && !live_.drill && !tissue_of_segments &&
      feltFieldOf(segments, live_.scan_field) == live_.hapticField() &&
      feltIsovalueOf(segments, live_.isovalue) == live_.hapticIsovalue()) {
    LiveValues next = live_;
    next.segments = segments;
    if (haptics_->replaceSegments(segments, makeServoTechnique(next, nullptr))) {
      live_.segments = std::move(segments);
      live_.segmentation = live_.segments != nullptr ? std::move(spec) : std::nullopt;
      notify(SessionChange::kSegments);
      return;
    }
  }
  // The cavity so far is kept on the old felt field (the stop comes before the change).
  std::shared_ptr<const SegmentSet> old_segments = live_.segments;
  std::optional<SegmentationSpec> old_spec = live_.segmentation;
  std::function<void()> undo;
  if (tissue_of_segments) {
    undo = [&] {
      live_.segments = old_segments;
      live_.segmentation = old_spec;
    };
  }
  restartHaptics(SessionChange::kSegments, [&](const haptics::Pose& X_WP) {
    if (tissue_of_segments) tissue_kept_.reset();  // built on the old segments
    live_.segments = std::move(segments);
    live_.segmentation = live_.segments != nullptr ? std::move(spec) : std::nullopt;
    // The proxy must start free of the new surface: where it is, else above the volume.
    const haptics::ScalarVolume& field = *live_.hapticField();
    if (live_.tool == nullptr || countPointsInside(field, live_.tool->point_shell, X_WP, live_.hapticIsovalue()) == 0)
      return X_WP;
    const haptics::Pose free = defaultInitialPose(field, live_.tool->point_shell, X_WP.R_AB, live_.hapticIsovalue());
    if (SimulatedDevice* sim = simulatedDevice()) sim->setPose(free);
    return free;
  }, undo);
}

void Session::setDrilling(bool on) {
  if (!has_scene_) return;
  if (!live_.drill) {
    if (!on) return;
    // A drill that cannot be built leaves the tool touching as it was.
    restartHaptics(
        SessionChange::kDrill,
        [&](const haptics::Pose& X_WP) {
          live_.drill = DrillSpec{};
          live_.drill->on = true;
          live_.drill->hardness_J_per_mm3 = hardness_for_drill_;
          if (SimulatedDevice* sim = simulatedDevice()) sim->setPose(X_WP);
          return X_WP;
        },
        [&] { live_.drill.reset(); });
    return;
  }
  if (live_.drill->on == on) return;
  live_.drill->on = on;
  if (haptics_ != nullptr) haptics_->setDrilling(on);
  notify(SessionChange::kDrill);
}

void Session::setHardness(const std::string& material, double J_per_mm3) {
  if (!(J_per_mm3 > 0.0) || !std::isfinite(J_per_mm3))
    throw std::invalid_argument("Session::setHardness: '" + material + "' needs a specific energy > 0 J/mm^3");
  if (!has_scene_) return;
  if (!live_.drill) {
    hardness_for_drill_[material] = J_per_mm3;
    notify(SessionChange::kDrill);
    return;
  }
  live_.drill->hardness_J_per_mm3[material] = J_per_mm3;
  if (haptics_ != nullptr && haptics_->drill() != nullptr) {
    haptics::MaterialRemoval& removal = haptics_->drill()->removal();
    for (std::size_t m = 0; m < removal.materials().size(); ++m) {
      const int segment = haptics_->drill()->segmentOfMaterial(static_cast<int>(m));
      const bool named = namesMaterial(material, removal.materials()[m].name) ||
                         (segment >= 0 && live_.segments != nullptr && namesMaterial(material, live_.segments->segment(segment).id));
      if (named) removal.setSpecificEnergy(static_cast<int>(m), J_per_mm3);
    }
    haptics_->recordEvent("hardness", nlohmann::json{{"material", material}, {"J_per_mm3", J_per_mm3}}.dump());
  }
  notify(SessionChange::kDrill);
}

void Session::setDevice(std::shared_ptr<Device> device) {
  if (!has_scene_) {
    device_ = std::move(device);
    notify(SessionChange::kDevice);
    return;
  }
  restartHaptics(SessionChange::kDevice, [&](const haptics::Pose& X_WP) {
    device_ = std::move(device);
    if (SimulatedDevice* sim = simulatedDevice()) sim->setPose(X_WP);
    return X_WP;
  });
}

void Session::keepCavity() {
  if (haptics_ == nullptr || (haptics_->running() && !haptics_->cuttingHeld()) || haptics_->drill() == nullptr ||
      !live_.drill || live_.hapticField() == nullptr)
    return;
  // The drill carved a copy of the felt field the threads were built on (live_.hapticField():
  // segments change only after retireHaptics()).
  const Drill& drill = *haptics_->drill();
  auto cavity = std::make_shared<DrilledCavity>(
      cavityOf(drill.removal().volume(), *live_.hapticField(), drill.cavityAtStart().get()));
  live_.drill->cavity = cavity->voxels.empty() ? nullptr : std::move(cavity);
}

void Session::retireHaptics() {
  if (haptics_ == nullptr) return;
  haptics_->stop();
  keepCavity();
  tissue_kept_ = haptics_->tissue();  // the next threads reuse it on the same surface
  haptics_.reset();
  restart_memory_hold_.reset();
}

void Session::keepMemoryLock(std::unique_ptr<MemoryLockHold> hold) {
  if (hapticsRunning()) restart_memory_hold_ = std::move(hold);
}

void Session::restartHaptics(SessionChange what, const std::function<haptics::Pose(const haptics::Pose& X_WP)>& change,
                             const std::function<void()>& undo) {
  auto memory_hold = std::make_unique<MemoryLockHold>();  // see restart_memory_hold_
  const bool was_running = hapticsRunning();
  const haptics::Pose X_WP_before = proxyPose();
  retireHaptics();  // force ramped to zero before anything the hand feels changes
  const haptics::Pose X_WP = change(X_WP_before);
  try {
    rebuildHaptics(X_WP);
  } catch (...) {
    if (!undo) throw;
    undo();
    rebuildHaptics(X_WP);
    if (was_running && haptics_ != nullptr) haptics_->start();
    keepMemoryLock(std::move(memory_hold));
    throw;
  }
  if (was_running && haptics_ != nullptr) haptics_->start();
  keepMemoryLock(std::move(memory_hold));
  notify(what | (was_running != hapticsRunning() ? SessionChange::kRunning : SessionChange{}));
}

void Session::rebuildHaptics(const haptics::Pose& X_WP, PreparedDrill* prepared) {
  retireHaptics();
  if (device_ == nullptr || !has_scene_ || live_.hapticField() == nullptr || live_.tool == nullptr) return;
  HapticThreadOptions options;
  options.monitor = monitor_;
  options.tissue = std::move(tissue_kept_);  // reused when built for this scan and isovalue (tissue_kept_ left empty)
  haptics_ = makeHapticThread(live_, device_, servo_rate_Hz_, X_WP, options, prepared);
  haptics_built_X_WP_ = X_WP;
}

std::optional<haptics::Pose> Session::prepareRecording() {
  if (!has_scene_ || haptics_ == nullptr) return std::nullopt;
  HapticSnapshot latest;
  haptics_->latestSnapshot(latest);
  if (latest.tick == 0 && !haptics_->running()) return haptics_built_X_WP_;  // fresh threads
  using Clock = std::chrono::steady_clock;
  const auto ms = [](Clock::time_point a, Clock::time_point b) {
    return std::chrono::duration<double, std::milli>(b - a).count();
  };
  const Clock::time_point begin = Clock::now();
  // The memory stays locked over the restart (unlocking took 20 to 40 ms of the stop on a CT).
  auto memory_hold = std::make_unique<MemoryLockHold>();
  // Running threads with a drill: the new drill's field and materials (0.3 s on a CT) are built
  // while these threads go on rendering the force and cutting. They are held from cutting only
  // while the cavity so far is read (one pass over the field); what the burr removes after that
  // is caught up at the stop, from the box it cut in (MaterialRemoval::cutsSinceMark()), so the
  // new drill starts from the cavity these threads end with, as the replay's will. Without a
  // drill, or when the hold or the preparation fails, everything is built after the stop.
  std::optional<PreparedDrill> prepared;
  Drill* const old_drill = haptics_->drill().get();
  double held_ms = 0.0;
  if (haptics_->running() && old_drill != nullptr && live_.drill && live_.hapticField() != nullptr &&
      haptics_->holdCutting()) {
    try {
      keepCavity();
      old_drill->removal().markCuts();
      haptics_->releaseCutting();
      held_ms = ms(begin, Clock::now());
      prepared = prepareServoDrill(live_);
    } catch (...) {
      prepared.reset();
      haptics_->releaseCutting();
    }
  }
  const Clock::time_point stopping = Clock::now();
  // Where the proxy stopped: free of the surface (the renderer's own pose). The cavity so far is
  // kept (below, or by retireHaptics()) and the new drill starts from it, as the replay's will.
  haptics_->stop();
  const haptics::Pose X_WP = proxyPose();
  std::size_t caught_up = 0;
  if (prepared) {
    try {
      caught_up = catchUpCavity(*old_drill, *live_.hapticField(), live_.drill->cavity, *prepared);
      haptics_.reset();  // its cavity is kept above, the cut since then caught up
    } catch (...) {
      prepared.reset();  // built after the stop instead, from the whole cavity
    }
  }
  if (!prepared) retireHaptics();
  rebuildHaptics(X_WP, prepared ? &*prepared : nullptr);
  const Clock::time_point end = Clock::now();
  last_restart_ = RestartTiming{ms(begin, stopping), ms(stopping, end), prepared.has_value(), held_ms, caught_up};
  keepMemoryLock(std::move(memory_hold));
  notify(SessionChange::kRunning);
  return X_WP;
}

void Session::setMonitor(std::shared_ptr<SnapshotChannel> monitor) {
  if (monitor == monitor_) return;
  monitor_ = std::move(monitor);
  if (haptics_ == nullptr) return;
  // Rebuilt from live(): the felt isovalue (the segments' level when segments are felt) and gains.
  restartHaptics(SessionChange::kDevice, [&](const haptics::Pose& X_WP) {
    if (SimulatedDevice* sim = simulatedDevice()) sim->setPose(X_WP);
    return X_WP;
  });
}

namespace {

/// The device's last pose the threads saw (the simulated device's own when there is one).
std::optional<haptics::Pose> lastDevicePose(HapticThread& thread, SimulatedDevice* sim) {
  if (sim != nullptr) return sim->pose();
  HapticSnapshot snapshot;
  thread.latestSnapshot(snapshot);
  if (snapshot.tick == 0) return std::nullopt;
  return snapshot.X_WD;
}

}  // namespace

void Session::startHaptics() {
  if (haptics_ == nullptr || haptics_->running()) return;
  HapticSnapshot snapshot;
  haptics_->latestSnapshot(snapshot);
  if (snapshot.tick > 0) {  // ran before: from a legal pose near the device, not where it stopped
    const haptics::HapticRenderer& r = haptics_->renderer();
    if (const auto X_WD = lastDevicePose(*haptics_, simulatedDevice())) {
      haptics_->placeProxy(legalPoseNear(r.volume(), r.tool().point_shell, *X_WD, r.feltIsovalue(), r.proxyPose()));
    }
  }
  haptics_->start();
  notify(SessionChange::kRunning);
}

void Session::resetDevice() {
  if (!has_scene_) return;
  SimulatedDevice* sim = simulatedDevice();
  if (sim != nullptr) sim->setPose(live_.X_WT_initial);
  if (haptics_ == nullptr) return;
  const bool was_running = haptics_->running();
  if (was_running) haptics_->stop();  // force ramped to zero; the drill keeps its field
  const haptics::HapticRenderer& r = haptics_->renderer();
  const haptics::Pose X_WD = sim != nullptr ? live_.X_WT_initial : lastDevicePose(*haptics_, nullptr).value_or(live_.X_WT_initial);
  haptics_->placeProxy(legalPoseNear(r.volume(), r.tool().point_shell, X_WD, r.feltIsovalue()));
  if (was_running) haptics_->start();
  notify(SessionChange::kRunning);
}

void Session::stopHaptics() {
  if (haptics_ == nullptr || !haptics_->running()) return;
  haptics_->stop();
  restart_memory_hold_.reset();
  keepCavity();
  notify(SessionChange::kRunning);
}

bool Session::latestSnapshot(HapticSnapshot& out) const {
  if (haptics_ == nullptr) return false;
  HapticSnapshot latest;
  haptics_->latestSnapshot(latest);
  if (latest.tick == 0) return false;
  out = latest;
  return true;
}

haptics::Pose Session::proxyPose() const {
  if (haptics_ != nullptr) {
    HapticSnapshot snapshot;
    haptics_->latestSnapshot(snapshot);
    if (snapshot.tick > 0) return snapshot.X_WP;
  }
  return live_.X_WT_initial;
}

}  // namespace vh::runtime
