#include "vh/ui/export/media_export.h"

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <iostream>
#include <limits>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>

#include <vtkActor.h>
#include <vtkCamera.h>
#include <vtkDataArray.h>
#include <vtkFloatArray.h>
#include <vtkGPUVolumeRayCastMapper.h>
#include <vtkPlaneCollection.h>
#include <vtkPointData.h>
#include <vtkPropCollection.h>
#include <vtkTexture.h>
#include <vtkUnsignedCharArray.h>
#include <vtkVolume.h>
#include <vtkImageData.h>
#include <vtkMapper.h>
#include <vtkRect.h>
#include <vtkNew.h>
#include <vtkOggTheoraWriter.h>
#include <vtkPNGWriter.h>
#include <vtkRenderWindow.h>
#include <vtkRenderer.h>
#include <vtkTextActor.h>
#include <vtkTextProperty.h>
#include <vtkWindowToImageFilter.h>

#include <nlohmann/json.hpp>

#include "vh/audio/ogg_vorbis_track.h"
#include "vh/audio/timed_sound.h"
#include "vh/io/private_files.h"
#include "vh/runtime/drilling.h"
#include "vh/runtime/session_metadata.h"
#include "vh/ui/drill_controller.h"
#include "vh/ui/view/scene_view.h"
#include "vh/ui/view/tool_shadow.h"

