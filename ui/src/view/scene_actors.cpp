#include "vh/ui/view/scene_actors.h"

#include "drillable_volume_mapper.h"
#include "isosurface_mesh.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <utility>

#include <vtkActor.h>
#include <vtkArrowSource.h>
#include <vtkCamera.h>
#include <vtkCellArray.h>
#include <vtkDelaunay2D.h>
#include <vtkColorTransferFunction.h>
#include <vtkCommand.h>
#include <vtkContourValues.h>
#include <vtkGPUVolumeRayCastMapper.h>
#include <vtkImageData.h>
#include <vtkMatrix4x4.h>
#include <vtkPiecewiseFunction.h>
#include <vtkPlane.h>
#include <vtkPoints.h>
#include <vtkPolyData.h>
#include <vtkPolyDataMapper.h>
#include <vtkPolyDataNormals.h>
#include <vtkProperty.h>
#include <vtkRenderWindow.h>
#include <vtkRenderer.h>
#include <vtkStructuredData.h>
#include <vtkTextActor.h>
#include <vtkTextProperty.h>
#include <vtkDataArray.h>
#include <vtkPointData.h>
#include <vtkVolume.h>
#include <vtkVolumeProperty.h>

namespace vh::ui {


namespace {

// Colours (RGB in [0, 1]).
constexpr double kBone[3] = {0.93, 0.87, 0.74};
constexpr double kSteel[3] = {0.62, 0.65, 0.70};
constexpr double kDevice[3] = {0.30, 0.75, 1.00};
constexpr double kContact[3] = {1.00, 0.25, 0.20};
constexpr double kForce[3] = {1.00, 0.80, 0.10};
constexpr double kShadow[3] = {0.10, 0.10, 0.13};
constexpr double kGapLine[3] = {0.95, 0.95, 0.75};

vtkSmartPointer<vtkPolyData> polyDataFromMesh(const haptics::TriangleMesh& mesh) {
  vtkNew<vtkPoints> points;
  points->SetDataTypeToDouble();
  points->SetNumberOfPoints(static_cast<vtkIdType>(mesh.vertices_T_m.size()));
  for (std::size_t i = 0; i < mesh.vertices_T_m.size(); ++i) {
    const Eigen::Vector3d& v = mesh.vertices_T_m[i];
    points->SetPoint(static_cast<vtkIdType>(i), v.x(), v.y(), v.z());
  }
  vtkNew<vtkCellArray> polys;
  polys->AllocateExact(static_cast<vtkIdType>(mesh.triangles.size()),
                       static_cast<vtkIdType>(3 * mesh.triangles.size()));
  for (const auto& t : mesh.triangles) {
    const vtkIdType ids[3] = {t[0], t[1], t[2]};
    polys->InsertNextCell(3, ids);
  }
  auto poly = vtkSmartPointer<vtkPolyData>::New();
  poly->SetPoints(points);
  poly->SetPolys(polys);
  return poly;
}

/// 4x4 matrix of a pose (rotation and translation), row-major into VTK.
void setMatrix(vtkMatrix4x4* m, const Eigen::Matrix3d& R, const Eigen::Vector3d& p) {
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) {
      m->SetElement(r, c, R(r, c));
    }
    m->SetElement(r, 3, p(r));
    m->SetElement(3, r, 0.0);
  }
  m->SetElement(3, 3, 1.0);
}

void setUserPose(vtkActor* actor, const haptics::Pose& X) {
  vtkMatrix4x4* m = actor->GetUserMatrix();
  if (m == nullptr) {
    vtkNew<vtkMatrix4x4> fresh;
    actor->SetUserMatrix(fresh);
    m = actor->GetUserMatrix();
  }
  setMatrix(m, X.R_AB.normalized().toRotationMatrix(), X.p_AB_m);
  m->Modified();
  actor->Modified();
}

}  // namespace

SceneActors::SceneActors(vtkRenderer* renderer, const SceneActorsSpec& spec) : renderer_(renderer) {
  drillable_ = DrillableVolumeMapper::New();
  volume_mapper_.TakeReference(drillable_);
  image_ = spec.image;
  buildVolume(spec);
  buildTools(spec);
  buildOverlay(spec);
  render_observer_ = renderer_->AddObserver(vtkCommand::StartEvent, this, &SceneActors::beforeRender);
}

void SceneActors::prepareRemoval() {
  if (drilled_image_ != nullptr || image_ == nullptr) return;
  drilled_image_ = vtkSmartPointer<vtkImageData>::New();
  drilled_image_->DeepCopy(image_);
  volume_mapper_->SetInputData(drilled_image_);  // one whole upload, on the next frame
  drillable_->clearPending();
  if (mesh_ != nullptr) mesh_->setImage(drilled_image_, /*same_values=*/true);
}

