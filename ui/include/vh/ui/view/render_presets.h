#pragma once
/// @file
/// How the volume is drawn: rendering modes and the transfer functions of the composite and MIP
/// modes (CT presets in HU, after 3D Slicer's volume rendering presets). No Qt, no VTK: the
/// presets are plain point lists that SceneActors hands to VTK, so they are unit tested.

#include <string>
#include <vector>

namespace vh::ui {

/// What the volume prop shows.
enum class RenderMode {
  kIsosurface,  ///< The haptic surface F = s, shaded, opaque (GPU ray-cast isosurface).
  kComposite,   ///< Emission-absorption ray casting with a preset transfer function.
  kMip,         ///< Maximum intensity projection, grey window.
};

/// Composite presets. Defined in HU for CT; for data in other units the HU axis is mapped
/// linearly from [-1024, 3071] onto the data's range (a rough start, to be adjusted by the
/// isovalue later).
enum class VolumePreset {
  kBone,        ///< Bone opaque and ivory, soft tissue transparent.
  kSoftTissue,  ///< Fat and muscle translucent (yellow / red), bone white.
  kSkin,        ///< The air/skin boundary as an opaque skin-coloured surface.
};

/// One point of a colour transfer function: value in data units, RGB in [0, 1].
struct ColourPoint {
  double value = 0.0;
  double r = 0.0, g = 0.0, b = 0.0;
};

/// One point of a scalar opacity function: value in data units, opacity in [0, 1] per
/// `unit distance` of ray (VolumeLook::opacity_unit_distance_voxels).
struct OpacityPoint {
  double value = 0.0;
  double opacity = 0.0;
};

/// Transfer functions and shading of one mode / preset, in data units.
struct VolumeLook {
  std::vector<ColourPoint> colour;     ///< Increasing values.
  std::vector<OpacityPoint> opacity;   ///< Increasing values.
  bool shade = true;
  double ambient = 0.15, diffuse = 0.8, specular = 0.25, specular_power = 20.0;
  /// Opacity is given per this many voxels of ray length (vtkVolumeProperty's scalar opacity
  /// unit distance, in voxels of the smallest spacing).
  double opacity_unit_distance_voxels = 1.0;
};

/// Display name of a mode / preset ("Isosurface", "Composite", "MIP"; "Bone", "Soft tissue",
/// "Skin").
std::string modeName(RenderMode mode);
std::string presetName(VolumePreset preset);

/// The composite look of `preset` for data in [min_value, max_value]; `hounsfield` when the
/// values are HU (CT), else the HU points are mapped linearly onto the range.
VolumeLook compositeLook(VolumePreset preset, double min_value, double max_value, bool hounsfield);

/// The MIP look: a grey ramp over a window (-200..1500 HU for CT, the 2nd..98th percent of the
/// range otherwise), opacity rising with the value so the background stays dark.
VolumeLook mipLook(double min_value, double max_value, bool hounsfield);

/// The isosurface look: one colour (RGB in [0, 1]), opaque, shaded.
VolumeLook isosurfaceLook(double min_value, double max_value, double r, double g, double b);

}  // namespace vh::ui
