// Exact Euclidean distance transform and the point shell's proximity query (distance_field.h).
#include "vh/haptics/distance_field.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace vh::haptics {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

void checkGeometry(const VolumeGeometry& g, std::size_t mask_size, double margin_m) {
  for (int a = 0; a < 3; ++a) {
    if (g.dims[static_cast<std::size_t>(a)] < 1) throw std::invalid_argument("DistanceField: dims must be >= 1");
    if (!std::isfinite(g.spacing_m[a]) || g.spacing_m[a] <= 0.0)
      throw std::invalid_argument("DistanceField: voxel spacing must be finite and > 0");
  }
  if (!g.origin_W_m.allFinite() || !g.direction_W.allFinite())
    throw std::invalid_argument("DistanceField: origin or direction not finite");
  if (!(g.direction_W.transpose() * g.direction_W).isIdentity(1e-6))
    throw std::invalid_argument("DistanceField: direction matrix is not orthonormal");
  if (mask_size != g.voxelCount())
    throw std::invalid_argument("DistanceField: mask of " + std::to_string(mask_size) + " voxels, expected " +
                                std::to_string(g.voxelCount()));
  if (!std::isfinite(margin_m) || margin_m < 0.0)
    throw std::invalid_argument("DistanceField: margin must be finite and >= 0 (got " + std::to_string(margin_m) + ")");
}

/// One line of the separable transform (Felzenszwalb and Huttenlocher 2012, algorithm DT(f)):
/// d[x] = min_q ((x - q) h)^2 + f[q] over the finite f[q]; +infinity when there is none.
/// v, z: scratch of n and n + 1 entries.
void transformLine(const double* f, double* d, int n, double h, int* v, double* z) {
  int k = -1;
  const double h2 = h * h;
  auto cross = [&](int q, int p) {  // where the parabolas of q and p meet (q > p), in index units
    return ((f[q] + h2 * q * q) - (f[p] + h2 * p * p)) / (2.0 * h2 * (q - p));
  };
  for (int q = 0; q < n; ++q) {
    if (!std::isfinite(f[q])) continue;
    if (k < 0) {
      k = 0;
      v[0] = q;
      z[0] = -kInf;
      z[1] = kInf;
      continue;
    }
    double s = cross(q, v[k]);
    while (s <= z[k]) s = cross(q, v[--k]);  // z[0] = -inf stops it at k = 0
    ++k;
    v[k] = q;
    z[k] = s;
    z[k + 1] = kInf;
  }
  if (k < 0) {
    std::fill(d, d + n, kInf);
    return;
  }
  k = 0;
  for (int x = 0; x < n; ++x) {
    while (z[k + 1] < x) ++k;
    const double t = (x - v[k]) * h;
    d[x] = t * t + f[v[k]];
  }
}

/// Runs transformLine() along `axis` of the box grid `g` (sizes n, x fastest), in place.
void transformAxis(std::vector<double>& g, const std::array<int, 3>& n, int axis, double h) {
  const auto a = static_cast<std::size_t>(axis);
  const std::size_t stride = axis == 0 ? 1 : axis == 1 ? static_cast<std::size_t>(n[0])
                                                       : static_cast<std::size_t>(n[0]) * static_cast<std::size_t>(n[1]);
  const int len = n[a];
  std::vector<double> f(static_cast<std::size_t>(len)), d(static_cast<std::size_t>(len)),
      z(static_cast<std::size_t>(len) + 1);
  std::vector<int> v(static_cast<std::size_t>(len));
  const std::size_t lines = g.size() / static_cast<std::size_t>(len);
  for (std::size_t line = 0; line < lines; ++line) {
    // The line's first voxel: `line` enumerates the other two axes, x fastest.
    std::size_t base = 0;
    if (axis == 0) {
      base = line * static_cast<std::size_t>(n[0]);
    } else if (axis == 1) {
      base = (line % static_cast<std::size_t>(n[0])) + (line / static_cast<std::size_t>(n[0])) * stride * static_cast<std::size_t>(len);
    } else {
      base = line;
    }
    for (int x = 0; x < len; ++x) f[static_cast<std::size_t>(x)] = g[base + static_cast<std::size_t>(x) * stride];
    transformLine(f.data(), d.data(), len, h, v.data(), z.data());
    for (int x = 0; x < len; ++x) g[base + static_cast<std::size_t>(x) * stride] = d[static_cast<std::size_t>(x)];
  }
}

}  // namespace

