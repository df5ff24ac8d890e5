#include "vh/ui/panels/pacs_dialog.h"

#include <algorithm>
#include <exception>
#include <mutex>
#include <thread>
#include <system_error>

#include <QCheckBox>
#include <QDialogButtonBox>
#include <QFileDialog>
#include <QFormLayout>
#include <QHBoxLayout>
#include <QHeaderView>
#include <QLabel>
#include <QLineEdit>
#include <QProgressDialog>
#include <QPushButton>
#include <QStandardPaths>
#include <QTimer>
#include <QTreeWidget>
#include <QTreeWidgetItemIterator>
#include <QVBoxLayout>

namespace vh::ui {
namespace {

namespace fs = std::filesystem;

constexpr int kProgressPollMs = 100;  // how often the progress dialog reads the retrieval's counters
constexpr int kSeriesAskedRole = Qt::UserRole + 5;  // a study item: its series were asked for

QString q(const std::string& s) { return QString::fromStdString(s); }

/// "20240131" -> "2024-01-31"; other text unchanged.
QString dicomDate(const std::string& d) {
  if (d.size() != 8) return q(d);
  return q(d.substr(0, 4) + "-" + d.substr(4, 2) + "-" + d.substr(6, 2));
}

/// A DICOM person name for people: "Family^Given" -> "Family, Given".
QString personName(const std::string& pn) {
  QString s = q(pn);
  const int caret = s.indexOf('^');
  if (caret >= 0) s = s.left(caret) + ", " + s.mid(caret + 1).replace('^', ' ');
  s = s.trimmed();
  if (s.endsWith(',')) s.chop(1);
  return s.isEmpty() ? QString("(no name)") : s;
}

}  // namespace

/// How a network thread hands its result to the dialog that started it: the thread puts a
/// closure here and wakes the dialog with a queued call; the dialog runs it on the GUI thread.
/// Once the dialog is gone (close()), nothing more is put or posted, and events already posted to
/// it die with it. The threads are plain std::threads, detached: they own what they use and may
/// outlive the dialog; the hand-over is this mutex, which ThreadSanitizer sees (as SceneLoader's).
class PacsMailbox : public std::enable_shared_from_this<PacsMailbox> {
 public:
  explicit PacsMailbox(QObject* receiver) : receiver_(receiver) {}

  /// From any thread: `done` is run on the receiver's thread, unless it is gone.
  void post(std::function<void()> done) {
    const std::lock_guard<std::mutex> lock(mutex_);
    if (receiver_ == nullptr) return;
    inbox_.push_back(std::move(done));
    QMetaObject::invokeMethod(
        receiver_, [mailbox = shared_from_this()] { mailbox->drain(); }, Qt::QueuedConnection);
  }
  /// The receiver is going: nothing more for it.
  void close() {
    const std::lock_guard<std::mutex> lock(mutex_);
    receiver_ = nullptr;
    inbox_.clear();
  }

 private:
  void drain() {
    std::vector<std::function<void()>> items;
    {
      const std::lock_guard<std::mutex> lock(mutex_);
      items.swap(inbox_);
    }
    for (auto& f : items) f();
  }

  std::mutex mutex_;
  QObject* receiver_;  // guarded by mutex_
  std::vector<std::function<void()>> inbox_;
};

namespace {

/// Runs `work` on a detached thread of its own, then `done` through `mailbox` on the GUI thread.
void runDetached(const std::shared_ptr<PacsMailbox>& mailbox, std::function<void()> work, std::function<void()> done) {
  std::thread([mailbox, work = std::move(work), done = std::move(done)]() mutable {
    work();
    mailbox->post(std::move(done));
  }).detach();
}

}  // namespace

fs::path pacsCacheFolder(const std::string& series_uid, const fs::path& cache_root) {
  fs::path root = cache_root;
  if (root.empty()) root = fs::path(QStandardPaths::writableLocation(QStandardPaths::CacheLocation).toStdString());
  std::string name = series_uid;
  for (char& c : name) {
    if (c != '.' && (c < '0' || c > '9')) c = '_';  // a UID is digits and dots; anything else is made harmless
  }
  if (name.empty() || name == "." || name == "..") name = "unnamed";
  return root / "pacs" / name;
}

std::vector<fs::path> prunePacsCache(const fs::path& pacs_folder, std::uintmax_t max_bytes, const fs::path& keep) {
  struct Entry {
    fs::path folder;
    fs::file_time_type time;
    std::uintmax_t bytes = 0;
  };
  std::vector<Entry> entries;
  std::uintmax_t total = 0;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(pacs_folder, ec)) {
    if (!e.is_directory(ec)) continue;
    Entry entry{e.path(), fs::last_write_time(e.path(), ec), 0};
    for (const auto& f : fs::recursive_directory_iterator(e.path(), ec)) {
      if (f.is_regular_file(ec)) entry.bytes += f.file_size(ec);
    }
    total += entry.bytes;
    entries.push_back(std::move(entry));
  }
  std::sort(entries.begin(), entries.end(), [](const Entry& a, const Entry& b) { return a.time < b.time; });
  std::vector<fs::path> removed;
  for (const Entry& e : entries) {
    if (total <= max_bytes) break;
    if (fs::equivalent(e.folder, keep, ec)) continue;
    if (fs::remove_all(e.folder, ec) != static_cast<std::uintmax_t>(-1) && !ec) {
      total -= e.bytes;
      removed.push_back(e.folder);
    }
  }
  return removed;
}

