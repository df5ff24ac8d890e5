#include "vh/runtime/drilling.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <iterator>
#include <limits>
#include <stdexcept>

namespace vh::runtime {

namespace {
std::string lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

constexpr double kMinBurrRadius_m = 0.001, kMaxBurrRadius_m = 0.006;
}  // namespace

bool namesMaterial(const std::string& given, const std::string& name) { return lower(given) == lower(name); }

DrilledCavity cavityOf(const haptics::ScalarVolume& carved, const haptics::ScalarVolume& undrilled,
                       const DrilledCavity* started_from, const std::optional<VoxelBox>& within) {
  if (!carved.geometry().sameGridAs(undrilled.geometry()) || carved.bytes().size() != undrilled.bytes().size())
    throw std::invalid_argument("cavityOf: the carved field and the undrilled one lie on different grids");
  DrilledCavity cavity;
  cavity.grid = carved.geometry();
  const std::size_t n = cavity.grid.voxelCount();
  const std::size_t bytes_per_voxel = n > 0 ? carved.bytes().size() / n : 0;
  const std::byte* a = carved.bytes().data();
  const std::byte* b = undrilled.bytes().data();
  const std::array<int, 3>& dims = cavity.grid.dims;
  VoxelBox box{{0, 0, 0}, {dims[0] - 1, dims[1] - 1, dims[2] - 1}};
  if (within) {
    for (int axis = 0; axis < 3; ++axis) {
      box.lo[axis] = std::max(box.lo[axis], within->lo[axis]);
      box.hi[axis] = std::min(box.hi[axis], within->hi[axis]);
    }
  }
  const std::size_t sy = static_cast<std::size_t>(dims[0]), sz = sy * static_cast<std::size_t>(dims[1]);
  if (n > 0 && box.lo[0] <= box.hi[0] && box.lo[1] <= box.hi[1] && box.lo[2] <= box.hi[2]) {
    for (int k = box.lo[2]; k <= box.hi[2]; ++k)
      for (int j = box.lo[1]; j <= box.hi[1]; ++j) {
        const std::size_t row = static_cast<std::size_t>(k) * sz + static_cast<std::size_t>(j) * sy;
        const std::size_t first = row + static_cast<std::size_t>(box.lo[0]), last = row + static_cast<std::size_t>(box.hi[0]);
        // Most rows are untouched: one comparison of the whole row, then voxel by voxel where it differs.
        if (std::memcmp(a + first * bytes_per_voxel, b + first * bytes_per_voxel, (last - first + 1) * bytes_per_voxel) == 0)
          continue;
        for (std::size_t i = first; i <= last; ++i)
          if (std::memcmp(a + i * bytes_per_voxel, b + i * bytes_per_voxel, bytes_per_voxel) != 0)
            cavity.voxels.push_back(i);
      }
  }
  if (started_from != nullptr && !started_from->voxels.empty()) {
    const std::vector<std::uint64_t> before = cavityVoxelsOn(*started_from, cavity.grid);
    std::vector<std::uint64_t> both;
    both.reserve(before.size() + cavity.voxels.size());
    std::set_union(before.begin(), before.end(), cavity.voxels.begin(), cavity.voxels.end(), std::back_inserter(both));
    cavity.voxels = std::move(both);
  }
  return cavity;
}

std::vector<std::uint64_t> cavityVoxelsOn(const DrilledCavity& cavity, const haptics::VolumeGeometry& grid) {
  if (cavity.grid.sameGridAs(grid) || cavity.voxels.empty()) return cavity.voxels;
  const haptics::VolumeGeometry& c = cavity.grid;
  // The box of the cavity's voxels in its grid, its corners in `grid`'s coordinates.
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
  for (const std::uint64_t index : cavity.voxels) {
    const std::array<int, 3> v = c.voxelOf(index);
    const Eigen::Vector3d ijk(v[0], v[1], v[2]);
    lo = lo.cwiseMin(ijk);
    hi = hi.cwiseMax(ijk);
  }
  const Eigen::Matrix3d grid_from_W = grid.direction_W.inverse(), cavity_from_W = c.direction_W.inverse();
  const auto gridIjk = [&](const Eigen::Vector3d& p_W) {
    return Eigen::Vector3d((grid_from_W * (p_W - grid.origin_W_m)).cwiseQuotient(grid.spacing_m));
  };
  Eigen::Vector3d box_lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity()), box_hi = -box_lo;
  for (int corner = 0; corner < 8; ++corner) {
    const Eigen::Vector3d ijk((corner & 1) ? hi.x() + 0.5 : lo.x() - 0.5, (corner & 2) ? hi.y() + 0.5 : lo.y() - 0.5,
                              (corner & 4) ? hi.z() + 0.5 : lo.z() - 0.5);
    const Eigen::Vector3d q = gridIjk(c.pointOf_W(ijk));
    box_lo = box_lo.cwiseMin(q);
    box_hi = box_hi.cwiseMax(q);
  }
  int from[3], to[3];
  for (int a = 0; a < 3; ++a) {
    from[a] = static_cast<int>(std::max(0.0, std::floor(box_lo[a])));
    to[a] = static_cast<int>(std::min(static_cast<double>(grid.dims[a] - 1), std::ceil(box_hi[a])));
  }
  std::vector<std::uint64_t> out;
  for (int k = from[2]; k <= to[2]; ++k)
    for (int j = from[1]; j <= to[1]; ++j)
      for (int i = from[0]; i <= to[0]; ++i) {
        const Eigen::Vector3d q =
            (cavity_from_W * (grid.pointOf_W(Eigen::Vector3d(i, j, k)) - c.origin_W_m)).cwiseQuotient(c.spacing_m);
        const long a = std::lround(q.x()), b = std::lround(q.y()), d = std::lround(q.z());
        if (a < 0 || b < 0 || d < 0 || a >= c.dims[0] || b >= c.dims[1] || d >= c.dims[2]) continue;
        if (std::binary_search(cavity.voxels.begin(), cavity.voxels.end(), c.indexOf(a, b, d)))
          out.push_back(grid.indexOf(i, j, k));
      }
  return out;
}

