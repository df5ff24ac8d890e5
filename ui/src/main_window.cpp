#include "vh/ui/main_window.h"

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <iostream>
#include <limits>
#include <numbers>
#include <stdexcept>

#include <QAction>
#include <QActionGroup>
#include <QApplication>
#include <QCheckBox>
#include <QCloseEvent>
#include <QColorDialog>
#include <QComboBox>
#include <QDir>
#include <QDockWidget>
#include <QDoubleSpinBox>
#include <QDragEnterEvent>
#include <QDropEvent>
#include <QFileDialog>
#include <QFileInfo>
#include <QFormLayout>
#include <QGridLayout>
#include <QGroupBox>
#include <QHBoxLayout>
#include <QKeyEvent>
#include <QLabel>
#include <QMenu>
#include <QMenuBar>
#include <QMessageBox>
#include <QMimeData>
#include <QMouseEvent>
#include <QProgressBar>
#include <QPushButton>
#include <QSettings>
#include <QSignalBlocker>
#include <QSlider>
#include <QStatusBar>
#include <QTimer>
#include <QToolButton>
#include <QUrl>
#include <QVBoxLayout>
#include <QWheelEvent>

#include <vtkActor.h>
#include <vtkCamera.h>
#include <vtkImageData.h>
#include <vtkRenderer.h>
#include <vtkTextActor.h>
#include <vtkTextProperty.h>
#include <vtkVolume.h>

#include "vh/devices/device_catalog.h"
#include "vh/devices/fallback_device.h"
#include "vh/runtime/device.h"
#include "vh/runtime/placement.h"
#include "vh/ui/about_dialog.h"
#include "vh/ui/device_manipulation.h"
#include "vh/ui/haptics_panel.h"
#include "vh/ui/histogram_slider.h"
#include "vh/ui/load_notices.h"
#include "vh/ui/orientation_marker.h"
#include "vh/ui/replay_panel.h"
#include "vh/ui/scene_actors.h"
#include "vh/ui/scene_loader.h"
#include "vh/ui/series_chooser.h"
#include "vh/ui/session_recorder.h"
#include "vh/ui/strip_chart.h"
#include "vh/ui/vtk_view.h"

#include <vtkGenericOpenGLRenderWindow.h>

namespace vh::ui {
namespace {

namespace fs = std::filesystem;

constexpr int kSliderSteps = 1000;
constexpr int kDisplayPeriodMs = 33;     // ~30 Hz prop updates
constexpr int kStatusEveryTicks = 6;     // status text at ~5 Hz (readable)
constexpr int kSettleMs = 300;           // still frame this long after the last motion
constexpr int kNoticeStatusMs = 10000;   // a load notice stays in the status bar this long
constexpr double kKeyRotation_rad = 5.0 * std::numbers::pi / 180.0;

const char* kHintCamera = "Camera: left drag rotate | middle drag pan | right drag / wheel zoom";
const char* kHintDevice =
    "Device: Ctrl+left drag move in view plane | Ctrl+wheel or Ctrl+right drag move in depth\n"
    "        Shift+left drag rotate | keys (click the view): arrows, PgUp/PgDn, Shift+arrows, Home";

const char* kControlsHtml =
    "<h3>Mouse in the view</h3><table cellpadding='2'>"
    "<tr><td>left drag</td><td>rotate the camera</td></tr>"
    "<tr><td>middle drag / right drag or wheel</td><td>pan / zoom the camera</td></tr>"
    "<tr><td>Ctrl + left drag</td><td>move the simulated device in the view plane</td></tr>"
    "<tr><td>Ctrl + wheel, Ctrl + right drag</td><td>move the device along the view direction</td></tr>"
    "<tr><td>Shift + left drag</td><td>rotate the device about the tool's centre</td></tr></table>"
    "<h3>Keys (click the view first)</h3><table cellpadding='2'>"
    "<tr><td>arrows</td><td>move the device in the view plane</td></tr>"
    "<tr><td>Page Up / Page Down</td><td>move the device away / towards you</td></tr>"
    "<tr><td>Shift + arrows</td><td>rotate the device by 5&deg;</td></tr>"
    "<tr><td>Home</td><td>device back to its starting pose</td></tr>"
    "<tr><td>[ and ]</td><td>isovalue down / up one step</td></tr></table>"
    "<p>The solid tool is the proxy, which stays on the surface; the wire tool is the device. "
    "The yellow arrow is the force on your hand, red dots are the contacts.</p>";

bool posesDiffer(const haptics::Pose& a, const haptics::Pose& b) {
  if ((a.p_AB_m - b.p_AB_m).norm() > 1e-5) {  // 10 um
    return true;
  }
  return a.R_AB.angularDistance(b.R_AB) > 1e-4;  // rad
}

int decimalsFor(double range) {
  if (range >= 100.0) return 0;
  if (range >= 1.0) return 2;
  return 4;
}

QString q(const std::string& s) { return QString::fromStdString(s); }

/// "12 N", "unbounded".
QString limitValue(double v, const char* unit, int decimals = 1) {
  if (!std::isfinite(v)) return "unbounded";
  return QString::fromUtf8("%1 %2").arg(v, 0, 'f', decimals).arg(QString::fromUtf8(unit));
}

/// The device's limits as text, when the device interface reports them (newer runtimes).
template <typename D>
QString deviceLimitsText(const D& device) {
  if constexpr (requires { device.limits(); }) {
    const auto l = device.limits();
    if constexpr (requires { l.max_force_N; l.workspace_radius_m; }) {
      if (!std::isfinite(l.max_force_N) && !std::isfinite(l.workspace_radius_m)) {
        return "No force or workspace limits (no hardware).";
      }
    }
    QStringList lines;
    if constexpr (requires { l.max_force_N; l.max_torque_Nm; }) {
      lines << QString::fromUtf8("max force %1, torque %2")
                   .arg(limitValue(l.max_force_N, "N"), limitValue(l.max_torque_Nm, "N\u00b7m", 2));
    }
    if constexpr (requires { l.max_linear_stiffness_N_per_m; l.max_angular_stiffness_Nm_per_rad; }) {
      lines << QString::fromUtf8("max stiffness %1, %2")
                   .arg(limitValue(l.max_linear_stiffness_N_per_m, "N/m", 0),
                        limitValue(l.max_angular_stiffness_Nm_per_rad, "N\u00b7m/rad", 2));
    }
    if constexpr (requires { l.workspace_radius_m; }) {
      lines << QString("workspace radius %1")
                   .arg(std::isfinite(l.workspace_radius_m) ? QString("%1 mm").arg(l.workspace_radius_m * 1e3, 0, 'f', 0)
                                                            : QString("unbounded"));
    }
    return lines.join("\n");
  } else {
    return {};
  }
}

/// Spacing [m] a loaded tool was sampled at.
double spacingOf(const runtime::LoadedScene& loaded) {
  const runtime::ToolSpec& t = loaded.spec.tool;
  if (t.point_count == 0 && t.point_spacing_m > 0.0) return t.point_spacing_m;
  if (loaded.tool == nullptr || loaded.volume.field == nullptr) return 0.0;
  if (t.point_count > 0) {
    return std::sqrt(loaded.tool->mesh_T.area_m2() / static_cast<double>(std::max<std::size_t>(1, t.point_count)));
  }
  return automaticPointSpacing_m(loaded.tool->mesh_T, *loaded.volume.field);
}

std::array<double, 3> rgb(const QColor& c) { return {c.redF(), c.greenF(), c.blueF()}; }

}  // namespace

ViewerScene makeViewerScene(const runtime::LoadedScene& loaded, std::shared_ptr<runtime::Device> device,
                            std::unique_ptr<runtime::HapticThread> haptics) {
  ViewerScene v;
  v.volume = loaded.volume;
  v.tool = loaded.tool;
  v.isovalue = loaded.isovalue;
  v.X_WT_initial = loaded.X_WT_initial;
  v.device = std::move(device);
  v.haptics = std::move(haptics);
  v.title = loaded.volume.info.source.filename().string();
  if (v.title.empty()) v.title = loaded.spec.volume.path;
  v.tool_spec = loaded.spec.tool;
  v.tool_spec.X_WT_initial.R_AB = loaded.X_WT_initial.R_AB;
  v.tool_spec.initial_orientation_set = true;
  v.gains = loaded.spec.gains;
  v.point_spacing_m = spacingOf(loaded);
  v.scene_file = !loaded.spec.source.empty();
  v.spec = loaded.spec;
  return v;
}

// ---- Construction ------------------------------------------------------------------------------

MainWindow::MainWindow(QWidget* parent) : QMainWindow(parent) {
  {
    QSettings settings;
    prefs_ = Preferences::load(settings);
  }
  gains_.linear_N_per_m = prefs_.linear_stiffness_N_per_m;
  gains_.angular_Nm_per_rad = prefs_.torsional_stiffness_Nm_per_rad;
  tools_ = toolCatalog(runtime::sharedDatasetsDir());

  view_ = new VtkView(this);
  view_->setObjectName("vtkView");
  marker_ = std::make_unique<OrientationMarker>(view_->renderWindow(), view_->renderer());
  marker_->setVisible(false);  // shown with a scene
  view_->renderer()->GradientBackgroundOn();

  // What an empty window says.
  vtkNew<vtkTextActor> welcome;
  welcome->SetInput(
      "Open a scan: File > Open DICOM Folder (Ctrl+D), Open Volume File (Ctrl+O) or Open Scene\n"
      "(Ctrl+Shift+O) - or drop a DICOM folder, a NRRD / MetaImage file or a scene .json here.");
  welcome->GetTextProperty()->SetFontSize(15);
  welcome->GetTextProperty()->SetColor(0.9, 0.9, 0.9);
  welcome->GetTextProperty()->SetJustificationToCentered();
  welcome->GetTextProperty()->SetVerticalJustificationToCentered();
  welcome->GetPositionCoordinate()->SetCoordinateSystemToNormalizedViewport();
  welcome->GetPositionCoordinate()->SetValue(0.5, 0.5);
  view_->renderer()->AddActor2D(welcome);
  welcome_ = welcome;

  loader_ = new SceneLoader(this);
  buildUi();
  recorder_ = new SessionRecorder(this);
  replay_ = new ReplayController(this);
  buildDocks();
  buildMenus();
  connectLoader();
  setUpDevicePicker();
  applyColours();
  view_->installEventFilter(this);
  setAcceptDrops(true);

  display_timer_ = new QTimer(this);
  display_timer_->setInterval(kDisplayPeriodMs);
  connect(display_timer_, &QTimer::timeout, this, [this] { refreshFromHaptics(); });

  // Interactive (cheaper) frames while something moves, a full-quality one when it settles.
  settle_timer_ = new QTimer(this);
  settle_timer_->setSingleShot(true);
  settle_timer_->setInterval(kSettleMs);
  connect(settle_timer_, &QTimer::timeout, this, [this] {
    if (!camera_interacting_ && !slider_dragging_) {
      renderStill();
    }
  });
  connect(view_, &VtkView::interactionStarted, this, [this] {
    camera_interacting_ = true;
    noteMotion();
  });
  connect(view_, &VtkView::interactionEnded, this, [this] {
    camera_interacting_ = false;
    settle_timer_->start();
  });
  connect(view_, &VtkView::frameRendered, this, [this] {
    if (actors_ != nullptr && view_->frameCount() > upload_frame_ + 1) {
      // The first frame of a scene also compiles shaders and uploads the volume.
      actors_->adaptQuality(view_->lastFrameMs());
    }
    if (upload_pending_ && view_->frameCount() > upload_frame_) {
      upload_pending_ = false;
      if (!loader_->busy()) hideProgress();
    }
  });
  clock_.start();
  slider_->setEnabled(false);
  spin_->setEnabled(false);
  haptics_panel_->setEnabled(false);
  updateWindowTitle();
  updateHapticsPanel();
  updateStatus();
  resize(1280, 860);
}

MainWindow::MainWindow(ViewerScene scene, QWidget* parent) : MainWindow(parent) { setScene(std::move(scene)); }

MainWindow::~MainWindow() {
  hotplug_.reset();  // joins its polling thread
  delete loader_;  // cancels and waits for the worker
  loader_ = nullptr;
  teardownScene();
  if (view_->context() != nullptr) {
    view_->makeCurrent();
    marker_.reset();
    view_->doneCurrent();
  }
  marker_.reset();
}

void MainWindow::buildUi() {
  auto* central = new QWidget(this);
  auto* layout = new QVBoxLayout(central);
  layout->setContentsMargins(4, 4, 4, 4);
  layout->setSpacing(4);

  auto* controls = new QHBoxLayout();
  iso_label_ = new QLabel("Isovalue", central);
  slider_ = new HistogramSlider(central);
  slider_->setObjectName("isovalueSlider");
  slider_->setRange(0, kSliderSteps);
  slider_->setMinimumWidth(240);
  slider_->setToolTip(
      "Isosurface value: the rendered and the felt surface follow it live. Behind the slider: the "
      "volume's histogram (log scale).");
  spin_ = new QDoubleSpinBox(central);
  spin_->setObjectName("isovalueSpinBox");
  spin_->setKeyboardTracking(false);
  spin_->setMinimumWidth(90);
  spin_->setToolTip("Isovalue in the data's units (HU for CT)");
  controls->addWidget(iso_label_);
  controls->addWidget(slider_, 1);
  controls->addWidget(spin_);
  notices_ = new LoadNoticePanel(central);
  connect(notices_, &LoadNoticePanel::reloadRequested, this,
          [this](const runtime::SceneSpec& spec, const fs::path& opened) { openScene(spec, opened); });
  layout->addWidget(notices_);
  layout->addLayout(controls);
  layout->addWidget(view_, 1);
  setCentralWidget(central);

  connect(slider_, &QSlider::valueChanged, this, &MainWindow::onSliderMoved);
  connect(slider_, &QSlider::sliderPressed, this, [this] {
    slider_dragging_ = true;
    noteMotion();
  });
  connect(slider_, &QSlider::sliderReleased, this, [this] {
    slider_dragging_ = false;
    settle_timer_->start();
  });
  connect(spin_, &QDoubleSpinBox::valueChanged, this, &MainWindow::onSpinChanged);

  status_label_ = new QLabel(this);
  status_label_->setObjectName("hapticStatus");
  status_label_->setTextInteractionFlags(Qt::TextSelectableByMouse);
  statusBar()->addWidget(status_label_, 1);
  // A message (a load notice, "Loading cancelled") replaces the statistics while it lasts; the
  // status bar alone leaves both painted over each other once the label's text changes.
  connect(statusBar(), &QStatusBar::messageChanged, status_label_,
          [this](const QString& message) { status_label_->setVisible(message.isEmpty()); });

  progress_box_ = new QWidget(this);
  auto* progress_layout = new QHBoxLayout(progress_box_);
  progress_layout->setContentsMargins(0, 0, 0, 0);
  progress_label_ = new QLabel(progress_box_);
  progress_label_->setObjectName("progressLabel");
  progress_bar_ = new QProgressBar(progress_box_);
  progress_bar_->setObjectName("progressBar");
  progress_bar_->setFixedWidth(160);
  progress_bar_->setMaximumHeight(16);
  progress_cancel_ = new QToolButton(progress_box_);
  progress_cancel_->setObjectName("progressCancel");
  progress_cancel_->setText("Cancel");
  progress_cancel_->setToolTip("Stop loading; what is open stays (Esc)");
  progress_layout->addWidget(progress_label_);
  progress_layout->addWidget(progress_bar_);
  progress_layout->addWidget(progress_cancel_);
  statusBar()->addPermanentWidget(progress_box_);
  progress_box_->hide();
  connect(progress_cancel_, &QToolButton::clicked, this, &MainWindow::cancelLoading);
}

void MainWindow::buildDocks() {
  // ---- Display: rendering mode, preset, standard views, clipping, markers.
  auto* display = new QWidget(this);
  auto* display_layout = new QVBoxLayout(display);
  display_layout->setContentsMargins(6, 6, 6, 6);
  auto* form = new QFormLayout();
  mode_box_ = new QComboBox(display);
  mode_box_->setObjectName("renderMode");
  for (const RenderMode m : {RenderMode::kIsosurface, RenderMode::kComposite, RenderMode::kMip}) {
    mode_box_->addItem(q(modeName(m)), static_cast<int>(m));
  }
  mode_box_->setToolTip("Isosurface: the surface you feel. Composite: translucent tissue by preset. MIP: "
                        "maximum intensity projection.");
  preset_box_ = new QComboBox(display);
  preset_box_->setObjectName("volumePreset");
  for (const VolumePreset p : {VolumePreset::kBone, VolumePreset::kSoftTissue, VolumePreset::kSkin}) {
    preset_box_->addItem(q(presetName(p)), static_cast<int>(p));
  }
  preset_box_->setToolTip("Transfer function of the composite mode (CT presets, in HU)");
  form->addRow("Rendering", mode_box_);
  form->addRow("Preset", preset_box_);
  display_layout->addLayout(form);

  auto* views = new QGroupBox("Views", display);
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
    connect(button, &QPushButton::clicked, this, [this, v] { setStandardView(v); });
    grid->addWidget(button, b.row, b.column);
  }
  auto* reset_view = new QPushButton("Reset view", views);
  reset_view->setObjectName("resetView");
  connect(reset_view, &QPushButton::clicked, this, [this] {
    resetCamera();
    view_->requestRender();
  });
  grid->addWidget(reset_view, 3, 0, 1, 2);
  display_layout->addWidget(views);

