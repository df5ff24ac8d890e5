#include "vh/haptics/penetration.h"

#include <algorithm>

namespace vh::haptics {

double maxPenetration_m(const ScalarVolume& volume, const PointShell& shell, const Pose& X_WT, double isovalue,
                        int* deepest_point) noexcept {
  const double voxel_diagonal_m = volume.geometry().spacing_m.norm();
  double deepest = 0.0;
  int deepest_index = -1;
  const auto& points = shell.points_T_m();
  for (std::size_t i = 0; i < points.size(); ++i) {
    const Eigen::Vector3d p_W = X_WT * points[i];
    if (!volume.isInside(p_W, isovalue)) continue;
    const double grad_norm = volume.gradient(p_W).norm();
    const double depth = grad_norm > 1e-12 ? (volume.sample(p_W) - isovalue) / grad_norm : voxel_diagonal_m;
    if (depth > deepest || deepest_index < 0) {
      deepest = std::max(deepest, depth);
      deepest_index = static_cast<int>(i);
    }
  }
  if (deepest_point != nullptr) *deepest_point = deepest_index;
  return deepest;
}

}  // namespace vh::haptics
