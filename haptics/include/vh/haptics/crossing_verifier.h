#pragma once
/// @file
/// Reference check that the proxy never passes through the isosurface: each shell
/// point's true path over a tick (eq. 2, the arc the proxy moved along) is sampled densely and
/// every sample is tested with ScalarVolume::isInside(). Independent of CollisionDetector: it
/// shares neither its segments, its chords, its cubic nor its min-max tree (it culls with its
/// own brute-force block maxima), so a tunnel the detector misses is reported, never hidden.

#include <array>
#include <cstdint>
#include <limits>
#include <vector>

#include "vh/haptics/point_shell.h"
#include "vh/haptics/rigid_motion.h"
#include "vh/haptics/scalar_volume.h"

namespace vh::haptics {

/// Dense-sampling oracle of crossings. Not for the servo loop (it may take milliseconds).
class CrossingVerifier {
 public:
  /// Result of one check.
  struct Result {
    int crossing_points = 0;    ///< Points outside at t = 0 with an inside sample on [0, t_stop].
    int first_point = -1;       ///< One such point (the lowest index), or -1.
    double first_t = 1.0;       ///< Time of its first inside sample, in [0, t_stop].
    int started_inside = 0;     ///< Points inside at t = 0 (embedded or penetrating; not checked).
    std::int64_t samples = 0;   ///< isInside() calls.
  };

  /// @param volume, shell must outlive the verifier.
  /// @param step_voxels largest distance between samples along a path, in units of the smallest
  ///        voxel side (1e-3: the 1/1000 voxel; benchmarks use 1e-2).
  /// @throws std::invalid_argument when step_voxels is not finite and > 0.
  CrossingVerifier(const ScalarVolume& volume, const PointShell& shell, double step_voxels);

  /// Samples every point's path p(t) = motion.pointAt(r0, t), t in [0, t_stop], with r0 the
  /// point's radial vector at the motion's start; a point counts when it is outside at t = 0 and
  /// inside at a later sample. Paths whose bounding ball (radius half the path-length bound)
  /// lies in blocks whose largest voxel value is <= isovalue are not sampled.
  Result check(const RigidMotion& motion, double t_stop, double isovalue) const;

  /// Result of checkEdges().
  struct EdgeResult {
    int crossing_edges = 0;     ///< Edges free at t = 0 with an inside sample at a checked time.
    int first_j = -1, first_k = -1;  ///< One such edge's ends (the first found), or -1.
    double first_t = 1.0;       ///< The first checked time at which an edge was inside.
    int started_inside = 0;     ///< Edges with an inside sample at t = 0 (not checked).
    std::int64_t samples = 0;   ///< isInside() calls.
  };

  /// The tool's surface between its points (haptics/README.md, "Between the points"): each
  /// edge (j, k) of `edges` (makeShellEdges() of this verifier's shell), its ends moved `inset_m`
  /// into the tool along their normals, is sampled every step_m() along its length at
  /// `time_samples` times t_stop * i / time_samples, i = 1 .. time_samples (1: the end of the move
  /// only, which is what RendererOptions::edge_test guarantees; more: the move swept, which it
  /// does not), every `along_step_m` along the edge (<= 0: step_m()), leaving out its first and
  /// last inset_m (there the surface is within 2 inset_m of the end's point: the point's own
  /// contact tolerance; the edge test's walk likewise lets an end that starts inside pass while
  /// it leaves). An edge counts when it has no inside sample at t = 0 and one at a checked time.
  /// Edges whose ball (over the whole move) holds no block above the isovalue are skipped.
  /// @param inset_m >= 0 [m]: the detector's epsilon (CollisionDetector::epsilon_m()).
  /// @throws std::invalid_argument when `edges` does not belong to a shell of this size or
  ///         time_samples < 1.
  EdgeResult checkEdges(const RigidMotion& motion, double t_stop, double isovalue, const ShellEdges& edges,
                        double inset_m, int time_samples = 1, double along_step_m = 0.0) const;

  double step_m() const noexcept { return step_m_; }

 private:
  bool ballMayBeInside(const Eigen::Vector3d& centre_W_m, double radius_m, double isovalue) const;

  static constexpr int kBlock = 8;  // cells per block side
  const ScalarVolume* volume_;
  const PointShell* shell_;
  double step_m_;
  std::array<int, 3> blocks_{0, 0, 0};
  std::vector<double> block_max_;   // largest F over each block's voxels, its upper border included
};

}  // namespace vh::haptics