  clip_group_ = new QGroupBox("Clipping plane", display);
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
  display_layout->addWidget(clip_group_);

  marker_box_ = new QCheckBox("Orientation marker", display);
  marker_box_->setChecked(prefs_.orientation_marker);
  device_box_ = new QCheckBox("Show the device tool (wire)", display);
  device_box_->setChecked(prefs_.show_device);
  display_layout->addWidget(marker_box_);
  display_layout->addWidget(device_box_);
  display_layout->addStretch(1);

  connect(mode_box_, &QComboBox::currentIndexChanged, this,
          [this](int i) { setRenderMode(static_cast<RenderMode>(mode_box_->itemData(i).toInt())); });
  connect(preset_box_, &QComboBox::currentIndexChanged, this,
          [this](int i) { setPreset(static_cast<VolumePreset>(preset_box_->itemData(i).toInt())); });
  connect(clip_group_, &QGroupBox::toggled, this, [this] { updateClipFromWidgets(); });
  connect(clip_axis_, &QComboBox::currentIndexChanged, this, [this] { updateClipFromWidgets(); });
  connect(clip_position_, &QSlider::valueChanged, this, [this] {
    noteMotion();
    updateClipFromWidgets();
  });
  connect(clip_flip_, &QCheckBox::toggled, this, [this] { updateClipFromWidgets(); });
  connect(marker_box_, &QCheckBox::toggled, this, &MainWindow::setOrientationMarkerVisible);
  connect(device_box_, &QCheckBox::toggled, this, &MainWindow::setDeviceToolVisible);

  display_dock_ = new QDockWidget("Display", this);
  display_dock_->setObjectName("displayDock");
  display_dock_->setWidget(display);
  addDockWidget(Qt::RightDockWidgetArea, display_dock_);

  // ---- Haptics.
  haptics_panel_ = new HapticsPanel(this);
  haptics_dock_ = new QDockWidget("Haptics", this);
  haptics_dock_->setObjectName("hapticsDock");
  {
    auto* haptics_box = new QWidget(this);
    auto* haptics_layout = new QVBoxLayout(haptics_box);
    haptics_layout->setContentsMargins(0, 0, 0, 0);
    haptics_layout->setSpacing(0);
    haptics_layout->addWidget(recorder_->makeDockControls(haptics_box));
    haptics_layout->addWidget(haptics_panel_, 1);
    haptics_dock_->setWidget(haptics_box);
  }
  addDockWidget(Qt::RightDockWidgetArea, haptics_dock_);
  connect(haptics_panel_, &HapticsPanel::startStopRequested, this, [this](bool run) {
    if (run) {
      startHaptics();
    } else {
      stopHaptics();
    }
  });
  connect(haptics_panel_, &HapticsPanel::toolRequested, this,
          [this](int index, double spacing_m) { selectTool(index, spacing_m); });
  connect(haptics_panel_, &HapticsPanel::gainsChanged, this, &MainWindow::setGains);
  connect(haptics_panel_, &HapticsPanel::resetDeviceRequested, this, [this] {
    if (hasScene()) setDevicePose(scene_.X_WT_initial);
  });
  connect(haptics_panel_, &HapticsPanel::rescanRequested, this, &MainWindow::rescanDevices);
  connect(haptics_panel_, &HapticsPanel::deviceChoiceRequested, this, [this](int index) { chooseDevice(index); });

  // ---- Strip chart.
  chart_ = new StripChart(this);
  chart_dock_ = new QDockWidget("Force and haptic thread timing", this);
  chart_dock_->setObjectName("chartDock");
  chart_dock_->setWidget(chart_);
  addDockWidget(Qt::BottomDockWidgetArea, chart_dock_);
  // Display and Haptics share the right side as tabs (Haptics in front): both together would be
  // taller than a laptop screen.
  tabifyDockWidget(display_dock_, haptics_dock_);
  haptics_dock_->raise();
  resizeDocks({chart_dock_}, {190}, Qt::Vertical);
  resizeDocks({haptics_dock_}, {300}, Qt::Horizontal);
}

