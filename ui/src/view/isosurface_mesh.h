#pragma once
// The felt isosurface as a triangle mesh, for the main view's moving frames on a renderer that
// cannot ray cast them at a readable resolution (scene_actors.cpp). Private to vh::ui's view.
#include <array>
#include <chrono>
#include <cstddef>

#include <vtkNew.h>
#include <vtkSmartPointer.h>

class vtkActor;
class vtkFlyingEdges3D;
class vtkImageData;
class vtkImageShrink3D;
class vtkMatrix4x4;
class vtkPlane;
class vtkPolyData;
class vtkPolyDataMapper;

namespace vh::ui {

/// The isosurface F = isovalue of the shown image, drawn as triangles: VTK's flying edges over
/// a coarse copy of the image (the mean of f x f x f voxel blocks, vtkImageShrink3D), with the
/// gradient's normals, back faces culled. The coarse copy follows the image's changes box by box
/// (drilling, soft tissue: only the blocks a changed box touches are averaged again), and the
/// triangles are rebuilt from it when the isovalue or the image changed, at most once every
/// kRebuildMs while things keep changing (the cost of a rebuild, 5-10 ms for a 512 x 512 x 275 CT
/// at f = 5 on two cores, is not paid every frame of a drilling).
///
/// Frames: the image's own (index to metres by its origin and spacing); the actor takes the
/// volume's user matrix, so the mesh lies where the ray-cast isosurface does in W.
class IsosurfaceMesh {
 public:
  /// At most this many voxels in the coarse copy: f is the smallest block edge that gets there.
  static constexpr double kCoarseVoxels = 1.2e6;
  static constexpr int kMaxFactor = 16;
  static constexpr double kRebuildMs = 120.0;

  /// `image` (not owned, kept alive by the caller's smart pointer), `user_matrix` the volume's
  /// image-to-W matrix (shared, not copied).
  IsosurfaceMesh(vtkImageData* image, vtkMatrix4x4* user_matrix);
  ~IsosurfaceMesh();
  IsosurfaceMesh(const IsosurfaceMesh&) = delete;
  IsosurfaceMesh& operator=(const IsosurfaceMesh&) = delete;

  /// The image shown now; `same_values`: a copy of the last one (drilling's private copy made
  /// before any change), so the coarse copy stays; otherwise it is averaged again at the next
  /// update().
  void setImage(vtkImageData* image, bool same_values);
  /// The voxels [lo, hi] (indices of the image, inclusive) changed.
  void markChanged(const int lo[3], const int hi[3]);
  void setIsovalue(double isovalue);
  /// A coarser copy (f + 1, up to kMaxFactor): the frames drawing the mesh are late. @return
  /// false at kMaxFactor (nothing changed).
  bool coarsen();
  /// Brings the triangles up to date: now when `force` or kRebuildMs after the last rebuild,
  /// else leaves them for a later call. @return whether the mesh is current.
  bool update(bool force);
  /// Whether there is a mesh to draw (an image of at least 2 coarse voxels on each axis).
  bool drawable() const noexcept;

  vtkActor* actor() const noexcept;
  void setClipPlane(vtkPlane* plane);  ///< nullptr: none
  void setLook(const double rgb[3], double ambient, double diffuse, double specular, double specular_power);

  std::size_t triangles() const noexcept;
  int factor() const noexcept { return factor_; }

 private:
  void rebuildCoarse();
  void refreshCoarseBox();

  vtkImageData* image_;
  int factor_ = 1;
  std::array<int, 3> factors_{1, 1, 1};
  vtkNew<vtkImageShrink3D> shrink_;
  vtkSmartPointer<vtkImageData> coarse_;
  vtkNew<vtkFlyingEdges3D> contour_;
  vtkNew<vtkPolyData> poly_;
  vtkNew<vtkPolyDataMapper> mapper_;
  vtkNew<vtkActor> actor_;
  double isovalue_ = 0.0;
  bool coarse_stale_ = true;   // the whole coarse copy must be averaged again
  bool box_pending_ = false;   // [lo_, hi_] changed since the last refresh
  std::array<int, 3> lo_{0, 0, 0}, hi_{-1, -1, -1};
  bool mesh_stale_ = true;
  std::chrono::steady_clock::time_point built_at_{};
};

}  // namespace vh::ui
