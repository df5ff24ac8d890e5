#pragma once
/// @file
/// Pictures and videos of a session recording: the recorded scene is rendered off
/// screen (its own vtkRenderWindow with OffScreenRenderingOn(), no Qt; needs an X display with
/// OpenGL, e.g. under xvfb-run) with the proxy, device, force arrow and isovalue of the record
/// shown at each frame's time, read back through vtkWindowToImageFilter and written with
/// vtkOggTheoraWriter (Ogg/Theora video) or vtkPNGWriter. A drilled recording's video carries
/// the burr's sound as an Ogg Vorbis track (runtime::recordingSound(), audio::addVorbisTrack()).
///
/// Frame times: frame k of a video shows the record at t = start_s + k / fps (the last record
/// with time_s <= t; recordIndexAt()), up to end_s.

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <iosfwd>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <vtkSmartPointer.h>

#include "vh/haptics/pose.h"
#include "vh/runtime/recording.h"
#include "vh/runtime/recording_sound.h"
#include "vh/runtime/replay.h"
#include "vh/runtime/scene.h"
#include "vh/ui/view/view_look.h"
#include "vh/ui/view/render_presets.h"
#include "vh/ui/view/scene_actors.h"
#include "vh/ui/view/segment_surfaces.h"
#include "vh/ui/view/scene_frames.h"
#include "vh/ui/view/tool_shadow.h"
#include "vh/ui/replay/recorded_camera.h"
#include "vh/ui/replay/replay_guide.h"
#include "vh/ui/view/expert_ghost.h"

class vtkCamera;
class vtkImageData;
class vtkRenderWindow;
class vtkRenderer;
class vtkTextActor;
class vtkWindowToImageFilter;

namespace vh::ui {

/// Index of the record shown at recording time `t_s` [s]: the last record with time_s <= t_s
/// (0 before the first; the last one after the end). @throws std::invalid_argument when empty.
std::size_t recordIndexAt(const std::vector<runtime::TickRecord>& records, double t_s);
/// A cavity growing over a recording's records, on one grid: its voxels (linear indices, x
/// fastest) in removal order, first the cavity the recording started from (`at_start` of them),
/// then the voxels its replay removed, and per record how many are removed by its end.
struct CavityOrder {
  std::vector<std::uint64_t> voxels;
  std::uint64_t at_start = 0;
  /// Per record: how many of `voxels` are removed by the end of it (empty: at_start at every
  /// record).
  std::vector<std::uint64_t> after_record;
  /// How many of `voxels` are removed at record `index` (the last count past the end).
  std::uint64_t removedAt(std::size_t index) const noexcept {
    if (after_record.empty()) return std::min<std::uint64_t>(at_start, voxels.size());
    return std::min<std::uint64_t>(after_record[std::min(index, after_record.size() - 1)], voxels.size());
  }
};

/// The cavity of a drilled recording over its records: what a view removes to show the cavity
/// as it was at any record, and what the tool's shadow falls on then.
struct DrillingTimeline {
  /// On the picture's grid (the scan as SceneActors shows it).
  CavityOrder picture;
  /// On the felt field's grid (the field the shadow falls on).
  CavityOrder felt;
  /// The replay was cancelled (runtime::ReplayProgress::cancel): only the start cavity is in.
  bool cancelled = false;
  /// The burr's sound over the records, heard in the same replay (runtime::RecordingSound: one
  /// state per record); no states when the burr never ran or the replay was cancelled.
  runtime::RecordingSound sound;
  /// Where and why the replay parted from the recording (runtime::replayDifference()); "" when
  /// it matched every record (or was not needed).
  std::string replay_difference;
};

/// The cavity the drill of `scene` starts from (drilled before the recording started), on the
/// picture's grid; no removals after it yet. Empty for a scene without a drill.
DrillingTimeline drillingAtStart(const runtime::LoadedScene& scene);

/// Adds to `timeline` (drillingAtStart(scene)) what `recording` removed, when a record has the
/// drill on: a replay of the recording removes the same voxels (runtime::replayRecording():
/// seconds on a big CT), mapped onto the picture's grid (pictureIndices()), and gives the burr's
/// sound (DrillingTimeline::sound); a cancelled replay sets `cancelled` and adds nothing. Any thread (no VTK); not the servo thread.
/// @throws as runtime::replayRecording().
void addReplayedRemovals(DrillingTimeline& timeline, const runtime::LoadedScene& scene,
                         const runtime::Recording& recording, const runtime::ReplayProgress& progress = {});

/// The drilling of `recording` on `scene` (the scene it was recorded on, or loaded from its
/// metadata): drillingAtStart() and addReplayedRemovals(). @throws as runtime::replayRecording().
DrillingTimeline drillingTimeline(const runtime::LoadedScene& scene, const runtime::Recording& recording,
                                  const runtime::ReplayProgress& progress = {});

/// Carves `carved` so that it holds `field` with the first felt.removedAt(record_index) of
/// felt.voxels removed (`felt`: DrillingTimeline::felt, on `field`'s grid): on from what it
/// holds, or from `field` again for an earlier record or another field (the tool's shadow at that
/// record, castToolShadow()).
void carveToRecord(CarvedRegion& carved, const std::shared_ptr<const haptics::ScalarVolume>& field,
                   const CavityOrder& felt, std::size_t record_index);

/// Carves `actors`' picture so that the first `target` of picture.voxels (DrillingTimeline::
/// picture) are removed, `shown` being removed now (updated): fewer than shown restores the scan
/// first. A removed voxel takes the scan's lowest value, as in the live view (DrillController).
void showDrilledVoxels(SceneActors& actors, const CavityOrder& picture, std::uint64_t target,
                       std::uint64_t& shown);

/// An off-screen render window with the scene's props, for frames of a recording.
///
/// In isosurface mode the volume is ray cast only when what it shows changes (the camera, the
/// isovalue, the drilled cavity), not at every frame: its picture and its depth (the ray
/// caster's depth image, vtkGPUVolumeRayCastMapper::SetRenderToImage()) are kept, and each
/// frame draws the tools, the shadow and the overlays (cheap geometry) and lays them over the
/// kept picture wherever they are nearer than the surface: the same picture as a full render
/// (where a tool meets the surface the ray caster also stops at the nearer of the two), in a
/// few tens of milliseconds instead of seconds on software OpenGL. While the cavity grows under
/// the burr, the volume is cast again only over the pixels whose rays can meet the removed
/// voxels; while anything else it shows changes at every frame (the isovalue swept), each frame
/// is one full render instead. Composite and MIP modes, whose volume is not an opaque surface,
/// are ray cast at every frame.
class RecordingFrameRenderer {
 public:
  /// @param width, height frame size [px] (at least 16; rounded up to even for video).
  /// @param look colours, rendering mode and preset (the defaults: the app's defaults).
  /// @throws std::invalid_argument for a spec without image or a bad size.
  RecordingFrameRenderer(const SceneActorsSpec& spec, int width, int height,
                         const ViewLook& look = ViewLook{});
  ~RecordingFrameRenderer();
  RecordingFrameRenderer(const RecordingFrameRenderer&) = delete;
  RecordingFrameRenderer& operator=(const RecordingFrameRenderer&) = delete;

