// A folder with a damaged DICOM file: the error names the file (the reader process's probe), the
// window reads that name back (damagedFileNamed()) and offers the series without it, opened from
// a folder of links to the other files (folderWithout()). On the shared CT head (skipped with a
// message when absent), with a stand-in reader that crashes as vtk-dicom did on damaged files and
// names CTHead8.dcm, as tests/app/io/dicom_isolation_test.cpp does. Oracles: the files of the
// folder (every one but the damaged one, linked to the original) and the loader's own result.
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <set>
#include <string>

#include <unistd.h>

#include <QAbstractButton>
#include <QMessageBox>
#include <QSignalSpy>
#include <QString>

#include <gtest/gtest.h>

#include "ui_test_util.h"
#include "vh/io/volume_loader.h"
#include "vh/ui/main_window.h"
#include "vh/ui/scene_opener.h"

namespace vh::ui {
namespace {

namespace fs = std::filesystem;

std::set<std::string> namesIn(const fs::path& folder) {
  std::set<std::string> names;
  for (const auto& e : fs::directory_iterator(folder)) names.insert(e.path().filename().string());
  return names;
}

TEST(DamagedFile, TheErrorNamesTheFileAndTheSeriesOpensWithoutIt) {
  if (!fs::exists(test::kHead)) GTEST_SKIP() << test::kHead << " is absent (the shared datasets, ../shared/datasets)";
  // The error as the reader process reports a crash on a damaged file.
  const fs::path tmp = fs::temp_directory_path() / ("vh_damaged_" + std::to_string(::getpid()));
  fs::create_directories(tmp);
  const fs::path script = tmp / "worker.sh";
  std::ofstream(script) << "#!/bin/sh\n"
                           "if [ \"$1\" = probe ]; then echo \"file $2/CTHead7.dcm\"; echo ok; echo \"file $2/CTHead8.dcm\"; fi\n"
                           "kill -SEGV $$\n";
  fs::permissions(script, fs::perms::owner_all);
  std::string message;
  ::setenv("VH_DICOM_WORKER", script.c_str(), 1);
  try {
    (void)io::loadVolume(test::kHead);
  } catch (const io::LoadError& e) {
    message = e.what();
  }
  ::unsetenv("VH_DICOM_WORKER");
  ASSERT_FALSE(message.empty()) << "the stand-in reader's crash was not reported";
  EXPECT_NE(message.find("To open the series without it, move CTHead8.dcm out of the folder"), std::string::npos) << message;
  const std::vector<fs::path> named = damagedFilesNamed(QString::fromStdString(message));
  ASSERT_EQ(named.size(), 1u) << message;
  const fs::path damaged = named[0];
  EXPECT_EQ(damaged, test::kHead / "CTHead8.dcm") << message;
  EXPECT_TRUE(damagedFilesNamed("volume.nrrd: not a volume").empty());

  // The series without it: every other file, linked, and it loads (a missing slice filled).
  const fs::path without = folderWithout(test::kHead, {damaged});
  std::set<std::string> expected = namesIn(test::kHead);
  ASSERT_EQ(expected.erase("CTHead8.dcm"), 1u);
  EXPECT_EQ(namesIn(without), expected);
  EXPECT_TRUE(fs::equivalent(without / "CTHead7.dcm", test::kHead / "CTHead7.dcm"));
  const io::LoadedVolume volume = io::loadVolume(without);
  EXPECT_EQ(volume.field->geometry().dims[0], 64);
  bool gap_noticed = false;
  for (const std::string& n : volume.info.notices) gap_noticed = gap_noticed || n.find("missing") != std::string::npos;
  EXPECT_TRUE(gap_noticed) << "the slice left out is not named as missing";
  EXPECT_TRUE(fs::exists(test::kHead / "CTHead8.dcm")) << "the original folder is left as it is";
  EXPECT_THROW((void)folderWithout(tmp / "nowhere", {damaged}), std::runtime_error);
  fs::remove_all(without);

  // The window asks, and "Open Without It" opens the rest of the series.
  MainWindow window;
  window.setInteractive(true);
  window.resize(800, 600);
  window.show();
  QSignalSpy loaded(&window, &MainWindow::sceneLoaded);
  window.opener()->reportError(QString::fromStdString(test::kHead.string()), QString::fromStdString(message));
  auto* box = window.findChild<QMessageBox*>("damagedFileBox");
  ASSERT_NE(box, nullptr) << "no question for a damaged file";
  EXPECT_TRUE(box->text().contains("CTHead8.dcm is damaged")) << box->text().toStdString();
  EXPECT_TRUE(box->informativeText().contains("Open the series without CTHead8.dcm?"));
  QAbstractButton* open = box->button(QMessageBox::Open);
  ASSERT_NE(open, nullptr);
  EXPECT_EQ(open->text().toStdString(), "Open Without It");
  open->click();
  ASSERT_TRUE(test::waitFor([&] { return loaded.count() > 0; }, 30000 * test::kSanitizerSlowdown))
      << window.opener()->lastError().toStdString();
  const fs::path source = window.session().loaded().volume.info.source;
  EXPECT_NE(source.string().find("without-CTHead8.dcm"), std::string::npos) << source;
  EXPECT_FALSE(fs::exists(source / "CTHead8.dcm"));
  window.session().stopHaptics();
  fs::remove_all(source);
  fs::remove_all(tmp);
}

TEST(DamagedFile, ThreeDamagedFilesAreEachNamedAndTheSeriesOpensWithoutThem) {
  if (!fs::exists(test::kHead)) GTEST_SKIP() << test::kHead << " is absent (the shared datasets, ../shared/datasets)";
  // A stand-in reader that crashes on three files of the series, as vtk-dicom's parser did on
  // damaged ones: its probe walks the sorted files past --after FILE and crashes on each of
  // them; the load crashes too. The oracle is the set the script crashes on.
  const fs::path tmp = fs::temp_directory_path() / ("vh_damaged3_" + std::to_string(::getpid()));
  fs::create_directories(tmp);
  const std::set<std::string> bad = {"CTHead12.dcm", "CTHead3.dcm", "CTHead30.dcm"};
  const fs::path script = tmp / "worker.sh";
  std::ofstream(script) << "#!/bin/sh\n"
                           "export LC_ALL=C\n"
                           "if [ \"$1\" = probe ]; then\n"
                           "  after=\"\"; [ \"$3\" = --after ] && after=\"$4\"\n"
                           "  for f in $(ls \"$2\" | LC_ALL=C sort); do\n"
                           "    p=\"$2/$f\"\n"
                           "    if [ -n \"$after\" ] && ! expr \"$p\" \\> \"$after\" >/dev/null; then continue; fi\n"
                           "    echo \"file $p\"\n"
                           "    case \"$f\" in CTHead3.dcm|CTHead12.dcm|CTHead30.dcm) kill -SEGV $$;; esac\n"
                           "    echo ok\n"
                           "  done\n"
                           "  exit 0\n"
                           "fi\n"
                           "kill -SEGV $$\n";
  fs::permissions(script, fs::perms::owner_all);
  std::string message;
  ::setenv("VH_DICOM_WORKER", script.c_str(), 1);
  try {
    (void)io::loadVolume(test::kHead);
  } catch (const io::LoadError& e) {
    message = e.what();
  }
  ::unsetenv("VH_DICOM_WORKER");
  ASSERT_FALSE(message.empty()) << "the stand-in reader's crash was not reported";
  EXPECT_NE(message.find("on 3 damaged files"), std::string::npos) << message;
  std::set<std::string> named;
  for (const fs::path& p : damagedFilesNamed(QString::fromStdString(message))) {
    EXPECT_EQ(p.parent_path(), test::kHead) << message;
    named.insert(p.filename().string());
  }
  EXPECT_EQ(named, bad) << message;

  // The window asks once for all three, and "Open Without Them" opens the rest of the series.
  MainWindow window;
  window.setInteractive(true);
  window.resize(800, 600);
  window.show();
  QSignalSpy loaded(&window, &MainWindow::sceneLoaded);
  window.opener()->reportError(QString::fromStdString(test::kHead.string()), QString::fromStdString(message));
  auto* box = window.findChild<QMessageBox*>("damagedFileBox");
  ASSERT_NE(box, nullptr) << "no question for the damaged files";
  for (const std::string& b : bad) EXPECT_TRUE(box->text().contains(QString::fromStdString(b))) << box->text().toStdString();
  QAbstractButton* open = box->button(QMessageBox::Open);
  ASSERT_NE(open, nullptr);
  EXPECT_EQ(open->text().toStdString(), "Open Without Them");
  open->click();
  ASSERT_TRUE(test::waitFor([&] { return loaded.count() > 0; }, 30000 * test::kSanitizerSlowdown))
      << window.opener()->lastError().toStdString();
  const fs::path source = window.session().loaded().volume.info.source;
  std::set<std::string> expected = namesIn(test::kHead);
  for (const std::string& b : bad) ASSERT_EQ(expected.erase(b), 1u) << b;
  EXPECT_EQ(namesIn(source), expected);
  window.session().stopHaptics();
  fs::remove_all(source);
  fs::remove_all(tmp);
}

}  // namespace
}  // namespace vh::ui
