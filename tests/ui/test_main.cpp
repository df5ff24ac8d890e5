// GoogleTest main for the GUI tests: one QApplication per run (ctest starts one run per test), created after the
// default surface format VTK needs (OpenGL 3.2 core, depth 24, stencil 8, no MSAA). Settings go
// to a temporary folder so the tests never read or change the user's.
#include <dlfcn.h>

#include <QApplication>
#include <QSettings>
#include <QStandardPaths>
#include <QSurfaceFormat>
#include <QTemporaryDir>

#include <gtest/gtest.h>

int main(int argc, char** argv) {
  ::testing::InitGoogleTest(&argc, argv);
  // Listing the cases (ctest's discovery at build time) needs no display.
  if (::testing::GTEST_FLAG(list_tests)) return RUN_ALL_TESTS();
#if defined(__SANITIZE_ADDRESS__)
  // Mesa's software GL driver (loaded under Xvfb) keeps a few blocks for its lifetime and is
  // unloaded when the last GL context goes, after which LeakSanitizer can no longer name it
  // (so tests/sanitizers/lsan.supp could not suppress it by name). Load it first and never unload.
  dlopen("/usr/lib/x86_64-linux-gnu/dri/swrast_dri.so", RTLD_NOW | RTLD_NODELETE);
#endif
  QSurfaceFormat format;
  format.setRenderableType(QSurfaceFormat::OpenGL);
  format.setVersion(3, 2);
  format.setProfile(QSurfaceFormat::CoreProfile);
  format.setDepthBufferSize(24);
  format.setStencilBufferSize(8);
  format.setAlphaBufferSize(8);
  format.setSamples(0);
  QSurfaceFormat::setDefaultFormat(format);
  QStandardPaths::setTestModeEnabled(true);
  QApplication app(argc, argv);
  QApplication::setOrganizationName("VolumeHapticsTests");
  QApplication::setApplicationName("vh_ui_tests");
  QTemporaryDir settings_dir;
  QSettings::setPath(QSettings::NativeFormat, QSettings::UserScope, settings_dir.path());
  QSettings::setPath(QSettings::IniFormat, QSettings::UserScope, settings_dir.path());
  return RUN_ALL_TESTS();
}
