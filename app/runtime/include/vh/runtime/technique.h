#pragma once
/// @file
/// Live feedback on technique: simple rules a surgical educator can read and set, evaluated
/// every servo tick while the trainee works, each turning into a status message, a sound and a
/// recorded "technique" event that the report counts.
///
/// The rules (the scene file's "technique" section; defaults below):
///  - force: |F| on the hand above the safe level of what the tool presses on for longer than
///    force_hold_s. A brief peak is part of cutting; a sustained push is what cracks thin bone
///    and heats it. The level is per material (a segment's name, "cortical bone", ...: what the
///    burr cut this tick, else the segment the contacts touch), else the default.
///  - speed: the tool moving faster than max_speed_near_critical_m_per_s while its nearest
///    critical segment is closer than near_critical_m: near a nerve a trainee should slow down.
///  - shaft: the burr spinning while a contact lies on the tool's shaft (farther than
///    shaft_margin_m outside the burr's sphere) for longer than shaft_hold_s: the shaft rubs and
///    heats bone it cannot cut, and a trainee who leans it on bone cannot see the burr.
/// These are the kinds of measures Sewell et al. computed after a temporal-bone simulator
/// session ("Providing metrics and performance feedback in a surgical simulator", Computer
/// Aided Surgery 13(2), 2008: forces and speed near critical structures), given here while the
/// trainee drills, as the Melbourne simulator's real-time feedback does (Wijewickrema et al.).
/// The default levels are conservative starting points, not figures from a study: an educator
/// sets them for the procedure in the scene file.
///
/// A rule becomes active when its condition held for its hold time and stays active until the
/// condition has been clear for clear_s, so one episode gives one event however it flickers.
/// Frames and units: W [m], forces [N], time [s].

#include <cstdint>
#include <limits>
#include <map>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "vh/haptics/contact_set.h"
#include "vh/haptics/pose.h"

namespace vh::runtime {

/// The rules, as bits of TechniqueMonitor::update()'s result and of TickRecord::flags
/// (kRecordFlagTechniqueForce etc. are these shifted).
enum TechniqueRule : std::uint32_t {
  kTechniqueForce = 1u << 0,  ///< Force above the safe level for too long.
  kTechniqueSpeed = 1u << 1,  ///< Too fast near a critical segment.
  kTechniqueShaft = 1u << 2,  ///< The burr spinning with the shaft in contact.
};
inline constexpr int kTechniqueRuleCount = 3;

/// The rule's name in events, reports and the scene file: "force", "speed", "shaft".
std::string_view techniqueRuleName(int rule_index) noexcept;
/// What the rule asks of the trainee, one short sentence for the status bar; `drilling`: the
/// scene has a drill (the force rule's advice then speaks of the burr; without one, a probe
/// pressing hard is told to ease off, not to let a burr it does not have cut).
std::string_view techniqueRuleAdvice(int rule_index, bool drilling = true) noexcept;
/// What the window says when the burr spins and only the shaft or the handle touches (the burr
/// cannot cut): how to bring the burr to the surface.
std::string_view shaftOnlyAdvice() noexcept;

/// The scene file's "technique" section.
struct TechniqueRules {
  bool on = true;                          ///< "on": false turns every rule off.
  double safe_force_N = 3.0;               ///< "safe_force_N": the default safe level [N].
  /// "safe_force_by_material_N": per material or segment name (case-insensitive) [N].
  std::map<std::string, double> safe_force_by_material_N;
  double force_hold_s = 0.5;               ///< "force_hold_s" [s].
  double near_critical_m = 0.003;          ///< "near_critical_m": where the speed rule applies [m].
  double max_speed_near_critical_m_per_s = 0.01;  ///< "max_speed_near_critical_m_per_s" [m/s].
  double shaft_margin_m = 0.0005;          ///< "shaft_margin_m": outside the burr by this [m].
  double shaft_hold_s = 0.1;               ///< "shaft_hold_s" [s].
  double clear_s = 0.5;                    ///< "clear_s": a rule ends after this long clear [s].
  /// Low-pass time constant of the tool's speed [s]: a 1 kHz finite difference of a device's
  /// encoders is noise; 20 ms keeps a hand's motion (a few Hz).
  double speed_filter_s = 0.02;