void MainWindow::buildMenus() {
  // ---- File.
  QMenu* file = menuBar()->addMenu("&File");
  QAction* open_dicom = file->addAction("Open &DICOM Folder...", this, &MainWindow::openDicomFolderDialog);
  open_dicom->setShortcut(QKeySequence("Ctrl+D"));
  QAction* open_volume = file->addAction("&Open Volume File (NRRD, MetaImage)...", this,
                                         &MainWindow::openVolumeFileDialog);
  open_volume->setShortcut(QKeySequence::Open);
  QAction* open_scene = file->addAction("Open &Scene...", this, &MainWindow::openSceneFileDialog);
  open_scene->setShortcut(QKeySequence("Ctrl+Shift+O"));
  recent_menu_ = file->addMenu("Open &Recent");
  recent_menu_->setObjectName("recentFilesMenu");
  rebuildRecentMenu();
  file->addSeparator();
  replay_->addFileMenuActions(file);
  file->addSeparator();
  QAction* shot = file->addAction("Save Screens&hot...", this, [this] {
    const QString path = QFileDialog::getSaveFileName(this, "Save a screenshot of the window",
                                                      QDir(prefs_.last_folder).filePath("volume-haptics.png"),
                                                      "PNG images (*.png)");
    if (!path.isEmpty() && !saveScreenshot(path)) {
      reportError(path, path + ": the screenshot could not be written");
    }
  });
  shot->setShortcut(QKeySequence("Ctrl+Shift+S"));
  file->addSeparator();
  QAction* quit = file->addAction("&Quit", this, &QWidget::close);
  quit->setShortcut(QKeySequence::Quit);

  // ---- View.
  QMenu* viewMenu = menuBar()->addMenu("&View");
  mode_actions_ = new QActionGroup(this);
  const char* mode_keys[] = {"Ctrl+1", "Ctrl+2", "Ctrl+3"};
  int k = 0;
  for (const RenderMode m : {RenderMode::kIsosurface, RenderMode::kComposite, RenderMode::kMip}) {
    QAction* a = viewMenu->addAction(q(modeName(m)), this, [this, m] { setRenderMode(m); });
    a->setCheckable(true);
    a->setData(static_cast<int>(m));
    a->setShortcut(QKeySequence(mode_keys[k++]));
    mode_actions_->addAction(a);
  }
  QMenu* presets = viewMenu->addMenu("Composite &Preset");
  preset_actions_ = new QActionGroup(this);
  for (const VolumePreset p : {VolumePreset::kBone, VolumePreset::kSoftTissue, VolumePreset::kSkin}) {
    QAction* a = presets->addAction(q(presetName(p)), this, [this, p] {
      setPreset(p);
      setRenderMode(RenderMode::kComposite);
    });
    a->setCheckable(true);
    a->setData(static_cast<int>(p));
    preset_actions_->addAction(a);
  }
  viewMenu->addSeparator();
  QAction* reset = viewMenu->addAction("&Reset View", this, [this] {
    resetCamera();
    view_->requestRender();
  });
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
  QMenu* standard = viewMenu->addMenu("Standard &Views");
  for (const ViewEntry& e : entries) {
    const StandardView v = e.view;
    QAction* a = standard->addAction(e.text, this, [this, v] { setStandardView(v); });
    a->setShortcut(QKeySequence(e.key));
    addAction(a);  // shortcuts work while the menu is closed
  }
  QAction* focus = viewMenu->addAction("&Focus on the Tool", this, &MainWindow::focusOnTool);
  focus->setShortcut(QKeySequence("Ctrl+F"));
  viewMenu->addSeparator();
  marker_action_ = viewMenu->addAction("Orientation &Marker", this, &MainWindow::setOrientationMarkerVisible);
  marker_action_->setCheckable(true);
  marker_action_->setChecked(prefs_.orientation_marker);
  marker_action_->setShortcut(QKeySequence("Ctrl+M"));
  clip_action_ = viewMenu->addAction("&Clipping Plane", this, [this](bool on) { clip_group_->setChecked(on); });
  clip_action_->setCheckable(true);
  clip_action_->setShortcut(QKeySequence("Ctrl+K"));
  device_action_ = viewMenu->addAction("&Device Tool", this, &MainWindow::setDeviceToolVisible);
  device_action_->setCheckable(true);
  device_action_->setChecked(prefs_.show_device);
  QMenu* colours = viewMenu->addMenu("C&olours");
  colours->addAction("Background (top)...", this, [this] { chooseColour(&Preferences::background_top, "Background, top"); });
  colours->addAction("Background (bottom)...", this,
                     [this] { chooseColour(&Preferences::background_bottom, "Background, bottom"); });
  colours->addAction("Surface...", this, [this] { chooseColour(&Preferences::surface, "Isosurface colour"); });
  colours->addAction("Tool (proxy)...", this, [this] { chooseColour(&Preferences::tool, "Tool colour"); });
  colours->addAction("Device (wire)...", this, [this] { chooseColour(&Preferences::device, "Device colour"); });
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
  viewMenu->addSeparator();
  viewMenu->addAction(display_dock_->toggleViewAction());
  viewMenu->addAction(haptics_dock_->toggleViewAction());
  viewMenu->addAction(chart_dock_->toggleViewAction());

  // ---- Haptics.
  QMenu* hapticsMenu = menuBar()->addMenu("&Haptics");
  haptics_action_ = hapticsMenu->addAction("&Run Haptic Thread", this, [this](bool on) {
    if (on) {
      startHaptics();
    } else {
      stopHaptics();
    }
  });
  haptics_action_->setCheckable(true);
  haptics_action_->setShortcut(QKeySequence("Ctrl+H"));
  QAction* reset_device = hapticsMenu->addAction("Reset &Device", this, [this] {
    if (hasScene()) setDevicePose(scene_.X_WT_initial);
  });
  reset_device->setShortcut(QKeySequence("Ctrl+Home"));
  QAction* touch = hapticsMenu->addAction("&Touch the Surface", this, [this] {
    if (!touchSurface(0.003)) statusBar()->showMessage("No simulated device, or no surface towards the volume's centre", 4000);
  });
  touch->setShortcut(QKeySequence("Ctrl+T"));
  touch->setToolTip("Moves the simulated device straight towards the volume's centre until the tool rests on the surface");
  hapticsMenu->addSeparator();
  hapticsMenu->addAction(recorder_->recordAction());
  hapticsMenu->addAction(recorder_->markerAction());
  addAction(recorder_->markerAction());  // M works wherever the focus is in the window
  hapticsMenu->addSeparator();
  device_menu_ = hapticsMenu->addMenu("De&vice");
  device_actions_ = new QActionGroup(this);
  device_actions_->setExclusive(true);

  // ---- Help.
  QMenu* help = menuBar()->addMenu("H&elp");
  QAction* controls = help->addAction("&Controls", this, [this] {
    QMessageBox box(QMessageBox::Information, "Controls", kControlsHtml, QMessageBox::Close, this);
    box.setTextFormat(Qt::RichText);
    box.exec();
  });
  controls->setShortcut(QKeySequence::HelpContents);
  help->addAction("Load &Notes", this, [this] { notices_->reopen(); })
      ->setStatusTip("What the loader corrected or chose for the open scan (gantry tilt, missing slices, series)");
  help->addAction("&About VolumeHaptics", this, [this] { showAboutDialog(this); });
  help->addAction("About &Qt", qApp, &QApplication::aboutQt);

  QAction* cancel = new QAction(this);
  cancel->setShortcut(QKeySequence(Qt::Key_Escape));
  cancel->setShortcutContext(Qt::WindowShortcut);
  connect(cancel, &QAction::triggered, this, [this] {
    if (loader_ != nullptr && loader_->busy()) cancelLoading();
  });
  addAction(cancel);

  // Reflect the preferences.
  for (QAction* a : mode_actions_->actions()) a->setChecked(a->data().toInt() == static_cast<int>(prefs_.mode));
  for (QAction* a : preset_actions_->actions()) a->setChecked(a->data().toInt() == static_cast<int>(prefs_.preset));
  {
    const QSignalBlocker b1(mode_box_);
    const QSignalBlocker b2(preset_box_);
    mode_box_->setCurrentIndex(mode_box_->findData(static_cast<int>(prefs_.mode)));
    preset_box_->setCurrentIndex(preset_box_->findData(static_cast<int>(prefs_.preset)));
  }
  preset_box_->setEnabled(prefs_.mode == RenderMode::kComposite);
}

void MainWindow::connectLoader() {
  connect(loader_, &SceneLoader::progress, this,
          [this](const QString& stage, int percent) { showProgress(stage, percent, true); });
  connect(loader_, &SceneLoader::sceneLoaded, this, &MainWindow::onSceneLoaded);
  connect(loader_, &SceneLoader::toolBuilt, this, &MainWindow::onToolBuilt);
  connect(loader_, &SceneLoader::seriesListed, this,
          [this](const QString& folder, std::shared_ptr<std::vector<io::DicomSeriesInfo>> series) {
            onSeriesListed(folder, *series);
          });
  connect(loader_, &SceneLoader::failed, this, [this](const QString& what, const QString& message) {
    haptics_panel_->setBuilding(false);
    updateHapticsPanel();
    reportError(what, message);
  });
  connect(loader_, &SceneLoader::cancelled, this, [this] {
    haptics_panel_->setBuilding(false);
    updateHapticsPanel();
    statusBar()->showMessage("Loading cancelled; what was open is kept", 4000);
  });
  connect(loader_, &SceneLoader::idle, this, [this] {
    if (!upload_pending_) hideProgress();
  });
}

// ---- Scenes --------------------------------------------------------------------------------------

void MainWindow::teardownScene() {
  if (replay_ != nullptr) replay_->onSceneTeardown();
  stopHaptics();
  if (actors_ != nullptr) {
    // VTK props release their GL objects when they leave the renderer: give them the context.
    if (view_->context() != nullptr) {
      view_->makeCurrent();
      actors_.reset();
      view_->doneCurrent();
    }
    actors_.reset();
  }
  scene_.haptics.reset();  // joins nothing: stopped above
}

void MainWindow::setScene(ViewerScene scene) {
  if (scene.volume.image == nullptr) {
    throw std::invalid_argument("MainWindow: the scene's volume has no image to render");
  }
  if (loader_ != nullptr && loader_->busy()) loader_->cancel();  // e.g. a tool built for the old scene
  teardownScene();
  scene_ = std::move(scene);
  installScene();
  showLoadNotices();
}

void MainWindow::showLoadNotices() {
  const io::VolumeInfo& info = scene_.volume.info;
  notices_->setLoaded(q(scene_.title), scene_.spec, info, scene_.opened);
  for (const std::string& n : info.notices) std::cerr << "volume-haptics: note: " << n << '\n';
  const std::string first = primaryNotice(info.notices);
  if (first.empty()) return;
  QString text = "Note: " + q(first);
  if (info.notices.size() > 1) text += QString(" (+%1 more, see Help > Load Notes)").arg(info.notices.size() - 1);
  statusBar()->showMessage(text, kNoticeStatusMs);
}

