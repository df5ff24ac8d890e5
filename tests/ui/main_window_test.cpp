// The main window on the small CT head (64 x 64 x 93): rendering, the isovalue slider driving
// both the picture and the haptic thread, the tool actors, the mouse-driven device and a touch.
#include "vh/ui/main_window.h"

#include <chrono>
#include <cmath>
#include <filesystem>
#include <functional>
#include <memory>
#include <thread>

#include <QApplication>
#include <QDoubleSpinBox>
#include <QImage>
#include <QMouseEvent>
#include <QSlider>

#include <gtest/gtest.h>
#include <vtkActor.h>
#include <vtkCamera.h>
#include <vtkImageData.h>
#include <vtkMapper.h>
#include <vtkMatrix4x4.h>
#include <vtkPolyData.h>
#include <vtkRenderer.h>

#include "vh/runtime/device.h"
#include "vh/runtime/scene.h"
#include "vh/ui/device_manipulation.h"
#include "vh/ui/scene_actors.h"
#include "vh/ui/vtk_view.h"

namespace vh::ui {
namespace {

const std::filesystem::path kHead = std::filesystem::path(VH_SHARED_DATASETS_DIR) / "ct/ct-head-small";

/// Processes events until `done` or the timeout; @return done().
bool waitFor(const std::function<bool()>& done, int timeout_ms) {
  const auto end = std::chrono::steady_clock::now() + std::chrono::milliseconds(timeout_ms);
  while (!done()) {
    if (std::chrono::steady_clock::now() > end) {
      return false;
    }
    QApplication::processEvents(QEventLoop::AllEvents, 10);
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  return true;
}

/// Fraction of pixels whose colour differs by more than `threshold` in some channel.
double differingFraction(const QImage& a, const QImage& b, int threshold = 24) {
  if (a.size() != b.size() || a.isNull()) {
    return 1.0;
  }
  const QImage ra = a.convertToFormat(QImage::Format_RGB32);
  const QImage rb = b.convertToFormat(QImage::Format_RGB32);
  std::size_t differing = 0;
  for (int y = 0; y < ra.height(); ++y) {
    const auto* pa = reinterpret_cast<const QRgb*>(ra.constScanLine(y));
    const auto* pb = reinterpret_cast<const QRgb*>(rb.constScanLine(y));
    for (int x = 0; x < ra.width(); ++x) {
      if (std::abs(qRed(pa[x]) - qRed(pb[x])) > threshold ||
          std::abs(qGreen(pa[x]) - qGreen(pb[x])) > threshold ||
          std::abs(qBlue(pa[x]) - qBlue(pb[x])) > threshold) {
        ++differing;
      }
    }
  }
  return static_cast<double>(differing) / (static_cast<double>(ra.width()) * ra.height());
}

/// Fraction of pixels brighter than the background gradient (grey level > 100).
double brightFraction(const QImage& image) {
  const QImage rgb = image.convertToFormat(QImage::Format_RGB32);
  std::size_t bright = 0;
  for (int y = 0; y < rgb.height(); ++y) {
    const auto* p = reinterpret_cast<const QRgb*>(rgb.constScanLine(y));
    for (int x = 0; x < rgb.width(); ++x) {
      bright += qGray(p[x]) > 100 ? 1 : 0;
    }
  }
  return static_cast<double>(bright) / (static_cast<double>(rgb.width()) * rgb.height());
}

Eigen::Vector3d translationOf(vtkActor* actor) {
  vtkMatrix4x4* m = actor->GetUserMatrix();
  return m == nullptr ? Eigen::Vector3d::Zero()
                      : Eigen::Vector3d(m->GetElement(0, 3), m->GetElement(1, 3), m->GetElement(2, 3));
}

class MainWindowTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    if (std::filesystem::exists(kHead)) {
      loaded_ = std::make_unique<runtime::LoadedScene>(
          runtime::loadScene(runtime::sceneForVolume(kHead)));
    }
  }
  static void TearDownTestSuite() { loaded_.reset(); }

  void SetUp() override {
    if (loaded_ == nullptr) {
      GTEST_SKIP() << "dataset absent: " << kHead << " (the small CT head of ../shared/datasets)";
    }
    ViewerScene scene;
    scene.volume = loaded_->volume;
    scene.tool = loaded_->tool;
    scene.isovalue = loaded_->isovalue;
    scene.X_WT_initial = loaded_->X_WT_initial;
    scene.device = loaded_->makeDevice();
    scene.haptics = loaded_->makeHapticThread(scene.device);
    scene.title = "ct-head-small";
    window_ = std::make_unique<MainWindow>(std::move(scene));
    window_->resize(640, 560);
    window_->show();
    ASSERT_TRUE(waitFor([this] { return window_->view()->frameCount() > 0; }, 20000))
        << "the view never rendered";
    window_->startHaptics();
  }

