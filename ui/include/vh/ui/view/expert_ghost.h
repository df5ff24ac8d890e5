#pragma once
/// @file
/// The expert's tool as a ghost (no Qt): while guidance from an expert's recording is on, a
/// translucent green copy of the tool at the expert's pose at the nearest point of the expert's
/// path (runtime::ExpertPath::poseAt()), and that path as a thin green polyline.
///
/// Both are drawn in the view's overlay layer (SceneActors::overlayRenderer(): same camera, its
/// own depth buffer), over the scan and the tools: a translucent prop in the scan's renderer
/// would be covered by the ray-cast surface behind it (the volume is composited after
/// translucent geometry), and the expert's tool is most worth seeing where it went into the
/// surface. Back faces are culled so the ghost is one even veil of kOpacity.
///
/// Frames: W the scene frame [m]; the tool mesh is in the tool frame T [m].

#include <vtkNew.h>

#include "vh/haptics/path_guidance.h"
#include "vh/haptics/pose.h"

class vtkActor;
class vtkAlgorithmOutput;
class vtkPoints;
class vtkPolyData;
class vtkRenderer;

namespace vh::ui {

class ExpertGhost {
 public:
  /// Opacity of the ghost tool (0..1) and its colour, RGB in [0, 1] (green: apart from the steel
  /// proxy, the blue device, the red contacts and the yellow force arrow).
  static constexpr double kOpacity = 0.3;
  static constexpr double kRgb[3] = {0.15, 0.85, 0.25};

  /// Adds the (hidden) ghost and path to `layer`. `tool_T` is the tool's display mesh in T [m]
  /// (the proxy mapper's input: a new tool mesh shows in the ghost too). Both outlive this.
  ExpertGhost(vtkRenderer* layer, vtkAlgorithmOutput* tool_T);
  ~ExpertGhost();  ///< Takes the props out of the layer.
  ExpertGhost(const ExpertGhost&) = delete;
  ExpertGhost& operator=(const ExpertGhost&) = delete;

  /// The expert's path drawn as its segments, in W [m] (null or empty: no path drawn). Hides the
  /// ghost until the next show().
  void setPath(const haptics::GuidancePath* path);
  /// The ghost tool at X_WE (the expert's tool pose in W [m]) and the path, shown.
  void show(const haptics::Pose& X_WE);
  /// Ghost and path hidden.
  void hide();
  bool visible() const noexcept { return visible_; }
  /// The pose last shown [m].
  const haptics::Pose& pose() const noexcept { return X_WE_; }

  vtkActor* toolActor() const noexcept { return tool_; }
  vtkActor* pathActor() const noexcept { return path_actor_; }

 private:
  vtkRenderer* layer_;  // not owned
  vtkNew<vtkActor> tool_;
  vtkNew<vtkPoints> path_points_;
  vtkNew<vtkPolyData> path_poly_;
  vtkNew<vtkActor> path_actor_;
  bool has_path_ = false;
  bool visible_ = false;
  haptics::Pose X_WE_;
};

}  // namespace vh::ui
