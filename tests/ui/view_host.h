#pragma once
// A window holding a SceneView and a DisplayPanel, with the Session, Preferences and
// ViewController a test creates over them: the main window's view wiring without the rest of it.

#include <memory>

#include <QMainWindow>
#include <QVBoxLayout>
#include <QWidget>

#include "vh/runtime/session.h"
#include "vh/ui/panels/display_panel.h"
#include "vh/ui/preferences.h"
#include "vh/ui/view/scene_view.h"
#include "vh/ui/view/vtk_view.h"
#include "vh/ui/view_controller.h"

namespace vh::ui::test {

/// A main window whose central widget is a SceneView (400 x 300), shown: for the controllers
/// that draw into the view and add docks to the window (drilling, tissue).
struct SceneWindowHost {
  SceneWindowHost() {
    view = new SceneView(&window);
    window.setCentralWidget(view->widget());
    window.resize(400, 300);
    window.show();
  }
  QMainWindow window;
  SceneView* view = nullptr;  // owned by the window
};

struct ViewControllerHost {
  ViewControllerHost() {
    auto* layout = new QVBoxLayout(&widget);
    view = new SceneView(&widget);
    layout->addWidget(view->widget());
    panel = new DisplayPanel(&widget);
    layout->addWidget(panel);
    widget.resize(320, 400);
    widget.show();
  }
  ~ViewControllerHost() {
    controller.reset();
    session.clear();
  }
  QWidget widget;
  SceneView* view = nullptr;     // owned by the widget
  DisplayPanel* panel = nullptr;  // owned by the widget
  Preferences prefs;
  runtime::Session session;
  std::unique_ptr<ViewController> controller;  ///< The test creates it (after setting prefs).
};

}  // namespace vh::ui::test
