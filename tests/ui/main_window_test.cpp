// The main window on the small CT head (64 x 64 x 93): rendering, the isovalue slider driving
// both the picture and the haptic thread, rendering modes, standard views and clipping, the tool
// actors against the haptic state, the mouse-driven device, loading off the GUI thread (and its
// errors and cancel), the haptics panel (gains, tool change).
#include "vh/ui/main_window.h"
#include "vh/ui/devices/device_input.h"
#include "vh/ui/devices/device_picker.h"
#include "vh/ui/panels/isovalue_bar.h"
#include "vh/ui/tool_picker.h"
#include "vh/ui/haptics_controller.h"
#include "vh/ui/panels/haptics_panel.h"
#include "vh/ui/tool_fit_checker.h"
#include "vh/ui/view_controller.h"

#include <cmath>
#include <filesystem>
#include <fstream>
#include <memory>

#include <QApplication>
#include <QCheckBox>
#include <QComboBox>
#include <QDockWidget>
#include <QDoubleSpinBox>
#include <QImage>
#include <QLabel>
#include <QMenu>
#include <QMimeData>
#include <QUrl>
#include <QDropEvent>
#include <QMessageBox>
#include <QMouseEvent>
#include <QPushButton>
#include <QSignalSpy>
#include <QSlider>
#include <QTemporaryDir>

#include <gtest/gtest.h>
#include <vtkActor.h>
#include <vtkCamera.h>
#include <vtkImageData.h>
#include <vtkMapper.h>
#include <vtkMatrix4x4.h>
#include <vtkPolyData.h>
#include <vtkRenderer.h>

#include "ui_test_util.h"
#include "vh/devices/device_catalog.h"
#include "vh/runtime/device.h"
#include "vh/runtime/placement.h"
#include "vh/runtime/scene.h"
#include "vh/runtime/servo_factory.h"
#include "vh/runtime/tool_fit.h"
#include "vh/ui/view/device_manipulation.h"
#include "vh/ui/panels/haptics_panel.h"
#include "vh/ui/panels/histogram_slider.h"
#include "vh/ui/view/scene_actors.h"
#include "vh/ui/scene_loader.h"
#include "vh/ui/view/vtk_view.h"

namespace vh::ui {
namespace {

using test::brightFraction;
using test::differingFraction;
using test::kHead;
using test::waitFor;

Eigen::Vector3d translationOf(vtkActor* actor) {
  vtkMatrix4x4* m = actor->GetUserMatrix();
  return m == nullptr ? Eigen::Vector3d::Zero()
                      : Eigen::Vector3d(m->GetElement(0, 3), m->GetElement(1, 3), m->GetElement(2, 3));
}

/// The actor's user matrix as a pose (rotation part and translation).
haptics::Pose poseOf(vtkActor* actor) {
  vtkMatrix4x4* m = actor->GetUserMatrix();
  Eigen::Matrix3d R;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) R(r, c) = m->GetElement(r, c);
  }
  haptics::Pose X;
  X.R_AB = Eigen::Quaterniond(R);
  X.p_AB_m = translationOf(actor);
  return X;
}

class MainWindowOnHead : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    if (std::filesystem::exists(kHead)) {
      loaded_ = std::make_unique<runtime::LoadedScene>(runtime::loadScene(runtime::sceneForVolume(kHead)));
    }
  }
  static void TearDownTestSuite() { loaded_.reset(); }

  void SetUp() override {
    if (loaded_ == nullptr) {
      GTEST_SKIP() << "dataset absent: " << kHead << " (the small CT head of ../shared/datasets)";
    }
    std::shared_ptr<runtime::Device> device = loaded_->makeDevice();
    ViewerScene scene = makeViewerScene(*loaded_, device);
    scene.title = "ct-head-small";
    window_ = std::make_unique<MainWindow>(std::move(scene));
    window_->setInteractive(false);
    // Docks closed: their widgets work hidden, and the view stays small (software GL).
    for (auto* dock : window_->findChildren<QDockWidget*>()) dock->hide();
    window_->resize(640, 540);
    window_->show();
    ASSERT_TRUE(waitFor([this] { return window_->sceneView()->widget()->frameCount() > 0; }, 20000)) << "the view never rendered";
    window_->startHaptics();
  }

  void TearDown() override {
    if (window_ != nullptr) {
      window_->close();
      EXPECT_FALSE(window_->session().hapticThread() != nullptr && window_->session().hapticThread()->running())
          << "closing the window must stop the haptic thread";
      window_.reset();
    }
  }

  /// Sends a mouse event to the view.
  void mouse(QEvent::Type type, QPointF pos, Qt::MouseButton button, Qt::MouseButtons buttons,
             Qt::KeyboardModifiers modifiers) {
    QMouseEvent event(type, pos, window_->sceneView()->widget()->mapToGlobal(pos), button, buttons, modifiers);
    QApplication::sendEvent(window_->sceneView()->widget(), &event);
  }

  static std::unique_ptr<runtime::LoadedScene> loaded_;
  std::unique_ptr<MainWindow> window_;
};

