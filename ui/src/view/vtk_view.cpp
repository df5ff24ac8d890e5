/// @file
/// The Qt6 <-> VTK bridge (see vtk_view.h and ../shared/docs/qt6-vtk-embedding.md).
/// Raw GL calls go through QOpenGLExtraFunctions; this file must never include vtk_glew.h.

#include "vh/ui/view/vtk_view.h"

#include <chrono>

#include <QCoreApplication>
#include <QEnterEvent>
#include <QExposeEvent>
#include <QMouseEvent>
#include <QOpenGLContext>
#include <QOffscreenSurface>
#include <QOpenGLExtraFunctions>
#include <QPainter>
#include <QResizeEvent>
#include <QSurfaceFormat>
#include <QVBoxLayout>
#include <QWheelEvent>
#include <QWindow>

#include <vtkCommand.h>
#include <vtkGenericOpenGLRenderWindow.h>
#include <vtkGenericRenderWindowInteractor.h>
#include <vtkInteractorStyleTrackballCamera.h>
#include <vtkOpenGLFramebufferObject.h>
#include <vtkOpenGLState.h>
#include <vtkRenderer.h>

namespace vh::ui {

/// The native OpenGL window VTK's frames are swapped into. It never takes the keyboard focus;
/// its input goes on to the widget that hosts it.
class VtkView::Surface : public QWindow {
 public:
  explicit Surface(VtkView* host) : host_(host) {
    setSurfaceType(QWindow::OpenGLSurface);
    QSurfaceFormat format = QSurfaceFormat::defaultFormat();
    format.setAlphaBufferSize(0);  // an opaque window: nothing shows through where VTK drew alpha < 1
    setFormat(format);
    setFlag(Qt::WindowDoesNotAcceptFocus, true);
  }
  /// The host is going: nothing more is passed to it (the window goes with the host's
  /// container, a moment later).
  void detach() noexcept { host_ = nullptr; }

 protected:
  bool event(QEvent* event) override {
    if (host_ == nullptr) return QWindow::event(event);
    switch (event->type()) {
      case QEvent::UpdateRequest:
        // Only a frame still asked for: renderNow() in between has drawn what was asked.
        host_->render_posted_ = false;
        if (host_->render_requested_) host_->renderNow();
        return true;
      case QEvent::MouseButtonPress:
      case QEvent::MouseButtonDblClick:
        host_->setFocus(Qt::MouseFocusReason);
        [[fallthrough]];
      case QEvent::MouseButtonRelease:
      case QEvent::Wheel:
      case QEvent::Enter:
      case QEvent::Leave:
      case QEvent::KeyPress:
      case QEvent::KeyRelease:
        QCoreApplication::sendEvent(host_, event);
        return true;
      case QEvent::MouseMove:
        // The X server reports every motion over a native window; a widget without mouse
        // tracking sees moves only while a button is held.
        if (host_->hasMouseTracking() || static_cast<QMouseEvent*>(event)->buttons() != Qt::NoButton)
          QCoreApplication::sendEvent(host_, event);
        return true;
      default:
        return QWindow::event(event);
    }
  }
  void exposeEvent(QExposeEvent* /*event*/) override {
    if (host_ != nullptr && isExposed()) host_->renderNow();
  }
  void resizeEvent(QResizeEvent* /*event*/) override {
    if (host_ != nullptr) host_->surfaceResized();
  }

