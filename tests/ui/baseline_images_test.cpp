// The main view's pictures held against baseline images, so that a refactor cannot silently
// break what the clinician sees: the isosurface, composite and MIP renderings of the built-in
// sphere with the proxy and device meshes mirrored where a tick put them, a segment surface, an
// exported frame's overlay (time, |F|, |torque|, a marker's label, a critical alert) and the
// View > Stereo pictures (side by side, anaglyph).
// The comparison is VTK's own regression-test metric (vtkImageDifference, as vtkTesting's
// RegressionTest uses it: the mean thresholded pixel error, which tolerates the one-pixel shifts
// and small colour differences of anti-aliasing and a different rasteriser, at a threshold of 10).
// That tolerance also lets thin glyph strokes go missing, so the overlay's text and alert are in
// addition compared pixel for pixel in their bands (textDifferingFraction()).
//
// Baselines live in tests/ui/baselines/ (Mesa llvmpipe under Xvfb, 320 x 240). After a deliberate
// change of the picture, look at the new images and renew them:
//   VH_UPDATE_BASELINES=1 xvfb-run -a tests/ui/vh_ui_tests --gtest_filter='BaselineImages.*'
// Each run writes what it rendered (and, on a mismatch, the difference image) to
// baseline-images/ in the test's working folder.
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
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
#include "vh/runtime/recording.h"
#include "vh/runtime/scene.h"
#include "vh/runtime/segments.h"
#include "vh/runtime/session.h"
#include "vh/ui/export/media_export.h"
#include "vh/ui/panels/display_panel.h"
#include "vh/ui/view_controller.h"
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
    // Best quality again for the frame grabbed: a still frame drawn meanwhile that took longer
    // than SceneActors' kStillSlowMs (3 s, a busy machine) steps the next still frames down.
    view->renderStill(true);
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

/// A recording exporter's frame as a QImage: `frame` is RGB with the bottom row first
/// (RecordingFrameRenderer::render()).
QImage toQImage(vtkImageData* frame) {
  int dims[3];
  frame->GetDimensions(dims);
  QImage image(dims[0], dims[1], QImage::Format_RGB888);
  if (frame->GetNumberOfScalarComponents() != 3) return {};
  const auto* rows = static_cast<const unsigned char*>(frame->GetScalarPointer());
  for (int y = 0; y < dims[1]; ++y) {
    std::memcpy(image.scanLine(dims[1] - 1 - y), rows + static_cast<std::size_t>(3 * dims[0]) * y,
                static_cast<std::size_t>(3 * dims[0]));
  }
  return image;
}

/// 1 s of the proxy at rest 20 mm above the sphere's centre (its top), the device 2 mm below it,
/// with a fixed force (3, 4, 0) N (|F| = 5 N) and torque (0, 0, -0.012) N*m, at the scene's own
/// isovalue; a marker "nerve close" at 0.5 s and the critical segment "facial nerve" drilled at 0.6 s.
runtime::Recording overlayRecording() {
  const runtime::LoadedScene& scene = sphereProbeScene();
  const double isovalue = runtime::LiveValues::initial(scene).isovalue;
  runtime::Recording recording;
  for (int i = 0; i <= 100; ++i) {
    runtime::TickRecord r;
    r.time_s = 0.01 * i;
    r.tick = static_cast<std::uint64_t>(i);
    r.p_WP_m[2] = 0.020;
    r.p_WD_m[2] = 0.018;
    r.force_W_N[0] = 3.0, r.force_W_N[1] = 4.0;
    r.torque_W_Nm[2] = -0.012;
    r.isovalue = isovalue;
    recording.records.push_back(r);
  }
  recording.events.push_back({0.5, 50, "marker", R"({"label":"nerve close"})"});
  recording.events.push_back({0.6, 60, "critical_removed", R"({"segment":"facial nerve","voxels":3,"mm3":0.1})"});
  return recording;
}

/// The exported frame (320 x 240, the exporter's default camera) of the record at 0.70 s, when the
/// marker's label and the critical alert are both shown; without the overlay when `overlay` is null.
QImage exportedFrame(const runtime::Recording& records, const runtime::Recording* overlay) {
  const runtime::LoadedScene& scene = sphereProbeScene();
  RecordingFrameRenderer frames(sceneActorsSpecFor(scene, runtime::LiveValues::initial(scene)), 320, 240, ViewLook{});
  frames.setOverlay(overlay);
  frames.show(records.records[70]);
  frames.resetCamera();
  return toQImage(frames.render()).copy();
}

/// The fraction of the pixels of `region` whose largest channel difference between `frame` and
/// tests/ui/baselines/BASELINE.png exceeds 64 of 255 (1 when the baseline is missing or its size
/// differs). A pixel-exact measure for what is drawn in 2-D, in the same pixels whatever the
/// rasteriser (text: FreeType's glyphs): vtkImageDifference's one-pixel shift tolerance lets thin
/// glyph strokes go missing unseen (a frame without the overlay's two lines of text scores about 1).
double textDifferingFraction(const QImage& frame, const std::string& baseline_name, const QRect& region) {
  const QImage baseline(QString::fromStdString((kBaselineDir / (baseline_name + ".png")).string()));
  if (baseline.isNull() || baseline.size() != frame.size()) return 1.0;
  const QImage a = frame.convertToFormat(QImage::Format_RGB32);
  const QImage b = baseline.convertToFormat(QImage::Format_RGB32);
  const QRect r = region.intersected(a.rect());
  std::size_t differing = 0;
  for (int y = r.top(); y <= r.bottom(); ++y) {
    const auto* pa = reinterpret_cast<const QRgb*>(a.constScanLine(y));
    const auto* pb = reinterpret_cast<const QRgb*>(b.constScanLine(y));
    for (int x = r.left(); x <= r.right(); ++x) {
      const int d = std::max({std::abs(qRed(pa[x]) - qRed(pb[x])), std::abs(qGreen(pa[x]) - qGreen(pb[x])),
                              std::abs(qBlue(pa[x]) - qBlue(pb[x]))});
      differing += d > 64 ? 1 : 0;
    }
  }
  return r.isEmpty() ? 1.0 : static_cast<double>(differing) / (static_cast<double>(r.width()) * r.height());
}

