#pragma once
/// @file
/// The Qt6 <-> VTK 9.1 bridge: a widget that hosts a native OpenGL window (a QWindow in a
/// window container) in which a vtkGenericOpenGLRenderWindow renders.
///
/// Debian 12's VTK Qt module (QVTKOpenGLNativeWidget) is built against Qt5, so this project
/// carries its own small bridge (../shared/docs/qt6-vtk-embedding.md). With a VTK >= 9.2 built
/// against Qt6, QVTKOpenGLWindow in a window container can replace this class.
///
/// Why a native window and not a QOpenGLWidget: a QOpenGLWidget makes Qt compose the whole
/// top-level window with OpenGL on every frame (the widget's texture and every other widget's
/// pixels drawn into the window, then swapped whole). On software OpenGL (Mesa's llvmpipe) that
/// composition cost about 25 ms a frame at 1280 x 720 whatever VTK drew; a native window swaps
/// only the view's own pixels and the panels beside it are not redrawn.
///
/// How it works:
///  - A private QWindow (OpenGL surface) fills the widget through
///    QWidget::createWindowContainer(); the widget owns the QOpenGLContext, created when the
///    window is first shown.
///  - VTK renders into its own framebuffer in that context (SetOwnContext(false), frame blit
///    mode NoBlit, SwapBuffers off: no copy into its display framebuffer); renderNow() renders,
///    blits VTK's render framebuffer into the window's back buffer and swaps.
///  - Render requests (requestRender(), the interactor's RenderEvent, VTK frames rendered
///    outside renderNow()) post one render event to the window, behind the input already
///    waiting: many mouse moves share one frame.
///  - The native window never takes keyboard focus; its mouse, wheel and enter/leave events are
///    sent on to this widget, so event filters installed on the widget (the main window's
///    simulated-device drags) see them first, and keys go to the widget as before.
///  - The widget's cursor (setCursor(), unsetCursor()) is passed on to the native window.
///  - QWidget::grab() cannot see into a native window: screenshots of a window holding the view
///    use grabWithView().

#include <chrono>
#include <cstdint>
#include <memory>

#include <QImage>
#include <QPointer>
#include <QWindow>
#include <QWidget>

#include <vtkNew.h>

class QOffscreenSurface;
class QOpenGLContext;
class vtkGenericOpenGLRenderWindow;
class vtkGenericRenderWindowInteractor;
class vtkInteractorStyleTrackballCamera;
class vtkObject;
class vtkOpenGLState;
class vtkRenderer;

namespace vh::ui {

class VtkView : public QWidget {
  Q_OBJECT

 public:
  explicit VtkView(QWidget* parent = nullptr);
  ~VtkView() override;
  VtkView(const VtkView&) = delete;
  VtkView& operator=(const VtkView&) = delete;

  vtkGenericOpenGLRenderWindow* renderWindow() const noexcept;
  /// The one renderer of this view (created with it).
  vtkRenderer* renderer() const noexcept;
  vtkGenericRenderWindowInteractor* interactor() const noexcept;

  /// Asks for a frame; requests are coalesced into one render, posted to the window behind the
  /// input already waiting, and a renderNow() or grabFrame() before then answers them.
  void requestRender();

  /// Renders a frame now and shows it. @return false (nothing rendered) while the view is not
  /// on screen (its window not exposed).
  bool renderNow();

  /// Renders the scene into VTK's own framebuffer without showing it (no blit, no swap, no
  /// frame counted, no render requested): a render that readies GL state (shaders, buffers) for
  /// later frames. @return false (nothing rendered) while the view is not on screen.
  bool renderUnseen();

  /// Renders a frame now and returns the view's pixels (device pixels, top row first); a null
  /// image when the view was never shown.
  QImage grabFrame();

  /// The native window the frames are shown in (owned by the view's window container).
  QWindow* nativeWindow() const noexcept;

  /// The view's OpenGL context: null until the view is first shown.
  QOpenGLContext* context() const noexcept;
  /// Makes the view's context current on its window, or on an offscreen surface once the window
  /// has gone (for releasing GL objects); false while there is no context.
  bool makeCurrent();
  void doneCurrent();

