// File > Open from PACS (ui/panels/pacs_dialog.h): the tree filled from a C-FIND result, and
// the dialog against a real PACS, Orthanc, started by the ctest fixture of the io tests
// (tests/app/io/pacs_orthanc_fixture.sh) with the shared small CT head in it: search, expand,
// retrieve into the cache, cancel, a closed port. The oracle is the dataset folder itself.

#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <string>

#include <QAction>
#include <QApplication>
#include <QCheckBox>
#include <QLabel>
#include <QLineEdit>
#include <QSignalSpy>
#include <QTimer>
#include <QProgressDialog>
#include <QPushButton>
#include <QSpinBox>
#include <QTemporaryDir>
#include <QTreeWidget>
#include <QTreeWidgetItemIterator>

#include <gtest/gtest.h>

#include "hostile_pacs.h"
#include "ui_test_util.h"
#include "vh/io/volume_loader.h"
#include "vh/ui/main_window.h"
#include "vh/ui/panels/pacs_dialog.h"
#include "vh/ui/replay/session_recorder.h"
#include "vh/ui/scene_opener.h"
#include "vh/runtime/recording.h"
#include "vh/runtime/session.h"

namespace vh::ui {
namespace {

namespace fs = std::filesystem;
using io::test::closedPort;

std::map<std::string, std::string> fixtureValues() {
  std::map<std::string, std::string> v;
  std::ifstream in(VH_PACS_FIXTURE_ENV);
  std::string line;
  while (std::getline(in, line)) {
    const auto eq = line.find('=');
    if (eq != std::string::npos) v[line.substr(0, eq)] = line.substr(eq + 1);
  }
  return v;
}

io::PacsServer fixtureServer(const std::map<std::string, std::string>& v) {
  io::PacsServer s;
  s.host = v.at("host");
  s.port = std::stoi(v.at("dicom_port"));
  s.called_aet = v.at("aet");
  s.calling_aet = v.at("client_aet");
  s.timeout_s = 20;
  return s;
}

#define VH_REQUIRE_ORTHANC(values)                                                                              \
  const auto values = fixtureValues();                                                                          \
  if (!values.count("status") || values.at("status") != "ready") {                                              \
    GTEST_SKIP() << "no test PACS: " << (values.count("reason") ? values.at("reason") : "fixture not started"); \
  }

std::size_t dicomFilesIn(const fs::path& folder) {
  std::size_t n = 0;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(folder, ec)) n += e.path().extension() == ".dcm" ? 1 : 0;
  return n;
}

/// The dialog's first series item once its study is expanded (null on timeout).
QTreeWidgetItem* firstSeries(PacsBrowserDialog& dialog) {
  QTreeWidgetItem* series = nullptr;
  test::waitFor(
      [&] {
        for (QTreeWidgetItemIterator it(dialog.tree()); *it != nullptr; ++it) {
          if ((*it)->data(0, kPacsKindRole).toInt() == kPacsSeries) series = *it;
        }
        return series != nullptr;
      },
      20000);
  return series;
}

TEST(PacsTree, FilledFromAFindResult) {
  io::PacsStudy a{"DOE^JANE", "P1", "19700101", "F", "1.2.3.1", "20240131", "", "Head", "A1", "CT\\PT", 2};
  io::PacsStudy b = a;
  b.study_uid = "1.2.3.2";
  b.description = "";
  io::PacsStudy c{"ROE^RICHARD", "P2", "", "M", "1.2.3.3", "20230101", "", "Knee", "", "MR", 1};
  QTreeWidget tree;
  fillPacsTree(tree, io::pacsPatientsOf({a, c, b}));
  ASSERT_EQ(tree.topLevelItemCount(), 2);  // two patients: P1 with two studies, P2 with one
  QTreeWidgetItem* jane = tree.topLevelItem(0);
  EXPECT_EQ(jane->text(0), "DOE, JANE  (P1)");
  ASSERT_EQ(jane->childCount(), 2);
  EXPECT_EQ(jane->child(0)->text(0), "Head");
  EXPECT_EQ(jane->child(0)->text(1), "2024-01-31");
  EXPECT_EQ(jane->child(0)->text(2), "CT, PT");
  EXPECT_EQ(jane->child(0)->data(0, kPacsUidRole).toString(), "1.2.3.1");
  EXPECT_EQ(jane->child(1)->text(0), "(study without description)");
  EXPECT_EQ(tree.topLevelItem(1)->childCount(), 1);

  io::PacsSeries s1{"1.2.3.1", "1.2.3.1.7", "CT", "Bone", 7, 93};
  io::PacsSeries s2{"1.2.3.1", "1.2.3.1.8", "PT", "", -1, -1};
  fillPacsSeries(*jane->child(0), {s1, s2});
  ASSERT_EQ(jane->child(0)->childCount(), 2);
  EXPECT_EQ(jane->child(0)->child(0)->text(0), "#7 Bone");
  EXPECT_EQ(jane->child(0)->child(0)->text(3), "93");
  EXPECT_EQ(jane->child(0)->child(0)->data(0, kPacsInstancesRole).toInt(), 93);
  EXPECT_EQ(jane->child(0)->child(1)->text(3), "?");
  EXPECT_EQ(jane->child(0)->child(1)->data(0, kPacsStudyUidRole).toString(), "1.2.3.1");
}

TEST(PacsTree, CacheFolderIsPerSeriesAndHarmless) {
  EXPECT_EQ(pacsCacheFolder("1.2.840.5", "/tmp/c"), fs::path("/tmp/c/pacs/1.2.840.5"));
  EXPECT_EQ(pacsCacheFolder("../../etc", "/tmp/c"), fs::path("/tmp/c/pacs/.._..____"));
  EXPECT_EQ(pacsCacheFolder("..", "/tmp/c"), fs::path("/tmp/c/pacs/unnamed"));
}

TEST(PacsTree, TheCacheDropsItsOldestSeriesBeyondItsSize) {
  QTemporaryDir dir;
  const fs::path pacs = fs::path(dir.path().toStdString()) / "pacs";
  const auto now = fs::file_time_type::clock::now();
  // Four series of 1000 bytes each, written 4, 3, 2 and 1 hours ago; "b" is the one just retrieved.
  const char* names[] = {"a", "b", "c", "d"};
  for (int i = 0; i < 4; ++i) {
    fs::create_directories(pacs / names[i]);
    std::ofstream(pacs / names[i] / "1.dcm") << std::string(1000, 'x');
    fs::last_write_time(pacs / names[i], now - std::chrono::hours(4 - i));
  }
  const std::vector<fs::path> removed = prunePacsCache(pacs, 2500, pacs / "b");
  // 4000 bytes > 2500: "a" goes (oldest), "b" is kept though older than "c", then "c" goes.
  ASSERT_EQ(removed.size(), 2u);
  EXPECT_EQ(removed[0].filename(), "a");
  EXPECT_EQ(removed[1].filename(), "c");
  EXPECT_TRUE(fs::exists(pacs / "b" / "1.dcm"));
  EXPECT_TRUE(fs::exists(pacs / "d" / "1.dcm"));
  EXPECT_FALSE(fs::exists(pacs / "a"));
  EXPECT_TRUE(prunePacsCache(pacs, 2500, pacs / "b").empty()) << "within its size: nothing goes";
}

TEST(PacsDialog, SearchExpandAndRetrieveIntoTheCache) {
  VH_REQUIRE_ORTHANC(values);
  QTemporaryDir cache;
  PacsBrowserDialog dialog(fixtureServer(values), {}, nullptr, fs::path(cache.path().toStdString()));
  dialog.show();
  dialog.patientFilter()->setText("Aus");  // the CT head's patient is "Austrialian"; a prefix matches
  dialog.search();
  ASSERT_TRUE(test::waitFor([&] { return dialog.tree()->topLevelItemCount() > 0; }, 20000)) << dialog.statusText().toStdString();
  ASSERT_EQ(dialog.tree()->topLevelItemCount(), 1);
  QTreeWidgetItem* study = dialog.tree()->topLevelItem(0)->child(0);
  ASSERT_NE(study, nullptr);
  study->setExpanded(true);  // lists its series
  QTreeWidgetItem* series = firstSeries(dialog);
  ASSERT_NE(series, nullptr) << dialog.statusText().toStdString();
  const int instances = std::stoi(values.at("instances"));
  EXPECT_EQ(series->text(2), "CT");
  EXPECT_EQ(series->text(3).toInt(), instances);

  dialog.tree()->setCurrentItem(series);
  series->setSelected(true);
  int files = -1;
  QObject::connect(&dialog, &PacsBrowserDialog::retrievalFinished, [&](int n, bool, const QString&) { files = n; });
  dialog.retrieveSelected();
  ASSERT_TRUE(test::waitFor([&] { return files >= 0; }, 60000)) << dialog.statusText().toStdString();
  EXPECT_EQ(files, instances) << dialog.statusText().toStdString();
  EXPECT_EQ(dialog.result(), QDialog::Accepted);
  const fs::path folder = dialog.retrievedFolder();
  EXPECT_EQ(folder, pacsCacheFolder(series->text(4).toStdString(), fs::path(cache.path().toStdString())));
  EXPECT_EQ(dicomFilesIn(folder), static_cast<std::size_t>(instances));
  // What SceneOpener then opens: the folder loads as the original does.
  const io::LoadedVolume retrieved = io::loadVolume(folder);
  const io::LoadedVolume original = io::loadVolume(values.at("dataset"));
  EXPECT_EQ(retrieved.field->geometry().dims, original.field->geometry().dims);
}

TEST(PacsDialog, CancelInTheProgressDialogKeepsNothing) {
  VH_REQUIRE_ORTHANC(values);
  QTemporaryDir cache;
  PacsBrowserDialog dialog(fixtureServer(values), {}, nullptr, fs::path(cache.path().toStdString()));
  dialog.show();
  dialog.search();
  ASSERT_TRUE(test::waitFor([&] { return dialog.tree()->topLevelItemCount() > 0; }, 20000));
  dialog.tree()->topLevelItem(0)->child(0)->setExpanded(true);
  QTreeWidgetItem* series = firstSeries(dialog);
  ASSERT_NE(series, nullptr);
  series->setSelected(true);
  bool cancelled = false, finished = false;
  QObject::connect(&dialog, &PacsBrowserDialog::retrievalFinished, [&](int, bool c, const QString&) {
    finished = true;
    cancelled = c;
  });
  const fs::path folder = pacsCacheFolder(series->text(4).toStdString(), fs::path(cache.path().toStdString()));
  dialog.retrieveSelected();
  QProgressDialog* progress = nullptr;
  // Cancelled once two files are in: seen in the cache folder itself, as soon as they are written,
  // rather than through the progress dialog's 100 ms poll, so that the retrieval (a second or so
  // for the small CT head) has as much of its way still to go as can be.
  ASSERT_TRUE(test::waitFor(
      [&] {
        progress = dialog.findChild<QProgressDialog*>("pacsProgress");
        return progress != nullptr && (progress->value() >= 2 || dicomFilesIn(folder) >= 2);
      },
      30000));
  QPushButton* cancel_button = progress->findChild<QPushButton*>();
  ASSERT_NE(cancel_button, nullptr);
  EXPECT_EQ(cancel_button->text(), "Cancel");
  const int received_at_cancel = progress->value();
  const std::size_t files_at_cancel = dicomFilesIn(folder);
  cancel_button->click();
  ASSERT_TRUE(test::waitFor([&] { return finished; }, 30000));
  EXPECT_TRUE(cancelled) << dialog.statusText().toStdString();
  std::printf("[ CANCEL   ] the dialog showed %d of %s files (%zu in the cache folder) when Cancel was clicked\n",
              received_at_cancel, values.at("instances").c_str(), files_at_cancel);
  EXPECT_NE(dialog.result(), QDialog::Accepted);
  EXPECT_TRUE(dialog.statusText().contains("cancelled")) << dialog.statusText().toStdString();
  EXPECT_EQ(dicomFilesIn(folder), 0u);
}

TEST(PacsDialog, AClosedPortIsSaidInTheDialog) {
  VH_REQUIRE_ORTHANC(values);
  io::PacsServer server = fixtureServer(values);
  server.port = closedPort();
  PacsBrowserDialog dialog(server, {}, nullptr);
  dialog.show();
  dialog.search();
  ASSERT_TRUE(test::waitFor([&] { return !dialog.busy(); }, 20000));
  EXPECT_TRUE(dialog.statusText().contains("no connection")) << dialog.statusText().toStdString();
  EXPECT_TRUE(dialog.statusText().contains(QString::fromStdString(server.describe())));
  EXPECT_EQ(dialog.tree()->topLevelItemCount(), 0);
}

TEST(PacsDialog, ClosingNeverWaitsForTheNetwork) {
  // A server that accepts the connection and never answers: the search would wait its 30 s out.
  // The oracle is the server's side of the search's connection, not a clock: still open when the
  // dialog's close has returned (a close that waited for the search would return only after the
  // search gave up and closed it).
  const int listener = ::socket(AF_INET, SOCK_STREAM, 0);
  ASSERT_GE(listener, 0);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  socklen_t len = sizeof addr;
  ASSERT_EQ(::bind(listener, reinterpret_cast<sockaddr*>(&addr), sizeof addr), 0);
  ASSERT_EQ(::listen(listener, 4), 0);
  ASSERT_EQ(::getsockname(listener, reinterpret_cast<sockaddr*>(&addr), &len), 0);
  io::PacsServer silent;
  silent.host = "127.0.0.1";
  silent.port = ntohs(addr.sin_port);
  silent.timeout_s = 30;
  auto dialog = std::make_unique<PacsBrowserDialog>(silent, nullptr, nullptr);
  dialog->show();
  dialog->search();
  test::pump(200);
  ASSERT_TRUE(dialog->busy());
  auto t0 = std::chrono::steady_clock::now();
  dialog.reset();  // closed while the search waits
  const double close_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::printf("[ TIMING   ] closed during a search of a silent server in %.3f s (measured, not checked)\n", close_s);
  pollfd pending{listener, POLLIN, 0};
  ASSERT_EQ(::poll(&pending, 1, 30000), 1) << "the search never connected";
  const int connection = ::accept(listener, nullptr, nullptr);
  ASSERT_GE(connection, 0);
  char request[4096];
  ssize_t got = 0;
  while ((got = ::recv(connection, request, sizeof request, MSG_DONTWAIT)) > 0) {
  }
  const int recv_error = errno;
  EXPECT_TRUE(got < 0 && (recv_error == EAGAIN || recv_error == EWOULDBLOCK))
      << "the search's connection was closed when the dialog's close returned (recv " << got << ", errno "
      << recv_error << ")";
  // Closing the server's side ends the search's wait (its thread then hands its result to no one).
  ::signal(SIGPIPE, SIG_IGN);
  ::close(connection);
  ::close(listener);
  test::pump(500);
}

TEST(PacsDialog, TheSettingsCarryTheTimeoutAndTlsAndTheTestObeysTheTimeout) {
  // A socket that accepts connections (the kernel's backlog) and never answers.
  const int listener = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  socklen_t len = sizeof addr;
  ASSERT_EQ(::bind(listener, reinterpret_cast<sockaddr*>(&addr), sizeof addr), 0);
  ASSERT_EQ(::listen(listener, 4), 0);
  ASSERT_EQ(::getsockname(listener, reinterpret_cast<sockaddr*>(&addr), &len), 0);
  io::PacsServer start;
  start.host = "127.0.0.1";
  start.port = ntohs(addr.sin_port);
  start.timeout_s = 45;
  start.ca_cert = "/etc/pki/hospital-ca.pem";
  PacsSettingsDialog dialog(start);
  auto* timeout = dialog.findChild<QSpinBox*>("pacsTimeout");
  auto* tls = dialog.findChild<QCheckBox*>("pacsTls");
  auto* ca = dialog.findChild<QLineEdit*>("pacsCaCert");
  auto* key = dialog.findChild<QLineEdit*>("pacsClientKey");
  ASSERT_TRUE(timeout && tls && ca && key);
  EXPECT_EQ(timeout->value(), 45);
  EXPECT_FALSE(tls->isChecked());
  EXPECT_EQ(ca->text(), "/etc/pki/hospital-ca.pem");
  EXPECT_FALSE(ca->isEnabled()) << "the TLS files are for TLS only";
  tls->setChecked(true);
  EXPECT_TRUE(ca->isEnabled());
  key->setText(" /home/u/ws7.key ");
  timeout->setValue(2);
  const io::PacsServer edited = dialog.server();
  EXPECT_TRUE(edited.tls);
  EXPECT_EQ(edited.timeout_s, 2);
  EXPECT_EQ(edited.ca_cert, "/etc/pki/hospital-ca.pem");
  EXPECT_EQ(edited.client_key, "/home/u/ws7.key");

  // The Test button uses the timeout shown: the silent server's test fails after it.
  tls->setChecked(false);
  dialog.show();
  auto* result = dialog.findChild<QLabel*>("pacsTestResult");
  auto* test_button = dialog.findChild<QPushButton*>("pacsTest");
  ASSERT_TRUE(result && test_button);
  const auto t0 = std::chrono::steady_clock::now();
  test_button->click();
  // The dialog's first timeout was 45 s: an answer within 30 s comes from the 2 s one shown (a busy
  // machine may add seconds to it, not 43).
  ASSERT_TRUE(test::waitFor([&] { return result->text().contains("timeout"); }, 30000)) << result->text().toStdString();
  const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::printf("[ TIMING   ] Test Connection to a silent server: %.3f s: %s\n", s, result->text().toStdString().c_str());
  EXPECT_TRUE(result->text().contains("within the timeout of 2 s")) << result->text().toStdString();
  ::close(listener);
}

TEST(PacsDialog, ClosingDuringARetrievalCancelsIt) {
  VH_REQUIRE_ORTHANC(values);
  QTemporaryDir cache;
  auto dialog = std::make_unique<PacsBrowserDialog>(fixtureServer(values), nullptr, nullptr,
                                                    fs::path(cache.path().toStdString()));
  dialog->show();
  dialog->search();
  ASSERT_TRUE(test::waitFor([&] { return dialog->tree()->topLevelItemCount() > 0; }, 20000));
  dialog->tree()->topLevelItem(0)->child(0)->setExpanded(true);
  QTreeWidgetItem* series = firstSeries(*dialog);
  ASSERT_NE(series, nullptr);
  const fs::path folder = pacsCacheFolder(series->text(4).toStdString(), fs::path(cache.path().toStdString()));
  series->setSelected(true);
  dialog->retrieveSelected();
  ASSERT_TRUE(test::waitFor([&] { return dicomFilesIn(folder) >= 3; }, 30000));
  const auto t0 = std::chrono::steady_clock::now();
  dialog.reset();  // closed mid-retrieval (how long the close took is printed, not checked: that it
                   // never waits for the network is ClosingNeverWaitsForTheNetwork's)
  const double close_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  // The retrieval's thread stops (C-CANCEL) and deletes what it received.
  EXPECT_TRUE(test::waitFor([&] { return dicomFilesIn(folder) == 0; }, 30000)) << dicomFilesIn(folder) << " files left";
  std::printf("[ TIMING   ] closed during a retrieval in %.3f s; its files gone %.3f s later\n", close_s,
              std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
  test::pump(500);  // the thread's last steps (releasing the association)
}

// The whole path in the window: File > Open from PACS, the dialog driven as a user would (a
// timer acts inside its modal loop), and the retrieved series opened as a DICOM folder.
TEST(PacsMainWindow, OpensTheRetrievedSeriesAsADicomFolder) {
  VH_REQUIRE_ORTHANC(values);
  MainWindow window;
  window.setInteractive(false);
  window.preferences().pacs = fixtureServer(values);
  window.resize(800, 600);
  window.show();
  QSignalSpy loaded(&window, &MainWindow::sceneLoaded);
  QAction* open_from_pacs = nullptr;
  for (QAction* a : window.findChildren<QAction*>()) {
    if (a->text() == "Open from &PACS...") open_from_pacs = a;
  }
  ASSERT_NE(open_from_pacs, nullptr) << "File > Open from PACS";
  EXPECT_EQ(open_from_pacs->shortcut(), QKeySequence("Ctrl+Shift+D"));

  int step = 0;
  std::string series_uid;
  QTimer driver;
  QObject::connect(&driver, &QTimer::timeout, [&] {
    auto* dialog = qobject_cast<PacsBrowserDialog*>(QApplication::activeModalWidget());
    if (dialog == nullptr || dialog->busy()) return;
    if (step == 0) {
      dialog->search();
      step = 1;
    } else if (step == 1 && dialog->tree()->topLevelItemCount() > 0) {
      dialog->tree()->topLevelItem(0)->child(0)->setExpanded(true);
      step = 2;
    } else if (step == 2) {
      for (QTreeWidgetItemIterator it(dialog->tree()); *it != nullptr; ++it) {
        if ((*it)->data(0, kPacsKindRole).toInt() == kPacsSeries) {
          series_uid = (*it)->text(4).toStdString();
          (*it)->setSelected(true);
          dialog->retrieveSelected();  // accepts the dialog once the files are in
          step = 3;
          break;
        }
      }
    }
  });
  driver.start(50);
  open_from_pacs->trigger();  // returns once the dialog is closed
  driver.stop();
  ASSERT_EQ(step, 3) << "the dialog closed before a series was retrieved";
  ASSERT_TRUE(test::waitFor([&] { return loaded.count() > 0; }, 30000)) << window.opener()->lastError().toStdString();
  ASSERT_TRUE(window.hasScene());
  const auto& dims = window.session().loaded().volume.field->geometry().dims;
  const io::LoadedVolume original = io::loadVolume(values.at("dataset"));
  EXPECT_EQ(dims, original.field->geometry().dims);
  EXPECT_EQ(window.session().loaded().volume.info.modality, "CT");
  const fs::path cached = pacsCacheFolder(series_uid);
  ASSERT_FALSE(window.preferences().recent_files.isEmpty());
  EXPECT_EQ(window.preferences().recent_files.front().toStdString(), fs::absolute(cached).lexically_normal().string());
  EXPECT_EQ(dicomFilesIn(cached), static_cast<std::size_t>(std::stoi(values.at("instances"))));
  window.close();
  std::error_code ec;
  fs::remove_all(cached, ec);  // the test-mode cache (QStandardPaths::setTestModeEnabled)
}

// A hostile server's answer in the window while a recording runs: File > Open from PACS >
// Search against a server whose C-FIND answer is nested 100,000 deep (which crashes DCMTK's
// parser). The dialog says what happened; the window, the haptic threads and the recording go on,
// and the recording reads back whole.
TEST(PacsMainWindow, AHostileAnswerDuringARecordingEndsNeitherTheWindowNorTheRecording) {
  io::test::HostilePacs pacs(io::test::nestedSequencesIdentifier(100'000));
  ASSERT_TRUE(pacs.waitUntilUp()) << "the hostile server did not start";
  MainWindow window;
  window.setInteractive(false);
  window.preferences().pacs = pacs.server();
  window.resize(800, 600);
  window.show();
  QSignalSpy loaded(&window, &MainWindow::sceneLoaded);
  const fs::path dir = fs::path(::testing::TempDir());
  const fs::path scene_file = dir / "pacs_hostile_sphere.json";
  {
    std::ofstream out(scene_file);
    out << R"({"volume": {"path": "builtin:sphere"}, "tool": {"mesh": "builtin:probe"}, "device": {"kind": "simulated"}})";
  }
  window.openPath(QString::fromStdString(scene_file.string()));
  ASSERT_TRUE(test::waitFor([&] { return loaded.count() > 0; }, 30000)) << window.opener()->lastError().toStdString();
  ASSERT_TRUE(test::waitFor([&] { return window.session().hapticsRunning(); }, 30000));
  const fs::path rec = dir / "pacs_hostile_recording.vhrec";
  ASSERT_TRUE(window.recorder()->start(rec)) << window.recorder()->lastError().toStdString();
  ASSERT_TRUE(test::waitFor([&] { return window.recorder()->recordsWritten() > 100; }, 30000));

  QAction* open_from_pacs = nullptr;
  for (QAction* a : window.findChildren<QAction*>()) {
    if (a->text() == "Open from &PACS...") open_from_pacs = a;
  }
  ASSERT_NE(open_from_pacs, nullptr) << "File > Open from PACS";
  int step = 0;
  QString status;
  QTimer driver;
  QObject::connect(&driver, &QTimer::timeout, [&] {
    auto* dialog = qobject_cast<PacsBrowserDialog*>(QApplication::activeModalWidget());
    if (dialog == nullptr || dialog->busy()) return;
    if (step == 0) {
      dialog->search();
      step = 1;
    } else if (step == 1) {
      status = dialog->statusText();
      dialog->reject();
      step = 2;
    }
  });
  driver.start(50);
  open_from_pacs->trigger();  // returns once the dialog is closed
  driver.stop();
  ASSERT_EQ(step, 2) << "the dialog closed before its search ended";
  std::printf("[ MESSAGE  ] the dialog said: %s\n", status.toStdString().c_str());
  EXPECT_TRUE(status.contains("the DICOM network process crashed (SIGSEGV)")) << status.toStdString();
  EXPECT_EQ(pacs.findsAnswered(), 1) << "the hostile answer was not sent";
  // The window, its haptics and the recording go on.
  EXPECT_TRUE(window.recorder()->recording());
  EXPECT_TRUE(window.session().hapticsRunning());
  const auto written = window.recorder()->recordsWritten();
  EXPECT_TRUE(test::waitFor([&] { return window.recorder()->recordsWritten() > written + 100; }, 30000))
      << "the recording stopped growing after the search";
  window.recorder()->stop();
  const runtime::Recording read = runtime::readRecording(rec);
  EXPECT_TRUE(read.warnings.empty()) << read.warnings.front();
  EXPECT_GT(read.records.size(), 200u);
  window.session().stopHaptics();
  window.close();
}

}  // namespace
}  // namespace vh::ui
