#include "vh/ui/replay/replay_controller.h"

#include "vh/ui/drill_controller.h"
#include "vh/ui/export/session_report.h"
#include "vh/runtime/replay.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <iostream>
#include <limits>
#include <stdexcept>

#include <QAction>
#include <QApplication>
#include <QComboBox>
#include <QDir>
#include <QDockWidget>
#include <QFileDialog>
#include <QFileInfo>
#include <QHBoxLayout>
#include <QInputDialog>
#include <QLabel>
#include <QListWidget>
#include <QMainWindow>
#include <QMenu>
#include <QMessageBox>
#include <QProgressDialog>
#include <QPushButton>
#include <QSignalBlocker>
#include <QStatusBar>
#include <QTimer>
#include <QVBoxLayout>

#include <nlohmann/json.hpp>
#include <vtkImageData.h>
#include <vtkRenderer.h>

#include "vh/io/private_files.h"
#include "vh/runtime/session_metadata.h"
#include "vh/runtime/scene.h"
#include "vh/runtime/session.h"
#include "vh/ui/preferences.h"
#include "vh/ui/view/scene_view.h"
#include "vh/ui/view/vtk_view.h"
#include "vh/ui/export/media_export.h"
#include "vh/ui/view/scene_actors.h"
#include "vh/ui/view/tool_shadow.h"

