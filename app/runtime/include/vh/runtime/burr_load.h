#pragma once
/// @file
/// What the burr cut against on one servo tick, as the burr's sound follows it (vh::audio's
/// BurrState): the headless run (runner.cpp) and the GUI's snapshots (haptic_thread.cpp) both
/// take it from here, so that the two sounds follow the same rule.

#include "vh/haptics/haptic_renderer.h"
#include "vh/haptics/material_removal.h"

namespace vh::runtime {

/// |F| on the hand [N] and the hardness of what the burr cut [J/mm^3] on a tick; both 0 when it
/// cut nothing (the burr running free), whatever the force of a contact elsewhere on the tool.
struct BurrLoad {
  double force_N = 0.0;
  double specific_energy_J_per_mm3 = 0.0;
};

inline BurrLoad burrLoadOf(const haptics::CutResult& cut, const haptics::TickOutput& out) noexcept {
  if (!(cut.energy_J > 0.0)) return {};
  return {out.force_W_N.norm(), cut.specific_energy_J_per_mm3};
}

}  // namespace vh::runtime