Burr burrOf(const haptics::ToolModel& tool, const DrillSpec& spec) {
  Burr burr;
  if (spec.burr_radius_m != 0.0) {
    if (!(spec.burr_radius_m >= kMinBurrRadius_m && spec.burr_radius_m <= kMaxBurrRadius_m))
      throw std::invalid_argument("drill.burr_radius_m: expected 0.001 to 0.006 m (1 to 6 mm), found " +
                                  std::to_string(spec.burr_radius_m));
    burr.radius_m = spec.burr_radius_m;
  }
  if (spec.burr_center_T_m) {
    if (!spec.burr_center_T_m->allFinite()) throw std::invalid_argument("drill.burr_center_T_m: not finite");
    burr.center_T_m = *spec.burr_center_T_m;
    return burr;
  }
  // The tip: the mesh vertex (else shell point) farthest from the centre of mass.
  const Eigen::Vector3d com = tool.mass.p_TCm_m;
  const auto& vertices = tool.mesh_T.vertices_T_m.empty() ? tool.point_shell.points_T_m() : tool.mesh_T.vertices_T_m;
  Eigen::Vector3d tip = com;
  double far = -1.0;
  for (const auto& v : vertices) {
    const double d = (v - com).squaredNorm();
    if (d > far) far = d, tip = v;
  }
  const Eigen::Vector3d inward = com - tip;
  burr.center_T_m = inward.norm() > burr.radius_m ? Eigen::Vector3d(tip + burr.radius_m * inward.normalized()) : com;
  return burr;
}

namespace {

/// The HU class of a scan value: 0 soft tissue, 1 cancellous bone, 2 cortical bone; 0 (one class)
/// without Hounsfield units.
std::uint8_t huClassOf(double value, bool hounsfield) {
  if (!hounsfield) return 0;
  return value >= kCorticalFrom_HU ? 2 : value >= kCancellousFrom_HU ? 1 : 0;
}

/// The scene's hardness overrides (drill.hardness) by lower-case material or segment name, and
/// which of them a material used.
class HardnessOverrides {
 public:
  /// @throws std::invalid_argument for a specific energy that is not > 0 and finite.
  explicit HardnessOverrides(const DrillSpec& spec) {
    for (const auto& [name, e] : spec.hardness_J_per_mm3) {
      if (!(e > 0.0) || !std::isfinite(e))
        throw std::invalid_argument("drill.hardness." + name + ": expected a specific energy > 0 J/mm^3");
      hardness_[lower(name)] = e;
    }
  }

