#pragma once
/// @file
/// The shown segments of a scene as coloured surfaces beside the ray-cast scan: each
/// shown segment's smoothed indicator (io::segmentIndicatorField(), the felt surface's own
/// field) contoured at F = 0.5 with vtkFlyingEdges3D, in the segment's colour (opaque; when
/// some segments are felt, the others are drawn translucent as context). Surfaces are
/// cached per segment, so showing and hiding one costs no new contour.
///
/// Frames: W the scene frame [m] (the segmentation's patient LPS). Threads: GUI thread only.
#include <array>
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

/// An sRGB colour, each channel 0..1.
using Rgb = std::array<double, 3>;

/// The CIE 1976 colour difference Delta E*ab between two sRGB colours: both converted to CIELAB
/// (sRGB's transfer function undone, to XYZ with the sRGB primaries, D65 white) and their
/// Euclidean distance taken. 0 for equal colours; 100 between black and white; about 2.3 is the
/// smallest difference people notice side by side.
double colourDifference_Lab(const Rgb& a, const Rgb& b);

/// Segments whose colour lies closer than this (Delta E*ab) to the scan surface's are hard to
/// tell from it in the view: they are drawn in a distinct colour instead.
inline constexpr double kMinSegmentContrast_Lab = 20.0;

/// The colour a segment is drawn in: `segment_rgb` (its file's) when it differs from
/// `surface_rgb` (the scan surface's) by at least kMinSegmentContrast_Lab, else the colour of a
/// fixed palette (green, blue, magenta, cyan, orange, yellow, red, purple) that lies farthest,
/// in Delta E*ab, from the surface and from every colour in `taken` (the other segments').
Rgb distinctSegmentColour(const Rgb& segment_rgb, const Rgb& surface_rgb, const std::vector<Rgb>& taken);

/// One segment's surface as SegmentSurfaces draws it: the contour in the image's frame and the
/// matrix that turns it into W (the image has no direction: the matrix applies it about W's
/// origin, as the volume's actor does).
struct SegmentSurface {
  vtkSmartPointer<vtkPolyData> surface;
  vtkSmartPointer<vtkMatrix4x4> X_W_image;
};

/// Builds segment `s`'s surface of `set` (its smoothed indicator contoured at
/// io::kSegmentSurfaceLevel): seconds on a CT-sized grid. Any thread (it touches only its own
/// VTK objects), so a load can build surfaces off the GUI thread and hand them to
/// SegmentSurfaces::adopt().
/// @throws std::invalid_argument as io::segmentIndicatorField() for a bad segment index.
SegmentSurface buildSegmentSurface(const runtime::SegmentSet& set, int s);

class SegmentSurfaces {
 public:
  /// Adds nothing yet; the actors go into `renderer` (which must outlive this object).
  explicit SegmentSurfaces(vtkRenderer* renderer);
  /// Moves the actors into `renderer` (which must outlive this object); the next ones go there too.
  void setRenderer(vtkRenderer* renderer);
  vtkRenderer* renderer() const noexcept { return renderer_; }
  ~SegmentSurfaces();  ///< Removes the actors from the renderer.
  SegmentSurfaces(const SegmentSurfaces&) = delete;
  SegmentSurfaces& operator=(const SegmentSurfaces&) = delete;

  /// Shows the shown segments of `set` (null: none), each in distinctSegmentColour() against
  /// `surface_rgb` (the scan surface's colour) and the segments drawn before it. A different
  /// segmentation file or smoothing drops the cached surfaces.
  void show(const runtime::SegmentSet* set, const Rgb& surface_rgb);
  /// Takes surfaces built elsewhere (buildSegmentSurface(), on a worker thread) for `set`'s
  /// segments into the cache, so the next show() of `set` contours nothing.
  void adopt(const runtime::SegmentSet& set, std::map<int, SegmentSurface> built);
  /// The colour segment `s` is drawn in (empty when it is not shown).
  std::vector<double> colour(int s) const;
  /// The shown segments drawn in another colour than their file's (too close to the surface).
  const std::vector<int>& recoloured() const noexcept { return recoloured_; }
  /// Emphasises `segment` (the one touched; -1: none) by drawing it brighter.
  void setTouched(int segment);
  /// Segments with an actor now.
  std::vector<int> shownSegments() const;
  /// The bounds of segment `s`'s surface in W [m] (xmin xmax ymin ymax zmin zmax) into
  /// `bounds_W`; false when it is not shown or empty.
  bool bounds_W(int s, double bounds_W[6]) const;
  /// The surface of segment `s` in W [m], or null when it is not shown.
  vtkPolyData* surface(int s) const;

 private:
  vtkRenderer* renderer_;
  std::string source_;            // segmentation file of the cached surfaces
  double smoothing_voxels_ = -1.0;
  std::map<int, SegmentSurface> cache_;  // per segment: its contour and the matrix into W
  /// Keeps the cached surfaces when they are `set`'s file and smoothing, else drops them.
  void keepCacheFor(const runtime::SegmentSet& set);
  std::map<int, vtkSmartPointer<vtkActor>> actors_;
  std::map<int, std::vector<double>> colours_;
  std::vector<int> recoloured_;
  int touched_ = -1;
};

}  // namespace vh::ui