void MainWindow::installScene() {
  // Value range: the field's, else the image's.
  if (scene_.volume.field != nullptr) {
    value_min_ = scene_.volume.field->minValue();
    value_max_ = scene_.volume.field->maxValue();
  } else {
    double range[2];
    scene_.volume.image->GetScalarRange(range);
    value_min_ = range[0];
    value_max_ = range[1];
  }
  if (!(value_max_ > value_min_)) value_max_ = value_min_ + 1.0;
  isovalue_ = std::clamp(scene_.isovalue, value_min_, value_max_);
  const bool hounsfield = scene_.volume.info.value_unit == "HU";

  // A scene file's gains are part of its experiment; plain volumes get the remembered ones.
  if (scene_.scene_file) {
    gains_ = scene_.gains;
  }
  if (scene_.haptics != nullptr) scene_.haptics->setGains(gains_);

  SceneActorsSpec spec;
  spec.image = scene_.volume.image;
  if (scene_.volume.field != nullptr) spec.direction_W = scene_.volume.field->geometry().direction_W;
  spec.isovalue = isovalue_;
  if (scene_.tool != nullptr) {
    spec.tool_mesh_T = scene_.tool->mesh_T;
    spec.p_TCm_m = scene_.tool->mass.p_TCm_m;
  }
  spec.show_device = scene_.device != nullptr && scene_.haptics != nullptr && prefs_.show_device;
  spec.hounsfield = hounsfield;
  actors_ = std::make_unique<SceneActors>(view_->renderer(), spec);
  actors_->setProxyPose(scene_.X_WT_initial);
  actors_->setDevicePose(scene_.X_WT_initial);
  actors_->setRenderMode(prefs_.mode, prefs_.preset);
  shown_X_WP_ = scene_.X_WT_initial;
  shown_X_WD_ = scene_.X_WT_initial;
  shown_contacts_ = -1;
  shown_force_W_N_.setZero();
  have_snapshot_ = false;
  snapshot_ = runtime::HapticSnapshot{};
  if (welcome_ != nullptr) welcome_->SetVisibility(false);
  marker_->setVisible(prefs_.orientation_marker);
  slider_->setEnabled(true);
  spin_->setEnabled(true);
  haptics_panel_->setEnabled(true);
  applyColours();

  // Isovalue widgets with the histogram.
  if (!scene_.histogram.has_value()) scene_.histogram = computeHistogram(scene_.volume.image, 256);
  const std::string& unit = scene_.volume.info.value_unit;
  iso_label_->setText(q(unit.empty() ? "Isovalue" : "Isovalue [" + unit + "]"));
  {
    const QSignalBlocker block_slider(slider_);
    const QSignalBlocker block_spin(spin_);
    const double range = value_max_ - value_min_;
    spin_->setDecimals(decimalsFor(range));
    spin_->setRange(value_min_, value_max_);
    spin_->setSingleStep(range >= 100.0 ? std::max(1.0, std::round(range / 200.0)) : range / 200.0);
    spin_->setValue(isovalue_);
    slider_->setValue(valueToSlider(isovalue_));
  }
  slider_->setHistogram(*scene_.histogram, value_min_, value_max_, hounsfield);

  // Tools: the catalog plus the scene's own tool.
  tools_ = toolCatalog(runtime::sharedDatasetsDir());
  tool_index_ = findOrAddSceneTool(tools_, scene_.tool_spec);

  resetCamera();
  updateClipFromWidgets();
  updateHint();
  updateHapticsPanel();
  updateWindowTitle();
  chart_->clear();
  updateStatus();
  recorder_->updateUi();
  view_->requestRender();
}

void MainWindow::openPath(const QString& path) {
  const fs::path p = fs::path(path.toStdString());
  std::error_code ec;
  if (path.isEmpty() || !fs::exists(p, ec)) {
    reportError(path, path + ": no such file or folder");
    return;
  }
  prefs_.last_folder = QFileInfo(path).absolutePath();
  if (fs::is_directory(p, ec)) {
    loader_->listSeries(p);
    return;
  }
  std::string ext = p.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  if (ext == ".vhrec") {
    replay_->openRecording(p);
    return;
  }
  if (ext == ".json") {
    try {
      openScene(runtime::loadSceneFile(p), p);
    } catch (const std::exception& e) {
      reportError(path, q(e.what()));
    }
    return;
  }
  openScene(runtime::sceneForVolume(p), p);
}

void MainWindow::openScene(const runtime::SceneSpec& spec, const fs::path& opened) {
  loader_->loadScene(spec, opened);
  haptics_panel_->setEnabled(false);
}

void MainWindow::openDicomSeries(const io::DicomSeriesInfo& series, int phase) {
  if (series.files.empty()) {
    reportError(q(series.folder.string()), q(series.folder.string()) + ": the chosen series has no files");
    return;
  }
  // The folder and the series UID (what a recording's scene names); without a UID, one file of
  // the series, which loadVolume() reads as exactly that series.
  runtime::SceneSpec spec = runtime::sceneForVolume(series.series_uid.empty() ? series.files.front() : series.folder);
  spec.volume.series = series.series_uid;
  spec.volume.phase = phase;
  loader_->loadScene(spec, series.folder);
  haptics_panel_->setEnabled(false);
}

void MainWindow::onSeriesListed(const QString& folder, const std::vector<io::DicomSeriesInfo>& series) {
  if (series.empty()) {
    reportError(folder, folder + ": no DICOM image series found in the folder");
    return;
  }
  if (series.size() == 1 || !interactive_) {
    const auto largest = std::max_element(series.begin(), series.end(), [](const auto& a, const auto& b) {
      return a.slice_count < b.slice_count;
    });
    openDicomSeries(*largest);
    return;
  }
  hideProgress();
  SeriesChooserDialog dialog(folder, series, this);
  if (dialog.exec() == QDialog::Accepted && dialog.selectedRow() >= 0) {
    openDicomSeries(dialog.model()->series(dialog.selectedRow()), dialog.selectedPhase());
  }
}

void MainWindow::onSceneLoaded(std::shared_ptr<LoadedViewerScene> loaded) {
  haptics_panel_->setEnabled(true);
  ViewerScene v = makeViewerScene(loaded->scene, loaded->device, std::move(loaded->haptics));
  v.histogram = std::move(loaded->histogram);
  v.opened = loaded->opened;
  if (!loaded->title.empty()) v.title = loaded->title;
  const std::string& description = loaded->scene.volume.info.description;
  if (!description.empty() && loaded->scene.volume.info.format == "DICOM" && description != v.title) {
    v.title += " - " + description;
  }
  showProgress("Uploading the volume to the GPU", 95, false);
  try {
    setScene(std::move(v));
  } catch (const std::exception& e) {
    hideProgress();
    reportError(q(loaded->title), q(e.what()));
    return;
  }
  upload_pending_ = true;
  upload_frame_ = view_->frameCount();
  if (!loaded->opened.empty()) {
    prefs_.addRecentFile(q(fs::absolute(loaded->opened).lexically_normal().string()));
    rebuildRecentMenu();
  }
  last_error_.clear();
  if (auto_start_haptics_) startHaptics();
  emit sceneLoaded();
}

bool MainWindow::loading() const noexcept { return (loader_ != nullptr && loader_->busy()) || upload_pending_; }

void MainWindow::cancelLoading() {
  if (loader_ != nullptr) loader_->cancel();
  haptics_panel_->setEnabled(hasScene());
  hideProgress();
}

void MainWindow::reportError(const QString& what, const QString& message) {
  last_error_ = message;
  hideProgress();
  haptics_panel_->setEnabled(hasScene());
  std::cerr << "volume-haptics: " << message.toStdString() << '\n';
  emit loadFailed(message);
  if (!interactive_) return;
  auto* box = new QMessageBox(QMessageBox::Critical, "VolumeHaptics",
                              QString("Cannot open %1").arg(QFileInfo(what).fileName().isEmpty() ? what
                                                                                                 : QFileInfo(what).fileName()),
                              QMessageBox::Ok, this);
  box->setObjectName("errorBox");
  box->setInformativeText(message + "\n\n" +
                          (hasScene() ? "What was open before is kept."
                                      : "Open another file with the File menu, or drop it on the window."));
  box->setAttribute(Qt::WA_DeleteOnClose);
  box->open();  // window-modal, does not block the haptic display
}

void MainWindow::showProgress(const QString& stage, int percent, bool cancellable) {
  progress_label_->setText(stage);
  if (percent < 0) {
    progress_bar_->setRange(0, 0);  // busy indicator
  } else {
    progress_bar_->setRange(0, 100);
    progress_bar_->setValue(percent);
  }
  progress_cancel_->setVisible(cancellable);
  progress_box_->show();
}

void MainWindow::hideProgress() { progress_box_->hide(); }

void MainWindow::rebuildRecentMenu() {
  recent_menu_->clear();
  for (const QString& path : prefs_.recent_files) {
    QAction* a = recent_menu_->addAction(QFileInfo(path).fileName().isEmpty() ? path : QFileInfo(path).fileName(),
                                         this, [this, path] { openPath(path); });
    a->setToolTip(path);
    a->setStatusTip(path);
  }
  if (!prefs_.recent_files.isEmpty()) {
    recent_menu_->addSeparator();
    recent_menu_->addAction("Clear List", this, [this] {
      prefs_.recent_files.clear();
      rebuildRecentMenu();
    });
  }
  recent_menu_->setEnabled(!prefs_.recent_files.isEmpty());
}

void MainWindow::openDicomFolderDialog() {
  const QString folder =
      QFileDialog::getExistingDirectory(this, "Open a DICOM folder", prefs_.last_folder, QFileDialog::ShowDirsOnly);
  if (!folder.isEmpty()) openPath(folder);
}

void MainWindow::openVolumeFileDialog() {
  const QString file = QFileDialog::getOpenFileName(this, "Open a volume file", prefs_.last_folder,
                                                    q(io::volumeFileDialogFilter()));
  if (!file.isEmpty()) openPath(file);
}

void MainWindow::openSceneFileDialog() {
  const QString file = QFileDialog::getOpenFileName(this, "Open a scene", prefs_.last_folder,
                                                    "Scenes (*.json);;All files (*)");
  if (!file.isEmpty()) openPath(file);
}

void MainWindow::dragEnterEvent(QDragEnterEvent* event) {
  const QMimeData* mime = event->mimeData();
  if (mime->hasUrls() && !mime->urls().isEmpty() && mime->urls().front().isLocalFile()) {
    event->acceptProposedAction();
  }
}

void MainWindow::dropEvent(QDropEvent* event) {
  const QList<QUrl> urls = event->mimeData()->urls();
  if (urls.isEmpty() || !urls.front().isLocalFile()) return;
  event->acceptProposedAction();
  QString path = urls.front().toLocalFile();
  // Several files of one DICOM series dropped together: open their folder.
  if (urls.size() > 1 && !QFileInfo(path).isDir()) path = QFileInfo(path).absolutePath();
  openPath(path);
}