DistanceField DistanceField::FromMask(const VolumeGeometry& geometry, std::span<const std::uint8_t> mask,
                                      double margin_m) {
  checkGeometry(geometry, mask.size(), margin_m);
  DistanceField out;
  out.geometry_ = geometry;
  out.W_to_I_ = geometry.spacing_m.cwiseInverse().asDiagonal() * geometry.direction_W.transpose();
  std::array<int, 3> bb_lo{geometry.dims[0], geometry.dims[1], geometry.dims[2]}, bb_hi{-1, -1, -1};
  for (std::size_t idx = 0; idx < mask.size(); ++idx) {
    if (mask[idx] == 0) continue;
    ++out.mask_voxels_;
    const auto ijk = geometry.voxelOf(idx);
    for (std::size_t a = 0; a < 3; ++a) {
      bb_lo[a] = std::min(bb_lo[a], ijk[a]);
      bb_hi[a] = std::max(bb_hi[a], ijk[a]);
    }
  }
  if (out.mask_voxels_ == 0) return out;
  for (std::size_t a = 0; a < 3; ++a) {
    const double m = std::ceil(margin_m / geometry.spacing_m[static_cast<Eigen::Index>(a)]);
    const int grow = static_cast<int>(std::min(m, static_cast<double>(geometry.dims[a])));
    out.lo_[a] = std::max(0, bb_lo[a] - grow);
    out.hi_[a] = std::min(geometry.dims[a] - 1, bb_hi[a] + grow);
    out.n_[a] = out.hi_[a] - out.lo_[a] + 1;
  }
  const auto& n = out.n_;
  std::vector<double> g(static_cast<std::size_t>(n[0]) * static_cast<std::size_t>(n[1]) * static_cast<std::size_t>(n[2]));
  std::size_t b = 0;
  for (int k = 0; k < n[2]; ++k)
    for (int j = 0; j < n[1]; ++j)
      for (int i = 0; i < n[0]; ++i, ++b)
        g[b] = mask[geometry.indexOf(i + out.lo_[0], j + out.lo_[1], k + out.lo_[2])] != 0 ? 0.0 : kInf;
  for (int axis = 0; axis < 3; ++axis) transformAxis(g, n, axis, geometry.spacing_m[axis]);
  for (double& x : g) x = std::sqrt(x);
  out.distance_m_ = std::move(g);
  return out;
}

double DistanceField::voxelDistance_m(int i, int j, int k) const noexcept {
  if (distance_m_.empty()) return kInf;
  const auto b = static_cast<std::size_t>(i - lo_[0]) +
                 static_cast<std::size_t>(n_[0]) *
                     (static_cast<std::size_t>(j - lo_[1]) + static_cast<std::size_t>(n_[1]) * static_cast<std::size_t>(k - lo_[2]));
  return distance_m_[b];
}

double DistanceField::sample_m(const Eigen::Vector3d& p_W_m) const noexcept {
  if (distance_m_.empty() || !p_W_m.allFinite()) return kInf;
  const Eigen::Vector3d u = W_to_I_ * (p_W_m - geometry_.origin_W_m);
  double outside2 = 0.0;  // squared distance from p to the stored box [m^2]
  std::array<int, 3> i0{};
  std::array<double, 3> t{};
  const std::array<std::size_t, 3> stride{1, static_cast<std::size_t>(n_[0]),
                                          static_cast<std::size_t>(n_[0]) * static_cast<std::size_t>(n_[1])};
  std::array<std::size_t, 3> step = stride;  // to the cell's far corner along each axis
  std::size_t base = 0;
  for (std::size_t a = 0; a < 3; ++a) {
    const auto ea = static_cast<Eigen::Index>(a);
    const double x = u[ea] - lo_[a];
    const double xc = std::clamp(x, 0.0, static_cast<double>(n_[a] - 1));
    const double off = (x - xc) * geometry_.spacing_m[ea];
    outside2 += off * off;
    i0[a] = std::min(static_cast<int>(xc), std::max(0, n_[a] - 2));
    t[a] = xc - i0[a];
    if (n_[a] == 1) step[a] = 0;  // a one-voxel axis: both corners are the same voxel
    base += static_cast<std::size_t>(i0[a]) * stride[a];
  }
  const double* d = distance_m_.data() + base;
  auto lerp = [](double a, double b, double s) { return a + s * (b - a); };
  const std::size_t sx = step[0], sy = step[1], sz = step[2];
  const double c00 = lerp(d[0], d[sx], t[0]), c10 = lerp(d[sy], d[sy + sx], t[0]);
  const double c01 = lerp(d[sz], d[sz + sx], t[0]), c11 = lerp(d[sz + sy], d[sz + sy + sx], t[0]);
  const double inside = lerp(lerp(c00, c10, t[1]), lerp(c01, c11, t[1]), t[2]);
  return outside2 > 0.0 ? std::sqrt(outside2 + inside * inside) : inside;
}

std::vector<double> bruteForceSquaredDistances_m2(const VolumeGeometry& geometry, std::span<const std::uint8_t> mask) {
  checkGeometry(geometry, mask.size(), 0.0);
  std::vector<std::array<int, 3>> in;
  for (std::size_t idx = 0; idx < mask.size(); ++idx)
    if (mask[idx] != 0) in.push_back(geometry.voxelOf(idx));
  std::vector<double> out(mask.size(), kInf);
  const Eigen::Vector3d& h = geometry.spacing_m;
  for (std::size_t idx = 0; idx < mask.size(); ++idx) {
    const auto p = geometry.voxelOf(idx);
    for (const auto& q : in) {
      const double dx = (p[0] - q[0]) * h.x(), dy = (p[1] - q[1]) * h.y(), dz = (p[2] - q[2]) * h.z();
      out[idx] = std::min(out[idx], dz * dz + (dy * dy + dx * dx));
    }
  }
  return out;
}

}  // namespace vh::haptics
