#pragma once
/// @file
/// Replaying a session recording in the main window. File > Open Recording (and a
/// dropped or command-line `.vhrec`) reads the file (warnings shown, not fatal), reloads its
/// scene from the metadata (runtime::sceneFromSessionMetadata(); a missing or changed dataset
/// is an error dialog naming it and the current scene stays), stops the haptic thread and shows
/// the Replay dock: play / pause, speed 0.25x .. 4x, a timeline with |F| and the markers that
/// can be scrubbed, the marker list, and the time / tick / force / contacts of the record shown.
/// The proxy, device, force arrow and isovalue follow the records, and so does the expert's ghost
/// of a recording made with guidance (ReplayGuide); Close Replay returns to live
/// haptics on the same scene. File > Export Recording writes CSV / JSON (runtime), a video
/// (Ogg/Theora) and a PNG (media_export.h).
///
/// Threads: GUI thread only; the haptic thread is stopped while a replay is shown.

#include <atomic>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <thread>
#include <vector>

#include <QElapsedTimer>
#include <QObject>
#include <QString>
#include <QWidget>

#include "vh/runtime/recording.h"
#include "vh/ui/export/media_export.h"
#include "vh/ui/replay/force_timeline.h"
#include "vh/ui/replay/replay_guide.h"

class QAction;
class QComboBox;
class QDockWidget;
class QLabel;
class QListWidget;
class QMenu;
class QPushButton;
class QMainWindow;
class QProgressDialog;
class QTimer;

namespace vh::runtime {
class Session;
struct SceneSpec;
}  // namespace vh::runtime

namespace vh::ui {

class SceneView;
struct Preferences;

/// The replay mode of the main window: its dock, playback and the File menu's recording
/// entries. It asks the window to open the recording's scene (openSceneRequested()); once the
/// window shows it (onSceneShown()), it stops the session's haptic threads and shows records on
/// the scene view; Close Replay starts them again.
class ReplayController : public QObject {
  Q_OBJECT

 public:
  /// `window` hosts the dock (tabbed with `tab_with` when given) and parents the dialogs;
  /// `prefs` gives the look of exported frames and the folder of file dialogs. All must outlive
  /// the controller.
  ReplayController(runtime::Session& session, SceneView& view, Preferences& prefs, QMainWindow* window,
                   QDockWidget* tab_with);
  ~ReplayController() override;

  /// Adds Open Recording..., Export Recording > CSV / JSON / Video / Screenshot and Session
  /// Report... to `file`.
  void addFileMenuActions(QMenu* file);

  /// Reads `path`, checks its dataset and asks for its scene (openSceneRequested(); then
  /// replayStarted() once the window calls onSceneShown(), or nothing after onLoadFailed()).
  /// @return false when the file cannot be read or its dataset is missing / changed: the error
  /// is reported (errorReported()) and the current scene stays.
  bool openRecording(const std::filesystem::path& path);
  /// True while the replay dock drives the view (haptics stopped).
  bool active() const noexcept { return active_; }
  /// True from openRecording() until its scene is shown or failed.
  bool pending() const noexcept { return pending_.has_value(); }
  /// Leaves the replay; the haptic thread starts again (live mode).
  void closeReplay();

  /// Shows the record at recording time `t_s` [s] (clamped): props, isovalue, labels, cursor.
  void setTime(double t_s);
  double time_s() const noexcept { return time_s_; }
  /// Index of the record shown.
  std::size_t currentIndex() const noexcept { return index_; }
  void play();
  void pause();
  bool playing() const noexcept;
  /// Playback speed factor (0.25 .. 4).
  void setSpeed(double factor);
  double speed() const noexcept { return speed_; }

  const runtime::Recording& recording() const noexcept { return recording_; }
  /// The expert's ghost of a recording made with guidance (ReplayGuide: shown when the expert's
  /// recording is found unchanged; else the status bar says it is not available).
  const ReplayGuide& guide() const noexcept { return guide_; }
  /// The felt field carved to the cavity shown at the replay's time, for the tool's shadow (the
  /// window's ViewController reads it while a replay is shown).
  const CarvedRegion& carved() const noexcept { return carved_; }
  const std::filesystem::path& path() const noexcept { return path_; }
  ForceTimeline* timeline() const noexcept { return timeline_; }
  QListWidget* markerList() const noexcept { return marker_list_; }
  QDockWidget* dock() const noexcept { return dock_; }
  /// "t 1.234 s  tick 1234  |F| 0.52 N  contacts 3".
  QString readout() const;

  /// Exports of the replayed recording (File > Export Recording), also for scripts and tests.
  /// @throws std::runtime_error naming the file, or std::logic_error when no replay is shown.
  void exportCsv(const std::filesystem::path& path) const;
  void exportJson(const std::filesystem::path& path) const;
  /// Video of the whole recording at `fps`, frames of `width` x `height` px (0: the view's size)
  /// seen from the view's camera, with the overlay (time, |F|, |torque|, markers, the critical
  /// alert: RecordingFrameRenderer::setOverlay()) unless `overlay` is false, and with the burr's
  /// sound as an Ogg Vorbis track (heard in the drilling's replay, as `export --video`) unless
  /// `sound` is false or there is none (hasVideoSound()). @return frames written (fewer when
  /// `progress` cancelled).
  int exportVideo(const std::filesystem::path& path, double fps = 30.0, int width = 0, int height = 0,
                  const std::function<bool(int, int)>& progress = {}, bool overlay = true, bool sound = true);
  /// Whether a video exported now carries the burr's sound: the recording's burr ran and the
  /// drilling's replay is done (not while it runs, nor when it was cancelled).
  bool hasVideoSound() const noexcept { return !drill_.sound.states.empty(); }
  /// PNG of the record shown now, from the view's camera at the view's size (or the size given),
  /// with the overlay unless `overlay` is false.
  void exportPng(const std::filesystem::path& path, int width = 0, int height = 0, bool overlay = true);
  /// The session report (export/session_report.h) of the replayed recording as an HTML page.
  void exportReport(const std::filesystem::path& path) const;

