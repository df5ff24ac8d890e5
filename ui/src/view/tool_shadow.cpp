#include "vh/ui/view/tool_shadow.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace vh::ui {

ToolShadow castToolShadow(const haptics::ScalarVolume& field, double isovalue, const haptics::Pose& X_WP,
                          std::span<const Eigen::Vector3d> samples_T_m, const Eigen::Vector3d& direction_W,
                          std::optional<double> reach) {
  ToolShadow shadow;
  const haptics::VolumeGeometry& g = field.geometry();
  const double reach_m = reach.value_or(
      Eigen::Vector3d(g.dims[0] * g.spacing_m[0], g.dims[1] * g.spacing_m[1], g.dims[2] * g.spacing_m[2]).norm());
  const double length = direction_W.norm();
  if (field.empty() || !(length > 0.0) || !std::isfinite(length) || !(reach_m > 0.0) || !std::isfinite(isovalue)) {
    return shadow;
  }
  const Eigen::Vector3d d_W = direction_W / length;
  // The bracket's width along the ray: a twentieth of a voxel.
  const double u_tolerance = std::max(0.05 * g.minSpacing() / reach_m, 1e-9);
  shadow.footprint_W_m.reserve(samples_T_m.size());
  double best = std::numeric_limits<double>::infinity();
  for (const Eigen::Vector3d& p_T : samples_T_m) {
    const Eigen::Vector3d a_W = X_WP * p_T;
    if (!a_W.allFinite() || field.isInside(a_W, isovalue)) continue;
    const Eigen::Vector3d b_W = a_W + reach_m * d_W;
    const haptics::SegmentEntry entry = field.firstEntryOnSegment(field.gridCoordinates(a_W), field.gridCoordinates(b_W),
                                                                 isovalue, 1.0, u_tolerance);
    if (!entry.hit) continue;
    const Eigen::Vector3d hit_W = a_W + entry.u_outside * reach_m * d_W;
    shadow.footprint_W_m.push_back(hit_W);
    const double gap = entry.u_outside * reach_m;
    if (gap < best) {
      best = gap;
      shadow.has_gap = true;
      shadow.gap_from_W_m = a_W;
      shadow.gap_to_W_m = hit_W;
      shadow.gap_m = gap;
    }
  }
  return shadow;
}

std::vector<Eigen::Vector3d> toolShadowSamples(const haptics::ToolModel& tool) {
  return shadowSamples(tool.point_shell.empty() ? tool.mesh_T.vertices_T_m : tool.point_shell.points_T_m(),
                       kShadowSamples);
}

Eigen::Vector3d shadowLightDirection_W(const ViewCamera& camera) {
  return (-camera.up_W() + 0.5 * camera.right_W() + 0.5 * camera.forward_W()).normalized();
}

std::vector<Eigen::Vector3d> shadowSamples(std::span<const Eigen::Vector3d> vertices_T_m, int count) {
  if (count <= 0 || vertices_T_m.empty()) return {};
  if (vertices_T_m.size() <= static_cast<std::size_t>(count)) {
    return {vertices_T_m.begin(), vertices_T_m.end()};
  }
  std::vector<Eigen::Vector3d> samples;
  samples.reserve(static_cast<std::size_t>(count));
  // Squared distance from each vertex to the samples taken so far.
  std::vector<double> distance2(vertices_T_m.size(), std::numeric_limits<double>::infinity());
  std::size_t next = 0;
  for (int s = 0; s < count; ++s) {
    samples.push_back(vertices_T_m[next]);
    std::size_t farthest = 0;
    double farthest_d2 = -1.0;
    for (std::size_t i = 0; i < vertices_T_m.size(); ++i) {
      distance2[i] = std::min(distance2[i], (vertices_T_m[i] - vertices_T_m[next]).squaredNorm());
      if (distance2[i] > farthest_d2) {
        farthest_d2 = distance2[i];
        farthest = i;
      }
    }
    if (farthest_d2 <= 0.0) break;  // every vertex is a sample already (duplicates)
    next = farthest;
  }
  return samples;
}

}  // namespace vh::ui
