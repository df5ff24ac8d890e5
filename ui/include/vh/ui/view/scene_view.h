#pragma once
/// @file
/// The scene view (Slicer's displayable manager): the one owner of the main view's VTK props
/// (SceneActors), its orientation marker and welcome text, the camera (reset, standard views,
/// focus on the tool) and the clipping plane; it turns a live haptic snapshot and a recorded
/// tick into the same picture (ToolFrame, showToolFrame()). It draws; it holds none of the
/// session's values (the isovalue, the tool and the poses it shows come from runtime::Session
/// through the window, or from a recording).
///
/// Frames: W the scene frame [m] (patient LPS for scans: +x left, +y posterior, +z superior).
/// Threads: GUI thread only.

#include <limits>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <QObject>
#include <vtkSmartPointer.h>

#include "vh/haptics/path_guidance.h"
#include "vh/haptics/pose.h"
#include "vh/haptics/tool_model.h"
#include "vh/ui/view/device_manipulation.h"
#include "vh/ui/view/view_look.h"
#include "vh/ui/view/render_presets.h"
#include "vh/ui/view/scene_actors.h"
#include "vh/ui/view/segment_surfaces.h"

class QTimer;
class QWidget;
class vtkActor;
class vtkRenderer;
class vtkTextActor;

namespace vh::ui {

class ExpertGhost;
class OrientationMarker;
class VtkView;

/// Standard camera directions for a patient frame W = LPS (+x left, +y posterior, +z superior).
enum class StandardView { kAnterior, kPosterior, kLeft, kRight, kSuperior, kInferior };

/// Axis of the clipping plane in W.
enum class ClipAxis { kX, kY, kZ };

class SceneView : public QObject {
  Q_OBJECT

 public:
  /// Creates the VTK view widget (a child of `parent`) with the welcome text of an empty window.
  explicit SceneView(QWidget* parent);
  ~SceneView() override;  ///< Releases the props with the view's GL context current.

  VtkView* widget() const noexcept { return view_; }

  // ---- Scene ---------------------------------------------------------------------------------
  /// Builds the props for `spec` (replacing any; the segment surfaces stay), the tools at
  /// `X_WT`, the look of `look` (segments through the scan included), and resets the camera;
  /// hides the welcome text. @throws std::invalid_argument without an image.
  void setScene(const SceneActorsSpec& spec, const haptics::Pose& X_WT, const ViewLook& look);
  /// Removes the props and the segment surfaces (the welcome text stays hidden once a scene was
  /// shown).
  void clearScene();
  bool hasScene() const noexcept { return actors_ != nullptr; }
  /// The props; only while hasScene().
  SceneActors& actors() const noexcept { return *actors_; }
  OrientationMarker* marker() const noexcept { return marker_.get(); }
  /// Shows the shown segments of `set` as coloured surfaces (null: none; SegmentSurfaces), each
  /// in a colour that stands out from the scan surface's (the look's last applyColours()).
  /// @return the segments drawn in another colour than their file's (SegmentSurfaces::recoloured()).
  const std::vector<int>& setSegments(const runtime::SegmentSet* set);
  /// Surfaces of `set`'s segments built off the GUI thread (buildSegmentSurface()), for the next
  /// setSegments(set) to draw without contouring (SegmentSurfaces::adopt()).
  void adoptSegmentSurfaces(const runtime::SegmentSet& set, std::map<int, SegmentSurface> built);
  /// Emphasises the touched segment (-1: none); a non-empty `alert` is shown in red at the top
  /// of the view (a critical segment touched), an empty one hides it.
  void setTouchedSegment(int segment, const std::string& alert);
  /// The tool coloured by its nearest critical segment (SceneActors::setProximityLevel()).
  void setToolProximity(int level);
  /// The segment surfaces (null before the first scene).
  const SegmentSurfaces* segmentSurfaces() const noexcept { return segments_.get(); }
  /// Draws the shown segments through the scan (`on`), in front of its surface, which hides a
  /// segment inside the body: in segmentLayer(), a renderer over the scan's (layer 1, the same
  /// camera) with a depth buffer of its own, so the segments hide one another as they lie; the
  /// tools are drawn there too, so that a tool nearer than a segment stays in front of it (and
  /// shows through the scan as the segments do). The contacts and the force arrow stay on top.
  /// Off: the segments are in the scan's renderer, where its surface hides those inside it.
  void setSegmentsThroughScan(bool on);
  bool segmentsThroughScan() const noexcept { return through_scan_; }
  /// The renderer the segments are drawn in through the scan; it draws only while that is on
  /// and some segment is shown.
  vtkRenderer* segmentLayer() const noexcept;
  /// The alert text shown now ("" when none).
  std::string alertText() const;
  // ---- The expert's ghost (guidance from an expert's recording: ExpertGhost) ------------------
  /// The expert's path drawn with the ghost (null: none); hides the ghost until showGhost().
  /// `path` must stay alive while it is shown (the caller keeps its runtime::ExpertPath).
  void setGhostPath(const haptics::GuidancePath* path);
  /// The expert's tool at X_WE [m, W] (ExpertPath::poseAt() of the nearest point), translucent
  /// green, with the path; a frame is asked for when it moved or appeared.
  void showGhost(const haptics::Pose& X_WE);
  void hideGhost();
  /// The ghost (null before the first scene); a new scene has a new, hidden one.
  const ExpertGhost* ghost() const noexcept { return ghost_.get(); }

