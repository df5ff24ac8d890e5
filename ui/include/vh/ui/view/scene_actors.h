#pragma once
/// @file
/// The VTK side of the main view (no Qt): the volume's isosurface (GPU ray casting; a surface
/// mesh for moving frames on a software renderer), the proxy and device tools, contact points,
/// the force arrow and the on-screen hint. The main window
/// edits the scene only through this class; it never touches the mapper directly.
///
/// Frames: everything is drawn in the world frame W [m]. The vtkImageData has spacing and origin
/// in metres but no direction; the volume prop's user matrix applies the direction D about the
/// origin o: p_W = o + D (p_image - o).

#include <array>
#include <cstddef>
#include <functional>
#include <limits>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include <Eigen/Core>

#include <vtkNew.h>
#include <vtkSmartPointer.h>

#include "vh/haptics/pose.h"
#include "vh/haptics/triangle_mesh.h"
#include "vh/ui/view/render_presets.h"
#include "vh/ui/view/tool_shadow.h"

class vtkActor;
class vtkCamera;
class vtkColorTransferFunction;
class vtkGPUVolumeRayCastMapper;
class vtkImageData;
class vtkPiecewiseFunction;
class vtkPlane;
class vtkPoints;
class vtkPolyData;
class vtkRenderer;
class vtkTextActor;
class vtkVolume;
class vtkVolumeProperty;

namespace vh::ui {

class DrillableVolumeMapper;  // src/view/drillable_volume_mapper.h
class IsosurfaceMesh;         // src/view/isosurface_mesh.h

/// What the moving frames of the isosurface mode draw (still frames are always the ray cast).
enum class MovingView {
  /// The surface mesh where the ray cast would have to cast rays more than 3 px apart (at 3
  /// voxels between samples) to keep to the frame time: a software renderer (Mesa's llvmpipe in
  /// a virtual desktop or an office PC), whose coarse ray cast is blocks of up to 8 px; the ray
  /// cast everywhere else (a GPU: unchanged).
  kAuto,
  kRayCast,      ///< Always the ray cast, however coarse.
  kSurfaceMesh,  ///< Always the surface mesh.
};

/// Inputs of the scene's props.
struct SceneActorsSpec {
  vtkSmartPointer<vtkImageData> image;                      ///< Scalars in data units, metres.
  Eigen::Matrix3d direction_W = Eigen::Matrix3d::Identity(); ///< Columns: image i, j, k axes in W.
  double isovalue = 0.0;                                     ///< Data units (HU for CT).
  haptics::TriangleMesh tool_mesh_T;                         ///< Tool display mesh in T [m].
  Eigen::Vector3d p_TCm_m = Eigen::Vector3d::Zero();         ///< Tool centre of mass in T [m].
  bool show_device = true;                                   ///< Draw the device tool.
  std::string hint;                                          ///< Text overlay (may be empty).
  bool hounsfield = false;  ///< Values are HU (CT): the composite presets apply as defined.
  /// A recording's ticks carry the scan's isovalue (the picture follows them); false when
  /// segments were felt: the ticks carry the segments' level, and the picture keeps `isovalue`.
  bool isovalue_from_records = true;
};

class SceneActors {
 public:
  /// Builds the props and adds them to `renderer`, which must already be in its render window:
  /// contacts and the force arrow go to an overlay renderer (layer 1, same camera) added to it.
  SceneActors(vtkRenderer* renderer, const SceneActorsSpec& spec);
  ~SceneActors();
  SceneActors(const SceneActors&) = delete;
  SceneActors& operator=(const SceneActors&) = delete;

