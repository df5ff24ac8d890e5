#include "vh/haptics/material_removal.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace vh::haptics {

MaterialRemoval::MaterialRemoval(std::shared_ptr<ScalarVolume> volume, std::vector<std::uint8_t> voxel_material,
                                 std::vector<CuttingMaterial> materials, const RemovalModel& model)
    : volume_(std::move(volume)), voxel_material_(std::move(voxel_material)), materials_(std::move(materials)),
      model_(model) {
  if (volume_ == nullptr || volume_->empty()) throw std::invalid_argument("MaterialRemoval: no volume to carve");
  const std::size_t n = volume_->geometry().voxelCount();
  if (materials_.empty() || materials_.size() > 255)
    throw std::invalid_argument("MaterialRemoval: 1 to 255 materials expected, got " + std::to_string(materials_.size()));
  for (const auto& m : materials_)
    if (!(m.specific_energy_J_per_mm3 > 0.0) || !std::isfinite(m.specific_energy_J_per_mm3))
      throw std::invalid_argument("MaterialRemoval: material '" + m.name + "' needs a finite specific energy > 0 J/mm^3");
  if (!voxel_material_.empty()) {
    if (voxel_material_.size() != n)
      throw std::invalid_argument("MaterialRemoval: " + std::to_string(voxel_material_.size()) +
                                  " voxel materials for " + std::to_string(n) + " voxels");
    const auto top = *std::max_element(voxel_material_.begin(), voxel_material_.end());
    if (top >= materials_.size())
      throw std::invalid_argument("MaterialRemoval: voxel material " + std::to_string(top) + " but only " +
                                  std::to_string(materials_.size()) + " materials");
  }
  if (!(model_.burr_speed_rad_per_s > 0.0) || !std::isfinite(model_.burr_speed_rad_per_s))
    throw std::invalid_argument("MaterialRemoval: the burr speed must be finite and > 0 rad/s");
  if (model_.log_capacity == 0) throw std::invalid_argument("MaterialRemoval: the removal log needs a capacity");
  const Eigen::Vector3d s_mm = 1e3 * volume_->geometry().spacing_m;
  voxel_mm3_ = s_mm.prod();
  for (std::size_t m = 0; m < materials_.size(); ++m)
    energy_J_per_voxel_[m].store(materials_[m].specific_energy_J_per_mm3 * voxel_mm3_, std::memory_order_relaxed);
  removed_raw_ = volume_->lowestRaw();
  remaining_.resize(n);
  for (std::size_t i = 0; i < n; ++i) remaining_[i] = volume_->rawAt(i) == removed_raw_ ? 0 : kWhole;
  log_.resize(model_.log_capacity);
}

void MaterialRemoval::setSpecificEnergy(int material, double J_per_mm3) noexcept {
  if (material < 0 || static_cast<std::size_t>(material) >= materials_.size() || !(J_per_mm3 > 0.0) ||
      !std::isfinite(J_per_mm3))
    return;
  energy_J_per_voxel_[static_cast<std::size_t>(material)].store(J_per_mm3 * voxel_mm3_, std::memory_order_relaxed);
}

std::size_t MaterialRemoval::removeCavity(std::span<const std::uint64_t> voxels) noexcept {
  ScalarVolume& v = *volume_;
  const VolumeGeometry& g = v.geometry();
  std::array<int, 3> lo = g.dims, hi = {-1, -1, -1};
  std::size_t removed = 0;
  for (const std::uint64_t index : voxels) {
    if (index >= remaining_.size() || remaining_[index] == 0) continue;
    remaining_[index] = 0;
    v.writeRaw(index, removed_raw_);
    ++removed;
    const std::array<int, 3> ijk = g.voxelOf(index);
    for (int a = 0; a < 3; ++a) {
      lo[a] = std::min(lo[a], ijk[a]);
      hi[a] = std::max(hi[a], ijk[a]);
    }
  }
  if (removed > 0) v.refreshRegion(lo, hi);
  return removed;
}

std::uint64_t MaterialRemoval::removedVoxels() const noexcept {
  std::uint64_t total = 0;
  for (std::size_t m = 0; m < materials_.size(); ++m) total += removed_[m].load(std::memory_order_relaxed);
  return total;
}