  /// The override for the material `name` (else its segment `id`), or `fallback` [J/mm^3].
  double energyOf(const std::string& name, const std::string& id, double fallback) {
    for (const std::string& key : {lower(name), lower(id)}) {
      const auto it = hardness_.find(key);
      if (!key.empty() && it != hardness_.end()) {
        used_[key] = true;
        return it->second;
      }
    }
    return fallback;
  }

  /// @throws std::invalid_argument listing `materials` when an override names none of them.
  void requireAllUsed(const std::vector<haptics::CuttingMaterial>& materials) const {
    for (const auto& [key, e] : hardness_)
      if (!used_.count(key))
        throw std::invalid_argument("drill.hardness: '" + key + "' names no material of this scene (" +
                                    [&] {
                                      std::string list;
                                      for (const auto& m : materials) list += (list.empty() ? "" : ", ") + m.name;
                                      return list;
                                    }() +
                                    ")");
  }

 private:
  std::map<std::string, double> hardness_;
  std::map<std::string, bool> used_;
};

/// The scan's value at the felt grid's voxel centres (the voxel itself when both share a grid).
struct ScanAtFeltVoxels {
  const haptics::VolumeGeometry& g;  // the felt field's grid
  const haptics::ScalarVolume& scan;
  bool same_grid;
  Eigen::Vector3d centre(int i, int j, int k) const { return g.pointOf_W(Eigen::Vector3d(i, j, k)); }
  double value(int i, int j, int k) const { return same_grid ? scan.voxel(i, j, k) : scan.sample(centre(i, j, k)); }
};

/// First pass over the felt grid: each voxel's segment (stored as segment + 1, 0 none: the label
/// of the nearest segmentation voxel), and per segment the sum of its scan values and its count.
std::vector<std::uint16_t> segmentOfVoxels(const ScanAtFeltVoxels& scan, const io::LoadedSegmentation& seg,
                                           std::vector<double>& sum, std::vector<std::size_t>& count) {
  const auto& g = scan.g;
  std::vector<std::uint16_t> segment_of_voxel(g.voxelCount(), 0);
  std::size_t idx = 0;
  std::array<int, 3> v{};
  for (int k = 0; k < g.dims[2]; ++k)
    for (int j = 0; j < g.dims[1]; ++j)
      for (int i = 0; i < g.dims[0]; ++i, ++idx) {
        if (!seg.nearestVoxel(scan.centre(i, j, k), v)) continue;
        for (std::size_t s = 0; s < seg.segments.size() && s < 65535; ++s) {
          const auto& info = seg.segments[s];
          if (seg.label(info.layer, v[0], v[1], v[2]) == info.label_value) {
            segment_of_voxel[idx] = static_cast<std::uint16_t>(s + 1);
            sum[s] += scan.value(i, j, k);
            ++count[s];
            break;
          }
        }
      }
  return segment_of_voxel;
}

/// One material per segment with voxels (critical segments critical; at most 255 materials in
/// all), its specific energy the override or that of its mean value's HU class.
/// @return each segment's material, -1 for none.
std::vector<int> addSegmentMaterials(DrillMaterials& out, const SegmentSet& segments, const io::LoadedSegmentation& seg,
                                     const std::vector<double>& sum, const std::vector<std::size_t>& count,
                                     HardnessOverrides& hardness, bool hounsfield) {
  std::vector<int> material_of_segment(seg.segments.size(), -1);
  for (std::size_t s = 0; s < seg.segments.size(); ++s) {
    if (count[s] == 0 || out.materials.size() >= 255) continue;
    const auto& info = seg.segments[s];
    const double mean = sum[s] / static_cast<double>(count[s]);
    const double fallback = out.materials[huClassOf(mean, hounsfield)].specific_energy_J_per_mm3;
    material_of_segment[s] = static_cast<int>(out.materials.size());
    out.materials.push_back({info.name, hardness.energyOf(info.name, info.id, fallback),
                             segments.isCritical(static_cast<int>(s))});
    out.segment_of_material.push_back(static_cast<int>(s));
  }
  return material_of_segment;
}

}  // namespace

