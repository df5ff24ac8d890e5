#pragma once
/// @file
/// File > Open from PACS: the PACS section of the preferences (PacsSettingsDialog: host, port,
/// the server's and our AE titles, with a connection test) and the browser (PacsBrowserDialog:
/// patients > studies > series from C-FIND, one series retrieved by C-GET into the cache with a
/// progress dialog and Cancel). Every network call runs on a thread of its own, never on the GUI
/// thread; the dialogs only show what comes back, and closing one never waits for the network (a
/// call still running ends on its own, within the server settings' timeout; a retrieval is cancelled). The retrieved folder is then opened as any
/// DICOM folder (SceneOpener::openPath()).

#include <atomic>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <functional>
#include <vector>

#include <QDialog>
#include <QString>

#include "vh/io/pacs.h"
#include "vh/ui/panels/range_spin_box.h"

class QCheckBox;
class QFormLayout;
class QLabel;
class QLineEdit;
class QProgressDialog;
class QPushButton;
class QTimer;
class QTreeWidget;
class QTreeWidgetItem;

namespace vh::ui {

class PacsMailbox;  // how the network threads hand their results back (pacs_dialog.cpp)

/// The PACS settings: host, port, called AE title (the server's), calling AE title (ours), the
/// timeout, DICOM TLS with its CA certificate (and ours with its key, for a server that asks for
/// one), and a Test button (C-ECHO, off the GUI thread) that says whether the server answers.
class PacsSettingsDialog : public QDialog {
  Q_OBJECT

 public:
  PacsSettingsDialog(const io::PacsServer& server, QWidget* parent = nullptr);
  /// A connection test still running ends on its own thread; its answer is dropped.
  ~PacsSettingsDialog() override;
  /// The settings as edited.
  io::PacsServer server() const;

 private:
  /// The rows of DICOM TLS: the switch and the three files, each with a Browse button.
  void addTlsRows(QFormLayout& form, const io::PacsServer& server);

  QLineEdit* host_;
  RangeIntSpinBox* port_;
  QLineEdit* called_;
  QLineEdit* calling_;
  RangeIntSpinBox* timeout_;
  QCheckBox* tls_;
  QLineEdit* ca_cert_;
  QLineEdit* client_cert_;
  QLineEdit* client_key_;
  QLabel* test_result_;
  bool testing_ = false;
  io::PacsServer base_;
  std::shared_ptr<PacsMailbox> mailbox_;
};

/// The cache folder of a retrieved series: CACHE/pacs/SERIES_UID (CACHE: the user's cache,
/// QStandardPaths::CacheLocation, unless `cache_root` is given).
std::filesystem::path pacsCacheFolder(const std::string& series_uid, const std::filesystem::path& cache_root = {});

/// The most the PACS cache keeps [bytes]: after each retrieval the oldest series go beyond it.
constexpr std::uintmax_t kPacsCacheMaxBytes = std::uintmax_t{4} << 30;  // 4 GiB

/// Removes the oldest series folders (by last write time) of `pacs_folder` (CACHE/pacs) until
/// the files left take at most `max_bytes`; `keep` (the series just retrieved) always stays.
/// Files that cannot be removed are left (no error). @return the folders removed, oldest first.
std::vector<std::filesystem::path> prunePacsCache(const std::filesystem::path& pacs_folder, std::uintmax_t max_bytes,
                                                  const std::filesystem::path& keep);

/// Tree item roles and kinds of PacsBrowserDialog's tree.
enum PacsItemKind { kPacsPatient = 1, kPacsStudy = 2, kPacsSeries = 3 };
constexpr int kPacsKindRole = 0x0100 + 1;       ///< Qt::UserRole + 1: a PacsItemKind.
constexpr int kPacsUidRole = 0x0100 + 2;        ///< The study's or series' UID.
constexpr int kPacsStudyUidRole = 0x0100 + 3;   ///< A series' study UID.
constexpr int kPacsInstancesRole = 0x0100 + 4;  ///< A series' instance count (-1: unknown).

/// Fills `tree` with one item per patient, its studies below (columns: name / description,
/// date, modality, files, UID). Studies get a placeholder child until their series are listed.
void fillPacsTree(QTreeWidget& tree, const std::vector<io::PacsPatient>& patients);
/// Puts `series` under `study_item` (replacing what was there).
void fillPacsSeries(QTreeWidgetItem& study_item, const std::vector<io::PacsSeries>& series);

/// Browses the server of `server` and retrieves one series. Accepted once a series has been
/// retrieved: retrievedFolder() names its folder.
class PacsBrowserDialog : public QDialog {
  Q_OBJECT

 public:
  /// `settings_changed` is called with new settings edited through the Server button (the
  /// caller stores them). `cache_root` empty: the user's cache.
  PacsBrowserDialog(const io::PacsServer& server, std::function<void(const io::PacsServer&)> settings_changed,
                    QWidget* parent = nullptr, std::filesystem::path cache_root = {});
  /// Cancels a running retrieval (its files are deleted); network calls still running end on
  /// their own threads without it.
  ~PacsBrowserDialog() override;

  /// Lists the studies whose patient name matches the filter field (asynchronous).
  void search();
  /// Lists the series of `study_item` (asynchronous; done once per study).
  void listSeries(QTreeWidgetItem* study_item);
  /// Retrieves the selected series into the cache (asynchronous, with the progress dialog).
  void retrieveSelected();

  QTreeWidget* tree() const { return tree_; }
  QLineEdit* patientFilter() const { return filter_; }
  /// What the dialog says now: the last result or error.
  QString statusText() const;
  /// True while a network call runs.
  bool busy() const { return running_ > 0; }
  /// The folder of the retrieved series (valid once accepted).
  const std::filesystem::path& retrievedFolder() const { return retrieved_; }
  /// Asks a running retrieval to stop (as the progress dialog's Cancel does).
  void cancelRetrieval() {
    if (retrieval_) retrieval_->cancel = true;
  }

 signals:
  /// A retrieval ended: `files` received, `cancelled` or with `error` (empty when none).
  void retrievalFinished(int files, bool cancelled, const QString& error);

 private:
  /// What a retrieval's thread and the dialog share; the thread keeps it alive after the dialog.
  struct Retrieval {
    std::atomic<bool> cancel{false};
    std::atomic<int> received{0};  ///< Files so far.
    std::atomic<int> total{-1};    ///< Files expected; -1: unknown.
  };

  /// Runs `work` on a thread of its own, then `done` on the GUI thread unless the dialog is gone.
  /// `work` must not use the dialog: it may outlive it.
  void runInBackground(std::function<void()> work, std::function<void()> done);
  void setStatus(const QString& text, bool error = false);
  void updateButtons();
  void editServer();

  io::PacsServer server_;
  std::function<void(const io::PacsServer&)> settings_changed_;
  std::filesystem::path cache_root_;
  QLabel* server_label_;
  QLineEdit* filter_;
  QPushButton* search_button_;
  QTreeWidget* tree_;
  QLabel* status_;
  QPushButton* open_button_;
  QProgressDialog* progress_ = nullptr;
  QTimer* progress_timer_ = nullptr;
  int running_ = 0;                     // network calls under way
  std::shared_ptr<Retrieval> retrieval_;  // the running retrieval, if any
  std::shared_ptr<PacsMailbox> mailbox_;  // the network threads' answers
  std::filesystem::path retrieved_;
};

}  // namespace vh::ui
