// Settings round trip (ui/preferences.h) and the recent-files list.
#include "vh/ui/preferences.h"

#include <sys/stat.h>

#include <QSettings>
#include <QTemporaryDir>

#include <gtest/gtest.h>

namespace vh::ui {
namespace {

TEST(Preferences, RoundTripThroughQSettings) {
  QTemporaryDir dir;
  const QString file = dir.filePath("prefs.ini");
  Preferences p;
  p.background_top = QColor(10, 20, 30);
  p.background_bottom = QColor(1, 2, 3);
  p.surface = QColor(200, 100, 50);
  p.tool = QColor(9, 8, 7);
  p.device = QColor(250, 0, 250);
  p.linear_stiffness_N_per_m = 2345.0;
  p.torsional_stiffness_Nm_per_rad = 0.75;
  p.passivity_control = true;
  p.mode = RenderMode::kMip;
  p.preset = VolumePreset::kSkin;
  p.orientation_marker = false;
  p.show_device = false;
  p.tool_shadow = false;
  p.segments_through_scan = true;
  p.burr_sound = true;
  p.alert_sound = true;
  p.addRecentFile("/data/a.nrrd");
  p.addRecentFile("/data/dicom");
  p.last_folder = "/data";
  p.pacs.host = "pacs.example.org";
  p.pacs.port = 11112;
  p.pacs.called_aet = "HOSPITAL";
  p.pacs.calling_aet = "WORKSTATION7";
  p.pacs.timeout_s = 45;
  p.pacs.tls = true;
  p.pacs.ca_cert = "/etc/pki/hospital-ca.pem";
  p.pacs.client_cert = "/home/u/ws7.pem";
  p.pacs.client_key = "/home/u/ws7.key";
  {
    QSettings s(file, QSettings::IniFormat);
    p.save(s);
  }
  QSettings s(file, QSettings::IniFormat);
  const Preferences back = Preferences::load(s);
  EXPECT_TRUE(back == p);
  EXPECT_EQ(back.recent_files, (QStringList{"/data/dicom", "/data/a.nrrd"}));
  EXPECT_EQ(back.mode, RenderMode::kMip);
  EXPECT_EQ(back.surface, QColor(200, 100, 50));
  EXPECT_EQ(back.pacs.describe(), "HOSPITAL at pacs.example.org:11112");
  EXPECT_EQ(back.pacs.calling_aet, "WORKSTATION7");
  EXPECT_EQ(back.pacs.timeout_s, 45);
  EXPECT_TRUE(back.pacs.tls);
  EXPECT_EQ(back.pacs.ca_cert, "/etc/pki/hospital-ca.pem");
  EXPECT_EQ(back.pacs.client_key, "/home/u/ws7.key");
}

TEST(Preferences, MissingOrInvalidEntriesKeepTheDefaults) {
  QTemporaryDir dir;
  QSettings s(dir.filePath("bad.ini"), QSettings::IniFormat);
  s.setValue("preferences/colours/surface", "not a colour");
  s.setValue("preferences/haptics/linear_stiffness_N_per_m", -5.0);
  s.setValue("preferences/view/mode", 42);
  s.setValue("preferences/pacs/port", 70000);
  s.setValue("preferences/pacs/timeout_s", 0);
  const Preferences p = Preferences::load(s);
  const Preferences defaults;
  EXPECT_EQ(p.surface, defaults.surface);
  EXPECT_EQ(p.linear_stiffness_N_per_m, defaults.linear_stiffness_N_per_m);
  EXPECT_EQ(p.mode, defaults.mode);
  EXPECT_EQ(p.pacs.port, defaults.pacs.port);
  EXPECT_TRUE(p == defaults);
}

TEST(Preferences, RecentFilesAreUniqueNewestFirstAndBounded) {
  Preferences p;
  for (int i = 0; i < Preferences::kMaxRecentFiles + 5; ++i) p.addRecentFile(QString("/f%1").arg(i));
  EXPECT_EQ(p.recent_files.size(), Preferences::kMaxRecentFiles);
  EXPECT_EQ(p.recent_files.front(), QString("/f%1").arg(Preferences::kMaxRecentFiles + 4));
  p.addRecentFile("/f10");
  EXPECT_EQ(p.recent_files.front(), "/f10");
  EXPECT_EQ(p.recent_files.count("/f10"), 1);
  p.addRecentFile("");
  EXPECT_EQ(p.recent_files.front(), "/f10");
}

// The settings file lists recent scans' paths (often folders named after patients): owner-only.
// Made so at start-up, it stays 0600 (and its folder 0700) after Qt has rewritten it with a
// recent path, under the usual umask 022 (before: 0644 and 0755). The oracle is stat().
TEST(Preferences, TheSettingsFileIsOwnerOnlyAndStaysSo) {
  const mode_t old_umask = ::umask(022);
  {  // a file as Qt leaves it without the call: the control
    QSettings before;
    before.setValue("recent/files", QStringList{"/scans/control"});
    before.sync();
  }
  const std::string file = QSettings().fileName().toStdString();
  struct stat st {};
  ASSERT_EQ(::stat(file.c_str(), &st), 0) << file;
  ::chmod(file.c_str(), 0644);
  makeSettingsPrivate();
  {
    QSettings settings;
    settings.setValue("recent/files", QStringList{"/scans/Doe^Jane/CT"});
    settings.sync();
    ASSERT_EQ(settings.status(), QSettings::NoError);
  }
  ::umask(old_umask);
  ASSERT_EQ(::stat(file.c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 0777, 0600u) << file;
  const std::string folder = file.substr(0, file.rfind('/'));
  ASSERT_EQ(::stat(folder.c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 0777, 0700u) << folder;
}

}  // namespace
}  // namespace vh::ui