DrillMaterials makeDrillMaterials(const haptics::ScalarVolume& felt, const haptics::ScalarVolume& scan, bool hounsfield,
                                  const SegmentSet* segments, const DrillSpec& spec) {
  DrillMaterials out;
  HardnessOverrides hardness(spec);
  // The HU classes (or one class), materials 0..2 (or 0).
  if (hounsfield) {
    out.materials.push_back({"soft tissue", hardness.energyOf("soft tissue", "", kSoftTissue_J_per_mm3), false});
    out.materials.push_back(
        {"cancellous bone", hardness.energyOf("cancellous bone", "", kCancellousBone_J_per_mm3), false});
    out.materials.push_back({"cortical bone", hardness.energyOf("cortical bone", "", kCorticalBone_J_per_mm3), false});
  } else {
    out.materials.push_back({"tissue", hardness.energyOf("tissue", "", kTissue_J_per_mm3), false});
  }
  out.segment_of_material.assign(out.materials.size(), -1);

  const auto& g = felt.geometry();
  const std::size_t n = g.voxelCount();
  out.voxel_material.resize(n);
  const ScanAtFeltVoxels scan_at{g, scan, &felt == &scan || g.sameGridAs(scan.geometry())};

  // Segments: one material each (critical ones critical), the label of the nearest voxel.
  const io::LoadedSegmentation* seg = segments != nullptr ? &segments->segmentation() : nullptr;
  if (seg != nullptr && !seg->layers.empty()) {
    std::vector<double> sum(seg->segments.size(), 0.0);
    std::vector<std::size_t> count(seg->segments.size(), 0);
    const std::vector<std::uint16_t> segment_of_voxel = segmentOfVoxels(scan_at, *seg, sum, count);
    const std::vector<int> material_of_segment =
        addSegmentMaterials(out, *segments, *seg, sum, count, hardness, hounsfield);
    std::size_t idx = 0;
    for (int k = 0; k < g.dims[2]; ++k)
      for (int j = 0; j < g.dims[1]; ++j)
        for (int i = 0; i < g.dims[0]; ++i, ++idx) {
          const int s = static_cast<int>(segment_of_voxel[idx]) - 1;
          const int m = s >= 0 ? material_of_segment[static_cast<std::size_t>(s)] : -1;
          out.voxel_material[idx] = m >= 0 ? static_cast<std::uint8_t>(m) : huClassOf(scan_at.value(i, j, k), hounsfield);
        }
  } else {
    std::size_t idx = 0;
    for (int k = 0; k < g.dims[2]; ++k)
      for (int j = 0; j < g.dims[1]; ++j)
        for (int i = 0; i < g.dims[0]; ++i, ++idx) out.voxel_material[idx] = huClassOf(scan_at.value(i, j, k), hounsfield);
  }
  hardness.requireAllUsed(out.materials);
  return out;
}

Drill::Drill(std::shared_ptr<haptics::MaterialRemoval> removal, Burr burr, double dt_s,
             std::vector<int> segment_of_material, std::shared_ptr<const DrilledCavity> cavity_at_start)
    : removal_(std::move(removal)), burr_(burr), dt_s_(dt_s), segment_of_material_(std::move(segment_of_material)),
      cavity_at_start_(std::move(cavity_at_start)) {
  if (removal_ == nullptr) throw std::invalid_argument("Drill: no material removal");
  if (!(dt_s_ > 0.0) || !std::isfinite(dt_s_)) throw std::invalid_argument("Drill: the period must be > 0 s");
}