std::unique_ptr<runtime::LoadedScene> MainWindowOnHead::loaded_;

TEST_F(MainWindowOnHead, IsovalueSliderChangesThePictureAndTheHapticIsovalue) {
  VtkView* view = window_->sceneView()->widget();
  const QImage before = view->grabFrame();
  ASSERT_FALSE(before.isNull());
  EXPECT_GT(brightFraction(before), 0.03) << "the isosurface should cover part of the view";

  QSlider* slider = window_->isovalueBar()->slider();
  const double old_isovalue = window_->session().isovalue();
  // Move to the other side of the range: the skin (low values) vs the bone (high values).
  const int target = slider->value() < 400 ? 600 : 150;
  slider->setValue(target);
  const double new_isovalue = window_->session().isovalue();
  ASSERT_NE(new_isovalue, old_isovalue);
  EXPECT_DOUBLE_EQ(window_->sceneView()->actors().isovalue(), new_isovalue);
  EXPECT_NEAR(window_->isovalueBar()->spinBox()->value(), new_isovalue,
              std::pow(10.0, -window_->isovalueBar()->spinBox()->decimals()));
  ASSERT_NE(window_->session().hapticThread(), nullptr);
  EXPECT_DOUBLE_EQ(window_->session().hapticThread()->isovalue(), new_isovalue);

  const QImage after = view->grabFrame();
  const double changed = differingFraction(before, after);
  EXPECT_GT(changed, 0.02) << "isovalue " << old_isovalue << " -> " << new_isovalue;

  // The servo loop applies the new isovalue on its next tick.
  EXPECT_TRUE(waitFor([&] {
    window_->viewController()->refresh();
    return window_->viewController()->lastSnapshot().isovalue == new_isovalue;
  }, 30000)) << "snapshot isovalue " << window_->viewController()->lastSnapshot().isovalue;

  // The spin box drives it too.
  window_->isovalueBar()->spinBox()->setValue(old_isovalue);
  EXPECT_NEAR(window_->session().isovalue(), old_isovalue, std::pow(10.0, -window_->isovalueBar()->spinBox()->decimals()));
  EXPECT_DOUBLE_EQ(window_->session().hapticThread()->isovalue(), window_->session().isovalue());
}

TEST_F(MainWindowOnHead, HistogramIsDrawnBehindTheSlider) {
  const Histogram& h = window_->isovalueBar()->slider()->histogram();
  ASSERT_FALSE(h.empty());
  EXPECT_EQ(h.total(), 64u * 64u * 93u);
  EXPECT_LE(h.min_value, window_->isovalueBar()->spinBox()->minimum() + 1e-9);
  EXPECT_GE(h.max_value, window_->isovalueBar()->spinBox()->maximum() - 1e-9);
  // The slider paints it: its pixels differ from a plain slider's.
  const QImage with = window_->isovalueBar()->slider()->grab().toImage();
  window_->isovalueBar()->slider()->clearHistogram();
  const QImage without = window_->isovalueBar()->slider()->grab().toImage();
  EXPECT_GT(differingFraction(with, without, 8), 0.05);
}

TEST_F(MainWindowOnHead, RenderingModesChangeThePicture) {
  VtkView* view = window_->sceneView()->widget();
  ASSERT_EQ(window_->preferences().mode, RenderMode::kIsosurface);
  // Each picture at the same (best) quality.
  auto grab = [&] {
    window_->sceneView()->renderStill(true);
    return view->grabFrame();
  };
  const QImage iso = grab();
  window_->viewController()->setPreset(VolumePreset::kBone);
  window_->viewController()->setRenderMode(RenderMode::kComposite);
  EXPECT_EQ(window_->sceneView()->actors().renderMode(), RenderMode::kComposite);
  const QImage composite = grab();
  window_->viewController()->setRenderMode(RenderMode::kMip);
  const QImage mip = grab();
  EXPECT_GT(differingFraction(iso, composite), 0.02);
  EXPECT_GT(differingFraction(iso, mip), 0.02);
  EXPECT_GT(differingFraction(composite, mip), 0.02);
  EXPECT_GT(brightFraction(composite), 0.01) << "the bone preset should show something";
  window_->viewController()->setPreset(VolumePreset::kSkin);
  window_->viewController()->setRenderMode(RenderMode::kComposite);
  EXPECT_GT(differingFraction(composite, grab()), 0.02) << "skin vs bone preset";
  window_->viewController()->setRenderMode(RenderMode::kIsosurface);
  EXPECT_LT(differingFraction(iso, grab()), 0.01) << "back to the same isosurface";
}

