#include "vh/ui/main_window.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <iostream>
#include <stdexcept>

#include <QAction>
#include <QActionGroup>
#include <QApplication>
#include <QCloseEvent>
#include <QColorDialog>
#include <QDir>
#include <QDockWidget>
#include <QDragEnterEvent>
#include <QDropEvent>
#include <QFileDialog>
#include <QFileInfo>
#include <QGroupBox>
#include <QMenu>
#include <QMenuBar>
#include <QMessageBox>
#include <QMimeData>
#include <QSettings>
#include <QSignalBlocker>
#include <QStatusBar>
#include <QTimer>
#include <QUrl>
#include <QVBoxLayout>
#include <vtkImageData.h>

#include "vh/io/segmentation.h"
#include "vh/ui/panels/about_dialog.h"
#include "vh/ui/devices/device_input.h"
#include "vh/ui/devices/device_picker.h"
#include "vh/ui/panels/display_panel.h"
#include "vh/ui/panels/haptics_panel.h"
#include "vh/ui/panels/histogram_slider.h"
#include "vh/ui/panels/isovalue_bar.h"
#include "vh/ui/panels/load_notices.h"
#include "vh/ui/export/media_export.h"
#include "vh/ui/replay/replay_panel.h"
#include "vh/ui/view/scene_actors.h"
#include "vh/ui/scene_loader.h"
#include "vh/ui/segments_controller.h"
#include "vh/ui/panels/series_chooser.h"
#include "vh/ui/panels/igtl_panel.h"
#include "vh/ui/replay/session_recorder.h"
#include "vh/ui/panels/status_line.h"
#include "vh/ui/panels/strip_chart.h"
#include "vh/ui/view/vtk_view.h"

