// SceneActors' rendering quality (scene_actors.h, "Rendering quality"): the ray cast's sampling
// while still and while moving, the controller that adapts it to the frame time, and what the
// moving frames draw (the surface mesh, the composite unshaded) where the ray cast would be coarse.
#include "vh/ui/view/scene_actors.h"

#include "isosurface_mesh.h"

#include <algorithm>
#include <cmath>
#include <utility>

#include <vtkActor.h>
#include <vtkGPUVolumeRayCastMapper.h>
#include <vtkRenderer.h>
#include <vtkVolume.h>
#include <vtkVolumeProperty.h>

namespace vh::ui {

namespace {
// Still-frame quality levels: ray sample distance in voxels, image sample distance in pixels.
constexpr double kStillSampleVoxels[3] = {0.5, 1.0, 1.0};
constexpr double kStillImageSample[3] = {1.0, 1.0, 1.5};
// A still frame is full quality (half-voxel samples, a ray per pixel) unless it took longer than
// this (a very large view on software GL, where it would freeze the window for seconds each time
// the hand rests): then the next still frames step down, and back up once faster than kStillFastMs.
constexpr double kStillSlowMs = 3000.0;
constexpr double kStillFastMs = 750.0;
// Interactive frames: the work of a ray cast at one sample per voxel and one ray per pixel,
// divided by the reduction r (1 to kMaxReduction). Rays go first (image sample distance up to
// kFirstImageSample pixels: the picture gets softer but keeps thin bone), then samples along the
// rays (up to kMaxSampleVoxels apart), then rays again (up to kMaxImageSample pixels).
constexpr double kFirstImageSample = 3.0;
constexpr double kMaxSampleVoxels = 3.0;
constexpr double kMaxImageSample = 8.0;
constexpr double kMaxReduction = kMaxImageSample * kMaxImageSample * kMaxSampleVoxels;
// Interactive frames sample the nearest voxel above this reduction (rays 4 px apart), and
// trilinearly again below the lower one: a factor of 4 between them, more than the 2-3x that
// nearest sampling saves on llvmpipe, so neither choice makes the controller switch back.
constexpr double kNearestAboveReduction = 16.0;
constexpr double kLinearBelowReduction = 4.0;
// MovingView::kAuto draws the surface mesh above this reduction: rays more than kFirstImageSample
// pixels apart, with samples already kMaxSampleVoxels apart along them.
constexpr double kMeshAboveReduction = kFirstImageSample * kFirstImageSample * kMaxSampleVoxels;
// The mesh's frames are late over this many times the interactive target (30 ms: under about 16
// frames a second): three in a row make the mesh coarser.
constexpr double kMeshLateRatio = 2.0;
constexpr int kMeshLateFrames = 3;

/// The ray sample distance [voxels] and image sample distance [px] of the reduction `r`: the
/// work of a frame falls as 1 / (samples apart x pixels apart^2).
std::pair<double, double> interactiveSampling(double r) {
  const double first = std::min(std::sqrt(r), kFirstImageSample);
  const double samples = std::clamp(r / (first * first), 1.0, kMaxSampleVoxels);
  const double pixels = std::clamp(std::sqrt(r / samples), 1.0, kMaxImageSample);
  return {samples, pixels};
}
}  // namespace

void SceneActors::applyQuality() {
  // Heavily reduced interactive frames sample the nearest voxel: on software GL the trilinear
  // fetch (8 voxels a sample) is most of a ray's cost, and a picture of rays several pixels
  // apart loses little more by it. With hysteresis, so that the view does not flicker between
  // the two where one is late and the other early.
  if (interactive_reduction_ > kNearestAboveReduction) {
    nearest_when_interactive_ = true;
  } else if (interactive_reduction_ < kLinearBelowReduction) {
    nearest_when_interactive_ = false;
  }
  const bool capped = std::isfinite(interactive_cap_px_);
  const int interpolation =
      interactive_ && nearest_when_interactive_ && !capped ? VTK_NEAREST_INTERPOLATION : VTK_LINEAR_INTERPOLATION;
  if (volume_property_->GetInterpolationType() != interpolation) volume_property_->SetInterpolationType(interpolation);
  if (interactive_) {
    const auto [samples, sampled_pixels] = interactiveSampling(interactive_reduction_);
    const double pixels = std::min(sampled_pixels, interactive_cap_px_);
    volume_mapper_->SetSampleDistance(static_cast<float>(std::max(samples, kStillSampleVoxels[still_level_]) * min_spacing_m_));
    volume_mapper_->SetImageSampleDistance(static_cast<float>(std::max(pixels, kStillImageSample[still_level_])));
  } else {
    volume_mapper_->SetSampleDistance(
        static_cast<float>(kStillSampleVoxels[still_level_] * min_spacing_m_));
    volume_mapper_->SetImageSampleDistance(static_cast<float>(kStillImageSample[still_level_]));
  }
  // A composite ray cast that must cast rays more than 3 px apart to keep to time (a software
  // renderer) leaves out the shading of its moving frames from then on: the gradient's six extra
  // fetches a sample are most of its cost (2.8 times cheaper unshaded on llvmpipe), so its rays
  // can lie closer. Still frames keep the shading.
  if (interactive_ && mode_ == RenderMode::kComposite && !capped && interactive_reduction_ > kMeshAboveReduction)
    composite_unshaded_motion_ = true;
  applyShade();
  applyMovingView();
}

void SceneActors::applyShade() {
  const int shade = look_shaded_ && !unshadedMotion() ? 1 : 0;
  if (volume_property_->GetShade() != shade) volume_property_->SetShade(shade);
}

void SceneActors::sampleAsFirstMotion() {
  volume_property_->SetInterpolationType(VTK_NEAREST_INTERPOLATION);
  const auto [samples, pixels] = interactiveSampling(kMaxReduction);
  volume_mapper_->SetSampleDistance(static_cast<float>(samples * min_spacing_m_));
  volume_mapper_->SetImageSampleDistance(static_cast<float>(pixels));
}

bool SceneActors::unshadedMotion() const noexcept {
  return interactive_ && mode_ == RenderMode::kComposite && composite_unshaded_motion_ &&
         !std::isfinite(interactive_cap_px_);
}

bool SceneActors::volumeShaded() const { return volume_property_->GetShade() != 0; }

void SceneActors::applyMovingView() {
  // A replay's capped frames (setInteractiveImageSampleCap_px()) stay the ray cast: the voxels
  // as they were drilled, not a mesh of their block averages.
  bool want = interactive_ && mode_ == RenderMode::kIsosurface && !std::isfinite(interactive_cap_px_) &&
              (moving_view_ == MovingView::kSurfaceMesh ||
               (moving_view_ == MovingView::kAuto && interactive_reduction_ > kMeshAboveReduction));
  if (want && !mesh_shown_) {
    if (mesh_ == nullptr) {
      mesh_ = std::make_unique<IsosurfaceMesh>(shownImage(), volume_->GetUserMatrix());
      mesh_->setIsovalue(isovalue());
      const VolumeLook look = isosurfaceLook(range_[0], range_[1], surface_rgb_[0], surface_rgb_[1], surface_rgb_[2]);
      mesh_->setLook(surface_rgb_, look.ambient, look.diffuse, look.specular, look.specular_power);
      mesh_->setClipPlane(clipping_ ? clip_plane_.GetPointer() : nullptr);
      renderer_->AddActor(mesh_->actor());
    }
    late_mesh_frames_ = 0;
    want = mesh_->drawable() && mesh_->update(/*force=*/true);
  }
  if (want == mesh_shown_) return;
  mesh_shown_ = want;
  mesh_->actor()->SetVisibility(want);
  volume_->SetVisibility(!want);
}

void SceneActors::beforeRender() {
  if (mesh_shown_) mesh_->update(/*force=*/false);
}

void SceneActors::setMovingView(MovingView view) {
  moving_view_ = view;
  applyMovingView();
}

std::size_t SceneActors::surfaceMeshTriangles() const noexcept { return mesh_ != nullptr ? mesh_->triangles() : 0; }
int SceneActors::surfaceMeshFactor() const noexcept { return mesh_ != nullptr ? mesh_->factor() : 0; }
vtkActor* SceneActors::surfaceMeshActor() const noexcept { return mesh_ != nullptr ? mesh_->actor() : nullptr; }

void SceneActors::setInteractive(bool interactive) {
  if (interactive != interactive_) {
    interactive_ = interactive;
    applyQuality();
  }
}

void SceneActors::setInteractiveImageSampleCap_px(double pixels) {
  const double cap = std::isnan(pixels) ? std::numeric_limits<double>::infinity() : std::max(pixels, 1.0);
  if (cap == interactive_cap_px_) return;
  interactive_cap_px_ = cap;
  applyQuality();
}

void SceneActors::resetQuality() {
  still_level_ = 0;
  applyQuality();
}

double SceneActors::sampleDistance_m() const { return volume_mapper_->GetSampleDistance(); }
double SceneActors::imageSampleDistance_px() const { return volume_mapper_->GetImageSampleDistance(); }
bool SceneActors::nearestSampling() const { return volume_property_->GetInterpolationType() == VTK_NEAREST_INTERPOLATION; }

void SceneActors::adaptQuality(double last_frame_ms, double interactive_target_ms) {
  if (!(last_frame_ms > 0.0) || !(interactive_target_ms > 0.0)) {
    return;
  }
  const double ratio = last_frame_ms / interactive_target_ms;
  if (interactive_ && mesh_shown_) {
    // The mesh's frame: nothing about the ray cast's cost. A mesh too heavy for this renderer
    // gets coarser (f + 1: about 0.7 times the triangles).
    late_mesh_frames_ = ratio > kMeshLateRatio ? late_mesh_frames_ + 1 : 0;
    if (late_mesh_frames_ >= kMeshLateFrames) {
      late_mesh_frames_ = 0;
      if (mesh_->coarsen()) mesh_->update(/*force=*/true);
    }
    return;
  }
  if (interactive_) {
    // Late: at once to what meets the target (the next frame must not be late too); early:
    // halfway (geometrically), so the picture does not flicker between settings.
    const double fit = interactive_reduction_ * ratio;  // the reduction that would just have met the target
    interactive_reduction_ = std::clamp(interactive_reduction_ * (ratio > 1.0 ? ratio : std::sqrt(ratio)), 1.0, kMaxReduction);
    const auto mode = static_cast<std::size_t>(mode_);
    // At full quality and early, where the frames settled is the fit below 1 (a fast GPU: frames
    // well inside the target at a ray per pixel), so that a larger view resumes at full quality
    // as long as its rays still fit, rather than at a reduction scaled from the clamp.
    settled_reduction_[mode] = interactive_reduction_ > 1.0 ? interactive_reduction_ : std::min(1.0, fit);
    settled_pixels_[mode] = viewPixels();
  } else {
    // A still frame: the first interactive frame's guess from it (cost ~ 1 / (sample distance x
    // image sample distance^2)), and still frames kept from freezing the window for seconds.
    const double still_work = kStillSampleVoxels[still_level_] * kStillImageSample[still_level_] * kStillImageSample[still_level_];
    // Nor below where this mode's last interactive frames settled: the still frame's cost
    // grows less than in proportion to its work (what each frame costs whatever its rays), so
    // its guess alone came too low, and each resumed motion began with frames 2-4x late.
    interactive_reduction_ = std::clamp(std::max(still_work * ratio, resumedReduction(ratio)), 1.0, kMaxReduction);
    if (last_frame_ms > kStillSlowMs && still_level_ < 2) {
      ++still_level_;
    } else if (last_frame_ms < kStillFastMs && still_level_ > 0) {
      --still_level_;
    }
  }
  applyQuality();
}

double SceneActors::viewPixels() const {
  const int* size = renderer_->GetSize();
  return size == nullptr ? 0.0 : static_cast<double>(size[0]) * static_cast<double>(size[1]);
}

double SceneActors::resumedReduction(double still_ratio) const {
  const auto mode = static_cast<std::size_t>(mode_);
  // No motion in this mode yet. A still frame that met the interactive target cast twice the
  // samples of a full-quality interactive frame over the same rays: full quality then (a GPU).
  // Otherwise from the largest reduction, relaxed halfway each early frame (a few frames too
  // coarse, rather than the first ones late); on a GPU that way down showed a coarse picture for
  // the first 10 to 20 frames of each mode.
  if (!(settled_reduction_[mode] > 0.0)) return still_ratio <= 1.0 ? 1.0 : kMaxReduction;
  // The same picture in a larger view casts more rays.
  const double now = viewPixels(), then = settled_pixels_[mode];
  return now > 0.0 && then > 0.0 ? settled_reduction_[mode] * now / then : settled_reduction_[mode];
}

}  // namespace vh::ui