// ---- settings ----

PacsSettingsDialog::PacsSettingsDialog(const io::PacsServer& server, QWidget* parent)
    : QDialog(parent), base_(server), mailbox_(std::make_shared<PacsMailbox>(this)) {
  setWindowTitle("PACS Server");
  setObjectName("pacsSettingsDialog");
  auto* form = new QFormLayout;
  host_ = new QLineEdit(q(server.host));
  host_->setObjectName("pacsHost");
  port_ = new RangeIntSpinBox("the port");
  port_->setObjectName("pacsPort");
  port_->setRange(1, 65535);
  port_->setValue(server.port);
  called_ = new QLineEdit(q(server.called_aet));
  called_->setObjectName("pacsCalledAet");
  called_->setMaxLength(16);
  calling_ = new QLineEdit(q(server.calling_aet));
  calling_->setObjectName("pacsCallingAet");
  calling_->setMaxLength(16);
  form->addRow("Host:", host_);
  form->addRow("Port:", port_);
  form->addRow("Server's AE title (called):", called_);
  form->addRow("Our AE title (calling):", calling_);
  timeout_ = new RangeIntSpinBox("the timeout");
  timeout_->setObjectName("pacsTimeout");
  timeout_->setRange(1, 3600);
  timeout_->setSuffix(" s");
  timeout_->setValue(server.timeout_s);
  timeout_->setToolTip("The longest a test or a search may take in all, and a retrieval for each next file; "
                       "past it the connection is cut off.");
  form->addRow("Timeout:", timeout_);
  addTlsRows(*form, server);
  auto* hint = new QLabel("The server must know our AE title, with this computer's address, to answer queries and "
                          "retrievals (C-FIND, C-GET).");
  hint->setWordWrap(true);
  auto* test = new QPushButton("Test Connection");
  test->setObjectName("pacsTest");
  test_result_ = new QLabel;
  test_result_->setObjectName("pacsTestResult");
  test_result_->setWordWrap(true);
  auto* buttons = new QDialogButtonBox(QDialogButtonBox::Ok | QDialogButtonBox::Cancel);
  connect(buttons, &QDialogButtonBox::accepted, this, unlessRefused(*this, {port_, timeout_}, [this] { accept(); }));
  connect(buttons, &QDialogButtonBox::rejected, this, &QDialog::reject);
  connect(test, &QPushButton::clicked, this, [this, test] {
    if (testing_) return;
    testing_ = true;
    test->setEnabled(false);
    test_result_->setText("Testing...");
    auto error = std::make_shared<std::string>();
    const io::PacsServer s = this->server();
    runDetached(
        mailbox_,
        [s, error] {
          try {
            io::pacsEcho(s);
          } catch (const std::exception& e) {
            *error = e.what();
          }
        },
        [this, test, error, s] {
          testing_ = false;
          test->setEnabled(true);
          test_result_->setText(error->empty() ? q(s.describe() + " answers (C-ECHO).") : q(*error));
        });
  });
  auto* layout = new QVBoxLayout(this);
  layout->addLayout(form);
  layout->addWidget(hint);
  auto* test_row = new QHBoxLayout;
  test_row->addWidget(test);
  test_row->addWidget(test_result_, 1);
  layout->addLayout(test_row);
  layout->addWidget(buttons);
}