  /// A new tool's display mesh, both tools at `X_WT`, no contacts, no force.
  void setTool(const haptics::ToolModel& tool, const haptics::Pose& X_WT);

  // ---- The tools -----------------------------------------------------------------------------
  /// Shows `frame` (showToolFrame(): poses, contacts, force arrow, isovalue). A new frame, and
  /// interactive frames until the still one 300 ms later, are asked for only when something
  /// changed visibly (changedVisibly()). @return true when it did.
  bool show(const ToolFrame& frame);
  /// Whether `frame` would change the picture against the one shown: the contact count
  /// changed, a corner of the tool's bounding box (proxy or device) or the force arrow's start
  /// or tip moved by a pixel or more at its depth in the view, or the arrow appeared or went.
  /// A proxy resting on a surface under the hand's steady push moves micrometres a tick: no
  /// change, so the full-quality still frame comes.
  bool changedVisibly(const ToolFrame& frame) const;
  /// The device tool at `X_WD` now (mouse feedback before the haptic thread answers).
  void showDevicePose(const haptics::Pose& X_WD);
  /// The proxy's pose last shown [m].
  const haptics::Pose& shownProxyPose() const noexcept { return shown_X_WP_; }
  void setIsovalue(double isovalue);
  void setDeviceVisible(bool visible);
  /// The tool's shadow cast along `direction_W` (SceneActors::setShadow()); asks for a frame.
  void showShadow(const ToolShadow& shadow, const Eigen::Vector3d& direction_W);
  void setShadowVisible(bool visible);
  /// The direction shadows are cast along now: shadowLightDirection_W() of the camera.
  Eigen::Vector3d shadowDirection_W() const;
  void setHint(const std::string& hint);

  // ---- Look ----------------------------------------------------------------------------------
  void setRenderMode(RenderMode mode, VolumePreset preset);
  /// Background gradient, surface, tool and device colours.
  void applyColours(const ViewLook& look);
  void setMarkerVisible(bool visible);

  // ---- Camera and clipping -------------------------------------------------------------------
  /// From anterior, 30 degrees to the patient's right and 25 degrees up, fitted to the props.
  void resetCamera();
  /// Keeps the viewing direction; looks at `tool`'s centre of mass at `X_WP` from about 2.5
  /// tool lengths.
  void focusOn(const haptics::ToolModel& tool, const haptics::Pose& X_WP);
  void setStandardView(StandardView view);
  /// "Go to segment": keeps the viewing direction and frames segment `s`'s surface (its
  /// bounds fill 60% of the view). @return false (nothing moves) when it is not shown.
  bool frameSegment(int s);
  /// The camera now, for the mouse and key manipulation of the device.
  ViewCamera camera() const;
  /// Clips the volume (visual only) normal to `axis` at `fraction` (0..1) of its extent;
  /// `flip` keeps the lower side.
  void setClipping(bool enabled, ClipAxis axis, double fraction, bool flip);