runtime::LoadedScene MainWindow::currentLoadedScene() const {
  runtime::LoadedScene s;
  s.spec = scene_.spec;
  s.spec.tool = scene_.tool_spec;
  s.spec.gains = gains_;
  s.spec.volume.isovalue = isovalue_;
  s.spec.volume.isovalue_set = true;
  s.volume = scene_.volume;
  s.tool = scene_.tool;
  s.isovalue = isovalue_;
  s.X_WT_initial = scene_.X_WT_initial;
  return s;
}

// ---- Haptics -------------------------------------------------------------------------------------

runtime::SimulatedDevice* MainWindow::simulatedDevice() const noexcept {
  if (auto* fallback = dynamic_cast<devices::FallbackDevice*>(scene_.device.get())) {
    return fallback->usingFallback() ? fallback->simulated().get() : nullptr;
  }
  return dynamic_cast<runtime::SimulatedDevice*>(scene_.device.get());
}

vtkVolume* MainWindow::volumeProp() const noexcept { return actors_ != nullptr ? actors_->volume() : nullptr; }
vtkActor* MainWindow::proxyActor() const noexcept { return actors_ != nullptr ? actors_->proxyActor() : nullptr; }
vtkActor* MainWindow::deviceActor() const noexcept { return actors_ != nullptr ? actors_->deviceActor() : nullptr; }
QSlider* MainWindow::isovalueSlider() const noexcept { return slider_; }

bool MainWindow::hapticsRunning() const noexcept { return scene_.haptics != nullptr && scene_.haptics->running(); }

void MainWindow::startHaptics() {
  if (replay_ != nullptr && replay_->active()) {
    recorder_->showNotice("A recording is replayed: Close Replay first", 4000);
    return;
  }
  if (scene_.haptics != nullptr && !scene_.haptics->running()) {
    scene_.haptics->setIsovalue(isovalue_);
    scene_.haptics->setGains(gains_);
    scene_.haptics->start();
  }
  if (scene_.haptics != nullptr) display_timer_->start();
  updateHapticsPanel();
  updateStatus();
}

void MainWindow::stopHaptics() {
  if (display_timer_ != nullptr) display_timer_->stop();
  if (scene_.haptics != nullptr && scene_.haptics->running()) scene_.haptics->stop();
  if (recorder_ != nullptr) recorder_->onHapticsStopped();  // after the thread stopped
  if (haptics_panel_ != nullptr) updateHapticsPanel();
  updateStatus();
}

void MainWindow::setGains(const haptics::CouplingGains& gains) {
  if (!std::isfinite(gains.linear_N_per_m) || !std::isfinite(gains.angular_Nm_per_rad)) return;
  gains_ = gains;
  prefs_.linear_stiffness_N_per_m = gains.linear_N_per_m;
  prefs_.torsional_stiffness_Nm_per_rad = gains.angular_Nm_per_rad;
  if (scene_.haptics != nullptr) scene_.haptics->setGains(gains);
  haptics_panel_->setGains(gains);  // while recording, HapticThread::setGains() records a "gains" event
}

void MainWindow::selectTool(int choice_index, double point_spacing_m) {
  if (!hasScene() || scene_.volume.field == nullptr || choice_index < 0 ||
      choice_index >= static_cast<int>(tools_.size())) {
    return;
  }
  if (loader_->busy()) {
    statusBar()->showMessage("Busy loading; change the tool when it is done", 4000);
    updateHapticsPanel();
    return;
  }
  haptics::RendererOptions options;
  options.gains = gains_;
  recorder_->noteTool(q(tools_[static_cast<std::size_t>(choice_index)].label), point_spacing_m);
  haptics_panel_->setBuilding(true);
  loader_->buildTool(choice_index, tools_[static_cast<std::size_t>(choice_index)], point_spacing_m,
                     scene_.volume.field, isovalue_, options);
}

void MainWindow::onToolBuilt(std::shared_ptr<RebuiltTool> rebuilt) {
  haptics_panel_->setBuilding(false);
  if (!hasScene()) return;
  const bool was_running = hapticsRunning();
  stopHaptics();  // force ramped to zero before the tool changes under the user's hand
  scene_.tool = rebuilt->built.tool;
  scene_.X_WT_initial = rebuilt->built.X_WT_initial;
  scene_.point_spacing_m = rebuilt->built.point_spacing_m;
  tool_index_ = rebuilt->choice_index;
  const ToolChoice& choice = tools_[static_cast<std::size_t>(tool_index_)];
  scene_.tool_spec.mesh = choice.mesh;
  scene_.tool_spec.scale_to_m = choice.scale_to_m;
  scene_.tool_spec.point_spacing_m = rebuilt->built.point_spacing_m;
  scene_.tool_spec.point_count = 0;
  scene_.tool_spec.X_WT_initial.R_AB = choice.R_WT;
  if (scene_.device != nullptr) {
    if (runtime::SimulatedDevice* sim = simulatedDevice()) sim->setPose(scene_.X_WT_initial);
    scene_.haptics.reset();
    scene_.haptics = std::make_unique<runtime::HapticThread>(std::move(rebuilt->renderer), scene_.device, isovalue_);
    scene_.haptics->setGains(gains_);
  }
  actors_->setToolMesh(scene_.tool->mesh_T, scene_.tool->mass.p_TCm_m);
  actors_->setProxyPose(scene_.X_WT_initial);
  actors_->setDevicePose(scene_.X_WT_initial);
  actors_->setContacts({});
  actors_->setForce(Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero());
  shown_X_WP_ = shown_X_WD_ = scene_.X_WT_initial;
  have_snapshot_ = false;
  if (was_running) startHaptics();
  updateHapticsPanel();
  view_->requestRender();
  emit toolChanged();
}

void MainWindow::setDevice(std::shared_ptr<runtime::Device> device, const QString& limits_text) {
  device_limits_text_ = limits_text;
  if (!hasScene()) {
    scene_.device = std::move(device);
    updateHapticsPanel();
    return;
  }
  const bool was_running = hapticsRunning();
  haptics::Pose X_WP = have_snapshot_ ? snapshot_.X_WP : scene_.X_WT_initial;
  stopHaptics();
  scene_.haptics.reset();
  scene_.device = std::move(device);
  if (scene_.device != nullptr && scene_.tool != nullptr && scene_.volume.field != nullptr) {
    haptics::RendererOptions options;
    options.gains = gains_;
    auto renderer = std::make_unique<haptics::HapticRenderer>(scene_.volume.field, scene_.tool, options, X_WP, isovalue_);
    scene_.haptics = std::make_unique<runtime::HapticThread>(std::move(renderer), scene_.device, isovalue_);
    if (runtime::SimulatedDevice* sim = simulatedDevice()) sim->setPose(X_WP);
  }
  actors_->setDeviceVisible(scene_.haptics != nullptr && prefs_.show_device);
  have_snapshot_ = false;
  updateHint();
  if (was_running) startHaptics();
  updateHapticsPanel();
  view_->requestRender();
}

void MainWindow::updateHapticsPanel() {
  if (haptics_panel_ == nullptr) return;
  const bool replaying = replay_ != nullptr && replay_->active();  // the haptic thread waits
  haptics_panel_->setRunning(hapticsRunning(), scene_.haptics != nullptr && !replaying);
  if (haptics_action_ != nullptr) {
    const QSignalBlocker block(haptics_action_);
    haptics_action_->setEnabled(scene_.haptics != nullptr && !replaying);
    haptics_action_->setChecked(hapticsRunning());
  }
  haptics_panel_->setGains(gains_);
  if (hasScene()) {
    haptics_panel_->setTools(tools_, tool_index_);
    haptics_panel_->setPointShell(scene_.point_spacing_m,
                                  scene_.tool != nullptr ? scene_.tool->point_shell.size() : std::size_t{0});
  }
  QString name = "No device: haptics off";
  QString limits = device_limits_text_;
  if (scene_.device != nullptr) {
    name = q(scene_.device->name());
    if (limits.isEmpty()) {
      if (simulatedDevice() != nullptr) {
        limits = "Moved with the mouse and keys; its force is computed and shown, not felt.";
      }
      const QString reported = deviceLimitsText(*scene_.device);
      if (!reported.isEmpty()) limits += (limits.isEmpty() ? "" : "\n") + reported;
    }
  }
  haptics_panel_->setDevice(name, limits);
  syncDeviceChoice();
}

void MainWindow::setIsovalue(double isovalue) {
  if (!std::isfinite(isovalue) || !hasScene()) {
    return;
  }
  isovalue_ = std::clamp(isovalue, value_min_, value_max_);
  {
    const QSignalBlocker block_slider(slider_);
    const QSignalBlocker block_spin(spin_);
    slider_->setValue(valueToSlider(isovalue_));
    spin_->setValue(isovalue_);
  }
  actors_->setIsovalue(isovalue_);
  if (scene_.haptics != nullptr) {
    scene_.haptics->setIsovalue(isovalue_);
  }
  view_->requestRender();
}

double MainWindow::sliderToValue(int position) const {
  return value_min_ + (value_max_ - value_min_) * static_cast<double>(position) / kSliderSteps;
}

int MainWindow::valueToSlider(double value) const {
  const double t = (value - value_min_) / (value_max_ - value_min_);
  return static_cast<int>(std::lround(std::clamp(t, 0.0, 1.0) * kSliderSteps));
}

void MainWindow::onSliderMoved(int position) { setIsovalue(sliderToValue(position)); }
void MainWindow::onSpinChanged(double value) { setIsovalue(value); }

void MainWindow::setDevicePose(const haptics::Pose& X_WD) {
  runtime::SimulatedDevice* device = simulatedDevice();
  if (device == nullptr || !X_WD.allFinite() || !hasScene()) {
    return;
  }
  device->setPose(X_WD);
  // Show the target at once; the proxy follows with the next snapshot.
  actors_->setDevicePose(X_WD);
  shown_X_WD_ = X_WD;
  noteMotion();
  view_->requestRender();
}

bool MainWindow::touchSurface(double depth_m) {
  runtime::SimulatedDevice* device = simulatedDevice();
  if (device == nullptr || scene_.tool == nullptr || scene_.volume.field == nullptr) {
    return false;
  }
  const haptics::ScalarVolume& field = *scene_.volume.field;
  const haptics::PointShell& shell = scene_.tool->point_shell;
  const haptics::Pose X_WD = device->pose();
  const Eigen::Vector3d c_W = X_WD * scene_.tool->mass.p_TCm_m;
  const Eigen::Vector3d lo = field.boundsMin_W_m();
  const Eigen::Vector3d hi = field.boundsMax_W_m();
  const Eigen::Vector3d centre_W = 0.5 * (lo + hi);
  const double extent_m = (hi - lo).norm();
  Eigen::Vector3d dir_W = centre_W - c_W;
  if (dir_W.norm() < 1e-9) {
    dir_W = -Eigen::Vector3d::UnitZ();
  }
  dir_W.normalize();
  const double max_travel_m = (c_W - centre_W).norm() + extent_m;
  // Straight towards the centre first; where that ray slips through a hole in the surface, start
  // from points around it on rings perpendicular to the ray (up to 30% of the volume's size).
  const Eigen::Vector3d e1 = dir_W.unitOrthogonal();
  const Eigen::Vector3d e2 = dir_W.cross(e1);
  for (const double ring : {0.0, 0.05, 0.1, 0.2, 0.3}) {
    const int n = ring == 0.0 ? 1 : 8;
    for (int k = 0; k < n; ++k) {
      const double a = 2.0 * std::numbers::pi * k / n;
      haptics::Pose start = X_WD;
      start.p_AB_m += ring * extent_m * (std::cos(a) * e1 + std::sin(a) * e2);
      if (runtime::countPointsInside(field, shell, start, isovalue_) > 0) {
        continue;
      }
      const std::optional<double> free_m = runtime::firstContactDistance(
          field, shell, start, dir_W, max_travel_m, isovalue_, 0.05 * field.featureSize_m());
      if (!free_m) {
        continue;
      }
      haptics::Pose target = start;
      target.p_AB_m += (*free_m + std::max(0.0, depth_m)) * dir_W;
      if (ring == 0.0) {
        setDevicePose(target);
      } else {
        // Sideways through free space first, so the proxy follows the device, then in.
        setDevicePose(start);
        QTimer::singleShot(300, this, [this, target] { setDevicePose(target); });
      }
      return true;
    }
  }
  return false;
}

