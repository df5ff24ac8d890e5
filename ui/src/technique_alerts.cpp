#include "vh/ui/technique_alerts.h"

#include "vh/runtime/technique.h"

namespace vh::ui {

void TechniqueAlerts::showSnapshot(const runtime::HapticSnapshot& snapshot) {
  const std::uint32_t risen = snapshot.technique & ~active_;
  active_ = snapshot.technique;
  if (risen == 0) return;
  for (int rule = 0; rule < runtime::kTechniqueRuleCount; ++rule) {
    if ((risen & (1u << rule)) == 0) continue;
    ++shown_;
    const std::string_view advice = runtime::techniqueRuleAdvice(rule);
    emit message("Technique: " + QString::fromUtf8(advice.data(), static_cast<int>(advice.size())), 5000);
  }
  emit alertRequested();
}

}  // namespace vh::ui
