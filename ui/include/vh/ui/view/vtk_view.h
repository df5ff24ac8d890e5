#pragma once
/// @file
/// The Qt6 <-> VTK 9.1 bridge: a QOpenGLWidget that hosts a vtkGenericOpenGLRenderWindow.
///
/// Debian 12's VTK Qt module (QVTKOpenGLNativeWidget) is built against Qt5, so this project
/// carries its own small bridge (../shared/docs/qt6-vtk-embedding.md). With a VTK >= 9.2 built
/// against Qt6, QVTKOpenGLNativeWidget can replace this class.
///
/// How it works:
///  - VTK renders into its own framebuffer inside Qt's context (SetOwnContext(false),
///    frame blit mode NoBlit); paintGL() renders and blits VTK's display framebuffer into the
///    widget's framebuffer (defaultFramebufferObject()), then forces alpha to 1.
///  - WindowMakeCurrentEvent makes only Qt's *context* current: never QOpenGLWidget::
///    makeCurrent(), which would rebind Qt's framebuffer behind VTK's back (black frames).
///  - Every render happens in paintGL(): render requests (requestRender(), the interactor's
///    RenderEvent) only call update(), so many mouse moves share one frame.
///  - Mouse and wheel events go to a vtkGenericRenderWindowInteractor with
///    vtkInteractorStyleTrackballCamera (left: rotate, middle: pan, right/wheel: zoom).
///    Install an event filter on the view to take some events first (the main window does so
///    for the simulated device's Ctrl/Shift drags).
///  - GL resources are released when Qt's context goes away (re-parenting or destruction).

#include <cstdint>

#include <QImage>
#include <QOpenGLWidget>

#include <vtkNew.h>

class vtkGenericOpenGLRenderWindow;
class vtkGenericRenderWindowInteractor;
class vtkInteractorStyleTrackballCamera;
class vtkObject;
class vtkRenderer;

namespace vh::ui {

class VtkView : public QOpenGLWidget {
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

  /// Asks for a frame; requests are coalesced into one paintGL() (QWidget::update()).
  void requestRender();

  /// Renders a frame now and returns the view's pixels (QOpenGLWidget::grabFramebuffer()).
  QImage grabFrame();

  /// Frames rendered so far, and the wall time of the last one [ms].
  std::uint64_t frameCount() const noexcept { return frames_; }
  double lastFrameMs() const noexcept { return last_frame_ms_; }

 signals:
  /// Emitted after each frame was rendered and blitted (inside paintGL()).
  void frameRendered();
  /// A camera interaction (mouse drag, wheel) started / ended: a chance to lower the quality
  /// of expensive props meanwhile.
  void interactionStarted();
  void interactionEnded();

 protected:
  void initializeGL() override;
  void resizeGL(int w, int h) override;
  void paintGL() override;

  void mousePressEvent(QMouseEvent* event) override;
  void mouseReleaseEvent(QMouseEvent* event) override;
  void mouseMoveEvent(QMouseEvent* event) override;
  void mouseDoubleClickEvent(QMouseEvent* event) override;
  void wheelEvent(QWheelEvent* event) override;
  void enterEvent(QEnterEvent* event) override;
  void leaveEvent(QEvent* event) override;

 private slots:
  void onContextAboutToBeDestroyed();

 private:
  void onRenderWindowEvent(vtkObject* caller, unsigned long event_id, void* call_data);
  void onInteractorRender(vtkObject* caller, unsigned long event_id, void* call_data);
  void onStyleInteraction(vtkObject* caller, unsigned long event_id, void* call_data);
  void releaseGraphics();
  void forwardMouse(QMouseEvent* event, unsigned long vtk_event, bool repeat);

  vtkNew<vtkGenericOpenGLRenderWindow> render_window_;
  vtkNew<vtkRenderer> renderer_;
  vtkNew<vtkGenericRenderWindowInteractor> interactor_;
  vtkNew<vtkInteractorStyleTrackballCamera> style_;
  unsigned long observer_ids_[6] = {0, 0, 0, 0, 0, 0};
  bool in_paint_ = false;
  std::uint64_t frames_ = 0;
  double last_frame_ms_ = 0.0;
};

}  // namespace vh::ui
