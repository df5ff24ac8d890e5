#pragma once
/// @file
/// Haptic guidance toward an expert's path: a spring from the device's position to the nearest
/// point of a set of line segments (the expert's recorded device path in W), capped and faded.
///
/// Why the nearest point and not the time-aligned one: nearest-point guidance is a path
/// ("virtual fixture") constraint. It does not pull the trainee along in time, so a trainee who
/// moves slower or faster than the expert is guided toward the same path, not dragged ahead or
/// held back (Feygin, Keehner and Tendick, "Haptic guidance: experimental evaluation of a haptic
/// training method for a perceptual motor skill", HAPTICS 2002, guided both in space and time and
/// found the time component the part trainees least retain). The force is the gradient of the
/// potential 1/2 K max(0, d - d_0)^2 (d the distance to the path, d_0 the deadband), capped in
/// magnitude: a function of the position only, hence conservative (it stores and returns energy,
/// never creates it, in continuous time). Sampled at the servo rate it is as passive as any
/// virtual spring of stiffness K: keep K below the device's rated stiffness (the runtime clamps
/// it there, as it clamps the coupling's gains).
///
/// Fading: the stiffness applied on repetition r (0 for the first) is K fade^r, the fading
/// schedule of Crespo and Reinkensmeyer ("Haptic guidance can enhance motor learning of a
/// steering task", J. Motor Behavior 40(6), 2008; guidance that is withdrawn as the trainee
/// repeats the task, so that it does not become a crutch: the "guidance hypothesis"). Guidance is
/// kept weak (a few N at most, the cap) so that it informs rather than drives the hand: Powell
/// and O'Malley, "The task-dependent efficacy of shared-control haptic guidance paradigms", IEEE
/// ToH 5(3), 2012, found strong guidance helps during training but not after it.
///
/// Translation only: the guidance force acts on the tool origin; there is no guidance torque.
///
/// Frames and units: positions p_W in the scene frame W [m]; forces F_W [N] on the user's hand.
/// Nearest-point query: a uniform grid over the segments' bounding box (padded by a quarter of
/// its extent; cells about four segments long, at most cells_per_axis along the longest side),
/// each cell listing the segments whose bounding box overlaps it. A query searches rings of
/// cells around the query's cell outwards until the next ring cannot hold anything nearer; a
/// query still unsettled after kMaxRings rings (far from the path) tests the occupied cells
/// nearer than its best so far instead. Exact; no allocation, no throw.
/// GuidancePath::nearestBruteForce() is the reference it is tested against.

#include <cstddef>
#include <cstdint>
#include <vector>

#include <Eigen/Core>

namespace vh::haptics {

/// The nearest point of a GuidancePath to a query.
struct PathPoint {
  Eigen::Vector3d p_W_m = Eigen::Vector3d::Zero();  ///< The nearest point, in W [m].
  double distance_m = 0.0;  ///< |query - p_W_m| [m]; infinity for an empty path.
  std::int64_t segment = -1;  ///< Index of the segment it lies on (-1: empty path).
  double s = 0.0;  ///< Where on that segment: p = a + s (b - a), s in [0, 1].
};

/// A set of line segments in W (the expert's path, possibly with gaps), with a grid for the
/// nearest-point query. Immutable once built; safe to query from any number of threads.
class GuidancePath {
 public:
  /// One segment from a to b in W [m].
  struct Segment {
    Eigen::Vector3d a_W_m, b_W_m;
  };

  GuidancePath() = default;
  /// @param segments (n x 2 points) in W [m], all finite.
  /// @param cells_per_axis the most cells along the longest side of the bounding box (>= 1);
  ///        the cells are cubes.
  /// @throws std::invalid_argument for a non-finite point or cells_per_axis < 1.
  explicit GuidancePath(std::vector<Segment> segments, int cells_per_axis = 128);
  /// A polyline through `points` (n x 3, W, [m]): segments (i, i + 1).
  static GuidancePath polyline(const std::vector<Eigen::Vector3d>& points, int cells_per_axis = 128);

  bool empty() const noexcept { return segments_.empty(); }
  std::size_t size() const noexcept { return segments_.size(); }
  const std::vector<Segment>& segments() const noexcept { return segments_; }

  /// The nearest point of the path to p_W [m] (grid search: exact). Never allocates or throws.
  PathPoint nearest(const Eigen::Vector3d& p_W_m) const noexcept;
  /// The same by testing every segment (the reference; O(n)).
  PathPoint nearestBruteForce(const Eigen::Vector3d& p_W_m) const noexcept;
  /// The nearest point of one segment `i` to p_W [m].
  PathPoint nearestOnSegment(std::size_t i, const Eigen::Vector3d& p_W_m) const noexcept;

 private:
  std::size_t cellIndex(int ix, int iy, int iz) const noexcept {
    return (static_cast<std::size_t>(iz) * static_cast<std::size_t>(dims_[1]) + static_cast<std::size_t>(iy)) *
               static_cast<std::size_t>(dims_[0]) +
           static_cast<std::size_t>(ix);
  }
  /// Tests the segments of cell (ix, iy, iz) against p, keeping the nearest in `best`.
  void searchCell(int ix, int iy, int iz, const Eigen::Vector3d& p, PathPoint& best) const noexcept;
  /// The fallback far from the path: every occupied cell nearer than `best`.
  void searchOccupiedCells(const Eigen::Vector3d& p, PathPoint& best) const noexcept;
  static constexpr int kMaxRings = 3;

  std::vector<Segment> segments_;
  Eigen::Vector3d origin_W_m_ = Eigen::Vector3d::Zero();  ///< Lower corner of the grid [m].
  double cell_m_ = 1.0;                                   ///< Cell side [m].
  int dims_[3] = {0, 0, 0};
  std::vector<std::uint32_t> cell_start_;  ///< (cells + 1) offsets into cell_segments_ (CSR).
  std::vector<std::uint32_t> cell_segments_;
  std::vector<std::uint32_t> occupied_cells_;  ///< Cells that hold a segment.
};

/// The guidance spring's settings.
struct GuidanceGains {
  /// Stiffness K of the spring toward the path on the first repetition [N/m] (>= 0).
  double stiffness_N_per_m = 200.0;
  /// Largest |F| the guidance ever renders [N] (>= 0); the direction is kept.
  double cap_N = 1.5;
  /// Distance from the path within which there is no force [m] (>= 0); beyond it the spring
  /// stretches by d - deadband.
  double deadband_m = 0.0;
  /// Fade per repetition, in (0, 1]: the stiffness on repetition r is K fade^r.
  double fade = 0.7;
  /// Which repetition this is (0: the first; >= 0).
  int repetition = 0;

  /// K fade^repetition [N/m].
  double effectiveStiffness_N_per_m() const noexcept;
  /// Whether every field is finite and in range.
  bool valid() const noexcept;
};

/// The guidance force at one tick.
struct GuidanceForce {
  Eigen::Vector3d force_W_N = Eigen::Vector3d::Zero();  ///< On the user's hand, in W [N].
  PathPoint nearest;                                    ///< The path's nearest point.
};

/// F = min(K_r max(0, d - d_0), cap) (n - p) / d, K_r = GuidanceGains::effectiveStiffness_N_per_m(),
/// for the device at p_W [m]; zero for an empty path or an invalid gain. |F| <= cap always.
/// Never allocates or throws.
GuidanceForce guidanceForce(const GuidancePath& path, const GuidanceGains& gains, const Eigen::Vector3d& p_WD_m) noexcept;

}  // namespace vh::haptics
