// Embedded points (haptics/README.md, "Isovalue changes"): the points inside the isosurface
// when the isovalue changed or the proxy was reset do not constrain the proxy until they are
// outside again; and the largest field over the shell, below which a lowered isovalue stops.
#include "collision_detector_impl.h"

#include <algorithm>

#include "shell_tree.h"

namespace vh::haptics {

double CollisionDetector::Impl::maxFieldOnShell(const Pose& X_WP, double floor) noexcept {
  const auto& points = tool_->point_shell.points_T_m();
  double m = floor;
  const auto visit = [&](int j) {
    if (embedded_[j]) return;
    ++counters_.samples;
    const Eigen::Vector3d p = X_WP * points[j];
    if (!volume_->inBounds(p)) return;  // out of the grid is never inside, at any isovalue
    m = std::max(m, volume_->sample(p));
  };
  if (mode_ == DetectionMode::kAccelerated) {
    // A node whose ball lies in bricks whose values stay <= m cannot raise m.
    walkShellTree(
        stack_.data(), 0,
        [&](const ShellNode& node) {
          return ballMayBeInside(counters_, X_WP * node.center_T_m, node.radius_m * (1.0 + 1e-9) + 1e-12, m);
        },
        [&](int j) {
          visit(j);
          return false;
        });
  } else {
    for (std::size_t j = 0; j < points.size(); ++j) visit(static_cast<int>(j));
  }
  return m;
}

int CollisionDetector::Impl::updateEmbedded(const Pose& X_WP, double isovalue) noexcept {
  const auto& points = tool_->point_shell.points_T_m();
  embedded_count_ = 0;
  if (mode_ == DetectionMode::kAccelerated) {
    // The point-shell tree at the pose X_WP: a node whose ball lies in bricks that cannot hold
    // an inside point has no embedded point (its points are cleared as it is skipped); the test
    // of each point is the paper's.
    walkShellTree(
        stack_.data(), 0,
        [&](const ShellNode& node) {
          if (ballMayBeInside(counters_, X_WP * node.center_T_m, node.radius_m * (1.0 + 1e-9) + 1e-12, isovalue))
            return true;
          for (int i = node.begin; i < node.end; ++i) embedded_[order_[i]] = 0;
          return false;
        },
        [&](int j) {
          embedded_[j] = inside(X_WP * points[j], isovalue) ? 1 : 0;
          embedded_count_ += embedded_[j];
          return false;
        });
  } else {
    for (std::size_t j = 0; j < points.size(); ++j) {
      embedded_[j] = inside(X_WP * points[j], isovalue) ? 1 : 0;
      embedded_count_ += embedded_[j];
    }
  }
  if (embedded_count_ > 0) {  // embedded points leave the contact set
    std::size_t kept = 0;
    for (std::size_t i = 0; i < contact_count_; ++i) {
      const int j = contacts_[i].point_index;
      if (j >= 0 && embedded_[j]) in_set_[j] = 0;
      else contacts_[kept++] = contacts_[i];
    }
    contact_count_ = kept;
  }
  return embedded_count_;
}

int CollisionDetector::Impl::releaseEmbedded(const Pose& X_WP, double isovalue) noexcept {
  if (embedded_count_ == 0) return 0;
  const auto& points = tool_->point_shell.points_T_m();
  for (std::size_t j = 0; j < points.size(); ++j)
    if (embedded_[j] && !inside(X_WP * points[j], isovalue)) {
      embedded_[j] = 0;
      --embedded_count_;
    }
  return embedded_count_;
}

}  // namespace vh::haptics
