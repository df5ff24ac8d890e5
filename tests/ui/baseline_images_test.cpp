// The main view's pictures held against baseline images, so that a refactor cannot silently
// break what the clinician sees: the isosurface, composite and MIP renderings of the built-in
// sphere with the proxy and device meshes mirrored where a tick put them, and a segment surface.
// The comparison is VTK's own regression-test metric (vtkImageDifference, as vtkTesting's
// RegressionTest uses it: the mean thresholded pixel error, which tolerates the one-pixel shifts
// and small colour differences of anti-aliasing and a different rasteriser, at a threshold of 10).
//
// Baselines live in tests/ui/baselines/ (Mesa llvmpipe under Xvfb, 320 x 240). After a deliberate
// change of the picture, look at the new images and renew them:
//   VH_UPDATE_BASELINES=1 xvfb-run -a tests/ui/vh_ui_tests --gtest_filter='BaselineImages.*'
// Each run writes what it rendered (and, on a mismatch, the difference image) to
// baseline-images/ in the test's working folder.
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <memory>
#include <numbers>
#include <string>
#include <vector>

#include <QVBoxLayout>
#include <QWidget>

#include <gtest/gtest.h>
#include <vtkCamera.h>
#include <vtkImageData.h>
#include <vtkImageDifference.h>
#include <vtkNew.h>
#include <vtkPNGReader.h>
#include <vtkPNGWriter.h>
#include <vtkRenderer.h>

#include "ui_test_util.h"
#include "vh/haptics/scalar_volume.h"
#include "vh/io/segmentation.h"
#include "vh/runtime/scene.h"
#include "vh/runtime/segments.h"
#include "vh/ui/export/media_export.h"
#include "vh/ui/view/scene_view.h"
#include "vh/ui/view/vtk_view.h"

namespace vh::ui {
namespace {

namespace fs = std::filesystem;
using haptics::Pose;
using test::sphereProbeScene;

/// VTK's regression tests pass an image whose thresholded error is at most 10 (vtkTesting).
constexpr double kVtkRegressionThreshold = 10.0;

const fs::path kBaselineDir = fs::path(VH_SOURCE_DIR) / "tests/ui/baselines";
const fs::path kOutputDir = fs::current_path() / "baseline-images";

/// vtkImageDifference's thresholded error of `image_png` against `baseline_png`; `diff_png`
/// receives the difference image. Negative when the sizes differ.
double thresholdedError(const fs::path& image_png, const fs::path& baseline_png, const fs::path& diff_png) {
  vtkNew<vtkPNGReader> image;
  image->SetFileName(image_png.c_str());
  vtkNew<vtkPNGReader> baseline;
  baseline->SetFileName(baseline_png.c_str());
  image->Update();
  baseline->Update();
  int a[3];
  int b[3];
  image->GetOutput()->GetDimensions(a);
  baseline->GetOutput()->GetDimensions(b);
  if (a[0] != b[0] || a[1] != b[1]) return -1.0;
  vtkNew<vtkImageDifference> difference;
  difference->SetInputConnection(image->GetOutputPort());
  difference->SetImageConnection(baseline->GetOutputPort());
  difference->Update();
  vtkNew<vtkPNGWriter> writer;
  writer->SetInputConnection(difference->GetOutputPort());
  writer->SetFileName(diff_png.c_str());
  writer->Write();
  return difference->GetThresholdedError();
}

/// Saves `frame` as baseline-images/NAME.png and compares it with tests/ui/baselines/BASELINE.png
/// (BASELINE = NAME when empty; renewed instead when VH_UPDATE_BASELINES is set).
::testing::AssertionResult matchesBaseline(const QImage& frame, const std::string& name, double* error_out = nullptr,
                                           const std::string& baseline_name = {}) {
  fs::create_directories(kOutputDir);
  const fs::path rendered = kOutputDir / (name + ".png");
  if (frame.isNull() || !frame.convertToFormat(QImage::Format_RGB888).save(QString::fromStdString(rendered.string()))) {
    return ::testing::AssertionFailure() << "could not save the rendered frame to " << rendered;
  }
  const fs::path baseline = kBaselineDir / ((baseline_name.empty() ? name : baseline_name) + ".png");
  if (std::getenv("VH_UPDATE_BASELINES") != nullptr) {
    fs::create_directories(kBaselineDir);
    fs::copy_file(rendered, baseline, fs::copy_options::overwrite_existing);
    return ::testing::AssertionSuccess() << "renewed " << baseline;
  }
  if (!fs::exists(baseline)) {
    return ::testing::AssertionFailure() << "no baseline " << baseline
                                         << " (render one with VH_UPDATE_BASELINES=1 and look at it)";
  }
  const fs::path diff = kOutputDir / (name + ".diff.png");
  const double error = thresholdedError(rendered, baseline, diff);
  if (error_out != nullptr) *error_out = error;
  std::cout << name << " against " << baseline.filename().string() << ": thresholded error " << error << '\n';
  if (error < 0.0) return ::testing::AssertionFailure() << name << ": the frame's size differs from the baseline's";
  if (error > kVtkRegressionThreshold) {
    return ::testing::AssertionFailure() << name << ": thresholded error " << error << " > " << kVtkRegressionThreshold
                                         << " (rendered " << rendered << ", difference " << diff << ")";
  }
  return ::testing::AssertionSuccess() << name << ": thresholded error " << error;
}

/// A 320 x 240 window holding the main view on the built-in sphere (radius 20 mm) with the
/// probe, the camera reset as for every opened scan, then zoomed 1.5 times.
struct BaselineView {
  BaselineView() {
    auto* layout = new QVBoxLayout(&host);
    layout->setContentsMargins(0, 0, 0, 0);
    view = new SceneView(&host);
    layout->addWidget(view->widget());
    host.resize(320, 240);
    host.show();
    const runtime::LoadedScene& scene = sphereProbeScene();
    view->setScene(sceneActorsSpecFor(scene, runtime::LiveValues::initial(scene)), scene.X_WT_initial, ViewLook{});
    view->setMarkerVisible(false);
    view->resetCamera();
    // The reset frames the sphere and the probe above it with a margin; closer in, a few
    // millimetres of the tool's motion are more pixels (the comparison's teeth).
    view->widget()->renderer()->GetActiveCamera()->Zoom(1.5);
    view->widget()->renderer()->ResetCameraClippingRange();
  }

