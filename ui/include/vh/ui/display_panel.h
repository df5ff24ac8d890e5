#pragma once
/// @file
/// The Display dock's panel: rendering mode and composite preset, standard views and Reset
/// view, the clipping plane (axis, position, side), the orientation marker and the device tool.
/// It edits and shows; the main window acts on its signals (preferences and the scene view).
/// GUI thread only.

#include <QWidget>

#include "vh/ui/render_presets.h"
#include "vh/ui/scene_view.h"

class QCheckBox;
class QComboBox;
class QGroupBox;
class QSlider;

namespace vh::ui {

class DisplayPanel : public QWidget {
  Q_OBJECT

 public:
  explicit DisplayPanel(QWidget* parent = nullptr);

  // Shown values (no signal is emitted).
  void setRenderMode(RenderMode mode);
  void setPreset(VolumePreset preset);
  void setClipping(bool enabled, ClipAxis axis, double fraction, bool flip);
  void setMarkerVisible(bool visible);
  void setDeviceToolVisible(bool visible);

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

 private:
  QComboBox* mode_box_ = nullptr;
  QComboBox* preset_box_ = nullptr;
  QGroupBox* clip_group_ = nullptr;
  QComboBox* clip_axis_ = nullptr;
  QSlider* clip_position_ = nullptr;
  QCheckBox* clip_flip_ = nullptr;
  QCheckBox* marker_box_ = nullptr;
  QCheckBox* device_box_ = nullptr;
};

}  // namespace vh::ui