void PacsSettingsDialog::addTlsRows(QFormLayout& form, const io::PacsServer& server) {
  tls_ = new QCheckBox("DICOM TLS (the server's certificate checked against the CA)");
  tls_->setObjectName("pacsTls");
  tls_->setChecked(server.tls);
  form.addRow("Security:", tls_);
  const auto file_row = [&](QLineEdit*& edit, const std::string& value, const char* name, const QString& label,
                            const QString& filter) {
    edit = new QLineEdit(q(value));
    edit->setObjectName(name);
    auto* browse = new QPushButton("Browse...");
    connect(browse, &QPushButton::clicked, this, [this, edit, label, filter] {
      const QString file = QFileDialog::getOpenFileName(this, label, edit->text(), filter);
      if (!file.isEmpty()) edit->setText(file);
    });
    auto* row = new QHBoxLayout;
    row->addWidget(edit, 1);
    row->addWidget(browse);
    form.addRow(label + ":", row);
    const auto enable = [edit, browse](bool on) {
      edit->setEnabled(on);
      browse->setEnabled(on);
    };
    enable(server.tls);
    connect(tls_, &QCheckBox::toggled, this, enable);
  };
  const QString pem = "PEM files (*.pem *.crt *.cer *.key);;All files (*)";
  file_row(ca_cert_, server.ca_cert, "pacsCaCert", "CA certificate", pem);
  file_row(client_cert_, server.client_cert, "pacsClientCert", "Our certificate (optional)", pem);
  file_row(client_key_, server.client_key, "pacsClientKey", "Our private key (optional)", pem);
}

PacsSettingsDialog::~PacsSettingsDialog() { mailbox_->close(); }

io::PacsServer PacsSettingsDialog::server() const {
  io::PacsServer s = base_;
  s.host = host_->text().trimmed().toStdString();
  s.port = port_->value();
  s.called_aet = called_->text().trimmed().toStdString();
  s.calling_aet = calling_->text().trimmed().toStdString();
  s.timeout_s = timeout_->value();
  s.tls = tls_->isChecked();
  s.ca_cert = ca_cert_->text().trimmed().toStdString();
  s.client_cert = client_cert_->text().trimmed().toStdString();
  s.client_key = client_key_->text().trimmed().toStdString();
  return s;
}

// ---- the tree ----

void fillPacsTree(QTreeWidget& tree, const std::vector<io::PacsPatient>& patients) {
  tree.clear();
  for (const io::PacsPatient& p : patients) {
    auto* pi = new QTreeWidgetItem(&tree);
    pi->setText(0, personName(p.name) + (p.id.empty() ? QString() : "  (" + q(p.id) + ")"));
    pi->setText(1, dicomDate(p.birth_date));
    pi->setToolTip(1, "Birth date");
    pi->setData(0, kPacsKindRole, kPacsPatient);
    pi->setData(0, kPacsUidRole, q(p.id));
    for (const io::PacsStudy& s : p.studies) {
      auto* si = new QTreeWidgetItem(pi);
      si->setText(0, s.description.empty() ? QString("(study without description)") : q(s.description));
      si->setText(1, dicomDate(s.study_date));
      si->setText(2, q(s.modalities).replace('\\', ", "));
      if (s.series_count >= 0) si->setText(3, QString("%1 series").arg(s.series_count));
      si->setText(4, q(s.study_uid));
      si->setData(0, kPacsKindRole, kPacsStudy);
      si->setData(0, kPacsUidRole, q(s.study_uid));
      auto* placeholder = new QTreeWidgetItem(si);  // makes the study expandable; replaced by its series
      placeholder->setText(0, "Listing the series...");
      placeholder->setFlags(Qt::ItemIsEnabled);
    }
    pi->setExpanded(true);
  }
}

void fillPacsSeries(QTreeWidgetItem& study_item, const std::vector<io::PacsSeries>& series) {
  qDeleteAll(study_item.takeChildren());
  for (const io::PacsSeries& s : series) {
    auto* item = new QTreeWidgetItem(&study_item);
    QString name = s.number >= 0 ? QString("#%1 ").arg(s.number) : QString();
    name += s.description.empty() ? QString("(series without description)") : q(s.description);
    item->setText(0, name);
    item->setText(2, q(s.modality));
    item->setText(3, s.instance_count >= 0 ? QString::number(s.instance_count) : QString("?"));
    item->setToolTip(3, "Files (instances) in the series");
    item->setText(4, q(s.series_uid));
    item->setData(0, kPacsKindRole, kPacsSeries);
    item->setData(0, kPacsUidRole, q(s.series_uid));
    item->setData(0, kPacsStudyUidRole, q(s.study_uid));
    item->setData(0, kPacsInstancesRole, s.instance_count);
  }
  if (series.empty()) {
    auto* none = new QTreeWidgetItem(&study_item);
    none->setText(0, "(no series)");
    none->setFlags(Qt::ItemIsEnabled);
  }
}