void SceneActors::removeVoxels(std::span<const std::uint64_t> indices, double value) {
  if (indices.empty() || image_ == nullptr) return;
  prepareRemoval();
  vtkDataArray* scalars = drilled_image_->GetPointData()->GetScalars();
  int dims[3];
  drilled_image_->GetDimensions(dims);
  const auto count = static_cast<std::uint64_t>(scalars->GetNumberOfTuples());
  int lo[3] = {VTK_INT_MAX, VTK_INT_MAX, VTK_INT_MAX}, hi[3] = {VTK_INT_MIN, VTK_INT_MIN, VTK_INT_MIN};
  for (const std::uint64_t index : indices) {
    if (index >= count) continue;
    scalars->SetComponent(static_cast<vtkIdType>(index), 0, value);
    int ijk[3];
    vtkStructuredData::ComputePointStructuredCoords(static_cast<vtkIdType>(index), dims, ijk);
    for (int a = 0; a < 3; ++a) {
      lo[a] = std::min(lo[a], ijk[a]);
      hi[a] = std::max(hi[a], ijk[a]);
    }
  }
  if (lo[0] <= hi[0]) {
    drillable_->markChanged(lo, hi);
    if (mesh_ != nullptr) mesh_->markChanged(lo, hi);
  }
}

bool SceneActors::showVoxelBox(const std::array<int, 3>& lo, const std::array<int, 3>& hi,
                               std::span<const float> values_F) {
  if (image_ == nullptr) return false;
  int dims[3];
  image_->GetDimensions(dims);
  const bool empty = hi[0] < lo[0] || hi[1] < lo[1] || hi[2] < lo[2];
  std::size_t count = 1;
  for (int a = 0; a < 3 && !empty; ++a) {
    if (lo[a] < 0 || hi[a] >= dims[a]) return false;
    count *= static_cast<std::size_t>(hi[a] - lo[a] + 1);
  }
  if (!empty && count != values_F.size()) return false;
  const bool had = box_hi_[0] >= box_lo_[0];
  if (empty && !had) return true;
  prepareRemoval();
  vtkDataArray* shown = drilled_image_->GetPointData()->GetScalars();
  vtkDataArray* rest = image_->GetPointData()->GetScalars();
  const bool integral = shown->GetDataType() != VTK_FLOAT && shown->GetDataType() != VTK_DOUBLE;
  const auto inBox = [](int i, int j, int k, const std::array<int, 3>& l, const std::array<int, 3>& h) {
    return i >= l[0] && i <= h[0] && j >= l[1] && j <= h[1] && k >= l[2] && k <= h[2];
  };
  const auto id = [&](int i, int j, int k) {
    return static_cast<vtkIdType>(i) + static_cast<vtkIdType>(dims[0]) * (static_cast<vtkIdType>(j) + static_cast<vtkIdType>(dims[1]) * k);
  };
  if (had) {  // the last box, outside the new one: back to rest
    for (int k = box_lo_[2]; k <= box_hi_[2]; ++k)
      for (int j = box_lo_[1]; j <= box_hi_[1]; ++j)
        for (int i = box_lo_[0]; i <= box_hi_[0]; ++i)
          if (empty || !inBox(i, j, k, lo, hi)) shown->SetComponent(id(i, j, k), 0, rest->GetComponent(id(i, j, k), 0));
    drillable_->markChanged(box_lo_.data(), box_hi_.data());
    if (mesh_ != nullptr) mesh_->markChanged(box_lo_.data(), box_hi_.data());
  }
  if (!empty) {
    std::size_t at = 0;
    for (int k = lo[2]; k <= hi[2]; ++k)
      for (int j = lo[1]; j <= hi[1]; ++j)
        for (int i = lo[0]; i <= hi[0]; ++i) {
          const double v = values_F[at++];
          shown->SetComponent(id(i, j, k), 0, integral ? std::round(v) : v);  // an integer scan: nearest
        }
    drillable_->markChanged(lo.data(), hi.data());
    if (mesh_ != nullptr) mesh_->markChanged(lo.data(), hi.data());
  }
  box_lo_ = lo;
  box_hi_ = empty ? std::array<int, 3>{-1, -1, -1} : hi;
  if (empty) box_lo_ = {0, 0, 0};
  return true;
}

void SceneActors::restoreVolume() {
  box_lo_ = {0, 0, 0};
  box_hi_ = {-1, -1, -1};
  if (drilled_image_ == nullptr) return;
  drilled_image_ = nullptr;
  drillable_->clearPending();
  volume_mapper_->SetInputData(image_);
  if (mesh_ != nullptr) mesh_->setImage(image_, /*same_values=*/false);
}

vtkImageData* SceneActors::shownImage() const noexcept {
  return drilled_image_ != nullptr ? drilled_image_.Get() : image_.Get();
}

