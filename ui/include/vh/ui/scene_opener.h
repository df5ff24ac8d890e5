#pragma once
/// @file
/// Opening files the way a user does: File menu dialogs, recent files, drag and drop, a DICOM
/// folder's series chooser, a volume received over OpenIGTLink. Turns what was opened into a
/// runtime::SceneSpec for SceneLoader (which reads it off the GUI thread) and reports progress,
/// failures (a dialog naming the file and the problem; what is open stays) and cancellation.
/// A recording (.vhrec) or a segmentation of the open scan is handed on by a signal.
///
/// Data flows one way: a path -> SceneLoader -> this (sceneLoaded()) -> the window -> Session.
/// The opener hears that its scene is shown from the Session (a new scene), not from the window.
/// GUI thread only.

#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <QObject>
#include <QString>

#include "vh/io/dicom_series.h"
#include "vh/io/volume_loader.h"
#include "vh/runtime/device.h"
#include "vh/runtime/scene.h"
#include "vh/ui/panels/histogram.h"

class QMenu;
class QMimeData;
class QStatusBar;
class QWidget;

namespace vh::runtime {
class Session;
}

namespace vh::ui {

/// The files a reader's error names as damaged ("... on PATH: a damaged file ..." or "... on N
/// damaged files: PATH | PATH; ..."), in the message's order; empty when it names none.
std::vector<std::filesystem::path> damagedFilesNamed(const QString& message);

/// A new temporary folder that mirrors `folder` and its sub-folders with a symbolic link (a copy
/// where links fail) to every file but those in `without`: the series opened without its
/// damaged files, the original folder untouched.
/// @throws std::runtime_error naming the folder when it cannot be made.
std::filesystem::path folderWithout(const std::filesystem::path& folder,
                                    const std::vector<std::filesystem::path>& without);

class SceneLoader;
class StatusLine;
struct LoadedViewerScene;
struct Preferences;

/// What the main window opens: a loaded scene with its device (null: haptics off) and what the
/// window shows about it. The session builds the haptic threads.
struct ViewerScene {
  runtime::LoadedScene scene;               ///< As loaded: volume (field + image), tool, isovalue, pose, spec.
  std::shared_ptr<runtime::Device> device;  ///< Null: no device (haptics off).
  std::optional<Histogram> histogram;       ///< Absent: computed when shown.
  std::string title;                        ///< Window title detail (e.g. file name).
  std::filesystem::path opened;             ///< What the user opened (recent files).
};

/// A ViewerScene for `loaded` driving `device` (null: haptics off), titled by its file name.
ViewerScene makeViewerScene(const runtime::LoadedScene& loaded, std::shared_ptr<runtime::Device> device);
/// The ViewerScene of a finished load: its histogram, what was opened, and a title of the file
/// name and, for DICOM, the series description.
ViewerScene viewerSceneFor(LoadedViewerScene& loaded);
/// "VolumeHaptics - TITLE (FORMAT MODALITY  NXxNYxNZ  SPACING)" for the session's loaded scene;
/// "VolumeHaptics" without one.
QString windowTitleFor(const std::string& title, const runtime::Session& session);

class SceneOpener : public QObject {
  Q_OBJECT

 public:
  /// File dialogs and error boxes are parented to `window`; notes go to `status_bar`. All
  /// references outlive this. Observes `session`: the scene of its own load, once the session
  /// holds it, joins the recent files and waits for its first frame (loading()).
  SceneOpener(SceneLoader& loader, const runtime::Session& session, Preferences& prefs, StatusLine& status,
              QStatusBar* status_bar, QWidget* window);
  ~SceneOpener() override;

  /// Opens `path`: a scene .json, a recording .vhrec (recordingRequested()), a DICOM folder (a
  /// chooser when it holds several series), a segmentation .seg.nrrd (segmentationRequested()
  /// while a scan is open, else its own scan), or a NRRD / MetaImage / DICOM file. Asynchronous.
  void openPath(const QString& path);
  /// Loads a parsed scene; `opened` goes to the recent files once it is shown.
  void openScene(const runtime::SceneSpec& spec, const std::filesystem::path& opened = {});
  /// Opens a volume already in memory (received over OpenIGTLink) with the default tool.
  void openLoadedVolume(io::LoadedVolume volume);
  /// Loads series `series` of a listed DICOM folder, time point `phase` (0-based).
  void openDicomSeries(const io::DicomSeriesInfo& series, int phase = 0);
  /// The path a drop of `mime` opens (several files of one series: their folder); empty: none.
  static QString droppedPath(const QMimeData& mime);

  /// File > Open from PACS: the browser (PacsBrowserDialog) on the server of the preferences;
  /// the series it retrieves into the cache opens as a DICOM folder (openPath()).
  void openFromPacs();

  /// Adds Open DICOM Folder / from PACS / Volume File / Scene to `file`.
  void addFileMenuActions(QMenu* file);
  /// The recent files, each opened with openPath(); disabled while empty.
  QMenu* recentFilesMenu() const noexcept { return recent_menu_; }

  /// The view rendered its frame number `frame_count`; after a new scene, loading() stays true
  /// until the first frame after it (the volume's GPU upload).
  void frameRendered(std::uint64_t frame_count);
  /// True from a load's start until its scene is shown and rendered once (or it failed).
  bool loading() const noexcept;
  /// Abandons the running load; what is open stays.
  void cancelLoading();

  /// Dialogs (errors, the series chooser) when true; otherwise errors go to stderr only and the
  /// largest DICOM series is taken (scripted runs, tests).
  void setInteractive(bool interactive) { interactive_ = interactive; }
  /// Shows `message` about `what` (a path) and emits loadFailed(). When it names a damaged file
  /// of the folder `what` (or several), the dialog offers to open the series without them
  /// (folderWithout()).
  void reportError(const QString& what, const QString& message);
  /// The last error ("FILE: problem"); empty when none or after a successful load.
  QString lastError() const { return last_error_; }

 signals:
  /// A scene the loader finished, as the window shows it (viewerSceneFor()): the loader reports
  /// to the opener only; the window gives it to the Session, which the opener observes.
  void sceneLoaded(std::shared_ptr<vh::ui::ViewerScene> scene);
  void loadStarted();
  void loadFailed(const QString& message);
  void loadCancelled();
  void recordingRequested(const std::filesystem::path& path);
  void segmentationRequested(const std::filesystem::path& path);

 private:
  /// When `message` names damaged files inside the folder `what`: the dialog offering the series
  /// without them, and true; else false.
  bool offerWithoutDamaged(const QString& what, const QString& message);
  void onSeriesListed(const QString& folder, const std::vector<io::DicomSeriesInfo>& series);
  void openFileDialog(int kind);
  void rebuildRecentMenu();
  /// The Session holds the scene of this opener's load: `opened` joins the recent files; the
  /// progress stays until the next frame.
  void onOwnSceneShown(const std::filesystem::path& opened);

  SceneLoader& loader_;
  const runtime::Session& session_;
  Preferences& prefs_;
  StatusLine& status_;
  QStatusBar* status_bar_;
  QWidget* window_;
  QMenu* recent_menu_ = nullptr;
  bool interactive_ = true;
  int observer_ = 0;
  // What this opener's finished load opened, until the Session holds its scene (or it failed).
  std::optional<std::filesystem::path> shown_pending_;
  std::uint64_t last_frame_ = 0;  // the view's last frame number (frameRendered())
  bool upload_pending_ = false;   // a new scene waits for its first frame (GPU upload)
  std::uint64_t upload_frame_ = 0;
  QString last_error_;
};

}  // namespace vh::ui