TEST_F(MainWindowOnHead, StandardViewsAndClipping) {
  vtkCamera* camera = window_->sceneView()->widget()->renderer()->GetActiveCamera();
  double dop[3], up[3];
  window_->sceneView()->setStandardView(StandardView::kAnterior);
  camera->GetDirectionOfProjection(dop);
  EXPECT_NEAR(dop[1], 1.0, 1e-9) << "anterior: looking from -y (A) towards +y (P)";
  window_->sceneView()->setStandardView(StandardView::kLeft);
  camera->GetDirectionOfProjection(dop);
  EXPECT_NEAR(dop[0], -1.0, 1e-9) << "left lateral: looking from +x (L)";
  window_->sceneView()->setStandardView(StandardView::kSuperior);
  camera->GetDirectionOfProjection(dop);
  camera->GetViewUp(up);
  EXPECT_NEAR(dop[2], -1.0, 1e-9) << "superior: looking down";
  EXPECT_NEAR(up[1], -1.0, 1e-9) << "anterior up";

  window_->sceneView()->setStandardView(StandardView::kAnterior);
  const QImage whole = window_->sceneView()->widget()->grabFrame();
  window_->viewController()->setClipping(true, ClipAxis::kY, 0.5);
  EXPECT_TRUE(window_->sceneView()->actors().clipping());
  const QImage clipped = window_->sceneView()->widget()->grabFrame();
  EXPECT_GT(differingFraction(whole, clipped), 0.02) << "a coronal cut opens the head";
  window_->viewController()->setClipping(false);
  EXPECT_FALSE(window_->sceneView()->actors().clipping());
}

TEST_F(MainWindowOnHead, ToolActorsExistAndFollowTheHapticThread) {
  vtkRenderer* renderer = window_->sceneView()->widget()->renderer();
  ASSERT_NE(window_->sceneView()->actors().proxyActor(), nullptr);
  ASSERT_NE(window_->sceneView()->actors().deviceActor(), nullptr);
  EXPECT_TRUE(renderer->HasViewProp(window_->sceneView()->actors().proxyActor()));
  EXPECT_TRUE(renderer->HasViewProp(window_->sceneView()->actors().deviceActor()));
  EXPECT_TRUE(renderer->HasViewProp(window_->sceneView()->actors().volume()));
  EXPECT_TRUE(window_->sceneView()->actors().proxyActor()->GetVisibility());
  EXPECT_TRUE(window_->sceneView()->actors().deviceActor()->GetVisibility());
  EXPECT_GT(window_->sceneView()->actors().proxyActor()->GetMapper()->GetInput()->GetNumberOfCells(), 0);

  // Lift the device 5 mm (free space): the proxy follows it.
  ASSERT_NE(window_->session().simulatedDevice(), nullptr);
  haptics::Pose target = window_->session().simulatedDevice()->pose();
  target.p_AB_m.z() += 0.005;
  window_->deviceInput()->setDevicePose(target);
  EXPECT_TRUE(waitFor([&] {
    window_->viewController()->refresh();
    return (translationOf(window_->sceneView()->actors().proxyActor()) - target.p_AB_m).norm() < 1e-4;
  }, 30000)) << "proxy at " << translationOf(window_->sceneView()->actors().proxyActor()).transpose();
  EXPECT_LT((translationOf(window_->sceneView()->actors().deviceActor()) - target.p_AB_m).norm(), 1e-6);
  EXPECT_TRUE(waitFor([&] {
    window_->viewController()->refresh();
    return window_->statusText().contains("Hz");
  }, 30000)) << window_->statusText().toStdString();
  EXPECT_GT(window_->stripChart() != nullptr, 0);
}

