#include "vh/runtime/technique.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <stdexcept>

#include "vh/runtime/drilling.h"

namespace vh::runtime {

std::string_view techniqueRuleName(int rule_index) noexcept {
  switch (rule_index) {
    case 0: return "force";
    case 1: return "speed";
    case 2: return "shaft";
    default: return "";
  }
}

std::string_view techniqueRuleAdvice(int rule_index, bool drilling) noexcept {
  switch (rule_index) {
    case 0: return drilling ? "pressing too hard for too long: ease off and let the burr cut"
                            : "pressing too hard for too long: ease off";
    case 1: return "moving fast near a critical structure: slow down";
    case 2: return "the shaft is on bone while the burr spins: bring the burr, not the shaft, to the bone";
    default: return "";
  }
}

std::string_view shaftOnlyAdvice() noexcept {
  return "only the shaft touches, so the burr cannot cut: Touch the Surface (Ctrl+T) points the burr at the "
         "surface, or turn the tool (Shift+arrow keys)";
}

double TechniqueRules::safeForceFor(const std::string& name) const {
  if (!name.empty()) {
    for (const auto& [given, level_N] : safe_force_by_material_N) {
      if (namesMaterial(given, name)) return level_N;
    }
  }
  return safe_force_N;
}

void TechniqueRules::validate() const {
  const auto positive = [](double v, const char* field) {
    if (!(v > 0.0) || !std::isfinite(v))
      throw std::invalid_argument(std::string("technique.") + field + ": expected a positive number");
  };
  const auto non_negative = [](double v, const char* field) {
    if (!(v >= 0.0) || !std::isfinite(v))
      throw std::invalid_argument(std::string("technique.") + field + ": expected a number >= 0");
  };
  positive(safe_force_N, "safe_force_N");
  for (const auto& [name, level_N] : safe_force_by_material_N) {
    if (!(level_N > 0.0) || !std::isfinite(level_N))
      throw std::invalid_argument("technique.safe_force_by_material_N." + name + ": expected a positive number");
  }
  non_negative(force_hold_s, "force_hold_s");
  positive(near_critical_m, "near_critical_m");
  positive(max_speed_near_critical_m_per_s, "max_speed_near_critical_m_per_s");
  non_negative(shaft_margin_m, "shaft_margin_m");
  non_negative(shaft_hold_s, "shaft_hold_s");
  non_negative(clear_s, "clear_s");
  positive(speed_filter_s, "speed_filter_s");
}

int shaftContacts(std::span<const haptics::Contact> contacts, const Eigen::Vector3d& burr_center_T_m,
                  double burr_radius_m, double margin_m) noexcept {
  const double limit_m = burr_radius_m + margin_m;
  int n = 0;
  for (const haptics::Contact& c : contacts) {
    if ((c.p_T_m - burr_center_T_m).squaredNorm() > limit_m * limit_m) ++n;
  }
  return n;
}

bool TechniqueMonitor::step(int i, bool condition, double hold_s, double time_s) noexcept {
  const std::uint32_t bit = 1u << i;
  if (condition) {
    if (!holding_[i]) {
      holding_[i] = true;
      since_s_[i] = time_s;
    }
    clearing_[i] = false;
    if (!(active_ & bit) && time_s - since_s_[i] >= hold_s) {
      active_ |= bit;
      ++episodes_[i];
    }
  } else {
    holding_[i] = false;
    if (active_ & bit) {
      if (!clearing_[i]) {
        clearing_[i] = true;
        clear_since_s_[i] = time_s;
      }
      if (time_s - clear_since_s_[i] >= rules_.clear_s) {
        active_ &= ~bit;
        clearing_[i] = false;
      }
    }
  }
  return (active_ & bit) != 0;
}

std::uint32_t TechniqueMonitor::update(const TechniqueSample& s) noexcept {
  if (!rules_.on || !std::isfinite(s.time_s)) return active_ = 0;
  // The tool's speed: a first-order low pass of the finite difference (a bad sample's pose is
  // skipped, not differenced).
  if (have_previous_ && s.p_W_m.allFinite() && !s.placed) {
    const double dt_s = s.time_s - previous_time_s_;
    if (dt_s > 0.0) {
      const double raw = (s.p_W_m - previous_p_W_m_).norm() / dt_s;
      const double a = 1.0 - std::exp(-dt_s / rules_.speed_filter_s);
      speed_ += a * (raw - speed_);
    }
  }
  if (s.p_W_m.allFinite()) {
    have_previous_ = true;
    previous_time_s_ = s.time_s;
    previous_p_W_m_ = s.p_W_m;
  }
  const bool pushing = std::isfinite(s.force_N) && s.force_N > s.safe_force_N;
  const bool fast_near = s.nearest_critical_m < rules_.near_critical_m && speed_ > rules_.max_speed_near_critical_m_per_s;
  const bool shaft = s.burr_on && s.shaft_contacts > 0;
  step(0, pushing, rules_.force_hold_s, s.time_s);
  step(1, fast_near, 0.0, s.time_s);
  step(2, shaft, rules_.shaft_hold_s, s.time_s);
  return active_;
}

std::uint64_t TechniqueMonitor::episodes(int rule_index) const noexcept {
  return rule_index >= 0 && rule_index < kTechniqueRuleCount ? episodes_[rule_index] : 0;
}

void TechniqueMonitor::reset() noexcept {
  active_ = 0;
  have_previous_ = false;
  speed_ = 0.0;
  for (int i = 0; i < kTechniqueRuleCount; ++i) {
    holding_[i] = clearing_[i] = false;
    episodes_[i] = 0;
  }
}

ServoTechnique::ServoTechnique(TechniqueRules rules, const std::vector<std::string>& material_names,
                               const std::vector<std::string>& segment_names, const Eigen::Vector3d& burr_center_T_m,
                               double burr_radius_m)
    : burr_center_T_m_(burr_center_T_m), burr_radius_m_(burr_radius_m) {
  rules.validate();
  for (const std::string& name : material_names) material_safe_N_.push_back(rules.safeForceFor(name));
  for (const std::string& name : segment_names) segment_safe_N_.push_back(rules.safeForceFor(name));
  monitor_ = TechniqueMonitor(std::move(rules));
}

double ServoTechnique::safeForce_N(int material, int segment) const noexcept {
  if (material >= 0 && static_cast<std::size_t>(material) < material_safe_N_.size())
    return material_safe_N_[static_cast<std::size_t>(material)];
  if (segment >= 0 && static_cast<std::size_t>(segment) < segment_safe_N_.size())
    return segment_safe_N_[static_cast<std::size_t>(segment)];
  return monitor_.rules().safe_force_N;
}

std::uint32_t ServoTechnique::tick(double time_s, const haptics::Pose& X_WD, double force_N,
                                   std::span<const haptics::Contact> contacts, bool burr_on, int cut_material,
                                   int segment, double nearest_critical_m, bool placed) noexcept {
  TechniqueSample s;
  s.placed = placed;
  s.time_s = time_s;
  s.p_W_m = X_WD * burr_center_T_m_;
  s.force_N = force_N;
  s.safe_force_N = safeForce_N(cut_material, segment);
  s.nearest_critical_m = nearest_critical_m;
  s.burr_on = burr_on && burr_radius_m_ > 0.0;
  s.shaft_contacts = s.burr_on ? shaftContacts(contacts, burr_center_T_m_, burr_radius_m_, monitor_.rules().shaft_margin_m) : 0;
  return monitor_.update(s);
}

}  // namespace vh::runtime
