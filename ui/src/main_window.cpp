#include "vh/ui/main_window.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>

#include <QCloseEvent>
#include <QDoubleSpinBox>
#include <QHBoxLayout>
#include <QLabel>
#include <QMouseEvent>
#include <QPushButton>
#include <QSignalBlocker>
#include <QSlider>
#include <QStatusBar>
#include <QTimer>
#include <QVBoxLayout>
#include <QWheelEvent>

#include <vtkActor.h>
#include <vtkCamera.h>
#include <vtkImageData.h>
#include <vtkRenderer.h>
#include <vtkVolume.h>

#include "vh/runtime/device.h"
#include "vh/runtime/placement.h"
#include "vh/ui/device_manipulation.h"
#include "vh/ui/scene_actors.h"
#include "vh/ui/vtk_view.h"

namespace vh::ui {
namespace {

constexpr int kSliderSteps = 1000;
constexpr int kDisplayPeriodMs = 33;     // ~30 Hz prop updates
constexpr int kStatusEveryTicks = 6;     // status text at ~5 Hz (readable)
constexpr int kSettleMs = 300;           // still frame this long after the last motion

const char* kHintDevice =
    "Camera: left drag rotate | middle drag pan | right drag / wheel zoom\n"
    "Device: Ctrl+left drag move in view plane | Ctrl+wheel or Ctrl+right drag move in depth\n"
    "        Shift+left drag rotate about the tool's centre";
const char* kHintCamera = "Camera: left drag rotate | middle drag pan | right drag / wheel zoom";

bool posesDiffer(const haptics::Pose& a, const haptics::Pose& b) {
  if ((a.p_AB_m - b.p_AB_m).norm() > 1e-5) {  // 10 um
    return true;
  }
  return a.R_AB.angularDistance(b.R_AB) > 1e-4;  // rad
}

int decimalsFor(double range) {
  if (range >= 100.0) return 0;
  if (range >= 1.0) return 2;
  return 4;
}

}  // namespace

MainWindow::MainWindow(ViewerScene scene, QWidget* parent)
    : QMainWindow(parent), scene_(std::move(scene)) {
  if (scene_.volume.image == nullptr) {
    throw std::invalid_argument("MainWindow: the scene's volume has no image to render");
  }
  if (scene_.volume.field != nullptr) {
    value_min_ = scene_.volume.field->minValue();
    value_max_ = scene_.volume.field->maxValue();
  } else if (scene_.volume.image != nullptr) {
    double range[2];
    scene_.volume.image->GetScalarRange(range);
    value_min_ = range[0];
    value_max_ = range[1];
  }
  if (!(value_max_ > value_min_)) {
    value_max_ = value_min_ + 1.0;
  }
  isovalue_ = std::clamp(scene_.isovalue, value_min_, value_max_);

  view_ = new VtkView(this);

  SceneActorsSpec spec;
  spec.image = scene_.volume.image;
  if (scene_.volume.field != nullptr) {
    spec.direction_W = scene_.volume.field->geometry().direction_W;
  }
  spec.isovalue = isovalue_;
  if (scene_.tool != nullptr) {
    spec.tool_mesh_T = scene_.tool->mesh_T;
    spec.p_TCm_m = scene_.tool->mass.p_TCm_m;
  }
  spec.show_device = scene_.device != nullptr && scene_.haptics != nullptr;
  if (simulatedDevice() != nullptr) {
    spec.hint = kHintDevice;
  } else if (scene_.device != nullptr) {
    spec.hint = std::string(kHintCamera) + "\nDevice: " + scene_.device->name();
  } else {
    spec.hint = std::string(kHintCamera) + "\nNo device in this scene: haptics off";
  }
  actors_ = std::make_unique<SceneActors>(view_->renderer(), spec);
  actors_->setProxyPose(scene_.X_WT_initial);
  actors_->setDevicePose(scene_.X_WT_initial);
  shown_X_WP_ = scene_.X_WT_initial;
  shown_X_WD_ = scene_.X_WT_initial;

  vtkRenderer* renderer = view_->renderer();
  renderer->GradientBackgroundOn();
  renderer->SetBackground(0.06, 0.07, 0.09);
  renderer->SetBackground2(0.22, 0.25, 0.31);
  resetCamera();

  buildUi();
  view_->installEventFilter(this);

  display_timer_ = new QTimer(this);
  display_timer_->setInterval(kDisplayPeriodMs);
  connect(display_timer_, &QTimer::timeout, this, [this] { refreshFromHaptics(); });

  // Interactive (cheaper) frames while something moves, a full-quality one when it settles.
  settle_timer_ = new QTimer(this);
  settle_timer_->setSingleShot(true);
  settle_timer_->setInterval(kSettleMs);
  connect(settle_timer_, &QTimer::timeout, this, [this] {
    if (!camera_interacting_ && !slider_dragging_) {
      renderStill();
    }
  });
  connect(view_, &VtkView::interactionStarted, this, [this] {
    camera_interacting_ = true;
    noteMotion();
  });
  connect(view_, &VtkView::interactionEnded, this, [this] {
    camera_interacting_ = false;
    settle_timer_->start();
  });
  connect(view_, &VtkView::frameRendered, this, [this] {
    if (view_->frameCount() > 1) {  // the first frame also compiles shaders and uploads the volume
      actors_->adaptQuality(view_->lastFrameMs());
    }
  });
}

MainWindow::~MainWindow() {
  stopHaptics();
  // VTK props release their GL objects when they leave the renderer: give them the context.
  if (view_->context() != nullptr) {
    view_->makeCurrent();
    actors_.reset();
    view_->doneCurrent();
  }
  actors_.reset();
}

void MainWindow::buildUi() {
  const std::string& unit = scene_.volume.info.value_unit;

  auto* central = new QWidget(this);
  auto* layout = new QVBoxLayout(central);
  layout->setContentsMargins(4, 4, 4, 4);
  layout->setSpacing(4);

  auto* controls = new QHBoxLayout();
  auto* iso_label = new QLabel(
      QString::fromStdString(unit.empty() ? "Isovalue" : "Isovalue [" + unit + "]"), central);
  slider_ = new QSlider(Qt::Horizontal, central);
  slider_->setObjectName("isovalueSlider");
  slider_->setRange(0, kSliderSteps);
  slider_->setValue(valueToSlider(isovalue_));
  slider_->setMinimumWidth(240);
  slider_->setToolTip("Isosurface value: rendering and haptics follow it live");
  spin_ = new QDoubleSpinBox(central);
  spin_->setObjectName("isovalueSpinBox");
  const double range = value_max_ - value_min_;
  spin_->setDecimals(decimalsFor(range));
  spin_->setRange(value_min_, value_max_);
  spin_->setSingleStep(range >= 100.0 ? std::max(1.0, std::round(range / 200.0)) : range / 200.0);
  spin_->setKeyboardTracking(false);
  spin_->setValue(isovalue_);
  spin_->setMinimumWidth(90);
  auto* reset_camera = new QPushButton("Reset camera", central);
  controls->addWidget(iso_label);
  controls->addWidget(slider_, 1);
  controls->addWidget(spin_);
  controls->addSpacing(12);
  if (simulatedDevice() != nullptr) {
    auto* reset_device = new QPushButton("Reset device", central);
    reset_device->setToolTip("Moves the simulated device back to the scene's initial pose");
    connect(reset_device, &QPushButton::clicked, this,
            [this] { setDevicePose(scene_.X_WT_initial); });
    controls->addWidget(reset_device);
  }
  controls->addWidget(reset_camera);
  layout->addLayout(controls);
  layout->addWidget(view_, 1);
  setCentralWidget(central);

  connect(slider_, &QSlider::valueChanged, this, &MainWindow::onSliderMoved);
  connect(slider_, &QSlider::sliderPressed, this, [this] {
    slider_dragging_ = true;
    noteMotion();
  });
  connect(slider_, &QSlider::sliderReleased, this, [this] {
    slider_dragging_ = false;
    settle_timer_->start();
  });
  connect(spin_, &QDoubleSpinBox::valueChanged, this, &MainWindow::onSpinChanged);
  connect(reset_camera, &QPushButton::clicked, this, [this] {
    resetCamera();
    view_->requestRender();
  });

  status_label_ = new QLabel(this);
  status_label_->setObjectName("hapticStatus");
  status_label_->setTextInteractionFlags(Qt::TextSelectableByMouse);
  statusBar()->addWidget(status_label_, 1);
  const io::VolumeInfo& info = scene_.volume.info;
  QString volume_text;
  if (scene_.volume.field != nullptr) {
    const auto& g = scene_.volume.field->geometry();
    const double lo_mm = g.spacing_m.minCoeff() * 1e3;
    const double hi_mm = g.spacing_m.maxCoeff() * 1e3;
    const QString spacing = hi_mm > lo_mm * 1.001
                                ? QString("%1..%2 mm").arg(lo_mm, 0, 'g', 3).arg(hi_mm, 0, 'g', 3)
                                : QString("%1 mm").arg(lo_mm, 0, 'g', 3);
    volume_text = QString("%1 %2  %3x%4x%5  %6")
                      .arg(QString::fromStdString(info.format), QString::fromStdString(info.modality))
                      .arg(g.dims[0])
                      .arg(g.dims[1])
                      .arg(g.dims[2])
                      .arg(spacing);
  }
  // The volume's facts go to the title, so the status bar keeps its width for the statistics.
  QString title = "VolumeHaptics";
  if (!scene_.title.empty()) {
    title += " - " + QString::fromStdString(scene_.title);
  }
  if (!volume_text.simplified().isEmpty()) {
    title += " (" + volume_text.simplified() + ")";
  }
  setWindowTitle(title);
  updateStatus();
}

runtime::SimulatedDevice* MainWindow::simulatedDevice() const noexcept {
  return dynamic_cast<runtime::SimulatedDevice*>(scene_.device.get());
}

vtkVolume* MainWindow::volumeProp() const noexcept { return actors_->volume(); }
vtkActor* MainWindow::proxyActor() const noexcept { return actors_->proxyActor(); }
vtkActor* MainWindow::deviceActor() const noexcept { return actors_->deviceActor(); }

void MainWindow::startHaptics() {
  if (scene_.haptics != nullptr && !scene_.haptics->running()) {
    scene_.haptics->setIsovalue(isovalue_);
    scene_.haptics->start();
  }
  display_timer_->start();
}

void MainWindow::stopHaptics() {
  if (display_timer_ != nullptr) {
    display_timer_->stop();
  }
  if (scene_.haptics != nullptr && scene_.haptics->running()) {
    scene_.haptics->stop();
  }
}

double MainWindow::sliderToValue(int position) const {
  return value_min_ + (value_max_ - value_min_) * static_cast<double>(position) / kSliderSteps;
}

int MainWindow::valueToSlider(double value) const {
  const double t = (value - value_min_) / (value_max_ - value_min_);
  return static_cast<int>(std::lround(std::clamp(t, 0.0, 1.0) * kSliderSteps));
}

void MainWindow::onSliderMoved(int position) { setIsovalue(sliderToValue(position)); }
void MainWindow::onSpinChanged(double value) { setIsovalue(value); }

void MainWindow::setIsovalue(double isovalue) {
  if (!std::isfinite(isovalue)) {
    return;
  }
  isovalue_ = std::clamp(isovalue, value_min_, value_max_);
  {
    const QSignalBlocker block_slider(slider_);
    const QSignalBlocker block_spin(spin_);
    slider_->setValue(valueToSlider(isovalue_));
    spin_->setValue(isovalue_);
  }
  actors_->setIsovalue(isovalue_);
  if (scene_.haptics != nullptr) {
    scene_.haptics->setIsovalue(isovalue_);
  }
  view_->requestRender();
}

void MainWindow::setDevicePose(const haptics::Pose& X_WD) {
  runtime::SimulatedDevice* device = simulatedDevice();
  if (device == nullptr || !X_WD.allFinite()) {
    return;
  }
  device->setPose(X_WD);
  // Show the target at once; the proxy follows with the next snapshot.
  actors_->setDevicePose(X_WD);
  shown_X_WD_ = X_WD;
  noteMotion();
  view_->requestRender();
}

bool MainWindow::touchSurface(double depth_m) {
  runtime::SimulatedDevice* device = simulatedDevice();
  if (device == nullptr || scene_.tool == nullptr || scene_.volume.field == nullptr) {
    return false;
  }
  const haptics::ScalarVolume& field = *scene_.volume.field;
  const haptics::PointShell& shell = scene_.tool->point_shell;
  const haptics::Pose X_WD = device->pose();
  const Eigen::Vector3d c_W = X_WD * scene_.tool->mass.p_TCm_m;
  const Eigen::Vector3d lo = field.boundsMin_W_m();
  const Eigen::Vector3d hi = field.boundsMax_W_m();
  const Eigen::Vector3d centre_W = 0.5 * (lo + hi);
  const double extent_m = (hi - lo).norm();
  Eigen::Vector3d dir_W = centre_W - c_W;
  if (dir_W.norm() < 1e-9) {
    dir_W = -Eigen::Vector3d::UnitZ();
  }
  dir_W.normalize();
  const double max_travel_m = (c_W - centre_W).norm() + extent_m;
  // Straight towards the centre first; where that ray slips through a hole in the surface, start
  // from points around it on rings perpendicular to the ray (up to 30% of the volume's size).
  const Eigen::Vector3d e1 = dir_W.unitOrthogonal();
  const Eigen::Vector3d e2 = dir_W.cross(e1);
  for (const double ring : {0.0, 0.05, 0.1, 0.2, 0.3}) {
    const int n = ring == 0.0 ? 1 : 8;
    for (int k = 0; k < n; ++k) {
      const double a = 2.0 * std::numbers::pi * k / n;
      haptics::Pose start = X_WD;
      start.p_AB_m += ring * extent_m * (std::cos(a) * e1 + std::sin(a) * e2);
      if (runtime::countPointsInside(field, shell, start, isovalue_) > 0) {
        continue;
      }
      const std::optional<double> free_m = runtime::firstContactDistance(
          field, shell, start, dir_W, max_travel_m, isovalue_, 0.05 * field.featureSize_m());
      if (!free_m) {
        continue;
      }
      haptics::Pose target = start;
      target.p_AB_m += (*free_m + std::max(0.0, depth_m)) * dir_W;
      if (ring == 0.0) {
        setDevicePose(target);
      } else {
        // Sideways through free space first, so the proxy follows the device, then in.
        setDevicePose(start);
        QTimer::singleShot(300, this, [this, target] { setDevicePose(target); });
      }
      return true;
    }
  }
  return false;
}

ViewCamera MainWindow::currentCamera() const {
  vtkCamera* cam = view_->renderer()->GetActiveCamera();
  ViewCamera c;
  double v[3];
  cam->GetPosition(v);
  c.position_W_m = Eigen::Vector3d(v[0], v[1], v[2]);
  cam->GetFocalPoint(v);
  c.focal_point_W_m = Eigen::Vector3d(v[0], v[1], v[2]);
  cam->GetViewUp(v);
  c.view_up_W = Eigen::Vector3d(v[0], v[1], v[2]);
  c.view_angle_deg = cam->GetViewAngle();
  c.parallel = cam->GetParallelProjection() != 0;
  c.parallel_scale_m = cam->GetParallelScale();
  const int* size = view_->renderer()->GetSize();
  c.viewport_height_px = std::max(1, size[1] > 0 ? size[1] : view_->height());
  return c;
}

double MainWindow::wheelStep_m() const {
  if (scene_.volume.field == nullptr) {
    return 1e-3;
  }
  const double diagonal =
      (scene_.volume.field->boundsMax_W_m() - scene_.volume.field->boundsMin_W_m()).norm();
  return std::clamp(diagonal / 200.0, 0.5e-3, 5e-3);
}

bool MainWindow::eventFilter(QObject* watched, QEvent* event) {
  runtime::SimulatedDevice* device = simulatedDevice();
  if (watched != view_ || device == nullptr) {
    return QMainWindow::eventFilter(watched, event);
  }
  const Eigen::Vector3d p_DCm = scene_.tool != nullptr ? scene_.tool->mass.p_TCm_m
                                                       : Eigen::Vector3d::Zero();
  switch (event->type()) {
    case QEvent::MouseButtonPress: {
      auto* e = static_cast<QMouseEvent*>(event);
      const bool ctrl = e->modifiers() & Qt::ControlModifier;
      const bool shift = e->modifiers() & Qt::ShiftModifier;
      if (ctrl && e->button() == Qt::LeftButton) {
        drag_ = DragMode::kTranslate;
      } else if (ctrl && e->button() == Qt::RightButton) {
        drag_ = DragMode::kDepth;
      } else if (shift && !ctrl && e->button() == Qt::LeftButton) {
        drag_ = DragMode::kRotate;
      } else {
        return false;  // the camera's
      }
      drag_last_ = e->position();
      view_->setCursor(drag_ == DragMode::kRotate ? Qt::ClosedHandCursor : Qt::SizeAllCursor);
      return true;
    }
    case QEvent::MouseMove: {
      if (drag_ == DragMode::kNone) {
        return false;
      }
      auto* e = static_cast<QMouseEvent*>(event);
      const QPointF delta = (e->position() - drag_last_) * view_->devicePixelRatioF();
      drag_last_ = e->position();
      const ViewCamera camera = currentCamera();
      const haptics::Pose X_WD = device->pose();
      switch (drag_) {
        case DragMode::kTranslate:
          setDevicePose(dragInViewPlane(X_WD, camera, X_WD * p_DCm, delta.x(), delta.y()));
          break;
        case DragMode::kDepth:
          setDevicePose(moveAlongView(X_WD, camera,
                                      -delta.y() * camera.metresPerPixelAt(X_WD * p_DCm)));
          break;
        case DragMode::kRotate:
          setDevicePose(rotateTrackball(X_WD, camera, p_DCm, delta.x(), delta.y(),
                                        std::numbers::pi / camera.viewport_height_px));
          break;
        case DragMode::kNone:
          break;
      }
      return true;
    }
    case QEvent::MouseButtonRelease: {
      if (drag_ == DragMode::kNone) {
        return false;
      }
      drag_ = DragMode::kNone;
      view_->unsetCursor();
      return true;
    }
    case QEvent::MouseButtonDblClick:
      return drag_ != DragMode::kNone;
    case QEvent::Wheel: {
      auto* e = static_cast<QWheelEvent*>(event);
      if (!(e->modifiers() & Qt::ControlModifier)) {
        return false;
      }
      const double notches = e->angleDelta().y() / 120.0;
      setDevicePose(moveAlongView(device->pose(), currentCamera(), notches * wheelStep_m()));
      return true;
    }
    default:
      return false;
  }
}

bool MainWindow::refreshFromHaptics(bool update_status_now) {
  if (scene_.haptics == nullptr) {
    return false;
  }
  scene_.haptics->latestSnapshot(snapshot_);
  if (snapshot_.tick == 0) {
    return false;  // nothing published yet
  }
  have_snapshot_ = true;
  bool changed = posesDiffer(snapshot_.X_WP, shown_X_WP_) ||
                 posesDiffer(snapshot_.X_WD, shown_X_WD_) || snapshot_.contacts != shown_contacts_ ||
                 (snapshot_.force_W_N - shown_force_W_N_).norm() > 0.01;
  if (changed) {
    shown_X_WP_ = snapshot_.X_WP;
    shown_X_WD_ = snapshot_.X_WD;
    shown_contacts_ = snapshot_.contacts;
    shown_force_W_N_ = snapshot_.force_W_N;
    actors_->setProxyPose(snapshot_.X_WP);
    actors_->setDevicePose(snapshot_.X_WD);
    const int n = std::clamp(snapshot_.contacts_shown, 0, runtime::HapticSnapshot::kMaxContactsShown);
    actors_->setContacts(std::span<const Eigen::Vector3d>(snapshot_.contact_p_W_m.data(),
                                                          static_cast<std::size_t>(n)));
    // The force arrow starts at the contacts' centroid (or the proxy's centre of mass).
    Eigen::Vector3d origin_W = Eigen::Vector3d::Zero();
    if (n > 0) {
      for (int i = 0; i < n; ++i) {
        origin_W += snapshot_.contact_p_W_m[static_cast<std::size_t>(i)];
      }
      origin_W /= n;
    } else {
      origin_W = snapshot_.X_WP * (scene_.tool != nullptr ? scene_.tool->mass.p_TCm_m
                                                         : Eigen::Vector3d::Zero());
    }
    actors_->setForce(origin_W, snapshot_.force_W_N);
    noteMotion();
    view_->requestRender();
  }
  if (--status_countdown_ <= 0 || update_status_now) {
    status_countdown_ = kStatusEveryTicks;
    updateStatus();
  }
  return changed;
}

void MainWindow::noteMotion() {
  actors_->setInteractive(true);
  settle_timer_->start();  // restarts: the still frame comes kSettleMs after the last motion
}

void MainWindow::renderStill(bool best_quality) {
  settle_timer_->stop();
  if (actors_->interactive() || best_quality) {
    actors_->setInteractive(false);
    if (best_quality) {
      actors_->resetQuality();
    }
    view_->requestRender();
  }
}

void MainWindow::updateStatus() {
  if (status_label_ == nullptr) {
    return;
  }
  if (scene_.haptics == nullptr) {
    status_label_->setText("Haptics off: the scene has no device");
    return;
  }
  if (!have_snapshot_) {
    status_label_->setText("Haptic thread starting...");
    return;
  }
  const runtime::HapticSnapshot& s = snapshot_;
  status_label_->setText(
      QString::fromUtf8("Servo %1 Hz  |  tick %2 / %3 us (mean / max)  |  contacts %4  |  "
                        "|F| %5 N  |  |\u03c4| %6 N\u00b7m  |  misses %7")
          .arg(s.servo_rate_Hz, 0, 'f', 0)
          .arg(s.mean_tick_us, 0, 'f', 1)
          .arg(s.max_tick_us, 0, 'f', 1)
          .arg(s.contacts)
          .arg(s.force_W_N.norm(), 0, 'f', 2)
          .arg(s.torque_W_Nm.norm(), 0, 'f', 4)
          .arg(static_cast<qulonglong>(s.deadline_misses)));
}

QString MainWindow::statusText() const {
  return status_label_ != nullptr ? status_label_->text() : QString();
}

void MainWindow::resetCamera() {
  vtkRenderer* renderer = view_->renderer();
  vtkCamera* cam = renderer->GetActiveCamera();
  // Default view: from -y (anterior for LPS/RAS patient frames) and above, +z up, turned a
  // little for depth cues.
  double bounds[6];
  actors_->volume()->GetBounds(bounds);
  const Eigen::Vector3d centre(0.5 * (bounds[0] + bounds[1]), 0.5 * (bounds[2] + bounds[3]),
                               0.5 * (bounds[4] + bounds[5]));
  cam->SetFocalPoint(centre.x(), centre.y(), centre.z());
  cam->SetPosition(centre.x(), centre.y() - 1.0, centre.z());
  cam->SetViewUp(0.0, 0.0, 1.0);
  cam->Azimuth(-30.0);
  cam->Elevation(25.0);
  cam->OrthogonalizeViewUp();
  renderer->ResetCamera();  // fits the visible props (volume and tools)
  cam->Zoom(1.2);  // the fit is to the props' bounding sphere: generous
  renderer->ResetCameraClippingRange();
}

void MainWindow::closeEvent(QCloseEvent* event) {
  stopHaptics();  // force ramped to zero before anything else goes away
  QMainWindow::closeEvent(event);
}

}  // namespace vh::ui
