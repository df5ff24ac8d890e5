// Shown segments as coloured surfaces (see segment_surfaces.h).
#include "vh/ui/view/segment_surfaces.h"

#include <algorithm>
#include <cmath>

#include <vtkActor.h>
#include <vtkFlyingEdges3D.h>
#include <vtkImageData.h>
#include <vtkMatrix4x4.h>
#include <vtkNew.h>
#include <vtkPolyData.h>
#include <vtkPolyDataMapper.h>
#include <vtkProperty.h>
#include <vtkRenderer.h>

#include "vh/io/volume_loader.h"

namespace vh::ui {

namespace {

/// sRGB (0..1) to CIELAB (D65 white), IEC 61966-2-1 and CIE 15.
std::array<double, 3> toLab(const Rgb& rgb) {
  const auto linear = [](double c) {
    c = std::clamp(c, 0.0, 1.0);
    return c <= 0.04045 ? c / 12.92 : std::pow((c + 0.055) / 1.055, 2.4);
  };
  const double r = linear(rgb[0]), g = linear(rgb[1]), b = linear(rgb[2]);
  const double X = 0.4124564 * r + 0.3575761 * g + 0.1804375 * b;
  const double Y = 0.2126729 * r + 0.7151522 * g + 0.0721750 * b;
  const double Z = 0.0193339 * r + 0.1191920 * g + 0.9503041 * b;
  const auto f = [](double t) {
    constexpr double d = 6.0 / 29.0;
    return t > d * d * d ? std::cbrt(t) : t / (3.0 * d * d) + 4.0 / 29.0;
  };
  const double fx = f(X / 0.95047), fy = f(Y / 1.0), fz = f(Z / 1.08883);
  return {116.0 * fy - 16.0, 500.0 * (fx - fy), 200.0 * (fy - fz)};
}

/// Distinct, saturated colours for segments the file's colour would hide.
constexpr std::array<Rgb, 8> kPalette = {{{0.20, 0.80, 0.20},
                                          {0.20, 0.45, 1.00},
                                          {0.90, 0.20, 0.85},
                                          {0.10, 0.85, 0.90},
                                          {1.00, 0.55, 0.05},
                                          {1.00, 0.95, 0.10},
                                          {0.90, 0.10, 0.10},
                                          {0.55, 0.25, 0.90}}};

}  // namespace

double colourDifference_Lab(const Rgb& a, const Rgb& b) {
  const auto la = toLab(a), lb = toLab(b);
  return std::sqrt((la[0] - lb[0]) * (la[0] - lb[0]) + (la[1] - lb[1]) * (la[1] - lb[1]) +
                   (la[2] - lb[2]) * (la[2] - lb[2]));
}

Rgb distinctSegmentColour(const Rgb& segment_rgb, const Rgb& surface_rgb, const std::vector<Rgb>& taken) {
  if (colourDifference_Lab(segment_rgb, surface_rgb) >= kMinSegmentContrast_Lab) return segment_rgb;
  Rgb best = kPalette.front();
  double best_gap = -1.0;
  for (const Rgb& c : kPalette) {
    double gap = colourDifference_Lab(c, surface_rgb);
    for (const Rgb& t : taken) gap = std::min(gap, colourDifference_Lab(c, t));
    if (gap > best_gap) {
      best_gap = gap;
      best = c;
    }
  }
  return best;
}

SegmentSurface buildSegmentSurface(const runtime::SegmentSet& set, int s) {
  const auto field = io::segmentIndicatorField(set.segmentation(), {s}, set.smoothingVoxels());
  const io::ImagePtr image = io::imageFromField(field);
  vtkNew<vtkFlyingEdges3D> contour;
  contour->SetInputData(image.get());
  contour->SetValue(0, io::kSegmentSurfaceLevel);
  contour->ComputeNormalsOn();
  contour->Update();
  SegmentSurface out;
  out.surface = contour->GetOutput();
  const haptics::VolumeGeometry& g = field->geometry();
  const Eigen::Vector3d t = g.origin_W_m - g.direction_W * g.origin_W_m;
  out.X_W_image = vtkSmartPointer<vtkMatrix4x4>::New();
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) out.X_W_image->SetElement(r, c, g.direction_W(r, c));
    out.X_W_image->SetElement(r, 3, t[r]);
  }
  return out;
}

SegmentSurfaces::SegmentSurfaces(vtkRenderer* renderer) : renderer_(renderer) {}

