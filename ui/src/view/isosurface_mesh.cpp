#include "isosurface_mesh.h"

#include <algorithm>
#include <cmath>

#include <vtkActor.h>
#include <vtkFlyingEdges3D.h>
#include <vtkImageData.h>
#include <vtkImageShrink3D.h>
#include <vtkMatrix4x4.h>
#include <vtkPlane.h>
#include <vtkPolyData.h>
#include <vtkPolyDataMapper.h>
#include <vtkProperty.h>

namespace vh::ui {

namespace {
double msSince(std::chrono::steady_clock::time_point t) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t).count();
}
}  // namespace

IsosurfaceMesh::IsosurfaceMesh(vtkImageData* image, vtkMatrix4x4* user_matrix) : image_(image) {
  int dims[3] = {1, 1, 1};
  if (image_ != nullptr) image_->GetDimensions(dims);
  const double voxels = static_cast<double>(dims[0]) * dims[1] * dims[2];
  factor_ = std::clamp(static_cast<int>(std::ceil(std::cbrt(voxels / kCoarseVoxels) - 1e-9)), 1, kMaxFactor);
  shrink_->MeanOn();
  contour_->SetNumberOfContours(1);
  contour_->ComputeNormalsOn();
  contour_->ComputeGradientsOff();
  contour_->ComputeScalarsOff();
  contour_->InterpolateAttributesOff();
  mapper_->SetInputData(poly_);
  mapper_->ScalarVisibilityOff();
  actor_->SetMapper(mapper_);
  actor_->SetUserMatrix(user_matrix);
  actor_->GetProperty()->BackfaceCullingOn();  // the surface's triangles face out of the region F >= s
  actor_->PickableOff();
  actor_->VisibilityOff();
}

IsosurfaceMesh::~IsosurfaceMesh() = default;

void IsosurfaceMesh::setImage(vtkImageData* image, bool same_values) {
  image_ = image;
  if (!same_values) coarse_stale_ = true;
  mesh_stale_ = mesh_stale_ || !same_values;
}

void IsosurfaceMesh::markChanged(const int lo[3], const int hi[3]) {
  for (int a = 0; a < 3; ++a) {
    lo_[a] = box_pending_ ? std::min(lo_[a], lo[a]) : lo[a];
    hi_[a] = box_pending_ ? std::max(hi_[a], hi[a]) : hi[a];
  }
  box_pending_ = true;
  mesh_stale_ = true;
}

void IsosurfaceMesh::setIsovalue(double isovalue) {
  if (isovalue == isovalue_ && !mesh_stale_) return;
  isovalue_ = isovalue;
  mesh_stale_ = true;
}

bool IsosurfaceMesh::coarsen() {
  if (factor_ >= kMaxFactor) return false;
  ++factor_;
  coarse_stale_ = true;
  mesh_stale_ = true;
  return true;
}

void IsosurfaceMesh::rebuildCoarse() {
  coarse_ = nullptr;
  box_pending_ = false;
  coarse_stale_ = false;
  if (image_ == nullptr) return;
  int dims[3];
  image_->GetDimensions(dims);
  for (int a = 0; a < 3; ++a) factors_[a] = std::clamp(std::min(factor_, dims[a] / 2), 1, kMaxFactor);
  shrink_->SetInputData(image_);
  shrink_->SetShrinkFactors(factors_.data());
  shrink_->Modified();
  shrink_->Update();
  coarse_ = vtkSmartPointer<vtkImageData>::New();
  coarse_->DeepCopy(shrink_->GetOutput());
  // vtkImageShrink3D puts the mean of voxels f i .. f i + f - 1 at voxel f i's position: its
  // centre is (f - 1) / 2 voxels further along.
  double origin[3], spacing[3];
  image_->GetOrigin(origin);
  image_->GetSpacing(spacing);
  for (int a = 0; a < 3; ++a) origin[a] += 0.5 * (factors_[a] - 1) * spacing[a];
  coarse_->SetOrigin(origin);
  contour_->SetInputData(coarse_);
}

void IsosurfaceMesh::refreshCoarseBox() {
  box_pending_ = false;
  if (coarse_ == nullptr || image_ == nullptr) return;
  int coarse_extent[6];
  coarse_->GetExtent(coarse_extent);
  int ext[6];
  for (int a = 0; a < 3; ++a) {
    ext[2 * a] = std::max(lo_[a] / factors_[a], coarse_extent[2 * a]);
    ext[2 * a + 1] = std::min(hi_[a] / factors_[a], coarse_extent[2 * a + 1]);
    if (ext[2 * a] > ext[2 * a + 1]) return;  // beyond the blocks the copy covers
  }
  shrink_->SetInputData(image_);  // the drilled copy since the last full average, perhaps
  shrink_->Modified();
  shrink_->UpdateExtent(ext);
  coarse_->CopyAndCastFrom(shrink_->GetOutput(), ext);
  coarse_->Modified();
}

bool IsosurfaceMesh::update(bool force) {
  if (!coarse_stale_ && !box_pending_ && !mesh_stale_) return true;
  if (!force && msSince(built_at_) < kRebuildMs) return false;
  if (coarse_stale_) rebuildCoarse();
  if (box_pending_) refreshCoarseBox();
  if (coarse_ != nullptr && drawable()) {
    contour_->SetValue(0, isovalue_);
    contour_->Modified();
    contour_->Update();
    poly_->ShallowCopy(contour_->GetOutput());
  } else {
    poly_->Initialize();
  }
  poly_->Modified();
  mesh_stale_ = false;
  built_at_ = std::chrono::steady_clock::now();
  return true;
}

bool IsosurfaceMesh::drawable() const noexcept {
  // The coarse copy keeps at least 2 blocks on an axis of at least 2 voxels (rebuildCoarse()).
  if (image_ == nullptr) return false;
  int dims[3];
  image_->GetDimensions(dims);
  return dims[0] >= 2 && dims[1] >= 2 && dims[2] >= 2;
}

vtkActor* IsosurfaceMesh::actor() const noexcept { return actor_; }

void IsosurfaceMesh::setClipPlane(vtkPlane* plane) {
  mapper_->RemoveAllClippingPlanes();
  if (plane != nullptr) mapper_->AddClippingPlane(plane);
}

void IsosurfaceMesh::setLook(const double rgb[3], double ambient, double diffuse, double specular, double specular_power) {
  vtkProperty* p = actor_->GetProperty();
  p->SetColor(rgb[0], rgb[1], rgb[2]);
  p->SetAmbient(ambient);
  p->SetDiffuse(diffuse);
  p->SetSpecular(specular);
  p->SetSpecularPower(specular_power);
}

std::size_t IsosurfaceMesh::triangles() const noexcept { return static_cast<std::size_t>(poly_->GetNumberOfPolys()); }

}  // namespace vh::ui