std::array<int, 3> SceneActors::textureBlocks() const noexcept { return drillable_->blocks; }
std::uint64_t SceneActors::partialUploads() const noexcept { return drillable_->partial_uploads; }
std::uint64_t SceneActors::fullUploads() const noexcept { return drillable_->full_uploads; }

void SceneActors::buildVolume(const SceneActorsSpec& spec) {
  // --- Volume: GPU ray-cast isosurface, shaded, one bone colour, opaque at the surface.
  double range[2] = {0.0, 1.0};
  spec.image->GetScalarRange(range);
  volume_mapper_->SetInputData(spec.image);
  volume_mapper_->SetBlendModeToIsoSurface();
  // Explicit quality control (setInteractive()): VTK's automatic adjustment splits the frame
  // budget evenly over all props and picks poor still-frame sample distances for thin bone.
  {
    double spacing[3] = {1e-3, 1e-3, 1e-3};
    spec.image->GetSpacing(spacing);
    min_spacing_m_ = std::min({spacing[0], spacing[1], spacing[2]});
  }
  volume_mapper_->SetAutoAdjustSampleDistances(0);
  volume_mapper_->SetLockSampleDistanceToInputSpacing(0);
  applyQuality();
  range_[0] = range[0];
  range_[1] = range[1] > range[0] ? range[1] : range[0] + 1.0;
  hounsfield_ = spec.hounsfield;
  surface_rgb_[0] = kBone[0];
  surface_rgb_[1] = kBone[1];
  surface_rgb_[2] = kBone[2];
  volume_property_->SetColor(colour_);
  volume_property_->SetScalarOpacity(opacity_);
  volume_property_->SetInterpolationTypeToLinear();
  applyLook();
  volume_property_->GetIsoSurfaceValues()->SetNumberOfContours(1);
  volume_property_->GetIsoSurfaceValues()->SetValue(0, spec.isovalue);
  volume_->SetMapper(volume_mapper_);
  volume_->SetProperty(volume_property_);
  {
    // p_W = o + D (p_image - o)  =>  [D | o - D o].
    double origin[3];
    spec.image->GetOrigin(origin);
    const Eigen::Vector3d o(origin[0], origin[1], origin[2]);
    vtkNew<vtkMatrix4x4> m;
    setMatrix(m, spec.direction_W, o - spec.direction_W * o);
    volume_->SetUserMatrix(m);
  }
  renderer_->AddVolume(volume_);
}

void SceneActors::buildTools(const SceneActorsSpec& spec) {
  // --- Tools: the proxy solid steel, the device as a wireframe (lines write depth, so the
  // part inside the bone is hidden correctly; translucency would not be).
  vtkNew<vtkPolyDataNormals> normals;
  normals->SetInputData(polyDataFromMesh(spec.tool_mesh_T));
  normals->SetFeatureAngle(40.0);
  normals->SplittingOn();
  normals->ConsistencyOn();
  normals->Update();
  vtkNew<vtkPolyDataMapper> tool_mapper;
  tool_mapper->SetInputConnection(normals->GetOutputPort());
  tool_mapper->ScalarVisibilityOff();

  proxy_actor_->SetMapper(tool_mapper);
  tool_rgb_ = {kSteel[0], kSteel[1], kSteel[2]};
  proxy_actor_->GetProperty()->SetColor(kSteel[0], kSteel[1], kSteel[2]);
  proxy_actor_->GetProperty()->SetAmbient(0.15);
  proxy_actor_->GetProperty()->SetDiffuse(0.75);
  proxy_actor_->GetProperty()->SetSpecular(0.6);
  proxy_actor_->GetProperty()->SetSpecularPower(40.0);
  proxy_actor_->PickableOff();
  renderer_->AddActor(proxy_actor_);

  // The device shares the mesh but not the mapper. Where device and proxy coincide (free
  // motion, or sliding along a side) the solid proxy must win over the device's lines: the
  // proxy's polygons are pulled forward in depth with a slope-scaled offset (which also works at
  // grazing angles, unlike offsets on lines), the device's lines keep no forward pull.
  // Offsets only apply in polygon-offset mode, which VTK leaves off; its default parameters are
  // zero for polygons, so turning it on changes nothing else but lines and points drawn over
  // surfaces (pulled slightly forward, which is what they want).
  vtkMapper::SetResolveCoincidentTopologyToPolygonOffset();
  tool_mapper->SetRelativeCoincidentTopologyPolygonOffsetParameters(-2.0, -60.0);
  vtkNew<vtkPolyDataMapper> device_mapper;
  device_mapper->SetInputConnection(normals->GetOutputPort());
  device_mapper->ScalarVisibilityOff();
  device_mapper->SetRelativeCoincidentTopologyLineOffsetParameters(0.0, 4.0);
  device_mapper->SetRelativeCoincidentTopologyPolygonOffsetParameters(0.0, 4.0);
  device_actor_->SetMapper(device_mapper);
  device_actor_->GetProperty()->SetRepresentationToWireframe();
  device_actor_->GetProperty()->SetColor(kDevice[0], kDevice[1], kDevice[2]);
  device_actor_->GetProperty()->LightingOff();
  device_actor_->GetProperty()->SetLineWidth(1.0);
  device_actor_->PickableOff();
  device_actor_->SetVisibility(spec.show_device);
  renderer_->AddActor(device_actor_);

  setProxyPose(haptics::Pose::Identity());
  setDevicePose(haptics::Pose::Identity());
}

