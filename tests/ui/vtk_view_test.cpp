// VtkView, the Qt <-> VTK bridge: its frames live in a native window inside the widget, so what
// the user does over that window must still reach the widget (and the filters installed on it),
// and screenshots must still show the frame. Oracles: the events counted by a filter on the
// widget, the camera VTK's trackball moved, and the renderer's own background colour.
#include "vh/ui/view/vtk_view.h"

#include <chrono>
#include <cmath>
#include <cstdint>
#include <thread>

#include <QGuiApplication>
#include <QHBoxLayout>
#include <QLabel>
#include <QMouseEvent>
#include <QTest>
#include <QWidget>
#include <QWindow>

#include <gtest/gtest.h>
#include <vtkCamera.h>
#include <vtkRenderer.h>

#include "ui_test_util.h"

namespace vh::ui {
namespace {

/// Counts the mouse events that reach a widget's event filters.
class MouseCounter : public QObject {
 public:
  int presses = 0, moves = 0, hovers = 0, releases = 0, wheels = 0;

 protected:
  bool eventFilter(QObject* /*watched*/, QEvent* event) override {
    switch (event->type()) {
      case QEvent::MouseButtonPress: ++presses; break;
      case QEvent::MouseMove:
        ++(static_cast<QMouseEvent*>(event)->buttons() != Qt::NoButton ? moves : hovers);
        break;
      case QEvent::MouseButtonRelease: ++releases; break;
      case QEvent::Wheel: ++wheels; break;
      default: break;
    }
    return false;
  }
};

/// A window with a panel on the left and the view on the right.
struct Window {
  Window() {
    auto* layout = new QHBoxLayout(&widget);
    layout->setContentsMargins(0, 0, 0, 0);
    layout->setSpacing(0);
    panel = new QLabel("panel", &widget);
    panel->setFixedWidth(80);
    panel->setAutoFillBackground(true);
    QPalette palette = panel->palette();
    palette.setColor(QPalette::Window, Qt::white);
    panel->setPalette(palette);
    layout->addWidget(panel);
    view = new VtkView(&widget);
    layout->addWidget(view, 1);
    view->renderer()->SetBackground(1.0, 0.0, 0.0);
    widget.resize(320, 200);
    widget.show();
  }
  QWidget widget;
  QLabel* panel = nullptr;
  VtkView* view = nullptr;
};

TEST(VtkView, MouseOverItsNativeWindowReachesTheWidgetAndVtk) {
  Window w;
  ASSERT_TRUE(test::waitFor([&] { return w.view->frameCount() > 0; }, 20000)) << "the view never rendered";
  QWindow* native = w.view->nativeWindow();
  ASSERT_NE(native, nullptr);
  MouseCounter counter;
  w.view->installEventFilter(&counter);
  vtkCamera* camera = w.view->renderer()->GetActiveCamera();
  double before[3];
  camera->GetPosition(before);

  // A left drag over the native window, as the X server delivers it: to the window.
  const QPoint centre(native->width() / 2, native->height() / 2);
  QTest::mouseMove(native, centre + QPoint(-30, 0));  // no button held: not a drag
  QTest::mousePress(native, Qt::LeftButton, Qt::NoModifier, centre);
  for (int i = 1; i <= 5; ++i) {
    QMouseEvent move(QEvent::MouseMove, QPointF(centre + QPoint(8 * i, 0)), native->mapToGlobal(QPointF(centre + QPoint(8 * i, 0))),
                     Qt::NoButton, Qt::LeftButton, Qt::NoModifier);
    QGuiApplication::sendEvent(native, &move);
  }
  QTest::mouseRelease(native, Qt::LeftButton, Qt::NoModifier, centre + QPoint(40, 0));

  EXPECT_EQ(counter.presses, 1);
  EXPECT_EQ(counter.releases, 1);
  EXPECT_GE(counter.moves, 5) << "moves while the button is held reach the widget";
  EXPECT_EQ(counter.hovers, 0) << "moves without a button do not (the widget tracks no hovering)";
  double after[3];
  camera->GetPosition(after);
  const double moved = std::hypot(after[0] - before[0], after[1] - before[1], after[2] - before[2]);
  EXPECT_GT(moved, 1e-3) << "VTK's trackball turned the camera";
  EXPECT_EQ(w.widget.focusWidget(), w.view) << "a click in the view gives the widget the keyboard focus";
  EXPECT_NE(QGuiApplication::focusWindow(), native) << "the native window never takes the focus";
}

TEST(VtkView, TheWidgetsCursorShowsOverItsNativeWindow) {
  // The simulated device's drags set a cursor on the view widget; the pointer is over the
  // native window, which must show it.
  Window w;
  QWindow* native = w.view->nativeWindow();
  ASSERT_NE(native, nullptr);
  w.view->setCursor(Qt::ClosedHandCursor);
  EXPECT_EQ(native->cursor().shape(), Qt::ClosedHandCursor);
  w.view->setCursor(Qt::SizeAllCursor);
  EXPECT_EQ(native->cursor().shape(), Qt::SizeAllCursor);
  w.view->unsetCursor();
  EXPECT_EQ(native->cursor().shape(), Qt::ArrowCursor);
}

TEST(VtkView, AViewWhoseNativeWindowWentFirstStillReleasesItsGraphics) {
  // At a window's end its QWindow may go before the view (the native window is its child):
  // nothing is drawn any more, and VTK's GL objects are released in their context all the same.
  Window w;
  ASSERT_TRUE(test::waitFor([&] { return w.view->frameCount() > 0; }, 20000)) << "the view never rendered";
  delete w.view->nativeWindow();
  EXPECT_EQ(w.view->nativeWindow(), nullptr);
  EXPECT_TRUE(w.view->makeCurrent()) << "an offscreen surface for the context";
  w.view->doneCurrent();
  EXPECT_FALSE(w.view->renderNow());
  EXPECT_TRUE(w.view->grabFrame().isNull());
  w.view->requestRender();
  w.view->setCursor(Qt::SizeAllCursor);
  test::pump(50);
  delete w.view;  // releases VTK's GL objects: must not crash
}

TEST(VtkView, AScreenshotOfTheWindowShowsTheViewsFrameInItsPlace) {
  Window w;
  ASSERT_TRUE(test::waitFor([&] { return w.view->frameCount() > 0; }, 20000)) << "the view never rendered";
  const QImage frame = w.view->grabFrame();
  ASSERT_FALSE(frame.isNull());
  EXPECT_EQ(frame.size(), w.view->size() * w.view->devicePixelRatio());
  const QRgb centre = frame.pixel(frame.width() / 2, frame.height() / 2);
  EXPECT_GT(qRed(centre), 240);
  EXPECT_LT(qGreen(centre), 15);

  const QImage shot = grabWithView(w.widget, *w.view);
  ASSERT_FALSE(shot.isNull());
  const double dpr = shot.devicePixelRatio();
  const QPoint view_at = w.view->mapTo(&w.widget, QPoint(0, 0));
  int red_in_view = 0, red_in_panel = 0, samples = 0;
  for (int y = 4; y < w.view->height() - 4; y += 7) {
    for (int x = 4; x < w.view->width() - 4; x += 7) {
      const QRgb in_view = shot.pixel(static_cast<int>((view_at.x() + x) * dpr), static_cast<int>((view_at.y() + y) * dpr));
      red_in_view += qRed(in_view) > 240 && qGreen(in_view) < 15 && qBlue(in_view) < 15;
      ++samples;
    }
  }
  for (int y = 4; y < w.panel->height() - 4; y += 7) {
    const QRgb in_panel = shot.pixel(static_cast<int>(40 * dpr), static_cast<int>(y * dpr));
    red_in_panel += qRed(in_panel) > 240 && qGreen(in_panel) < 15 && qBlue(in_panel) < 15;
  }
  EXPECT_EQ(red_in_view, samples) << "the view's frame fills its place in the screenshot";
  EXPECT_EQ(red_in_panel, 0) << "the panel beside it keeps its own pixels";
}

TEST(VtkView, AFrameRenderedNowAnswersTheRequestsBeforeIt) {
  // A caller that renders now (an export, a benchmark) after the props asked for a frame must
  // not get that frame drawn twice: once now, once at the next display refresh.
  Window w;
  ASSERT_TRUE(test::waitFor([&] { return w.view->frameCount() > 0; }, 20000)) << "the view never rendered";
  // The first frames settle: each expose of the newly shown window draws one. Waited for until
  // 300 ms pass without a frame (on a busy machine they come later, not in a fixed time).
  std::uint64_t settled = w.view->frameCount();
  for (int i = 0; i < 100; ++i) {
    test::pump(300);
    if (w.view->frameCount() == settled) break;
    settled = w.view->frameCount();
  }
  for (int i = 0; i < 5; ++i) {
    const std::uint64_t before = w.view->frameCount();
    w.view->requestRender();
    w.view->requestRender();
    ASSERT_TRUE(w.view->renderNow());
    test::pump(100);  // the display refreshes that would draw a request
    EXPECT_EQ(w.view->frameCount() - before, 1u) << "round " << i;
  }
  // A request alone is drawn, once: waited for, then 100 ms more for a second frame that must not come.
  const std::uint64_t before = w.view->frameCount();
  w.view->requestRender();
  w.view->requestRender();
  ASSERT_TRUE(test::waitFor([&] { return w.view->frameCount() > before; }, 30000)) << "the request was never drawn";
  test::pump(100);
  EXPECT_EQ(w.view->frameCount() - before, 1u);
}

TEST(VtkView, TheGapBeforeAFrameIsTheTimeSinceThePreviousFrameEnded) {
  // Oracle: the steady clock around a known pause between two frames rendered now.
  Window w;
  ASSERT_TRUE(test::waitFor([&] { return w.view->frameCount() > 0; }, 20000)) << "the view never rendered";
  const auto before = std::chrono::steady_clock::now();
  ASSERT_TRUE(w.view->renderNow());
  const auto ended = std::chrono::steady_clock::now();  // the frame's end and its swap
  std::this_thread::sleep_for(std::chrono::milliseconds(40));
  const auto started = std::chrono::steady_clock::now();
  ASSERT_TRUE(w.view->renderNow());
  const auto after = std::chrono::steady_clock::now();
  const auto ms = [](auto d) { return std::chrono::duration<double, std::milli>(d).count(); };
  EXPECT_GE(w.view->lastGapMs(), ms(started - ended)) << "from the end of the previous frame's render";
  EXPECT_LE(w.view->lastGapMs(), ms(after - before) - w.view->lastFrameMs() + 1e-6)
      << "to the start of this frame's render, whose own time is not in it";
  // The swap is the rest of renderNow(): together with the render it fits inside the call, and
  // the gap (the previous swap and the pause) holds the previous frame's swap.
  EXPECT_GT(w.view->lastSwapMs(), 0.0);
  EXPECT_LE(w.view->lastFrameMs() + w.view->lastSwapMs(), ms(after - started) + 1e-6);
}

}  // namespace
}  // namespace vh::ui