namespace vh::ui {
namespace {

namespace fs = std::filesystem;


int evenUp(int v) { return v + (v % 2); }

}  // namespace

std::size_t recordIndexAt(const std::vector<runtime::TickRecord>& records, double t_s) {
  if (records.empty()) throw std::invalid_argument("recordIndexAt: the recording has no records");
  const auto after = std::upper_bound(records.begin(), records.end(), t_s,
                                      [](double t, const runtime::TickRecord& r) { return t < r.time_s; });
  if (after == records.begin()) return 0;
  return static_cast<std::size_t>(after - records.begin()) - 1;
}

// ---- RecordingFrameRenderer ----------------------------------------------------------------------

RecordingFrameRenderer::RecordingFrameRenderer(const SceneActorsSpec& spec, int width, int height,
                                               const ViewLook& look)
    : tool_vertices_T_m_(spec.tool_mesh_T.vertices_T_m),
      isovalue_from_records_(spec.isovalue_from_records),
      width_(evenUp(width)),
      height_(evenUp(height)) {
  if (spec.image == nullptr) throw std::invalid_argument("RecordingFrameRenderer: the scene has no image");
  if (width < 16 || height < 16 || width > 8192 || height > 8192) {
    throw std::invalid_argument("RecordingFrameRenderer: frame size " + std::to_string(width) + " x " +
                                std::to_string(height) + " is outside 16 .. 8192 pixels");
  }
  window_ = vtkSmartPointer<vtkRenderWindow>::New();
  window_->SetOffScreenRendering(1);
  window_->SetMultiSamples(0);
  window_->SetSize(width_, height_);
  window_->SetWindowName("volume-haptics export");
  renderer_ = vtkSmartPointer<vtkRenderer>::New();
  window_->AddRenderer(renderer_);
  renderer_->GradientBackgroundOn();
  actors_ = std::make_unique<SceneActors>(renderer_, spec);
  applyColours(renderer_, actors_.get(), look);
  actors_->setRenderMode(look.mode, look.preset);
  actors_->setShadowVisible(look.tool_shadow);
  actors_->setInteractive(false);
  actors_->resetQuality();
  grabber_ = vtkSmartPointer<vtkWindowToImageFilter>::New();
  grabber_->SetInput(window_);
  grabber_->SetInputBufferTypeToRGB();
  grabber_->ReadFrontBufferOff();
  grabber_->ShouldRerenderOff();  // render() renders first
  // The second pass of a frame over the kept volume picture: the composite as the background
  // texture, the overlay's text over it (setOverlay()), then the overlay layer (contacts, force).
  backdrop_ = vtkSmartPointer<vtkRenderer>::New();
  backdrop_->SetLayer(0);
  backdrop_->InteractiveOff();
  backdrop_->SetDraw(false);
  composite_ = vtkSmartPointer<vtkImageData>::New();
  composite_->SetDimensions(width_, height_, 1);
  composite_->AllocateScalars(VTK_UNSIGNED_CHAR, 3);
  vtkNew<vtkTexture> texture;
  texture->SetInputData(composite_);
  texture->InterpolateOff();
  texture->RepeatOff();
  backdrop_->SetBackgroundTexture(texture);
  backdrop_->TexturedBackgroundOn();
  window_->AddRenderer(backdrop_);
  resetCamera();
}

RecordingFrameRenderer::~RecordingFrameRenderer() {
  grabber_ = nullptr;
  if (window_ != nullptr) window_->MakeCurrent();
  segments_.reset();  // props leave the renderer while its window (and context) still exists
  ghost_.reset();
  actors_.reset();
  if (window_ != nullptr) window_->Finalize();
}

void RecordingFrameRenderer::resetCamera() {
  vtkCamera* cam = renderer_->GetActiveCamera();
  double bounds[6];
  actors_->volumeBounds_W(bounds);
  const double c[3] = {0.5 * (bounds[0] + bounds[1]), 0.5 * (bounds[2] + bounds[3]), 0.5 * (bounds[4] + bounds[5])};
  cam->SetFocalPoint(c);
  cam->SetPosition(c[0], c[1] - 1.0, c[2]);  // from anterior (-y in LPS)
  cam->SetViewUp(0.0, 0.0, 1.0);
  renderer_->ResetCamera();
  cam->Azimuth(-30.0);
  cam->Elevation(25.0);
  cam->OrthogonalizeViewUp();
  renderer_->ResetCamera();
  cam->Zoom(1.2);
  renderer_->ResetCameraClippingRange();
  ++camera_generation_;
}

void RecordingFrameRenderer::copyCamera(vtkCamera* camera) {
  if (camera == nullptr) return;
  renderer_->GetActiveCamera()->DeepCopy(camera);
  renderer_->ResetCameraClippingRange();
  ++camera_generation_;
}

void RecordingFrameRenderer::setRecordedCameras(std::vector<RecordedCamera> cameras) {
  recorded_cameras_ = std::move(cameras);
  recorded_camera_shown_ = 0;
}

ViewCamera RecordingFrameRenderer::camera() const { return viewCameraOf(renderer_->GetActiveCamera(), height_, width_); }

void RecordingFrameRenderer::show(const runtime::TickRecord& record) {
  // The user's camera at this time (the latest recorded at or before it).
  std::size_t latest = 0;  // 1 + index
  for (std::size_t c = 0; c < recorded_cameras_.size() && recorded_cameras_[c].time_s <= record.time_s + 1e-12; ++c)
    latest = c + 1;
  if (latest != 0 && latest != recorded_camera_shown_) {
    const ViewCamera& v = recorded_cameras_[latest - 1].camera;
    vtkCamera* cam = renderer_->GetActiveCamera();
    cam->SetPosition(v.position_W_m.data());
    cam->SetFocalPoint(v.focal_point_W_m.data());
    cam->SetViewUp(v.view_up_W.data());
    cam->SetViewAngle(v.view_angle_deg);
    cam->SetParallelProjection(v.parallel ? 1 : 0);
    cam->SetParallelScale(v.parallel_scale_m);
    cam->OrthogonalizeViewUp();
    renderer_->ResetCameraClippingRange();
    recorded_camera_shown_ = latest;
    ++camera_generation_;
  }
  ToolFrame frame = toolFrameOf(record);
  if (!isovalue_from_records_) frame.isovalue = std::numeric_limits<double>::quiet_NaN();  // felt segments' level
  showToolFrame(*actors_, frame, tool_vertices_T_m_);
  if (shadow_field_ != nullptr) {
    const Eigen::Vector3d light_W = shadowLightDirection_W(viewCameraOf(renderer_->GetActiveCamera(), height_));
    const double isovalue = std::isfinite(record.isovalue) ? record.isovalue : shadow_isovalue_;
    actors_->setShadow(castToolShadow(*shadow_field_, shadow_carved_, isovalue, frame.X_WP, shadow_samples_T_m_, light_W),
                       light_W);
  }
  if (segments_ != nullptr) segments_->setTouched(runtime::recordSegment(record.flags));
  if (ghost_ != nullptr) {  // the nearest point of the expert's path only while guidance was on
    std::optional<haptics::Pose> X_WE;
    if (guide_.onAt(record.time_s))
      X_WE = guide_.ghostPose(Eigen::Vector3d(record.p_WD_m[0], record.p_WD_m[1], record.p_WD_m[2]));
    if (X_WE && X_WE->allFinite()) ghost_->show(*X_WE);
    else ghost_->hide();
  }
  if (overlay_ != nullptr) showOverlay(record);
}

void RecordingFrameRenderer::setGuide(ReplayGuide guide) {
  guide_ = std::move(guide);
  ghost_.reset();
  if (guide_.expert() == nullptr) return;
  ghost_ = std::make_unique<ExpertGhost>(actors_->overlayRenderer(),
                                         actors_->proxyActor()->GetMapper()->GetInputConnection(0, 0));
  ghost_->setPath(&guide_.expert()->path());
}

void RecordingFrameRenderer::setSegments(std::shared_ptr<const runtime::SegmentSet> set, const Rgb& surface_rgb) {
  segment_set_ = std::move(set);
  if (segment_set_ == nullptr) {
    segments_.reset();
    return;
  }
  if (segments_ == nullptr) segments_ = std::make_unique<SegmentSurfaces>(renderer_);
  segments_->show(segment_set_.get(), surface_rgb);
}

void RecordingFrameRenderer::setShadow(std::shared_ptr<const haptics::ScalarVolume> field, double isovalue,
                                       std::vector<Eigen::Vector3d> samples_T_m) {
  shadow_field_ = std::move(field);
  shadow_carved_.clear();  // carved again by the next showCavityAt()
  shadow_isovalue_ = isovalue;
  shadow_samples_T_m_ = std::move(samples_T_m);
  if (shadow_field_ == nullptr) actors_->setShadow(ToolShadow{}, Eigen::Vector3d::UnitZ());
}

void RecordingFrameRenderer::setOverlay(const runtime::Recording* recording) {
  overlay_ = recording;
  if (overlay_text_ == nullptr) {
    const double font = std::max(10.0, height_ / 32.0);  // about 22 px at 720 lines
    overlay_text_ = vtkSmartPointer<vtkTextActor>::New();
    overlay_text_->GetTextProperty()->SetFontSize(static_cast<int>(font));
    overlay_text_->GetTextProperty()->SetColor(1.0, 1.0, 1.0);
    overlay_text_->GetTextProperty()->SetBackgroundColor(0.0, 0.0, 0.0);
    overlay_text_->GetTextProperty()->SetBackgroundOpacity(0.5);
    overlay_text_->GetTextProperty()->SetVerticalJustificationToTop();
    overlay_text_->GetPositionCoordinate()->SetCoordinateSystemToNormalizedViewport();
    overlay_text_->GetPositionCoordinate()->SetValue(0.01, 0.985);
    backdrop_->AddActor2D(overlay_text_);
    overlay_alert_ = vtkSmartPointer<vtkTextActor>::New();
    overlay_alert_->GetTextProperty()->SetFontSize(static_cast<int>(1.2 * font));
    overlay_alert_->GetTextProperty()->SetBold(true);
    overlay_alert_->GetTextProperty()->SetColor(1.0, 1.0, 1.0);
    overlay_alert_->GetTextProperty()->SetBackgroundColor(0.75, 0.1, 0.1);
    overlay_alert_->GetTextProperty()->SetBackgroundOpacity(0.9);
    overlay_alert_->GetTextProperty()->SetJustificationToCentered();
    overlay_alert_->GetTextProperty()->SetVerticalJustificationToBottom();
    overlay_alert_->GetPositionCoordinate()->SetCoordinateSystemToNormalizedViewport();
    overlay_alert_->GetPositionCoordinate()->SetValue(0.5, 0.03);
    backdrop_->AddActor2D(overlay_alert_);
  }
  overlay_text_->SetVisibility(false);
  overlay_alert_->SetVisibility(false);
}

void RecordingFrameRenderer::showOverlay(const runtime::TickRecord& record) {
  const double t = record.time_s;
  const double f = std::sqrt(record.force_W_N[0] * record.force_W_N[0] + record.force_W_N[1] * record.force_W_N[1] +
                             record.force_W_N[2] * record.force_W_N[2]);
  const double tau = std::sqrt(record.torque_W_Nm[0] * record.torque_W_Nm[0] +
                               record.torque_W_Nm[1] * record.torque_W_Nm[1] +
                               record.torque_W_Nm[2] * record.torque_W_Nm[2]);
  char line[160];
  std::snprintf(line, sizeof line, "t = %.2f s   |F| = %.2f N   |torque| = %.3f N*m", t, f, tau);
  std::string text = line, alert;
  // The events of the last kOverlayHold_s, the newest last.
  for (const runtime::RecordingEvent& e : overlay_->events) {
    if (e.time_s > t || e.time_s < t - kOverlayHold_s) continue;
    const nlohmann::json detail = nlohmann::json::parse(e.detail_json, nullptr, /*allow_exceptions=*/false);
    const auto field = [&](const char* key) {
      return detail.is_object() && detail.contains(key) && detail[key].is_string() ? detail[key].get<std::string>() : std::string();
    };
    if (e.type == "marker") text = std::string(line) + "\nmarker: " + field("label");
    if (e.type == "critical_removed") alert = "CRITICAL: " + field("segment") + " drilled";
  }
  overlay_text_->SetInput(text.c_str());
  overlay_text_->SetVisibility(true);
  overlay_alert_->SetInput(alert.c_str());
  overlay_alert_->SetVisibility(!alert.empty());
}

std::string RecordingFrameRenderer::overlayText() const {
  return overlay_text_ != nullptr && overlay_text_->GetVisibility() && overlay_text_->GetInput() != nullptr
             ? overlay_text_->GetInput()
             : "";
}

std::string RecordingFrameRenderer::overlayAlert() const {
  return overlay_alert_ != nullptr && overlay_alert_->GetVisibility() && overlay_alert_->GetInput() != nullptr
             ? overlay_alert_->GetInput()
             : "";
}

void RecordingFrameRenderer::setDrilling(DrillingTimeline timeline) {
  drilling_ = std::move(timeline);
  actors_->restoreVolume();
  cavity_shown_ = 0;
  shadow_carved_.clear();
}

void RecordingFrameRenderer::showCavityAt(std::size_t record_index) {
  showDrilledVoxels(*actors_, drilling_.picture, drilling_.picture.removedAt(record_index), cavity_shown_);
  if (shadow_field_ != nullptr) carveToRecord(shadow_carved_, shadow_field_, drilling_.felt, record_index);
}

void carveToRecord(CarvedRegion& carved, const std::shared_ptr<const haptics::ScalarVolume>& field,
                   const CavityOrder& felt, std::size_t record_index) {
  const std::uint64_t target = felt.removedAt(record_index);
  if (target < carved.removedCount() || carved.field() != field) {
    carved.reset(field, std::span<const std::uint64_t>(felt.voxels.data(), target));
  } else if (target > carved.removedCount()) {
    carved.remove(std::span<const std::uint64_t>(felt.voxels.data() + carved.removedCount(),
                                                 target - carved.removedCount()));
  }
}

void showDrilledVoxels(SceneActors& actors, const CavityOrder& picture, std::uint64_t target,
                       std::uint64_t& shown) {
  target = std::min<std::uint64_t>(target, picture.voxels.size());
  if (target == shown) return;
  if (target < shown) {  // an earlier record: from the undrilled picture again
    actors.restoreVolume();
    shown = 0;
  }
  actors.removeVoxels(std::span<const std::uint64_t>(picture.voxels.data() + shown,
                                                     static_cast<std::size_t>(target - shown)),
                      actors.removedValue());
  shown = target;
}

vtkImageData* RecordingFrameRenderer::render() {
  draw();
  return readBack();
}

void RecordingFrameRenderer::draw(bool wait) {
  if (reuse_volume_ && actors_->renderMode() == RenderMode::kIsosurface && actors_->volume()->GetVisibility() != 0)
    drawOverKeptVolume();
  else
    drawFull();
  if (wait) window_->WaitForCompletion();
}

void RecordingFrameRenderer::setReuseVolume(bool reuse) {
  reuse_volume_ = reuse;
  kept_.valid = false;
  last_frame_.valid = false;
  changed_last_frame_ = false;
}

namespace {

/// Distance along the view axis [world units] of a window depth in [0, 1] (glDepthRange 0..1)
/// under a camera with clipping range [near, far]; +inf for the far plane (nothing drawn).
float eyeDepth(float window_depth, double near, double far, bool parallel) {
  if (!(window_depth < 1.0f)) return std::numeric_limits<float>::infinity();
  if (parallel) return static_cast<float>(near + window_depth * (far - near));
  const double ndc = 2.0 * window_depth - 1.0;
  return static_cast<float>(2.0 * near * far / ((far + near) - ndc * (far - near)));
}

}  // namespace

void RecordingFrameRenderer::drawFull() {
  backdrop_->SetDraw(false);
  renderer_->SetDraw(true);
  actors_->overlayRenderer()->SetDraw(true);
  if (overlay_text_ != nullptr) {  // the text is drawn by backdrop_, which a full render leaves out
    backdrop_->RemoveActor2D(overlay_text_);
    backdrop_->RemoveActor2D(overlay_alert_);
    renderer_->AddActor2D(overlay_text_);
    renderer_->AddActor2D(overlay_alert_);
  }
  renderer_->ResetCameraClippingRange();
  window_->Render();
  ++volume_renders_;
  volume_pixels_cast_ += static_cast<std::uint64_t>(width_) * static_cast<std::uint64_t>(height_);
  if (overlay_text_ != nullptr) {
    renderer_->RemoveActor2D(overlay_text_);
    renderer_->RemoveActor2D(overlay_alert_);
    backdrop_->AddActor2D(overlay_text_);
    backdrop_->AddActor2D(overlay_alert_);
  }
}

void RecordingFrameRenderer::keepVolume(const std::optional<PixelRect>& rect) {
  // The volume alone: every other prop of the scene's renderer hidden, the overlay layer and
  // the backdrop off; the clipping range a full render has. With `rect`, the camera's scissor
  // keeps the ray caster to those pixels (glScissor: no fragment outside it is shaded), only
  // they are copied into the kept picture, and their depth is cast here (surfaceEyeDepthIn()):
  // the ray caster's depth image (render to image) ignores the scissor and costs a whole frame.
  const PixelRect r = rect.value_or(PixelRect{0, 0, width_, height_});
  vtkCamera* camera = renderer_->GetActiveCamera();
  renderer_->ResetCameraClippingRange();
  vtkPropCollection* props = renderer_->GetViewProps();
  std::vector<std::pair<vtkProp*, int>> shown;
  props->InitTraversal();
  for (vtkProp* prop = props->GetNextProp(); prop != nullptr; prop = props->GetNextProp()) {
    if (prop == actors_->volume() || prop->GetVisibility() == 0) continue;
    shown.emplace_back(prop, prop->GetVisibility());
    prop->SetVisibility(false);
  }
  backdrop_->SetDraw(false);
  renderer_->SetDraw(true);
  actors_->overlayRenderer()->SetDraw(false);
  if (rect) {  // vtkOpenGLCamera clears UseScissor after each render
    camera->SetScissorRect(vtkRecti(r.x, r.y, r.width, r.height));
    camera->SetUseScissor(true);
  }
  window_->Render();
  const std::size_t pixels = static_cast<std::size_t>(width_) * height_;
  if (kept_rgb_.size() != pixels * 3) std::vector<unsigned char>(pixels * 3).swap(kept_rgb_);
  vtkNew<vtkUnsignedCharArray> rgb;
  window_->GetPixelData(r.x, r.y, r.x + r.width - 1, r.y + r.height - 1, /*front=*/0, rgb, /*right=*/0);
  for (int y = 0; y < r.height; ++y)
    std::copy_n(rgb->GetPointer(3 * static_cast<vtkIdType>(y) * r.width), 3 * r.width,
                kept_rgb_.begin() + 3 * (static_cast<std::ptrdiff_t>(r.y + y) * width_ + r.x));
  ++volume_renders_;
  volume_pixels_cast_ += static_cast<std::uint64_t>(r.width) * static_cast<std::uint64_t>(r.height);
  kept_eye_depth_.resize(pixels);
  if (rect) {
    for (auto& [prop, visibility] : shown) prop->SetVisibility(visibility);
    surfaceEyeDepthIn(r);
    return;
  }
  // Its depth: the ray caster's own, where it first met the surface (1 where it met nothing).
  vtkGPUVolumeRayCastMapper* mapper = actors_->volumeMapper();
  mapper->SetRenderToImage(true);
  mapper->SetDepthImageScalarTypeToFloat();
  window_->Render();
  vtkNew<vtkImageData> depth;
  mapper->GetDepthImage(depth);
  mapper->SetRenderToImage(false);
  ++volume_renders_;
  volume_pixels_cast_ += pixels;
  for (auto& [prop, visibility] : shown) prop->SetVisibility(visibility);
  int dims[3] = {0, 0, 0};
  depth->GetDimensions(dims);
  vtkDataArray* z = depth->GetPointData() != nullptr ? depth->GetPointData()->GetScalars() : nullptr;
  if (z == nullptr || dims[0] != width_ || dims[1] != height_)
    throw std::runtime_error("the volume's depth image could not be read back (" + std::to_string(dims[0]) + " x " +
                             std::to_string(dims[1]) + ")");
  double range[2];
  camera->GetClippingRange(range);
  const bool parallel = camera->GetParallelProjection() != 0;
  for (std::size_t i = 0; i < pixels; ++i)
    kept_eye_depth_[i] = eyeDepth(static_cast<float>(z->GetComponent(static_cast<vtkIdType>(i), 0)), range[0], range[1], parallel);
}

void RecordingFrameRenderer::drawOverKeptVolume() {
  const KeptKey now{actors_->isovalue(), cavity_shown_, camera_generation_, true};
  const auto same = [](const KeptKey& a, const KeptKey& b) {
    return a.valid && b.valid && a.isovalue == b.isovalue && a.cavity == b.cavity && a.camera == b.camera;
  };
  const bool changed_since_last_frame = !same(now, last_frame_);
  last_frame_ = now;
  if (!same(now, kept_)) {
    // Only the cavity grew (the burr drilling, the camera and the isovalue as they were): the
    // volume is cast again where the removed voxels lie on the screen, not over the frame.
    // (Not under a clipping plane, which the depth cast here does not know.)
    vtkPlaneCollection* planes = actors_->volumeMapper()->GetClippingPlanes();
    const bool cavity_grew = kept_.valid && now.isovalue == kept_.isovalue && now.camera == kept_.camera &&
                             now.cavity > kept_.cavity && (planes == nullptr || planes->GetNumberOfItems() == 0);
    const std::optional<PixelRect> rect = cavity_grew ? cavityRect(kept_.cavity, now.cavity) : std::nullopt;
    if (rect) {
      if (rect->width > 0 && rect->height > 0) keepVolume(rect);
    } else if (changed_since_last_frame && changed_last_frame_) {
      // Changing at every frame otherwise (the isovalue swept): one full render a frame costs
      // less than keeping a picture (colour and depth) that the next frame throws away.
      drawFull();
      return;
    } else {
      keepVolume();
    }
    kept_ = now;
  }
  changed_last_frame_ = changed_since_last_frame;
  // First pass: the scene's props without the volume, with their depth; the clipping range a
  // full render has (the volume counted), which the overlay layer shares in the second pass.
  renderer_->ResetCameraClippingRange();
  actors_->volume()->SetVisibility(false);
  backdrop_->SetDraw(false);
  renderer_->SetDraw(true);
  actors_->overlayRenderer()->SetDraw(false);
  window_->Render();
  actors_->volume()->SetVisibility(true);
  vtkNew<vtkUnsignedCharArray> rgb;
  window_->GetPixelData(0, 0, width_ - 1, height_ - 1, /*front=*/0, rgb, /*right=*/0);
  vtkNew<vtkFloatArray> z;
  window_->GetZbufferData(0, 0, width_ - 1, height_ - 1, z);
  double range[2];
  renderer_->GetActiveCamera()->GetClippingRange(range);
  const bool parallel = renderer_->GetActiveCamera()->GetParallelProjection() != 0;
  // The composite: a prop's pixel where it is nearer than the surface, else the kept picture.
  auto* out = static_cast<unsigned char*>(composite_->GetScalarPointer());
  const unsigned char* props_rgb = rgb->GetPointer(0);
  const float* props_z = z->GetPointer(0);
  const std::size_t n = kept_eye_depth_.size();
  for (std::size_t i = 0; i < n; ++i) {
    const bool prop_in_front = props_z[i] < 1.0f && eyeDepth(props_z[i], range[0], range[1], parallel) < kept_eye_depth_[i];
    const unsigned char* from = prop_in_front ? props_rgb + 3 * i : kept_rgb_.data() + 3 * i;
    out[3 * i] = from[0], out[3 * i + 1] = from[1], out[3 * i + 2] = from[2];
  }
  composite_->Modified();
  // Second pass: the composite as the background, the text and the overlay layer over it.
  renderer_->SetDraw(false);
  backdrop_->SetDraw(true);
  actors_->overlayRenderer()->SetDraw(true);
  window_->Render();
  renderer_->SetDraw(true);
  backdrop_->SetDraw(false);
}

vtkImageData* RecordingFrameRenderer::readBack() {
  grabber_->Modified();
  grabber_->Update();
  return grabber_->GetOutput();
}

vtkWindowToImageFilter* RecordingFrameRenderer::imageFilter() const noexcept { return grabber_; }
vtkRenderer* RecordingFrameRenderer::renderer() const noexcept { return renderer_; }
double RecordingFrameRenderer::isovalue() const { return actors_->isovalue(); }
vtkRenderWindow* RecordingFrameRenderer::renderWindow() const noexcept { return window_; }

DrillingTimeline drillingAtStart(const runtime::LoadedScene& scene) {
  DrillingTimeline timeline;
  if (!scene.spec.drill || scene.spec.drill->cavity == nullptr) return timeline;
  const runtime::LiveValues live = runtime::LiveValues::initial(scene);
  if (live.scan_field == nullptr) return timeline;
  timeline.picture.voxels = runtime::cavityVoxelsOn(*scene.spec.drill->cavity, live.scan_field->geometry());
  timeline.picture.at_start = timeline.picture.voxels.size();
  if (live.hapticField() != nullptr) {
    timeline.felt.voxels = runtime::cavityVoxelsOn(*scene.spec.drill->cavity, live.hapticField()->geometry());
    timeline.felt.at_start = timeline.felt.voxels.size();
  }
  return timeline;
}

DrillingTimeline drillingTimeline(const runtime::LoadedScene& scene, const runtime::Recording& recording,
                                  const runtime::ReplayProgress& progress) {
  DrillingTimeline timeline = drillingAtStart(scene);
  addReplayedRemovals(timeline, scene, recording, progress);
  return timeline;
}

void addReplayedRemovals(DrillingTimeline& timeline, const runtime::LoadedScene& scene,
                         const runtime::Recording& recording, const runtime::ReplayProgress& progress) {
  if (!scene.spec.drill) return;
  const runtime::LiveValues live = runtime::LiveValues::initial(scene);
  if (live.scan_field == nullptr) return;
  const bool drilled = std::any_of(recording.records.begin(), recording.records.end(), [](const runtime::TickRecord& r) {
    return (r.flags & runtime::kRecordFlagDrillOn) != 0;
  });
  if (!drilled) return;
  // The same renderer and drill as the session's, fed the recorded samples, remove the same
  // voxels (the replay is bit for bit) and hear the same burr.
  runtime::RecordingSound sound;
  sound.burr = runtime::burrSoundModelOf(scene);
  sound.tick_period_s = runtime::recordedServoPeriod_s(recording);
  runtime::ReplayProgress hearing = progress;
  hearing.on_drill_tick = [&](const runtime::DrillTick& d) { sound.add(d, recording); };
  const runtime::ReplayComparison replay = runtime::replayRecording(scene, recording, {}, hearing);
  if (replay.cancelled) {
    timeline.cancelled = true;
    return;
  }
  sound.completeFrom(recording);
  timeline.sound = std::move(sound);
  timeline.replay_difference = runtime::replayDifference(replay, recording);
  const std::vector<std::uint64_t> removed = pictureIndices(*live.hapticField(), *live.scan_field, replay.removed_voxels);
  timeline.picture.voxels.insert(timeline.picture.voxels.end(), removed.begin(), removed.end());
  // Felt indices map one to one onto picture indices (or are dropped outside the scan); the
  // counts per record are kept as they are, clipped to what was mapped.
  timeline.picture.after_record = replay.removed_after_record;
  for (auto& n : timeline.picture.after_record) n = timeline.picture.at_start + std::min<std::uint64_t>(n, removed.size());
  timeline.felt.voxels.insert(timeline.felt.voxels.end(), replay.removed_voxels.begin(), replay.removed_voxels.end());
  timeline.felt.after_record = replay.removed_after_record;
  for (auto& n : timeline.felt.after_record) n += timeline.felt.at_start;
}

// ---- Writers -------------------------------------------------------------------------------------

namespace {

/// Writes to `out` the Theora video `theora` with `sound` as its Vorbis track: from the first
/// frame's time `begin_s` [s] (the sound before it rendered and dropped, so that the burr's speed
/// there is the session's), as long as the `frames` frames at `fps`.
void addSoundTrack(const fs::path& theora, std::ostream& out, const runtime::RecordingSound& sound, double begin_s,
                   int frames, double fps) {
  audio::TimedSound renderer = sound.renderer();
  renderer.skipTo(renderer.frameAt(begin_s));
  const double rate_Hz = renderer.sampleRate_Hz();
  const auto samples = static_cast<std::uint64_t>(std::llround(static_cast<double>(frames) / fps * rate_Hz));
  audio::addVorbisTrack(theora, out, samples, rate_Hz, [&renderer](std::span<float> x) { renderer.render(x); });
}

}  // namespace

int writeRecordingVideo(RecordingFrameRenderer& frames, const runtime::Recording& recording, const fs::path& path,
                        double fps, double start_s, double end_s, const FrameProgress& progress,
                        std::vector<VideoFrameTimes>* times, const runtime::RecordingSound* sound) {
  if (recording.records.empty()) throw std::invalid_argument(path.string() + ": the recording has no records");
  if (!(fps >= 1.0 && fps <= 120.0)) {
    throw std::invalid_argument(path.string() + ": frame rate " + std::to_string(fps) + " is outside 1 .. 120 fps");
  }
  const double last_s = recording.records.back().time_s;
  const double first_s = recording.records.front().time_s;
  const double begin = std::max(first_s, start_s);
  const double end = end_s < 0.0 ? last_s : std::min(end_s, last_s);
  if (!(end >= begin)) {
    throw std::invalid_argument(path.string() + ": empty time range " + std::to_string(begin) + " .. " +
                                std::to_string(end) + " s");
  }
  const int total = static_cast<int>(std::floor((end - begin) * fps + 1e-9)) + 1;
  io::PrivateOutput file(path);  // 0600, renamed into place only when written
  // With sound, the Theora stream goes to a temporary of its own (removed at the end), which the
  // sound track's muxer reads.
  const bool with_sound = sound != nullptr && !sound->states.empty();
  std::optional<io::PrivateOutput> theora;
  if (with_sound) theora.emplace(path);
  const fs::path video_path = with_sound ? theora->tempPath() : file.tempPath();
  vtkNew<vtkOggTheoraWriter> writer;
  writer->SetInputConnection(frames.imageFilter()->GetOutputPort());
  writer->SetFileName(video_path.string().c_str());
  writer->SetRate(std::max(1, static_cast<int>(std::lround(fps))));
  writer->SetQuality(2);
  // 4:2:0 chroma, as players expect and twice as fast to encode as 4:4:4 (which took half of
  // each frame's time at 640 x 480 on a 2-core machine).
  writer->SetSubsampling(1);
  const auto showAt = [&](double t) {
    const std::size_t i = recordIndexAt(recording.records, t);
    frames.showCavityAt(i);  // the cavity first: the shadow falls into it
    frames.show(recording.records[i]);
  };
  showAt(begin);
  frames.render();
  writer->Start();
  int done = 0;
  using Clock = std::chrono::steady_clock;
  const auto ms = [](Clock::time_point a, Clock::time_point b) { return std::chrono::duration<double, std::milli>(b - a).count(); };
  for (int k = 0; k < total; ++k) {
    const Clock::time_point t0 = Clock::now();
    showAt(begin + static_cast<double>(k) / fps);
    const Clock::time_point t1 = Clock::now();
    frames.draw(/*wait=*/times != nullptr);
    const Clock::time_point t2 = Clock::now();
    frames.readBack();
    const Clock::time_point t3 = Clock::now();
    writer->Write();
    if (times != nullptr) times->push_back({ms(t0, t1), ms(t1, t2), ms(t2, t3), ms(t3, Clock::now())});
    if (writer->GetError() != 0) break;
    ++done;
    if (progress && !progress(done, total)) break;
  }
  writer->End();
  if (writer->GetError() != 0) throw std::runtime_error(path.string() + ": the video could not be written");
  std::error_code ec;
  if (!fs::exists(video_path, ec) || fs::file_size(video_path, ec) == 0) {
    throw std::runtime_error(path.string() + ": the video could not be written");
  }
  if (with_sound && done > 0) {
    try {
      addSoundTrack(video_path, file.stream(), *sound, begin, done, fps);
    } catch (const std::exception& e) {
      throw std::runtime_error(path.string() + ": the sound track could not be added: " + e.what());
    }
  }
  file.commit();
  return done;
}

const runtime::RecordingSound* videoSoundOf(const RecordingFrameRenderer& frames) noexcept {
  return frames.drilling().sound.states.empty() ? nullptr : &frames.drilling().sound;
}

void writeRecordingPng(RecordingFrameRenderer& frames, const runtime::Recording& recording, double t_s,
                       const fs::path& path) {
  if (recording.records.empty()) throw std::invalid_argument(path.string() + ": the recording has no records");
  const std::size_t i = recordIndexAt(recording.records, t_s);
  frames.showCavityAt(i);  // the cavity first: the shadow falls into it
  frames.show(recording.records[i]);
  frames.render();
  io::PrivateOutput file(path);
  vtkNew<vtkPNGWriter> writer;
  writer->SetInputConnection(frames.imageFilter()->GetOutputPort());
  writer->SetFileName(file.tempPath().string().c_str());
  writer->Write();
  std::error_code ec;
  if (writer->GetErrorCode() != 0 || !fs::exists(file.tempPath(), ec) || fs::file_size(file.tempPath(), ec) == 0) {
    throw std::runtime_error(path.string() + ": the PNG could not be written");
  }
  file.commit();
}

namespace {

std::atomic<bool> interrupted{false};  // Ctrl+C during `export --video`
extern "C" void onInterrupt(int /*signal*/) { interrupted.store(true); }

/// `export --video` on the console: a line with the frames done of the total and the time left,
/// at most twice a second; Ctrl+C (SIGINT) ends the video after the frame being written, a
/// valid shorter file. The previous SIGINT handler is back when this goes.
class ConsoleVideoProgress {
 public:
  ConsoleVideoProgress() {
    interrupted.store(false);
    struct sigaction action{};
    action.sa_handler = onInterrupt;
    sigemptyset(&action.sa_mask);
    sigaction(SIGINT, &action, &previous_);
  }
  ~ConsoleVideoProgress() { sigaction(SIGINT, &previous_, nullptr); }
  ConsoleVideoProgress(const ConsoleVideoProgress&) = delete;
  ConsoleVideoProgress& operator=(const ConsoleVideoProgress&) = delete;

