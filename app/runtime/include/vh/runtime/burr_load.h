#pragma once
/// @file
/// What the burr cut against on one servo tick, as the burr's sound follows it (vh::audio's
/// BurrState): the headless run (runner.cpp), the GUI's snapshots (haptic_thread.cpp) and the
/// replay of a recording (replay.cpp, for an exported video's sound) all take it from here, so
/// that their sounds follow the same rule.

#include <cstdint>

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

/// The burr after one tick of a drilling scene: what its sound follows (vh::audio::BurrState)
/// and what sounds its alert (RunOptions::on_drill_tick, ReplayProgress::on_drill_tick).
struct DrillTick {
  std::uint64_t tick = 0;                  ///< The tick's number, as the recording numbers them.
  double time_s = 0.0;                     ///< Its time [s] (the record's time_s).
  bool burr_on = false;                    ///< The burr spins (the drill is on; the sample was rendered).
  double force_N = 0.0;                    ///< |F| when the burr cut this tick, else 0 (free running) [N].
  double specific_energy_J_per_mm3 = 0.0;  ///< Hardness of what it cut (haptics::CutResult), else 0 [J/mm^3].
  double removal_rate_mm3_per_s = 0.0;     ///< Material eroded this tick over the servo period [mm^3/s].
  /// The tool touches a critical segment, or the burr removed part of one, this tick.
  bool critical = false;
};

/// The DrillTick of a tick that cut `cut` (empty when the burr was off) after the renderer
/// returned `out`: the load from burrLoadOf(), the removal rate `eroded_mm3` (eroded this tick
/// [mm^3]) over `period_s` [s], critical when the cut removed part of a critical segment or
/// `critical_contact` (the contacts lie on a critical segment).
inline DrillTick drillTickOf(std::uint64_t tick, double time_s, bool burr_on, const haptics::CutResult& cut,
                             const haptics::TickOutput& out, double eroded_mm3, double period_s,
                             bool critical_contact) noexcept {
  DrillTick d;
  d.tick = tick;
  d.time_s = time_s;
  d.burr_on = burr_on;
  const BurrLoad load = burrLoadOf(cut, out);
  d.force_N = load.force_N;
  d.specific_energy_J_per_mm3 = load.specific_energy_J_per_mm3;
  d.removal_rate_mm3_per_s = eroded_mm3 / period_s;
  d.critical = cut.critical_removed > 0 || critical_contact;
  return d;
}

}  // namespace vh::runtime
