#include "vh/runtime/drilling.h"

#include <algorithm>
#include <cctype>
#include <cmath>
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

DrillMaterials makeDrillMaterials(const haptics::ScalarVolume& felt, const haptics::ScalarVolume& scan, bool hounsfield,
                                  const SegmentSet* segments, const DrillSpec& spec) {
  DrillMaterials out;
  std::map<std::string, double> hardness;
  for (const auto& [name, e] : spec.hardness_J_per_mm3) {
    if (!(e > 0.0) || !std::isfinite(e))
      throw std::invalid_argument("drill.hardness." + name + ": expected a specific energy > 0 J/mm^3");
    hardness[lower(name)] = e;
  }
  std::map<std::string, bool> used;
  const auto energyOf = [&](const std::string& name, const std::string& id, double fallback) {
    for (const std::string& key : {lower(name), lower(id)}) {
      const auto it = hardness.find(key);
      if (!key.empty() && it != hardness.end()) {
        used[key] = true;
        return it->second;
      }
    }
    return fallback;
  };
  // The HU classes (or one class), materials 0..2 (or 0).
  const auto classOf = [&](double value) -> std::uint8_t {
    if (!hounsfield) return 0;
    return value >= kCorticalFrom_HU ? 2 : value >= kCancellousFrom_HU ? 1 : 0;
  };
  if (hounsfield) {
    out.materials.push_back({"soft tissue", energyOf("soft tissue", "", kSoftTissue_J_per_mm3), false});
    out.materials.push_back({"cancellous bone", energyOf("cancellous bone", "", kCancellousBone_J_per_mm3), false});
    out.materials.push_back({"cortical bone", energyOf("cortical bone", "", kCorticalBone_J_per_mm3), false});
  } else {
    out.materials.push_back({"tissue", energyOf("tissue", "", kTissue_J_per_mm3), false});
  }
  out.segment_of_material.assign(out.materials.size(), -1);

  const auto& g = felt.geometry();
  const std::size_t n = g.voxelCount();
  out.voxel_material.resize(n);
  const bool same_grid = &felt == &scan || (felt.geometry().dims == scan.geometry().dims &&
                                            felt.geometry().origin_W_m == scan.geometry().origin_W_m &&
                                            felt.geometry().spacing_m == scan.geometry().spacing_m &&
                                            felt.geometry().direction_W == scan.geometry().direction_W);
  const auto centre = [&](int i, int j, int k) {
    return Eigen::Vector3d(g.origin_W_m + g.direction_W * g.spacing_m.cwiseProduct(Eigen::Vector3d(i, j, k)));
  };
  const auto scanValue = [&](int i, int j, int k) {
    return same_grid ? scan.voxel(i, j, k) : scan.sample(centre(i, j, k));
  };

  // Segments: one material each (critical ones critical), the label of the nearest voxel.
  std::vector<int> material_of_segment;
  const io::LoadedSegmentation* seg = segments != nullptr ? &segments->segmentation() : nullptr;
  if (seg != nullptr && !seg->layers.empty()) {
    std::vector<double> sum(seg->segments.size(), 0.0);
    std::vector<std::size_t> count(seg->segments.size(), 0);
    // First pass: each voxel's segment (stored as segment + 1, 0 none) and the segments' mean value.
    std::vector<std::uint16_t> segment_of_voxel(n, 0);
    const haptics::ScalarVolume& grid = *seg->layers.front();
    const auto& sd = grid.geometry().dims;
    std::size_t idx = 0;
    for (int k = 0; k < g.dims[2]; ++k)
      for (int j = 0; j < g.dims[1]; ++j)
        for (int i = 0; i < g.dims[0]; ++i, ++idx) {
          const Eigen::Vector3d q = grid.gridCoordinates(centre(i, j, k));
          const int a = static_cast<int>(std::lround(q.x())), b = static_cast<int>(std::lround(q.y())),
                    c = static_cast<int>(std::lround(q.z()));
          if (a < 0 || b < 0 || c < 0 || a >= sd[0] || b >= sd[1] || c >= sd[2]) continue;
          for (std::size_t s = 0; s < seg->segments.size() && s < 65535; ++s) {
            const auto& info = seg->segments[s];
            if (seg->label(info.layer, a, b, c) == info.label_value) {
              segment_of_voxel[idx] = static_cast<std::uint16_t>(s + 1);
              sum[s] += scanValue(i, j, k);
              ++count[s];
              break;
            }
          }
        }
    material_of_segment.assign(seg->segments.size(), -1);
    for (std::size_t s = 0; s < seg->segments.size(); ++s) {
      if (count[s] == 0 || out.materials.size() >= 255) continue;
      const auto& info = seg->segments[s];
      const double mean = sum[s] / static_cast<double>(count[s]);
      const double fallback = out.materials[classOf(mean)].specific_energy_J_per_mm3;
      material_of_segment[s] = static_cast<int>(out.materials.size());
      out.materials.push_back({info.name, energyOf(info.name, info.id, fallback),
                               segments->isCritical(static_cast<int>(s))});
      out.segment_of_material.push_back(static_cast<int>(s));
    }
    idx = 0;
    for (int k = 0; k < g.dims[2]; ++k)
      for (int j = 0; j < g.dims[1]; ++j)
        for (int i = 0; i < g.dims[0]; ++i, ++idx) {
          const int s = static_cast<int>(segment_of_voxel[idx]) - 1;
          const int m = s >= 0 ? material_of_segment[static_cast<std::size_t>(s)] : -1;
          out.voxel_material[idx] = m >= 0 ? static_cast<std::uint8_t>(m) : classOf(scanValue(i, j, k));
        }
  } else {
    std::size_t idx = 0;
    for (int k = 0; k < g.dims[2]; ++k)
      for (int j = 0; j < g.dims[1]; ++j)
        for (int i = 0; i < g.dims[0]; ++i, ++idx) out.voxel_material[idx] = classOf(scanValue(i, j, k));
  }
  for (const auto& [key, e] : hardness)
    if (!used.count(key))
      throw std::invalid_argument("drill.hardness: '" + key + "' names no material of this scene (" +
                                  [&] {
                                    std::string list;
                                    for (const auto& m : out.materials) list += (list.empty() ? "" : ", ") + m.name;
                                    return list;
                                  }() +
                                  ")");
  return out;
}