  /// FrameProgress: prints, and returns false once Ctrl+C was pressed.
  bool operator()(int done, int total) {
    const double elapsed_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0_).count();
    if (done == total || elapsed_s - printed_s_ >= 0.5) {
      printed_s_ = elapsed_s;
      const double left_s = done > 0 ? elapsed_s * (total - done) / done : 0.0;
      std::fprintf(stderr, "volume-haptics export: frame %d of %d, %.0f s left\n", done, total, left_s);
    }
    return !interrupted.load();
  }
  bool wasInterrupted() const { return interrupted.load(); }

 private:
  struct sigaction previous_{};
  std::chrono::steady_clock::time_point t0_ = std::chrono::steady_clock::now();
  double printed_s_ = -1.0;
};

}  // namespace

std::unique_ptr<RecordingFrameRenderer> exportFrameRenderer(const runtime::LoadedScene& scene,
                                                            const runtime::Recording& recording,
                                                            const MediaExportOptions& options, std::ostream* log,
                                                            const fs::path& recording_file) {
  ViewLook look;
  look.mode = options.mode;
  look.preset = options.preset;
  auto frames = std::make_unique<RecordingFrameRenderer>(sceneActorsSpecFor(scene, runtime::LiveValues::initial(scene)),
                                                         options.width, options.height, look);
  if (options.overlay) frames->setOverlay(&recording);
  if (options.shadow && scene.tool != nullptr) {
    frames->setShadow(scene.hapticField(), scene.hapticIsovalue(), toolShadowSamples(*scene.tool));
  }
  if (scene.segments != nullptr)
    frames->setSegments(scene.segments, {look.surface.redF(), look.surface.greenF(), look.surface.blueF()});
  if (scene.spec.drill) {
    // The cavity grows in the frames as it did in the session: the recording is replayed
    // first (a few seconds on a big CT).
    if (log != nullptr) *log << "volume-haptics export: replaying the drilling for the cavity...\n";
    DrillingTimeline timeline = drillingTimeline(scene, recording);
    if (log != nullptr)
      *log << "volume-haptics export: the cavity grows to " << timeline.picture.removedAt(recording.records.size())
           << " voxels\n";
    if (log != nullptr && !timeline.replay_difference.empty())
      *log << "volume-haptics export: warning: " << timeline.replay_difference
           << "; the cavity is shown as it was there and the burr's sound runs free (no load) after it\n";
    frames->setDrilling(std::move(timeline));
  }
  // The expert's ghost where the session was guided, as its replay shows it.
  ReplayGuide guide(recording, recording_file);
  if (log != nullptr && !guide.notice().empty()) *log << "volume-haptics export: " << guide.notice() << "\n";
  if (log != nullptr && guide.expert() != nullptr)
    *log << "volume-haptics export: the expert's ghost of " << guide.expert()->fileName() << "\n";
  frames->setGuide(std::move(guide));
  if (!recording.records.empty()) frames->show(recording.records.front());
  frames->resetCamera();  // fitted to the volume and the tools where they start
  // Seen as the user saw it where the recording holds the window's camera.
  std::vector<RecordedCamera> cameras = recordedCameras(recording);
  if (log != nullptr && !cameras.empty())
    *log << "volume-haptics export: the view's camera as recorded (" << cameras.size() << " camera events)\n";
  frames->setRecordedCameras(std::move(cameras));
  return frames;
}