void MaterialRemoval::gatherReach(const Eigen::Vector3d& c, double reach, double raw_threshold, bool rising,
                                  BurrReach& r) const noexcept {
  const ScalarVolume& v = *volume_;
  const VolumeGeometry& g = v.geometry();
  const Eigen::Vector3d& s = g.spacing_m;
  const std::ptrdiff_t sy = g.dims[0], sz = static_cast<std::ptrdiff_t>(g.dims[0]) * g.dims[1];
  r.sum_w = 0.0;
  r.count = 0;
  r.felt = false;
  r.nearest_felt = std::numeric_limits<double>::infinity();
  for (int a = 0; a < 3; ++a) {
    r.lo[a] = static_cast<int>(std::max(0.0, std::ceil(c[a] - reach / s[a])));
    r.hi[a] = static_cast<int>(std::min(static_cast<double>(g.dims[a] - 1), std::floor(c[a] + reach / s[a])));
  }
  for (int k = r.lo[2]; k <= r.hi[2]; ++k)
    for (int j = r.lo[1]; j <= r.hi[1]; ++j)
      for (int i = r.lo[0]; i <= r.hi[0]; ++i) {
        const std::size_t idx = static_cast<std::size_t>(i + j * sy + k * sz);
        if (remaining_[idx] == 0) continue;
        const double d = Eigen::Vector3d((i - c[0]) * s[0], (j - c[1]) * s[1], (k - c[2]) * s[2]).norm();
        if (d >= reach) continue;
        r.sum_w += reach - d;
        ++r.count;
        const double raw = v.rawAt(idx);
        if (rising ? raw > raw_threshold : raw < raw_threshold) {
          r.felt = true;
          r.nearest_felt = std::min(r.nearest_felt, d);
        }
      }
}

bool MaterialRemoval::feltReach(const Eigen::Vector3d& c, double burr_radius_m, double raw_threshold, bool rising,
                                double& reach, BurrReach& r, bool& widened) const noexcept {
  const Eigen::Vector3d& s = volume_->geometry().spacing_m;
  reach = burr_radius_m;
  gatherReach(c, reach, raw_threshold, rising, r);
  if (r.felt) return true;
  // The surface touches the burr but its voxels lie farther: cut the nearest layer of them
  // (a quarter voxel beyond the nearest), at most one voxel diagonal beyond the burr.
  gatherReach(c, burr_radius_m + s.norm(), raw_threshold, rising, r);
  if (!r.felt) return false;
  reach = std::min(r.nearest_felt + 0.25 * s.minCoeff(), burr_radius_m + s.norm());
  gatherReach(c, reach, raw_threshold, rising, r);
  widened = true;
  return true;
}

void MaterialRemoval::removeVoxel(std::size_t idx, int m, std::uint64_t& head, std::uint64_t tail,
                                  CutResult& result) noexcept {
  volume_->writeRaw(idx, removed_raw_);
  removed_[static_cast<std::size_t>(m)].fetch_add(1, std::memory_order_relaxed);
  ++result.voxels_removed;
  if (materials_[static_cast<std::size_t>(m)].critical) {
    ++result.critical_removed;
    if (result.critical_material < 0) result.critical_material = m;
  }
  if (head - tail < log_.size()) {
    log_[head % log_.size()] = idx;
    ++head;
  } else {
    dropped_.fetch_add(1, std::memory_order_relaxed);
  }
}