ViewCamera MainWindow::currentCamera() const {
  vtkCamera* cam = view_->renderer()->GetActiveCamera();
  ViewCamera c;
  double v[3];
  cam->GetPosition(v);
  c.position_W_m = Eigen::Vector3d(v[0], v[1], v[2]);
  cam->GetFocalPoint(v);
  c.focal_point_W_m = Eigen::Vector3d(v[0], v[1], v[2]);
  cam->GetViewUp(v);
  c.view_up_W = Eigen::Vector3d(v[0], v[1], v[2]);
  c.view_angle_deg = cam->GetViewAngle();
  c.parallel = cam->GetParallelProjection() != 0;
  c.parallel_scale_m = cam->GetParallelScale();
  const int* size = view_->renderer()->GetSize();
  c.viewport_height_px = std::max(1, size[1] > 0 ? size[1] : view_->height());
  return c;
}

double MainWindow::wheelStep_m() const {
  if (scene_.volume.field == nullptr) {
    return 1e-3;
  }
  const double diagonal =
      (scene_.volume.field->boundsMax_W_m() - scene_.volume.field->boundsMin_W_m()).norm();
  return std::clamp(diagonal / 200.0, 0.5e-3, 5e-3);
}

bool MainWindow::handleDeviceKey(QKeyEvent* e) {
  // Isovalue steps work with or without a device.
  if (e->key() == Qt::Key_BracketLeft || e->key() == Qt::Key_BracketRight) {
    setIsovalue(isovalue_ + (e->key() == Qt::Key_BracketRight ? 1.0 : -1.0) * spin_->singleStep());
    return true;
  }
  runtime::SimulatedDevice* device = simulatedDevice();
  if (device == nullptr) return false;
  const Eigen::Vector3d p_DCm = scene_.tool != nullptr ? scene_.tool->mass.p_TCm_m : Eigen::Vector3d::Zero();
  const ViewCamera camera = currentCamera();
  const haptics::Pose X_WD = device->pose();
  const bool shift = e->modifiers() & Qt::ShiftModifier;
  const double step_m = wheelStep_m();
  const double px = step_m / std::max(1e-12, camera.metresPerPixelAt(X_WD * p_DCm));
  double dx = 0.0, dy = 0.0;
  switch (e->key()) {
    case Qt::Key_Left: dx = -1.0; break;
    case Qt::Key_Right: dx = 1.0; break;
    case Qt::Key_Up: dy = -1.0; break;
    case Qt::Key_Down: dy = 1.0; break;
    case Qt::Key_PageUp:
      setDevicePose(moveAlongView(X_WD, camera, step_m));
      return true;
    case Qt::Key_PageDown:
      setDevicePose(moveAlongView(X_WD, camera, -step_m));
      return true;
    case Qt::Key_Home:
      setDevicePose(scene_.X_WT_initial);
      return true;
    default:
      return false;
  }
  if (shift) {
    setDevicePose(rotateTrackball(X_WD, camera, p_DCm, dx, dy, kKeyRotation_rad));
  } else {
    setDevicePose(dragInViewPlane(X_WD, camera, X_WD * p_DCm, dx * px, dy * px));
  }
  return true;
}

bool MainWindow::eventFilter(QObject* watched, QEvent* event) {
  if (watched != view_ || !hasScene()) {
    return QMainWindow::eventFilter(watched, event);
  }
  if (event->type() == QEvent::KeyPress) {
    return handleDeviceKey(static_cast<QKeyEvent*>(event));
  }
  runtime::SimulatedDevice* device = simulatedDevice();
  if (device == nullptr) {
    return QMainWindow::eventFilter(watched, event);
  }
  const Eigen::Vector3d p_DCm = scene_.tool != nullptr ? scene_.tool->mass.p_TCm_m
                                                       : Eigen::Vector3d::Zero();
  switch (event->type()) {
    case QEvent::MouseButtonPress: {
      auto* e = static_cast<QMouseEvent*>(event);
      const bool ctrl = e->modifiers() & Qt::ControlModifier;
      const bool shift = e->modifiers() & Qt::ShiftModifier;
      if (ctrl && e->button() == Qt::LeftButton) {
        drag_ = DragMode::kTranslate;
      } else if (ctrl && e->button() == Qt::RightButton) {
        drag_ = DragMode::kDepth;
      } else if (shift && !ctrl && e->button() == Qt::LeftButton) {
        drag_ = DragMode::kRotate;
      } else {
        return false;  // the camera's
      }
      drag_last_ = e->position();
      view_->setCursor(drag_ == DragMode::kRotate ? Qt::ClosedHandCursor : Qt::SizeAllCursor);
      return true;
    }
    case QEvent::MouseMove: {
      if (drag_ == DragMode::kNone) {
        return false;
      }
      auto* e = static_cast<QMouseEvent*>(event);
      const QPointF delta = (e->position() - drag_last_) * view_->devicePixelRatioF();
      drag_last_ = e->position();
      const ViewCamera camera = currentCamera();
      const haptics::Pose X_WD = device->pose();
      switch (drag_) {
        case DragMode::kTranslate:
          setDevicePose(dragInViewPlane(X_WD, camera, X_WD * p_DCm, delta.x(), delta.y()));
          break;
        case DragMode::kDepth:
          setDevicePose(moveAlongView(X_WD, camera,
                                      -delta.y() * camera.metresPerPixelAt(X_WD * p_DCm)));
          break;
        case DragMode::kRotate:
          setDevicePose(rotateTrackball(X_WD, camera, p_DCm, delta.x(), delta.y(),
                                        std::numbers::pi / camera.viewport_height_px));
          break;
        case DragMode::kNone:
          break;
      }
      return true;
    }
    case QEvent::MouseButtonRelease: {
      if (drag_ == DragMode::kNone) {
        return false;
      }
      drag_ = DragMode::kNone;
      view_->unsetCursor();
      return true;
    }
    case QEvent::MouseButtonDblClick:
      return drag_ != DragMode::kNone;
    case QEvent::Wheel: {
      auto* e = static_cast<QWheelEvent*>(event);
      if (!(e->modifiers() & Qt::ControlModifier)) {
        return false;
      }
      const double notches = e->angleDelta().y() / 120.0;
      setDevicePose(moveAlongView(device->pose(), currentCamera(), notches * wheelStep_m()));
      return true;
    }
    default:
      return false;
  }
}

bool MainWindow::refreshFromHaptics(bool update_status_now) {
  if (scene_.haptics == nullptr || !hasScene()) {
    return false;
  }
  scene_.haptics->latestSnapshot(snapshot_);
  if (snapshot_.tick == 0) {
    return false;  // nothing published yet
  }
  have_snapshot_ = true;
  bool changed = posesDiffer(snapshot_.X_WP, shown_X_WP_) ||
                 posesDiffer(snapshot_.X_WD, shown_X_WD_) || snapshot_.contacts != shown_contacts_ ||
                 (snapshot_.force_W_N - shown_force_W_N_).norm() > 0.01;
  // The tools always show the latest snapshot exactly; a new frame is asked for only when
  // something moved visibly.
  actors_->setProxyPose(snapshot_.X_WP);
  actors_->setDevicePose(snapshot_.X_WD);
  if (changed) {
    shown_X_WP_ = snapshot_.X_WP;
    shown_X_WD_ = snapshot_.X_WD;
    shown_contacts_ = snapshot_.contacts;
    shown_force_W_N_ = snapshot_.force_W_N;
    const int n = std::clamp(snapshot_.contacts_shown, 0, runtime::HapticSnapshot::kMaxContactsShown);
    actors_->setContacts(std::span<const Eigen::Vector3d>(snapshot_.contact_p_W_m.data(),
                                                          static_cast<std::size_t>(n)));
    // The force arrow starts at the contacts' centroid (or the proxy's centre of mass).
    Eigen::Vector3d origin_W = Eigen::Vector3d::Zero();
    if (n > 0) {
      for (int i = 0; i < n; ++i) {
        origin_W += snapshot_.contact_p_W_m[static_cast<std::size_t>(i)];
      }
      origin_W /= n;
    } else {
      origin_W = snapshot_.X_WP * (scene_.tool != nullptr ? scene_.tool->mass.p_TCm_m
                                                         : Eigen::Vector3d::Zero());
    }
    actors_->setForce(origin_W, snapshot_.force_W_N);
    noteMotion();
    view_->requestRender();
  }
  if (chart_dock_->isVisible()) {
    chart_->addSample(1e-3 * static_cast<double>(clock_.elapsed()), snapshot_.force_W_N.norm(),
                      snapshot_.solver.mean_tick_us, snapshot_.solver.max_tick_us, snapshot_.coupling.jitter_us);
  }
  if (--status_countdown_ <= 0 || update_status_now) {
    status_countdown_ = kStatusEveryTicks;
    updateStatus();
  }
  if (update_status_now) chart_->flush();
  return changed;
}

void MainWindow::noteMotion() {
  if (actors_ == nullptr) return;
  actors_->setInteractive(true);
  settle_timer_->start();  // restarts: the still frame comes kSettleMs after the last motion
}

void MainWindow::renderStill(bool best_quality) {
  settle_timer_->stop();
  if (actors_ == nullptr) return;
  if (actors_->interactive() || best_quality) {
    actors_->setInteractive(false);
    if (best_quality) {
      actors_->resetQuality();
    }
    view_->requestRender();
  }
}