  void TearDown() override {
    if (window_ != nullptr) {
      window_->close();
      EXPECT_FALSE(window_->hapticThread() != nullptr && window_->hapticThread()->running())
          << "closing the window must stop the haptic thread";
      window_.reset();
    }
  }

  /// Sends a mouse event to the view.
  void mouse(QEvent::Type type, QPointF pos, Qt::MouseButton button, Qt::MouseButtons buttons,
             Qt::KeyboardModifiers modifiers) {
    QMouseEvent event(type, pos, window_->view()->mapToGlobal(pos), button, buttons, modifiers);
    QApplication::sendEvent(window_->view(), &event);
  }

  static std::unique_ptr<runtime::LoadedScene> loaded_;
  std::unique_ptr<MainWindow> window_;
};

std::unique_ptr<runtime::LoadedScene> MainWindowTest::loaded_;

TEST_F(MainWindowTest, IsovalueSliderChangesThePictureAndTheHapticIsovalue) {
  VtkView* view = window_->view();
  const QImage before = view->grabFrame();
  ASSERT_FALSE(before.isNull());
  EXPECT_GT(brightFraction(before), 0.03) << "the isosurface should cover part of the view";

  QSlider* slider = window_->isovalueSlider();
  const double old_isovalue = window_->isovalue();
  // Move to the other side of the range: the skin (low values) vs the bone (high values).
  const int target = slider->value() < 400 ? 600 : 150;
  slider->setValue(target);
  const double new_isovalue = window_->isovalue();
  ASSERT_NE(new_isovalue, old_isovalue);
  EXPECT_DOUBLE_EQ(window_->actors().isovalue(), new_isovalue);
  EXPECT_NEAR(window_->isovalueSpinBox()->value(), new_isovalue,
              std::pow(10.0, -window_->isovalueSpinBox()->decimals()));
  ASSERT_NE(window_->hapticThread(), nullptr);
  EXPECT_DOUBLE_EQ(window_->hapticThread()->isovalue(), new_isovalue);

  const QImage after = view->grabFrame();
  const double changed = differingFraction(before, after);
  EXPECT_GT(changed, 0.02) << "isovalue " << old_isovalue << " -> " << new_isovalue;

  // The servo loop applies the new isovalue on its next tick.
  EXPECT_TRUE(waitFor([&] {
    window_->refreshFromHaptics();
    return window_->lastSnapshot().isovalue == new_isovalue;
  }, 3000)) << "snapshot isovalue " << window_->lastSnapshot().isovalue;

  // The spin box drives it too.
  window_->isovalueSpinBox()->setValue(old_isovalue);
  EXPECT_NEAR(window_->isovalue(), old_isovalue,
              std::pow(10.0, -window_->isovalueSpinBox()->decimals()));
  EXPECT_DOUBLE_EQ(window_->hapticThread()->isovalue(), window_->isovalue());
}

TEST_F(MainWindowTest, ToolActorsExistAndFollowTheHapticThread) {
  vtkRenderer* renderer = window_->view()->renderer();
  ASSERT_NE(window_->proxyActor(), nullptr);
  ASSERT_NE(window_->deviceActor(), nullptr);
  EXPECT_TRUE(renderer->HasViewProp(window_->proxyActor()));
  EXPECT_TRUE(renderer->HasViewProp(window_->deviceActor()));
  EXPECT_TRUE(renderer->HasViewProp(window_->volumeProp()));
  EXPECT_TRUE(window_->proxyActor()->GetVisibility());
  EXPECT_TRUE(window_->deviceActor()->GetVisibility());
  EXPECT_GT(window_->proxyActor()->GetMapper()->GetInput()->GetNumberOfCells(), 0);

  // Lift the device 5 mm (free space): the proxy follows it.
  ASSERT_NE(window_->simulatedDevice(), nullptr);
  haptics::Pose target = window_->simulatedDevice()->pose();
  target.p_AB_m.z() += 0.005;
  window_->setDevicePose(target);
  EXPECT_TRUE(waitFor([&] {
    window_->refreshFromHaptics();
    return (translationOf(window_->proxyActor()) - target.p_AB_m).norm() < 1e-4;
  }, 3000)) << "proxy at " << translationOf(window_->proxyActor()).transpose();
  EXPECT_LT((translationOf(window_->deviceActor()) - target.p_AB_m).norm(), 1e-6);
  EXPECT_TRUE(waitFor([&] {
    window_->refreshFromHaptics();
    return window_->statusText().contains("Hz");
  }, 3000)) << window_->statusText().toStdString();
}

TEST_F(MainWindowTest, CtrlDragMovesTheDeviceAndPlainDragTheCamera) {
  VtkView* view = window_->view();
  runtime::SimulatedDevice* device = window_->simulatedDevice();
  ASSERT_NE(device, nullptr);
  vtkCamera* camera = view->renderer()->GetActiveCamera();
  double cam_before[3];
  camera->GetPosition(cam_before);
  const haptics::Pose before = device->pose();
  double right[3];
  {
    double up[3], dir[3];
    camera->GetViewUp(up);
    camera->GetDirectionOfProjection(dir);
    const Eigen::Vector3d r = Eigen::Vector3d(dir[0], dir[1], dir[2])
                                  .cross(Eigen::Vector3d(up[0], up[1], up[2])).normalized();
    right[0] = r.x(); right[1] = r.y(); right[2] = r.z();
  }

  const QPointF start(view->width() / 2.0, view->height() / 2.0);
  mouse(QEvent::MouseButtonPress, start, Qt::LeftButton, Qt::LeftButton, Qt::ControlModifier);
  mouse(QEvent::MouseMove, start + QPointF(40, 0), Qt::NoButton, Qt::LeftButton, Qt::ControlModifier);
  mouse(QEvent::MouseButtonRelease, start + QPointF(40, 0), Qt::LeftButton, Qt::NoButton,
        Qt::ControlModifier);
  const Eigen::Vector3d moved = device->pose().p_AB_m - before.p_AB_m;
  EXPECT_GT(moved.norm(), 1e-4);
  EXPECT_GT(moved.dot(Eigen::Vector3d(right[0], right[1], right[2])), 0.99 * moved.norm())
      << "Ctrl+drag to the right moves the device to screen-right";
  double cam_after[3];
  camera->GetPosition(cam_after);
  EXPECT_EQ(cam_before[0], cam_after[0]);
  EXPECT_EQ(cam_before[1], cam_after[1]);
  EXPECT_EQ(cam_before[2], cam_after[2]);

  // Shift+drag rotates the device, leaving its centre of mass in place.
  const haptics::Pose before_rotation = device->pose();
  mouse(QEvent::MouseButtonPress, start, Qt::LeftButton, Qt::LeftButton, Qt::ShiftModifier);
  mouse(QEvent::MouseMove, start + QPointF(0, -30), Qt::NoButton, Qt::LeftButton, Qt::ShiftModifier);
  mouse(QEvent::MouseButtonRelease, start + QPointF(0, -30), Qt::LeftButton, Qt::NoButton,
        Qt::ShiftModifier);
  const haptics::Pose after_rotation = device->pose();
  EXPECT_GT(after_rotation.R_AB.angularDistance(before_rotation.R_AB), 0.05);
  const Eigen::Vector3d p_Cm = loaded_->tool->mass.p_TCm_m;
  EXPECT_LT((after_rotation * p_Cm - before_rotation * p_Cm).norm(), 1e-9);

  // A plain drag turns the camera and leaves the device alone.
  const haptics::Pose before_camera = device->pose();
  mouse(QEvent::MouseButtonPress, start, Qt::LeftButton, Qt::LeftButton, Qt::NoModifier);
  mouse(QEvent::MouseMove, start + QPointF(60, 10), Qt::NoButton, Qt::LeftButton, Qt::NoModifier);
  mouse(QEvent::MouseButtonRelease, start + QPointF(60, 10), Qt::LeftButton, Qt::NoButton,
        Qt::NoModifier);
  camera->GetPosition(cam_after);
  EXPECT_GT(std::abs(cam_after[0] - cam_before[0]) + std::abs(cam_after[1] - cam_before[1]) +
                std::abs(cam_after[2] - cam_before[2]),
            1e-6);
  EXPECT_EQ(device->pose().p_AB_m, before_camera.p_AB_m);
}

TEST_F(MainWindowTest, TouchRestsTheProxyOnTheSurfaceWithAForce) {
  ASSERT_TRUE(window_->touchSurface(0.003));
  EXPECT_TRUE(waitFor([&] {
    window_->refreshFromHaptics();
    const runtime::HapticSnapshot& s = window_->lastSnapshot();
    return s.contacts > 0 && s.force_W_N.norm() > 0.1;
  }, 10000)) << "contacts " << window_->lastSnapshot().contacts << ", |F| "
            << window_->lastSnapshot().force_W_N.norm() << " N";
  // The proxy stays out while the device sinks in; the force arrow and contacts are drawn.
  const runtime::HapticSnapshot& s = window_->lastSnapshot();
  EXPECT_GT((s.X_WD.p_AB_m - s.X_WP.p_AB_m).norm(), 1e-3);
  EXPECT_TRUE(window_->actors().forceActor()->GetVisibility());
  EXPECT_TRUE(window_->actors().contactActor()->GetVisibility());
  EXPECT_FALSE(window_->view()->grabFrame().isNull());
}

}  // namespace
}  // namespace vh::ui
