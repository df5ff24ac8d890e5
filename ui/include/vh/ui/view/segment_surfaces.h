#pragma once
/// @file
/// The shown segments of a scene as coloured surfaces beside the ray-cast scan: each
/// shown segment's smoothed indicator (io::segmentIndicatorField(), the felt surface's own
/// field) contoured at F = 0.5 with vtkFlyingEdges3D, in the segment's colour (opaque; when
/// some segments are felt, the others are drawn translucent as context). Surfaces are
/// cached per segment, so showing and hiding one costs no new contour.
///
/// Frames: W the scene frame [m] (the segmentation's patient LPS). Threads: GUI thread only.
#include <map>
#include <string>
#include <vector>

#include <vtkSmartPointer.h>

#include "vh/runtime/segments.h"

class vtkActor;
class vtkMatrix4x4;
class vtkPolyData;
class vtkRenderer;

namespace vh::ui {

class SegmentSurfaces {
 public:
  /// Adds nothing yet; the actors go into `renderer` (which must outlive this object).
  explicit SegmentSurfaces(vtkRenderer* renderer);
  ~SegmentSurfaces();  ///< Removes the actors from the renderer.
  SegmentSurfaces(const SegmentSurfaces&) = delete;
  SegmentSurfaces& operator=(const SegmentSurfaces&) = delete;

  /// Shows the shown segments of `set` (null: none). A different segmentation file or smoothing
  /// drops the cached surfaces.
  void show(const runtime::SegmentSet* set);
  /// Emphasises `segment` (the one touched; -1: none) by drawing it brighter.
  void setTouched(int segment);
  /// Segments with an actor now.
  std::vector<int> shownSegments() const;
  /// The surface of segment `s` in W [m], or null when it is not shown.
  vtkPolyData* surface(int s) const;

 private:
  vtkRenderer* renderer_;
  std::string source_;            // segmentation file of the cached surfaces
  double smoothing_voxels_ = -1.0;
  std::map<int, vtkSmartPointer<vtkPolyData>> cache_;
  std::map<int, vtkSmartPointer<vtkMatrix4x4>> matrices_;  // direction about the origin
  std::map<int, vtkSmartPointer<vtkActor>> actors_;
  std::map<int, std::vector<double>> colours_;
  int touched_ = -1;
};

}  // namespace vh::ui