  /// The main window's default view: from anterior, 30 degrees to the patient's right and 25
  /// degrees up, fitted to the props (the volume and the tools where the last show() put them).
  void resetCamera();
  /// Uses a copy of `camera` (e.g. the main view's) for the next frames.
  void copyCamera(vtkCamera* camera);
  /// From the next show() on, each frame is seen from the camera the user had at its record's
  /// time (the latest of `cameras` at or before it: recordedCameras() of the recording); before
  /// the first, or with none, the camera set by resetCamera() / copyCamera() stays.
  void setRecordedCameras(std::vector<RecordedCamera> cameras);
  /// The view camera now (as viewCameraOf() reads the frame's VTK camera).
  ViewCamera camera() const;
  /// Shows `record` (see showRecord()).
  void show(const runtime::TickRecord& record);
  /// Renders a frame and returns its pixels (RGB, vtkWindowToImageFilter; bottom row first):
  /// draw() then readBack().
  vtkImageData* render();
  /// Draws a frame in the window; with `wait`, returns once the drawing is done (for timing it).
  void draw(bool wait = false);
  /// The pixels of the frame last drawn (RGB, bottom row first).
  vtkImageData* readBack();
  /// Whether frames reuse the kept volume picture (see the class comment; on by default). Off:
  /// every frame is one full render, as the main view draws it.
  void setReuseVolume(bool reuse);
  /// Times the volume was ray cast for frames so far (a whole kept picture costs two: colour and
  /// depth; a full render, and a cavity's update of the kept picture (colour only), one).
  std::uint64_t volumeRenders() const noexcept { return volume_renders_; }
  /// Pixels the volume was ray cast for so far by the ray caster (a full render: the frame's; a
  /// whole kept picture twice, colour and depth; a cavity's update the pixels it covers): what
  /// the ray casting cost, on any machine.
  std::uint64_t volumePixelsCast() const noexcept { return volume_pixels_cast_; }
  /// The filter render() reads the window through (input of the writers).
  vtkWindowToImageFilter* imageFilter() const noexcept;

