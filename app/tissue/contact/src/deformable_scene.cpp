#include "vh/tissue/deformable_scene.h"

#include <algorithm>
#include <chrono>
#include <climits>
#include <cstdio>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

#include <Eigen/LU>

#include "vh/tissue/hex_element.h"

namespace vh::tissue {
namespace {

using Clock = std::chrono::steady_clock;

// The raw value (stored type's scale) of a field value F.
double rawOf(const haptics::ScalarVolume& v, double F) noexcept { return (F - v.valueOffset()) / v.valueScale(); }

}  // namespace

DeformableScene::DeformableScene(std::shared_ptr<const haptics::ScalarVolume> scan, TissueRegion region,
                                 double isovalue, const DeformableSceneOptions& options)
    : scan_(std::move(scan)), region_(std::move(region)), isovalue_(isovalue), options_(options) {
  if (!scan_ || scan_->empty()) throw std::invalid_argument("deformable scene: no scan");
  if (!std::isfinite(isovalue_)) throw std::invalid_argument("deformable scene: the isovalue is not finite");
  if (options_.max_contacts < 1 || options_.max_nodes < 8 || options_.max_sweeps < 1 ||
      options_.max_window_voxels < 8 || options_.compliance_threads < 1 || options_.max_proxy_points < 1 || options_.touchable_layers < 1 || !(options_.max_table_bytes > 0.0) || !(options_.contact_margin_m >= 0.0) ||
      !(options_.window_margin_m >= 0.0) || !std::isfinite(options_.contact_margin_m) ||
      !std::isfinite(options_.window_margin_m))
    throw std::invalid_argument("deformable scene: bad options (capacities >= 1, margins >= 0 and finite)");
  const haptics::VolumeGeometry& geo = scan_->geometry();
  origin_W_ = geo.origin_W_m;
  D_W_ = geo.direction_W;
  spacing_m_ = geo.spacing_m;
  const HexLattice& L = region_.model.lattice();
  const LatticeGeometry& lg = L.geometry();
  const Eigen::Vector3d lattice_hi = lg.origin_W_m + lg.spacing_m * lg.cells.cast<double>();
  const Eigen::Vector3d grid_hi = spacing_m_.cwiseProduct(Eigen::Vector3d(geo.dims[0] - 1, geo.dims[1] - 1, geo.dims[2] - 1));
  // The region's lattice covers the grid's voxel boxes, its last cell past them by less than a cell.
  if ((lg.origin_W_m.array() < -(lg.spacing_m + spacing_m_.array())).any() ||
      (lattice_hi.array() > (grid_hi.array() + lg.spacing_m + spacing_m_.array())).any())
    throw std::invalid_argument("deformable scene: the tissue's lattice leaves the scan's grid");
  margin_m_ = options_.contact_margin_m > 0.0 ? options_.contact_margin_m : geo.minSpacing();
  window_margin_m_ = options_.window_margin_m > 0.0 ? options_.window_margin_m : lg.spacing_m;

  // The table's size is known before any solve: refused up front when it would not fit.
  const std::vector<int> touchable = outerLayerNodes(L, options_.touchable_layers);
  {
    std::vector<char> held(static_cast<std::size_t>(L.dofCount()), 0);
    for (const int dof : region_.fixed_dofs)
      if (dof >= 0 && dof < L.dofCount()) held[static_cast<std::size_t>(dof)] = 1;
    double free_nodes = 0.0;
    for (const int n : touchable)
      free_nodes += !(held[static_cast<std::size_t>(3 * n)] && held[static_cast<std::size_t>(3 * n + 1)] &&
                      held[static_cast<std::size_t>(3 * n + 2)]);
    const double bytes = 36.0 * free_nodes * free_nodes;
    if (bytes > options_.max_table_bytes) {
      char message[512];
      std::snprintf(message, sizeof message,
                    "deformable scene: the compliance table would hold %.0f touchable nodes of %d (%.2f GB, limit %.2f GB) "
                    "and take %.0f solves of %d unknowns to build: use a coarser lattice (cell_size_m, now %.1f mm), "
                    "fewer touchable layers (now %d) or a smaller region",
                    free_nodes, L.nodeCount(), bytes / 1e9, options_.max_table_bytes / 1e9, 3.0 * free_nodes,
                    L.dofCount(), lg.spacing_m * 1e3, options_.touchable_layers);
      throw std::invalid_argument(message);
    }
  }
  solver_ = std::make_unique<StaticSolver>(region_.model, region_.fixed_dofs);
  compliance_ = std::make_unique<SurfaceCompliance>(*solver_, touchable, options_.compliance_threads);
  contact_ = std::make_unique<CompliantContact>(L, *compliance_, options_.max_contacts, options_.max_nodes);

  // The depth of a point deep in the tissue: its distance to the nearest voxel outside the rest
  // surface, over the lattice's box grown by two cells (the tissue's surface lies in it).
  {
    std::vector<std::uint8_t> mask(geo.voxelCount(), 0);
    std::array<int, 3> lo{}, hi{};
    for (int a = 0; a < 3; ++a) {
      lo[a] = std::max(0, static_cast<int>(std::floor((lg.origin_W_m[a] - 2.0 * lg.spacing_m) / spacing_m_[a])));
      hi[a] = std::min(geo.dims[a] - 1, static_cast<int>(std::ceil((lattice_hi[a] + 2.0 * lg.spacing_m) / spacing_m_[a])));
    }
    for (int k = lo[2]; k <= hi[2]; ++k)
      for (int j = lo[1]; j <= hi[1]; ++j)
        for (int i = lo[0]; i <= hi[0]; ++i)
          if (!(scan_->voxel(i, j, k) > isovalue_)) mask[geo.indexOf(i, j, k)] = 1;
    outside_depth_ = haptics::DistanceField::FromMask(geo, mask, 0.0);
    // The surface band over the same box: per voxel, how many voxel steps (26-neighbours, at
    // most 255) to the nearest voxel with a 6-neighbour on the other side of the isovalue. A
    // voxel farther from the surface than it is displaced (plus two voxels) keeps its value's
    // side and cannot move the isosurface: step() leaves it at rest without resampling it.
    band_lo_ = lo;
    for (int a = 0; a < 3; ++a) band_dims_[a] = hi[a] - lo[a] + 1;
    band_.assign(static_cast<std::size_t>(band_dims_[0]) * band_dims_[1] * band_dims_[2], 255);
    std::vector<std::size_t> queue;
    const auto at = [&](int i, int j, int k) {
      return static_cast<std::size_t>(i - lo[0]) +
             static_cast<std::size_t>(band_dims_[0]) * (static_cast<std::size_t>(j - lo[1]) +
                                                       static_cast<std::size_t>(band_dims_[1]) * static_cast<std::size_t>(k - lo[2]));
    };
    for (int k = lo[2]; k <= hi[2]; ++k)
      for (int j = lo[1]; j <= hi[1]; ++j)
        for (int i = lo[0]; i <= hi[0]; ++i) {
          const bool in = scan_->voxel(i, j, k) > isovalue_;
          const bool straddles = (scan_->voxel(i - 1, j, k) > isovalue_) != in || (scan_->voxel(i + 1, j, k) > isovalue_) != in ||
                                 (scan_->voxel(i, j - 1, k) > isovalue_) != in || (scan_->voxel(i, j + 1, k) > isovalue_) != in ||
                                 (scan_->voxel(i, j, k - 1) > isovalue_) != in || (scan_->voxel(i, j, k + 1) > isovalue_) != in;
          if (straddles) {
            band_[at(i, j, k)] = 0;
            queue.push_back(at(i, j, k));
          }
        }
    for (std::size_t head = 0; head < queue.size(); ++head) {
      const std::size_t q = queue[head];
      const int i = static_cast<int>(q % static_cast<std::size_t>(band_dims_[0]));
      const int j = static_cast<int>((q / static_cast<std::size_t>(band_dims_[0])) % static_cast<std::size_t>(band_dims_[1]));
      const int k = static_cast<int>(q / (static_cast<std::size_t>(band_dims_[0]) * static_cast<std::size_t>(band_dims_[1])));
      const int next = band_[q] + 1;
      if (next >= 255) continue;
      for (int dk = -1; dk <= 1; ++dk)
        for (int dj = -1; dj <= 1; ++dj)
          for (int di = -1; di <= 1; ++di) {
            const int a = i + di, b = j + dj, c = k + dk;
            if (a < 0 || b < 0 || c < 0 || a >= band_dims_[0] || b >= band_dims_[1] || c >= band_dims_[2]) continue;
            const std::size_t r = static_cast<std::size_t>(a) +
                                  static_cast<std::size_t>(band_dims_[0]) * (static_cast<std::size_t>(b) + static_cast<std::size_t>(band_dims_[1]) * static_cast<std::size_t>(c));
            if (band_[r] <= next) continue;
            band_[r] = static_cast<std::uint8_t>(next);
            queue.push_back(r);
          }
    }
  }

  felt_ = std::make_shared<haptics::ScalarVolume>(*scan_);
  const auto m = static_cast<std::size_t>(options_.max_contacts);
  contacts_.resize(m);
  contact_point_.assign(m, -1);
  prev_point_.assign(m, -1);
  prev_push_N_.assign(m, 0.0);
  // u on the lattice's grid of nodes (zero off the window), and which grid cells carry it.
  node_dims_ = lg.cells + Eigen::Vector3i::Ones();
  inverse_cell_m_ = 1.0 / lg.spacing_m;
  u_grid_.assign(static_cast<std::size_t>(3 * node_dims_.prod()), 0.0);
  window_nodes_.reserve(static_cast<std::size_t>(compliance_->nodeCount()));
  window_grid_nodes_.reserve(static_cast<std::size_t>(compliance_->nodeCount()));
  window_u_.reserve(static_cast<std::size_t>(3 * compliance_->nodeCount()));
  cell_touchable_.assign(static_cast<std::size_t>(lg.cellCount()), 0);
  for (int e = 0; e < L.elementCount(); ++e) {
    bool all = true;
    for (const int node : L.elementNodes(e)) all = all && compliance_->indexOf(node) >= 0;
    const Eigen::Vector3i c = L.elementCell(e);
    cell_touchable_[cellIndex(c.x(), c.y(), c.z())] = all ? 1 : 0;
  }
  // The window's workspace: the largest window plus the last one (what goes back to rest).
  old_raw_.reserve(static_cast<std::size_t>(2 * options_.max_window_voxels));
  new_raw_.reserve(static_cast<std::size_t>(2 * options_.max_window_voxels));
  proxy_points_W_.reserve(static_cast<std::size_t>(options_.max_proxy_points));
  proxy_old_F_.reserve(static_cast<std::size_t>(options_.max_proxy_points));
  // The view's slots hold the largest window held (a window and the last one's union).
  for (DeformedWindow& slot : view_slots_) slot.values_F.reserve(static_cast<std::size_t>(2 * options_.max_window_voxels));
}

void DeformableScene::publishView(Clock::time_point now, bool changed, const DeformableStep& step) noexcept {
  view_dirty_ = view_dirty_ || changed;
  if (!view_dirty_) return;
  // While the field moves, at most every kViewPublishInterval_ms; the state it settles in always
  // (the first step that changes nothing publishes it).
  if (changed && std::chrono::duration<double, std::milli>(now - view_published_).count() < kViewPublishInterval_ms) return;
  DeformedWindow& slot = view_slots_[view_write_];
  slot.lo = last_lo_;
  slot.hi = last_hi_;
  slot.step = steps_;
  slot.indentation_m = step.indentation_m;
  slot.push_N = step.contact.force_on_device_N.norm();
  slot.felt_fraction = step.felt_fraction;
  slot.values_F.clear();
  if (!slot.empty()) {
    std::size_t count = 1;
    for (int a = 0; a < 3; ++a) count *= static_cast<std::size_t>(last_hi_[a] - last_lo_[a] + 1);
    if (count > slot.values_F.capacity()) return;  // never reallocates (the held window fits: see the constructor)
    const haptics::VolumeGeometry& geo = felt_->geometry();
    const double scale = felt_->valueScale(), offset = felt_->valueOffset();
    for (int k = last_lo_[2]; k <= last_hi_[2]; ++k)
      for (int j = last_lo_[1]; j <= last_hi_[1]; ++j)
        for (int i = last_lo_[0]; i <= last_hi_[0]; ++i)
          slot.values_F.push_back(static_cast<float>(scale * felt_->rawAt(geo.indexOf(i, j, k)) + offset));
  }
  view_write_ = view_middle_.exchange(view_write_ | kFresh, std::memory_order_acq_rel) & ~kFresh;
  view_published_ = now;
  view_dirty_ = false;
}

void DeformableScene::reset() noexcept {
  // Outside the held window the felt volume is the scan already (every write lies in it).
  if (last_hi_[0] >= last_lo_[0] && last_hi_[1] >= last_lo_[1] && last_hi_[2] >= last_lo_[2]) {
    const haptics::VolumeGeometry& geo = scan_->geometry();
    for (int k = last_lo_[2]; k <= last_hi_[2]; ++k)
      for (int j = last_lo_[1]; j <= last_hi_[1]; ++j)
        for (int i = last_lo_[0]; i <= last_hi_[0]; ++i) {
          const std::size_t index = geo.indexOf(i, j, k);
          felt_->writeRaw(index, scan_->rawAt(index));
        }
    felt_->refreshRegion(last_lo_, last_hi_);
  }
  last_lo_ = {0, 0, 0};
  last_hi_ = {-1, -1, -1};
  std::fill(prev_point_.begin(), prev_point_.end(), -1);
  std::fill(prev_push_N_.begin(), prev_push_N_.end(), 0.0);
  std::fill(contact_point_.begin(), contact_point_.end(), -1);
  contact_count_ = 0;
  for (const std::size_t q : window_grid_nodes_) u_grid_[3 * q] = u_grid_[3 * q + 1] = u_grid_[3 * q + 2] = 0.0;
  window_nodes_.clear();
  window_grid_nodes_.clear();
  view_dirty_ = true;  // the rest state, at the next step
  view_published_ = {};
}

bool DeformableScene::takeDeformedWindow(DeformedWindow& out) {
  if ((view_middle_.load(std::memory_order_acquire) & kFresh) == 0) return false;
  view_read_ = view_middle_.exchange(view_read_, std::memory_order_acq_rel) & ~kFresh;
  out = view_slots_[view_read_];
  return true;
}

void DeformableScene::gatherContacts(const haptics::Pose& X_WD, const haptics::ToolModel& tool,
                                     DeformableStep& out) noexcept {
  contact_count_ = 0;
  const LatticeGeometry& lg = region_.model.lattice().geometry();
  const Eigen::Vector3d box_lo = lg.origin_W_m.array() - margin_m_;
  const Eigen::Vector3d box_hi = (lg.origin_W_m + lg.spacing_m * lg.cells.cast<double>()).array() + margin_m_;
  const std::vector<Eigen::Vector3d>& points = tool.point_shell.points_T_m();
  if (pool_ == nullptr || points.size() > near_points_.size()) {
    NearPoint near;
    for (std::size_t j = 0; j < points.size(); ++j)
      if (nearPoint(X_WD * points[j], box_lo, box_hi, near)) addContact(static_cast<int>(j), near, out);
    return;
  }
  // On the lanes: each claims a few points at a time until none is left; then the near ones
  // join in the tool's order.
  struct Job {
    DeformableScene* scene;
    const haptics::Pose* X_WD;
    const std::vector<Eigen::Vector3d>* points;
    const Eigen::Vector3d* box_lo;
    const Eigen::Vector3d* box_hi;
    std::atomic<std::size_t> next{0};  // the first point no lane has claimed yet
  } job{this, &X_WD, &points, &box_lo, &box_hi};
  pool_->run(
      [](void* context, int) noexcept {
        constexpr std::size_t kPointsPerClaim = 32;
        Job& g = *static_cast<Job*>(context);
        DeformableScene& s = *g.scene;
        const std::size_t n = g.points->size();
        for (std::size_t first = g.next.fetch_add(kPointsPerClaim, std::memory_order_relaxed); first < n;
             first = g.next.fetch_add(kPointsPerClaim, std::memory_order_relaxed))
          for (std::size_t j = first; j < std::min(n, first + kPointsPerClaim); ++j)
            s.point_near_[j] = s.nearPoint(*g.X_WD * (*g.points)[j], *g.box_lo, *g.box_hi, s.near_points_[j]) ? 1 : 0;
      },
      &job, lanes_);
  for (std::size_t j = 0; j < points.size(); ++j)
    if (point_near_[j] != 0) addContact(static_cast<int>(j), near_points_[j], out);
}

bool DeformableScene::nearPoint(const Eigen::Vector3d& p_W, const Eigen::Vector3d& box_lo, const Eigen::Vector3d& box_hi,
                                NearPoint& near) const noexcept {
  const double voxel_m = scan_->geometry().minSpacing();
  const Eigen::Vector3d g = toG(p_W);
  if ((g.array() < box_lo.array()).any() || (g.array() > box_hi.array()).any()) return false;
  if (!scan_->inBounds(p_W)) return false;
  const double F = scan_->sample(p_W);
  // Farther than the margin outside, by the local Lipschitz bound: not a contact.
  const double L = scan_->localLipschitzBound(scan_->gridCoordinates(p_W));
  if (isovalue_ - F > L * margin_m_) return false;
  // The interpolant's own gradient: exact where F is linear across the surface (eq. 1's central
  // difference halves the slope of a ramp one voxel wide, and doubles the depth with it).
  const Eigen::Vector3d grad = scan_->interpolantGradient(p_W);
  const double gnorm = grad.norm();
  double gap = 0.0;
  Eigen::Vector3d n_W;
  if (gnorm > 0.0 && std::abs(isovalue_ - F) <= gnorm * voxel_m) {
    gap = (isovalue_ - F) / gnorm;  // first order, within a voxel of the surface
    n_W = -grad / gnorm;
  } else if (F > isovalue_) {
    // Deeper: the distance transform of the voxels outside, and its direction.
    const double d = outside_depth_.sample_m(p_W);
    if (!std::isfinite(d)) return false;
    gap = -std::max(0.0, d - 0.5 * voxel_m);
    Eigen::Vector3d dd;
    for (int a = 0; a < 3; ++a) {
      const Eigen::Vector3d e = D_W_.col(a) * (0.5 * spacing_m_[a]);
      dd[a] = outside_depth_.sample_m(p_W + e) - outside_depth_.sample_m(p_W - e);
    }
    dd = D_W_ * dd.cwiseQuotient(spacing_m_);  // back to W: the depth's gradient
    if (!(dd.norm() > 0.0) || !dd.allFinite()) return false;
    n_W = -dd.normalized();
  } else {
    return false;  // outside on a flat field: no surface near
  }
  if (gap > margin_m_) return false;
  near.X_G_m = toG(p_W - gap * n_W);
  near.n_G = D_W_.transpose() * n_W;
  near.gap_m = gap;
  return true;
}

void DeformableScene::addContact(int j, const NearPoint& near, DeformableStep& out) noexcept {
  ++out.tool_points_near;
  TissueContactPoint c;
  c.X_G_m = near.X_G_m;
  c.n_G = near.n_G;
  c.gap_m = near.gap_m;
  c.push_guess_N = 0.0;
  for (std::size_t q = 0; q < prev_point_.size() && prev_point_[q] >= 0; ++q)
    if (prev_point_[q] == j) {
      c.push_guess_N = prev_push_N_[q];
      break;
    }
  const auto cap = static_cast<int>(contacts_.size());
  int slot = contact_count_;
  if (contact_count_ == cap) {  // full: replace the shallowest when this one is deeper
    slot = 0;
    for (int q = 1; q < cap; ++q)
      if (contacts_[static_cast<std::size_t>(q)].gap_m > contacts_[static_cast<std::size_t>(slot)].gap_m) slot = q;
    if (!(near.gap_m < contacts_[static_cast<std::size_t>(slot)].gap_m)) return;
  } else {
    ++contact_count_;
  }
  contacts_[static_cast<std::size_t>(slot)] = c;
  contact_point_[static_cast<std::size_t>(slot)] = j;
}

bool DeformableScene::carryOut(const haptics::ToolModel& tool, const haptics::Pose& X_WP, const Eigen::Vector3d& box_lo,
                               const Eigen::Vector3d& box_hi, Eigen::Vector3d& dp_W) const noexcept {
  // The outward normals (-grad F) at the swallowed points, weighted by how deep each is.
  Eigen::Vector3d dir = Eigen::Vector3d::Zero();
  for (std::size_t q = 0; q < proxy_points_W_.size(); ++q) {
    const double F = felt_->sample(proxy_points_W_[q]);
    if (!(F > isovalue_) || proxy_old_F_[q] > isovalue_) continue;
    const Eigen::Vector3d g = felt_->interpolantGradient(proxy_points_W_[q]);
    const double gn = g.norm();
    if (!(gn > 0.0)) return false;
    dir -= g * ((F - isovalue_) / (gn * gn));
  }
  if (!(dir.norm() > 0.0)) return false;
  dir.normalize();
  double need_m = 0.0;  // along dir, first order, for the deepest
  for (std::size_t q = 0; q < proxy_points_W_.size(); ++q) {
    const double F = felt_->sample(proxy_points_W_[q]);
    if (!(F > isovalue_) || proxy_old_F_[q] > isovalue_) continue;
    const Eigen::Vector3d g = felt_->interpolantGradient(proxy_points_W_[q]);
    const double gn = g.norm();
    need_m = std::max(need_m, (F - isovalue_) / gn / std::max(0.3, -dir.dot(g) / gn));
  }
  const double voxel = spacing_m_.minCoeff();
  for (int attempt = 0; attempt < 3; ++attempt, need_m *= 2.0) {
    const double distance = 1.1 * need_m + 1e-3 * voxel;
    if (!(distance <= 0.5 * voxel)) return false;  // more than the surface moves in a tick: held back instead
    dp_W = distance * dir;
    bool clear = true;
    std::size_t collected = 0;  // the tool's points in the written box come in proxy_points_W_'s order
    for (const Eigen::Vector3d& p_T : tool.point_shell.points_T_m()) {
      const Eigen::Vector3d p_W = X_WP * p_T;
      const bool in_box = inWrittenBox(p_W, box_lo, box_hi);
      const double old_F = in_box ? proxy_old_F_[collected++] : felt_->sample(p_W);  // outside the box: unchanged
      const Eigen::Vector3d moved = p_W + dp_W;
      if (!felt_->inBounds(moved) || !(felt_->sample(moved) > isovalue_)) continue;
      // Inside after the move: allowed only for a point embedded before this step (left out of
      // the contact, as the renderer leaves it).
      if (!(old_F > isovalue_)) {
        clear = false;
        break;
      }
    }
    if (clear) return true;
  }
  return false;
}

const DeformableScene::CellCorners* DeformableScene::displacementAt(const Eigen::Vector3d& X_G, CornerCache& cache,
                                                                     Eigen::Vector3d& u) const noexcept {
  const LatticeGeometry& lg = region_.model.lattice().geometry();
  int c[3];
  double f[3];
  for (int a = 0; a < 3; ++a) {
    const double t = (X_G[a] - lg.origin_W_m[a]) * inverse_cell_m_;
    if (!(t >= 0.0 && t <= lg.cells[a])) return nullptr;
    c[a] = std::min(static_cast<int>(t), lg.cells[a] - 1);  // the top face belongs to the last cell
    f[a] = t - c[a];
  }
  const auto holds = [&c](const CellCorners& e) { return e.cell[0] == c[0] && e.cell[1] == c[1] && e.cell[2] == c[2]; };
  if (!holds(cache.cells[static_cast<std::size_t>(cache.recent)])) {
    cache.recent = 1 - cache.recent;
    CellCorners& corners = cache.cells[static_cast<std::size_t>(cache.recent)];
    if (!holds(corners)) {  // neither: read it in place of the least recently used
      corners.cell = {c[0], c[1], c[2]};
      corners.touchable = cell_touchable_[cellIndex(c[0], c[1], c[2])] != 0;
      if (corners.touchable) {
        const std::size_t nx = static_cast<std::size_t>(node_dims_.x()), nxy = nx * static_cast<std::size_t>(node_dims_.y());
        const std::size_t base = static_cast<std::size_t>(c[0]) + nx * static_cast<std::size_t>(c[1]) + nxy * static_cast<std::size_t>(c[2]);
        for (int a = 0; a < 8; ++a) {
          const double* node = u_grid_.data() + 3 * (base + static_cast<std::size_t>(a & 1) + nx * static_cast<std::size_t>((a >> 1) & 1) +
                                                     nxy * static_cast<std::size_t>((a >> 2) & 1));
          for (int r = 0; r < 3; ++r) corners.u[r][a] = node[r];
        }
        // I + grad u at the centre: each derivative the mean of the cell's four edge differences
        // (hexShapeGradients() at xi = 0 written out; through it, the resampling took 1.1x).
        Eigen::Matrix3d J = Eigen::Matrix3d::Identity();
        for (int r = 0; r < 3; ++r) {
          const double* v = corners.u[r];
          J(r, 0) += 0.25 * inverse_cell_m_ * ((v[1] - v[0]) + (v[3] - v[2]) + (v[5] - v[4]) + (v[7] - v[6]));
          J(r, 1) += 0.25 * inverse_cell_m_ * ((v[2] - v[0]) + (v[3] - v[1]) + (v[6] - v[4]) + (v[7] - v[5]));
          J(r, 2) += 0.25 * inverse_cell_m_ * ((v[4] - v[0]) + (v[5] - v[1]) + (v[6] - v[2]) + (v[7] - v[3]));
        }
        // A cell near inversion (far beyond the linear model's small strains): plain fixed-point steps.
        corners.inverse_gradient = J.determinant() > 0.1 ? Eigen::Matrix3d(J.inverse()) : Eigen::Matrix3d::Identity();
      }
    }
  }
  const CellCorners& corners = cache.cells[static_cast<std::size_t>(cache.recent)];
  if (!corners.touchable) return nullptr;
  // Trilinear over the cell's corners (the hexahedron's shape functions on a cube), as lerps
  // along x, then y, then z.
  for (int r = 0; r < 3; ++r) {
    const double* v = corners.u[r];
    const double x00 = v[0] + f[0] * (v[1] - v[0]), x10 = v[2] + f[0] * (v[3] - v[2]);
    const double x01 = v[4] + f[0] * (v[5] - v[4]), x11 = v[6] + f[0] * (v[7] - v[6]);
    const double y0 = x00 + f[1] * (x10 - x00), y1 = x01 + f[1] * (x11 - x01);
    u[r] = y0 + f[2] * (y1 - y0);
  }
  return &corners;
}

bool DeformableScene::inBand(int i, int j, int k, double displacement_m) const noexcept {
  const int a = i - band_lo_[0], b = j - band_lo_[1], c = k - band_lo_[2];
  if (a < 0 || b < 0 || c < 0 || a >= band_dims_[0] || b >= band_dims_[1] || c >= band_dims_[2]) return true;
  const int steps = band_[static_cast<std::size_t>(a) +
                          static_cast<std::size_t>(band_dims_[0]) *
                              (static_cast<std::size_t>(b) + static_cast<std::size_t>(band_dims_[1]) * static_cast<std::size_t>(c))];
  return steps < 255 && steps <= displacement_m / spacing_m_.minCoeff() + 2.0;
}

double DeformableScene::deformedValue(int i, int j, int k, CornerCache& cache) const noexcept {
  const Eigen::Vector3d p = spacing_m_.cwiseProduct(Eigen::Vector3d(i, j, k));
  // X + u(X) = p by chord steps X <- X - J^-1 (X + u(X) - p), J = I + grad u at the centre of the
  // cell X lies in (Newton with the cell's mean Jacobian: u is trilinear, its gradient varies
  // little within a cell, so each step shrinks the error by that variation rather than by
  // |grad u| as plain fixed-point steps X <- p - u(X) do); stopped when a step moves X by under
  // a thousandth of a voxel (at most 8 steps). The start: the last voxel's material point moved
  // by dX_dx when that voxel is this one's neighbour along the row (the same step's
  // resampling, never an earlier step's: no history), else p.
  bool follows = cache.has_last && cache.last_voxel[0] == i - 1 && cache.last_voxel[1] == j && cache.last_voxel[2] == k;
  cache.has_last = false;
  if (follows) {  // only where the start from p would solve too: p in a touchable cell
    const LatticeGeometry& lg = region_.model.lattice().geometry();
    int c[3];
    for (int a = 0; a < 3; ++a) {
      const double t = (p[a] - lg.origin_W_m[a]) * inverse_cell_m_;
      if (!(t >= 0.0 && t <= lg.cells[a])) return scan_->voxel(i, j, k);  // off the lattice: rest
      c[a] = std::min(static_cast<int>(t), lg.cells[a] - 1);
    }
    if (cell_touchable_[cellIndex(c[0], c[1], c[2])] == 0) return scan_->voxel(i, j, k);
  }
  Eigen::Vector3d X = follows ? Eigen::Vector3d(cache.last_X_G_m + cache.dX_dx_m) : p, u;
  const double tolerance_m = 1e-3 * spacing_m_.minCoeff();
  for (int it = 0; it < 8; ++it) {
    const CellCorners* cell = displacementAt(X, cache, u);
    if (cell == nullptr && it == 0 && follows) {  // the start left the touchable cells: from p after all
      X = p;
      cell = displacementAt(X, cache, u);
    }
    if (cell == nullptr) {
      if (it == 0) return scan_->voxel(i, j, k);  // not in a touchable cell: rest
      break;
    }
    if (it == 0 && (u.squaredNorm() < tolerance_m * tolerance_m || !inBand(i, j, k, u.norm())))
      return scan_->voxel(i, j, k);  // not moved, or too far from the surface to move it
    const Eigen::Vector3d step = cell->inverse_gradient * (X + u - p);
    X -= step;
    cache.dX_dx_m = cell->inverse_gradient.col(0) * spacing_m_[0];
    if (step.squaredNorm() < tolerance_m * tolerance_m) break;
  }
  cache.has_last = true;
  cache.last_voxel = {i, j, k};
  cache.last_X_G_m = X;
  return scan_->sampleGrid(X.cwiseQuotient(spacing_m_));  // G is the grid's frame scaled by the spacing
}

void DeformableScene::resampleRows(Resampling& job, int lane) noexcept {
  constexpr int kRowsPerClaim = 8;
  const haptics::VolumeGeometry& geo = scan_->geometry();
  CornerCache& cache = lane_caches_[static_cast<std::size_t>(lane)];
  const int nx = job.u_hi[0] - job.u_lo[0] + 1, ny = job.u_hi[1] - job.u_lo[1] + 1;
  const int rows = ny * (job.u_hi[2] - job.u_lo[2] + 1);
  for (int first = job.next_row.fetch_add(kRowsPerClaim, std::memory_order_relaxed); first < rows;
       first = job.next_row.fetch_add(kRowsPerClaim, std::memory_order_relaxed)) {
    for (int row = first; row < std::min(rows, first + kRowsPerClaim); ++row) {
      const int j = job.u_lo[1] + row % ny, k = job.u_lo[2] + row / ny;
      const bool row_inside = job.window && j >= job.lo[1] && j <= job.hi[1] && k >= job.lo[2] && k <= job.hi[2];
      std::size_t at = static_cast<std::size_t>(row) * static_cast<std::size_t>(nx);
      for (int i = job.u_lo[0]; i <= job.u_hi[0]; ++i, ++at) {
        const std::size_t index = geo.indexOf(i, j, k);
        old_raw_[at] = felt_->rawAt(index);
        const bool inside = row_inside && i >= job.lo[0] && i <= job.hi[0];
        // A voxel farther from the rest surface than the window's largest displacement (plus the
        // band's two voxels) cannot move the surface: the scan's value, without solving for X.
        new_raw_[at] = inside && inBand(i, j, k, job.max_displacement_m) ? rawOf(*scan_, deformedValue(i, j, k, cache))
                                                                         : scan_->rawAt(index);
      }
    }
  }
}

void DeformableScene::setLanes(int lanes) {
  if (lanes < 1 || lanes > haptics::WorkerPool::kMaxLanes)
    throw std::invalid_argument("deformable scene: lanes must be 1 to " + std::to_string(haptics::WorkerPool::kMaxLanes));
  std::shared_ptr<haptics::WorkerPool> pool = lanes > 1 ? haptics::WorkerPool::shared(lanes) : nullptr;
  const auto points = static_cast<std::size_t>(lanes > 1 ? options_.max_proxy_points : 0);
  std::vector<std::uint8_t> point_near(points, 0);
  std::vector<NearPoint> near_points(points);
  lane_caches_.assign(static_cast<std::size_t>(lanes), CornerCache{});
  point_near_ = std::move(point_near);
  near_points_ = std::move(near_points);
  pool_ = std::move(pool);
  lanes_ = lanes;
}

DeformableStep DeformableScene::step(const haptics::Pose& X_WD, haptics::HapticRenderer& renderer) noexcept {
  const auto start = Clock::now();
  DeformableStep out;
  ++steps_;
  if (!X_WD.allFinite()) return out;
  const haptics::ToolModel& tool = renderer.tool();
  gatherContacts(X_WD, tool, out);
  auto phase = Clock::now();
  const auto lap = [&phase](double& us) {
    const auto now = Clock::now();
    us = std::chrono::duration<double, std::micro>(now - phase).count();
    phase = now;
  };
  out.gather_us = std::chrono::duration<double, std::micro>(phase - start).count();
  const double k_N_per_m = renderer.coupling().gains().linear_N_per_m;
  out.contact = contact_->solve({contacts_.data(), static_cast<std::size_t>(contact_count_)}, k_N_per_m, options_.max_sweeps);
  lap(out.solve_us);
  // The indentation: at a pushed contact the surface's recession is -gap - n . (proxy offset)
  // (complementarity: the pushed points touch the deformed surface).
  for (int q = 0; q < out.contact.contacts; ++q) {
    if (!(contact_->pushes_N()(q) > 0.0)) continue;
    const TissueContactPoint& c = contacts_[static_cast<std::size_t>(q)];
    const double n_norm = c.n_G.norm();
    if (!(n_norm > 0.0)) continue;
    const double recession = -c.gap_m - (c.n_G / n_norm).dot(out.contact.proxy_offset_m);  // both in G
    out.indentation_m = std::max(out.indentation_m, recession);
  }
  // The pushes, for the next step's warm start.
  std::fill(prev_point_.begin(), prev_point_.end(), -1);
  for (int q = 0; q < contact_count_ && q < out.contact.contacts; ++q) {
    prev_point_[static_cast<std::size_t>(q)] = contact_point_[static_cast<std::size_t>(q)];
    prev_push_N_[static_cast<std::size_t>(q)] = contact_->pushes_N()(q);
  }

  // The window: the contacts' material points, grown; in voxel indices.
  const haptics::VolumeGeometry& geo = scan_->geometry();
  const LatticeGeometry& lg = region_.model.lattice().geometry();
  std::array<int, 3> lo{0, 0, 0}, hi{-1, -1, -1};
  double push_total = 0.0;
  for (int q = 0; q < out.contact.contacts; ++q) push_total += contact_->pushes_N()(q);
  if (push_total > 0.0) {
    Eigen::Vector3d g_lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
    Eigen::Vector3d g_hi = -g_lo;
    int deepest = 0;
    for (int q = 0; q < out.contact.contacts; ++q) {
      const TissueContactPoint& c = contacts_[static_cast<std::size_t>(q)];
      g_lo = g_lo.cwiseMin(c.X_G_m);
      g_hi = g_hi.cwiseMax(c.X_G_m);
      if (c.gap_m < contacts_[static_cast<std::size_t>(deepest)].gap_m) deepest = q;
    }
    std::int64_t voxels = 1;
    for (int a = 0; a < 3; ++a) {
      lo[a] = std::max(0, static_cast<int>(std::floor((g_lo[a] - window_margin_m_) / spacing_m_[a])));
      hi[a] = std::min(geo.dims[a] - 1, static_cast<int>(std::ceil((g_hi[a] + window_margin_m_) / spacing_m_[a])));
      voxels *= std::max(0, hi[a] - lo[a] + 1);
    }
    if (voxels > options_.max_window_voxels) {  // clipped to a cube about the deepest contact
      out.window_clipped = true;
      const int side = std::max(2, static_cast<int>(std::cbrt(static_cast<double>(options_.max_window_voxels))));
      const Eigen::Vector3d& X = contacts_[static_cast<std::size_t>(deepest)].X_G_m;
      for (int a = 0; a < 3; ++a) {
        const int centre = static_cast<int>(std::lround(X[a] / spacing_m_[a]));
        lo[a] = std::max({lo[a], 0, centre - side / 2});
        hi[a] = std::min({hi[a], geo.dims[a] - 1, lo[a] + side - 1});
      }
    }
  }
  const bool window = hi[0] >= lo[0] && hi[1] >= lo[1] && hi[2] >= lo[2];
  const bool last_window = last_hi_[0] >= last_lo_[0];

  // u at the touchable nodes about the window (one cell beyond it, where material points of
  // its voxels may lie); the last window's nodes back to zero first.
  for (const std::size_t q : window_grid_nodes_) u_grid_[3 * q] = u_grid_[3 * q + 1] = u_grid_[3 * q + 2] = 0.0;
  window_nodes_.clear();
  window_grid_nodes_.clear();
  if (window) {
    const HexLattice& L = region_.model.lattice();
    std::array<int, 3> n_lo{}, n_hi{};
    for (int a = 0; a < 3; ++a) {
      n_lo[a] = std::max(0, static_cast<int>(std::floor((lo[a] * spacing_m_[a] - lg.origin_W_m[a]) / lg.spacing_m)) - 1);
      n_hi[a] = std::min(lg.cells[a], static_cast<int>(std::ceil((hi[a] * spacing_m_[a] - lg.origin_W_m[a]) / lg.spacing_m)) + 1);
    }
    for (int c = n_lo[2]; c <= n_hi[2]; ++c)
      for (int b = n_lo[1]; b <= n_hi[1]; ++b)
        for (int a = n_lo[0]; a <= n_hi[0]; ++a) {
          const int node = L.nodeAt(a, b, c);
          const int s = node < 0 ? -1 : compliance_->indexOf(node);
          if (s < 0) continue;
          window_nodes_.push_back(s);  // within the reserve: never reallocates
          window_grid_nodes_.push_back(static_cast<std::size_t>(a) +
                                       static_cast<std::size_t>(node_dims_.x()) *
                                           (static_cast<std::size_t>(b) + static_cast<std::size_t>(node_dims_.y()) * static_cast<std::size_t>(c)));
        }
    window_u_.resize(3 * window_nodes_.size());  // within the reserve
    contact_->touchableDisplacement(window_nodes_, window_u_.data());
    for (std::size_t w = 0; w < window_nodes_.size(); ++w) {
      const std::size_t q = window_grid_nodes_[w];
      for (int r = 0; r < 3; ++r) u_grid_[3 * q + static_cast<std::size_t>(r)] = window_u_[3 * w + static_cast<std::size_t>(r)];
      out.max_displacement_m = std::max(
          out.max_displacement_m, Eigen::Vector3d(window_u_[3 * w], window_u_[3 * w + 1], window_u_[3 * w + 2]).norm());
    }
  }
  lap(out.displace_us);
  if (!window && !last_window) {
    publishView(Clock::now(), false, out);
    out.step_us = std::chrono::duration<double, std::micro>(Clock::now() - start).count();
    return out;
  }

  // What is written: the union of this window and the last (which goes back to rest where this
  // one does not reach).
  std::array<int, 3> u_lo = lo, u_hi = hi;
  if (!window) {
    u_lo = last_lo_;
    u_hi = last_hi_;
  } else if (last_window) {
    for (int a = 0; a < 3; ++a) {
      u_lo[a] = std::min(lo[a], last_lo_[a]);
      u_hi[a] = std::max(hi[a], last_hi_[a]);
    }
  }
  std::size_t count = 1;
  for (int a = 0; a < 3; ++a) count *= static_cast<std::size_t>(u_hi[a] - u_lo[a] + 1);
  if (count > old_raw_.capacity()) {  // the union of two far windows: back to rest first, next tick the new one
    u_lo = last_window ? last_lo_ : lo;
    u_hi = last_window ? last_hi_ : hi;
    count = 1;
    for (int a = 0; a < 3; ++a) count *= static_cast<std::size_t>(u_hi[a] - u_lo[a] + 1);
    if (last_window) {
      for (int a = 0; a < 3; ++a) lo[a] = 0, hi[a] = -1;  // this tick: rest only
    }
  }
  const bool writes_window = hi[0] >= lo[0] && hi[1] >= lo[1] && hi[2] >= lo[2];
  old_raw_.resize(count);
  new_raw_.resize(count);
  for (CornerCache& cache : lane_caches_) cache = CornerCache{};  // u_grid_ is final for this step
  Resampling job;
  job.scene = this;
  job.u_lo = u_lo;
  job.u_hi = u_hi;
  job.lo = lo;
  job.hi = hi;
  job.window = writes_window;
  job.max_displacement_m = out.max_displacement_m;
  const int rows = (u_hi[1] - u_lo[1] + 1) * (u_hi[2] - u_lo[2] + 1);
  const int lanes = pool_ != nullptr ? std::min(lanes_, rows) : 1;
  if (lanes > 1) {
    pool_->run([](void* context, int lane) noexcept {
                 auto& j = *static_cast<Resampling*>(context);
                 j.scene->resampleRows(j, lane);
               },
               &job, lanes);
  } else {
    resampleRows(job, 0);
  }

  out.window_voxels = static_cast<int>(count);
  lap(out.resample_us);
  // The proxy's points in the written box (one voxel around it): F before the write.
  const haptics::Pose& X_WP = renderer.proxyPose();
  const Eigen::Vector3d box_lo = spacing_m_.cwiseProduct(Eigen::Vector3d(u_lo[0] - 1, u_lo[1] - 1, u_lo[2] - 1));
  const Eigen::Vector3d box_hi = spacing_m_.cwiseProduct(Eigen::Vector3d(u_hi[0] + 1, u_hi[1] + 1, u_hi[2] + 1));
  proxy_points_W_.clear();
  proxy_old_F_.clear();
  for (const Eigen::Vector3d& p_T : tool.point_shell.points_T_m()) {
    const Eigen::Vector3d p_W = X_WP * p_T;
    if (!inWrittenBox(p_W, box_lo, box_hi)) continue;
    if (proxy_points_W_.size() == proxy_points_W_.capacity()) break;  // never reallocates (checked below)
    proxy_points_W_.push_back(p_W);
    proxy_old_F_.push_back(felt_->sample(p_W));
  }
  const bool all_points_checked = proxy_points_W_.size() < proxy_points_W_.capacity();

  // Only the voxels whose value changes are written; their box is what the bounds refresh, and
  // the most a written value rose above its value before this step is what the renderer's
  // certificates must allow for (max_rise_raw, in the stored values: F's scale is positive).
  std::array<int, 3> c_lo{INT_MAX, INT_MAX, INT_MAX}, c_hi{-1, -1, -1};
  double max_rise_raw = 0.0;
  const auto write = [&](double alpha) {
    std::size_t q = 0;
    int changed = 0;
    max_rise_raw = 0.0;
    for (int k = u_lo[2]; k <= u_hi[2]; ++k)
      for (int j = u_lo[1]; j <= u_hi[1]; ++j)
        for (int i = u_lo[0]; i <= u_hi[0]; ++i, ++q) {
          if (new_raw_[q] == old_raw_[q]) continue;
          const double raw = old_raw_[q] + alpha * (new_raw_[q] - old_raw_[q]);
          const std::size_t index = geo.indexOf(i, j, k);
          const double before = felt_->rawAt(index);
          felt_->writeRaw(index, raw);
          const double after = felt_->rawAt(index);
          // A NaN rise (a value no scan holds) stays: the renderer then drops every certificate.
          const double rise = after - old_raw_[q];
          if (!(rise <= max_rise_raw) && !std::isnan(max_rise_raw)) max_rise_raw = rise;
          if (after == before) continue;
          ++changed;
          c_lo = {std::min(c_lo[0], i), std::min(c_lo[1], j), std::min(c_lo[2], k)};
          c_hi = {std::max(c_hi[0], i), std::max(c_hi[1], j), std::max(c_hi[2], k)};
        }
    return changed;
  };
  const auto firstSwallowed = [&]() {
    for (std::size_t q = 0; q < proxy_points_W_.size(); ++q)
      if (proxy_old_F_[q] <= isovalue_ && felt_->sample(proxy_points_W_[q]) > isovalue_) return static_cast<int>(q);
    return -1;
  };
  int changed = write(1.0);
  double alpha = all_points_checked ? 1.0 : 0.0;
  // Springing back onto the held proxy: the surface carries it (the proxy is massless, the hand
  // then feels the tissue push back), when a short push along the surface's normal leaves every
  // point of the tool outside the new field; else the write is held back (below).
  if (alpha > 0.0 && firstSwallowed() >= 0) {
    Eigen::Vector3d dp_W = Eigen::Vector3d::Zero();
    if (carryOut(tool, X_WP, box_lo, box_hi, dp_W)) {
      renderer.carryProxy(dp_W);
      out.proxy_carried_m = dp_W.norm();
    }
  }
  if (alpha > 0.0 && out.proxy_carried_m == 0.0) {
    // alpha: the largest fraction with (1 - a) F_old + a F_new <= s at every point, F linear in the voxels.
    for (std::size_t q = 0; q < proxy_points_W_.size(); ++q) {
      const double f_new = felt_->sample(proxy_points_W_[q]);
      const double f_old = proxy_old_F_[q];
      // A point already inside (embedded after a reset) does not constrain the proxy: left out.
      if (f_new > isovalue_ && f_old <= isovalue_) alpha = std::min(alpha, 0.9 * (isovalue_ - f_old) / (f_new - f_old));
    }
  }
  if (alpha < 1.0) {
    changed = write(alpha);
    if (firstSwallowed() >= 0) {  // the stored type's rounding: nothing this tick
      changed = write(0.0);
      alpha = 0.0;
    }
  }
  out.felt_fraction = alpha;
  out.voxels_written = changed;
  if (changed > 0) {
    felt_->refreshRegion(c_lo, c_hi);
    // The rise in F units, rounded up; NaN, or a field whose scale is not positive: unknown (all
    // dropped).
    const double scale = felt_->valueScale();
    renderer.noteFieldChanged(scale > 0.0 ? std::nextafter(scale * max_rise_raw, std::numeric_limits<double>::infinity())
                                          : std::numeric_limits<double>::infinity());
  }
  // The window now held: this one when written in full or in part; the union's old part is at
  // rest only when alpha is 1.
  if (alpha >= 1.0) {
    last_lo_ = lo;
    last_hi_ = hi;
    if (!writes_window) last_hi_ = {-1, -1, -1};
  } else {
    last_lo_ = u_lo;
    last_hi_ = u_hi;
  }
  publishView(phase, changed > 0, out);
  lap(out.write_us);
  out.step_us = std::chrono::duration<double, std::micro>(Clock::now() - start).count();
  return out;
}

}  // namespace vh::tissue
