// The session report's table of what the burr removed, per material (report_drilling.h).

#include "report_drilling.h"

#include <cstdint>

#include "vh/runtime/anonymize.h"
#include "vh/runtime/drilling.h"
#include "vh/ui/export/report_format.h"

namespace vh::ui::detail {

std::string drilledByMaterialSection(const DrilledByMaterial& d, const std::vector<std::string>& scrub) {
  if (!d.report && d.why.empty()) return {};
  std::string html = "<h2>Drilled away, per material</h2>\n";
  if (!d.report)
    return html + "<p>Per material: not known: " + escapeHtml(runtime::scrubText(d.why, scrub)) + ".</p>\n";
  html += "<p class=\"small\">What the burr removed during the recording (the cavity it began on left out), "
          "from a replay of the recording on its scene, by the rule of <code>volume-haptics run</code>'s report. "
          "\"Below the felt surface\": voxels whose value was under the felt isovalue, which the burr's reach "
          "took with the tissue beside them. \"air\": on a CT, voxels below " + formatNumber(runtime::kAirBelow_HU) +
          " HU in the scan, charged at the hardness of the class they were counted in.</p>\n"
          "<table>\n<tr><th>material</th><th>critical</th><th>drilled away</th><th>of it below the felt "
          "surface</th><th>hardness charged</th></tr>\n";
  std::uint64_t voxels = 0;
  double mm3 = 0.0;
  for (const runtime::DrillReport::Material& m : d.report->materials) {
    if (m.voxels == 0) continue;
    voxels += m.voxels;
    mm3 += m.removed_mm3;
    html += "<tr" + std::string(m.critical ? " class=\"critical\"" : "") + "><td>" + escapeHtml(m.name) + "</td><td>" +
            (m.critical ? "yes" : "no") + "</td><td class=\"n\">" + formatQuantity(m.removed_mm3, "mm^3") + " (" +
            std::to_string(m.voxels) + " voxels)</td><td class=\"n\">" +
            formatQuantity(m.below_surface_mm3, "mm^3") + "</td><td class=\"n\">" +
            formatQuantity(m.specific_energy_J_per_mm3, "J/mm^3") + "</td></tr>\n";
  }
  html += "<tr><th>all</th><td></td><td class=\"n\">" + formatQuantity(mm3, "mm^3") + " (" +
          std::to_string(voxels) + " voxels)</td><td></td><td></td></tr>\n";
  return html + "</table>\n";
}

}  // namespace vh::ui::detail
