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

CutResult MaterialRemoval::cut(const Eigen::Vector3d& burr_center_W_m, double burr_radius_m, double force_N,
                               double dt_s, double isovalue, bool burr_touches) noexcept {
  CutResult result;
  if (!burr_touches || !burr_center_W_m.allFinite() || !(burr_radius_m > 0.0) || !std::isfinite(burr_radius_m) ||
      !(force_N > 0.0) || !std::isfinite(force_N) || !(dt_s > 0.0) || !std::isfinite(dt_s))
    return result;
  ScalarVolume& v = *volume_;
  const VolumeGeometry& g = v.geometry();
  const Eigen::Vector3d c = v.gridCoordinates(burr_center_W_m);
  const Eigen::Vector3d& s = g.spacing_m;
  const double raw_threshold = (isovalue - v.valueOffset()) / v.valueScale();  // raw above (or below) it is felt
  const bool rising = v.valueScale() > 0.0;
  const std::ptrdiff_t sy = g.dims[0], sz = static_cast<std::ptrdiff_t>(g.dims[0]) * g.dims[1];

  int lo[3], hi[3];
  double sum_w = 0.0;
  int count = 0;
  bool felt = false;
  double nearest_felt = std::numeric_limits<double>::infinity();  // centre distance of the nearest felt voxel
  // One pass over the voxels within `reach` of the centre: their count, weights, and whether
  // (and how near) one of them is felt.
  const auto gather = [&](double reach) {
    sum_w = 0.0;
    count = 0;
    felt = false;
    nearest_felt = std::numeric_limits<double>::infinity();
    for (int a = 0; a < 3; ++a) {
      lo[a] = static_cast<int>(std::max(0.0, std::ceil(c[a] - reach / s[a])));
      hi[a] = static_cast<int>(std::min(static_cast<double>(g.dims[a] - 1), std::floor(c[a] + reach / s[a])));
    }
    for (int k = lo[2]; k <= hi[2]; ++k)
      for (int j = lo[1]; j <= hi[1]; ++j)
        for (int i = lo[0]; i <= hi[0]; ++i) {
          const std::size_t idx = static_cast<std::size_t>(i + j * sy + k * sz);
          if (remaining_[idx] == 0) continue;
          const double d = Eigen::Vector3d((i - c[0]) * s[0], (j - c[1]) * s[1], (k - c[2]) * s[2]).norm();
          if (d >= reach) continue;
          sum_w += reach - d;
          ++count;
          const double raw = v.rawAt(idx);
          if (rising ? raw > raw_threshold : raw < raw_threshold) {
            felt = true;
            nearest_felt = std::min(nearest_felt, d);
          }
        }
  };
  // The box of voxel centres is empty when the burr is far outside the grid.
  if (!c.allFinite() || (c.array() < -1e6).any() || (c.array() > 1e9).any()) return result;
  double reach = burr_radius_m;
  gather(reach);
  if (!felt) {
    // The surface touches the burr but its voxels lie farther: cut the nearest layer of them
    // (a quarter voxel beyond the nearest), at most one voxel diagonal beyond the burr.
    gather(burr_radius_m + s.norm());
    if (!felt) return result;
    reach = std::min(nearest_felt + 0.25 * s.minCoeff(), burr_radius_m + s.norm());
    gather(reach);
    result.widened = true;
  }
  const double energy_J = force_N * model_.burr_speed_rad_per_s * burr_radius_m * dt_s;
  result.energy_J = energy_J;
  double hardness_w = 0.0;  // sum of weight x energy per voxel, over the voxels in reach
  int changed_lo[3] = {g.dims[0], g.dims[1], g.dims[2]}, changed_hi[3] = {-1, -1, -1};
  std::uint64_t head = head_.load(std::memory_order_relaxed);
  const std::uint64_t tail = tail_.load(std::memory_order_acquire);
  for (int k = lo[2]; k <= hi[2]; ++k)
    for (int j = lo[1]; j <= hi[1]; ++j)
      for (int i = lo[0]; i <= hi[0]; ++i) {
        const std::size_t idx = static_cast<std::size_t>(i + j * sy + k * sz);
        std::uint16_t& left = remaining_[idx];
        if (left == 0) continue;
        const double d = Eigen::Vector3d((i - c[0]) * s[0], (j - c[1]) * s[1], (k - c[2]) * s[2]).norm();
        if (d >= reach) continue;
        const int m = materialOf(idx);
        const double voxel_J = energy_J_per_voxel_[static_cast<std::size_t>(m)].load(std::memory_order_relaxed);
        hardness_w += (reach - d) * voxel_J;
        const double fraction = energy_J * (reach - d) / sum_w / voxel_J;
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
        v.writeRaw(idx, removed_raw_);
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
        const int ijk[3] = {i, j, k};
        for (int a = 0; a < 3; ++a) {
          changed_lo[a] = std::min(changed_lo[a], ijk[a]);
          changed_hi[a] = std::max(changed_hi[a], ijk[a]);
        }
      }
  head_.store(head, std::memory_order_release);
  if (sum_w > 0.0) result.specific_energy_J_per_mm3 = hardness_w / sum_w / voxel_mm3_;
  if (result.voxels_removed > 0) {
    v.refreshRegion({changed_lo[0], changed_lo[1], changed_lo[2]}, {changed_hi[0], changed_hi[1], changed_hi[2]});
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