namespace {

/// Points drawn as spheres (shader impostors; cheap on llvmpipe too): `poly` holds `points` as
/// its vertices, drawn by `actor` in `rgb`, `size_px` wide, not pickable.
void setUpPointSprites(vtkPoints* points, vtkPolyData* poly, vtkActor* actor, const double rgb[3], double size_px) {
  points->SetDataTypeToDouble();
  poly->SetPoints(points);
  vtkNew<vtkCellArray> verts;
  poly->SetVerts(verts);
  vtkNew<vtkPolyDataMapper> mapper;
  mapper->SetInputData(poly);
  actor->SetMapper(mapper);
  actor->GetProperty()->SetColor(rgb[0], rgb[1], rgb[2]);
  actor->GetProperty()->SetPointSize(size_px);
  actor->GetProperty()->SetRenderPointsAsSpheres(true);
  actor->PickableOff();
}

/// The force arrow: a unit arrow along +x, placed and scaled by its user matrix, hidden until
/// there is a force.
void setUpForceArrow(vtkActor* force_actor) {
  vtkNew<vtkArrowSource> arrow;
  arrow->SetShaftRadius(0.04);
  arrow->SetTipRadius(0.1);
  arrow->SetTipLength(0.3);
  arrow->SetShaftResolution(16);
  arrow->SetTipResolution(16);
  vtkNew<vtkPolyDataMapper> arrow_mapper;
  arrow_mapper->SetInputConnection(arrow->GetOutputPort());
  force_actor->SetMapper(arrow_mapper);
  force_actor->GetProperty()->SetColor(kForce[0], kForce[1], kForce[2]);
  force_actor->GetProperty()->SetAmbient(0.3);
  force_actor->PickableOff();
  force_actor->VisibilityOff();
  vtkNew<vtkMatrix4x4> arrow_matrix;
  force_actor->SetUserMatrix(arrow_matrix);
}

/// The drop line from the tool to its shadow: one segment between the two points, hidden until
/// the shadow is shown.
void setUpGapLine(vtkPoints* gap_points, vtkPolyData* gap_poly, vtkActor* gap_actor) {
  gap_points->SetDataTypeToDouble();
  gap_points->SetNumberOfPoints(2);
  gap_poly->SetPoints(gap_points);
  vtkNew<vtkCellArray> gap_lines;
  const vtkIdType gap_ids[2] = {0, 1};
  gap_lines->InsertNextCell(2, gap_ids);
  gap_poly->SetLines(gap_lines);
  vtkNew<vtkPolyDataMapper> gap_mapper;
  gap_mapper->SetInputData(gap_poly);
  gap_actor->SetMapper(gap_mapper);
  gap_actor->GetProperty()->SetColor(kGapLine[0], kGapLine[1], kGapLine[2]);
  gap_actor->GetProperty()->SetLineWidth(1.5);
  gap_actor->GetProperty()->SetAmbient(1.0);
  gap_actor->GetProperty()->SetDiffuse(0.0);
  gap_actor->PickableOff();
  gap_actor->VisibilityOff();
}

/// The hint text, screen space top left (hidden when there is none).
void setUpHint(vtkTextActor* hint_actor, const std::string& hint) {
  hint_actor->SetInput(hint.c_str());
  hint_actor->GetTextProperty()->SetFontSize(13);
  hint_actor->GetTextProperty()->SetColor(0.92, 0.92, 0.92);
  hint_actor->GetTextProperty()->ShadowOn();
  hint_actor->GetTextProperty()->SetVerticalJustificationToTop();
  hint_actor->GetPositionCoordinate()->SetCoordinateSystemToNormalizedViewport();
  hint_actor->GetPositionCoordinate()->SetValue(0.01, 0.985);
  hint_actor->SetVisibility(!hint.empty());
}

}  // namespace

