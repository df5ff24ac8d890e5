#include "vh/haptics/crossing_verifier.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace vh::haptics {

CrossingVerifier::CrossingVerifier(const ScalarVolume& volume, const PointShell& shell, double step_voxels)
    : volume_(&volume), shell_(&shell) {
  if (!(step_voxels > 0.0) || !std::isfinite(step_voxels))
    throw std::invalid_argument("CrossingVerifier: step " + std::to_string(step_voxels) + " voxels must be finite and > 0");
  if (volume.empty()) throw std::invalid_argument("CrossingVerifier: the volume is empty");
  step_m_ = step_voxels * volume.geometry().minSpacing();
  const auto& dims = volume.geometry().dims;
  for (int a = 0; a < 3; ++a) blocks_[a] = (dims[a] - 2) / kBlock + 1;  // cells 0 .. n - 2
  block_max_.assign(static_cast<std::size_t>(blocks_[0]) * blocks_[1] * blocks_[2],
                    -std::numeric_limits<double>::infinity());
  // Brute force: every voxel raises the maximum of each block whose cells use it (a voxel on a
  // block's upper border belongs to two blocks along that axis).
  for (int k = 0; k < dims[2]; ++k)
    for (int j = 0; j < dims[1]; ++j)
      for (int i = 0; i < dims[0]; ++i) {
        const double v = volume.voxel(i, j, k);
        const int idx[3] = {i, j, k};
        int lo[3], hi[3];
        for (int a = 0; a < 3; ++a) {
          hi[a] = std::min(idx[a] / kBlock, blocks_[a] - 1);
          lo[a] = idx[a] % kBlock == 0 && idx[a] > 0 ? std::min(idx[a] / kBlock - 1, blocks_[a] - 1) : hi[a];
        }
        for (int c = lo[2]; c <= hi[2]; ++c)
          for (int b = lo[1]; b <= hi[1]; ++b)
            for (int a = lo[0]; a <= hi[0]; ++a) {
              double& m = block_max_[a + static_cast<std::size_t>(blocks_[0]) * (b + static_cast<std::size_t>(blocks_[1]) * c)];
              m = std::max(m, v);
            }
      }
}

bool CrossingVerifier::ballMayBeInside(const Eigen::Vector3d& centre_W_m, double radius_m, double isovalue) const {
  const auto& geometry = volume_->geometry();
  const Eigen::Vector3d g = volume_->gridCoordinates(centre_W_m);
  int lo[3], hi[3];
  for (int a = 0; a < 3; ++a) {
    const double r = radius_m / geometry.spacing_m[a] + 1e-6;
    const double upper = geometry.dims[a] - 1.0;
    if (g[a] + r < 0.0 || g[a] - r > upper) return false;  // out of bounds is never inside
    lo[a] = std::clamp(static_cast<int>(std::floor(std::max(0.0, g[a] - r))) / kBlock, 0, blocks_[a] - 1);
    hi[a] = std::clamp(static_cast<int>(std::floor(std::min(upper, g[a] + r))) / kBlock, 0, blocks_[a] - 1);
    // A point on a block's lower face may belong to the block below (its upper border).
    lo[a] = std::max(0, lo[a] - 1);
  }
  for (int c = lo[2]; c <= hi[2]; ++c)
    for (int b = lo[1]; b <= hi[1]; ++b)
      for (int a = lo[0]; a <= hi[0]; ++a)
        if (block_max_[a + static_cast<std::size_t>(blocks_[0]) * (b + static_cast<std::size_t>(blocks_[1]) * c)] > isovalue)
          return true;
  return false;
}

