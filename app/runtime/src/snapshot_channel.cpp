// The merge of the haptic threads' snapshots of vh/runtime/snapshot_channel.h.
#include "vh/runtime/snapshot_channel.h"

namespace vh::runtime {

void mergeSnapshots(const CouplingSnapshot& c, const SolverSnapshot& s, HapticSnapshot& out) noexcept {
  out.tick = c.tick;
  out.solver_tick = s.tick;
  out.time_ns = c.time_ns;
  out.X_WP = c.X_WP;
  out.X_WD = c.X_WD;
  out.force_W_N = c.force_W_N;
  out.torque_W_Nm = c.torque_W_Nm;
  out.isovalue = s.isovalue;
  out.contacts = s.contacts;
  out.contacts_shown = s.contacts_shown;
  out.segment = s.segment;
  out.critical_segment = s.critical_segment;
  out.critical_distance_m = s.critical_distance_m;
  out.drill = s.drill;
  out.shaft_only = s.shaft_only;
  out.burr_on = s.burr_on;
  out.burr_force_N = s.burr_force_N;
  out.burr_specific_energy_J_per_mm3 = s.burr_specific_energy_J_per_mm3;
  out.burr_eroded_mm3 = s.burr_eroded_mm3;
  out.technique = s.technique;
  out.contact_p_W_m = s.contact_p_W_m;
  out.contact_n_W = s.contact_n_W;
  out.coupling = c.timing;
  out.solver = s.timing;
  out.bad_device_samples = c.bad_samples + s.rejected;
  out.implausible_samples = c.implausible_samples;
  out.held_ticks = c.held_ticks;
  out.skipped_samples = s.skipped;
  out.passivity_active_ticks = c.passivity_active_ticks;
  out.passivity_dissipated_J = c.passivity_dissipated_J;
  out.guidance_on = c.guidance_on;
  out.guidance_force_W_N = c.guidance_force_W_N;
  out.guidance_segment = c.guidance_segment;
  out.guidance_s = c.guidance_s;
  out.guidance_nearest_W_m = c.guidance_nearest_W_m;
}

}  // namespace vh::runtime
