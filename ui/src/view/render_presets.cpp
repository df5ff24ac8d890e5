#include "vh/ui/view/render_presets.h"

#include <algorithm>

namespace vh::ui {
namespace {

constexpr double kHuMin = -1024.0;
constexpr double kHuMax = 3071.0;

/// Maps an HU value onto the data's units: identity for HU data, else linear from the CT range.
double mapHu(double hu, double lo, double hi, bool hounsfield) {
  if (hounsfield) return hu;
  return lo + (hu - kHuMin) / (kHuMax - kHuMin) * (hi - lo);
}

/// Keeps the points inside [lo, hi] with the end points pinned, so VTK's functions cover the
/// data and stay increasing.
template <typename Point>
std::vector<Point> clampPoints(std::vector<Point> pts, double lo, double hi) {
  std::vector<Point> out;
  for (Point p : pts) {
    p.value = std::clamp(p.value, lo, hi);
    if (!out.empty() && p.value <= out.back().value) {
      out.back() = p;  // collapsed onto the range's edge: the later point wins
      continue;
    }
    out.push_back(p);
  }
  return out;
}

VolumeLook fromHu(std::vector<ColourPoint> colour, std::vector<OpacityPoint> opacity, double lo, double hi,
                  bool hounsfield) {
  VolumeLook look;
  for (auto& c : colour) c.value = mapHu(c.value, lo, hi, hounsfield);
  for (auto& o : opacity) o.value = mapHu(o.value, lo, hi, hounsfield);
  look.colour = clampPoints(std::move(colour), lo, hi);
  look.opacity = clampPoints(std::move(opacity), lo, hi);
  return look;
}

}  // namespace

std::string modeName(RenderMode mode) {
  switch (mode) {
    case RenderMode::kIsosurface: return "Isosurface";
    case RenderMode::kComposite: return "Composite";
    case RenderMode::kMip: return "MIP";
  }
  return "?";
}

std::string presetName(VolumePreset preset) {
  switch (preset) {
    case VolumePreset::kBone: return "Bone";
    case VolumePreset::kSoftTissue: return "Soft tissue";
    case VolumePreset::kSkin: return "Skin";
  }
  return "?";
}

VolumeLook compositeLook(VolumePreset preset, double lo, double hi, bool hounsfield) {
  if (!(hi > lo)) hi = lo + 1.0;
  VolumeLook look;
  switch (preset) {
    case VolumePreset::kBone:
      look = fromHu({{-1024, 0.0, 0.0, 0.0}, {140, 0.55, 0.25, 0.15}, {300, 0.88, 0.72, 0.52},
                     {700, 0.96, 0.91, 0.80}, {3071, 1.0, 1.0, 1.0}},
                    {{-1024, 0.0}, {150, 0.0}, {300, 0.12}, {500, 0.55}, {1000, 0.85}, {3071, 0.9}}, lo, hi,
                    hounsfield);
      look.ambient = 0.2;
      look.diffuse = 0.9;
      look.specular = 0.3;
      look.specular_power = 15.0;
      break;
    case VolumePreset::kSoftTissue:
      look = fromHu({{-1024, 0.0, 0.0, 0.0}, {-600, 0.0, 0.0, 0.0}, {-120, 0.85, 0.70, 0.38},
                     {40, 0.80, 0.33, 0.28}, {250, 0.95, 0.85, 0.75}, {3071, 1.0, 1.0, 1.0}},
                    {{-1024, 0.0}, {-650, 0.0}, {-500, 0.015}, {-120, 0.03}, {20, 0.06}, {100, 0.10},
                     {250, 0.3}, {500, 0.75}, {3071, 0.85}},
                    lo, hi, hounsfield);
      look.ambient = 0.25;
      look.diffuse = 0.8;
      look.specular = 0.15;
      look.specular_power = 10.0;
      break;
    case VolumePreset::kSkin:
      look = fromHu({{-1024, 0.0, 0.0, 0.0}, {-600, 0.85, 0.62, 0.50}, {0, 0.95, 0.76, 0.64},
                     {500, 1.0, 0.93, 0.86}, {3071, 1.0, 1.0, 1.0}},
                    {{-1024, 0.0}, {-650, 0.0}, {-400, 0.9}, {3071, 0.95}}, lo, hi, hounsfield);
      look.ambient = 0.2;
      look.diffuse = 0.85;
      look.specular = 0.2;
      look.specular_power = 20.0;
      break;
  }
  look.shade = true;
  look.opacity_unit_distance_voxels = 1.0;
  return look;
}

VolumeLook mipLook(double lo, double hi, bool hounsfield) {
  if (!(hi > lo)) hi = lo + 1.0;
  double w0 = lo + 0.02 * (hi - lo);
  double w1 = lo + 0.98 * (hi - lo);
  if (hounsfield) {
    w0 = std::clamp(-200.0, lo, hi);
    w1 = std::clamp(1500.0, lo, hi);
    if (!(w1 > w0)) {
      w0 = lo;
      w1 = hi;
    }
  }
  VolumeLook look;
  look.colour = clampPoints(std::vector<ColourPoint>{{lo, 0, 0, 0}, {w0, 0, 0, 0}, {w1, 1, 1, 1}, {hi, 1, 1, 1}}, lo, hi);
  look.opacity = clampPoints(std::vector<OpacityPoint>{{lo, 0.0}, {w0, 0.0}, {w1, 1.0}, {hi, 1.0}}, lo, hi);
  look.shade = false;
  return look;
}

VolumeLook isosurfaceLook(double lo, double hi, double r, double g, double b) {
  if (!(hi > lo)) hi = lo + 1.0;
  VolumeLook look;
  look.colour = {{lo, r, g, b}, {hi, r, g, b}};
  look.opacity = {{lo, 1.0}, {hi, 1.0}};
  look.shade = true;
  look.ambient = 0.15;
  look.diffuse = 0.8;
  look.specular = 0.25;
  look.specular_power = 20.0;
  return look;
}

}  // namespace vh::ui
