// Soft tissue in a scene (tissue_scene.h): the region cut from the scan by segments and value bands.
#include "vh/runtime/tissue_scene.h"

#include <algorithm>
#include <array>
#include <stdexcept>
#include <thread>
#include <utility>

#include "vh/haptics/scalar_volume.h"
#include "vh/io/segmentation.h"
#include "vh/tissue/deformable_scene.h"
#include "vh/tissue/material.h"
#include "vh/tissue/tissue_region.h"

namespace vh::runtime {

std::shared_ptr<tissue::DeformableScene> makeTissueScene(const TissueSpec& spec,
                                                         std::shared_ptr<const haptics::ScalarVolume> field,
                                                         double isovalue, bool scan_in_HU,
                                                         const io::LoadedSegmentation* segmentation) {
  if (field == nullptr || field->empty()) throw std::invalid_argument("tissue: no volume");
  if (spec.bands.empty() && spec.segments.empty()) throw std::invalid_argument("tissue: no band of values and no segment");
  // The materials, one per distinct name, in the order the segments, then the bands, first name them.
  std::vector<std::string> names;
  std::vector<tissue::Material> materials;
  const auto materialIndex = [&](const std::string& name) {
    auto it = std::find(names.begin(), names.end(), name);
    if (it == names.end()) {
      materials.push_back(tissue::materialPreset(name));  // throws for an unknown name
      names.push_back(name);
      it = names.end() - 1;
    }
    return static_cast<int>(it - names.begin());
  };
  // Each segment's layer, label and material.
  struct SegmentMaterial {
    int layer = 0, label = 0, material = 0;
  };
  std::vector<SegmentMaterial> segment_materials;
  if (!spec.segments.empty()) {
    if (segmentation == nullptr || segmentation->layers.empty())
      throw std::invalid_argument("tissue: its segments need the scene's segmentation, and there is none");
    for (const TissueSegment& ts : spec.segments) {
      const int s = segmentation->find(ts.segment);
      if (s < 0) {
        std::string list;
        for (const io::SegmentInfo& info : segmentation->segments) list += (list.empty() ? "" : ", ") + info.name;
        throw std::invalid_argument("tissue: the segmentation has no segment '" + ts.segment + "' (it has: " + list + ")");
      }
      const io::SegmentInfo& info = segmentation->segments[static_cast<std::size_t>(s)];
      segment_materials.push_back({info.layer, info.label_value, materialIndex(ts.material)});
    }
  }
  std::vector<int> band_material;
  for (const TissueBand& band : spec.bands) {
    if (!(band.max > band.min)) throw std::invalid_argument("tissue: a band's max must exceed its min");
    band_material.push_back(materialIndex(band.material));
  }
  const haptics::VolumeGeometry& geo = field->geometry();
  tissue::VoxelGrid grid;
  grid.dims = Eigen::Vector3i(geo.dims[0], geo.dims[1], geo.dims[2]);
  grid.spacing_m = geo.spacing_m;
  tissue::RegionSpec region;
  region.cell_size_m = spec.cell_size_m;
  const haptics::ScalarVolume* volume = field.get();
  const std::vector<TissueBand>* bands = &spec.bands;
  region.material_of_voxel = [volume, bands, band_material, segmentation, segment_materials](int i, int j, int k) {
    std::array<int, 3> v_seg{};
    if (!segment_materials.empty() &&
        segmentation->nearestVoxel(volume->geometry().pointOf_W(Eigen::Vector3d(i, j, k)), v_seg)) {
      for (const SegmentMaterial& sm : segment_materials)
        if (segmentation->label(sm.layer, v_seg[0], v_seg[1], v_seg[2]) == sm.label) return sm.material;
    }
    const double v = volume->voxel(i, j, k);
    for (std::size_t b = 0; b < bands->size(); ++b)
      if (v >= (*bands)[b].min && v < (*bands)[b].max) return band_material[b];
    return -1;
  };
  const std::optional<double> rigid = spec.rigid_above ? spec.rigid_above : scan_in_HU ? std::optional<double>(300.0) : std::nullopt;
  if (rigid) {
    const double above = *rigid;
    region.is_rigid_voxel = [volume, above](int i, int j, int k) { return volume->voxel(i, j, k) > above; };
  }
  region.hold_at_scan_border = true;
  tissue::TissueRegion cut = tissue::buildTissueRegion(grid, region, std::move(materials));
  tissue::DeformableSceneOptions options;
  options.touchable_layers = spec.touchable_layers;
  options.compliance_threads = std::max(1, static_cast<int>(std::thread::hardware_concurrency()));
  return std::make_shared<tissue::DeformableScene>(std::move(field), std::move(cut), isovalue, options);
}

}  // namespace vh::runtime