  int width() const noexcept { return width_; }
  int height() const noexcept { return height_; }
  SceneActors& actors() noexcept { return *actors_; }
  vtkRenderer* renderer() const noexcept;
  /// The isovalue the picture shows now (data units): the spec's, then each shown record's
  /// unless SceneActorsSpec::isovalue_from_records is false.
  double isovalue() const;
  vtkRenderWindow* renderWindow() const noexcept;

  /// From the next show() on, draws over each frame what explains it (null: nothing, the
  /// default): top left the recording time [s], |F| [N] and |torque| [N*m] of the record shown
  /// and the label of a marker passed within the last kOverlayHold_s; top centre, in red, a
  /// critical segment drilled (a "critical_removed" event) within as long. `recording` is the one
  /// whose records show() is given; it must outlive its use here.
  void setOverlay(const runtime::Recording* recording);
  /// From now on, frames show the drilled cavity of `timeline` as it was at the record given to
  /// showCavityAt() (the picture's copy of the scan is carved; going back to an earlier record
  /// restores the scan first). The writers below call showCavityAt() for every frame.
  void setDrilling(DrillingTimeline timeline);
  /// Carves the picture to the cavity at record `record_index` (nothing without setDrilling()).
  void showCavityAt(std::size_t record_index);
  /// The timeline of setDrilling() (empty before), its sound among it.
  const DrillingTimeline& drilling() const noexcept { return drilling_; }
  /// From the next show() on, frames show the tool's shadow on `field` (the felt field, in W
  /// [m]) cast from `samples_T_m` (toolShadowSamples()) along the light of the frame's camera
  /// (shadowLightDirection_W()), at each record's isovalue (the felt one) or `isovalue` when a
  /// record has none, as the main view shows it live; drawn unless the look's tool_shadow is off.
  /// A null field: no shadow (the default). With setDrilling(), the shadow falls into the cavity
  /// as it was at the frame's record (showCavityAt() carves it).
  void setShadow(std::shared_ptr<const haptics::ScalarVolume> field, double isovalue,
                 std::vector<Eigen::Vector3d> samples_T_m);
  /// From now on, frames show the shown segments of `set` as the main view draws them
  /// (SegmentSurfaces: each in its colour, or a distinct one where it is too close to
  /// `surface_rgb`, the scan surface's), the segment a record's contacts touch emphasised; null:
  /// none (the default).
  void setSegments(std::shared_ptr<const runtime::SegmentSet> set, const Rgb& surface_rgb);
  /// From the next show() on, frames show the expert's ghost of a guided recording as its replay
  /// shows it (ExpertGhost in the overlay layer: the expert's tool at the nearest point of its
  /// path to the record's device, and the path, while `guide` is on at the record's time); a
  /// guide without an expert (not guided, or the expert's recording not found): none.
  void setGuide(ReplayGuide guide);
  /// The ghost drawn (null without an expert to show).
  const ExpertGhost* ghost() const noexcept { return ghost_.get(); }
  /// The segment surfaces drawn (null without setSegments()).
  const SegmentSurfaces* segmentSurfaces() const noexcept { return segments_.get(); }
  /// Voxels of the picture removed now (the cavity shown).
  std::uint64_t cavityVoxelsShown() const noexcept { return cavity_shown_; }
  /// The shadow's field carved to the cavity shown (empty without setShadow()).
  const CarvedRegion& shadowCarved() const noexcept { return shadow_carved_; }
  /// The overlay's lines and its alert as last shown ("" when none).
  std::string overlayText() const;
  std::string overlayAlert() const;
  /// How long a marker's label or a critical alert stays on the frames after its event [s].
  static constexpr double kOverlayHold_s = 2.0;

 private:
  void showOverlay(const runtime::TickRecord& record);

