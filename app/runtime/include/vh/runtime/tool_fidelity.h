#pragma once
/// @file
/// How closely the hand feels the tool's mesh, as the application reports it: the gap between
/// the mesh and the point shell's felt net (haptics::measureShellFidelity), and the notice a
/// user gets when a point spacing is too coarse for the tool's features.

#include <string>

#include "vh/haptics/shell_fidelity.h"
#include "vh/haptics/tool_model.h"

namespace vh::runtime {

/// The gap between `tool`'s mesh and what is felt of it: its points joined by their neighbour
/// edges when `edge_test` (RendererOptions::edge_test), else its points alone. Sampled at a
/// step of a quarter of the spacing (0.1 mm at least), coarser on very large meshes so that
/// about 300,000 samples are taken at most (tens of milliseconds; the step is reported by
/// the result's accuracy, see measureShellFidelity()).
/// @return all zeros for a tool without a mesh (a bare point shell).
haptics::ShellFidelity feltGap(const haptics::ToolModel& tool, bool edge_test);

/// The sentence for the user when `gap.max_gap_m` exceeds haptics::kShellGapWarning_m: how far
/// a surface may come inside the tool's mesh before it is felt, at which spacing, and what to
/// do; empty when the tool is felt within the warning.
/// @param spacing_m the point spacing the shell was sampled at [m].
std::string feltGapNotice(const haptics::ShellFidelity& gap, double spacing_m);

}  // namespace vh::runtime