  /// The main window calls this when its scene is about to be replaced.
  void onSceneTeardown();
  /// The main window showed the scene it was asked for (the recording's, when one is pending).
  void onSceneShown();
  /// The scene load failed or was cancelled: a pending recording is dropped.
  void onLoadFailed();
  /// Dialogs (damaged-recording warnings, export file names, the drilling replay's progress)
  /// when true.
  void setInteractive(bool interactive) { interactive_ = interactive; }
  /// True while the drilling of the replayed recording is being replayed (on its own thread,
  /// with a progress dialog; the picture shows the cavity the recording started from meanwhile,
  /// then the cavity at the replay's time: drillingReplayed()).
  bool drillingPending() const noexcept { return drill_pending_; }

 signals:
  /// A recording's scene is shown and the replay dock drives it.
  void replayStarted();
  void replayClosed();
  /// The cavity shown changed (carved() with it): the shadow is cast again.
  void cavityShown();
  /// Open the recording's scene (`opened`: the recording, for the recent files).
  void openSceneRequested(const vh::runtime::SceneSpec& spec, const std::filesystem::path& opened);
  /// `what` (a file) could not be read or written: `message` names it and the problem.
  void errorReported(const QString& what, const QString& message);
  /// A short message for the status bar.
  void noticeRequested(const QString& text, int ms = 5000);
  /// The drilling replay finished (`ok`: the cavity now follows the replay's time; false: it
  /// failed, the picture keeps the cavity the recording started from).
  void drillingReplayed(bool ok);

 private:
  void buildDock();
  void advance();
  void exportFromMenu(int kind);
  /// An off-screen renderer of the replayed recording for an export: `width` x `height` pixels
  /// (0: the view's size, at least 16), the view's camera, the overlay when asked, the tool's
  /// shadow as the main view casts it and the cavity as the replay shows it.
  std::unique_ptr<RecordingFrameRenderer> exportFrames(int width, int height, bool overlay) const;
  /// File > Session Report: of the replayed recording, else of one the user picks.
  void reportFromMenu();
  /// The replayed recording, else one the user picks (read into `loaded`; null when cancelled);
  /// `from` is set to its file.
  const runtime::Recording* recordingToExport(runtime::Recording& loaded, std::filesystem::path& from,
                                              const QString& folder) const;
  void updateActions();

  runtime::Session& session_;
  SceneView& view_;
  Preferences& prefs_;
  QMainWindow* window_;
  QDockWidget* tab_with_;
  bool interactive_ = true;
  runtime::Recording recording_;
  std::filesystem::path path_;
  ReplayGuide guide_;
  /// The expert's ghost at record `r` (hidden where the recording was not guided).
  void showGhostAt(const runtime::TickRecord& r);
  std::optional<runtime::Recording> pending_;
  std::filesystem::path pending_path_;
  bool active_ = false;
  double time_s_ = 0.0;
  std::size_t index_ = 0;
  double speed_ = 1.0;
  QElapsedTimer play_clock_;
  double play_origin_s_ = 0.0;
  QTimer* play_timer_ = nullptr;
  QDockWidget* dock_ = nullptr;
  ForceTimeline* timeline_ = nullptr;
  QPushButton* play_button_ = nullptr;
  QComboBox* speed_box_ = nullptr;
  QLabel* readout_ = nullptr;
  QListWidget* marker_list_ = nullptr;
  std::vector<double> marker_times_s_;
  // Drilling: the cavity the recording started from, then (once replayed) the voxels a
  // deterministic replay removed and how many by each record; the picture shows the first
  // drill_shown_ of drill_.picture.voxels.
  DrillingTimeline drill_;
  std::uint64_t drill_shown_ = 0;
  CarvedRegion carved_;  // the felt field carved as the picture is, for the tool's shadow
  void replayDrilling();
  void finishDrillingReplay(std::uint64_t generation, bool ok, DrillingTimeline timeline);
  /// Cancels a drilling replay under way and waits for its thread (a result it sent is dropped).
  void stopDrillingReplay();
  // The drilling replay's thread and what it shares with the GUI thread.
  std::thread drill_thread_;
  std::atomic<bool> drill_cancel_{false};
  std::atomic<double> drill_progress_{0.0};
  std::uint64_t drill_generation_ = 0;
  bool drill_pending_ = false;
  QProgressDialog* drill_dialog_ = nullptr;
  QTimer* drill_timer_ = nullptr;
  void showDrillingAt(std::size_t record_index);
  std::vector<QAction*> export_actions_;
};

}  // namespace vh::ui