void SceneActors::buildOverlay(const SceneActorsSpec& spec) {
  // --- Overlay layer for contacts and force: drawn over everything (same camera), because
  // both sit where the tool meets the surface and the tool would hide them.
  if (vtkRenderWindow* window = renderer_->GetRenderWindow()) {
    window->SetNumberOfLayers(std::max(2, window->GetNumberOfLayers()));
    window->AddRenderer(overlay_);
  }
  overlay_->SetLayer(1);
  overlay_->SetActiveCamera(renderer_->GetActiveCamera());
  overlay_->InteractiveOff();
  overlay_->PreserveDepthBufferOff();

  // --- Contacts: points drawn as spheres (shader impostors; cheap on llvmpipe too).
  setUpPointSprites(contact_points_, contact_poly_, contact_actor_, kContact, 7.0);
  overlay_->AddActor(contact_actor_);

  // --- Force arrow: a unit arrow along +x, placed and scaled by the user matrix.
  const Eigen::Vector3d extent = spec.tool_mesh_T.empty()
                                     ? Eigen::Vector3d(0.02, 0.02, 0.02)
                                     : Eigen::Vector3d(spec.tool_mesh_T.boundsMax_T_m() -
                                                       spec.tool_mesh_T.boundsMin_T_m());
  arrow_reference_m_ = std::max(0.5 * extent.norm(), 1e-3);
  setUpForceArrow(force_actor_);
  overlay_->AddActor(force_actor_);

  // --- The tool's shadow and drop line: in the scene, not the overlay (the tool hides them).
  setUpPointSprites(shadow_points_, shadow_poly_, shadow_actor_, kShadow, 6.0);
  shadow_actor_->GetProperty()->SetAmbient(1.0);
  shadow_actor_->GetProperty()->SetDiffuse(0.0);
  // Drawn in front of the surface it lies on (its triangles are chords of a curved surface): the
  // patch's depth is pulled toward the camera, and the ray-cast volume stops at that depth.
  shadow_actor_->GetMapper()->SetResolveCoincidentTopologyToPolygonOffset();
  shadow_actor_->GetMapper()->SetRelativeCoincidentTopologyPolygonOffsetParameters(-2.0, -400.0);
  shadow_actor_->VisibilityOff();
  renderer_->AddActor(shadow_actor_);
  setUpGapLine(gap_points_, gap_poly_, gap_actor_);
  renderer_->AddActor(gap_actor_);

  // --- Hint text (screen space, top left).
  setUpHint(hint_actor_, spec.hint);
  renderer_->AddActor2D(hint_actor_);
}

SceneActors::~SceneActors() {
  renderer_->RemoveObserver(render_observer_);
  if (mesh_ != nullptr) renderer_->RemoveActor(mesh_->actor());
  renderer_->RemoveVolume(volume_);
  renderer_->RemoveActor(proxy_actor_);
  renderer_->RemoveActor(device_actor_);
  overlay_->RemoveActor(contact_actor_);
  overlay_->RemoveActor(force_actor_);
  renderer_->RemoveActor(shadow_actor_);
  renderer_->RemoveActor(gap_actor_);
  if (vtkRenderWindow* window = renderer_->GetRenderWindow()) {
    window->RemoveRenderer(overlay_);
  }
  renderer_->RemoveActor2D(hint_actor_);
}

void SceneActors::applyLook() {
  VolumeLook look;
  switch (mode_) {
    case RenderMode::kIsosurface:
      volume_mapper_->SetBlendModeToIsoSurface();
      look = isosurfaceLook(range_[0], range_[1], surface_rgb_[0], surface_rgb_[1], surface_rgb_[2]);
      break;
    case RenderMode::kComposite:
      volume_mapper_->SetBlendModeToComposite();
      look = compositeLook(preset_, range_[0], range_[1], hounsfield_);
      break;
    case RenderMode::kMip:
      volume_mapper_->SetBlendModeToMaximumIntensity();
      look = mipLook(range_[0], range_[1], hounsfield_);
      break;
  }
  colour_->RemoveAllPoints();
  for (const ColourPoint& c : look.colour) colour_->AddRGBPoint(c.value, c.r, c.g, c.b);
  opacity_->RemoveAllPoints();
  for (const OpacityPoint& o : look.opacity) opacity_->AddPoint(o.value, o.opacity);
  look_shaded_ = look.shade;
  applyShade();
  volume_property_->SetAmbient(look.ambient);
  volume_property_->SetDiffuse(look.diffuse);
  volume_property_->SetSpecular(look.specular);
  volume_property_->SetSpecularPower(look.specular_power);
  // Opacities are per voxel of ray (the image is in metres: VTK's default unit distance, 1, would
  // be a metre and make every composite rendering nearly transparent).
  volume_property_->SetScalarOpacityUnitDistance(look.opacity_unit_distance_voxels * min_spacing_m_);
  volume_property_->Modified();
  if (mesh_ != nullptr && mode_ == RenderMode::kIsosurface)
    mesh_->setLook(surface_rgb_, look.ambient, look.diffuse, look.specular, look.specular_power);
  applyMovingView();
}

