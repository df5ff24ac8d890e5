#include "vh/ui/replay/session_recorder.h"

#include "vh/ui/replay/recorded_camera.h"

#include <algorithm>
#include <filesystem>
#include <iostream>
#include <stdexcept>

#include <QAction>
#include <QDateTime>
#include <QDir>
#include <QFileDialog>
#include <QHBoxLayout>
#include <QInputDialog>
#include <QLabel>
#include <QLineEdit>
#include <QPushButton>
#include <QSignalBlocker>
#include <QStandardPaths>
#include <QStatusBar>
#include <QTimer>

#include <nlohmann/json.hpp>

#include "vh/io/private_files.h"
#include "vh/runtime/recording.h"
#include "vh/runtime/session_metadata.h"
#include "vh/runtime/session.h"

namespace vh::ui {
namespace {

namespace fs = std::filesystem;

constexpr int kStatusPeriodMs = 250;

QString sizeText(double bytes) {
  if (bytes < 1024.0 * 1024.0) return QString("%1 KB").arg(bytes / 1024.0, 0, 'f', 0);
  return QString("%1 MB").arg(bytes / (1024.0 * 1024.0), 0, 'f', 1);
}

}  // namespace

SessionRecorder::SessionRecorder(runtime::Session& session, QStatusBar* status_bar, QWidget* dialog_parent)
    : QObject(dialog_parent), session_(session), dialog_parent_(dialog_parent) {
  setObjectName("sessionRecorder");
  record_action_ = new QAction("&Record Session", this);
  record_action_->setObjectName("recordSessionAction");
  record_action_->setCheckable(true);
  record_action_->setShortcut(QKeySequence("Ctrl+Shift+R"));
  record_action_->setToolTip("Records every servo tick (poses, force, contacts, isovalue) and your markers to a .vhrec file");
  connect(record_action_, &QAction::triggered, this, &SessionRecorder::toggleFromUi);
  marker_action_ = new QAction("Add &Marker", this);
  marker_action_->setObjectName("addMarkerAction");
  marker_action_->setShortcut(QKeySequence(Qt::Key_M));
  marker_action_->setToolTip("Adds a labelled marker to the recording at the current tick (M)");
  connect(marker_action_, &QAction::triggered, this, &SessionRecorder::addMarkerFromUi);

  status_label_ = new QLabel(status_bar);
  status_label_->setObjectName("recordingStatus");
  status_bar->addPermanentWidget(status_label_);
  status_label_->hide();
  status_timer_ = new QTimer(this);
  status_timer_->setInterval(kStatusPeriodMs);
  connect(status_timer_, &QTimer::timeout, this, [this] {
    checkWriter();
    noteCamera();
    updateUi();
  });
  observer_ = session_.addObserver([this](runtime::SessionChange what) {
    using runtime::SessionChange;
    const bool replaced = runtime::has(what, SessionChange::kScene) || runtime::has(what, SessionChange::kTool) ||
                          runtime::has(what, SessionChange::kDevice) || runtime::has(what, SessionChange::kSegments);
    if (replaced || (runtime::has(what, SessionChange::kRunning) && !session_.hapticsRunning())) onHapticsStopped();
    updateUi();
  });
  updateUi();
}

SessionRecorder::~SessionRecorder() {
  session_.removeObserver(observer_);
  // The window stops its haptic thread before its children go; this is the last safety net.
  stop();
}

void SessionRecorder::setReplayActive(bool active) {
  replay_active_ = active;
  updateUi();
}

fs::path SessionRecorder::defaultPath() {
  QString docs = QStandardPaths::writableLocation(QStandardPaths::DocumentsLocation);
  if (docs.isEmpty()) docs = QDir::homePath();
  const QString folder = QDir(docs).filePath("VolumeHaptics");
  try {
    io::createPrivateDirectories(folder.toStdString());  // 0700: recordings are patient data
  } catch (const std::runtime_error&) {  // NOLINT(bugprone-empty-catch): start() reports the file it cannot create
  }
  const QString name = "session-" + QDateTime::currentDateTime().toString("yyyyMMdd-HHmmss") + ".vhrec";
  return fs::path(QDir(folder).filePath(name).toStdString());
}

bool SessionRecorder::start(const fs::path& path) {
  if (recording()) stop();
  last_error_.clear();
  failure_text_.clear();
  if (!session_.hasScene() || session_.hapticThread() == nullptr) {
    last_error_ = "Nothing to record: the scene has no device and haptic thread";
    updateUi();
    return false;
  }
  if (replay_active_ && !session_.hapticsRunning()) {  // the haptic thread waits while a replay is shown
    last_error_ = "Nothing to record: the haptic thread is not running (close the replay first)";
    updateUi();
    return false;
  }
  // The dataset's checksum first (cached from then on): a missing or unreadable scan is told
  // before the hand is touched, and the hashing does not lengthen the pause below.
  try {
    (void)runtime::datasetChecksum(session_.loaded().spec.volume.path);
  } catch (const std::exception& e) {
    last_error_ = QString::fromStdString(path.string()) + ": " + QString::fromUtf8(e.what());
    std::cerr << "volume-haptics: recording: " << last_error_.toStdString() << '\n';
    updateUi();
    return false;
  }
  // A replay re-runs the recording through fresh threads from its initial pose and cavity: the
  // recording starts with such threads (rebuilt where the proxy is when they had run) and holds
  // every one of their ticks, so it replays bit for bit whenever it was started. The force lets
  // go meanwhile, for the ramp and the threads' build (0.1 s; a drill is prepared before it).
  const std::optional<haptics::Pose> X_WP_start = session_.prepareRecording();
  runtime::HapticThread* haptics = session_.hapticThread();
  if (!X_WP_start || haptics == nullptr) {
    last_error_ = "Nothing to record: the haptic thread could not be rebuilt";
    updateUi();
    return false;
  }
  try {
    runtime::SessionInfo info;
    if (session_.device() != nullptr) info.device_name = session_.device()->name();
    info.device_kind = session_.simulatedDevice() != nullptr ? "simulated"
                       : session_.loaded().spec.device.has_value() ? session_.loaded().spec.device->kind
                                                                   : "hardware";
    runtime::LiveValues live = session_.live();
    live.X_WT_initial = *X_WP_start;
    const std::string metadata = runtime::makeSessionMetadata(session_.loaded(), live, info);
    runtime::RecordingWriterOptions options;
    options.servo_rate_Hz = haptics->solverRate_Hz();  // one record per solver tick
    if (options.chunk_records >= options.servo_rate_Hz) {
      options.chunk_records = static_cast<std::size_t>(std::max(1.0, options.servo_rate_Hz / 2.0));
    }
    if (!path.parent_path().empty()) io::createPrivateDirectories(path.parent_path());
    writer_ = std::make_unique<runtime::RecordingWriter>(path, metadata, options);
  } catch (const std::exception& e) {
    writer_.reset();
    last_error_ = QString::fromStdString(path.string()) + ": " + QString::fromUtf8(e.what());
    std::cerr << "volume-haptics: recording: " << last_error_.toStdString() << '\n';
    session_.startHaptics();
    updateUi();
    return false;
  }
  path_ = path;
  marker_count_ = 0;
  camera_recorded_.reset();
  haptics->setRecorder(writer_.get());  // before the threads' first tick
  session_.startHaptics();
  noteCamera();  // the view as the recording starts
  elapsed_.start();
  status_timer_->start();
  updateUi();
  status_label_->setToolTip("Recording to " + QString::fromStdString(path.string()));
  emit recordingChanged(true);
  return true;
}

void SessionRecorder::stop() {
  if (writer_ == nullptr) return;
  runtime::HapticThread* haptics = session_.hapticThread();
  const bool thread_running = haptics != nullptr && haptics->running();
  if (haptics != nullptr) haptics->setRecorder(nullptr);
  try {
    writer_->close();
  } catch (const std::exception& e) {
    last_error_ = QString::fromStdString(path_.string()) + ": " + QString::fromUtf8(e.what());
    std::cerr << "volume-haptics: recording: " << last_error_.toStdString() << '\n';
  }
  const std::uint64_t records = writer_->recordsWritten();
  const std::uint64_t dropped = writer_->dropped();
  if (writer_->failed()) {
    failure_text_ = QString::fromUtf8("REC stopped: %1 \u2014 %2 ticks kept")
                        .arg(QString::fromStdString(writer_->failure()))
                        .arg(static_cast<qulonglong>(records));
    status_label_->setToolTip(failure_text_ + "\n" + QString::fromStdString(path_.string()));
  }
  if (thread_running) {
    retired_.push_back(std::move(writer_));  // the servo thread may be inside push() still
  } else {
    writer_.reset();
  }
  status_timer_->stop();
  updateUi();
  if (last_error_.isEmpty()) {
    showNotice(QString("Recording saved: %1 (%2 ticks, %3 dropped)")
                   .arg(QString::fromStdString(path_.filename().string()))
                   .arg(static_cast<qulonglong>(records))
                   .arg(static_cast<qulonglong>(dropped)),
               8000);
    status_label_->setToolTip(QString::fromStdString(path_.string()));
  }
  emit recordingChanged(false);
}

void SessionRecorder::checkWriter() {
  // stop() closes the writer (the end marker when it fits; the file keeps its whole chunks)
  // and words the failure.
  if (writer_ != nullptr && writer_->failed()) stop();
}

std::uint64_t SessionRecorder::recordsWritten() const noexcept {
  return writer_ != nullptr ? writer_->recordsWritten() : 0;
}

std::uint64_t SessionRecorder::dropped() const noexcept { return writer_ != nullptr ? writer_->dropped() : 0; }

void SessionRecorder::onHapticsStopped() {
  stop();
  runtime::HapticThread* haptics = session_.hapticThread();
  if (haptics == nullptr || !haptics->running()) retired_.clear();
}

bool SessionRecorder::recordEvent(const std::string& type, const std::string& detail_json) {
  runtime::HapticThread* haptics = session_.hapticThread();
  if (writer_ == nullptr || haptics == nullptr) return false;
  haptics->recordEvent(type, detail_json);
  return true;
}

bool SessionRecorder::addMarker(const QString& label) {
  const nlohmann::json detail = {{"label", label.toStdString()}};
  if (!recordEvent("marker", detail.dump())) return false;
  ++marker_count_;
  showNotice("marker: " + label, 2500);
  return true;
}

void SessionRecorder::noteTool(const QString& name, double point_spacing_m) {
  if (!recording()) return;
  recordEvent("tool", nlohmann::json({{"tool", name.toStdString()}, {"point_spacing_m", point_spacing_m}}).dump());
}

void SessionRecorder::toggleFromUi(bool on) {
  if (!on) {
    stop();
    return;
  }
  fs::path path = defaultPath();
  if (interactive_) {
    const QString chosen = QFileDialog::getSaveFileName(dialog_parent_, "Record the session to",
                                                        QString::fromStdString(path.string()),
                                                        "Session recordings (*.vhrec)");
    if (chosen.isEmpty()) {
      updateUi();
      return;
    }
    path = fs::path(chosen.toStdString());
    if (path.extension().empty()) path += ".vhrec";
  }
  if (!start(path)) emit failed(QString::fromStdString(path.string()), last_error_);
}

void SessionRecorder::noteCamera() {
  if (writer_ == nullptr || !camera_source_) return;
  const ViewCamera camera = camera_source_();
  if (camera_recorded_ && sameView(*camera_recorded_, camera)) return;
  if (recordEvent("camera", cameraEventJson(camera))) camera_recorded_ = camera;
}

void SessionRecorder::addMarkerFromUi() {
  if (!recording()) {
    showNotice("Markers go into a recording: start one first (Ctrl+Shift+R)", 4000);
    return;
  }
  QString label = QString("Marker %1").arg(marker_count_ + 1);
  if (interactive_) {
    bool ok = false;
    label = QInputDialog::getText(dialog_parent_, "Add a marker", "Label:", QLineEdit::Normal, label, &ok);
    if (!ok) return;
  }
  addMarker(label);
}

void SessionRecorder::showNotice(const QString& text, int ms) {
  notice_ = text;
  notice_until_ms_ = QDateTime::currentMSecsSinceEpoch() + ms;
  updateUi();
  QTimer::singleShot(ms + 50, this, &SessionRecorder::updateUi);
}

QString SessionRecorder::statusText() const {
  const bool notice = !notice_.isEmpty() && QDateTime::currentMSecsSinceEpoch() < notice_until_ms_;
  if (!recording()) {
    if (!failure_text_.isEmpty()) return failure_text_ + (notice ? "   " + notice_ : QString());
    return notice ? notice_ : QString();
  }
  const qint64 s = elapsed_.elapsed() / 1000;
  const double bytes = static_cast<double>(writer_->recordsWritten()) * sizeof(runtime::TickRecord);
  return QString::fromUtf8("\u25cf REC %1:%2  %3  dropped %4")
      .arg(s / 60)
      .arg(s % 60, 2, 10, QChar('0'))
      .arg(sizeText(bytes))
      .arg(static_cast<qulonglong>(writer_->dropped())) + (notice ? "   " + notice_ : QString());
}

void SessionRecorder::updateUi() {
  const bool on = recording();
  const QString text = statusText();
  status_label_->setText(text);
  status_label_->setStyleSheet(on || !failure_text_.isEmpty() ? "QLabel { color: #d03030; font-weight: bold; }" : "");
  status_label_->setVisible(!text.isEmpty());
  {
    const QSignalBlocker block(record_action_);
    record_action_->setChecked(on);
  }
  record_action_->setEnabled(on || (session_.hapticThread() != nullptr && !replay_active_));
  marker_action_->setEnabled(on);
  if (record_button_ != nullptr) {
    const QSignalBlocker block(record_button_);
    record_button_->setChecked(on);
    record_button_->setText(on ? "Stop Recording" : "Record");
    record_button_->setEnabled(record_action_->isEnabled());
  }
  if (marker_button_ != nullptr) marker_button_->setEnabled(on);
}

QWidget* SessionRecorder::makeDockControls(QWidget* parent) {
  auto* row = new QWidget(parent);
  auto* layout = new QHBoxLayout(row);
  layout->setContentsMargins(6, 0, 6, 6);
  record_button_ = new QPushButton("Record", row);
  record_button_->setObjectName("recordButton");
  record_button_->setCheckable(true);
  record_button_->setToolTip(record_action_->toolTip() + " (Ctrl+Shift+R)");
  marker_button_ = new QPushButton("Add Marker", row);
  marker_button_->setObjectName("markerButton");
  marker_button_->setToolTip(marker_action_->toolTip());
  layout->addWidget(record_button_);
  layout->addWidget(marker_button_);
  connect(record_button_, &QPushButton::clicked, this, &SessionRecorder::toggleFromUi);
  connect(marker_button_, &QPushButton::clicked, this, &SessionRecorder::addMarkerFromUi);
  updateUi();
  return row;
}

}  // namespace vh::ui