  /// Drilling: the voxels at `indices` (linear, x fastest, of the scene's image) take `value`
  /// (data units) in a private copy of the image, made on the first call (the scene's image is
  /// never written); the next frame uploads only the box that holds them into the GPU's volume
  /// texture (glTexSubImage3D), not the whole volume, where the texture is one block of the
  /// image's own type (else the whole volume once per frame). Indices out of range are ignored.
  void removeVoxels(std::span<const std::uint64_t> indices, double value);
  /// What a removed voxel shows: the scene's image's lowest value [data units] (air), read once
  /// when the scene was set (the drilled copy's own range would be a pass over all its voxels,
  /// 30 ms for a 512 x 512 x 275 CT, at the first frame of each drilling).
  double removedValue() const noexcept { return range_[0]; }
  /// Makes the private copy removeVoxels() writes now (the burr started), so that its whole
  /// upload (a second on software GL for a 512 x 512 x 275 CT) is not a frame of the drilling.
  void prepareRemoval();
  /// Back to the scene's own image (drilling undone for the eyes: a rebuilt haptic thread).
  void restoreVolume();
  /// Soft tissue: the voxel box [lo, hi] (indices of the scene's image, inclusive) takes
  /// `values_F` (data units, x fastest, one per voxel of the box), and the voxels of the last box
  /// shown that this one does not cover go back to the scene's image (the tissue at rest there);
  /// an empty box (hi < lo) puts the whole last box back. Written into the private copy as
  /// removeVoxels() writes (the next frame uploads the union of both boxes only). A box outside
  /// the image or a size mismatch changes nothing and returns false.
  bool showVoxelBox(const std::array<int, 3>& lo, const std::array<int, 3>& hi, std::span<const float> values_F);
  /// Volume texture uploads so far: boxes uploaded alone, and whole-volume uploads the removal
  /// needed (a texture the partial path could not reach).
  std::uint64_t partialUploads() const noexcept;
  std::uint64_t fullUploads() const noexcept;
  /// The image the volume shows now: the drilled copy, else the scene's.
  vtkImageData* shownImage() const noexcept;
  /// Blocks of the volume's texture per axis, chosen at the first frame: 1 1 1 (one texture)
  /// unless the volume is longer than the GPU's 3-D texture limit on an axis, which then holds
  /// several blocks each within it (the whole volume is drawn, never a blank view).
  std::array<int, 3> textureBlocks() const noexcept;

  /// Isosurface value in data units.
  void setIsovalue(double isovalue);
  double isovalue() const;

  /// How the volume is drawn: the isosurface (the haptic surface, in the surface colour), a
  /// composite ray cast with `preset`'s transfer functions, or a MIP.
  void setRenderMode(RenderMode mode, VolumePreset preset = VolumePreset::kBone);
  RenderMode renderMode() const noexcept { return mode_; }
  VolumePreset preset() const noexcept { return preset_; }
  /// Colours, RGB in [0, 1]: the isosurface, the proxy tool (solid), the device tool (lines).
  void setSurfaceColour(double r, double g, double b);
  void setToolColour(double r, double g, double b);
  void setDeviceColour(double r, double g, double b);
  /// Replaces the tool's display mesh (in T [m]) of both tool actors; `p_TCm_m` its centre of
  /// mass sets the force arrow's scale.
  void setToolMesh(const haptics::TriangleMesh& mesh_T, const Eigen::Vector3d& p_TCm_m);
  /// Clips the volume (not the tools) with the plane through p_W_origin_m [m] with normal
  /// n_W; the half space the normal points into is kept. Visual only: the haptic surface stays
  /// whole.
  void setClipPlane(bool enabled, const Eigen::Vector3d& p_W_origin_m = Eigen::Vector3d::Zero(),
                    const Eigen::Vector3d& n_W = Eigen::Vector3d::UnitZ());
  bool clipping() const noexcept { return clipping_; }
  /// Text in the top left corner (empty: none).
  void setHint(const std::string& hint);
  /// The volume's world bounds in W [m] (xmin, xmax, ymin, ymax, zmin, zmax).
  void volumeBounds_W(double bounds[6]) const;

  void setProxyPose(const haptics::Pose& X_WP);
  void setDevicePose(const haptics::Pose& X_WD);
  void setDeviceVisible(bool visible);
  /// Contact points in W [m] (small spheres drawn over everything).
  void setContacts(std::span<const Eigen::Vector3d> p_W_m);
  /// Force on the user's hand [N], drawn over everything as an arrow from p_W_origin_m; its
  /// length is arrowReferenceLength_m() per 3 N (clamped to 0.15..2.5 times); hidden below 1 mN.
  void setForce(const Eigen::Vector3d& p_W_origin_m, const Eigen::Vector3d& force_W_N);
  /// The tool's shadow on the isosurface (castToolShadow(), cast along `direction_W`): its
  /// footprint as dark points and the drop line from the tool's nearest sample to its shadow,
  /// drawn in the scene (the tool hides what is under it). The points are lifted half a voxel
  /// back along the direction so that the ray-cast surface they lie on does not hide them.
  /// Nothing is drawn for an empty shadow or while the shadow is switched off.
  void setShadow(const ToolShadow& shadow, const Eigen::Vector3d& direction_W);
  void setShadowVisible(bool visible);
  bool shadowVisible() const noexcept { return shadow_on_; }
  /// Calls `render` with what appears only later drawn once: the contact points, the force
  /// arrow, the shadow's points and drop line (given a point each and shown) and the volume at
  /// the first interactive frames' sampling (the largest reduction, the nearest voxel); then
  /// puts every one of them back as it was. A GL driver compiles a prop's shaders the first time
  /// it draws it: without this, the first contact's frame paid for them (on llvmpipe at 720p,
  /// 47-52 ms against 33-38 for the frames after it).
  void primeLaterProps(const std::function<void()>& render);