void MaterialRemoval::shareEnergy(const Eigen::Vector3d& c, double reach, const BurrReach& r, double energy_J,
                                  CutResult& result, std::array<int, 3>& changed_lo,
                                  std::array<int, 3>& changed_hi) noexcept {
  const VolumeGeometry& g = volume_->geometry();
  const Eigen::Vector3d& s = g.spacing_m;
  const std::ptrdiff_t sy = g.dims[0], sz = static_cast<std::ptrdiff_t>(g.dims[0]) * g.dims[1];
  double hardness_w = 0.0;  // sum of weight x energy per voxel, over the voxels in reach
  double deepest_w = 0.0;   // the largest weight so far: its voxel's material is the cut's
  std::uint64_t head = head_.load(std::memory_order_relaxed);
  const std::uint64_t tail = tail_.load(std::memory_order_acquire);
  for (int k = r.lo[2]; k <= r.hi[2]; ++k)
    for (int j = r.lo[1]; j <= r.hi[1]; ++j)
      for (int i = r.lo[0]; i <= r.hi[0]; ++i) {
        const std::size_t idx = static_cast<std::size_t>(i + j * sy + k * sz);
        std::uint16_t& left = remaining_[idx];
        if (left == 0) continue;
        const double d = Eigen::Vector3d((i - c[0]) * s[0], (j - c[1]) * s[1], (k - c[2]) * s[2]).norm();
        if (d >= reach) continue;
        const int m = materialOf(idx);
        const double voxel_J = energy_J_per_voxel_[static_cast<std::size_t>(m)].load(std::memory_order_relaxed);
        hardness_w += (reach - d) * voxel_J;
        if (reach - d > deepest_w) {
          deepest_w = reach - d;
          result.material = m;
        }
        const double fraction = energy_J * (reach - d) / r.sum_w / voxel_J;
        // Rounded down, the remainder carried to the next voxel (and tick): the removed material
        // never exceeds the energy delivered, and a light press on hard bone still cuts.
        const double exact = std::min(fraction, 1.0) * kWhole + carry_;
        const double step = std::floor(exact);
        carry_ = exact - step;
        if (step < left) {
          left = static_cast<std::uint16_t>(left - static_cast<std::uint16_t>(step));
          eroded_ += static_cast<std::uint64_t>(step);
          continue;
        }
        eroded_ += left;
        left = 0;
        removeVoxel(idx, m, head, tail, result);
        const int ijk[3] = {i, j, k};
        for (int a = 0; a < 3; ++a) {
          changed_lo[a] = std::min(changed_lo[a], ijk[a]);
          changed_hi[a] = std::max(changed_hi[a], ijk[a]);
        }
      }
  head_.store(head, std::memory_order_release);
  if (r.sum_w > 0.0) result.specific_energy_J_per_mm3 = hardness_w / r.sum_w / voxel_mm3_;
}

CutResult MaterialRemoval::cut(const Eigen::Vector3d& burr_center_W_m, double burr_radius_m, double force_N,
                               double dt_s, double isovalue, bool burr_touches) noexcept {
  CutResult result;
  if (!burr_touches || !burr_center_W_m.allFinite() || !(burr_radius_m > 0.0) || !std::isfinite(burr_radius_m) ||
      !(force_N > 0.0) || !std::isfinite(force_N) || !(dt_s > 0.0) || !std::isfinite(dt_s))
    return result;
  ScalarVolume& v = *volume_;
  const VolumeGeometry& g = v.geometry();
  const Eigen::Vector3d c = v.gridCoordinates(burr_center_W_m);
  const double raw_threshold = (isovalue - v.valueOffset()) / v.valueScale();  // raw above (or below) it is felt
  const bool rising = v.valueScale() > 0.0;
  // The box of voxel centres is empty when the burr is far outside the grid.
  if (!c.allFinite() || (c.array() < -1e6).any() || (c.array() > 1e9).any()) return result;
  double reach = 0.0;
  BurrReach in_reach;
  if (!feltReach(c, burr_radius_m, raw_threshold, rising, reach, in_reach, result.widened)) return result;
  const double energy_J = force_N * model_.burr_speed_rad_per_s * burr_radius_m * dt_s;
  result.energy_J = energy_J;
  std::array<int, 3> changed_lo = {g.dims[0], g.dims[1], g.dims[2]}, changed_hi = {-1, -1, -1};
  shareEnergy(c, reach, in_reach, energy_J, result, changed_lo, changed_hi);
  if (result.voxels_removed > 0) {
    v.refreshRegion(changed_lo, changed_hi);
    for (int a = 0; a < 3; ++a) {
      cut_lo_[a] = std::min(cut_lo_[a], changed_lo[a]);
      cut_hi_[a] = std::max(cut_hi_[a], changed_hi[a]);
    }
  }
  return result;
}

void MaterialRemoval::markCuts() noexcept {
  cut_lo_ = kNoCutLo;
  cut_hi_ = kNoCutHi;
}

bool MaterialRemoval::cutsSinceMark(std::array<int, 3>& lo, std::array<int, 3>& hi) const noexcept {
  if (cut_hi_[0] < cut_lo_[0]) return false;
  lo = cut_lo_;
  hi = cut_hi_;
  return true;
}

std::size_t MaterialRemoval::drainRemoved(std::span<std::uint64_t> out) noexcept {
  const std::uint64_t head = head_.load(std::memory_order_acquire);
  std::uint64_t tail = tail_.load(std::memory_order_relaxed);
  std::size_t n = 0;
  while (tail < head && n < out.size()) out[n++] = log_[tail++ % log_.size()];
  tail_.store(tail, std::memory_order_release);
  return n;
}

}  // namespace vh::haptics
