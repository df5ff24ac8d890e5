#include "vh/ui/main_window.h"

#include <algorithm>
#include <stdexcept>

#include <QAction>
#include <QApplication>
#include <QCloseEvent>
#include <QDir>
#include <QDockWidget>
#include <QDragEnterEvent>
#include <QDropEvent>
#include <QFileDialog>
#include <QMenu>
#include <QMenuBar>
#include <QMessageBox>
#include <QMimeData>
#include <QSettings>
#include <QStatusBar>
#include <QVBoxLayout>

#include "vh/io/private_files.h"
#include "vh/runtime/haptic_thread.h"
#include "vh/ui/devices/device_input.h"
#include "vh/ui/devices/device_picker.h"
#include "vh/ui/haptics_controller.h"
#include "vh/ui/panels/about_dialog.h"
#include "vh/ui/panels/display_panel.h"
#include "vh/ui/panels/haptics_panel.h"
#include "vh/ui/panels/igtl_panel.h"
#include "vh/ui/panels/isovalue_bar.h"
#include "vh/ui/panels/load_notices.h"
#include "vh/ui/panels/status_line.h"
#include "vh/ui/panels/strip_chart.h"
#include "vh/ui/replay/replay_controller.h"
#include "vh/ui/replay/session_recorder.h"
#include "vh/ui/scene_loader.h"
#include "vh/ui/scene_opener.h"
#include "vh/ui/panels/segments_panel.h"
#include "vh/ui/segments_controller.h"
#include "vh/ui/proximity_alerts.h"
#include "vh/ui/technique_alerts.h"
#include "vh/ui/sound_output.h"
#include "vh/ui/drill_controller.h"
#include "vh/ui/tissue_controller.h"
#include "vh/ui/tool_picker.h"
#include "vh/ui/view/vtk_view.h"
#include "vh/ui/view_controller.h"

