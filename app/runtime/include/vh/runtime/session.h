#pragma once
/// @file
/// The one owner of an interactive haptic session: the loaded scene (immutable: volume, tool and
/// segments as loaded, the spec that describes them), the live values (LiveValues: isovalue,
/// coupling gains, tool, segments), the device and the haptic threads. No Qt: the GUI's widgets
/// observe it (addObserver()) and send it commands; nothing else keeps a copy that could
/// disagree.
///
/// One value, one place: loaded() is what was opened and never changes until the next scene;
/// live() is what the user changes, written only here. Every reader (the renderer, the
/// recorder's metadata, the monitor and the OpenIGTLink link, the panels) takes the live values
/// from live(). The haptic thread receives them as commands (HapticThread::setIsovalue(),
/// setGains()) and is built in one place, rebuildHaptics(), by makeHapticThread(live()).
///
/// Threads: every member is called on one thread (the GUI thread); observers run on it,
/// synchronously, after the change. The haptic threads are read only through
/// latestSnapshot() (never blocks).
///
/// Frames and units: W the scene (world) frame [m]; the isovalue in the data's units (HU for
/// CT); gains [N/m] and [N*m/rad].

#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <utility>
#include <vector>

#include "vh/haptics/pose.h"
#include "vh/haptics/tool_model.h"
#include "vh/haptics/virtual_coupling.h"
#include "vh/runtime/device.h"
#include "vh/runtime/haptic_thread.h"
#include "vh/runtime/scene.h"

namespace vh::tissue {
class DeformableScene;
}

namespace vh::runtime {

/// What changed, for observers (a bit set).
enum class SessionChange : std::uint32_t {
  kScene = 1u << 0,     ///< A new scene (or none): everything else may have changed too.
  kIsovalue = 1u << 1,  ///< isovalue()
  kGains = 1u << 2,     ///< gains()
  kTool = 1u << 3,      ///< scene().tool and its spec; the haptic thread was rebuilt.
  kDevice = 1u << 4,    ///< device(); the haptic thread was rebuilt.
  kRunning = 1u << 5,   ///< hapticsRunning()
  kSegments = 1u << 6,  ///< scene().segments (felt, shown, critical); the haptic thread was rebuilt.
  kDrill = 1u << 7,     ///< drilling() or live().drill; the haptic thread may have been rebuilt.
};
constexpr SessionChange operator|(SessionChange a, SessionChange b) {
  return static_cast<SessionChange>(static_cast<std::uint32_t>(a) | static_cast<std::uint32_t>(b));
}
/// True when `set` contains `bit`.
constexpr bool has(SessionChange set, SessionChange bit) {
  return (static_cast<std::uint32_t>(set) & static_cast<std::uint32_t>(bit)) != 0;
}

class Session {
 public:
  using Observer = std::function<void(SessionChange what)>;

  /// @param servo_rate_Hz the rate of the haptic threads this session builds [Hz].
  /// @throws std::invalid_argument for a rate that is not a positive number.
  explicit Session(double servo_rate_Hz = 1000.0);
  ~Session();  ///< Stops the haptic threads (force ramped to zero).
  Session(const Session&) = delete;
  Session& operator=(const Session&) = delete;

  /// Calls `observer(what)` after every change from now on. @return an id for removeObserver().
  /// Const: observing is not a change (a reader that holds the session const may observe it).
  int addObserver(Observer observer) const;
  void removeObserver(int id) const;

  // ---- Scene ---------------------------------------------------------------------------------
  /// Replaces the scene: the old haptic threads stop (force ramped to zero) and go; the new ones
  /// are built (not started) when `device` is set and the scene has a field and a tool. The live
  /// values start as the scene's (LiveValues::initial()), the isovalue clamped to the field's
  /// value range.
  /// @throws std::invalid_argument when the scene has no field (nothing to touch or show).
  void setScene(LoadedScene scene, std::shared_ptr<Device> device);
  /// Stops the haptic threads and forgets the scene and the device (the gains stay).
  void clear();
  bool hasScene() const noexcept { return has_scene_; }
  /// The scene as it was loaded (immutable until the next setScene()): the volume, its info and
  /// spec. Its tool, isovalue, gains and segments are the values it was opened with; what is
  /// felt and shown now is live().
  const LoadedScene& loaded() const noexcept { return loaded_; }
  /// The values the user changes, as they are now: what is felt, shown and recorded.
  const LiveValues& live() const noexcept { return live_; }
  /// The field's value range [min, max] (data units); {0, 1} without a scene.
  std::pair<double, double> valueRange() const noexcept { return {value_min_, value_max_}; }

