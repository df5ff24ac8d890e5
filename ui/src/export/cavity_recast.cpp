// The kept volume picture updated where a growing cavity lies (media_export.h,
// RecordingFrameRenderer): which pixels' rays can meet the removed voxels, and the depth of the
// surface along them, which the ray caster's depth image gives only for a whole frame.

#include "vh/ui/export/media_export.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <optional>

#include <Eigen/Core>
#include <vtkCamera.h>
#include <vtkDataArray.h>
#include <vtkGPUVolumeRayCastMapper.h>
#include <vtkImageData.h>
#include <vtkMatrix4x4.h>
#include <vtkNew.h>
#include <vtkPointData.h>
#include <vtkRenderer.h>
#include <vtkVolume.h>

namespace vh::ui {

void RecordingFrameRenderer::surfaceEyeDepthIn(const PixelRect& r) {
  auto* image = vtkImageData::SafeDownCast(actors_->volumeMapper()->GetInput());
  vtkDataArray* values = image != nullptr && image->GetPointData() != nullptr ? image->GetPointData()->GetScalars() : nullptr;
  int dims[3] = {0, 0, 0};
  double origin[3] = {0, 0, 0}, spacing[3] = {1, 1, 1};
  if (image != nullptr) image->GetDimensions(dims), image->GetOrigin(origin), image->GetSpacing(spacing);
  vtkCamera* camera = renderer_->GetActiveCamera();
  double eye[3], dop[3];
  camera->GetPosition(eye);
  camera->GetDirectionOfProjection(dop);
  vtkNew<vtkMatrix4x4> image_from_W;
  vtkMatrix4x4::Invert(actors_->volume()->GetMatrix(), image_from_W);
  const double iso = actors_->isovalue();
  // The scan's continuous index of a point of W, and back.
  const auto indexOf = [&](const double p_W[3]) {
    double in[4] = {p_W[0], p_W[1], p_W[2], 1.0}, out[4];
    image_from_W->MultiplyPoint(in, out);
    return Eigen::Vector3d((out[0] / out[3] - origin[0]) / spacing[0], (out[1] / out[3] - origin[1]) / spacing[1],
                           (out[2] / out[3] - origin[2]) / spacing[2]);
  };
  const auto valueAt = [&](const Eigen::Vector3d& u) {  // trilinear, u within [0, dims - 1]
    int i0[3];
    double f[3];
    for (int a = 0; a < 3; ++a) {
      i0[a] = std::clamp(static_cast<int>(std::floor(u[a])), 0, std::max(0, dims[a] - 2));
      f[a] = std::clamp(u[a] - i0[a], 0.0, 1.0);
    }
    double v = 0.0;
    for (int c = 0; c < 8; ++c) {
      const int i = std::min(i0[0] + (c & 1), dims[0] - 1), j = std::min(i0[1] + (c >> 1 & 1), dims[1] - 1),
                k = std::min(i0[2] + (c >> 2 & 1), dims[2] - 1);
      const double w = ((c & 1) != 0 ? f[0] : 1 - f[0]) * ((c >> 1 & 1) != 0 ? f[1] : 1 - f[1]) * ((c >> 2 & 1) != 0 ? f[2] : 1 - f[2]);
      if (w != 0.0) v += w * values->GetComponent(i + static_cast<vtkIdType>(dims[0]) * (j + static_cast<vtkIdType>(dims[1]) * k), 0);
    }
    return v;
  };
  for (int y = r.y; y < r.y + r.height; ++y)
    for (int x = r.x; x < r.x + r.width; ++x) {
      float& depth = kept_eye_depth_[static_cast<std::size_t>(y) * width_ + x];
      depth = std::numeric_limits<float>::infinity();
      if (values == nullptr || dims[0] < 2 || dims[1] < 2 || dims[2] < 2) continue;
      // The pixel's ray from the near to the far plane, in the scan's index space.
      double ends_W[2][4];
      for (int e = 0; e < 2; ++e) {
        renderer_->SetDisplayPoint(x + 0.5, y + 0.5, e);
        renderer_->DisplayToWorld();
        renderer_->GetWorldPoint(ends_W[e]);
        for (int a = 0; a < 3; ++a) ends_W[e][a] /= ends_W[e][3];
      }
      const Eigen::Vector3d u0 = indexOf(ends_W[0]), u1 = indexOf(ends_W[1]);
      // Clipped to the scan's box [0, dims - 1] (slab test).
      double t_in = 0.0, t_out = 1.0;
      for (int a = 0; a < 3 && t_in <= t_out; ++a) {
        const double d = u1[a] - u0[a], hi = dims[a] - 1.0;
        if (std::abs(d) < 1e-12) {
          if (u0[a] < 0.0 || u0[a] > hi) t_in = 2.0;
          continue;
        }
        double ta = (0.0 - u0[a]) / d, tb = (hi - u0[a]) / d;
        if (ta > tb) std::swap(ta, tb);
        t_in = std::max(t_in, ta), t_out = std::min(t_out, tb);
      }
      if (!(t_in <= t_out)) continue;
      // Marched a quarter voxel at a time; the first change of side of the isovalue is refined
      // by bisection: where the surface is, as finely as the ray caster samples it or finer.
      const double length = ((u1 - u0) * (t_out - t_in)).cwiseAbs().maxCoeff();
      const int steps = std::max(1, static_cast<int>(std::ceil(length * 4.0)));
      const auto at = [&](double t) { return Eigen::Vector3d(u0 + (u1 - u0) * t); };
      double t_prev = t_in;
      bool below = valueAt(at(t_prev)) < iso;
      std::optional<double> t_hit;
      if (!below) t_hit = t_in;  // the near end already inside the surface
      for (int n = 1; n <= steps && !t_hit; ++n) {
        const double t = t_in + (t_out - t_in) * n / steps;
        if ((valueAt(at(t)) < iso) != below) {
          double lo = t_prev, hi = t;
          for (int b = 0; b < 12; ++b) {
            const double mid = 0.5 * (lo + hi);
            ((valueAt(at(mid)) < iso) == below ? lo : hi) = mid;
          }
          t_hit = hi;
        }
        t_prev = t;
      }
      if (!t_hit) continue;
      double p_W[3];
      for (int a = 0; a < 3; ++a) p_W[a] = ends_W[0][a] + (ends_W[1][a] - ends_W[0][a]) * *t_hit;
      depth = static_cast<float>((p_W[0] - eye[0]) * dop[0] + (p_W[1] - eye[1]) * dop[1] + (p_W[2] - eye[2]) * dop[2]);
    }
}

std::optional<RecordingFrameRenderer::PixelRect> RecordingFrameRenderer::cavityRect(std::uint64_t from,
                                                                                    std::uint64_t to) const {
  const std::vector<std::uint64_t>& voxels = drilling_.picture.voxels;
  to = std::min<std::uint64_t>(to, voxels.size());
  auto* image = vtkImageData::SafeDownCast(actors_->volumeMapper()->GetInput());
  if (image == nullptr || from >= to) return std::nullopt;
  int dims[3];
  image->GetDimensions(dims);
  // The removed voxels' index box, grown by 2 voxels: the trilinear samples and the central
  // differences of the shading's gradient reach one voxel on from a changed one.
  std::array<long long, 3> lo{dims[0], dims[1], dims[2]}, hi{-1, -1, -1};
  const auto nx = static_cast<std::uint64_t>(dims[0]), nxy = nx * static_cast<std::uint64_t>(dims[1]);
  for (std::uint64_t n = from; n < to; ++n) {
    const std::uint64_t v = voxels[n];
    const std::array<long long, 3> ijk{static_cast<long long>(v % nx), static_cast<long long>((v / nx) % dims[1]),
                                       static_cast<long long>(v / nxy)};
    for (int a = 0; a < 3; ++a) lo[a] = std::min(lo[a], ijk[a]), hi[a] = std::max(hi[a], ijk[a]);
  }
  if (hi[0] < lo[0]) return std::nullopt;
  // Its corners in W (the volume's matrix), then on the screen (display pixels, bottom left 0).
  vtkMatrix4x4* X_W_image = actors_->volume()->GetMatrix();
  double x_min = std::numeric_limits<double>::infinity(), y_min = x_min, x_max = -x_min, y_max = -x_min;
  for (int corner = 0; corner < 8; ++corner) {
    double ijk[3], p_image[4], p_W[4];
    for (int a = 0; a < 3; ++a) ijk[a] = static_cast<double>((corner >> a & 1) != 0 ? hi[a] + 2 : lo[a] - 2);
    image->TransformContinuousIndexToPhysicalPoint(ijk, p_image);
    p_image[3] = 1.0;
    X_W_image->MultiplyPoint(p_image, p_W);
    renderer_->SetWorldPoint(p_W[0] / p_W[3], p_W[1] / p_W[3], p_W[2] / p_W[3], 1.0);
    renderer_->WorldToDisplay();
    double d[3];
    renderer_->GetDisplayPoint(d);
    if (!std::isfinite(d[0]) || !std::isfinite(d[1]) || d[2] < 0.0 || d[2] > 1.0) return std::nullopt;  // behind the eye
    x_min = std::min(x_min, d[0]), x_max = std::max(x_max, d[0]);
    y_min = std::min(y_min, d[1]), y_max = std::max(y_max, d[1]);
  }
  // Two pixels more on each side: a ray's samples lie on the pixel's centre line.
  const int x0 = std::max(0, static_cast<int>(std::floor(x_min)) - 2);
  const int y0 = std::max(0, static_cast<int>(std::floor(y_min)) - 2);
  const int x1 = std::min(width_, static_cast<int>(std::ceil(x_max)) + 3);
  const int y1 = std::min(height_, static_cast<int>(std::ceil(y_max)) + 3);
  if (x1 <= x0 || y1 <= y0) return PixelRect{0, 0, 0, 0};  // off the screen: nothing to cast
  return PixelRect{x0, y0, x1 - x0, y1 - y0};
}

}  // namespace vh::ui