  /// The safe level for material `name` (empty: the default) [N].
  double safeForceFor(const std::string& name) const;
  /// @throws std::invalid_argument naming the field for a level, time or distance that is not a
  ///         positive finite number (clear_s and the hold times may be 0).
  void validate() const;
};

/// One tick's inputs.
struct TechniqueSample {
  double time_s = 0.0;                         ///< Servo time [s].
  Eigen::Vector3d p_W_m = Eigen::Vector3d::Zero();  ///< The tool's working point (burr centre or tip) in W [m].
  double force_N = 0.0;                        ///< |F| on the hand [N].
  double safe_force_N = 3.0;                   ///< The safe level for what it presses on (TechniqueRules::safeForceFor) [N].
  /// Distance from the tool to its nearest critical segment [m]; +inf: none or unknown.
  double nearest_critical_m = std::numeric_limits<double>::infinity();
  bool burr_on = false;                        ///< The burr spins.
  int shaft_contacts = 0;                      ///< Contacts on the shaft (shaftContacts()).
  /// A placement (Touch the Surface, Home, Reset Device) put the tool at p_W_m just before this
  /// tick: not the hand's motion, so no speed is taken across it (the speed rule never fires
  /// on a jump the hand did not make).
  bool placed = false;
};

/// The contacts of `contacts` that lie off the burr: farther than burr_radius_m + margin_m from
/// its centre (T [m]). No allocation.
int shaftContacts(std::span<const haptics::Contact> contacts, const Eigen::Vector3d& burr_center_T_m,
                  double burr_radius_m, double margin_m) noexcept;

/// Evaluates the rules tick by tick. No allocation, no exception; one caller thread.
class TechniqueMonitor {
 public:
  explicit TechniqueMonitor(TechniqueRules rules = {}) : rules_(std::move(rules)) {}
  const TechniqueRules& rules() const noexcept { return rules_; }
  /// One tick. @return the active rules (TechniqueRule bits).
  std::uint32_t update(const TechniqueSample& s) noexcept;
  /// The active rules after the last update().
  std::uint32_t active() const noexcept { return active_; }
  /// The tool's filtered speed after the last update() [m/s].
  double speed_m_per_s() const noexcept { return speed_; }
  /// Episodes (rising edges) of rule i so far.
  std::uint64_t episodes(int rule_index) const noexcept;
  void reset() noexcept;

 private:
  /// Rule bit `bit`'s condition this tick: whether the rule is active after it.
  bool step(int rule_index, bool condition, double hold_s, double time_s) noexcept;

  TechniqueRules rules_;
  std::uint32_t active_ = 0;
  bool have_previous_ = false;
  double previous_time_s_ = 0.0;
  Eigen::Vector3d previous_p_W_m_ = Eigen::Vector3d::Zero();
  double speed_ = 0.0;
  double since_s_[kTechniqueRuleCount] = {0, 0, 0};        ///< When the condition began to hold (if holding_).
  double clear_since_s_[kTechniqueRuleCount] = {0, 0, 0};  ///< When an active rule's condition cleared (if clearing_).
  bool holding_[kTechniqueRuleCount] = {false, false, false};
  bool clearing_[kTechniqueRuleCount] = {false, false, false};
  std::uint64_t episodes_[kTechniqueRuleCount] = {0, 0, 0};
};

/// The rules inside a servo loop (the headless runner's, the haptic thread's solver): the safe
/// level of each drill material and each segment looked up once, off the servo thread, so that a
/// tick compares numbers only; the burr for the shaft rule.
class ServoTechnique {
 public:
  /// @param material_names the drill's materials in order (MaterialRemoval::materials()); empty
  ///        without a drill. @param segment_names the scene's segments in order; empty without.
  /// @param burr_radius_m 0: no burr (the shaft rule never fires). burr_center_T_m in T [m].
  /// @throws std::invalid_argument as TechniqueRules::validate().
  ServoTechnique(TechniqueRules rules, const std::vector<std::string>& material_names,
                 const std::vector<std::string>& segment_names, const Eigen::Vector3d& burr_center_T_m,
                 double burr_radius_m);
  /// One servo tick. @param X_WD the device pose [m] (the hand's speed is the burr centre's, or
  /// T's origin without a burr); @param force_N |F| on the hand [N]; @param contacts the contact
  /// set after the tick; @param cut_material the material the burr cut this tick (CutResult::
  /// material, -1: none); @param segment the segment the contacts touch (-1: none);
  /// @param nearest_critical_m the nearest critical segment [m] (+inf: none); @param placed a
  /// placement put the tools at X_WD just before this tick (TechniqueSample::placed).
  /// @return the active rules (TechniqueRule bits). No allocation, no exception.
  std::uint32_t tick(double time_s, const haptics::Pose& X_WD, double force_N,
                     std::span<const haptics::Contact> contacts, bool burr_on, int cut_material, int segment,
                     double nearest_critical_m, bool placed = false) noexcept;
  const TechniqueMonitor& monitor() const noexcept { return monitor_; }
  /// The safe level for a tick that cut `material` while touching `segment` [N].
  double safeForce_N(int material, int segment) const noexcept;

 private:
  TechniqueMonitor monitor_;
  std::vector<double> material_safe_N_, segment_safe_N_;
  Eigen::Vector3d burr_center_T_m_;
  double burr_radius_m_;
};

}  // namespace vh::runtime