// ---- the browser ----

PacsBrowserDialog::PacsBrowserDialog(const io::PacsServer& server,
                                     std::function<void(const io::PacsServer&)> settings_changed, QWidget* parent,
                                     fs::path cache_root)
    : QDialog(parent),
      server_(server),
      settings_changed_(std::move(settings_changed)),
      cache_root_(std::move(cache_root)),
      mailbox_(std::make_shared<PacsMailbox>(this)) {
  setWindowTitle("Open from PACS");
  setObjectName("pacsBrowserDialog");
  resize(820, 520);
  server_label_ = new QLabel;
  server_label_->setObjectName("pacsServerLabel");
  auto* server_button = new QPushButton("Server...");
  server_button->setObjectName("pacsServerButton");
  connect(server_button, &QPushButton::clicked, this, &PacsBrowserDialog::editServer);
  filter_ = new QLineEdit;
  filter_->setObjectName("pacsPatientFilter");
  filter_->setPlaceholderText("Patient's name (empty: all; * and ? as wildcards)");
  search_button_ = new QPushButton("Search");
  search_button_->setObjectName("pacsSearch");
  search_button_->setDefault(true);  // Enter in the filter field searches
  connect(search_button_, &QPushButton::clicked, this, &PacsBrowserDialog::search);
  tree_ = new QTreeWidget;
  tree_->setObjectName("pacsTree");
  tree_->setHeaderLabels({"Patient / study / series", "Date", "Modality", "Files", "UID"});
  tree_->setSelectionMode(QAbstractItemView::SingleSelection);
  tree_->header()->setSectionResizeMode(0, QHeaderView::Stretch);
  connect(tree_, &QTreeWidget::itemExpanded, this, [this](QTreeWidgetItem* item) {
    if (item->data(0, kPacsKindRole).toInt() == kPacsStudy) listSeries(item);
  });
  connect(tree_, &QTreeWidget::itemSelectionChanged, this, [this] {
    const auto selected = tree_->selectedItems();
    if (!selected.isEmpty() && selected.front()->data(0, kPacsKindRole).toInt() == kPacsStudy) {
      listSeries(selected.front());
    }
    updateButtons();
  });
  connect(tree_, &QTreeWidget::itemDoubleClicked, this, [this](QTreeWidgetItem* item) {
    if (item->data(0, kPacsKindRole).toInt() == kPacsSeries) retrieveSelected();
  });
  status_ = new QLabel;
  status_->setObjectName("pacsStatus");
  status_->setWordWrap(true);
  status_->setTextInteractionFlags(Qt::TextSelectableByMouse);
  open_button_ = new QPushButton("Retrieve and Open");
  open_button_->setObjectName("pacsOpen");
  connect(open_button_, &QPushButton::clicked, this, &PacsBrowserDialog::retrieveSelected);
  auto* close = new QPushButton("Close");
  connect(close, &QPushButton::clicked, this, &QDialog::reject);

  auto* top = new QHBoxLayout;
  top->addWidget(server_label_, 1);
  top->addWidget(server_button);
  auto* find_row = new QHBoxLayout;
  find_row->addWidget(filter_, 1);
  find_row->addWidget(search_button_);
  auto* bottom = new QHBoxLayout;
  bottom->addWidget(status_, 1);
  bottom->addWidget(open_button_);
  bottom->addWidget(close);
  auto* layout = new QVBoxLayout(this);
  layout->addLayout(top);
  layout->addLayout(find_row);
  layout->addWidget(tree_, 1);
  layout->addLayout(bottom);
  server_label_->setText("Server: " + q(server_.describe()) + ", we are " + q(server_.calling_aet));
  setStatus("Search lists the server's patients and studies; expand a study for its series.");
  updateButtons();
}

PacsBrowserDialog::~PacsBrowserDialog() {
  mailbox_->close();
  if (retrieval_) retrieval_->cancel = true;  // its thread stops and deletes what it received
}