void SceneActors::setRenderMode(RenderMode mode, VolumePreset preset) {
  mode_ = mode;
  preset_ = preset;
  applyLook();
}

void SceneActors::setSurfaceColour(double r, double g, double b) {
  surface_rgb_[0] = r;
  surface_rgb_[1] = g;
  surface_rgb_[2] = b;
  if (mode_ == RenderMode::kIsosurface) applyLook();
}

void SceneActors::setToolColour(double r, double g, double b) {
  tool_rgb_ = {r, g, b};
  if (proximity_level_ == 0) proxy_actor_->GetProperty()->SetColor(r, g, b);  // a warning's colour stays
}
void SceneActors::setDeviceColour(double r, double g, double b) { device_actor_->GetProperty()->SetColor(r, g, b); }

void SceneActors::setToolMesh(const haptics::TriangleMesh& mesh_T, const Eigen::Vector3d& /*p_TCm_m*/) {
  // Both tool mappers read the same normals filter; replacing its input updates both.
  auto* proxy_mapper = vtkPolyDataMapper::SafeDownCast(proxy_actor_->GetMapper());
  if (proxy_mapper == nullptr) return;
  auto* normals = vtkPolyDataNormals::SafeDownCast(proxy_mapper->GetInputAlgorithm());
  if (normals == nullptr) return;
  normals->SetInputData(polyDataFromMesh(mesh_T));
  normals->Update();
  const Eigen::Vector3d extent = mesh_T.empty() ? Eigen::Vector3d(0.02, 0.02, 0.02)
                                                : Eigen::Vector3d(mesh_T.boundsMax_T_m() - mesh_T.boundsMin_T_m());
  arrow_reference_m_ = std::max(0.5 * extent.norm(), 1e-3);
}

void SceneActors::setClipPlane(bool enabled, const Eigen::Vector3d& p_W_origin_m, const Eigen::Vector3d& n_W) {
  clipping_ = enabled && p_W_origin_m.allFinite() && n_W.norm() > 0.0;
  volume_mapper_->RemoveAllClippingPlanes();
  if (mesh_ != nullptr) mesh_->setClipPlane(nullptr);
  if (!clipping_) return;
  // The GPU ray caster takes clipping planes in world coordinates (it applies the prop's user
  // matrix itself; VTK's TestGPURayCastClippingUserTransform).
  const Eigen::Vector3d n = n_W.normalized();
  clip_plane_->SetOrigin(p_W_origin_m.x(), p_W_origin_m.y(), p_W_origin_m.z());
  clip_plane_->SetNormal(n.x(), n.y(), n.z());
  volume_mapper_->AddClippingPlane(clip_plane_);
  if (mesh_ != nullptr) mesh_->setClipPlane(clip_plane_);
}

void SceneActors::setHint(const std::string& hint) {
  hint_actor_->SetInput(hint.c_str());
  hint_actor_->SetVisibility(!hint.empty());
}

void SceneActors::volumeBounds_W(double bounds[6]) const { volume_->GetBounds(bounds); }

void SceneActors::setIsovalue(double isovalue) {
  volume_property_->GetIsoSurfaceValues()->SetValue(0, isovalue);
  volume_property_->Modified();
  if (mesh_ != nullptr) mesh_->setIsovalue(isovalue);
}

double SceneActors::isovalue() const {
  return volume_property_->GetIsoSurfaceValues()->GetValue(0);
}

void SceneActors::setProxyPose(const haptics::Pose& X_WP) { setUserPose(proxy_actor_, X_WP); }
void SceneActors::setDevicePose(const haptics::Pose& X_WD) { setUserPose(device_actor_, X_WD); }
void SceneActors::setDeviceVisible(bool visible) { device_actor_->SetVisibility(visible); }

namespace {
/// `poly` (whose points are `points`) as one vertex per point of p_W_m, each moved by offset_W.
void setVertices(vtkPoints* points, vtkPolyData* poly, std::span<const Eigen::Vector3d> p_W_m,
                 const Eigen::Vector3d& offset_W = Eigen::Vector3d::Zero()) {
  const auto n = static_cast<vtkIdType>(p_W_m.size());
  points->SetNumberOfPoints(n);
  vtkNew<vtkCellArray> verts;
  verts->AllocateExact(n, n);
  for (vtkIdType i = 0; i < n; ++i) {
    const Eigen::Vector3d p = p_W_m[static_cast<std::size_t>(i)] + offset_W;
    points->SetPoint(i, p.x(), p.y(), p.z());
    verts->InsertNextCell(1, &i);
  }
  points->Modified();
  poly->SetVerts(verts);
  poly->Modified();
}
}  // namespace