void MainWindow::updateStatus() {
  if (status_label_ == nullptr) {
    return;
  }
  if (!hasScene()) {
    status_label_->setText("No scan open");
    return;
  }
  if (replay_ != nullptr && replay_->active()) {
    status_label_->setText("Replaying " + q(replay_->path().filename().string()) +
                           ": haptics stopped (Close Replay in the Replay dock to go live)");
    return;
  }
  if (scene_.haptics == nullptr) {
    status_label_->setText("Haptics off: the scene has no device");
    return;
  }
  if (!scene_.haptics->running()) {
    status_label_->setText("Haptic thread stopped (Haptics > Run, Ctrl+H)");
    return;
  }
  if (!have_snapshot_) {
    status_label_->setText("Haptic thread starting...");
    return;
  }
  // Two threads (paper section 3.2): the coupling thread renders the force at the device's
  // rate, the solver thread moves the proxy (HapticRenderer::tick()) at its own.
  const runtime::HapticSnapshot& s = snapshot_;
  QString text =
      QString::fromUtf8("Coupling %1 Hz (jitter %2 \u00b5s, misses %3)  |  Solver %4 Hz (tick %5 / %6 \u00b5s "
                        "mean / max, misses %7)  |  contacts %8  |  |F| %9 N  |  |\u03c4| %10 N\u00b7m")
          .arg(s.coupling.rate_Hz, 0, 'f', 0)
          .arg(s.coupling.jitter_us, 0, 'f', 0)
          .arg(static_cast<qulonglong>(s.coupling.deadline_misses))
          .arg(s.solver.rate_Hz, 0, 'f', 0)
          .arg(s.solver.mean_tick_us, 0, 'f', 1)
          .arg(s.solver.max_tick_us, 0, 'f', 1)
          .arg(static_cast<qulonglong>(s.solver.deadline_misses))
          .arg(s.contacts)
          .arg(s.force_W_N.norm(), 0, 'f', 2)
          .arg(s.torque_W_Nm.norm(), 0, 'f', 4);
  if (s.skipped_samples > 0) {
    text += QString("  |  solver skipped %1 device samples").arg(static_cast<qulonglong>(s.skipped_samples));
  }
  status_label_->setText(text);
  status_label_->setToolTip(
      "Coupling: the thread that reads the device and sends the force (virtual coupling), at the "
      "device's rate; jitter is the largest deviation of its wake-up interval from the period over "
      "the last second.\nSolver: the thread that moves the proxy against the surface; tick is its "
      "computing time per tick over the last second.\nMisses: ticks that started more than one period "
      "late (total).");
}

QString MainWindow::statusText() const {
  return status_label_ != nullptr ? status_label_->text() : QString();
}

void MainWindow::updateHint() {
  if (actors_ == nullptr) return;
  std::string hint = kHintCamera;
  if (simulatedDevice() != nullptr && scene_.haptics != nullptr) {
    hint += std::string("\n") + kHintDevice;
  } else if (scene_.device != nullptr) {
    hint += "\nDevice: " + scene_.device->name();
  } else {
    hint += "\nNo device in this scene: haptics off";
  }
  actors_->setHint(hint);
}

void MainWindow::updateWindowTitle() {
  QString title = "VolumeHaptics";
  if (!hasScene()) {
    setWindowTitle(title);
    return;
  }
  if (!scene_.title.empty()) title += " - " + q(scene_.title);
  const io::VolumeInfo& info = scene_.volume.info;
  if (scene_.volume.field != nullptr) {
    const auto& g = scene_.volume.field->geometry();
    const double lo_mm = g.spacing_m.minCoeff() * 1e3;
    const double hi_mm = g.spacing_m.maxCoeff() * 1e3;
    const QString spacing = hi_mm > lo_mm * 1.001
                                ? QString("%1..%2 mm").arg(lo_mm, 0, 'g', 3).arg(hi_mm, 0, 'g', 3)
                                : QString("%1 mm").arg(lo_mm, 0, 'g', 3);
    const QString facts = QString("%1 %2  %3x%4x%5  %6")
                              .arg(q(info.format), q(info.modality))
                              .arg(g.dims[0])
                              .arg(g.dims[1])
                              .arg(g.dims[2])
                              .arg(spacing)
                              .simplified();
    if (!facts.isEmpty()) title += " (" + facts + ")";
  }
  setWindowTitle(title);
}

// ---- Viewing ------------------------------------------------------------------------------------

void MainWindow::setRenderMode(RenderMode mode) {
  prefs_.mode = mode;
  {
    const QSignalBlocker block(mode_box_);
    mode_box_->setCurrentIndex(mode_box_->findData(static_cast<int>(mode)));
  }
  for (QAction* a : mode_actions_->actions()) a->setChecked(a->data().toInt() == static_cast<int>(mode));
  preset_box_->setEnabled(mode == RenderMode::kComposite);
  if (actors_ != nullptr) {
    actors_->setRenderMode(prefs_.mode, prefs_.preset);
    view_->requestRender();
  }
}

void MainWindow::setPreset(VolumePreset preset) {
  prefs_.preset = preset;
  {
    const QSignalBlocker block(preset_box_);
    preset_box_->setCurrentIndex(preset_box_->findData(static_cast<int>(preset)));
  }
  for (QAction* a : preset_actions_->actions()) a->setChecked(a->data().toInt() == static_cast<int>(preset));
  if (actors_ != nullptr) {
    actors_->setRenderMode(prefs_.mode, prefs_.preset);
    view_->requestRender();
  }
}

void MainWindow::fitCamera(const double direction_W[3], const double up_W[3], double zoom) {
  if (actors_ == nullptr) return;
  vtkRenderer* renderer = view_->renderer();
  vtkCamera* cam = renderer->GetActiveCamera();
  double bounds[6];
  actors_->volumeBounds_W(bounds);
  const double c[3] = {0.5 * (bounds[0] + bounds[1]), 0.5 * (bounds[2] + bounds[3]), 0.5 * (bounds[4] + bounds[5])};
  cam->SetFocalPoint(c);
  cam->SetPosition(c[0] + direction_W[0], c[1] + direction_W[1], c[2] + direction_W[2]);
  cam->SetViewUp(up_W[0], up_W[1], up_W[2]);
  cam->OrthogonalizeViewUp();
  renderer->ResetCamera();  // fits the visible props (volume and tools)
  cam->Zoom(zoom);          // the fit is to the props' bounding sphere: generous
  renderer->ResetCameraClippingRange();
}

void MainWindow::resetCamera() {
  if (actors_ == nullptr) return;
  // Default view: from the front (-y: anterior for LPS) turned 30 degrees to the patient's right
  // and 25 degrees up, +z up.
  vtkCamera* cam = view_->renderer()->GetActiveCamera();
  const double front[3] = {0.0, -1.0, 0.0};
  const double up[3] = {0.0, 0.0, 1.0};
  fitCamera(front, up, 1.0);
  cam->Azimuth(-30.0);
  cam->Elevation(25.0);
  cam->OrthogonalizeViewUp();
  view_->renderer()->ResetCamera();
  cam->Zoom(1.2);
  view_->renderer()->ResetCameraClippingRange();
}

void MainWindow::focusOnTool() {
  if (actors_ == nullptr || scene_.tool == nullptr) return;
  // Keep the viewing direction; look at the proxy's centre of mass from about 2.5 tool lengths.
  const haptics::Pose X_WP = have_snapshot_ ? snapshot_.X_WP : shown_X_WP_;
  const Eigen::Vector3d c_W = X_WP * scene_.tool->mass.p_TCm_m;
  const Eigen::Vector3d extent = scene_.tool->mesh_T.empty()
                                     ? Eigen::Vector3d(0.05, 0.05, 0.05)
                                     : Eigen::Vector3d(scene_.tool->mesh_T.boundsMax_T_m() - scene_.tool->mesh_T.boundsMin_T_m());
  vtkCamera* cam = view_->renderer()->GetActiveCamera();
  double dop[3];
  cam->GetDirectionOfProjection(dop);
  const double half_height_m = 0.75 * extent.norm();
  const double distance_m = half_height_m / std::tan(0.5 * cam->GetViewAngle() * std::numbers::pi / 180.0);
  cam->SetFocalPoint(c_W.x(), c_W.y(), c_W.z());
  cam->SetPosition(c_W.x() - distance_m * dop[0], c_W.y() - distance_m * dop[1], c_W.z() - distance_m * dop[2]);
  view_->renderer()->ResetCameraClippingRange();
  noteMotion();
  view_->requestRender();
}

void MainWindow::setStandardView(StandardView v) {
  // W = patient LPS: the camera sits on the named side of the patient.
  double dir[3] = {0, 0, 0};
  double up[3] = {0, 0, 1};
  switch (v) {
    case StandardView::kAnterior: dir[1] = -1; break;
    case StandardView::kPosterior: dir[1] = 1; break;
    case StandardView::kLeft: dir[0] = 1; break;
    case StandardView::kRight: dir[0] = -1; break;
    case StandardView::kSuperior:
      dir[2] = 1;
      up[2] = 0;
      up[1] = -1;  // anterior up
      break;
    case StandardView::kInferior:
      dir[2] = -1;
      up[2] = 0;
      up[1] = -1;
      break;
  }
  fitCamera(dir, up, 1.2);
  noteMotion();
  view_->requestRender();
}

void MainWindow::setClipping(bool enabled, ClipAxis axis, double fraction, bool flip) {
  {
    const QSignalBlocker b1(clip_group_);
    const QSignalBlocker b2(clip_axis_);
    const QSignalBlocker b3(clip_position_);
    const QSignalBlocker b4(clip_flip_);
    clip_group_->setChecked(enabled);
    clip_axis_->setCurrentIndex(clip_axis_->findData(static_cast<int>(axis)));
    clip_position_->setValue(static_cast<int>(std::lround(std::clamp(fraction, 0.0, 1.0) * 1000.0)));
    clip_flip_->setChecked(flip);
  }
  updateClipFromWidgets();
}

void MainWindow::updateClipFromWidgets() {
  const bool enabled = clip_group_->isChecked();
  if (clip_action_ != nullptr) {
    const QSignalBlocker block(clip_action_);
    clip_action_->setChecked(enabled);
  }
  if (actors_ == nullptr) return;
  const int a = clip_axis_->currentData().toInt();
  double b[6];
  actors_->volumeBounds_W(b);
  const double f = clip_position_->value() / 1000.0;
  Eigen::Vector3d origin(0.5 * (b[0] + b[1]), 0.5 * (b[2] + b[3]), 0.5 * (b[4] + b[5]));
  origin[a] = b[2 * a] + f * (b[2 * a + 1] - b[2 * a]);
  Eigen::Vector3d normal = Eigen::Vector3d::Zero();
  normal[a] = clip_flip_->isChecked() ? -1.0 : 1.0;
  actors_->setClipPlane(enabled, origin, normal);
  view_->requestRender();
}

void MainWindow::setOrientationMarkerVisible(bool visible) {
  prefs_.orientation_marker = visible;
  marker_->setVisible(visible && hasScene());
  {
    const QSignalBlocker b1(marker_box_);
    marker_box_->setChecked(visible);
  }
  if (marker_action_ != nullptr) {
    const QSignalBlocker b2(marker_action_);
    marker_action_->setChecked(visible);
  }
  view_->requestRender();
}