namespace vh::ui {
namespace {

namespace fs = std::filesystem;
using runtime::SessionChange;

constexpr int kDisplayPeriodMs = 33;    // ~30 Hz prop updates
constexpr int kStatusEveryTicks = 6;    // status text at ~5 Hz (readable)
constexpr int kNoticeStatusMs = 10000;  // a load notice stays in the status bar this long

QString q(const std::string& s) { return QString::fromStdString(s); }

}  // namespace

ViewerScene makeViewerScene(const runtime::LoadedScene& loaded, std::shared_ptr<runtime::Device> device) {
  ViewerScene v;
  v.scene = loaded;
  v.device = std::move(device);
  v.title = loaded.volume.info.source.filename().string();
  if (v.title.empty()) v.title = loaded.spec.volume.path;
  return v;
}

// ---- Construction ------------------------------------------------------------------------------

MainWindow::MainWindow(QWidget* parent) : QMainWindow(parent) {
  {
    QSettings settings;
    prefs_ = Preferences::load(settings);
  }
  session_.setGains({prefs_.linear_stiffness_N_per_m, prefs_.torsional_stiffness_Nm_per_rad, prefs_.passivity_control});
  tools_ = toolCatalog(runtime::sharedDatasetsDir());
  loader_ = new SceneLoader(this);
  buildUi();
  // OpenIGTLink: the channel is the session's from the start, so switching the link on never
  // rebuilds the haptic threads.
  igtl_ = new IgtlPanel(statusBar(), session_.servoRate_Hz(), this);
  session_.setMonitor(igtl_->channel());
  igtl_->setOnVolume([this](io::LoadedVolume volume) { openLoadedVolume(std::move(volume)); });
  recorder_ = new SessionRecorder(session_, statusBar(), this);
  buildDocks();
  igtl_->setSegmentNames(segments_->names());
  replay_ = new ReplayController(session_, *view_, prefs_, this, chart_dock_);
  device_picker_ = new DevicePicker(session_, this);
  buildMenus();
  device_picker_->setMenu(device_menu_);
  connectParts();
  observer_ = session_.addObserver([this](SessionChange what) { onSessionChanged(what); });
  applyColours();
  setAcceptDrops(true);
  clock_.start();
  haptics_panel_->setEnabled(false);
  updateWindowTitle();
  updateHapticsPanel();
  updateStatus();
  resize(1280, 860);
}

MainWindow::MainWindow(ViewerScene scene, QWidget* parent) : MainWindow(parent) { setScene(std::move(scene)); }

MainWindow::~MainWindow() {
  delete loader_;  // cancels and waits for the worker
  loader_ = nullptr;
  session_.removeObserver(observer_);
  if (replay_ != nullptr) replay_->onSceneTeardown();
  session_.stopHaptics();  // force ramped to zero before anything else goes
  // The parts that observe the session go before it does (children outlive members otherwise).
  delete recorder_;
  delete replay_;
  delete device_picker_;
  delete iso_bar_;
  session_.clear();
}

void MainWindow::buildUi() {
  auto* central = new QWidget(this);
  auto* layout = new QVBoxLayout(central);
  layout->setContentsMargins(4, 4, 4, 4);
  layout->setSpacing(4);
  view_ = new SceneView(central);
  device_input_ = new DeviceInput(session_, *view_);
  iso_bar_ = new IsovalueBar(session_, central);
  notices_ = new LoadNoticePanel(central);
  layout->addWidget(notices_);
  layout->addWidget(iso_bar_);
  layout->addWidget(view_->widget(), 1);
  setCentralWidget(central);
  status_ = new StatusLine(statusBar());

  display_timer_ = new QTimer(this);
  display_timer_->setInterval(kDisplayPeriodMs);
  connect(display_timer_, &QTimer::timeout, this, [this] { refreshFromHaptics(); });
}

void MainWindow::buildDocks() {
  display_panel_ = new DisplayPanel(this);
  display_panel_->setMarkerVisible(prefs_.orientation_marker);
  display_panel_->setDeviceToolVisible(prefs_.show_device);
  display_dock_ = new QDockWidget("Display", this);
  display_dock_->setObjectName("displayDock");
  display_dock_->setWidget(display_panel_);
  addDockWidget(Qt::RightDockWidgetArea, display_dock_);

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

  chart_ = new StripChart(this);
  chart_dock_ = new QDockWidget("Force and haptic thread timing", this);
  chart_dock_->setObjectName("chartDock");
  chart_dock_->setWidget(chart_);
  addDockWidget(Qt::BottomDockWidgetArea, chart_dock_);
  segments_ = new SegmentsController(session_, *view_, this, statusBar());
  // Display, Segments and Haptics share the right side as tabs (Haptics in front): together they
  // would be taller than a laptop screen.
  tabifyDockWidget(display_dock_, segments_->dock());
  tabifyDockWidget(segments_->dock(), haptics_dock_);
  haptics_dock_->raise();
  resizeDocks({chart_dock_}, {190}, Qt::Vertical);
  resizeDocks({haptics_dock_}, {300}, Qt::Horizontal);
}

void MainWindow::connectParts() {
  // The isovalue bar's drags: interactive frames meanwhile.
  connect(iso_bar_, &IsovalueBar::dragStarted, view_, [this] { view_->setInteracting(true); });
  connect(iso_bar_, &IsovalueBar::dragEnded, view_, [this] { view_->setInteracting(false); });
  connect(device_input_, &DeviceInput::isovalueStepRequested, iso_bar_, &IsovalueBar::step);
  connect(notices_, &LoadNoticePanel::reloadRequested, this,
          [this](const runtime::SceneSpec& spec, const fs::path& opened) { openScene(spec, opened); });
  connect(status_, &StatusLine::cancelRequested, this, &MainWindow::cancelLoading);
  connect(view_->widget(), &VtkView::frameRendered, this, [this] {
    if (upload_pending_ && view_->widget()->frameCount() > upload_frame_) {
      upload_pending_ = false;
      if (!loader_->busy()) status_->hideProgress();
    }
  });

  // Display panel -> preferences and the scene view.
  connect(display_panel_, &DisplayPanel::renderModeChosen, this, &MainWindow::setRenderMode);
  connect(display_panel_, &DisplayPanel::presetChosen, this, &MainWindow::setPreset);
  connect(display_panel_, &DisplayPanel::standardViewRequested, this, &MainWindow::setStandardView);
  connect(display_panel_, &DisplayPanel::resetViewRequested, this, [this] {
    resetCamera();
    view_->requestRender();
  });
  connect(display_panel_, &DisplayPanel::clippingChanged, this, [this](bool moving) {
    if (moving) view_->noteMotion();
    applyClippingFromPanel();
  });
  connect(display_panel_, &DisplayPanel::markerToggled, this, &MainWindow::setOrientationMarkerVisible);
  connect(display_panel_, &DisplayPanel::deviceToolToggled, this, &MainWindow::setDeviceToolVisible);

  // Haptics panel -> the session.
  connect(haptics_panel_, &HapticsPanel::startStopRequested, this, [this](bool run) { run ? startHaptics() : stopHaptics(); });
  connect(haptics_panel_, &HapticsPanel::toolRequested, this, [this](int index, double spacing_m) { selectTool(index, spacing_m); });
  connect(haptics_panel_, &HapticsPanel::gainsChanged, this, &MainWindow::setGains);
  connect(haptics_panel_, &HapticsPanel::resetDeviceRequested, this, [this] {
    if (hasScene()) setDevicePose(session_.live().X_WT_initial);
  });
  connect(haptics_panel_, &HapticsPanel::rescanRequested, device_picker_, &DevicePicker::rescan);
  connect(haptics_panel_, &HapticsPanel::deviceChoiceRequested, device_picker_, &DevicePicker::choose);

  // Device picker -> the haptics panel and the status bar.
  connect(device_picker_, &DevicePicker::choicesChanged, haptics_panel_, &HapticsPanel::setDeviceChoices);
  connect(device_picker_, &DevicePicker::choiceChanged, haptics_panel_, &HapticsPanel::setDeviceChoice);
  connect(device_picker_, &DevicePicker::message, this, [this](const QString& text, int ms) { statusBar()->showMessage(text, ms); });
  connect(igtl_, &IgtlPanel::message, this, [this](const QString& text, int ms) { statusBar()->showMessage(text, ms); });
  device_picker_->rescan();

  // Loader.
  connect(loader_, &SceneLoader::progress, this,
          [this](const QString& stage, int percent) { status_->showProgress(stage, percent, true); });
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
    replay_->onLoadFailed();
    statusBar()->showMessage("Loading cancelled; what was open is kept", 4000);
  });
  connect(loader_, &SceneLoader::idle, this, [this] {
    if (!upload_pending_) status_->hideProgress();
  });

  // Recorder and replay -> the window.
  connect(recorder_, &SessionRecorder::failed, this, &MainWindow::reportError);
  connect(segments_, &SegmentsController::errorReported, this, &MainWindow::reportError);
  connect(replay_, &ReplayController::openSceneRequested, this,
          [this](const runtime::SceneSpec& spec, const fs::path& opened) { openScene(spec, opened); });
  connect(replay_, &ReplayController::errorReported, this, &MainWindow::reportError);
  connect(replay_, &ReplayController::noticeRequested, recorder_, &SessionRecorder::showNotice);
  const auto replay_changed = [this] {
    recorder_->setReplayActive(replay_->active());
    updateHapticsPanel();
    updateStatus();
  };
  connect(replay_, &ReplayController::replayStarted, this, replay_changed);
  connect(replay_, &ReplayController::replayClosed, this, replay_changed);
}