  /// The proxy tilted 20 degrees with its tip at height `z_m` above the sphere's centre (0.0205:
  /// resting on the top), the device 4 mm inside and to the side of it (the virtual coupling's
  /// stretch), with its force.
  void showPressedTool(double z_m = 0.0205) {
    ToolFrame frame;
    frame.X_WP.R_AB = Eigen::Quaterniond(Eigen::AngleAxisd(20.0 * std::numbers::pi / 180.0, Eigen::Vector3d::UnitX()));
    frame.X_WP.p_AB_m = Eigen::Vector3d(0.0, 0.0, z_m);
    frame.X_WD = frame.X_WP;
    frame.X_WD.p_AB_m += Eigen::Vector3d(0.004, 0.0, -0.004);
    frame.force_W_N = Eigen::Vector3d(-1.0, 0.0, 2.0);
    view->show(frame);
  }

  QImage still() {
    view->renderStill(true);
    test::pump(100);
    return view->widget()->grabFrame();
  }

  QWidget host;
  SceneView* view = nullptr;
};

TEST(BaselineImages, TheIsosurfaceWithTheProxyAndDeviceMeshes) {
  BaselineView v;
  v.showPressedTool();
  v.view->setRenderMode(RenderMode::kIsosurface, VolumePreset::kBone);
  EXPECT_TRUE(matchesBaseline(v.still(), "isosurface-proxy-device"));
}

TEST(BaselineImages, TheCompositeRendering) {
  BaselineView v;
  v.showPressedTool();
  v.view->setRenderMode(RenderMode::kComposite, VolumePreset::kSoftTissue);
  EXPECT_TRUE(matchesBaseline(v.still(), "composite"));
}

TEST(BaselineImages, TheMaximumIntensityProjection) {
  BaselineView v;
  v.showPressedTool();
  v.view->setRenderMode(RenderMode::kMip, VolumePreset::kBone);
  EXPECT_TRUE(matchesBaseline(v.still(), "mip"));
}

TEST(BaselineImages, ASegmentSurfaceBesideTheScan) {
  BaselineView v;
  // One segment: a ball of radius 8 mm centred 14 mm to the side and 14 mm up, so that it
  // stands out of the scan's surface.
  const io::LoadedSegmentation seg =
      test::ballSegmentation(*sphereProbeScene().volume.field, Eigen::Vector3d(0.014, 0.0, 0.014), 0.008);
  const auto set = std::make_shared<const runtime::SegmentSet>(seg, std::vector<int>{}, std::vector<int>{0},
                                                               std::vector<int>{}, 1.0);
  v.view->setSegments(set.get());
  v.view->setRenderMode(RenderMode::kIsosurface, VolumePreset::kBone);
  EXPECT_TRUE(matchesBaseline(v.still(), "segment-surface"));
}

TEST(BaselineImages, TheComparisonSeesAProxyMovedBy5mm) {
  // The metric has teeth: the same scene with the proxy 5 mm higher is not the baseline.
  if (std::getenv("VH_UPDATE_BASELINES") != nullptr) GTEST_SKIP() << "renewing the baselines";
  BaselineView v;
  v.showPressedTool(0.0255);
  v.view->setRenderMode(RenderMode::kIsosurface, VolumePreset::kBone);
  double error = 0.0;
  ASSERT_TRUE(fs::exists(kBaselineDir / "isosurface-proxy-device.png"));
  EXPECT_FALSE(matchesBaseline(v.still(), "isosurface-proxy-moved", &error, "isosurface-proxy-device"));
  EXPECT_GT(error, kVtkRegressionThreshold);
}

}  // namespace
}  // namespace vh::ui