 private:
  VtkView* host_;
};

VtkView::VtkView(QWidget* parent) : QWidget(parent) {
  setFocusPolicy(Qt::StrongFocus);
  setMouseTracking(false);
  setMinimumSize(160, 120);

  auto* surface = new Surface(this);
  surface_ = surface;
  QWidget* container = QWidget::createWindowContainer(surface, this);
  container->setFocusPolicy(Qt::NoFocus);
  auto* layout = new QVBoxLayout(this);
  layout->setContentsMargins(0, 0, 0, 0);
  layout->addWidget(container);

  // VTK renders into its own framebuffer in the view's context; renderFrame() blits it.
  render_window_->SetOwnContext(false);
  render_window_->SetFrameBlitModeToNoBlit();
  render_window_->SetReadyForRendering(false);  // until the context exists
  render_window_->SetMultiSamples(0);
  // No copy of each frame into VTK's display framebuffer (colour and depth, every pixel): the
  // window's back buffer is filled from VTK's render framebuffer directly (renderFrame()).
  render_window_->SetSwapBuffers(0);
  render_window_->SetForceMaximumHardwareLineWidth(1);
  render_window_->AddRenderer(renderer_);

  interactor_->SetRenderWindow(render_window_);
  interactor_->SetInteractorStyle(style_);
  interactor_->EnableRenderOff();  // its render requests become requestRender() (RenderEvent below)
  interactor_->Initialize();       // enables it; never Start(): Qt runs the event loop

  observer_ids_[0] = render_window_->AddObserver(vtkCommand::WindowMakeCurrentEvent, this,
                                                 &VtkView::onRenderWindowEvent);
  observer_ids_[1] = render_window_->AddObserver(vtkCommand::WindowIsCurrentEvent, this,
                                                 &VtkView::onRenderWindowEvent);
  observer_ids_[2] = render_window_->AddObserver(vtkCommand::WindowFrameEvent, this,
                                                 &VtkView::onRenderWindowEvent);
  observer_ids_[3] =
      interactor_->AddObserver(vtkCommand::RenderEvent, this, &VtkView::onInteractorRender);
  observer_ids_[4] = style_->AddObserver(vtkCommand::StartInteractionEvent, this,
                                         &VtkView::onStyleInteraction);
  observer_ids_[5] = style_->AddObserver(vtkCommand::EndInteractionEvent, this,
                                         &VtkView::onStyleInteraction);
}

VtkView::~VtkView() {
  // The native window's events stop reaching this half-destroyed widget.
  if (surface_ != nullptr) static_cast<Surface*>(surface_.data())->detach();
  // Release GL resources while the context still exists, then detach the observers: the render
  // window may outlive this widget when someone else holds a reference to it.
  if (context_ != nullptr && makeCurrent()) {
    render_window_->Finalize();
    render_window_->SetReadyForRendering(false);
    doneCurrent();
  }
  render_window_->RemoveObserver(observer_ids_[0]);
  render_window_->RemoveObserver(observer_ids_[1]);
  render_window_->RemoveObserver(observer_ids_[2]);
  interactor_->RemoveObserver(observer_ids_[3]);
  style_->RemoveObserver(observer_ids_[4]);
  style_->RemoveObserver(observer_ids_[5]);
}

vtkGenericOpenGLRenderWindow* VtkView::renderWindow() const noexcept { return render_window_; }
vtkRenderer* VtkView::renderer() const noexcept { return renderer_; }
vtkGenericRenderWindowInteractor* VtkView::interactor() const noexcept { return interactor_; }
QOpenGLContext* VtkView::context() const noexcept { return context_.get(); }
QWindow* VtkView::nativeWindow() const noexcept { return surface_; }

bool VtkView::event(QEvent* event) {
  if (event->type() == QEvent::CursorChange && surface_ != nullptr) {
    // The pointer is over the native window, whose own cursor X shows; a widget's cursor would
    // not reach it.
    if (testAttribute(Qt::WA_SetCursor)) {
      surface_->setCursor(cursor());
    } else {
      surface_->unsetCursor();
    }
  }
  return QWidget::event(event);
}

void VtkView::requestRender() {
  render_requested_ = true;
  // A render event queued behind the events already waiting (input first), at most one at a
  // time. Not QWindow::requestUpdate(): without a compositor's frame callbacks (X11 without
  // _NET_WM_FRAME_DRAWN, Xvfb) Qt delivers it through a 5 ms timer, a sixth of a 30 Hz frame.
  if (surface_ != nullptr && !render_posted_) {
    render_posted_ = true;
    QCoreApplication::postEvent(surface_, new QEvent(QEvent::UpdateRequest), Qt::LowEventPriority);
  }
}

bool VtkView::makeCurrent() {
  if (context_ == nullptr) return false;
  if (surface_ != nullptr && surface_->handle() != nullptr) return context_->makeCurrent(surface_);
  // The native window has gone (at the end of the window that held it): an offscreen surface,
  // so that VTK's GL objects are still released in their context.
  if (offscreen_ == nullptr) {
    offscreen_ = std::make_unique<QOffscreenSurface>();
    offscreen_->setFormat(context_->format());
    offscreen_->create();
  }
  return context_->makeCurrent(offscreen_.get());
}

void VtkView::doneCurrent() {
  if (context_ != nullptr) context_->doneCurrent();
}

bool VtkView::prepareContext() {
  if (surface_ == nullptr || surface_->handle() == nullptr) return false;  // not shown yet: no native window
  if (context_ == nullptr) {
    auto context = std::make_unique<QOpenGLContext>();
    context->setFormat(surface_->requestedFormat());
    if (!context->create()) return false;
    context_ = std::move(context);
    if (!context_->makeCurrent(surface_)) return false;
    render_window_->SetReadyForRendering(true);
    render_window_->OpenGLInitContext();
    surfaceResized();
    return true;
  }
  return context_->makeCurrent(surface_);
}

QSize VtkView::surfacePixels() const {
  if (surface_ == nullptr) return {};
  const qreal dpr = surface_->devicePixelRatio();
  return {static_cast<int>(surface_->width() * dpr), static_cast<int>(surface_->height() * dpr)};
}

void VtkView::surfaceResized() {
  const QSize pixels = surfacePixels();
  const int* size = render_window_->GetSize();
  if (size[0] != pixels.width() || size[1] != pixels.height()) interactor_->UpdateSize(pixels.width(), pixels.height());
}

void VtkView::renderFrame() {
  in_paint_ = true;
  render_requested_ = false;  // a request made while this frame renders asks for the next one
  const auto t0 = std::chrono::steady_clock::now();
  if (frames_ > 0) last_gap_ms_ = std::chrono::duration<double, std::milli>(t0 - last_frame_end_).count();

  surfaceResized();  // a resize whose event has not come yet
  const QSize pixels = surfacePixels();
  const int w = pixels.width(), h = pixels.height();

  vtkOpenGLState* state = renderVtk();

  // Blit VTK's render framebuffer into the window's back buffer.
  QOpenGLExtraFunctions* f = context_->extraFunctions();
  f->glBindFramebuffer(GL_DRAW_FRAMEBUFFER, context_->defaultFramebufferObject());
  const GLenum draw_buffer = GL_BACK_LEFT;
  f->glDrawBuffers(1, &draw_buffer);
  state->vtkglDisable(GL_SCISSOR_TEST);
  f->glDisable(GL_SCISSOR_TEST);
  f->glViewport(0, 0, w, h);
  vtkOpenGLFramebufferObject* rendered = render_window_->GetRenderFramebuffer();
  const int* source_size = rendered->GetLastSize();
  rendered->Bind(GL_READ_FRAMEBUFFER);
  rendered->ActivateReadBuffer(0);
  f->glBlitFramebuffer(0, 0, source_size[0], source_size[1], 0, 0, w, h, GL_COLOR_BUFFER_BIT, GL_LINEAR);
  state->Pop();

  last_frame_end_ = std::chrono::steady_clock::now();
  last_frame_ms_ = std::chrono::duration<double, std::milli>(last_frame_end_ - t0).count();
  ++frames_;
  in_paint_ = false;
  emit frameRendered();
}

vtkOpenGLState* VtkView::renderVtk() {
  vtkOpenGLState* state = render_window_->GetState();
  state->Reset();
  state->Push();
  state->vtkglDepthFunc(GL_LEQUAL);  // VTK expects GL_LEQUAL
  render_window_->Render();  // into VTK's own render framebuffer (no copy to its display one)
  return state;
}

bool VtkView::readyToRender() {
  return !in_paint_ && surface_ != nullptr && surface_->isExposed() && prepareContext();
}

bool VtkView::renderNow() {
  if (!readyToRender()) return false;
  renderFrame();
  const auto t0 = std::chrono::steady_clock::now();
  context_->swapBuffers(surface_);
  last_swap_ms_ = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  return true;
}

bool VtkView::renderUnseen() {
  if (!readyToRender()) return false;
  in_paint_ = true;  // VTK's end-of-frame event asks for no frame to show this one
  renderVtk()->Pop();
  in_paint_ = false;
  return true;
}

QImage VtkView::grabFrame() {
  if (in_paint_ || !prepareContext()) return {};
  renderFrame();
  const QSize pixels = surfacePixels();
  const int w = pixels.width(), h = pixels.height();
  if (w <= 0 || h <= 0) return {};
  QOpenGLExtraFunctions* f = context_->extraFunctions();
  f->glBindFramebuffer(GL_READ_FRAMEBUFFER, context_->defaultFramebufferObject());
  f->glReadBuffer(GL_BACK);
  f->glPixelStorei(GL_PACK_ALIGNMENT, 4);
  QImage image(w, h, QImage::Format_RGBX8888);
  f->glReadPixels(0, 0, w, h, GL_RGBA, GL_UNSIGNED_BYTE, image.bits());
  context_->swapBuffers(surface_);  // and show it
  QImage top_down = image.mirrored();  // GL's rows run bottom-up
  top_down.setDevicePixelRatio(surface_->devicePixelRatio());
  return top_down;
}

QImage grabWithView(QWidget& window, VtkView& view) {
  QImage shot = window.grab().toImage();
  const QImage frame = view.grabFrame();
  if (frame.isNull() || shot.isNull()) return shot;
  const QPoint at = view.mapTo(&window, QPoint(0, 0));
  QPainter painter(&shot);
  painter.drawImage(QPointF(at), frame);  // both in device-independent coordinates of `window`
  return shot;
}

void VtkView::onRenderWindowEvent(vtkObject* /*caller*/, unsigned long event_id, void* call_data) {
  QOpenGLContext* ctx = context();
  switch (event_id) {
    case vtkCommand::WindowMakeCurrentEvent:
      // The view's context on its window, when another one is current (VTK releasing GL
      // objects outside a frame); a view never shown has none, and VTK then renders nothing.
      if (ctx != nullptr && QOpenGLContext::currentContext() != ctx) {
        makeCurrent();
      }
      break;
    case vtkCommand::WindowIsCurrentEvent:
      if (call_data != nullptr) {
        *static_cast<bool*>(call_data) = ctx != nullptr && QOpenGLContext::currentContext() == ctx;
      }
      break;
    case vtkCommand::WindowFrameEvent:
      // VTK finished a frame; when it rendered outside renderFrame() the window must show one.
      if (!in_paint_) {
        requestRender();
      }
      break;
    default:
      break;
  }
}

void VtkView::onInteractorRender(vtkObject* /*caller*/, unsigned long /*event_id*/,
                                 void* /*call_data*/) {
  requestRender();
}

void VtkView::onStyleInteraction(vtkObject* /*caller*/, unsigned long event_id,
                                 void* /*call_data*/) {
  if (event_id == vtkCommand::StartInteractionEvent) {
    emit interactionStarted();
  } else {
    emit interactionEnded();
  }
}

void VtkView::forwardMouse(QMouseEvent* event, unsigned long vtk_event, bool repeat) {
  const qreal dpr = devicePixelRatioF();
  const QPointF p = event->position();
  const auto mods = event->modifiers();
  interactor_->SetEventInformationFlipY(static_cast<int>(p.x() * dpr), static_cast<int>(p.y() * dpr),
                                        (mods & Qt::ControlModifier) ? 1 : 0,
                                        (mods & Qt::ShiftModifier) ? 1 : 0, 0, repeat ? 1 : 0);
  interactor_->SetAltKey((mods & Qt::AltModifier) ? 1 : 0);
  interactor_->InvokeEvent(vtk_event, event);
}

namespace {
unsigned long pressEventFor(Qt::MouseButton button) {
  switch (button) {
    case Qt::LeftButton: return vtkCommand::LeftButtonPressEvent;
    case Qt::MiddleButton: return vtkCommand::MiddleButtonPressEvent;
    case Qt::RightButton: return vtkCommand::RightButtonPressEvent;
    default: return vtkCommand::NoEvent;
  }
}
unsigned long releaseEventFor(Qt::MouseButton button) {
  switch (button) {
    case Qt::LeftButton: return vtkCommand::LeftButtonReleaseEvent;
    case Qt::MiddleButton: return vtkCommand::MiddleButtonReleaseEvent;
    case Qt::RightButton: return vtkCommand::RightButtonReleaseEvent;
    default: return vtkCommand::NoEvent;
  }
}
}  // namespace

void VtkView::mousePressEvent(QMouseEvent* event) {
  const unsigned long id = pressEventFor(event->button());
  if (id != vtkCommand::NoEvent) {
    forwardMouse(event, id, false);
  }
  event->accept();
}

void VtkView::mouseDoubleClickEvent(QMouseEvent* event) {
  const unsigned long id = pressEventFor(event->button());
  if (id != vtkCommand::NoEvent) {
    forwardMouse(event, id, true);
  }
  event->accept();
}

void VtkView::mouseReleaseEvent(QMouseEvent* event) {
  const unsigned long id = releaseEventFor(event->button());
  if (id != vtkCommand::NoEvent) {
    forwardMouse(event, id, false);
  }
  event->accept();
}

void VtkView::mouseMoveEvent(QMouseEvent* event) {
  forwardMouse(event, vtkCommand::MouseMoveEvent, false);
  event->accept();
}

void VtkView::wheelEvent(QWheelEvent* event) {
  const qreal dpr = devicePixelRatioF();
  const QPointF p = event->position();
  const auto mods = event->modifiers();
  interactor_->SetEventInformationFlipY(static_cast<int>(p.x() * dpr), static_cast<int>(p.y() * dpr),
                                        (mods & Qt::ControlModifier) ? 1 : 0,
                                        (mods & Qt::ShiftModifier) ? 1 : 0);
  const int delta = event->angleDelta().y();
  if (delta > 0) {
    interactor_->InvokeEvent(vtkCommand::MouseWheelForwardEvent, event);
  } else if (delta < 0) {
    interactor_->InvokeEvent(vtkCommand::MouseWheelBackwardEvent, event);
  }
  event->accept();
}

void VtkView::enterEvent(QEnterEvent* event) {
  interactor_->InvokeEvent(vtkCommand::EnterEvent, event);
  QWidget::enterEvent(event);
}

void VtkView::leaveEvent(QEvent* event) {
  interactor_->InvokeEvent(vtkCommand::LeaveEvent, event);
  QWidget::leaveEvent(event);
}

}  // namespace vh::ui