void PacsBrowserDialog::runInBackground(std::function<void()> work, std::function<void()> done) {
  ++running_;
  runDetached(mailbox_, std::move(work), [this, done = std::move(done)] {
    --running_;
    done();
    updateButtons();
  });
  updateButtons();
}

void PacsBrowserDialog::setStatus(const QString& text, bool error) {
  status_->setText(text);
  status_->setStyleSheet(error ? "color: #c0392b;" : "");
}

QString PacsBrowserDialog::statusText() const { return status_->text(); }

void PacsBrowserDialog::updateButtons() {
  const auto selected = tree_->selectedItems();
  const bool series = !selected.isEmpty() && selected.front()->data(0, kPacsKindRole).toInt() == kPacsSeries;
  open_button_->setEnabled(series && progress_ == nullptr);
  search_button_->setEnabled(progress_ == nullptr);
}

void PacsBrowserDialog::editServer() {
  PacsSettingsDialog dialog(server_, this);
  if (dialog.exec() != QDialog::Accepted) return;
  server_ = dialog.server();
  if (settings_changed_) settings_changed_(server_);
  server_label_->setText("Server: " + q(server_.describe()) + ", we are " + q(server_.calling_aet));
  tree_->clear();
  setStatus("Server changed: Search again.");
}

void PacsBrowserDialog::search() {
  io::PacsStudyQuery query;
  query.patient_name = filter_->text().trimmed().toStdString();
  // A plain name matches its beginning, as people expect of a search field.
  if (!query.patient_name.empty() && query.patient_name.find_first_of("*?") == std::string::npos) {
    query.patient_name += '*';
  }
  const io::PacsServer server = server_;
  auto patients = std::make_shared<std::vector<io::PacsPatient>>();
  auto studies = std::make_shared<std::size_t>(0);
  auto error = std::make_shared<std::string>();
  setStatus("Searching " + q(server.describe()) + "...");
  runInBackground(
      [server, query, patients, studies, error] {
        try {
          const std::vector<io::PacsStudy> found = io::pacsFindStudies(server, query);
          *studies = found.size();
          *patients = io::pacsPatientsOf(found);
        } catch (const std::exception& e) {
          *error = e.what();
        }
      },
      [this, patients, studies, error] {
        if (!error->empty()) {
          setStatus(q(*error), true);
          return;
        }
        fillPacsTree(*tree_, *patients);
        setStatus(QString("%1 patients, %2 studies. Expand a study for its series; choose one to open.")
                      .arg(patients->size())
                      .arg(*studies));
      });
}

void PacsBrowserDialog::listSeries(QTreeWidgetItem* study_item) {
  if (study_item == nullptr || study_item->data(0, kPacsKindRole).toInt() != kPacsStudy) return;
  if (study_item->data(0, kSeriesAskedRole).toBool()) return;
  study_item->setData(0, kSeriesAskedRole, true);
  const std::string study_uid = study_item->data(0, kPacsUidRole).toString().toStdString();
  const io::PacsServer server = server_;
  auto series = std::make_shared<std::vector<io::PacsSeries>>();
  auto error = std::make_shared<std::string>();
  runInBackground(
      [server, study_uid, series, error] {
        try {
          *series = io::pacsFindSeries(server, study_uid);
        } catch (const std::exception& e) {
          *error = e.what();
        }
      },
      [this, study_uid, series, error] {
        // The tree may have been refilled meanwhile: find the study again by its UID.
        QTreeWidgetItem* item = nullptr;
        for (QTreeWidgetItemIterator it(tree_); *it != nullptr && item == nullptr; ++it) {
          if ((*it)->data(0, kPacsKindRole).toInt() == kPacsStudy &&
              (*it)->data(0, kPacsUidRole).toString().toStdString() == study_uid) {
            item = *it;
          }
        }
        if (!error->empty()) {
          if (item != nullptr) item->setData(0, kSeriesAskedRole, false);  // may be asked again
          setStatus(q(*error), true);
          return;
        }
        if (item != nullptr) fillPacsSeries(*item, *series);
      });
}

