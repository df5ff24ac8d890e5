#pragma once
/// @file
/// Soft tissue in a scene: the scene file's "tissue" section and the deformable scene built from
/// it (vh::tissue::DeformableScene: the renderer feels the deformed tissue through its own copy
/// of the field). A scene without the section builds none of it.
///
///   "tissue": {"bands": [{"min": 20, "max": 45, "material": "brain grey matter"},
///                        {"min": 45, "max": 80, "material": "brain white matter"}],
///              "segments": [{"segment": "tumour", "material": "tumour"}],  // optional
///              "rigid_above": 300,        // optional: voxels above it hold the tissue (bone)
///              "cell_size_m": 0.002,      // optional: the lattice's cell side (default 2 mm)
///              "touchable_layers": 2}     // optional: cell layers the compliance table holds
///
/// A band takes the voxels whose value v (the scan's units, HU for CT) has min <= v < max; its
/// material is one of the presets (vh::tissue::materialPresets(), each with its source). A
/// segment of the scene's segmentation (its name or ID) takes the voxels whose centre's nearest
/// segmentation voxel carries its label (io::LoadedSegmentation::nearestVoxel()), before any
/// band: an organ segmented in the scan, or a stiffer tumour inside a band's soft tissue. At
/// least one band or segment.
/// "rigid_above" absent: 300 HU for CT in HU (bone), else no rigid voxel. The tissue is also held
/// where the scan's border cuts it. Not with "drill" (no cutting of tissue yet) nor with felt
/// segments (the tissue's surface is the scan's isosurface).
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace vh::haptics {
class ScalarVolume;
}
namespace vh::tissue {
class DeformableScene;
}
namespace vh::io {
struct LoadedSegmentation;
}

namespace vh::runtime {

struct TissueBand {
  double min = 0.0;      ///< Lowest value of the band (inclusive), the scan's units.
  double max = 0.0;      ///< Highest (exclusive), > min.
  std::string material;  ///< A preset's name (vh::tissue::materialPreset()).
};

struct TissueSegment {
  std::string segment;   ///< A segment of the scene's segmentation: its name or ID (case-insensitive).
  std::string material;  ///< A preset's name (vh::tissue::materialPreset()).
};

struct TissueSpec {
  std::vector<TissueBand> bands;          ///< Value bands (with segments: at least one of the two).
  std::vector<TissueSegment> segments;    ///< Segments, taken before the bands.
  std::optional<double> rigid_above;      ///< Voxels above it are rigid; absent: see the file comment.
  double cell_size_m = 0.002;             ///< Lattice cell side [m], at least the largest voxel side.
  int touchable_layers = 2;               ///< DeformableSceneOptions::touchable_layers, 1 to 4.
};

/// The deformable scene of `spec` on `field` (the scan's field, its values in the scan's units)
/// felt at `isovalue`: the region (a voxel takes the first of spec's segments it lies in, else
/// the first band holding its value), the factorisation and the compliance table. Seconds for
/// thousands of nodes: off the servo thread.
/// @param scan_in_HU the scan is CT in HU (the default rigid_above of 300 HU).
/// @param segmentation the scene's segmentation (on its own grid, in W): needed when spec names
///        segments, else unused (may be null).
/// @throws std::invalid_argument naming the problem: an unknown material, segments without a
///         segmentation or a segment it does not hold, no voxel in any band or segment, a region
///         nothing holds, a cell below the voxel size.
std::shared_ptr<tissue::DeformableScene> makeTissueScene(const TissueSpec& spec,
                                                         std::shared_ptr<const haptics::ScalarVolume> field,
                                                         double isovalue, bool scan_in_HU,
                                                         const io::LoadedSegmentation* segmentation = nullptr);

}  // namespace vh::runtime
