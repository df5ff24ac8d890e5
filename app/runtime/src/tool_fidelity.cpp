#include "vh/runtime/tool_fidelity.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace vh::runtime {

haptics::ShellFidelity feltGap(const haptics::ToolModel& tool, bool edge_test) {
  if (tool.mesh_T.empty() || tool.point_shell.empty()) return {};
  constexpr double kMaxSamples = 300e3;
  const haptics::ShellEdges edges = edge_test ? haptics::makeShellEdges(tool.point_shell) : haptics::ShellEdges{};
  const double spacing = edges.spacing_m > 0.0 ? edges.spacing_m : tool.point_shell.meanNearestNeighbourSpacing_m();
  double step = std::max(0.1e-3, spacing / 4.0);
  // About area / (h^2 / 2) samples at step h (measureShellFidelity() steps along the shorter sides).
  const double samples = 2.0 * tool.mesh_T.area_m2() / (step * step);
  if (samples > kMaxSamples) step *= std::sqrt(samples / kMaxSamples) * 1.05;
  return haptics::measureShellFidelity(tool.mesh_T, tool.point_shell, edges, step);
}

std::string feltGapNotice(const haptics::ShellFidelity& gap, double spacing_m) {
  if (!(gap.max_gap_m > haptics::kShellGapWarning_m)) return {};
  char text[400];
  std::snprintf(text, sizeof text,
                "tool: at %.2f mm point spacing a surface can come up to %.2f mm inside the tool's mesh before it is "
                "felt (%s; 99 %% of the mesh within %.2f mm): choose a finer spacing for a tool with features this "
                "small",
                spacing_m * 1e3, gap.max_gap_m * 1e3,
                gap.edges ? "between the point shell's edges" : "between its points, the edge test off",
                gap.p99_gap_m * 1e3);
  return text;
}

}  // namespace vh::runtime