  vtkSmartPointer<vtkRenderWindow> window_;
  vtkSmartPointer<vtkRenderer> renderer_;
  vtkSmartPointer<vtkWindowToImageFilter> grabber_;
  std::unique_ptr<SceneActors> actors_;
  std::shared_ptr<const runtime::SegmentSet> segment_set_;  ///< setSegments()
  std::unique_ptr<SegmentSurfaces> segments_;               ///< setSegments(); null: none
  ReplayGuide guide_;                                       ///< setGuide()
  std::unique_ptr<ExpertGhost> ghost_;                      ///< setGuide() with an expert; null: none
  std::vector<Eigen::Vector3d> tool_vertices_T_m_;
  bool isovalue_from_records_ = true;  ///< SceneActorsSpec::isovalue_from_records.
  const runtime::Recording* overlay_ = nullptr;  ///< setOverlay(); not owned.
  DrillingTimeline drilling_;                    ///< setDrilling().
  std::uint64_t cavity_shown_ = 0;               ///< Of drilling_.picture.voxels, removed in the picture.
  std::shared_ptr<const haptics::ScalarVolume> shadow_field_;  ///< setShadow(); null: none.
  CarvedRegion shadow_carved_;  ///< shadow_field_ carved to the cavity shown (showCavityAt()).
  double shadow_isovalue_ = 0.0;
  std::vector<Eigen::Vector3d> shadow_samples_T_m_;
  vtkSmartPointer<vtkTextActor> overlay_text_, overlay_alert_;
  int width_;
  int height_;