void SceneActors::setContacts(std::span<const Eigen::Vector3d> p_W_m) {
  setVertices(contact_points_, contact_poly_, p_W_m);
  contact_actor_->SetVisibility(!p_W_m.empty());
}

double SceneActors::forceArrowLength_m(double magnitude_N) const noexcept {
  if (!(magnitude_N > 1e-3)) return 0.0;
  return arrow_reference_m_ * std::clamp(magnitude_N / kReferenceForce_N, 0.15, 2.5);
}

void SceneActors::setForce(const Eigen::Vector3d& p_W_origin_m, const Eigen::Vector3d& force_W_N) {
  const double magnitude = force_W_N.norm();
  if (!(magnitude > 1e-3) || !p_W_origin_m.allFinite()) {
    force_actor_->VisibilityOff();
    return;
  }
  const double length = forceArrowLength_m(magnitude);
  const Eigen::Vector3d x = force_W_N / magnitude;
  const Eigen::Vector3d y = x.unitOrthogonal();
  const Eigen::Vector3d z = x.cross(y);
  Eigen::Matrix3d M;
  M.col(0) = length * x;
  M.col(1) = length * y;
  M.col(2) = length * z;
  setMatrix(force_actor_->GetUserMatrix(), M, p_W_origin_m);
  force_actor_->GetUserMatrix()->Modified();
  force_actor_->Modified();
  force_actor_->VisibilityOn();
}

void SceneActors::setShadow(const ToolShadow& shadow, const Eigen::Vector3d& direction_W) {
  const double length = direction_W.norm();
  const Eigen::Vector3d lift_W =
      length > 0.0 && std::isfinite(length) ? Eigen::Vector3d(-0.5 * min_spacing_m_ / length * direction_W)
                                            : Eigen::Vector3d::Zero();
  const std::size_t n = shadow.footprint_W_m.size();
  setVertices(shadow_points_, shadow_poly_, shadow.footprint_W_m, lift_W);
  // A shadow, not scattered dots: the footprint's points triangulated (2-D Delaunay in their
  // best-fitting plane, across the light: the convex hull of the tool's footprint), each
  // triangle's corners on the surface itself, so the patch follows it; drawn dark and opaque
  // (the ray-cast volume is composited after translucent geometry and would paint over a
  // translucent patch). The points stay drawn as before, in the same colour: they round the
  // patch's edge and keep a small tool's shadow visible when the view is small.
  vtkNew<vtkCellArray> triangles;
  if (n >= 3) {
    vtkNew<vtkPolyData> cloud;
    cloud->SetPoints(shadow_points_);
    vtkNew<vtkDelaunay2D> delaunay;
    delaunay->SetInputData(cloud);
    delaunay->SetProjectionPlaneMode(VTK_BEST_FITTING_PLANE);
    delaunay->Update();
    if (delaunay->GetOutput()->GetNumberOfPoints() == static_cast<vtkIdType>(n))  // ids are the footprint's
      triangles->DeepCopy(delaunay->GetOutput()->GetPolys());
  }
  shadow_poly_->SetPolys(triangles);
  shadow_poly_->Modified();
  if (shadow.has_gap) {
    const Eigen::Vector3d to = shadow.gap_to_W_m + lift_W;
    gap_points_->SetPoint(0, shadow.gap_from_W_m.x(), shadow.gap_from_W_m.y(), shadow.gap_from_W_m.z());
    gap_points_->SetPoint(1, to.x(), to.y(), to.z());
    gap_points_->Modified();
    gap_poly_->Modified();
  }
  shadow_shown_ = n > 0;
  gap_shown_ = shadow.has_gap;
  shadow_actor_->SetVisibility(shadow_on_ && shadow_shown_);
  gap_actor_->SetVisibility(shadow_on_ && gap_shown_);
}

void SceneActors::setShadowVisible(bool visible) {
  shadow_on_ = visible;
  shadow_actor_->SetVisibility(shadow_on_ && shadow_shown_);
  gap_actor_->SetVisibility(shadow_on_ && gap_shown_);
}