namespace {

/// The modal progress dialog of a retrieval from `server` of `expected` files (-1: unknown).
QProgressDialog* makeRetrievalProgress(const QString& server, int expected, QWidget* parent) {
  auto* progress = new QProgressDialog("Retrieving the series from " + server + "...", "Cancel", 0,
                                       std::max(expected, 0), parent);
  progress->setObjectName("pacsProgress");
  progress->setWindowTitle("Open from PACS");
  progress->setWindowModality(Qt::WindowModal);
  progress->setAutoClose(false);
  progress->setAutoReset(false);
  progress->setMinimumDuration(0);
  progress->setValue(0);
  return progress;
}

/// A retrieval's work, off the GUI thread: the series into `folder` of the cache (an earlier,
/// perhaps partial, copy replaced), counting into `received` / `total`, then the cache pruned.
/// An exception's text goes to `error`.
void retrieveIntoCache(const io::PacsServer& server, const std::string& study_uid, const std::string& series_uid,
                       const fs::path& folder, int expected, std::atomic<bool>& cancel, std::atomic<int>& received,
                       std::atomic<int>& total, io::PacsRetrieveResult& result, std::string& error) {
  try {
    std::error_code ec;
    fs::remove_all(folder, ec);
    io::PacsRetrieveOptions options;
    options.expected_instances = expected;
    options.cancel = &cancel;
    options.progress = [&](const io::PacsRetrieveProgress& p) {
      received = p.received;
      if (p.total > 0) total = p.total;
    };
    result = io::pacsRetrieveSeries(server, study_uid, series_uid, folder, options);
    if (!result.cancelled) prunePacsCache(folder.parent_path(), kPacsCacheMaxBytes, folder);
  } catch (const std::exception& e) {
    error = e.what();
  }
}

}  // namespace

void PacsBrowserDialog::retrieveSelected() {
  const auto selected = tree_->selectedItems();
  if (selected.isEmpty() || progress_ != nullptr) return;
  const QTreeWidgetItem* item = selected.front();
  if (item->data(0, kPacsKindRole).toInt() != kPacsSeries) return;
  const std::string series_uid = item->data(0, kPacsUidRole).toString().toStdString();
  const std::string study_uid = item->data(0, kPacsStudyUidRole).toString().toStdString();
  const int expected = item->data(0, kPacsInstancesRole).toInt();
  const fs::path folder = pacsCacheFolder(series_uid, cache_root_);
  const io::PacsServer server = server_;

  auto state = std::make_shared<Retrieval>();
  state->total = expected;
  retrieval_ = state;
  progress_ = makeRetrievalProgress(q(server.describe()), expected, this);
  connect(progress_, &QProgressDialog::canceled, this, [this, state] {
    state->cancel = true;
    if (progress_ != nullptr) progress_->setLabelText("Cancelling...");
  });
  progress_timer_ = new QTimer(this);
  connect(progress_timer_, &QTimer::timeout, this, [this, state] {
    if (progress_ != nullptr && progress_->wasCanceled()) state->cancel = true;  // by Esc or cancel()
    if (progress_ == nullptr || state->cancel) return;
    const int total = state->total;
    const int received = state->received;
    progress_->setLabelText(total > 0 ? QString("Retrieved %1 of %2 files").arg(received).arg(total)
                                      : QString("Retrieved %1 files").arg(received));
    if (total > 0 && progress_->maximum() != total) progress_->setMaximum(total);
    // Last: a modal progress dialog's setValue() processes events, among them perhaps the end of
    // the retrieval, which deletes the progress dialog.
    progress_->setValue(received);
  });
  progress_timer_->start(kProgressPollMs);
  setStatus("Retrieving into " + q(folder.string()) + "...");
  updateButtons();

  auto result = std::make_shared<io::PacsRetrieveResult>();
  auto error = std::make_shared<std::string>();
  runInBackground(
      [state, server, study_uid, series_uid, folder, expected, result, error] {
        // `state` lives as long as this thread.
        retrieveIntoCache(server, study_uid, series_uid, folder, expected, state->cancel, state->received,
                          state->total, *result, *error);
      },
      [this, result, error] {
        retrieval_.reset();
        progress_timer_->stop();
        progress_timer_->deleteLater();
        progress_timer_ = nullptr;
        progress_->close();
        progress_->deleteLater();
        progress_ = nullptr;
        if (!error->empty()) {
          setStatus(q(*error), true);
          emit retrievalFinished(0, false, q(*error));
          return;
        }
        if (result->cancelled) {
          setStatus("Retrieval cancelled; nothing was kept.");
          emit retrievalFinished(0, true, {});
          return;
        }
        retrieved_ = result->folder;
        setStatus(QString("Retrieved %1 files in %2 s.").arg(result->files.size()).arg(result->seconds, 0, 'f', 1));
        emit retrievalFinished(static_cast<int>(result->files.size()), false, {});
        accept();
      });
}

}  // namespace vh::ui