  // The kept volume picture (see the class comment).
  /// Draws the frame as a full render of every prop (the volume ray cast).
  void drawFull();
  /// Draws the frame over the kept volume picture, keeping it first when out of date.
  void drawOverKeptVolume();
  /// A rectangle of the frame's pixels (bottom left origin, as OpenGL's).
  struct PixelRect {
    int x = 0, y = 0, width = 0, height = 0;
  };
  /// Ray casts the volume alone: its picture (with the background) and its depth, into the kept
  /// picture; with `rect`, within those pixels only (the rest of the kept picture stays).
  void keepVolume(const std::optional<PixelRect>& rect = std::nullopt);
  /// The pixels whose rays can meet the voxels of drilling_.picture.voxels [from, to) or their
  /// neighbours (the box that holds them, grown by 2 voxels, projected, grown by 2 pixels); an
  /// empty rectangle when it lies off the frame; none when nothing is removed or a corner lies
  /// behind the eye (then the whole frame).
  std::optional<PixelRect> cavityRect(std::uint64_t from, std::uint64_t to) const;
  /// The kept depth within `r`: along each pixel's ray (through its centre, near to far plane),
  /// the first crossing of the isovalue in the picture's scan (trilinear, marched a quarter voxel
  /// at a time and bisected), as a distance along the view axis; +inf where the ray meets none.
  void surfaceEyeDepthIn(const PixelRect& r);
  bool reuse_volume_ = true;
  std::uint64_t volume_renders_ = 0;
  std::uint64_t volume_pixels_cast_ = 0;
  std::uint64_t camera_generation_ = 0;  ///< Counts resetCamera() / copyCamera() / recorded cameras applied.
  std::vector<RecordedCamera> recorded_cameras_;  ///< setRecordedCameras()
  std::size_t recorded_camera_shown_ = 0;         ///< 1 + the index applied last (0: none yet)
  struct KeptKey {
    double isovalue = 0.0;
    std::uint64_t cavity = 0;
    std::uint64_t camera = 0;
    bool valid = false;
  } kept_, last_frame_;  ///< What the kept picture shows; what the last frame showed.
  bool changed_last_frame_ = false;  ///< The last frame showed something else than the one before.
  std::vector<unsigned char> kept_rgb_;  ///< The volume's picture, RGB, bottom row first.
  std::vector<float> kept_eye_depth_;    ///< Distance along the view axis of the surface per pixel [world units]; +inf: none.
  vtkSmartPointer<vtkRenderer> backdrop_;  ///< Layer 0 in the second pass: the composite as background, the text.
  vtkSmartPointer<vtkImageData> composite_;  ///< The tools laid over the kept picture (backdrop_'s texture).
};

/// Called after each video frame: (frames written, frames in all); return false to cancel.
using FrameProgress = std::function<bool(int done, int total)>;

/// Where one video frame's wall time went [ms] (`volume-haptics bench video`).
struct VideoFrameTimes {
  double show_ms = 0.0;      ///< The record's poses, cavity, shadow and overlay set on the props.
  double render_ms = 0.0;    ///< The window drawn, to completion (vtkRenderWindow::WaitForCompletion()).
  double readback_ms = 0.0;  ///< Its pixels read back (vtkWindowToImageFilter).
  double encode_ms = 0.0;    ///< The frame encoded and written (vtkOggTheoraWriter::Write()).
};

/// Writes an Ogg/Theora video of `recording` from `start_s` to `end_s` (negative: its end) at
/// `fps` frames per second [1, 120], one rendered frame per frame time. With `sound` (its states
/// those of `recording`'s records; null or no states: none), the file also holds the sound as an
/// Ogg Vorbis stream (48 kHz mono), as long as the frames written (frames / fps) from the first
/// frame's time, the video's pages and its interleaved by time (audio::addVorbisTrack()).
/// @return the frames written (fewer when cancelled; the file then holds those).
/// @throws std::invalid_argument for an empty recording or a bad fps / time range;
///         std::runtime_error naming the file when it cannot be written.
/// With `times` not null, each frame written appends its VideoFrameTimes there (the window is
/// then waited for after each render, so that drawing and reading back are timed apart).
int writeRecordingVideo(RecordingFrameRenderer& frames, const runtime::Recording& recording,
                        const std::filesystem::path& path, double fps, double start_s = 0.0,
                        double end_s = -1.0, const FrameProgress& progress = {},
                        std::vector<VideoFrameTimes>* times = nullptr, const runtime::RecordingSound* sound = nullptr);

/// The sound a video of the frames of `frames` carries: its drilling timeline's (null when that
/// has none: no drill, the burr never ran, or its replay was cancelled or is not done).
const runtime::RecordingSound* videoSoundOf(const RecordingFrameRenderer& frames) noexcept;

/// Writes a PNG of the record at `t_s` [s]. @throws std::invalid_argument for an empty
/// recording; std::runtime_error naming the file when it cannot be written.
void writeRecordingPng(RecordingFrameRenderer& frames, const runtime::Recording& recording, double t_s,
                       const std::filesystem::path& path);

/// What `volume-haptics export` renders besides CSV / JSON.
struct MediaExportOptions {
  std::filesystem::path video;  ///< Ogg/Theora video (.ogv) to write; empty: none.
  std::filesystem::path png;    ///< PNG to write; empty: none.
  double png_time_s = 0.0;      ///< Recording time of the PNG [s] (clamped to the recording).
  double fps = 30.0;            ///< Video frame rate [frames/s], 1..120.
  int width = 640;              ///< Frame width [px].
  int height = 480;             ///< Frame height [px].
  double start_s = 0.0;         ///< Video start [s].
  double end_s = -1.0;          ///< Video end [s]; negative: the recording's end.
  /// Draw the time, |F|, |torque|, markers and critical alerts over the frames
  /// (RecordingFrameRenderer::setOverlay()).
  bool overlay = true;
  /// Draw the tool's shadow on the surface, as the main view does (RecordingFrameRenderer::setShadow()).
  bool shadow = true;
  /// Give the video the burr's sound (an Ogg Vorbis track; none when the burr never ran).
  bool sound = true;
  RenderMode mode = RenderMode::kIsosurface;  ///< How the volume is drawn.
  VolumePreset preset = VolumePreset::kBone;  ///< Composite preset.
};

/// The frames of `recording` as `volume-haptics export` renders them: `scene` (the recording's,
/// runtime::loadScene(runtime::sceneFromSessionMetadata()), without its device; it must outlive
/// the renderer) in the look, size, overlay and shadow of `options`; a drilled scene's cavity
/// replayed (messages on `log` when not null); the camera fitted to the first record, then, where
/// the recording holds the window's camera ("camera" events: recordedCameras()), the camera the
/// user had at each shown record's time; for a guided recording, the expert's ghost (ReplayGuide
/// of `recording_file`, the path the recording was read from: the expert is looked for at its
/// recorded path, then beside it; a notice on `log` when it is not found).
/// @throws as RecordingFrameRenderer and drillingTimeline().
std::unique_ptr<RecordingFrameRenderer> exportFrameRenderer(const runtime::LoadedScene& scene,
                                                            const runtime::Recording& recording,
                                                            const MediaExportOptions& options,
                                                            std::ostream* log = nullptr,
                                                            const std::filesystem::path& recording_file = {});

/// Command line export: reads `recording` (warnings to stderr), reloads its scene
/// (runtime::sceneFromSessionMetadata(), runtime::loadScene()), renders off screen (no Qt
/// application; needs an X display with OpenGL, e.g. xvfb-run) and writes the video and / or
/// PNG, printing what was written. `argc` / `argv` are accepted for symmetry with
/// runApplication() and not used.
/// @return 0 on success; 1 with a message on stderr naming the file and problem (unreadable
///         recording, missing dataset, unwritable output).
int exportRecordingMedia(int argc, char** argv, const std::filesystem::path& recording,
                         const MediaExportOptions& options);

}  // namespace vh::ui