/// The overlay's bands of the 320 x 240 frame: the figures and the marker's label top left, the
/// critical alert bottom centre (the scene's props stay out of them but for the tool's tip).
const QRect kOverlayTextBand(0, 0, 320, 30);
const QRect kOverlayAlertBand(0, 210, 320, 30);
/// At most 0.3 % of a band's pixels may differ. Measured on llvmpipe: the camera turned by 0.5
/// degrees (the tool's tip in the text band) 0.15 %; |F| shown as 5.41 instead of 5.00 N 0.45 %,
/// the marker's line missing 2.4 %, no overlay 6.4 % of the text band and 28 % of the alert's.
constexpr double kTextDifferingFractionMax = 0.003;

TEST(BaselineImages, TheExportOverlayOnAFrame) {
  const runtime::Recording recording = overlayRecording();
  const QImage frame = exportedFrame(recording, &recording);
  EXPECT_TRUE(matchesBaseline(frame, "export-overlay"));
  const double text = textDifferingFraction(frame, "export-overlay", kOverlayTextBand);
  const double alert = textDifferingFraction(frame, "export-overlay", kOverlayAlertBand);
  std::cout << "export-overlay: differing pixels " << text << " of the text band, " << alert << " of the alert's\n";
  EXPECT_LE(text, kTextDifferingFractionMax) << "the overlay's figures or marker label changed";
  EXPECT_LE(alert, kTextDifferingFractionMax) << "the overlay's critical alert changed";
}

TEST(BaselineImages, TheComparisonSeesAFrameExportedWithoutTheOverlay) {
  // The metric has teeth: the same frame with --no-overlay is not the overlay's baseline.
  if (std::getenv("VH_UPDATE_BASELINES") != nullptr) GTEST_SKIP() << "renewing the baselines";
  ASSERT_TRUE(fs::exists(kBaselineDir / "export-overlay.png"));
  const runtime::Recording recording = overlayRecording();
  double error = 0.0;
  const QImage frame = exportedFrame(recording, nullptr);
  EXPECT_FALSE(matchesBaseline(frame, "export-no-overlay", &error, "export-overlay"));
  EXPECT_GT(error, kVtkRegressionThreshold);
  const double text = textDifferingFraction(frame, "export-overlay", kOverlayTextBand);
  std::cout << "export-no-overlay: differing pixels " << text << " of the text band\n";
  EXPECT_GT(text, kTextDifferingFractionMax);
}

/// The baseline view with View > Stereo's controller: no session scene (the view keeps the one
/// BaselineView set), the display panel out of the picture. The focal point is moved back to 1.5
/// times its distance from the camera (the camera stays where it is): VTK's eyes turn about the
/// focal point, so the sphere, in front of it now, is seen with a disparity of several pixels
/// instead of none, which an anaglyph shows as red and cyan fringes wide enough for the metric.
struct StereoBaselineView : BaselineView {
  StereoBaselineView() : panel(new DisplayPanel(&host)) {
    panel->hide();
    controller = std::make_unique<ViewController>(session, *view, *panel, prefs);
    showPressedTool();
    view->setRenderMode(RenderMode::kIsosurface, VolumePreset::kBone);
    vtkCamera* camera = view->widget()->renderer()->GetActiveCamera();
    camera->SetDistance(1.5 * camera->GetDistance());
    view->widget()->renderer()->ResetCameraClippingRange();
  }
  ~StereoBaselineView() { controller.reset(); }

  /// The view's picture in stereo `mode`.
  QImage stereoStill(ViewController::Stereo mode) {
    controller->setStereo(mode);
    return still();
  }

  DisplayPanel* panel;
  Preferences prefs;
  runtime::Session session;
  std::unique_ptr<ViewController> controller;
};

TEST(BaselineImages, TheStereoSideBySidePicture) {
  StereoBaselineView v;
  EXPECT_TRUE(matchesBaseline(v.stereoStill(ViewController::Stereo::kSideBySide), "stereo-side-by-side"));
}

TEST(BaselineImages, TheStereoAnaglyphPicture) {
  StereoBaselineView v;
  EXPECT_TRUE(matchesBaseline(v.stereoStill(ViewController::Stereo::kAnaglyph), "stereo-anaglyph"));
}

TEST(BaselineImages, TheComparisonSeesAMonoPictureForAStereoOne) {
  // The metric has teeth: the same view without stereo is neither stereo baseline.
  if (std::getenv("VH_UPDATE_BASELINES") != nullptr) GTEST_SKIP() << "renewing the baselines";
  ASSERT_TRUE(fs::exists(kBaselineDir / "stereo-side-by-side.png"));
  ASSERT_TRUE(fs::exists(kBaselineDir / "stereo-anaglyph.png"));
  StereoBaselineView v;
  const QImage mono = v.stereoStill(ViewController::Stereo::kOff);
  double error = 0.0;
  EXPECT_FALSE(matchesBaseline(mono, "stereo-off-vs-side-by-side", &error, "stereo-side-by-side"));
  EXPECT_GT(error, kVtkRegressionThreshold);
  EXPECT_FALSE(matchesBaseline(mono, "stereo-off-vs-anaglyph", &error, "stereo-anaglyph"));
  EXPECT_GT(error, kVtkRegressionThreshold);
}

}  // namespace
}  // namespace vh::ui
