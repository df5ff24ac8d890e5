#include "vh/ui/view/tool_shadow.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>

namespace vh::ui {

namespace {

/// castToolShadow()'s loop over the samples; `inside(a_W)` and `entry(a_W, b_W, u_tolerance)`
/// answer on the field (u: the parameter of a -> b where the ray is still outside, or nullopt).
template <typename Inside, typename Entry>
ToolShadow castSamples(const haptics::ScalarVolume& field, double isovalue, const haptics::Pose& X_WP,
                       std::span<const Eigen::Vector3d> samples_T_m, const Eigen::Vector3d& direction_W,
                       std::optional<double> reach, Inside inside, Entry entry) {
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
    if (!a_W.allFinite() || inside(a_W)) continue;
    const Eigen::Vector3d b_W = a_W + reach_m * d_W;
    const std::optional<double> u_outside = entry(a_W, b_W, u_tolerance);
    if (!u_outside) continue;
    const Eigen::Vector3d hit_W = a_W + *u_outside * reach_m * d_W;
    shadow.footprint_W_m.push_back(hit_W);
    const double gap = *u_outside * reach_m;
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

/// The first entry of a -> b [W] into {F > isovalue} of `field` on the part [u0, u1] of it, in
/// the parameter of the whole segment (bracket u_tolerance of the whole).
std::optional<double> entryOnPiece(const haptics::ScalarVolume& field, const Eigen::Vector3d& a_W,
                                   const Eigen::Vector3d& b_W, double u0, double u1, double isovalue,
                                   double u_tolerance) {
  if (!(u1 > u0)) return std::nullopt;
  const haptics::SegmentEntry e =
      field.firstEntryOnSegment(field.gridCoordinates(a_W + u0 * (b_W - a_W)), field.gridCoordinates(a_W + u1 * (b_W - a_W)),
                                isovalue, 1.0, std::max(u_tolerance / (u1 - u0), 1e-12));
  if (!e.hit) return std::nullopt;
  return u0 + e.u_outside * (u1 - u0);
}

/// The parameter interval of a -> b (grid coordinates of `box`) inside its box of voxel
/// centres, or an empty one (u0 > u1).
std::pair<double, double> clipToBox(const haptics::ScalarVolume& box, const Eigen::Vector3d& a_ijk,
                                    const Eigen::Vector3d& b_ijk) {
  double u0 = 0.0, u1 = 1.0;
  for (int axis = 0; axis < 3; ++axis) {
    const double hi = box.geometry().dims[static_cast<std::size_t>(axis)] - 1.0;
    const double a = a_ijk[axis], d = b_ijk[axis] - a_ijk[axis];
    if (d == 0.0) {
      if (a < 0.0 || a > hi) return {1.0, 0.0};
      continue;
    }
    double t0 = (0.0 - a) / d, t1 = (hi - a) / d;
    if (t0 > t1) std::swap(t0, t1);
    u0 = std::max(u0, t0);
    u1 = std::min(u1, t1);
  }
  return {u0, u1};
}

}  // namespace

ToolShadow castToolShadow(const haptics::ScalarVolume& field, double isovalue, const haptics::Pose& X_WP,
                          std::span<const Eigen::Vector3d> samples_T_m, const Eigen::Vector3d& direction_W,
                          std::optional<double> reach) {
  return castSamples(
      field, isovalue, X_WP, samples_T_m, direction_W, reach,
      [&](const Eigen::Vector3d& a_W) { return field.isInside(a_W, isovalue); },
      [&](const Eigen::Vector3d& a_W, const Eigen::Vector3d& b_W, double u_tolerance) {
        return entryOnPiece(field, a_W, b_W, 0.0, 1.0, isovalue, u_tolerance);
      });
}

ToolShadow castToolShadow(const haptics::ScalarVolume& field, const CarvedRegion& carved, double isovalue,
                          const haptics::Pose& X_WP, std::span<const Eigen::Vector3d> samples_T_m,
                          const Eigen::Vector3d& direction_W, std::optional<double> reach) {
  const haptics::ScalarVolume* box = carved.box();
  if (box == nullptr || carved.field().get() != &field) {
    return castToolShadow(field, isovalue, X_WP, samples_T_m, direction_W, reach);
  }
  // The box holds every cell a removed voxel reaches; outside it the field is as loaded. A ray is
  // walked on the field up to the box, on the box across it, on the field after it: on the box's
  // faces both agree (no removed voxel reaches them).
  return castSamples(
      field, isovalue, X_WP, samples_T_m, direction_W, reach,
      [&](const Eigen::Vector3d& a_W) {
        return box->inBounds(a_W) ? box->isInside(a_W, isovalue) : field.isInside(a_W, isovalue);
      },
      [&](const Eigen::Vector3d& a_W, const Eigen::Vector3d& b_W, double u_tolerance) -> std::optional<double> {
        const auto [u0, u1] = clipToBox(*box, box->gridCoordinates(a_W), box->gridCoordinates(b_W));
        if (!(u1 > u0)) return entryOnPiece(field, a_W, b_W, 0.0, 1.0, isovalue, u_tolerance);
        if (auto u = entryOnPiece(field, a_W, b_W, 0.0, u0, isovalue, u_tolerance)) return u;
        if (auto u = entryOnPiece(*box, a_W, b_W, u0, u1, isovalue, u_tolerance)) return u;
        return entryOnPiece(field, a_W, b_W, u1, 1.0, isovalue, u_tolerance);
      });
}

void CarvedRegion::clear() {
  field_.reset();
  removed_.clear();
  box_.reset();
  lo_ = {0, 0, 0};
  hi_ = {-1, -1, -1};
  ++version_;
}

void CarvedRegion::reset(std::shared_ptr<const haptics::ScalarVolume> field, std::span<const std::uint64_t> removed) {
  clear();
  field_ = std::move(field);
  remove(removed);
}

void CarvedRegion::remove(std::span<const std::uint64_t> removed) {
  if (field_ == nullptr || field_->empty() || removed.empty()) return;
  const auto& g = field_->geometry();
  std::array<int, 3> lo = lo_, hi = hi_;
  const bool had_box = box_ != nullptr;
  const std::size_t first_new = removed_.size();
  for (const std::uint64_t index : removed) {
    if (index >= g.voxelCount()) continue;
    removed_.push_back(index);
    const std::array<int, 3> ijk = g.voxelOf(index);
    for (std::size_t a = 0; a < 3; ++a) {
      // One voxel around it: the cells it is a corner of.
      const int l = std::max(ijk[a] - 1, 0), h = std::min(ijk[a] + 1, g.dims[a] - 1);
      if (hi[a] < lo[a]) {
        lo[a] = l;
        hi[a] = h;
      } else {
        lo[a] = std::min(lo[a], l);
        hi[a] = std::max(hi[a], h);
      }
    }
  }
  if (removed_.size() == first_new) return;
  ++version_;
  if (!had_box || lo != lo_ || hi != hi_) {
    // Grown: 8 voxels to spare on every side, so that a burr working outwards copies the box
    // again every few voxels, not at every drain.
    constexpr int kSpare = 8;
    for (std::size_t a = 0; a < 3; ++a) {
      lo_[a] = std::max(lo[a] - kSpare, 0);
      hi_[a] = std::min(hi[a] + kSpare, g.dims[a] - 1);
    }
    rebuild();
    return;
  }
  // The box already holds them: write the new ones and refresh their bricks.
  const std::array<int, 3>& dims = box_->geometry().dims;
  std::array<int, 3> rlo = dims, rhi{-1, -1, -1};
  for (std::size_t n = first_new; n < removed_.size(); ++n) {
    const std::array<int, 3> b = carveInBox(removed_[n]);
    for (std::size_t a = 0; a < 3; ++a) {
      rlo[a] = std::min(rlo[a], b[a]);
      rhi[a] = std::max(rhi[a], b[a]);
    }
  }
  box_->refreshRegion(rlo, rhi);
}

std::array<int, 3> CarvedRegion::carveInBox(std::uint64_t index) {
  const std::array<int, 3> ijk = field_->geometry().voxelOf(index);
  const std::array<int, 3> b{ijk[0] - lo_[0], ijk[1] - lo_[1], ijk[2] - lo_[2]};
  box_->writeRaw(static_cast<std::size_t>(box_->geometry().indexOf(b[0], b[1], b[2])), field_->lowestRaw());
  return b;
}

void CarvedRegion::rebuild() {
  // At least two voxels on every axis (a volume needs them): the field has them, and the box
  // spans one voxel each side of every removed voxel.
  const auto& g = field_->geometry();
  haptics::VolumeGeometry bg = g;
  bg.dims = {hi_[0] - lo_[0] + 1, hi_[1] - lo_[1] + 1, hi_[2] - lo_[2] + 1};
  bg.origin_W_m = g.pointOf_W(Eigen::Vector3d(lo_[0], lo_[1], lo_[2]));
  // The box's raw voxels, copied row by row from the field's (the same type, scale and offset:
  // its trilinear field is the field's, bit for bit, until carved).
  const std::size_t size = haptics::voxelTypeSize(field_->voxelType());
  const std::size_t row = static_cast<std::size_t>(bg.dims[0]) * size;
  std::vector<std::byte> bytes(bg.voxelCount() * size);
  const std::byte* src = field_->bytes().data();
  std::byte* dst = bytes.data();
  for (int k = lo_[2]; k <= hi_[2]; ++k)
    for (int j = lo_[1]; j <= hi_[1]; ++j, dst += row) {
      const auto at = static_cast<std::size_t>(g.indexOf(lo_[0], j, k));
      std::copy_n(src + at * size, row, dst);
    }
  box_ = std::make_unique<haptics::ScalarVolume>(haptics::ScalarVolume::FromBytes(
      bg, field_->voxelType(), std::move(bytes), field_->valueScale(), field_->valueOffset()));
  for (const std::uint64_t index : removed_) (void)carveInBox(index);
  box_->refreshRegion({0, 0, 0}, {bg.dims[0] - 1, bg.dims[1] - 1, bg.dims[2] - 1});
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