  /// Frames rendered so far, and the wall time of the last one [ms] (VTK's render and the
  /// blit; the swap not included).
  std::uint64_t frameCount() const noexcept { return frames_; }
  double lastFrameMs() const noexcept { return last_frame_ms_; }
  /// The wall time from the end of the previous frame's render to the start of the last one
  /// [ms]: its swap and whatever the GUI thread did in between (events, timers, other widgets,
  /// idle time); negative before the second frame.
  double lastGapMs() const noexcept { return last_gap_ms_; }
  /// The wall time of the last renderNow()'s buffer swap [ms]: where the GL driver waits for the
  /// GPU to finish the frame, and for the display's refresh when the swap is synchronised to it
  /// (under VirtualGL, its read-back of the frame too); 0 before the first.
  double lastSwapMs() const noexcept { return last_swap_ms_; }

 signals:
  /// Emitted after each frame was rendered and blitted.
  void frameRendered();
  /// A camera interaction (mouse drag, wheel) started / ended: a chance to lower the quality
  /// of expensive props meanwhile.
  void interactionStarted();
  void interactionEnded();

 protected:
  /// Passes the widget's cursor on to the native window, which the pointer is over.
  bool event(QEvent* event) override;
  void mousePressEvent(QMouseEvent* event) override;
  void mouseReleaseEvent(QMouseEvent* event) override;
  void mouseMoveEvent(QMouseEvent* event) override;
  void mouseDoubleClickEvent(QMouseEvent* event) override;
  void wheelEvent(QWheelEvent* event) override;
  void enterEvent(QEnterEvent* event) override;
  void leaveEvent(QEvent* event) override;

 private:
  class Surface;

  /// Creates the context on the first call with a created window; makes it current.
  bool prepareContext();
  /// Renders into the window's back buffer (context current); no swap.
  void renderFrame();
  /// VTK's render into its own framebuffer (context current), with VTK's GL state reset and
  /// pushed: the caller pops it when done with the frame. @return that state.
  vtkOpenGLState* renderVtk();
  /// Not inside a frame, the window exposed, and the context current on it.
  bool readyToRender();
  /// The native window's size in device pixels (empty once it has gone).
  QSize surfacePixels() const;
  /// Tells VTK the window's size in device pixels when it changed.
  void surfaceResized();
  void onRenderWindowEvent(vtkObject* caller, unsigned long event_id, void* call_data);
  void onInteractorRender(vtkObject* caller, unsigned long event_id, void* call_data);
  void onStyleInteraction(vtkObject* caller, unsigned long event_id, void* call_data);
  void forwardMouse(QMouseEvent* event, unsigned long vtk_event, bool repeat);

  vtkNew<vtkGenericOpenGLRenderWindow> render_window_;
  vtkNew<vtkRenderer> renderer_;
  vtkNew<vtkGenericRenderWindowInteractor> interactor_;
  vtkNew<vtkInteractorStyleTrackballCamera> style_;
  // Owned by the container (QWidget::createWindowContainer), and a child of the top-level
  // window's QWindow: null once that has gone, whichever goes first at the window's end.
  QPointer<QWindow> surface_;
  std::unique_ptr<QOpenGLContext> context_;
  std::unique_ptr<QOffscreenSurface> offscreen_;  // makeCurrent() once the window has gone
  unsigned long observer_ids_[6] = {0, 0, 0, 0, 0, 0};
  bool in_paint_ = false;
  bool render_requested_ = false;  // requestRender() since the last frame began
  bool render_posted_ = false;     // a render event is queued for the window
  std::uint64_t frames_ = 0;
  double last_frame_ms_ = 0.0;
  double last_gap_ms_ = -1.0;
  double last_swap_ms_ = 0.0;
  std::chrono::steady_clock::time_point last_frame_end_{};
};

/// A picture of `window` (a top-level widget) with the view's frame drawn where the view is:
/// QWidget::grab() leaves a native child window blank. Device pixels of the window.
QImage grabWithView(QWidget& window, VtkView& view);

}  // namespace vh::ui
