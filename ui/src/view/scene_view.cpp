#include "vh/ui/view/scene_view.h"
#include "vh/ui/view/tool_shadow.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>

#include <QTimer>
#include <vtkActor.h>
#include <vtkCamera.h>
#include <vtkGenericOpenGLRenderWindow.h>
#include <vtkGenericRenderWindowInteractor.h>
#include <vtkMapper.h>
#include <vtkNew.h>
#include <vtkRenderer.h>
#include <vtkTextActor.h>
#include <vtkTextProperty.h>

#include "vh/ui/view/expert_ghost.h"
#include "vh/ui/view/orientation_marker.h"
#include "vh/ui/view/vtk_view.h"

namespace vh::ui {
namespace {

constexpr int kSettleMs = 300;  // still frame this long after the last motion
// The frame rates asked of VTK (vtkRenderWindowInteractor's desired and still update rates):
// interactive frames at 33 Hz (30 ms from one frame to the next, render and the GUI's other work
// together: 30 frames per second with a tenth to spare for the machine's noise), which keeps the
// whole frame within 50 ms on software GL (Mesa's llvmpipe) at 1280 x 720; still frames
// unhurried (full quality). The ray caster follows them through SceneActors::adaptQuality(), not
// through its own automatic sample distances.
constexpr double kInteractiveRate_Hz = 33.0;
constexpr double kStillRate_Hz = 0.0001;

// A point that moved less than this on screen [px] has not moved visibly: the proxy's
// micro-motion while it rests on a surface (a few micrometres a tick under the hand's steady
// push) neither redraws the view nor keeps its frames interactive (coarse).
constexpr double kVisibleShift_px = 1.0;

/// The 8 corners of the axis-aligned box around `vertices_T_m` (T [m]); the origin alone when empty.
std::vector<Eigen::Vector3d> boxCorners(const std::vector<Eigen::Vector3d>& vertices_T_m) {
  if (vertices_T_m.empty()) return {Eigen::Vector3d::Zero()};
  Eigen::Vector3d lo = vertices_T_m.front(), hi = lo;
  for (const Eigen::Vector3d& v : vertices_T_m) {
    lo = lo.cwiseMin(v);
    hi = hi.cwiseMax(v);
  }
  std::vector<Eigen::Vector3d> corners;
  for (int c = 0; c < 8; ++c) corners.emplace_back((c & 1) ? hi.x() : lo.x(), (c & 2) ? hi.y() : lo.y(), (c & 4) ? hi.z() : lo.z());
  return corners;
}

/// How far `a_W` lies from `b_W` in pixels of `camera` at a's depth (the whole 3-D distance:
/// a motion along the view ray counts too, so this never underestimates the shift on screen).
double shift_px(const ViewCamera& camera, const Eigen::Vector3d& a_W, const Eigen::Vector3d& b_W) {
  const double m_per_px = camera.metresPerPixelAt(a_W);
  if (!(m_per_px > 0.0) || !std::isfinite(m_per_px)) return std::numeric_limits<double>::infinity();
  return (a_W - b_W).norm() / m_per_px;
}


/// The renderer the segments are drawn in through the scan, added to `view`'s window: a layer
/// (1) over the scan's renderer with its camera and a depth buffer of its own (in front of the
/// scan, in order among themselves), not interactive, drawing nothing until asked.
vtkSmartPointer<vtkRenderer> addSegmentLayer(VtkView& view) {
  auto layer = vtkSmartPointer<vtkRenderer>::New();
  layer->SetLayer(1);
  layer->SetActiveCamera(view.renderer()->GetActiveCamera());
  layer->InteractiveOff();
  layer->PreserveDepthBufferOff();
  layer->SetDraw(false);
  view.renderWindow()->SetNumberOfLayers(std::max(2, view.renderWindow()->GetNumberOfLayers()));
  view.renderWindow()->AddRenderer(layer);
  return layer;
}

}  // namespace

SceneView::SceneView(QWidget* parent) : QObject(parent) {
  view_ = new VtkView(parent);
  view_->setObjectName("vtkView");
  // Before the orientation marker's and the contacts' layers: drawn over it, in that order.
  segment_layer_ = addSegmentLayer(*view_);
  marker_ = std::make_unique<OrientationMarker>(view_->renderWindow(), view_->renderer());
  marker_->setVisible(false);  // shown with a scene
  view_->renderer()->GradientBackgroundOn();
  view_->interactor()->SetDesiredUpdateRate(kInteractiveRate_Hz);
  view_->interactor()->SetStillUpdateRate(kStillRate_Hz);

  // What an empty window says.
  vtkNew<vtkTextActor> welcome;
  welcome->SetInput(
      "Open a scan: File > Open DICOM Folder (Ctrl+D), Open Volume File (Ctrl+O) or Open Scene\n"
      "(Ctrl+Shift+O) - or drop a DICOM folder, a NRRD / MetaImage file or a scene .json here.");
  welcome->GetTextProperty()->SetFontSize(15);
  welcome->GetTextProperty()->SetColor(0.9, 0.9, 0.9);
  welcome->GetTextProperty()->SetJustificationToCentered();
  welcome->GetTextProperty()->SetVerticalJustificationToCentered();
  welcome->GetPositionCoordinate()->SetCoordinateSystemToNormalizedViewport();
  welcome->GetPositionCoordinate()->SetValue(0.5, 0.5);
  view_->renderer()->AddActor2D(welcome);
  welcome_ = welcome;

  // A critical segment touched: red text at the top of the view.
  vtkNew<vtkTextActor> alert;
  alert->GetTextProperty()->SetFontSize(22);
  alert->GetTextProperty()->SetBold(true);
  alert->GetTextProperty()->SetColor(1.0, 1.0, 1.0);
  alert->GetTextProperty()->SetBackgroundColor(0.75, 0.1, 0.1);
  alert->GetTextProperty()->SetBackgroundOpacity(0.9);
  alert->GetTextProperty()->SetJustificationToCentered();
  alert->GetTextProperty()->SetVerticalJustificationToTop();
  alert->GetPositionCoordinate()->SetCoordinateSystemToNormalizedViewport();
  alert->GetPositionCoordinate()->SetValue(0.5, 0.88);  // below the hint lines
  alert->SetVisibility(false);
  view_->renderer()->AddActor2D(alert);
  alert_ = alert;

  // Interactive (cheaper) frames while something moves, a full-quality one when it settles.
  settle_timer_ = new QTimer(this);
  settle_timer_->setSingleShot(true);
  settle_timer_->setInterval(kSettleMs);
  connect(settle_timer_, &QTimer::timeout, this, [this] {
    if (!camera_dragging_ && !interacting_) renderStill();
  });
  connect(view_, &VtkView::interactionStarted, this, [this] {
    camera_dragging_ = true;
    noteMotion();
  });
  connect(view_, &VtkView::interactionEnded, this, [this] {
    camera_dragging_ = false;
    settle_timer_->start();
  });
  connect(view_, &VtkView::frameRendered, this, [this] {
    // After the scene's first frame (shown), an unseen render readies the props that appear
    // only later, so that the first contact's frame compiles no shaders.
    if (prime_pending_ && actors_ != nullptr) {
      prime_pending_ = false;
      QTimer::singleShot(0, this, [this] {
        if (actors_ != nullptr) actors_->primeLaterProps([this] { view_->renderUnseen(); });
      });
    }
    noteFrameGap();
    // The first frame of a scene also compiles shaders and uploads the volume.
    if (actors_ != nullptr && view_->frameCount() > scene_frame_ + 1)
      actors_->adaptQuality(view_->lastFrameMs(), interactiveTargetMs());
    // The still frame comes kSettleMs after the last interactive frame was drawn, not after the
    // motion that asked for it: with frames slower than kSettleMs (software GL), every frame of
    // a moving tool would otherwise be followed by a still one.
    if (actors_ != nullptr && actors_->interactive() && settle_timer_->isActive()) settle_timer_->start();
  });
}

double SceneView::interactivePeriodMs() const { return 1000.0 / view_->interactor()->GetDesiredUpdateRate(); }

void SceneView::noteFrameGap() {
  // Back-to-back interactive frames only: a longer gap is the view at rest, not the GUI's cost.
  const double gap_ms = view_->lastGapMs();
  if (actors_ != nullptr && actors_->interactive() && gap_ms >= 0.0 && gap_ms < interactivePeriodMs())
    frame_gap_ms_ += 0.3 * (gap_ms - frame_gap_ms_);
}

double SceneView::interactiveTargetMs() const {
  const double period_ms = interactivePeriodMs();
  return std::max(period_ms - frame_gap_ms_, 0.5 * period_ms);
}

SceneView::~SceneView() {
  // VTK props release their GL objects when they leave the renderer: give them the context.
  const bool current = view_->context() != nullptr && view_->makeCurrent();
  takeToolsOutOfLayer();
  ghost_.reset();
  actors_.reset();
  segments_.reset();
  marker_.reset();
  view_->renderWindow()->RemoveRenderer(segment_layer_);
  if (current) view_->doneCurrent();
}

void SceneView::setScene(const SceneActorsSpec& spec, const haptics::Pose& X_WT, const ViewLook& look) {
  if (spec.image == nullptr) throw std::invalid_argument("SceneView: the scene's volume has no image to render");
  // The scan's props only: the segment surfaces follow the session's segments (setSegments()).
  if (view_->context() != nullptr) {
    view_->makeCurrent();
    takeToolsOutOfLayer();
    ghost_.reset();
    actors_.reset();
    view_->doneCurrent();
  }
  takeToolsOutOfLayer();
  actors_ = std::make_unique<SceneActors>(view_->renderer(), spec);
  ghost_ = std::make_unique<ExpertGhost>(actors_->overlayRenderer(),
                                         actors_->proxyActor()->GetMapper()->GetInputConnection(0, 0));
  tool_vertices_T_m_ = spec.tool_mesh_T.vertices_T_m;
  tool_corners_T_m_ = boxCorners(tool_vertices_T_m_);
  actors_->setProxyPose(X_WT);
  actors_->setDevicePose(X_WT);
  actors_->setRenderMode(look.mode, look.preset);
  actors_->setShadowVisible(look.tool_shadow);
  setSharpMotion(sharp_motion_);
  shown_X_WP_ = shown_X_WD_ = X_WT;
  shown_contacts_ = -1;
  shown_force_W_N_.setZero();
  scene_frame_ = view_->frameCount();
  prime_pending_ = true;
  if (welcome_ != nullptr) welcome_->SetVisibility(false);
  marker_->setVisible(look.orientation_marker);
  through_scan_ = look.segments_through_scan;
  placeSegments();
  applyColours(look);
  resetCamera();
  requestRender();
}

void SceneView::clearScene() {
  if (actors_ == nullptr) return;
  if (view_->context() != nullptr) {
    view_->makeCurrent();
    takeToolsOutOfLayer();
    ghost_.reset();
    actors_.reset();
    segments_.reset();
    view_->doneCurrent();
  }
  takeToolsOutOfLayer();
  ghost_.reset();
  actors_.reset();
  segments_.reset();
  segment_layer_->SetDraw(false);
  if (alert_ != nullptr) alert_->SetVisibility(false);
}

const std::vector<int>& SceneView::setSegments(const runtime::SegmentSet* set) {
  if (segments_ == nullptr) segments_ = std::make_unique<SegmentSurfaces>(view_->renderer());
  segments_->show(set, surface_rgb_);
  placeSegments();
  return segments_->recoloured();
}

void SceneView::adoptSegmentSurfaces(const runtime::SegmentSet& set, std::map<int, SegmentSurface> built) {
  if (segments_ == nullptr) segments_ = std::make_unique<SegmentSurfaces>(view_->renderer());
  segments_->adopt(set, std::move(built));
}

void SceneView::setSegmentsThroughScan(bool on) {
  through_scan_ = on;
  placeSegments();
}

vtkRenderer* SceneView::segmentLayer() const noexcept { return segment_layer_; }

void SceneView::takeToolsOutOfLayer() {
  for (const vtkSmartPointer<vtkActor>& tool : layer_tools_) segment_layer_->RemoveActor(tool);
  layer_tools_.clear();
}

void SceneView::placeSegments() {
  takeToolsOutOfLayer();
  const bool layered = through_scan_ && segments_ != nullptr && !segments_->shownSegments().empty();
  if (segments_ != nullptr) segments_->setRenderer(through_scan_ ? segment_layer_.Get() : view_->renderer());
  // The tools in the layer too (they stay in the scan's renderer): each drawn where it lies
  // against the segments, not under them.
  if (layered && actors_ != nullptr) {
    for (vtkActor* tool : {actors_->proxyActor(), actors_->deviceActor()}) {
      if (tool == nullptr) continue;
      segment_layer_->AddActor(tool);
      layer_tools_.emplace_back(tool);
    }
  }
  segment_layer_->SetDraw(layered);
  requestRender();
}

void SceneView::setTouchedSegment(int segment, const std::string& alert) {
  if (segments_ != nullptr) segments_->setTouched(segment);
  if (alert_ != nullptr) {
    alert_->SetInput(alert.c_str());
    alert_->SetVisibility(!alert.empty());
  }
  requestRender();
}

void SceneView::setGhostPath(const haptics::GuidancePath* path) {
  if (ghost_ == nullptr) return;
  ghost_->setPath(path);
  requestRender();
}

void SceneView::showGhost(const haptics::Pose& X_WE) {
  if (ghost_ == nullptr || !X_WE.allFinite()) return;
  const bool moved = !ghost_->visible() || ghost_->pose().p_AB_m != X_WE.p_AB_m ||
                     ghost_->pose().R_AB.coeffs() != X_WE.R_AB.coeffs();
  ghost_->show(X_WE);
  if (moved) requestRender();
}

void SceneView::hideGhost() {
  if (ghost_ == nullptr || !ghost_->visible()) return;
  ghost_->hide();
  requestRender();
}

void SceneView::setToolProximity(int level) {
  if (actors_ == nullptr) return;
  actors_->setProximityLevel(level);
  requestRender();
}

std::string SceneView::alertText() const {
  return alert_ != nullptr && alert_->GetVisibility() && alert_->GetInput() != nullptr ? alert_->GetInput() : "";
}

void SceneView::setTool(const haptics::ToolModel& tool, const haptics::Pose& X_WT) {
  if (actors_ == nullptr) return;
  tool_vertices_T_m_ = tool.mesh_T.vertices_T_m;
  tool_corners_T_m_ = boxCorners(tool_vertices_T_m_);
  actors_->setToolMesh(tool.mesh_T, tool.mass.p_TCm_m);
  ToolFrame frame;
  frame.X_WP = frame.X_WD = X_WT;
  showToolFrame(*actors_, frame, tool_vertices_T_m_);
  shown_X_WP_ = shown_X_WD_ = X_WT;
  shown_contacts_ = -1;
  requestRender();
}

bool SceneView::changedVisibly(const ToolFrame& frame) const {
  if (static_cast<int>(frame.contacts_W_m.size()) != shown_contacts_) return true;
  if (!frame.X_WP.allFinite() || !frame.X_WD.allFinite()) return false;  // nothing to draw anew
  const ViewCamera cam = camera();
  for (const Eigen::Vector3d& c_T : tool_corners_T_m_) {
    if (shift_px(cam, frame.X_WP * c_T, shown_X_WP_ * c_T) >= kVisibleShift_px ||
        shift_px(cam, frame.X_WD * c_T, shown_X_WD_ * c_T) >= kVisibleShift_px)
      return true;
  }
  // The force arrow: shown or hidden, its start (the tool's extreme point against the force)
  // and its tip.
  const double length_m = actors_->forceArrowLength_m(frame.force_W_N.norm());
  const double shown_length_m = actors_->forceArrowLength_m(shown_force_W_N_.norm());
  if ((length_m > 0.0) != (shown_length_m > 0.0)) return true;
  if (length_m > 0.0) {
    const Eigen::Vector3d from_W = forceOrigin_W(frame.X_WP, frame.force_W_N, tool_vertices_T_m_);
    const Eigen::Vector3d shown_from_W = forceOrigin_W(shown_X_WP_, shown_force_W_N_, tool_vertices_T_m_);
    const Eigen::Vector3d tip_W = from_W + length_m * frame.force_W_N.normalized();
    const Eigen::Vector3d shown_tip_W = shown_from_W + shown_length_m * shown_force_W_N_.normalized();
    if (shift_px(cam, from_W, shown_from_W) >= kVisibleShift_px || shift_px(cam, tip_W, shown_tip_W) >= kVisibleShift_px)
      return true;
  }
  return false;
}

bool SceneView::show(const ToolFrame& frame) {
  if (actors_ == nullptr) return false;
  const int contacts = static_cast<int>(frame.contacts_W_m.size());
  const bool changed = changedVisibly(frame);
  // The tools always show the latest frame exactly; a new picture (and interactive frames until
  // it settles) is asked for only when something moved by a pixel or more on screen.
  actors_->setProxyPose(frame.X_WP);
  actors_->setDevicePose(frame.X_WD);
  if (!changed) return false;
  showToolFrame(*actors_, frame, tool_vertices_T_m_);
  shown_X_WP_ = frame.X_WP;
  shown_X_WD_ = frame.X_WD;
  shown_contacts_ = contacts;
  shown_force_W_N_ = frame.force_W_N;
  noteMotion();
  requestRender();
  emit toolFrameShown();
  return true;
}

void SceneView::showDevicePose(const haptics::Pose& X_WD) {
  if (actors_ == nullptr) return;
  actors_->setDevicePose(X_WD);
  shown_X_WD_ = X_WD;
  noteMotion();
  requestRender();
}

void SceneView::setIsovalue(double isovalue) {
  if (actors_ == nullptr) return;
  actors_->setIsovalue(isovalue);
  requestRender();
}

void SceneView::setDeviceVisible(bool visible) {
  if (actors_ == nullptr) return;
  actors_->setDeviceVisible(visible);
  requestRender();
}

void SceneView::showShadow(const ToolShadow& shadow, const Eigen::Vector3d& direction_W) {
  if (actors_ == nullptr) return;
  actors_->setShadow(shadow, direction_W);
  requestRender();
}

void SceneView::setShadowVisible(bool visible) {
  if (actors_ == nullptr) return;
  actors_->setShadowVisible(visible);
  requestRender();
}

Eigen::Vector3d SceneView::shadowDirection_W() const { return shadowLightDirection_W(camera()); }

void SceneView::setHint(const std::string& hint) {
  if (actors_ != nullptr) actors_->setHint(hint);
}

void SceneView::setRenderMode(RenderMode mode, VolumePreset preset) {
  if (actors_ == nullptr) return;
  actors_->setRenderMode(mode, preset);
  requestRender();
}

void SceneView::applyColours(const ViewLook& look) {
  surface_rgb_ = {look.surface.redF(), look.surface.greenF(), look.surface.blueF()};
  ui::applyColours(view_->renderer(), actors_.get(), look);
  requestRender();
}

void SceneView::setMarkerVisible(bool visible) {
  marker_->setVisible(visible && actors_ != nullptr);
  requestRender();
}

namespace {

/// Fraction of the viewport's half width and half height the volume's bounds may fill when the
/// camera frames them: a margin of 5 % on each side.
constexpr double kFrameFill = 0.9;

/// Moves `cam` along its direction of projection (and sets the parallel scale) so that the 8
/// corners of `bounds` [m, W: xmin xmax ymin ymax zmin zmax] project inside `fill` (0..1) of
/// the viewport of aspect `aspect` (width / height), the focal point at the bounds' centre.
/// The direction of projection and the view up are kept. Exact for the box's corners (the
/// perspective of the nearer corners included), unlike vtkRenderer::ResetCamera(), which fits
/// the bounding sphere and cuts a long body off once zoomed.
void frameBounds(vtkCamera* cam, const double bounds[6], double aspect, double fill) {
  const Eigen::Vector3d centre(0.5 * (bounds[0] + bounds[1]), 0.5 * (bounds[2] + bounds[3]),
                               0.5 * (bounds[4] + bounds[5]));
  double v[3];
  cam->GetDirectionOfProjection(v);
  const Eigen::Vector3d dop = Eigen::Vector3d(v[0], v[1], v[2]).normalized();
  cam->GetViewUp(v);
  const Eigen::Vector3d up = Eigen::Vector3d(v[0], v[1], v[2]).normalized();
  const Eigen::Vector3d right = dop.cross(up).normalized();
  const double tan_v = fill * std::tan(0.5 * cam->GetViewAngle() * std::numbers::pi / 180.0);
  const double tan_h = tan_v * aspect;
  double distance = 0.0;      // camera to focal point [m] (perspective)
  double half_height = 0.0;   // parallel scale [m]
  double nearest = 0.0;       // the corner nearest the camera, along -dop from the centre [m]
  for (int corner = 0; corner < 8; ++corner) {
    const Eigen::Vector3d p(bounds[(corner & 1) ? 1 : 0], bounds[(corner & 2) ? 3 : 2], bounds[(corner & 4) ? 5 : 4]);
    const Eigen::Vector3d d = p - centre;
    const double towards = -d.dot(dop);  // nearer the camera than the focal point
    const double x = std::abs(d.dot(right));
    const double y = std::abs(d.dot(up));
    distance = std::max({distance, towards + y / tan_v, towards + x / tan_h});
    half_height = std::max({half_height, y / fill, x / (fill * aspect)});
    nearest = std::max(nearest, towards);
  }
  if (cam->GetParallelProjection() != 0) distance = std::max(distance, 2.0 * nearest + 1e-3);
  distance = std::max(distance, 1e-3);
  cam->SetFocalPoint(centre.x(), centre.y(), centre.z());
  cam->SetPosition(centre.x() - distance * dop.x(), centre.y() - distance * dop.y(), centre.z() - distance * dop.z());
  cam->SetParallelScale(std::max(half_height, 1e-4));
}

}  // namespace

void SceneView::fitCamera(const double direction_W[3], const double up_W[3], double zoom) {
  if (actors_ == nullptr) return;
  vtkRenderer* renderer = view_->renderer();
  vtkCamera* cam = renderer->GetActiveCamera();
  // The whole volume, and the tools where they are (at load, just above it).
  double bounds[6];
  actors_->volumeBounds_W(bounds);
  for (vtkActor* tool : {actors_->proxyActor(), actors_->deviceActor()}) {
    if (tool == nullptr || tool->GetVisibility() == 0) continue;
    const double* b = tool->GetBounds();
    if (b == nullptr || !(b[0] <= b[1])) continue;
    for (int i = 0; i < 3; ++i) {
      bounds[2 * i] = std::min(bounds[2 * i], b[2 * i]);
      bounds[2 * i + 1] = std::max(bounds[2 * i + 1], b[2 * i + 1]);
    }
  }
  const double c[3] = {0.5 * (bounds[0] + bounds[1]), 0.5 * (bounds[2] + bounds[3]), 0.5 * (bounds[4] + bounds[5])};
  cam->SetFocalPoint(c);
  cam->SetPosition(c[0] + direction_W[0], c[1] + direction_W[1], c[2] + direction_W[2]);
  cam->SetViewUp(up_W[0], up_W[1], up_W[2]);
  cam->OrthogonalizeViewUp();
  const int* size = renderer->GetSize();
  const double aspect = size[0] > 0 && size[1] > 0 ? static_cast<double>(size[0]) / size[1] : 1.0;
  frameBounds(cam, bounds, aspect, kFrameFill);  // the whole volume, whatever its shape
  cam->Zoom(zoom);                               // > 1 magnifies beyond the framed volume
  renderer->ResetCameraClippingRange();
}

void SceneView::resetCamera() {
  if (actors_ == nullptr) return;
  // Default view: from the front (-y: anterior for LPS) turned 30 degrees to the patient's right
  // and 25 degrees up, +z up; the whole volume in view (a whole-body scan head to feet).
  vtkCamera* cam = view_->renderer()->GetActiveCamera();
  const double front[3] = {0.0, -1.0, 0.0};
  const double up[3] = {0.0, 0.0, 1.0};
  fitCamera(front, up, 1.0);
  cam->Azimuth(-30.0);
  cam->Elevation(25.0);
  cam->OrthogonalizeViewUp();
  const double direction[3] = {cam->GetPosition()[0] - cam->GetFocalPoint()[0], cam->GetPosition()[1] - cam->GetFocalPoint()[1],
                               cam->GetPosition()[2] - cam->GetFocalPoint()[2]};
  double view_up[3];
  cam->GetViewUp(view_up);
  fitCamera(direction, view_up, 1.0);
}

void SceneView::focusOn(const haptics::ToolModel& tool, const haptics::Pose& X_WP) {
  if (actors_ == nullptr) return;
  const Eigen::Vector3d c_W = X_WP * tool.mass.p_TCm_m;
  const Eigen::Vector3d extent = tool.mesh_T.empty() ? Eigen::Vector3d(0.05, 0.05, 0.05)
                                                     : Eigen::Vector3d(tool.mesh_T.boundsMax_T_m() - tool.mesh_T.boundsMin_T_m());
  vtkCamera* cam = view_->renderer()->GetActiveCamera();
  double dop[3];
  cam->GetDirectionOfProjection(dop);
  const double half_height_m = 0.75 * extent.norm();
  const double distance_m = half_height_m / std::tan(0.5 * cam->GetViewAngle() * std::numbers::pi / 180.0);
  cam->SetFocalPoint(c_W.x(), c_W.y(), c_W.z());
  cam->SetPosition(c_W.x() - distance_m * dop[0], c_W.y() - distance_m * dop[1], c_W.z() - distance_m * dop[2]);
  view_->renderer()->ResetCameraClippingRange();
  noteMotion();
  requestRender();
}

void SceneView::setStandardView(StandardView v) {
  // W = patient LPS: the camera sits on the named side of the patient.
  double dir[3] = {0, 0, 0};
  double up[3] = {0, 0, 1};
  switch (v) {
    case StandardView::kAnterior: dir[1] = -1; break;
    case StandardView::kPosterior: dir[1] = 1; break;
    case StandardView::kLeft: dir[0] = 1; break;
    case StandardView::kRight: dir[0] = -1; break;
    case StandardView::kSuperior:
      dir[2] = 1;
      up[2] = 0;
      up[1] = -1;  // anterior up
      break;
    case StandardView::kInferior:
      dir[2] = -1;
      up[2] = 0;
      up[1] = -1;
      break;
  }
  fitCamera(dir, up, 1.0);
  noteMotion();
  requestRender();
}

bool SceneView::frameSegment(int s) {
  double bounds[6];
  if (actors_ == nullptr || segments_ == nullptr || !segments_->bounds_W(s, bounds)) return false;
  vtkRenderer* renderer = view_->renderer();
  const int* size = renderer->GetSize();
  const double aspect = size[0] > 0 && size[1] > 0 ? static_cast<double>(size[0]) / size[1] : 1.0;
  frameBounds(renderer->GetActiveCamera(), bounds, aspect, 0.6);
  renderer->ResetCameraClippingRange();
  noteMotion();
  requestRender();
  return true;
}

ViewCamera SceneView::camera() const {
  const int* size = view_->renderer()->GetSize();
  return viewCameraOf(view_->renderer()->GetActiveCamera(), size[1] > 0 ? size[1] : view_->height(),
                      size[0] > 0 ? size[0] : view_->width());
}

void SceneView::setClipping(bool enabled, ClipAxis axis, double fraction, bool flip) {
  if (actors_ == nullptr) return;
  const int a = static_cast<int>(axis);
  double b[6];
  actors_->volumeBounds_W(b);
  const double f = std::clamp(fraction, 0.0, 1.0);
  Eigen::Vector3d origin(0.5 * (b[0] + b[1]), 0.5 * (b[2] + b[3]), 0.5 * (b[4] + b[5]));
  origin[a] = b[2 * a] + f * (b[2 * a + 1] - b[2 * a]);
  Eigen::Vector3d normal = Eigen::Vector3d::Zero();
  normal[a] = flip ? -1.0 : 1.0;
  actors_->setClipPlane(enabled, origin, normal);
  requestRender();
}

void SceneView::requestRender() { view_->requestRender(); }

void SceneView::noteMotion() {
  if (actors_ == nullptr) return;
  actors_->setInteractive(true);
  settle_timer_->start();  // restarts: the still frame comes kSettleMs after the last motion
}

void SceneView::setInteracting(bool interacting) {
  interacting_ = interacting;
  if (interacting) noteMotion();
  else settle_timer_->start();
}

void SceneView::setSharpMotion(bool on) {
  sharp_motion_ = on;
  if (actors_ != nullptr)
    actors_->setInteractiveImageSampleCap_px(on ? kReplayImageSample_px : std::numeric_limits<double>::infinity());
}

void SceneView::renderStill(bool best_quality) {
  settle_timer_->stop();
  if (actors_ == nullptr) return;
  if (actors_->interactive() || best_quality) {
    actors_->setInteractive(false);
    if (best_quality) actors_->resetQuality();
    requestRender();
  }
}

}  // namespace vh::ui