  /// Rendering quality of the volume, chosen here on purpose (VTK's automatic adjustment of the
  /// sample distances is off: it splits a frame budget over all props and blurs thin bone).
  /// Still frames are full quality: a ray per pixel, sampled every half voxel. Interactive
  /// frames (camera drags, moving tools, drilling, slider drags) sample every voxel and cast
  /// fewer rays (image sample distance, adaptQuality()) so that they keep to a frame time.
  void setInteractive(bool interactive);
  bool interactive() const noexcept { return interactive_; }
  /// Interactive frames never coarser than `pixels` between rays (>= 1; infinity: as
  /// adaptQuality() finds, up to 8) nor sampled at the nearest voxel when capped: what a replay
  /// shows (fewer frames, none in blocks). Still frames are unchanged.
  void setInteractiveImageSampleCap_px(double pixels);
  /// Adapts the quality to the wall time of the frame just rendered [ms]. Interactive frames
  /// aim at `interactive_target_ms`: their work (one sample per voxel, one ray per pixel) is
  /// divided by a reduction, taken first from the rays (image sample distance up to 3 px), then
  /// from the samples along them (up to 3 voxels apart), then from the rays again (up to 8 px);
  /// a late frame sets the next one's at once, an early one relaxes it halfway. Once rays are
  /// about 4 px apart (a reduction over 16) interactive frames also sample the nearest voxel
  /// instead of trilinearly (back below a reduction of 4); still frames are always trilinear. A
  /// still frame sets the first interactive frame's guess, never below the reduction the last
  /// interactive frames of the same render mode settled on (scaled by the view's pixels then and
  /// now; frames that settled early at full quality keep the reduction that would have just met
  /// the target, below 1, so a larger view stays at full quality while its rays fit), and the
  /// first motion of a mode starts from the largest reduction and relaxes from there, unless the
  /// still frame itself met the interactive target (then at full quality): a frame's fixed cost
  /// (the full-size passes around the ray cast, 15 ms at 720p on llvmpipe) makes the still
  /// frame's guess too low, while a GPU need not show a coarse picture for the first frames of
  /// each mode. Still frames that take over 3 s (software GL, very large views) step down to
  /// voxel-spaced samples, then to 1.5 pixel image sampling, and back up when they get fast again.
  void adaptQuality(double last_frame_ms, double interactive_target_ms = 40.0);
  /// Back to the best still quality (half-voxel samples, every pixel).
  void resetQuality();
  /// What the isosurface mode's moving frames draw (default kAuto). The surface mesh is the
  /// felt isosurface of the shown image (drilled cavity and soft tissue included) triangulated by
  /// flying edges over a copy averaged in blocks of f^3 voxels (at most 1.2 million of them; f
  /// grows by one when the mesh's frames take over twice the interactive target, i.e. under
  /// about 16 frames/s), rebuilt when the isovalue or the image changes, at most every 120 ms
  /// while it keeps changing; it is made the first time a moving frame needs it (a scene on a GPU
  /// never makes one). Once a motion shows the mesh, its frames leave the ray cast's sampling as
  /// it was (they do not measure it): the next motion decides again. Frames capped by
  /// setInteractiveImageSampleCap_px() (a replay) are always the ray cast.
  void setMovingView(MovingView view);
  MovingView movingView() const noexcept { return moving_view_; }
  /// Whether the frame drawn now shows the surface mesh (the ray-cast volume hidden).
  bool surfaceMeshShown() const noexcept { return mesh_shown_; }
  /// The surface mesh's triangles and block edge f [voxels]; 0 and 0 before it was made.
  std::size_t surfaceMeshTriangles() const noexcept;
  int surfaceMeshFactor() const noexcept;
  /// The mesh's actor (nullptr before it was made).
  vtkActor* surfaceMeshActor() const noexcept;