void MainWindow::setDeviceToolVisible(bool visible) {
  prefs_.show_device = visible;
  {
    const QSignalBlocker b1(device_box_);
    device_box_->setChecked(visible);
  }
  if (device_action_ != nullptr) {
    const QSignalBlocker b2(device_action_);
    device_action_->setChecked(visible);
  }
  if (actors_ != nullptr) {
    actors_->setDeviceVisible(visible && scene_.haptics != nullptr);
    view_->requestRender();
  }
}

void MainWindow::applyColours() {
  vtkRenderer* renderer = view_->renderer();
  const auto bottom = rgb(prefs_.background_bottom);
  const auto top = rgb(prefs_.background_top);
  renderer->SetBackground(bottom[0], bottom[1], bottom[2]);
  renderer->SetBackground2(top[0], top[1], top[2]);
  if (actors_ != nullptr) {
    const auto s = rgb(prefs_.surface);
    const auto t = rgb(prefs_.tool);
    const auto d = rgb(prefs_.device);
    actors_->setSurfaceColour(s[0], s[1], s[2]);
    actors_->setToolColour(t[0], t[1], t[2]);
    actors_->setDeviceColour(d[0], d[1], d[2]);
  }
  view_->requestRender();
}

void MainWindow::chooseColour(QColor Preferences::*field, const QString& title) {
  const QColor chosen = QColorDialog::getColor(prefs_.*field, this, title);
  if (chosen.isValid()) {
    prefs_.*field = chosen;
    applyColours();
  }
}

bool MainWindow::saveScreenshot(const QString& path) {
  refreshFromHaptics(/*update_status_now=*/true);
  renderStill(/*best_quality=*/true);
  // QWidget::grab() renders the GL view (paintGL) and composites it with the widgets.
  const QImage shot = grab().toImage();
  return shot.save(path, "PNG");
}

// ---- Settings and shutdown ---------------------------------------------------------------------

void MainWindow::saveSettings() const {
  QSettings settings;
  prefs_.save(settings);
  settings.setValue("window/geometry", saveGeometry());
  settings.setValue("window/state", saveState());
}

void MainWindow::restoreLayout() {
  QSettings settings;
  const QByteArray geometry = settings.value("window/geometry").toByteArray();
  const QByteArray state = settings.value("window/state").toByteArray();
  if (!geometry.isEmpty()) restoreGeometry(geometry);
  if (!state.isEmpty()) restoreState(state);
}

void MainWindow::closeEvent(QCloseEvent* event) {
  if (loader_ != nullptr) loader_->cancel();
  stopHaptics();  // force ramped to zero before anything else goes away
  saveSettings();
  QMainWindow::closeEvent(event);
}

// ---- Device picker -------------------------------------------------------------------------------

namespace {
constexpr char kFalconFirmwareKey[] = "devices/falcon_firmware";
constexpr int kHotplugPeriodMs = 1000;
const QString kSimulatedChoice = "Simulated device (mouse/keyboard)";
}  // namespace

void MainWindow::setUpDevicePicker() {
  try {
    catalog_ = std::make_shared<devices::DeviceCatalog>();
  } catch (const std::exception& e) {  // no backend at all: only the simulated device
    std::cerr << "volume-haptics: no device backends: " << e.what() << std::endl;
  }
  if (device_menu_ != nullptr) {
    connect(device_actions_, &QActionGroup::triggered, this, [this](QAction* action) {
      if (!chooseDevice(action->data().toInt())) syncDeviceChoice();
    });
  }
  rescanDevices();
  if (catalog_ != nullptr) {
    hotplug_ = std::make_unique<devices::HotplugMonitor>(catalog_, std::chrono::milliseconds(kHotplugPeriodMs));
    hotplug_->start();
    hotplug_timer_ = new QTimer(this);
    hotplug_timer_->setInterval(kHotplugPeriodMs);
    connect(hotplug_timer_, &QTimer::timeout, this, &MainWindow::pollHotplug);
    hotplug_timer_->start();
  }
}

void MainWindow::rescanDevices() {
  std::vector<devices::FoundDevice> found;
  device_problems_.clear();
  if (catalog_ != nullptr) {
    found = catalog_->enumerate();  // never throws
    device_problems_ = catalog_->problems();
  }
  // The device in use stays listed (and selected) even when it did not answer this time.
  picked_index_ = -1;
  if (picked_device_ != nullptr && picked_device_ == scene_.device && device_choice_ > 0 &&
      device_choice_ <= static_cast<int>(found_.size())) {
    const devices::FoundDevice in_use = found_[static_cast<std::size_t>(device_choice_ - 1)];
    auto it = std::find_if(found.begin(), found.end(), [&](const devices::FoundDevice& d) { return d.sameDeviceAs(in_use); });
    if (it == found.end()) it = found.insert(found.end(), in_use);
    picked_index_ = static_cast<int>(it - found.begin()) + 1;
  }
  found_ = std::move(found);
  if (!device_problems_.empty() && statusBar() != nullptr) {
    statusBar()->showMessage("Listing devices: " + q(device_problems_.front()), 6000);
  }
  showDeviceChoices();
}

QStringList MainWindow::deviceChoices() const {
  QStringList labels{kSimulatedChoice};
  for (const devices::FoundDevice& d : found_) labels << q(d.label());
  return labels;
}

void MainWindow::showDeviceChoices() {
  QString problems;
  for (const std::string& p : device_problems_) problems += (problems.isEmpty() ? "" : "\n") + q(p);
  const QStringList labels = deviceChoices();
  if (device_menu_ != nullptr) {
    device_menu_->clear();
    for (QAction* a : device_actions_->actions()) device_actions_->removeAction(a);
    for (int i = 0; i < labels.size(); ++i) {
      QAction* action = device_menu_->addAction(labels[i]);
      action->setCheckable(true);
      action->setData(i);
      device_actions_->addAction(action);
    }
    if (labels.size() == 1) {
      QAction* none = device_menu_->addAction(problems.isEmpty() ? "No haptic device found" : "No haptic device found (see tooltip)");
      none->setEnabled(false);
    }
    device_menu_->addSeparator();
    QAction* rescan = device_menu_->addAction("&Rescan Devices", this, &MainWindow::rescanDevices);
    rescan->setToolTip(problems.isEmpty() ? "List the connected devices again" : problems);
    device_menu_->setToolTipsVisible(true);
  }
  if (haptics_panel_ != nullptr) haptics_panel_->setDeviceChoices(labels, -1, problems);
  syncDeviceChoice();
}

void MainWindow::syncDeviceChoice() {
  int choice = -1;
  if (scene_.device != nullptr) {
    if (picked_device_ != nullptr && scene_.device == picked_device_) {
      choice = picked_index_;
    } else if (dynamic_cast<runtime::SimulatedDevice*>(scene_.device.get()) != nullptr) {
      choice = 0;
    }
  }
  device_choice_ = choice;
  if (haptics_panel_ != nullptr) haptics_panel_->setDeviceChoice(choice);
  if (device_actions_ != nullptr) {
    for (QAction* a : device_actions_->actions()) {
      const QSignalBlocker block(a);
      a->setChecked(a->data().toInt() == choice);
    }
  }
}

bool MainWindow::chooseDevice(int index) {
  last_device_error_.clear();
  if (index < 0 || index > static_cast<int>(found_.size())) return false;
  const haptics::Pose X_WP = have_snapshot_ ? snapshot_.X_WP : scene_.X_WT_initial;
  if (index == 0) {
    if (dynamic_cast<runtime::SimulatedDevice*>(scene_.device.get()) == nullptr || scene_.device == nullptr) {
      picked_device_.reset();
      setDevice(std::make_shared<runtime::SimulatedDevice>(X_WP));
    }
    syncDeviceChoice();
    return true;
  }
  const devices::FoundDevice found = found_[static_cast<std::size_t>(index - 1)];
  if (picked_device_ != nullptr && scene_.device == picked_device_ && picked_index_ == index) return true;
  devices::OpenOptions options;
  options.X_WT_initial = scene_.X_WT_initial;
  if (found.kind == "falcon") {
    QSettings settings;
    QString firmware = settings.value(kFalconFirmwareKey).toString();
    if ((firmware.isEmpty() || !QFileInfo::exists(firmware)) && interactive_) {
      firmware = QFileDialog::getOpenFileName(this, "Novint Falcon firmware", firmware,
                                              "Falcon firmware (*.bin *.rbf);;All files (*)");
      if (firmware.isEmpty()) {
        syncDeviceChoice();
        return false;  // cancelled
      }
      settings.setValue(kFalconFirmwareKey, firmware);
    }
    if (!firmware.isEmpty()) options.falcon_firmware = firmware.toStdString();
  }
  std::shared_ptr<runtime::Device> device;
  QString limits;
  try {
    std::shared_ptr<runtime::MappedDevice> hardware = catalog_->open(found, options);
    limits = deviceLimitsText(*hardware);
    device = std::make_shared<devices::FallbackDevice>(hardware, std::make_shared<runtime::SimulatedDevice>(X_WP));
  } catch (const std::exception& e) {
    last_device_error_ = q(e.what());
    if (interactive_) {
      QMessageBox::warning(this, "VolumeHaptics", "Could not open " + q(found.label()) + ":\n" + last_device_error_);
    } else {
      std::cerr << "volume-haptics: could not open " << found.label() << ": " << e.what() << std::endl;
    }
    syncDeviceChoice();
    return false;
  }
  picked_device_ = device;
  picked_index_ = index;
  setDevice(device, limits);
  statusBar()->showMessage("Using " + q(found.label()), 4000);
  return true;
}

void MainWindow::pollHotplug() {
  if (hotplug_ == nullptr) return;
  const std::vector<devices::HotplugEvent> events = hotplug_->takeEvents();
  if (events.empty()) return;
  bool changed = false;
  QString message;
  for (const devices::HotplugEvent& event : events) {
    const bool listed = std::any_of(found_.begin(), found_.end(),
                                    [&](const devices::FoundDevice& d) { return d.sameDeviceAs(event.device); });
    if (event.kind == devices::HotplugEvent::Kind::kArrived) {
      if (listed) continue;  // already listed (e.g. the monitor's first poll)
      message = "Device connected: " + q(event.device.label());
      const bool in_use_and_lost = picked_device_ != nullptr && scene_.device == picked_device_ &&
                                   !picked_device_->connected() && picked_index_ > 0 &&
                                   found_[static_cast<std::size_t>(picked_index_ - 1)].sameDeviceAs(event.device);
      if (in_use_and_lost) message += " (pick it again in Haptics > Device to reconnect)";
    } else {
      message = "Device removed: " + q(event.device.label());
      if (auto* fallback = dynamic_cast<devices::FallbackDevice*>(scene_.device.get())) {
        // The stand-in takes over where the hardware left the tool.
        if (have_snapshot_) fallback->simulated()->setPose(snapshot_.X_WD);
      }
    }
    changed = true;
  }
  if (!changed) return;
  statusBar()->showMessage(message, 6000);
  rescanDevices();
}

}  // namespace vh::ui
