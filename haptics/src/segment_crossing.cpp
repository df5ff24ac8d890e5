// ScalarVolume::firstEntryOnSegment(): the exact first crossing of a straight segment into
// {F > s}, cell by cell, so the proxy never passes through a thin feature (haptics/README.md,
// "Never through").
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>

#include "vh/haptics/scalar_volume.h"

namespace vh::haptics {
namespace {

// g(w) = c0 + c1 w + c2 w^2 + c3 w^3 (Horner).
struct Cubic {
  double c0, c1, c2, c3;
  double operator()(double w) const noexcept { return ((c3 * w + c2) * w + c1) * w + c0; }
};

// Roots of g'(w) = c1 + 2 c2 w + 3 c3 w^2 strictly inside (0, w_end), sorted; returns the count.
int criticalPoints(const Cubic& g, double w_end, double* out) noexcept {
  const double a = 3.0 * g.c3, b = 2.0 * g.c2, c = g.c1;
  double r[2];
  int n = 0;
  if (a == 0.0) {
    if (b != 0.0) r[n++] = -c / b;
  } else {
    const double disc = b * b - 4.0 * a * c;
    if (disc >= 0.0) {
      // The numerically stable pair: q = -(b + sign(b) sqrt(disc)) / 2, roots q / a and c / q.
      const double q = -0.5 * (b + std::copysign(std::sqrt(disc), b));
      r[n++] = q / a;
      if (q != 0.0) r[n++] = c / q;
    }
  }
  int m = 0;
  for (int i = 0; i < n; ++i)
    if (r[i] > 0.0 && r[i] < w_end && std::isfinite(r[i])) out[m++] = r[i];
  if (m == 2 && out[1] < out[0]) std::swap(out[0], out[1]);
  return m;
}

// The box test: clips u in [0, 1] to the grid's box of voxel centres [0, upper] per axis (slab
// method). False: the segment misses the box (or, parallel to an axis, lies outside it).
inline bool clipToGrid(const Eigen::Vector3d& a, const Eigen::Vector3d& d, const Eigen::Vector3d& upper,
                       double& u_lo, double& u_hi) noexcept {
  for (int axis = 0; axis < 3; ++axis) {
    if (d[axis] == 0.0) {
      if (a[axis] < 0.0 || a[axis] > upper[axis]) return false;
      continue;
    }
    double t0 = (0.0 - a[axis]) / d[axis], t1 = (upper[axis] - a[axis]) / d[axis];
    if (t0 > t1) std::swap(t0, t1);
    u_lo = std::max(u_lo, t0);
    u_hi = std::min(u_hi, t1);
  }
  return u_lo <= u_hi;
}

// The walk's start (a 3-D DDA over the cells): the cell containing start = a + u_lo d, stepping
// into the one the segment moves into when the start lies on a cell face; per axis the step
// (-1, 0, 1), the u of the next face and the u between faces.
inline void startCellWalk(const Eigen::Vector3d& a, const Eigen::Vector3d& d, const Eigen::Vector3d& start,
                          const std::array<int, 3>& dims, int (&cell)[3], int (&step)[3], double (&u_next)[3],
                          double (&u_delta)[3]) noexcept {
  for (int axis = 0; axis < 3; ++axis) {
    const int top = dims[axis] - 2;
    double fl = std::floor(start[axis]);
    if (d[axis] < 0.0 && fl == start[axis]) fl -= 1.0;
    cell[axis] = static_cast<int>(std::clamp(fl, 0.0, static_cast<double>(top)));
    step[axis] = d[axis] > 0.0 ? 1 : (d[axis] < 0.0 ? -1 : 0);
    if (step[axis] == 0) {
      u_next[axis] = u_delta[axis] = std::numeric_limits<double>::infinity();
    } else {
      const double face = step[axis] > 0 ? cell[axis] + 1.0 : static_cast<double>(cell[axis]);
      u_next[axis] = (face - a[axis]) / d[axis];
      u_delta[axis] = 1.0 / std::abs(d[axis]);
    }
  }
}

// The eight corner values of one cell (raw), c_xyz at corner offset (x, y, z).
struct CellCorners {
  double c000, c100, c010, c110, c001, c101, c011, c111;
};

// Reads the corners of the cell whose (0, 0, 0) corner is at c; sy, sz: the voxel strides.
template <typename T>
inline CellCorners loadCorners(const T* c, std::ptrdiff_t sy, std::ptrdiff_t sz) noexcept {
  const auto at = [c](std::ptrdiff_t offset) { return static_cast<double>(c[offset]); };
  return {at(0), at(1), at(sy), at(1 + sy), at(sz), at(1 + sz), at(sy + sz), at(1 + sy + sz)};
}

// The cell's trilinear interpolant (raw) along the chord a + u' d, as a cubic in w = u' - u
// from the cell's entry u (grid coordinates; cell: the cell's (0, 0, 0) corner).
inline Cubic chordCubicInCell(const CellCorners& cc, const Eigen::Vector3d& a, const Eigen::Vector3d& d, double u,
                              const int (&cell)[3]) noexcept {
  // Local coordinates at the cell's entry, then the cubic in w = u - u_entry.
  const double x = a[0] + u * d[0] - cell[0], y = a[1] + u * d[1] - cell[1], z = a[2] + u * d[2] - cell[2];
  const double dx = d[0], dy = d[1], dz = d[2];
  const double k0 = cc.c000, k1 = cc.c100 - cc.c000, k2 = cc.c010 - cc.c000, k3 = cc.c001 - cc.c000;
  const double k4 = cc.c110 - cc.c010 - cc.c100 + cc.c000, k5 = cc.c101 - cc.c001 - cc.c100 + cc.c000,
               k6 = cc.c011 - cc.c001 - cc.c010 + cc.c000;
  const double k7 = cc.c111 - cc.c011 - cc.c101 - cc.c110 + cc.c100 + cc.c010 + cc.c001 - cc.c000;
  const double r0 = k0 + k1 * x + k2 * y + k3 * z + k4 * x * y + k5 * x * z + k6 * y * z + k7 * x * y * z;
  const double r1 = k1 * dx + k2 * dy + k3 * dz + k4 * (x * dy + y * dx) + k5 * (x * dz + z * dx) +
                    k6 * (y * dz + z * dy) + k7 * (dx * y * z + x * dy * z + x * y * dz);
  const double r2 = k4 * dx * dy + k5 * dx * dz + k6 * dy * dz + k7 * (x * dy * dz + dx * y * dz + dx * dy * z);
  const double r3 = k7 * dx * dy * dz;
  return {r0, r1, r2, r3};
}

// The walk's step (3-D DDA): into the next cell along every axis whose face it reaches at
// u_exit. False when that leaves the grid's cells.
inline bool stepToNextCell(double u_exit, const std::array<int, 3>& dims, const int (&step)[3],
                           const double (&u_delta)[3], int (&cell)[3], double (&u_next)[3]) noexcept {
  bool out_of_grid = false;
  for (int axis = 0; axis < 3; ++axis) {
    if (u_next[axis] != u_exit) continue;
    cell[axis] += step[axis];
    u_next[axis] += u_delta[axis];
    if (cell[axis] < 0 || cell[axis] > dims[axis] - 2) out_of_grid = true;
  }
  return !out_of_grid;
}

// The root refinement in one examined cell: g (the cell's cubic with the bubble, minus the
// threshold, in w = u' - u from the cell's entry u) on [0, w_end], split at its critical points
// into monotone pieces, each bisected to u_tolerance where it crosses 0. inside_run: entered
// before this cell (only a start inside, leaving); first: the segment's own start. True when
// the walk ends here: result.hit with u_outside and u_inside set.
inline bool refineInCell(const Cubic& g, double w_end, double u, double u_lo, double u_tolerance, bool first,
                         bool& inside_run, SegmentEntry& result) noexcept {
  double breaks[4];
  int nb = 0;
  breaks[nb++] = 0.0;
  nb += criticalPoints(g, w_end, breaks + nb);
  breaks[nb++] = w_end;
  double gp = g(0.0);
  result.excess_max = std::max(result.excess_max, gp);
  if (first) {
    inside_run = gp > 0.0;  // the segment starts inside
  } else if (!inside_run && gp > 0.0) {
    // Entered exactly on a cell face (the previous cell's cubic rounded to <= 0 there), or on
    // the grid box's face from outside it (out of bounds is outside).
    result.hit = true;
    result.u_outside = u == u_lo && u_lo > 0.0 ? std::max(0.0, u - u_tolerance) : u;
    result.u_inside = u;
    return true;
  } else if (inside_run && gp <= 0.0) {
    inside_run = false;
  }
  for (int i = 0; i + 1 < nb; ++i) {
    double p = breaks[i], q = breaks[i + 1];
    const double gq = g(q);
    result.excess_max = std::max(result.excess_max, gq);
    if (inside_run) {
      if (gq > gp) {  // going deeper while inside: stop here
        result.hit = true;
        result.u_outside = result.u_inside = u + p;
        return true;
      }
      if (gq > 0.0) {  // still inside at q
        gp = gq;
        continue;
      }
      // Leaves in (p, q]: find the exit (g decreasing), then outside up to q.
      while (q - p > u_tolerance) {
        const double m = 0.5 * (p + q);
        if (g(m) > 0.0) p = m; else q = m;
      }
      inside_run = false;
      gp = gq;
      continue;
    }
    if (gq > 0.0) {  // enters in (p, q]: g increases on the piece, g(p) <= 0
      // An entry within the tolerance of the piece's start stops there (a contact resting
      // within the tolerance and pushed in is blocked at once, as the paper's bisection
      // from the segment's start does); else bisect.
      if (q - p > u_tolerance && g(p + u_tolerance) > 0.0) q = p + u_tolerance;
      while (q - p > u_tolerance) {
        const double m = 0.5 * (p + q);
        if (g(m) > 0.0) q = m; else p = m;
      }
      result.hit = true;
      result.u_outside = u + p;
      result.u_inside = u + q;
      return true;
    }
    gp = gq;
  }
  return false;
}

}  // namespace

template <typename T>
SegmentEntry ScalarVolume::firstEntry(const Eigen::Vector3d& a, const Eigen::Vector3d& b, double threshold,
                                      double u_limit, double u_tolerance, bool at_segment_start,
                                      const SegmentBubble& bubble) const noexcept {
  SegmentEntry result;
  // Conservative answers where the walk cannot decide: stopped at u (never let through).
  const auto stopAt = [&result](double u) {
    result.hit = true;
    result.u_outside = result.u_inside = u;
    return result;
  };
  if (!a.allFinite() || !b.allFinite()) return stopAt(0.0);
  const Eigen::Vector3d d = b - a;
  // The box test: only the part of the segment in the grid's box of voxel centres is walked.
  double u_lo = 0.0, u_hi = 1.0;
  if (!clipToGrid(a, d, upper_, u_lo, u_hi)) return result;

  const T* data = reinterpret_cast<const T*>(bytes_.data());
  const std::ptrdiff_t sy = geometry_.dims[0], sz = sy * geometry_.dims[1];
  // The walk (a 3-D DDA) starts in the cell containing the clipped segment's start.
  int cell[3], step[3];
  double u_next[3], u_delta[3];
  startCellWalk(a, d, a + u_lo * d, geometry_.dims, cell, step, u_next, u_delta);
  // State along the walk: inside (entered before this point; only a start inside, leaving).
  bool inside_run = false;
  bool first = at_segment_start && u_lo == 0.0;  // the segment's own start: inside there may mean leaving
  double u = u_lo;
  const double sign = scale_ > 0.0 ? 1.0 : -1.0;
  // A segment crosses at most 3 cells per voxel of length (+ 3); past 2^20 cells (a segment
  // of some 350,000 voxels, never a servo tick's) the rest is not walked: stop there.
  for (int guard = 0;; ++guard) {
    if (guard == 1 << 20) return stopAt(u);
    if (u > u_limit && u > u_lo) break;
    ++result.cells_walked;
    const double u_exit = std::min({u_next[0], u_next[1], u_next[2], u_hi});
    const double w_end = std::max(0.0, u_exit - u);
    const CellCorners cc = loadCorners(data + cell[0] + sy * cell[1] + sz * cell[2], sy, sz);
    const double corner_max =
        sign > 0.0 ? std::max({cc.c000, cc.c100, cc.c010, cc.c110, cc.c001, cc.c101, cc.c011, cc.c111})
                   : std::min({cc.c000, cc.c100, cc.c010, cc.c110, cc.c001, cc.c101, cc.c011, cc.c111});
    // The bubble's height over this cell: the local Lipschitz bound (valid within a cell of
    // this one, where the arc is) times the sagitta.
    const double height = bubble.sagitta_m > 0.0
        ? static_cast<double>(tree_.brickLipschitz(cell[0], cell[1], cell[2])) * bubble.sagitta_m
        : 0.0;
    // A cell is skipped when the chord with its bubble stays below the threshold, or, for an
    // arc, when no voxel of this cell and the cells next to it (where the arc is) rises above
    // it: near a wild outlier (a -3e38 "no data" border) the Lipschitz bubble is huge while
    // the field itself stays low. (A corner above it decides at once: the cell is examined.)
    const double corner_bound = scale_ * corner_max + offset_;
    if (corner_bound + height <= threshold ||
        (height > 0.0 && corner_bound <= threshold && upperBoundInBox(Eigen::Vector3d(cell[0] - 1.0, cell[1] - 1.0, cell[2] - 1.0),
                                         Eigen::Vector3d(cell[0] + 2.0, cell[1] + 2.0, cell[2] + 2.0)) <= threshold)) {
      inside_run = false;  // the whole cell is outside
      result.excess_max = std::max(result.excess_max, corner_bound + height - threshold);
    } else {
      ++result.cells;
      const Cubic r = chordCubicInCell(cc, a, d, u, cell);
      // The bubble 4 h U (1 - U), U = U0 + D (u + w) the parameter of the whole chord.
      const double Uc = bubble.u0 + bubble.du * u, D = bubble.du, h4 = 4.0 * height;
      const Cubic g{scale_ * r.c0 + offset_ - threshold + h4 * Uc * (1.0 - Uc), scale_ * r.c1 + h4 * D * (1.0 - 2.0 * Uc),
                    scale_ * r.c2 - h4 * D * D, scale_ * r.c3};
      if (refineInCell(g, w_end, u, u_lo, u_tolerance, first, inside_run, result)) return result;
    }
    first = false;
    if (u_exit >= u_hi) break;
    // Step into the next cell along every axis whose face is reached here.
    u = u_exit;
    if (!stepToNextCell(u_exit, geometry_.dims, step, u_delta, cell, u_next)) break;
  }
  return result;
}

SegmentEntry ScalarVolume::walkSegment(const Eigen::Vector3d& a, const Eigen::Vector3d& b, double threshold,
                                       double u_limit, double u_tolerance, bool at_segment_start,
                                       const SegmentBubble& bubble) const noexcept {
  switch (type_) {
    case VoxelType::kUInt8: return firstEntry<std::uint8_t>(a, b, threshold, u_limit, u_tolerance, at_segment_start, bubble);
    case VoxelType::kInt16: return firstEntry<std::int16_t>(a, b, threshold, u_limit, u_tolerance, at_segment_start, bubble);
    case VoxelType::kUInt16: return firstEntry<std::uint16_t>(a, b, threshold, u_limit, u_tolerance, at_segment_start, bubble);
    case VoxelType::kFloat32: return firstEntry<float>(a, b, threshold, u_limit, u_tolerance, at_segment_start, bubble);
  }
  return {};
}

SegmentEntry ScalarVolume::firstEntryOnSegment(const Eigen::Vector3d& a_ijk, const Eigen::Vector3d& b_ijk,
                                               double threshold, double u_limit, double u_tolerance,
                                               const Eigen::Vector3d& reach_ijk, double arc_sagitta_m) const noexcept {
  if (!(reach_ijk.maxCoeff() > 0.0))
    return walkSegment(a_ijk, b_ijk, threshold, u_limit, u_tolerance, true, {arc_sagitta_m, 0.0, 1.0});
  // A point within reach of the segment may be in the grid's box while the segment is not:
  // walk the segment's projection onto the box (clamped per axis: a polyline in the box, one
  // piece between consecutive crossings of a box plane) where the segment is within reach of
  // the box. Projection onto the box is non-expansive and fixes points of the box, so a point of
  // the box within reach of the segment is within reach of the projection.
  const Eigen::Vector3d d = b_ijk - a_ijk;
  double u_lo = 0.0, u_hi = 1.0;
  double cuts[8];
  int n_cuts = 0;
  for (int axis = 0; axis < 3; ++axis) {
    const double lo = -reach_ijk[axis], hi = upper_[axis] + reach_ijk[axis];
    if (d[axis] == 0.0) {
      if (a_ijk[axis] < lo || a_ijk[axis] > hi) return {};
      continue;
    }
    double t0 = (lo - a_ijk[axis]) / d[axis], t1 = (hi - a_ijk[axis]) / d[axis];
    if (t0 > t1) std::swap(t0, t1);
    u_lo = std::max(u_lo, t0);
    u_hi = std::min(u_hi, t1);
    cuts[n_cuts++] = (0.0 - a_ijk[axis]) / d[axis];
    cuts[n_cuts++] = (upper_[axis] - a_ijk[axis]) / d[axis];
  }
  if (!(u_lo <= u_hi)) return {};
  double breaks[8];
  int nb = 0;
  breaks[nb++] = u_lo;
  for (int i = 0; i < n_cuts; ++i)
    if (cuts[i] > u_lo && cuts[i] < u_hi) breaks[nb++] = cuts[i];
  std::sort(breaks + 1, breaks + nb);
  breaks[nb++] = u_hi;
  SegmentEntry result;
  for (int i = 0; i + 1 < nb; ++i) {
    const double p = breaks[i], q = breaks[i + 1];
    if (p > u_limit) break;
    if (!(q > p)) continue;
    const Eigen::Vector3d pa = (a_ijk + p * d).cwiseMax(Eigen::Vector3d::Zero()).cwiseMin(upper_);
    const Eigen::Vector3d pb = (a_ijk + q * d).cwiseMax(Eigen::Vector3d::Zero()).cwiseMin(upper_);
    const double span = q - p;
    const SegmentEntry e = walkSegment(pa, pb, threshold, (u_limit - p) / span, u_tolerance / span, p == 0.0,
                                       {arc_sagitta_m, p, span});
    result.cells += e.cells;
    result.cells_walked += e.cells_walked;
    result.excess_max = std::max(result.excess_max, e.excess_max);
    if (e.hit) {
      result.hit = true;
      result.u_outside = p + e.u_outside * span;
      result.u_inside = p + e.u_inside * span;
      // An entry at the start of a later piece: the piece before was outside up to p.
      return result;
    }
  }
  return result;
}

}  // namespace vh::haptics