  /// Ray sample distance [m] and image sample distance [px] now in use.
  double sampleDistance_m() const;
  double imageSampleDistance_px() const;
  /// Whether the volume is sampled at the nearest voxel now (VTK_NEAREST_INTERPOLATION) rather
  /// than trilinearly.
  bool nearestSampling() const;
  /// Whether the ray cast is shaded now. The composite's moving frames are cast unshaded (cheaper
  /// samples, so rays closer together) from the first of its motions that needed rays more than
  /// 3 px apart (a software renderer) on; still frames, replays' capped frames and a GPU shade.
  bool volumeShaded() const;

  /// Length [m] of the arrow drawn for 3 N: half the tool's bounding-box diagonal.
  double arrowReferenceLength_m() const noexcept { return arrow_reference_m_; }
  /// Length [m] of the arrow drawn for a force of `magnitude_N` [N] (none below 1 mN): the
  /// reference length scaled by magnitude / 3 N, within 0.15 to 2.5 of it.
  double forceArrowLength_m(double magnitude_N) const noexcept;

  vtkVolume* volume() const noexcept;
  vtkGPUVolumeRayCastMapper* volumeMapper() const noexcept;
  vtkActor* proxyActor() const noexcept;
  /// The proxy tool's colour by its nearest critical segment: 0 its own colour (clear:
  /// setToolColour()'s, steel by default), 1 amber (within the warning distance), 2 red (within
  /// the alarm distance).
  void setProximityLevel(int level);
  vtkActor* deviceActor() const noexcept;
  vtkActor* contactActor() const noexcept;
  vtkActor* forceActor() const noexcept;
  vtkActor* shadowActor() const noexcept;
  vtkActor* gapLineActor() const noexcept;
  vtkRenderer* overlayRenderer() const noexcept;
  vtkTextActor* hintActor() const noexcept;

 private:
  /// The GPU ray-cast volume (isosurface at spec.isovalue, quality policy, image-to-W matrix).
  void buildVolume(const SceneActorsSpec& spec);
  /// The proxy (solid) and device (wireframe) tools sharing the display mesh.
  void buildTools(const SceneActorsSpec& spec);
  /// The overlay layer (contacts, force arrow) and the hint text.
  void buildOverlay(const SceneActorsSpec& spec);

