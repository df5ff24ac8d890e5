#pragma once
// The surgeon's set-up of the drilling and depth-cue tests: the Philips head phantom open in the
// main window at 400 HU (bone) with the built-in drill picked.

#include <filesystem>

#include <QString>

#include <gtest/gtest.h>

#include "ui_test_util.h"
#include "vh/ui/main_window.h"
#include "vh/ui/tool_picker.h"

namespace vh::ui::test {

/// The shared head phantom (512 x 512 x 140 CT); tests skip when it is absent.
inline const std::filesystem::path kHeadPhantom = kSharedData / "ct/philips-head-phantom-bone";

/// Shows `window` (1280 x 860, not interactive), opens the head phantom, sets the isovalue to
/// 400 HU and picks the built-in drill at 1 mm point spacing. Fails when a step does not finish.
inline ::testing::AssertionResult openPhantomWithDrill(MainWindow& window) {
  window.setInteractive(false);
  window.resize(1280, 860);
  window.show();
  window.openPath(QString::fromStdString(kHeadPhantom.string()));
  // A 512 x 512 x 140 CT read, its trees built and uploaded: generous, a busy machine takes several
  // times as long as an idle one.
  if (!waitFor([&] { return window.hasScene() && !window.opener()->loading(); }, 120000))
    return ::testing::AssertionFailure() << "the head phantom did not open";
  window.session().setIsovalue(400.0);
  int drill_index = -1;
  for (std::size_t i = 0; i < window.toolPicker()->choices().size(); ++i)
    if (window.toolPicker()->choices()[i].id == "builtin:drill") drill_index = static_cast<int>(i);
  if (drill_index < 0) return ::testing::AssertionFailure() << "no built-in drill in the tool picker";
  window.toolPicker()->select(drill_index, 0.001);
  if (!waitFor([&] { return window.toolPicker()->currentIndex() == drill_index; }, 60000))
    return ::testing::AssertionFailure() << "the drill was not built";
  return ::testing::AssertionSuccess();
}

}  // namespace vh::ui::test
