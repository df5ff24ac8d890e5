#pragma once
/// @file
/// How closely what is felt follows the tool's mesh: the gap between the mesh's surface and the
/// point shell's felt net (its points, and with the edge test its neighbour edges).
///
/// The proxy is felt at its point shell (paper section 2.2); with RendererOptions::edge_test
/// also along the neighbour edges between the points (haptics/README.md, "Between the points").
/// Anything the isosurface touches elsewhere on the mesh is not felt: a wall can come into the
/// tool's surface until it meets a point or an edge. The largest distance from any point of the
/// mesh's surface to that net bounds how far a surface feature the size of the tool's own
/// (a plate's rim, a ridge) can come inside the mesh before it is felt, up to the edge test's
/// inset epsilon. A probe's 1 mm shaft sampled at 2 mm spacing has 3 points round it: its gap is
/// about a millimetre, the shaft's whole radius.

#include <cstddef>

#include <Eigen/Core>

#include "vh/haptics/point_shell.h"
#include "vh/haptics/triangle_mesh.h"

namespace vh::haptics {

/// The one-sided distance from the mesh's surface to the felt net, sampled densely.
struct ShellFidelity {
  double max_gap_m = 0.0;    ///< Largest distance from a mesh sample to the net [m].
  double p99_gap_m = 0.0;    ///< Its 99th percentile over the samples (area-weighted) [m].
  double mean_gap_m = 0.0;   ///< Its mean over the samples (area-weighted) [m].
  Eigen::Vector3d worst_p_T_m = Eigen::Vector3d::Zero();  ///< The mesh sample of max_gap_m, in T [m].
  std::size_t samples = 0;   ///< Mesh samples measured.
  bool edges = false;        ///< The net included the neighbour edges (else points only).
};

/// Measures the gap between `mesh_T` and the net of `shell`'s points joined by `edges` (pass an
/// empty ShellEdges for points only, as the paper's proxy is felt).
/// Each triangle is sampled on a grid of steps of at most `sample_step_m` along its two shorter
/// sides (its corners and sides included), so every point of the mesh lies within about one
/// step of a sample and, the gap being 1-Lipschitz, the max is found to within about one step.
/// Cost: O(samples) grid lookups (about area / step^2 samples); once per tool, outside the servo loop.
/// @param mesh_T the tool's mesh in T [m]; @param shell its point shell in T [m].
/// @param edges  makeShellEdges(shell), or empty; @param sample_step_m > 0 [m].
/// @throws std::invalid_argument for an empty mesh or shell, a non-positive step, or a step
///         that would need more than 20 million samples.
ShellFidelity measureShellFidelity(const TriangleMesh& mesh_T, const PointShell& shell, const ShellEdges& edges,
                                   double sample_step_m);

/// The same by brute force over every point and edge (for tests: O(samples x edges)).
/// @throws as measureShellFidelity().
ShellFidelity measureShellFidelityBruteForce(const TriangleMesh& mesh_T, const PointShell& shell,
                                             const ShellEdges& edges, double sample_step_m);

/// The gap above which a tool is warned of as too coarsely sampled [m]: a millimetre, a clinical
/// CT's slice thickness, so the tool is felt about as finely as the bone is imaged. A resampled
/// shell's gap is about its spacing at its worst place, so this warns of spacings above about 1 mm.
inline constexpr double kShellGapWarning_m = 1.0e-3;

}  // namespace vh::haptics