Drill::Drill(std::shared_ptr<haptics::MaterialRemoval> removal, Burr burr, double dt_s,
             std::vector<int> segment_of_material)
    : removal_(std::move(removal)), burr_(burr), dt_s_(dt_s), segment_of_material_(std::move(segment_of_material)) {
  if (removal_ == nullptr) throw std::invalid_argument("Drill: no material removal");
  if (!(dt_s_ > 0.0) || !std::isfinite(dt_s_)) throw std::invalid_argument("Drill: the period must be > 0 s");
}

haptics::CutResult Drill::step(const haptics::HapticRenderer& renderer, const haptics::TickOutput& out) noexcept {
  const Eigen::Vector3d c_W = renderer.proxyPose() * burr_.center_T_m;
  const double on_burr_m = burr_.radius_m + 2.0 * renderer.epsilon_m();
  bool touches = false;
  for (const haptics::Contact& contact : renderer.contacts())
    if ((contact.p_W_m - c_W).norm() <= on_burr_m) {
      touches = true;
      break;
    }
  return removal_->cut(c_W, burr_.radius_m, out.force_W_N.norm(), dt_s_, renderer.feltIsovalue(), touches);
}

DrillingRenderer makeDrillingRenderer(const haptics::ScalarVolume& felt, double felt_isovalue,
                                      std::shared_ptr<const haptics::ToolModel> tool, DrillMaterials materials,
                                      const DrillSpec& spec, const haptics::RendererOptions& options,
                                      const haptics::Pose& X_WP, double servo_rate_Hz) {
  if (tool == nullptr) throw std::invalid_argument("drilling needs a tool");
  if (!(spec.burr_speed_rpm > 0.0) || !std::isfinite(spec.burr_speed_rpm))
    throw std::invalid_argument("drill.burr_speed_rpm: expected a speed > 0");
  const Burr burr = burrOf(*tool, spec);
  auto copy = std::make_shared<haptics::ScalarVolume>(felt);  // the renderer's own, carved
  haptics::RemovalModel model;
  model.burr_speed_rad_per_s = spec.burr_speed_rpm * 2.0 * 3.14159265358979323846 / 60.0;
  auto removal = std::make_shared<haptics::MaterialRemoval>(copy, std::move(materials.voxel_material),
                                                            std::move(materials.materials), model);
  DrillingRenderer out;
  out.renderer = std::make_unique<haptics::HapticRenderer>(copy, std::move(tool), options, X_WP, felt_isovalue);
  out.drill = std::make_shared<Drill>(std::move(removal), burr, 1.0 / servo_rate_Hz,
                                      std::move(materials.segment_of_material));
  return out;
}

}  // namespace vh::runtime
