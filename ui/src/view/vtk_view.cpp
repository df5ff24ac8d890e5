/// @file
/// The Qt6 <-> VTK bridge (see vtk_view.h and ../shared/docs/qt6-vtk-embedding.md).
/// Raw GL calls go through QOpenGLExtraFunctions; this file must never include vtk_glew.h.

#include "vh/ui/view/vtk_view.h"

#include <chrono>

#include <QEnterEvent>
#include <QMouseEvent>
#include <QOpenGLContext>
#include <QOpenGLExtraFunctions>
#include <QWheelEvent>

#include <vtkCommand.h>
#include <vtkGenericOpenGLRenderWindow.h>
#include <vtkGenericRenderWindowInteractor.h>
#include <vtkInteractorStyleTrackballCamera.h>
#include <vtkOpenGLFramebufferObject.h>
#include <vtkOpenGLState.h>
#include <vtkRenderer.h>

namespace vh::ui {

VtkView::VtkView(QWidget* parent) : QOpenGLWidget(parent) {
  setFocusPolicy(Qt::StrongFocus);
  setMouseTracking(false);
  setMinimumSize(160, 120);

  // VTK renders into its own framebuffer in Qt's context; paintGL() blits it.
  render_window_->SetOwnContext(false);
  render_window_->SetFrameBlitModeToNoBlit();
  render_window_->SetReadyForRendering(false);  // until initializeGL()
  render_window_->SetMultiSamples(0);
  render_window_->SetForceMaximumHardwareLineWidth(1);
  render_window_->AddRenderer(renderer_);

  interactor_->SetRenderWindow(render_window_);
  interactor_->SetInteractorStyle(style_);
  interactor_->EnableRenderOff();  // its render requests become update() (RenderEvent below)
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
  // Release GL resources while the context still exists, then detach the observers: the render
  // window may outlive this widget when someone else holds a reference to it.
  if (context() != nullptr) {
    // ~QOpenGLWidget destroys the context later and would call back into this half-destroyed
    // object: disconnect first.
    disconnect(context(), nullptr, this, nullptr);
    makeCurrent();
    releaseGraphics();
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

void VtkView::requestRender() { update(); }

QImage VtkView::grabFrame() {
  // grabFramebuffer() calls paintGL() into a fresh framebuffer and reads it back.
  return grabFramebuffer();
}

void VtkView::initializeGL() {
  // A new context (first show, or after re-parenting): VTK must know it.
  connect(context(), &QOpenGLContext::aboutToBeDestroyed, this,
          &VtkView::onContextAboutToBeDestroyed, Qt::UniqueConnection);
  render_window_->SetReadyForRendering(true);
  render_window_->OpenGLInitContext();
  const qreal dpr = devicePixelRatioF();
  interactor_->UpdateSize(static_cast<int>(width() * dpr), static_cast<int>(height() * dpr));
}

void VtkView::onContextAboutToBeDestroyed() {
  // Re-parenting (or destruction) replaces the context: free VTK's GL objects in the old one,
  // or the view stays blank afterwards.
  makeCurrent();
  releaseGraphics();
  doneCurrent();
}

void VtkView::releaseGraphics() {
  render_window_->Finalize();
  render_window_->SetReadyForRendering(false);
}

void VtkView::resizeGL(int w, int h) {
  const qreal dpr = devicePixelRatioF();
  interactor_->UpdateSize(static_cast<int>(w * dpr), static_cast<int>(h * dpr));
}

void VtkView::paintGL() {
  if (in_paint_) {
    return;
  }
  in_paint_ = true;
  const auto t0 = std::chrono::steady_clock::now();

  vtkOpenGLState* state = render_window_->GetState();
  state->Reset();
  state->Push();
  state->vtkglDepthFunc(GL_LEQUAL);  // Qt leaves GL_LESS; VTK expects GL_LEQUAL

  render_window_->Render();  // into VTK's own render framebuffer, copied to its display one

  // Blit VTK's display framebuffer into the widget's framebuffer.
  QOpenGLExtraFunctions* f = context()->extraFunctions();
  f->glBindFramebuffer(GL_DRAW_FRAMEBUFFER, defaultFramebufferObject());
  const GLenum draw_buffer = GL_COLOR_ATTACHMENT0;
  f->glDrawBuffers(1, &draw_buffer);
  state->vtkglDisable(GL_SCISSOR_TEST);
  f->glDisable(GL_SCISSOR_TEST);

  const qreal dpr = devicePixelRatioF();
  const int w = static_cast<int>(width() * dpr);
  const int h = static_cast<int>(height() * dpr);
  const int* source_size = render_window_->GetRenderFramebuffer()->GetLastSize();
  render_window_->BlitDisplayFramebuffer(0, 0, 0, source_size[0], source_size[1], 0, 0, w, h,
                                         GL_COLOR_BUFFER_BIT, GL_LINEAR);

  // Alpha 1 everywhere, or the compositor blends the view with what lies behind (Mesa).
  f->glColorMask(GL_FALSE, GL_FALSE, GL_FALSE, GL_TRUE);
  f->glClearColor(0.0f, 0.0f, 0.0f, 1.0f);
  f->glViewport(0, 0, w, h);
  f->glClear(GL_COLOR_BUFFER_BIT);
  f->glColorMask(GL_TRUE, GL_TRUE, GL_TRUE, GL_TRUE);

  state->Pop();

  last_frame_ms_ =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  ++frames_;
  in_paint_ = false;
  emit frameRendered();
}

void VtkView::onRenderWindowEvent(vtkObject* /*caller*/, unsigned long event_id, void* call_data) {
  QOpenGLContext* ctx = context();
  switch (event_id) {
    case vtkCommand::WindowMakeCurrentEvent:
      // Only the context: QOpenGLWidget::makeCurrent() would rebind Qt's framebuffer in the
      // middle of VTK's render and every frame would come out black.
      if (ctx != nullptr && QOpenGLContext::currentContext() != ctx) {
        ctx->makeCurrent(ctx->surface());
      }
      break;
    case vtkCommand::WindowIsCurrentEvent:
      if (call_data != nullptr) {
        *static_cast<bool*>(call_data) = ctx != nullptr && QOpenGLContext::currentContext() == ctx;
      }
      break;
    case vtkCommand::WindowFrameEvent:
      // VTK finished a frame; when it rendered outside paintGL() the widget must repaint.
      if (!in_paint_) {
        update();
      }
      break;
    default:
      break;
  }
}

void VtkView::onInteractorRender(vtkObject* /*caller*/, unsigned long /*event_id*/,
                                 void* /*call_data*/) {
  update();
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
  QOpenGLWidget::enterEvent(event);
}

void VtkView::leaveEvent(QEvent* event) {
  interactor_->InvokeEvent(vtkCommand::LeaveEvent, event);
  QOpenGLWidget::leaveEvent(event);
}

}  // namespace vh::ui