  // ---- Isovalue and gains --------------------------------------------------------------------
  double isovalue() const noexcept { return live_.isovalue; }
  /// Sets the isovalue, clamped to valueRange(); the haptic thread applies it at its next tick
  /// (felt segments: the hand keeps the segments' surface, the isovalue sets the scan's picture).
  /// Soft tissue (live().tissue): the tissue's region, depth field and compliance belong to one
  /// surface, so the haptic threads are rebuilt on the new one (force ramped to zero, seconds for
  /// thousands of lattice nodes); when that fails (no tissue left at the new surface) the old
  /// isovalue stays, for the eyes and the hand, and the error is thrown.
  /// A non-finite value or no scene: ignored.
  /// @throws std::invalid_argument (tissue only) naming why the tissue cannot be built there.
  void setIsovalue(double isovalue);
  const haptics::CouplingGains& gains() const noexcept { return live_.gains; }
  /// Sets the coupling gains [N/m], [N*m/rad] (applied at the haptic thread's next tick, clamped
  /// there to the device's stable stiffness). Non-finite or negative gains: ignored. Kept
  /// without a scene too; setScene() then starts from the new scene's spec.gains.
  void setGains(const haptics::CouplingGains& gains);

  // ---- Tool ----------------------------------------------------------------------------------
  /// Swaps the tool (e.g. one rebuilt by the GUI's tool picker): the haptic threads stop (force
  /// ramped to zero), the tool and its spec replace the live ones, the device (when simulated)
  /// moves to `X_WT_initial` (a free pose), the threads are rebuilt there and restarted when
  /// they ran. `spec` should name the spacing the shell was sampled at (point_spacing_m, or
  /// point_count): live().pointSpacing_m() derives it from there.
  /// @throws std::invalid_argument for a null tool or no scene.
  void setTool(std::shared_ptr<const haptics::ToolModel> tool, const ToolSpec& spec, const haptics::Pose& X_WT_initial);
  /// Switches the edge test between the tool's shell points (ToolSpec::edge_test): the haptic
  /// threads stop (force ramped to zero) and are rebuilt with it where the proxy is, then
  /// restarted when they ran. The same value again: nothing happens.
  /// @throws std::invalid_argument without a scene.
  void setEdgeTest(bool on);

  // ---- Segments ------------------------------------------------------------------------------
  /// Replaces the live segments (null: none) and their spec (what recordings and scene files
  /// say). When the felt surface stays the same (LiveValues::hapticField() and its isovalue:
  /// segments opened to be seen, other segments shown or critical) and there is no drill, the
  /// running threads take them between two ticks (HapticThread::replaceSegments()): the force
  /// goes on. Otherwise, or while recording, the haptic threads stop (force ramped to zero) and are rebuilt on the new felt field
  /// (LiveValues::hapticField()) at the proxy's pose when no shell point is inside the new
  /// surface there, else at a free pose above the volume (defaultInitialPose(); a simulated
  /// device is moved there); restarted when they ran. Soft tissue made of segments
  /// (TissueSpec::segments) is always rebuilt on the new ones; when it cannot be (the segments
  /// closed, or without one it names), the old segments stay, the threads are rebuilt on them,
  /// and the error is thrown.
  /// @throws std::invalid_argument without a scene, or for segments without a spec; as
  ///         makeTissueScene().
  void setSegments(std::shared_ptr<const SegmentSet> segments, std::optional<SegmentationSpec> spec);

  // ---- Drilling --------------------------------------------------------------------------------
  /// Starts or stops the burr (drilling.h). In a scene without a "drill" section the first start
  /// adds one (DrillSpec's defaults: the tool's tip, 2.5 mm, hardness from HU or segments) and
  /// rebuilds the haptic threads at the proxy's pose, restarted when they ran (one pass over the
  /// field for the hardness: about a second on a 512 x 512 x 140 CT); then the burr only spins up
  /// or down (HapticThread::setDrilling()). The cavity outlives the threads: rebuilding them for
  /// another reason (tool, segments, device, monitor) keeps it in live().drill->cavity and the
  /// new drill starts from it (on the new felt field, where the segments changed it); only a new
  /// scene starts undrilled. No scene: ignored.
  /// @throws std::invalid_argument as makeDrillingRenderer() (e.g. a tool too small for a burr).
  void setDrilling(bool on);
  /// Whether the burr spins.
  bool drilling() const noexcept { return live_.drill.has_value() && live_.drill->on; }
  /// Sets the hardness of a drilling material, its specific cutting energy [J/mm^3]: a segment's
  /// name or ID, or "cortical bone", "cancellous bone", "soft tissue", "tissue" (drilling.h).
  /// Kept in live().drill (without one, kept for the burr's first start); a drill that exists
  /// cuts with it from its next tick (no rebuild: the cavity stays), and a recording gets a
  /// "hardness" event {"material": NAME, "J_per_mm3": E}, which a replay applies from the next
  /// record on. No scene: ignored.
  /// @throws std::invalid_argument for an energy that is not finite and > 0.
  void setHardness(const std::string& material, double J_per_mm3);
  /// The hardness set so far by material or segment [J/mm^3] (live().drill's, else the ones kept
  /// for the burr's first start).
  const std::map<std::string, double>& hardness() const noexcept {
    return live_.drill ? live_.drill->hardness_J_per_mm3 : hardness_for_drill_;
  }

