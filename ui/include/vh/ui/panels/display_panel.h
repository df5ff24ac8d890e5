#pragma once
/// @file
/// The Display dock's panel: rendering mode and composite preset, standard views and Reset
/// view, the clipping plane (axis, position, side), the orientation marker, the device tool and
/// the tool's shadow;
/// and the same choices as View menu actions (addViewMenuActions()), kept in step with the dock.
/// It edits and shows; the main window acts on its signals (preferences and the scene view).
/// GUI thread only.

#include <QWidget>

#include "vh/ui/view/render_presets.h"
#include "vh/ui/view/scene_view.h"

class QAction;
class QActionGroup;
class QCheckBox;
class QComboBox;
class QFormLayout;
class QGroupBox;
class QMenu;
class QSlider;

namespace vh::ui {

class DisplayPanel : public QWidget {
  Q_OBJECT

 public:
  explicit DisplayPanel(QWidget* parent = nullptr);

  /// Adds to `menu`: the rendering modes (Ctrl+1..3), Composite Preset, Reset View (Ctrl+R),
  /// Standard Views (Alt+A/P/L/R/S/I, also added to `shortcut_owner` so they work while the
  /// menu is closed), Orientation Marker (Ctrl+M), Clipping Plane (Ctrl+K), Device Tool and
  /// Tool Shadow.
  /// They emit the panel's signals. @return the Orientation Marker action (the first toggle).
  QAction* addViewMenuActions(QMenu* menu, QWidget* shortcut_owner);

  // Shown values (no signal is emitted).
  void setRenderMode(RenderMode mode);
  /// The mode the panel shows.
  RenderMode renderMode() const;
  void setPreset(VolumePreset preset);
  void setClipping(bool enabled, ClipAxis axis, double fraction, bool flip);
  void setMarkerVisible(bool visible);
  void setDeviceToolVisible(bool visible);
  void setToolShadowVisible(bool visible);

  bool clippingEnabled() const;
  ClipAxis clipAxis() const;
  /// 0..1 along the axis.
  double clipFraction() const;
  bool clipFlipped() const;
  QGroupBox* clipGroup() const noexcept { return clip_group_; }

 signals:
  void renderModeChosen(vh::ui::RenderMode mode);
  void presetChosen(vh::ui::VolumePreset preset);
  void standardViewRequested(vh::ui::StandardView view);
  void resetViewRequested();
  /// Any clipping widget changed; `moving` while the position slider is dragged.
  void clippingChanged(bool moving);
  void markerToggled(bool visible);
  void deviceToolToggled(bool visible);
  void toolShadowToggled(bool visible);

 private:
  QComboBox* mode_box_ = nullptr;
  QComboBox* preset_box_ = nullptr;
  QGroupBox* clip_group_ = nullptr;
  QComboBox* clip_axis_ = nullptr;
  QSlider* clip_position_ = nullptr;
  QCheckBox* clip_flip_ = nullptr;
  QCheckBox* marker_box_ = nullptr;
  QCheckBox* device_box_ = nullptr;
  QCheckBox* shadow_box_ = nullptr;
  QActionGroup* mode_actions_ = nullptr;
  QActionGroup* preset_actions_ = nullptr;
  QAction* marker_action_ = nullptr;
  QAction* clip_action_ = nullptr;
  QAction* device_action_ = nullptr;
  QAction* shadow_action_ = nullptr;
  // The constructor's groups, top to bottom, then the controls' signals.
  QFormLayout* buildRenderingForm();  ///< The rendering mode and the composite mode's preset.
  QGroupBox* buildViewsBox();         ///< The standard views and reset view (their signals too).
  QGroupBox* buildClipBox();          ///< The clipping plane's switch, axis, position and side.
  void connectControls();
};

}  // namespace vh::ui