  // ---- Frames --------------------------------------------------------------------------------
  void requestRender();
  /// Interactive (cheaper) frames until 300 ms after the last motion.
  void noteMotion();
  /// While true (a camera or slider drag) frames stay interactive.
  void setInteracting(bool interacting);
  /// While true (a replay shown), frames while anything moves cast a ray every kReplayImageSample_px
  /// pixels at most (SceneActors::setInteractiveImageSampleCap_px()): a replay is watched for what
  /// it shows, so it gets fewer frames rather than coarse ones. Kept across scenes.
  void setSharpMotion(bool on);
  static constexpr double kReplayImageSample_px = 2.0;
  /// Ends interactive frames now; `best_quality` also resets the still quality (screenshots).
  void renderStill(bool best_quality = false);
  /// What an interactive frame's render may take [ms]: the interactive period (1 / 33 Hz) less
  /// the GUI thread's time between back-to-back interactive frames (VtkView::lastGapMs(),
  /// smoothed), so that frames, not only their renders, come at that rate; never under half the
  /// period. SceneActors::adaptQuality() aims at it.
  double interactiveTargetMs() const;

 signals:
  /// show() drew a new pose of the tools (a live snapshot or a replayed tick), before the
  /// frame that shows it is rendered: what follows the tool (its shadow) updates in that frame.
  void toolFrameShown();

 private:
  void fitCamera(const double direction_W[3], const double up_W[3], double zoom);
  /// Puts the segment actors in the scan's renderer or in segmentLayer() (with the tools) as
  /// through_scan_ says, and draws the layer only when it holds segments.
  void placeSegments();
  /// Takes the tools out of segmentLayer() (before their props go).
  void takeToolsOutOfLayer();

  VtkView* view_ = nullptr;
  std::unique_ptr<SceneActors> actors_;
  std::unique_ptr<ExpertGhost> ghost_;  // in actors_'s overlay layer: goes before it
  std::unique_ptr<SegmentSurfaces> segments_;
  bool sharp_motion_ = false;  // setSharpMotion()
  vtkSmartPointer<vtkRenderer> segment_layer_;
  std::vector<vtkSmartPointer<vtkActor>> layer_tools_;  // the tools also drawn in segment_layer_
  bool through_scan_ = false;
  Rgb surface_rgb_ = {237.0 / 255.0, 222.0 / 255.0, 189.0 / 255.0};  // ViewLook::surface's default
  vtkTextActor* alert_ = nullptr;  // owned by the renderer
  std::unique_ptr<OrientationMarker> marker_;
  vtkTextActor* welcome_ = nullptr;  // owned by the renderer while shown
  QTimer* settle_timer_ = nullptr;
  bool interacting_ = false;
  bool camera_dragging_ = false;
  std::uint64_t scene_frame_ = 0;  // the view's frame count when the props were built
  bool prime_pending_ = false;     // SceneActors::primeLaterProps() after the scene's first frame
  double frame_gap_ms_ = 0.0;      // between interactive frames, smoothed; see interactiveTargetMs()
  /// Folds the gap before the frame just rendered into frame_gap_ms_ (weight 0.3) when that
  /// frame was interactive and the gap shorter than the interactive period.
  void noteFrameGap();
  /// The interactive frame period [ms]: 1 / the interactor's desired update rate.
  double interactivePeriodMs() const;
  std::vector<Eigen::Vector3d> tool_vertices_T_m_;
  std::vector<Eigen::Vector3d> tool_corners_T_m_{Eigen::Vector3d::Zero()};  // bounding box of the vertices, T [m]
  haptics::Pose shown_X_WP_;
  haptics::Pose shown_X_WD_;
  int shown_contacts_ = -1;
  Eigen::Vector3d shown_force_W_N_ = Eigen::Vector3d::Zero();
};

}  // namespace vh::ui
