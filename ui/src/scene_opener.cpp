#include "vh/ui/scene_opener.h"

#include <algorithm>
#include <cctype>
#include <iostream>
#include <set>
#include <stdexcept>
#include <string>
#include <system_error>

#include <QAbstractButton>
#include <QCoreApplication>
#include <QDir>
#include <QFileDialog>
#include <QFileInfo>
#include <QMenu>
#include <QMessageBox>
#include <QMimeData>
#include <QRegularExpression>
#include <QStatusBar>
#include <QUrl>

#include "vh/io/dicom_rtstruct.h"
#include "vh/io/dicom_seg.h"
#include "vh/io/private_files.h"
#include "vh/io/segmentation.h"
#include "vh/runtime/session.h"
#include "vh/ui/panels/pacs_dialog.h"
#include "vh/ui/panels/series_chooser.h"
#include "vh/ui/panels/status_line.h"
#include "vh/ui/preferences.h"
#include "vh/ui/scene_loader.h"

namespace vh::ui {
namespace {

namespace fs = std::filesystem;

constexpr int kNoticeStatusMs = 10000;  // a note stays in the status bar this long

QString q(const std::string& s) { return QString::fromStdString(s); }

std::string lowerExtension(const fs::path& p) {
  std::string ext = p.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return ext;
}

enum FileDialogKind { kDicomFolder = 0, kVolumeFile = 1, kSceneFile = 2 };

}  // namespace

QString windowTitleFor(const std::string& title, const runtime::Session& session) {
  QString text = "VolumeHaptics";
  if (!session.hasScene()) return text;
  if (!title.empty()) text += " - " + q(title);
  const io::VolumeInfo& info = session.loaded().volume.info;
  const auto& g = session.loaded().volume.field->geometry();
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
  if (!facts.isEmpty()) text += " (" + facts + ")";
  return text;
}


ViewerScene makeViewerScene(const runtime::LoadedScene& loaded, std::shared_ptr<runtime::Device> device) {
  ViewerScene v;
  v.scene = loaded;
  v.device = std::move(device);
  v.title = loaded.volume.info.source.filename().string();
  if (v.title.empty()) v.title = loaded.spec.volume.path;
  return v;
}

namespace {

/// Whether `name` is a DICOM UID (digits and dots, e.g. the folder a PACS retrieve wrote into),
/// which names nothing a user recognises.
bool isDicomUid(const std::string& name) {
  return name.size() >= 8 && name.find('.') != std::string::npos &&
         std::all_of(name.begin(), name.end(), [](char c) { return c == '.' || (c >= '0' && c <= '9'); });
}

}  // namespace

ViewerScene viewerSceneFor(LoadedViewerScene& loaded) {
  ViewerScene v = makeViewerScene(loaded.scene, loaded.device);
  v.histogram = std::move(loaded.histogram);
  v.opened = loaded.opened;
  if (!loaded.title.empty()) v.title = loaded.title;
  const std::string& description = loaded.scene.volume.info.description;
  // Some scanners write the text "None" where the series has no description: no title part.
  const QString words = q(description).trimmed();
  const bool says_nothing = words.isEmpty() || words.compare("none", Qt::CaseInsensitive) == 0;
  if (!says_nothing && loaded.scene.volume.info.format == "DICOM" && description != v.title) {
    // A folder named by the series UID (a PACS retrieve): the description alone names it.
    v.title = isDicomUid(v.title) ? description : v.title + " - " + description;
  }
  return v;
}

SceneOpener::SceneOpener(SceneLoader& loader, const runtime::Session& session, Preferences& prefs, StatusLine& status,
                         QStatusBar* status_bar, QWidget* window)
    : QObject(window), loader_(loader), session_(session), prefs_(prefs), status_(status), status_bar_(status_bar),
      window_(window) {
  connect(&loader_, &SceneLoader::progress, this,
          [this](const QString& stage, int percent) { status_.showProgress(stage, percent, true); });
  connect(&loader_, &SceneLoader::seriesListed, this,
          [this](const QString& folder, std::shared_ptr<std::vector<io::DicomSeriesInfo>> series) {
            onSeriesListed(folder, *series);
          });
  connect(&loader_, &SceneLoader::sceneLoaded, this, [this](std::shared_ptr<LoadedViewerScene> loaded) {
    shown_pending_ = loaded->opened;
    emit sceneLoaded(std::make_shared<ViewerScene>(viewerSceneFor(*loaded)));
    shown_pending_.reset();  // not taken (the window refused it): nothing joins the recent files
  });
  connect(&loader_, &SceneLoader::failed, this, &SceneOpener::reportError);
  observer_ = session_.addObserver([this](runtime::SessionChange what) {
    if (runtime::has(what, runtime::SessionChange::kScene) && shown_pending_.has_value() && session_.hasScene()) {
      const fs::path opened = *shown_pending_;
      shown_pending_.reset();
      onOwnSceneShown(opened);
    }
  });
  connect(&loader_, &SceneLoader::cancelled, this, [this] {
    status_bar_->showMessage("Loading cancelled; what was open is kept", 4000);
    emit loadCancelled();
  });
  connect(&loader_, &SceneLoader::idle, this, [this] {
    if (!upload_pending_) status_.hideProgress();
  });
  connect(&status_, &StatusLine::cancelRequested, this, &SceneOpener::cancelLoading);
  recent_menu_ = new QMenu("Open &Recent", window_);
  recent_menu_->setObjectName("recentFilesMenu");
  rebuildRecentMenu();
}

void SceneOpener::openPath(const QString& path) {
  const fs::path p = fs::path(path.toStdString());
  std::error_code ec;
  if (path.isEmpty() || !fs::exists(p, ec)) {
    reportError(path, path + ": no such file or folder");
    return;
  }
  prefs_.last_folder = QFileInfo(path).absolutePath();
  if (fs::is_directory(p, ec)) {
    loader_.listSeries(p);
    return;
  }
  const std::string ext = lowerExtension(p);
  if (ext == ".vhrec") {
    emit recordingRequested(p);
    return;
  }
  // A DICOM SEG or RT Structure Set: segments drawn on a scan, placed on it.
  const bool dicom_seg =
      ext != ".nrrd" && ext != ".nhdr" && (io::isDicomSegmentationFile(p) || io::isDicomRtStructFile(p));
  if (dicom_seg && !session_.hasScene()) {
    reportError(path, path + ": a DICOM SEG or RT Structure Set is opened on the scan it segments: open that scan first");
    return;
  }
  const bool nifti = ext == ".nii" || ext == ".gz" || ext == ".hdr";  // a label map says so in its intent_code
  if (dicom_seg || ((ext == ".nrrd" || ext == ".nhdr" || nifti) && io::isSegmentationFile(p))) {
    // A segmentation: the segments of the scan shown; alone, a .seg.nrrd is its own scan.
    if (session_.hasScene()) {
      emit segmentationRequested(p);
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

void SceneOpener::openScene(const runtime::SceneSpec& spec, const fs::path& opened) {
  loader_.loadScene(spec, opened);
  emit loadStarted();
}

void SceneOpener::openLoadedVolume(io::LoadedVolume volume) {
  status_bar_->showMessage(q("Opening '" + volume.info.description + "' received over OpenIGTLink"), kNoticeStatusMs);
  const runtime::SceneSpec spec = runtime::sceneForLoadedVolume(volume);
  loader_.loadScene(spec, {}, std::move(volume));
  emit loadStarted();
}

void SceneOpener::openDicomSeries(const io::DicomSeriesInfo& series, int phase) {
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

void SceneOpener::onSeriesListed(const QString& folder, const std::vector<io::DicomSeriesInfo>& series) {
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
  status_.hideProgress();
  SeriesChooserDialog dialog(folder, series, window_);
  if (dialog.exec() == QDialog::Accepted && dialog.selectedRow() >= 0) {
    openDicomSeries(dialog.model()->series(dialog.selectedRow()), dialog.selectedPhase());
  }
}

QString SceneOpener::droppedPath(const QMimeData& mime) {
  const QList<QUrl> urls = mime.urls();
  if (urls.isEmpty() || !urls.front().isLocalFile()) return {};
  QString path = urls.front().toLocalFile();
  // Several files of one DICOM series dropped together: open their folder.
  if (urls.size() > 1 && !QFileInfo(path).isDir()) path = QFileInfo(path).absolutePath();
  return path;
}

SceneOpener::~SceneOpener() { session_.removeObserver(observer_); }

void SceneOpener::onOwnSceneShown(const fs::path& opened) {
  upload_pending_ = true;
  upload_frame_ = last_frame_;
  status_.showProgress("Uploading the volume to the GPU", 95, false);
  if (!opened.empty()) {
    prefs_.addRecentFile(q(fs::absolute(opened).lexically_normal().string()));
    rebuildRecentMenu();
  }
  last_error_.clear();
}

void SceneOpener::frameRendered(std::uint64_t frame_count) {
  last_frame_ = frame_count;
  if (upload_pending_ && frame_count > upload_frame_) {
    upload_pending_ = false;
    if (!loader_.busy()) status_.hideProgress();
  }
}

bool SceneOpener::loading() const noexcept { return loader_.busy() || upload_pending_; }

void SceneOpener::cancelLoading() {
  loader_.cancel();
  status_.hideProgress();
  emit loadCancelled();
}

std::vector<fs::path> damagedFilesNamed(const QString& message) {
  static const QRegularExpression several(" on \\d+ damaged files: (.*?)(?:; |\\. To open|$)");
  if (const QRegularExpressionMatch m = several.match(message); m.hasMatch()) {
    std::vector<fs::path> files;
    for (const QString& p : m.captured(1).split(" | ", Qt::SkipEmptyParts)) files.emplace_back(p.toStdString());
    return files;
  }
  const qsizetype end = message.indexOf(": a damaged file");
  if (end < 0) return {};
  const qsizetype on = message.lastIndexOf(" on ", end);
  if (on < 0) return {};
  return {fs::path(message.mid(on + 4, end - on - 4).toStdString())};
}

fs::path folderWithout(const fs::path& folder, const std::vector<fs::path>& without) {
  std::error_code ec;
  if (!fs::is_directory(folder, ec)) throw std::runtime_error(folder.string() + ": not a folder");
  const fs::path base = fs::path(QDir::tempPath().toStdString());
  fs::path out;
  for (int n = 0; n < 1000; ++n) {
    const std::string left_out = without.size() == 1 ? without[0].filename().string()
                                                     : std::to_string(without.size()) + "-damaged-files";
    out = base / ("volume-haptics-" + folder.filename().string() + "-without-" + left_out + "-" +
                  std::to_string(QCoreApplication::applicationPid()) + "-" + std::to_string(n));
    if (fs::create_directory(out, ec)) {
      fs::permissions(out, io::kPrivateDirPerms, ec);  // copies of the patient's files: owner only
      break;
    }
    out.clear();
  }
  if (out.empty()) throw std::runtime_error(folder.string() + ": cannot make a folder in " + base.string());
  std::set<fs::path> skip;
  for (const fs::path& w : without) skip.insert(fs::weakly_canonical(w, ec));
  for (auto it = fs::recursive_directory_iterator(folder, ec); !ec && it != fs::recursive_directory_iterator();
       it.increment(ec)) {
    const fs::path rel = it->path().lexically_relative(folder);
    if (it->is_directory(ec)) {
      fs::create_directories(out / rel, ec);
      continue;
    }
    if (skip.count(fs::weakly_canonical(it->path(), ec)) != 0) continue;
    std::error_code link_ec;
    fs::create_symlink(fs::absolute(it->path()), out / rel, link_ec);
    if (link_ec) fs::copy_file(it->path(), out / rel, link_ec);
    if (link_ec) throw std::runtime_error((out / rel).string() + ": cannot link or copy " + it->path().string());
  }
  if (ec) throw std::runtime_error(folder.string() + ": cannot list it (" + ec.message() + ")");
  return out;
}

bool SceneOpener::offerWithoutDamaged(const QString& what, const QString& message) {
  // Damaged files of a folder, every one inside it: offer the series without them.
  std::error_code ec;
  const fs::path folder = fs::path(what.toStdString());
  const std::vector<fs::path> damaged = damagedFilesNamed(message);
  if (damaged.empty() || !fs::is_directory(folder, ec)) return false;
  for (const fs::path& d : damaged) {
    const fs::path within = fs::relative(d, folder, ec);
    if (ec || within.empty() || *within.begin() == ".." || !fs::is_regular_file(d, ec)) return false;
  }
  QString names;
  for (std::size_t i = 0; i < damaged.size(); ++i) {
    names += (i == 0 ? "" : i + 1 == damaged.size() ? " and " : ", ") + QString::fromStdString(damaged[i].filename().string());
  }
  const bool one = damaged.size() == 1;
  auto* box = new QMessageBox(QMessageBox::Question, "VolumeHaptics",
                              QString("Cannot open %1: %2 %3 damaged").arg(QFileInfo(what).fileName(), names, one ? "is" : "are"),
                              QMessageBox::Open | QMessageBox::Cancel, window_);
  box->setObjectName("damagedFileBox");
  box->setInformativeText(message + "\n\nOpen the series without " + (one ? names : "these " + QString::number(damaged.size()) + " files") +
                          "? (The folder is left as it is; the other files are opened from a temporary folder.)");
  box->button(QMessageBox::Open)->setText(one ? "Open Without It" : "Open Without Them");
  box->setAttribute(Qt::WA_DeleteOnClose);
  connect(box, &QMessageBox::finished, this, [this, box, folder, damaged](int) {
    if (box->clickedButton() != box->button(QMessageBox::Open)) return;
    try {
      openPath(QString::fromStdString(folderWithout(folder, damaged).string()));
    } catch (const std::exception& e) {
      reportError(QString::fromStdString(folder.string()), QString::fromUtf8(e.what()));
    }
  });
  box->open();
  return true;
}

void SceneOpener::reportError(const QString& what, const QString& message) {
  last_error_ = message;
  status_.hideProgress();
  std::cerr << "volume-haptics: " << message.toStdString() << '\n';
  emit loadFailed(message);
  if (!interactive_) return;
  if (offerWithoutDamaged(what, message)) return;
  const QString name = QFileInfo(what).fileName().isEmpty() ? what : QFileInfo(what).fileName();
  auto* box = new QMessageBox(QMessageBox::Critical, "VolumeHaptics", QString("Cannot open %1").arg(name),
                              QMessageBox::Ok, window_);
  box->setObjectName("errorBox");
  box->setInformativeText(message + "\n\n" +
                          (session_.hasScene() ? "What was open before is kept."
                                               : "Open another file with the File menu, or drop it on the window."));
  box->setAttribute(Qt::WA_DeleteOnClose);
  box->open();  // window-modal, does not block the haptic display
}

void SceneOpener::addFileMenuActions(QMenu* file) {
  file->addAction("Open &DICOM Folder...", this, [this] { openFileDialog(kDicomFolder); })
      ->setShortcut(QKeySequence("Ctrl+D"));
  file->addAction("Open from &PACS...", this, &SceneOpener::openFromPacs)->setShortcut(QKeySequence("Ctrl+Shift+D"));
  file->addAction("&Open Volume File (NRRD, MetaImage)...", this, [this] { openFileDialog(kVolumeFile); })
      ->setShortcut(QKeySequence::Open);
  file->addAction("Open &Scene...", this, [this] { openFileDialog(kSceneFile); })
      ->setShortcut(QKeySequence("Ctrl+Shift+O"));
}

void SceneOpener::openFromPacs() {
  PacsBrowserDialog dialog(prefs_.pacs, [this](const io::PacsServer& server) { prefs_.pacs = server; }, window_);
  if (dialog.exec() != QDialog::Accepted || dialog.retrievedFolder().empty()) return;
  // Opened as any DICOM folder; the file dialogs keep starting where the user left them, not in the cache.
  const QString last_folder = prefs_.last_folder;
  openPath(q(dialog.retrievedFolder().string()));
  prefs_.last_folder = last_folder;
}

void SceneOpener::rebuildRecentMenu() {
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

void SceneOpener::openFileDialog(int kind) {
  QString path;
  if (kind == kDicomFolder) {
    path = QFileDialog::getExistingDirectory(window_, "Open a DICOM folder", prefs_.last_folder, QFileDialog::ShowDirsOnly);
  } else if (kind == kVolumeFile) {
    path = QFileDialog::getOpenFileName(window_, "Open a volume file", prefs_.last_folder, q(io::volumeFileDialogFilter()));
  } else {
    path = QFileDialog::getOpenFileName(window_, "Open a scene", prefs_.last_folder, "Scenes (*.json);;All files (*)");
  }
  if (!path.isEmpty()) openPath(path);
}

}  // namespace vh::ui
