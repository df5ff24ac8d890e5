#include "vh/ui/panels/display_panel.h"

#include <algorithm>
#include <cmath>

#include <QAction>
#include <QActionGroup>
#include <QCheckBox>
#include <QComboBox>
#include <QFormLayout>
#include <QGridLayout>
#include <QGroupBox>
#include <QMenu>
#include <QPushButton>
#include <QSignalBlocker>
#include <QSlider>
#include <QVBoxLayout>

namespace vh::ui {

DisplayPanel::DisplayPanel(QWidget* parent) : QWidget(parent) {
  auto* layout = new QVBoxLayout(this);
  layout->setContentsMargins(6, 6, 6, 6);
  layout->addLayout(buildRenderingForm());
  layout->addWidget(buildViewsBox());
  layout->addWidget(buildClipBox());
  marker_box_ = new QCheckBox("Orientation marker", this);
  device_box_ = new QCheckBox("Show the device tool (wire)", this);
  layout->addWidget(marker_box_);
  layout->addWidget(device_box_);
  shadow_box_ = new QCheckBox("Tool shadow on the surface", this);
  shadow_box_->setObjectName("toolShadow");
  shadow_box_->setToolTip("A depth cue: the tool's shadow under a light above the view, and a line from the tool "
                          "to it, on the surface the hand feels");
  layout->addWidget(shadow_box_);
  layout->addStretch(1);
  connectControls();
}

QFormLayout* DisplayPanel::buildRenderingForm() {
  auto* form = new QFormLayout();
  mode_box_ = new QComboBox(this);
  mode_box_->setObjectName("renderMode");
  for (const RenderMode m : {RenderMode::kIsosurface, RenderMode::kComposite, RenderMode::kMip}) {
    mode_box_->addItem(QString::fromStdString(modeName(m)), static_cast<int>(m));
  }
  mode_box_->setToolTip("Isosurface: the surface you feel. Composite: translucent tissue by preset. MIP: "
                        "maximum intensity projection.");
  preset_box_ = new QComboBox(this);
  preset_box_->setObjectName("volumePreset");
  for (const VolumePreset p : {VolumePreset::kBone, VolumePreset::kSoftTissue, VolumePreset::kSkin}) {
    preset_box_->addItem(QString::fromStdString(presetName(p)), static_cast<int>(p));
  }
  preset_box_->setToolTip("Transfer function of the composite mode (CT presets, in HU)");
  form->addRow("Rendering", mode_box_);
  form->addRow("Preset", preset_box_);
  return form;
}

QGroupBox* DisplayPanel::buildViewsBox() {
  auto* views = new QGroupBox("Views", this);
  auto* grid = new QGridLayout(views);
  struct ViewButton {
    const char* text;
    StandardView view;
    int row, column;
  };
  const ViewButton buttons[] = {{"Anterior", StandardView::kAnterior, 0, 0},
                                {"Posterior", StandardView::kPosterior, 0, 1},
                                {"Left", StandardView::kLeft, 1, 0},
                                {"Right", StandardView::kRight, 1, 1},
                                {"Superior", StandardView::kSuperior, 2, 0},
                                {"Inferior", StandardView::kInferior, 2, 1}};
  for (const ViewButton& b : buttons) {
    auto* button = new QPushButton(b.text, views);
    const StandardView v = b.view;
    connect(button, &QPushButton::clicked, this, [this, v] { emit standardViewRequested(v); });
    grid->addWidget(button, b.row, b.column);
  }
  auto* reset_view = new QPushButton("Reset view", views);
  reset_view->setObjectName("resetView");
  connect(reset_view, &QPushButton::clicked, this, &DisplayPanel::resetViewRequested);
  grid->addWidget(reset_view, 3, 0, 1, 2);
  return views;
}

QGroupBox* DisplayPanel::buildClipBox() {
  clip_group_ = new QGroupBox("Clipping plane", this);
  clip_group_->setObjectName("clipGroup");
  clip_group_->setCheckable(true);
  clip_group_->setChecked(false);
  clip_group_->setToolTip("Cuts the rendered volume open to see inside (the felt surface stays whole)");
  auto* clip_form = new QFormLayout(clip_group_);
  clip_axis_ = new QComboBox(clip_group_);
  clip_axis_->addItem("Sagittal (x, L-R)", static_cast<int>(ClipAxis::kX));
  clip_axis_->addItem("Coronal (y, A-P)", static_cast<int>(ClipAxis::kY));
  clip_axis_->addItem("Axial (z, I-S)", static_cast<int>(ClipAxis::kZ));
  clip_position_ = new QSlider(Qt::Horizontal, clip_group_);
  clip_position_->setObjectName("clipPosition");
  clip_position_->setRange(0, 1000);
  clip_position_->setValue(500);
  clip_flip_ = new QCheckBox("Keep the other side", clip_group_);
  clip_form->addRow("Axis", clip_axis_);
  clip_form->addRow("Position", clip_position_);
  clip_form->addRow(clip_flip_);
  return clip_group_;
}

void DisplayPanel::connectControls() {
  connect(mode_box_, &QComboBox::currentIndexChanged, this,
          [this](int i) { emit renderModeChosen(static_cast<RenderMode>(mode_box_->itemData(i).toInt())); });
  connect(preset_box_, &QComboBox::currentIndexChanged, this,
          [this](int i) { emit presetChosen(static_cast<VolumePreset>(preset_box_->itemData(i).toInt())); });
  connect(clip_group_, &QGroupBox::toggled, this, [this](bool on) {
    if (clip_action_ != nullptr) {
      const QSignalBlocker block(clip_action_);
      clip_action_->setChecked(on);
    }
    emit clippingChanged(false);
  });
  connect(clip_axis_, &QComboBox::currentIndexChanged, this, [this] { emit clippingChanged(false); });
  connect(clip_position_, &QSlider::valueChanged, this, [this] { emit clippingChanged(true); });
  connect(clip_flip_, &QCheckBox::toggled, this, [this] { emit clippingChanged(false); });
  connect(marker_box_, &QCheckBox::toggled, this, &DisplayPanel::markerToggled);
  connect(device_box_, &QCheckBox::toggled, this, &DisplayPanel::deviceToolToggled);
  connect(shadow_box_, &QCheckBox::toggled, this, &DisplayPanel::toolShadowToggled);
}

QAction* DisplayPanel::addViewMenuActions(QMenu* menu, QWidget* shortcut_owner) {
  mode_actions_ = new QActionGroup(this);
  const char* mode_keys[] = {"Ctrl+1", "Ctrl+2", "Ctrl+3"};
  int k = 0;
  for (const RenderMode m : {RenderMode::kIsosurface, RenderMode::kComposite, RenderMode::kMip}) {
    QAction* a = menu->addAction(QString::fromStdString(modeName(m)), this, [this, m] { emit renderModeChosen(m); });
    a->setCheckable(true);
    a->setData(static_cast<int>(m));
    a->setShortcut(QKeySequence(mode_keys[k++]));
    mode_actions_->addAction(a);
  }
  QMenu* presets = menu->addMenu("Composite &Preset");
  preset_actions_ = new QActionGroup(this);
  for (const VolumePreset p : {VolumePreset::kBone, VolumePreset::kSoftTissue, VolumePreset::kSkin}) {
    QAction* a = presets->addAction(QString::fromStdString(presetName(p)), this, [this, p] {
      emit presetChosen(p);
      emit renderModeChosen(RenderMode::kComposite);
    });
    a->setCheckable(true);
    a->setData(static_cast<int>(p));
    preset_actions_->addAction(a);
  }
  menu->addSeparator();
  QAction* reset = menu->addAction("&Reset View", this, &DisplayPanel::resetViewRequested);
  reset->setShortcut(QKeySequence("Ctrl+R"));
  struct ViewEntry {
    const char* text;
    const char* key;
    StandardView view;
  };
  const ViewEntry entries[] = {{"Anterior", "Alt+A", StandardView::kAnterior},
                               {"Posterior", "Alt+P", StandardView::kPosterior},
                               {"Left Lateral", "Alt+L", StandardView::kLeft},
                               {"Right Lateral", "Alt+R", StandardView::kRight},
                               {"Superior", "Alt+S", StandardView::kSuperior},
                               {"Inferior", "Alt+I", StandardView::kInferior}};
  QMenu* standard = menu->addMenu("Standard &Views");
  for (const ViewEntry& e : entries) {
    const StandardView v = e.view;
    QAction* a = standard->addAction(e.text, this, [this, v] { emit standardViewRequested(v); });
    a->setShortcut(QKeySequence(e.key));
    if (shortcut_owner != nullptr) shortcut_owner->addAction(a);  // shortcuts work while the menu is closed
  }
  marker_action_ = menu->addAction("Orientation &Marker", this, [this](bool on) { emit markerToggled(on); });
  marker_action_->setCheckable(true);
  marker_action_->setChecked(marker_box_->isChecked());
  marker_action_->setShortcut(QKeySequence("Ctrl+M"));
  clip_action_ = menu->addAction("&Clipping Plane", this, [this](bool on) { clip_group_->setChecked(on); });
  clip_action_->setCheckable(true);
  clip_action_->setChecked(clip_group_->isChecked());
  clip_action_->setShortcut(QKeySequence("Ctrl+K"));
  device_action_ = menu->addAction("&Device Tool", this, [this](bool on) { emit deviceToolToggled(on); });
  device_action_->setCheckable(true);
  device_action_->setChecked(device_box_->isChecked());
  shadow_action_ = menu->addAction("Tool &Shadow", this, [this](bool on) { emit toolShadowToggled(on); });
  shadow_action_->setCheckable(true);
  shadow_action_->setChecked(shadow_box_->isChecked());
  setRenderMode(static_cast<RenderMode>(mode_box_->currentData().toInt()));
  setPreset(static_cast<VolumePreset>(preset_box_->currentData().toInt()));
  return marker_action_;
}

RenderMode DisplayPanel::renderMode() const { return static_cast<RenderMode>(mode_box_->currentData().toInt()); }

void DisplayPanel::setRenderMode(RenderMode mode) {
  const QSignalBlocker block(mode_box_);
  mode_box_->setCurrentIndex(mode_box_->findData(static_cast<int>(mode)));
  preset_box_->setEnabled(mode == RenderMode::kComposite);
  if (mode_actions_ != nullptr) {
    for (QAction* a : mode_actions_->actions()) a->setChecked(a->data().toInt() == static_cast<int>(mode));
  }
}

void DisplayPanel::setPreset(VolumePreset preset) {
  const QSignalBlocker block(preset_box_);
  preset_box_->setCurrentIndex(preset_box_->findData(static_cast<int>(preset)));
  if (preset_actions_ != nullptr) {
    for (QAction* a : preset_actions_->actions()) a->setChecked(a->data().toInt() == static_cast<int>(preset));
  }
}

void DisplayPanel::setClipping(bool enabled, ClipAxis axis, double fraction, bool flip) {
  const QSignalBlocker b1(clip_group_);
  const QSignalBlocker b2(clip_axis_);
  const QSignalBlocker b3(clip_position_);
  const QSignalBlocker b4(clip_flip_);
  clip_group_->setChecked(enabled);
  clip_axis_->setCurrentIndex(clip_axis_->findData(static_cast<int>(axis)));
  clip_position_->setValue(static_cast<int>(std::lround(std::clamp(fraction, 0.0, 1.0) * 1000.0)));
  clip_flip_->setChecked(flip);
  if (clip_action_ != nullptr) {
    const QSignalBlocker block(clip_action_);
    clip_action_->setChecked(enabled);
  }
}

namespace {

/// Shows `checked` on a toggle's check box and its View menu action (null before the menu is
/// built) without emitting.
void showToggle(QCheckBox* box, QAction* action, bool checked) {
  const QSignalBlocker block(box);
  box->setChecked(checked);
  if (action != nullptr) {
    const QSignalBlocker block_action(action);
    action->setChecked(checked);
  }
}

}  // namespace

void DisplayPanel::setMarkerVisible(bool visible) { showToggle(marker_box_, marker_action_, visible); }
void DisplayPanel::setDeviceToolVisible(bool visible) { showToggle(device_box_, device_action_, visible); }
void DisplayPanel::setToolShadowVisible(bool visible) { showToggle(shadow_box_, shadow_action_, visible); }

bool DisplayPanel::clippingEnabled() const { return clip_group_->isChecked(); }
ClipAxis DisplayPanel::clipAxis() const { return static_cast<ClipAxis>(clip_axis_->currentData().toInt()); }
double DisplayPanel::clipFraction() const { return clip_position_->value() / 1000.0; }
bool DisplayPanel::clipFlipped() const { return clip_flip_->isChecked(); }

}  // namespace vh::ui