CrossingVerifier::Result CrossingVerifier::check(const RigidMotion& motion, double t_stop, double isovalue) const {
  Result result;
  if (!(t_stop > 0.0) || motion.isStill()) return result;
  const auto& points = shell_->points_T_m();
  const double piece_m = kBlock * volume_->geometry().minSpacing();
  for (std::size_t j = 0; j < points.size(); ++j) {
    const Eigen::Vector3d r0 = motion.radial_W(points[j]);
    // Its own (the paper's, looser) path-length bound, |v| + |omega| |r0|.
    const double path = (motion.v_W_m().norm() + motion.omega_W_rad().norm() * r0.norm()) * t_stop;
    // Samples t_i = t_stop i / n; the path is cut into pieces of at most 8 voxels, each skipped
    // when its ball (radius half its path-length bound) holds no block above the isovalue.
    const double n = std::max(1.0, std::ceil(path / step_m_));
    const double pieces = std::max(1.0, std::ceil(path / piece_m));
    bool start_checked = false;
    for (double k = 0.0; k < pieces; k += 1.0) {
      const double ta = t_stop * (k / pieces), tb = t_stop * ((k + 1.0) / pieces);
      if (!ballMayBeInside(motion.pointAt(r0, 0.5 * (ta + tb)), 0.5 * path / pieces * (1.0 + 1e-9) + 1e-12, isovalue))
        continue;
      if (!start_checked) {
        start_checked = true;
        if (k == 0.0) {
          ++result.samples;
          if (volume_->isInside(motion.pointAt(r0, 0.0), isovalue)) {
            ++result.started_inside;
            break;
          }
        }
      }
      bool crossed = false;
      for (double i = std::max(1.0, std::ceil(n * k / pieces)); i <= n && i <= std::floor(n * (k + 1.0) / pieces) + 1.0; i += 1.0) {
        const double t = t_stop * (i / n);
        ++result.samples;
        if (volume_->isInside(motion.pointAt(r0, t), isovalue)) {
          if (result.crossing_points++ == 0) {
            result.first_point = static_cast<int>(j);
            result.first_t = t;
          }
          crossed = true;
          break;
        }
      }
      if (crossed) break;
    }
  }
  return result;
}

CrossingVerifier::EdgeResult CrossingVerifier::checkEdges(const RigidMotion& motion, double t_stop, double isovalue,
                                                          const ShellEdges& edges, double inset_m,
                                                          int time_samples, double along_step_m) const {
  const auto& points = shell_->points_T_m();
  if (edges.offsets.size() != points.size() + 1 && !(edges.offsets.empty() && points.empty()))
    throw std::invalid_argument("CrossingVerifier::checkEdges: the edges belong to a shell of " +
                                std::to_string(edges.offsets.size() - 1) + " points, not " + std::to_string(points.size()));
  if (time_samples < 1) throw std::invalid_argument("CrossingVerifier::checkEdges: time_samples must be >= 1");
  EdgeResult result;
  if (!(t_stop > 0.0) || motion.isStill() || edges.size() == 0) return result;
  const bool normals = shell_->hasNormals();
  const double step = along_step_m > 0.0 ? along_step_m : step_m_;
  const auto end_T = [&](int i) {
    return normals ? Eigen::Vector3d(points[i] - inset_m * shell_->normals_T()[i]) : points[i];
  };
  // Whether the edge a-b (in T) has an inside sample at time t.
  const auto edgeInside = [&](const Eigen::Vector3d& a_T, const Eigen::Vector3d& b_T, double t) {
    const Pose X = motion.poseAt(t);
    const Eigen::Vector3d a = X * a_T, b = X * b_T;
    const double length = (b - a).norm();
    const double n = std::max(1.0, std::ceil(length / step));
    for (double i = 0.0; i <= n; i += 1.0) {
      // Within inset_m of an end the surface is as close to that end's point as a contact
      // point's own tolerance allows (an inset end just inside a surface its point touches).
      const double along = (i / n) * length;
      if (along < inset_m || length - along < inset_m) continue;
      ++result.samples;
      if (volume_->isInside(a + (i / n) * (b - a), isovalue)) return true;
    }
    return false;
  };
  for (int j = 0; j + 1 < static_cast<int>(edges.offsets.size()); ++j) {
    const Eigen::Vector3d a_T = end_T(j);
    for (int e = edges.offsets[j]; e < edges.offsets[j + 1]; ++e) {
      const int k = edges.targets[e];
      const Eigen::Vector3d b_T = end_T(k);
      // The edge's ball over the whole move: its midpoint's path-length bound plus half its length.
      const Eigen::Vector3d mid_T = 0.5 * (a_T + b_T);
      const Eigen::Vector3d r0 = motion.radial_W(mid_T);
      const double path = (motion.v_W_m().norm() + motion.omega_W_rad().norm() * r0.norm()) * t_stop;
      const double radius = 0.5 * path + 0.5 * (b_T - a_T).norm();
      if (!ballMayBeInside(motion.pointAt(r0, 0.5 * t_stop), radius * (1.0 + 1e-9) + 1e-12, isovalue)) continue;
      if (edgeInside(a_T, b_T, 0.0)) {
        ++result.started_inside;
        continue;
      }
      for (int i = 1; i <= time_samples; ++i) {
        const double t = t_stop * i / time_samples;
        if (edgeInside(a_T, b_T, t)) {
          if (result.crossing_edges++ == 0 || t < result.first_t) {
            result.first_j = j;
            result.first_k = k;
            result.first_t = t;
          }
          break;
        }
      }
    }
  }
  return result;
}

}  // namespace vh::haptics
