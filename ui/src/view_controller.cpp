#include "vh/ui/view_controller.h"

#include <algorithm>
#include <cmath>
#include <span>

#include <QActionGroup>
#include <QColorDialog>
#include <QMenu>
#include <QScreen>
#include <QTimer>
#include <vtkGenericOpenGLRenderWindow.h>

#include "vh/ui/devices/device_input.h"
#include "vh/ui/panels/display_panel.h"
#include "vh/ui/view/scene_actors.h"
#include "vh/ui/view/scene_frames.h"
#include "vh/ui/view/scene_view.h"
#include "vh/ui/view/tool_shadow.h"
#include "vh/ui/view/vtk_view.h"

namespace vh::ui {
int displayPeriodMsFor(double screen_refresh_Hz) noexcept {
  const double hz = std::isfinite(screen_refresh_Hz) && screen_refresh_Hz > 0.0 ? screen_refresh_Hz : 60.0;
  return std::clamp(static_cast<int>(std::floor(1000.0 / std::clamp(hz, 30.0, 240.0))), 4, 33);
}

ViewController::ViewController(runtime::Session& session, SceneView& view, DisplayPanel& panel, Preferences& prefs,
                               QObject* parent)
    : QObject(parent),
      session_(session),
      view_(view),
      panel_(panel),
      prefs_(prefs),
      opening_mode_(prefs.mode),
      opening_preset_(prefs.preset) {
  timer_ = new QTimer(this);
  timer_->setTimerType(Qt::PreciseTimer);  // a coarse timer may stretch 16 ms by 5 %
  timer_->setInterval(displayPeriodMsFor(60.0));
  connect(timer_, &QTimer::timeout, this, [this] { refresh(); });
  observer_ = session_.addObserver([this](runtime::SessionChange what) { onSessionChanged(what); });

  panel_.setMarkerVisible(prefs_.orientation_marker);
  panel_.setDeviceToolVisible(prefs_.show_device);
  panel_.setPreset(prefs_.preset);
  panel_.setRenderMode(prefs_.mode);
  connect(&panel_, &DisplayPanel::renderModeChosen, this, &ViewController::setRenderMode);
  connect(&panel_, &DisplayPanel::presetChosen, this, &ViewController::setPreset);
  connect(&panel_, &DisplayPanel::standardViewRequested, this, [this](StandardView v) {
    view_.setStandardView(v);
    updateShadow();
  });
  connect(&panel_, &DisplayPanel::resetViewRequested, this, [this] {
    view_.resetCamera();
    view_.requestRender();
    updateShadow();
  });
  connect(&panel_, &DisplayPanel::clippingChanged, this, [this](bool moving) {
    if (moving) view_.noteMotion();
    applyClippingFromPanel();
  });
  connect(&panel_, &DisplayPanel::markerToggled, this, &ViewController::setOrientationMarkerVisible);
  connect(&panel_, &DisplayPanel::deviceToolToggled, this, &ViewController::setDeviceToolVisible);
  panel_.setToolShadowVisible(prefs_.tool_shadow);
  connect(&panel_, &DisplayPanel::toolShadowToggled, this, &ViewController::setToolShadowVisible);
  // The shadow follows the tool, live or replayed; its light turns with the camera: cast again
  // once a drag ends.
  connect(&view_, &SceneView::toolFrameShown, this, [this] { updateShadow(); });
  connect(view_.widget(), &VtkView::interactionEnded, this, [this] { updateShadow(); });
  applyColours();
}

ViewController::~ViewController() { session_.removeObserver(observer_); }

int ViewController::displayPeriodMs() const noexcept { return timer_->interval(); }

void ViewController::onSessionChanged(runtime::SessionChange what) {
  using runtime::SessionChange;
  if (runtime::has(what, SessionChange::kScene)) showScene();
  if (runtime::has(what, SessionChange::kIsovalue)) view_.setIsovalue(session_.isovalue());
  if (runtime::has(what, SessionChange::kTool) && !runtime::has(what, SessionChange::kScene) &&
      session_.live().tool != nullptr) {
    view_.setTool(*session_.live().tool, session_.live().X_WT_initial);
    have_snapshot_ = false;
  }
  if (runtime::has(what, SessionChange::kScene) || runtime::has(what, SessionChange::kTool)) {
    shadow_samples_T_m_.clear();
    if (session_.live().tool != nullptr) shadow_samples_T_m_ = toolShadowSamples(*session_.live().tool);
    shadow_cast_ = false;
  }
  updateShadow();  // casts only if its inputs changed (isovalue, felt segments, tool, scene)
  if (runtime::has(what, SessionChange::kDevice)) {
    view_.setDeviceVisible(session_.hapticThread() != nullptr && prefs_.show_device);
    have_snapshot_ = false;
    updateHint();
  }
  if (session_.hapticsRunning()) {
    if (!timer_->isActive()) {
      const QScreen* screen = view_.widget()->screen();
      timer_->setInterval(displayPeriodMsFor(screen != nullptr ? screen->refreshRate() : 0.0));
    }
    timer_->start();
  } else {
    timer_->stop();
  }
}

void ViewController::showScene() {
  view_.clearScene();
  ghost_expert_.reset();  // the new scene's view has a new, hidden ghost
  have_snapshot_ = false;
  snapshot_ = runtime::HapticSnapshot{};
  if (!session_.hasScene()) return;
  prefs_.mode = opening_mode_;
  prefs_.preset = opening_preset_;
  panel_.setRenderMode(prefs_.mode);
  panel_.setPreset(prefs_.preset);
  SceneActorsSpec spec = sceneActorsSpecFor(session_.loaded(), session_.live());
  spec.show_device = session_.hapticThread() != nullptr && prefs_.show_device;
  view_.setScene(spec, session_.live().X_WT_initial, prefs_);
  applyClippingFromPanel();
}

bool ViewController::refresh(bool update_status_now) {
  if (!session_.hasScene() || !view_.hasScene() || !session_.latestSnapshot(snapshot_)) return false;
  have_snapshot_ = true;
  ToolFrame frame;
  frame.X_WP = snapshot_.X_WP;
  frame.X_WD = snapshot_.X_WD;
  frame.force_W_N = snapshot_.force_W_N;
  const int n = std::clamp(snapshot_.contacts_shown, 0, runtime::HapticSnapshot::kMaxContactsShown);
  frame.contacts_W_m = std::span<const Eigen::Vector3d>(snapshot_.contact_p_W_m.data(), static_cast<std::size_t>(n));
  const bool changed = view_.show(frame);  // a new pose casts the shadow (toolFrameShown)
  updateGhost();
  emit snapshotShown(snapshot_, update_status_now);
  return changed;
}

void ViewController::setLiveGhost(bool on) {
  live_ghost_ = on;
  ghost_expert_.reset();
  if (!on) return;
  view_.setGhostPath(nullptr);
  updateGhost();
}

void ViewController::updateGhost() {
  if (!live_ghost_) return;
  const runtime::HapticThread* thread = session_.hapticThread();
  const std::shared_ptr<const runtime::ExpertPath> expert =
      thread != nullptr && view_.hasScene() ? thread->guidance() : nullptr;
  if (expert != ghost_expert_) {
    ghost_expert_ = expert;
    view_.setGhostPath(expert != nullptr ? &expert->path() : nullptr);  // hides it
  }
  if (expert == nullptr) {
    view_.hideGhost();
    return;
  }
  haptics::PathPoint nearest;
  const std::int64_t segment = have_snapshot_ && snapshot_.guidance_on ? snapshot_.guidance_segment : -1;
  if (segment >= 0 && static_cast<std::size_t>(segment) < expert->path().size()) {
    nearest.segment = segment;
    nearest.s = snapshot_.guidance_s;
    nearest.p_W_m = snapshot_.guidance_nearest_W_m;
  } else {
    nearest = expert->path().nearest(have_snapshot_ ? snapshot_.X_WD.p_AB_m : session_.live().X_WT_initial.p_AB_m);
  }
  view_.showGhost(expert->poseAt(nearest));
}

bool ViewController::updateShadow() {
  if (!prefs_.tool_shadow || !session_.hasScene() || !view_.hasScene()) return false;
  const std::shared_ptr<const haptics::ScalarVolume>& field = session_.live().hapticField();
  if (field == nullptr) return false;
  ShadowKey key;
  // The pose the view shows, live or replayed: it changes only when SceneView::show() found the
  // tool moved visibly, so the same pose, to the bit, means the same shadow.
  key.X_WP = view_.shownProxyPose();
  key.direction_W = view_.shadowDirection_W();
  key.isovalue = session_.live().hapticIsovalue();
  key.field = field.get();
  key.carved = carved_;
  key.carved_version = carved_ != nullptr ? carved_->version() : 0;
  if (shadow_cast_ && key.X_WP.p_AB_m == shadow_key_.X_WP.p_AB_m &&
      key.X_WP.R_AB.coeffs() == shadow_key_.X_WP.R_AB.coeffs() &&
      (key.direction_W - shadow_key_.direction_W).norm() < 1e-3 && key.isovalue == shadow_key_.isovalue &&
      key.field == shadow_key_.field && key.carved == shadow_key_.carved &&
      key.carved_version == shadow_key_.carved_version) {
    return false;
  }
  // Drilled: on the field the hand feels, with the cavity.
  const ToolShadow shadow =
      carved_ != nullptr ? castToolShadow(*field, *carved_, key.isovalue, key.X_WP, shadow_samples_T_m_, key.direction_W)
                         : castToolShadow(*field, key.isovalue, key.X_WP, shadow_samples_T_m_, key.direction_W);
  view_.showShadow(shadow, key.direction_W);
  shadow_key_ = key;
  shadow_cast_ = true;
  return true;
}

void ViewController::setToolShadowVisible(bool visible) {
  prefs_.tool_shadow = visible;
  panel_.setToolShadowVisible(visible);
  view_.setShadowVisible(visible);
  if (visible) {
    shadow_cast_ = false;
    updateShadow();
  }
}

void ViewController::setRenderMode(RenderMode mode) {
  if (!session_.hasScene()) opening_mode_ = mode;
  prefs_.mode = mode;
  panel_.setRenderMode(mode);
  view_.setRenderMode(prefs_.mode, prefs_.preset);
}

void ViewController::setPreset(VolumePreset preset) {
  if (!session_.hasScene()) opening_preset_ = preset;
  prefs_.preset = preset;
  panel_.setPreset(preset);
  view_.setRenderMode(prefs_.mode, prefs_.preset);
}

void ViewController::setClipping(bool enabled, ClipAxis axis, double fraction, bool flip) {
  panel_.setClipping(enabled, axis, fraction, flip);
  applyClippingFromPanel();
}

void ViewController::applyClippingFromPanel() {
  view_.setClipping(panel_.clippingEnabled(), panel_.clipAxis(), panel_.clipFraction(), panel_.clipFlipped());
}

void ViewController::setOrientationMarkerVisible(bool visible) {
  prefs_.orientation_marker = visible;
  view_.setMarkerVisible(visible);
  panel_.setMarkerVisible(visible);
}

void ViewController::setDeviceToolVisible(bool visible) {
  prefs_.show_device = visible;
  panel_.setDeviceToolVisible(visible);
  view_.setDeviceVisible(visible && session_.hapticThread() != nullptr);
}

void ViewController::focusOnTool() {
  if (session_.live().tool == nullptr || !view_.hasScene()) return;
  view_.focusOn(*session_.live().tool, have_snapshot_ ? snapshot_.X_WP : view_.shownProxyPose());
}

void ViewController::updateHint() {
  if (view_.hasScene()) view_.setHint(DeviceInput::hint(session_));
}

void ViewController::applyColours() { view_.applyColours(prefs_); }

void ViewController::chooseColour(QColor Preferences::*field, const QString& title, QWidget* parent) {
  const QColor chosen = QColorDialog::getColor(prefs_.*field, parent, title);
  if (chosen.isValid()) {
    prefs_.*field = chosen;
    applyColours();
  }
}

void ViewController::setStereo(Stereo mode) {
  vtkRenderWindow* window = view_.widget()->renderWindow();
  if (mode == Stereo::kQuadBuffer && window->GetStereoCapableWindow() == 0) mode = Stereo::kOff;
  stereo_ = mode;
  switch (mode) {
    case Stereo::kOff: window->StereoRenderOff(); break;
    case Stereo::kSideBySide: window->SetStereoTypeToSplitViewportHorizontal(); break;
    case Stereo::kAnaglyph: window->SetStereoTypeToAnaglyph(); break;
    case Stereo::kQuadBuffer: window->SetStereoTypeToCrystalEyes(); break;
  }
  if (mode != Stereo::kOff) window->StereoRenderOn();
  view_.requestRender();
}

void ViewController::addStereoMenu(QMenu* view_menu) {
  QMenu* stereo = view_menu->addMenu("&Stereo");
  auto* group = new QActionGroup(stereo);
  const auto add = [&](const char* label, Stereo mode, bool enabled) {
    QAction* a = stereo->addAction(label, this, [this, mode] { setStereo(mode); });
    a->setCheckable(true);
    a->setChecked(mode == stereo_);
    a->setEnabled(enabled);
    group->addAction(a);
  };
  add("&Off", Stereo::kOff, true);
  add("&Side by Side", Stereo::kSideBySide, true);
  add("&Anaglyph (Red / Cyan)", Stereo::kAnaglyph, true);
  add("&Quad Buffer (Shutter Glasses)", Stereo::kQuadBuffer,
      view_.widget()->renderWindow()->GetStereoCapableWindow() != 0);
}

void ViewController::addColoursMenu(QMenu* view_menu, QWidget* dialog_parent) {
  QMenu* colours = view_menu->addMenu("C&olours");
  const auto add = [&](const char* label, QColor Preferences::*field, const char* title) {
    colours->addAction(label, this, [this, field, title, dialog_parent] { chooseColour(field, title, dialog_parent); });
  };
  add("Background (top)...", &Preferences::background_top, "Background, top");
  add("Background (bottom)...", &Preferences::background_bottom, "Background, bottom");
  add("Surface...", &Preferences::surface, "Isosurface colour");
  add("Tool (proxy)...", &Preferences::tool, "Tool colour");
  add("Device (wire)...", &Preferences::device, "Device colour");
  colours->addSeparator();
  colours->addAction("Reset Colours", this, [this] {
    const Preferences defaults;
    prefs_.background_top = defaults.background_top;
    prefs_.background_bottom = defaults.background_bottom;
    prefs_.surface = defaults.surface;
    prefs_.tool = defaults.tool;
    prefs_.device = defaults.device;
    applyColours();
  });
}

}  // namespace vh::ui