void SegmentSurfaces::keepCacheFor(const runtime::SegmentSet& set) {
  const std::string source = set.segmentation().source.string();
  if (source == source_ && set.smoothingVoxels() == smoothing_voxels_) return;
  cache_.clear();
  source_ = source;
  smoothing_voxels_ = set.smoothingVoxels();
}

void SegmentSurfaces::adopt(const runtime::SegmentSet& set, std::map<int, SegmentSurface> built) {
  keepCacheFor(set);
  for (auto& [s, b] : built) {
    if (b.surface != nullptr && b.X_W_image != nullptr) cache_[s] = std::move(b);
  }
}

void SegmentSurfaces::setRenderer(vtkRenderer* renderer) {
  if (renderer == renderer_ || renderer == nullptr) return;
  for (auto& [s, actor] : actors_) {
    renderer_->RemoveActor(actor);
    renderer->AddActor(actor);
  }
  renderer_ = renderer;
}

SegmentSurfaces::~SegmentSurfaces() {
  for (auto& [s, actor] : actors_) renderer_->RemoveActor(actor);
}

void SegmentSurfaces::show(const runtime::SegmentSet* set, const Rgb& surface_rgb) {
  for (auto& [s, actor] : actors_) renderer_->RemoveActor(actor);
  actors_.clear();
  colours_.clear();
  recoloured_.clear();
  std::vector<Rgb> taken;
  if (set == nullptr) return;
  keepCacheFor(*set);
  for (const int s : set->shown()) {
    const io::SegmentInfo& info = set->segment(s);
    if (info.voxel_count == 0) continue;
    SegmentSurface& cached = cache_[s];
    if (cached.surface == nullptr) cached = buildSegmentSurface(*set, s);
    vtkNew<vtkPolyDataMapper> mapper;
    mapper->SetInputData(cached.surface);
    mapper->ScalarVisibilityOff();
    vtkNew<vtkActor> actor;
    actor->SetMapper(mapper);
    actor->SetUserMatrix(cached.X_W_image);
    const Rgb file_rgb = {info.color_rgb[0], info.color_rgb[1], info.color_rgb[2]};
    const Rgb rgb = distinctSegmentColour(file_rgb, surface_rgb, taken);
    if (rgb != file_rgb) recoloured_.push_back(s);
    taken.push_back(rgb);
    actor->GetProperty()->SetColor(rgb[0], rgb[1], rgb[2]);
    actor->GetProperty()->SetSpecular(0.2);
    // With some segments felt, the others are context: translucent, so the felt ones show.
    actor->GetProperty()->SetOpacity(set->felt().empty() || set->isFelt(s) ? 1.0 : 0.35);
    actor->PickableOff();
    renderer_->AddActor(actor);
    actors_[s] = actor;
    colours_[s] = {rgb[0], rgb[1], rgb[2]};
  }
  setTouched(touched_);
}

void SegmentSurfaces::setTouched(int segment) {
  touched_ = segment;
  for (auto& [s, actor] : actors_) {
    const auto& c = colours_[s];
    const double gain = s == segment ? 1.0 : 0.85;
    actor->GetProperty()->SetColor(std::min(1.0, c[0] * gain + (s == segment ? 0.15 : 0.0)),
                                   std::min(1.0, c[1] * gain + (s == segment ? 0.15 : 0.0)),
                                   std::min(1.0, c[2] * gain + (s == segment ? 0.15 : 0.0)));
    actor->GetProperty()->SetAmbient(s == segment ? 0.35 : 0.1);
  }
}

bool SegmentSurfaces::bounds_W(int s, double bounds_W[6]) const {
  const auto it = actors_.find(s);
  if (it == actors_.end()) return false;
  const double* b = it->second->GetBounds();  // with the actor's direction matrix
  if (b == nullptr || !(b[0] <= b[1])) return false;
  std::copy(b, b + 6, bounds_W);
  return true;
}

std::vector<double> SegmentSurfaces::colour(int s) const {
  const auto it = colours_.find(s);
  return it != colours_.end() ? it->second : std::vector<double>{};
}

std::vector<int> SegmentSurfaces::shownSegments() const {
  std::vector<int> out;
  for (const auto& [s, actor] : actors_) out.push_back(s);
  return out;
}

vtkPolyData* SegmentSurfaces::surface(int s) const {
  const auto it = cache_.find(s);
  return actors_.count(s) != 0 && it != cache_.end() ? it->second.surface.Get() : nullptr;
}

}  // namespace vh::ui
