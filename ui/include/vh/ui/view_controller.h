#pragma once
/// @file
/// The scene view's controller: shows the Session in the SceneView (its scene, isovalue, tool
/// and device as they change, and the haptic thread's latest snapshot ~30 times a second while
/// the threads run), and applies the Display panel's choices (render mode, preset, clipping,
/// marker, device tool, tool shadow, colours) to the view and the preferences. It casts the
/// tool's shadow (castToolShadow()) on the session's felt field whenever the proxy, the camera's
/// light, the isovalue or the tool changed.
///
/// Data flows one way: Session -> this -> SceneView; DisplayPanel -> this -> Preferences and
/// SceneView. Threads: GUI thread only; the haptic thread is read through
/// Session::latestSnapshot(), which never blocks.

#include <QObject>
#include <QString>

#include "vh/runtime/haptic_thread.h"
#include "vh/runtime/session.h"
#include "vh/ui/preferences.h"
#include "vh/ui/view/render_presets.h"
#include "vh/ui/view/scene_view.h"
#include "vh/ui/view/tool_shadow.h"

class QColor;
class QMenu;
class QTimer;
class QWidget;


namespace vh::ui {

class DisplayPanel;

/// The period [ms] at which the view takes the haptic threads' latest snapshot while they run:
/// one per refresh of the screen (QScreen::refreshRate()), rounded down so that no refresh goes
/// without a new pose; 60 Hz where the screen reports no rate (0, NaN), and between 240 Hz
/// (4 ms) and 30 Hz (33 ms). A frame that takes longer than the period is simply the next one:
/// requests in between are coalesced into one paint (VtkView::requestRender()).
int displayPeriodMsFor(double screen_refresh_Hz) noexcept;

class ViewController : public QObject {
  Q_OBJECT

 public:
  /// Observes `session` from now on. Register it before other observers that draw into `view`
  /// (the segment surfaces): a new scene clears the view first. All references outlive this.
  ViewController(runtime::Session& session, SceneView& view, DisplayPanel& panel, Preferences& prefs,
                 QObject* parent = nullptr);
  ~ViewController() override;

  /// Reads the session's latest snapshot now and shows it; snapshotShown() follows.
  /// @return true when something visible changed.
  bool refresh(bool update_status_now = false);
  /// The last snapshot read; null before the first of this scene, tool or device.
  const runtime::HapticSnapshot* snapshot() const noexcept { return have_snapshot_ ? &snapshot_ : nullptr; }
  /// The last snapshot read (default-constructed before the first of this scene).
  const runtime::HapticSnapshot& lastSnapshot() const noexcept { return snapshot_; }
  /// The period [ms] the snapshot is read at while the haptic threads run: displayPeriodMsFor()
  /// of the view's screen, taken when they start.
  int displayPeriodMs() const noexcept;

  /// The rendering mode and preset of the scan shown. Chosen while no scan is shown (the
  /// preferences at start, `--render-mode`), they are also what every scan opens with: a MIP
  /// chosen for one scan does not carry over to the next file or to a replay.
  void setRenderMode(RenderMode mode);
  void setPreset(VolumePreset preset);
  void setClipping(bool enabled, ClipAxis axis = ClipAxis::kX, double fraction = 0.5, bool flip = false);
  void setOrientationMarkerVisible(bool visible);
  void setDeviceToolVisible(bool visible);
  /// The tool's shadow on the surface (a depth cue) on or off.
  void setToolShadowVisible(bool visible);
  /// Casts the tool's shadow again if the proxy pose shown, the camera's light, the isovalue,
  /// the field or the tool changed since the last cast (at most 128 segment walks).
  /// @return true when it cast.
  bool updateShadow();
  /// The shadow falls on the felt field carved by `carved` (DrillController::carved(); not owned,
  /// it outlives this; null: the field as loaded) and is cast again when it changes.
  void setCarvedRegion(const CarvedRegion* carved) noexcept { carved_ = carved; }
  /// Samples of the tool the shadow is cast from (shadowSamples() of its point shell).
  const std::vector<Eigen::Vector3d>& shadowSamples_T_m() const noexcept { return shadow_samples_T_m_; }
  /// The expert's ghost (SceneView::showGhost()) while the haptic thread guides along an
  /// expert's path (HapticThread::guidance()): at ExpertPath::poseAt() of the last snapshot's
  /// nearest point of the path, or of the path's nearest point to the device shown before the
  /// coupling thread found one; hidden without guidance. Called with every snapshot and when
  /// guidance starts or stops.
  void updateGhost();
  /// Whether updateGhost() drives the view's ghost (true, the default); false while a replay
  /// shows the ghost of its own recording (ReplayController). Back on, the live guidance's
  /// ghost is shown again (or none).
  void setLiveGhost(bool on);
  /// The tool's bounding sphere in view, at the proxy's latest pose.
  void focusOnTool();
  /// The preferences' colours on the view.
  void applyColours();
  /// Adds View > Colours (a colour dialog per colour, parented to `dialog_parent`; reset).
  void addColoursMenu(QMenu* view_menu, QWidget* dialog_parent);
  /// Adds View > Stereo: Off, Side by Side, Anaglyph (red / cyan glasses) and Quad Buffer (shutter
  /// glasses; enabled only where the display's GL context is stereo capable).
  void addStereoMenu(QMenu* view_menu);

  /// How the two eyes' pictures are shown (VTK's stereo rendering of the same camera and props,
  /// so what is seen stays in register with what is felt: only the eye positions change).
  enum class Stereo { kOff, kSideBySide, kAnaglyph, kQuadBuffer };
  /// Sets the stereo mode and renders; kQuadBuffer without a stereo capable context is kOff.
  void setStereo(Stereo mode);
  Stereo stereo() const noexcept { return stereo_; }

 signals:
  /// A snapshot was read and shown (strip chart, status line, segment alerts follow it).
  void snapshotShown(const vh::runtime::HapticSnapshot& snapshot, bool update_status_now);

 private:
  void onSessionChanged(runtime::SessionChange what);
  void showScene();
  void applyClippingFromPanel();
  void updateHint();
  void chooseColour(QColor Preferences::*field, const QString& title, QWidget* parent);

  runtime::Session& session_;
  SceneView& view_;
  Stereo stereo_ = Stereo::kOff;
  DisplayPanel& panel_;
  Preferences& prefs_;
  QTimer* timer_ = nullptr;
  RenderMode opening_mode_;      // what a new scan opens with (see setRenderMode())
  VolumePreset opening_preset_;
  runtime::HapticSnapshot snapshot_;
  bool have_snapshot_ = false;
  int observer_ = 0;
  std::shared_ptr<const runtime::ExpertPath> ghost_expert_;  // whose path the view's ghost draws
  bool live_ghost_ = true;
  std::vector<Eigen::Vector3d> shadow_samples_T_m_;
  struct ShadowKey {
    haptics::Pose X_WP;
    Eigen::Vector3d direction_W = Eigen::Vector3d::Zero();
    double isovalue = 0.0;
    const void* field = nullptr;
    const void* carved = nullptr;
    std::uint64_t carved_version = 0;
  };
  const CarvedRegion* carved_ = nullptr;
  ShadowKey shadow_key_;
  bool shadow_cast_ = false;  // shadow_key_ holds the last cast's inputs
};

}  // namespace vh::ui
