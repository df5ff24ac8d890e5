// Soft tissue in a scene (tissue_scene.h): the region cut from the scan by value bands.
#include "vh/runtime/tissue_scene.h"

#include <algorithm>
#include <stdexcept>
#include <thread>
#include <utility>

#include "vh/haptics/scalar_volume.h"
#include "vh/tissue/deformable_scene.h"
#include "vh/tissue/material.h"
#include "vh/tissue/tissue_region.h"

namespace vh::runtime {

std::shared_ptr<tissue::DeformableScene> makeTissueScene(const TissueSpec& spec,
                                                         std::shared_ptr<const haptics::ScalarVolume> field,
                                                         double isovalue, bool scan_in_HU) {
  if (field == nullptr || field->empty()) throw std::invalid_argument("tissue: no volume");
  if (spec.bands.empty()) throw std::invalid_argument("tissue: no band of values");
  // The materials, one per distinct name, in the order the bands first name them.
  std::vector<std::string> names;
  std::vector<tissue::Material> materials;
  std::vector<int> band_material;
  for (const TissueBand& band : spec.bands) {
    if (!(band.max > band.min)) throw std::invalid_argument("tissue: a band's max must exceed its min");
    auto it = std::find(names.begin(), names.end(), band.material);
    if (it == names.end()) {
      materials.push_back(tissue::materialPreset(band.material));  // throws for an unknown name
      names.push_back(band.material);
      it = names.end() - 1;
    }
    band_material.push_back(static_cast<int>(it - names.begin()));
  }
  const haptics::VolumeGeometry& geo = field->geometry();
  tissue::VoxelGrid grid;
  grid.dims = Eigen::Vector3i(geo.dims[0], geo.dims[1], geo.dims[2]);
  grid.spacing_m = geo.spacing_m;
  tissue::RegionSpec region;
  region.cell_size_m = spec.cell_size_m;
  const haptics::ScalarVolume* volume = field.get();
  const std::vector<TissueBand>* bands = &spec.bands;
  region.material_of_voxel = [volume, bands, band_material](int i, int j, int k) {
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
