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
  const fs::path damaged = damagedFileNamed(QString::fromStdString(message));
  EXPECT_EQ(damaged, test::kHead / "CTHead8.dcm") << message;
  EXPECT_TRUE(damagedFileNamed("volume.nrrd: not a volume").empty());

  // The series without it: every other file, linked, and it loads (a missing slice filled).
  const fs::path without = folderWithout(test::kHead, damaged);
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
  EXPECT_THROW((void)folderWithout(tmp / "nowhere", damaged), std::runtime_error);
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

}  // namespace
}  // namespace vh::ui
