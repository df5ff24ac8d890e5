#pragma once
/// @file
/// How the 3D view looks, as the user chose it: the colours, the rendering mode and preset, the
/// orientation marker, the device tool, the tool's shadow and the segments drawn through the scan. The view reads it; what the application remembers
/// between runs (Preferences, one floor up) extends it, so the view never depends on settings.

#include <QColor>

#include "vh/ui/view/render_presets.h"

class vtkRenderer;

namespace vh::ui {

class SceneActors;

struct ViewLook {
  QColor background_bottom = QColor(15, 18, 23);  ///< View background, lower edge of the gradient.
  QColor background_top = QColor(56, 64, 79);     ///< View background, upper edge.
  QColor surface = QColor(237, 222, 189);         ///< Isosurface colour (bone).
  QColor tool = QColor(158, 166, 179);            ///< Proxy (solid) tool colour.
  QColor device = QColor(77, 191, 255);           ///< Device (wireframe) tool colour.

  RenderMode mode = RenderMode::kIsosurface;
  VolumePreset preset = VolumePreset::kBone;
  bool orientation_marker = true;
  bool show_device = true;  ///< Draw the device's (wireframe) tool.
  bool tool_shadow = true;  ///< Draw the tool's shadow on the surface (a depth cue; ToolShadow).
  /// Draw the shown segments in front of the scan's surface, which hides a segment inside the
  /// body (SceneView::setSegmentsThroughScan()); off: in the scene, where the surface hides them.
  bool segments_through_scan = false;

  bool operator==(const ViewLook& other) const = default;
};

/// The colours of `look` (VTK's 0..1 RGB from the QColors): `renderer`'s background gradient
/// (bottom, top) and, when `actors` is set, the isosurface, proxy tool and device tool. The one
/// place both the main view (SceneView) and exported frames take their colours from.
void applyColours(vtkRenderer* renderer, SceneActors* actors, const ViewLook& look);

}  // namespace vh::ui