TEST_F(MainWindowOnHead, CtrlDragMovesTheDeviceAndPlainDragTheCamera) {
  VtkView* view = window_->sceneView()->widget();
  runtime::SimulatedDevice* device = window_->session().simulatedDevice();
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

  // The keyboard moves it too (arrow right: screen-right by one step).
  const haptics::Pose before_key = device->pose();
  QKeyEvent key(QEvent::KeyPress, Qt::Key_Right, Qt::NoModifier);
  QApplication::sendEvent(view, &key);
  const Eigen::Vector3d key_moved = device->pose().p_AB_m - before_key.p_AB_m;
  EXPECT_GT(key_moved.norm(), 1e-4);
  EXPECT_GT(key_moved.dot(Eigen::Vector3d(right[0], right[1], right[2])), 0.99 * key_moved.norm());

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

TEST_F(MainWindowOnHead, DeviceDrivenIntoTheSurfaceLeavesTheProxyOutsideWhereTheActorShowsIt) {
  ASSERT_TRUE(window_->deviceInput()->touchSurface(0.003));
  EXPECT_TRUE(waitFor([&] {
    window_->viewController()->refresh();
    const runtime::HapticSnapshot& s = window_->viewController()->lastSnapshot();
    return s.contacts > 0 && s.force_W_N.norm() > 0.1;
  }, 30000)) << "contacts " << window_->viewController()->lastSnapshot().contacts << ", |F| "
            << window_->viewController()->lastSnapshot().force_W_N.norm() << " N";
  // Freeze the haptic state (the force ramps down; the proxy stays), then read it once more.
  window_->session().stopHaptics();
  window_->viewController()->refresh(true);
  const runtime::HapticSnapshot& s = window_->viewController()->lastSnapshot();
  // The proxy actor shows exactly the haptic thread's proxy pose.
  const haptics::Pose shown = poseOf(window_->sceneView()->actors().proxyActor());
  EXPECT_LT((shown.p_AB_m - s.X_WP.p_AB_m).norm(), 1e-12);
  EXPECT_LT(shown.R_AB.angularDistance(s.X_WP.R_AB), 1e-9);
  EXPECT_LT((translationOf(window_->sceneView()->actors().deviceActor()) - s.X_WD.p_AB_m).norm(), 1e-12);
  // The device sank in; the proxy stayed outside the isosurface (within the collision tolerance).
  EXPECT_GT((s.X_WD.p_AB_m - s.X_WP.p_AB_m).norm(), 1e-3);
  const haptics::ScalarVolume& field = *loaded_->volume.field;
  const double depth_m = haptics::maxPenetration_m(field, loaded_->tool->point_shell, shown, window_->session().isovalue());
  EXPECT_LE(depth_m, 0.25 * field.featureSize_m()) << "proxy " << depth_m * 1e3 << " mm inside";
  EXPECT_GT(haptics::maxPenetration_m(field, loaded_->tool->point_shell, s.X_WD, window_->session().isovalue()), 1e-3)
      << "the device itself is inside";
  // The force arrow and contacts are drawn.
  EXPECT_TRUE(window_->sceneView()->actors().contactActor()->GetVisibility());
  EXPECT_FALSE(window_->sceneView()->widget()->grabFrame().isNull());
}

TEST_F(MainWindowOnHead, ToolRestingOnTheSurfaceGetsTheFullQualityStillFrame) {
  // The tool pressed onto the skin and left there with the haptic threads running: the proxy
  // moves micrometres a tick under the steady push, which is no visible motion, so the view
  // settles on its full-quality still frame (300 ms after the last visible change).
  ASSERT_TRUE(window_->deviceInput()->touchSurface(0.003));
  ASSERT_TRUE(waitFor([&] {
    window_->viewController()->refresh();
    const runtime::HapticSnapshot& s = window_->viewController()->lastSnapshot();
    return !window_->deviceInput()->touchInProgress() && s.contacts > 0;
  }, 20000)) << "the tool never came to rest on the surface";
  test::pump(2000);  // the hand rests for 2 s
  ASSERT_TRUE(window_->session().hapticsRunning());
  window_->viewController()->refresh();
  SceneView* view = window_->sceneView();
  // The still frame comes 300 ms after the last visible change; on a busy machine the proxy may take
  // longer to settle under the push, so it is waited for (a view that took every micrometre for
  // motion would stay interactive and fail here). No events run from here to the frames grabbed.
  EXPECT_TRUE(waitFor([&] { return !view->actors().interactive(); }, 30000))
      << "still interactive (coarse) frames with the tool at rest";
  const runtime::HapticSnapshot& s = window_->viewController()->lastSnapshot();
  EXPECT_GT(s.contacts, 0) << "the tool should still rest on the surface";
  const double rest_sample_m = view->actors().sampleDistance_m();
  const double rest_image_px = view->actors().imageSampleDistance_px();
  const QImage at_rest = view->widget()->grabFrame();  // the frame at the quality it rests at
  // The oracle: the same frame at the best still quality (the screenshot path).
  view->renderStill(/*best_quality=*/true);
  const QImage full = view->widget()->grabFrame();
  EXPECT_DOUBLE_EQ(rest_sample_m, view->actors().sampleDistance_m());
  EXPECT_DOUBLE_EQ(rest_image_px, view->actors().imageSampleDistance_px());
  ASSERT_FALSE(at_rest.isNull());
  EXPECT_LT(differingFraction(at_rest, full, 8), 0.002) << "the frame at rest differs from a full-quality render";
}

TEST_F(MainWindowOnHead, GainsFromThePanelApplyLiveAndPersist) {
  HapticsPanel* panel = window_->hapticsPanel();
  ASSERT_NE(panel, nullptr);
  panel->linearStiffnessBox()->setValue(2500.0);
  panel->torsionalStiffnessBox()->setValue(1.5);
  EXPECT_DOUBLE_EQ(window_->session().gains().linear_N_per_m, 2500.0);
  EXPECT_DOUBLE_EQ(window_->session().gains().angular_Nm_per_rad, 1.5);
  EXPECT_DOUBLE_EQ(window_->preferences().linear_stiffness_N_per_m, 2500.0);
  EXPECT_DOUBLE_EQ(window_->preferences().torsional_stiffness_Nm_per_rad, 1.5);
  EXPECT_FALSE(window_->session().gains().passivity_control);
  panel->passivityControlBox()->setChecked(true);
  EXPECT_TRUE(window_->session().gains().passivity_control);
  EXPECT_DOUBLE_EQ(window_->session().gains().linear_N_per_m, 2500.0);
  EXPECT_TRUE(window_->preferences().passivity_control);
  panel->passivityControlBox()->setChecked(false);
  EXPECT_FALSE(window_->session().gains().passivity_control);
  EXPECT_FALSE(window_->preferences().passivity_control);
  EXPECT_EQ(panel->pointCountLabel()->text().toULongLong(), loaded_->tool->point_shell.size());
  // The edge test between shell points is the session's, on by default, switched from the panel.
  EXPECT_TRUE(panel->edgeTestBox()->isChecked());
  panel->edgeTestBox()->setChecked(false);
  EXPECT_FALSE(window_->session().live().tool_spec.edge_test);
  panel->edgeTestBox()->setChecked(true);
  EXPECT_TRUE(window_->session().live().tool_spec.edge_test);
  EXPECT_TRUE(window_->session().hapticsRunning());
  // The start/stop button stops and restarts the thread.
  panel->startStopButton()->click();
  EXPECT_FALSE(window_->session().hapticsRunning());
  panel->startStopButton()->click();
  EXPECT_TRUE(window_->session().hapticsRunning());
}

// The fit check in the window, judged with a fixed cost of a work unit (so that the verdict is
// the same on every machine): a cost at which the head's tool would be cut at its worst ticks is
// said in the panel with a coarser spacing offered; the offer, clicked, rebuilds the tool at that
// spacing, and the check of the rebuilt tool says it is on time.
TEST_F(MainWindowOnHead, TheFitCheckSaysWhenTheToolIsLateAndItsOfferRebuildsAToolThatIsNot) {
  HapticsPanel* panel = window_->hapticsPanel();
  ToolFitChecker& checker = window_->haptics()->fitChecker();
  // The tool's heaviest tick of the warm-up, counted in work units (the same on every machine).
  runtime::ToolFitOptions probe;
  probe.ns_per_work = 1e-3;
  probe.lanes = 1;
  const runtime::ToolFit free_fit = runtime::checkToolFit(window_->session().live(), probe);
  ASSERT_TRUE(free_fit.fits());
  ASSERT_GT(free_fit.asked.work_max, 100);
  // A cost at which that tick takes twice the deadline: late.
  runtime::ToolFitOptions costly = probe;
  costly.ns_per_work = 2.0 * 1e3 * runtime::solverDeadline_us(1000.0) / static_cast<double>(free_fit.asked.work_max);
  QSignalSpy checked(&checker, &ToolFitChecker::checked);
  checker.setOptions(costly);
  checker.check(window_->session().live());
  ASSERT_TRUE(waitFor([&] { return checked.count() > 0; }, 60000)) << "the fit check never ended";
  ASSERT_TRUE(checker.last());
  const runtime::ToolFit fit = *checker.last();
  std::printf("[ FIT      ] %s\n", fit.summary().c_str());
  EXPECT_FALSE(fit.fits());
  EXPECT_TRUE(panel->toolFitLabel()->text().startsWith("late")) << panel->toolFitLabel()->text().toStdString();
  ASSERT_TRUE(fit.suggested) << "no coarser spacing fits at this cost";
  EXPECT_TRUE(panel->useFittingSpacingButton()->isVisibleTo(panel));
  EXPECT_TRUE(panel->useFittingSpacingButton()->text().contains(
      QString::number(fit.suggested->spacing_m * 1e3, 'f', 2)));
  // The offer taken: the tool rebuilt at the suggested spacing, checked again, on time.
  QSignalSpy changed(window_->toolPicker(), &ToolPicker::toolChanged);
  panel->useFittingSpacingButton()->click();
  ASSERT_TRUE(waitFor([&] { return changed.count() > 0; }, 60000)) << "the tool was never rebuilt";
  EXPECT_EQ(window_->session().live().tool->point_shell.size(), fit.suggested->points);
  ASSERT_TRUE(waitFor([&] { return checked.count() > 1; }, 60000)) << "the rebuilt tool was never checked";
  ASSERT_TRUE(checker.last());
  EXPECT_TRUE(checker.last()->fits()) << checker.last()->summary();
  EXPECT_TRUE(panel->toolFitLabel()->text().startsWith("on time")) << panel->toolFitLabel()->text().toStdString();
  EXPECT_FALSE(panel->useFittingSpacingButton()->isVisibleTo(panel));
}

TEST_F(MainWindowOnHead, ChoosingAToolRebuildsTheHapticThread) {
  const auto& tools = window_->toolPicker()->choices();
  int sphere = -1;
  for (std::size_t i = 0; i < tools.size(); ++i) {
    if (tools[i].id == "builtin:sphere") sphere = static_cast<int>(i);
  }
  ASSERT_GE(sphere, 0);
  const vtkIdType cells_before = window_->sceneView()->actors().proxyActor()->GetMapper()->GetInput()->GetNumberOfCells();
  QSignalSpy changed(window_->toolPicker(), &ToolPicker::toolChanged);
  window_->toolPicker()->select(sphere, 0.001);
  ASSERT_TRUE(waitFor([&] { return changed.count() > 0; }, 20000)) << "the tool was never rebuilt";
  EXPECT_EQ(window_->toolPicker()->currentIndex(), sphere);
  EXPECT_NE(window_->sceneView()->actors().proxyActor()->GetMapper()->GetInput()->GetNumberOfCells(), cells_before);
  EXPECT_EQ(window_->hapticsPanel()->pointCountLabel()->text().toULongLong(), window_->session().live().tool->point_shell.size());
  EXPECT_NEAR(window_->hapticsPanel()->pointSpacing_m(), 0.001, 1e-9);
  EXPECT_TRUE(window_->session().hapticsRunning());
  // The panel names how closely the 5 mm ball at 1 mm spacing is felt: a gap up to about the spacing.
  const QString gap = window_->hapticsPanel()->feltGapLabel()->text();
  EXPECT_TRUE(gap.contains("mm of the mesh")) << gap.toStdString();
  EXPECT_GT(gap.split(' ').front().toDouble(), 0.0) << gap.toStdString();
  EXPECT_LE(gap.split(' ').front().toDouble(), 1.5) << gap.toStdString();
  // The probe's 1 mm shaft at 2 mm spacing is not: the panel says so, with the gap.
  int probe = -1;
  for (std::size_t i = 0; i < tools.size(); ++i)
    if (tools[i].id == "builtin:probe") probe = static_cast<int>(i);
  ASSERT_GE(probe, 0);
  window_->toolPicker()->select(probe, 0.002);
  ASSERT_TRUE(waitFor([&] { return changed.count() > 1; }, 20000)) << "the probe was never built";
  const QString coarse = window_->hapticsPanel()->feltGapLabel()->text();
  EXPECT_TRUE(coarse.contains("too coarse")) << coarse.toStdString();
  EXPECT_GT(coarse.split(' ').front().toDouble(), 1.0) << coarse.toStdString();
  // The new thread runs with the new tool: the proxy follows the device from the new pose.
  EXPECT_TRUE(waitFor([&] {
    window_->viewController()->refresh();
    return window_->viewController()->lastSnapshot().tick > 0 &&
           (window_->viewController()->lastSnapshot().X_WP.p_AB_m - window_->session().live().X_WT_initial.p_AB_m).norm() < 1e-4;
  }, 30000));
}

TEST_F(MainWindowOnHead, DevicePickerListsTheSimulatedDeviceAndWhatIsFound) {
  // Entry 0 is the simulated device, then whatever the catalog finds (none on a build machine).
  devices::DeviceCatalog catalog;
  const std::vector<devices::FoundDevice> found = catalog.enumerate();
  window_->devicePicker()->rescan();
  const QStringList choices = window_->devicePicker()->choices();
  ASSERT_EQ(choices.size(), static_cast<qsizetype>(found.size() + 1));
  EXPECT_EQ(choices.front().toStdString(), "Simulated device (mouse/keyboard)");
  for (std::size_t i = 0; i < found.size(); ++i) EXPECT_EQ(choices[static_cast<qsizetype>(i + 1)].toStdString(), found[i].label());
  // The panel's combo box and the Haptics > Device menu show the same list.
  QComboBox* box = window_->hapticsPanel()->deviceBox();
  ASSERT_NE(box, nullptr);
  ASSERT_EQ(box->count(), choices.size());
  for (int i = 0; i < box->count(); ++i) EXPECT_EQ(box->itemText(i).toStdString(), choices[i].toStdString());
  ASSERT_NE(window_->devicePicker()->menu(), nullptr);
  EXPECT_EQ(window_->devicePicker()->menu()->actions().front()->text().toStdString(), choices.front().toStdString());
  EXPECT_EQ(window_->devicePicker()->currentChoice(), 0) << "the scene's simulated device is entry 0";
  EXPECT_EQ(box->currentIndex(), 0);

  // Another device (not in the list), then back to the simulated one: a new SimulatedDevice
  // drives a running haptic thread whose ticks advance.
  window_->session().setDevice(std::make_shared<runtime::ScriptedDevice>(
      runtime::Trajectory({runtime::TrajectorySample{0.0, window_->session().live().X_WT_initial}})));
  EXPECT_EQ(window_->devicePicker()->currentChoice(), -1);
  EXPECT_EQ(box->currentIndex(), -1);
  ASSERT_TRUE(window_->devicePicker()->choose(0));
  EXPECT_EQ(window_->devicePicker()->currentChoice(), 0);
  EXPECT_EQ(box->currentIndex(), 0);
  ASSERT_NE(window_->session().simulatedDevice(), nullptr);
  EXPECT_TRUE(window_->session().hapticsRunning());
  ASSERT_TRUE(waitFor([&] { window_->viewController()->refresh(); return window_->viewController()->lastSnapshot().tick > 0; }, 30000));
  const auto first = window_->viewController()->lastSnapshot().tick;
  EXPECT_TRUE(waitFor([&] { window_->viewController()->refresh(); return window_->viewController()->lastSnapshot().tick > first + 10; }, 30000))
      << "the haptic thread stopped ticking";
  // Choosing it again keeps the same device; an entry past the list is refused.
  runtime::Device* sim = window_->session().device();
  EXPECT_TRUE(window_->devicePicker()->choose(0));
  EXPECT_EQ(window_->session().device(), sim);
  EXPECT_FALSE(window_->devicePicker()->choose(static_cast<int>(choices.size())));
  EXPECT_EQ(window_->session().device(), sim);
}

TEST_F(MainWindowOnHead, LoadingErrorKeepsThePreviousScene) {
  vtkVolume* volume_before = window_->sceneView()->actors().volume();
  runtime::HapticThread* thread_before = window_->session().hapticThread();
  const double isovalue_before = window_->session().isovalue();
  QTemporaryDir dir;
  const QString bad = dir.filePath("broken.nrrd");
  {
    std::ofstream out(bad.toStdString(), std::ios::binary);
    out << "NRRD0004\ntype: short\ndimension: 3\nsizes: 64 64 64\nencoding: raw\n\n" << std::string(100, '\0');
  }
  QSignalSpy failed(window_.get(), &MainWindow::loadFailed);
  window_->openPath(bad);
  ASSERT_TRUE(waitFor([&] { return failed.count() > 0; }, 30000)) << "no error reported";
  EXPECT_TRUE(window_->opener()->lastError().contains("broken.nrrd")) << window_->opener()->lastError().toStdString();
  EXPECT_FALSE(window_->opener()->loading());
  EXPECT_EQ(window_->sceneView()->actors().volume(), volume_before);
  EXPECT_EQ(window_->session().hapticThread(), thread_before);
  EXPECT_TRUE(window_->session().hapticsRunning());
  EXPECT_DOUBLE_EQ(window_->session().isovalue(), isovalue_before);

  // A missing path fails at once; interactively the error dialog names the file.
  window_->setInteractive(true);
  window_->openPath(dir.filePath("missing.mha"));
  EXPECT_TRUE(window_->opener()->lastError().contains("missing.mha"));
  auto* box = window_->findChild<QMessageBox*>("errorBox");
  ASSERT_NE(box, nullptr);
  EXPECT_TRUE(box->text().contains("missing.mha"));
  EXPECT_TRUE(box->informativeText().contains("kept"));
  box->close();
  EXPECT_EQ(window_->sceneView()->actors().volume(), volume_before);
}

TEST(MainWindowDataFolder, TheChosenFolderListsItsToolsPersistsAndAFolderWithoutDatasetsIsRefused) {
  // The environment would win over the choice: unset for the test, restored after.
  const char* env = std::getenv("VH_SHARED_DATASETS_DIR");
  const std::string saved = env != nullptr ? env : "";
  ::unsetenv("VH_SHARED_DATASETS_DIR");
  QTemporaryDir tmp;
  ASSERT_TRUE(tmp.isValid());
  // A folder holding one real-tool mesh by its shared path (a tetrahedron written here), and one
  // holding nothing of the datasets.
  const QString data = QDir(tmp.path()).filePath("data"), empty = QDir(tmp.path()).filePath("empty");
  ASSERT_TRUE(QDir().mkpath(data + "/meshes/wrench") && QDir().mkpath(empty));
  {
    std::ofstream stl((data + "/meshes/wrench/adjustable-wrench-body.stl").toStdString());
    stl << "solid t\n";
    const char* faces[4][3] = {{"0 0 0", "0.01 0 0", "0 0.01 0"}, {"0 0 0", "0 0 0.01", "0.01 0 0"},
                               {"0 0 0", "0 0.01 0", "0 0 0.01"}, {"0.01 0 0", "0 0 0.01", "0 0.01 0"}};
    for (const auto& f : faces) {
      stl << "facet normal 0 0 0\nouter loop\n";
      for (const char* v : f) stl << "vertex " << v << "\n";
      stl << "endloop\nendfacet\n";
    }
    stl << "endsolid t\n";
  }
  const std::string wrench = (std::filesystem::path(data.toStdString()) / "meshes/wrench/adjustable-wrench-body.stl").string();
  const auto hasWrench = [&](const MainWindow& w) {
    for (const ToolChoice& t : w.toolPicker()->choices())
      if (std::filesystem::path(t.mesh).lexically_normal() == std::filesystem::path(wrench).lexically_normal()) return true;
    return false;
  };
  {
    MainWindow window;
    window.setInteractive(true);
    EXPECT_FALSE(hasWrench(window));
    EXPECT_FALSE(window.setDataFolder(empty));
    auto* box = window.findChild<QMessageBox*>("dataFolderBox");
    ASSERT_NE(box, nullptr) << "the refusal is said";
    EXPECT_TRUE(box->text().contains(empty)) << box->text().toStdString();
    box->close();
    EXPECT_NE(window.preferences().datasets_dir, empty);

    ASSERT_TRUE(window.setDataFolder(data));
    EXPECT_EQ(runtime::sharedDatasetsDir(), std::filesystem::path(data.toStdString()));
    EXPECT_TRUE(hasWrench(window)) << "the tools list what the chosen folder holds";
    EXPECT_EQ(window.preferences().datasets_dir, data);
    window.saveSettings();
  }
  runtime::setPreferredSharedDatasetsDir({});
  {
    MainWindow again;  // the next start reads the choice back
    EXPECT_EQ(again.preferences().datasets_dir, data);
    EXPECT_EQ(runtime::sharedDatasetsDir(), std::filesystem::path(data.toStdString()));
    EXPECT_TRUE(hasWrench(again));
    again.preferences().datasets_dir.clear();
    again.saveSettings();
  }
  runtime::setPreferredSharedDatasetsDir({});
  if (env != nullptr) ::setenv("VH_SHARED_DATASETS_DIR", saved.c_str(), 1);
}

// ---- Windows that load by themselves ------------------------------------------------------------

TEST(MainWindowLoad, OpensADroppedFolderOffTheGuiThreadAndCancels) {
  if (!std::filesystem::exists(kHead)) GTEST_SKIP() << "dataset absent: " << kHead;
  MainWindow window;
  window.setInteractive(false);
  window.resize(800, 600);
  window.show();
  EXPECT_FALSE(window.hasScene());
  QSignalSpy loaded(&window, &MainWindow::sceneLoaded);
  // Dropped on the window like a folder from a file manager.
  QMimeData mime;
  mime.setUrls({QUrl::fromLocalFile(QString::fromStdString(kHead.string()))});
  QDragEnterEvent enter(QPoint(400, 300), Qt::CopyAction, &mime, Qt::LeftButton, Qt::NoModifier);
  QApplication::sendEvent(&window, &enter);
  EXPECT_TRUE(enter.isAccepted()) << "a local folder is welcome";
  QDropEvent drop(QPointF(400, 300), Qt::CopyAction, &mime, Qt::LeftButton, Qt::NoModifier);
  QApplication::sendEvent(&window, &drop);
  EXPECT_TRUE(drop.isAccepted());
  EXPECT_TRUE(window.opener()->loading()) << "the load runs on the worker";
  ASSERT_TRUE(waitFor([&] { return loaded.count() > 0; }, 20000)) << window.opener()->lastError().toStdString();
  ASSERT_TRUE(window.hasScene());
  EXPECT_TRUE(waitFor([&] { return !window.opener()->loading(); }, 20000)) << "first frame (GPU upload) never came";
  EXPECT_TRUE(window.session().hapticsRunning()) << "haptics start after a load";
  EXPECT_FALSE(window.isovalueBar()->slider()->histogram().empty()) << "histogram computed on the loader thread";
  EXPECT_TRUE(window.windowTitle().contains("ct-head-small")) << window.windowTitle().toStdString();
  ASSERT_FALSE(window.preferences().recent_files.isEmpty());
  EXPECT_TRUE(window.preferences().recent_files.front().endsWith("ct-head-small"));
  EXPECT_GE(window.opener()->recentFilesMenu()->actions().size(), 1);

  // Cancel: the running load is abandoned, the scene shown stays.
  vtkVolume* shown = window.sceneView()->actors().volume();
  window.openPath(QString::fromStdString(kHead.string()));
  window.opener()->cancelLoading();
  EXPECT_FALSE(window.opener()->loading());
  window.loader()->waitForIdle();
  test::pump(200);
  EXPECT_EQ(window.sceneView()->actors().volume(), shown);
  EXPECT_EQ(loaded.count(), 1);
  window.close();
}

}  // namespace
}  // namespace vh::ui