namespace vh::ui {
namespace {

using runtime::SessionChange;

constexpr int kStatusPeriodMs = 200;   // status text at ~5 Hz (readable), whatever the display rate
constexpr int kNoticeStatusMs = 10000;  // a load notice stays in the status bar this long

QString q(const std::string& s) { return QString::fromStdString(s); }

}  // namespace

// ---- Construction ------------------------------------------------------------------------------

MainWindow::MainWindow(QWidget* parent) : QMainWindow(parent) {
  {
    QSettings settings;
    prefs_ = Preferences::load(settings);
  }
  runtime::setPreferredSharedDatasetsDir(prefs_.datasets_dir.toStdString());
  session_.setGains({prefs_.linear_stiffness_N_per_m, prefs_.torsional_stiffness_Nm_per_rad, prefs_.passivity_control});
  loader_ = new SceneLoader(this);
  tool_picker_ = new ToolPicker(session_, *loader_, runtime::sharedDatasetsDir(), this);
  buildUi();
  opener_ = new SceneOpener(*loader_, session_, prefs_, *status_, statusBar(), this);
  // OpenIGTLink: the channel is the session's from the start, so switching the link on never
  // rebuilds the haptic threads.
  igtl_ = new IgtlPanel(statusBar(), session_.servoRate_Hz(), this);
  session_.setMonitor(igtl_->channel());
  // A received volume reaches here only after the user's yes (IgtlPanel asks, saying that a
  // recording would end): the recording is ended cleanly, with a marker saying why, before the
  // new scene replaces the session.
  igtl_->setRecordingQuery([this] { return recorder_ != nullptr && recorder_->recording(); });
  igtl_->setOnVolume([this](io::LoadedVolume volume) {
    if (recorder_->recording()) {
      recorder_->addMarker("recording ended: a volume received over OpenIGTLink replaces the scene");
      recorder_->stop();
    }
    opener_->openLoadedVolume(std::move(volume));
  });
  recorder_ = new SessionRecorder(session_, statusBar(), this);
  recorder_->setCameraSource([this] { return view_->camera(); });  // exports see what the user saw
  buildDocks();
  igtl_->setSegmentNames(segments_->names());
  replay_ = new ReplayController(session_, *view_, prefs_, this, chart_dock_);
  device_picker_ = new DevicePicker(session_, this);
  haptics_ = new HapticsController(session_, *haptics_panel_, *tool_picker_, *device_picker_, *device_input_, *recorder_,
                                   *replay_, this);
  buildMenus();
  connectParts();
  connectGuidance();
  observer_ = session_.addObserver([this](SessionChange what) { onSessionChanged(what); });
  setAcceptDrops(true);
  haptics_panel_->setEnabled(false);
  updateWindowTitle();
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
  delete haptics_;
  delete device_picker_;
  delete iso_bar_;
  delete segments_;
  delete tool_picker_;
  delete view_controller_;
  session_.clear();
}

void MainWindow::buildUi() {
  auto* central = new QWidget(this);
  auto* layout = new QVBoxLayout(central);
  layout->setContentsMargins(4, 4, 4, 4);
  layout->setSpacing(4);
  view_ = new SceneView(central);
  display_panel_ = new DisplayPanel(this);
  // The first observer that draws: a new scene clears the view before the segments are drawn.
  view_controller_ = new ViewController(session_, *view_, *display_panel_, prefs_, this);
  device_input_ = new DeviceInput(session_, *view_);
  iso_bar_ = new IsovalueBar(session_, central);
  notices_ = new LoadNoticePanel(central);
  layout->addWidget(notices_);
  layout->addWidget(iso_bar_);
  layout->addWidget(view_->widget(), 1);
  setCentralWidget(central);
  status_ = new StatusLine(statusBar());
}

void MainWindow::buildDocks() {
  display_dock_ = new QDockWidget("Display", this);
  display_dock_->setObjectName("displayDock");
  display_dock_->setWidget(display_panel_);
  addDockWidget(Qt::RightDockWidgetArea, display_dock_);

  haptics_panel_ = new HapticsPanel(this);
  haptics_dock_ = new QDockWidget("Haptics", this);
  haptics_dock_->setObjectName("hapticsDock");
  auto* haptics_box = new QWidget(this);
  auto* haptics_layout = new QVBoxLayout(haptics_box);
  haptics_layout->setContentsMargins(0, 0, 0, 0);
  haptics_layout->setSpacing(0);
  haptics_layout->addWidget(recorder_->makeDockControls(haptics_box));
  haptics_layout->addWidget(haptics_panel_, 1);
  haptics_dock_->setWidget(haptics_box);
  addDockWidget(Qt::RightDockWidgetArea, haptics_dock_);

  chart_ = new StripChart(this);
  chart_dock_ = new QDockWidget("Force and haptic thread timing", this);
  chart_dock_->setObjectName("chartDock");
  chart_dock_->setWidget(chart_);
  addDockWidget(Qt::BottomDockWidgetArea, chart_dock_);
  segments_ = new SegmentsController(session_, *view_, this, statusBar(), prefs_, device_input_);
  drill_ = new DrillController(session_, *view_, this);
  tissue_ = new TissueController(session_, *view_, this);
  sound_ = new SoundOutput(this);
  technique_ = new TechniqueAlerts(this);
  proximity_ = new ProximityAlerts(this);
  // Display, Segments and Haptics share the right side as tabs (Haptics in front): together they
  // would be taller than a laptop screen.
  tabifyDockWidget(display_dock_, segments_->dock());
  tabifyDockWidget(segments_->dock(), haptics_dock_);
  tabifyDockWidget(haptics_dock_, tissue_->dock());
  haptics_dock_->raise();
  resizeDocks({chart_dock_}, {190}, Qt::Vertical);
  resizeDocks({haptics_dock_}, {300}, Qt::Horizontal);
}

void MainWindow::connectSound() {
  // The burr's sound and the alert beeps on one mixer, the audio output opened at the first use.
  connect(segments_->panel(), &SegmentsPanel::burrSoundToggled, sound_, [this](bool on) {
    if (on) sound_->start();
    sound_->setBurrEnabled(on);
  });
  if (segments_->panel()->burrSound()) {  // remembered from the last session
    sound_->start();
    sound_->setBurrEnabled(true);
  }
  const auto alert = [this] {
    sound_->start();
    sound_->beep();
  };
  connect(segments_, &SegmentsController::alertSoundRequested, sound_, alert);
  connect(technique_, &TechniqueAlerts::alertRequested, sound_, [this, alert] {
    if (segments_->panel()->alertSound()) alert();
  });
  connect(proximity_, &ProximityAlerts::cueChanged, sound_, [this](bool on, double rate_Hz) {
    if (on && !segments_->panel()->alertSound()) return;
    if (on) sound_->start();
    sound_->setProximityCue(on, rate_Hz);
  });
}

void MainWindow::connectParts() {
  // The isovalue bar's drags: interactive frames meanwhile.
  connect(iso_bar_, &IsovalueBar::dragStarted, view_, [this] { view_->setInteracting(true); });
  connect(iso_bar_, &IsovalueBar::dragEnded, view_, [this] { view_->setInteracting(false); });
  connect(device_input_, &DeviceInput::isovalueStepRequested, iso_bar_, &IsovalueBar::step);
  connect(view_->widget(), &VtkView::frameRendered, opener_, [this] { opener_->frameRendered(view_->widget()->frameCount()); });

  // What the view shows -> the chart, the status line and the segment alerts.
  connect(view_controller_, &ViewController::snapshotShown, this,
          [this](const runtime::HapticSnapshot& snap, bool update_status_now) {
            segments_->showSnapshot(snap);
            technique_->showSnapshot(snap);
            proximity_->showSnapshot(snap, session_.live().segments.get());
            followSound(snap);
            if (chart_dock_->isVisible()) chart_->addSnapshot(snap);
            if (--status_countdown_ <= 0 || update_status_now) {
              status_countdown_ = std::max(1, kStatusPeriodMs / view_controller_->displayPeriodMs());
              updateStatus();
            }
            if (update_status_now) chart_->flush();
          });

  // Notes for the status bar.
  const auto show_message = [this](const QString& text, int ms) { statusBar()->showMessage(text, ms); };
  connect(device_picker_, &DevicePicker::message, this, show_message);
  connect(igtl_, &IgtlPanel::message, this, show_message);
  connect(tool_picker_, &ToolPicker::message, this, show_message);
  connect(haptics_, &HapticsController::message, this, show_message);
  connect(drill_, &DrillController::message, this, show_message);
  connect(tissue_, &TissueController::message, this, show_message);
  connect(iso_bar_, &IsovalueBar::message, this, show_message);
  connect(sound_, &SoundOutput::message, this, show_message);
  connect(technique_, &TechniqueAlerts::message, this, show_message);
  connect(proximity_, &ProximityAlerts::message, this, show_message);
  connect(proximity_, &ProximityAlerts::levelChanged, view_,
          [this](runtime::ProximityLevel level) { view_->setToolProximity(static_cast<int>(level)); });
  connectSound();
  connect(device_input_, &DeviceInput::message, this, show_message);
  view_controller_->setCarvedRegion(&drill_->carved());
  connect(drill_, &DrillController::cavityChanged, view_controller_, [this] { view_controller_->updateShadow(); });
  device_picker_->rescan();

  // Opening files -> the window; the recorder and the replay.
  connect(opener_, &SceneOpener::sceneLoaded, this, &MainWindow::onSceneLoaded);
  connect(opener_, &SceneOpener::loadStarted, this, [this] { haptics_panel_->setEnabled(false); });
  connect(opener_, &SceneOpener::loadFailed, this, [this](const QString& message) {
    onLoadEnded();
    emit loadFailed(message);
  });
  connect(opener_, &SceneOpener::loadCancelled, this, &MainWindow::onLoadEnded);
  connect(opener_, &SceneOpener::recordingRequested, replay_, &ReplayController::openRecording);
  connect(opener_, &SceneOpener::segmentationRequested, segments_, &SegmentsController::open);
  connect(notices_, &LoadNoticePanel::reloadRequested, opener_, &SceneOpener::openScene);
  connect(replay_, &ReplayController::openSceneRequested, opener_, &SceneOpener::openScene);
  connect(recorder_, &SessionRecorder::failed, opener_, &SceneOpener::reportError);
  connect(segments_, &SegmentsController::errorReported, opener_, &SceneOpener::reportError);
  connect(replay_, &ReplayController::errorReported, opener_, &SceneOpener::reportError);
  connect(replay_, &ReplayController::noticeRequested, recorder_, &SessionRecorder::showNotice);
  connect(replay_, &ReplayController::replayStarted, this, &MainWindow::updateStatus);
  connect(replay_, &ReplayController::replayClosed, this, &MainWindow::updateStatus);
  // The shadow falls into the cavity shown: the replay's at its time, else the live drill's.
  connect(replay_, &ReplayController::replayStarted, view_controller_,
          [this] { view_controller_->setCarvedRegion(&replay_->carved()); });
  connect(replay_, &ReplayController::replayClosed, view_controller_, [this] {
    view_controller_->setCarvedRegion(&drill_->carved());
    view_controller_->updateShadow();
  });
  connect(replay_, &ReplayController::cavityShown, view_controller_, [this] { view_controller_->updateShadow(); });
}

void MainWindow::connectGuidance() {
  // The expert's ghost: the live guidance's, else the replayed recording's while a replay is shown.
  connect(haptics_, &HapticsController::guidanceChanged, view_controller_, [this] {
    if (!replay_->active()) view_controller_->updateGhost();
  });
  connect(replay_, &ReplayController::replayStarted, view_controller_, [this] { view_controller_->setLiveGhost(false); });
  connect(replay_, &ReplayController::replayClosed, view_controller_, [this] { view_controller_->setLiveGhost(true); });
}

void MainWindow::followSound(const runtime::HapticSnapshot& snap) {
  if (!sound_->playing()) return;
  const runtime::HapticThread* thread = session_.hapticThread();
  if (thread != nullptr && thread->drill() != nullptr && session_.live().drill)
    sound_->setBurr(session_.live().drill->burr_speed_rpm, thread->drill()->burr().radius_m);
  sound_->follow(snap);
}

void MainWindow::startHaptics() { haptics_->start(); }

void MainWindow::setInteractive(bool interactive) {
  opener_->setInteractive(interactive);
  recorder_->setInteractive(interactive);
  replay_->setInteractive(interactive);
  device_picker_->setInteractive(interactive);
}

bool MainWindow::hasScene() const noexcept { return session_.hasScene() && view_->hasScene(); }

void MainWindow::openPath(const QString& path) { opener_->openPath(path); }

// ---- The session ---------------------------------------------------------------------------------

void MainWindow::onSessionChanged(SessionChange what) {
  if (runtime::has(what, SessionChange::kGains)) {
    // Remembered for the next plain volume.
    prefs_.linear_stiffness_N_per_m = session_.gains().linear_N_per_m;
    prefs_.torsional_stiffness_Nm_per_rad = session_.gains().angular_Nm_per_rad;
    prefs_.passivity_control = session_.gains().passivity_control;
  }
  updateStatus();
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
  title_ = v.title;
  opened_ = v.opened;
  const Histogram histogram = v.histogram.has_value() ? *v.histogram : computeHistogram(v.scene.volume.image.get(), 256);
  session_.setScene(std::move(v.scene), std::move(v.device));  // observers: view, bar, recorder, panels
  iso_bar_->setHistogram(histogram, session_.loaded().volume.info.value_unit);
  haptics_panel_->setEnabled(true);
  updateWindowTitle();
  chart_->clear();
  updateStatus();
  notices_->setLoaded(q(title_), session_.loaded().spec, session_.loaded().volume.info, opened_);
  if (const QString note = statusNote(session_.loaded().volume.info.notices); !note.isEmpty()) {
    statusBar()->showMessage(note, kNoticeStatusMs);
  }
}

void MainWindow::onSceneLoaded(const std::shared_ptr<ViewerScene>& loaded) {
  haptics_panel_->setEnabled(true);
  const QString title = q(loaded->title);
  try {
    setScene(std::move(*loaded));
  } catch (const std::exception& e) {
    opener_->reportError(title, q(e.what()));
    return;
  }
  // A scene file's "openigtlink" section switches the link on (or moves it to its port / rate).
  if (QString error; !igtl_->applySceneSection(session_.loaded().spec.openigtlink, &error)) {
    statusBar()->showMessage(error, kNoticeStatusMs);
  }
  const bool replay_pending = replay_->pending();
  replay_->onSceneShown();  // a recording's scene: its replay starts, haptics stay off
  if (auto_start_haptics_ && !replay_pending) startHaptics();
  emit sceneLoaded();
}

void MainWindow::onLoadEnded() {
  haptics_panel_->setEnabled(hasScene());
  haptics_->refresh();
  replay_->onLoadFailed();
}

void MainWindow::dragEnterEvent(QDragEnterEvent* event) {
  if (!SceneOpener::droppedPath(*event->mimeData()).isEmpty()) event->acceptProposedAction();
}

void MainWindow::dropEvent(QDropEvent* event) {
  const QString path = SceneOpener::droppedPath(*event->mimeData());
  if (path.isEmpty()) return;
  event->acceptProposedAction();
  opener_->openPath(path);
}

// ---- Panels --------------------------------------------------------------------------------------

void MainWindow::updateStatus() {
  if (status_ == nullptr) return;
  const QString replaying =
      replay_ != nullptr && replay_->active() ? q(replay_->path().filename().string()) : QString();
  status_->showHaptics(session_, view_controller_->snapshot(), replaying);
}

bool MainWindow::setDataFolder(const QString& dir) {
  const QDir d(dir);
  const QStringList parts = {"ct", "nrrd", "classic", "meshes"};
  if (!d.exists() || std::none_of(parts.begin(), parts.end(), [&](const QString& p) { return d.exists(p); })) {
    auto* box = new QMessageBox(QMessageBox::Warning, "Data Folder",
                                dir + " holds none of ct/, nrrd/, classic/ and meshes/: it is not the shared "
                                      "datasets' folder. The data folder stays " +
                                    q(runtime::sharedDatasetsDir().string()) + ".",
                                QMessageBox::Ok, this);
    box->setObjectName("dataFolderBox");
    box->setAttribute(Qt::WA_DeleteOnClose);
    box->open();  // window-modal, does not block the haptic display
    return false;
  }
  prefs_.datasets_dir = d.absolutePath();
  runtime::setPreferredSharedDatasetsDir(prefs_.datasets_dir.toStdString());
  tool_picker_->setSharedDatasetsDir(runtime::sharedDatasetsDir());
  statusBar()->showMessage(
      runtime::sharedDatasetsDirFromEnvironment()
          ? "Data folder kept for later; VH_SHARED_DATASETS_DIR is set and wins: " + q(runtime::sharedDatasetsDir().string())
          : "Data folder: " + prefs_.datasets_dir,
      kNoticeStatusMs);
  return true;
}

QString MainWindow::statusText() const { return status_ != nullptr ? status_->text() : QString(); }

void MainWindow::updateWindowTitle() { setWindowTitle(windowTitleFor(title_, session_)); }

// ---- Menus ---------------------------------------------------------------------------------------

void MainWindow::buildMenus() {
  QMenu* file = menuBar()->addMenu("&File");
  opener_->addFileMenuActions(file);
  file->addAction("Open Se&gmentation (.seg.nrrd, DICOM SEG, RTSTRUCT)...", this, [this] { segments_->openDialog(prefs_.last_folder); })
      ->setShortcut(QKeySequence("Ctrl+G"));
  file->addMenu(opener_->recentFilesMenu());
  file->addSeparator();
  replay_->addFileMenuActions(file);
  file->addSeparator();
  QAction* shot = file->addAction("Save Screens&hot...", this, [this] {
    const QString path = QFileDialog::getSaveFileName(this, "Save a screenshot of the window",
                                                      QDir(prefs_.last_folder).filePath("volume-haptics.png"),
                                                      "PNG images (*.png)");
    if (!path.isEmpty() && !saveScreenshot(path)) opener_->reportError(path, path + ": the screenshot could not be written");
  });
  shot->setShortcut(QKeySequence("Ctrl+Shift+S"));
  drill_->addMenuActions(nullptr, file, this);
  file->addSeparator();
  file->addAction("Data &Folder...", this, [this] {
    const QString dir = QFileDialog::getExistingDirectory(
        this, "The folder holding the shared datasets (ct/, nrrd/, classic/, meshes/)",
        QString::fromStdString(runtime::sharedDatasetsDir().string()));
    if (!dir.isEmpty()) setDataFolder(dir);
  });
  file->addAction("&Quit", this, &QWidget::close)->setShortcut(QKeySequence::Quit);

  // View: the Display panel's actions (the same choices as its dock), then the window's.
  QMenu* view_menu = menuBar()->addMenu("&View");
  QAction* first_toggle = display_panel_->addViewMenuActions(view_menu, this);
  auto* focus = new QAction("&Focus on the Tool", this);
  connect(focus, &QAction::triggered, view_controller_, &ViewController::focusOnTool);
  focus->setShortcut(QKeySequence("Ctrl+F"));
  view_menu->insertAction(first_toggle, focus);
  view_menu->insertSeparator(first_toggle);
  view_controller_->addColoursMenu(view_menu, this);
  view_controller_->addStereoMenu(view_menu);
  view_menu->addSeparator();
  view_menu->addAction(display_dock_->toggleViewAction());
  view_menu->addAction(haptics_dock_->toggleViewAction());
  view_menu->addAction(chart_dock_->toggleViewAction());

  QMenu* haptics_menu = haptics_->addMenu(menuBar(), this);
  haptics_menu->addSeparator();
  drill_->addMenuActions(haptics_menu, nullptr, this);
  menuBar()->addMenu("&Connections")->addAction(igtl_->action());

  QMenu* help = menuBar()->addMenu("H&elp");
  help->addAction("&Controls", this, [this] {
        QMessageBox box(QMessageBox::Information, "Controls", DeviceInput::controlsHtml(), QMessageBox::Close, this);
        box.setTextFormat(Qt::RichText);
        box.exec();
      })->setShortcut(QKeySequence::HelpContents);
  help->addAction("Load &Notes", this, [this] { notices_->reopen(); })
      ->setStatusTip("What the loader corrected or chose for the open scan (gantry tilt, missing slices, series)");
  help->addAction("&About VolumeHaptics", this, [this] { showAboutDialog(this); });
  help->addAction("About &Qt", qApp, &QApplication::aboutQt);

  auto* cancel = new QAction(this);
  cancel->setShortcut(QKeySequence(Qt::Key_Escape));
  cancel->setShortcutContext(Qt::WindowShortcut);
  connect(cancel, &QAction::triggered, this, [this] {
    if (loader_->busy()) opener_->cancelLoading();
  });
  addAction(cancel);
}

// ---- Screenshots, settings and shutdown ----------------------------------------------------------

bool MainWindow::saveScreenshot(const QString& path) {
  view_controller_->refresh(/*update_status_now=*/true);
  view_->renderStill(/*best_quality=*/true);
  // The widgets, with the view's frame rendered into its place (QWidget::grab() alone leaves the
  // view's native window blank).
  try {
    io::PrivateOutput file(std::filesystem::path(path.toStdString()));  // 0600: a picture of the scan
    if (!grabWithView(*this, *view_->widget()).save(QString::fromStdString(file.tempPath().string()), "PNG")) return false;
    file.commit();
    return true;
  } catch (const std::runtime_error&) {
    return false;
  }
}

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
  session_.stopHaptics();  // force ramped to zero before anything else goes away
  saveSettings();
  QMainWindow::closeEvent(event);
}

}  // namespace vh::ui