  // ---- Device and haptic threads -------------------------------------------------------------
  /// Drives `device` instead (null: haptics off): the threads are rebuilt with the current tool
  /// at the proxy's current pose (a simulated device is moved there) and restarted when they
  /// ran. Without a scene only the device is kept.
  void setDevice(std::shared_ptr<Device> device);
  Device* device() const noexcept { return device_.get(); }
  const std::shared_ptr<Device>& sharedDevice() const noexcept { return device_; }
  /// The simulated device the mouse and keys move: device()->simulatedDevice(), or null.
  SimulatedDevice* simulatedDevice() const noexcept { return device_ != nullptr ? device_->simulatedDevice() : nullptr; }
  /// Null without a device (haptics off) or a scene.
  HapticThread* hapticThread() const noexcept { return haptics_.get(); }
  bool hapticsRunning() const noexcept { return haptics_ != nullptr && haptics_->running(); }
  /// Starts the haptic threads (built with the live isovalue and gains; no effect without them).
  /// Threads that ran before (stopped, not recording) start with the proxy at a legal pose near
  /// the device (legalPoseNear(): the device's last pose when no shell point is inside there on
  /// the felt, drilled field, else where the proxy stopped), so a restart never holds the hand
  /// where the proxy was jammed.
  void startHaptics();
  /// Reset Device: a simulated device goes back to live().X_WT_initial, and the proxy (threads
  /// stopped for it, force ramped to zero, restarted when they ran) to a legal pose near the
  /// device (legalPoseNear() on the felt, drilled field: X_WT_initial when free, else above the
  /// volume; for a hardware device its last pose). While recording the proxy stays (a recording
  /// replays the renderer's own motion). No scene: ignored.
  void resetDevice();
  /// Ramps the force to zero and joins the threads; idempotent. While drilling, live().drill->cavity
  /// then holds every voxel removed so far (a recording started next carries it).
  void stopHaptics();
  /// Makes the haptic state one that a recording started next replays bit for bit, and returns
  /// the proxy pose in W [m] those threads start from (the recording's initial pose; nullopt:
  /// no scene or no threads, nothing happens). replayRecording() starts a fresh renderer at the
  /// recorded initial pose with the recorded cavity, so the threads the recording holds must
  /// start that way too. Threads that have ticked (running, or stopped after running) are
  /// stopped (force ramped to zero), keep their cavity (live().drill->cavity) and are rebuilt at
  /// the pose the proxy stopped at; the device stays where it is (a hand pressing on bone
  /// presses on the new proxy at once). With a drill the new drill's field and materials are
  /// prepared before the stop, while the running threads still render the force and cut: the
  /// burr is held (HapticThread::holdCutting()) only while the cavity so far is read, and what it
  /// removes during the preparation is removed from the new drill's field at the stop (the
  /// cavity the old threads end with is the one the new ones start from). So the force lets go
  /// only for the ramp and the rest of the build (on a 512 x 512 x 140 CT about 60 ms without
  /// force: the process's memory stays locked over the restart, MemoryLockHold), and the burr
  /// stops cutting only for the one read (lastRestart()).
  /// Threads that never ticked are kept, with the pose they were built at. Either way they are
  /// left stopped: build the metadata from live() with X_WT_initial set to the returned pose
  /// (live().X_WT_initial stays the scene's free placement, where Reset Device goes), attach the
  /// recorder (HapticThread::setRecorder()), then startHaptics(), so the recording holds every
  /// tick of these threads.
  std::optional<haptics::Pose> prepareRecording();
  /// What the last prepareRecording() that restarted threads cost: the time the old threads
  /// went on rendering the force while the new drill was prepared [ms], the time from their stop
  /// (the force's ramp to zero) to the new threads built [ms] (they start with startHaptics()),
  /// whether the drill was prepared before the stop (false: no drill, or built after it), the
  /// time the burr was held from cutting for the read of the cavity [ms] (part of the first),
  /// and the voxels it cut during the rest of the preparation, caught up in the new drill.
  struct RestartTiming {
    double while_feeling_ms = 0.0;
    double without_force_ms = 0.0;
    bool prepared_while_feeling = false;
    double cutting_held_ms = 0.0;
    std::size_t voxels_cut_while_preparing = 0;
  };
  const RestartTiming& lastRestart() const noexcept { return last_restart_; }
  /// The haptic threads' latest snapshot into `out` (false, `out` untouched, without threads or
  /// before their first tick). Never blocks.
  bool latestSnapshot(HapticSnapshot& out) const;
  /// The proxy's pose in W [m]: the latest snapshot's, else live().X_WT_initial.
  haptics::Pose proxyPose() const;
  double servoRate_Hz() const noexcept { return servo_rate_Hz_; }