void SceneActors::primeLaterProps(const std::function<void()>& render) {
  // A point at the proxy (inside the tool), for each prop that has none.
  Eigen::Vector3d at_W = Eigen::Vector3d::Zero();
  if (vtkMatrix4x4* m = proxy_actor_->GetUserMatrix()) {
    for (int i = 0; i < 3; ++i) at_W[i] = m->GetElement(i, 3);
  }
  const bool volume_shown = volume_->GetVisibility() != 0;
  const bool contacts_shown = contact_actor_->GetVisibility() != 0, force_shown = force_actor_->GetVisibility() != 0;
  const bool shadow_shown = shadow_actor_->GetVisibility() != 0, gap_shown = gap_actor_->GetVisibility() != 0;
  const bool no_contacts = contact_points_->GetNumberOfPoints() == 0, no_shadow = shadow_points_->GetNumberOfPoints() == 0;
  const std::span<const Eigen::Vector3d> one_point(&at_W, 1), no_point;
  if (no_contacts) setVertices(contact_points_, contact_poly_, one_point);
  if (no_shadow) setVertices(shadow_points_, shadow_poly_, one_point);
  for (vtkActor* actor : {contact_actor_.GetPointer(), force_actor_.GetPointer(), shadow_actor_.GetPointer(),
                          gap_actor_.GetPointer()})
    actor->SetVisibility(true);
  // The volume as the first interactive frames draw it: the largest reduction (the ray caster's
  // reduced image), the nearest voxel.
  volume_->SetVisibility(true);
  sampleAsFirstMotion();
  render();
  applyQuality();  // the sampling of the frames in hand again
  if (no_contacts) setVertices(contact_points_, contact_poly_, no_point);
  if (no_shadow) setVertices(shadow_points_, shadow_poly_, no_point);
  volume_->SetVisibility(volume_shown);
  contact_actor_->SetVisibility(contacts_shown);
  force_actor_->SetVisibility(force_shown);
  shadow_actor_->SetVisibility(shadow_shown);
  gap_actor_->SetVisibility(gap_shown);
}

vtkActor* SceneActors::shadowActor() const noexcept { return shadow_actor_; }
vtkActor* SceneActors::gapLineActor() const noexcept { return gap_actor_; }

vtkVolume* SceneActors::volume() const noexcept { return volume_; }
vtkGPUVolumeRayCastMapper* SceneActors::volumeMapper() const noexcept { return volume_mapper_; }
vtkActor* SceneActors::proxyActor() const noexcept { return proxy_actor_; }

void SceneActors::setProximityLevel(int level) {
  static constexpr double kAmber[3] = {1.0, 0.72, 0.18}, kRed[3] = {0.95, 0.22, 0.18};
  proximity_level_ = level;
  const double* c = level >= 2 ? kRed : level == 1 ? kAmber : tool_rgb_.data();
  proxy_actor_->GetProperty()->SetColor(c[0], c[1], c[2]);
}
vtkActor* SceneActors::deviceActor() const noexcept { return device_actor_; }
vtkActor* SceneActors::contactActor() const noexcept { return contact_actor_; }
vtkActor* SceneActors::forceActor() const noexcept { return force_actor_; }
vtkTextActor* SceneActors::hintActor() const noexcept { return hint_actor_; }
vtkRenderer* SceneActors::overlayRenderer() const noexcept { return overlay_; }

ViewCamera viewCameraOf(vtkCamera* camera, int viewport_height_px, int viewport_width_px) {
  ViewCamera c;
  double v[3];
  camera->GetPosition(v);
  c.position_W_m = Eigen::Vector3d(v[0], v[1], v[2]);
  camera->GetFocalPoint(v);
  c.focal_point_W_m = Eigen::Vector3d(v[0], v[1], v[2]);
  camera->GetViewUp(v);
  c.view_up_W = Eigen::Vector3d(v[0], v[1], v[2]);
  c.view_angle_deg = camera->GetViewAngle();
  c.parallel = camera->GetParallelProjection() != 0;
  c.parallel_scale_m = camera->GetParallelScale();
  c.viewport_height_px = std::max(1, viewport_height_px);
  c.viewport_width_px = std::max(1, viewport_width_px);
  return c;
}

Eigen::Vector3d forceOrigin_W(const haptics::Pose& X_WP, const Eigen::Vector3d& force_W_N,
                              const std::vector<Eigen::Vector3d>& tool_vertices_T_m) {
  if (tool_vertices_T_m.empty() || !(force_W_N.norm() > 1e-3)) return X_WP.p_AB_m;
  const Eigen::Vector3d f_T = X_WP.R_AB.inverse() * force_W_N;  // the force in T
  const auto least = std::min_element(tool_vertices_T_m.begin(), tool_vertices_T_m.end(),
                                      [&](const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
                                        return f_T.dot(a) < f_T.dot(b);
                                      });
  return X_WP * *least;
}

void showToolFrame(SceneActors& actors, const ToolFrame& frame, const std::vector<Eigen::Vector3d>& tool_vertices_T_m) {
  actors.setProxyPose(frame.X_WP);
  actors.setDevicePose(frame.X_WD);
  actors.setContacts(frame.contacts_W_m);
  actors.setForce(forceOrigin_W(frame.X_WP, frame.force_W_N, tool_vertices_T_m), frame.force_W_N);
  if (std::isfinite(frame.isovalue)) actors.setIsovalue(frame.isovalue);
}

}  // namespace vh::ui