void MainWindow::setInteractive(bool interactive) {
  interactive_ = interactive;
  recorder_->setInteractive(interactive);
  replay_->setInteractive(interactive);
  device_picker_->setInteractive(interactive);
}

// ---- The session ---------------------------------------------------------------------------------

void MainWindow::onSessionChanged(SessionChange what) {
  if (runtime::has(what, SessionChange::kIsovalue)) view_->setIsovalue(session_.isovalue());
  if (runtime::has(what, SessionChange::kGains)) {
    // Remembered for the next plain volume.
    prefs_.linear_stiffness_N_per_m = session_.gains().linear_N_per_m;
    prefs_.torsional_stiffness_Nm_per_rad = session_.gains().angular_Nm_per_rad;
    prefs_.passivity_control = session_.gains().passivity_control;
  }
  if (runtime::has(what, SessionChange::kTool) || runtime::has(what, SessionChange::kScene)) {
    tool_index_ = findOrAddSceneTool(tools_, session_.live().tool_spec);
  }
  if (runtime::has(what, SessionChange::kTool) && !runtime::has(what, SessionChange::kScene) &&
      session_.live().tool != nullptr) {
    view_->setTool(*session_.live().tool, session_.live().X_WT_initial);
    have_snapshot_ = false;
  }
  if (runtime::has(what, SessionChange::kDevice)) {
    view_->setDeviceVisible(session_.hapticThread() != nullptr && prefs_.show_device);
    have_snapshot_ = false;
    updateHint();
    device_picker_->sync();
  }
  if (session_.hapticsRunning()) {
    display_timer_->start();
  } else {
    display_timer_->stop();
  }
  updateHapticsPanel();
  updateStatus();
}