  /// Every haptic thread this session builds from now on also publishes into `monitor`
  /// (HapticThreadOptions::monitor; null: none), so a consumer other than the GUI (the
  /// OpenIGTLink link) reads them at up to the servo rate; a rebuilt thread keeps feeding it.
  /// Threads that exist are rebuilt at the proxy's pose (force ramped to zero for ~50 ms) and
  /// restarted when they ran: set it once, before the first scene, to avoid that.
  void setMonitor(std::shared_ptr<SnapshotChannel> monitor);
  const std::shared_ptr<SnapshotChannel>& monitor() const noexcept { return monitor_; }

 private:
  /// The one function that builds the renderer and the haptic threads (not started), with the
  /// proxy at `X_WP`; none without a device, a field or a tool.
  void rebuildHaptics(const haptics::Pose& X_WP, PreparedDrill* prepared = nullptr);
  /// Stops the haptic threads (force ramped to zero), keeps their cavity, and drops them.
  void retireHaptics();
  /// With the threads stopped, or their cutting held (HapticThread::holdCutting()): their drill's
  /// cavity into live_.drill->cavity (one pass over the felt field).
  void keepCavity();
  /// After a restart of running threads: keeps `hold` (made before the stop) in
  /// restart_memory_hold_ while the new threads run; dropped when they do not.
  void keepMemoryLock(std::unique_ptr<MemoryLockHold> hold);
  /// The setters' restart (tool, edge test, segments, drill, device, monitor): with the memory
  /// lock held throughout, stops the threads (force ramped to zero), lets `change` write the live
  /// values (it gets the proxy's pose before the stop and returns the pose to rebuild at),
  /// rebuilds the threads, starts them again when they ran, and notifies `what` (plus kRunning
  /// when that changed). When the rebuild throws and `undo` is given, `undo` restores the live
  /// values and the threads are rebuilt as they were before the exception is passed on.
  /// @throws whatever `change` or the rebuild throws.
  void restartHaptics(SessionChange what, const std::function<haptics::Pose(const haptics::Pose& X_WP)>& change,
                      const std::function<void()>& undo = {});
  void notify(SessionChange what);

  double servo_rate_Hz_;
  LoadedScene loaded_;  ///< As loaded; written only by setScene() and clear().
  LiveValues live_;     ///< The one copy of every live value.
  bool has_scene_ = false;
  double value_min_ = 0.0;
  double value_max_ = 1.0;
  std::shared_ptr<Device> device_;
  std::unique_ptr<HapticThread> haptics_;
  // The soft tissue of the threads last retired, for the next ones on the same scene and surface
  // (its compliance table takes seconds to a minute to build); handed on by rebuildHaptics().
  std::shared_ptr<tissue::DeformableScene> tissue_kept_;
  // Keeps the memory lock from a restart of running threads (prepareRecording(), and the setters
  // that rebuild them: tool, edge test, segments, drill, device, monitor) until these threads
  // stop: the restart neither unlocks nor locks again. Kept, not dropped when the restart
  // returns: the new coupling thread takes its own share only once it runs, after start().
  std::unique_ptr<MemoryLockHold> restart_memory_hold_;
  haptics::Pose haptics_built_X_WP_;  ///< The proxy pose haptics_ was built at (rebuildHaptics()).
  RestartTiming last_restart_;
  std::shared_ptr<SnapshotChannel> monitor_;
  std::map<std::string, double> hardness_for_drill_;  ///< setHardness() before any drill
  mutable std::vector<std::pair<int, Observer>> observers_;  ///< Who hears changes; not the session's state.
  mutable int next_observer_ = 1;
};

}  // namespace vh::runtime