bool Drill::burrTouches(const haptics::HapticRenderer& renderer) const noexcept {
  const Eigen::Vector3d c_W = renderer.proxyPose() * burr_.center_T_m;
  const double on_burr_m = burr_.radius_m + 2.0 * renderer.epsilon_m();
  for (const haptics::Contact& contact : renderer.contacts())
    if ((contact.p_W_m - c_W).norm() <= on_burr_m) return true;
  return false;
}

haptics::CutResult Drill::step(const haptics::HapticRenderer& renderer, const haptics::TickOutput& out) noexcept {
  const Eigen::Vector3d c_W = renderer.proxyPose() * burr_.center_T_m;
  return removal_->cut(c_W, burr_.radius_m, out.force_W_N.norm(), dt_s_, renderer.feltIsovalue(), burrTouches(renderer));
}

PreparedDrill prepareDrill(const haptics::ScalarVolume& felt, DrillMaterials materials, const DrillSpec& spec) {
  if (!(spec.burr_speed_rpm > 0.0) || !std::isfinite(spec.burr_speed_rpm))
    throw std::invalid_argument("drill.burr_speed_rpm: expected a speed > 0");
  auto copy = std::make_shared<haptics::ScalarVolume>(felt);  // the renderer's own, carved
  haptics::RemovalModel model;
  model.burr_speed_rad_per_s = spec.burr_speed_rpm * 2.0 * 3.14159265358979323846 / 60.0;
  PreparedDrill out;
  out.removal = std::make_shared<haptics::MaterialRemoval>(std::move(copy), std::move(materials.voxel_material),
                                                           std::move(materials.materials), model);
  // The cavity drilled before this renderer, removed before it first reads its field.
  if (spec.cavity != nullptr)
    out.removal->removeCavity(cavityVoxelsOn(*spec.cavity, out.removal->volume().geometry()));
  out.segment_of_material = std::move(materials.segment_of_material);
  out.cavity = spec.cavity;
  return out;
}

std::size_t catchUpCavity(const Drill& old_drill, const haptics::ScalarVolume& undrilled,
                          std::shared_ptr<const DrilledCavity>& cavity, PreparedDrill& prepared) {
  if (prepared.removal == nullptr) throw std::invalid_argument("catchUpCavity: the prepared drill has no removal");
  VoxelBox cut;
  if (!old_drill.removal().cutsSinceMark(cut.lo, cut.hi)) return 0;
  // The cavity and what differs from `undrilled` in the box cut since the mark: the new part is
  // what the burr cut after `prepared` was built.
  auto grown = std::make_shared<DrilledCavity>(cavityOf(old_drill.removal().volume(), undrilled, cavity.get(), cut));
  std::vector<std::uint64_t> added;
  if (cavity != nullptr) {
    std::set_difference(grown->voxels.begin(), grown->voxels.end(), cavity->voxels.begin(), cavity->voxels.end(),
                        std::back_inserter(added));
  } else {
    added = grown->voxels;
  }
  if (added.empty()) return 0;
  const std::size_t removed = prepared.removal->removeCavity(added);
  cavity = grown;
  prepared.cavity = std::move(grown);
  return removed;
}

DrillingRenderer makeDrillingRenderer(PreparedDrill prepared, double felt_isovalue,
                                      std::shared_ptr<const haptics::ToolModel> tool, const DrillSpec& spec,
                                      const haptics::RendererOptions& options, const haptics::Pose& X_WP,
                                      double servo_rate_Hz) {
  if (tool == nullptr) throw std::invalid_argument("drilling needs a tool");
  if (prepared.removal == nullptr) throw std::invalid_argument("drilling: the prepared drill has no removal");
  const Burr burr = burrOf(*tool, spec);
  DrillingRenderer out;
  out.renderer = std::make_unique<haptics::HapticRenderer>(prepared.removal->sharedVolume(), std::move(tool), options,
                                                           X_WP, felt_isovalue);
  out.drill = std::make_shared<Drill>(std::move(prepared.removal), burr, 1.0 / servo_rate_Hz,
                                      std::move(prepared.segment_of_material), std::move(prepared.cavity));
  return out;
}

}  // namespace vh::runtime
