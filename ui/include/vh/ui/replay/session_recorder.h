#pragma once
/// @file
/// Recording a session from the main window: Haptics > Record Session (Ctrl+Shift+R,
/// and the Record button in the Haptics dock) writes a `.vhrec` (runtime::RecordingWriter, one
/// TickRecord per servo tick) with the scene's metadata (runtime::makeSessionMetadata()), plus
/// events: "marker" (Haptics > Add Marker, key M) and "tool" (a tool swap was asked for). The
/// runtime adds the others by itself: "isovalue" {"from": A, "to": B} and device
/// (dis)connections from the records (runtime::RecordingWriter), "gains" from
/// HapticThread::setGains(); so the slider and the haptics panel add none here.
///
/// Lifetime: the writer is set on the running haptic thread (HapticThread::setRecorder()). A
/// recording ends with the haptic thread: stopping haptics, a tool or device swap, a new scene
/// and closing the window all stop it (the thread first, then the writer closes and flushes).
/// Stopping by hand while the thread runs clears the thread's recorder and closes the writer at
/// once; the closed writer object is kept until the thread stops (the servo thread may still be
/// inside RecordingWriter::push(), see HapticThread::setRecorder()).
///
/// A write that fails while recording (disk full, file size limit) ends the recording within
/// one status refresh (0.25 s): the writer keeps every whole chunk and adds the end marker when
/// it fits, and the REC text turns into "REC stopped: disk full (No space left on device) — N
/// ticks kept", which stays until the next recording starts.
///
/// Threads: GUI thread only (events go through HapticThread::recordEvent(), stamped with the
/// latest tick). It observes runtime::Session; it holds no copy of the scene.

#include <chrono>
#include <filesystem>
#include <functional>
#include <optional>
#include <memory>
#include <string>
#include <vector>

#include <QElapsedTimer>
#include <QObject>
#include <QString>

#include "vh/ui/view/device_manipulation.h"


class QAction;
class QLabel;
class QMenu;
class QStatusBar;
class QPushButton;
class QTimer;
class QWidget;

namespace vh::runtime {
class RecordingWriter;
class Session;
}

namespace vh::ui {

class MainWindow;

class SessionRecorder : public QObject {
  Q_OBJECT

 public:
  /// Records `session`'s haptic thread (observed: a recording ends when the thread stops or is
  /// replaced); adds its label to `status_bar`; `dialog_parent` parents its dialogs and owns it.
  SessionRecorder(runtime::Session& session, QStatusBar* status_bar, QWidget* dialog_parent);
  ~SessionRecorder() override;

  /// `documents/VolumeHaptics/session-YYYYMMDD-HHMMSS.vhrec` (the folder is created).
  static std::filesystem::path defaultPath();

  /// Starts recording into `path` (the haptic thread is started when it is not running).
  /// @return false (and lastError() names the file and problem) when there is no scene with a
  ///         haptic thread, a replay is shown, or the file cannot be created.
  bool start(const std::filesystem::path& path);
  /// Stops and closes the recording (idempotent). Errors go to lastError() and the status bar.
  void stop();
  bool recording() const noexcept { return writer_ != nullptr; }
  /// The file being (or last) written.
  const std::filesystem::path& path() const noexcept { return path_; }
  QString lastError() const { return last_error_; }
  /// Ticks written to disk so far / dropped (ring overflow) in the current recording.
  std::uint64_t recordsWritten() const noexcept;
  std::uint64_t dropped() const noexcept;

  /// Records a "marker" event {"label": label}. @return false when not recording.
  bool addMarker(const QString& label);
  /// Records a "tool" {"tool": label, "point_spacing_m": s} event when recording (no-op
  /// otherwise); s = 0: automatic spacing.
  void noteTool(const QString& name, double point_spacing_m);

  /// While a replay is shown the haptic thread waits: nothing can be recorded.
  void setReplayActive(bool active);
  /// Where the view's camera is read from (the window's scene view): a recording then holds a
  /// "camera" event at its start and whenever the camera moved since, at most every 250 ms
  /// (recorded_camera.h), so its exported pictures are seen as the user saw them. Unset: none.
  void setCameraSource(std::function<ViewCamera()> source) { camera_source_ = std::move(source); }
  /// Dialogs (file name, marker label) when true; else the default path and labels.
  void setInteractive(bool interactive) { interactive_ = interactive; }

  /// Haptics > Record Session (checkable, Ctrl+Shift+R) and Add Marker (M).
  QAction* recordAction() const noexcept { return record_action_; }
  QAction* markerAction() const noexcept { return marker_action_; }
  /// A row with the Record and Add Marker buttons for the Haptics dock.
  QWidget* makeDockControls(QWidget* parent);
  /// The status bar's recording text ("REC 0:12  2.3 MB  dropped 0"; after a write failure
  /// "REC stopped: <cause> — N ticks kept"; else empty or a notice).
  QString statusText() const;
  /// The write failure that ended the last recording ("REC stopped: ..."); empty when none.
  QString failureText() const { return failure_text_; }
  /// Refreshes the actions, buttons and status text (e.g. after a scene change).
  void updateUi();
  /// Shows `text` in the recording's status bar label for `ms` milliseconds (after the REC
  /// text while recording). Used instead of QStatusBar::showMessage(), which would be drawn
  /// over the servo statistics.
  void showNotice(const QString& text, int ms = 5000);

 signals:
  void recordingChanged(bool recording);
  /// A recording could not be started: `what` the file, `message` the problem.
  void failed(const QString& what, const QString& message);

 private:
  void toggleFromUi(bool on);
  void addMarkerFromUi();
  bool recordEvent(const std::string& type, const std::string& detail_json);

  /// The haptic thread stopped or was replaced: the recording ends, closed writers go.
  void onHapticsStopped();
  /// Records a "camera" event when the view's camera moved since the last one (or none yet).
  void noteCamera();
  /// Status refresh: a writer whose write failed ends the recording, and the REC text says why.
  void checkWriter();

  runtime::Session& session_;
  QWidget* dialog_parent_;
  int observer_ = 0;
  bool replay_active_ = false;
  bool interactive_ = true;
  std::unique_ptr<runtime::RecordingWriter> writer_;
  std::vector<std::unique_ptr<runtime::RecordingWriter>> retired_;  // closed, thread still running
  std::filesystem::path path_;
  std::function<ViewCamera()> camera_source_;
  std::optional<ViewCamera> camera_recorded_;  // the last "camera" event of this recording
  QString last_error_;
  QElapsedTimer elapsed_;
  QTimer* status_timer_ = nullptr;
  QLabel* status_label_ = nullptr;
  QAction* record_action_ = nullptr;
  QAction* marker_action_ = nullptr;
  QPushButton* record_button_ = nullptr;
  QPushButton* marker_button_ = nullptr;
  int marker_count_ = 0;
  QString failure_text_;
  QString notice_;
  qint64 notice_until_ms_ = 0;  // QDateTime::currentMSecsSinceEpoch()
};

}  // namespace vh::ui