  vtkRenderer* renderer_;  // not owned
  vtkNew<vtkRenderer> overlay_;
  vtkSmartPointer<vtkGPUVolumeRayCastMapper> volume_mapper_;  // a DrillableVolumeMapper
  DrillableVolumeMapper* drillable_ = nullptr;                 // the same object
  vtkSmartPointer<vtkImageData> image_;          // the scene's image (never written)
  vtkSmartPointer<vtkImageData> drilled_image_;  // a private copy once voxels were removed
  std::array<int, 3> box_lo_{0, 0, 0}, box_hi_{-1, -1, -1};  // showVoxelBox()'s last box
  vtkNew<vtkVolumeProperty> volume_property_;
  vtkNew<vtkColorTransferFunction> colour_;
  vtkNew<vtkPiecewiseFunction> opacity_;
  vtkNew<vtkVolume> volume_;
  vtkNew<vtkActor> proxy_actor_;
  std::array<double, 3> tool_rgb_{0.0, 0.0, 0.0};  // the tool's own colour (setToolColour())
  int proximity_level_ = 0;                        // setProximityLevel()
  vtkNew<vtkActor> device_actor_;
  vtkNew<vtkPoints> contact_points_;
  vtkNew<vtkPolyData> contact_poly_;
  vtkNew<vtkActor> contact_actor_;
  vtkNew<vtkActor> force_actor_;
  vtkNew<vtkPoints> shadow_points_;
  vtkNew<vtkPolyData> shadow_poly_;
  vtkNew<vtkActor> shadow_actor_;
  vtkNew<vtkPoints> gap_points_;
  vtkNew<vtkPolyData> gap_poly_;
  vtkNew<vtkActor> gap_actor_;
  bool shadow_on_ = true;
  bool shadow_shown_ = false;  // the last setShadow() had a footprint
  bool gap_shown_ = false;     // ... and a drop line
  vtkNew<vtkTextActor> hint_actor_;
  vtkNew<vtkPlane> clip_plane_;
  double arrow_reference_m_ = 0.01;
  void applyQuality();
  void applyLook();
  /// The ray cast's shading: the look's, less the composite's unshaded motion (volumeShaded()).
  void applyShade();
  /// The volume sampled as a mode's first motion draws it: the largest reduction, the nearest voxel.
  void sampleAsFirstMotion();
  /// Shows the surface mesh or the ray-cast volume, as the moving view and the motion ask.
  void applyMovingView();
  /// Before each render: the shown mesh brought up to date (throttled).
  void beforeRender();
  std::unique_ptr<IsosurfaceMesh> mesh_;  // made on first need
  bool look_shaded_ = true;                // the look's shading (applyLook())
  bool composite_unshaded_motion_ = false;  // latched: see volumeShaded()
  bool unshadedMotion() const noexcept;
  MovingView moving_view_ = MovingView::kAuto;
  bool mesh_shown_ = false;
  int late_mesh_frames_ = 0;
  unsigned long render_observer_ = 0;
  RenderMode mode_ = RenderMode::kIsosurface;
  VolumePreset preset_ = VolumePreset::kBone;
  bool hounsfield_ = false;
  bool clipping_ = false;
  double range_[2] = {0.0, 1.0};
  double surface_rgb_[3] = {0.93, 0.87, 0.74};
  double min_spacing_m_ = 1e-3;
  int still_level_ = 0;  // 0 best; see adaptQuality()
  double interactive_reduction_ = 1.0;  // interactive work divided by this; see adaptQuality()
  /// Where the last interactive frames of each render mode settled (0: none yet), and the
  /// view's size in pixels then: a motion resumes from it, scaled to the view's size now.
  std::array<double, 3> settled_reduction_{0.0, 0.0, 0.0};
  std::array<double, 3> settled_pixels_{0.0, 0.0, 0.0};
  double viewPixels() const;
  /// The reduction a motion resumes from after a still frame that took `still_ratio` times the
  /// interactive target (may be below 1: the caller clamps).
  double resumedReduction(double still_ratio) const;
  bool nearest_when_interactive_ = false;    // interactive frames sample the nearest voxel
  bool interactive_ = false;
  double interactive_cap_px_ = std::numeric_limits<double>::infinity();  // setInteractiveImageSampleCap_px()
  static constexpr double kReferenceForce_N = 3.0;
};

/// One picture of the tools: what a live haptic snapshot and a recorded tick both become, so
/// the live view and the replay (and its exports) draw the same thing the same way.
struct ToolFrame {
  haptics::Pose X_WP;                                   ///< Proxy pose in W [m].
  haptics::Pose X_WD;                                   ///< Device pose in W [m].
  Eigen::Vector3d force_W_N = Eigen::Vector3d::Zero();  ///< Force on the hand in W [N].
  /// Isovalue (data units); NaN: leave the shown one.
  double isovalue = std::numeric_limits<double>::quiet_NaN();
  /// Contact points in W [m] (recordings keep none: empty).
  std::span<const Eigen::Vector3d> contacts_W_m;
};

/// `camera` as ViewCamera (position, focal point, view up, view angle, projection; W [m]), for a
/// viewport `viewport_width_px` x `viewport_height_px` pixels.
ViewCamera viewCameraOf(vtkCamera* camera, int viewport_height_px = 1, int viewport_width_px = 1);

/// Where the force arrow starts: the proxy tool's extreme point against the force (the vertex of
/// `tool_vertices_T_m` (tool frame T, metres) with the least F.p in W: where the surface pushes
/// when one side of the tool touches, e.g. a probe's tip pushed up); the proxy's origin when
/// there is no force (below 1 mN) or no vertex. The one rule for live and replayed frames.
Eigen::Vector3d forceOrigin_W(const haptics::Pose& X_WP, const Eigen::Vector3d& force_W_N,
                              const std::vector<Eigen::Vector3d>& tool_vertices_T_m);

/// Shows `frame` on `actors`: proxy and device poses, the contact points, the force arrow from
/// forceOrigin_W(), and the isovalue when finite.
void showToolFrame(SceneActors& actors, const ToolFrame& frame, const std::vector<Eigen::Vector3d>& tool_vertices_T_m);

}  // namespace vh::ui
