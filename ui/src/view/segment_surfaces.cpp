// Shown segments as coloured surfaces (see segment_surfaces.h).
#include "vh/ui/view/segment_surfaces.h"

#include <algorithm>

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

SegmentSurfaces::SegmentSurfaces(vtkRenderer* renderer) : renderer_(renderer) {}

SegmentSurfaces::~SegmentSurfaces() {
  for (auto& [s, actor] : actors_) renderer_->RemoveActor(actor);
}

void SegmentSurfaces::show(const runtime::SegmentSet* set) {
  for (auto& [s, actor] : actors_) renderer_->RemoveActor(actor);
  actors_.clear();
  colours_.clear();
  if (set == nullptr) return;
  const std::string source = set->segmentation().source.string();
  if (source != source_ || set->smoothingVoxels() != smoothing_voxels_) {
    cache_.clear();
    matrices_.clear();
    source_ = source;
    smoothing_voxels_ = set->smoothingVoxels();
  }
  for (const int s : set->shown()) {
    const io::SegmentInfo& info = set->segment(s);
    if (info.voxel_count == 0) continue;
    auto& surface = cache_[s];
    if (surface == nullptr) {
      const auto field = io::segmentIndicatorField(set->segmentation(), {s}, set->smoothingVoxels());
      const io::ImagePtr image = io::imageFromField(field);
      vtkNew<vtkFlyingEdges3D> contour;
      contour->SetInputData(image.get());
      contour->SetValue(0, io::kSegmentSurfaceLevel);
      contour->ComputeNormalsOn();
      contour->Update();
      surface = contour->GetOutput();
      // The image has no direction: the actor applies it about the origin, as the volume's.
      const haptics::VolumeGeometry& g = field->geometry();
      const Eigen::Vector3d t = g.origin_W_m - g.direction_W * g.origin_W_m;
      vtkNew<vtkMatrix4x4> m;
      for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 3; ++c) m->SetElement(r, c, g.direction_W(r, c));
        m->SetElement(r, 3, t[r]);
      }
      matrices_[s] = m;
    }
    vtkNew<vtkPolyDataMapper> mapper;
    mapper->SetInputData(surface);
    mapper->ScalarVisibilityOff();
    vtkNew<vtkActor> actor;
    actor->SetMapper(mapper);
    actor->SetUserMatrix(matrices_[s]);
    const auto& rgb = info.color_rgb;
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

std::vector<int> SegmentSurfaces::shownSegments() const {
  std::vector<int> out;
  for (const auto& [s, actor] : actors_) out.push_back(s);
  return out;
}

vtkPolyData* SegmentSurfaces::surface(int s) const {
  const auto it = cache_.find(s);
  return actors_.count(s) != 0 && it != cache_.end() ? it->second.Get() : nullptr;
}

}  // namespace vh::ui