namespace vh::ui {
namespace {

namespace fs = std::filesystem;

constexpr int kPlayPeriodMs = 33;
constexpr double kSpeeds[] = {0.25, 0.5, 1.0, 2.0, 4.0};

QString q(const std::string& s) { return QString::fromStdString(s); }

// Whether an exported picture or video carries the overlay (asked, yes by default).
bool askOverlay(QWidget* parent) {
  return QMessageBox::question(parent, "Export",
                               "Draw the overlay on the pictures: the time, |F|, |torque|, the markers' labels and "
                               "the critical-segment alert?",
                               QMessageBox::Yes | QMessageBox::No, QMessageBox::Yes) == QMessageBox::Yes;
}

/// A marker event's label ({"label": ...}), else its detail text.
QString markerLabel(const runtime::RecordingEvent& e) {
  try {
    const nlohmann::json j = nlohmann::json::parse(e.detail_json);
    if (j.is_object() && j.contains("label") && j["label"].is_string()) return q(j["label"].get<std::string>());
  } catch (const std::exception&) {
  }
  return q(e.detail_json);
}

}  // namespace

// ---- ReplayController ----------------------------------------------------------------------------

ReplayController::ReplayController(runtime::Session& session, SceneView& view, Preferences& prefs, QMainWindow* window,
                                   QDockWidget* tab_with)
    : QObject(window), session_(session), view_(view), prefs_(prefs), window_(window), tab_with_(tab_with) {
  setObjectName("replayController");
  play_timer_ = new QTimer(this);
  play_timer_->setInterval(kPlayPeriodMs);
  connect(play_timer_, &QTimer::timeout, this, &ReplayController::advance);
}

ReplayController::~ReplayController() { stopDrillingReplay(); }

void ReplayController::addFileMenuActions(QMenu* file) {
  QAction* open = file->addAction("Open Re&cording...", this, [this] {
    const QString path = QFileDialog::getOpenFileName(window_, "Open a session recording", prefs_.last_folder,
                                                      "Session recordings (*.vhrec);;All files (*)");
    if (!path.isEmpty()) openRecording(fs::path(path.toStdString()));
  });
  open->setObjectName("openRecordingAction");
  open->setShortcut(QKeySequence("Ctrl+Shift+P"));
  QMenu* exports = file->addMenu("E&xport Recording");
  exports->setObjectName("exportRecordingMenu");
  const char* names[] = {"&CSV (one row per tick)...", "&JSON (metadata, summary, events)...",
                         "&Video (Ogg/Theora) of the Replay...", "&Screenshot (PNG) of the View..."};
  for (int kind = 0; kind < 4; ++kind) {
    QAction* a = exports->addAction(names[kind], this, [this, kind] { exportFromMenu(kind); });
    export_actions_.push_back(a);
  }
  export_actions_[2]->setToolTip("Renders the replayed recording frame by frame from the view's camera");
  QAction* report = file->addAction("Session &Report...", this, [this] { reportFromMenu(); });
  report->setObjectName("sessionReportAction");
  report->setToolTip("An HTML page of the recording for a teacher: force, motion, contacts, segments, timing");
  updateActions();
}

void ReplayController::updateActions() {
  if (export_actions_.size() == 4) export_actions_[2]->setEnabled(active_);
}

bool ReplayController::openRecording(const fs::path& path) {
  const QString file = q(path.string());
  runtime::Recording recording;
  try {
    recording = runtime::readRecording(path, runtime::RecordingFiles::kVhrecOnly);
  } catch (const std::exception& e) {
    emit errorReported(file, QString::fromUtf8(e.what()));
    return false;
  }
  if (recording.records.empty()) {
    emit errorReported(file, file + ": the recording holds no ticks to replay");
    return false;
  }
  runtime::SceneSpec spec;
  try {
    spec = runtime::sceneFromSessionMetadata(recording.metadata_json);
  } catch (const std::exception& e) {
    emit errorReported(file, file + ": cannot reload the recorded scene: " + QString::fromUtf8(e.what()));
    return false;
  }
  // A simulated device (not started) so the device tool is drawn and Close Replay goes live.
  spec.device = runtime::DeviceSpec{};
  if (!recording.warnings.empty()) {
    QStringList lines;
    for (const std::string& w : recording.warnings) {
      lines << q(w);
      std::cerr << "volume-haptics: " << path.string() << ": warning: " << w << '\n';
    }
    emit noticeRequested("Damaged recording: " + lines.join("; "), 10000);
    if (interactive_) {
      auto* box = new QMessageBox(QMessageBox::Warning, "VolumeHaptics", "The recording is damaged at its end",
                                  QMessageBox::Ok, window_);
      box->setObjectName("recordingWarningBox");
      box->setInformativeText(lines.join("\n") + "\n\nThe ticks before the damage are replayed.");
      box->setAttribute(Qt::WA_DeleteOnClose);
      box->open();
    }
  }
  session_.stopHaptics();
  pending_ = std::move(recording);
  pending_path_ = path;
  prefs_.last_folder = QFileInfo(file).absolutePath();
  emit openSceneRequested(spec, path);
  return true;
}

void ReplayController::onLoadFailed() {
  if (!pending_.has_value()) return;
  pending_.reset();
  // The scene shown before stays; so does its replay (when one was shown).
  if (!active_) session_.startHaptics();
}

void ReplayController::onSceneShown() {
  if (!pending_.has_value()) return;
  recording_ = std::move(*pending_);
  pending_.reset();
  path_ = pending_path_;
  session_.stopHaptics();
  if (dock_ == nullptr) buildDock();
  std::vector<double> t, f;
  t.reserve(recording_.records.size());
  f.reserve(recording_.records.size());
  for (const runtime::TickRecord& r : recording_.records) {
    t.push_back(r.time_s);
    f.push_back(forceNormOf(r));
  }
  timeline_->setSamples(std::move(t), std::move(f));
  marker_times_s_.clear();
  QStringList labels;
  marker_list_->clear();
  for (const runtime::RecordingEvent& e : recording_.events) {
    if (e.type != "marker") continue;
    marker_times_s_.push_back(e.time_s);
    labels << markerLabel(e);
    marker_list_->addItem(QString("%1 s   %2").arg(e.time_s, 0, 'f', 3).arg(labels.back()));
  }
  timeline_->setMarkers(marker_times_s_, labels);
  dock_->setWindowTitle("Replay: " + QFileInfo(q(path_.string())).fileName());
  active_ = true;
  view_.setSharpMotion(true);  // a replay is watched for what it shows: fewer frames, none coarse
  dock_->show();
  dock_->raise();
  speed_box_->setCurrentIndex(2);
  speed_ = 1.0;
  replayDrilling();
  guide_ = ReplayGuide(recording_, path_);
  view_.setGhostPath(guide_.expert() != nullptr ? &guide_.expert()->path() : nullptr);
  if (!guide_.notice().empty()) emit noticeRequested(QString::fromStdString(guide_.notice()), 10000);
  setTime(recording_.records.front().time_s);
  updateActions();
  dock_->setToolTip(QString("%1: %2 ticks, %3 s, %4 markers")
                        .arg(q(path_.string()))
                        .arg(recording_.records.size())
                        .arg(timeline_->duration_s(), 0, 'f', 2)
                        .arg(marker_times_s_.size()));
  emit replayStarted();
}

void ReplayController::onSceneTeardown() {
  stopDrillingReplay();
  if (!active_) return;
  pause();
  active_ = false;
  view_.setSharpMotion(false);
  view_.setGhostPath(nullptr);  // hidden; the expert's path goes with guide_
  guide_ = ReplayGuide();
  if (dock_ != nullptr) dock_->hide();
  updateActions();
  emit replayClosed();
}

void ReplayController::closeReplay() {
  if (!active_) return;
  onSceneTeardown();
  // Live again on the recording's scene: its drill starts from the cavity the recording started
  // from, and so does the picture.
  if (view_.hasScene()) showDrilledVoxels(view_.actors(), drill_.picture, drill_.picture.at_start, drill_shown_);
  if (session_.hasScene()) {
    if (view_.hasScene()) view_.actors().setForce(Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero());
    session_.startHaptics();
  }
}

void ReplayController::buildDock() {
  auto* panel = new QWidget(window_);
  auto* layout = new QVBoxLayout(panel);
  layout->setContentsMargins(6, 4, 6, 4);
  auto* row = new QHBoxLayout();
  play_button_ = new QPushButton("Play", panel);
  play_button_->setObjectName("replayPlay");
  play_button_->setToolTip("Play / pause the recording (Space)");
  play_button_->setShortcut(QKeySequence(Qt::Key_Space));
  speed_box_ = new QComboBox(panel);
  speed_box_->setObjectName("replaySpeed");
  for (double s : kSpeeds) speed_box_->addItem(QString("%1x").arg(s), s);
  speed_box_->setCurrentIndex(2);
  readout_ = new QLabel(panel);
  readout_->setObjectName("replayReadout");
  readout_->setTextInteractionFlags(Qt::TextSelectableByMouse);
  auto* close = new QPushButton("Close Replay", panel);
  close->setObjectName("replayClose");
  close->setToolTip("Back to live haptics on this scene");
  row->addWidget(play_button_);
  row->addWidget(new QLabel("Speed", panel));
  row->addWidget(speed_box_);
  row->addWidget(readout_, 1);
  row->addWidget(close);
  layout->addLayout(row);
  auto* body = new QHBoxLayout();
  timeline_ = new ForceTimeline(panel);
  marker_list_ = new QListWidget(panel);
  marker_list_->setObjectName("replayMarkers");
  marker_list_->setToolTip("Markers: click one to jump to it");
  marker_list_->setMaximumWidth(220);
  body->addWidget(timeline_, 1);
  body->addWidget(marker_list_);
  layout->addLayout(body, 1);

  dock_ = new QDockWidget("Replay", window_);
  dock_->setObjectName("replayDock");
  dock_->setWidget(panel);
  dock_->setFeatures(QDockWidget::DockWidgetMovable | QDockWidget::DockWidgetFloatable);
  window_->addDockWidget(Qt::BottomDockWidgetArea, dock_);
  if (tab_with_ != nullptr) window_->tabifyDockWidget(tab_with_, dock_);

  connect(play_button_, &QPushButton::clicked, this, [this] { playing() ? pause() : play(); });
  connect(speed_box_, &QComboBox::currentIndexChanged, this,
          [this](int i) { setSpeed(speed_box_->itemData(i).toDouble()); });
  connect(close, &QPushButton::clicked, this, &ReplayController::closeReplay);
  connect(timeline_, &ForceTimeline::scrubbed, this, [this](double t) {
    pause();
    setTime(t);
  });
  const auto jump = [this](int row_index) {
    if (row_index < 0 || row_index >= static_cast<int>(marker_times_s_.size())) return;
    pause();
    setTime(marker_times_s_[static_cast<std::size_t>(row_index)]);
  };
  connect(marker_list_, &QListWidget::currentRowChanged, this, jump);
  connect(marker_list_, &QListWidget::itemClicked, this,
          [this, jump](QListWidgetItem* item) { jump(marker_list_->row(item)); });
}

void ReplayController::setTime(double t_s) {
  if (!active_ || recording_.records.empty() || !session_.hasScene() || !view_.hasScene()) return;
  const double first = recording_.records.front().time_s;
  const double last = recording_.records.back().time_s;
  time_s_ = std::clamp(std::isfinite(t_s) ? t_s : first, first, last);
  index_ = recordIndexAt(recording_.records, time_s_);
  const runtime::TickRecord& r = recording_.records[index_];
  // The session owns the isovalue: the bar, the view and (when live again) the hand follow it.
  // Ticks of felt segments carry the segments' level, not the scan's isovalue: neither the
  // session nor the picture takes it (as RecordingFrameRenderer::show() for exports).
  const bool scan_isovalue = !session_.live().feltSegments();
  if (std::isfinite(r.isovalue) && scan_isovalue) {
    try {
      session_.setIsovalue(r.isovalue);
    } catch (const std::exception&) {  // soft tissue not buildable there: the picture keeps the session's
    }
  }
  ToolFrame frame = toolFrameOf(r);  // the same picture as a live snapshot
  if (!scan_isovalue) frame.isovalue = std::numeric_limits<double>::quiet_NaN();
  view_.show(frame);
  showGhostAt(r);
  showDrillingAt(index_);
  timeline_->setCursor_s(time_s_);
  readout_->setText(readout());
  view_.noteMotion();
  view_.requestRender();
}

void ReplayController::showGhostAt(const runtime::TickRecord& r) {
  if (guide_.onAt(r.time_s)) view_.showGhost(guide_.ghostPose(devicePoseOf(r).p_AB_m));
  else view_.hideGhost();
}

void ReplayController::replayDrilling() {
  stopDrillingReplay();
  drill_ = {};
  drill_shown_ = 0;
  carved_.clear();
  if (view_.hasScene()) view_.actors().restoreVolume();
  const bool drilled = std::any_of(recording_.records.begin(), recording_.records.end(), [](const runtime::TickRecord& r) {
    return (r.flags & runtime::kRecordFlagDrillOn) != 0;
  });
  if (!session_.hasScene() || !session_.loaded().spec.drill) return;
  // The cavity the session started from, at once (drilled before the recording started); every
  // record shows it until the replay below is done.
  drill_ = drillingAtStart(session_.loaded());
  if (!drilled) return;

  // The same renderer and drill as the session's, fed the recorded samples, remove the same
  // voxels: a few seconds on a big CT, so on a thread of its own (a scene copy without the
  // picture's VTK image, the records copied), with a progress dialog; the result comes back
  // through a queued call, the cavity growing with the replay's time from then on.
  auto scene = std::make_shared<runtime::LoadedScene>(session_.loaded());
  scene->volume.image = nullptr;  // VTK objects stay on the GUI thread
  auto recording = std::make_shared<const runtime::Recording>(recording_);
  const std::uint64_t generation = ++drill_generation_;
  drill_cancel_.store(false);
  drill_progress_.store(0.0);
  drill_pending_ = true;
  drill_thread_ = std::thread([this, scene, recording, generation, timeline = drill_]() mutable {
    bool ok = false;
    try {
      runtime::ReplayProgress progress;
      progress.cancel = &drill_cancel_;
      progress.progress = [this](double fraction) { drill_progress_.store(fraction); };
      addReplayedRemovals(timeline, *scene, *recording, progress);
      ok = !timeline.cancelled;
    } catch (const std::exception& e) {  // the picture keeps the cavity at the start; the replay goes on
      std::cerr << "volume-haptics: replaying the drilling: " << e.what() << '\n';
    }
    QMetaObject::invokeMethod(
        this,
        [this, generation, ok, timeline = std::move(timeline)]() mutable {
          finishDrillingReplay(generation, ok, std::move(timeline));
        },
        Qt::QueuedConnection);
  });
  if (interactive_) {
    drill_dialog_ = new QProgressDialog("Replaying the drilling (the cavity is shown when done)...", "Cancel", 0, 100,
                                        window_);
    drill_dialog_->setObjectName("drillingReplayProgress");
    drill_dialog_->setWindowModality(Qt::NonModal);
    drill_dialog_->setMinimumDuration(400);
    drill_dialog_->setAutoClose(false);
    drill_dialog_->setAutoReset(false);
    connect(drill_dialog_, &QProgressDialog::canceled, this, [this] {
      stopDrillingReplay();
      emit noticeRequested("Drilling replay cancelled: the picture shows only the cavity the recording started from", 6000);
    });
  }
  if (drill_timer_ == nullptr) {
    drill_timer_ = new QTimer(this);
    drill_timer_->setInterval(100);
    connect(drill_timer_, &QTimer::timeout, this, [this] {
      if (drill_dialog_ != nullptr) drill_dialog_->setValue(static_cast<int>(100.0 * drill_progress_.load()));
    });
  }
  drill_timer_->start();
}

void ReplayController::finishDrillingReplay(std::uint64_t generation, bool ok, DrillingTimeline timeline) {
  if (generation != drill_generation_) return;  // cancelled, or another replay since
  if (drill_thread_.joinable()) drill_thread_.join();  // it posted this as its last act
  drill_pending_ = false;
  if (drill_timer_ != nullptr) drill_timer_->stop();
  if (drill_dialog_ != nullptr) {
    drill_dialog_->deleteLater();
    drill_dialog_ = nullptr;
  }
  if (ok && active_) {
    if (!timeline.replay_difference.empty()) {
      std::string text = timeline.replay_difference;
      text[0] = static_cast<char>(std::toupper(static_cast<unsigned char>(text[0])));
      emit noticeRequested(QString::fromStdString(text) + "; the cavity is shown as it was there", 15000);
    }
    // It starts with the cavity shown since the replay began (a copy of drill_).
    drill_ = std::move(timeline);
    showDrillingAt(index_);
    view_.requestRender();
  }
  emit drillingReplayed(ok);
}

void ReplayController::stopDrillingReplay() {
  drill_cancel_.store(true);
  if (drill_thread_.joinable()) drill_thread_.join();
  ++drill_generation_;  // a result it posted is dropped
  drill_pending_ = false;
  if (drill_timer_ != nullptr) drill_timer_->stop();
  if (drill_dialog_ != nullptr) {
    QProgressDialog* dialog = drill_dialog_;
    drill_dialog_ = nullptr;  // before close(): a cancel it emits finds nothing to stop
    dialog->blockSignals(true);
    dialog->deleteLater();
  }
}

void ReplayController::showDrillingAt(std::size_t record_index) {
  if (view_.hasScene()) showDrilledVoxels(view_.actors(), drill_.picture, drill_.picture.removedAt(record_index), drill_shown_);
  if (!session_.hasScene()) return;
  const std::uint64_t version = carved_.version();
  carveToRecord(carved_, session_.live().hapticField(), drill_.felt, record_index);
  if (carved_.version() != version) emit cavityShown();
}

QString ReplayController::readout() const {
  if (recording_.records.empty()) return {};
  const runtime::TickRecord& r = recording_.records[index_];
  return QString::fromUtf8("t %1 / %2 s   tick %3   |F| %4 N   contacts %5")
      .arg(r.time_s, 0, 'f', 3)
      .arg(recording_.records.back().time_s, 0, 'f', 2)
      .arg(static_cast<qulonglong>(r.tick))
      .arg(forceNormOf(r), 0, 'f', 2)
      .arg(r.contacts);
}

void ReplayController::play() {
  if (!active_) return;
  if (time_s_ >= recording_.records.back().time_s) setTime(recording_.records.front().time_s);
  play_origin_s_ = time_s_;
  play_clock_.start();
  play_timer_->start();
  if (play_button_ != nullptr) play_button_->setText("Pause");
}

void ReplayController::pause() {
  play_timer_->stop();
  if (play_button_ != nullptr) play_button_->setText("Play");
}

bool ReplayController::playing() const noexcept { return play_timer_->isActive(); }

void ReplayController::setSpeed(double factor) {
  speed_ = std::clamp(factor, 0.25, 4.0);
  if (playing()) {
    play_origin_s_ = time_s_;
    play_clock_.start();
  }
  if (speed_box_ != nullptr) {
    for (int i = 0; i < speed_box_->count(); ++i) {
      if (speed_box_->itemData(i).toDouble() == speed_ && speed_box_->currentIndex() != i) {
        const QSignalBlocker block(speed_box_);
        speed_box_->setCurrentIndex(i);
      }
    }
  }
}

void ReplayController::advance() {
  const double t = play_origin_s_ + 1e-3 * static_cast<double>(play_clock_.elapsed()) * speed_;
  setTime(t);
  if (t >= recording_.records.back().time_s) pause();
}

// ---- Exports -------------------------------------------------------------------------------------

void ReplayController::exportCsv(const fs::path& path) const {
  if (!active_) throw std::logic_error("exportCsv: no recording is replayed");
  runtime::writeRecordingCsv(recording_, path);
}

void ReplayController::exportJson(const fs::path& path) const {
  if (!active_) throw std::logic_error("exportJson: no recording is replayed");
  runtime::writeRecordingJson(recording_, path);
}

std::unique_ptr<RecordingFrameRenderer> ReplayController::exportFrames(int width, int height, bool overlay) const {
  if (width <= 0 || height <= 0) {
    width = std::max(16, view_.widget()->width());
    height = std::max(16, view_.widget()->height());
  }
  auto frames = std::make_unique<RecordingFrameRenderer>(sceneActorsSpecFor(session_.loaded(), session_.live()),
                                                         width, height, prefs_);
  frames->copyCamera(view_.widget()->renderer()->GetActiveCamera());
  if (overlay) frames->setOverlay(&recording_);
  // The tool's shadow as the main view draws it (the look's tool_shadow decides whether it shows).
  const runtime::LiveValues& live = session_.live();
  if (live.tool != nullptr) frames->setShadow(live.hapticField(), live.hapticIsovalue(), toolShadowSamples(*live.tool));
  // The segments as the replay shows them.
  if (live.segments != nullptr)
    frames->setSegments(live.segments, {prefs_.surface.redF(), prefs_.surface.greenF(), prefs_.surface.blueF()});
  // The cavity as the replay shows it (only the start cavity while its replay still runs).
  frames->setDrilling(drill_);
  frames->setGuide(guide_);  // the expert's ghost, as the replay shows it
  return frames;
}

int ReplayController::exportVideo(const fs::path& path, double fps, int width, int height,
                                  const std::function<bool(int, int)>& progress, bool overlay, bool sound) {
  if (!active_) throw std::logic_error("exportVideo: no recording is replayed");
  const double t_shown = time_s_;
  // The burr's sound as its drilling replay heard it (none while that replay still runs).
  const std::unique_ptr<RecordingFrameRenderer> frames = exportFrames(width, height, overlay);
  const int frames_written = writeRecordingVideo(*frames, recording_, path, fps, 0.0, -1.0, progress, nullptr,
                                                 sound ? videoSoundOf(*frames) : nullptr);
  setTime(t_shown);
  return frames_written;
}

void ReplayController::exportPng(const fs::path& path, int width, int height, bool overlay) {
  if (!active_) throw std::logic_error("exportPng: no recording is replayed");
  writeRecordingPng(*exportFrames(width, height, overlay), recording_, time_s_, path);
}

const runtime::Recording* ReplayController::recordingToExport(runtime::Recording& loaded, fs::path& from,
                                                              const QString& folder) const {
  if (active_) {
    from = path_;
    return &recording_;
  }
  const QString in =
      QFileDialog::getOpenFileName(window_, "Export which recording?", folder, "Session recordings (*.vhrec)");
  if (in.isEmpty()) return nullptr;
  loaded = runtime::readRecording(fs::path(in.toStdString()), runtime::RecordingFiles::kVhrecOnly);
  from = fs::path(in.toStdString());
  return &loaded;
}

void ReplayController::exportReport(const fs::path& path) const {
  if (!active_) throw std::logic_error("exportReport: no recording is replayed");
  writeSessionReport(recording_, path_.filename().string(), path);
}

void ReplayController::reportFromMenu() {
  const QString folder = path_.empty() ? prefs_.last_folder : q(path_.parent_path().string());
  try {
    runtime::Recording loaded;
    fs::path from;
    const runtime::Recording* source = recordingToExport(loaded, from, folder);
    if (source == nullptr) return;
    const QString out = QFileDialog::getSaveFileName(window_, "Write a session report",
                                                     QDir(folder).filePath(q(from.stem().string()) + "-report.html"),
                                                     "HTML pages (*.html)");
    if (out.isEmpty()) return;
    QApplication::setOverrideCursor(Qt::WaitCursor);
    try {
      writeSessionReport(*source, from.filename().string(), fs::path(out.toStdString()));
    } catch (...) {
      QApplication::restoreOverrideCursor();
      throw;
    }
    QApplication::restoreOverrideCursor();
    emit noticeRequested("Session report written: " + QFileInfo(out).fileName());
  } catch (const std::exception& e) {
    emit errorReported(q(path_.string()), QString::fromUtf8(e.what()));
  }
}

void ReplayController::exportFromMenu(int kind) {
  const QString folder = path_.empty() ? prefs_.last_folder : q(path_.parent_path().string());
  const QString stem = path_.empty() ? QString("session") : q(path_.stem().string());
  try {
    if (kind == 0 || kind == 1) {
      runtime::Recording loaded;
      fs::path from;
      const runtime::Recording* source = recordingToExport(loaded, from, folder);
      if (source == nullptr) return;
      const QString ext = kind == 0 ? "csv" : "json";
      const QString out = QFileDialog::getSaveFileName(window_, "Export the recording as " + ext.toUpper(),
                                                       QDir(folder).filePath(stem + "." + ext),
                                                       ext.toUpper() + " files (*." + ext + ")");
      if (out.isEmpty()) return;
      if (kind == 0) {
        runtime::writeRecordingCsv(*source, fs::path(out.toStdString()));
      } else {
        runtime::writeRecordingJson(*source, fs::path(out.toStdString()));
      }
      emit noticeRequested("Exported " + QFileInfo(out).fileName());
      return;
    }
    if (kind == 2) {
      if (!active_) return;
      const QString out = QFileDialog::getSaveFileName(window_, "Export a video of the replay",
                                                       QDir(folder).filePath(stem + ".ogv"), "Ogg video, Theora with Vorbis sound (*.ogv)");
      if (out.isEmpty()) return;
      bool ok = false;
      const int fps = QInputDialog::getInt(window_, "Video", "Frames per second:", 30, 1, 120, 1, &ok);
      if (!ok) return;
      const bool overlay = askOverlay(window_);
      pause();
      const double duration = timeline_->duration_s();
      QProgressDialog progress("Rendering the video...", "Cancel", 0,
                               static_cast<int>(std::floor(duration * fps)) + 1, window_);
      progress.setWindowModality(Qt::WindowModal);
      progress.setMinimumDuration(0);
      const int n = exportVideo(fs::path(out.toStdString()), fps, 0, 0, [&](int done, int total) {
        progress.setMaximum(total);
        progress.setValue(done);
        QApplication::processEvents();
        return !progress.wasCanceled();
      }, overlay);
      progress.reset();
      emit noticeRequested(QString("Video written: %1 (%2 frames, %3)")
                               .arg(QFileInfo(out).fileName())
                               .arg(n)
                               .arg(hasVideoSound() ? "with the burr's sound" : "without sound"));
      return;
    }
    // Screenshot of the view.
    const QString out = QFileDialog::getSaveFileName(window_, "Save a PNG of the view",
                                                     QDir(folder).filePath(stem + ".png"), "PNG images (*.png)");
    if (out.isEmpty()) return;
    if (active_) {
      exportPng(fs::path(out.toStdString()), 0, 0, askOverlay(window_));
    } else {
      io::PrivateOutput file(fs::path(out.toStdString()));  // 0600, renamed into place when whole
      if (!view_.widget()->grabFrame().save(QString::fromStdString(file.tempPath().string()), "PNG")) {
        throw std::runtime_error(out.toStdString() + ": the PNG could not be written");
      }
      file.commit();
    }
    emit noticeRequested("Saved " + QFileInfo(out).fileName());
  } catch (const std::exception& e) {
    emit errorReported(q(path_.string()), QString::fromUtf8(e.what()));
  }
}

}  // namespace vh::ui
