#include "vh/ui/technique_alerts.h"

#include "vh/runtime/technique.h"

namespace vh::ui {

void TechniqueAlerts::showSnapshot(const runtime::HapticSnapshot& snapshot) {
  showShaftOnly(snapshot);
  const std::uint32_t risen = snapshot.technique & ~active_;
  active_ = snapshot.technique;
  if (risen == 0) return;
  for (int rule = 0; rule < runtime::kTechniqueRuleCount; ++rule) {
    if ((risen & (1u << rule)) == 0) continue;
    ++shown_;
    const std::string_view advice = runtime::techniqueRuleAdvice(rule, snapshot.drill);
    emit message("Technique: " + QString::fromUtf8(advice.data(), static_cast<int>(advice.size())), 5000);
  }
  emit alertRequested();
}

void TechniqueAlerts::showShaftOnly(const runtime::HapticSnapshot& snapshot) {
  // An episode: the burr spinning with only the shaft touching for kShaftOnlyTicks solver ticks
  // (a touch that passes over the burr's edge is not one); it ends when the burr touches, spins
  // down or the tool leaves the surface.
  const bool shaft_only = snapshot.drill && snapshot.burr_on && snapshot.shaft_only;
  if (!shaft_only) {
    shaft_only_since_.reset();
    shaft_only_said_ = false;
    return;
  }
  if (!shaft_only_since_) shaft_only_since_ = snapshot.solver_tick;
  if (shaft_only_said_ || snapshot.solver_tick < *shaft_only_since_ + kShaftOnlyTicks) return;
  shaft_only_said_ = true;
  ++shaft_only_shown_;
  const std::string_view advice = runtime::shaftOnlyAdvice();
  emit message("Burr: " + QString::fromUtf8(advice.data(), static_cast<int>(advice.size())), 8000);
}

}  // namespace vh::ui