void MainWindow::startHaptics() {
  if (replay_ != nullptr && replay_->active()) {
    recorder_->showNotice("A recording is replayed: Close Replay first", 4000);
    return;
  }
  session_.startHaptics();
}

void MainWindow::selectTool(int choice_index, double point_spacing_m) {
  if (!hasScene() || session_.loaded().volume.field == nullptr || choice_index < 0 ||
      choice_index >= static_cast<int>(tools_.size())) {
    return;
  }
  if (loader_->busy()) {
    statusBar()->showMessage("Busy loading; change the tool when it is done", 4000);
    updateHapticsPanel();
    return;
  }
  recorder_->noteTool(q(tools_[static_cast<std::size_t>(choice_index)].label), point_spacing_m);
  haptics_panel_->setBuilding(true);
  loader_->buildTool(choice_index, tools_[static_cast<std::size_t>(choice_index)], point_spacing_m,
                     session_.live().hapticField(), session_.live().hapticIsovalue());
}

void MainWindow::onToolBuilt(std::shared_ptr<RebuiltTool> rebuilt) {
  haptics_panel_->setBuilding(false);
  if (!hasScene()) return;
  const ToolChoice& choice = tools_[static_cast<std::size_t>(rebuilt->choice_index)];
  runtime::ToolSpec spec = session_.live().tool_spec;
  spec.mesh = choice.mesh;
  spec.scale_to_m = choice.scale_to_m;
  spec.point_spacing_m = rebuilt->built.point_spacing_m;
  spec.point_count = 0;
  spec.X_WT_initial.R_AB = choice.R_WT;
  spec.initial_orientation_set = true;
  // The session ramps the force to zero before the tool changes under the user's hand.
  session_.setTool(rebuilt->built.tool, spec, rebuilt->built.X_WT_initial);
  emit toolChanged();
}