int exportRecordingMedia(int /*argc*/, char** /*argv*/, const fs::path& recording_path,
                         const MediaExportOptions& options) {
  try {
    if (options.video.empty() && options.png.empty()) return 0;
    const runtime::Recording recording = runtime::readRecording(recording_path);
    for (const std::string& w : recording.warnings) {
      std::cerr << "volume-haptics export: warning: " << recording_path.string() << ": " << w << '\n';
    }
    if (recording.records.empty()) {
      throw std::runtime_error(recording_path.string() + ": the recording has no records to render");
    }
    runtime::SceneSpec spec = runtime::sceneFromSessionMetadata(recording.metadata_json);
    spec.device.reset();
    const runtime::LoadedScene scene = runtime::loadScene(spec);
    const std::unique_ptr<RecordingFrameRenderer> renderer =
        exportFrameRenderer(scene, recording, options, &std::cerr, recording_path);
    RecordingFrameRenderer& frames = *renderer;
    if (!options.png.empty()) {
      writeRecordingPng(frames, recording, options.png_time_s, options.png);
      std::cout << "volume-haptics export: " << options.png.string() << " (" << frames.width() << " x "
                << frames.height() << ", t = " << options.png_time_s << " s)\n";
    }
    if (!options.video.empty()) {
      ConsoleVideoProgress progress;
      const runtime::RecordingSound* sound = options.sound ? videoSoundOf(frames) : nullptr;
      const int n = writeRecordingVideo(frames, recording, options.video, options.fps, options.start_s, options.end_s,
                                        [&progress](int done, int total) { return progress(done, total); }, nullptr,
                                        sound);
      std::cout << "volume-haptics export: " << options.video.string() << " (" << n << " frames at "
                << options.fps << " fps, " << frames.width() << " x " << frames.height() << ", "
                << (sound != nullptr ? "with the burr's sound (Ogg Vorbis)"
                                     : options.sound ? "no sound: the burr never ran" : "no sound (--no-audio)")
                << ")"
                << (progress.wasInterrupted() ? ", stopped by Ctrl+C: the video ends there" : "") << "\n";
    }
    return 0;
  } catch (const std::exception& e) {
    std::cerr << "volume-haptics export: error: " << e.what() << '\n';
    return 1;
  }
}

}  // namespace vh::ui