bool MainWindow::refreshFromHaptics(bool update_status_now) {
  if (!hasScene() || !session_.latestSnapshot(snapshot_)) return false;
  have_snapshot_ = true;
  ToolFrame frame;
  frame.X_WP = snapshot_.X_WP;
  frame.X_WD = snapshot_.X_WD;
  frame.force_W_N = snapshot_.force_W_N;
  const int n = std::clamp(snapshot_.contacts_shown, 0, runtime::HapticSnapshot::kMaxContactsShown);
  frame.contacts_W_m = std::span<const Eigen::Vector3d>(snapshot_.contact_p_W_m.data(), static_cast<std::size_t>(n));
  const bool changed = view_->show(frame);
  segments_->showSnapshot(snapshot_);
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

// ---- Scenes --------------------------------------------------------------------------------------

void MainWindow::setScene(ViewerScene v) {
  if (v.scene.volume.image == nullptr || v.scene.volume.field == nullptr) {
    throw std::invalid_argument("MainWindow: the scene's volume has no image or field to show");
  }
  if (loader_ != nullptr && loader_->busy()) loader_->cancel();  // e.g. a tool built for the old scene
  replay_->onSceneTeardown();
  // A scene file's gains are part of its experiment; plain volumes get the remembered ones.
  if (v.scene.spec.source.empty()) {
    v.scene.spec.gains = {prefs_.linear_stiffness_N_per_m, prefs_.torsional_stiffness_Nm_per_rad,
                          prefs_.passivity_control};
  }
  view_->clearScene();
  title_ = v.title;
  opened_ = v.opened;
  const Histogram histogram = v.histogram.has_value() ? *v.histogram : computeHistogram(v.scene.volume.image.get(), 256);
  session_.setScene(std::move(v.scene), std::move(v.device));  // observers: bar, recorder, panel
  SceneActorsSpec spec = sceneActorsSpecFor(session_.loaded(), session_.live());
  spec.show_device = session_.hapticThread() != nullptr && prefs_.show_device;
  view_->setScene(spec, session_.live().X_WT_initial, prefs_);
  iso_bar_->setHistogram(histogram, session_.loaded().volume.info.value_unit);
  have_snapshot_ = false;
  snapshot_ = runtime::HapticSnapshot{};
  haptics_panel_->setEnabled(true);
  applyClippingFromPanel();
  updateHint();
  updateHapticsPanel();
  updateWindowTitle();
  chart_->clear();
  updateStatus();
  showLoadNotices(session_.loaded().volume.info, session_.loaded().spec);
}

void MainWindow::showLoadNotices(const io::VolumeInfo& info, const runtime::SceneSpec& spec) {
  notices_->setLoaded(q(title_), spec, info, opened_);
  for (const std::string& n : info.notices) std::cerr << "volume-haptics: note: " << n << '\n';
  const std::string first = primaryNotice(info.notices);
  if (first.empty()) return;
  QString text = "Note: " + q(first);
  if (info.notices.size() > 1) text += QString(" (+%1 more, see Help > Load Notes)").arg(info.notices.size() - 1);
  statusBar()->showMessage(text, kNoticeStatusMs);
}

void MainWindow::buildMenus() {
  // ---- File.
  QMenu* file = menuBar()->addMenu("&File");
  QAction* open_dicom = file->addAction("Open &DICOM Folder...", this, [this] { openFileDialog(0); });
  open_dicom->setShortcut(QKeySequence("Ctrl+D"));
  QAction* open_volume = file->addAction("&Open Volume File (NRRD, MetaImage)...", this, [this] { openFileDialog(1); });
  open_volume->setShortcut(QKeySequence::Open);
  QAction* open_scene = file->addAction("Open &Scene...", this, [this] { openFileDialog(2); });
  open_scene->setShortcut(QKeySequence("Ctrl+Shift+O"));
  QAction* open_segments = file->addAction("Open Se&gmentation (3D Slicer .seg.nrrd)...", this,
                                           [this] { segments_->openDialog(prefs_.last_folder); });
  open_segments->setShortcut(QKeySequence("Ctrl+G"));
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

  // ---- View: the Display panel's actions (the same choices as its dock), then the window's.
  QMenu* viewMenu = menuBar()->addMenu("&View");
  QAction* first_toggle = display_panel_->addViewMenuActions(viewMenu, this);
  QAction* focus = new QAction("&Focus on the Tool", this);
  connect(focus, &QAction::triggered, this, &MainWindow::focusOnTool);
  focus->setShortcut(QKeySequence("Ctrl+F"));
  viewMenu->insertAction(first_toggle, focus);
  viewMenu->insertSeparator(first_toggle);
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
    if (hasScene()) setDevicePose(session_.live().X_WT_initial);
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

  // ---- Connections.
  menuBar()->addMenu("&Connections")->addAction(igtl_->action());

  // ---- Help.
  QMenu* help = menuBar()->addMenu("H&elp");
  QAction* controls = help->addAction("&Controls", this, [this] {
    QMessageBox box(QMessageBox::Information, "Controls", DeviceInput::controlsHtml(), QMessageBox::Close, this);
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
  display_panel_->setPreset(prefs_.preset);
  display_panel_->setRenderMode(prefs_.mode);
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
  if ((ext == ".nrrd" || ext == ".nhdr") && io::isSegmentationFile(p)) {
    // A segmentation: the segments of the scan shown; alone, it is its own scan.
    if (hasScene()) {
      segments_->open(p);
    } else {
      runtime::SceneSpec spec = runtime::sceneForVolume(p);
      spec.segmentation = runtime::SegmentationSpec{};
      spec.segmentation->path = spec.volume.path;
      openScene(spec, p);
    }
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

void MainWindow::openLoadedVolume(io::LoadedVolume volume) {
  statusBar()->showMessage(q("Opening '" + volume.info.description + "' received over OpenIGTLink"), kNoticeStatusMs);
  const runtime::SceneSpec spec = runtime::sceneForLoadedVolume(volume);
  loader_->loadScene(spec, {}, std::move(volume));
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
  openScene(spec, series.folder);
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
  status_->hideProgress();
  SeriesChooserDialog dialog(folder, series, this);
  if (dialog.exec() == QDialog::Accepted && dialog.selectedRow() >= 0) {
    openDicomSeries(dialog.model()->series(dialog.selectedRow()), dialog.selectedPhase());
  }
}

void MainWindow::onSceneLoaded(std::shared_ptr<LoadedViewerScene> loaded) {
  haptics_panel_->setEnabled(true);
  ViewerScene v = makeViewerScene(loaded->scene, loaded->device);
  v.histogram = std::move(loaded->histogram);
  v.opened = loaded->opened;
  if (!loaded->title.empty()) v.title = loaded->title;
  const std::string& description = loaded->scene.volume.info.description;
  if (!description.empty() && loaded->scene.volume.info.format == "DICOM" && description != v.title) {
    v.title += " - " + description;
  }
  status_->showProgress("Uploading the volume to the GPU", 95, false);
  try {
    setScene(std::move(v));
  } catch (const std::exception& e) {
    status_->hideProgress();
    reportError(q(loaded->title), q(e.what()));
    return;
  }
  upload_pending_ = true;
  upload_frame_ = view_->widget()->frameCount();
  if (!loaded->opened.empty()) {
    prefs_.addRecentFile(q(fs::absolute(loaded->opened).lexically_normal().string()));
    rebuildRecentMenu();
  }
  last_error_.clear();
  // A scene file's "openigtlink" section switches the link on (or moves it to its port / rate).
  if (const std::optional<runtime::OpenIgtlinkSpec>& o = session_.loaded().spec.openigtlink; o.has_value()) {
    const IgtlSettings now = igtl_->settings();
    if (!igtl_->running() || now.port != o->port || now.rate_Hz != o->rate_Hz) {
      QString error;
      if (!igtl_->apply({true, o->port, o->rate_Hz}, &error)) statusBar()->showMessage(error, kNoticeStatusMs);
    }
  }
  const bool replay_pending = replay_->pending();
  replay_->onSceneShown();  // a recording's scene: its replay starts, haptics stay off
  if (auto_start_haptics_ && !replay_pending) startHaptics();
  emit sceneLoaded();
}

bool MainWindow::loading() const noexcept { return (loader_ != nullptr && loader_->busy()) || upload_pending_; }

void MainWindow::cancelLoading() {
  if (loader_ != nullptr) loader_->cancel();
  haptics_panel_->setEnabled(hasScene());
  status_->hideProgress();
}

void MainWindow::reportError(const QString& what, const QString& message) {
  last_error_ = message;
  status_->hideProgress();
  haptics_panel_->setEnabled(hasScene());
  replay_->onLoadFailed();
  std::cerr << "volume-haptics: " << message.toStdString() << '\n';
  emit loadFailed(message);
  if (!interactive_) return;
  const QString name = QFileInfo(what).fileName().isEmpty() ? what : QFileInfo(what).fileName();
  auto* box = new QMessageBox(QMessageBox::Critical, "VolumeHaptics", QString("Cannot open %1").arg(name),
                              QMessageBox::Ok, this);
  box->setObjectName("errorBox");
  box->setInformativeText(message + "\n\n" +
                          (hasScene() ? "What was open before is kept."
                                      : "Open another file with the File menu, or drop it on the window."));
  box->setAttribute(Qt::WA_DeleteOnClose);
  box->open();  // window-modal, does not block the haptic display
}

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

void MainWindow::openFileDialog(int kind) {
  QString path;
  if (kind == 0) {
    path = QFileDialog::getExistingDirectory(this, "Open a DICOM folder", prefs_.last_folder, QFileDialog::ShowDirsOnly);
  } else if (kind == 1) {
    path = QFileDialog::getOpenFileName(this, "Open a volume file", prefs_.last_folder, q(io::volumeFileDialogFilter()));
  } else {
    path = QFileDialog::getOpenFileName(this, "Open a scene", prefs_.last_folder, "Scenes (*.json);;All files (*)");
  }
  if (!path.isEmpty()) openPath(path);
}

void MainWindow::dragEnterEvent(QDragEnterEvent* event) {
  const QMimeData* mime = event->mimeData();
  if (mime->hasUrls() && !mime->urls().isEmpty() && mime->urls().front().isLocalFile()) event->acceptProposedAction();
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

// ---- Panels --------------------------------------------------------------------------------------

void MainWindow::updateHapticsPanel() {
  if (haptics_panel_ == nullptr) return;
  const bool replaying = replay_ != nullptr && replay_->active();  // the haptic thread waits
  haptics_panel_->showSession(session_, tools_, tool_index_, device_picker_ != nullptr ? device_picker_->limitsText() : QString(),
                              replaying);
  if (haptics_action_ != nullptr) {
    const QSignalBlocker block(haptics_action_);
    haptics_action_->setEnabled(session_.hapticThread() != nullptr && !replaying);
    haptics_action_->setChecked(hapticsRunning());
  }
}

void MainWindow::updateStatus() {
  if (status_ == nullptr) return;
  const QString replaying =
      replay_ != nullptr && replay_->active() ? q(replay_->path().filename().string()) : QString();
  status_->showHaptics(session_, have_snapshot_ ? &snapshot_ : nullptr, replaying);
}

QString MainWindow::statusText() const { return status_ != nullptr ? status_->text() : QString(); }

void MainWindow::updateHint() {
  if (view_->hasScene()) view_->setHint(DeviceInput::hint(session_));
}

void MainWindow::updateWindowTitle() {
  QString title = "VolumeHaptics";
  if (!hasScene()) {
    setWindowTitle(title);
    return;
  }
  if (!title_.empty()) title += " - " + q(title_);
  const io::VolumeInfo& info = session_.loaded().volume.info;
  const auto& g = session_.loaded().volume.field->geometry();
  const double lo_mm = g.spacing_m.minCoeff() * 1e3;
  const double hi_mm = g.spacing_m.maxCoeff() * 1e3;
  const QString spacing = hi_mm > lo_mm * 1.001 ? QString("%1..%2 mm").arg(lo_mm, 0, 'g', 3).arg(hi_mm, 0, 'g', 3)
                                                : QString("%1 mm").arg(lo_mm, 0, 'g', 3);
  const QString facts = QString("%1 %2  %3x%4x%5  %6")
                            .arg(q(info.format), q(info.modality))
                            .arg(g.dims[0])
                            .arg(g.dims[1])
                            .arg(g.dims[2])
                            .arg(spacing)
                            .simplified();
  if (!facts.isEmpty()) title += " (" + facts + ")";
  setWindowTitle(title);
}

// ---- Viewing ------------------------------------------------------------------------------------

void MainWindow::setRenderMode(RenderMode mode) {
  prefs_.mode = mode;
  display_panel_->setRenderMode(mode);
  view_->setRenderMode(prefs_.mode, prefs_.preset);
}

void MainWindow::setPreset(VolumePreset preset) {
  prefs_.preset = preset;
  display_panel_->setPreset(preset);
  view_->setRenderMode(prefs_.mode, prefs_.preset);
}

void MainWindow::resetCamera() { view_->resetCamera(); }

void MainWindow::focusOnTool() {
  if (session_.live().tool == nullptr) return;
  view_->focusOn(*session_.live().tool, have_snapshot_ ? snapshot_.X_WP : view_->shownProxyPose());
}

void MainWindow::setStandardView(StandardView v) { view_->setStandardView(v); }

void MainWindow::setClipping(bool enabled, ClipAxis axis, double fraction, bool flip) {
  display_panel_->setClipping(enabled, axis, fraction, flip);
  applyClippingFromPanel();
}

void MainWindow::applyClippingFromPanel() {
  const bool enabled = display_panel_->clippingEnabled();
  view_->setClipping(enabled, display_panel_->clipAxis(), display_panel_->clipFraction(), display_panel_->clipFlipped());
}

void MainWindow::setOrientationMarkerVisible(bool visible) {
  prefs_.orientation_marker = visible;
  view_->setMarkerVisible(visible);
  display_panel_->setMarkerVisible(visible);
}

void MainWindow::setDeviceToolVisible(bool visible) {
  prefs_.show_device = visible;
  display_panel_->setDeviceToolVisible(visible);
  view_->setDeviceVisible(visible && session_.hapticThread() != nullptr);
}

void MainWindow::applyColours() { view_->applyColours(prefs_); }

void MainWindow::chooseColour(QColor Preferences::*field, const QString& title) {
  const QColor chosen = QColorDialog::getColor(prefs_.*field, this, title);
  if (chosen.isValid()) {
    prefs_.*field = chosen;
    applyColours();
  }
}

void MainWindow::renderStill(bool best_quality) { view_->renderStill(best_quality); }

bool MainWindow::saveScreenshot(const QString& path) {
  refreshFromHaptics(/*update_status_now=*/true);
  renderStill(/*best_quality=*/true);
  // QWidget::grab() renders the GL view (paintGL) and composites it with the widgets.
  const QImage shot = grab().toImage();
  return shot.save(path, "PNG");
}

// ---- Devices -------------------------------------------------------------------------------------

void MainWindow::rescanDevices() { device_picker_->rescan(); }
QStringList MainWindow::deviceChoices() const { return device_picker_->choices(); }
int MainWindow::currentDeviceChoice() const noexcept { return device_picker_->currentChoice(); }
bool MainWindow::chooseDevice(int index) { return device_picker_->choose(index); }
QString MainWindow::lastDeviceError() const { return device_picker_->lastError(); }
void MainWindow::setDevicePose(const haptics::Pose& X_WD) { device_input_->setDevicePose(X_WD); }
bool MainWindow::touchSurface(double depth_m) { return device_input_->touchSurface(depth_m); }

// ---- Parts ---------------------------------------------------------------------------------------

VtkView* MainWindow::view() const noexcept { return view_->widget(); }
QSlider* MainWindow::isovalueSlider() const noexcept { return iso_bar_->slider(); }
HistogramSlider* MainWindow::histogramSlider() const noexcept { return iso_bar_->slider(); }
QDoubleSpinBox* MainWindow::isovalueSpinBox() const noexcept { return iso_bar_->spinBox(); }
SceneActors& MainWindow::actors() const noexcept { return view_->actors(); }
OrientationMarker* MainWindow::orientationMarker() const noexcept { return view_->marker(); }
vtkVolume* MainWindow::volumeProp() const noexcept { return view_->hasScene() ? view_->actors().volume() : nullptr; }
vtkActor* MainWindow::proxyActor() const noexcept { return view_->hasScene() ? view_->actors().proxyActor() : nullptr; }
vtkActor* MainWindow::deviceActor() const noexcept { return view_->hasScene() ? view_->actors().deviceActor() : nullptr; }

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

}  // namespace vh::ui
